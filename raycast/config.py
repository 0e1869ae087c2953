"""Tunables and JIT flags for every kernel in `raycast`, in one place, and where the compiled
kernels are cached (a folder per version of the sources, shared by checkouts, and a cache that
treats a damaged entry as a miss); also quicker copies in Numba's compiler
(`_quicker_copy_propagation`, `_scope_copied_once`)."""
import atexit
import functools
import hashlib
import os
import re
import shutil
import tempfile
import threading
from pathlib import Path


def _source_digest():
    """Digest of every kernel source file: this package's modules, and those of `parc` that
    define kernels (``@kernel``)."""
    here = Path(__file__).parent
    h = hashlib.sha1()
    for f in sorted(here.glob("*.py")) + sorted((here.parent / "parc").rglob("*.py")):
        text = f.read_bytes()
        if f.parent == here or b"@kernel" in text:
            h.update(f.relative_to(here.parent).as_posix().encode())
            h.update(text)
    return h.hexdigest()[:12]


# Numba's OpenMP workers otherwise spin for a while after each parallel
# loop, on the two cores llvmpipe's rasterizer threads need next: a CT head
# frame's raster pass took 6-7 ms right after a cast, 4 ms with them asleep.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numba  # noqa: E402
import numba.core.config  # noqa: E402
import numba.core.event  # noqa: E402

#: Shares the parallel loops deal their tiles into (`raycast.rays.spread`):
#: the threads Numba starts with. A compile-time constant (asking Numba in
#: a kernel would keep it out of the cache), so the cache folder names it.
SPREAD_WAYS = max(1, int(numba.config.NUMBA_NUM_THREADS))


#: What this process undoes as it ends (`at_exit`), for a run ended at once, which skips `atexit`
#: (`data_tools.signals.end_at_once`).
EXIT_CLEANUPS = []


def at_exit(fn, *args, **kwargs):
    """Call ``fn(*args, **kwargs)`` when the process ends, by `atexit` or at once."""
    atexit.register(fn, *args, **kwargs)
    EXIT_CLEANUPS.append(functools.partial(fn, *args, **kwargs))


def cache_base(environ):
    """The folder PARC caches in, the kernels' folders among what it holds: ``PARC_CACHE_DIR``,
    or ``parc`` in ``XDG_CACHE_HOME`` (``~/.cache``)."""
    given = environ.get("PARC_CACHE_DIR")
    if given:
        return given
    return os.path.join(environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "parc")


def choose_cache_folder(environ, name):
    """``(folder, refused)``: where the kernels named ``name`` are cached, and the folder that
    could not be written instead (None when it could).

    The folder is ``name`` under ``NUMBA_CACHE_DIR`` (or `cache_base`); a
    ``NUMBA_CACHE_DIR`` already ending in ``name`` is this one's, passed on
    to a child process. Where it cannot be written the cache goes to a new
    temporary folder: Numba would otherwise fall back to ``__pycache__``
    beside the sources, whose entries it checks only against the file that
    defines a kernel, and run stale code after an edit to a function that
    kernel inlines.
    """
    given = environ.get("NUMBA_CACHE_DIR")
    if given and Path(given).name == name:
        folder = given
    else:
        folder = os.path.join(given or cache_base(environ), name)
    try:
        os.makedirs(folder, exist_ok=True)
        writable = os.access(folder, os.W_OK)
    except OSError:
        writable = False
    if writable:
        return folder, None
    temporary = tempfile.mkdtemp(prefix="parc-kernels-")
    at_exit(shutil.rmtree, temporary, ignore_errors=True)
    return temporary, folder


#: Versions of the kernels whose folders `forget_old_versions` keeps, the one in use among them:
#: each takes 40-50 MB, and every edit to a kernel source (`_source_digest`) makes a new one.
KEPT_VERSIONS = 6

_VERSION_FOLDER = re.compile(r"numba-[0-9a-f]{12}-[0-9]+t")


def forget_old_versions(folder, keep=KEPT_VERSIONS):
    """Mark the kernel folder ``folder`` used now, and remove its siblings (other versions of the
    kernels, or thread counts) but the ``keep - 1`` used last.

    A process still using a folder removed under it compiles what it lacks, and caches no more.
    """
    folder = Path(folder)
    try:
        os.utime(folder)
        siblings = [(f.stat().st_mtime, f) for f in folder.parent.iterdir()
                    if f != folder and _VERSION_FOLDER.fullmatch(f.name) and f.is_dir()]
    except OSError:
        return
    for _, old in sorted(siblings, reverse=True)[max(keep - 1, 0):]:
        shutil.rmtree(old, ignore_errors=True)


# Compiled kernels are cached outside the package, in a folder named for
# the kernels' sources and the thread count (`SPREAD_WAYS`): Numba checks
# only the file that defines a kernel, so an edit to a function it inlines
# from another module would otherwise leave a stale compiled kernel in use.
# Checkouts of the same sources share the folder (`_cache_shared_by_checkouts`);
# naming it for `parc`'s kernel modules too keeps two versions of a kernel
# out of one folder, where a process could read one version's index and
# the other's data, written at that moment by a process of another checkout.
# Numba reads NUMBA_CACHE_DIR when it is first imported, and `parc` modules
# may import it before this one, so it gets the folder directly as well.
# Kernels pick their cache folder when they are decorated, after this line.
_FOLDER, _REFUSED = choose_cache_folder(os.environ, f"numba-{_source_digest()}-{SPREAD_WAYS}t")
os.environ["NUMBA_CACHE_DIR"] = _FOLDER
numba.core.config.CACHE_DIR = _FOLDER
if _REFUSED is None:
    forget_old_versions(_FOLDER)


def _cache_shared_by_checkouts():
    """File each kernel of `raycast` and `parc` in the cache folder under its package's name.

    Numba files a kernel under a hash of its folder's absolute path, so every
    checkout, virtual environment or install of the same sources compiled
    every kernel again (ten CPU-minutes for the test suite's). The folder is
    named for the contents of every kernel source, and Numba still checks
    each entry against the file that defines its kernel. A Numba without
    the locators this extends files kernels its own way.
    """
    from numba.core import caching

    # Older Numbas name them with a leading underscore.
    base = getattr(caching, "UserProvidedCacheLocator", getattr(caching, "_UserProvidedCacheLocator", None))
    impl = getattr(caching, "CacheImpl", getattr(caching, "_CacheImpl", None))
    locators = getattr(impl, "_locator_classes", None)
    if not (isinstance(base, type) and isinstance(locators, list)):
        return

    class PackageCacheLocator(base):
        def __init__(self, py_func, py_file):
            super().__init__(py_func, py_file)
            self._cache_path = os.path.join(numba.core.config.CACHE_DIR, *py_func.__module__.split(".")[:-1])

        @classmethod
        def from_function(cls, py_func, py_file):
            # A function made by exec() may have no module at all.
            if (getattr(py_func, "__module__", None) or "").partition(".")[0] not in ("raycast", "parc"):
                return None
            return super().from_function(py_func, py_file)

    locators.insert(0, PackageCacheLocator)


_cache_shared_by_checkouts()


def _cache_is_only_a_shortcut():
    """Make Numba's cache files treat a damaged entry as a miss and a failed write as none.

    Numba raised the unpickler's error for a truncated or garbled index or
    data file (a full disk or a killed process can leave one), on every run
    until the folder was removed by hand, and the write's error for a full
    disk (``No space left on device``, which named no folder): a kernel that
    runs would not. Damaged entries are compiled again, and their next save
    writes them over.
    """
    from numba.core.caching import IndexDataCacheFile
    load_index, load_data, save = IndexDataCacheFile._load_index, IndexDataCacheFile._load_data, IndexDataCacheFile.save

    def _load_index(self):
        try:
            return load_index(self)
        except Exception:       # noqa: BLE001 - whatever a damaged pickle raises
            return {}

    def _load_data(self, name):
        try:
            return load_data(self, name)
        except OSError:
            raise               # `load` already takes these as a miss
        except Exception as exc:    # noqa: BLE001
            raise OSError(f"damaged cache entry {name}") from exc

    def _save(self, key, data):
        try:
            save(self, key, data)
        except OSError:
            pass

    IndexDataCacheFile._load_index = _load_index
    IndexDataCacheFile._load_data = _load_data
    IndexDataCacheFile.save = _save


_cache_is_only_a_shortcut()


def _copy_module(deepcopy):
    """The `copy` module with ``deepcopy`` in place of its own, for one of Numba's modules to use."""
    import copy
    import types

    shim = types.ModuleType("copy")
    shim.__dict__.update(copy.__dict__)
    shim.deepcopy = deepcopy
    return shim


def _quicker_copy_propagation():
    """Copy Numba's sets of copies and aliases without ``copy.deepcopy``, to the same result.

    Numba's copy propagation and alias analysis (`numba.core.ir_utils`) copy a
    ``{label or name: set of names or (name, name)}`` with ``copy.deepcopy`` at each step of
    their fixed points: in a parallel loop's inlined body, a quarter of its compile (the merged
    walk's `cast_plain`: 7 s of 28 under ``cProfile``). ``deepcopy`` returns strings, and tuples
    of them, as they are, and rebuilds each set from a list of its members; so does this, and
    the copies iterate in the same order (``set(v)`` would not, after removals). The merged
    walk's variants compile in 9.7 s against 11.2 (`cast_plain`, one uint8 volume) and 11.4
    against 13.2 (`cast_record`), their machine code the same instruction for instruction.
    Anything else goes to ``copy.deepcopy``, and a Numba whose ``ir_utils`` does not use the
    ``copy`` module is left as it is.
    """
    import copy

    from numba.core import ir_utils

    def names(x):
        return type(x) is str or (type(x) is tuple and all(type(s) is str for s in x))

    def deepcopy(x, memo=None):
        if (type(x) is dict and memo is None
                and all(type(k) in (int, str) and type(v) is set and all(names(e) for e in v)
                        for k, v in x.items())):
            return {k: set(list(v)) for k, v in x.items()}
        return copy.deepcopy(x, memo)

    if getattr(ir_utils, "copy", None) is copy:
        ir_utils.copy = _copy_module(deepcopy)


_quicker_copy_propagation()


def _scope_copied_once():
    """Let two of Numba's passes copy a function's scope once per call, not once per piece.

    Each variable of Numba's IR holds its function's whole `ir.Scope`, so
    ``copy.deepcopy`` of one statement or block copies every variable of the
    function with it. Two passes copy IR a piece at a time:
    ``parfors.parfor.get_parfor_reductions`` each statement of a parallel
    loop that updates a variable from outside the loop, and
    ``InlineWorker.inline_ir`` (``inline="always"``) each block of the
    function it inlines. In `raycast.iso.cast_iso_image` that was a fifth of
    the compile. Within one call of either, the copies now share one copy of
    each scope, made when first needed; neither pass changes a scope between
    its copies, and the shared copy is still a copy, so what the inliner
    later does to it (renaming the callee's variables) leaves the original
    alone, as before. `cast_iso_image` compiles in 12.4 s against 15.5, and
    the test suite's 159 kernels in 846 s against 911 (two workers' sum).
    The 255 kernels that `brute` and PARC renders (with bit planes too) of
    an isosurface, a shaded translucent volume, and both lit and shadowed
    compile for uint8, int16 and float64 samples have the same machine code,
    instruction for instruction (the hashed names Numba gives string
    constants aside). A Numba whose passes are not where this looks is left
    as it is.
    """
    import copy

    from numba.core import inline_closurecall, ir
    from numba.parfors import parfor

    def copying_scopes_once(piece, shared):
        # shared.scopes: {id(scope): (scope, its copy)} while the pass runs, else None.
        def deepcopy(x, memo=None):
            scopes = getattr(shared, "scopes", None)
            if memo is None and scopes is not None and isinstance(x, piece):
                scope = x.target.scope if piece is ir.Assign else x.scope
                if isinstance(scope, ir.Scope):
                    held = scopes.get(id(scope))
                    if held is None:
                        held = scopes[id(scope)] = (scope, copy.deepcopy(scope))
                    return copy.deepcopy(x, {id(scope): held[1]})
            return copy.deepcopy(x, memo)
        return _copy_module(deepcopy)

    def sharing(run, shared, per_call):
        # The reductions pass calls itself for nested loops, under the outer call's copies;
        # each inlining gets its own, as the inliner renames variables in them afterwards.
        @functools.wraps(run)
        def wrapper(*args, **kwargs):
            outer = getattr(shared, "scopes", None)
            if outer is not None and not per_call:
                return run(*args, **kwargs)
            shared.scopes = {}
            try:
                return run(*args, **kwargs)
            finally:
                shared.scopes = outer
        return wrapper

    worker = getattr(inline_closurecall, "InlineWorker", None)
    if getattr(parfor, "copy", None) is copy and callable(getattr(parfor, "get_parfor_reductions", None)):
        reducing = threading.local()
        parfor.copy = copying_scopes_once(ir.Assign, reducing)
        parfor.get_parfor_reductions = sharing(parfor.get_parfor_reductions, reducing, per_call=False)
    if getattr(inline_closurecall, "copy", None) is copy and callable(getattr(worker, "inline_ir", None)):
        inlining = threading.local()
        inline_closurecall.copy = copying_scopes_once(ir.Block, inlining)
        worker.inline_ir = sharing(worker.inline_ir, inlining, per_call=True)


_scope_copied_once()


class _CompilerLockWatch(numba.core.event.Listener):
    """How deep Numba's compiler lock is held (compiling, or loading a kernel from the cache),
    and what is to be done once it is let go.

    A KeyboardInterrupt raised inside a compile, or in the finalizers of llvmlite's objects
    that run during one, was swallowed (the run went on and wrote its file), crashed the
    process, or left the kernel broken ("no compiled object yet"). A run's signal handler
    (`parc.cli`) therefore hands what it would raise to `after_compile` while `compiling`, and
    it is raised here, after the lock's last release, where nothing is half built.
    """

    def __init__(self):
        self.depth = 0
        self.pending = None

    def on_start(self, event):
        if threading.current_thread() is threading.main_thread():    # where signal handlers run
            self.depth += 1

    def on_end(self, event):
        if threading.current_thread() is not threading.main_thread():
            return
        self.depth -= 1
        if self.depth == 0 and self.pending is not None:
            act, self.pending = self.pending, None
            act()


_LOCK_WATCH = _CompilerLockWatch()
numba.core.event.register("numba:compiler_lock", _LOCK_WATCH)


def compiling():
    """Whether the main thread is compiling a kernel with Numba (or loading one from its cache)."""
    return _LOCK_WATCH.depth > 0


def after_compile(act):
    """Call ``act`` once the compile under way ends (it may raise); False if one is already
    waiting, which is then kept."""
    if _LOCK_WATCH.pending is not None:
        return False
    _LOCK_WATCH.pending = act
    return True


def cache_folder():
    """The folder this version of the kernels is cached in."""
    return Path(numba.core.config.CACHE_DIR)


def cache_refused():
    """The cache folder asked for that could not be written (the kernels then compile in every
    process, cached in a temporary folder), or None."""
    return _REFUSED


#: Flags shared by all kernels. fastmath stays off: PARC and the
#: unaccelerated caster must round identically, and the root finder relies
#: on IEEE comparisons with inf.
JIT = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
#: The same for an ``@overload``'s implementation, which is compiled into
#: the kernels that call it and cached with them.
OVERLOAD_JIT = {key: value for key, value in JIT.items() if key != "cache"}


def named_for(**flags):
    """Rename a kernel's Python function for the flags its factory closes over, before `kernel`.

    ``accumulate`` made with ``shaded=True, planes=False`` becomes
    ``accumulate_shaded``; with neither, ``accumulate_plain``. Numba names a
    compiled kernel by its qualified name and a counter that starts again in
    every process, and links kernels loaded from the cache by that name: two
    variants of one factory, compiled in different processes, could get the
    same name, and a process that loaded both ran the first one's code for
    both (a shaded image came out unshaded). Distinct names also give each
    variant its own cache index.
    """
    suffix = "_".join(name for name, on in flags.items() if on) or "plain"

    def rename(fn):
        fn.__name__ = f"{fn.__name__}_{suffix}"
        fn.__qualname__ = f"{fn.__qualname__}_{suffix}"
        return fn
    return rename


#: Image tiles, as in Parker et al. §2.2: 32 pixels wide (a cache line of
#: float32 per row) and 4 high.
TILE_W = 32
TILE_H = 4

#: Parallel loops over single rays or pixels hand out runs of this many
#: (`raycast.rays.spread`): spreading item by item cost more than the
#: shading it balanced (an integer division per pixel).
SPREAD_CHUNK = 64

#: Parallel passes over volume-sized arrays of value ranges (`parc.classify`'s isovalue tests,
#: `parc.transfer`'s range query) give each thread runs of this many, one after another.
RANGE_CHUNK = 1 << 16

#: Root finder: bisection/Newton stops when the bracket is this small
#: relative to the cell's t-interval (well below the 1e-9-of-a-cell target).
ROOT_REL_TOL = 1e-15
ROOT_MAX_ITER = 100


def kernel(fn=None, **extra):
    """Decorate a kernel with the project's JIT flags.

    ``@kernel(inline="always")`` marks a small helper that takes arrays and
    runs inside a per-sample or per-ray loop: LLVM left such helpers as
    calls, and each call passes every array as a struct of 7-11 words
    (the per-sample bit-plane test, the transfer function's colour, the
    light-buffer lookup of every shadow ray). Inlining them in Numba's IR
    made PARC's translucent cast 1.3x and its shadow rays 1.8x faster (CT
    head and Fig. 13 scenes). The same goes for what an isosurface ray
    calls once, or once per cubic: `raycast.iso.cast_iso_ray` and
    `raycast.cubic.first_root` inlined took 4% off PARC's CT head bone
    frame (`brute`'s as fast as before) for about 10 s more compiling in a
    cold test run. Not inlined, for compile time: `raycast.iso._walk_iso`
    into the kernels that inline `cast_iso_ray` (their compile time tripled for
    another few percent) and the traversal's `start_index` and
    `entry_anchor` (with them inlined too, the iso, hard-ray, PARC-equals-
    brute and shadow tests took 200 s from a cold cache instead of 150).
    """
    flags = dict(JIT, **extra)
    if fn is None:
        return lambda f: numba.njit(**flags)(f)
    return numba.njit(**flags)(fn)
