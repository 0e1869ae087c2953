"""Accumulation along rays: front-to-back compositing, maximum and average intensity.

About this technique
--------------------
Each ray is sampled every ``step`` world units on a lattice anchored where
it enters the volume: ``t_n = t_in + n step`` for ``n = 0 .. N-1``,
``N = floor((t_out - t_in) / step) + 1``; by default a quarter of the
smallest spacing (Sobierajski & Avila 1995, §6, took samples every 0.25
world units, on volumes of spacing near 1). A sample interpolates the
data trilinearly (post-classification: interpolate the value, then look it
up in the transfer function).

The ray walks cell by cell, with the isosurface caster's traversal
(`raycast.traverse`), and each cell takes the lattice points in its
interval ``[c0, c1)`` of the walk (`cell_lattice`), interpolated from its
eight corners read once. A cell's interval depends on the ray and the
cell alone, so a walk started anywhere takes the same samples from there
on, in the same cells. Interpolating per cell rather than locating every
sample's cell by ``floor`` made the CT head at 300x300 cast 1.15x faster
unaccelerated and 1.3x faster with PARC, and lets PARC pass over a
transparent cell, or a plane of supercells whose bit is clear, without
touching its samples.

- *composite*: front-to-back ``C += (1 - A) a c``, ``A += (1 - A) a`` with
  the opacity corrected for the step (`raycast.transfer.correct_opacity`)
  and, optionally, the colour shaded with the gradient (Blinn-Phong: lit
  by the scene's lights, unshadowed, or by a headlight where it has none;
  with shadows `raycast.merged` records the samples to light them later);
  the ray stops once ``A`` reaches the threshold.
- *mip*: the largest value among samples with non-zero opacity; the pixel
  takes the transfer function's colour and opacity there.
- *average*: the sum over samples with non-zero opacity of their height
  above the data's minimum, over all ``N`` lattice samples of the ray in
  the volume and the data range: an X-ray-like grey level of what the
  transfer function shows, the same whatever constant the data are offset
  by (a transparent sample counts as the minimum).

Why every mode is defined through non-zero opacity: PARC skips samples it
has proven transparent (outside ``[near, far]``, in a plane of
supercells whose bit is clear, or in a cell, or a cube of cells, whose
value range the transfer function makes transparent). A transparent sample adds exactly nothing
to any of the three sums, so skipping it changes no bit of the result,
and the accelerated image equals the unaccelerated one. The skipped
samples are the same lattice points the unaccelerated caster would have
taken; PARC never re-anchors the lattice.
"""
import math

import numpy as np
from numba import prange

from .config import TILE_H, TILE_W, kernel, named_for
from .rays import camera_ray, dealt_tile, tile_count
from .shade import KIND_HEADLIGHT, blinn_phong, to_light, trilinear_gradient, unit_normal
from .transfer import correct_opacity, tf_color, tf_lookup, tf_opacity
from .traverse import (advance, cell_corners, cell_entry, clip_box, cube_exit, entry_anchor, grid_shape, step_cell,
                       to_index_space, walk_from)

MODE_COMPOSITE = 0
MODE_MIP = 1
MODE_AVERAGE = 2

# Layout of the ``params`` array every accumulation kernel takes.
P_STEP = 0          # world units between samples
P_MODE = 1          # MODE_*
P_THRESHOLD = 2     # early ray termination once accumulated opacity reaches it
P_RATIO = 3         # step / reference step, for the opacity correction
P_SHADE = 4         # 1: shade composite samples with the gradient
P_LO = 5            # data range, for the average mode's grey level
P_HI = 6
P_AMBIENT = 7       # material, as `raycast.shade.blinn_phong` takes it (4 values)
P_PLANE_AXIS = 11   # bit planes: the major viewing axis (0, 1, 2)
P_PLANE_SIZE = 12   # supercell size along it, in cells
P_PLANE_FIRST = 13  # plane index of bit 0
P_PLANE_COUNT = 14  # number of planes (bits)
P_ORIGIN = 15       # the volume's origin (3 values): where its shaded samples are, for the lights
P_LIGHT_COUNT = 18  # light rows that follow (the headlight's one where a scene has no lights)
P_LIGHTS = 19       # rows of 7, as `raycast.shade` lays lights out
N_PARAMS = 19       # without the rows


@kernel
def interpolate(data, x, y, z, i, j, k):
    """Trilinear value at ``(x, y, z)`` in cell ``(i, j, k)``, and the local coordinates ``(u, v, w)``."""
    u = x - i
    v = y - j
    w = z - k
    v000, v100, v010, v110, v001, v101, v011, v111 = cell_corners(data, i, j, k)
    return trilinear(v000, v100, v010, v110, v001, v101, v011, v111, u, v, w), u, v, w


@kernel(inline="always")
def trilinear(v000, v100, v010, v110, v001, v101, v011, v111, u, v, w):
    """The trilinear interpolant of corners ``vIJK`` at local ``(u, v, w)``, by nested lerps.

    The value leaves the corners' range by at most `INTERP_ROUNDING` of their magnitude for ``u, v, w`` in [0, 1].
    """
    c00 = v000 + u * (v100 - v000)
    c10 = v010 + u * (v110 - v010)
    c01 = v001 + u * (v101 - v001)
    c11 = v011 + u * (v111 - v011)
    c0 = c00 + v * (c10 - c00)
    c1 = c01 + v * (c11 - c01)
    return c0 + w * (c1 - c0)


#: The nested lerps of `trilinear` can round past the corners' range (a
#: difference like ``c10 - c00`` is inexact): by at most a few units of
#: 2^-53 of the corners' largest magnitude (about 1 sample in 1,000 on
#: corners mixing 1 and -1e-16). Classifying a cell for a transfer
#: function widens its range by this fraction of that magnitude
#: (`parc.transfer.TransferFunction.nonzero_in`'s ``rounding``), so a
#: function that starts just past the range cannot show in ``brute`` alone.
#: (Clamping each sample to the range instead cost the unaccelerated
#: caster half its speed.)
INTERP_ROUNDING = 2.0 ** -44


#: A span this close (in planes) to a boundary between planes of
#: supercells tests the bits of both: its float positions may round to
#: either side of where the OpenGL pass saw the ray cross.
PLANE_TOL = 1e-6

#: ... and, on top of that, this fraction of ``|O_a| + |t D_a|`` (cells):
#: the position ``O_a + t D_a`` rounds by a few units of 2^-53 of its
#: terms, which an eye far from the volume makes large (eye 3e8 world
#: units away: |O_a| ~ 1.6e9 cells, rounding ~4e-7 cells, 3e-6 of a
#: 1/8-cell plane, past PLANE_TOL; brute took samples PARC skipped).
POS_ROUNDING = 2.0 ** -48

#: ... and this many cells: the grid's plane boundaries are ``q m`` snapped to an integer
#: this close, and a last plane this much short of the grid's end is merged into the one
#: before (`parc.ranges.SNAP` is this). Below a thousandth of a cell, PLANE_TOL planes
#: are less than that: with planes of 1e-4 cells, a ray along the last 5e-10 cells of the
#: grid would lie past the last plane for the caster, which would never test its bit.
BOUNDARY_SNAP = 1e-9


@kernel(inline="always")
def _bit(bits, py, px, q, params):
    q -= int(params[P_PLANE_FIRST])
    if q < 0 or q >= int(params[P_PLANE_COUNT]):
        return False
    return (bits[py, px, q >> 5] >> (q & 31)) & 1 != 0


@kernel(inline="always")
def clear_planes(bits, py, px, params, Aa, Da, Ua, ta, c0, c1):
    """Whether every plane of supercells the ray meets over ``[c0, c1]`` has a clear bit:
    ``(clear, t, t0, t1)``.

    If so, ``t`` is the time the ray may skip to: within tolerance of the
    far side of the last of them. If not, ``[t0, t1]`` is the stretch of
    the ray in a plane whose bit is set, so that a cell meeting it is taken
    without a test. The ray's position along the plane axis is
    ``Aa + t Da`` (anchored at ``t = ta`` from an origin ``Ua``: its
    rounding, `POS_ROUNDING`); positions within `PLANE_TOL` planes (and
    `BOUNDARY_SNAP` cells) of a boundary test both planes.
    """
    m = params[P_PLANE_SIZE]
    p0 = Aa + c0 * Da
    p1 = Aa + c1 * Da
    err = POS_ROUNDING * (abs(Ua) + max(abs((ta + c0) * Da), abs((ta + c1) * Da)))
    tol = PLANE_TOL + (err + BOUNDARY_SNAP) / m
    # Only planes first .. last have bits; the others are clear. Clamped to one plane either
    # side of them while still floats (math.floor gives an int64 in kernels): along a plane axis
    # of tiny spacing an origin far off makes ``tol`` huge (spacing 1e-21, eye 14 away: ~5e7
    # planes, some 1e8 turns of the loop a cell), and past 2^63 planes the conversion wraps.
    first = params[P_PLANE_FIRST]
    last = first + params[P_PLANE_COUNT] - 1.0
    q_lo = int(math.floor(min(max(min(p0, p1) / m - tol, first - 1.0), last + 1.0)))
    q_hi = int(math.floor(max(min(max(p0, p1) / m + tol, last + 1.0), first - 1.0)))
    for q in range(q_lo, q_hi + 1):
        if _bit(bits, py, px, q, params):
            if Da == 0.0:
                return False, 0.0, -math.inf, math.inf
            ta_ = (q * m - Aa) / Da
            tb_ = ((q + 1) * m - Aa) / Da
            return False, 0.0, min(ta_, tb_), max(ta_, tb_)
    if Da > 0.0:
        return True, ((q_hi + 1 - tol) * m - Aa) / Da, 0.0, 0.0
    if Da < 0.0:
        return True, ((q_lo + tol) * m - Aa) / Da, 0.0, 0.0
    return True, math.inf, 0.0, 0.0


#: The skip table `accumulate_ray` takes has one int8 per cell
#: (`parc.classify.VolumeIndex.tf_skip`): this where the cell may
#: contribute, else ``r + 1`` where every cell within Chebyshev distance
#: ``r`` is transparent (its samples need no interpolation, and a ray may
#: jump to the cube's exit).
MAY_CONTRIBUTE = 0


@kernel(inline="always")
def cell_lattice(c0, c1, t_in, t_out, step, n_last):
    """``(n_lo, n_hi)``: the lattice points ``t_in + n step`` in a cell's interval ``[c0, c1)``
    (the last cell, ``c1 = t_out``, keeps its end).

    Consecutive cells share their crossing time, so every lattice point
    belongs to exactly one cell, whichever cell a walk started from.
    """
    n_lo = int(math.ceil((c0 - t_in) / step))
    if c1 >= t_out:
        return n_lo, n_last
    return n_lo, int(math.ceil((c1 - t_in) / step)) - 1


#: What `visit_cell` tells the walk to do with a cell.
TAKE = 0            # take its lattice points
PASS = 1            # pass it: step on to the next cell
MOVED = 2           # a jump landed the walk on another cell: visit that one
END = 3             # nothing more to take along this ray


@kernel(inline="always")
def visit_cell(A, s, inv, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, c0, c1, t_end,
               skip, jump_min, bits, py, px, use_bits, params, plane):
    """What the walk does at cell ``(i, j, k)`` (interval ``[c0, c1]``):
    ``(action, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, tq0, tq1)``, ``action``
    one of `TAKE`, `PASS`, `MOVED` (the state is then the landing cell's)
    or `END`.

    A cell is passed over when the skip table marks it transparent (a
    cube of such cells of radius ``jump_min`` or more is jumped, to the
    cell the walk is in where the ray leaves it) or, with ``use_bits``,
    when every plane of supercells it meets has a clear bit (the planes'
    clear stretch is jumped too). Either way its samples are all
    transparent. ``A``, ``s`` and ``inv``: the anchored ray's origin, and
    its steps and ``1 / D`` along each axis; ``plane``: ``(Aa, Da, Ua, ta)``
    as `clear_planes` takes them, and ``(tq0, tq1)``, a stretch of the ray
    in a plane whose bit is set (empty: ``(inf, -inf)``), returned updated.
    (Tuples: Numba inlines no function of more than about 30 arguments.)
    """
    tq0, tq1 = plane[4], plane[5]
    e = cell_entry(skip, i, j, k) if jump_min >= 0 else MAY_CONTRIBUTE
    if e == MAY_CONTRIBUTE:
        if not use_bits:
            return TAKE, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, tq0, tq1
        Aa, Da, Ua, ta, tq0, tq1 = plane
        if c0 <= tq1 and c1 >= tq0:
            return TAKE, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, tq0, tq1
        clear, tb, tq0, tq1 = clear_planes(bits, py, px, params, Aa, Da, Ua, ta, c0, c1)
        if not clear:
            return TAKE, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, tq0, tq1
    else:
        if e - 1 < jump_min:
            return PASS, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, tq0, tq1
        tb = cube_exit(A[0], A[1], A[2], s[0], s[1], s[2], inv[0], inv[1], inv[2], i, j, k, e - 1)
    if tb >= t_end:
        return END, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, tq0, tq1
    if tb <= c1:
        return PASS, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, tq0, tq1
    # A jump: to the cell the walk is in at tb, by its own crossing times.
    i, tx0, tx1 = advance(A[0], inv[0], s[0], i, tx0, tx1, tb)
    j, ty0, ty1 = advance(A[1], inv[1], s[1], j, ty0, ty1, tb)
    k, tz0, tz1 = advance(A[2], inv[2], s[2], k, tz0, tz1, tb)
    return MOVED, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, tq0, tq1


@kernel(inline="always")
def shade_color(data, spc, i, j, k, u, vv, w, dx, dy, dz, params, cr, cg, cb):
    """The colour ``(cr, cg, cb)`` of a composite sample in cell ``(i, j, k)`` at local
    ``(u, vv, w)``, seen along the world ray direction ``d``: lit by the lights of ``params``
    as an isosurface hit is (`raycast.shadow.combine_lights`, nothing in the way); a
    `KIND_HEADLIGHT` row shines along ``d``.

    Inlined: the sampling loops that shade are compiled apart from those
    that do not (`_accumulator`), and the call cost the shaded CT head
    (`ct_skin_bone` at 300², `parc compare`, runs alternated) 0.0397-0.0400 s
    against 0.0350-0.0352 s inlined. Nor did inlining slow the merged walk,
    where shading is decided per volume: a shaded CT head beside an
    unshaded one took 0.0570-0.0571 s inlined, 0.0596-0.0600 s called.
    """
    # A flat region has no gradient: it faces the viewer, as a flat isosurface cell
    # does (`raycast.shade.headlight_pixel`), highlight included.
    gx, gy, gz = trilinear_gradient(data, i, j, k, u, vv, w, spc)
    gx, gy, gz = unit_normal(gx, gy, gz, dx, dy, dz)
    material = params[P_AMBIENT:P_AMBIENT + 4]
    fr = fg = fb = material[0]
    sr = sg = sb = 0.0
    for n in range(int(params[P_LIGHT_COUNT])):
        light = params[P_LIGHTS + 7 * n:P_LIGHTS + 7 * n + 7]
        if light[0] == KIND_HEADLIGHT:
            lx, ly, lz = -dx, -dy, -dz
        else:
            # The sample's world point, found only for the lights that need it.
            lx, ly, lz, dist = to_light(light, params[P_ORIGIN] + spc[0] * (i + u),
                                        params[P_ORIGIN + 1] + spc[1] * (j + vv),
                                        params[P_ORIGIN + 2] + spc[2] * (k + w))
            if dist == 0.0:
                continue            # a light at the sample: no direction to it
        diff, spec = blinn_phong(gx, gy, gz, -dx, -dy, -dz, lx, ly, lz, material)
        fr += diff * light[4]
        fg += diff * light[5]
        fb += diff * light[6]
        sr += spec * light[4]
        sg += spec * light[5]
        sb += spec * light[6]
    return cr * fr + sr, cg * fg + sg, cb * fb + sb


@kernel(inline="always")
def composite_sample(data, spc, v, i, j, k, u, vv, w, a, dx, dy, dz, params, col_x, col_rgb, shade):
    """Step-corrected opacity and colour of a composite sample of value ``v`` and opacity ``a > 0``,
    shaded when ``shade`` (the casters pass a constant where they can, so that the call is compiled out)."""
    a = correct_opacity(a, params[P_RATIO])
    cr, cg, cb = tf_color(col_x, col_rgb, v)
    if shade:
        cr, cg, cb = shade_color(data, spc, i, j, k, u, vv, w, dx, dy, dz, params, cr, cg, cb)
        # Specular light can pass 1; clamped per sample, as a lit surface's is, the
        # premultiplied colour stays within the opacity.
        cr, cg, cb = min(cr, 1.0), min(cg, 1.0), min(cb, 1.0)
    return a, cr, cg, cb


@kernel(inline="always")
def ray_span(data, Ox, Oy, Oz, Dx, Dy, Dz, seg0, seg1, t_stop, step):
    """What a ray's walk covers: ``(ta, Ax, Ay, Az, t_in, t_out, n_last, t_start, t_end)``.

    The ray is anchored at its entry into the volume (`entry_anchor`: ``A``
    is its point at ``t = ta``, and the walk's times count from there); its
    lattice points are ``t_in + n step``, ``n = 0 .. n_last``; the walk
    goes from ``t_start`` (the segment's start, or the entry) and need not
    pass ``t_end`` (the segment's end, the stop or the exit).
    ``t_start > t_end`` when there is nothing to walk.
    """
    nz, ny, nx = grid_shape(data)
    ta, Ax, Ay, Az = entry_anchor(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz)
    t_in, t_out = clip_box(Ax, Ay, Az, Dx, Dy, Dz, nx, ny, nz)
    if not t_in <= t_out:
        return ta, Ax, Ay, Az, t_in, t_out, -1, 1.0, 0.0
    n_last = int(math.floor((t_out - t_in) / step))
    return ta, Ax, Ay, Az, t_in, t_out, n_last, max(t_in, seg0 - ta), min(t_out, min(seg1, t_stop) - ta)


@kernel(parallel=True)
def box_entry_image(data, org, spc, cam, width, height, out):
    """Per pixel, where the camera ray enters the volume's sample box, inf where it misses:
    the ``t`` of the first point of its sample lattice, the very number a sample there carries
    (`ray_span`'s), so that what is placed at the entry orders exactly against such samples."""
    for y in prange(height):
        for x in range(width):
            ox, oy, oz, dx, dy, dz = camera_ray(cam, width, height, x, y)
            Ox, Oy, Oz, Dx, Dy, Dz = to_index_space(ox, oy, oz, dx, dy, dz, org, spc)
            ta, _, _, _, t_in, t_out, _, _, _ = ray_span(data, Ox, Oy, Oz, Dx, Dy, Dz, -math.inf, math.inf,
                                                         math.inf, 1.0)
            out[y, x] = ta + t_in if t_in <= t_out else math.inf


@kernel(inline="always")
def local_coords(Ax, Ay, Az, Dx, Dy, Dz, i, j, k, t):
    """Local ``(u, v, w)`` of the anchored ray's point at ``t`` in cell ``(i, j, k)``, clamped to the cell:
    the walk's cell and the point's rounded position may disagree by an ulp at a face."""
    u = min(max((Ax - i) + t * Dx, 0.0), 1.0)
    v = min(max((Ay - j) + t * Dy, 0.0), 1.0)
    w = min(max((Az - k) + t * Dz, 0.0), 1.0)
    return u, v, w


def _accumulator(shaded, planes):
    """`accumulate_ray` with gradient shading (``shaded``) and the bit-plane test (``planes``)
    compiled in or out.

    Four kernels rather than tests in the walk: code left in the loop, even
    untaken, made LLVM keep the loop's values around it (the shading call,
    the planes' test), and PARC's unshaded CT head frame without bit
    planes took 1.15x as long, `brute`'s 1.1x.
    """
    @kernel
    @named_for(shaded=shaded, planes=planes)
    def accumulate(data, spc, Ox, Oy, Oz, Dx, Dy, Dz, dx, dy, dz, seg0, seg1, t_stop, params,
                   op_x, op_y, col_x, col_rgb, bits, py, px, skip, jump_min):
        """Accumulate one ray (index space ``O + t D``; world direction ``d``) over ``[seg0, seg1]``.

        Returns premultiplied ``(r, g, b, a, samples)``; ``samples`` counts the
        trilinear interpolations done. Lattice points at ``t >= t_stop`` (an
        opaque surface, a light) are not taken. The walk goes cell by cell and
        takes each cell's lattice points from its eight corners (module
        docstring); `visit_cell` passes over the cells it can prove
        transparent: by the skip table ``skip[k, j, i]`` when ``jump_min >= 0``
        (the unaccelerated caster passes `raycast.iso.NO_SKIP` and -1), and,
        in the kernels with the planes' test, by the bit planes ``bits[py, px]``.
        """
        nz, ny, nx = grid_shape(data)
        step = params[P_STEP]
        mode = int(params[P_MODE])
        threshold = params[P_THRESHOLD]
        lo = params[P_LO]
        ta, Ax, Ay, Az, t_in, t_out, n_last, t_start, t_end = ray_span(data, Ox, Oy, Oz, Dx, Dy, Dz, seg0, seg1,
                                                                       t_stop, step)
        if not t_start <= t_end:
            return 0.0, 0.0, 0.0, 0.0, 0          # every mode's empty ray
        i, j, k, sx, sy, sz, ix, iy, iz, tx0, tx1, ty0, ty1, tz0, tz1 = walk_from(Ax, Ay, Az, Dx, Dy, Dz,
                                                                                 t_start, nx, ny, nz)
        # Bit planes: the ray along the plane axis, anchored and as given (its rounding).
        axis = int(params[P_PLANE_AXIS])
        Aa, Da, Ua = (Ax, Dx, Ox) if axis == 0 else ((Ay, Dy, Oy) if axis == 1 else (Az, Dz, Oz))
        tq0 = math.inf
        tq1 = -math.inf
        r = 0.0
        g = 0.0
        b = 0.0
        acc = 0.0
        vmax = -math.inf
        total = 0.0
        samples = 0
        while True:
            c0 = max(t_in, max(tx0, max(ty0, tz0)))
            c1 = min(t_out, min(tx1, min(ty1, tz1)))
            action, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, tq0, tq1 = visit_cell(
                (Ax, Ay, Az), (sx, sy, sz), (ix, iy, iz), i, j, k, tx0, tx1, ty0, ty1, tz0, tz1, c0, c1, t_end,
                skip, jump_min, bits, py, px, planes, params, (Aa, Da, Ua, ta, tq0, tq1))
            if action == MOVED:
                continue
            if action == END:
                break
            done = False
            if action == TAKE:
                n_lo, n_hi = cell_lattice(c0, c1, t_in, t_out, step, n_last)
                if n_lo <= n_hi:
                    v000, v100, v010, v110, v001, v101, v011, v111 = cell_corners(data, i, j, k)
                    for n in range(n_lo, n_hi + 1):
                        tl = t_in + n * step
                        if ta + tl >= t_stop:
                            done = True
                            break
                        u, vv, w = local_coords(Ax, Ay, Az, Dx, Dy, Dz, i, j, k, tl)
                        v = trilinear(v000, v100, v010, v110, v001, v101, v011, v111, u, vv, w)
                        samples += 1
                        a = tf_opacity(op_x, op_y, v)
                        if not a > 0.0:
                            continue
                        if mode == MODE_COMPOSITE:
                            a, cr, cg, cb = composite_sample(data, spc, v, i, j, k, u, vv, w, a, dx, dy, dz,
                                                             params, col_x, col_rgb, shaded)
                            wgt = (1.0 - acc) * a
                            r += wgt * cr
                            g += wgt * cg
                            b += wgt * cb
                            acc += wgt
                            if acc >= threshold:
                                done = True
                                break
                        elif mode == MODE_MIP:
                            if v > vmax:
                                vmax = v
                        else:
                            total += v - lo
            if done or c1 >= t_end:
                break
            inside, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1 = step_cell(Ax, Ay, Az, sx, sy, sz, ix, iy, iz, i, j, k,
                                                                      tx0, tx1, ty0, ty1, tz0, tz1, nx, ny, nz)
            if not inside:
                break
        if mode == MODE_COMPOSITE:
            return min(r, 1.0), min(g, 1.0), min(b, 1.0), min(acc, 1.0), samples
        if mode == MODE_MIP:
            if vmax == -math.inf:
                return 0.0, 0.0, 0.0, 0.0, samples
            cr, cg, cb, a = tf_lookup(op_x, op_y, col_x, col_rgb, vmax)
            return cr * a, cg * a, cb * a, a, samples
        grey = average_grey(total, n_last + 1, params)
        return grey, grey, grey, grey, samples
    return accumulate


_ACCUMULATORS = {(shaded, planes): _accumulator(shaded, planes)
                 for shaded in (False, True) for planes in (False, True)}
#: One ray, without shading or bit planes: what a shadow ray through a
#: translucent volume takes (its opacity does not depend on the shading).
#: The image casters take the kernel the volume needs (`cast_accumulate_image`).
accumulate_ray = _ACCUMULATORS[False, False]


@kernel
def average_grey(total, count, params):
    """The average mode's grey level: ``total``, the sum of the visible samples' heights above
    the data's minimum, over ``count`` lattice samples and the data range."""
    span = params[P_HI] - params[P_LO]
    if not span > 0.0:
        return 0.0          # a constant volume: every sample at the minimum
    return min(max(total / count / span, 0.0), 1.0)


_ACCUMULATE_PLAIN = _ACCUMULATORS[False, False]
_ACCUMULATE_SHADED = _ACCUMULATORS[True, False]
_ACCUMULATE_PLANES = _ACCUMULATORS[False, True]
_ACCUMULATE_SHADED_PLANES = _ACCUMULATORS[True, True]


@kernel(inline="always")
def _accumulate_kind(shaded, planes, data, spc, Ox, Oy, Oz, Dx, Dy, Dz, dx, dy, dz, seg0, seg1, t_stop, params,
                     op_x, op_y, col_x, col_rgb, bits, py, px, skip, jump_min):
    """The `_accumulator` kernel for ``(shaded, planes)``, called; the drivers pass constants, and
    the three calls not taken are compiled out."""
    if shaded:
        if planes:
            return _ACCUMULATE_SHADED_PLANES(data, spc, Ox, Oy, Oz, Dx, Dy, Dz, dx, dy, dz, seg0, seg1, t_stop,
                                             params, op_x, op_y, col_x, col_rgb, bits, py, px, skip, jump_min)
        return _ACCUMULATE_SHADED(data, spc, Ox, Oy, Oz, Dx, Dy, Dz, dx, dy, dz, seg0, seg1, t_stop, params,
                                  op_x, op_y, col_x, col_rgb, bits, py, px, skip, jump_min)
    if planes:
        return _ACCUMULATE_PLANES(data, spc, Ox, Oy, Oz, Dx, Dy, Dz, dx, dy, dz, seg0, seg1, t_stop, params,
                                  op_x, op_y, col_x, col_rgb, bits, py, px, skip, jump_min)
    return _ACCUMULATE_PLAIN(data, spc, Ox, Oy, Oz, Dx, Dy, Dz, dx, dy, dz, seg0, seg1, t_stop, params,
                             op_x, op_y, col_x, col_rgb, bits, py, px, skip, jump_min)


def _image_caster(shaded, planes):
    """A parallel driver of the `_accumulator` kernel for ``(shaded, planes)`` over image tiles
    (`cast_accumulate_image`).

    It closes over the two flags, not over the kernel: Numba keys a
    closure's cache entry by its pickled closure, and a kernel pickles
    with an id new in every process, so a driver closing over one was
    compiled again in each process (2.3 s of a translucent `parc render`).
    """
    @kernel(parallel=True)
    @named_for(shaded=shaded, planes=planes)
    def cast(data, org, spc, cam, width, height, params, op_x, op_y, col_x, col_rgb,
             seg, use_seg, stop, use_stop, bits, skip, jump_min, image, counts, row0, row1):
        tiles = tile_count(width, row0, row1, TILE_W, TILE_H)
        samples = 0
        for it in prange(tiles):
            x0, x1, y0, y1 = dealt_tile(it, tiles, width, row0, row1)
            for y in range(y0, y1):
                for x in range(x0, x1):
                    s0 = -math.inf
                    s1 = math.inf
                    if use_seg:
                        s0 = seg[y, x, 0]
                        s1 = seg[y, x, 1]
                        if not s0 <= s1:
                            counts[y * width + x] = 0
                            for c in range(4):
                                image[y, x, c] = 0.0
                            continue
                    ox, oy, oz, dx, dy, dz = camera_ray(cam, width, height, x, y)
                    Ox, Oy, Oz, Dx, Dy, Dz = to_index_space(ox, oy, oz, dx, dy, dz, org, spc)
                    r, g, b, a, n = _accumulate_kind(shaded, planes, data, spc, Ox, Oy, Oz, Dx, Dy, Dz, dx, dy,
                                                     dz, s0, s1, stop[y, x] if use_stop else math.inf, params,
                                                     op_x, op_y, col_x, col_rgb, bits, y, x, skip, jump_min)
                    image[y, x, 0] = r
                    image[y, x, 1] = g
                    image[y, x, 2] = b
                    image[y, x, 3] = a
                    counts[y * width + x] = n
                    samples += n
        return samples
    return cast


#: One driver per `_accumulator` kernel: a driver that called all four
#: (choosing per ray) ran `brute`'s CT head frame 1.1x slower.
_IMAGE_CASTERS = {key: _image_caster(*key) for key in _ACCUMULATORS}


def cast_accumulate_image(data, org, spc, cam, width, height, params, op_x, op_y, col_x, col_rgb,
                          seg, use_seg, stop, use_stop, bits, use_bits, skip, jump_min, image, counts,
                          row0, row1):
    """Accumulate every pixel of rows ``row0 <= y < row1``, tile by tile.

    ``image`` is ``(height, width, 4)`` float32 premultiplied RGBA,
    ``counts[y * width + x]`` the samples taken. With ``use_seg`` a pixel
    whose ``seg[y, x]`` has ``near > far`` costs nothing. With ``use_stop``
    no sample is taken at ``t >= stop[y, x]`` (an opaque surface there).
    ``skip``/``jump_min``: the skip table (`accumulate_ray`).
    Returns the samples taken over the rows cast.
    """
    cast = _IMAGE_CASTERS[bool(params[P_SHADE] != 0.0), bool(use_bits)]
    return cast(data, org, spc, cam, width, height, params, op_x, op_y, col_x, col_rgb, seg, use_seg, stop,
                use_stop, bits, skip, jump_min, image, counts, row0, row1)


@kernel(parallel=True)
def over_background(image, background):
    """Composite a premultiplied RGBA ``(H, W, 4)`` float32 image over ``background`` (premultiplied RGBA), in place.

    One pass over the pixels; NumPy's broadcast expression took 6-7 ms a
    frame at 512x512, a tenth of a PARC frame.
    """
    h, w, _ = image.shape
    for y in prange(h):
        for x in range(w):
            a = np.float32(1.0) - image[y, x, 3]
            for c in range(4):
                image[y, x, c] += a * background[c]
