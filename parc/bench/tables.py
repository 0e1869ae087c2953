"""Sobierajski & Avila's Tables 1-3, measured: `brute` against `parc`, same columns, one run per size.

Each table's scene is rendered by `parc.compare` (a warm-up, then the
median of the suite's repeats; `brute` first, as the reference). The
columns follow the paper:

* *casting time*: rays cast, plus, for PARC, rasterizing the proxy (the
  paper's casting time "includes the time required to project the
  polygonal model");
* *total time*: the whole `render` call, wall clock;
* *cells*: cells considered for intersection (visited by the walk);
  *samples*: trilinear samples taken.

Next to them, the ideal bound (`parc.ideal`): the cells or samples a
caster that classifies whole cells needs at least (those in possibly
contributing cells), the contributing ones among them (the surface's cell
of each hit; samples of non-zero opacity), and the error of each image
against `brute`'s (zero is what exactness means).
"""
from __future__ import annotations

from ..comparison import compare
from ..ideal import ideal_and_contributing_samples
from ..renderer import render
from ..scene import Translucent
from . import scenes


def _cast_seconds(row):
    ph = row["phases"]
    return ph.get("cast", 0.0) + ph.get("raster", 0.0) + ph.get("raster_bits", 0.0)


def _error(row):
    return {k: row[k] for k in ("hit_mismatches", "max_depth_cells", "max_color", "psnr")}


def _spread(row):
    """The lowest and highest of the rounds' own speedups (`parc.compare`): the run's noise."""
    return {k: row[k] for k in ("speedup_low", "speedup_high") if k in row}


def work_maps(scene, count):
    """``brute``'s and ``parc``'s work per pixel on ``scene`` (`parc.render`'s ``work``), with checks.

    Returns ``{"maps": {method: (H, W) array}, "checks": {...}}``: whether
    each map sums to the method's ``stats[count]`` (``"cells_visited"`` or
    ``"samples"``) and whether ``parc`` does no more than ``brute`` at any
    pixel. The report draws the maps (`parc.bench.report.work_map_md`) and
    keeps the checks; the maps stay out of results.json.
    """
    runs = {m: render(scene, m, work=True) for m in ("brute", "parc")}
    maps = {m: run.work for m, run in runs.items()}
    return {"maps": maps,
            "checks": {"sums": all(int(maps[m].sum()) == runs[m].stats[count] for m in maps),
                       "parc_within_brute": bool((maps["parc"] <= maps["brute"]).all())}}


def _rows(scene, methods, options, suite, progress, label):
    return compare(scene, methods=methods, options=options, repeats=suite.repeats,
                   warmup=1, progress=lambda m: progress(f"{label}: {m}"))


def table1(suite, progress, images):
    """CT translucent (Fig. 11): samples, casting and total time; `parc` with depth, and with depth and bits.

    Also `parc` with depth buffers alone, without the empty-block jumps
    inside its segments (``blocks=False``): the paper's depth-buffer PARC.
    """
    out, source, work = [], None, None
    for size in suite.sizes:
        scene, source = scenes.ct_translucent(size, suite.data_dir, suite.small_volumes)
        if work is None:
            progress(f"Table 1, {size}²: samples per pixel")
            work = work_maps(scene, "samples")
        options = {"parc:segments": {"buffers": ("depth",), "blocks": False},
                   "parc": {"buffers": ("depth",)}, "parc:bits": {"buffers": ("depth", "bits")}}
        rows = _rows(scene, ["brute", "parc:segments", "parc", "parc:bits"], options, suite, progress,
                     f"Table 1, {size}²")
        progress(f"Table 1, {size}²: ideal samples")
        ideal, seen = ideal_and_contributing_samples(scene, scene.volumes[0])
        for r in rows:
            out.append({"method": {"brute": "brute", "parc:segments": "parc (depth, no blocks)",
                                   "parc": "parc (depth)", "parc:bits": "parc (depth+bits)"}[r["method"]],
                        "size": size, "samples": r["samples"], "ideal_samples": ideal,
                        "contributing_samples": seen,
                        "cast_seconds": _cast_seconds(r), "total_seconds": r["seconds"],
                        "speedup": r["speedup"], **_spread(r), "polygons": r["polygons"], **_error(r)})
        images["table1"] = scene
    return {"source": source, "rows": out, "work": work, "work_size": suite.sizes[0]}


def table2(suite, progress, images):
    """Iron protein (Fig. 12): an isosurface inside a translucent volume; cells, samples, times."""
    out, source = [], None
    for size in suite.sizes:
        scene, source = scenes.iron_protein(size, suite.data_dir, suite.small_volumes)
        rows = _rows(scene, ["brute", "parc"], {}, suite, progress, f"Table 2, {size}²")
        progress(f"Table 2, {size}²: ideal samples")
        depth = render(scene, method="brute").depth
        trans = [v for v in scene.volumes if isinstance(v, Translucent)]
        counted = [ideal_and_contributing_samples(scene, v, stop=depth) for v in trans]
        ideal_s, seen_s = sum(c[0] for c in counted), sum(c[1] for c in counted)
        brute = next(r for r in rows if r["method"] == "brute")
        for r in rows:
            out.append({"method": r["method"], "size": size, "cells": r["cells_visited"],
                        "ideal_cells": brute["cubic_solves"], "contributing_cells": brute["hits"],
                        "samples": r["samples"], "ideal_samples": ideal_s, "contributing_samples": seen_s,
                        "cast_seconds": _cast_seconds(r), "total_seconds": r["seconds"],
                        "speedup": r["speedup"], **_spread(r), "polygons": r["polygons"], **_error(r)})
        images["table2"] = scene
    return {"source": source, "rows": out}


def table3(suite, progress, images):
    """Neuron on a floor with two shadowing lights (Fig. 13): primary and shadow rays apart."""
    out, source = [], None
    for size in suite.sizes:
        scene, source = scenes.neuron_floor(size, suite.data_dir, suite.small_volumes)
        rows = _rows(scene, ["brute", "parc"], {}, suite, progress, f"Table 3, {size}²")
        brute = rows[0]
        for r in rows:
            ph = r["phases"]
            shadow = ph.get("shadow", 0.0) + ph.get("raster_lights", 0.0)
            primary_cast = ph.get("cast", 0.0) + ph.get("raster", 0.0)
            out.append({"method": r["method"], "size": size,
                        "primary_cells": r["cells_visited"], "ideal_primary_cells": brute["cubic_solves"],
                        "contributing_primary_cells": brute["hits"],
                        "primary_cast_seconds": primary_cast,
                        "primary_total_seconds": r["seconds"] - shadow,
                        "shadow_cells": r["shadow_cells"], "ideal_shadow_cells": brute["shadow_solves"],
                        "shadow_seconds": shadow, "total_seconds": r["seconds"],
                        "speedup": r["speedup"], **_spread(r), **_error(r)})
        b = out[-len(rows)]
        for r in out[-len(rows):]:
            # The paper's primary-ray ratio is of totals (its 3.5x: 35.61 s / 10.06 s); casting is its own.
            for ratio, seconds in (("primary_speedup", "primary_cast_seconds"),
                                   ("primary_total_speedup", "primary_total_seconds"),
                                   ("shadow_speedup", "shadow_seconds")):
                r[ratio] = b[seconds] / max(r[seconds], 1e-12)
        images["table3"] = scene
    return {"source": source, "rows": out}
