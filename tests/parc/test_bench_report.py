"""What `parc bench` runs and shows: the methods and settings each section compares, the sizes it
sweeps, and the report's cells, texts and charts against the numbers handed to it. Hand-made rows
and stand-in scenes (no rendering, no timing): each figure is written out here by hand, and the
charts are decoded with Pillow."""
import copy
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from bench_rows import compare_row, table_cells
from parc.bench import _checks_md, charts, parker, report, scenes, sweeps, tables
from parc.bench.charts import PALETTE


def _rgb(path):
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def _mask(img, colour):
    return np.all(img == np.array(colour, np.uint8), axis=2)


# --------------------------------------------------------------------------
# What each section runs
# --------------------------------------------------------------------------

def test_table1_compares_the_papers_methods_with_their_own_buffers(monkeypatch):
    # Labels and settings must go together: the report names each row by the buffers it used.
    seen = []

    def compare(scene, methods, options, **kw):
        seen.append((list(methods), copy.deepcopy(options)))
        return [compare_row(m, 1.0, samples=10) for m in methods]
    monkeypatch.setattr(tables, "compare", compare)
    monkeypatch.setattr(tables.scenes, "ct_translucent",
                        lambda size, *a: (SimpleNamespace(size=(size, size), volumes=[None]), "stand-in"))
    monkeypatch.setattr(tables, "ideal_and_contributing_samples", lambda *a, **kw: (5, 2))
    monkeypatch.setattr(tables, "work_maps", lambda *a: None)
    suite = SimpleNamespace(sizes=(8,), data_dir=None, small_volumes=True, repeats=1)
    got = tables.table1(suite, lambda m: None, {})["rows"]
    methods, options = seen[0]
    assert methods == ["brute", "parc:segments", "parc", "parc:bits"]
    assert options == {"parc:segments": {"buffers": ("depth",), "blocks": False},
                       "parc": {"buffers": ("depth",)}, "parc:bits": {"buffers": ("depth", "bits")}}
    assert [r["method"] for r in got] == ["brute", "parc (depth, no blocks)", "parc (depth)", "parc (depth+bits)"]


def test_table1_work_maps_are_of_the_size_the_report_names(monkeypatch):
    # The report draws the maps once and titles them with work_size: they must be that size's.
    drawn = []
    monkeypatch.setattr(tables.scenes, "ct_translucent",
                        lambda size, *a: (SimpleNamespace(size=(size, size), volumes=[None]), "stand-in"))
    monkeypatch.setattr(tables, "_rows", lambda *a: [compare_row("brute", 1.0, samples=10)])
    monkeypatch.setattr(tables, "ideal_and_contributing_samples", lambda *a, **kw: (5, 2))
    monkeypatch.setattr(tables, "work_maps", lambda scene, count: drawn.append(scene.size) or {"checks": {}})
    suite = SimpleNamespace(sizes=(8, 16), data_dir=None, small_volumes=True, repeats=1)
    got = tables.table1(suite, lambda m: None, {})
    assert drawn == [(got["work_size"], got["work_size"])] == [(8, 8)]


@pytest.mark.parametrize("parc_map, within", [(np.full((2, 3), 4), True), (np.array([[4, 4, 4], [4, 4, 6]]), False)])
def test_work_maps_flag_parc_doing_more_than_brute_at_one_pixel(monkeypatch, parc_map, within):
    maps = {"brute": np.full((2, 3), 5), "parc": parc_map}
    monkeypatch.setattr(tables, "render", lambda scene, m, work: SimpleNamespace(
        work=maps[m], stats={"samples": int(maps[m].sum())}))
    assert tables.work_maps(None, "samples")["checks"]["parc_within_brute"] is within


def test_supercell_sweep_runs_brute_the_cost_models_choice_and_every_size_asked(monkeypatch):
    seen = {}

    def compare(scene, methods, options, **kw):
        seen.update(methods=list(methods), options=options)
        return [compare_row(m, 1.0, supercell=options.get(m, {}).get("supercell") and [options[m]["supercell"]] * 3)
                for m in methods]
    monkeypatch.setattr(sweeps.scenes, "ct_iso", lambda *a: (None, "stand-in"))
    monkeypatch.setattr(sweeps, "compare", compare)
    monkeypatch.setattr(sweeps, "work_maps", lambda *a: None)
    suite = SimpleNamespace(parker_size=8, supercells=(0.5, 2.0), repeats=1, data_dir=None, small_volumes=True)
    got = sweeps.supercell_sweep(suite, lambda m: None)["rows"]
    assert seen["methods"] == ["brute", "parc", "parc:0.5", "parc:2"]
    assert seen["options"] == {"parc:0.5": {"supercell": 0.5}, "parc:2": {"supercell": 2.0}}
    assert [r["supercell"] for r in got] == ["-", "-", "0.5x0.5x0.5", "2x2x2"]


def test_step_sweep_renders_at_the_size_it_reports(monkeypatch):
    seen = []
    monkeypatch.setattr(sweeps, "step_sweep", lambda scene, steps, **kw: seen.append(scene.size) or [])
    suite = SimpleNamespace(sizes=(8, 12), steps=(1.0,), repeats=1, data_dir=None, small_volumes=True)
    got = sweeps.step_size_sweep(suite, lambda m: None)
    assert seen == [(got["size"], got["size"])] == [(8, 8)]


def test_precision_rows_count_each_stored_volumes_bytes_and_errors_in_smallest_spacings(monkeypatch):
    # The tiny CT phantom is 32x32x16 with spacing 1, 1, 2: a cell is 1; the field 12^3 samples, spacing 1.
    cells, iso = [], []

    def image_error(run, ref, cell):
        cells.append(cell)
        return {"hit_mismatches": 0, "max_depth_cells": 0.0, "max_color": 0.0}

    def compare(scene, methods, **kw):
        iso.append(scene.volumes[0].value)
        return [compare_row("brute", 1.0), compare_row("parc", 0.5)]
    monkeypatch.setattr(sweeps, "render", lambda scene, method: None)
    monkeypatch.setattr(sweeps, "image_error", image_error)
    monkeypatch.setattr(sweeps, "compare", compare)
    suite = SimpleNamespace(parker_size=4, data_dir=None, small_volumes=True, repeats=1)
    got = sweeps.precision(suite, lambda m: None)["rows"]
    ct, field = 32 * 32 * 16, 12 ** 3
    assert [(r["dtype"], r["bytes"]) for r in got] == [
        ("int16", 2 * ct), ("float64", 8 * ct), ("float32", 4 * ct),
        ("float64", 8 * field), ("float32", 4 * field)]
    assert cells == [1.0] * 5
    assert iso[:3] == [600.0] * 3 and [f"{v:.4g}" for v in iso[3:]] == [got[3]["volume"].split()[-1]] * 2


@pytest.mark.parametrize("most, counts", [(1, [1]), (4, [1, 2, 4]), (6, [1, 2, 4, 6]), (12, [1, 2, 4, 8, 12])])
def test_thread_scaling_runs_one_thread_the_powers_of_two_and_every_thread(monkeypatch, most, counts):
    now = {"k": 3}
    ran = []
    monkeypatch.setattr(parker.numba.config, "NUMBA_NUM_THREADS", most)
    monkeypatch.setattr(parker.numba, "get_num_threads", lambda: now["k"])
    monkeypatch.setattr(parker.numba, "set_num_threads", lambda k: now.update(k=k))
    monkeypatch.setattr(parker.scenes, "ct_iso", lambda *a: (None, "stand-in"))

    def compare(*a, **kw):
        ran.append(now["k"])
        return [compare_row("brute", 1.0 / now["k"]), compare_row("parc", 0.5 / now["k"])]
    monkeypatch.setattr(parker, "compare", compare)
    suite = SimpleNamespace(parker_size=8, repeats=1, data_dir=None, small_volumes=True)
    got = parker.thread_scaling(suite, lambda m: None)
    assert ran == counts and [r["threads"] for r in got["rows"]] == counts
    assert now["k"] == 3                                 # the sections after it run on the threads they had
    assert got["median_parc_fps"] == pytest.approx(float(np.median([2.0 * k for k in counts])))


def test_time_shares_are_measured_on_one_thread_and_give_the_threads_back(monkeypatch):
    now = {"k": 2}
    ran = []
    monkeypatch.setattr(parker.numba, "get_num_threads", lambda: now["k"])
    monkeypatch.setattr(parker.numba, "set_num_threads", lambda k: now.update(k=k))
    monkeypatch.setattr(parker.scenes, "ct_iso", lambda *a: (None, "stand-in"))
    monkeypatch.setattr(parker, "recorded_walk", lambda scene: (None, None, None, np.zeros((4, 5))))
    monkeypatch.setattr(parker, "_solve_seconds", lambda r: ran.append(("solve", now["k"])) or 0.1)
    monkeypatch.setattr(parker, "_shade_seconds", lambda *a: ran.append(("shade", now["k"])) or 0.1)
    monkeypatch.setattr(parker, "compare", lambda *a, **kw: ran.append(("frame", now["k"])) or [
        compare_row("brute", 1.0, {"cast": 0.9}, cubic_solves=4)])
    parker.time_shares(SimpleNamespace(parker_size=8, repeats=1, data_dir=None, small_volumes=True), lambda m: None)
    assert ran == [("solve", 1), ("shade", 1), ("frame", 1)] * 2
    assert now["k"] == 2


def test_a_real_ct_head_is_described_as_the_file_read(tmp_path):
    # A file written byte by byte: 4 x 3 x 2 int16 samples, spacing 1, 1, 2.
    head = b"NRRD0004\ntype: int16\ndimension: 3\nsizes: 4 3 2\nspacings: 1 1 2\nencoding: raw\nendian: little\n\n"
    (tmp_path / "CThead.nrrd").write_bytes(head + np.arange(24, dtype="<i2").tobytes())
    vol, source = scenes.ct_volume(tmp_path, False)
    assert source == "`CThead.nrrd` (4×3×2 int16, spacing 1, 1, 2)"
    assert vol.data.shape == (2, 3, 4) and int(vol.data[1, 2, 3]) == 23


def test_a_folder_named_like_a_volume_is_not_taken_for_it(tmp_path):
    (tmp_path / "CThead.nrrd").mkdir()
    assert "not found" in scenes.ct_volume(tmp_path, True)[1]


def test_table1_is_the_translucent_the_report_describes():
    # "transfer function `ct_skin_bone`, composite, step a quarter of the smallest spacing"
    vis = scenes.ct_translucent(8, None, True)[0].volumes[0]
    assert (vis.tf.name, vis.mode) == ("ct_skin_bone", "composite")
    assert float(vis.step) == min(vis.volume.spacing) / 4


def test_the_scenes_render_the_isovalues_their_sources_name():
    scene, source = scenes.iron_protein(8, None, True)
    assert "isosurface 80" in source and scene.volumes[0].value == 80.0
    scene, source = scenes.neuron_floor(8, None, True)
    assert "(isosurface 80)" in source and scene.volumes[0].value == 80.0
    assert scene.shadows and len(scene.lights) == 2


# --------------------------------------------------------------------------
# The report's cells and texts
# --------------------------------------------------------------------------

def test_an_error_too_small_to_matter_is_still_not_printed_as_zero():
    assert [report._err(v) for v in (0.0, 1e-9, 0.25)] == ["0", "1.0e-09", "2.5e-01"]


def test_exact_needs_both_equal_hit_masks_and_equal_colours():
    assert report._exact({"hit_mismatches": 0, "max_color": 0.0}) == "yes"
    assert report._exact({"hit_mismatches": 3, "max_color": 0.0}) == "no (3 px, Δ 0.0e+00)"
    assert report._exact({"hit_mismatches": 0, "max_color": 0.01}) == "no (0 px, Δ 1.0e-02)"


def test_brutes_own_speedup_has_no_spread():
    row = {"speedup": 1.0, "speedup_low": 0.9, "speedup_high": 1.2}
    assert report._xr({"method": "brute", **row}) == "1.00×"
    assert report._xr({"method": "parc", **row}) == "1.00× (0.90–1.20)"
    slow = {"method": "parc", "speedup": 0.0087, "speedup_low": 0.0081, "speedup_high": 0.0093}
    assert report._xr(slow) == "0.0087× (0.0081–0.0093)"


def _parker_results(th_rows=()):
    sh = {"size": 8, "source": "-", "rows": [
        {"surface": "skin (600)", "method": "parc", "seconds": 0.2,
         "parts_seconds": {"traversal": 0.02, "intersection": 0.04, "shading": 0.06, "OpenGL": 0.08, "other": 0.0},
         "shares": {"traversal": 0.1, "intersection": 0.2, "shading": 0.3, "OpenGL": 0.4, "other": 0.0},
         "cubics": 1000, "ns_per_solve": 40.0},
        {"surface": "skin (600)", "method": "brute", "seconds": 0.4,
         "parts_seconds": {"traversal": 0.1, "intersection": 0.1, "shading": 0.0, "other": 0.2},
         "shares": {"traversal": 0.25, "intersection": 0.25, "shading": 0.0, "other": 0.5},
         "cubics": 1000, "ns_per_solve": 40.0}]}
    th = {"size": 8, "cores": 2, "rows": list(th_rows) or [
        {"threads": 1, "brute_fps": 1.0, "parc_fps": 4.0, "brute_speedup": 1.0, "parc_speedup": 1.0},
        {"threads": 2, "brute_fps": 2.0, "parc_fps": 5.0, "brute_speedup": 2.0, "parc_speedup": 1.25}]}
    return {"time_shares": sh, "threads": th}


def test_time_share_columns_are_each_parts_own(tmp_path):
    rows = table_cells(report.parker(_parker_results(), tmp_path), "### Share of time")
    assert [(r["traversal"], r["intersection"], r["shading"], r["OpenGL"], r["other"]) for r in rows] == [
        ("10%", "20%", "30%", "40%", "0%"), ("25%", "25%", "0%", "–", "50%")]


def test_time_share_bars_are_stacked_from_each_parts_seconds(tmp_path):
    # The brute bar: traversal 0.1, intersection 0.1, other 0.2 of 0.4 s; parts in PALETTE order of first use.
    report.parker(_parker_results(), tmp_path)
    img = _rgb(tmp_path / "time_shares.png")
    colour = dict(zip(("traversal", "intersection", "shading", "OpenGL", "other"), PALETTE))
    width = img.shape[1]
    # The plot's right half holds the second (brute) bar; its segments' heights in one column.
    col = next(c for c in range(width // 2, width) if _mask(img[:, c:c + 1], colour["other"]).any())
    heights = {k: int(_mask(img[:, col + 10:col + 11], c).sum()) for k, c in colour.items()}
    assert heights["shading"] == heights["OpenGL"] == 0
    assert heights["other"] == pytest.approx(heights["traversal"] + heights["intersection"], abs=3)
    assert heights["traversal"] == pytest.approx(heights["intersection"], abs=2)


def test_thread_chart_plots_each_methods_own_frames_per_second(tmp_path):
    report.parker(_parker_results(), tmp_path)
    img = _rgb(tmp_path / "thread_scaling.png")[:, :560]          # the plot, left of the legend
    brute, parc = (np.nonzero(_mask(img, c))[0] for c in PALETTE[:2])
    assert brute.size and parc.size and parc.max() < brute.min()   # parc's 4-5 FPS above brute's 1-2


def _sweep_results(sc_rows=None, st_rows=None):
    sc = {"size": 8, "source": "-", "isovalue": 600.0, "rows": sc_rows or [
        {"method": "brute", "supercell": "-", "polygons": 0, "opengl_seconds": 0.0, "cells_per_pixel": 30.0,
         "seconds": 0.8, "speedup": 1.0, "hit_mismatches": 0, "max_depth_cells": 0.0, "max_color": 0.0},
        {"method": "parc:2", "supercell": "2x2x2", "polygons": 1234, "opengl_seconds": 0.05, "cells_per_pixel": 3.0,
         "seconds": 0.2, "speedup": 4.0, "hit_mismatches": 0, "max_depth_cells": 0.0, "max_color": 0.0}]}
    st = {"size": 8, "reference_step": 0.125, "rows": st_rows or [
        {"step": 1.0, "brute_seconds": 0.5, "parc_seconds": 0.25, "speedup": 2.0, "brute_samples": 9000,
         "parc_samples": 4000, "max_color": 0.02, "psnr": 40.0, "parc_vs_brute": 0.0},
        {"step": 0.5, "brute_seconds": 1.0, "parc_seconds": 0.5, "speedup": 2.0, "brute_samples": 18000,
         "parc_samples": 8000, "max_color": 0.0, "psnr": float("inf"), "parc_vs_brute": 0.0}]}
    kinds = {k: 0 for k in report.FAILURE_KINDS}
    rt = {"rows": [{"name": "project", "ns_per_solve": 50.0, "max_err_cells": 2e-10, "median_err_cells": 1e-12,
                    "failures": 0, "rays": 100, "required": 60, "solves": 500, **kinds}]}
    pr = {"size": 8, "rows": [
        {"volume": "CT", "dtype": "int16", "bytes": 2_500_000, "brute_seconds": 1.0, "parc_seconds": 0.5,
         "hit_mismatches": 0, "max_depth_cells": 0.0, "max_color": 0.0, "parc_vs_brute": 0.0}]}
    return {"supercells": sc, "steps": st, "roots": rt, "precision": pr}


def test_sweep_tables_show_each_rows_own_numbers(tmp_path):
    md = report.sweeps(_sweep_results(), tmp_path)
    sc = table_cells(md, "### Supercell size")[1]
    assert (sc["polygons"], sc["classify+proxy+raster (s)"], sc["cells/pixel"], sc["total (s)"], sc["speedup"]) == \
        ("1,234", "0.0500", "3.0", "0.200", "4.00×")
    st = table_cells(md, "### Sample step")
    assert [(r["brute samples (×10³)"], r["parc samples (×10³)"], r["PSNR (dB)"]) for r in st] == [
        ("9.0", "4.0", "40.0"), ("18.0", "8.0", "inf")]
    roots = table_cells(md, "### Cubic root finders")[0]
    assert (roots["ns/solve"], roots["max error"], roots["median error"]) == ("50.0", "2.0e-10", "1.0e-12")
    assert table_cells(md, "### Storage precision")[0]["MB"] == "2.5"


@pytest.mark.parametrize("error, words", [(0.0, "every image equal to brute's"), (1e-3, "errors in the table")])
def test_supercell_chart_title_says_whether_every_size_was_exact(tmp_path, monkeypatch, error, words):
    drawn = {}
    monkeypatch.setattr(charts, "scatter_chart", lambda path, points, **kw: drawn.setdefault(path.name, (points, kw)))
    rows = _sweep_results()["supercells"]["rows"]
    rows += [{**rows[1], "method": "parc:4", "supercell": "4x4x4", "max_color": error}]
    report.sweeps(_sweep_results(sc_rows=rows), tmp_path)
    points, kw = drawn["sweep_supercell.png"]
    assert kw["title"].endswith(words) and "brute 0.800 s" in kw["title"]
    assert [(p["x"], p["y"]) for p in points] == [(1234, 0.2), (1234, 0.2)]


def test_step_chart_is_time_against_the_error_to_the_fine_reference(tmp_path, monkeypatch):
    drawn = {}
    monkeypatch.setattr(charts, "scatter_chart", lambda path, points, **kw: drawn.setdefault(path.name, (points, kw)))
    report.sweeps(_sweep_results(), tmp_path)
    points, kw = drawn["sweep_step.png"]
    assert [(p["series"], p["x"], p["y"]) for p in points] == [
        ("brute", 0.02, 0.5), ("parc", 0.02, 0.25), ("brute", 0.0, 1.0), ("parc", 0.0, 0.5)]
    assert kw["x_log"] is True                     # one error is positive: the zero goes to its own slot
    assert drawn["sweep_precision.png"][1]["x_log"] is False     # every error zero: a log axis has no decade


def _vw(seconds=(0.05, 0.1), size=512):
    surfaces = [{"surface": name, "isovalue": iso, "brute_seconds": 1.0, "parc_seconds": s, "speedup": 1.0 / s,
                 "proxy_build_seconds": 1.0, "first_frame_seconds": 2.0, "polygons": 100, "brute_cells": 1600,
                 "parc_cells": 80, "ideal_cells": 24, "hit_mismatches": 0, "max_color": 0.0}
                for (name, iso), s in zip((("skin", 600.5), ("bone", 1500.5)), seconds)]
    return {"shape": [8, 8, 8], "dtype": "int16", "bytes": 1024, "generate_seconds": None, "path": "x.raw",
            "size": size, "threads": 1, "minmax_seconds": 0.1, "minmax_bytes": 10, "peak_rss_bytes": 1e6,
            "surfaces": surfaces, "iso_change": {"isovalue": 1200.5, "reclassify_proxy_seconds": 0.1,
                                                 "first_frame_seconds": 0.2}}


@pytest.mark.parametrize("size, words", [(512, "20.0 frames per second at 512² on 1 thread, on one view of a phantom "
                                                "simpler than the real body (200% of their rate"),
                                         (256, "20.0 frames per second at 256² on 1 thread, on one view of a phantom "
                                               "simpler than the real body (a reduced size: not comparable)")])
def test_visible_woman_text_gives_the_fastest_surfaces_rate(tmp_path, size, words):
    # 0.05 s and 0.1 s a frame: 20 and 10 FPS; the text names the best, against Parker et al.'s 10.
    text = " ".join(report.scale({"visible_woman": _vw(size=size)}, tmp_path))
    assert words in text


def test_ideal_table_bounds_each_unit_by_its_own_ideal():
    t2 = [{"method": "parc", "size": 8, "cells": 7000, "ideal_cells": 2000, "contributing_cells": 300,
           "samples": 5000, "ideal_samples": 4000, "contributing_samples": 1000}]
    res = {"table1": {"rows": []}, "table2": {"rows": t2}, "table3": {"rows": []},
           "visible_woman": {"surfaces": [], "size": 8}}
    _, rows = report.ideal(res)
    assert rows == [("Table 2 protein isosurface", 8, "cells", "parc", 2000, 300, 7000),
                    ("Table 2 protein translucent", 8, "samples", "parc", 4000, 1000, 5000)]


def test_the_consistency_section_counts_and_names_the_failed_checks():
    md = _checks_md([{"check": "a", "ok": True}, {"check": "b", "ok": False}, {"check": "c", "ok": True}])
    assert md[2].startswith("2 of 3 checks pass") and "None fails" not in md[2]
    assert [line for line in md if line.startswith("- ")] == ["- FAILED: b"]
    assert _checks_md([{"check": "a", "ok": True}])[2].endswith("None fails.")


def test_a_thread_count_without_parc_frames_fails_its_check():
    from parc.bench import consistency
    res = {"table1": {"rows": []}, "table2": {"rows": []}, "table3": {"rows": []}, "supercells": {"rows": []},
           "time_shares": {"rows": []}, "visible_woman": {"surfaces": [], "size": 8}, "steps": {"rows": []},
           "precision": {"rows": []}, "ideal": [], "roots": {"rows": [{"name": "project", "failures": 0}]},
           "threads": {"rows": [{"threads": 1, "brute_fps": 2.0, "parc_fps": 4.0}]}}
    assert all(c["ok"] for c in consistency(res))
    res["threads"]["rows"][0]["parc_fps"] = 0.0
    assert [c["check"] for c in consistency(res) if not c["ok"]] == ["threads 1: frames per second positive"]


def test_the_visible_woman_child_renders_the_suites_phantom_size_and_repeats(tmp_path, monkeypatch):
    import subprocess
    from pathlib import Path

    import data_tools.synthetic
    from parc.bench import Suite, scale
    cmds = []

    def child(cmd, **kw):
        cmds.append(cmd)
        Path(cmd[cmd.index("--json") + 1]).write_text("{}")
        return subprocess.CompletedProcess(cmd, 0)
    monkeypatch.setattr(scale.subprocess, "run", child)
    monkeypatch.setattr(data_tools.synthetic, "ct_phantom_to_disk", lambda path, shape: Path(path).write_bytes(b""))
    suite = Suite.tiny(cache_dir=tmp_path, vw_shape=(8, 8, 12), vw_size=20, parker_size=12, repeats=3)
    got = scale.visible_woman(suite, lambda m: None)
    cmd = cmds[0]
    assert (cmd[cmd.index("--size") + 1], cmd[cmd.index("--repeats") + 1]) == ("20", "3")
    assert cmd[3] == got["path"] == str(tmp_path / "vw_phantom_8x8x12_int16.raw")


def test_visible_woman_proxy_time_is_classification_and_proxy_and_raster_is_parcs(monkeypatch, tmp_path):
    from data_tools.synthetic import ct_phantom_to_disk

    import parc.comparison
    import parc.renderer
    from parc.bench import scale
    path = scale.phantom_path(tmp_path, (16, 16, 24))
    ct_phantom_to_disk(str(path), (16, 16, 24))
    first = {"classify": 0.25, "proxy": 0.5, "raster": 0.125, "cast": 1.0}
    monkeypatch.setattr(parc.renderer, "render", lambda scene, method: SimpleNamespace(stats={"seconds": first}))
    monkeypatch.setattr(parc.comparison, "compare", lambda *a, **kw: [
        compare_row("brute", 1.0, {"cast": 0.9}, cells_visited=900, cubic_solves=40),
        compare_row("parc", 0.5, {"raster": 0.0625, "cast": 0.3}, cells_visited=60, cubic_solves=38, speedup=2.0)])
    got = scale.measure(str(path), 4, 1, lambda m: None)
    assert [(s["proxy_build_seconds"], s["raster_seconds"]) for s in got["surfaces"]] == [(0.75, 0.0625)] * 2
    assert got["iso_change"]["reclassify_proxy_seconds"] == 0.75
