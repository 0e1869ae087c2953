"""Helpers the synthetic volumes share: grid sizes, world coordinates, names, soft edges."""
from __future__ import annotations

import operator

import numpy as np

from .errors import InputError


def grid_dims(size, what="size"):
    """``(nx, ny, nz)`` from an int ``n`` (a cube) or three ints."""
    try:
        # operator.index: a whole number of a whole-number type (12.7 is not cut to 12, nor "12" read).
        dims = (operator.index(size),) * 3 if np.ndim(size) == 0 else tuple(operator.index(s) for s in size)
    except TypeError:
        raise InputError(f"{what} must be an integer or three integers, got {size!r}") from None
    if len(dims) != 3 or min(dims) < 2:
        raise InputError(f"{what} must give at least 2 samples per axis, got {size!r}")
    return dims


def grid_axes(dims, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)):
    """World coordinates as broadcastable arrays ``x[None,None,:]``, ``y[None,:,None]``, ``z[:,None,None]``."""
    nx, ny, nz = dims
    x = origin[0] + spacing[0] * np.arange(nx, dtype=np.float64)
    y = origin[1] + spacing[1] * np.arange(ny, dtype=np.float64)
    z = origin[2] + spacing[2] * np.arange(nz, dtype=np.float64)
    return x[None, None, :], y[None, :, None], z[:, None, None]


def volume_label(name, dims):
    return f"{name} {dims[0]}x{dims[1]}x{dims[2]}"


def soft_inside(dist, width):
    """Soft inside indicator of a region with signed distance ``dist`` (negative inside)."""
    return 0.5 - 0.5 * np.tanh(dist / width)
