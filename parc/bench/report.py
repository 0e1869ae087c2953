"""The bench's results as `report.md` and its charts: tables in the papers' columns, one chart per sweep."""
from __future__ import annotations

import math
from pathlib import Path

from ..comparison import ratio_text
from ..rootstudy import FAILURE_KINDS
from . import charts, heatmaps


def _scatter(path, points, **kw):
    """A scatter chart, log in x only when some error is non-zero (all zero is the usual PARC result)."""
    return charts.scatter_chart(path, points, x_log=any(p["x"] > 0 for p in points), **kw)


def counted(n, word):
    """``n word`` or ``n words``: the tiny suite's one render, core or thread read as such."""
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def _s(v):
    return f"{v:.3f}" if v >= 0.1 else f"{v:.4f}"


def _k(n):
    return f"{n / 1000:,.1f}"


def _x(v):
    return f"{ratio_text(v)}×"


def _xr(r):
    """A row's speedup with, where the run has them, the lowest and highest of its rounds."""
    if "speedup_low" not in r or r["method"].startswith("brute"):
        return _x(r["speedup"])
    return f"{_x(r['speedup'])} ({ratio_text(r['speedup_low'])}–{ratio_text(r['speedup_high'])})"


def _err(v):
    return "0" if v == 0 else f"{v:.1e}"


def _table(head, rows):
    out = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def _exact(r):
    return "yes" if r["hit_mismatches"] == 0 and r["max_color"] <= 1e-6 else (
        f"no ({r['hit_mismatches']} px, Δ {r['max_color']:.1e})")


def work_map_md(section, out, name, what, scene, why):
    """Draw a section's work maps (`parc.bench.tables.work_maps`) to ``out/name``, dropping the
    arrays from the results, and return the paragraph and picture that show them."""
    work = section.get("work")
    if work is None or "maps" not in work:
        return []
    heatmaps.work_heat_maps(out / name, work.pop("maps"), what, scene)
    return [f"Where the work goes: the {what} per pixel by `brute` and `parc` (default settings), on one "
            f"colour scale. {why}", "", f"![{what} per pixel]({name})", ""]


def paper_tables(res, out):
    t1, t2, t3 = res["table1"], res["table2"], res["table3"]
    md = ["## 1. Sobierajski & Avila, Tables 1–3", "",
          "Columns as in the paper: casting time includes rasterizing the proxy; total time is the whole "
          "render. Unlike the paper's, a cast here shades its hits as it goes, so casting is most of the "
          "total. In Table 1, `parc (depth, no blocks)` is the paper's depth-buffer PARC; `parc (depth)` "
          "adds jumps over empty cells inside the segments, which neither of the paper's methods has, and "
          "`parc (depth+bits)` adds to that the bit planes of its Color-buffer PARC. "
          "*Ideal* is the least a caster that classifies whole cells, as PARC does, can take: the cells or "
          "samples in possibly contributing cells (section 5, with the contributing ones among them). "
          "*Exact* means identical hit masks and |Δcolour| ≤ 1e-6 against `brute` on every pixel.", "",
          "### Table 1: CT, translucent (Fig. 11)", "", f"Volume: {t1['source']}; transfer function "
          "`ct_skin_bone`, composite, step a quarter of the smallest spacing.", ""]
    md.append(_table(("method", "image (px²)", "samples (×10³)", "ideal samples (×10³)", "casting (s)",
                      "total (s)", "speedup", "exact"),
                     [(r["method"], r["size"], _k(r["samples"]), _k(r["ideal_samples"]), _s(r["cast_seconds"]),
                       _s(r["total_seconds"]), _xr(r), _exact(r)) for r in t1["rows"]]))
    md += ["", "![Table 1 scene](images/table1.png)", ""]
    md += work_map_md(t1, out, "work_table1.png", "samples taken", f"CT ct_skin_bone at {t1['work_size']}x"
                      f"{t1['work_size']}", "`brute` samples every ray through the whole volume; `parc` only "
                      "the rays its OpenGL pass flags, and only in cells the transfer function shows.")
    md += ["### Table 2: iron protein, isosurface inside a translucent volume (Fig. 12)", "",
           f"Volumes: {t2['source']}.", ""]
    md.append(_table(("method", "image (px²)", "cells (×10³)", "ideal cells (×10³)", "samples (×10³)",
                      "ideal samples (×10³)", "casting (s)", "total (s)", "speedup", "exact"),
                     [(r["method"], r["size"], _k(r["cells"]), _k(r["ideal_cells"]), _k(r["samples"]),
                       _k(r["ideal_samples"]), _s(r["cast_seconds"]), _s(r["total_seconds"]), _xr(r),
                       _exact(r)) for r in t2["rows"]]))
    md += ["", "![Table 2 scene](images/table2.png)", "",
           "### Table 3: neuron on a floor, two shadowing point lights (Fig. 13)", "",
           f"Volumes: {t3['source']}. Primary total is the shaded image without shadow rays; shadow time "
           "includes the light buffers' rasterization. The paper's primary-ray speedup is of primary "
           "totals; the casting speedup (its cast and rasterization alone) is the larger.", ""]
    md.append(_table(("method", "image (px²)", "primary cells (×10³)", "ideal (×10³)", "primary casting (s)",
                      "primary total (s)", "shadow cells (×10³)", "ideal (×10³)", "shadow (s)", "total (s)",
                      "primary casting speedup", "primary total speedup", "shadow speedup", "total speedup",
                      "exact"),
                     [(r["method"], r["size"], _k(r["primary_cells"]), _k(r["ideal_primary_cells"]),
                       _s(r["primary_cast_seconds"]), _s(r["primary_total_seconds"]), _k(r["shadow_cells"]),
                       _k(r["ideal_shadow_cells"]), _s(r["shadow_seconds"]), _s(r["total_seconds"]),
                       _x(r["primary_speedup"]), _x(r["primary_total_speedup"]), _x(r["shadow_speedup"]),
                       _xr(r), _exact(r))
                      for r in t3["rows"]]))
    md += ["", "![Table 3 scene](images/table3.png)", ""]
    return md


def parker(res, out):
    sh, th = res["time_shares"], res["threads"]
    md = ["## 2. Parker et al., Tables 1 and 2", "",
          f"### Share of time (their Table 1), CT at {sh['size']}², one thread", "",
          f"Volume: {sh['source']}. Intersection is the frame's own cubics solved again in a tight loop, "
          "shading its hits shaded again in one (the render shades each hit inside its cast); traversal is "
          "the cast less both; OpenGL is PARC's classification, proxy and rasterization; other is the rest "
          "of the frame (setup, and the median frame's difference from the run whose phases are shown; "
          "`parc.bench.parker`).",
          ""]
    md.append(_table(("surface", "method", "frame (s)", "traversal", "intersection", "shading", "OpenGL",
                      "other", "cubics", "ns/solve"),
                     [(r["surface"], r["method"], _s(r["seconds"]),
                       *(f"{100 * r['shares'].get(k, 0.0):.0f}%" if k in r["shares"] else "–"
                         for k in ("traversal", "intersection", "shading", "OpenGL", "other")),
                       f"{r['cubics']:,}", f"{r['ns_per_solve']:.0f}") for r in sh["rows"]]))
    charts.stacked_bar_chart(out / "time_shares.png",
                             [(f"{r['surface'].split()[0]} {r['method']} {1e3 * r['seconds']:.1f} ms",
                               r["parts_seconds"]) for r in sh["rows"]],
                             title=f"Where an isosurface frame's time goes: CT at {sh['size']}x{sh['size']}, "
                                   "1 thread")
    md += ["", "![time shares](time_shares.png)", "",
           f"### Thread scaling (their Table 2), bone isosurface at {th['size']}²", "",
           f"{counted(th['cores'], 'core')} available to Numba.", ""]
    # Scaling is each method against itself on 1 thread; the speedup, as everywhere, parc against brute.
    md.append(_table(("threads", "brute FPS", "brute vs 1 thread", "parc FPS", "parc vs 1 thread",
                      "speedup (parc over brute)"),
                     [(r["threads"], f"{r['brute_fps']:.2f}", _x(r["brute_speedup"]), f"{r['parc_fps']:.2f}",
                       _x(r["parc_speedup"]), _x(r["parc_fps"] / r["brute_fps"])) for r in th["rows"]]))
    charts.line_chart(out / "thread_scaling.png",
                      {m: [(r["threads"], r[f"{m}_fps"]) for r in th["rows"]] for m in ("brute", "parc")},
                      title=f"Frames per second against threads: CT bone at {th['size']}x{th['size']}",
                      x_label="threads", y_label="frames per second")
    md += ["", "![thread scaling](thread_scaling.png)", ""]
    return md


def sweeps(res, out):
    sc, st, rt, pr = res["supercells"], res["steps"], res["roots"], res["precision"]
    md = ["## 3. Speed against error", "",
          f"### Supercell size: CT skin isosurface at {sc['size']}²", "",
          f"Volume: {sc['source']}. `parc` is the cost model's choice.", ""]
    md.append(_table(("method", "supercell", "polygons", "classify+proxy+raster (s)", "cells/pixel", "total (s)", "speedup",
                      "hit≠", "max Δdepth (cells)", "max Δcolour"),
                     [(r["method"], r["supercell"], f"{r['polygons']:,}", _s(r["opengl_seconds"]),
                       f"{r['cells_per_pixel']:.1f}", _s(r["seconds"]), _x(r["speedup"]), r["hit_mismatches"],
                       _err(r["max_depth_cells"]), _err(r["max_color"])) for r in sc["rows"]]))
    # Time against the polygons drawn, the trade the cost model weighs; the error is its title's
    # when it is zero at every size (an x axis of one value plotted nothing readable).
    brute = next(r for r in sc["rows"] if r["method"] == "brute")
    sized = [r for r in sc["rows"] if r["method"] != "brute"]
    exact = all(r["hit_mismatches"] == 0 and r["max_color"] == 0 and r["max_depth_cells"] == 0 for r in sized)
    charts.scatter_chart(out / "sweep_supercell.png",
                         [{"x": r["polygons"], "y": r["seconds"], "label": r["supercell"], "series": r["method"]}
                          for r in sized], x_log=True,
                         title=f"Supercell size, CT skin at {sc['size']}x{sc['size']}: brute {_s(brute['seconds'])} s; "
                               + ("every image equal to brute's" if exact else "errors in the table"),
                         x_label="polygons drawn (log)", y_label="seconds per frame")
    md += ["", "![supercell sweep](sweep_supercell.png)", ""]
    md += work_map_md(sc, out, "work_per_pixel.png", "cells visited",
                      f"CT skin ({sc['isovalue']:g}) at {sc['size']}x{sc['size']}",
                      "`brute` walks every ray from the volume's entry to its hit; `parc` casts only the pixels "
                      "its OpenGL pass flags, from the first possibly contributing supercell on, and jumps the "
                      "empty cubes of cells inside.")
    md += [f"### Sample step: CT translucent at {st['size']}²", "",
           f"Error against `brute` at step {st['reference_step']:g}; `parc≠brute` is `parc` against `brute` "
           "at the same step.", ""]
    md.append(_table(("step", "brute (s)", "parc (s)", "speedup", "brute samples (×10³)", "parc samples (×10³)",
                      "max Δcolour vs fine", "PSNR (dB)", "parc≠brute"),
                     [(f"{r['step']:g}", _s(r["brute_seconds"]), _s(r["parc_seconds"]), _x(r["speedup"]),
                       _k(r["brute_samples"]), _k(r["parc_samples"]), _err(r["max_color"]),
                       "inf" if math.isinf(r["psnr"]) else f"{r['psnr']:.1f}", _err(r["parc_vs_brute"]))
                      for r in st["rows"]]))
    pts = [{"x": r["max_color"], "y": r[f"{m}_seconds"], "label": f"{r['step']:g}", "series": m}
           for r in st["rows"] for m in ("brute", "parc")]
    _scatter(out / "sweep_step.png", pts,
             title=f"Sample step (labels, world units): time against error, CT translucent at "
                   f"{st['size']}x{st['size']}",
             x_label="max colour difference against the fine-step reference", y_label="seconds per frame")
    rows = rt["rows"]
    md += ["", "![step sweep](sweep_step.png)", "",
           "### Cubic root finders on the hard-ray suite", "",
           f"{rows[0]['rays']:,} rays ({rows[0]['required']:,} with a required root), {rows[0]['solves']:,} "
           "cubics timed single-threaded (`python -m parc.rootstudy`); error |t − r| in smallest spacings "
           "against mpmath roots.", ""]
    md.append(_table(("finder", "ns/solve", "max error", "median error", "failures", *FAILURE_KINDS),
                     [(r["name"], f"{r['ns_per_solve']:.1f}", _err(r["max_err_cells"]), _err(r["median_err_cells"]),
                       f"{r['failures']:,}", *(f"{r[k]:,}" for k in FAILURE_KINDS)) for r in rows]))
    md += ["", "Failures by kind (they add up to the failures): missed, a required root and no hit; false, "
           "a hit with no root within a cell; wrong, the first root skipped and a later one hit; "
           "inaccurate, within a cell of the true root but outside its tolerance (1e-9 of a cell plus "
           "the rounding of t; for the first root of a close pair, which float can tell from the second, "
           "16 times its conditioning); cell, cell or local coordinates inconsistent with t.", ""]
    _scatter(out / "sweep_roots.png",
             [{"x": r["max_err_cells"], "y": r["ns_per_solve"], "label": f"{r['name']}: {r['failures']:,} failures",
               "series": r["name"]} for r in rows],
             title="Root finders: time per solve against max error", x_label="max error (cells)",
             y_label="ns per solve")
    md += ["", "![root finders](sweep_roots.png)", "",
           f"### Storage precision at {pr['size']}²", "",
           "The caster computes in float64 whatever the samples' type; the volume is stored natively, as "
           "float64 or as float32. Error of `brute` against the float64 image.", ""]
    md.append(_table(("volume", "stored as", "MB", "brute (s)", "parc (s)", "hit≠", "max Δdepth (cells)",
                      "max Δcolour", "parc≠brute"),
                     [(r["volume"], r["dtype"], f"{r['bytes'] / 1e6:.1f}", _s(r["brute_seconds"]),
                       _s(r["parc_seconds"]), r["hit_mismatches"], _err(r["max_depth_cells"]), _err(r["max_color"]),
                       _err(r["parc_vs_brute"])) for r in pr["rows"]]))
    _scatter(out / "sweep_precision.png",
                         [{"x": r["max_color"], "y": r["parc_seconds"], "label": r["dtype"], "series": r["volume"]}
                          for r in pr["rows"]],
                         title="Storage precision: parc time against error", x_label="max colour difference against float64",
                         y_label="seconds per frame")
    md += ["", "![precision](sweep_precision.png)", ""]
    return md


def scale(res, out):
    vw = res["visible_woman"]
    nx, ny, nz = vw["shape"]
    gen = ("generated in this run in " + _s(vw["generate_seconds"]) + " s"
           if vw.get("generate_seconds") is not None else "reused from an earlier run")
    md = ["## 4. Visible Woman scale", "",
          f"A {nx}×{ny}×{nz} {vw['dtype']} CT-like phantom ({vw['bytes'] / 1e6:,.0f} MB), {gen}, memory-mapped "
          f"read-only (`{Path(vw['path']).name}` in the cache folder); {vw['size']}² images, "
          f"{counted(vw['threads'], 'thread')}. Cell min/max once per "
          f"volume: {_s(vw['minmax_seconds'])} s ({vw['minmax_bytes'] / 1e6:,.0f} MB). Peak resident memory of "
          f"the section's process: {vw['peak_rss_bytes'] / 1e6:,.0f} MB.", ""]
    md.append(_table(("surface", "brute s/frame", "parc s/frame", "speedup", "parc FPS", "proxy build (s)",
                      "first frame (s)", "polygons", "cells/px brute", "cells/px parc", "ideal cells/px", "exact"),
                     [(f"{r['surface']} ({r['isovalue']:g})", _s(r["brute_seconds"]), _s(r["parc_seconds"]),
                       _x(r["speedup"]), f"{1 / r['parc_seconds']:.1f}", _s(r["proxy_build_seconds"]),
                       _s(r["first_frame_seconds"]), f"{r['polygons']:,}",
                       f"{r['brute_cells'] / vw['size'] ** 2:.1f}", f"{r['parc_cells'] / vw['size'] ** 2:.1f}",
                       f"{r['ideal_cells'] / vw['size'] ** 2:.2f}", _exact(r)) for r in vw["surfaces"]]))
    ch = vw["iso_change"]
    best = max(1 / r["parc_seconds"] for r in vw["surfaces"])
    md += ["", f"Changing the isovalue (to {ch['isovalue']:g}): reclassification and proxy "
               f"{_s(ch['reclassify_proxy_seconds'])} s, first frame {_s(ch['first_frame_seconds'])} s.", "",
           f"Parker et al. reached about 10 frames per second at 512² on 64 processors, over the real body "
           f"and their views. Here `parc` gives {best:.1f} frames per second at {vw['size']}² on "
           f"{counted(vw['threads'], 'thread')}, on one view of a phantom simpler than the real body"
           + (f" ({best / 10:.0%} of their rate; a like-for-like comparison would need the real data)"
              if vw["size"] == 512 else " (a reduced size: not comparable)")
           + ". Frames are timed round by round, `brute` and `parc` in turn.", ""]
    return md


def ideal(res):
    rows = []
    for r in res["table1"]["rows"]:
        rows.append(("Table 1 CT translucent", r["size"], "samples", r["method"], r["ideal_samples"],
                     r.get("contributing_samples"), r["samples"]))
    for r in res["table2"]["rows"]:
        rows.append(("Table 2 protein isosurface", r["size"], "cells", r["method"], r["ideal_cells"],
                     r.get("contributing_cells"), r["cells"]))
        rows.append(("Table 2 protein translucent", r["size"], "samples", r["method"], r["ideal_samples"],
                     r.get("contributing_samples"), r["samples"]))
    for r in res["table3"]["rows"]:
        rows.append(("Table 3 primary rays", r["size"], "cells", r["method"], r["ideal_primary_cells"],
                     r.get("contributing_primary_cells"), r["primary_cells"]))
        rows.append(("Table 3 shadow rays", r["size"], "cells", r["method"], r["ideal_shadow_cells"], None,
                     r["shadow_cells"]))
    for r in res["visible_woman"]["surfaces"]:
        for m in ("brute", "parc"):
            rows.append((f"Visible Woman {r['surface']}", res["visible_woman"]["size"], "cells", m, r["ideal_cells"],
                         r.get("contributing_cells"), r[f"{m}_cells"]))
    md = ["## 5. Ideal bound", "",
          "Sobierajski & Avila's ideal caster looks only at the *contributing* cells of each ray, those where "
          "the ray meets the surface or a value of non-zero opacity. Which they are depends on the ray; what "
          "a caster can know before casting is the *possibly contributing* cells, whose value range holds "
          "the isovalue or meets the non-zero opacity. *Ideal* is what a caster that classifies whole cells, "
          "as PARC does, touches at least: for isosurfaces the cells whose range holds the isovalue before "
          "the hit, exactly the cubics `brute` solves, and `parc` too with supercells of a cell or more "
          "(sub-cell supercells bound parts of cells, and can skip a cell whose range holds the isovalue "
          "where the ray misses that part); for translucent volumes the samples inside cells whose value "
          "range has non-zero opacity, before the ray terminates (`parc.ideal`). *Contributing* is the "
          "paper's ideal within it: the surface's cell of each ray that hits (a shadow ray's is not "
          "counted: –), and the samples of non-zero opacity, which every caster of the lattice takes.", ""]
    md.append(_table(("scene", "image (px²)", "unit", "method", "ideal (×10³)", "contributing (×10³)",
                      "touched (×10³)", "touched / ideal"),
                     [(s, n, u, m, _k(i), "–" if c is None else _k(c), _k(t), f"{t / i:.1f}" if i else "–")
                      for s, n, u, m, i, c, t in rows]))
    md.append("")
    return md, rows
