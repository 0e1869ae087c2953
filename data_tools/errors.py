"""The one error type for bad user input (files, arguments, values)."""
import re


class InputError(ValueError):
    """Bad input from the user: the message is one line, fit to print as is.

    The command line prints it after ``parc: error:`` and exits with status 2,
    without a traceback.
    """


def os_reason(exc: OSError) -> str:
    """Why an operating-system call failed, in a few words: the system's reason, or for NumPy's
    short write (which names no reason) how much was written, and the likely cause."""
    if exc.strerror:
        return exc.strerror
    text = str(exc)
    m = re.fullmatch(r"(\d+) requested and (\d+) written", text)
    if m:
        return f"only {int(m.group(2)):,} of {int(m.group(1)):,} bytes were written; is the disk full?"
    return text or type(exc).__name__
