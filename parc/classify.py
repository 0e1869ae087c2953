"""The classification of cells and supercells for an isovalue or a transfer function, and the
per-volume cache of everything classification and the walks derive from a volume.

About this technique
--------------------
PARC (Sobierajski & Avila 1995, §2) sorts the volume's cells into *empty*
ones, whose trilinear interpolant cannot reach the isovalue, and *possibly
contributing* (PC) ones. Their ranges (`parc.ranges`: cells, and supercells
of any size) are computed once per volume, and a new isovalue only re-runs
the cheap comparison in `classify_iso`; a transfer function's is
`classify_tf`. `VolumeIndex` keeps the ranges, grids and skip tables.

`parc.costmodel.choose_supercell` picks a size with a measured cost
model: rasterizing the proxy costs per polygon, walking a ray costs per
cell, and bigger supercells trade the first for the second.
"""
from __future__ import annotations

import numpy as np
from numba import prange

from raycast.composite import INTERP_ROUNDING
from raycast.config import RANGE_CHUNK, kernel
from raycast.iso import NO_SKIP_OCTANTS, OCTANTS
from raycast.rays import chunk_count, chunk_run

from .ranges import block_ranges, cell_minmax, supercell_grid, supercell_ranges, supercell_size
from .skip import ISO_JUMP_MIN, SKIP_CAP, TF_JUMP_MIN, octant_radius, skip_radius

#: Skip tables (isovalues, transfer functions) kept per volume.
SKIP_CACHE_SIZE = 4

#: Isovalues a volume remembers being rendered at, so that a second frame builds their skip
#: tables by octant (`VolumeIndex.iso_octant_skip`).
ASKS_KEPT = 64


# --------------------------------------------------------------------------
# Classification
# --------------------------------------------------------------------------

def classify_iso(mn, mx, iso):
    """Possibly contributing boxes for an isosurface: ``mn <= iso <= mx``.

    Parameters
    ----------
    mn, mx : ndarray
        Ranges from `cell_minmax` or `supercell_ranges`.
    iso : float

    Returns
    -------
    ndarray of bool, same shape

    Notes
    -----
    The comparison is done in float64, as the caster does
    (``float(sample) - iso``): in float32 the isovalue would round and
    misclassify boxes whose range ends between the two. Inclusive at both
    ends, so a surface that only touches a box (isovalue equal to a corner)
    keeps it.
    """
    return _over_boxes(_classify_iso, mn, mx, iso, np.bool_)


def _over_boxes(kernel, mn, mx, iso, dtype):
    """``kernel(mn, mx, iso, out)`` over the ranges flattened, into a new ``dtype`` array of their shape."""
    mn = np.ascontiguousarray(mn)
    mx = np.ascontiguousarray(mx)
    if mn.shape != mx.shape:
        raise ValueError(f"ranges of shapes {mn.shape} and {mx.shape}")
    out = np.empty(mn.shape, dtype)
    if out.size:
        kernel(mn.reshape(-1), mx.reshape(-1), np.float64(iso), out.reshape(-1))
    return out


@kernel(parallel=True)
def _classify_iso(mn, mx, iso, out):
    """One parallel pass: 57 million int16 ranges (a 512x512x1734 volume's blocks of 2 cells,
    which the cost model classifies for every new isovalue) in 0.026 s, against 0.047 s for
    NumPy's two comparisons through float64 and their ``&``."""
    n = out.shape[0]
    for c in prange(chunk_count(n, RANGE_CHUNK)):
        m0, m1 = chunk_run(c, RANGE_CHUNK, n)
        for m in range(m0, m1):
            out[m] = (np.float64(mn[m]) <= iso) & (np.float64(mx[m]) >= iso)


def classify_tf(mn, mx, tf):
    """Possibly contributing boxes for a transfer function: its opacity is non-zero somewhere in ``[mn, mx]``.

    Each range is widened by `raycast.composite.INTERP_ROUNDING`, how far
    the casters' interpolated samples can round past a cell's corners, so
    that a function starting just past a range cannot show in ``brute``
    alone. Every classification for a transfer function goes through here
    (supercells, the skip table, the ideal counts).
    """
    return tf.nonzero_in(mn, mx, rounding=INTERP_ROUNDING)


def tf_key(tf):
    """What a classification for ``tf`` depends on, as a cache key: its opacity points alone
    (a new colour map classifies nothing again)."""
    op_x, op_y, _, _ = tf.arrays()
    return ("tf", op_x.tobytes(), op_y.tobytes())


def sign_iso(mn, mx, iso):
    """Which side of an isovalue each box lies on: int8 +1 (all above), -1 (all below), 0 (neither).

    The classes of `skip_radius` for an isosurface (`raycast.iso.cast_iso_ray`). Strict where
    `classify_iso` is inclusive, so the two never disagree: a box is signed
    exactly when it is not possibly contributing, and the sign is that of
    ``float(sample) - iso`` at each of its samples, as the caster computes it.
    One parallel pass (`_sign_iso`): a 512x512x1734 volume's cells in 0.21 s,
    against 1.9 s for NumPy's two comparisons through float64.
    """
    return _over_boxes(_sign_iso, mn, mx, iso, np.int8)


@kernel(parallel=True)
def _sign_iso(mn, mx, iso, out):
    n = out.shape[0]
    for c in prange(chunk_count(n, RANGE_CHUNK)):
        m0, m1 = chunk_run(c, RANGE_CHUNK, n)
        for m in range(m0, m1):
            # In float64, as the caster compares: a float32 isovalue would misplace ranges ending
            # between the two roundings.
            out[m] = (1 if np.float64(mn[m]) > iso else 0) - (1 if np.float64(mx[m]) < iso else 0)


# --------------------------------------------------------------------------
# Per-volume cache
# --------------------------------------------------------------------------

class VolumeIndex:
    """Everything classification needs from one volume, computed once and kept.

    Cell ranges and per-size supercell ranges are computed on first use;
    a new isovalue only calls `classify`. Get the shared instance with
    `VolumeIndex.of(volume)` (kept in ``volume.meta``).
    """

    _META_KEY = "_parc_index"

    def __init__(self, volume):
        self.volume = volume
        self._cells = None
        self._ranges = {}
        self._grids = {}
        self._kept = {}

    @classmethod
    def of(cls, volume):
        """The volume's index, created on first call and kept in ``volume.meta``."""
        idx = volume.meta.get(cls._META_KEY)
        if idx is None or idx.volume is not volume:
            idx = cls(volume)
            volume.meta[cls._META_KEY] = idx
        return idx

    def kept(self, stage):
        """A dict kept with the index for a later stage's results over this volume (skip tables,
        the chosen supercell size, proxies, light buffers): they go with the volume, and a volume
        made anew (``dataclasses.replace``) starts without them."""
        return self._kept.setdefault(stage, {})

    def cell_minmax(self):
        """`cell_minmax` of the volume's data (cached)."""
        if self._cells is None:
            self._cells = cell_minmax(self.volume.data)
        return self._cells

    def grid(self, size):
        """The `SupercellGrid` for ``size`` (cached)."""
        key = supercell_size(size)
        if key not in self._grids:
            self._grids[key] = supercell_grid(self.volume.dims, key)
        return self._grids[key]

    def ranges(self, size):
        """Supercell ranges for ``size`` (cached); see `supercell_ranges`."""
        key = supercell_size(size)
        if key not in self._ranges:
            grid = self.grid(key)
            if key == (1.0, 1.0, 1.0):
                self._ranges[key] = self.cell_minmax()
            elif grid.integral:
                self._ranges[key] = self._from_blocks(grid)
            else:
                self._ranges[key] = supercell_ranges(self.volume.data, grid)
        return self._ranges[key]

    def _from_blocks(self, grid):
        """Whole-cell ranges of ``grid`` reduced from the coarsest ranges kept whose blocks tile
        its supercells (cells at worst): the cost model asks for 2, 3, 4, 6, 8 and 12 in turn,
        and only 2 and 3 then read every cell. A 512x512x1734 volume's six sizes take 0.13 s so
        (two threads). Before `_block_ranges` reduced whole rows of blocks they took 0.66 s, and
        1.48 s with every size reduced from the cells."""
        self._ranges.setdefault((1.0, 1.0, 1.0), self.cell_minmax())
        cells = [n - 1 for n in grid.dims]

        def tiles(d):
            return all(b.is_integer() and all(e % b == 0 or e == c for e in edges)
                       for b, edges, c in zip(d, grid.edges, cells))

        d = min((d for d in self._ranges if tiles(d)), key=lambda d: self._ranges[d][0].size)
        # Each supercell's cells, counted in blocks of d: its last block may end early with it.
        return block_ranges(self._ranges[d], [np.ceil(e / b) for e, b in zip(grid.edges, d)], grid.shape)

    def classify(self, iso, size):
        """Possibly contributing supercells of ``size`` for isovalue ``iso``: bool ``grid.shape``."""
        mn, mx = self.ranges(size)
        return classify_iso(mn, mx, iso)

    def iso_skip(self, iso):
        """The skip table for isovalue ``iso`` and the smallest radius worth a jump, kept for the last few.

        One int8 per cell (`raycast.iso.cast_iso_ray`): `skip_radius` of the
        cells' `sign_iso`, i.e. ``s * (r + 1)`` where every cell within
        Chebyshev distance ``r`` has the sign ``s`` (±1), 0 for a cell whose
        range holds the isovalue. The walk steps a signed cell without
        reading its corners and jumps across the cube of radius ``r``.
        """
        def table():
            mn, mx = self.cell_minmax()
            return skip_radius(sign_iso(mn, mx, iso), SKIP_CAP)

        return self._skip(("iso", float(iso)), table, ISO_JUMP_MIN)

    def iso_octant_skip(self, iso, octants):
        """Skip tables for isovalue ``iso`` by ray octant, and the smallest radius worth a jump.

        An int8 array ``(8, nz, ny, nx)``: entry ``o`` is `octant_radius` of
        the cells' `sign_iso` for the rays of octant ``o``
        (`raycast.iso.octant`), built for the octants in ``octants`` (and any
        built before). The others hold 0, "may contribute", everywhere: a
        ray of such an octant still gets the same hit, reading every cell's
        corners. The array is allocated zeroed, so an octant never built
        takes no memory (Linux maps zero pages on first touch). An
        isovalue's first frame gets none, ``(NO_SKIP_OCTANTS, -1)``, unless
        `expect_frames` said more will follow.
        """
        mn, mx = self.cell_minmax()
        if ("iso octants", float(iso)) not in self.kept("skip tables") and not self._asked_before(iso):
            # One frame does not repay a table: the CT head's cost 12 ms an octant to save 4 ms of its
            # cast, a 512x512x1734 volume's 0.9-2.6 s to save none (its walks end within a cell
            # or two). The walk without one finds the same hits; a second frame of the
            # isovalue, or one `expect_frames` announced, builds them.
            return NO_SKIP_OCTANTS, -1

        def table():
            return np.zeros((OCTANTS,) + mn.shape, np.int8), set()

        (tables, built), jump_min = self._skip(("iso octants", float(iso)), table, ISO_JUMP_MIN)
        missing = sorted(set(int(o) for o in octants) - built)
        if missing:
            classes = sign_iso(mn, mx, iso)
            for o in missing:
                octant_radius(classes, o, SKIP_CAP, tables[o])
                built.add(o)
        return tables, jump_min

    def expect_frames(self, iso):
        """Say that isovalue ``iso`` will be rendered again (`parc.compare` times frames after
        the first): its skip tables by octant are built from its next frame on."""
        self._asked_before(iso)

    def _asked_before(self, iso):
        """Whether `iso_octant_skip` was asked for isovalue ``iso`` before; this ask is kept
        (the last `ASKS_KEPT` isovalues)."""
        asks = self.kept("octant asks")
        seen = asks.pop(float(iso), False)
        asks[float(iso)] = True
        while len(asks) > ASKS_KEPT:
            asks.pop(next(iter(asks)))
        return seen

    def tf_skip(self, tf):
        """The skip table for transfer function ``tf`` and the smallest radius worth a jump, kept for the last few.

        One int8 per cell (`raycast.composite.accumulate_ray`):
        `MAY_CONTRIBUTE` (0) where the opacity is non-zero somewhere in the
        cell's range, else ``r + 1`` where every cell within Chebyshev
        distance ``r`` is transparent too (`skip_radius`). A sample in a
        transparent cell is not interpolated; the first one in a cube of
        radius at least the jump minimum skips the samples up to its exit.
        """
        def table():
            mn, mx = self.cell_minmax()
            # Inverted in place: one volume-sized array fewer (a 512x512x1734 volume's is 455 MB).
            transparent = classify_tf(mn, mx, tf)
            np.logical_not(transparent, out=transparent)
            return skip_radius(transparent.view(np.int8), SKIP_CAP)

        return self._skip(tf_key(tf), table, TF_JUMP_MIN)

    def _skip(self, key, table, jump_min):
        cache = self.kept("skip tables")
        if key not in cache:
            if len(cache) >= SKIP_CACHE_SIZE:
                cache.pop(next(iter(cache)))
            cache[key] = table()
        return cache[key], jump_min
