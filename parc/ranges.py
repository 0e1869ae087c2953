"""Cell and supercell value ranges: what the classification of `parc.classify` compares.

About this technique
--------------------
A cell's trilinear interpolant is a convex combination of its eight
corners, so its range is exactly ``[min, max]`` of the corners:
`cell_minmax` computes those once per volume.

Cells are grouped into *supercells* of ``m x n x p`` cells (paper, Table 4:
3x5x5, 1.03^3, 6x4x3.125, ...): fewer, larger boxes mean fewer proxy
polygons but longer walks through empty cells inside PC supercells.
Sizes are real numbers. Along x, supercell ``a`` covers the index
interval ``[a m, min((a+1) m, nx-1)]`` and there are ``ceil((nx-1)/m)``
(`supercell_grid`).

The range of a supercell is the *exact* range of the interpolant over its
box, also when the box cuts cells (fractional sizes, sub-cells): refine
each axis with the supercell boundaries (sample positions plus the
fractional boundaries), evaluate the interpolant on that refined lattice
(trilinear is a tensor product of linear interpolants, so this is three
separable 1-D interpolations), and reduce min/max over the refined points
in each supercell's closed box. Every refined box lies inside one cell and
the interpolant is multilinear there, so its extremes sit at refined
corners: the result is exact, not merely conservative. For whole-cell
sizes no refinement is needed and the ranges stay in the data's native
dtype, reduced from cell ranges or coarser whole-cell ones (`block_ranges`);
along an axis whose boundaries are all integers nothing is interpolated.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import prange

from data_tools import InputError
from data_tools.volume import text_or_flag
from raycast.composite import BOUNDARY_SNAP
from raycast.config import kernel

#: Supercell boundaries this close to an integer (in cells) are snapped to
#: it, so that e.g. ``10 * 0.1`` does not leave a 2e-16-cell sliver.
SNAP = BOUNDARY_SNAP

#: Refined values per chunk when ranges are computed slab by slab: bounds
#: the temporaries (float64 where interpolated) to ~32 MB per array.
CHUNK_VALUES = 1 << 22

#: Interpolated ranges are widened by this fraction of the data's largest
#: magnitude, so a supercell whose exact range only touches the isovalue
#: stays PC. The three nested lerps round to a few ulps (~1e-15 relative);
#: the caster's own positions round by a few 2^-53 of the ray origin's
#: distance in cells (up to `raycast.traverse.FAR_ORIGIN` grid extents and
#: `FAR_ORIGIN_CELLS`, beyond which it walks from the volume's entry), and a field can change
#: by up to ~6 times its largest magnitude per cell: 2^-32 (~2e-10) covers
#: origins some 40,000 cells away. Positions inside a grid round by as much
#: of its length: a grid longer than `RANGE_PAD_CELLS` has its pad grown in
#: proportion (a steep field along 2.2 million samples told the methods apart).
RANGE_PAD = 2.0 ** -32
RANGE_PAD_CELLS = 32768

#: Most supercells a grid may have (a guard against sub-cell sizes on big
#: volumes, which would need tens of GB).
MAX_SUPERCELLS = 1 << 28


# --------------------------------------------------------------------------
# Cell ranges
# --------------------------------------------------------------------------

def cell_minmax(data):
    """Min and max of the eight corners of every cell.

    Parameters
    ----------
    data : ndarray, shape (nz, ny, nx)
        Samples, any real dtype, none NaN (`data_tools.Volume` refuses them).

    Returns
    -------
    mn, mx : ndarray, shape (nz-1, ny-1, nx-1), ``data.dtype``
        The exact range of the trilinear interpolant over each cell.

    Notes
    -----
    One parallel pass over the samples (`_cell_minmax`), with no
    temporaries: 512^3 int16 samples in 0.035 s on two threads, against
    0.14 s for NumPy's six separable ``np.minimum``/``np.maximum`` passes
    over z-slabs (a new volume's first PARC frame pays it).
    """
    data = np.asarray(data)
    nz, ny, nx = data.shape
    mn = np.empty((max(nz - 1, 0), max(ny - 1, 0), max(nx - 1, 0)), data.dtype)
    mx = np.empty_like(mn)
    if mn.size:
        _cell_minmax(np.ascontiguousarray(data), mn, mx)
    return mn, mx


@kernel(parallel=True)
def _cell_minmax(data, mn, mx):
    nz, ny, nx = data.shape
    for k in prange(nz - 1):
        for j in range(ny - 1):
            # Each column of four samples (two rows, two slices) is reduced once and shared by
            # the two cells either side of it.
            lo = min(min(data[k, j, 0], data[k, j + 1, 0]), min(data[k + 1, j, 0], data[k + 1, j + 1, 0]))
            hi = max(max(data[k, j, 0], data[k, j + 1, 0]), max(data[k + 1, j, 0], data[k + 1, j + 1, 0]))
            for i in range(1, nx):
                a, b = data[k, j, i], data[k, j + 1, i]
                c, d = data[k + 1, j, i], data[k + 1, j + 1, i]
                clo = min(min(a, b), min(c, d))
                chi = max(max(a, b), max(c, d))
                mn[k, j, i - 1] = min(lo, clo)
                mx[k, j, i - 1] = max(hi, chi)
                lo = clo
                hi = chi


# --------------------------------------------------------------------------
# Supercell grids
# --------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class SupercellGrid:
    """Supercell boundaries of one volume for one supercell size.

    Attributes
    ----------
    size : (m, n, p)
        Cells per supercell along x, y, z (real numbers).
    dims : (nx, ny, nz)
        Samples of the volume.
    edges : tuple of three float64 arrays
        Index-space boundaries along x, y, z: supercell ``a`` along x spans
        ``[edges[0][a], edges[0][a+1]]``; first 0, last ``nx - 1``.
    """

    size: tuple
    dims: tuple
    edges: tuple = field(repr=False)

    @property
    def counts(self):
        """Supercells along ``(x, y, z)``."""
        return tuple(len(e) - 1 for e in self.edges)

    @property
    def shape(self):
        """``(Az, Ay, Ax)``: the shape of range and mask arrays."""
        ax, ay, az = self.counts
        return (az, ay, ax)

    @property
    def integral(self):
        """True when every boundary lies on a sample plane (whole cells only)."""
        return all(_is_integral(e) for e in self.edges)

    def world_edges(self, volume):
        """Boundaries in world coordinates: ``origin + edges * spacing`` per axis."""
        return tuple(o + e * s for o, e, s in zip(volume.origin, self.edges, volume.spacing))


def supercell_grid(dims, size):
    """The supercell boundaries of a volume with ``dims`` samples.

    Parameters
    ----------
    dims : (nx, ny, nz)
        Sample counts, each at least 2.
    size : float or (m, n, p)
        Cells per supercell along x, y, z; positive. Sizes below 1 make
        sub-cells, non-integers cut cells.

    Returns
    -------
    SupercellGrid

    Raises
    ------
    InputError
        A size that is not positive and finite, or so small that the grid
        would exceed `MAX_SUPERCELLS`.
    """
    size = supercell_size(size)
    # Counted before the edges are built: a size of 1e-9 would ask for gigabytes of them.
    # In floats: a size of 5e-324 gives an infinite count, which no integer holds.
    quotients = [(n - 1 - SNAP) / m for n, m in zip(dims, size)]
    total = (math.prod(max(1, math.ceil(q)) for q in quotients) if all(math.isfinite(q) for q in quotients)
             else math.inf)
    if total > MAX_SUPERCELLS:
        count = (f"{total:.3g}" if total < 1e300 else "over 1e300" if total == math.inf
                 else f"about 1e{len(str(total)) - 1}")   # not 300 digits
        raise InputError(f"supercell size {_fmt_size(size)} gives {count} supercells "
                         f"(at most {MAX_SUPERCELLS}); choose a larger size")
    edges = tuple(_axis_edges(n, m) for n, m in zip(dims, size))
    return SupercellGrid(size=size, dims=tuple(int(n) for n in dims), edges=edges)


def supercell_size(size):
    """``(m, n, p)`` floats from a number or three numbers, validated."""
    try:
        parts = [size] * 3 if np.ndim(size) == 0 else list(size)
        if any(text_or_flag(s) for s in parts):
            raise TypeError
        t = tuple(float(s) for s in parts)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"supercell size must be a number or three numbers, got {size!r}") from None
    if len(t) != 3:
        raise InputError(f"supercell size must be a number or three numbers, got {len(t)}: {size!r}")
    if not all(math.isfinite(s) and s > 0 for s in t):
        raise InputError(f"supercell size must be positive and finite, got {size!r}")
    return t


def _fmt_size(size):
    return "x".join(f"{s:g}" for s in size)


def _axis_edges(n, m):
    """Boundaries ``0, m, 2m, ..., n-1`` (index space) along one axis of ``n`` samples."""
    cells = n - 1
    # Interior boundaries stay more than SNAP below the last one: a last
    # supercell thinner than that is merged into its neighbour.
    count = max(1, math.ceil((cells - SNAP) / m))
    e = np.arange(count + 1, dtype=np.float64) * m
    e[-1] = cells
    near = np.abs(e - np.round(e)) <= SNAP
    e[near] = np.round(e[near])
    return e


def _is_integral(e):
    return bool(np.all(e == np.round(e)))


# --------------------------------------------------------------------------
# Supercell ranges
# --------------------------------------------------------------------------

def supercell_ranges(data, grid, *, cell_ranges=None):
    """Exact range of the trilinear interpolant over every supercell.

    Parameters
    ----------
    data : ndarray, shape (nz, ny, nx)
    grid : SupercellGrid
        Built for this data's dims.
    cell_ranges : (mn, mx) or None
        `cell_minmax` of the data, if already known: whole-cell grids are
        then reduced from it (cheaper than from the samples).

    Returns
    -------
    mn, mx : ndarray, shape ``grid.shape``
        Native dtype for whole-cell grids; float64, widened by `RANGE_PAD`
        of the data's magnitude, when any boundary cuts a cell.

    Notes
    -----
    Exact for every size (see the module notes): the extremes over a
    sub-box of a cell lie at its corners, whose values are interpolated
    separably along each axis that has fractional boundaries.
    """
    data = np.asarray(data)
    nz, ny, nx = data.shape
    if grid.dims != (nx, ny, nz):
        raise InputError(f"supercell grid is for {grid.dims} samples, data has {(nx, ny, nz)}")
    if grid.integral and cell_ranges is not None:
        return block_ranges(cell_ranges, grid.edges, grid.shape)
    axes = [_refine(n, e) for n, e in zip((nx, ny, nz), grid.edges)]
    ax_x, ax_y, ax_z = axes
    fractional = not grid.integral
    az, ay, axn = grid.shape
    out_dtype = np.float64 if fractional else data.dtype
    mn = np.empty((az, ay, axn), out_dtype)
    mx = np.empty_like(mn)
    # Chunk over slabs of supercells in z, each one split along y, then x, where a single
    # supercell's slab would not fit: a supercell 0.0001 cells wide in x and 64 in y and z
    # refines into billions of points per slab. Each chunk needs the refined points of its
    # closed boxes, so neighbouring chunks share one boundary plane.
    qz, qy, qx = ax_z.q, ax_y.q, ax_x.q
    for c0, c1 in _spans(qz, len(ax_y.pos) * len(ax_x.pos)):
        pz = qz[c1] - qz[c0] + 1
        for b0, b1 in _spans(qy, pz * len(ax_x.pos)):
            py = qy[b1] - qy[b0] + 1
            for a0, a1 in _spans(qx, pz * py):
                r = _refined_block(data, (ax_z, ax_y, ax_x),
                                   ((qz[c0], qz[c1] + 1), (qy[b0], qy[b1] + 1), (qx[a0], qx[a1] + 1)))
                for out, op in ((mn, np.minimum), (mx, np.maximum)):
                    v = _closed_reduce(r, qx[a0:a1 + 1] - qx[a0], 2, op)
                    v = _closed_reduce(v, qy[b0:b1 + 1] - qy[b0], 1, op)
                    out[c0:c1, b0:b1, a0:a1] = _closed_reduce(v, qz[c0:c1 + 1] - qz[c0], 0, op)
    if fractional:
        lo, hi = float(data.min()), float(data.max())
        pad = (RANGE_PAD * max(1.0, max(nx, ny, nz) / RANGE_PAD_CELLS)
               * max(abs(lo), abs(hi), np.finfo(np.float64).tiny))
        mn -= pad
        mx += pad
    return mn, mx


@dataclass
class _Axis:
    """One refined axis: positions, their lerp (index, weight), and where the boundaries sit."""
    pos: np.ndarray      # refined positions (index space), sorted
    i: np.ndarray        # floor cell index per position, clamped to n-2
    w: np.ndarray        # weight of sample i+1
    q: np.ndarray        # index into pos of each supercell boundary
    integral: bool


def _refine(n, edges):
    if _is_integral(edges):
        pos = np.arange(n, dtype=np.float64)
        return _Axis(pos, np.arange(n), np.zeros(n), edges.astype(np.int64), True)
    pos = np.union1d(np.arange(n, dtype=np.float64), edges)
    i = np.minimum(np.floor(pos).astype(np.int64), n - 2)
    return _Axis(pos, i, pos - i, np.searchsorted(pos, edges), False)


def _lerp_axis(a, ax, axis, lo, hi):
    """Values at refined positions ``lo:hi`` along ``axis`` of ``a`` (whose index 0 is sample ``ax.i[lo]``)."""
    if ax.integral:
        return a
    base = ax.i[lo]
    i = ax.i[lo:hi] - base
    w = ax.w[lo:hi]
    shape = [1, 1, 1]
    shape[axis] = -1
    w = w.reshape(shape)
    a0 = np.take(a, i, axis=axis).astype(np.float64)
    a1 = np.take(a, i + 1, axis=axis).astype(np.float64)
    # (1 - w) a0 + w a1 gives the sample itself at w = 0 and w = 1.
    return (1.0 - w) * a0 + w * a1


def _spans(q, per):
    """Runs ``(b0, b1)`` of the blocks between boundaries ``q`` (indices of refined points)
    whose points, ``q[b1] - q[b0] + 1``, times ``per`` fit `CHUNK_VALUES`; one block at least."""
    fit = max(CHUNK_VALUES // max(per, 1), 2)
    count = len(q) - 1
    b0 = 0
    while b0 < count:
        b1 = int(np.searchsorted(q, q[b0] + fit - 1, side="right")) - 1
        b1 = min(max(b1, b0 + 1), count)
        yield b0, b1
        b0 = b1


def _refined_block(data, axes, bounds):
    """The interpolant on the refined lattice at points ``lo:hi`` of each axis, ``axes`` and
    ``bounds`` given in the order z, y, x."""
    rows = []
    for n, ax, (lo, hi) in zip(data.shape, axes, bounds):
        k0 = int(ax.i[lo]) if not ax.integral else lo
        k1 = int(ax.i[hi - 1]) + 2 if not ax.integral else hi
        rows.append(slice(k0, min(k1, n)))
    r = data[tuple(rows)]
    for axis, (ax, (lo, hi)) in enumerate(zip(axes, bounds)):
        r = _lerp_axis(r, ax, axis, lo, hi)
    return r


def _closed_reduce(a, q, axis, op):
    """Reduce ``a`` along ``axis`` over closed index blocks ``[q[b], q[b+1]]``."""
    q = np.asarray(q, dtype=np.int64)
    if np.all(np.diff(q) == 1):
        # Blocks of one interval: neighbour pairs.
        n = a.shape[axis]
        return op(np.take(a, np.arange(n - 1), axis=axis), np.take(a, np.arange(1, n), axis=axis))
    half = op.reduceat(a, q[:-1], axis=axis)
    return op(half, np.take(a, q[1:], axis=axis))


def block_ranges(ranges, edges, shape):
    """Min and max of whole-cell ranges ``(mn, mx)`` (cells' own, or blocks of them) over the
    boxes ``[ez[c], ez[c+1]) x [ey[b], ey[b+1]) x [ex[a], ex[a+1])`` of ``edges = (ex, ey, ez)``,
    counted in those ranges' boxes: ``(mn, mx)`` of ``shape``, in their dtype. One parallel
    pass (`_block_ranges`)."""
    mn, mx = ranges
    out_mn = np.empty(shape, mn.dtype)
    out_mx = np.empty(shape, mx.dtype)
    _block_ranges(mn, mx, *(np.asarray(e, dtype=np.int64) for e in edges), out_mn, out_mx)
    return out_mn, out_mx


@kernel(parallel=True)
def _block_ranges(mn, mx, ex, ey, ez, out_mn, out_mx):
    """Min of ``mn`` and max of ``mx`` over the cells ``[ez[c], ez[c+1]) x [ey[b], ey[b+1]) x
    [ex[a], ex[a+1])`` of each block ``(c, b, a)``.

    Each row of cells is reduced along x into a row of blocks, then folded into its block row.
    The cost model reads every cell of a big volume for blocks of 2 and 3: a 512x512x1734
    volume's blocks of 2 took 0.58 s reduced a cell at a time into the output, and take 0.05 s
    so (two threads), near the 0.04 s of a pass that only reads both arrays."""
    cz, cy, cx = out_mn.shape
    # The leading blocks of the first one's width, when it is 2 or 3 (the others by their edges).
    s = ex[0]
    w = ex[1] - s
    full = 0
    while (w == 2 or w == 3) and full < cx and ex[full + 1] - ex[full] == w:
        full += 1
    for c in prange(cz):
        row_mn = np.empty(cx, mn.dtype)
        row_mx = np.empty(cx, mx.dtype)
        for b in range(cy):
            lo = out_mn[c, b]
            hi = out_mx[c, b]
            first = True
            for k in range(ez[c], ez[c + 1]):
                for j in range(ey[b], ey[b + 1]):
                    # From the first block on: an index plus a loaded offset might be negative,
                    # and the test for it kept LLVM from vectorizing the loops.
                    rm = mn[k, j, s:]
                    rx = mx[k, j, s:]
                    # Widths of 2 and 3 spelled out, so that LLVM vectorizes their loops.
                    if w == 2:
                        for a in range(full):
                            row_mn[a] = min(rm[2 * a], rm[2 * a + 1])
                            row_mx[a] = max(rx[2 * a], rx[2 * a + 1])
                    elif w == 3:
                        for a in range(full):
                            row_mn[a] = min(min(rm[3 * a], rm[3 * a + 1]), rm[3 * a + 2])
                            row_mx[a] = max(max(rx[3 * a], rx[3 * a + 1]), rx[3 * a + 2])
                    for a in range(full, cx):
                        lo_ = rm[ex[a] - s]
                        hi_ = rx[ex[a] - s]
                        for i in range(ex[a] - s + 1, ex[a + 1] - s):
                            lo_ = min(lo_, rm[i])
                            hi_ = max(hi_, rx[i])
                        row_mn[a] = lo_
                        row_mx[a] = hi_
                    if first:
                        for a in range(cx):
                            lo[a] = row_mn[a]
                            hi[a] = row_mx[a]
                        first = False
                    else:
                        for a in range(cx):
                            lo[a] = min(lo[a], row_mn[a])
                            hi[a] = max(hi[a], row_mx[a])
