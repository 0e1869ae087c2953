"""The bench sections' arithmetic on hand-made `parc.compare` rows: each figure the report prints is
recomputed here by hand (no rendering, no timing), where the tiny suite's own numbers, all
consistent, would not show a swapped ratio or a dropped phase."""
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from bench_rows import compare_row, table_cells
from parc.bench import parker, report, sweeps, tables


def test_supercell_sweep_divides_cells_by_pixels_and_sums_the_proxy_phases(monkeypatch):
    rows = [compare_row("brute", 0.8, {"cast": 0.7}, cells_visited=6400, pixels=64),
            compare_row("parc", 0.2, {"classify": 0.01, "proxy": 0.02, "raster": 0.04, "cast": 0.1}, cells_visited=320,
                 pixels=64, supercell=[4.0, 4.0, 4.0], polygons=12, speedup=4.0)]
    monkeypatch.setattr(sweeps.scenes, "ct_iso", lambda *a: (None, "stand-in"))
    monkeypatch.setattr(sweeps, "compare", lambda *a, **kw: rows)
    monkeypatch.setattr(sweeps, "work_maps", lambda *a: None)
    suite = SimpleNamespace(parker_size=8, supercells=(), repeats=1, data_dir=None, small_volumes=True)
    got = sweeps.supercell_sweep(suite, lambda m: None)["rows"]
    assert [r["cells_per_pixel"] for r in got] == [100.0, 5.0]               # 6400 / 64, 320 / 64
    assert got[1]["opengl_seconds"] == pytest.approx(0.07)                   # classify + proxy + raster
    assert got[1]["raster_seconds"] == 0.04 and got[0]["opengl_seconds"] == 0.0
    assert [r["supercell"] for r in got] == ["-", "4x4x4"] and got[1]["speedup"] == 4.0


def test_thread_scaling_is_frames_per_second_over_one_threads(monkeypatch):
    seconds = {1: (1.0, 0.25), 2: (0.5, 0.2), 4: (0.4, 0.1)}       # (brute, parc) per thread count
    now = {"k": 1}
    monkeypatch.setattr(parker.numba.config, "NUMBA_NUM_THREADS", 4)
    monkeypatch.setattr(parker.numba, "get_num_threads", lambda: 1)
    monkeypatch.setattr(parker.numba, "set_num_threads", lambda k: now.update(k=k))
    monkeypatch.setattr(parker.scenes, "ct_iso", lambda *a: (None, "stand-in"))
    monkeypatch.setattr(parker, "compare", lambda *a, **kw: [compare_row("brute", seconds[now["k"]][0]),
                                                            compare_row("parc", seconds[now["k"]][1])])
    suite = SimpleNamespace(parker_size=8, repeats=1, data_dir=None, small_volumes=True)
    got = parker.thread_scaling(suite, lambda m: None)["rows"]
    assert [r["threads"] for r in got] == [1, 2, 4]
    assert [r["brute_fps"] for r in got] == pytest.approx([1.0, 2.0, 2.5])
    assert [r["parc_fps"] for r in got] == pytest.approx([4.0, 5.0, 10.0])
    assert [r["brute_speedup"] for r in got] == pytest.approx([1.0, 2.0, 2.5])
    assert [r["parc_speedup"] for r in got] == pytest.approx([1.0, 1.25, 2.5])


def test_time_shares_split_the_cast_into_traversal_intersection_and_shading(monkeypatch):
    rec = np.zeros((10, 5))                                          # the frame's 10 cubics
    monkeypatch.setattr(parker.scenes, "ct_iso", lambda *a: (None, "stand-in"))
    monkeypatch.setattr(parker, "recorded_walk", lambda scene: (None, None, None, rec))
    monkeypatch.setattr(parker, "_solve_seconds", lambda r: 0.2)
    monkeypatch.setattr(parker, "_shade_seconds", lambda *a: 0.1)
    monkeypatch.setattr(parker, "compare", lambda *a, **kw: [
        compare_row("brute", 1.0, {"cast": 0.9}, cubic_solves=10),
        compare_row("parc", 0.6, {"classify": 0.05, "proxy": 0.05, "raster": 0.1, "cast": 0.35}, cubic_solves=10)])
    suite = SimpleNamespace(parker_size=8, repeats=1, data_dir=None, small_volumes=True)
    got = parker.time_shares(suite, lambda m: None)["rows"][:2]
    brute, parc = ({k: pytest.approx(v) for k, v in r["parts_seconds"].items()} for r in got)
    assert brute == {"traversal": 0.6, "intersection": 0.2, "shading": 0.1, "other": 0.1}
    assert parc == {"traversal": 0.05, "intersection": 0.2, "shading": 0.1, "OpenGL": 0.2, "other": 0.05}
    assert got[1]["shares"]["OpenGL"] == pytest.approx(0.2 / 0.6)
    assert got[0]["ns_per_solve"] == pytest.approx(2e7)               # 0.2 s over 10 cubics


def test_table1_casting_includes_each_raster_pass_and_the_ideal_is_its_scenes(monkeypatch):
    runs = [compare_row("brute", 1.0, {"cast": 0.9}, samples=1000),
            compare_row("parc:segments", 0.5, {"cast": 0.3, "raster": 0.1}, samples=600, speedup=2.0),
            compare_row("parc", 0.4, {"cast": 0.2, "raster": 0.1}, samples=300, speedup=2.5),
            compare_row("parc:bits", 0.4, {"cast": 0.15, "raster": 0.1, "raster_bits": 0.05}, samples=300, speedup=2.5)]
    monkeypatch.setattr(tables.scenes, "ct_translucent",
                        lambda size, *a: (SimpleNamespace(size=size, volumes=[None]), "stand-in"))
    monkeypatch.setattr(tables, "work_maps", lambda *a: None)
    monkeypatch.setattr(tables, "_rows", lambda *a: [dict(r) for r in runs])
    monkeypatch.setattr(tables, "ideal_and_contributing_samples",
                        lambda scene, vis, stop=None: (7 * scene.size, 3 * scene.size))
    suite = SimpleNamespace(sizes=(8, 16), data_dir=None, small_volumes=True, repeats=1)
    got = tables.table1(suite, lambda m: None, {})["rows"]
    assert [r["cast_seconds"] for r in got[:4]] == pytest.approx([0.9, 0.4, 0.3, 0.3])
    assert [r["ideal_samples"] for r in got] == [56] * 4 + [112] * 4
    assert [r["contributing_samples"] for r in got] == [24] * 4 + [48] * 4
    assert [r["samples"] for r in got[:4]] == [1000, 600, 300, 300]


def test_step_sweep_steps_are_in_smallest_spacings(monkeypatch):
    seen = {}
    vol = SimpleNamespace(spacing=(0.5, 0.75, 1.0))
    monkeypatch.setattr(sweeps.scenes, "ct_translucent",
                        lambda *a: (SimpleNamespace(volumes=[SimpleNamespace(volume=vol)]), "stand-in"))
    monkeypatch.setattr(sweeps, "step_sweep", lambda scene, steps, **kw: seen.setdefault("steps", steps) and [])
    suite = SimpleNamespace(sizes=(8,), steps=(2.0, 1.0, 0.5), repeats=1, data_dir=None, small_volumes=True)
    got = sweeps.step_size_sweep(suite, lambda m: None)
    assert seen["steps"] == [1.0, 0.5, 0.25]
    assert got["reference_step"] == 0.0625           # a quarter of the finest, as `step_sweep` renders it


def test_visible_woman_table_is_per_pixel_of_the_image(tmp_path):
    surface = {"surface": "skin", "isovalue": 600.5, "brute_seconds": 0.5, "parc_seconds": 0.05, "speedup": 10.0,
               "proxy_build_seconds": 1.0, "first_frame_seconds": 2.0, "polygons": 100, "brute_cells": 1600,
               "parc_cells": 80, "ideal_cells": 24, "hit_mismatches": 0, "max_color": 0.0}
    vw = {"shape": [8, 8, 8], "dtype": "int16", "bytes": 1024, "generate_seconds": None, "path": "x.raw",
          "size": 4, "threads": 1, "minmax_seconds": 0.1, "minmax_bytes": 10, "peak_rss_bytes": 1e6,
          "surfaces": [surface], "iso_change": {"isovalue": 1200.5, "reclassify_proxy_seconds": 0.1,
                                                "first_frame_seconds": 0.2}}
    md = report.scale({"visible_woman": vw}, tmp_path)
    row = table_cells(md, "## 4. Visible Woman scale")[0]
    assert (row["cells/px brute"], row["cells/px parc"], row["ideal cells/px"]) == ("100.0", "5.0", "1.50")
    assert (row["speedup"], row["parc FPS"]) == ("10.00×", "20.0")


def test_time_shares_never_give_shading_more_than_the_cast_leaves(monkeypatch):
    # Shading re-timed in a loop can exceed what the cast has left after the cubics: capped, traversal 0.
    monkeypatch.setattr(parker.scenes, "ct_iso", lambda *a: (None, "stand-in"))
    monkeypatch.setattr(parker, "recorded_walk", lambda scene: (None, None, None, np.zeros((4, 5))))
    monkeypatch.setattr(parker, "_solve_seconds", lambda r: 0.2)
    monkeypatch.setattr(parker, "_shade_seconds", lambda *a: 0.5)
    monkeypatch.setattr(parker, "compare", lambda *a, **kw: [compare_row("brute", 1.0, {"cast": 0.6}, cubic_solves=4)])
    suite = SimpleNamespace(parker_size=8, repeats=1, data_dir=None, small_volumes=True)
    parts = parker.time_shares(suite, lambda m: None)["rows"][0]["parts_seconds"]
    assert {k: pytest.approx(v) for k, v in parts.items()} == {"traversal": 0.0, "intersection": 0.2,
                                                               "shading": 0.4, "other": 0.4}


def test_table2_ideal_is_brutes_cubics_and_samples_stopped_at_brutes_surface(monkeypatch):
    depth = np.full((4, 4), 3.0)
    monkeypatch.setattr(tables, "render", lambda scene, method: SimpleNamespace(depth=depth))
    # 5 samples when stopped at brute's depth, 9 without a stop.
    monkeypatch.setattr(tables, "ideal_and_contributing_samples",
                        lambda scene, vis, stop=None: (5, 2) if stop is depth else (9, 4))
    monkeypatch.setattr(tables, "_rows", lambda *a: [
        compare_row("brute", 1.0, {"cast": 0.9}, cubic_solves=40, hits=12),
        compare_row("parc", 0.5, {"cast": 0.4}, cubic_solves=39, hits=11)])
    suite = SimpleNamespace(sizes=(4,), data_dir=None, small_volumes=True, repeats=1)
    got = tables.table2(suite, lambda m: None, {})["rows"]
    assert [(r["ideal_cells"], r["ideal_samples"]) for r in got] == [(40, 5), (40, 5)]
    # The contributing cells are brute's hits, one a ray, whichever method's row.
    assert [(r["contributing_cells"], r["contributing_samples"]) for r in got] == [(12, 2), (12, 2)]


def test_precision_errors_are_each_storage_against_float64_and_parc_against_brute(monkeypatch):
    def render(scene, method):
        return SimpleNamespace(dtype=str(scene.volumes[0].volume.dtype))

    order = {"float64": 0.0, "float32": 1.0, "int16": 2.0}
    monkeypatch.setattr(sweeps, "render", render)
    monkeypatch.setattr(sweeps, "image_error", lambda run, ref, cell: {
        "hit_mismatches": 0, "max_depth_cells": 0.0, "max_color": abs(order[run.dtype] - order[ref.dtype])})
    monkeypatch.setattr(sweeps, "compare", lambda *a, **kw: [compare_row("brute", 1.0, max_color=0.0),
                                                             compare_row("parc", 0.5, max_color=0.25)])
    suite = SimpleNamespace(parker_size=4, data_dir=None, small_volumes=True, repeats=1)
    got = sweeps.precision(suite, lambda m: None)["rows"]
    assert [(r["dtype"], r["max_color"]) for r in got] == [("int16", 2.0), ("float64", 0.0), ("float32", 1.0),
                                                           ("float64", 0.0), ("float32", 1.0)]
    assert {r["parc_vs_brute"] for r in got} == {0.25}
    assert [(r["brute_seconds"], r["parc_seconds"]) for r in got] == [(1.0, 0.5)] * 5


def test_the_paper_tables_show_each_rows_own_counts(tmp_path):
    t1 = [{"method": "parc (depth)", "size": 8, "samples": 12000, "ideal_samples": 3000, "cast_seconds": 0.25,
           "total_seconds": 0.5, "speedup": 2.0, "hit_mismatches": 0, "max_color": 0.0}]
    t2 = [{"method": "parc", "size": 8, "cells": 7000, "ideal_cells": 2000, "samples": 5000, "ideal_samples": 4000,
           "cast_seconds": 0.25, "total_seconds": 0.5, "speedup": 2.0, "hit_mismatches": 0, "max_color": 0.0}]
    md = report.paper_tables({"table1": {"rows": t1, "source": "-", "work_size": 8},
                              "table2": {"rows": t2, "source": "-"}, "table3": {"rows": [], "source": "-"}}, tmp_path)
    one = table_cells(md, "### Table 1")[0]
    assert (one["samples (×10³)"], one["ideal samples (×10³)"], one["casting (s)"], one["total (s)"]) == \
        ("12.0", "3.0", "0.250", "0.500")
    two = table_cells(md, "### Table 2")[0]
    assert (two["cells (×10³)"], two["ideal cells (×10³)"], two["samples (×10³)"], two["ideal samples (×10³)"]) == \
        ("7.0", "2.0", "5.0", "4.0")


def test_visible_woman_ideal_is_brutes_cubics(monkeypatch, tmp_path):
    from data_tools.synthetic import ct_phantom_to_disk

    import parc.comparison
    import parc.renderer
    from parc.bench import scale
    path = scale.phantom_path(tmp_path, (16, 16, 24))
    ct_phantom_to_disk(str(path), (16, 16, 24))
    monkeypatch.setattr(parc.renderer, "render", lambda scene, method: SimpleNamespace(stats={"seconds": {}}))
    monkeypatch.setattr(parc.comparison, "compare", lambda *a, **kw: [
        compare_row("brute", 1.0, cells_visited=900, cubic_solves=40),
        compare_row("parc", 0.5, {"raster": 0.1}, cells_visited=60, cubic_solves=38, speedup=2.0)])
    got = scale.measure(str(path), 4, 1, lambda m: None)["surfaces"]
    assert [(s["brute_cells"], s["parc_cells"], s["ideal_cells"], s["speedup"]) for s in got] == [(900, 60, 40, 2.0)] * 2


@pytest.mark.parametrize("table, key", [("table2", "samples"), ("table3", "shadow_cells"), ("visible_woman", "parc_cells")])
def test_parc_touching_more_than_brute_fails_its_check_in_every_count_the_report_bounds(table, key):
    """The report says "ideal ≤ touched ≤ brute": each count it lists for both methods is checked."""
    from parc.bench import consistency

    def results(parc_count):
        res = {"table1": {"rows": []}, "table2": {"rows": []}, "table3": {"rows": []}, "supercells": {"rows": []},
               "time_shares": {"rows": []}, "visible_woman": {"surfaces": [], "size": 8}, "steps": {"rows": []},
               "precision": {"rows": []}, "ideal": [], "roots": {"rows": [{"name": "project", "failures": 0}]},
               "threads": {"rows": []}}
        if table == "visible_woman":
            res[table]["surfaces"] = [{"surface": "skin", "hit_mismatches": 0, "max_color": 0.0, "brute_cells": 100,
                                       "parc_cells": parc_count}]
        else:
            counts = {"cells": 50, "samples": 50, "primary_cells": 50, "shadow_cells": 50}
            res[table]["rows"] = [{"method": m, "size": 8, "cast_seconds": 0.1, "total_seconds": 0.2,
                                   "hit_mismatches": 0, "max_color": 0.0, **counts, key: c}
                                  for m, c in (("brute", 100), ("parc", parc_count))]
        return [c["check"] for c in consistency(res) if not c["ok"]]
    assert results(60) == []
    assert len(results(150)) == 1


def test_thread_table_says_what_each_ratio_is_against(tmp_path):
    """Scaling columns are against the method's own 1-thread rate; the speedup column is parc over brute at
    the same thread count (the project's one meaning of "speedup")."""
    sh = {"size": 8, "source": "-", "rows": [{"surface": "bone (1500)", "method": "parc", "seconds": 0.5,
                                              "parts_seconds": {"traversal": 0.5}, "shares": {"traversal": 1.0},
                                              "cubics": 10, "ns_per_solve": 5.0}]}
    th = {"size": 8, "cores": 2, "rows": [
        {"threads": 1, "brute_fps": 1.0, "parc_fps": 4.0, "brute_speedup": 1.0, "parc_speedup": 1.0},
        {"threads": 2, "brute_fps": 2.0, "parc_fps": 5.0, "brute_speedup": 2.0, "parc_speedup": 1.25}]}
    rows = table_cells(report.parker({"time_shares": sh, "threads": th}, tmp_path), "### Thread scaling")
    assert [(r["brute vs 1 thread"], r["parc vs 1 thread"], r["speedup (parc over brute)"]) for r in rows] == \
        [("1.00×", "1.00×", "4.00×"), ("2.00×", "1.25×", "2.50×")]


def test_a_slow_methods_ratio_keeps_two_significant_digits():
    # 0.004 at two decimals reads 0.00×, as if the method never finished.
    assert [report._x(v) for v in (0.004, 0.0123, 3.456)] == ["0.004×", "0.01×", "3.46×"]


def _head_top(vol):
    """The z end where the head's top lies, -1 or +1: the end slice with less soft tissue (above 600);
    the other end holds the neck."""
    tissue = [(vol.data[k] > 600).sum() for k in (0, -1)]
    return -1.0 if tissue[0] < tissue[1] else 1.0


@pytest.mark.parametrize("scene", ["ct_iso", "ct_translucent"])
def test_the_ct_scenes_show_the_head_upright_whichever_volume_stands_in(scene):
    # The phantom that stands in for CThead is built head up, CThead head down: the scene's view
    # must turn with the volume, so that the head's top is up in the picture, seen from where
    # CThead is (its view mirrored in z: both have their faces to -y).
    from data_tools import Volume
    from parc.bench import scenes
    make = getattr(scenes, scene)
    args = (32, 600.0) if scene == "ct_iso" else (32,)
    built, _ = make(*args, None, True)
    vol = built.volumes[0].volume
    assert vol.meta.get("synthetic") == "ct_phantom" and _head_top(vol) == 1.0
    u = built.camera.basis()[2]
    assert u[2] > 0.9
    ct = scenes._ct_camera(Volume(np.zeros((3, 3, 3), np.int16), spacing=(127.5, 127.5, 112.0)))
    # Eye offsets in units of each box's half diagonal: the same framing of boxes of two sizes.
    want = np.subtract(ct.eye, ct.look_at) * [1.0, 1.0, -1.0] / (0.5 * np.linalg.norm([255.0, 255.0, 224.0]))
    got = np.subtract(built.camera.eye, built.camera.look_at) / (0.5 * np.linalg.norm(np.subtract(*vol.bounds[::-1])))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert ct.basis()[2][2] < -0.9                   # CThead's top, at -z, is up in its picture
    head = Path(__file__).parents[2].parent / "shared" / "data" / "CThead.nrrd"
    if head.is_file():
        real, _ = make(*args, head.parent, False)
        assert _head_top(real.volumes[0].volume) == -1.0 and real.camera == ct
