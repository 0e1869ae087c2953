"""What the command line writes: output paths checked before any work, files written
all or nothing, strict JSON, and progress on stderr."""
from __future__ import annotations

import contextlib
import json
import os
import pickle
import stat
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from data_tools import InputError
from data_tools.errors import os_reason, printable
from data_tools.io import written_path
from data_tools.signals import signals_held


def to_json(obj):
    """Strict JSON (RFC 8259 has no Infinity or NaN): a non-finite number is written as null,
    e.g. the PSNR of an image identical to the reference, or the depth of a pixel with no hit."""
    def clean(v):
        if isinstance(v, dict):
            return {str(k): clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        if isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, Path):
            return str(v)
        if isinstance(v, float) and not np.isfinite(v):
            return None
        return v
    return json.dumps(clean(obj), indent=2, allow_nan=False)


def check_output(path, allowed):
    """Refuse an output path before any work: wrong extension, missing or unwritable folder."""
    if str(path) == "":
        raise InputError(f"the output path is empty; give a file ending in {' or '.join(allowed)}")
    if str(path).endswith(("/", os.sep)):
        # Path() drops the slash: "out.png/" would write the file out.png, where the user named a folder.
        raise InputError(f"{path}: ends in a slash, as a folder's name does; give a file ending in {' or '.join(allowed)}")
    path = Path(path)
    if path.suffix.lower() not in allowed:
        raise InputError(f"{path}: output must end in {' or '.join(allowed)}")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        if folder.exists():
            raise InputError(f"{path}: {folder} is a file, not a folder")
        raise InputError(f"{path}: folder {folder} does not exist")
    if path.is_dir():
        raise InputError(f"{path}: is a folder")
    written_path(path)      # a device or pipe, a link to one, or a link in a loop: refused before any work
    if path.is_symlink():
        # The file is written where the link leads (`atomic_write_all`): that folder must take it.
        target = Path(os.path.realpath(path))
        if not target.parent.is_dir():
            raise InputError(f"{path}: a link to {target}, whose folder does not exist")
        folder = target.parent
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise InputError(f"{path}: not writable")
    return path


def _real(path):
    """Where ``path`` leads: Path.resolve raises RuntimeError for a link in a loop (Python 3.11)."""
    return Path(os.path.realpath(path))


def check_distinct(source, outputs, read=(), flags=()):
    """Refuse two outputs on one file, or an output on a file read: ``source`` (the volume or
    scene file named, or None) or one of ``read`` (a header's data file, a sidecar, a scene's
    volumes and transfer functions). ``flags`` name the first outputs, to say which two met."""
    seen = {}
    named = _real(source) if source is not None else None
    others = {_real(p) for p in read}
    for n, path in enumerate(outputs):
        if path is None:
            continue
        key = _real(path)
        if key in seen:
            first, was = seen[key]
            if n < len(flags):
                raise InputError(f"{path}: given to both {flags[first]} and {flags[n]}; each output needs a file "
                                 "of its own")
            raise InputError(f"{path}: given for two outputs ({was} and {path})")
        if key == named:
            raise InputError(f"{path}: is the input file; write the output elsewhere")
        if key in others:
            raise InputError(f"{path}: is read by this run (a volume, its data file or sidecar, or a "
                             "transfer function); write the output elsewhere")
        seen[key] = (n, path)


def stale_sidecars(paths):
    """The spacing-and-origin sidecars (``X.npy.json``, `data_tools.io.npy`) of the ``.npy``
    files among ``paths``: an array written over ``X.npy`` is not the volume they describe, and
    read back as a volume it would take their spacing and origin. `atomic_write_all` removes
    them with the write. Both names count for a link: the sidecar beside the name given, which
    a reader of that name finds, and the one beside the file it leads to. A file of that name
    that is no sidecar (a run's stats) is left alone; a folder is refused before any work."""
    from data_tools.io.npy import is_sidecar, sidecar_path
    stale = []
    for path in paths:
        if path is None or Path(path).suffix.lower() != ".npy":
            continue
        for side in dict.fromkeys([sidecar_path(path), sidecar_path(written_path(Path(path)))]):
            if side.is_dir():
                raise InputError(f"{side}: the sidecar of {Path(path).name} (its spacing and origin) is not a "
                                 "file; move it or write elsewhere")
            if is_sidecar(side) and side not in stale:
                stale.append(side)
    return stale


def check_not_sidecar(path, outputs=()):
    """Refuse to write ``path`` (a JSON output) where a ``.npy`` volume beside it reads its
    spacing and origin: over its sidecar it would lose its placement, and in either case fail
    to load (a sidecar of other keys). A volume among this run's ``outputs`` is written over,
    its sidecar stale anyway; a JSON file of other keys is no sidecar, written over freely."""
    from data_tools.io.npy import is_sidecar
    written = {Path(os.path.realpath(o)) for o in outputs if o is not None}
    for side in dict.fromkeys([Path(path), written_path(Path(path))]):
        volume = side.with_name(side.name[:-len(".json")])
        if (side.name.lower().endswith(".npy.json") and volume.is_file()
                and Path(os.path.realpath(volume)) not in written):
            if is_sidecar(side):
                raise InputError(f"{path}: holds the spacing and origin of the volume {volume.name}; "
                                 "write elsewhere")
            if not side.exists():
                raise InputError(f"{path}: would be read as the spacing and origin of the volume {volume.name} "
                                 "beside it; write elsewhere")


def atomic_write_all(writes, remove=()):
    """Write each ``(path, write)`` through a temporary file beside it, then rename them all.

    Renaming starts only once every file is whole, so a failure (disk full, a
    folder gone) leaves none of the outputs, never a half-written one, nor
    an image without the depth and stats asked for with it. A path that is a
    symbolic link is written where it leads (`data_tools.io.written_path`).
    The files in ``remove`` (`stale_sidecars`) are removed just before the renames.
    """
    done = []
    path = writes[0][0]
    try:
        for path, write in writes:
            target = written_path(path)
            # A short name: the output's own, grown by a prefix, could pass the 255-byte limit.
            fd, tmp = tempfile.mkstemp(prefix=".parc-", suffix=path.suffix, dir=target.parent or ".")
            os.close(fd)
            done.append((Path(tmp), target, path))
            write(Path(tmp))
        umask = os.umask(0)
        os.umask(umask)
        for tmp, target, _ in done:
            # mkstemp makes owner-only files; outputs are ordinary files, and a file replaced keeps its mode.
            try:
                mode = stat.S_IMODE(os.stat(target).st_mode)
            except FileNotFoundError:
                mode = 0o666 & ~umask
            os.chmod(tmp, mode)
        # A Ctrl-C between two renames would leave a mixed set.
        with signals_held(done=", ".join(str(path) for _, _, path in done)):
            for path in remove:
                path.unlink(missing_ok=True)
            for tmp, target, path in done:
                os.replace(tmp, target)
    except OSError as exc:
        # Name the user's file: the temporary one beside it means nothing to them.
        raise InputError(f"{path}: cannot write: {os_reason(exc)}") from None
    finally:
        for tmp, _, _ in done:
            if tmp.exists():
                tmp.unlink()


def write_png(image, path):
    """Write a premultiplied RGBA float image as an 8-bit PNG, which stores straight alpha.

    The colour is divided by alpha before it is rounded: rounded first, a
    faint pixel's colour (alpha 0.05, 13 of 255) came out in steps of 1/13.
    """
    from PIL import Image
    img = np.asarray(image, dtype=np.float64)
    a = img[..., 3:4]
    rgb = np.divide(img[..., :3], a, out=np.zeros_like(img[..., :3]), where=a > 0)
    rgba = np.clip(np.rint(np.concatenate([rgb, a], axis=-1) * 255.0), 0, 255).astype(np.uint8)
    Image.fromarray(rgba, "RGBA").save(path, format="PNG")


def save_image(image, path, who="save_image"):
    """Write a render's premultiplied RGBA float image to ``path``, whole or not at all, as the
    command line writes it: a ``.png`` of 8-bit straight RGBA (`write_png`), or a ``.npy`` of the
    array as it is. ``who`` names the caller in the error for a path that is not text. Returns
    the path."""
    from data_tools.io.npy import save_array
    if not isinstance(path, (str, os.PathLike)) or not isinstance(os.fspath(path), str):
        raise InputError(f"{who} takes a file's path, got {type(path).__name__}")
    path = check_output(path, (".png", ".npy"))
    png = path.suffix.lower() == ".png"
    atomic_write_all([(path, (lambda tmp: write_png(image, tmp)) if png else (lambda tmp: save_array(tmp, image)))])
    return path


def time_left(seconds):
    """``about 40 s left``, ``about 3 min left``, ``about 2 h 5 min left``: a progress line's
    estimate, rounded as coarsely as an estimate of the rest of the work deserves."""
    said = max(1, round(seconds / 5) * 5 if seconds >= 10 else round(seconds))
    if said < 60:
        return f"about {said} s left"
    minutes = max(1, round(seconds / 60))
    if minutes < 60:
        return f"about {minutes} min left"
    return f"about {minutes // 60} h {minutes % 60} min left"


def _compile_clock():
    """A clock of the seconds Numba spends compiling from now on (``seconds(now)``, a compile
    under way counted to ``now``), until ``stop()``."""
    from numba.core import event

    class Clock(event.Listener):
        def __init__(self):
            self.total, self.began, self.depth = 0.0, 0.0, 0

        def on_start(self, ev):
            if self.depth == 0:
                self.began = time.perf_counter()
            self.depth += 1         # a kernel compiles the functions it calls inside its own compile

        def on_end(self, ev):
            self.depth -= 1
            if self.depth == 0:
                self.total += time.perf_counter() - self.began

        def seconds(self, now):
            return self.total + (now - self.began if self.depth else 0.0)

        def stop(self):
            if self in event._registered["numba:compile"]:
                event.unregister("numba:compile", self)

    clock = Clock()
    event.register("numba:compile", clock)
    return clock


class Progress:
    """Progress on stderr: a live percentage on a terminal, a few lines otherwise.

    Nothing is shown for work done within ``delay`` seconds, so that a
    quick render prints only its result, whatever its size. Progress is
    only news: a stderr that cannot be written (a closed pipe, a full disk)
    silences it and leaves the work to finish.
    """

    #: The Progress whose terminal line is unfinished (no newline yet), if any.
    open_line = None
    #: The Progress made last, whose first report may still be pending.
    latest = None

    def __init__(self, what, delay=1.0):
        self.what = what
        self.tty = sys.stderr.isatty()
        self.start = time.perf_counter()
        self.delay = delay
        self.last = -1
        self.mute = False
        self.first = None           # (time, fraction, compiling) at the first report of work done
        self.compiling = _compile_clock()
        self.width = 0              # of the terminal line last written, to write it over whole
        self.lock = threading.Lock()        # the first report may come from the timer's thread
        # Work before the first report (cell ranges of a large volume, the OpenGL pass)
        # can take seconds: once the delay is over, 0% says the work has begun.
        self.pending = threading.Timer(delay, self._begun)
        self.pending.daemon = True
        self.pending.start()
        Progress.latest = self

    def _begun(self):
        if self.last < 0:
            self(0.0)

    def __call__(self, fraction):
        with self.lock:
            now = time.perf_counter()
            if self.first is None and fraction > 0:
                self.first = (now, fraction, self.compiling.seconds(now))
            self._report(int(100 * fraction), self._left(now, fraction))

    def _left(self, now, fraction):
        """Seconds the work has left at the pace since its first report, or None before two.
        Not from the start, and less the time spent compiling since: the first part pays for
        what the rest reuses (the OpenGL pass), and compiling the casters (10 to 60 s, some of
        them after the first report: a lit scene's) would make an estimate far too long."""
        if self.first is None or fraction >= 1.0:
            return None
        t0, f0, c0 = self.first
        if fraction <= f0 or now - t0 < self.delay:
            return None
        working = (now - t0) - (self.compiling.seconds(now) - c0)
        return max(working, 0.0) / (fraction - f0) * (1.0 - fraction)

    def _report(self, pct, left=None):
        if self.mute or time.perf_counter() - self.start < self.delay:
            return
        # On a terminal the percentage keeps its width, and the line is padded over the last one.
        text = (f"parc: {self.what}: {pct:{3 if self.tty else 0}d}%"
                + (f", {time_left(left)}" if left is not None else ""))
        if self.tty:
            self._say(f"\r{text:{self.width}}", end="")
            self.width = len(text)
            Progress.open_line = self
        elif pct // 25 > self.last // 25 and pct < 100:
            self._say(text)
        self.last = pct

    def done(self):
        self.pending.cancel()
        self.compiling.stop()
        if self.last >= 0:
            # Off a terminal too: the lines stopped at 75%, and the work looked cut short.
            over = "\r" if self.tty else ""       # a terminal's live line is written over
            text = f"parc: {self.what}: done in {time.perf_counter() - self.start:.1f} s"
            self._say(f"{over}{text:{self.width if self.tty else 0}}")
            Progress.open_line = None

    def _say(self, text, end="\n"):
        if self.mute:
            return
        try:
            print(text, end=end, file=sys.stderr, flush=True)
        except (OSError, ValueError):
            self.mute = True
            Progress.open_line = None


#: Seconds of work after which `slow_note` speaks.
SLOW_NOTE_DELAY = 1.0


@contextlib.contextmanager
def slow_note(what, say, delay=None):
    """Say ``what ...`` once the work inside has taken ``delay`` seconds, and its time when it
    ends: reading a large volume (or its histogram) takes seconds before a render can report
    any progress, and a silent wait looks like a hang. Quick work says nothing; failed work
    leaves its error line to say the rest."""
    start = time.perf_counter()
    lock = threading.Lock()
    said = []

    def begun():
        with lock:
            if said is not None:
                said.append(True)
                say(f"{what} ...")

    delay = SLOW_NOTE_DELAY if delay is None else delay
    timer = threading.Timer(delay, begun)
    timer.daemon = True
    if delay > 0:
        timer.start()
    else:
        begun()
    try:
        yield
    finally:
        timer.cancel()
        with lock:
            spoke, said = bool(said), None
    if spoke:
        say(f"{what}: done in {time.perf_counter() - start:.1f} s")


def note(text, who="parc"):
    """``who: text``, one line on stderr. A stderr that cannot take it (a full disk, a closed
    pipe) loses the note, not the run: a render whose files were all written ended with status 2."""
    try:
        print(f"{who}: {printable(text)}", file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


def print_out(text, done=None, end="\n"):
    """Print ``text`` on standard output, a failure there named as such (``> /dev/full``
    would otherwise end in "No space left on device" alone, after the files were written), after
    ``done``, what the run did before (the files it wrote, which stay: they are whole). The text a
    failed flush leaves in the buffer would fail again at exit (a second complaint, status 120), so
    standard output is then pointed at the null device, as for a closed pipe."""
    try:
        print(text, end=end, flush=True)
    except BrokenPipeError:
        raise
    except OSError as exc:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        raise InputError(f"{f'{done}, but ' if done else ''}cannot write to standard output: "
                         f"{os_reason(exc)}") from None


def end_progress_line():
    """End an unfinished progress line, so that what follows (an error) starts a line of its own."""
    if Progress.latest is not None:
        Progress.latest.pending.cancel()
    line, Progress.open_line = Progress.open_line, None
    if line is not None:
        line._say("")


def error_line(text):
    """``parc: text`` on stderr, on a line of its own after any unfinished progress."""
    end_progress_line()
    note(text)


def compile_notice(say, kernels=()):
    """Say that the casters compile now, when this machine has not every one of ``kernels``
    compiled for these sources, or, with none named, no kernel at all. ``kernels``:
    ``(dispatcher, sample types)`` pairs, as `parc.renderer.kernel_samples` gives those a
    run needs, each kernel needed for every type.

    Numba compiles every kernel on its first use, for each type of samples it
    is given, and caches it (`raycast.kernel_cache` names the folder after the kernel
    sources), so the first render after a clone or an update spends several
    seconds, up to a minute for `parc bench`, before its progress starts, and
    so does the first render of another kind (translucent after isosurfaces,
    shadows...) or of other samples (the CT head's int16 after uint8: 5 s);
    without a word it looks hung.
    """
    from raycast.kernel_cache import cache_folder, cache_refused

    refused = cache_refused()
    _NOTICE_SAID[0] = refused is not None       # for this run: `late_compile_notice` says it otherwise
    if refused is not None:
        say(f"compiling the ray casters; {refused} cannot be written, so every run compiles them again "
            "(set PARC_CACHE_DIR to a writable folder, or NUMBA_CACHE_DIR, which wins over it when set)")
        return
    folder = cache_folder()
    if kernels:
        missing = not all(_cached(kernel, folder, samples) for kernel, samples in kernels)
    else:
        missing = next(folder.rglob("*.nbi"), None) is None
    if missing:
        _NOTICE_SAID[0] = True
        say(_compiling_once(folder))


def compile_took(seconds):
    """The words after a render's time for the part of it spent compiling: "once" only where the
    kernels were kept, as every run compiles them again otherwise."""
    from raycast.kernel_cache import cache_refused, cache_unsaved

    unsaved = cache_unsaved()
    if cache_refused():
        kept = ""
    elif unsaved:
        kept = f", not kept: {unsaved}"
    else:
        kept = ", once"
    return f" ({seconds:.1f} s of it compiling the casters{kept})"


def _compiling_once(folder):
    return f"compiling the ray casters for this kind of render and sample type, once on this machine (kept in {folder})"


#: Whether `compile_notice` or `late_compile_notice` has spoken for the run under way.
_NOTICE_SAID = [False]


@contextlib.contextmanager
def on_first_compile(act):
    """Call ``act()`` as the first Numba compile the thread running the block starts, once.
    Numba reports a compile, not a kernel loaded from its cache."""
    import numba.core.event
    thread, done = threading.get_ident(), []

    class FirstCompile(numba.core.event.Listener):
        def on_start(self, event):
            if not done and threading.get_ident() == thread:
                done.append(True)
                act()

        def on_end(self, event):
            pass                # a Listener must have one; the start is all that is told
    with numba.core.event.install_listener("numba:compile", FirstCompile()):
        yield


def late_compile_notice(say):
    """Say `compile_notice`'s line at the first compile the block starts, where it has not been
    said: the kernels a run needs are foretold (`parc.renderer.kernel_samples`), and one missed
    there (the cell ranges' passes and the shadow rays compile for each type of samples) compiled
    for seconds without a word."""
    from raycast.kernel_cache import cache_folder

    def notice():
        if not _NOTICE_SAID[0]:
            _NOTICE_SAID[0] = True
            end_progress_line()
            say(_compiling_once(cache_folder()))
    return on_first_compile(notice)


@contextlib.contextmanager
def compiling_seconds():
    """A one-item list, filled when the block ends with the seconds Numba spent compiling in it:
    a first run's render time is mostly that, and the line reporting it says so."""
    from numba.core.event import install_timer
    spent = [0.0]
    with install_timer("numba:compile", lambda seconds: spent.__setitem__(0, seconds)):
        yield spent


def _cached(kernel, folder, samples):
    """Whether Numba's cache in ``folder`` holds ``kernel``, compiled for a first argument of
    each of the Numba types ``samples``.

    The index that counts is the one Numba reads for this kernel, at its place in ``folder``
    (`raycast.kernel_cache` files each kernel under its package's name; Numba alone, under a hash of
    its checkout's path).
    """
    import numba.core.config

    try:
        own = Path(kernel._cache._cache_file._index_path)
        paths = [folder / own.relative_to(numba.core.config.CACHE_DIR)]
    except (AttributeError, ValueError):        # another Numba: any index of this kernel
        paths = list(folder.rglob(_index_name(kernel)))[:1]
    if not paths or not paths[0].is_file():
        return False
    if not samples:
        return True
    try:
        # Numba's index: its version, then (source stamp, {(signature, target): data file}).
        with open(paths[0], "rb") as f:
            pickle.load(f)
            _, overloads = pickle.loads(f.read())
        taken = {str(key[0][0]) for key in overloads}
    except Exception:  # noqa: BLE001 - an index of another Numba: there is one, and Numba will judge it
        return True
    return all(str(t) in taken for t in samples)


def _index_name(kernel):
    try:
        return Path(kernel._cache._cache_file._index_path).name
    except AttributeError:          # another Numba: any index will do
        return "*.nbi"
