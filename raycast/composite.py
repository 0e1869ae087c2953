"""Accumulation along rays: front-to-back compositing, maximum and average intensity.

About this technique
--------------------
Each ray is sampled every ``step`` world units on a lattice anchored where
it enters the volume: ``t_n = t_in + n step`` for ``n = 0 .. N-1``,
``N = floor((t_out - t_in) / step) + 1`` (Sobierajski & Avila 1995, §4:
samples every quarter of a unit by default). A sample interpolates the
data trilinearly (post-classification: interpolate the value, then look it
up in the transfer function).

- *composite*: front-to-back ``C += (1 - A) a c``, ``A += (1 - A) a`` with
  the opacity corrected for the step (`raycast.transfer.correct_opacity`)
  and, optionally, the colour shaded with the gradient (headlight,
  Blinn-Phong); the ray stops once ``A`` reaches the threshold.
- *mip*: the largest value among samples with non-zero opacity; the pixel
  takes the transfer function's colour and opacity there.
- *average*: the sum of the values of samples with non-zero opacity over
  all ``N`` lattice samples of the ray in the volume, normalized by the
  data range: an X-ray-like grey level of what the transfer function shows.

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

from .config import TILE_H, TILE_W, kernel
from .rays import camera_ray, dealt_tile, tile_count
from .shade import blinn_phong, trilinear_gradient
from .transfer import correct_opacity, tf_color, tf_lookup, tf_opacity
from .traverse import cell_corners, clip_box, entry_anchor, grid_shape, to_index_space

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
N_PARAMS = 15


@kernel
def sample_value(data, x, y, z):
    """Trilinear value at index-space ``(x, y, z)``, and the cell and local coordinates used.

    The value leaves the cell's corner range by at most `INTERP_ROUNDING` of the corners' magnitude.
    """
    i, j, k = sample_cell(data, x, y, z)
    val, u, v, w = interpolate(data, x, y, z, i, j, k)
    return val, i, j, k, u, v, w


@kernel
def sample_cell(data, x, y, z):
    """The cell `sample_value` interpolates in at index-space ``(x, y, z)``: the floor, clamped to the grid."""
    nz, ny, nx = grid_shape(data)
    return (min(max(int(math.floor(x)), 0), nx - 2), min(max(int(math.floor(y)), 0), ny - 2),
            min(max(int(math.floor(z)), 0), nz - 2))


@kernel
def interpolate(data, x, y, z, i, j, k):
    """Trilinear value at ``(x, y, z)`` in cell ``(i, j, k)``, and the local coordinates ``(u, v, w)``."""
    u = x - i
    v = y - j
    w = z - k
    v000, v100, v010, v110, v001, v101, v011, v111 = cell_corners(data, i, j, k)
    c00 = v000 + u * (v100 - v000)
    c10 = v010 + u * (v110 - v010)
    c01 = v001 + u * (v101 - v001)
    c11 = v011 + u * (v111 - v011)
    c0 = c00 + v * (c10 - c00)
    c1 = c01 + v * (c11 - c01)
    return c0 + w * (c1 - c0), u, v, w


#: The nested lerps of `interpolate` can round past the corners' range (a
#: difference like ``c10 - c00`` is inexact): by at most a few units of
#: 2^-53 of the corners' largest magnitude (about 1 sample in 1,000 on
#: corners mixing 1 and -1e-16). Classifying a cell for a transfer
#: function widens its range by this fraction of that magnitude
#: (`parc.transfer.TransferFunction.nonzero_in`'s ``rounding``), so a
#: function that starts just past the range cannot show in ``brute`` alone.
#: (Clamping each sample to the range instead cost the unaccelerated
#: caster half its speed.)
INTERP_ROUNDING = 2.0 ** -44


#: A sample this close (in planes) to a boundary between planes of
#: supercells tests the bits of both: its float position may round to
#: either side of where the OpenGL pass saw the ray cross.
PLANE_TOL = 1e-6

#: ... and, on top of that, this fraction of ``|O_a| + |t D_a|`` (cells):
#: the position ``O_a + t D_a`` rounds by a few units of 2^-53 of its
#: terms, which an eye far from the volume makes large (eye 3e8 world
#: units away: |O_a| ~ 1.6e9 cells, rounding ~4e-7 cells, 3e-6 of a
#: 1/8-cell plane, past PLANE_TOL; brute took samples PARC skipped).
POS_ROUNDING = 2.0 ** -48


@kernel(inline="always")
def _bit(bits, py, px, q, params):
    q -= int(params[P_PLANE_FIRST])
    if q < 0 or q >= int(params[P_PLANE_COUNT]):
        return False
    return (bits[py, px, q >> 5] >> (q & 31)) & 1 != 0


@kernel(inline="always")
def plane_bit(bits, py, px, pos, err, params):
    """Whether a bit is set for the supercell plane holding index coordinate ``pos``
    (rounded by up to ``err`` cells: see `POS_ROUNDING`)."""
    m = params[P_PLANE_SIZE]
    f = pos / m
    tol = PLANE_TOL + err / m
    lo = int(math.floor(f - tol))
    hi = int(math.floor(f + tol))
    return _bit(bits, py, px, lo, params) or (hi != lo and _bit(bits, py, px, hi, params))


@kernel
def next_plane_sample(n, t_in, step, O, D, pos, params):
    """A lattice index safely before the ray leaves the plane holding ``pos``.

    The samples skipped up to it lie strictly inside that plane (two steps
    of slack absorb the rounding of the crossing time), so when the plane's
    bit is clear they are all transparent.
    """
    if D == 0.0:
        return 1 << 62
    m = params[P_PLANE_SIZE]
    q = math.floor(pos / m)
    b = (q + 1.0) * m if D > 0.0 else q * m
    t_b = (b - O) / D
    target = int(math.floor((t_b - t_in) / step)) - 2
    return max(n + 1, target)


@kernel
def lattice_range(t_in, t_out, step, seg0, seg1):
    """``(n0, n1, n_last)``: the lattice points ``t_in + n step`` to take, ``n0 <= n <= n1``, of ``0 .. n_last``.

    The segment bounds only pick lattice points; one extra point at each
    end is harmless (PARC's segments end in transparent space).
    """
    n_last = int(math.floor((t_out - t_in) / step))
    n0 = 0
    n1 = n_last
    if seg0 > t_in:
        n0 = max(0, int(math.floor((seg0 - t_in) / step)))
    if seg1 < t_out:
        n1 = min(n_last, int(math.ceil((seg1 - t_in) / step)))
    return n0, n1, n_last


@kernel
def shade_color(data, spc, i, j, k, u, vv, w, dx, dy, dz, params, cr, cg, cb):
    """The colour ``(cr, cg, cb)`` of a composite sample in cell ``(i, j, k)`` at local
    ``(u, vv, w)``, lit by a headlight along the world ray direction ``d``.

    Kept apart from the sampling loops, which call it only when shading is
    on: inlined, it made every contributing sample of an unshaded ray cost
    about twice as much (the loop's registers spilled around code it never ran).
    """
    gx, gy, gz = trilinear_gradient(data, i, j, k, u, vv, w, spc)
    gl = math.sqrt(gx * gx + gy * gy + gz * gz)
    if gl > 0.0:
        diff, spec = blinn_phong(gx / gl, gy / gl, gz / gl, -dx, -dy, -dz,
                                 -dx, -dy, -dz, params[P_AMBIENT:P_AMBIENT + 4])
        f = params[P_AMBIENT] + diff
        return cr * f + spec, cg * f + spec, cb * f + spec
    f = params[P_AMBIENT] + params[P_AMBIENT + 1]
    return cr * f, cg * f, cb * f


@kernel(inline="always")
def composite_sample(data, spc, v, i, j, k, u, vv, w, a, dx, dy, dz, params, col_x, col_rgb):
    """Step-corrected opacity and (shaded) colour of a composite sample of value ``v`` and opacity ``a > 0``."""
    a = correct_opacity(a, params[P_RATIO])
    cr, cg, cb = tf_color(col_x, col_rgb, v)
    if params[P_SHADE] != 0.0:
        cr, cg, cb = shade_color(data, spc, i, j, k, u, vv, w, dx, dy, dz, params, cr, cg, cb)
    return a, cr, cg, cb


@kernel
def _cube_exit_axis(O, D, c, r):
    if D == 0.0:
        return math.inf
    b = c + r + 1 if D > 0.0 else c - r
    return (b - O) / D


@kernel
def cube_last_sample(n, t_in, step, Ox, Oy, Oz, Dx, Dy, Dz, i, j, k, r):
    """A lattice index safely before the ray leaves the cube of cells within ``r`` of cell ``(i, j, k)``,
    at least ``n``; as `next_plane_sample`, two steps of slack."""
    t_b = min(_cube_exit_axis(Ox, Dx, i, r), min(_cube_exit_axis(Oy, Dy, j, r), _cube_exit_axis(Oz, Dz, k, r)))
    if t_b == math.inf:
        return 1 << 62
    return max(n, int(math.floor((t_b - t_in) / step)) - 2)


#: The skip table `accumulate_ray` takes has one int8 per cell
#: (`parc.classify.VolumeIndex.tf_skip`): this where the cell may
#: contribute, else ``r + 1`` where every cell within Chebyshev distance
#: ``r`` is transparent (its samples need no interpolation, and a ray may
#: jump to the cube's exit).
MAY_CONTRIBUTE = 0


@kernel
def accumulate_ray(data, spc, Ox, Oy, Oz, Dx, Dy, Dz, dx, dy, dz, seg0, seg1, t_stop, params,
                   op_x, op_y, col_x, col_rgb, bits, py, px, use_bits, skip, jump_min):
    """Accumulate one ray (index space ``O + t D``; world direction ``d``) over ``[seg0, seg1]``.

    Returns premultiplied ``(r, g, b, a, samples)``; ``samples`` counts the
    trilinear interpolations done. Lattice points at ``t >= t_stop`` (an
    opaque surface, a light) are not taken. With ``use_bits``, samples in a
    plane of supercells whose bit in ``bits[py, px]`` is clear are skipped.
    With ``jump_min >= 0``, ``skip[k, j, i]`` (the skip table above)
    tells for each cell whether it is transparent: a sample there is not
    interpolated, and one in a cell whose cube of transparent cells has a
    radius of at least ``jump_min`` skips the samples up to the cube's exit.
    The unaccelerated caster passes `raycast.iso.NO_SKIP` and -1.
    """
    nz, ny, nx = grid_shape(data)
    t_in, t_out = clip_box(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz)
    if not t_in <= t_out:
        return 0.0, 0.0, 0.0, 0.0, 0
    step = params[P_STEP]
    mode = int(params[P_MODE])
    n0, n1, n_last = lattice_range(t_in, t_out, step, seg0, seg1)
    axis = int(params[P_PLANE_AXIS])
    threshold = params[P_THRESHOLD]
    r = 0.0
    g = 0.0
    b = 0.0
    acc = 0.0
    vmax = -math.inf
    total = 0.0
    samples = 0
    # Positions from the entry of a ray from a distant eye (`raycast.iso.cast_iso_ray`
    # says why): lattice point n at A + (base + n step) D, ``base`` 0 there and t_in otherwise.
    ta, Ax, Ay, Az = entry_anchor(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz)
    base = t_in - ta
    if axis == 0:
        Oa, Aa, Da = Ox, Ax, Dx
    elif axis == 1:
        Oa, Aa, Da = Oy, Ay, Dy
    else:
        Oa, Aa, Da = Oz, Az, Dz
    n = n0 - 1
    while n < n1:
        n += 1
        tl = base + n * step
        t = ta + tl               # t_in + n step, as before anchoring (ta is 0 or t_in)
        if t >= t_stop:
            break
        x = Ax + tl * Dx
        y = Ay + tl * Dy
        z = Az + tl * Dz
        i, j, k = sample_cell(data, x, y, z)
        if jump_min >= 0:
            clear = skip[k, j, i]
            if clear != MAY_CONTRIBUTE:
                if clear - 1 >= jump_min:
                    # The samples up to where the ray leaves the cube are transparent.
                    n = min(n1, cube_last_sample(n, t_in, step, Ox, Oy, Oz, Dx, Dy, Dz, i, j, k, clear - 1))
                continue
        # The plane test comes after the table's: a cell that may contribute
        # lies in a possibly contributing supercell, whose plane's bit the
        # ray has, so behind a table the test seldom skips anything; it is
        # taken only for the samples the table leaves (depth+bits on the CT
        # head at 300x300: 0.20 s with the test first, 0.14 s after).
        if use_bits:
            pos = Aa + tl * Da
            if not plane_bit(bits, py, px, pos, POS_ROUNDING * (abs(Oa) + abs(t * Da)), params):
                # Skip the rest of this plane: its samples are all transparent.
                n = max(n, min(n1, next_plane_sample(n, t_in, step, Oa, Da, pos, params)) - 1)
                continue
        samples += 1
        v, u, vv, w = interpolate(data, x, y, z, i, j, k)
        a = tf_opacity(op_x, op_y, v)
        if not a > 0.0:
            continue
        if mode == MODE_COMPOSITE:
            a, cr, cg, cb = composite_sample(data, spc, v, i, j, k, u, vv, w, a, dx, dy, dz, params,
                                             col_x, col_rgb)
            wgt = (1.0 - acc) * a
            r += wgt * cr
            g += wgt * cg
            b += wgt * cb
            acc += wgt
            if acc >= threshold:
                break
        elif mode == MODE_MIP:
            if v > vmax:
                vmax = v
        else:
            total += v
    if mode == MODE_COMPOSITE:
        return min(r, 1.0), min(g, 1.0), min(b, 1.0), min(acc, 1.0), samples
    if mode == MODE_MIP:
        if vmax == -math.inf:
            return 0.0, 0.0, 0.0, 0.0, samples
        cr, cg, cb, a = tf_lookup(op_x, op_y, col_x, col_rgb, vmax)
        return cr * a, cg * a, cb * a, a, samples
    grey = average_grey(total, n_last + 1, params)
    return grey, grey, grey, grey, samples


@kernel
def average_grey(total, count, params):
    """The average mode's grey level: the mean of ``count`` lattice samples' values (``total``) in the data range."""
    lo = params[P_LO]
    hi = params[P_HI]
    grey = 0.0
    if hi > lo:
        grey = min(max((total / count - lo) / (hi - lo), 0.0), 1.0)
    if total == 0.0:
        grey = 0.0
    return grey


@kernel(parallel=True)
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
                r, g, b, a, n = accumulate_ray(data, spc, Ox, Oy, Oz, Dx, Dy, Dz, dx, dy, dz, s0, s1,
                                               stop[y, x] if use_stop else math.inf, params, op_x, op_y, col_x, col_rgb,
                                               bits, y, x, use_bits, skip, jump_min)
                image[y, x, 0] = r
                image[y, x, 1] = g
                image[y, x, 2] = b
                image[y, x, 3] = a
                counts[y * width + x] = n
                samples += n
    return samples


@kernel(inline="always")
def _next_layer(layer_t, used, y, x, before):
    """The unused layer with the smallest ``t < before`` at pixel (y, x), or -1."""
    best = -1
    bt = before
    for j in range(layer_t.shape[0]):
        if not used[j] and layer_t[j, y, x] < bt:
            best = j
            bt = layer_t[j, y, x]
    return best


@kernel(parallel=True)
def cast_merged_image(datas, orgs, spcs, cam, width, height, params, op_x, op_y, col_x, col_rgb, tf_len,
                      seg, use_seg, skip, jump_mins, stop, layer_t, layer_rgba, image, counts):
    """Composite several overlapping volumes along each pixel's ray, samples merged in depth order.

    ``datas`` is a tuple of K volumes of one dtype, each with its own
    placement (``orgs[k]``, ``spcs[k]``), ``params[k]`` (composite mode),
    transfer function (rows ``k`` of the padded tables, lengths
    ``tf_len[k] = (opacity points, colour points)``) and PARC segments
    ``seg[k]``. Each volume keeps its own sample lattice (anchored where the
    ray enters it, as for one volume), so every sample is the one a
    single-volume cast would take; the samples of all volumes are taken in
    order of ``t`` (ties: the first volume first), composited front to
    back, and stop at ``stop[y, x]`` (an opaque surface) or once the
    opacity reaches the largest threshold. ``layer_t[j]``, ``layer_rgba[j]``
    are finished per-pixel layers (maximum or average intensity of another
    volume) composited where the ray reaches ``t = layer_t``. ``skip[k]``
    and ``jump_mins[k]``: volume k's skip table, as `accumulate_ray`
    takes it (`raycast.iso.NO_SKIP` and -1 for none); a skipped sample
    adds nothing, so the layers and the other volumes' samples keep their
    order.
    """
    nvol = len(datas)
    thr = 0.0
    for k in range(nvol):
        thr = max(thr, params[k, P_THRESHOLD])
    tiles = tile_count(width, 0, height, TILE_W, TILE_H)
    for it in prange(tiles):
        x0, x1, y0, y1 = dealt_tile(it, tiles, width, 0, height)
        st = np.empty((nvol, 13))
        used = np.zeros(layer_t.shape[0], np.bool_)
        for y in range(y0, y1):
            for x in range(x0, x1):
                ox, oy, oz, dx, dy, dz = camera_ray(cam, width, height, x, y)
                for k in range(nvol):
                    Ox, Oy, Oz, Dx, Dy, Dz = to_index_space(ox, oy, oz, dx, dy, dz, orgs[k], spcs[k])
                    nz, ny, nx = grid_shape(datas[k])
                    t_in, t_out = clip_box(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz)
                    n0, n1 = 0, -1
                    if t_in <= t_out:
                        s0 = -math.inf
                        s1 = math.inf
                        if use_seg:
                            s0 = seg[k, y, x, 0]
                            s1 = seg[k, y, x, 1]
                        if s0 <= s1:
                            n0, n1, _ = lattice_range(t_in, t_out, params[k, P_STEP], s0, s1)
                    st[k, 0], st[k, 1], st[k, 2] = Ox, Oy, Oz
                    st[k, 3], st[k, 4], st[k, 5] = Dx, Dy, Dz
                    st[k, 6], st[k, 7], st[k, 8] = t_in, n0, n1
                    ta, st[k, 9], st[k, 10], st[k, 11] = entry_anchor(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz)
                    st[k, 12] = t_in - ta
                used[:] = False
                r = 0.0
                g = 0.0
                b = 0.0
                acc = 0.0
                samples = 0
                t_stop = stop[y, x]
                while True:
                    best = -1
                    bt = t_stop
                    for k in range(nvol):
                        if st[k, 7] <= st[k, 8]:
                            t = st[k, 6] + st[k, 7] * params[k, P_STEP]
                            if t < bt:
                                best = k
                                bt = t
                    # Layers in front of the next sample (all of them at the end).
                    while True:
                        j = _next_layer(layer_t, used, y, x, bt if best >= 0 else math.inf)
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
                    tl = st[best, 12] + st[best, 7] * params[best, P_STEP]    # as accumulate_ray
                    st[best, 7] += 1.0
                    data = datas[best]
                    x_ = st[best, 9] + tl * st[best, 3]
                    y_ = st[best, 10] + tl * st[best, 4]
                    z_ = st[best, 11] + tl * st[best, 5]
                    i, j, k = sample_cell(data, x_, y_, z_)
                    jump_min = jump_mins[best]
                    if jump_min >= 0:
                        e = skip[best][k, j, i]
                        if e != MAY_CONTRIBUTE:
                            if e - 1 >= jump_min:
                                n = int(st[best, 7]) - 1
                                last = cube_last_sample(n, st[best, 6], params[best, P_STEP],
                                                        st[best, 0], st[best, 1], st[best, 2],
                                                        st[best, 3], st[best, 4], st[best, 5], i, j, k, e - 1)
                                st[best, 7] = min(float(last), st[best, 8]) + 1.0
                            continue
                    samples += 1
                    v, u, vv, w = interpolate(data, x_, y_, z_, i, j, k)
                    no = int(tf_len[best, 0])
                    nc = int(tf_len[best, 1])
                    a = tf_opacity(op_x[best, :no], op_y[best, :no], v)
                    if not a > 0.0:
                        continue
                    a, cr, cg, cb = composite_sample(data, spcs[best], v, i, j, k, u, vv, w, a, dx, dy, dz,
                                                     params[best], col_x[best, :nc], col_rgb[best, :nc])
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


@kernel(parallel=True)
def over_background(image, background):
    """Composite a premultiplied RGBA ``(H, W, 4)`` float32 image over ``background`` (RGBA), in place.

    One pass over the pixels; NumPy's broadcast expression took 6-7 ms a
    frame at 512x512, a tenth of a PARC frame.
    """
    h, w, _ = image.shape
    for y in prange(h):
        for x in range(w):
            a = np.float32(1.0) - image[y, x, 3]
            for c in range(4):
                image[y, x, c] += a * background[c]
