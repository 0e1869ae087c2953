"""The one error type for bad user input (files, arguments, values)."""
import re


class InputError(ValueError):
    """Bad input from the user: the message is one line, fit to print as is.

    The command line prints it after ``parc: error:`` and exits with status 2,
    without a traceback.
    """

    def __init__(self, message="", *args):
        # A value echoed into the message can break it over lines: a NumPy array's repr goes on
        # in indented lines, joined here with a space; a newline or escape in a name or path
        # the user gave is shown as its escape (``\\n``), as the command line shows it.
        if isinstance(message, str) and not message.isprintable():
            message = printable(re.sub(r"\n[ \t]+", " ", message))
        super().__init__(message, *args)


def printable(text):
    """``text`` for one line of a terminal: characters that are not printable (a newline or
    a carriage return, a terminal escape, a lone surrogate), which can come with a file name
    or a key the user gave, shown as their escapes (``\\n``, ``\\x1b``)."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape", "backslashreplace").decode("ascii")
                   for c in str(text))


def os_reason(exc: OSError) -> str:
    """Why an operating-system call failed, in a few words: the system's reason, or for NumPy's
    short write (which names no reason) how much was written, and the likely cause."""
    if exc.strerror:
        return exc.strerror
    text = str(exc)
    m = re.fullmatch(r"(\d+) requested and (\d+) written", text)
    if m:
        # NumPy counts the array's values, not bytes: "of 1,600 bytes" was a 12,800-byte depth map.
        return f"only {int(m.group(2)):,} of {int(m.group(1)):,} values were written; is the disk full?"
    return text or type(exc).__name__
