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
def signals_held(signums=STOPS):
    """Hold ``signums`` until the block ends, then act on them as they would have."""
    held, was = [], {}
    with contextlib.suppress(ValueError):           # not the main thread: nothing to hold
        for signum in signums:
            was[signum] = signal.signal(signum, lambda n, frame: held.append(n))
    try:
        yield
    finally:
        for signum, handler in was.items():
            # None: a handler set outside Python, which cannot be put back; the default then.
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)
        for signum in dict.fromkeys(held):
            signal.raise_signal(signum)


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
