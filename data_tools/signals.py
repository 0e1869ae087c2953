"""Hold Ctrl-C and the stop signals while several files are renamed into place, so that an
output made of several files (an image with its depth and stats, a header with its data file,
a report) is replaced all together or not at all."""
from __future__ import annotations

import contextlib
import signal

#: Ctrl-C and the signals that stop a run (`parc.cli`); SIGHUP is not on every system.
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
