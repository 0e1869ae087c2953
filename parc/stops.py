"""Ctrl-C and the stop signals (SIGTERM, SIGHUP) during a command-line run (`parc.cli.main`).

Each becomes an exception raised where the run is, so that the writes
under way remove their temporary files as they unwind; but not inside a
Numba compile, where one raised was lost, crashed the process or broke
the kernel: there it waits for the compile to end, and a second signal
ends the run at once (`data_tools.signals.end_at_once`).
"""
from __future__ import annotations

import contextlib
import signal
import sys

from data_tools.signals import STOPS, end_at_once

from .outputs import error_line


class Stopped(BaseException):
    """SIGTERM or SIGHUP, raised where the program is, so that the writes under way clean up
    their temporary files (`parc.outputs.atomic_write_all`, `data_tools.io.save_volume`) as on
    Ctrl-C."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


def stop_on_signals():
    """Turn SIGTERM and SIGHUP into `Stopped` and Ctrl-C into KeyboardInterrupt for the run,
    held while Numba compiles (`raycast.compiler.after_compile`). A second signal then stops the
    run at once. Returns the handlers they replace, for `restore_handlers`."""
    def stop(signum, frame):
        # Still importing, the modules may not have defined these yet.
        compiler, config = sys.modules.get("raycast.compiler"), sys.modules.get("raycast.config")
        compiling = getattr(compiler, "compiling", None)
        if compiling is not None and compiling():
            if compiler.after_compile(lambda: stop(signum, None)):
                again = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
                error_line(f"stopping once the kernel under way is ready ({again} again to stop at once)")
                return
            # Outputs are written after the casts; what a run fills meanwhile is marked `building`.
            error_line("interrupted" if signum == signal.SIGINT else f"stopped by {signal.Signals(signum).name}")
            end_at_once(128 + signum, getattr(config, "EXIT_CLEANUPS", ()))
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise Stopped(signum)
    replaced = {}
    for signum in STOPS:
        # An ignored signal stays ignored: SIGHUP under nohup, Ctrl-C for a job a script started with &.
        if signal.getsignal(signum) == signal.SIG_IGN:
            continue
        with contextlib.suppress(ValueError, OSError):     # not the main thread, or no such signal here
            replaced[signum] = signal.signal(signum, stop)
    return replaced


def restore_handlers(replaced):
    """Put back the handlers `stop_on_signals` replaced."""
    for signum, handler in replaced.items():
        if handler is not None:                 # None: set outside Python, not ours to restore
            signal.signal(signum, handler)
