"""What to show: volumes with their rendering mode, the camera, lights, image size."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from data_tools import InputError, Volume

from .camera import Camera

#: Default surface colour: a warm off-white that reads as tissue or bone.
DEFAULT_SURFACE = (0.93, 0.86, 0.74)
#: ambient, diffuse, specular, shininess.
DEFAULT_MATERIAL = (0.12, 0.78, 0.25, 40.0)


@dataclass(eq=False)
class Isosurface:
    """An opaque isosurface ``volume == value`` of a volume's trilinear interpolant.

    Parameters
    ----------
    volume : Volume
    value : float
        The isovalue; must lie within the data range.
    color : (r, g, b) in [0, 1]
    material : (ambient, diffuse, specular, shininess)

    Raises
    ------
    InputError
        An isovalue that is not finite or lies outside the data range.
    """

    volume: Volume
    value: float
    color: tuple = DEFAULT_SURFACE
    material: tuple = DEFAULT_MATERIAL

    def __post_init__(self):
        if not isinstance(self.volume, Volume):
            raise InputError(f"Isosurface needs a Volume, got {type(self.volume).__name__}")
        try:
            self.value = float(self.value)
        except (TypeError, ValueError):
            raise InputError(f"isovalue must be a number, got {self.value!r}") from None
        lo, hi = self.volume.value_range()
        if not math.isfinite(self.value) or not lo <= self.value <= hi:
            raise InputError(f"isovalue {self.value:g} is outside the data range "
                             f"[{lo:g}, {hi:g}] of {self.volume.name}")
        self.color = _unit_triple(self.color, "surface colour")


@dataclass(eq=False)
class Scene:
    """A camera, an image size and what to show.

    Parameters
    ----------
    camera : Camera
    size : (width, height)
        Image size in pixels, both at least 1.
    volumes : list of Isosurface
    lights : list
        Light sources; empty means a headlight at the eye.
    background : (r, g, b, a) or None
        Composited under the image; None leaves it transparent.
    """

    camera: Camera
    size: tuple = (512, 512)
    volumes: list = field(default_factory=list)
    lights: list = field(default_factory=list)
    background: tuple | None = None

    def __post_init__(self):
        if not isinstance(self.camera, Camera):
            raise InputError(f"Scene needs a Camera, got {type(self.camera).__name__}")
        try:
            w, h = (int(v) for v in self.size)
            ok = (w, h) == tuple(self.size)
        except (TypeError, ValueError):
            ok = False
        if not ok or w < 1 or h < 1:
            raise InputError(f"image size must be two positive integers, got {self.size!r}")
        self.size = (w, h)
        self.volumes = list(self.volumes)
        if not self.volumes:
            raise InputError("the scene shows nothing: give at least one volume")
        if self.background is not None:
            bg = np.asarray(self.background, dtype=np.float64)
            if bg.shape not in ((3,), (4,)) or not ((bg >= 0) & (bg <= 1)).all():
                raise InputError(f"background must be 3 or 4 numbers in [0, 1], got {self.background!r}")
            self.background = tuple(bg) + ((1.0,) if bg.shape == (3,) else ())

    @property
    def width(self):
        return self.size[0]

    @property
    def height(self):
        return self.size[1]


def _unit_triple(v, what):
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or not ((a >= 0) & (a <= 1)).all():
        raise InputError(f"{what} must be three numbers in [0, 1], got {v!r}")
    return tuple(float(c) for c in a)
