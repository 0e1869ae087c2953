"""Isosurface casting: walk the cells along a ray, solve the cubic where the range holds the isovalue.

Three layers, as in every caster here: `cast_iso_ray` follows one ray over
one segment; `cast_iso_image` (camera rays, image tiles) and
`cast_iso_rays` (any rays: the hard-case study) run it in parallel; shadow
rays call `cast_iso_ray` themselves (`raycast.shadow`).
PARC and the unaccelerated caster call the same `cast_iso_ray`; PARC only
passes the ray segment ``[seg0, seg1]`` its OpenGL pass found, the
unaccelerated caster ``[-inf, inf]``.

Skipping empty cells. A segment runs from the first possibly contributing
supercell the ray meets to the last, so it also crosses empty space:
between supercells, and inside a supercell whose surface the ray misses.
PARC passes a skip table with one entry per cell
(`parc.classify.VolumeIndex.iso_skip`): ``s (r + 1)`` where every sample
of every cell within Chebyshev distance ``r`` (a cube of ``2r + 1`` cells
a side around it) lies above (``s = +1``) or below (-1) the isovalue, 0
otherwise. A walk in a cell of radius at least ``jump_min`` jumps to the
cube's exit instead of stepping through it; a signed cell elsewhere is
stepped without reading its corners. Nothing else changes: an empty
cell's only effect on the walk is the sign it hands on, which is the
table's, and the jump lands on the cell the full walk would be in at that
time (the cube's exit and the landing cell both by the walk's own crossing
times, `advance`), so the hits are bit for bit the unaccelerated caster's. The
unaccelerated caster passes `NO_SKIP`.

A ray leaves that cube through its far faces only, those ahead of it in
the directions it steps. So a table may as well give, per cell, the side
``r + 1`` of the largest box of one sign that starts at the cell and grows
that way: the jump is the same, to the cube's far faces, and the ray stays
inside the box until then. Such boxes depend on the ray's octant
(`octant`), and near a surface they are larger than the cubes around the
cell. PARC's camera rays walk with a table per octant
(`parc.classify.VolumeIndex.iso_octant_skip`, ``(8, nz, ny, nx)``), each
ray with its own (`ray_table`). Shadow rays keep the centred table
(``(nz, ny, nx)``, which `ray_table` passes through): from the hits
towards a point light they go every way, and with a table per octant the
shadow rays of the neuron-and-floor scene took 9.9 ms a frame against 7.3.
"""
import math

import numpy as np
from numba import prange, types
from numba.extending import overload

from .config import OVERLOAD_JIT, TILE_H, TILE_W, kernel
from .cubic import cubic_along_ray, eval_cubic, first_root, trilinear_coefficients
from .rays import camera_ray, dealt_tile, spread_run, spread_runs, tile_count
from .shade import headlight_pixel
from .traverse import (TINY_DIRECTION, advance, axis_state, cell_corners, cell_entry, clip_box, cube_exit,
                       entry_anchor, grid_shape, step_cell, to_index_space, walk_from)

#: Octants of ray directions, numbered by `octant`.
OCTANTS = 8

#: The table a walk without one takes (with ``jump_min = -1``).
NO_SKIP = np.zeros((1, 1, 1), np.int8)
#: The same in the shape of a table by octant (`ray_table`), so that a caller
#: passing octant tables to PARC and none to `brute` compiles one kernel.
NO_SKIP_OCTANTS = np.zeros((OCTANTS, 1, 1, 1), np.int8)

#: The last four arguments of a `cast_iso_image` call that only casts (no shading).
NO_SHADING = (False, np.zeros(3), np.zeros(4), np.zeros((1, 1, 4), np.float32))


@kernel
def octant(Dx, Dy, Dz):
    """The octant (0-7) of direction ``D``: bit 0 set where ``Dx < 0``, bit 1 for y, bit 2 for z."""
    return (1 if Dx < 0.0 else 0) + (2 if Dy < 0.0 else 0) + (4 if Dz < 0.0 else 0)


def ray_table(skip, Dx, Dy, Dz):
    """The skip table a ray of direction ``D`` walks with: ``skip`` itself (one table for
    every ray, ``(nz, ny, nx)``) or its entry for the ray's `octant` (``(8, nz, ny, nx)``,
    `parc.classify.VolumeIndex.iso_octant_skip`). In kernels the call compiles to the one
    that matches the table's dimensions."""
    return skip if skip.ndim == 3 else skip[octant(Dx, Dy, Dz)]


@overload(ray_table, jit_options=OVERLOAD_JIT)
def _ray_table(skip, Dx, Dy, Dz):
    if isinstance(skip, types.Array) and skip.ndim == 3:
        return lambda skip, Dx, Dy, Dz: skip
    if isinstance(skip, types.Array) and skip.ndim == 4:
        return lambda skip, Dx, Dy, Dz: skip[octant(Dx, Dy, Dz)]
    return None


@kernel
def corners(data, iso, i, j, k):
    """The eight corner samples of cell ``(i, j, k)`` minus ``iso``, and their min and max."""
    c000, c100, c010, c110, c001, c101, c011, c111 = cell_corners(data, i, j, k)
    v000, v100, v010, v110 = c000 - iso, c100 - iso, c010 - iso, c110 - iso
    v001, v101, v011, v111 = c001 - iso, c101 - iso, c011 - iso, c111 - iso
    lo = min(min(min(v000, v100), min(v010, v110)), min(min(v001, v101), min(v011, v111)))
    hi = max(max(max(v000, v100), max(v010, v110)), max(max(v001, v101), max(v011, v111)))
    return v000, v100, v010, v110, v001, v101, v011, v111, lo, hi


@kernel
def cell_cubic(v000, v100, v010, v110, v001, v101, v011, v111,
               Ox, Oy, Oz, Dx, Dy, Dz, i, j, k, c0):
    """The cubic ``(A, B, C, D)`` of cell ``(i, j, k)`` along the ray, ``s``
    measured from ``t = c0``, and the local coordinates ``(u0, v0, w0)`` there.

    A ray in the plane of the cell's far face along an axis (local coordinate
    1 all along: only the last cell of an axis, where the walk's index is
    clamped, has such rays) reached the face's values through cancellation
    in the monomial form, a rounding off them: a face at the isovalue had no
    exact zero, and was hit late or missed, where in a near face (coordinate
    0) every term holding it vanishes and the zero is exact. So such a cell
    is read mirrored along that axis (`_far_face_cubic`): the same interpolant, at ``1 - 1 = 0``.
    """
    u0 = (Ox - i) + c0 * Dx
    v0 = (Oy - j) + c0 * Dy
    w0 = (Oz - k) + c0 * Dz
    if ((u0 == 1.0 and abs(Dx) < TINY_DIRECTION) or (v0 == 1.0 and abs(Dy) < TINY_DIRECTION)
            or (w0 == 1.0 and abs(Dz) < TINY_DIRECTION)):
        A, B, C, D = _far_face_cubic(v000, v100, v010, v110, v001, v101, v011, v111, u0, v0, w0, Dx, Dy, Dz)
        return A, B, C, D, u0, v0, w0
    a0, ax, ay, az, axy, ayz, azx, axyz = trilinear_coefficients(
        v000, v100, v010, v110, v001, v101, v011, v111)
    A, B, C, D = cubic_along_ray(a0, ax, ay, az, axy, ayz, azx, axyz, u0, v0, w0, Dx, Dy, Dz)
    return A, B, C, D, u0, v0, w0


@kernel
def _far_face_cubic(v000, v100, v010, v110, v001, v101, v011, v111, u0, v0, w0, Dx, Dy, Dz):
    """`cell_cubic`'s cubic for a ray in the plane of the cell's far face along an axis: the cell
    mirrored along each such axis, where the ray's coordinate is 0. Apart, so that the walk's
    loop, which meets it in the volume's last cells alone, carries none of its values."""
    if u0 == 1.0 and abs(Dx) < TINY_DIRECTION:
        v000, v100, v010, v110, v001, v101, v011, v111 = v100, v000, v110, v010, v101, v001, v111, v011
        u0, Dx = 0.0, -Dx
    if v0 == 1.0 and abs(Dy) < TINY_DIRECTION:
        v000, v100, v010, v110, v001, v101, v011, v111 = v010, v110, v000, v100, v011, v111, v001, v101
        v0, Dy = 0.0, -Dy
    if w0 == 1.0 and abs(Dz) < TINY_DIRECTION:
        v000, v100, v010, v110, v001, v101, v011, v111 = v001, v101, v011, v111, v000, v100, v010, v110
        w0, Dz = 0.0, -Dz
    a0, ax, ay, az, axy, ayz, azx, axyz = trilinear_coefficients(
        v000, v100, v010, v110, v001, v101, v011, v111)
    return cubic_along_ray(a0, ax, ay, az, axy, ayz, azx, axyz, u0, v0, w0, Dx, Dy, Dz)


@kernel
def exit_sign(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, i, j, k, c0, c1):
    """Sign of the field minus ``iso`` where the ray leaves cell ``(i, j, k)``
    (interval ``[c0, c1]``), computed exactly as the walk does; 0 if zero."""
    v000, v100, v010, v110, v001, v101, v011, v111, lo, hi = corners(data, iso, i, j, k)
    if lo > 0.0:
        return 1.0
    if hi < 0.0:
        return -1.0
    A, B, C, D, u0, v0, w0 = cell_cubic(v000, v100, v010, v110, v001, v101, v011, v111,
                                        Ox, Oy, Oz, Dx, Dy, Dz, i, j, k, c0)
    f = eval_cubic(A, B, C, D, c1 - c0)
    if f > 0.0:
        return 1.0
    if f < 0.0:
        return -1.0
    return 0.0


@kernel
def _entry_sign(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, i, j, k, sx, sy, sz,
                tx0, ty0, tz0, tx1, ty1, tz1, c0, t_in, t_out, skip, jump_min):
    """Sign at the exit of the cell a full walk visits just before cell (i, j, k).

    That cell is the neighbour across the face of the latest entry time
    ``c0`` (ties: the last axis, as `step_axis` steps x, then y, then z).
    Where the skip table signs that cell (a PARC segment starts on the face
    of a possibly contributing supercell, so the cell behind it lies in an
    empty one), the sign is the table's, as everywhere else in the walk,
    and its corners and cubic are not computed.
    """
    pi, pj, pk = i, j, k
    px0, py0, pz0, px1, py1, pz1 = tx0, ty0, tz0, tx1, ty1, tz1
    if tz0 == c0:
        pk = k - sz
        _, _, pz0, pz1 = axis_state(Oz, Dz, pk)
    elif ty0 == c0:
        pj = j - sy
        _, _, py0, py1 = axis_state(Oy, Dy, pj)
    else:
        pi = i - sx
        _, _, px0, px1 = axis_state(Ox, Dx, pi)
    if jump_min >= 0:
        sign = _cell_sign(cell_entry(skip, pi, pj, pk))
        if sign != 0:
            return float(sign)
    return exit_sign(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, pi, pj, pk,
                     max(t_in, max(px0, max(py0, pz0))),
                     min(t_out, min(px1, min(py1, pz1))))


@kernel
def on_level_face(v000, v100, v010, v110, v001, v101, v011, v111, tx, ty, tz, t, sx, sy, sz, leaving):
    """Whether the ray meets the cell at ``t`` on a face whose four corners all equal the isovalue.

    ``tx, ty, tz`` are the cell's entry (``leaving`` False) or exit
    (``leaving`` True) crossing times, ``sx, sy, sz`` the walk's steps: the
    ray enters or leaves through the face of each axis whose time is ``t``:
    entering, the face at local coordinate 0 of an axis it steps forwards
    along, 1 backwards; leaving, the opposite one. The interpolant is the isovalue exactly all over such a face
    (`corners` subtracts ``iso``, so the test is exact), and the ray is on it
    at ``t`` by the walk's own crossing times, whatever the rounding of the
    cell's cubic there.

    The walk asks only where ``t`` is where the ray enters the volume
    (``t_in``) or leaves it (``t_out``): inside, the cell on the other side of
    the face settles a root there (the entry-sign rule of `cast_iso_ray`);
    on the volume's own faces there is none.
    """
    return ((sx != 0 and tx == t and _level((sx > 0) == leaving, v000, v010, v001, v011, v100, v110, v101, v111))
            or (sy != 0 and ty == t and _level((sy > 0) == leaving, v000, v100, v001, v101, v010, v110, v011, v111))
            or (sz != 0 and tz == t and _level((sz > 0) == leaving, v000, v100, v010, v110, v001, v101, v011, v111)))


@kernel(inline="always")
def _level(far, a0, a1, a2, a3, b0, b1, b2, b3):
    """Whether the four corners of one face of a cell are zero: ``b`` (local coordinate 1 on the
    axis) when ``far``, else ``a`` (0)."""
    if far:
        return b0 == 0.0 and b1 == 0.0 and b2 == 0.0 and b3 == 0.0
    return a0 == 0.0 and a1 == 0.0 and a2 == 0.0 and a3 == 0.0


@kernel
def entry_face_time(tx0, ty0, tz0, t_in, anchored):
    """The crossing time of the face a ray enters the volume through at ``t_in``, for `on_level_face`.

    ``t_in`` itself: where the ray comes from outside, the entry plane's
    crossing and the volume's are the same product (`clip_box`,
    `axis_state`). But a ray moved to its entry (`entry_anchor`) has its
    origin on the face only to within a rounding: a hair inside, ``t_in``
    is 0 and the plane's crossing a hair below it, so there it is the
    latest of the cell's entry crossings.
    """
    if anchored:
        return max(tx0, max(ty0, tz0))
    return t_in


@kernel
def _cell_sign(entry):
    """The sign (+1, -1, 0) a sign-table entry gives its cell."""
    if entry > 0:
        return 1
    if entry < 0:
        return -1
    return 0


@kernel(inline="always")
def cast_iso_ray(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, seg0, seg1, skip, jump_min):
    """First isosurface hit along an index-space ray, within ``[seg0, seg1]``.

    Returns ``(t, i, j, k, u, v, w, cells, solves)``: the hit's ray
    parameter (``inf`` if none), its cell and local coordinates, the cells
    visited and the cubics solved.

    Each cell's cubic is evaluated in that cell's own frame, so where the
    ray crosses from one cell into the next exactly on the isosurface, the
    two cells' rounded values at the shared point can disagree in sign:
    the first cell ends on the near side, the second starts on the far
    side, and neither sees a root. So a cell whose value at its entry has
    the opposite sign from its predecessor's value there (the cell the ray
    leaves through that face, on the same numbers) is hit at its entry.
    The walk carries that sign from cell to cell; for the first cell of a
    segment it is recomputed, so any start gives the same answers. A cell
    whose corners all lie on the other side of the isovalue from the value
    its predecessor's cubic ends with is hit at its entry too: the surface is
    then within that cubic's rounding of the face, and the cell's own values
    there, all of one sign, hold no root (samples near 1e18 put a cubic's
    rounding far above a value 1e-18 from the isovalue: without this rule the
    ray would miss that surface). Between two cells of one sign each, signs
    cannot differ. That hit needs the solved cell before it: a walk started
    inside the one-signed cell would not see it. No segment starts there:
    PARC's segments start in front of a possibly contributing supercell,
    and the cells before it are one-signed and unsolved in `brute`'s walk
    too.

    Where the ray enters or leaves the volume there is no neighbour to ask,
    and an isosurface lying on the volume's own face (the isovalue is the
    data's min or max, taken all over the face) was found only where the
    cubic happened to round onto it. So a face whose four corners are all at
    the isovalue is hit where the ray enters through it (``t_in``), or
    leaves through it with no root before (``t_out``), by the walk's own
    crossing times (`on_level_face`). The volume is closed: a ray that only
    grazes such a face's edge or corner (``t_in == t_out``) hits it there, once.

    ``skip``/``jump_min``: the skip table and the smallest radius worth a
    jump (module docstring), or `NO_SKIP` and -1. ``cells`` counts the
    cells the walk looked at, not those a jump passed over.
    """
    # Walked from the ray's entry into the volume, not from the eye: local
    # coordinates like (O - i) + t D cancel terms as large as |O|, and with
    # an eye far away (a parallel view from 3e8 units) their rounding,
    # times a steep field, outgrew the margins of the sub-cell ranges PARC
    # classifies by, and the two methods found different hits. Both anchor
    # at the same point, so both still solve the same cubics.
    nz, ny, nx = grid_shape(data)
    ta, Ox, Oy, Oz = entry_anchor(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz)
    t, i, j, k, u, v, w, cells, solves = _walk_iso(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, seg0 - ta, seg1 - ta,
                                                   ray_table(skip, Dx, Dy, Dz), jump_min, ta > 0.0)
    return ta + t, i, j, k, u, v, w, cells, solves


@kernel
def _walk_iso(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, seg0, seg1, skip, jump_min, anchored):
    """`cast_iso_ray` on a ray already anchored near the volume (its ``t`` measured from there;
    ``anchored``: moved to its entry into the volume, `entry_anchor`)."""
    nz, ny, nx = grid_shape(data)
    t_in, t_out = clip_box(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz)
    t_start = max(t_in, seg0)
    t_end = min(t_out, seg1)
    if not t_start <= t_end:
        return math.inf, -1, -1, -1, 0.0, 0.0, 0.0, 0, 0
    i, j, k, sx, sy, sz, ix, iy, iz, tx0, tx1, ty0, ty1, tz0, tz1 = walk_from(Ox, Oy, Oz, Dx, Dy, Dz, t_start,
                                                                             nx, ny, nz)
    # Sign at the end of the previous cell (0: none). The walk's previous
    # cell is the neighbour across the face of the latest entry time (ties:
    # the last axis, as `step_axis` steps x, then y, then z).
    prev = 0.0
    # Whether prev is the previous cell's cubic, rounded at its exit, rather than its sign.
    rounded = False
    first = True
    cells = 0
    solves = 0
    while True:
        cells += 1
        c0 = max(t_in, max(tx0, max(ty0, tz0)))
        c1 = min(t_out, min(tx1, min(ty1, tz1)))
        sign = 0
        if jump_min >= 0:
            entry = cell_entry(skip, i, j, k)
            sign = _cell_sign(entry)
            if rounded and prev * sign < 0.0:
                return _signed_entry(Ox, Oy, Oz, Dx, Dy, Dz, i, j, k, c0, cells, solves)
            r = abs(entry) - 1
            if r >= jump_min:
                tb = cube_exit(Ox, Oy, Oz, sx, sy, sz, ix, iy, iz, i, j, k, r)
                if tb >= t_end:
                    break
                # A cube exit at or before the cell's own (rounding at a
                # corner of the cube) is no jump: the cell is stepped.
                if tb > c1:
                    i, tx0, tx1 = advance(Ox, ix, sx, i, tx0, tx1, tb)
                    j, ty0, ty1 = advance(Oy, iy, sy, j, ty0, ty1, tb)
                    k, tz0, tz1 = advance(Oz, iz, sz, k, tz0, tz1, tb)
                    c0 = max(t_in, max(tx0, max(ty0, tz0)))
                    c1 = min(t_out, min(tx1, min(ty1, tz1)))
                    first = False
                    prev = float(sign)
                    rounded = False
                    # The landing cell is the cube's last cell on the ray,
                    # never past it: `advance` stops in the cell it leaves
                    # at or after tb, the cube's exit. The step below leaves it.
                    sign = _cell_sign(cell_entry(skip, i, j, k))
        if sign != 0:
            prev = float(sign)
            rounded = False
        else:
            v000, v100, v010, v110, v001, v101, v011, v111, lo, hi = corners(data, iso, i, j, k)
            if lo > 0.0:
                if rounded and prev < 0.0:
                    return _signed_entry(Ox, Oy, Oz, Dx, Dy, Dz, i, j, k, c0, cells, solves)
                prev = 1.0
                rounded = False
            elif hi < 0.0:
                if rounded and prev > 0.0:
                    return _signed_entry(Ox, Oy, Oz, Dx, Dy, Dz, i, j, k, c0, cells, solves)
                prev = -1.0
                rounded = False
            else:
                if first and c0 > t_in:
                    # Only a possibly contributing start cell needs the sign its
                    # predecessor ends with; most PARC segments start in empty cells.
                    prev = _entry_sign(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, i, j, k, sx, sy, sz,
                                       tx0, ty0, tz0, tx1, ty1, tz1, c0, t_in, t_out, skip, jump_min)
                if c0 <= c1:
                    solves += 1
                    A, B, C, D, u0, v0, w0 = cell_cubic(v000, v100, v010, v110, v001, v101, v011, v111,
                                                        Ox, Oy, Oz, Dx, Dy, Dz, i, j, k, c0)
                    if c0 > t_in:
                        if prev != 0.0 and D != 0.0 and (D < 0.0) != (prev < 0.0):
                            return c0, i, j, k, u0, v0, w0, cells, solves
                    elif on_level_face(v000, v100, v010, v110, v001, v101, v011, v111, tx0, ty0, tz0,
                                       entry_face_time(tx0, ty0, tz0, c0, anchored), sx, sy, sz, False):
                        return c0, i, j, k, u0, v0, w0, cells, solves
                    L = c1 - c0
                    s = first_root(A, B, C, D, L)
                    if s >= 0.0:
                        return (c0 + s, i, j, k, u0 + s * Dx, v0 + s * Dy, w0 + s * Dz,
                                cells, solves)
                    if c1 == t_out and on_level_face(v000, v100, v010, v110, v001, v101, v011, v111,
                                                     tx1, ty1, tz1, c1, sx, sy, sz, True):
                        return c1, i, j, k, u0 + L * Dx, v0 + L * Dy, w0 + L * Dz, cells, solves
                    f = eval_cubic(A, B, C, D, L)
                    prev = 1.0 if f > 0.0 else (-1.0 if f < 0.0 else 0.0)
                    rounded = True
        first = False
        if c1 >= t_end:
            break
        inside, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1 = step_cell(Ox, Oy, Oz, sx, sy, sz, ix, iy, iz, i, j, k,
                                                                  tx0, tx1, ty0, ty1, tz0, tz1, nx, ny, nz)
        if not inside:
            break
    return math.inf, -1, -1, -1, 0.0, 0.0, 0.0, cells, solves


@kernel
def _signed_entry(Ox, Oy, Oz, Dx, Dy, Dz, i, j, k, c0, cells, solves):
    """`_walk_iso`'s hit at the entry ``c0`` of cell ``(i, j, k)``, all of whose corners lie on
    the side of the isovalue opposite to the sign the walk carries in."""
    return c0, i, j, k, (Ox - i) + c0 * Dx, (Oy - j) + c0 * Dy, (Oz - k) + c0 * Dz, cells, solves


@kernel
def _store(n, res, t, cell, uvw, counts):
    t[n] = res[0]
    cell[n, 0] = res[1]
    cell[n, 1] = res[2]
    cell[n, 2] = res[3]
    uvw[n, 0] = res[4]
    uvw[n, 1] = res[5]
    uvw[n, 2] = res[6]
    counts[n, 0] = res[7]
    counts[n, 1] = res[8]


@kernel(parallel=True)
def cast_iso_image(data, org, spc, cam, width, height, iso, seg, use_seg, skip, jump_min,
                   t, cell, uvw, counts, row0, row1, shade, color, material, image):
    """Cast every pixel of a ``width x height`` image, tile by tile.

    Outputs are flat per pixel (index ``y * width + x``): ``t``, ``cell``
    (i, j, k), ``uvw`` (local hit coordinates), ``counts`` (cells, solves).
    With ``use_seg``, ``seg[y, x] = (near, far)`` bounds each ray and a
    pixel with ``near > far`` costs nothing. ``skip``/``jump_min``: the
    skip table, or `NO_SKIP` and -1 (see `cast_iso_ray`). Only rows ``row0 <= y < row1``
    are cast, so a driver can report progress band by band.

    Returns ``(hits, cells, solves)`` over the rows cast: summing them
    afterwards, from ``counts`` and ``t``, read 6 MB again (0.4 ms of a
    9 ms 512x512 PARC frame).

    With ``shade``, each hit is also coloured into ``image`` (``(height,
    width, 4)`` float32, left as it is at misses), lit from the eye with
    ``color`` and ``material`` (`raycast.shade.headlight_pixel`), while its
    cell's corners are still in cache: a separate pass over the hits
    (`raycast.shade.shade_headlight`, the same colours) read them again
    from memory, 1 ms of a 17 ms CT head frame.
    """
    tiles = tile_count(width, row0, row1, TILE_W, TILE_H)
    hits = 0
    cells = 0
    solves = 0
    for it in prange(tiles):
        x0, x1, y0, y1 = dealt_tile(it, tiles, width, row0, row1)
        for y in range(y0, y1):
            for x in range(x0, x1):
                n = y * width + x
                s0 = -math.inf
                s1 = math.inf
                if use_seg:
                    s0 = seg[y, x, 0]
                    s1 = seg[y, x, 1]
                    if not s0 <= s1:
                        t[n] = math.inf
                        cell[n, 0] = -1
                        counts[n, 0] = 0
                        counts[n, 1] = 0
                        continue
                ox, oy, oz, dx, dy, dz = camera_ray(cam, width, height, x, y)
                Ox, Oy, Oz, Dx, Dy, Dz = to_index_space(ox, oy, oz, dx, dy, dz, org, spc)
                res = cast_iso_ray(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, s0, s1, skip, jump_min)
                _store(n, res, t, cell, uvw, counts)
                cells += res[7]
                solves += res[8]
                if res[0] < math.inf:
                    hits += 1
                    if shade:
                        headlight_pixel(data, spc, res[1], res[2], res[3], res[4], res[5], res[6],
                                        dx, dy, dz, color, material, image, y, x)
    return hits, cells, solves


@kernel(parallel=True)
def cast_iso_rays(data, org, spc, origins, dirs, iso, seg, use_seg, skip, jump_min, t, cell, uvw, counts):
    """Cast arbitrary world rays ``origins[n] + t dirs[n]`` (``|dirs[n]| = 1``)."""
    rays = origins.shape[0]
    runs = spread_runs(rays)
    for it in prange(runs):
        lo, hi = spread_run(it, runs, rays)
        for n in range(lo, hi):
            s0 = -math.inf
            s1 = math.inf
            if use_seg:
                s0 = seg[n, 0]
                s1 = seg[n, 1]
            Ox, Oy, Oz, Dx, Dy, Dz = to_index_space(
                origins[n, 0], origins[n, 1], origins[n, 2], dirs[n, 0], dirs[n, 1], dirs[n, 2], org, spc)
            res = cast_iso_ray(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, s0, s1, skip, jump_min)
            _store(n, res, t, cell, uvw, counts)


@kernel(parallel=True)
def keep_nearest(t, cell, uvw, n, depth, near_cell, near_uvw, winner):
    """Merge one surface's hits (``t``, ``cell``, ``uvw``) into the nearest so far, in place:
    where ``t`` is closer than ``depth``, take its hit and set ``winner`` to ``n``.

    One pass; NumPy's masked copies took 6 ms a frame at 300x300.
    """
    for m in prange(t.shape[0]):
        if t[m] < depth[m]:
            depth[m] = t[m]
            winner[m] = n
            for a in range(3):
                near_cell[m, a] = cell[m, a]
                near_uvw[m, a] = uvw[m, a]


def empty_outputs(n):
    """Per-ray output arrays for `n` rays, uninitialized: the drivers write every ray's ``t``,
    ``cell[:, 0]`` and ``counts``, and the rest wherever ``t`` is finite."""
    return np.empty(n), np.empty((n, 3), np.int32), np.empty((n, 3)), np.empty((n, 2), np.int64)
