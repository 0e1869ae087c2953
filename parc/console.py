"""The `parc` console script's entry point.

It imports the command line (`parc.cli`, and with it NumPy, Numba and
OpenGL: about 0.3 s) inside the run, so that a Ctrl-C while they load
ends in one line and status 130, as it does once the command runs,
instead of a traceback from the import machinery.
"""
import sys


def main():
    try:
        from .cli import main as run
    except KeyboardInterrupt:
        try:
            print("parc: interrupted", file=sys.stderr)
        except (OSError, ValueError, AttributeError):     # stderr closed
            pass
        return 130
    return run()
