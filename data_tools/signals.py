"""Hold Ctrl-C and the stop signals while several files are renamed into place, so that an
output made of several files (an image with its depth and stats, a header with its data file,
a report) is replaced all together or not at all; and end a run at once, leaving none of the
temporary files it was filling."""
from __future__ import annotations

import contextlib
import os
import shutil
import signal
from pathlib import Path

#: Ctrl-C and the signals that stop a run (`parc.stops`); SIGHUP is not on every system.
STOPS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


@contextlib.contextmanager
def signals_held(signums=STOPS, done=None):
    """Hold ``signums`` until the block ends, then act on them as they would have. ``done`` says
    what the block puts in place (``a.png, d.npy``): where it ends whole with a signal held, the
    run stops with its work in place, and its last line says so (`done_before_stop`)."""
    held, was = [], {}
    with contextlib.suppress(ValueError):           # not the main thread: nothing to hold
        for signum in signums:
            was[signum] = signal.signal(signum, lambda n, frame: held.append(n))
    whole = False
    try:
        yield
        whole = True
    finally:
        for signum, handler in was.items():
            # None: a handler set outside Python, which cannot be put back; the default then.
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)
        if held and whole and done:
            _DONE_BEFORE_STOP[0] = done
        for signum in dict.fromkeys(held):
            signal.raise_signal(signum)


#: What a block of `signals_held` put in place before acting on a signal held through it.
_DONE_BEFORE_STOP = [None]


def done_before_stop():
    """``"; a.png, d.npy had been written whole"`` where a stop signal came while outputs were put
    in place, and they were (the stop is acted on once they all are), else ``""``: "interrupted"
    alone read as if the earlier outputs had been kept."""
    done, _DONE_BEFORE_STOP[0] = _DONE_BEFORE_STOP[0], None
    return f"; {done} had been written whole" if done else ""


#: Temporary files and folders a run is filling (`building`).
_BUILDING = []


@contextlib.contextmanager
def building(path):
    """Mark ``path``, a temporary file or folder the block fills, to be removed should the run
    be ended at once (`end_at_once`), where no ``finally`` runs."""
    _BUILDING.append(Path(path))
    try:
        yield
    finally:
        _BUILDING.remove(Path(path))


def end_at_once(status, cleanups=()):
    """End the process now, without unwinding, for a signal given again while Numba compiles
    (`parc.stops`), where an exception cannot be raised: first remove what `building` marks and
    call ``cleanups``, what `atexit` would have done (`raycast.config.at_exit`)."""
    for path in _BUILDING:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                path.unlink()
    for cleanup in cleanups:
        with contextlib.suppress(Exception):
            cleanup()
    os._exit(status)
