"""Shadow rays and lighting of isosurface hits and of translucent samples.

A shadow ray leaves a hit point ``P`` (or a shaded translucent sample's
point, `raycast.merged`'s record) towards a light: towards a point
light's position (its length is the distance ``D``), or against a
directional light's direction (unbounded). It starts ``eps`` along its
way (``P' = P + eps l``, ``t = 0`` there), so the surface it leaves is not
found again at ``t = 0``, with the same rounding for every method, and
ends ``eps`` short of a point light, so a surface the light stands on
does not hide it (as rounding would decide, ray by ray). Along
it, each volume of the scene either blocks the light (an isosurface with
a root on the ray: `cast_iso_ray`, the primary rays' walk) or lets
through ``1 - a``, where ``a`` is the opacity the volume's accumulation
mode gives the ray (`accumulate_ray`, the primary rays' sampling, on a
lattice anchored where the shadow ray enters the volume).

With PARC, each (light, volume) pair has light buffers: near/far
distances from the light over every ray through each buffer pixel
(`parc.lights`). `light_segment` merges the four pixels around the
shadow ray's crossing of each view, and the shadow ray walks only
``[D - far, D - near]`` (point light) or ``[s_P - far, s_P - near]``
(directional; ``s_P`` the point's distance from the view plane).

Lights are rows ``[kind, x, y, z, r, g, b]`` (`parc.lights.light_array`;
the layout is `raycast.shade`'s, where every lit kernel reads it); views
rows of `N_VIEW` values (`parc.lights.view_array`), defined here.
"""
import math

import numpy as np
from numba import prange

from .composite import accumulate_ray
from .config import kernel
from .iso import cast_iso_ray
from .rays import camera_ray, spread_run, spread_runs
from .shade import KIND_HEADLIGHT, KIND_POINT, blinn_phong, to_light, trilinear_gradient, unit_normal
from .traverse import to_index_space

#: Layout of a light buffer's view row.
V_KIND = 0          # 0 perspective, 1 parallel
V_EYE = 1           # 3 values
V_FWD = 4
V_RIGHT = 7
V_UP = 10
V_SCALE = 13        # tan(fov / 2), or the parallel scale
N_VIEW = 14
#: Relative widening of the light buffers' segments: their float32 bounds
#: are already rounded outwards; this covers the float64 ``D - s``.
SEGMENT_SLACK = 4e-7


@kernel(inline="always")
def light_segment(views, near, far, px, py, pz):
    """``(lo, hi)``: the light buffers' bounds for the light's rays through ``P``.

    Over every view whose image holds ``P``'s direction (point light) or
    position (directional), the smallest near and largest far of the four
    pixels around the crossing. ``lo > hi`` when no possibly contributing
    supercell lies on those rays.
    """
    lo = math.inf
    hi = -math.inf
    n = near.shape[1]
    for v in range(views.shape[0]):
        qx = px - views[v, V_EYE]
        qy = py - views[v, V_EYE + 1]
        qz = pz - views[v, V_EYE + 2]
        qf = qx * views[v, V_FWD] + qy * views[v, V_FWD + 1] + qz * views[v, V_FWD + 2]
        qr = qx * views[v, V_RIGHT] + qy * views[v, V_RIGHT + 1] + qz * views[v, V_RIGHT + 2]
        qu = qx * views[v, V_UP] + qy * views[v, V_UP + 1] + qz * views[v, V_UP + 2]
        if views[v, V_KIND] == 0.0:
            if not qf > 0.0:
                continue
            sx = qr / (qf * views[v, V_SCALE])
            sy = qu / (qf * views[v, V_SCALE])
        else:
            sx = qr / views[v, V_SCALE]
            sy = qu / views[v, V_SCALE]
        if not (abs(sx) <= 1.0 + 1e-7 and abs(sy) <= 1.0 + 1e-7):
            continue
        x = (sx + 1.0) * 0.5 * n - 0.5
        y = (1.0 - sy) * 0.5 * n - 0.5
        x0 = int(math.floor(x))
        y0 = int(math.floor(y))
        for yy in range(y0, y0 + 2):
            yc = min(max(yy, 0), n - 1)
            for xx in range(x0, x0 + 2):
                xc = min(max(xx, 0), n - 1)
                lo = min(lo, near[v, yc, xc])
                hi = max(hi, far[v, yc, xc])
    return lo, hi


@kernel(inline="always")
def shadow_span(light, views, near, far, use_seg, px, py, pz, eps, dist):
    """The shadow ray's ``[s0, s1]`` (from ``P' = P + eps l``), ``s0 > s1`` if it meets nothing."""
    s0 = 0.0
    s1 = dist - 2.0 * eps       # P' is eps along; the ray stops eps short of the light
    if not use_seg:
        return s0, s1
    lo, hi = light_segment(views, near, far, px, py, pz)
    if not lo <= hi:
        return 1.0, 0.0
    if light[0] == KIND_POINT:
        ref = dist
    else:
        # Distance of P from the view plane, along the light's direction.
        ref = ((px - views[0, V_EYE]) * views[0, V_FWD] + (py - views[0, V_EYE + 1]) * views[0, V_FWD + 1]
               + (pz - views[0, V_EYE + 2]) * views[0, V_FWD + 2])
    a = ref - hi - eps
    b = ref - lo - eps
    m = SEGMENT_SLACK * (abs(ref) + abs(hi) + abs(lo)) + 4.0 * eps
    return max(s0, a - m), min(s1, b + m)


@kernel(inline="always")
def shadow_ray(points, n, light, eps, views, near, far, use_seg, org, spc, lead):
    """Shadow ray of ``points[n]`` in a volume's index space, and the span it walks.

    Returns ``(s0, s1, Ox, Oy, Oz, Dx, Dy, Dz, lx, ly, lz, dist)``: the span,
    the index-space ray ``O + s D``, the world unit direction ``l`` to the
    light and its distance; ``s0 > s1`` when nothing needs walking (the
    point at the light, or no PC supercell on the way; ``O`` and ``D`` are
    then zero). The ray starts ``lead`` further along than ``P'``, and its
    span counts from there.
    """
    px, py, pz = points[n, 0], points[n, 1], points[n, 2]
    lx, ly, lz, dist = to_light(light, px, py, pz)
    s0, s1 = 1.0, 0.0
    if dist > eps:
        s0, s1 = shadow_span(light, views, near, far, use_seg, px, py, pz, eps, dist)
        s0, s1 = max(s0 - lead, 0.0), s1 - lead
    if not s0 <= s1:
        # Most of PARC's shadow rays end here (no PC supercell on the way):
        # spare them the division into index space.
        return s0, s1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, lx, ly, lz, dist
    e = eps + lead
    Ox, Oy, Oz, Dx, Dy, Dz = to_index_space(px + e * lx, py + e * ly, pz + e * lz, lx, ly, lz, org, spc)
    return s0, s1, Ox, Oy, Oz, Dx, Dy, Dz, lx, ly, lz, dist


@kernel(parallel=True)
def shadow_iso(data, org, spc, iso, points, light, eps, views, near, far, use_seg, skip, jump_min, vis, counts):
    """Zero ``vis[n]`` where the isosurface blocks the shadow ray of ``points[n]``.

    ``skip``/``jump_min``: the skip table (`raycast.iso`), or `raycast.iso.NO_SKIP` and -1.
    Rays whose ``vis`` is already 0 are skipped. ``counts[n]`` gains the
    cells visited and cubics solved.
    """
    rays = points.shape[0]
    runs = spread_runs(rays)
    for it in prange(runs):
        lo, hi = spread_run(it, runs, rays)
        for n in range(lo, hi):
            if vis[n] == 0.0:
                continue
            s0, s1, Ox, Oy, Oz, Dx, Dy, Dz, lx, ly, lz, dist = shadow_ray(points, n, light, eps, views, near,
                                                                           far, use_seg, org, spc, 0.0)
            if not s0 <= s1:
                continue
            res = cast_iso_ray(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, s0, s1, skip, jump_min)
            counts[n, 0] += res[7]
            counts[n, 1] += res[8]
            if res[0] <= s1 and res[0] < math.inf:
                vis[n] = 0.0


@kernel(parallel=True)
def shadow_accumulate(data, org, spc, params, op_x, op_y, col_x, col_rgb, points, light, eps,
                      views, near, far, use_seg, skip, jump_min, vis, counts, lead):
    """Scale ``vis[n]`` by the light a translucent volume lets through along the shadow ray.

    ``1 - a`` with ``a`` the opacity the volume's mode accumulates over the
    ray from ``lead`` beyond ``P'`` to the light (`accumulate_ray`;
    ``skip``/``jump_min`` as there): ``lead`` is the volume's step for a
    sample of this volume, whose ray, starting inside it, takes its lattice
    from its start: without the lead its first point lies next to the
    sample itself, which then shadowed itself (an opaque sample was lit by
    the ambient term alone); 0 for a surface's hit or another volume's sample.
    ``counts[n, 2]`` gains the samples taken.
    """
    nobits = np.zeros((1, 1, 1), np.uint32)
    rays = points.shape[0]
    runs = spread_runs(rays)
    for it in prange(runs):
        lo, hi = spread_run(it, runs, rays)
        for n in range(lo, hi):
            if vis[n] == 0.0:
                continue
            s0, s1, Ox, Oy, Oz, Dx, Dy, Dz, lx, ly, lz, dist = shadow_ray(points, n, light, eps, views, near,
                                                                           far, use_seg, org, spc, lead)
            if not s0 <= s1:
                continue
            r, g, b, a, samples = accumulate_ray(data, spc, Ox, Oy, Oz, Dx, Dy, Dz, lx, ly, lz, s0, s1,
                                                 dist - 2.0 * eps - lead, params, op_x, op_y, col_x, col_rgb,
                                                 nobits, 0, 0, skip, jump_min)
            counts[n, 2] += samples
            vis[n] *= 1.0 - a


@kernel(parallel=True)
def surface_frames(data, org, spc, cam, width, height, pix, cell, uvw, points, normals, views):
    """Hit point, unit normal and unit direction to the eye of each hit pixel ``pix[m]``.

    The point is its cell's corner plus its place in the cell, as a
    translucent sample's is (`raycast.merged`), not ``eye + t d``: from a
    far eye that sum rounds off more than a shadow ray's ``eps`` lifts it,
    and the surface shadowed itself.
    A flat cell (all corners at the isovalue) has no gradient: its normal
    faces the viewer.
    """
    for m in prange(pix.shape[0]):
        n = pix[m]
        y = n // width
        x = n - y * width
        dx, dy, dz = camera_ray(cam, width, height, x, y)[3:]
        points[m, 0] = org[0] + spc[0] * (cell[n, 0] + uvw[n, 0])
        points[m, 1] = org[1] + spc[1] * (cell[n, 1] + uvw[n, 1])
        points[m, 2] = org[2] + spc[2] * (cell[n, 2] + uvw[n, 2])
        gx, gy, gz = trilinear_gradient(data, cell[n, 0], cell[n, 1], cell[n, 2],
                                        uvw[n, 0], uvw[n, 1], uvw[n, 2], spc)
        gx, gy, gz = unit_normal(gx, gy, gz, dx, dy, dz)
        normals[m, 0] = gx
        normals[m, 1] = gy
        normals[m, 2] = gz
        views[m, 0] = -dx
        views[m, 1] = -dy
        views[m, 2] = -dz


@kernel(parallel=True)
def light_terms(points, normals, views, materials, lights, diffuse, specular):
    """Unshadowed Blinn-Phong terms of every hit for every light: ``diffuse[l, m]``, ``specular[l, m]``.

    A row of kind `KIND_HEADLIGHT` is a light at the eye, as for one volume
    without lights (`raycast.shade.headlight_pixel`).

    A light on the far side of the surface (as seen from the eye) gives
    zero: it needs no shadow ray.
    """
    for m in prange(points.shape[0]):
        for k in range(lights.shape[0]):
            if lights[k, 0] == KIND_HEADLIGHT:
                lx, ly, lz, dist = views[m, 0], views[m, 1], views[m, 2], math.inf
            else:
                lx, ly, lz, dist = to_light(lights[k], points[m, 0], points[m, 1], points[m, 2])
            if dist == 0.0:
                diffuse[k, m] = 0.0
                specular[k, m] = 0.0
                continue
            d, s = blinn_phong(normals[m, 0], normals[m, 1], normals[m, 2],
                               views[m, 0], views[m, 1], views[m, 2], lx, ly, lz, materials[m])
            diffuse[k, m] = d
            specular[k, m] = s


@kernel(inline="always")
def lit_channel(colors, materials, lights, diffuse, specular, vis, m, c):
    """Channel ``c`` of point ``m`` lit: ``colour (ambient + sum_l vis d_l c_l) + sum_l vis s_l c_l``,
    clamped to 1."""
    acc = colors[m, c] * materials[m, 0]
    for k in range(lights.shape[0]):
        w = vis[k, m] * lights[k, 4 + c]
        acc += w * (colors[m, c] * diffuse[k, m] + specular[k, m])
    return min(1.0, acc)


@kernel(parallel=True)
def combine_lights(colors, materials, lights, diffuse, specular, vis, pix, image):
    """Colour each hit pixel ``pix[m]`` of the flat ``(H*W, 4)`` float32 ``image``, opaque (`lit_channel`)."""
    for m in prange(colors.shape[0]):
        n = pix[m]
        for c in range(3):
            image[n, c] = lit_channel(colors, materials, lights, diffuse, specular, vis, m, c)
        image[n, 3] = 1.0


@kernel(parallel=True)
def combine_samples(slots, counts, colors, weights, materials, lights, diffuse, specular, vis, p0, p1, image):
    """Add to pixels ``p0 <= n < p1`` of the flat ``(H*W, 4)`` float32 ``image`` their recorded samples
    (`raycast.merged.SampleRecord`), each lit as a hit is (`lit_channel`, clamped to 1 as a shaded
    sample is in `raycast.composite.composite_sample`), times its weight; the pixel clamped to 1."""
    for n in prange(p0, p1):
        first = slots[n]
        for c in range(3):
            add = 0.0
            for m in range(first, first + counts[n]):
                add += weights[m] * lit_channel(colors, materials, lights, diffuse, specular, vis, m, c)
            image[n, c] = min(1.0, image[n, c] + add)
