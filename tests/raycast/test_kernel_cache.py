"""Compiled kernels come back from Numba's on-disk cache in a new process, each as itself.

Numba keys the cache entry of a kernel built in a closure by the pickle of
its closure, and a kernel pickles with an id that is new in every process:
a driver closing over another kernel was compiled again in every process
(2.3 s of each translucent `parc render`), and its cache folder grew by an
entry each time.

Numba also names a compiled kernel by its qualified name and a counter
that starts again in every process: variants of one factory compiled in
different processes could share a name, and a process that loaded both
from the cache ran one variant's code for both (`raycast.config.named_for`).
"""
import importlib
import json
import os
import pkgutil
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from numba.core.dispatcher import Dispatcher

import parc
import raycast


def kernels():
    """``(name, dispatcher)`` for every kernel in `raycast` and `parc`, those kept in dicts and tuples too."""
    found = {}
    for package in (raycast, parc):
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            module = importlib.import_module(info.name)
            for name, value in vars(module).items():
                values = value.values() if isinstance(value, dict) else (
                    value if isinstance(value, (tuple, list)) else (value,))
                for v in values:
                    if isinstance(v, Dispatcher):
                        found.setdefault(id(v), (f"{info.name}.{name}", v))
    return list(found.values())


def test_no_kernel_closes_over_another():
    ks = kernels()
    assert len(ks) > 50      # the walk found the kernels
    closing = [name for name, k in ks
               if any(isinstance(c.cell_contents, Dispatcher) for c in k.py_func.__closure__ or ())]
    assert closing == []


def test_no_two_kernels_share_a_name():
    names = {}
    for name, k in kernels():
        names.setdefault((k.py_func.__module__, k.py_func.__qualname__), []).append(name)
    assert {key: found for key, found in names.items() if len(found) > 1} == {}


# A translucent render per argument, "float32:plain" or "uint8:shaded", each
# image saved to OUT/<argument>.npy.
_VARIANTS = """
import sys
import numpy as np
from parc import Camera, Scene, TransferFunction, Translucent, Volume, render
z, y, x = np.mgrid[0:24, 0:24, 0:24]
ball = (255 - 20 * np.sqrt((x - 11.5) ** 2 + (y - 11.5) ** 2 + (z - 11.5) ** 2)).clip(0, 255)
tf = TransferFunction([[0, 0.0], [120, 0.5], [250, 0.0]])
for arg in sys.argv[2:]:
    dtype, shade = arg.split(":")
    vol = Volume(ball.astype(dtype))
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(16, 16),
                  volumes=[Translucent(vol, tf, shade=shade == "shaded")])
    np.save(f"{sys.argv[1]}/{arg}.npy", render(scene, "brute").image)
"""


def test_variants_compiled_in_different_processes_load_as_themselves(tmp_path):
    # One order of processes in which the unshaded and shaded drivers, each
    # compiled by a process of its own, had come to the same name: the last
    # process, loading both, drew both images with the first one's code.
    env = dict(os.environ, PARC_CACHE_DIR=str(tmp_path / "cache"))
    env.pop("NUMBA_CACHE_DIR", None)
    alone = {}
    for n, runs in enumerate((["float32:plain"], ["uint8:plain"], ["uint8:shaded"], ["uint8:shaded", "uint8:plain"])):
        out = tmp_path / f"run{n}"
        out.mkdir()
        run = subprocess.run([sys.executable, "-c", _VARIANTS, str(out), *runs], capture_output=True, text=True,
                             timeout=600, env=env)
        assert run.returncode == 0, run.stderr[-2000:]
        for arg in runs:
            image = np.load(out / f"{arg}.npy")
            assert np.array_equal(image, alone.setdefault(arg, image)), arg
    # Shading changes the picture, so a variant standing in for the other shows.
    assert not np.array_equal(alone["uint8:plain"], alone["uint8:shaded"])


# Frames that compile the casters' kernels: isosurfaces with shadows, and
# the four translucent drivers (shaded or not, with bit planes or not).
_SCRIPT = """
import json, sys
import numpy as np
from data_tools.synthetic import blobs
from parc import Camera, Isosurface, PointLight, Scene, TransferFunction, Translucent, render
sys.path.insert(0, {tests!r})
from test_kernel_cache import kernels

vol = blobs((14, 12, 10), seed=3)
lo, hi = vol.bounds
cam = Camera.framing(lo, hi)
tf = TransferFunction(opacity=[[0.2, 0.0], [0.6, 0.5]], color=[[0.0, 1.0, 0.5, 0.2], [1.0, 0.2, 0.5, 1.0]])
iso = Scene(camera=cam, size=(12, 10), volumes=[Isosurface(vol, value=0.5)],
            lights=[PointLight(position=hi + 5.0)], shadows=True)
for method in ("brute", "parc"):
    render(iso, method=method)
for shade in (False, True):
    scene = Scene(camera=cam, size=(12, 10), volumes=[Translucent(vol, tf, shade=shade)])
    render(scene, method="brute")
    for buffers in (("depth",), ("depth", "bits")):
        render(scene, method="parc", buffers=buffers)
print(json.dumps(sorted(name for name, k in kernels() if sum(k.stats.cache_misses.values()))))
"""


def test_a_new_process_loads_the_casters_from_the_cache():
    script = _SCRIPT.format(tests=str(Path(__file__).parent))

    def misses():
        run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
        assert run.returncode == 0, run.stderr[-2000:]
        return json.loads(run.stdout.strip().splitlines()[-1])

    misses()                 # compiles what the cache lacks
    assert misses() == []    # ... so that a second process compiles nothing


def test_the_cache_folder_is_named_for_the_sources_wherever_it_is(tmp_path):
    from raycast.kernel_cache import choose_cache_folder
    name = "numba-0123abcd-2t"
    assert choose_cache_folder({"PARC_CACHE_DIR": str(tmp_path / "p")}, name) == (str(tmp_path / "p" / name), None)
    # A folder the user gives Numba gets the sources' name under it too, or an edit would go unseen...
    assert choose_cache_folder({"NUMBA_CACHE_DIR": str(tmp_path / "n")}, name) == (str(tmp_path / "n" / name), None)
    # ... unless it is this one's already, handed to a child process.
    assert choose_cache_folder({"NUMBA_CACHE_DIR": str(tmp_path / "n" / name)}, name)[0] == str(tmp_path / "n" / name)


def test_a_cache_folder_that_cannot_be_written_is_not_replaced_by_the_sources_own(tmp_path):
    # Numba's fallback, __pycache__ beside the sources, could hold stale kernels: a fresh folder instead.
    from raycast.kernel_cache import choose_cache_folder
    (tmp_path / "a file").write_text("")
    refused = str(tmp_path / "a file" / "cache")
    folder, said = choose_cache_folder({"PARC_CACHE_DIR": refused}, "numba-0123abcd-2t")
    assert said == str(Path(refused) / "numba-0123abcd-2t")
    assert Path(folder).is_dir() and not list(Path(folder).iterdir()) and "__pycache__" not in folder


_ONE_KERNEL = """
import sys
sys.path.insert(0, {folder!r})
from raycast.config import kernel
from tiny_kernel import plus_one
print(plus_one(1.0), sum(plus_one.stats.cache_hits.values()))
"""


def _tiny_kernel_runs(tmp_path):
    """A function that runs, each time in a new process, a one-line kernel cached under
    ``tmp_path / "cache"``, and returns what it prints: its result and its cache hits."""
    (tmp_path / "tiny_kernel.py").write_text("from raycast.config import kernel\n\n\n"
                                             "@kernel\ndef plus_one(x):\n    return x + 1.0\n")
    env = dict(os.environ, PARC_CACHE_DIR=str(tmp_path / "cache"))
    env.pop("NUMBA_CACHE_DIR", None)

    def run():
        p = subprocess.run([sys.executable, "-c", _ONE_KERNEL.format(folder=str(tmp_path))], capture_output=True,
                           text=True, timeout=300, env=env)
        assert p.returncode == 0, p.stderr[-2000:]
        return p.stdout.split()
    return run


def test_a_damaged_cache_entry_is_compiled_again(tmp_path):
    # A killed process or a full disk can leave an index or data file cut short; Numba
    # raised the unpickler's EOFError on every run until the folder was removed.
    run = _tiny_kernel_runs(tmp_path)
    assert run() == ["2.0", "0"]                           # compiled, and saved
    assert run() == ["2.0", "1"]                           # loaded
    entries = [f for f in (tmp_path / "cache").rglob("*") if f.suffix in (".nbi", ".nbc")]
    assert {f.suffix for f in entries} == {".nbi", ".nbc"}
    for cut in (0, 7):
        for f in entries:
            f.write_bytes(f.read_bytes()[:cut])
        assert run() == ["2.0", "0"]                       # compiled again, and written over
        assert run() == ["2.0", "1"]


def test_two_saves_at_once_keep_each_kernel_under_its_own_key(tmp_path, monkeypatch):
    # Numba's save reads the index, takes the first free data file and writes both. Two
    # processes compiling for two sample types at once both took file 1: the index named the
    # int32 code for float32 samples, and every later float32 render drew nothing. Each save here
    # waits (up to a second) for the other to have read the index too, as they can.
    import threading

    import raycast.kernel_cache  # noqa: F401 - locks each save
    from numba.core.caching import IndexDataCacheFile
    both_read = threading.Barrier(2, timeout=1.0)
    load_index = IndexDataCacheFile._load_index

    def load_then_wait(self):
        overloads = load_index(self)
        if threading.current_thread().name.startswith("save"):
            try:
                both_read.wait()
            except threading.BrokenBarrierError:     # the other waits on the lock: saves in turn
                pass
        return overloads
    monkeypatch.setattr(IndexDataCacheFile, "_load_index", load_then_wait)
    saves = [threading.Thread(target=IndexDataCacheFile(str(tmp_path), "kernel", "stamp").save, name=f"save {t}",
                              args=((t,), f"code for {t}")) for t in ("int32", "float32")]
    for t in saves:
        t.start()
    for t in saves:
        t.join()
    cache = IndexDataCacheFile(str(tmp_path), "kernel", "stamp")
    assert cache.load(("int32",)) == "code for int32" and cache.load(("float32",)) == "code for float32"


def test_a_cache_write_that_fails_leaves_the_kernel_uncached(tmp_path, monkeypatch):
    # A full disk: the write's OSError ('No space left on device') ended every render.
    import errno

    import raycast.kernel_cache  # noqa: F401 - makes the cache forgiving
    from numba.core.caching import IndexDataCacheFile

    def full(self, path):
        raise OSError(errno.ENOSPC, "No space left on device", path)
    cache = IndexDataCacheFile(str(tmp_path), "kernel", "stamp")
    monkeypatch.setattr(IndexDataCacheFile, "_open_for_write", full)
    cache.save(("sig",), b"compiled")
    assert cache.load(("sig",)) is None


def test_only_the_main_thread_compiling_counts_as_compiling():
    # A run's signal handler holds a Ctrl-C while `compiling` and raises it where the compile
    # ends, in the thread that compiled: a compile in another thread must neither hold the
    # signal nor receive it.
    import threading

    import numba
    import numba.core.event as ev
    from raycast.compiler import compiling
    seen = []

    class Look(ev.Listener):
        def on_start(self, event):
            seen.append((threading.current_thread() is threading.main_thread(), compiling()))

        def on_end(self, event):
            pass

    def fresh():
        @numba.njit
        def twice(x):
            return 2 * x
        return twice(3)
    look = Look()
    ev.register("numba:compile", look)
    try:
        worker = threading.Thread(target=fresh)
        worker.start()
        worker.join()
        fresh()
    finally:
        ev.unregister("numba:compile", look)
    assert seen == [(False, False), (True, True)]
    assert not compiling()


def test_numba_s_own_folder_wins_over_parc_s(tmp_path):
    # As the first-compile notice tells the user: NUMBA_CACHE_DIR "wins over it when set".
    from raycast.kernel_cache import choose_cache_folder
    name = "numba-0123abcd-2t"
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "n"), "PARC_CACHE_DIR": str(tmp_path / "p")}
    assert choose_cache_folder(env, name) == (str(tmp_path / "n" / name), None)


def test_the_default_cache_is_in_the_user_s_cache_folder_not_the_package(tmp_path):
    from raycast.kernel_cache import choose_cache_folder
    home = {"HOME": str(tmp_path / "home")}
    name = "numba-0123abcd-2t"
    assert choose_cache_folder(home, name) == (str(tmp_path / "home" / ".cache" / "parc" / name), None)
    assert (tmp_path / "home" / ".cache" / "parc" / name).is_dir()
    xdg = {"XDG_CACHE_HOME": str(tmp_path / "xdg")}
    assert choose_cache_folder(xdg, name) == (str(tmp_path / "xdg" / "parc" / name), None)
    # A relative XDG_CACHE_HOME is ignored, as the XDG specification says: it would be another
    # folder in every folder a command runs in.
    assert choose_cache_folder({**home, "XDG_CACHE_HOME": "xdg"}, name)[0] == str(
        tmp_path / "home" / ".cache" / "parc" / name)


@pytest.mark.parametrize("home", [None, "", "relative"])
def test_without_a_home_folder_the_kernels_compile_in_a_temporary_folder_said_as_such(tmp_path, monkeypatch, home):
    # An account with no home (a container's --user 12345): "~" was taken as a folder's name, and
    # the cache made anew in each working folder; HOME="" put it at /.cache.
    import pwd

    from raycast.kernel_cache import NO_HOME, cache_base, choose_cache_folder

    def no_entry(uid):
        raise KeyError(uid)
    monkeypatch.setattr(pwd, "getpwuid", no_entry)
    monkeypatch.chdir(tmp_path)
    environ = {} if home is None else {"HOME": home}
    assert cache_base(environ) is None
    folder, refused = choose_cache_folder(environ, "numba-0123abcd-2t")
    assert refused == NO_HOME and Path(folder).is_absolute() and Path(folder).is_dir()
    assert list(tmp_path.iterdir()) == []


# Which checkout a process imported, and whether it compiled or loaded a kernel of each package.
_CHECKOUT = """
import json
import numpy as np
import parc.ranges, raycast.rays
parc.ranges.cell_minmax(np.zeros((3, 3, 3), np.float32))
raycast.rays.chunk_count(10, 3)
compiled = [sum(k.stats.cache_misses.values()) for k in (parc.ranges._cell_minmax, raycast.rays.chunk_count)]
print(json.dumps([raycast.__file__, compiled]))
"""


def test_checkouts_of_the_same_sources_share_their_compiled_kernels(tmp_path):
    root = Path(raycast.__file__).parents[1]
    env = dict(os.environ, PARC_CACHE_DIR=str(tmp_path / "cache"))
    env.pop("NUMBA_CACHE_DIR", None)

    def run_in(name, edit=None):
        checkout = tmp_path / name
        for package in ("raycast", "parc", "data_tools"):
            shutil.copytree(root / package, checkout / package, ignore=shutil.ignore_patterns("__pycache__"))
        if edit is not None:
            with open(checkout / edit, "a") as f:
                f.write("\n# an edit\n")
        p = subprocess.run([sys.executable, "-c", _CHECKOUT], cwd=checkout, capture_output=True, text=True,
                           timeout=600, env=dict(env, PYTHONPATH=str(checkout)))
        assert p.returncode == 0, p.stderr[-2000:]
        used, compiled = json.loads(p.stdout.splitlines()[-1])
        assert Path(used) == checkout / "raycast" / "__init__.py"
        return compiled

    assert run_in("one") == [1, 1]
    assert run_in("two") == [0, 0]
    # An edit to a kernel's source moves the whole cache to a new folder, where the first
    # checkout's kernels are not written over.
    assert run_in("three", edit="parc/ranges.py") == [1, 1]
    assert len(list((tmp_path / "cache").glob("numba-*"))) == 2
    assert run_in("four") == [0, 0]


def test_only_the_kernels_of_parc_and_raycast_are_filed_by_package():
    import numba.core.config
    from numba.core import caching

    from parc.ranges import _cell_minmax
    locator = getattr(caching, "CacheImpl", getattr(caching, "_CacheImpl", None))._locator_classes[0]
    filed = locator.from_function(_cell_minmax.py_func, _cell_minmax.py_func.__code__.co_filename)
    assert Path(filed.get_cache_path()) == Path(numba.core.config.CACHE_DIR) / "parc"

    def plus_one(x):
        return x + 1
    assert locator.from_function(plus_one, __file__) is None
    plus_one.__module__ = None              # as exec() may leave it
    assert locator.from_function(plus_one, __file__) is None


def _versions(folder, count):
    """The names of ``count`` kernel folders made in ``folder``, each holding kernels, the first
    used last."""
    names = [f"numba-{n:012x}-2t" for n in range(count)]
    for age, name in enumerate(names):
        (folder / name / "raycast").mkdir(parents=True)
        os.utime(folder / name, (1e9 - age, 1e9 - age))
    return names


def test_the_cache_keeps_the_kernels_of_the_versions_used_last(tmp_path):
    from raycast.kernel_cache import forget_old_versions
    names = _versions(tmp_path, 8)
    (tmp_path / "bench").mkdir()
    (tmp_path / "numba-not-ours").mkdir()
    forget_old_versions(tmp_path / names[-1], keep=3)
    # The one in use, whatever its age, and the two used last; nothing that is not a version's folder.
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["bench", "numba-not-ours", *names[:2], names[-1]])
    assert (tmp_path / names[-1]).stat().st_mtime > 1e9


def test_a_run_that_caches_nothing_removes_no_version(tmp_path):
    # A mistyped command (or one with another thread count) made its empty folder and removed
    # the version used longest ago: a minute of compiling, for nothing.
    from raycast.kernel_cache import forget_old_versions
    names = _versions(tmp_path, 3)
    (tmp_path / "numba-00000000000e-1t").mkdir()
    forget_old_versions(tmp_path / "numba-00000000000e-1t", keep=3)
    assert len(list(tmp_path.iterdir())) == 4
    # Once it holds kernels, the empty folder of another run does not count either.
    (tmp_path / "numba-00000000000e-1t" / "raycast").mkdir()
    (tmp_path / "numba-00000000000f-9t").mkdir()
    forget_old_versions(tmp_path / "numba-00000000000e-1t", keep=3)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [*names[:2], "numba-00000000000e-1t", "numba-00000000000f-9t"])


def test_the_folder_name_changes_with_any_kernel_source(tmp_path, monkeypatch):
    # Numba checks only the file that defines a kernel: an edit to one it inlines must move the cache.
    import raycast.kernel_cache as kernel_cache
    src = tmp_path / "raycast"
    src.mkdir()
    (src / "kernel_cache.py").write_text("# kernel_cache\n")
    (src / "cubic.py").write_text("def root():\n    return 1.0\n")
    monkeypatch.setattr(kernel_cache, "__file__", str(src / "kernel_cache.py"))
    before = kernel_cache._source_digest()
    (src / "cubic.py").write_text("def root():\n    return 2.0\n")
    assert kernel_cache._source_digest() != before
    # `parc`'s modules count where they define kernels.
    (tmp_path / "parc" / "transfer").mkdir(parents=True)
    (tmp_path / "parc" / "cli.py").write_text("def main():\n    pass\n")
    (tmp_path / "parc" / "transfer" / "function.py").write_text("@kernel\ndef lookup():\n    pass\n")
    before = kernel_cache._source_digest()
    (tmp_path / "parc" / "cli.py").write_text("def main():\n    return 1\n")
    assert kernel_cache._source_digest() == before
    (tmp_path / "parc" / "transfer" / "function.py").write_text("@kernel\ndef lookup():\n    return 1\n")
    assert kernel_cache._source_digest() != before


_FOLDER_OF = "from raycast.kernel_cache import cache_folder, cache_refused; print(cache_folder()); print(cache_refused())"


def test_kernels_for_another_thread_count_are_cached_apart(tmp_path):
    # SPREAD_WAYS, the thread count, is compiled into the kernels as a constant.
    def folder(threads):
        env = dict(os.environ, PARC_CACHE_DIR=str(tmp_path), NUMBA_NUM_THREADS=threads)
        env.pop("NUMBA_CACHE_DIR", None)
        p = subprocess.run([sys.executable, "-c", _FOLDER_OF], capture_output=True, text=True, timeout=120, env=env)
        assert p.returncode == 0, p.stderr[-2000:]
        return Path(p.stdout.splitlines()[0])
    one, two = folder("1"), folder("2")
    assert one != two and one.parent == two.parent == tmp_path


def test_the_temporary_cache_of_a_refused_folder_goes_with_the_process(tmp_path):
    # Otherwise each run leaves a folder of compiled kernels in /tmp.
    (tmp_path / "a file").write_text("")
    (tmp_path / "tmp").mkdir()
    env = dict(os.environ, PARC_CACHE_DIR=str(tmp_path / "a file" / "cache"), TMPDIR=str(tmp_path / "tmp"))
    env.pop("NUMBA_CACHE_DIR", None)
    p = subprocess.run([sys.executable, "-c", _FOLDER_OF], capture_output=True, text=True, timeout=120, env=env)
    assert p.returncode == 0, p.stderr[-2000:]
    used, refused = p.stdout.splitlines()
    assert Path(used).parent == tmp_path / "tmp" and refused.startswith(str(tmp_path / "a file" / "cache"))
    assert list((tmp_path / "tmp").iterdir()) == []


def test_a_damaged_data_file_under_a_whole_index_is_compiled_again(tmp_path):
    # The index intact, Numba reads the data file it names: cut short, its unpickler's error would end the run.
    run = _tiny_kernel_runs(tmp_path)
    assert run() == ["2.0", "0"]
    data = [f for f in (tmp_path / "cache").rglob("*.nbc")]
    assert data
    for cut in (0, 7):
        for f in data:
            f.write_bytes(f.read_bytes()[:cut])
        assert run() == ["2.0", "0"]                       # compiled again, and written over
        assert run() == ["2.0", "1"]


def test_numba_copies_a_scope_once_for_the_pieces_a_pass_copies_and_never_uses_the_original(monkeypatch):
    # `raycast.compiler._scope_copied_once`: the statements a parallel loop's reductions keep, and the
    # blocks of an inlined function, each share one copy of their function's scope, which is a copy:
    # the inliner renames variables in it afterwards.
    import numba
    from numba.core import inline_closurecall
    from numba.parfors import parfor

    import raycast.compiler  # noqa: F401 - installs the copies, as every kernel's module does (through raycast.config)
    reductions, inlined = [], []
    reduce_nodes, inline_ir = parfor.get_reduce_nodes, inline_closurecall.InlineWorker.inline_ir

    def spy_reductions(param, nodes, func_ir):
        reductions.append(({id(n.target.scope) for n in nodes}, {id(b.scope) for b in func_ir.blocks.values()}))
        return reduce_nodes(param, nodes, func_ir)

    def spy_inlining(self, caller_ir, block, *args, **kwargs):
        made = inline_ir(self, caller_ir, block, *args, **kwargs)
        inlined.append(({id(b.scope) for b in made[0].blocks.values()}, len(made[0].blocks), id(block.scope)))
        return made

    monkeypatch.setattr(parfor, "get_reduce_nodes", spy_reductions)
    monkeypatch.setattr(inline_closurecall.InlineWorker, "inline_ir", spy_inlining)

    @numba.njit(inline="always")
    def folded(x):
        if x > 0.0:
            y = 2.0 * x
        else:
            y = -x
        return y + 1.0

    @numba.njit(parallel=True)
    def totals(a):
        s = 0.0
        m = 0.0
        for i in numba.prange(a.shape[0]):
            v = folded(a[i])
            s += v
            m = max(m, v)
        return s, m

    a = np.arange(-40.0, 57.0)
    made = np.where(a > 0, 2 * a, -a) + 1
    assert totals(a) == (made.sum(), made.max())
    assert len(reductions) >= 2 and inlined     # two reductions, found by the parfor pass and again by lowering
    for copies, own in reductions:
        assert len(copies) == 1 and not copies & own
    for copies, blocks, callers in inlined:
        assert blocks > 1 and len(copies) == 1 and callers not in copies


def test_numba_copies_its_sets_of_names_as_deepcopy_would(monkeypatch):
    # `raycast.compiler._quicker_copy_propagation`: the same copies, iterating in the same order,
    # so that Numba's fixed points (and the code it compiles) cannot change.
    import copy

    from numba.core import ir_utils

    import raycast.compiler  # noqa: F401 - installs the copies, as every kernel's module does (through raycast.config)
    assert ir_utils.copy is not copy and ir_utils.copy.copy is copy.copy
    removed = {("v%d" % i, "w%d" % i) for i in range(200)}
    for i in range(0, 200, 3):
        removed.discard(("v%d" % i, "w%d" % i))     # set(removed) would iterate in another order
    aliases = {"a": {"b", "c"}, "b": {"a"}, "c": set()}
    for sets in ({3: removed, 7: set(), 9: {("x", "y")}}, aliases):
        meant = copy.deepcopy(sets)
        with monkeypatch.context() as m:
            m.setattr(copy, "deepcopy", None)   # the point: these are copied without it
            made = ir_utils.copy.deepcopy(sets)
        assert made == meant and list(made) == list(meant)
        assert all(list(made[k]) == list(meant[k]) and made[k] is not sets[k] for k in sets)
    # Anything else is deep-copied by copy.deepcopy: lists inside are copies, not the same lists.
    nested = {1: [["a"]], 2: set()}
    made = ir_utils.copy.deepcopy(nested)
    assert made == nested and made[1][0] is not nested[1][0]
