"""Shading: analytic trilinear gradient normals, two-sided Blinn-Phong, and the lights.

Lights are rows ``[kind, x, y, z, r, g, b]`` (`parc.lights.light_array`):
``x, y, z`` a point light's position or the direction a directional
light's rays travel in, ``r, g, b`` its colour times intensity.
"""
import math

from numba import prange

from .config import kernel
from .rays import camera_ray, spread_run, spread_runs
from .traverse import cell_corners

#: A light row's kind (its first value).
KIND_POINT = 0
KIND_DIRECTIONAL = 1
#: A light at the eye (the default with no lights): its direction is the view direction.
KIND_HEADLIGHT = 2


@kernel
def trilinear_gradient(data, i, j, k, u, v, w, spc):
    """World-space gradient of the trilinear interpolant of cell (i, j, k) at local (u, v, w).

    Parker et al. Appendix A: the derivative of each corner weight, divided
    by the cell's size along that axis.
    """
    v000, v100, v010, v110, v001, v101, v011, v111 = cell_corners(data, i, j, k)
    gu = ((1 - v) * (1 - w) * (v100 - v000) + v * (1 - w) * (v110 - v010)
          + (1 - v) * w * (v101 - v001) + v * w * (v111 - v011))
    gv = ((1 - u) * (1 - w) * (v010 - v000) + u * (1 - w) * (v110 - v100)
          + (1 - u) * w * (v011 - v001) + u * w * (v111 - v101))
    gw = ((1 - u) * (1 - v) * (v001 - v000) + u * (1 - v) * (v101 - v100)
          + (1 - u) * v * (v011 - v010) + u * v * (v111 - v110))
    return gu / spc[0], gv / spc[1], gw / spc[2]


@kernel
def unit_normal(gx, gy, gz, dx, dy, dz):
    """The gradient ``g`` made a unit vector; where it is zero (a flat cell, all corners at
    one value), ``-d``: facing the viewer along ``d``.

    Its squared length leaves float64 for gradients past 1e154 or below 1e-154 (float64
    samples of 1e160, or of 1e-200, both accepted): ``inf`` gave a zero normal, lit by
    the ambient term alone, and 0 a flat cell's. Those are scaled towards 1 by a power of
    two first (exactly: the normal of ``g`` times 2^k is ``g``'s, to the last bit, wherever
    both are scaled); others are computed as they always were.
    """
    g2 = gx * gx + gy * gy + gz * gz
    if not 1e-300 < g2 < 1e300:
        m = max(abs(gx), max(abs(gy), abs(gz)))
        if m == 0.0:
            return -dx, -dy, -dz
        e = -math.frexp(m)[1]
        gx, gy, gz = math.ldexp(gx, e), math.ldexp(gy, e), math.ldexp(gz, e)
        g2 = gx * gx + gy * gy + gz * gz
    gl = math.sqrt(g2)
    return gx / gl, gy / gl, gz / gl


@kernel(inline="always")
def to_light(light, px, py, pz):
    """Unit direction from ``P`` to the light and the distance (``inf`` for directional)."""
    if light[0] == KIND_POINT:
        lx = light[1] - px
        ly = light[2] - py
        lz = light[3] - pz
        d = math.sqrt(lx * lx + ly * ly + lz * lz)
        if d == 0.0:
            return 0.0, 0.0, 0.0, 0.0
        return lx / d, ly / d, lz / d, d
    return -light[1], -light[2], -light[3], math.inf


@kernel
def power(x, e):
    """``x ** e``; by repeated squaring for whole exponents up to 1024 (shininess
    is nearly always a whole number), where ``pow`` was half the shading time."""
    if 0.0 <= e <= 1024.0 and e == math.floor(e):
        n = int(e)
        r = 1.0
        while n > 0:
            if n & 1:
                r *= x
            x *= x
            n >>= 1
        return r
    return x ** e


@kernel
def blinn_phong(nx, ny, nz, vx, vy, vz, lx, ly, lz, material):
    """Scalar Blinn-Phong terms (diffuse, specular) for unit n, v (to eye), l (to light).

    Two-sided: the normal is flipped to face the viewer, so a surface seen
    from inside the object is lit like one seen from outside.
    ``material = [ambient, diffuse, specular, shininess]``.
    """
    if nx * vx + ny * vy + nz * vz < 0.0:
        nx, ny, nz = -nx, -ny, -nz
    ndl = nx * lx + ny * ly + nz * lz
    if ndl <= 0.0:
        return 0.0, 0.0
    hx, hy, hz = lx + vx, ly + vy, lz + vz
    hl = math.sqrt(hx * hx + hy * hy + hz * hz)
    spec = 0.0
    if hl > 0.0:
        ndh = (nx * hx + ny * hy + nz * hz) / hl
        if ndh > 0.0:
            spec = material[2] * power(ndh, material[3])
    return material[1] * ndl, spec


@kernel(inline="always")
def headlight_pixel(data, spc, i, j, k, u, v, w, dx, dy, dz, color, material, image, y, x):
    """Write the colour of a hit in cell ``(i, j, k)`` at local ``(u, v, w)``, seen along the
    world direction ``d`` and lit from the eye, into pixel ``(y, x)`` of ``image``."""
    gx, gy, gz = trilinear_gradient(data, i, j, k, u, v, w, spc)
    gx, gy, gz = unit_normal(gx, gy, gz, dx, dy, dz)
    diff, spec = blinn_phong(gx, gy, gz, -dx, -dy, -dz, -dx, -dy, -dz, material)
    for c in range(3):
        image[y, x, c] = min(1.0, color[c] * (material[0] + diff) + spec)
    image[y, x, 3] = 1.0


@kernel(parallel=True)
def shade_headlight(data, spc, cam, width, height, t, cell, uvw, color, material, image):
    """Colour every hit pixel, lit by a light at the eye (the default headlight).

    ``image`` is ``(height, width, 4)`` float32, premultiplied RGBA; misses
    stay transparent. The one-isosurface render shades each hit as it is
    found instead (`raycast.iso.cast_iso_image`); this pass shades hits
    cast apart (the Parker bench's) and times shading alone. Scenes of
    several surfaces shade through `surface_frames` and `light_terms`.
    """
    pixels = width * height
    runs = spread_runs(pixels)
    for it in prange(runs):
        lo, hi = spread_run(it, runs, pixels)
        for n in range(lo, hi):
            if not t[n] < math.inf:
                continue
            y = n // width
            x = n - y * width
            ox, oy, oz, dx, dy, dz = camera_ray(cam, width, height, x, y)
            headlight_pixel(data, spc, cell[n, 0], cell[n, 1], cell[n, 2], uvw[n, 0], uvw[n, 1], uvw[n, 2],
                            dx, dy, dz, color, material, image, y, x)
