"""`parc.comparison.image_error`: the error figures `parc compare` prints, on images small enough to work out by hand.

Truth: the definitions in the function's docstring, evaluated here on
2x2 renders whose differences are chosen to give round numbers.
"""
import math
import re

import numpy as np
import pytest

from parc import RenderResult
from parc.comparison import image_error


def _result(depth, image):
    return RenderResult(image=np.asarray(image, np.float32), depth=np.asarray(depth, np.float64), stats={})


def test_image_error_by_hand():
    inf = math.inf
    image = np.zeros((2, 2, 4))
    ref = _result([[1.0, 2.0], [inf, 5.0]], image)
    changed = image.copy()
    changed[1, 1, 2] = 0.5            # one channel of sixteen differs by 0.5
    res = _result([[1.5, inf], [3.0, 5.0]], changed)
    err = image_error(res, ref, 0.25)
    # Hit in one image and not in the other: pixel (0, 1) in the reference only, (1, 0) in the result only.
    assert err["hit_mismatches"] == 2
    # Hit in both: |1.5 - 1| = 0.5 world units, two cells of 0.25; |5 - 5| = 0.
    assert err["max_depth_cells"] == 2.0
    assert err["max_color"] == 0.5
    rmse = math.sqrt(0.25 / 16)       # 0.125
    assert err["rmse"] == pytest.approx(rmse, rel=1e-12)
    assert err["psnr"] == pytest.approx(20 * math.log10(1 / rmse), rel=1e-12)     # 18.06 dB


def test_an_image_darker_and_nearer_than_the_reference_has_the_same_error():
    # Errors are magnitudes: a result below the reference counts as much as one above it.
    inf = math.inf
    image = np.full((2, 2, 4), 0.75)
    ref = _result([[1.0, 2.0], [inf, 5.0]], image)
    darker = image.copy()
    darker[1, 1, 2] = 0.25
    err = image_error(_result([[0.5, 2.0], [inf, 5.0]], darker), ref, 0.25)
    assert err["max_depth_cells"] == 2.0 and err["max_color"] == 0.5
    assert err["rmse"] == pytest.approx(math.sqrt(0.25 / 16), rel=1e-12)


def test_identical_images_have_no_error():
    ref = _result([[1.0, math.inf]], np.full((1, 2, 4), 0.3))
    err = image_error(ref, ref, 1.0)
    assert err == {"hit_mismatches": 0, "max_depth_cells": 0.0, "max_color": 0.0, "rmse": 0.0, "psnr": math.inf}


def test_no_pixel_hit_in_both_has_no_depth_error():
    image = np.zeros((1, 2, 4))
    err = image_error(_result([[1.0, math.inf]], image), _result([[math.inf, 7.0]], image), 1.0)
    assert err["hit_mismatches"] == 2 and err["max_depth_cells"] == 0.0


def test_a_rows_timings_come_from_its_median_run(monkeypatch):
    """Renders of scripted lengths on a clock of their own: the row's time is each method's
    median, its phases and OpenGL share the median run's (raster and raster_bits both), the
    rounds' ratios give the spread, and a scene whose volumes have different supercells has
    no one size."""
    import parc.comparison as comparison
    from data_tools.synthetic import blobs
    from parc import Camera, Isosurface, Scene
    clock = [0.0]

    class Clock:
        @staticmethod
        def perf_counter():
            return clock[0]

    walls = {"brute": [9.0, 4.0, 2.0, 3.0], "parc": [9.0, 1.0, 0.25, 0.5]}     # a warm-up, then 3 rounds

    def scripted(scene, method="brute", **options):
        wall = walls[method].pop(0)
        clock[0] += wall
        seconds = {"total": wall, "cast": wall / 2, "raster": wall / 4, "raster_bits": wall / 8}
        stats = {"seconds": seconds, "cells_visited": 1, "cubic_solves": 0, "hits": 0, "pixels": 64,
                 "polygons": 0, "supercell": None, "parameters": {}, "volumes": [{"supercell": 2.0}, {"supercell": 4.0}]}
        return RenderResult(image=np.zeros((8, 8, 4), np.float32), depth=np.full((8, 8), np.inf), stats=stats)

    monkeypatch.setattr(comparison, "time", Clock)
    monkeypatch.setattr(comparison, "render", scripted)
    vol = blobs(6, seed=1)
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(8, 8), volumes=[Isosurface(vol, 100.5)])
    brute, parc_row = comparison.compare(scene, methods=("brute", "parc"), repeats=3)
    assert brute["seconds"] == 3.0 and parc_row["seconds"] == 0.5
    assert parc_row["phases"]["total"] == 0.5 and parc_row["phases"]["raster_bits"] == 0.0625
    assert parc_row["opengl_share"] == pytest.approx(0.375)
    assert parc_row["speedup"] == 6.0
    assert (parc_row["speedup_low"], parc_row["speedup_high"]) == (4.0, 8.0)       # 4/1, 2/0.25, 3/0.5
    assert parc_row["supercell"] is None and parc_row["supercells"] == [2.0, 4.0]


def _scripted(monkeypatch, walls, phases_of, depth_of=None, image_of=None, size=(2, 2), stats_of=None):
    """compare/step_sweep's render and clock replaced: each render takes walls[method].pop(0) s."""
    import parc.comparison as comparison
    clock = [0.0]

    class Clock:
        @staticmethod
        def perf_counter():
            return clock[0]

    def scripted(scene, method="brute", **options):
        wall = walls[method].pop(0)
        clock[0] += wall
        w, h = size
        depth = np.full((h, w), 1.0) if depth_of is None else depth_of(method)
        image = np.zeros((h, w, 4), np.float32) if image_of is None else image_of(method)
        stats = {"seconds": phases_of(wall), "cells_visited": 1, "cubic_solves": 0, "hits": 0, "pixels": w * h,
                 "polygons": 0, "supercell": None, "parameters": {}, "samples": 1}
        if stats_of is not None:
            stats.update(stats_of(method))
        return RenderResult(image=image, depth=depth, stats=stats)

    monkeypatch.setattr(comparison, "time", Clock)
    monkeypatch.setattr(comparison, "render", scripted)
    return comparison


def test_opengl_share_counts_the_light_buffers_pass(monkeypatch):
    # A lit frame's OpenGL time is its depth, bit-plane and light-buffer passes: 1 + 0.5 + 2 of 8 s.
    from data_tools.synthetic import blobs
    from parc import Camera, Isosurface, Scene
    phases = lambda wall: {"total": wall, "cast": wall / 2, "raster": wall / 8, "raster_bits": wall / 16,  # noqa: E731
                           "raster_lights": wall / 4}
    comparison = _scripted(monkeypatch, {"brute": [8.0], "parc": [8.0]}, phases)
    vol = blobs(6, seed=1)
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(2, 2), volumes=[Isosurface(vol, 100.5)])
    _, row = comparison.compare(scene, repeats=1, warmup=0)
    assert row["opengl_share"] == pytest.approx((1.0 + 0.5 + 2.0) / 8.0, rel=1e-12)


def test_compare_gives_the_depth_error_in_the_smallest_spacing(monkeypatch):
    # Spacing (0.5, 1, 2): a cell is 0.5 world units (the finest), so a depth 0.25 off is half a cell.
    from data_tools import Volume
    from parc import Camera, Isosurface, Scene
    depth = {"brute": np.array([[3.0, 4.0], [np.inf, 5.0]]), "parc": np.array([[3.25, 4.0], [np.inf, 5.0]])}
    comparison = _scripted(monkeypatch, {"brute": [1.0], "parc": [1.0]}, lambda w: {"total": w},
                           depth_of=lambda m: depth[m])
    vol = Volume(np.arange(64, dtype=np.float32).reshape(4, 4, 4), spacing=(0.5, 1.0, 2.0))
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(2, 2), volumes=[Isosurface(vol, 10.5)])
    brute, row = comparison.compare(scene, repeats=1, warmup=0)
    assert brute["max_depth_cells"] == 0.0
    assert row["max_depth_cells"] == pytest.approx(0.25 / 0.5, rel=1e-12)
    assert row["hit_mismatches"] == 0


def test_format_table_puts_each_figure_under_its_heading():
    from parc.comparison import format_table
    row = {"method": "parc", "seconds": 0.5, "speedup": 6.0, "speedup_low": 4.0, "speedup_high": 8.0,
           "opengl_share": 0.25, "cells_visited": 300, "cubic_solves": 30, "samples": 0, "hits": 50,
           "pixels": 100, "polygons": 1234, "hit_mismatches": 7, "max_depth_cells": 0.125,
           "max_color": 0.5, "rmse": 0.125, "psnr": 18.0618, "phases": {"total": 0.5}}
    head, _, line = format_table([row]).splitlines()[:3]
    names = ["method", "time s", "speedup", "rounds", "OpenGL", "cells/px", "cubics/px", "samples/px",
             "hits/px", "polygons", "hit≠", "max Δdepth", "max Δcolour", "RMSE", "PSNR"]
    cells = line.split()
    assert len(cells) == len(names) and all(n in head for n in names)
    got = dict(zip(names, cells))
    assert got == {"method": "parc", "time s": "0.5000", "speedup": "6.00x", "rounds": "4.00-8.00x",
                   "OpenGL": "25%", "cells/px": "3.0", "cubics/px": "0.30", "samples/px": "0.0",
                   "hits/px": "0.500", "polygons": "1,234", "hit≠": "7", "max Δdepth": "1.25e-01",
                   "max Δcolour": "5.00e-01", "RMSE": "1.25e-01", "PSNR": "18.1"}


def test_every_column_of_the_table_is_explained_under_it_with_its_unit():
    # A reader of the table alone cannot tell cells from world units, or dB from a ratio: the legend
    # names each heading (alone or in a list before a colon) and the units of those that have one.
    from parc.comparison import format_table
    row = {"method": "parc", "seconds": 0.5, "speedup": 6.0, "speedup_low": 4.0, "speedup_high": 8.0,
           "opengl_share": 0.25, "cells_visited": 300, "cubic_solves": 30, "samples": 0, "hits": 50,
           "pixels": 100, "polygons": 1234, "hit_mismatches": 7, "max_depth_cells": 0.125,
           "max_color": 0.5, "rmse": 0.125, "psnr": 18.0618, "phases": {"total": 0.5}}
    lines = format_table([row]).splitlines()
    headings = [h for h in re.split(r"\s{2,}", lines[0].strip()) if h != "method"]
    legend = lines[3:lines.index("")]
    text = "\n".join(legend)
    # Each heading opens a legend line, or is listed there before a colon: "hit≠, max Δdepth, ...: ...".
    named = [h for h in headings if re.search(rf"(^|, |; ){re.escape(h)}(: |, )", text, re.M)]
    assert named == headings
    assert re.search(r"time s: [^\n]*seconds", text)
    assert re.search(r"max Δdepth[^\n]*in cells of the first volume's smallest spacing", text)
    assert re.search(r"PSNR[^\n]*PSNR in dB", text)


def test_the_terminal_table_shows_the_rmse_against_brute(monkeypatch):
    # The table is what `parc compare` prints: every error figure of a row is in it, RMSE too.
    # parc's image is 0.5 off brute's in one channel of sixteen: RMSE sqrt(0.25 / 16) = 0.125.
    from data_tools.synthetic import blobs
    from parc import Camera, Isosurface, Scene

    def image_of(method):
        img = np.zeros((2, 2, 4), np.float32)
        if method == "parc":
            img[1, 0, 1] = 0.5
        return img

    comparison = _scripted(monkeypatch, {"brute": [1.0], "parc": [1.0]}, lambda w: {"total": w},
                           image_of=image_of)
    vol = blobs(6, seed=1)
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(2, 2), volumes=[Isosurface(vol, 100.5)])
    rows = comparison.compare(scene, repeats=1, warmup=0)
    head, _, brute, parc_line = comparison.format_table(rows).splitlines()[:4]
    # The last two columns, RMSE and PSNR (headings with spaces split into several words).
    assert head.split()[-2:] == ["RMSE", "PSNR"]
    assert brute.split()[-2:] == ["0.00e+00", "inf"] and parc_line.split()[-2:] == ["1.25e-01", "18.1"]


def test_step_sweep_speedup_and_error_by_hand(monkeypatch):
    # brute 4 s, parc 1 s at the one step: 4x. brute's image differs from the reference (step 0.125)
    # by 0.5 in one channel of 16: max 0.5, RMSE sqrt(0.25 / 16) = 0.125; parc equals brute.
    from data_tools.synthetic import blobs
    from parc import Camera, Scene, Translucent
    calls = []

    def image_of(method):
        calls.append(method)
        img = np.zeros((2, 2, 4), np.float32)
        if len(calls) > 1:                 # the first render is the reference
            img[0, 1, 2] = 0.5
        return img

    comparison = _scripted(monkeypatch, {"brute": [0.0, 4.0], "parc": [1.0]}, lambda w: {"total": w},
                           image_of=image_of)
    vol = blobs(6, seed=1)
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(2, 2), volumes=[Translucent(vol, "greyscale")])
    (row,) = comparison.step_sweep(scene, [0.5], repeats=1, warmup=0)
    assert row["brute_seconds"] == 4.0 and row["parc_seconds"] == 1.0 and row["speedup"] == 4.0
    assert row["max_color"] == 0.5 and row["rmse"] == pytest.approx(0.125, rel=1e-12)
    assert row["psnr"] == pytest.approx(20 * math.log10(1 / 0.125), rel=1e-12)
    assert row["parc_vs_brute"] == 0.0


def test_a_step_sweep_renders_a_shaded_volume_under_the_scene_s_lights(gl):
    # brute's error at the step against its reference is that of the lit scene's own renders
    # at the step and at a quarter of it: the sweep's scenes keep the lights.
    from data_tools.synthetic import blobs
    from parc import Camera, PointLight, Scene, TransferFunction, Translucent, render
    from parc.comparison import step_sweep
    vol = blobs(8, seed=3)
    lo, hi = vol.value_range()
    tf = TransferFunction(opacity=[[lo, 0.0], [hi, 0.6]], color=[[lo, 1.0, 0.5, 0.2], [hi, 0.2, 0.6, 1.0]])
    cam = Camera.framing(*vol.bounds)

    def lit(step):
        return Scene(camera=cam, size=(8, 8), volumes=[Translucent(vol, tf, shade=True, step=step)],
                     lights=[PointLight((-20.0, 30.0, 5.0), color=(1.0, 0.2, 0.2))])

    (row,) = step_sweep(lit(0.5), [0.5], repeats=1, warmup=0)
    want = image_error(render(lit(0.5)), render(lit(0.125)), float(min(vol.spacing)))
    assert (row["max_color"], row["rmse"]) == (want["max_color"], want["rmse"])
    assert row["parc_vs_brute"] == 0.0 and len(row["parameters"]["lights"]) == 1


def test_max_colour_and_rmse_count_the_alpha_channel():
    # Coverage is a channel of the image as much as colour is: 0.5 off in one alpha of sixteen channels.
    ref = _result([[1.0, 1.0], [1.0, 1.0]], np.zeros((2, 2, 4)))
    changed = np.zeros((2, 2, 4))
    changed[0, 1, 3] = 0.5
    err = image_error(_result([[1.0, 1.0], [1.0, 1.0]], changed), ref, 1.0)
    assert err["max_color"] == 0.5
    assert err["rmse"] == pytest.approx(math.sqrt(0.25 / 16), rel=1e-12)


def _iso_scene(size=(2, 2)):
    from data_tools.synthetic import blobs
    from parc import Camera, Isosurface, Scene
    vol = blobs(6, seed=1)
    return Scene(camera=Camera.framing(*vol.bounds), size=size, volumes=[Isosurface(vol, 100.5)])


def test_an_even_number_of_rounds_gives_the_mean_of_the_middle_two_and_the_lower_ones_phases(monkeypatch):
    # A warm-up, then 4 rounds. brute sorted 1, 2, 3, 4: median 2.5; parc sorted 0.25, 0.5, 1, 2:
    # median 0.75, and its phases are those of the 0.5 s run (the lower of the middle two).
    walls = {"brute": [9.0, 4.0, 1.0, 3.0, 2.0], "parc": [9.0, 1.0, 0.5, 2.0, 0.25]}
    phases = lambda wall: {"total": wall, "raster": wall / 2 if wall == 0.5 else 0.0}       # noqa: E731
    comparison = _scripted(monkeypatch, walls, phases)
    brute, row = comparison.compare(_iso_scene(), repeats=4)
    assert brute["seconds"] == 2.5 and row["seconds"] == 0.75
    assert row["phases"] == {"total": 0.5, "raster": 0.25} and row["opengl_share"] == 0.5
    assert row["speedup"] == pytest.approx(2.5 / 0.75, rel=1e-12)
    # Round by round: 4/1, 1/0.5, 3/2, 2/0.25.
    assert (row["speedup_low"], row["speedup_high"]) == (1.5, 8.0)
    assert brute["repeats"] == row["repeats"] == 4


def test_a_rows_time_is_the_whole_render_call_and_its_opengl_share_the_frames(monkeypatch):
    # The frame is 0.8 of each 2 s call (the rest: argument and memory checks); OpenGL is 0.4 of 1.6 s.
    phases = lambda wall: {"total": 0.8 * wall, "cast": 0.4 * wall, "raster": 0.2 * wall}    # noqa: E731
    comparison = _scripted(monkeypatch, {"brute": [2.0], "parc": [2.0]}, phases)
    _, row = comparison.compare(_iso_scene(), repeats=1, warmup=0)
    assert row["seconds"] == 2.0
    assert row["phases"] == {"total": 1.6, "cast": 0.8, "raster": 0.4}
    assert row["opengl_share"] == pytest.approx(0.25, rel=1e-12)


def test_a_rows_counts_are_its_own_methods_render_stats(monkeypatch):
    counts = {"brute": dict(cells_visited=101, cubic_solves=11, samples=1001, shadow_cells=21, shadow_solves=22,
                            shadow_samples=23, shadow_rays=24, hits=3, pixels=4, polygons=0),
              "parc": dict(cells_visited=51, cubic_solves=12, samples=501, shadow_cells=31, shadow_solves=32,
                           shadow_samples=33, shadow_rays=34, hits=2, pixels=4, polygons=77)}
    # Both volumes on one grid of 2x2x4 cells: the row has that one size.
    grids = [{"supercell": (2.0, 2.0, 4.0)}, {"supercell": (2.0, 2.0, 4.0)}]
    comparison = _scripted(monkeypatch, {"brute": [1.0], "parc": [1.0]}, lambda w: {"total": w},
                           stats_of=lambda m: {**counts[m], "volumes": grids})
    rows = comparison.compare(_iso_scene(), repeats=1, warmup=0)
    for row in rows:
        assert {k: row[k] for k in counts[row["method"]]} == counts[row["method"]]
        assert row["supercell"] == (2.0, 2.0, 4.0) and row["supercells"] == [(2.0, 2.0, 4.0)] * 2


def test_methods_keep_the_order_given_with_brute_first():
    from parc.comparison import method_names
    assert method_names("parc:b,parc,brute,parc:a") == ["brute", "parc:b", "parc", "parc:a"]


@pytest.mark.parametrize("warmup, walls, rounds", [
    # Three warm-ups of 1 s a round: no round is slow, so none is announced.
    (3, [0.5] * 3 + [0.5] * 3, []),
    # A slow warm-up (3 s): every round is announced, fast ones after it too.
    (1, [1.5] + [0.05] * 3, [1, 2, 3]),
    # No warm-up: the first round, once it proves slow, announces the rest.
    (0, [1.5] + [0.05] * 2, [2, 3]),
])
def test_rounds_are_announced_from_the_first_slow_round_on(warmup, walls, rounds, monkeypatch):
    comparison = _scripted(monkeypatch, {"brute": list(walls), "parc": list(walls)}, lambda w: {"total": w})
    monkeypatch.setattr(comparison, "SLOW_ROUND", 2.0)
    said = []
    comparison.compare(_iso_scene(), repeats=3, warmup=warmup, progress=said.append)
    assert said == ["warming up brute", "warming up parc"] + [f"timing round {r} of 3" for r in rounds]


def test_format_table_gives_each_row_its_own_samples_share_and_phases():
    from parc.comparison import format_table
    base = {"seconds": 1.0, "speedup": 1.0, "speedup_low": 1.0, "speedup_high": 1.0, "cells_visited": 0,
            "cubic_solves": 0, "hits": 0, "pixels": 100, "polygons": 0, "hit_mismatches": 0,
            "max_depth_cells": 0.0, "max_color": 0.0, "rmse": 0.0, "psnr": math.inf}
    rows = [dict(base, method="brute", opengl_share=0.0, samples=250, phases={"total": 1.0, "cast": 0.75}),
            dict(base, method="parc", opengl_share=0.5, samples=40, phases={"total": 0.5, "raster": 0.25})]
    lines = format_table(rows).splitlines()
    brute, parc_line = (line.split() for line in lines[2:4])
    # OpenGL, samples/px: "-" for no OpenGL time at all; 250 and 40 samples over 100 pixels.
    assert (brute[4], brute[7]) == ("-", "2.5") and (parc_line[4], parc_line[7]) == ("50%", "0.4")
    assert "  brute      cast=0.7500  raster=0.0000  total=1.0000" in lines
    assert "  parc       cast=0.0000  raster=0.2500  total=0.5000" in lines


def test_step_sweep_takes_each_methods_median_and_samples_and_brutes_image_against_the_reference(monkeypatch):
    # Reference: zeros. brute's image is 0.5 off it in one channel; parc's differs from brute's by
    # 0.75 in another: "max Δ vs fine" is brute's 0.5, parc≠brute 0.75.
    from data_tools.synthetic import blobs
    from parc import Camera, Scene, Translucent
    calls = []

    def image_of(method):
        calls.append(method)
        img = np.zeros((2, 2, 4), np.float32)
        if len(calls) > 1:
            img[0, 1, 2] = 0.5
        if method == "parc":
            img[1, 0, 0] = 0.75
        return img

    # brute's reference, then three rounds: brute 5, 1, 3 (median 3) and parc 2, 0.5, 1 (median 1).
    comparison = _scripted(monkeypatch, {"brute": [0.0, 5.0, 1.0, 3.0], "parc": [2.0, 0.5, 1.0]},
                           lambda w: {"total": w}, image_of=image_of, stats_of=lambda m: {"samples": len(m)})
    vol = blobs(6, seed=1)
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(2, 2), volumes=[Translucent(vol, "greyscale")])
    (row,) = comparison.step_sweep(scene, [0.5], repeats=3, warmup=0)
    assert (row["brute_seconds"], row["parc_seconds"], row["speedup"]) == (3.0, 1.0, 3.0)
    assert (row["brute_samples"], row["parc_samples"]) == (5, 4)
    assert row["max_color"] == 0.5 and row["parc_vs_brute"] == 0.75


def test_format_step_table_gives_the_units_of_its_step_and_psnr():
    from parc.comparison import format_step_table
    row = dict(step=0.5, brute_seconds=2.0, parc_seconds=0.5, speedup=4.0, brute_samples=1000,
               parc_samples=400, max_color=0.25, psnr=30.0, parc_vs_brute=0.5)
    legend = "\n".join(format_step_table([row]).splitlines()[2:])
    assert "step: world distance between samples" in legend and "PSNR in dB" in legend


def test_format_step_table_puts_each_error_under_its_heading():
    from parc.comparison import format_step_table
    row = dict(step=0.5, brute_seconds=2.0, parc_seconds=0.5, speedup=4.0, brute_samples=1000,
               parc_samples=400, max_color=0.25, psnr=30.0, parc_vs_brute=0.5)
    cells = format_step_table([row]).splitlines()[1].split()
    assert cells == ["0.5", "2.0000", "0.5000", "4.00x", "1,000", "400", "2.50e-01", "30.0", "5.0e-01"]
