"""The `parc` console script's entry point.

It imports the command line (`parc.cli`, and with it NumPy and the
volume readers; Numba and OpenGL come with the first render) inside the
run, so that a Ctrl-C while they load ends in one line and status 130, as
it does once the command runs, instead of a traceback from the import
machinery; it checks, before Numba reads them, the thread count and
threading layer a user may set for Numba; and once the command has ended
it ignores Ctrl-C through the interpreter's exit.
"""
import os
import signal
import sys

#: More threads than this is a mistake (libgomp fails to start 40,000, and Numba crashed at 100,000).
MAX_THREADS = 1024


def main():
    _open_closed_standard_descriptors()
    threads = os.environ.get("NUMBA_NUM_THREADS")
    count = threads.strip() if threads is not None else ""
    if threads is not None and not count:
        del os.environ["NUMBA_NUM_THREADS"]           # set but empty: unset, without Numba's warning
    elif threads is not None and not (count.isascii() and count.isdigit() and 1 <= int(count) <= MAX_THREADS):
        # Checked before Numba is imported: it fails on 0 with a traceback, and warns on the others.
        _say(f"error: NUMBA_NUM_THREADS must be a whole number from 1 to {MAX_THREADS}, got {threads!r}")
        return 2
    if os.environ.get("NUMBA_THREADING_LAYER", "x").strip() == "":
        del os.environ["NUMBA_THREADING_LAYER"]       # set but empty: Numba's default, not "unknown ''"
    try:
        if os.environ.get("NUMBA_THREADING_LAYER") and (why := _threading_layer_refused()):
            _say(f"error: NUMBA_THREADING_LAYER={os.environ['NUMBA_THREADING_LAYER']!r}: {why} "
                 "(unset it, or give omp or workqueue)")
            return 2
        from .cli import main as run
    except KeyboardInterrupt:
        _say("interrupted")
        return 130
    status = run()
    _ignore_ctrl_c()
    return status


def _ignore_ctrl_c():
    """The command has ended and its files are in place: a Ctrl-C in the interpreter's exit
    (`atexit` callbacks, finalizers: about 0.3 s after a render) could only print a
    traceback after its last line."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:          # not the main thread: not ours to change
        pass


def _open_closed_standard_descriptors():
    """Give a standard descriptor closed at the start (``2>&-``) the null device: the next file
    opened would take its number, and what the C libraries print to stderr (Mesa's warnings) would
    go into it, an image being written, say."""
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)


def _threading_layer_refused():
    """Why Numba cannot start its threads with the layer asked for, or None. It reads the layer
    at the first parallel kernel, after a minute's compile, and fails with a traceback."""
    try:
        from numba.np.ufunc.parallel import _launch_threads
    except ImportError:         # a Numba that starts them otherwise: left to it
        return None
    try:
        _launch_threads()
    except ValueError as exc:
        return " ".join(str(exc).split("HINT:")[0].split())
    return None


def _say(text):
    # Not parc.outputs.note: importing it loads NumPy, which this module exists to put off.
    try:
        print(f"parc: {text}", file=sys.stderr)
    except (OSError, ValueError, AttributeError):     # stderr closed or full
        pass
