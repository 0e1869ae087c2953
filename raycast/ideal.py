"""The ideal caster's sample counts for accumulation: samples in possibly contributing cells, and
samples of non-zero opacity.

About this technique
--------------------
A benchmark should say how close each method comes to the *ideal* caster,
which Sobierajski & Avila (§2) define as one that looks only at the
*contributing* cells of each ray: those where the ray meets a value of
non-zero opacity. Which cells those are depends on the ray; what a caster
can know before casting is the *possibly contributing* cells, whose value
range, the min/max of their eight corners (the exact range of the
trilinear interpolant), meets the transfer function's non-zero opacity
somewhere (`parc.transfer.TransferFunction.nonzero_in` on
`parc.ranges.cell_minmax`, each range widened by
`raycast.composite.INTERP_ROUNDING` for the interpolation's rounding as
`parc.classify.classify_tf` does, gives this classification,
``contrib[k, j, i]``). Two counts follow:

- the *bound*: the samples that lie in possibly contributing cells, the
  fewest a caster that classifies whole cells, as PARC does, can take;
- the *contributing* samples: those of non-zero opacity, which any caster
  of this lattice must take to make the same image; the paper's ideal
  caster takes these and the transparent samples of the cells they are in.

For each pixel `ideal_ray_samples` walks exactly the unaccelerated
caster's cells and sample lattice: the same `ray_span` (no segment),
cell walk, `cell_lattice`, `trilinear`, `tf_opacity`, `correct_opacity`,
the same ``t >= t_stop`` rule and, in composite mode, the same early
termination once the accumulated opacity reaches the threshold (maximum
and average intensity never stop early). A sample's cell is the one whose
walk interval holds it (a sample exactly on a face between cells belongs
to the cell the walk enters there). Both counts are therefore exactly
subsets of ``accumulate_ray``'s samples (no segment, no bits):

- the bound never exceeds the unaccelerated caster's count
  (`cast_accumulate_image` without segments);
- PARC can never take fewer: its proxy covers every possibly contributing
  cell (depth segments from 1-cell supercells or larger are conservative),
  so each counted sample lies within the pixel's segment, and PARC stops
  where the unaccelerated caster stops (it skips only transparent samples);
- every contributing sample is in the bound (its value lies in its cell's
  range, which then meets the opacity's support).

The walk evaluates every lattice sample, in a possibly contributing cell
or not, so that the accumulated opacity, and hence the stopping sample,
is bit for bit the unaccelerated caster's; this is a counter for reports,
not a fast path.
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
    """``(bound, contributing)``: of the unaccelerated lattice of one ray (index space ``O + t D``),
    the samples that lie in possibly contributing cells, and those of non-zero opacity.

    ``contrib`` is uint8 ``(nz-1, ny-1, nx-1)``, non-zero for possibly
    contributing cells. Lattice points at ``t >= t_stop`` are not taken, and
    a composite ray stops where `accumulate_ray` stops.
    """
    nz, ny, nx = data.shape
    step = params[P_STEP]
    composite = int(params[P_MODE]) == MODE_COMPOSITE
    threshold = params[P_THRESHOLD]
    # No segment: every cell of the ray in the volume, as the brute caster walks them.
    ta, Ax, Ay, Az, t_in, t_out, n_last, t_start, t_end = ray_span(data, Ox, Oy, Oz, Dx, Dy, Dz, -math.inf,
                                                                   math.inf, t_stop, step)
    if not t_start <= t_end:
        return 0, 0
    i, j, k, sx, sy, sz, ix, iy, iz, tx0, tx1, ty0, ty1, tz0, tz1 = walk_from(Ax, Ay, Az, Dx, Dy, Dz, t_start,
                                                                             nx, ny, nz)
    acc = 0.0
    count = 0
    contributing = 0
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
                    return count, contributing
                if inside:
                    count += 1
                u, vv, w = local_coords(Ax, Ay, Az, Dx, Dy, Dz, i, j, k, tl)
                a = tf_opacity(op_x, op_y, trilinear(v000, v100, v010, v110, v001, v101, v011, v111, u, vv, w))
                if not a > 0.0:
                    continue
                contributing += 1
                if not composite:
                    continue            # maximum and average intensity take every lattice point
                # The step-corrected opacity exactly as the caster composites it; the colour is not needed.
                acc += (1.0 - acc) * correct_opacity(a, params[P_RATIO])
                if acc >= threshold:
                    return count, contributing
        if c1 >= t_end:
            break
        more, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1 = step_cell(Ax, Ay, Az, sx, sy, sz, ix, iy, iz, i, j, k,
                                                                tx0, tx1, ty0, ty1, tz0, tz1, nx, ny, nz)
        if not more:
            break
    return count, contributing


@kernel(parallel=True)
def ideal_samples_image(data, org, spc, cam, width, height, params, op_x, op_y,
                        contrib, stop, use_stop, counts):
    """`ideal_ray_samples` of every pixel into ``counts[y * width + x]`` (int64 ``(H * W, 2)``: the
    bound, then the samples of non-zero opacity), tile by tile.

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
                bound, contributing = ideal_ray_samples(data, contrib, Ox, Oy, Oz, Dx, Dy, Dz,
                                                        stop[y, x] if use_stop else math.inf, params, op_x, op_y)
                counts[y * width + x, 0] = bound
                counts[y * width + x, 1] = contributing
