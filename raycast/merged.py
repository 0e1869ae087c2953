"""Several overlapping composite volumes along one ray: their samples merged in depth order.

Each volume keeps the walk and sample lattice it has alone (`raycast.composite`:
the same `ray_span`, `walk_from`, `visit_cell`, `cell_lattice`, `trilinear`
and `composite_sample`), held between samples in a row of floats per volume;
the next sample is always the nearest of the volumes' next ones.

With shadows, the shaded samples are not lit in the walk: a shadow ray from
each, towards each light, must first find what the other volumes let
through. The walk then records them instead (`cast_merged_image`'s
``record``): each one's weight in the pixel, ``(1 - A) a``, depends on
opacities alone, so the pixel's colour is the walk's unshaded sum plus the
recorded samples' weights times their lit colours, added once their
shadow rays are cast (`raycast.shadow.combine_samples`).
"""
import math

import numpy as np
from numba import prange

from .composite import (END, MOVED, P_ORIGIN, P_PLANE_AXIS, P_RATIO, P_SHADE, P_STEP, P_THRESHOLD, PASS, cell_lattice,
                        composite_sample, local_coords, ray_span, trilinear, visit_cell)
from .config import TILE_H, TILE_W, kernel, named_for
from .rays import camera_ray, dealt_tile, tile_count
from .shade import trilinear_gradient, unit_normal
from .transfer import correct_opacity, tf_color, tf_opacity
from .traverse import cell_corners, grid_shape, step_cell, to_index_space, walk_from


@kernel(inline="always")
def _next_layer(layer_t, layer_ranks, used, y, x, before, before_rank):
    """The unused layer at pixel (y, x) to composite before a sample at ``t = before`` of the
    volume ranked ``before_rank`` (its place in the scene), or -1: the smallest ``t``, ties
    going to the volume listed first, as between samples."""
    best = -1
    bt = before
    br = before_rank
    for j in range(layer_t.shape[0]):
        t = layer_t[j, y, x]
        if not used[j] and (t < bt or (t == bt and layer_ranks[j] < br)):
            best = j
            bt = t
            br = layer_ranks[j]
    return best


# The walk state `cast_merged_image` keeps per volume (a row of floats).
_W_A = 0            # anchored ray: A (3), D (3)
_W_D = 3
_W_INV = 6          # 1 / D (3) and the step along each axis, -1, 0, 1 (3)
_W_STEP = 9
_W_CELL = 12        # i, j, k
_W_T = 15           # tx0, tx1, ty0, ty1, tz0, tz1
_W_T_IN = 21
_W_T_OUT = 22
_W_T_END = 23
_W_N_LAST = 24
_W_TA = 25
_W_N = 26           # next lattice point to take, and the last in the current cell
_W_N_HI = 27
_W_C1 = 28          # the current cell's exit
_W_LIVE = 29
_W_CORNERS = 30     # the current cell's eight corners
_W_UA = 38          # bit planes: the ray's origin along the plane axis, as given
_W_TQ = 39          # and its stretch in a plane whose bit is set (`visit_cell`'s tq0, tq1)
_W_SIZE = 41


@kernel(inline="always")
def _merged_advance(st, q, data, skip, jump_min, step, params, bits, py, px, use_bits, fresh):
    """Move volume ``q``'s walk on to its next cell with lattice points to take (from its
    current cell itself when ``fresh``); ``st[q, _W_LIVE] = 0`` once there is none. With
    ``use_bits``, cells in planes of supercells whose bit ``bits[py, px]`` is clear are passed
    over as well (`visit_cell`)."""
    nz, ny, nx = grid_shape(data)
    Ax, Ay, Az = st[q, _W_A], st[q, _W_A + 1], st[q, _W_A + 2]
    ix, iy, iz = st[q, _W_INV], st[q, _W_INV + 1], st[q, _W_INV + 2]
    sx, sy, sz = int(st[q, _W_STEP]), int(st[q, _W_STEP + 1]), int(st[q, _W_STEP + 2])
    i, j, k = int(st[q, _W_CELL]), int(st[q, _W_CELL + 1]), int(st[q, _W_CELL + 2])
    tx0, tx1, ty0, ty1 = st[q, _W_T], st[q, _W_T + 1], st[q, _W_T + 2], st[q, _W_T + 3]
    tz0, tz1 = st[q, _W_T + 4], st[q, _W_T + 5]
    t_in, t_out, t_end = st[q, _W_T_IN], st[q, _W_T_OUT], st[q, _W_T_END]
    n_last = int(st[q, _W_N_LAST])
    c1 = st[q, _W_C1]
    Aa = Da = Ua = ta = 0.0
    tq0, tq1 = math.inf, -math.inf
    if use_bits:
        axis = int(params[P_PLANE_AXIS])
        Aa, Da = st[q, _W_A + axis], st[q, _W_D + axis]
        Ua, ta = st[q, _W_UA], st[q, _W_TA]
        tq0, tq1 = st[q, _W_TQ], st[q, _W_TQ + 1]
    live = True
    while True:
        if not fresh:
            if c1 >= t_end:
                live = False
                break
            inside, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1 = step_cell(Ax, Ay, Az, sx, sy, sz, ix, iy, iz, i, j, k,
                                                                      tx0, tx1, ty0, ty1, tz0, tz1, nx, ny, nz)
            if not inside:
                live = False
                break
        fresh = False
        c0 = max(t_in, max(tx0, max(ty0, tz0)))
        c1 = min(t_out, min(tx1, min(ty1, tz1)))
        action, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, tq0, tq1 = visit_cell(
            (Ax, Ay, Az), (sx, sy, sz), (ix, iy, iz), i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, c0, c1, t_end,
            skip, jump_min, bits, py, px, use_bits, params, (Aa, Da, Ua, ta, tq0, tq1))
        if action == MOVED:
            fresh = True
            continue
        if action == END:
            live = False
            break
        if action == PASS:
            continue
        n_lo, n_hi = cell_lattice(c0, c1, t_in, t_out, step, n_last)
        if n_lo <= n_hi:
            st[q, _W_N] = n_lo
            st[q, _W_N_HI] = n_hi
            (st[q, _W_CORNERS], st[q, _W_CORNERS + 1], st[q, _W_CORNERS + 2], st[q, _W_CORNERS + 3],
             st[q, _W_CORNERS + 4], st[q, _W_CORNERS + 5], st[q, _W_CORNERS + 6],
             st[q, _W_CORNERS + 7]) = cell_corners(data, i, j, k)
            break
    st[q, _W_LIVE] = 1.0 if live else 0.0
    st[q, _W_CELL], st[q, _W_CELL + 1], st[q, _W_CELL + 2] = i, j, k
    st[q, _W_T], st[q, _W_T + 1], st[q, _W_T + 2], st[q, _W_T + 3] = tx0, tx1, ty0, ty1
    st[q, _W_T + 4], st[q, _W_T + 5] = tz0, tz1
    st[q, _W_C1] = c1
    if use_bits:
        st[q, _W_TQ], st[q, _W_TQ + 1] = tq0, tq1


@kernel(inline="always")
def _merged_start(st, q, data, Ox, Oy, Oz, Dx, Dy, Dz, seg0, seg1, t_stop, params, use_bits):
    """Volume ``q``'s walk over ``[seg0, seg1]``, set on its first cell: live when the span holds
    lattice points, to be moved on from that cell by `_merged_advance` (``fresh``)."""
    nz, ny, nx = grid_shape(data)
    step = params[P_STEP]
    ta, Ax, Ay, Az, t_in, t_out, n_last, t_start, t_end = ray_span(data, Ox, Oy, Oz, Dx, Dy, Dz, seg0, seg1,
                                                                   t_stop, step)
    if not t_start <= t_end:
        st[q, _W_LIVE] = 0.0
        return
    i, j, k, sx, sy, sz, ix, iy, iz, tx0, tx1, ty0, ty1, tz0, tz1 = walk_from(Ax, Ay, Az, Dx, Dy, Dz, t_start,
                                                                             nx, ny, nz)
    st[q, _W_A], st[q, _W_A + 1], st[q, _W_A + 2] = Ax, Ay, Az
    st[q, _W_D], st[q, _W_D + 1], st[q, _W_D + 2] = Dx, Dy, Dz
    st[q, _W_INV], st[q, _W_INV + 1], st[q, _W_INV + 2] = ix, iy, iz
    st[q, _W_STEP], st[q, _W_STEP + 1], st[q, _W_STEP + 2] = sx, sy, sz
    st[q, _W_CELL], st[q, _W_CELL + 1], st[q, _W_CELL + 2] = i, j, k
    st[q, _W_T], st[q, _W_T + 1], st[q, _W_T + 2], st[q, _W_T + 3] = tx0, tx1, ty0, ty1
    st[q, _W_T + 4], st[q, _W_T + 5] = tz0, tz1
    st[q, _W_T_IN], st[q, _W_T_OUT], st[q, _W_T_END] = t_in, t_out, t_end
    st[q, _W_N_LAST] = n_last
    st[q, _W_TA] = ta
    st[q, _W_C1] = -math.inf
    if use_bits:
        axis = int(params[P_PLANE_AXIS])
        st[q, _W_UA] = Ox if axis == 0 else (Oy if axis == 1 else Oz)
        st[q, _W_TQ], st[q, _W_TQ + 1] = math.inf, -math.inf
    st[q, _W_LIVE] = 1.0


def _merged_caster(shaded, record, planes):
    """`cast_merged_image`'s kernel, with gradient shading compiled in (``shaded``) or out,
    as `raycast.composite` does for one volume, or the shaded samples recorded (``record``),
    and the bit planes' test compiled in (``planes``) or out: in, even unused, it slowed the
    walk of two CT heads 1.17x (`brute`) and 1.07x (PARC)."""
    @kernel(parallel=True)
    @named_for(shaded=shaded, record=record, planes=planes)
    def cast(datas, orgs, spcs, cam, width, height, params, op_x, op_y, col_x, col_rgb, tf_len,
             seg, use_seg, skip, jump_mins, bits, bit_use, stop, ranks, layer_t, layer_ranks, layer_rgba, image, counts,
             row0, row1, rec_points, rec_normals, rec_views, rec_colors, rec_weights, rec_volumes, slots, rec_counts):
        nvol = len(datas)
        thr = 0.0
        for q in range(nvol):
            thr = max(thr, params[q, P_THRESHOLD])
        tiles = tile_count(width, row0, row1, TILE_W, TILE_H)
        for it in prange(tiles):
            x0, x1, y0, y1 = dealt_tile(it, tiles, width, row0, row1)
            st = np.zeros((nvol, _W_SIZE))
            used = np.zeros(layer_t.shape[0], np.bool_)
            for y in range(y0, y1):
                for x in range(x0, x1):
                    ox, oy, oz, dx, dy, dz = camera_ray(cam, width, height, x, y)
                    t_stop = stop[y, x]
                    for q in range(nvol):
                        Ox, Oy, Oz, Dx, Dy, Dz = to_index_space(ox, oy, oz, dx, dy, dz, orgs[q], spcs[q])
                        s0 = -math.inf
                        s1 = math.inf
                        if use_seg:
                            s0 = seg[q, y, x, 0]
                            s1 = seg[q, y, x, 1]
                        _merged_start(st, q, datas[q], Ox, Oy, Oz, Dx, Dy, Dz, s0, s1, t_stop, params[q],
                                      planes and bit_use[q])
                    used[:] = False
                    r = 0.0
                    g = 0.0
                    b = 0.0
                    acc = 0.0
                    samples = 0
                    kept = 0
                    # Walks are moved on at one place, which Numba's inlining copies once (two
                    # took 1.4x the compile): first every volume's from its first cell, then
                    # the one whose cell has no more lattice points.
                    fresh = 0
                    moving = -1
                    while True:
                        if fresh < nvol or moving >= 0:
                            q = fresh if fresh < nvol else moving
                            if st[q, _W_LIVE] != 0.0:
                                _merged_advance(st, q, datas[q], skip[q], jump_mins[q], params[q, P_STEP], params[q],
                                                bits[q], y, x, planes and bit_use[q], fresh < nvol)
                            if fresh < nvol:
                                fresh += 1
                            else:
                                moving = -1
                            continue
                        best = -1
                        bt = t_stop
                        for q in range(nvol):
                            if st[q, _W_LIVE] != 0.0:
                                t = st[q, _W_TA] + (st[q, _W_T_IN] + st[q, _W_N] * params[q, P_STEP])
                                if t < bt:
                                    best = q
                                    bt = t
                        # Layers in front of the next sample; all the rest once the samples end or the
                        # ray is opaque enough (they are finished, and a surface behind shows too).
                        while True:
                            last = best < 0 or acc >= thr
                            j = _next_layer(layer_t, layer_ranks, used, y, x, math.inf if last else bt,
                                            -1 if last else ranks[best])
                            if j < 0:
                                break
                            used[j] = True
                            wgt = 1.0 - acc
                            r += wgt * layer_rgba[j, y, x, 0]
                            g += wgt * layer_rgba[j, y, x, 1]
                            b += wgt * layer_rgba[j, y, x, 2]
                            acc += wgt * layer_rgba[j, y, x, 3]
                        if best < 0 or acc >= thr:
                            break
                        if acc >= params[best, P_THRESHOLD]:
                            # This volume's own threshold: it adds no more, as it would alone.
                            st[best, _W_LIVE] = 0.0
                            continue
                        tl = st[best, _W_T_IN] + st[best, _W_N] * params[best, P_STEP]
                        i, j, k = int(st[best, _W_CELL]), int(st[best, _W_CELL + 1]), int(st[best, _W_CELL + 2])
                        u, vv, w = local_coords(st[best, _W_A], st[best, _W_A + 1], st[best, _W_A + 2],
                                                st[best, _W_D], st[best, _W_D + 1], st[best, _W_D + 2], i, j, k, tl)
                        c = _W_CORNERS
                        v = trilinear(st[best, c], st[best, c + 1], st[best, c + 2], st[best, c + 3],
                                      st[best, c + 4], st[best, c + 5], st[best, c + 6], st[best, c + 7], u, vv, w)
                        samples += 1
                        st[best, _W_N] += 1.0
                        if st[best, _W_N] > st[best, _W_N_HI]:
                            moving = best
                        no = int(tf_len[best, 0])
                        nc = int(tf_len[best, 1])
                        a = tf_opacity(op_x[best, :no], op_y[best, :no], v)
                        if not a > 0.0:
                            continue
                        if record and params[best, P_SHADE] != 0.0:
                            a = correct_opacity(a, params[best, P_RATIO])
                            wgt = (1.0 - acc) * a
                            acc += wgt
                            if rec_weights.shape[0] > 0:
                                m = slots[y * width + x] + kept
                                _record(rec_points, rec_normals, rec_views, rec_colors, m, datas[best], spcs[best],
                                        params[best], i, j, k, u, vv, w, dx, dy, dz, col_x[best, :nc],
                                        col_rgb[best, :nc], v)
                                rec_weights[m] = wgt
                                rec_volumes[m] = best
                            kept += 1
                            continue
                        a, cr, cg, cb = composite_sample(datas[best], spcs[best], v, i, j, k, u, vv, w, a, dx, dy, dz,
                                                         params[best], col_x[best, :nc], col_rgb[best, :nc],
                                                         shaded and params[best, P_SHADE] != 0.0)
                        wgt = (1.0 - acc) * a
                        r += wgt * cr
                        g += wgt * cg
                        b += wgt * cb
                        acc += wgt
                    image[y, x, 0] = min(r, 1.0)
                    image[y, x, 1] = min(g, 1.0)
                    image[y, x, 2] = min(b, 1.0)
                    image[y, x, 3] = min(acc, 1.0)
                    counts[y * width + x] = samples
                    if record:
                        rec_counts[y * width + x] = kept
    return cast


@kernel(inline="always")
def _record(points, normals, views, colors, m, data, spc, params, i, j, k, u, vv, w, dx, dy, dz, col_x, col_rgb, v):
    """Row ``m`` of a recorded sample: its world point and unit normal as `raycast.composite.shade_color`
    finds them, the direction to the eye, and its transfer-function colour."""
    points[m, 0] = params[P_ORIGIN] + spc[0] * (i + u)
    points[m, 1] = params[P_ORIGIN + 1] + spc[1] * (j + vv)
    points[m, 2] = params[P_ORIGIN + 2] + spc[2] * (k + w)
    gx, gy, gz = trilinear_gradient(data, i, j, k, u, vv, w, spc)
    normals[m, 0], normals[m, 1], normals[m, 2] = unit_normal(gx, gy, gz, dx, dy, dz)
    views[m, 0], views[m, 1], views[m, 2] = -dx, -dy, -dz
    colors[m, 0], colors[m, 1], colors[m, 2] = tf_color(col_x, col_rgb, v)


_MERGED_CASTERS = {(shaded, record, planes): _merged_caster(shaded, record, planes)
                   for shaded, record in ((False, False), (True, False), (False, True)) for planes in (False, True)}


class SampleRecord:
    """The shaded samples `cast_merged_image` records for a band of rows, in pixel order:
    ``slots[p]`` is pixel ``p``'s first row (pixels of the band only), ``counts[p]`` how many
    it has; ``points``, ``normals`` (the unit gradient, not yet turned to the eye: `blinn_phong`
    turns it), ``views`` (unit, to the eye) and ``colors`` (the transfer function's) are
    ``(n, 3)``, ``weights`` the samples' weights in their pixels and ``volumes`` the index,
    among the merged volumes, of each one's volume.
    With ``n = 0`` the walk only counts them, into ``counts``."""

    def __init__(self, n, pixels):
        self.points = np.empty((n, 3))
        self.normals = np.empty((n, 3))
        self.views = np.empty((n, 3))
        self.colors = np.empty((n, 3))
        self.weights = np.empty(n)
        self.volumes = np.empty(n, np.int64)
        self.slots = np.zeros(pixels, np.int64)
        self.counts = np.zeros(pixels, np.int64)

    def arrays(self):
        return (self.points, self.normals, self.views, self.colors, self.weights, self.volumes, self.slots,
                self.counts)


#: The most composite volumes one merged walk takes. It takes their samples, skip tables and
#: bit planes as tuples, and Numba compiles a kernel for each length of tuple, the length a
#: constant in it. A first render of one uint8 volume's 8x8 pixels, every kernel compiled,
#: took 18-22 s with 2, 4, 8 or 16 such volumes and 38 s with 32; with 60 it was still
#: compiling after two and a half minutes, with 100 after twelve, and past 100 Numba refuses
#: the tuples (`parc.scene.Scene` refuses such scenes).
#: Tuples padded to a power of two, the count given apart, made fewer kernels but a slower
#: walk: two CT heads at 300x300 (`parc compare`, three rounds alternated) took `brute`
#: 0.615-0.650 s against 0.541-0.591.
MAX_MERGED = 32


def cast_merged_image(datas, orgs, spcs, cam, width, height, params, op_x, op_y, col_x, col_rgb, tf_len,
                      seg, use_seg, skip, jump_mins, stop, ranks, layer_t, layer_ranks, layer_rgba, image, counts,
                      row0=0, row1=None, record=None, bits=None):
    """Composite several overlapping volumes along each pixel's ray, samples merged in depth order.

    ``datas`` is a tuple of K volumes of one dtype, each with its own
    placement (``orgs[k]``, ``spcs[k]``), ``params[k]`` (composite mode),
    transfer function (rows ``k`` of the padded tables, lengths
    ``tf_len[k] = (opacity points, colour points)``) and PARC segments
    ``seg[k]``. Each volume keeps its own walk and sample lattice (as for
    one volume: `accumulate_ray`), so every sample is the one a
    single-volume cast would take; the samples of all volumes are taken in
    order of ``t`` (ties: the volume listed first, by ``ranks[k]``, its place in the scene), composited front to
    back, and stop at ``stop[y, x]`` (an opaque surface) or once the
    opacity reaches the largest threshold; a volume's samples stop
    counting once the opacity reaches its own. ``layer_t[j]``, ``layer_rgba[j]``
    are finished per-pixel layers (maximum or average intensity of another
    volume, ranked ``layer_ranks[j]``) composited where the ray reaches
    ``t = layer_t``, before a sample there of a volume listed later (`box_entry_image`
    gives the ``t`` of the lattice's first point, so that such ties are exact). ``skip[k]``
    and ``jump_mins[k]``: volume k's skip table, as `accumulate_ray`
    takes it (`raycast.iso.NO_SKIP` and -1 for none); a skipped sample
    adds nothing, so the layers and the other volumes' samples keep their
    order. Only rows ``row0 <= y < row1`` (default all) are cast.

    ``bits``, a sequence of K bit-plane buffers or None (`parc.bitplanes.PlaneBits.bits`, with
    ``params[k]``'s plane entries set), makes volume k's walk pass over the cells in
    planes of supercells whose bit is clear, as `accumulate_ray`'s does; a None
    among them, or ``bits=None``, leaves that volume's walk to its segments and skip table.

    With a `SampleRecord` as ``record``, the shaded volumes' samples are
    not shaded but recorded there (module docstring): ``image`` then holds
    the other samples' colour and every sample's opacity.
    """
    shaded = bool((params[:, P_SHADE] != 0.0).any())
    if record is None:
        record = _NO_RECORD
    else:
        shaded = False
    bits = [None] * len(datas) if bits is None else list(bits)
    bit_use = np.array([b is not None for b in bits])
    cast = _MERGED_CASTERS[shaded, record is not _NO_RECORD, bool(bit_use.any())]
    bits = tuple(_NO_BITS if b is None else b for b in bits)
    cast(datas, orgs, spcs, cam, width, height, params, op_x, op_y, col_x, col_rgb, tf_len, seg, use_seg, skip,
         jump_mins, bits, bit_use, stop, ranks, layer_t, layer_ranks, layer_rgba, image, counts, row0,
         height if row1 is None else row1, *record.arrays())


_NO_RECORD = SampleRecord(0, 0)
_NO_BITS = np.zeros((1, 1, 1), np.uint32)
