"""The hard-ray suite: exact-trilinear scenes and rays aimed at the cubic's and the traversal's hard cases.

About this suite. An *exact-trilinear* field (index coordinates i, j, k)

    F(i, j, k) = c0 + c1 i + c2 j + c3 k + c4 ij + c5 jk + c6 ki + c7 ijk

is reproduced exactly by trilinear interpolation of its samples, so the
caster's isosurface is exactly ``{F = iso}``. With integer or dyadic
coefficients the samples are exact in float64 (and in uint16/int16 when they
fit), so the true first hit along a float64 ray is known to any precision
(`raycast.reference` computes it in mpmath and holds the acceptance rule).
This module only builds the inputs, with numpy and exact fractions: scenes
(`Scene`, `random_scene`), ray generators aimed at the hard cases (axis and
near-axis rays, grazing and near-double roots, roots on faces, edges and
vertices, isovalues equal to samples, 16-bit magnitudes, long grids, far
eyes), and a driver that runs the unaccelerated caster on them (`cast`).

Everything is seeded and deterministic. Rays are world rays
``(origin, unit direction, iso)``, grouped per scene and category in a
`Batch`; `hard_batches` gives one category of the suite (`CATEGORIES`).
Used by the correctness tests (``tests/raycast``) and the root-finder study
(`parc.rootstudy`). Not a kernel module: it lives beside the caster it
drives, and imports no mpmath.
"""
import math
from collections import Counter, defaultdict
from fractions import Fraction

import numba
import numpy as np

from .iso import NO_SKIP, cast_iso_rays, empty_outputs

# ----------------------------------------------------------------- fields

def field_value(c, i, j, k):
    """F(i, j, k) exactly for int/Fraction/float (dyadic) inputs."""
    return (c[0] + c[1] * i + c[2] * j + c[3] * k + c[4] * i * j + c[5] * j * k
            + c[6] * k * i + c[7] * i * j * k)


def field_grad(c, i, j, k):
    """Index-space gradient of F (same exact arithmetic as the inputs)."""
    return (c[1] + c[4] * j + c[6] * k + c[7] * j * k,
            c[2] + c[4] * i + c[5] * k + c[7] * i * k,
            c[3] + c[5] * j + c[6] * i + c[7] * i * j)


def field_range(c, shape):
    """(min, max) of F over the sample box; F is multilinear, so at its corners."""
    nz, ny, nx = shape
    vals = [Fraction(field_value([Fraction(x) for x in c], i, j, k))
            for i in (0, nx - 1) for j in (0, ny - 1) for k in (0, nz - 1)]
    return min(vals), max(vals)


def sample_field(c, shape, dtype):
    """Samples ``data[k, j, i] = F(i, j, k)``, checked to be exact in ``dtype``.

    Coefficients must be dyadic (k / 2^e): the samples times the common
    denominator are then integers, computed exactly in int64 and required to
    stay below 2^53 so that they are exact in float64.
    """
    cf = [Fraction(x) for x in c]
    den = 1
    for x in cf:
        den = max(den, x.denominator)
    if den & (den - 1) or any(den % x.denominator for x in cf):
        raise ValueError("coefficients must be dyadic")
    ci = [int(x * den) for x in cf]
    nz, ny, nx = shape
    mono = [1, nx, ny, nz, nx * ny, ny * nz, nz * nx, nx * ny * nz]
    if sum(abs(a) * m for a, m in zip(ci, mono)) >= 2 ** 53:
        raise ValueError("field too large to be exact in float64")
    k, j, i = np.meshgrid(np.arange(nz, dtype=np.int64), np.arange(ny, dtype=np.int64),
                          np.arange(nx, dtype=np.int64), indexing="ij")
    exact = field_value(ci, i, j, k)               # int64, exact (< 2^53)
    data = exact.astype(np.float64) / den          # exact: power-of-two divisor
    if np.dtype(dtype) != np.float64:
        info = np.iinfo(dtype)
        if data.min() < info.min or data.max() > info.max or np.any(data != np.round(data)):
            raise ValueError(f"field samples do not fit {np.dtype(dtype)}")
    return data.astype(dtype)


class Scene:
    """An exact-trilinear field sampled on a grid with origin/spacing (x, y, z).

    ``coeffs`` are ``(c0, ..., c7)`` of ``F`` (exact in float64), ``shape``
    is ``(nz, ny, nx)``; ``data`` holds the samples in ``dtype``.
    """

    def __init__(self, coeffs, shape, dtype=np.float64, origin=(0.0, 0.0, 0.0),
                 spacing=(1.0, 1.0, 1.0), name=""):
        self.coeffs = tuple(float(x) for x in coeffs)
        if any(Fraction(x) != Fraction(y) for x, y in zip(self.coeffs, coeffs)):
            raise ValueError("coefficients must be exact in float64")
        self.shape = tuple(int(s) for s in shape)
        self.origin = np.array(origin, dtype=np.float64)
        self.spacing = np.array(spacing, dtype=np.float64)
        self.data = sample_field(self.coeffs, self.shape, dtype)
        self.name = name

    def index_to_world(self, p):
        return self.origin + np.asarray(p, dtype=np.float64) * self.spacing

    @property
    def lo_world(self):
        return self.origin.copy()

    @property
    def hi_world(self):
        nz, ny, nx = self.shape
        return self.origin + np.array([nx - 1, ny - 1, nz - 1]) * self.spacing

    def value_at_index(self, p):
        """F at an index point, exactly (Fraction)."""
        cf = [Fraction(x) for x in self.coeffs]
        return field_value(cf, *[Fraction(float(x)) for x in p])


# Grids: anisotropic with an origin far from 0, dyadic (grid planes exact in
# world coordinates), and the unit grid.
ANISO = dict(origin=(-5.5, 3.25, 100.0), spacing=(0.7, 1.3, 2.1))
DYADIC = dict(origin=(-4.0, 2.5, 8.0), spacing=(0.5, 1.0, 2.0))
UNIT = dict(origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0))

TERMS = {
    "full": (1, 1, 1, 1, 1, 1, 1, 1),
    "no_xyz": (1, 1, 1, 1, 1, 1, 1, 0),
    "linear": (1, 1, 1, 1, 0, 0, 0, 0),
    "saddle_xy": (1, 1, 1, 0, 1, 0, 0, 0),
    "xyz_only": (1, 0, 0, 0, 0, 0, 0, 1),
    "bilinear": (1, 0, 0, 0, 1, 1, 1, 0),
}


# ------------------------------------------------------------------ scenes

def random_scene(rng, shape, dtype=np.float64, terms="full", span=None, grid=ANISO,
                 denominator=1, name=""):
    """A random exact-trilinear field on ``shape`` whose samples span about ``span``.

    Integer coefficients (multiples of ``1/denominator`` for float64); for
    integer dtypes the field is shifted and shrunk until it fits.
    """
    nz, ny, nx = shape
    mono_max = [1, nx - 1, ny - 1, nz - 1, (nx - 1) * (ny - 1), (ny - 1) * (nz - 1),
                (nz - 1) * (nx - 1), (nx - 1) * (ny - 1) * (nz - 1)]
    if np.dtype(dtype).kind in "ui":
        info = np.iinfo(dtype)
        limit = int(info.max) - int(info.min)
        span = span or 0.9 * limit
    else:
        info, limit = None, None
        span = span or 1000.0
    mask = TERMS[terms]
    while True:
        w = rng.uniform(-1, 1, 8) * np.array(mask)
        w[0] = 0
        active = max(1, sum(mask[1:]))
        coeffs = [Fraction(round(w[m] * span / active / max(mono_max[m], 1) * denominator),
                           denominator) if mask[m] else Fraction(0) for m in range(8)]
        if all(c == 0 for c in coeffs[1:]):
            continue
        lo, hi = field_range(coeffs, shape)
        if hi > lo:      # stretch to the requested span (still integer / dyadic)
            f = Fraction(span) / (hi - lo)
            coeffs = [Fraction(math.floor(c * f * denominator), denominator) for c in coeffs]
            lo, hi = field_range(coeffs, shape)
        if info is not None:
            if hi - lo > limit:
                span *= 0.8
                continue
            shift = int(info.min) - lo + Fraction(int(rng.integers(0, int(limit - (hi - lo)) + 1)))
            coeffs[0] = Fraction(math.floor(shift))
        else:
            coeffs[0] = Fraction(round(rng.uniform(-1, 1) * span * denominator), denominator) - lo
        return Scene([float(c) for c in coeffs], shape, dtype, name=name or terms, **grid)


def data_range(scene):
    return float(scene.data.min()), float(scene.data.max())


def random_isos(rng, scene, n):
    """Mixed isovalues: random doubles in range, sample values, half-way values."""
    lo, hi = data_range(scene)
    flat = scene.data.ravel()
    out = []
    for m in range(n):
        kind = m % 3
        if kind == 0:
            out.append(float(rng.uniform(lo, hi)))
        elif kind == 1:
            out.append(float(flat[rng.integers(flat.size)]))
        else:
            out.append(float(flat[rng.integers(flat.size)]) + 0.5)
    return out


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
    return np.array(out)


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


# ------------------------------------------------------------------ running

class Batch:
    """Rays of one scene and category: origins, directions and per-ray isovalues."""

    def __init__(self, category, scene, origins, dirs, isos):
        self.category, self.scene = category, scene
        self.origins = np.ascontiguousarray(origins, dtype=np.float64)
        self.dirs = np.ascontiguousarray(dirs, dtype=np.float64)
        self.isos = np.broadcast_to(np.asarray(isos, dtype=np.float64),
                                    (len(self.origins),)).copy()

    def __len__(self):
        return len(self.origins)


def cast(scene, origins, dirs, iso, seg=None, skip=None):
    """Run the caster on world rays with one isovalue; returns (t, cell, uvw, counts).

    ``skip``: a skip table and the smallest radius worth a jump (``(int8
    array, jump_min)``, see `raycast.iso`), or None for none. Small groups run on one thread: a parallel launch on a busy machine costs
    milliseconds, and the per-ray kernel is the same either way.
    """
    n = len(origins)
    t, cell, uvw, counts = empty_outputs(n)
    use_seg = seg is not None
    seg = np.ascontiguousarray(seg, dtype=np.float64) if use_seg else np.empty((1, 2))
    if skip is None:
        skip = (NO_SKIP, -1)
    threads = numba.get_num_threads()
    if n < 256:
        numba.set_num_threads(1)
    try:
        cast_iso_rays(scene.data, scene.origin, scene.spacing,
                      np.ascontiguousarray(origins, dtype=np.float64),
                      np.ascontiguousarray(dirs, dtype=np.float64),
                      float(iso), seg, use_seg, *skip, t, cell, uvw, counts)
    finally:
        numba.set_num_threads(threads)
    return t, cell, uvw, counts


def cast_batch(batch):
    """`cast` every ray of a `Batch` (grouped by isovalue); returns (t, cell, uvw, counts)."""
    n = len(batch)
    t, cell, uvw, counts = empty_outputs(n)
    groups = defaultdict(list)
    for m, iso in enumerate(batch.isos):
        groups[float(iso)].append(m)
    for iso, idx in groups.items():
        idx = np.array(idx)
        r = cast(batch.scene, batch.origins[idx], batch.dirs[idx], iso)
        t[idx], cell[idx], uvw[idx], counts[idx] = r
    return t, cell, uvw, counts


def report(stats, failures, limit=8):
    """Text summary of `raycast.reference.run_batches`' result: counts, then the first failures."""
    lines = ["per category (outcome counts):"]
    for cat, c in sorted(stats.items()):
        lines.append(f"  {cat:>18}: {sum(c.values()):6d} rays  " + ", ".join(
            f"{k}={v}" for k, v in sorted(c.items())))
    if failures:
        per = Counter(f[0] for f in failures)
        lines.append(f"{len(failures)} FAILURES: " + ", ".join(f"{k}={v}" for k, v in per.items()))
        for f in failures[:limit]:
            lines.append(f"  [{f[0]} / {f[1]}] o={f[2]!r} d={f[3]!r} iso={f[4]!r} "
                         f"t={f[5]!r}: {f[6]}")
    return "\n".join(lines)


# --------------------------------------------------------- hard-ray suite

def _exact_iso(scene, p):
    """F(p) for an index point p, which must be exact in float64."""
    v = scene.value_at_index([float(x) for x in p])
    if Fraction(float(v)) != v:
        raise ValueError(f"F({p}) = {v} is not exact in float64")
    return float(v)


def _split(total, parts):
    return [total // parts + (1 if m < total % parts else 0) for m in range(parts)]


def _scenes(rng, specs):
    return [random_scene(rng, shape, dtype, terms, grid=grid, denominator=den,
                         name=f"{np.dtype(dtype).name}-{terms}-{shape[::-1]}")
            for shape, dtype, terms, grid, den in specs]


SMALL = (6, 7, 9)
STD_SPECS = [(SMALL, np.float64, "full", ANISO, 8), ((5, 8, 6), np.uint16, "full", ANISO, 1),
             ((7, 6, 8), np.float64, "full", DYADIC, 2), ((6, 6, 6), np.uint16, "no_xyz", UNIT, 1)]
LONG_SHAPE = (4, 4, 4096)


def cat_axis(rng, n):
    out = []
    for scene, k in zip(_scenes(rng, STD_SPECS), _split(n, len(STD_SPECS))):
        for iso, m in zip(random_isos(rng, scene, 5), _split(k, 5)):
            out.append(Batch("axis", scene, *axis_rays(rng, scene, m), iso))
    return out


def cat_near_axis(rng, n):
    out = []
    for scene, k in zip(_scenes(rng, STD_SPECS), _split(n, len(STD_SPECS))):
        for iso, m in zip(random_isos(rng, scene, 5), _split(k, 5)):
            out.append(Batch("near-axis", scene, *near_axis_rays(rng, scene, m // 2), iso))
            out.append(Batch("near-axis", scene, *plane_hugging_rays(rng, scene, m - m // 2), iso))
    return out


def cat_no_xyz(rng, n):
    specs = [(SMALL, np.float64, "no_xyz", ANISO, 8), ((5, 8, 6), np.uint16, "no_xyz", ANISO, 1),
             (SMALL, np.float64, "linear", ANISO, 4), ((6, 6, 6), np.float64, "saddle_xy", UNIT, 1),
             ((7, 6, 8), np.uint16, "bilinear", DYADIC, 1)]
    out = []
    for scene, k in zip(_scenes(rng, specs), _split(n, len(specs))):
        for iso, m in zip(random_isos(rng, scene, 4), _split(k, 4)):
            a, b, c = _split(m, 3)
            out.append(Batch("no-xyz", scene, *perspective_rays(rng, scene, a), iso))
            out.append(Batch("no-xyz", scene, *parallel_rays(rng, scene, b), iso))
            out.append(Batch("no-xyz", scene, *axis_rays(rng, scene, c), iso))
    return out


def _tangent_category(rng, n, name, offsets, per_point):
    specs = [(SMALL, np.float64, "full", ANISO, 8), ((5, 8, 6), np.uint16, "full", ANISO, 1),
             (SMALL, np.float64, "no_xyz", ANISO, 4), ((6, 6, 6), np.uint16, "xyz_only", UNIT, 1),
             ((7, 6, 8), np.float64, "saddle_xy", DYADIC, 2)]
    out = []
    for scene, k in zip(_scenes(rng, specs), _split(n, len(specs))):
        while k > 0:
            p = dyadic_point(rng, scene)
            rays = tangent_rays(rng, scene, p, min(per_point, k), offsets)
            if rays is None:
                continue
            out.append(Batch(name, scene, *rays, _exact_iso(scene, p)))
            k -= len(rays[0])
    return out


def cat_grazing(rng, n):
    return _tangent_category(rng, n, "grazing", (0.0,), 8)


def cat_near_double(rng, n):
    offs = tuple(s * 10.0 ** -e for e in (2, 4, 6, 8, 10, 12) for s in (1, -1))
    return _tangent_category(rng, n, "near-double", offs, len(offs))


def cat_face_edge_vertex(rng, n):
    specs = [(SMALL, np.float64, "full", ANISO, 8), ((5, 8, 6), np.uint16, "full", ANISO, 1),
             ((7, 6, 8), np.float64, "full", DYADIC, 2), ((6, 6, 6), np.uint16, "full", UNIT, 1)]
    out = []
    for scene, k in zip(_scenes(rng, specs), _split(n, len(specs))):
        while k > 0:
            fixed = tuple(rng.permutation(3)[:int(rng.integers(1, 4))])
            p = dyadic_point(rng, scene, fixed)
            pw = scene.index_to_world([float(x) for x in p])
            iso = _exact_iso(scene, p)
            o1, d1 = aimed_rays(rng, scene, pw, 4)
            o2, d2 = aimed_rays(rng, scene, pw, 3, outside=False, dist=(0.3, 6.0))
            o3, d3 = np.zeros((3, 3)), np.zeros((3, 3))
            for q in range(3):          # axis-aligned through p (exact on dyadic grids)
                a = int(rng.integers(3))
                s = rng.choice([-1.0, 1.0])
                d3[q, a] = s
                o3[q] = pw.copy()
                o3[q, a] -= s * float(rng.integers(1, 30)) * scene.spacing[a]
            o = np.concatenate([o1, o2, o3])[:k]
            d = np.concatenate([d1, d2, d3])[:k]
            out.append(Batch("face-edge-vertex", scene, o, d, iso))
            k -= len(o)
    return out


def cat_iso_sample(rng, n):
    specs = [(SMALL, np.float64, "full", ANISO, 1), ((5, 8, 6), np.uint16, "full", ANISO, 1),
             ((6, 6, 6), np.int16, "full", UNIT, 1), ((7, 6, 8), np.uint16, "no_xyz", DYADIC, 1)]
    out = []
    for scene, k in zip(_scenes(rng, specs), _split(n, len(specs))):
        nz, ny, nx = scene.shape
        while k > 0:
            v = np.array([int(x) for x in dyadic_point(rng, scene, fixed=(0, 1, 2))])
            iso = float(scene.data[v[2], v[1], v[0]])
            pw = scene.index_to_world(v.astype(float))
            parts = [aimed_rays(rng, scene, pw, 4), aimed_rays(rng, scene, pw, 2, False, (0.3, 5)),
                     perspective_rays(rng, scene, 4)]
            o = np.concatenate([x[0] for x in parts])[:k]
            d = np.concatenate([x[1] for x in parts])[:k]
            out.append(Batch("iso-sample", scene, o, d, iso))
            k -= len(o)
    return out


def cat_mag16(rng, n):
    specs = [((5, 8, 6), np.uint16, "full", ANISO, 1), ((6, 6, 6), np.uint16, "xyz_only", UNIT, 1),
             ((5, 7, 9), np.int16, "full", ANISO, 1), ((8, 5, 7), np.uint16, "bilinear", DYADIC, 1)]
    out = []
    for scene, k in zip(_scenes(rng, specs), _split(n, len(specs))):
        for iso, m in zip(random_isos(rng, scene, 6), _split(k, 6)):
            a, b, c = _split(m, 3)
            out.append(Batch("mag16", scene, *perspective_rays(rng, scene, a), iso))
            out.append(Batch("mag16", scene, *perspective_rays(rng, scene, b, inside=True), iso))
            out.append(Batch("mag16", scene, *parallel_rays(rng, scene, c), iso))
    return out


def long_scenes(rng):
    """4096 x 4 x 4 volumes: 16-bit ramps along x plus cross terms."""
    out = []
    for dtype, c in ((np.uint16, (50, 15, 300, 200, 0, 40, 0, 0)),
                     (np.float64, (-30000, 14.5, -250, 180, 0.75, 30, -1.25, 0.5)),
                     (np.uint16, (65000, -15, 20, 10, 0, 5, 0, 0))):
        out.append(Scene(c, LONG_SHAPE, dtype, name=f"long-{np.dtype(dtype).name}", **ANISO))
    return out


def cat_long_grid(rng, n):
    out = []
    for scene, k in zip(long_scenes(rng), _split(n, 3)):
        lo, hi = data_range(scene)
        h = scene.hi_world - scene.lo_world
        for iso, m in zip(list(rng.uniform(lo, hi, 4)) + random_isos(rng, scene, 2), _split(k, 6)):
            a, b, c, e = _split(m, 4)
            # near-axis along x from far behind, hitting far down the grid
            d = np.zeros((a, 3))
            d[:, 0] = rng.choice([-1.0, 1.0], a)
            d[:, 1:] = rng.choice([0.0, 1.0], (a, 2)) * 10.0 ** rng.uniform(-17, -3, (a, 2)) * \
                rng.choice([-1, 1], (a, 2))
            d = unit(d)
            o = box_points(rng, scene, a, 0.05, 0.95)
            back = rng.uniform(1.0, 300.0, a)
            o[:, 0] = np.where(d[:, 0] > 0, scene.lo_world[0] - back, scene.hi_world[0] + back)
            out.append(Batch("long-grid", scene, o, d, iso))
            # oblique rays from eyes far along x into far cells
            eyes = scene.lo_world + h * rng.uniform(-0.2, 1.2, (b, 3))
            tgt = scene.lo_world + h * rng.uniform(0, 1, (b, 3))
            out.append(Batch("long-grid", scene, eyes, unit(tgt - eyes), iso))
            # origin inside, at large x, nearly along x
            o = scene.lo_world + h * rng.uniform([0.5, 0, 0], [1, 1, 1], (c, 3))
            tilt = rng.normal(size=(c, 2)) * 10.0 ** rng.uniform(-9, -1, (c, 1))
            d = unit(np.concatenate([rng.choice([-1.0, 1.0], (c, 1)), tilt], 1))
            out.append(Batch("long-grid", scene, o, d, iso))
            out.append(Batch("long-grid", scene, *plane_hugging_rays(rng, scene, e), iso))
    return out


def cat_far_origin(rng, n):
    specs = [(SMALL, np.float64, "full", ANISO, 8), ((5, 8, 6), np.uint16, "full", ANISO, 1),
             ((6, 6, 6), np.uint16, "no_xyz", UNIT, 1)]
    out = []
    for scene, k in zip(_scenes(rng, specs), _split(n, len(specs))):
        c = 0.5 * (scene.lo_world + scene.hi_world)
        for iso, m in zip(random_isos(rng, scene, 5), _split(k, 5)):
            dist = 10.0 ** rng.uniform(2.5, 3.7, (m, 1))          # ~300 .. 5000 world units
            eyes = c + random_dirs(rng, m) * dist
            tgt = box_points(rng, scene, m)
            out.append(Batch("far-origin", scene, eyes, unit(tgt - eyes), iso))
    return out


CATEGORIES = {
    "axis": cat_axis, "near-axis": cat_near_axis, "no-xyz": cat_no_xyz,
    "grazing": cat_grazing, "near-double": cat_near_double,
    "face-edge-vertex": cat_face_edge_vertex, "iso-sample": cat_iso_sample,
    "mag16": cat_mag16, "long-grid": cat_long_grid, "far-origin": cat_far_origin,
}


def hard_batches(category, n, seed=0):
    """The rays of one hard category: about ``n`` rays, deterministic in ``seed``."""
    rng = np.random.default_rng([seed, list(CATEGORIES).index(category)])
    return CATEGORIES[category](rng, n)
