"""Speed against error: each method's median time and its image error against `brute`, in one run."""
from __future__ import annotations

import statistics
import time
from collections.abc import Iterator

import numpy as np

from data_tools import InputError
from data_tools.info import exact_text
from data_tools.volume import text_or_flag

from .renderer import render
from .skip import expect_frames
from .workspace import check_scene_memory

#: The most timed renders (and warm-ups) a comparison takes: a median of more measures nothing
#: new, and a count past it is more likely a slip of the keyboard than a plan to wait for days.
MAX_REPEATS = 10_000


def image_error(result, reference, cell_size):
    """Error of one render against the reference render of the same scene.

    Returns a dict: ``hit_mismatches`` (pixels hit in one and not the
    other), ``max_depth_cells`` (largest |Δdepth| over pixels hit in both,
    in units of ``cell_size``), ``max_color`` (largest |Δ| over RGBA
    channels), ``rmse`` and ``psnr`` (dB, ``inf`` when identical) over RGBA.
    """
    a, b = result.depth, reference.depth
    hit_a, hit_b = np.isfinite(a), np.isfinite(b)
    both = hit_a & hit_b
    dd = np.abs(a[both] - b[both]) / cell_size
    diff = result.image.astype(np.float64) - reference.image.astype(np.float64)
    rmse = float(np.sqrt(np.mean(diff * diff)))
    return {
        "hit_mismatches": int((hit_a != hit_b).sum()),
        "max_depth_cells": float(dd.max()) if dd.size else 0.0,
        "max_color": float(np.abs(diff).max()) if diff.size else 0.0,
        "rmse": rmse,
        "psnr": float("inf") if rmse == 0.0 else float(20 * np.log10(1.0 / rmse)),
    }


def compare(scene, methods=("brute", "parc"), *, repeats=3, warmup=1, options=None, progress=None):
    """Render a scene with each method; report speed against `brute` and error against its image.

    Parameters
    ----------
    scene : Scene
    methods : sequence of str
        Methods to run; ``"brute"`` is always run (first) as the reference.
    repeats : int, default 3
        Timed renders per method (at most `MAX_REPEATS`, 10,000), taken in rounds of one render per method
        (so that a drift in the machine's speed reaches every method
        alike); the median wall time of a whole `render` call is reported.
    warmup : int, default 1
        Untimed renders first (JIT compilation, OpenGL context, caches).
    options : dict of method -> dict, optional
        Keyword arguments for `render` per method, e.g.
        ``{"parc": {"supercell": 4}}``. A method name may carry a label after
        a colon (``"parc:4"``) so one method appears with several options.
    progress : callable(str) or None
        Told, as a line of text, which method warms up and, when a round
        lasts a while (`SLOW_ROUND`, 2 seconds), which round is timed.

    Returns
    -------
    list of dict
        One row per method: ``method``, ``seconds`` (the median wall time of a `render` call:
        its frame, ``phases["total"]``, and also its argument and memory checks, which
        for a small image can be as long as the frame), ``phases`` (seconds per phase of
        the median run), ``speedup`` against brute (brute's ``seconds`` over the method's),
        the `image_error` fields (depths in cells of the first volume's smallest spacing, the
        strictest reading of "a cell"; ``psnr`` is ``inf`` for an image identical to brute's,
        which strict JSON lacks: `parc.outputs.to_json` writes it as null, as ``--json`` does),
        ``cells_visited``, ``cubic_solves``, ``samples``, ``shadow_cells``, ``shadow_solves``,
        ``shadow_samples``, ``shadow_rays``, ``hits``,
        ``polygons``, ``supercell`` (where `render` gives its volumes' sizes under ``volumes``,
        the size they share, else None, and ``supercells`` each's), ``pixels``, ``opengl_share`` (the
        median run's share of time in `OPENGL_PHASES`), ``speedup_low`` and
        ``speedup_high`` (the lowest and highest of the rounds' own ratios,
        each round timing every method once), ``parameters`` (what was rendered, as `render`'s
        stats give it: size and camera, and the volume's own fields where one volume is cast
        alone (with ``lights`` and ``shadows`` where a translucent one has them), else
        ``volumes``, ``lights`` and ``shadows``: for several volumes, an isosurface with lights,
        or shaded samples with shadows, as `parc.render`'s ``stats`` says) and ``repeats``.
    """
    _check_runs("compare", scene, repeats, warmup)
    names = method_names(methods)
    options = _method_options(names, options)
    _check_progress(progress, "a line of text")
    check_scene_memory(scene, kept_images=len(names))
    check_options(scene, options)
    check_opengl(scene, names)
    vol = scene.volumes[0].volume
    cell = float(min(vol.spacing))
    runs = {name: [] for name in names}
    first = {}
    # Every frame is timed as one of many: tables a lone frame would go without are built
    # from the warm-up on.
    expect_frames(scene)
    t0 = time.perf_counter()
    for name in names:
        if progress:
            progress(f"warming up {name}")
        for _ in range(warmup):
            render(scene, method=name.split(":")[0], **options.get(name, {}))
    # Rounds are announced once one is known to take a while: the warm-up renders
    # each method as a round does (or, with none, the first round tells).
    slow = warmup > 0 and time.perf_counter() - t0 > warmup * SLOW_ROUND
    # Round by round, every method once per round: the machine's speed
    # drifts (by up to 1.5x over a minute on a shared one), and timing all
    # of brute's runs before any of parc's let the drift into the ratio.
    # Only each method's first image is kept (for the error): holding every
    # run's image made each later render fault in fresh pages, 7 ms of a
    # 512x512 shading phase that a method timed once memory was being
    # reused did not pay.
    for r in range(repeats):
        if progress and slow:
            progress(f"timing round {r + 1} of {repeats}")
        t_round = time.perf_counter()
        for name in names:
            t0 = time.perf_counter()
            out = render(scene, method=name.split(":")[0], **options.get(name, {}))
            out.stats["seconds"]["wall"] = time.perf_counter() - t0
            runs[name].append({"seconds": out.stats["seconds"]})     # a run's timings; its stats are the first's
            first.setdefault(name, out)
            del out
        slow = slow or time.perf_counter() - t_round > SLOW_ROUND
    reference = first["brute"]
    rows = []
    for name in names:
        med = statistics.median(s["seconds"]["wall"] for s in runs[name])
        # Phases of one run, the median one (the lower of the middle two):
        # medians taken phase by phase need not add up to any run's total.
        middle = sorted(runs[name], key=lambda s: s["seconds"]["wall"])[(repeats - 1) // 2]
        phases = {k: v for k, v in middle["seconds"].items() if k != "wall"}
        res = first[name]
        s = res.stats
        row = {"method": name, "seconds": med, "phases": phases,
               "cells_visited": s["cells_visited"], "cubic_solves": s["cubic_solves"],
               "samples": s.get("samples", 0),
               "shadow_cells": s.get("shadow_cells", 0), "shadow_solves": s.get("shadow_solves", 0),
               # A translucent volume dims shadow rays by sampling: that work too, as render's stats give it.
               "shadow_samples": s.get("shadow_samples", 0), "shadow_rays": s.get("shadow_rays", 0),
               "hits": s["hits"], "pixels": s["pixels"], "polygons": s.get("polygons", 0),
               "supercell": s.get("supercell"),
               # What was compared, in every row: rows saved from several runs tell which is which.
               "parameters": s["parameters"], "repeats": repeats}
        if "volumes" in s:
            # A scene's volumes each have their grid: the one size they share, if they do, and each's.
            sizes = [v.get("supercell") for v in s["volumes"]]
            row["supercells"] = sizes
            row["supercell"] = sizes[0] if sizes and all(z == sizes[0] for z in sizes) else None
        total = phases.get("total", 0.0)
        row["opengl_share"] = (sum(phases.get(k, 0.0) for k in OPENGL_PHASES) / total) if total > 0 else 0.0
        row.update(image_error(res, reference, cell))
        rows.append(row)
    base = rows[0]["seconds"]
    brute_walls = [s["seconds"]["wall"] for s in runs["brute"]]
    for row, name in zip(rows, names):
        row["speedup"] = base / row["seconds"] if row["seconds"] > 0 else float("inf")
        # The same ratio round by round: its spread is what the machine's
        # drift and noise did to this run.
        rounds = [b / s["seconds"]["wall"] for b, s in zip(brute_walls, runs[name])]
        row["speedup_low"], row["speedup_high"] = min(rounds), max(rounds)
    return rows


#: Phases spent in OpenGL: the depth pass (`parc.raster`), the bit-plane pass
#: (`parc.bitplanes`) and the light buffers' passes (`parc.lights`).
OPENGL_PHASES = ("raster", "raster_bits", "raster_lights")


#: What `compare`'s options may set per method (the rest of `render`'s arguments it sets itself).
RENDER_OPTIONS = {"supercell", "buffers", "blocks", "light_buffer"}


def method_names(methods, what="methods"):
    """``methods`` as a list, brute first (named or not); a string may name them as ``"brute,parc"``.
    A name given twice is refused: it would be timed once. ``what`` names the argument in
    messages (``--methods`` on the command line)."""
    from .renderer import METHODS
    given = methods
    if isinstance(methods, str):
        pieces = [m.strip() for m in methods.split(",")]
        if any(pieces) and not all(pieces):
            raise InputError(f"{what} {methods!r} has an empty name between commas")
        methods = methods.split(",")
    if isinstance(methods, (set, frozenset)):
        # Its order changes from run to run, and the rows of the table with it.
        raise InputError(f"{what} must be in an order, as a list or tuple, not a set: {methods!r}")
    shown = given           # in refusals: what was given, but an iterator's items (its repr names none)
    try:
        methods = list(methods)         # a generator is read once, here
        if isinstance(given, Iterator):
            shown = methods
        if not all(isinstance(m, str) for m in methods):
            raise TypeError
        names = [m.strip() for m in methods if m.strip()]
    except (TypeError, AttributeError):
        raise InputError(f"{what} must be names such as ('brute', 'parc'), got {shown!r}") from None
    if not names:
        raise InputError(f"{what} names no method, got {shown!r}; name some, such as 'brute,parc'")
    for m in names:
        if m.endswith(":"):
            raise InputError(f"{what}: {m!r} has an empty label; write one after the colon, as in 'parc:a'")
        if m.split(":")[0] not in METHODS:
            raise InputError(f"{what}: unknown method {m!r}; choose from {', '.join(METHODS)} "
                             "(a label may follow a colon, as in 'parc:a', to time a method twice)")
    twice = sorted({m for m in names if names.count(m) > 1})
    if twice:
        raise InputError(f"{what} names {twice[0]!r} twice; to time a method twice, label each run "
                         "after a colon, as in 'parc:a,parc:b'")
    return ["brute"] + [m for m in dict.fromkeys(names) if m != "brute"]


def work_per_pixel(scene, methods=("brute", "parc"), *, options=None):
    """Each method's work per pixel, from one more render of ``scene`` each, untimed: a dict of
    method name to (H, W) int64, cells visited for isosurfaces and samples taken for translucent
    volumes (`RenderResult.work`), as the heat maps beside `compare`'s table draw them
    (``parc compare --work``). ``methods`` and ``options`` as `compare` takes them."""
    names = method_names(methods)
    options = _method_options(names, options)
    check_options(scene, options)
    return {name: render(scene, method=name.split(":")[0], work=True, **options.get(name, {})).work
            for name in names}


def _method_options(names, options):
    """``options`` checked against the methods ``names`` run: a dict of method -> dict of render() arguments."""
    if options is None:
        options = {}
    if not isinstance(options, dict) or not all(isinstance(o, dict) for o in options.values()):
        raise InputError(f"options must map method names to dicts of render() arguments, got {options!r}")
    options = dict(options)
    unused = sorted(set(options) - set(names))
    if unused:
        raise InputError(f"options for {', '.join(map(repr, unused))}, which is not among the methods run")
    for name, opts in options.items():
        _check_render_options(name, opts)
    return options


def _check_render_options(name, opts):
    """Refuse an option for method ``name`` that `render` does not take."""
    unknown = sorted(set(opts) - RENDER_OPTIONS)
    if unknown:
        raise InputError(f"options for {name!r}: {', '.join(map(repr, unknown))} is not a render() option; "
                         f"known: {', '.join(sorted(RENDER_OPTIONS))}")


def check_opengl(scene, names):
    """For a run that includes parc, make the OpenGL context (as a render does, one thread at a
    time) and refuse an image past its viewport limit: no OpenGL, or too large an image, is said
    before brute's warm-up or a note, not after. Called once every argument is checked, so that
    their own refusals neither wait on making the context nor hide behind its absence."""
    if any(str(name).split(":")[0] == "parc" for name in names):
        from .gl import check_viewport, release_context
        from .renderer import RENDER_LOCK
        with RENDER_LOCK:
            try:
                check_viewport(*scene.size)
            finally:
                release_context()


def check_options(scene, options):
    """Refuse what `render` would refuse about each method's options (``buffers``, ``blocks``,
    ``light_buffer``, a supercell size no volume of the scene can take), before any render is
    timed: brute's warm-up (or a sweep's reference) may take minutes."""
    from .renderer import check_arguments
    for name, opts in options.items():
        check_arguments(scene, name.split(":")[0], **opts)


#: What each phase of a frame holds, for the legend under `format_table`.
PHASE_NOTES = {
    "cast": "the ray walks with their cubics or samples (an isosurface without lights shades each hit "
            "as it finds it)",
    "classify": "supercells labelled possibly contributing (cell ranges are computed once per volume)",
    "proxy": "the outer faces of those supercells (0 when reused)",
    "raster": "OpenGL near/far pass and read-back",
    "raster_bits": "OpenGL bit-plane pass and read-back",
    "raster_lights": "OpenGL light buffers for shadow rays",
    "setup": "camera, work arrays, and a volume cast alone its skip tables (built once, then kept with "
             "the volume; among several volumes, under cast and shadow)",
    "shade": "lighting the hits of surfaces under lights or among other volumes, and translucent samples "
             "with shadows",
    "shadow": "shadow rays",
    "total": "the whole frame",
}


#: The rest of `format_table`'s columns, for the legend under it: units and what each counts or compares.
COLUMN_NOTES = {
    "time s": "the median wall time of one render call, in seconds.",
    "cells/px, samples/px, hits/px": "cells visited (isosurfaces), samples taken (translucent volumes) and "
                                     "pixels where a surface is hit, over the image's pixels; polygons: the "
                                     "proxy faces rasterized.",
    "hit≠, max Δdepth, max Δcolour, RMSE, PSNR": "the image against brute's: pixels hit in one and not the "
                                                 "other; the largest depth difference where both hit, in cells "
                                                 "of the first volume's smallest spacing; the largest difference "
                                                 "and the root mean square over RGBA channels (0 to 1); PSNR in "
                                                 "dB, inf where the images are identical.",
}


#: Under a supercell sweep's table: what its rows' labels mean.
SUPERCELL_SWEEP_NOTE = ("parc:S: parc with supercells of S cells a side (SxTxU: S by T by U cells); "
                        "the images never depend on S, its times and counts do.")


def format_table(rows, notes=()):
    """A readable terminal table of `compare` rows; ``notes``, lines of text, join its legend."""
    head = ("method", "time s", "speedup", "rounds", "OpenGL", "cells/px", "cubics/px", "samples/px", "hits/px",
            "polygons", "hit≠", "max Δdepth", "max Δcolour", "RMSE", "PSNR")
    lines = []
    for r in rows:
        px = max(r["pixels"], 1)
        gl = r["opengl_share"]
        lines.append((r["method"], f"{r['seconds']:.4f}", f"{ratio_text(r['speedup'])}x",
                      f"{ratio_text(r['speedup_low'])}-{ratio_text(r['speedup_high'])}x",
                      f"{100 * gl:.0f}%" if gl else "-",
                      f"{r['cells_visited'] / px:.1f}", f"{r['cubic_solves'] / px:.2f}",
                      f"{r.get('samples', 0) / px:.1f}",
                      f"{r['hits'] / px:.3f}", f"{r['polygons']:,}", str(r["hit_mismatches"]),
                      f"{r['max_depth_cells']:.2e}", f"{r['max_color']:.2e}", f"{r['rmse']:.2e}",
                      "inf" if r["psnr"] == float("inf") else f"{r['psnr']:.1f}"))
    widths = [max(len(h), *(len(l[i]) for l in lines)) for i, h in enumerate(head)]
    fmt = "  ".join(("{:<%d}" if i == 0 else "{:>%d}") % w for i, w in enumerate(widths))
    out = [fmt.format(*head), fmt.format(*("-" * w for w in widths))]
    out += [fmt.format(*l) for l in lines]
    out.append("speedup: median against median; rounds: the lowest and highest ratio within one round "
               "(every method once).")
    out.append("OpenGL: the share of the frame spent in OpenGL passes (phases " + ", ".join(OPENGL_PHASES) + ").")
    out.append("cubics/px: cells whose range holds the isovalue, up to the hit: the fewest cells per pixel "
               "a caster that bounds whole cells can visit (sub-cell supercells can visit fewer).")
    out += [f"{k}: {v}" for k, v in COLUMN_NOTES.items()]
    out += list(notes)
    phases = sorted({k for r in rows for k in r["phases"]})
    out.append("")
    out.append("seconds per phase (the median run): " + ", ".join(phases))
    for r in rows:
        out.append(f"  {r['method']:<10} " + "  ".join(f"{k}={r['phases'].get(k, 0.0):.4f}" for k in phases))
    out += [f"  {k}: {PHASE_NOTES[k]}" for k in phases if k in PHASE_NOTES]
    return "\n".join(out)


#: A round of `compare` (every method once) longer than this, in seconds, is announced.
SLOW_ROUND = 2.0


def _check_runs(what, scene, repeats, warmup):
    from .scene import Scene
    if not isinstance(scene, Scene):
        raise InputError(f"{what} takes a Scene, got {type(scene).__name__}")
    for name, value, least in (("repeats", repeats, 1), ("warmup", warmup, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise InputError(f"{name} must be a whole number >= {least}, got {value!r}")
        if value > MAX_REPEATS:
            raise InputError(f"{name} must be at most {MAX_REPEATS}, got {value}")


def _check_progress(progress, of):
    if progress is not None and not callable(progress):
        raise InputError(f"progress must be a function of {of}, got {progress!r}")


def step_sweep(scene, steps, *, repeats=3, warmup=1, progress=None, options=None):
    """Speed against error over sample steps, for a translucent volume.

    Each step is rendered with ``brute`` and ``parc``; the error is taken
    against ``brute`` at a quarter of the finest step (the reference), and
    ``parc`` is also compared with ``brute`` at the same step (expected: 0).

    Returns
    -------
    list of dict
        Per step: ``step``, ``brute_seconds``, ``parc_seconds``, ``speedup``,
        ``brute_samples``, ``parc_samples``, ``max_color`` / ``rmse`` / ``psnr``
        against the reference, ``parc_vs_brute`` (max |Δcolour|), and as in `compare`
        ``parameters`` (what was rendered at that step) and ``repeats``.

    ``options``: `render` keyword arguments for ``parc`` (``buffers``,
    ``blocks``, ``supercell``...), as in `compare`.
    """
    from dataclasses import replace

    from .scene import Scene, Translucent
    _check_runs("a step sweep", scene, repeats, warmup)
    _check_progress(progress, "a line of text")
    vis = scene.volumes[0]
    if len(scene.volumes) != 1 or not isinstance(vis, Translucent):
        raise InputError("a step sweep takes a scene of one translucent volume (--tf)")
    if options is None:
        options = {}
    if not isinstance(options, dict):
        raise InputError(f"options must be a dict of render() arguments, got {options!r}")
    options = dict(options)
    _check_render_options("parc", options)
    # Options parc would refuse (a supercell size the volume cannot take) are refused before the
    # reference is rendered, as `compare` does.
    check_options(scene, {"parc": options})
    try:
        items = None if isinstance(steps, (str, bytes)) else list(steps)
        if any(text_or_flag(v) for v in items):
            raise TypeError
        values = sorted({float(v) for v in items}, reverse=True)
    except (TypeError, ValueError, OverflowError):
        values = []
    if not values or not all(np.isfinite(values)) or min(values) <= 0:
        raise InputError(f"sweep steps must be a list of positive numbers, got {steps!r}")
    steps = values
    # Held at once: the reference and the step's image from each method; earlier steps' are let go.
    check_scene_memory(scene, kept_images=3)

    # The lights shine, and shadows fall, on shaded samples alone; given to another volume they
    # would be said to change nothing again at every step.
    lit = vis.shade and vis.mode == "composite"

    def at(step):
        return Scene(camera=scene.camera, size=scene.size, background=scene.background,
                     volumes=[replace(vis, step=step, tf=vis.tf)], lights=scene.lights if lit else (),
                     shadows=scene.shadows and lit and bool(scene.lights))

    # Refuse a step the volume cannot take before any work, the reference's too.
    for step in steps:
        at(step)
    try:
        at(min(steps) / 4)
    except InputError as exc:
        raise InputError(f"the reference step, a quarter of the finest ({min(steps) / 4:g}), "
                         f"is too small: {exc}") from None

    check_opengl(scene, ["parc"])
    if progress:
        progress(f"reference at step {min(steps) / 4:g}")
    reference = render(at(min(steps) / 4), method="brute")
    cell = float(min(vis.volume.spacing))
    rows = []
    for step in steps:
        if progress:
            progress(f"step {step:g}")
        row = {"step": step}
        kwargs = {"brute": {}, "parc": options}
        for _ in range(warmup):
            for method in ("brute", "parc"):
                render(at(step), method=method, **kwargs[method])
        # In rounds, as `compare` times: the machine's drift stays out of the ratio.
        results = {}
        times = {"brute": [], "parc": []}
        for _ in range(repeats):
            for method in ("brute", "parc"):
                t0 = time.perf_counter()
                results[method] = render(at(step), method=method, **kwargs[method])
                times[method].append(time.perf_counter() - t0)
        for method in ("brute", "parc"):
            row[f"{method}_seconds"] = statistics.median(times[method])
            row[f"{method}_samples"] = results[method].stats["samples"]
        err = image_error(results["brute"], reference, cell)
        row.update({k: err[k] for k in ("max_color", "rmse", "psnr")})
        row["parc_vs_brute"] = image_error(results["parc"], results["brute"], cell)["max_color"]
        row["speedup"] = row["brute_seconds"] / row["parc_seconds"]
        row["parameters"], row["repeats"] = results["parc"].stats["parameters"], repeats    # as `compare`'s
        rows.append(row)
    return rows


def ratio_text(x):
    """A speedup to two decimals, or two significant digits below 0.01 (a slow method is not 0.00x)."""
    return f"{x:.2f}" if not 0 < x < 0.01 else f"{x:.2g}"


def format_step_table(rows):
    """A terminal table of `step_sweep` rows."""
    # Every digit a step needs (with :g, 0.5 and 0.5000001 both read "0.5"), in a column as wide as the longest.
    labels = [exact_text(r["step"]) for r in rows]
    sw = max([8] + [len(t) for t in labels])
    out = [f"{'step':>{sw}}  {'brute s':>8}  {'parc s':>8}  {'speedup':>7}  {'samples brute':>13}  "
           f"{'samples parc':>12}  {'max Δ vs fine':>13}  {'PSNR':>6}  {'parc≠brute':>10}"]
    for r, label in zip(rows, labels):
        psnr = "inf" if r["psnr"] == float("inf") else f"{r['psnr']:.1f}"
        out.append(f"{label:>{sw}}  {r['brute_seconds']:>8.4f}  {r['parc_seconds']:>8.4f}  "
                   f"{ratio_text(r['speedup']):>6}x  {r['brute_samples']:>13,}  {r['parc_samples']:>12,}  "
                   f"{r['max_color']:>13.2e}  {psnr:>6}  {r['parc_vs_brute']:>10.1e}")
    if rows:
        fine = min(r["step"] for r in rows) / 4
        out.append(f"max Δ vs fine, PSNR: brute's image against brute's at step {exact_text(fine)} (a quarter of the "
                   "finest), the reference; parc≠brute: max |Δcolour| between the methods at one step.")
        out.append("step: world distance between samples; brute s, parc s: median seconds of a render; "
                   "max Δ and parc≠brute over RGBA channels (0 to 1); PSNR in dB, inf where identical.")
    return "\n".join(out)
