"""`parc bench`: the reproducible scoreboard, speed against error, every figure measured in one run.

The suite (`run_bench`) writes ``report.md``, ``results.json``, PNG
charts and the scenes' pictures into one folder:

1. Sobierajski & Avila's Tables 1-3 (`tables`): CT translucent, iron
   protein isosurface inside a translucent volume, a neuron on a floor with
   two shadowing lights; `brute` against `parc` at two image sizes.
2. Parker et al.'s Tables 1-2 (`parker`): the share of traversal,
   intersection and shading in a CT isosurface frame; thread scaling.
3. Sweeps of speed against error (`sweeps`): supercell size, sample step,
   cubic root finder, storage precision.
4. Visible Woman scale (`scale`): a 512x512x1734 int16 phantom, memory-mapped.
5. The ideal bound (`parc.ideal`) and the contributing work within it, next to what each method
   touched.

Real volumes from ``../shared/data`` are used when present, synthetic
analogues otherwise; the report says which. Three suites: `Suite.full`
(the default, about 2 minutes on 2 cores), `Suite.quick` (under a minute)
and `Suite.tiny` (seconds; for the tests: its numbers check the report's
consistency, not speed).
"""
from __future__ import annotations

import contextlib
import json
import os
import platform
import shutil
import subprocess
import tempfile
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from data_tools import InputError
from data_tools.errors import os_reason
from data_tools.io import written_path
from data_tools.signals import building, signals_held

from ..outputs import compile_notice, late_compile_notice, note, print_out, to_json
from .scenes import default_data_dir


def default_cache_dir():
    """Where the Visible Woman phantom is kept between runs: ``bench`` in `raycast.kernel_cache.cache_base`;
    None where there is no home folder (each run then makes its own)."""
    from raycast.kernel_cache import cache_base

    base = cache_base(os.environ)
    return Path(base) / "bench" if base is not None else None


@dataclass(frozen=True)
class Suite:
    """What one bench run measures.

    Attributes
    ----------
    name : str
    sizes : tuple of int
        Image sides of the paper tables (the paper's 300 and 600).
    parker_size : int
        Image side of the CT isosurface sections (time shares, threads, sweeps).
    repeats : int
        Timed renders per measurement after one warm-up; medians are reported.
    supercells : tuple of float
        Supercell sizes of the sweep, in cells.
    steps : tuple of float
        Sample steps of the sweep, in smallest spacings.
    roots_quick : bool
        The root-finder study's quick sample of the hard-ray suite.
    roots_n : int or None
        Rays per hard-ray category (overrides ``roots_quick``).
    vw_shape : (nx, ny, nz)
        The memory-mapped phantom.
    vw_size : int
        Its image side.
    small_volumes : bool
        Small synthetic volumes everywhere (the tests' suite).
    data_dir, cache_dir : Path or None
        Real volumes (absent: synthetic analogues); where the phantom is kept (None: made
        anew in a temporary folder).
    """

    name: str = "full"
    sizes: tuple = (300, 600)
    parker_size: int = 512
    repeats: int = 5
    supercells: tuple = (0.5, 1.0, 2.0, 4.0, 8.0)
    steps: tuple = (2.0, 1.0, 0.5, 0.25)
    roots_quick: bool = False
    roots_n: int | None = None
    vw_shape: tuple = (512, 512, 1734)
    vw_size: int = 512
    small_volumes: bool = False
    data_dir: Path | None = field(default_factory=default_data_dir)
    cache_dir: Path | None = field(default_factory=default_cache_dir)

    @classmethod
    def full(cls, **kw):
        """The whole suite at the papers' sizes (about 2 minutes on 2 cores; the phantom's first build adds one)."""
        return cls(**kw)

    @classmethod
    def quick(cls, **kw):
        """A reduced suite, under a minute: half-size images, 2 repeats, a 256x256x867 phantom."""
        return replace(cls(name="quick", sizes=(150, 300), parker_size=256, repeats=2, supercells=(1.0, 2.0, 4.0, 8.0),
                           steps=(1.0, 0.5, 0.25), roots_quick=True, vw_shape=(256, 256, 867), vw_size=256), **kw)

    @classmethod
    def tiny(cls, **kw):
        """Seconds: tiny synthetic volumes and images, for checking the report, not for reading speed."""
        return replace(cls(name="tiny", sizes=(16, 24), parker_size=24, repeats=1, supercells=(1.0, 4.0),
                           steps=(1.0, 0.5), roots_n=40, vw_shape=(24, 24, 80), vw_size=24, small_volumes=True,
                           data_dir=None), **kw)


#: ``(key, title, function name)`` of each section, in report order.
SECTIONS = (
    ("table1", "Table 1: CT translucent", "tables.table1"),
    ("table2", "Table 2: iron protein", "tables.table2"),
    ("table3", "Table 3: neuron and floor, shadows", "tables.table3"),
    ("time_shares", "Parker Table 1: time shares", "parker.time_shares"),
    ("threads", "Parker Table 2: thread scaling", "parker.thread_scaling"),
    ("supercells", "supercell sweep", "sweeps.supercell_sweep"),
    ("steps", "step sweep", "sweeps.step_size_sweep"),
    ("roots", "root finders", "sweeps.root_finders"),
    ("precision", "storage precision", "sweeps.precision"),
    ("visible_woman", "Visible Woman scale", "scale.visible_woman"),
)


def machine():
    """The machine the numbers come from: CPU, cores, threads, OpenGL renderer, versions."""
    import moderngl
    import numba

    from ..gl import context_info
    cpu = platform.processor() or platform.machine()
    with contextlib.suppress(OSError):           # no /proc off Linux: keep platform's name
        with open("/proc/cpuinfo") as f:
            cpu = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), cpu)
    info = context_info()
    return {"cpu": cpu, "cores": os.cpu_count(), "numba_threads": numba.config.NUMBA_NUM_THREADS,
            "opengl": f"{info['GL_RENDERER']} (OpenGL {info['GL_VERSION']})",
            "python": platform.python_version(), "numpy": np.__version__, "numba": numba.__version__,
            "moderngl": moderngl.__version__, "os": platform.platform(), "parc": source_version(),
            "date": time.strftime("%Y-%m-%d %H:%M %Z")}


def source_version():
    """PARC's version and, run from a git checkout, its commit (``+changes`` when edited since):
    a report's figures are then tied to the code that made them."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        v = version("parc")
    except PackageNotFoundError:
        v = "unknown"
    root = Path(__file__).resolve().parents[2]
    try:
        git = subprocess.run(["git", "-C", str(root), "describe", "--always", "--dirty=+changes"],
                             capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return v
    commit = git.stdout.strip()
    return f"{v}, commit {commit}" if git.returncode == 0 and commit else v


def run_bench(out, suite=None, *, progress=None, command=None):
    """Run the suite and write ``out/report.md``, ``out/results.json``, charts and pictures.

    Parameters
    ----------
    out : str or Path
        Output folder (created). The report is written into a hidden folder
        in it (or in the nearest folder above it) and moved in once whole: a
        failed or interrupted run leaves an earlier report there as it was.
    suite : Suite, optional
        Default `Suite.full`.
    progress : callable(str) or None
        Told what is being measured, step by step.
    command : str, optional
        The command line to print in the report.

    Returns
    -------
    dict
        Everything measured (also in ``results.json``), with ``checks``: the
        consistency checks the report's numbers pass (see `consistency`).

    Raises
    ------
    OpenGLUnavailable
        No OpenGL context: PARC cannot run, so neither can the bench.
    """
    suite = suite or Suite.full()
    out = Path(out)
    _check_out(out)
    stage = _stage_for(out)
    try:
        try:
            with building(stage):
                res = _run(stage, suite, progress or (lambda msg: None), command)
        except OSError as exc:
            # A write into the hidden folder: its name, or none (a picture's save on a full
            # disk), would mean nothing to the user; the report's would.
            if exc.filename is not None and stage not in Path(exc.filename).parents:
                raise
            raise InputError(f"{out}: cannot write the report: {os_reason(exc)}") from None
        _publish(stage, out)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return res


#: What every report holds, beside its charts and pictures.
REPORT_FILES = ("report.md", "results.json")


def _check_out(out):
    """Refuse, before any work, an ``out`` the report cannot go into whole, or a folder that
    holds other files and no earlier report: the report would be mixed into it (the data
    folder, say), and a ``results.json`` there written over."""
    _check_places(out, REPORT_FILES, ["images"])
    if not out.is_dir() or _holds_a_report(out):
        return
    others = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    if others:
        shown = ", ".join(others[:3]) + (f" and {len(others) - 3} more" if len(others) > 3 else "")
        raise InputError(f"{out}: holds {shown}, and no earlier report; give a new or empty folder, "
                         "or one an earlier parc bench wrote")


def _holds_a_report(out):
    """Whether ``out`` holds an earlier report: a ``results.json`` with what every report's holds."""
    try:
        res = json.loads((out / "results.json").read_text())
    except (OSError, ValueError):
        return False
    return isinstance(res, dict) and {"suite", "machine", "checks"} <= set(res)


def _check_places(out, files, folders):
    """Refuse, before any work, a report whose files or folders ``out`` holds the other way round,
    or a file there that is a device or a pipe (renamed onto, it would become a plain file)."""
    for name in files:
        if (out / name).is_dir():
            raise InputError(f"{out / name}: is a folder; the report writes a file there")
        written_path(out / name)
    for name in folders:
        if (out / name).exists() and not (out / name).is_dir():
            raise InputError(f"{out / name}: is a file; the report writes a folder there")


def _stage_for(out):
    """A hidden folder the report is written into before it replaces the old one in ``out``:
    in ``out``, or in the nearest folder above it that exists, on the file system the report
    goes to (``out`` may be a mount or a link elsewhere), so that its files are renamed in."""
    if out.is_symlink() and not out.exists():
        raise InputError(f"{out}: is a link to {os.readlink(out)}, which does not exist")
    base = out
    while not base.exists() and base != base.parent:
        base = base.parent
    if not base.is_dir():
        raise InputError(f"{base}: is a file, where the report's folder {out} would go")
    try:
        return Path(tempfile.mkdtemp(prefix=f".{out.name}.parc-", dir=base))
    except OSError as exc:          # its name would mean nothing to the user
        raise InputError(f"{out}: cannot write the report there: {os_reason(exc)}") from None


def _publish(stage, out):
    """Move the staged report into ``out``, file by file, once each place has been checked. The
    files it replaces are moved aside into the stage first, and back if a move fails: an
    interrupted or failed run leaves the old report whole, and no new folder."""
    files = sorted(p for p in stage.rglob("*") if p.is_file())
    names = [p.relative_to(stage) for p in files]
    _check_places(out, names, {str(n.parent) for n in names if n.parent != Path(".")})
    replaced = stage / ".replaced"
    done, made = [], []
    with signals_held(done=f"the report in {out}"):      # its files move in all together or not at all
        try:
            for path, name in zip(files, names):
                place = out / name
                _make_folders(place.parent, made)
                aside = None
                if place.exists() or place.is_symlink():
                    aside = replaced / name
                    aside.parent.mkdir(parents=True, exist_ok=True)
                    shutil.move(place, aside)
                done.append((place, aside))
                shutil.move(path, place)            # a rename; a copy where a folder in out is a mount
        except BaseException:
            for place, aside in reversed(done):
                with contextlib.suppress(OSError):
                    place.unlink(missing_ok=True)
                    if aside is not None:
                        shutil.move(aside, place)
            for folder in reversed(made):
                with contextlib.suppress(OSError):
                    folder.rmdir()
            raise


def _make_folders(folder, made):
    """Make ``folder`` and those above it that are missing, adding each made to ``made``."""
    missing = []
    while not folder.exists():
        missing.append(folder)
        folder = folder.parent
    for folder in reversed(missing):
        folder.mkdir()
        made.append(folder)


def _run(out, suite, say, command):
    """The suite, run, its report written into ``out``: what `run_bench` returns."""
    from importlib import import_module

    from . import report

    images_dir = out / "images"
    images_dir.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    res = {"suite": {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(suite).items()},
           "machine": machine(), "command": command}
    images = {}
    for n, (key, title, func) in enumerate(SECTIONS, 1):
        module, name = func.split(".")
        t0 = time.perf_counter()
        say(f"[{n}/{len(SECTIONS)}] {title}")
        fn = getattr(import_module(f".{module}", __name__), name)
        step = lambda msg, n=n: say(f"[{n}/{len(SECTIONS)}]   {msg}")  # noqa: E731
        res[key] = fn(suite, step, images) if module == "tables" else fn(suite, step)
        res[key]["seconds"] = time.perf_counter() - t0
    say("pictures of the tables' scenes")
    _pictures(images, images_dir)
    res["seconds"] = time.perf_counter() - started
    md, ideal_rows = _report(res, out, report)
    res["ideal"] = [dict(zip(("scene", "size", "unit", "method", "ideal", "contributing", "touched"), r))
                    for r in ideal_rows]
    res["checks"] = consistency(res)
    md += _checks_md(res["checks"])
    (out / "report.md").write_text("\n".join(md) + "\n")
    (out / "results.json").write_text(to_json(res))
    return res


def _pictures(images, folder):
    from PIL import Image

    from ..renderer import render
    for key, scene in images.items():
        img = render(scene, method="parc").image
        rgba = np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)
        Image.fromarray(rgba, "RGBA").save(folder / f"{key}.png")


def _report(res, out, report):
    m = res["machine"]
    s = res["suite"]
    md = ["# PARC benchmark report", "",
          f"Suite `{s['name']}`, run {m['date']} in {res['seconds'] / 60:.1f} min"
          + (f" with `{res['command']}`" if res.get("command") else "") + ".", "",
          f"PARC {m.get('parc', 'unknown')}. Machine: {m['cpu']}, {report.counted(m['cores'], 'core')} "
          f"({report.counted(m['numba_threads'], 'Numba thread')}); OpenGL: {m['opengl']}; "
          f"Python {m['python']}, NumPy {m['numpy']}, Numba {m['numba']}, "
          f"moderngl {m['moderngl']}; {m['os']}.", "",
          "Every speedup is a ratio of two times measured in this run on this machine: each the median of "
          f"{report.counted(s['repeats'], 'render')} after a warm-up, the methods timed in turn round by round; "
          "in brackets after a speedup, the lowest and highest of the rounds' own ratios. `brute` is the unaccelerated "
          "caster; `parc` casts the same rays over OpenGL-rasterized segments with the same traversal and "
          "intersection code.", ""]
    md += report.paper_tables(res, out)
    md += report.parker(res, out)
    md += report.sweeps(res, out)
    md += report.scale(res, out)
    ideal_md, rows = report.ideal(res)
    md += ideal_md
    return md, rows


def consistency(res):
    """Checks the numbers must pass: counts positive, contributing ≤ ideal ≤ touched, zero error where
    exactness is claimed.

    Returns a list of ``{"check": str, "ok": bool}``.
    """
    checks = []

    def check(what, ok):
        checks.append({"check": what, "ok": bool(ok)})

    exact = [(f"table{n} {r['method']} {r['size']}²", r) for n in (1, 2, 3) for r in res[f"table{n}"]["rows"]]
    exact += [(f"supercell {r['supercell']}", r) for r in res["supercells"]["rows"]]
    exact += [(f"time shares {r['surface']} {r['method']}", r) for r in res["time_shares"]["rows"]]
    exact += [(f"Visible Woman {r['surface']}", r) for r in res["visible_woman"]["surfaces"]]
    for what, r in exact:
        check(f"{what}: parc equals brute (hit masks, |Δcolour| ≤ 1e-6)",
              r["hit_mismatches"] == 0 and r["max_color"] <= 1e-6)
    for r in res["steps"]["rows"]:
        check(f"step {r['step']:g}: parc equals brute", r["parc_vs_brute"] <= 1e-6)
    for r in res["precision"]["rows"]:
        check(f"precision {r['volume']} {r['dtype']}: parc equals brute", r["parc_vs_brute"] <= 1e-6)
    for r in res["ideal"]:
        check(f"{r['scene']} {r['size']}² {r['method']}: ideal {r['unit']} > 0 and ≤ touched",
              0 < r["ideal"] <= r["touched"])
        if r.get("contributing") is not None:
            check(f"{r['scene']} {r['size']}² {r['method']}: contributing {r['unit']} > 0 and ≤ ideal",
                  0 < r["contributing"] <= r["ideal"])
    for n, keys in ((1, ("samples",)), (2, ("cells", "samples")), (3, ("primary_cells", "shadow_cells"))):
        rows = res[f"table{n}"]["rows"]
        for key in keys:
            brute = {r["size"]: r[key] for r in rows if r["method"] == "brute"}
            for r in rows:
                check(f"table{n} {r['method']} {r['size']}²: {key} positive and ≤ brute's",
                      0 < r[key] <= brute[r["size"]])
        for r in rows:
            check(f"table{n} {r['method']} {r['size']}²: times positive, casting ≤ total",
                  0 < r.get("cast_seconds", r.get("primary_cast_seconds", 0)) <= r["total_seconds"])
    for r in res["visible_woman"]["surfaces"]:
        check(f"Visible Woman {r['surface']}: parc's cells positive and ≤ brute's", 0 < r["parc_cells"] <= r["brute_cells"])
    for key, what in (("supercells", "cells visited"), ("table1", "samples taken")):
        work = res[key].get("work")
        if work is not None:
            check(f"{key} work maps: each method's {what} per pixel sum to its total", work["checks"]["sums"])
            check(f"{key} work maps: parc's {what} at most brute's at every pixel",
                  work["checks"]["parc_within_brute"])
    project = next(r for r in res["roots"]["rows"] if r["name"] == "project")
    check("root finders: the project's finder has no failure on the hard-ray suite", project["failures"] == 0)
    for r in res["threads"]["rows"]:
        check(f"threads {r['threads']}: frames per second positive", r["brute_fps"] > 0 and r["parc_fps"] > 0)
    return checks


def _checks_md(checks):
    bad = [c for c in checks if not c["ok"]]
    md = ["## Consistency", "",
          f"{len(checks) - len(bad)} of {len(checks)} checks pass (counts positive, ideal ≤ touched ≤ brute, "
          "contributing ≤ ideal, zero error wherever exactness is claimed)." + ("" if bad else " None fails."), ""]
    md += [f"- FAILED: {c['check']}" for c in bad]
    return md + [""]


def _kernels_used():
    """The kernels of every kind of render the suite makes (isosurfaces, each translucent mode
    unshaded, bit planes, several volumes, shadows on isosurfaces), each asked for any sample
    type: a render's run leaves some compiled and others not, and the suite's first scene of
    another kind compiled for half a minute in silence. Other sample types compile in seconds,
    unsaid. Only those: a kernel no scene runs is never cached by the suite, and the notice
    asking for it said "compiling" on every run."""
    import parc
    from data_tools.synthetic import blobs

    from ..renderer import kernel_samples
    vol = blobs(4, seed=0)
    cam = parc.Camera.framing(*vol.bounds)
    iso = parc.Isosurface(vol, 100.5)
    # As the suite's scenes: Table 3's two isosurfaces alone are lit, with shadows.
    lamp = [parc.PointLight((9.0, 9.0, 9.0))]
    looks = [([iso], []), ([iso, parc.Translucent(vol, "greyscale")], []),
             ([iso, parc.Isosurface(vol, 50.5)], lamp)] + [
        ([parc.Translucent(vol, "greyscale", mode=mode)], []) for mode in ("composite", "mip", "average")]
    kernels = set()
    for volumes, lights in looks:
        scene = parc.Scene(camera=cam, size=(4, 4), volumes=volumes, lights=lights, shadows=bool(lights))
        # Its scenes of several volumes are drawn with depth buffers alone.
        for buffers in ("depth", "bits", "depth,bits") if len(volumes) == 1 else ("depth",):
            kernels |= {k for k, _ in kernel_samples(scene, ("brute", "parc"), buffers, repeated=True)}
    # Parker et al.'s section times the walk, the root finders and the shading apart.
    from raycast.shade import shade_headlight

    from ..rootstudy import solve_all, walk_rays
    kernels |= {walk_rays, solve_all, shade_headlight}
    return [(k, ()) for k in kernels]


def main(args):
    """`parc bench` (see `parc.cli`): run a suite, print progress on stderr, say where the report is."""
    suite = Suite.tiny() if args.tiny else Suite.quick() if args.quick else Suite.full()
    for flag, value in (("--out", args.out), ("--data", args.data)):
        if value == "":     # Path("") is the working folder: never what was meant
            raise InputError(f"{flag}: the folder is empty; give a folder's path")
    if args.data is not None:
        if not Path(args.data).is_dir():
            raise InputError(f"--data {args.data}: " + ("not a folder" if Path(args.data).exists() else "no such folder"))
        if args.tiny:
            # The tiny suite's volumes are synthetic by design: real ones would make it neither tiny nor quick.
            raise InputError("--data does not combine with --tiny (the tiny suite uses tiny synthetic volumes)")
        suite = replace(suite, data_dir=Path(args.data))
    elif not args.tiny and os.environ.get("PARC_DATA_DIR") and not Path(os.environ["PARC_DATA_DIR"]).is_dir():
        # Named, as --data is, so a slip in it is refused as --data's is, not run on stand-ins.
        env = os.environ["PARC_DATA_DIR"]
        raise InputError(f"PARC_DATA_DIR={env}: " + ("not a folder" if Path(env).exists() else "no such folder"))
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder")
    _check_out(out)             # before the compile notice, too
    t0 = time.perf_counter()

    def say(msg):
        note(f"{msg}  ({time.perf_counter() - t0:.0f} s)", "parc bench")

    compile_notice(say, _kernels_used())
    with late_compile_notice(say):
        res = run_bench(out, suite, progress=say, command="parc " + " ".join(args.argv))
    failed = [c for c in res["checks"] if not c["ok"]]
    print_out(f"{out / 'report.md'}: {len(res['checks']) - len(failed)} of {len(res['checks'])} checks pass "
              f"({res['seconds'] / 60:.1f} min)", done=f"wrote {out / 'report.md'}")
    return 1 if failed else 0
