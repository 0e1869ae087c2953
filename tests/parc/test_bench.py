"""`parc bench` on its tiny suite: the report is complete, its numbers consistent, its exactness claims true."""
import copy
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
from PIL import Image

from bench_rows import table_cells
from data_tools import InputError
from parc.bench import Suite, consistency, run_bench
from parc.cli import main

SECTIONS = ("## 1. Sobierajski & Avila, Tables 1–3", "### Table 1", "### Table 2", "### Table 3",
            "## 2. Parker et al.", "### Share of time", "### Thread scaling", "## 3. Speed against error",
            "### Supercell size", "### Sample step", "### Cubic root finders", "### Storage precision",
            "## 4. Visible Woman scale", "## 5. Ideal bound", "## Consistency")


@pytest.fixture(scope="module")
def bench(tmp_path_factory, gl_context):
    out = tmp_path_factory.mktemp("bench")
    suite = Suite.tiny(cache_dir=tmp_path_factory.mktemp("cache"))
    lines = []
    res = run_bench(out, suite, progress=lines.append)
    return out, suite, res, lines


def test_report_has_every_section_and_the_machine(bench):
    out, _, res, _ = bench
    md = (out / "report.md").read_text()
    for heading in SECTIONS:
        assert heading in md, heading
    assert res["machine"]["opengl"] in md
    assert f"{res['machine']['cores']} cores" in md
    # The code the figures come from: this checkout's commit.
    head = subprocess.run(["git", "-C", str(Path(__file__).parents[2]), "rev-parse", "--short=7", "HEAD"],
                          capture_output=True, text=True)
    if head.returncode == 0:
        assert f"PARC {res['machine']['parc']}." in md and f"commit {head.stdout.strip()}" in md
    assert "the tiny suite's stand-in" in md and "not found" not in md     # it chose synthetic volumes


def test_every_picture_the_report_links_is_a_png(bench):
    out, *_ = bench
    md = (out / "report.md").read_text()
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert len(links) >= 9
    for link in links:
        with Image.open(out / link) as img:
            assert img.format == "PNG" and img.width > 0


def test_results_json_matches_what_run_bench_returned(bench):
    out, _, res, _ = bench
    # Strict JSON: a non-finite number (the PSNR of identical images) is null, not Infinity.
    saved = json.loads((out / "results.json").read_text(), parse_constant=lambda c: pytest.fail(c))
    assert saved["checks"] == res["checks"]
    assert saved["table1"]["rows"][0]["samples"] == res["table1"]["rows"][0]["samples"]


def test_every_consistency_check_passes(bench):
    _, _, res, _ = bench
    failed = [c["check"] for c in res["checks"] if not c["ok"]]
    assert not failed, failed
    assert len(res["checks"]) > 50


@pytest.mark.parametrize("table", ["table1", "table2", "table3"])
def test_paper_tables_have_brute_and_parc_at_each_size(bench, table):
    _, suite, res, _ = bench
    rows = res[table]["rows"]
    for size in suite.sizes:
        methods = [r["method"] for r in rows if r["size"] == size]
        assert methods[0] == "brute" and any(m.startswith("parc") for m in methods)
        brute = next(r for r in rows if r["size"] == size and r["method"] == "brute")
        for r in rows:
            if r["size"] == size:
                # speedup is the ratio of the two medians in the same run
                assert r["speedup"] == pytest.approx(brute["total_seconds"] / r["total_seconds"], rel=1e-9)
                assert r["hit_mismatches"] == 0 and r["max_color"] <= 1e-6


def test_isosurface_rows_share_one_ideal_below_each_methods_cells(bench):
    """The ideal of an isosurface frame is the cubics it solves (`parc.ideal`), the same for both
    methods; each method visits at least those cells, PARC fewer than `brute`."""
    _, suite, res, _ = bench
    shares = res["time_shares"]["rows"]
    surfaces = {r["surface"] for r in shares}
    assert len(surfaces) == 2
    for surface in surfaces:
        rows = {r["method"]: r for r in shares if r["surface"] == surface}
        assert set(rows) == {"brute", "parc"}
        assert rows["brute"]["cubics"] == rows["parc"]["cubics"] > 0
        assert rows["brute"]["cells"] > rows["parc"]["cells"] >= rows["parc"]["cubics"]
    for size in suite.sizes:
        rows = [r for r in res["table3"]["rows"] if r["size"] == size]
        assert [r["method"] for r in rows] == ["brute", "parc"]
        for kind in ("primary", "shadow"):
            ideal = {r[f"ideal_{kind}_cells"] for r in rows}
            assert len(ideal) == 1 and 0 < min(ideal) <= min(r[f"{kind}_cells"] for r in rows)


def test_the_papers_tables_show_each_speedups_spread_over_its_rounds(bench):
    # The run's noise: a speedup alone from a median of 2 read as a fact. A tiny image under load
    # can make parc a hundred times slower than brute: below 0.01 a ratio keeps two significant digits.
    from parc.comparison import ratio_text
    out, _, res, _ = bench
    md = (out / "report.md").read_text()
    for table in ("table1", "table2", "table3"):
        for r in res[table]["rows"]:
            if r["method"] != "brute":
                assert r["speedup_low"] <= r["speedup"] * (1 + 1e-9) and r["speedup"] <= r["speedup_high"] * (1 + 1e-9)
                low, mid, high = (ratio_text(r[k]) for k in ("speedup_low", "speedup", "speedup_high"))
                assert f"{mid}× ({low}–{high})" in md, (table, r)


def test_time_shares_add_up(bench):
    _, _, res, _ = bench
    assert len(res["time_shares"]["rows"]) == 4          # skin and bone, by brute and parc
    for r in res["time_shares"]["rows"]:
        assert sum(r["shares"].values()) == pytest.approx(1.0)
        assert ("OpenGL" in r["shares"]) == (r["method"] != "brute")
        # Shares of the whole frame: the parts with the rest ("other") add up to its seconds.
        assert sum(r["parts_seconds"].values()) == pytest.approx(max(r["seconds"], sum(
            v for k, v in r["parts_seconds"].items() if k != "other")), rel=1e-12)


def test_sweeps_cover_what_the_suite_asked(bench):
    _, suite, res, _ = bench
    sizes = {r["supercell"] for r in res["supercells"]["rows"]}
    for s in suite.supercells:
        assert f"{s:g}x{s:g}x{s:g}" in sizes
    assert len(res["steps"]["rows"]) == len(suite.steps)
    assert {r["name"] for r in res["roots"]["rows"]} == {"project", "closed-form", "marmitt"}
    assert {r["dtype"] for r in res["precision"]["rows"]} >= {"float32", "float64"}


def test_root_finder_table_shows_failures_and_every_kind_adding_up(bench):
    out, _, res, _ = bench
    md = (out / "report.md").read_text()
    for r in res["roots"]["rows"]:
        kinds = [r[k] for k in ("missed", "false", "wrong", "inaccurate", "cell")]
        assert sum(kinds) == r["failures"]
        line = next(s for s in md.splitlines() if s.startswith(f"| {r['name']} |"))
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert [int(c.replace(",", "")) for c in cells[-6:]] == [r["failures"], *kinds]


def test_visible_woman_section_maps_the_phantom_it_built(bench):
    _, suite, res, _ = bench
    vw = res["visible_woman"]
    assert tuple(vw["shape"]) == tuple(suite.vw_shape)
    assert vw["bytes"] == 2 * suite.vw_shape[0] * suite.vw_shape[1] * suite.vw_shape[2]
    assert vw["generate_seconds"] is not None and vw["peak_rss_bytes"] > vw["bytes"]
    assert [s["surface"] for s in vw["surfaces"]] == ["skin", "bone"]
    assert vw["iso_change"]["reclassify_proxy_seconds"] > 0


def test_the_phantom_is_reused_on_the_next_run(bench):
    from parc.bench.scale import visible_woman
    _, suite, res, _ = bench
    again = visible_woman(suite, lambda m: None)
    assert again["generate_seconds"] is None
    assert again["path"] == res["visible_woman"]["path"]


def test_runs_at_once_keep_their_child_results_apart_and_out_of_the_terminals_reach(bench, monkeypatch):
    # Two runs shared one result file in the cache, and each deleted it after reading.
    import parc.bench.scale as scale
    _, suite, res, _ = bench
    seen = []

    def child(cmd, **kw):
        out = Path(cmd[cmd.index("--json") + 1])
        seen.append((out, kw.get("start_new_session")))
        out.write_text(json.dumps({"run": len(seen)}))
        return subprocess.CompletedProcess(cmd, 0)
    monkeypatch.setattr(scale.subprocess, "run", child)
    first, second = (scale.visible_woman(suite, lambda m: None) for _ in range(2))
    assert (first["run"], second["run"]) == (1, 2)
    assert seen[0][0] != seen[1][0] and not seen[0][0].exists() and Path(suite.cache_dir) not in seen[0][0].parents
    assert seen[0][1] is True          # a Ctrl-C stops the bench, which stops the child


def test_a_failed_child_is_one_line_of_the_bench_and_of_the_child(bench, monkeypatch, tmp_path, capfd):
    # It was a RuntimeError, a traceback under `parc bench`; the child's own failure a traceback too.
    import parc.bench.scale as scale
    _, suite, _, _ = bench
    monkeypatch.setattr(scale.subprocess, "run", lambda cmd, **kw: subprocess.CompletedProcess(cmd, 1))
    with pytest.raises(InputError, match=r"^the Visible Woman section failed in its child process \(exit 1\)"):
        scale.visible_woman(suite, lambda m: None)
    monkeypatch.undo()
    from data_tools import load_volume
    monkeypatch.setattr(scale, "_end_with_parent", lambda parent=None: None)     # this process is not a child
    monkeypatch.setattr(scale, "measure", lambda path, *_: load_volume(path))
    missing = tmp_path / "no_phantom.raw"
    assert scale.main([str(missing), "--size", "8", "--repeats", "1", "--json", str(tmp_path / "out.json")]) == 1
    err = capfd.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("parc bench: error: ") and str(missing) in err[0], err
    assert not (tmp_path / "out.json").exists()


def test_progress_names_every_section(bench):
    *_, lines = bench
    for n in range(1, 11):
        assert any(line.startswith(f"[{n}/10]") for line in lines)


def test_consistency_catches_a_broken_claim(bench):
    _, _, res, _ = bench
    broken = copy.deepcopy(res)
    broken["table2"]["rows"][1]["max_color"] = 1e-3
    assert [c for c in consistency(broken) if not c["ok"]]
    broken = copy.deepcopy(res)
    broken["ideal"][0]["ideal"] = broken["ideal"][0]["touched"] + 1
    assert [c for c in consistency(broken) if not c["ok"]]


#: What an earlier report's results.json holds that marks the folder as the reports' (`parc.bench._check_out`).
EARLIER_RESULTS = '{"suite": {}, "machine": {}, "checks": [], "seconds": 1.0}'


def _fake_run(fail):
    """A stand-in for the suite: writes a report into the folder it is given, then fails if asked."""
    def run(out, suite, say, command):
        (out / "images").mkdir()
        (out / "images" / "table1.png").write_text("new picture")
        (out / "report.md").write_text("new report")
        (out / "results.json").write_text("{}")
        if fail:
            raise KeyboardInterrupt
        return {"checks": []}
    return run


def _earlier_report(out):
    """An earlier report's files in ``out``."""
    (out / "images").mkdir(parents=True)
    (out / "report.md").write_text("old report")
    (out / "results.json").write_text(EARLIER_RESULTS)
    (out / "images" / "table1.png").write_text("old picture")


def _report_place(tmp_path, monkeypatch, fail, earlier):
    """``tmp_path/a/report`` for a bench whose suite is faked (failing midway where ``fail``),
    holding an earlier report where ``earlier``."""
    import parc.bench
    monkeypatch.setattr(parc.bench, "_run", _fake_run(fail=fail))
    out = tmp_path / "a" / "report"
    if earlier:
        _earlier_report(out)
    return out


@pytest.mark.parametrize("earlier", [False, True])
def test_an_interrupted_bench_leaves_no_folder_or_the_earlier_report_whole(tmp_path, monkeypatch, earlier):
    import parc.bench
    out = _report_place(tmp_path, monkeypatch, fail=True, earlier=earlier)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    with pytest.raises(KeyboardInterrupt):
        run_bench(out, Suite.tiny())
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before
    if earlier:
        assert (out / "report.md").read_text() == "old report"
    monkeypatch.setattr(parc.bench, "_run", _fake_run(fail=False))
    run_bench(out, Suite.tiny())
    assert (out / "report.md").read_text() == "new report"
    assert (out / "images" / "table1.png").read_text() == "new picture"
    assert sorted(p.name for p in tmp_path.rglob(".*")) == []          # no staging folder left


@pytest.mark.parametrize("where", ["no file", "staged file", "other file"])
def test_a_full_disk_names_the_report_not_the_hidden_folder(tmp_path, monkeypatch, where):
    import parc.bench

    def run(stage, suite, say, command):
        name = {"no file": None, "staged file": str(stage / "images" / "t.png"), "other file": "/data/x.nrrd"}[where]
        raise OSError(28, "No space left on device", name)
    monkeypatch.setattr(parc.bench, "_run", run)
    out = tmp_path / "rep"
    if where == "other file":          # a file the suite reads: its own name says it
        with pytest.raises(OSError) as exc:
            run_bench(out, Suite.tiny())
        assert exc.value.filename == "/data/x.nrrd"
    else:
        with pytest.raises(InputError, match=r"^\S*rep: cannot write the report: No space left on device$"):
            run_bench(out, Suite.tiny())
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("taken, words", [("report.md/", "is a folder; the report writes a file there"),
                                          ("results.json/", "is a folder; the report writes a file there"),
                                          ("images", "is a file; the report writes a folder there")])
def test_a_report_place_taken_the_other_way_is_refused_before_any_work(tmp_path, monkeypatch, capsys, taken, words):
    import parc.bench
    ran = []
    monkeypatch.setattr(parc.bench, "_run", lambda *a: ran.append(a))
    out = tmp_path / "r"
    out.mkdir()
    if taken.endswith("/"):
        (out / taken).mkdir()
    else:
        (out / taken).write_text("x")
    assert main(["bench", "--tiny", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{out / taken.rstrip('/')}: {words}" in err[0] and ran == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]


@pytest.mark.parametrize("held", [["results.json"], ["CThead.nrrd", "README.md", "neghip.slc", "x.raw"]])
def test_a_folder_of_other_files_is_refused_before_any_work(tmp_path, monkeypatch, capsys, held):
    # A user's own results.json was written over, and a data folder got the report mixed in.
    import parc.bench
    monkeypatch.setattr(parc.bench, "_run", lambda *a: pytest.fail("the suite ran"))
    out = tmp_path / "mine"
    out.mkdir()
    for name in held:
        (out / name).write_text('{"my": 1}')
    assert main(["bench", "--tiny", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    shown = ", ".join(held[:3]) + (" and 1 more" if len(held) > 3 else "")
    assert err == [f"parc: error: {out}: holds {shown}, and no earlier report; give a new or empty folder, "
                   "or one an earlier parc bench wrote"]
    assert sorted(p.name for p in out.iterdir()) == sorted(held) and (out / held[0]).read_text() == '{"my": 1}'


def test_an_empty_folder_or_one_with_an_earlier_report_and_more_takes_the_report(tmp_path, monkeypatch):
    import parc.bench
    monkeypatch.setattr(parc.bench, "_run", _fake_run(fail=False))
    empty, earlier = tmp_path / "empty", tmp_path / "earlier"
    empty.mkdir()
    (empty / ".hidden").write_text("x")          # hidden files do not count
    earlier.mkdir()
    (earlier / "results.json").write_text(EARLIER_RESULTS)
    (earlier / "notes.txt").write_text("mine")
    for out in (empty, earlier):
        run_bench(out, Suite.tiny())
        assert (out / "report.md").read_text() == "new report"
    assert (earlier / "notes.txt").read_text() == "mine"


def test_cli_refuses_an_output_that_is_a_file(tmp_path, capsys):
    f = tmp_path / "taken"
    f.write_text("x")
    assert main(["bench", "--tiny", "--out", str(f)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("parc: error:") and "not a folder" in err[0]


@pytest.mark.parametrize("flag", ["--out", "--data"])
def test_cli_refuses_an_empty_folder_name(flag, tmp_path, monkeypatch, capsys):
    # Path("") is the working folder: the report went there, or the data were looked for there.
    monkeypatch.chdir(tmp_path)
    assert main(["bench", "--tiny", flag, ""]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{flag}: the folder is empty" in err[0] and list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_a_full_standard_output_after_the_report_says_it_was_written(tmp_path, monkeypatch, capsys):
    # `parc bench > /dev/full` ended in "No space left on device" alone, the report written.
    import parc.bench
    monkeypatch.setattr(parc.bench, "run_bench", lambda out, *a, **k: {"checks": [{"ok": True}], "seconds": 60.0})
    monkeypatch.setattr(parc.bench, "compile_notice", lambda *a, **k: None)
    with open("/dev/full", "w") as full:
        monkeypatch.setattr(sys, "stdout", full)
        assert main(["bench", "--tiny", "--out", str(tmp_path / "rep")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"parc: error: wrote {tmp_path / 'rep' / 'report.md'}, but cannot write to standard output: "
                   "No space left on device"]


def test_cli_help_explains_the_report(capsys):
    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    text = capsys.readouterr().out
    assert "report.md" in text and "--quick" in text and "--out" in text


# The stand-alone scripts in benchmarks/ read the renderer's stats by name;
# run each on a tiny volume so a renamed statistic or phase breaks a test,
# not the next person's measurement.
BENCH_SCRIPTS = {
    "bricking.py": (["--synthetic", "sphere", "--n", "16", "--size", "32", "--repeats", "1"],
                    ["bricked/linear", "same as linear: True"]),
    "bricking.py --tf": (["--synthetic", "sphere", "--n", "16", "--size", "32", "--repeats", "1", "--tf", "greyscale"],
                         ["transfer function greyscale", "same as linear: True"]),
    "cast_parts.py": (["--synthetic", "sphere", "--n", "16", "--size", "32", "--repeats", "1"],
                      ["rays started only", "no skip table", "same as brute: True"]),
    "cast_parts.py --tf": (["--synthetic", "sphere", "--n", "16", "--size", "32", "--repeats", "1",
                            "--tf", "greyscale"], ["ns a sample", "same as brute: True"]),
    "caster_speed.py": (["--size", "16"], ["M cells/s", "skin iso 600", "bone iso 1500"]),
    # Too small for bone: the skin frame is still timed, and bone said to be left out.
    "caster_speed.py --size 8": (["--size", "8"], ["skin iso 600,", "bone iso 1500: not timed"]),
    "raster_speed.py": (["--synthetic", "sphere", "--n", "16", "--size", "64"], ["same as brute: True", "fit: draw"]),
    "context_settings.py": (["--synthetic", "sphere", "--n", "16", "--size", "32", "--repeats", "1",
                             "--rounds", "1"], ["pinned ", "unpinned ", "same as brute: True"]),
    "context_settings.py --setting wait": (["--setting", "wait", "--synthetic", "sphere", "--n", "16", "--size", "32",
                                            "--repeats", "1", "--rounds", "1"],
                                           ["USLEEP ", "default ", "NOTHING ", "same as brute: True"]),
    "raster_speed.py --stages": (["--synthetic", "sphere", "--n", "16", "--size", "64", "--stages"],
                                 ["draw", "readback", "total"]),
}


@pytest.mark.parametrize("script", sorted(BENCH_SCRIPTS))
def test_benchmark_script_runs_on_a_tiny_volume(script, gl_context):
    args, expected = BENCH_SCRIPTS[script]
    path = Path(__file__).resolve().parents[2] / "benchmarks" / script.split()[0]
    run = subprocess.run([sys.executable, str(path), *args], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "same as brute: False" not in run.stdout and "same as linear: False" not in run.stdout
    for text in expected:
        assert text in run.stdout, (text, run.stdout[-2000:])


@pytest.mark.parametrize("script, args, words", [
    ("raster_speed.py", ["--volume", "nope.nrrd", "--iso", "3"], "nope.nrrd: no such file"),
    ("cast_parts.py", ["--synthetic", "sphere", "--n", "8", "--tf", "nosuch"], "unknown transfer function preset"),
    ("bricking.py", ["--synthetic", "sphere", "--n", "8", "--iso", "1e9"], "outside"),
    ("raster_speed.py", ["--synthetic", "sphere", "--n", "8", "--iso", "1e9"], "outside"),
    ("raster_speed.py", ["--synthetic", "sphere", "--n", "8", "--iso", "nan"], "must be finite"),
    ("context_settings.py", ["--volume", "nope.nrrd", "--iso", "3"], "nope.nrrd: no such file"),
    ("caster_speed.py", ["--size", "0"], "must be a whole number of at least 1, got '0'"),
    ("cast_parts.py", ["--repeats", "-2"], "must be a whole number of at least 1, got '-2'"),
    # Flags that would change nothing: the figures would be of another scene than the one named.
    ("cast_parts.py", ["--synthetic", "sphere", "--n", "8", "--tf", "greyscale", "--iso", "3"], "--iso applies"),
    ("bricking.py", ["--volume", "v.nrrd", "--iso", "3", "--n", "8"], "--n sizes a --synthetic volume"),
    ("raster_speed.py", ["--synthetic", "sphere", "--volume", "v.nrrd"], "not both"),
    ("raster_speed.py", ["--synthetic", "sphere", "--n", "8", "--supercell", "2"], "--supercell applies with --stages"),
])
def test_benchmark_script_refuses_bad_input_in_one_line(script, args, words):
    # A missing file or a transfer function misspelt ended in a traceback.
    path = Path(__file__).resolve().parents[2] / "benchmarks" / script
    run = subprocess.run([sys.executable, str(path), *args], capture_output=True, text=True, timeout=300)
    last = run.stderr.splitlines()[-1]
    assert run.returncode == 2 and "Traceback" not in run.stderr, run.stderr[-2000:]
    assert last.startswith(f"{script}: error: ") and words in last, last


def test_a_report_file_that_is_a_pipe_is_refused_before_any_work(tmp_path):
    # Moved onto, a pipe (or for root a link to /dev/null) became a plain file.
    import stat
    from data_tools import InputError
    out = tmp_path / "report"
    out.mkdir()
    os.mkfifo(out / "results.json")
    with pytest.raises(InputError, match="results.json: not a regular file"):
        run_bench(out, Suite.tiny())
    assert stat.S_ISFIFO(os.stat(out / "results.json").st_mode) and sorted(os.listdir(out)) == ["results.json"]


def test_a_report_folder_that_cannot_be_made_is_refused_before_any_work(tmp_path):
    from data_tools import InputError
    blocked = tmp_path / "file"
    blocked.write_text("x")
    with pytest.raises(InputError, match=r"is a file, where the report's folder .* would go") as info:
        run_bench(blocked / "sub" / "report", Suite.tiny())
    assert str(info.value).startswith(f"{blocked}: ") and ".parc-" not in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_the_report_is_staged_inside_an_existing_out_and_moved_in_whole_despite_a_ctrl_c(tmp_path, monkeypatch):
    # Staged beside out, a report for a mount or a link to another file system failed to move
    # in after the whole suite ("Invalid cross-device link"); a Ctrl-C while moving mixed reports.
    import os
    import signal

    import parc.bench
    out = tmp_path / "out"
    _earlier_report(out)
    staged_in = []

    def run(stage, suite, say, command):
        staged_in.append(stage.parent)
        return _fake_run(fail=False)(stage, suite, say, command)
    monkeypatch.setattr(parc.bench, "_run", run)
    move = parc.bench.shutil.move

    def move_then_ctrl_c(src, dst):
        move(src, dst)
        os.kill(os.getpid(), signal.SIGINT)
    monkeypatch.setattr(parc.bench.shutil, "move", move_then_ctrl_c)
    was = signal.signal(signal.SIGINT, signal.default_int_handler)     # ignored in a run started in the background
    try:
        with pytest.raises(KeyboardInterrupt):
            run_bench(out, Suite.tiny())
    finally:
        signal.signal(signal.SIGINT, was)
    assert staged_in == [out]
    assert [(out / n).read_text() for n in ("report.md", "results.json", "images/table1.png")] == [
        "new report", "{}", "new picture"]
    assert sorted(p.name for p in out.iterdir()) == ["images", "report.md", "results.json"]


@pytest.mark.parametrize("earlier", [False, True])
def test_a_move_that_fails_midway_puts_the_earlier_report_back(tmp_path, monkeypatch, earlier):
    # The files moved one by one: a failure at the second left a new picture beside the old report.
    import parc.bench
    out = _report_place(tmp_path, monkeypatch, fail=False, earlier=earlier)
    before = {p.relative_to(tmp_path): p.is_file() and p.read_text() for p in tmp_path.rglob("*")}
    move = parc.bench.shutil.move

    def move_or_fail(src, dst):
        if Path(src).name == "report.md" and Path(src).read_text() == "new report":
            raise PermissionError(1, "Operation not permitted", str(dst))
        return move(src, dst)
    monkeypatch.setattr(parc.bench.shutil, "move", move_or_fail)
    with pytest.raises(PermissionError):
        run_bench(out, Suite.tiny())
    assert {p.relative_to(tmp_path): p.is_file() and p.read_text() for p in tmp_path.rglob("*")} == before


def test_a_link_to_nothing_as_out_is_refused_before_any_work(tmp_path, monkeypatch):
    import parc.bench
    from data_tools import InputError
    monkeypatch.setattr(parc.bench, "_run", lambda *a: pytest.fail("the suite ran"))
    (tmp_path / "link").symlink_to(tmp_path / "nowhere" / "deep")
    with pytest.raises(InputError, match="is a link to .*nowhere/deep, which does not exist"):
        run_bench(tmp_path / "link", Suite.tiny())


def test_an_interrupted_phantom_write_leaves_nothing_in_the_cache(tmp_path, monkeypatch):
    import data_tools.synthetic
    from parc.bench.scale import visible_woman

    def half_then_ctrl_c(path, shape):
        Path(path).write_bytes(b"half a phantom")
        raise KeyboardInterrupt
    monkeypatch.setattr(data_tools.synthetic, "ct_phantom_to_disk", half_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        visible_woman(Suite.tiny(cache_dir=tmp_path), lambda m: None)
    assert [p for p in tmp_path.rglob("*") if p.is_file()] == []


def test_without_a_cache_folder_the_phantom_is_made_in_a_temporary_one_and_removed(monkeypatch):
    # No home folder to keep it in (`raycast.kernel_cache.cache_base` is None): Path(None) had failed.
    import data_tools.synthetic
    from parc.bench.scale import visible_woman
    made = []

    def record_then_ctrl_c(path, shape):
        made.append(Path(path))
        Path(path).write_bytes(b"a phantom")
        raise KeyboardInterrupt
    monkeypatch.setattr(data_tools.synthetic, "ct_phantom_to_disk", record_then_ctrl_c)
    monkeypatch.setattr("raycast.kernel_cache.cache_base", lambda environ: None)
    suite = Suite.tiny()
    assert suite.cache_dir is None
    with pytest.raises(KeyboardInterrupt):
        visible_woman(suite, lambda m: None)
    assert made and made[0].parent.name.startswith("parc-vw-") and not made[0].parent.exists()


_GRANDCHILD = """
import os, subprocess, sys
child = subprocess.Popen([sys.executable, "-c", "import time; from parc.bench.scale import _end_with_parent; "
                          f"_end_with_parent({os.getpid()}); time.sleep(120)"])
print(child.pid, flush=True)
child.wait()
"""


def test_the_visible_woman_child_ends_with_the_bench(tmp_path):
    # In a session of its own no terminal's Ctrl-C reaches it: a bench stopped before it
    # could kill the child left it rendering for minutes.
    import os
    import signal
    import time
    bench = subprocess.Popen([sys.executable, "-c", _GRANDCHILD], stdout=subprocess.PIPE, text=True)
    child = int(bench.stdout.readline())
    time.sleep(1.0)
    state = Path(f"/proc/{child}/status")
    if not Path("/proc/self/status").exists():
        pytest.skip("no /proc to watch the child in")
    assert state.exists() and "\tZ" not in state.read_text()        # watching, not ended on its own
    os.kill(bench.pid, signal.SIGKILL)
    bench.wait()
    for _ in range(100):
        if not state.exists() or "\tZ" in state.read_text():
            break
        time.sleep(0.1)
    assert not state.exists() or "\tZ" in state.read_text()


# The consistency checks and the ideal table on hand-made results: the suite's own results are
# all consistent, so a loosened check passed on them.

def _hand_results(t1_rows=(), ideal_rows=()):
    return {"table1": {"rows": list(t1_rows)}, "table2": {"rows": []}, "table3": {"rows": []},
            "supercells": {"rows": []}, "time_shares": {"rows": []}, "visible_woman": {"surfaces": [], "size": 8},
            "steps": {"rows": []}, "precision": {"rows": []}, "ideal": list(ideal_rows),
            "roots": {"rows": [{"name": "project", "failures": 0}]}, "threads": {"rows": []}}


def _t1(method, samples):
    return {"method": method, "size": 8, "samples": samples, "ideal_samples": 50, "cast_seconds": 0.1,
            "total_seconds": 0.2, "hit_mismatches": 0, "max_color": 0.0}


def _failed(res):
    return [c["check"] for c in consistency(res) if not c["ok"]]


def test_a_zero_ideal_count_fails_its_check():
    row = {"scene": "s", "size": 8, "method": "parc", "unit": "cells", "ideal": 3, "touched": 5}
    assert _failed(_hand_results(ideal_rows=[row])) == []
    assert len(_failed(_hand_results(ideal_rows=[{**row, "ideal": 0}]))) == 1


def test_more_contributing_than_ideal_fails_its_check():
    row = {"scene": "s", "size": 8, "method": "parc", "unit": "cells", "ideal": 3, "contributing": 3, "touched": 5}
    assert _failed(_hand_results(ideal_rows=[row, {**row, "contributing": None}])) == []
    assert [c for c in _failed(_hand_results(ideal_rows=[{**row, "contributing": 4}])) if "≤ ideal" in c]
    assert [c for c in _failed(_hand_results(ideal_rows=[{**row, "contributing": 0}])) if "contributing" in c]


def test_parc_taking_more_samples_than_brute_fails_its_check():
    assert _failed(_hand_results(t1_rows=[_t1("brute", 100), _t1("parc", 60)])) == []
    assert [c for c in _failed(_hand_results(t1_rows=[_t1("brute", 100), _t1("parc", 150)])) if "≤ brute" in c]


def test_the_ideal_tables_ratio_is_touched_over_ideal():
    from parc.bench.report import ideal
    md, _ = ideal(_hand_results(t1_rows=[{**_t1("parc", 125_000), "ideal_samples": 50_000,
                                          "contributing_samples": 20_000}]))
    row = table_cells(md, "## 5. Ideal bound")[0]
    assert (row["ideal (×10³)"], row["contributing (×10³)"], row["touched (×10³)"]) == ("50.0", "20.0", "125.0")
    assert row["touched / ideal"] == "2.5"


def _t3_run(method, phases, seconds, cells, solves, shadow_cells, shadow_solves, speedup):
    """A `parc.compare` row as `parc.bench.tables.table3` reads it (hits: a tenth of the cells)."""
    return {"method": method, "phases": phases, "seconds": seconds, "cells_visited": cells, "cubic_solves": solves,
            "hits": cells // 10,
            "shadow_cells": shadow_cells, "shadow_solves": shadow_solves, "speedup": speedup,
            "hit_mismatches": 0, "max_depth_cells": 0.0, "max_color": 0.0, "psnr": float("inf")}


def test_table3_splits_primary_and_shadow_time_and_divides_by_brute_at_the_same_size(monkeypatch, tmp_path):
    """Primary casting is the cast plus the proxy's rasterization, shadow time the shadow rays
    plus the lights' rasterization, primary total the frame less the shadow time, the ideal
    counts brute's cubics at that size (the rows' own may differ); each speedup
    is brute's time over the method's at the same image size, and the report shows each in its
    column (hand-made runs, sums by hand)."""
    from types import SimpleNamespace

    from parc.bench import tables
    runs = {8: [_t3_run("brute", {"cast": 2.0, "shadow": 3.0}, 6.0, 100, 40, 50, 20, 1.0),
                _t3_run("parc", {"cast": 0.3, "raster": 0.2, "shadow": 0.5, "raster_lights": 0.5}, 2.0,
                        60, 39, 30, 19, 3.0)],
            16: [_t3_run("brute", {"cast": 9.0, "shadow": 4.0}, 15.0, 400, 160, 90, 35, 1.0),
                 _t3_run("parc", {"cast": 1.0, "raster": 0.5, "shadow": 1.5, "raster_lights": 0.5}, 5.0,
                         200, 158, 70, 34, 3.0)]}
    monkeypatch.setattr(tables.scenes, "neuron_floor", lambda size, *a: (SimpleNamespace(size=size), "stand-in"))
    monkeypatch.setattr(tables, "_rows", lambda scene, *a: copy.deepcopy(runs[scene.size]))
    suite = SimpleNamespace(sizes=(8, 16), data_dir=None, small_volumes=True, repeats=1)
    res = tables.table3(suite, lambda m: None, {})
    got = {(r["method"], r["size"]): r for r in res["rows"]}
    assert list(got) == [("brute", 8), ("parc", 8), ("brute", 16), ("parc", 16)]
    want = {  # (primary cast, primary total, shadow, primary casting speedup, primary total speedup, shadow speedup)
        ("brute", 8): (2.0, 3.0, 3.0, 1.0, 1.0, 1.0), ("parc", 8): (0.5, 1.0, 1.0, 4.0, 3.0, 3.0),
        ("brute", 16): (9.0, 11.0, 4.0, 1.0, 1.0, 1.0), ("parc", 16): (1.5, 3.0, 2.0, 6.0, 11.0 / 3.0, 2.0)}
    for key, (cast, total, shadow, primary_x, primary_total_x, shadow_x) in want.items():
        r = got[key]
        assert (r["primary_cast_seconds"], r["primary_total_seconds"], r["shadow_seconds"]) == \
            pytest.approx((cast, total, shadow)), key
        assert (r["primary_speedup"], r["primary_total_speedup"], r["shadow_speedup"]) == \
            pytest.approx((primary_x, primary_total_x, shadow_x)), key
        assert (r["ideal_primary_cells"], r["ideal_shadow_cells"]) == ((40, 20) if key[1] == 8 else (160, 35))
        assert r["contributing_primary_cells"] == (10 if key[1] == 8 else 40)     # brute's hits
    assert got[("parc", 16)]["primary_cells"] == 200 and got[("parc", 16)]["shadow_cells"] == 70
    from parc.bench.report import paper_tables
    md = paper_tables({"table1": {"rows": [], "source": "-", "work_size": 8}, "table2": {"rows": [], "source": "-"},
                       "table3": res}, tmp_path)
    after = md[md.index("### Table 3: neuron on a floor, two shadowing point lights (Fig. 13)"):]
    lines = next(part for part in after if part.startswith("| method")).splitlines()
    head = [c.strip() for c in lines[0].strip("|").split("|")]
    shown = [dict(zip(head, (c.strip() for c in line.strip("|").split("|")))) for line in lines[2:]]
    assert [(r["method"], r["primary casting speedup"], r["primary total speedup"], r["shadow speedup"],
             r["total speedup"]) for r in shown] == [
        ("brute", "1.00×", "1.00×", "1.00×", "1.00×"), ("parc", "4.00×", "3.00×", "3.00×", "3.00×"),
        ("brute", "1.00×", "1.00×", "1.00×", "1.00×"), ("parc", "6.00×", "3.67×", "2.00×", "3.00×")]
    assert [(r["primary casting (s)"], r["primary total (s)"], r["shadow (s)"]) for r in shown[:2]] == [
        ("2.000", "3.000", "3.000"), ("0.500", "1.000", "1.000")]


def test_the_visible_woman_child_already_adopted_ends_at_once():
    # The bench names itself: read in the child, the parent could be the process that had
    # already adopted it (a bench killed while the child started), which never ends.
    import os
    import time
    code = ("import sys, time; from parc.bench.scale import _end_with_parent; "
            "_end_with_parent(int(sys.argv[1])); print('watching', flush=True); time.sleep(60)")
    gone = 2 ** 22 + 12345                                    # no such process: the bench has ended
    child = subprocess.run([sys.executable, "-c", code, str(gone)], capture_output=True, text=True, timeout=50)
    assert child.returncode == 130
    # Named by a parent that is there, it watches (and does not end on its own).
    child = subprocess.Popen([sys.executable, "-c", code, str(os.getpid())], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline() == "watching\n"
        time.sleep(1.0)
        assert child.poll() is None
    finally:
        child.kill()
        child.wait()


def test_the_bench_says_it_compiles_while_any_kind_of_render_is_uncompiled(tmp_path, monkeypatch):
    # After a render had cached the isosurface casters, the suite's first translucent scene
    # compiled for half a minute unsaid: the notice looked for any kernel cached at all.
    import numba.core.config
    import raycast.kernel_cache
    from parc.bench import _kernels_used
    from parc.outputs import compile_notice
    from raycast.iso import cast_iso_image
    monkeypatch.setattr(raycast.kernel_cache, "cache_folder", lambda: tmp_path)
    kernels = [k for k, _ in _kernels_used()]
    modules = {k.py_func.__module__ for k in kernels}
    assert cast_iso_image in kernels and {"raycast.composite", "raycast.merged", "raycast.shadow",
                                          "parc.rootstudy", "raycast.shade"} <= modules

    def says():
        said = []
        compile_notice(said.append, _kernels_used())
        return bool(said) and "compiling the ray casters" in said[0]

    def cache(kernel):
        index = tmp_path / Path(kernel._cache._cache_file._index_path).relative_to(numba.core.config.CACHE_DIR)
        index.parent.mkdir(parents=True, exist_ok=True)    # as Numba reads it, in the folder given
        index.write_bytes(b"")

    cache(cast_iso_image)
    assert says()
    for kernel in kernels:
        cache(kernel)
    assert not says()


def test_the_kernels_the_notice_asks_for_are_those_the_suite_runs(tmp_path):
    # The notice asked for the shaded translucent casters too, which no scene of the suite
    # uses: never cached by it, they made every later run say it was compiling. In a process
    # of its own, so that no other test's renders compile them.
    code = ("import sys; from pathlib import Path; from parc.bench import Suite, _kernels_used, run_bench; "
            "run_bench(Path(sys.argv[1]), Suite.tiny(cache_dir=Path(sys.argv[2]))); "
            "print(sorted(k.py_func.__name__ for k, _ in _kernels_used() if not k.signatures))")
    p = subprocess.run([sys.executable, "-c", code, str(tmp_path / "out"), str(tmp_path / "cache")],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    assert p.stdout.strip().splitlines()[-1] == "[]"


def test_a_stand_in_names_the_files_it_stands_in_for(tmp_path):
    # With neghip.slc present, the report said "`poship.slc`/`neghip.slc` not found".
    from parc.bench.scenes import iron_protein
    (tmp_path / "neghip.slc").write_bytes(b"")
    assert iron_protein(8, tmp_path)[1].endswith("(`poship.slc` not found)")
    (tmp_path / "neghip.slc").unlink()
    assert iron_protein(8, tmp_path)[1].endswith("(`poship.slc` and `neghip.slc` not found)")


# Every consistency check must fail on hand-made results that break exactly its claim: the suite's
# own results are consistent, so a check made vacuous (a value compared with itself, a constant
# True, a dropped row kind) passes on them. Truth: the numbers below, written by hand.

def _exact_row(**kw):
    return {"hit_mismatches": 0, "max_color": 0.0, **kw}


@pytest.mark.parametrize("part, good, bad", [
    ("steps", {"step": 0.5, "parc_vs_brute": 0.0}, {"step": 0.5, "parc_vs_brute": 1e-3}),
    ("precision", {"volume": "v", "dtype": "uint8", "parc_vs_brute": 0.0},
     {"volume": "v", "dtype": "uint8", "parc_vs_brute": 1e-3}),
    ("supercells", _exact_row(supercell=4), _exact_row(supercell=4, hit_mismatches=3)),
    ("time_shares", _exact_row(surface="skin", method="parc"), _exact_row(surface="skin", method="parc", max_color=0.1)),
    ("visible_woman", _exact_row(surface="skin", brute_cells=9, parc_cells=3),
     _exact_row(surface="skin", brute_cells=9, parc_cells=3, hit_mismatches=1)),
])
def test_each_exactness_check_fails_on_its_own_broken_row(part, good, bad):
    def results(row):
        res = _hand_results()
        (res[part]["surfaces"] if part == "visible_woman" else res[part]["rows"]).append(row)
        return res
    assert _failed(results(good)) == []
    assert len(_failed(results(bad))) == 1


def test_casting_longer_than_the_total_fails_its_check():
    ok = _t1("parc", 60)
    assert _failed(_hand_results(t1_rows=[_t1("brute", 100), ok])) == []
    broken = {**ok, "cast_seconds": 0.3, "total_seconds": 0.2}
    assert [c for c in _failed(_hand_results(t1_rows=[_t1("brute", 100), broken])) if "casting ≤ total" in c]


def test_a_root_finder_failure_fails_its_check():
    res = _hand_results()
    res["roots"]["rows"] = [{"name": "project", "failures": 2}]
    assert [c for c in _failed(res) if "root finders" in c]


@pytest.mark.parametrize("key", ["sums", "parc_within_brute"])
def test_work_map_checks_fail_when_their_claim_is_false(key):
    res = _hand_results(t1_rows=[_t1("brute", 100), _t1("parc", 60)])
    res["table1"]["work"] = {"checks": {"sums": True, "parc_within_brute": True}}
    assert _failed(res) == []
    res["table1"]["work"]["checks"][key] = False
    assert len(_failed(res)) == 1


@pytest.mark.parametrize("parc_total", [60, 61])
def test_work_maps_sum_check_compares_the_map_with_the_render_stats(monkeypatch, parc_total):
    """`work_maps`'s "sums": each method's per-pixel map summed equals its stats' total (here by hand:
    brute's map sums to 100, parc's to 60; parc's stats say `parc_total`)."""
    import numpy as np
    from parc.bench import tables
    maps = {"brute": np.full((2, 5), 10), "parc": np.full((2, 5), 6)}
    totals = {"brute": 100, "parc": parc_total}
    monkeypatch.setattr(tables, "render", lambda scene, m, work: SimpleNamespace(
        work=maps[m], stats={"samples": totals[m]}))
    got = tables.work_maps(None, "samples")
    assert got["checks"]["sums"] is (parc_total == 60)
    assert got["checks"]["parc_within_brute"] is True


def test_the_scenes_pictures_are_their_images_rounded_to_bytes(tmp_path, gl_context):
    import numpy as np

    import parc
    from data_tools.synthetic import blobs
    from parc.bench import _pictures
    vol = blobs(6, seed=1)
    scene = parc.Scene(camera=parc.Camera.framing(*vol.bounds), size=(12, 10),
                       volumes=[parc.Translucent(vol, "greyscale")])
    _pictures({"table1": scene}, tmp_path)
    want = np.clip(np.rint(parc.render(scene, method="brute").image * 255.0), 0, 255)
    with Image.open(tmp_path / "table1.png") as img:
        assert img.mode == "RGBA" and img.size == (12, 10)
        assert (np.asarray(img) == want).all()


@pytest.mark.parametrize("flags, name", [([], "full"), (["--quick"], "quick"), (["--tiny"], "tiny")])
@pytest.mark.parametrize("ok", [True, False])
def test_cli_runs_the_suite_asked_and_fails_when_a_check_fails(tmp_path, monkeypatch, capsys, flags, name, ok):
    import parc.bench
    seen = []

    def run(out, suite, **kw):
        seen.append(suite)
        return {"checks": [{"check": "a", "ok": True}, {"check": "b", "ok": ok}], "seconds": 6.0}
    monkeypatch.setattr(parc.bench, "run_bench", run)
    monkeypatch.setattr(parc.bench, "_kernels_used", lambda: [])
    assert main(["bench", *flags, "--out", str(tmp_path / "r")]) == (0 if ok else 1)
    assert [s.name for s in seen] == [name]
    assert f"{2 if ok else 1} of 2 checks pass (0.1 min)" in capsys.readouterr().out


def test_cli_reads_real_volumes_from_the_folder_given(tmp_path, monkeypatch):
    import parc.bench
    seen = []
    monkeypatch.setattr(parc.bench, "run_bench", lambda out, suite, **kw: seen.append(suite) or {
        "checks": [], "seconds": 1.0})
    monkeypatch.setattr(parc.bench, "_kernels_used", lambda: [])
    assert main(["bench", "--quick", "--data", str(tmp_path), "--out", str(tmp_path / "r")]) == 0
    assert seen[0].data_dir == tmp_path and seen[0].name == "quick"


def test_the_reports_counts_of_one_read_in_the_singular(bench):
    # The tiny suite renders once a round: "the median of 1 renders" read as a slip.
    out, _, res, _ = bench
    md = (out / "report.md").read_text()
    repeats, cores = res["suite"]["repeats"], res["machine"]["cores"]
    assert f"the median of {repeats} render{'' if repeats == 1 else 's'} after a warm-up" in md
    assert f", {cores} core{'' if cores == 1 else 's'} (" in md
    assert "1 renders" not in md and "1 cores" not in md and "1 threads" not in md and "1 Numba threads" not in md
