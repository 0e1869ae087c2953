"""The ideal caster's sample count for accumulation: samples inside contributing cells only.

About this technique
--------------------
A benchmark should say how close each method comes to the *ideal* caster,
one that spends samples only where something can be seen. For
accumulation (composite, maximum and average intensity) a *contributing
cell* is one whose value range, the min/max of its eight corners (the
exact range of its trilinear interpolant), meets the transfer function's
non-zero opacity somewhere (`parc.transfer.TransferFunction.nonzero_in`
on `parc.ranges.cell_minmax`, each range widened by `raycast.composite.INTERP_ROUNDING`
for the interpolation's rounding as `parc.classify.classify_tf` does, gives this
classification, ``contrib[k, j, i]``).

For each pixel `ideal_ray_samples` walks exactly the unaccelerated
caster's cells and sample lattice: the same `ray_span` (no segment),
cell walk, `cell_lattice`, `trilinear`, `tf_opacity`, `correct_opacity`,
the same ``t >= t_stop`` rule and, in composite mode, the same early
termination once the accumulated opacity reaches the threshold (maximum
and average intensity never stop early). It counts the samples that lie
in a contributing cell, the cell being the one whose walk interval holds
the sample (a sample exactly on a face between cells belongs to the cell
the walk enters there). The count is therefore exactly the
subset of ``accumulate_ray``'s samples (no segment, no bits) taken inside
contributing cells:

- it never exceeds the unaccelerated caster's count (`cast_accumulate_image`
  without segments);
- PARC can never take fewer: its proxy covers every contributing cell
  (depth segments from 1-cell supercells or larger are conservative), so
  each counted sample lies within the pixel's segment, and PARC stops
  where the unaccelerated caster stops (it skips only transparent samples);
- every sample with non-zero opacity is counted (its value lies in its
  cell's range, which then meets the opacity's support).

The walk evaluates every lattice sample, contributing or not, so that the
accumulated opacity, and hence the stopping sample, is bit for bit the
unaccelerated caster's; this is a counter for reports, not a fast path.
"""
import math

from numba import prange

from .composite import (MODE_COMPOSITE, P_MODE, P_RATIO, P_STEP, P_THRESHOLD, cell_lattice, local_coords, ray_span,
                        trilinear)
from .config import TILE_H, TILE_W, kernel
from .rays import camera_ray, dealt_tile, tile_count
from .transfer import correct_opacity, tf_opacity
from .traverse import cell_corners, step_cell, to_index_space, walk_from


@kernel
def ideal_ray_samples(data, contrib, Ox, Oy, Oz, Dx, Dy, Dz, t_stop, params, op_x, op_y):
    """Samples of the unaccelerated lattice of one ray (index space ``O + t D``) that lie in contributing cells.

    ``contrib`` is uint8 ``(nz-1, ny-1, nx-1)``, non-zero for contributing
    cells. Lattice points at ``t >= t_stop`` are not taken, and a composite
    ray stops where `accumulate_ray` stops.
    """
    nz, ny, nx = data.shape
    step = params[P_STEP]
    composite = int(params[P_MODE]) == MODE_COMPOSITE
    threshold = params[P_THRESHOLD]
    # No segment: every cell of the ray in the volume, as the brute caster walks them.
    ta, Ax, Ay, Az, t_in, t_out, n_last, t_start, t_end = ray_span(data, Ox, Oy, Oz, Dx, Dy, Dz, -math.inf,
                                                                   math.inf, t_stop, step)
    if not t_start <= t_end:
        return 0
    i, j, k, sx, sy, sz, ix, iy, iz, tx0, tx1, ty0, ty1, tz0, tz1 = walk_from(Ax, Ay, Az, Dx, Dy, Dz, t_start,
                                                                             nx, ny, nz)
    acc = 0.0
    count = 0
    while True:
        c0 = max(t_in, max(tx0, max(ty0, tz0)))
        c1 = min(t_out, min(tx1, min(ty1, tz1)))
        n_lo, n_hi = cell_lattice(c0, c1, t_in, t_out, step, n_last)
        if n_lo <= n_hi:
            inside = contrib[k, j, i] != 0
            v000, v100, v010, v110, v001, v101, v011, v111 = cell_corners(data, i, j, k)
            for n in range(n_lo, n_hi + 1):
                tl = t_in + n * step
                if ta + tl >= t_stop:
                    return count
                if inside:
                    count += 1
                if not composite:
                    continue            # maximum and average intensity take every lattice point
                u, vv, w = local_coords(Ax, Ay, Az, Dx, Dy, Dz, i, j, k, tl)
                a = tf_opacity(op_x, op_y, trilinear(v000, v100, v010, v110, v001, v101, v011, v111, u, vv, w))
                if not a > 0.0:
                    continue
                # The step-corrected opacity exactly as the caster composites it; the colour is not needed.
                acc += (1.0 - acc) * correct_opacity(a, params[P_RATIO])
                if acc >= threshold:
                    return count
        if c1 >= t_end:
            break
        more, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1 = step_cell(Ax, Ay, Az, sx, sy, sz, ix, iy, iz, i, j, k,
                                                                tx0, tx1, ty0, ty1, tz0, tz1, nx, ny, nz)
        if not more:
            break
    return count


@kernel(parallel=True)
def ideal_samples_image(data, org, spc, cam, width, height, params, op_x, op_y,
                        contrib, stop, use_stop, counts):
    """`ideal_ray_samples` of every pixel into ``counts[y * width + x]`` (int64), tile by tile.

    Tiled as `cast_accumulate_image`; with ``use_stop`` no sample is counted
    at ``t >= stop[y, x]`` (an opaque surface there).
    """
    tiles = tile_count(width, 0, height, TILE_W, TILE_H)
    for it in prange(tiles):
        x0, x1, y0, y1 = dealt_tile(it, tiles, width, 0, height)
        for y in range(y0, y1):
            for x in range(x0, x1):
                ox, oy, oz, dx, dy, dz = camera_ray(cam, width, height, x, y)
                Ox, Oy, Oz, Dx, Dy, Dz = to_index_space(ox, oy, oz, dx, dy, dz, org, spc)
                counts[y * width + x] = ideal_ray_samples(
                    data, contrib, Ox, Oy, Oz, Dx, Dy, Dz, stop[y, x] if use_stop else math.inf, params, op_x, op_y)
