"""Memory the system can still hand out, and a one-line refusal of work that would not fit.

Without the refusal a job too large stops on NumPy's allocation error, or
the system kills the process once the pages are touched.
"""
from __future__ import annotations

from .errors import InputError


def available_memory():
    """Bytes the system can still hand out without swapping (``MemAvailable``), or None if unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def check_memory(need, what, hint=""):
    """Raise InputError when ``need`` bytes exceed the memory available (not checked where unknown).

    The message reads ``"{what} needs about N GB of memory; M GB is available{hint}"``.
    """
    have = available_memory()
    if have is not None and need > have:
        raise InputError(f"{what} needs about {_amount(need)} of memory; {_amount(have)} is available{hint}")


def _amount(n):
    """Bytes in MB or GB, and a need past a thousand TB as a power of ten (a header's
    99999999^3 samples needed a 32-digit number of GB)."""
    if n >= 2**50:
        try:
            gb = n / 2**30
        except OverflowError:       # an integer past float's range (an image --size 10**400 1)
            gb = float("inf")
        return f"{gb:.1e} GB" if gb < float("inf") else "over 1e+300 GB"
    return f"{n / 2**30:.1f} GB" if n >= 2**30 else f"{n / 2**20:.0f} MB"
