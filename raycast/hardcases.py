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
drives, and imports no mpmath. The scenes are `raycast.hardfields`', the
ray generators `raycast.hardrays`'; here are the categories and the driver.
"""
from collections import Counter, defaultdict
from fractions import Fraction

import numba
import numpy as np

from .hardfields import ANISO, DYADIC, UNIT, Scene, data_range, random_isos, random_scene
from .hardrays import (aimed_rays, axis_rays, box_points, dyadic_point, near_axis_rays, parallel_rays,
                       perspective_rays, plane_hugging_rays, random_dirs, tangent_rays, unit)
from .iso import NO_SKIP, cast_iso_rays, empty_outputs

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

    ``seg``: per-ray ``(near, far)`` bounds, ``(n, 2)``, or None for whole rays.
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
