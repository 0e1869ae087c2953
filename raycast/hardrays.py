"""Ray generators of the hard-ray suite (`raycast.hardcases`): world rays aimed at the hard cases.

Axis-aligned and near-axis rays, rays hugging grid planes, rays through
vertices, edges and faces, rays tangent to the surface (grazing and
near-double roots), from eyes outside the volume or inside it; each a
``(origins, unit directions)`` pair for a `raycast.hardfields.Scene`, seeded.
"""
import math
from fractions import Fraction

import numpy as np

from .hardfields import field_grad

# ------------------------------------------------------------ ray helpers

def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def random_dirs(rng, n):
    return unit(rng.normal(size=(n, 3)))


def box_points(rng, scene, n, lo=0.0, hi=1.0):
    """Uniform world points in the sample box scaled to fractions [lo, hi] per axis."""
    a, b = scene.lo_world, scene.hi_world
    return a + (b - a) * rng.uniform(lo, hi, (n, 3))


def eyes_outside(rng, scene, n, margin=0.6):
    a, b = scene.lo_world, scene.hi_world
    out = []
    while len(out) < n:
        p = a + (b - a) * rng.uniform(-margin, 1 + margin, 3)
        if np.any(p < a) or np.any(p > b):
            out.append(p)
    return np.array(out).reshape(n, 3)


def perspective_rays(rng, scene, n, inside=False):
    """Eyes outside (or inside) the box, aimed at random points in it."""
    eyes = box_points(rng, scene, n) if inside else eyes_outside(rng, scene, n)
    if inside:
        return eyes, random_dirs(rng, n)
    return eyes, unit(box_points(rng, scene, n) - eyes)


def parallel_rays(rng, scene, n):
    """One random direction; origins on a grid in a plane behind the box."""
    d = random_dirs(rng, 1)[0]
    a, b = scene.lo_world, scene.hi_world
    c, r = 0.5 * (a + b), 0.5 * np.linalg.norm(b - a)
    e1 = unit(np.cross(d, [0.3, 0.5, 0.8]))
    e2 = np.cross(d, e1)
    m = int(math.ceil(math.sqrt(n)))
    u, v = np.meshgrid(np.linspace(-r, r, m), np.linspace(-r, r, m))
    o = c - 1.5 * r * d + u.reshape(-1, 1)[:n] * e1 + v.reshape(-1, 1)[:n] * e2
    return o, np.repeat(d[None], n, axis=0)


def lattice_coord(rng, n_cells, kind):
    """An index coordinate: random, integer (grid plane), half-integer, or just off a plane."""
    if kind == "random":
        return rng.uniform(0, n_cells)
    m = int(rng.integers(0, n_cells + 1))
    if kind == "plane":
        return float(m)
    if kind == "half":
        return m + 0.5 if m < n_cells else m - 0.5
    # a few ulps (or 1e-12) to either side of a plane
    off = float(rng.choice([2.0 ** -50, 2.0 ** -45, 1e-12, 1e-9]))
    return float(np.clip(m + rng.choice([-1, 1]) * off * max(1, m), 0, n_cells))


def axis_rays(rng, scene, n, kinds=("random", "plane", "half", "near")):
    """Rays with d = +-e_a exactly; transverse coordinates random or on/near grid planes."""
    nz, ny, nx = scene.shape
    cells = (nx - 1, ny - 1, nz - 1)
    o, d = np.zeros((n, 3)), np.zeros((n, 3))
    for m in range(n):
        a = m % 3
        sign = 1.0 if rng.random() < 0.5 else -1.0
        idx = np.zeros(3)
        for b in range(3):
            if b != a:
                idx[b] = lattice_coord(rng, cells[b], kinds[rng.integers(len(kinds))])
        # along the axis: start outside (before the box) or inside
        start = rng.uniform(-3, 0) if rng.random() < 0.6 else rng.uniform(0, cells[a])
        idx[a] = start if sign > 0 else cells[a] - start
        o[m] = scene.index_to_world(idx)
        d[m, a] = sign
    return o, d


def near_axis_rays(rng, scene, n, eps_list=(1e-2, 1e-5, 1e-8, 1e-11, 1e-14, 1e-16, 1e-17,
                                             1e-20, 1e-30, 1e-100, 1e-199, 1e-250)):
    """Nearly axis-aligned rays: d = +-e_a + tiny components (A ~ 0, huge 1/D)."""
    o, d = axis_rays(rng, scene, n, kinds=("random", "plane", "near", "near"))
    for m in range(n):
        a = int(np.argmax(np.abs(d[m])))
        for b in range(3):
            if b != a and rng.random() < 0.8:
                tiny = eps_list[rng.integers(len(eps_list))]
                d[m, b] = rng.choice([-1, 1]) * tiny * rng.uniform(0.5, 2)
        d[m] = unit(d[m])
    return o, d


def world_coord_for_index(scene, axis, target):
    """A world coordinate whose index coordinate as the caster computes it,
    ``(x - origin) / spacing`` in float64, is ``target`` (or the closest below)."""
    org, spc = scene.origin[axis], scene.spacing[axis]
    x = org + target * spc
    f = (x - org) / spc
    step = math.inf if f < target else -math.inf
    for _ in range(10000):
        if f == target:
            return x
        y = np.nextafter(x, step)
        g = (y - org) / spc
        if (g > target) != (f > target) and g != target:
            return x if f < target else y          # crossed over: keep the one below
        x, f = y, g
    return x


def plane_hugging_rays(rng, scene, n):
    """Rays nearly parallel to a grid plane, an ulp or two from it where they enter.

    In index space (the caster's own rounded numbers): the ray enters the box
    through a face of axis ``a`` at ``t_in``, with ``O_b = m - k ulp`` just
    below the plane ``m`` of axis ``b`` and ``D_b = kappa ulp / t_in``,
    ``k - 1/2 < kappa < k``: the exact entry point is still below the plane
    (and stays below it until ``t = t_in k / kappa``, far along the ray), but
    ``O_b + t_in D_b`` rounds onto it. A start cell chosen by ``floor``
    alone lies above the plane and skips that whole stretch. A third of the
    rays take random sides, offsets and slopes instead.
    """
    nz, ny, nx = scene.shape
    cells = (nx - 1, ny - 1, nz - 1)
    o, d = np.zeros((n, 3)), np.zeros((n, 3))
    for q in range(n):
        a = int(rng.integers(3))
        b = (a + 1 + int(rng.integers(2))) % 3
        c = 3 - a - b
        T = rng.uniform(0.5, max(1.0, 0.6 * cells[a]))
        idx, dd = np.zeros(3), np.zeros(3)
        dd[a] = 1.0 if rng.random() < 0.5 else -1.0
        idx[a] = -T if dd[a] > 0 else cells[a] + T
        idx[c] = rng.uniform(0, cells[c])
        dd[c] = rng.choice([0.0, rng.uniform(-0.5, 0.5)])
        targeted = rng.random() < 2 / 3 and cells[b] >= 2
        if targeted:
            m = float(rng.integers(1, cells[b]))
            k = int(rng.integers(1, 3))
            ob = m - k * (m - np.nextafter(m, -math.inf))
        else:
            m = float(rng.integers(0, cells[b] + 1))
            ob = m + rng.choice([-1, 1]) * int(rng.integers(0, 6)) * math.ulp(max(m, 1.0))
        w = scene.index_to_world(idx)
        w[b] = world_coord_for_index(scene, b, ob)
        dw = unit(dd * scene.spacing)
        O = (w - scene.origin) / scene.spacing          # as the caster computes them
        D = dw / scene.spacing
        t_in = (0.0 - O[a]) / D[a] if D[a] > 0 else (cells[a] - O[a]) / D[a]
        ulp_b = O[b] - np.nextafter(O[b], -math.inf) if O[b] > 0 else math.ulp(1.0)
        if targeted:
            kb = round((m - O[b]) / ulp_b)
            slope = (kb - rng.uniform(0.05, 0.45)) * ulp_b / t_in
        else:
            slope = rng.choice([-1, 1]) * rng.uniform(0.2, 4.0) * ulp_b / t_in \
                * rng.choice([1.0, 1.0, 1e-3, 1e3])
        dw[b] = slope * scene.spacing[b]
        o[q], d[q] = w, dw
    return o, d


def aimed_rays(rng, scene, p_world, n, outside=True, dist=(0.5, 40.0)):
    """Rays from random eyes aimed at the world point ``p_world``."""
    if outside:
        eyes = eyes_outside(rng, scene, n)
    else:
        eyes = p_world - random_dirs(rng, n) * rng.uniform(*dist, (n, 1))
    return eyes, unit(p_world - eyes)


def dyadic_point(rng, scene, fixed=(), den=16, interior=0.85):
    """An index point with coordinates multiples of 1/den; axes in ``fixed`` integer.

    Integer coordinates avoid the box faces with probability ``interior``
    (a root on the box boundary may legitimately be hit or missed).
    """
    nz, ny, nx = scene.shape
    cells = (nx - 1, ny - 1, nz - 1)
    p = []
    for a in range(3):
        if a in fixed:
            inset = 1 if cells[a] >= 2 and rng.random() < interior else 0
            p.append(Fraction(int(rng.integers(inset, cells[a] - inset + 1))))
        else:
            p.append(Fraction(int(rng.integers(0, cells[a] * den + 1)), den))
    return p


def world_gradient(scene, p):
    g = np.array([float(x) for x in field_grad(scene.coeffs, *[float(x) for x in p])])
    return g / scene.spacing


def tangent_rays(rng, scene, p, n, offsets=(0.0,), dist=(0.5, 40.0)):
    """Rays tangent to the level set through index point p (double roots), optionally
    shifted by ``offset * h`` along the gradient (near-double roots or near misses)."""
    pw = scene.index_to_world([float(x) for x in p])
    g = world_gradient(scene, p)
    gn = np.linalg.norm(g)
    if gn == 0:
        return None
    g = g / gn
    u = unit(np.cross(g, random_dirs(rng, 1)[0]))
    v = np.cross(g, u)
    h = float(min(scene.spacing))
    o, d = [], []
    for m in range(n):
        th = rng.uniform(0, 2 * math.pi)
        dm = unit(math.cos(th) * u + math.sin(th) * v)
        off = offsets[m % len(offsets)]
        o.append(pw - rng.uniform(*dist) * dm + off * h * g)
        d.append(dm)
    return np.array(o), np.array(d)


def vertex_world(rng, scene, n):
    nz, ny, nx = scene.shape
    idx = np.stack([rng.integers(0, nx, n), rng.integers(0, ny, n), rng.integers(0, nz, n)], 1)
    return scene.index_to_world(idx.astype(np.float64))


def in_plane_rays(rng, scene, n):
    """Rays lying in a grid plane (one direction component exactly 0, origin on the plane)."""
    nz, ny, nx = scene.shape
    cells = (nx - 1, ny - 1, nz - 1)
    o, d = np.zeros((n, 3)), np.zeros((n, 3))
    eyes, dirs = perspective_rays(rng, scene, n)
    for m in range(n):
        a = m % 3
        idx = (eyes[m] - scene.origin) / scene.spacing
        idx[a] = float(rng.integers(0, cells[a] + 1))
        o[m] = scene.index_to_world(idx)
        dm = dirs[m].copy()
        dm[a] = 0.0
        d[m] = unit(dm) if np.linalg.norm(dm) > 0 else np.eye(3)[(a + 1) % 3]
    return o, d


def diagonal_vertex_rays(rng, scene, n):
    """On a unit grid: d = (a, a, 0) or (a, a, a) with equal float components, through
    rows of vertices exactly (ties between crossing times on every step)."""
    nz, ny, nx = scene.shape
    o, d = np.zeros((n, 3)), np.zeros((n, 3))
    for m in range(n):
        three = m % 2 == 0
        a = 1 / math.sqrt(3) if three else 1 / math.sqrt(2)
        dm = np.array([a, a, a if three else 0.0]) * rng.choice([-1, 1], 3)
        v = np.array([rng.integers(0, nx), rng.integers(0, ny), rng.integers(0, nz)], float)
        s = float(rng.integers(1, 5))
        o[m] = v - s * np.sign(dm) * (np.abs(dm) > 0)     # a vertex s cells back on the diagonal
        if not three:
            o[m, 2] = v[2] if rng.random() < 0.5 else rng.uniform(0, nz - 1)
        d[m] = dm
    return o, d
