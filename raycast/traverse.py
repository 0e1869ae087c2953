"""Rays in index space, ray/box clipping and Amanatides–Woo cell traversal.

Index space: a world point ``p`` has index coordinates ``(p - origin) / spacing``
(x, y, z), so sample ``data[k, j, i]`` sits at ``(i, j, k)`` and every cell
boundary is an integer plane. The ray ``o + t d`` becomes ``O + t D`` with
the same ``t`` (a world distance), so depths need no conversion.

Why the traversal is written the way it is: the unaccelerated caster starts
at the ray's entry into the volume, PARC somewhere later, and both must
see each cell with the very same t-interval so the cubic is solved on the
same numbers. Each crossing time is therefore computed directly from the
integer plane, ``(plane - O) * invD``, never accumulated; a cell's interval
is ``[max(t_in, entry planes), min(t_out, exit planes)]``, a function of the
ray and the cell alone, whichever cell the walk started from.

The casters move the origin of a ray from a distant eye to where it
enters the volume before walking it (`entry_anchor`): crossing times and
local coordinates like ``(O - i) + t D`` then round at the volume's scale
rather than the eye's distance, which an eye far away (a parallel view
from 1e8 units) makes large enough to matter.
"""
import math

import numpy as np

from numba import types
from numba.extending import overload

from .bricks import BrickedSamples, bricked_corners
from .config import OVERLOAD_JIT, kernel

#: Below this an index-space direction component counts as zero: its
#: reciprocal would overflow, and the ray moves less than 1e-200 cells per
#: unit of t along that axis.
TINY_DIRECTION = 1e-200


@kernel
def to_index_space(ox, oy, oz, dx, dy, dz, org, spc):
    """World ray -> index-space ray (O, D); ``org``/``spc`` are (x, y, z)."""
    return ((ox - org[0]) / spc[0], (oy - org[1]) / spc[1], (oz - org[2]) / spc[2],
            dx / spc[0], dy / spc[1], dz / spc[2])


@kernel
def _slab(o, d, hi):
    if abs(d) < TINY_DIRECTION:
        if o < 0.0 or o > hi:
            return math.inf, -math.inf
        return -math.inf, math.inf
    inv = 1.0 / d
    t0 = (0.0 - o) * inv
    t1 = (hi - o) * inv
    if t0 > t1:
        return t1, t0
    return t0, t1


@kernel
def clip_box(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz):
    """``(t_in, t_out)`` of the ray inside the sample box, ``t_in >= 0``.

    A miss gives ``t_in > t_out``.
    """
    ax, bx = _slab(Ox, Dx, nx - 1.0)
    ay, by = _slab(Oy, Dy, ny - 1.0)
    az, bz = _slab(Oz, Dz, nz - 1.0)
    t_in = max(0.0, max(ax, max(ay, az)))
    t_out = min(bx, min(by, bz))
    return t_in, t_out


@kernel
def anchor(Ox, Oy, Oz, Dx, Dy, Dz, t):
    """The ray's point at ``t``, ``O + t D``: an origin near the volume, so that
    positions measured from it round at the volume's scale, not the eye's distance."""
    return Ox + t * Dx, Oy + t * Dy, Oz + t * Dz


#: A ray whose origin lies farther than this many grid extents from index 0
#: is walked from its entry into the volume (`entry_anchor`). Nearer, the
#: origin stays: moving it rounds the ray itself by an ulp of the new
#: origin, which sends a ray running within an ulp of a cell plane (the
#: traversal tests build such rays) through other cells; farther, the
#: rounding of positions measured from the eye is the larger error.
FAR_ORIGIN = 16.0
#: ... and any origin farther than this many cells: the sub-cell ranges PARC classifies by are
#: padded for positions rounded at most this far out (`parc.ranges.RANGE_PAD`), and a grid
#: of 200,000 samples kept origins 3 million cells away unanchored.
FAR_ORIGIN_CELLS = 32768.0


@kernel
def entry_anchor(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz):
    """``(ta, Ax, Ay, Az)``: where to walk a ray from, and its point there.

    For an origin farther than `FAR_ORIGIN` grid extents (or `FAR_ORIGIN_CELLS`), the ray's entry
    into the sample box (`clip_box`) and its point there (`anchor`);
    otherwise, or for a miss, ``(0, O)``.
    """
    far = min(FAR_ORIGIN * max(nx, max(ny, nz)), FAR_ORIGIN_CELLS)
    if max(abs(Ox), max(abs(Oy), abs(Oz))) > far:
        t_in, t_out = clip_box(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz)
        if 0.0 < t_in <= t_out:
            Ax, Ay, Az = anchor(Ox, Oy, Oz, Dx, Dy, Dz, t_in)
            return t_in, Ax, Ay, Az
    return 0.0, Ox, Oy, Oz


@kernel
def start_index(O, D, t, n):
    """Index along one axis of the cell the walk starts in at ``t``, clamped to the grid.

    ``floor(O + t D)`` alone can disagree with the crossing times the walk
    uses (`axis_state`): near a plane, the rounded position may sit past it
    while ``(plane - O) * invD`` is still later than ``t``; with a small
    ``D`` that gap is long, and starting past the plane would skip it. So
    the index is corrected until, by those same crossing times, the cell is
    entered before ``t`` and left at or after it: where ``t`` is exactly a
    crossing, the cell before the plane. A walk started at ``t`` then visits
    the same cells from ``t`` on as one started earlier, including the
    zero-length cells where the ray passes exactly through an edge.
    """
    i = int(math.floor(O + t * D))
    if i < 0:
        i = 0
    if i > n - 2:
        i = n - 2
    if abs(D) < TINY_DIRECTION:
        return i
    inv = 1.0 / D
    if D > 0.0:
        while i > 0 and (i - O) * inv >= t:
            i -= 1
        while i < n - 2 and (i + 1.0 - O) * inv < t:
            i += 1
    else:
        while i < n - 2 and (i + 1.0 - O) * inv >= t:
            i += 1
        while i > 0 and (i - O) * inv < t:
            i -= 1
    return i


@kernel
def axis_state(O, D, i):
    """``(step, invD, t_enter, t_exit)`` of cell index ``i`` along one axis."""
    if abs(D) < TINY_DIRECTION:
        return 0, 0.0, -math.inf, math.inf
    inv = 1.0 / D
    if D > 0.0:
        return 1, inv, (i - O) * inv, (i + 1.0 - O) * inv
    return -1, inv, (i + 1.0 - O) * inv, (i - O) * inv


@kernel
def next_exit(O, inv, step, i):
    """Exit time of cell ``i`` along an axis walked in direction ``step``."""
    if step > 0:
        return (i + 1.0 - O) * inv
    return (i - O) * inv


@kernel
def advance(O, inv, step, i, t0, t1, t):
    """Step one axis's cell ``i`` (entered at ``t0``, left at ``t1``) on to the cell holding ``t``.

    The same cell `start_index` gives at ``t``, when ``i`` was entered
    before ``t``: entered before it and left at or after it, by the same
    crossing times. Stepping costs a multiply per cell crossed where
    `start_index` and `axis_state` cost a floor and two divisions (the
    skip-table jumps over a CT head frame's segments, one thread: 38 ms
    with this, 44 ms with those).
    """
    while t1 < t:
        i += step
        t0 = t1
        t1 = next_exit(O, inv, step, i)
    return i, t0, t1


@kernel
def step_axis(tx1, ty1, tz1):
    """Axis (0, 1, 2) whose boundary the ray crosses first; ties go to x, then y."""
    if tx1 <= ty1 and tx1 <= tz1:
        return 0
    if ty1 <= tz1:
        return 1
    return 2


@kernel
def cube_exit(Ox, Oy, Oz, sx, sy, sz, ix, iy, iz, i, j, k, r):
    """Time the ray leaves the cube of cells within ``r`` of cell ``(i, j, k)``, by the walk's crossing times."""
    ex = math.inf
    ey = math.inf
    ez = math.inf
    if sx != 0:
        ex = next_exit(Ox, ix, sx, i + sx * r)
    if sy != 0:
        ey = next_exit(Oy, iy, sy, j + sy * r)
    if sz != 0:
        ez = next_exit(Oz, iz, sz, k + sz * r)
    return min(ex, min(ey, ez))


@kernel(inline="always")
def walk_from(Ox, Oy, Oz, Dx, Dy, Dz, t, nx, ny, nz):
    """The walk's state in the cell holding ``t``:
    ``(i, j, k, sx, sy, sz, ix, iy, iz, tx0, tx1, ty0, ty1, tz0, tz1)``."""
    i = start_index(Ox, Dx, t, nx)
    j = start_index(Oy, Dy, t, ny)
    k = start_index(Oz, Dz, t, nz)
    sx, ix, tx0, tx1 = axis_state(Ox, Dx, i)
    sy, iy, ty0, ty1 = axis_state(Oy, Dy, j)
    sz, iz, tz0, tz1 = axis_state(Oz, Dz, k)
    return i, j, k, sx, sy, sz, ix, iy, iz, tx0, tx1, ty0, ty1, tz0, tz1


@kernel(inline="always")
def step_cell(Ox, Oy, Oz, sx, sy, sz, ix, iy, iz, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, nx, ny, nz):
    """The walk's next cell: ``(inside, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1)``, ``inside``
    False once the ray leaves the grid (`step_axis` picks the face)."""
    axis = step_axis(tx1, ty1, tz1)
    inside = True
    if axis == 0:
        i += sx
        if i < 0 or i > nx - 2:
            inside = False
        else:
            tx0 = tx1
            tx1 = next_exit(Ox, ix, sx, i)
    elif axis == 1:
        j += sy
        if j < 0 or j > ny - 2:
            inside = False
        else:
            ty0 = ty1
            ty1 = next_exit(Oy, iy, sy, j)
    else:
        k += sz
        if k < 0 or k > nz - 2:
            inside = False
        else:
            tz0 = tz1
            tz1 = next_exit(Oz, iz, sz, k)
    return inside, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1


def cell_corners(data, i, j, k):
    """The eight corner samples of cell ``(i, j, k)`` as float64, ``vIJK`` at local ``(I, J, K)``.

    Returned in the order v000, v100, v010, v110, v001, v101, v011, v111.
    ``data`` is the ``(nz, ny, nx)`` sample array, or the same samples
    bricked (`raycast.bricks`); in kernels the call compiles to the one
    that matches (`_cell_corners`), and here, in Python, it reads either.
    """
    if isinstance(data, BrickedSamples):
        return bricked_corners(data, i, j, k)
    return _linear_corners(data, i, j, k)


def grid_shape(data):
    """``(nz, ny, nx)`` of the samples, linear or bricked (as `cell_corners`)."""
    if isinstance(data, BrickedSamples):
        return data.nz, data.ny, data.nx
    return data.shape


def _layout(data):
    """``"linear"`` or ``"bricked"``: the sample layout a kernel argument's Numba type holds, else None."""
    if isinstance(data, types.Array) and data.ndim == 3:
        return "linear"
    if isinstance(data, types.BaseNamedTuple) and data.instance_class is BrickedSamples:
        return "bricked"
    return None


@overload(grid_shape, jit_options=OVERLOAD_JIT)
def _grid_shape(data):
    layout = _layout(data)
    if layout == "linear":
        return lambda data: data.shape
    if layout == "bricked":
        return lambda data: (data.nz, data.ny, data.nx)
    return None


@kernel(inline="always")
def cell_entry(table, i, j, k):
    """``table[k, j, i]``, read with unsigned indices as `cell_corners` reads samples."""
    return table[np.uint64(k), np.uint64(j), np.uint64(i)]


def _linear_corners(data, i, j, k):
    # np.float64, not float(): in Numba float() of a float32 stays float32, and
    # the differences of corners (interpolation, gradients) would round in
    # float32 -- past the corners' range, or to inf from +-3e38 -- where the
    # classification, in float64, rules the values out.
    # Unsigned indices (a cell's are never negative): Numba tests each signed index for being
    # negative, to add the axis's length, a compare and a select per index of every read;
    # without those, `brute`'s CT head walks took 5-7% less time.
    i = np.uint64(i)
    j = np.uint64(j)
    k = np.uint64(k)
    i1 = i + np.uint64(1)
    j1 = j + np.uint64(1)
    k1 = k + np.uint64(1)
    return (np.float64(data[k, j, i]), np.float64(data[k, j, i1]),
            np.float64(data[k, j1, i]), np.float64(data[k, j1, i1]),
            np.float64(data[k1, j, i]), np.float64(data[k1, j, i1]),
            np.float64(data[k1, j1, i]), np.float64(data[k1, j1, i1]))


@overload(cell_corners, jit_options=OVERLOAD_JIT)
def _cell_corners(data, i, j, k):
    """`cell_corners` in kernels: chosen by the type of ``data`` when a kernel compiles."""
    return {"linear": _linear_corners, "bricked": bricked_corners}.get(_layout(data))
