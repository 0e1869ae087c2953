"""Where compiled kernels are cached: a folder per version of the kernels' sources and thread
count, shared by every checkout and install of those sources, the six versions used last kept;
a cache that takes a damaged entry as a miss and a failed write as none; and a temporary folder,
said as such, where the folder asked for cannot be written."""
import contextlib
import hashlib
import os
import re
import shutil
import tempfile
from pathlib import Path

import numba
import numba.core.config

try:
    import fcntl
except ImportError:         # not on Windows
    fcntl = None

from .config import SPREAD_WAYS, at_exit


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


#: What `choose_cache_folder` says cannot be written where there is no home folder to cache in.
NO_HOME = "~/.cache/parc (there is no home folder: HOME is unset, empty or relative, and the account has none)"


def cache_base(environ):
    """The folder PARC caches in, the kernels' folders among what it holds: ``PARC_CACHE_DIR``,
    or ``parc`` in ``XDG_CACHE_HOME`` (``~/.cache``); None where there is no home folder. A
    relative ``XDG_CACHE_HOME`` or home is ignored, as the XDG specification has it: the cache
    would be made anew in each folder a command runs in (a folder named ``~`` for an account
    without a home, ``--user 12345`` in a container)."""
    given = environ.get("PARC_CACHE_DIR")
    if given:
        return given
    xdg = environ.get("XDG_CACHE_HOME")
    if xdg and os.path.isabs(xdg):
        return os.path.join(xdg, "parc")
    home = environ.get("HOME")
    if not home or not os.path.isabs(home):
        try:
            import pwd
            home = pwd.getpwuid(os.getuid()).pw_dir
        except (ImportError, KeyError):
            return None
    return os.path.join(home, ".cache", "parc") if os.path.isabs(home) else None


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
        base = given or cache_base(environ)
        folder = os.path.join(base, name) if base is not None else None
    writable = False
    if folder is not None:
        try:
            os.makedirs(folder, exist_ok=True)
            writable = os.access(folder, os.W_OK)
        except OSError:
            pass
    if writable:
        return folder, None
    temporary = tempfile.mkdtemp(prefix="parc-kernels-")
    at_exit(shutil.rmtree, temporary, ignore_errors=True)
    return temporary, folder if folder is not None else NO_HOME


#: Versions of the kernels whose folders `forget_old_versions` keeps, the one in use among them:
#: each takes 40-50 MB, and every edit to a kernel source (`_source_digest`) makes a new one.
KEPT_VERSIONS = 6

_VERSION_FOLDER = re.compile(r"numba-[0-9a-f]{12}-[0-9]+t")


def forget_old_versions(folder, keep=KEPT_VERSIONS):
    """Mark the kernel folder ``folder`` used now, and remove its siblings (other versions of the
    kernels, or thread counts) but the ``keep - 1`` used last.

    A process still using a folder removed under it compiles what it lacks, and caches no more.
    Nothing is removed for a folder still empty, and an empty sibling does not count: a command
    that compiles nothing (one mistyped, or run with another thread count) must not cost a
    version the minute its kernels take to compile.
    """
    folder = Path(folder)
    try:
        if next(folder.iterdir(), None) is None:
            return
        os.utime(folder)
        siblings = [(f.stat().st_mtime, f) for f in folder.parent.iterdir()
                    if f != folder and _VERSION_FOLDER.fullmatch(f.name) and f.is_dir()
                    and next(f.iterdir(), None) is not None]
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


@contextlib.contextmanager
def _saving_alone(folder):
    """Hold the cache folder's lock file while Numba saves an entry. Its save reads the index,
    takes the first free data file's number and writes both: two processes compiling a kernel
    for two sample types at once took the same number, and the index could name one type's
    code for the other (an empty image, or a crash, on every later run). ``flock`` locks are
    released by the system when a process dies; where there are none, saves go unlocked."""
    if fcntl is None:
        yield
        return
    with open(os.path.join(folder, ".save-lock"), "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


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
            with _saving_alone(self._cache_path):
                save(self, key, data)
        except OSError as exc:
            _UNSAVED.append(exc.strerror or str(exc))

    IndexDataCacheFile._load_index = _load_index
    IndexDataCacheFile._load_data = _load_data
    IndexDataCacheFile.save = _save


#: Why kernels compiled in this process could not be kept (a full disk), in the order it happened.
_UNSAVED = []

_cache_is_only_a_shortcut()


def cache_unsaved():
    """Why a kernel compiled in this process was not kept in the cache folder (``No space left
    on device``), or None when every one was: the next run then compiles it again."""
    return _UNSAVED[0] if _UNSAVED else None


def cache_folder():
    """The folder this version of the kernels is cached in."""
    return Path(numba.core.config.CACHE_DIR)


def cache_refused():
    """The cache folder asked for that could not be written (the kernels then compile in every
    process, cached in a temporary folder), or None."""
    return _REFUSED
