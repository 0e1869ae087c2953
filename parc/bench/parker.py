"""Parker et al.'s Tables 1 and 2, measured: where an isosurface frame's time goes, and thread scaling.

Share of time (Parker et al.'s Table 1). They read traversal,
intersection and shading shares off hardware cycle counters. Here, on one
thread so that seconds add up:

* *intersection*: the frame's own cubics, recorded by the root-finder
  study's walk (`parc.rootstudy.walk_rays`, checked to visit exactly the
  caster's cells: its solve count must equal the render's), then solved
  again in a tight loop (best of 3). That is the time the root finder
  takes inside the cast.
* *shading*: the frame's hits (from the same walk) shaded again by the
  shading kernel in a tight loop (best of 3); the render shades each hit
  inside its cast (`raycast.iso.cast_iso_image`), which takes a little less.
* *traversal*: the cast phase less the intersection and the shading: ray
  set-up, cell stepping, corner reads and the cubic's coefficients.
* *OpenGL* (PARC only): classification, proxy and rasterization.
* *other*: the frame's time the parts leave out (set-up, the median's other runs).

Thread scaling (their Table 2): frames per second of the bone isosurface
at 1 thread up to every core Numba has, each the median of the repeats.
"""
from __future__ import annotations

import statistics
import time

import numba
import numpy as np

from raycast.shade import shade_headlight

from ..comparison import compare
from ..rootstudy import PROJECT, solve_all, walk
from . import scenes

ISOS = (("skin", 600.0), ("bone", 1500.0))


def recorded_walk(scene):
    """The caster's walk over the scene's one isosurface: ``(t, cell, uvw, rec)``, the hits
    and the cubics ``(A, B, C, D, L)`` it solves, in ray order."""
    vis = scene.volumes[0]
    vol = vis.volume
    w, h = scene.size
    o, d = scene.camera.rays(w, h)
    o = np.ascontiguousarray(o.reshape(-1, 3))
    d = np.ascontiguousarray(d.reshape(-1, 3))
    return walk(vol.data, np.array(vol.origin), np.array(vol.spacing), o, d, np.full(len(o), float(vis.value)),
                PROJECT, record=True)


def _shade_seconds(scene, t, cell, uvw, repeats=3):
    """Best time of the headlight shading pass over the hits ``t``, ``cell``, ``uvw``."""
    vis = scene.volumes[0]
    vol = vis.volume
    w, h = scene.size
    args = (vol.data, np.array(vol.spacing), scene.camera.as_array(), w, h, t, cell, uvw,
            np.array(vis.color, dtype=np.float64), np.array(vis.material, dtype=np.float64))
    best = float("inf")
    for n in range(repeats + 1):
        image = np.zeros((h, w, 4), np.float32)
        t0 = time.perf_counter()
        shade_headlight(*args, image)
        if n:                  # the first run warms up, as `_solve_seconds`'s does
            best = min(best, time.perf_counter() - t0)
    return best


def _solve_seconds(rec, repeats=3):
    solve_all(rec[:16], PROJECT, 1)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        solve_all(rec, PROJECT, 1)
        best = min(best, time.perf_counter() - t0)
    return best


def time_shares(suite, progress):
    """Rows per (isosurface, method): seconds and shares of traversal, intersection, shading, OpenGL, other."""
    rows, source = [], None
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        for name, iso in ISOS:
            scene, source = scenes.ct_iso(suite.parker_size, iso, suite.data_dir, suite.small_volumes)
            progress(f"time shares, {name}: recording the frame's cubics")
            t, cell, uvw, rec = recorded_walk(scene)
            intersect = _solve_seconds(rec)
            shading = _shade_seconds(scene, t, cell, uvw)
            res = compare(scene, methods=("brute", "parc"), repeats=suite.repeats,
                          progress=lambda m: progress(f"time shares, {name}: {m}, 1 thread"))
            for r in res:
                if r["cubic_solves"] != len(rec):
                    raise RuntimeError(f"{name}: the recorded walk solved {len(rec)} cubics, "
                                       f"the {r['method']} render {r['cubic_solves']}")
                ph = r["phases"]
                cast = ph.get("cast", 0.0)
                gl = sum(ph.get(k, 0.0) for k in ("classify", "proxy", "raster"))
                parts = {"traversal": max(cast - intersect - shading, 0.0), "intersection": min(intersect, cast),
                         "shading": min(shading, max(cast - intersect, 0.0))}
                if r["method"] != "brute":
                    parts["OpenGL"] = gl
                # The frame's time the parts leave out (setup, the median's other runs): shares of
                # the parts alone hid it.
                parts["other"] = max(r["seconds"] - sum(parts.values()), 0.0)
                total = sum(parts.values())
                rows.append({"surface": f"{name} ({iso:g})", "method": r["method"], "seconds": r["seconds"],
                             "parts_seconds": parts,
                             "shares": {k: v / total if total > 0 else 0.0 for k, v in parts.items()},
                             "cubics": len(rec), "cells": r["cells_visited"],
                             "ns_per_solve": 1e9 * intersect / max(len(rec), 1),
                             "max_color": r["max_color"], "hit_mismatches": r["hit_mismatches"]})
    finally:
        numba.set_num_threads(threads)
    return {"source": source, "size": suite.parker_size, "rows": rows}


def thread_scaling(suite, progress):
    """Frames per second of the bone isosurface for 1 .. all threads, brute and parc."""
    scene, source = scenes.ct_iso(suite.parker_size, 1500.0, suite.data_dir, suite.small_volumes)
    most = numba.config.NUMBA_NUM_THREADS
    counts = sorted({1, 2, 4, 8, 16, 32, 64, most} & set(range(1, most + 1)))
    threads = numba.get_num_threads()
    rows = []
    try:
        for k in counts:
            numba.set_num_threads(k)
            res = compare(scene, methods=("brute", "parc"), repeats=suite.repeats,
                          progress=lambda m: progress(f"thread scaling: {m}, {k} thread(s)"))
            rows.append({"threads": k, **{f"{r['method']}_fps": 1.0 / r["seconds"] for r in res}})
    finally:
        numba.set_num_threads(threads)
    for m in ("brute", "parc"):
        base = rows[0][f"{m}_fps"]
        for r in rows:
            r[f"{m}_speedup"] = r[f"{m}_fps"] / base
    return {"source": source, "size": suite.parker_size, "cores": most, "rows": rows,
            "median_parc_fps": statistics.median(r["parc_fps"] for r in rows)}
