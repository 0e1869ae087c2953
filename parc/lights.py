"""Shadow PARC: the proxy rasterized from each light, and how shadow rays look it up.

About this technique
--------------------
Sobierajski & Avila (1995, §5) treat a point light as an eye: per light
and volume, near and far buffers are rendered with a perspective view
from the light towards the volume's box, with a field of view twice the
largest angle to the box's corners, split into several views of at most
90 degrees when that is wider (six, like a cube map, with the light
inside the box). A directional light gets a parallel view along its
direction, sized to the box's projection. A shadow ray from a surface
point towards the light is then one of the light's rays run backwards:
the distance ``s`` from the light maps to the shadow ray's ``t = D - s``
(``D`` the point's distance to the light), so the light's ``[near, far]``
becomes the shadow ray's ``[D - far, D - near]``.

A shadow ray does not pass through a light-buffer pixel's centre, which
is what the primary pass's bounds are exact for. So the light buffers are
made valid for *every* ray through a pixel's square: each face's
projection is grown by more than half a pixel (every pixel whose square
the face touches gets a fragment: conservative rasterization, which also
catches faces smaller than a pixel) and writes the face's whole range of
distances from the light, not the centre ray's crossing
(`parc.raster.raster_segments` with ``face_range=True``). Faces are not
merged into large rectangles here, so that range stays within a
supercell. The lookup merges the four pixels around the shadow ray's
crossing of the view (smallest near, largest far), as the paper does;
the crossing lies in one of their squares, so the merged segment covers
every possibly contributing supercell on the shadow ray, and the caster,
walking the same cells with the same code as the unaccelerated shadow
ray, finds the same occluders and the same samples.

Buffers are built once per light and volume (classification, supercell
size, buffer size) and kept while only the camera moves.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

import data_tools.memory
from data_tools.memory import check_memory
from raycast.shade import KIND_DIRECTIONAL, KIND_HEADLIGHT, KIND_POINT
from raycast.shadow import N_VIEW, V_EYE, V_FWD, V_KIND, V_RIGHT, V_SCALE, V_UP

from .camera import Camera, unit_vector
from .raster import box_corners
from .scene import DirectionalLight, PointLight

#: Light-buffer size in pixels (square). Finer buffers give tighter
#: segments for more raster time; 256 costs a few ms per view on llvmpipe.
LIGHT_BUFFER_SIZE = 256

#: Growth of each face's projection, pixels: over half a pixel, so every
#: pixel whose square the face touches is covered (see the module notes).
LIGHT_PAD_PX = 0.625

#: A single perspective view covers the box when its half-angle stays
#: below this (degrees); wider boxes, or a light inside, take cube views.
MAX_HALF_ANGLE = 44.0

#: Cached buffers per volume index (light, classification, size): a few cover a scene's lights.
LIGHT_BUFFER_CACHE_SIZE = 16
#: ... and their bytes at most, or a quarter of the memory where that is more
#: (`light_cache_bytes`): a point light's six views at 8192 pixels take 6 GB, so a few moves
#: of the light filled the memory. (The default size takes 6 MB a light.)
LIGHT_BUFFER_CACHE_BYTES = 1 << 30
#: Bytes a light buffer takes per pixel and view (near and far, float64), and per pixel of the
#: one view being drawn (the pass's read-back and segments).
_BYTES_PER_VIEW_PIXEL = 16
_BYTES_PER_PASS_PIXEL = 24


def buffer_bytes(views, size):
    """Bytes of the near and far buffers of ``views`` views of ``size`` x ``size`` pixels."""
    return _BYTES_PER_VIEW_PIXEL * views * size * size


def light_cache_bytes(held):
    """Bytes of light buffers the volumes may keep, ``held`` of them kept now: a quarter of the
    memory they and the memory available make, at least `LIGHT_BUFFER_CACHE_BYTES`. (A fixed
    bound alone made three lights inside a volume at 2048 pixels, 1.2 GB, evict each other
    and be drawn again every frame.)"""
    have = data_tools.memory.available_memory()
    return LIGHT_BUFFER_CACHE_BYTES if have is None else max(LIGHT_BUFFER_CACHE_BYTES, (have + held) // 4)


@dataclass
class LightBuffers:
    """Near/far buffers of one volume's proxy as seen from one light.

    Attributes
    ----------
    views : ndarray (V, N_VIEW) float64
        Each view's camera (see ``V_*``).
    near, far : ndarray (V, N, N) float64
        Distance from the light (point) or from the view plane along the
        light's direction (directional) over which each pixel's rays may
        meet a possibly contributing supercell; ``near > far`` where none.
    polygons : int
        Faces of the proxy the views were drawn from.
    seconds : float
        Raster time when built (0 when reused).
    info : dict
        ``views``: the number of views drawn.
    """

    views: np.ndarray
    near: np.ndarray
    far: np.ndarray
    polygons: int
    seconds: float = 0.0
    info: dict = field(default_factory=dict)


def light_array(lights):
    """The kernels' lights: ``(L, 7)`` rows ``[kind, x, y, z, r, g, b]``.

    ``x, y, z`` is the position of a point light, or the direction a
    directional light travels in; ``r, g, b`` its colour times intensity.
    No lights give one row: the white headlight (`KIND_HEADLIGHT`), which
    shines along each ray.
    """
    if not lights:
        return np.array([[KIND_HEADLIGHT, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]])
    out = np.zeros((len(lights), 7))
    for n, light in enumerate(lights):
        if isinstance(light, PointLight):
            out[n, 0] = KIND_POINT
            out[n, 1:4] = light.position
        else:
            out[n, 0] = KIND_DIRECTIONAL
            out[n, 1:4] = light.direction
        out[n, 4:7] = light.radiance
    return out


def _up_for(f):
    """An up vector well away from ``f``."""
    a = int(np.argmin(np.abs(f)))
    up = np.zeros(3)
    up[a] = 1.0
    return tuple(up)


def light_views(light, lo, hi):
    """The cameras the light's buffers are rendered with, for the box ``[lo, hi]``.

    Point light: one perspective view towards the box's centre if the box
    subtends less than ``2 * MAX_HALF_ANGLE``; else the cube views (90
    degrees each) that face some of the box, up to six (the light inside).
    Directional light: one parallel view along the light's direction,
    starting before the box and sized to its projection.
    """
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    corners = box_corners(lo, hi)
    centre = 0.5 * (lo + hi)
    size = float(np.linalg.norm(hi - lo)) + 1e-12 * (1.0 + float(np.abs(corners).max()))
    if isinstance(light, DirectionalLight):
        f = np.asarray(light.direction)
        cam0 = Camera(eye=tuple(centre - f * size), look_at=tuple(centre), up=_up_for(f), parallel_scale=1.0)
        _, r, u = cam0.basis()
        q = corners - centre
        pr, pu, pf = q @ r, q @ u, q @ f
        mid = centre + r * 0.5 * (pr.max() + pr.min()) + u * 0.5 * (pu.max() + pu.min())
        half = 0.5 * max(pr.max() - pr.min(), pu.max() - pu.min()) * (1.0 + 1e-6) + 1e-9 * size
        eye = mid + f * (pf.min() - 0.05 * size - 1e-9)
        reach = max(1.0, float(np.abs(eye).max()))     # eye + f rounds to eye past 2^53, and turns below
        return [Camera(eye=tuple(eye), look_at=tuple(eye + f * reach), up=_up_for(f), parallel_scale=half)]
    L = np.asarray(light.position)
    inside = bool(np.all(L >= lo - 1e-9 * size) and np.all(L <= hi + 1e-9 * size))
    if not inside:
        # Directions scaled first: a far light (1e160) would overflow their squared lengths.
        f = unit_vector(centre - L)
        q = np.array([unit_vector(c - L) for c in corners])
        half = math.degrees(math.acos(float(np.clip((q @ f).min(), -1.0, 1.0))))
        if half < MAX_HALF_ANGLE:
            fov = min(90.0, 2.0 * half * 1.02 + 0.5)
            # Looking at the centre, not L + f: far from the origin, L + f rounds to L.
            return [Camera(eye=tuple(L), look_at=tuple(centre), up=_up_for(f), fov=fov)]
    views = []
    for a in range(3):
        for s in (1.0, -1.0):
            if not inside and s * (hi[a] - L[a]) <= 0.0 and s * (lo[a] - L[a]) <= 0.0:
                continue      # the whole box is behind this face of the cube
            f = np.zeros(3)
            f[a] = s
            reach = max(1.0, float(np.abs(L).max()))   # so that L + f reach does not round to L
            views.append(Camera(eye=tuple(L), look_at=tuple(L + f * reach), up=_up_for(f), fov=90.0))
    return views


def view_array(cameras):
    """`LightBuffers.views` for a list of cameras."""
    out = np.zeros((len(cameras), N_VIEW))
    for n, cam in enumerate(cameras):
        f, r, u = cam.basis()
        out[n, V_KIND] = 1.0 if cam.parallel else 0.0
        out[n, V_EYE:V_EYE + 3] = cam.eye
        out[n, V_FWD:V_FWD + 3] = f
        out[n, V_RIGHT:V_RIGHT + 3] = r
        out[n, V_UP:V_UP + 3] = u
        out[n, V_SCALE] = cam.parallel_scale if cam.parallel else math.tan(math.radians(cam.fov) / 2.0)
    return out


def no_views():
    """``(views, near, far)`` for shadow rays that no buffer bounds: one view that sees nothing
    (a zero forward axis, which `raycast.shadow.light_segment` passes by), never none. Numba's
    parallel loops read the first view's row once before the loop, however deep in a branch
    the code reads it: from an empty array that read was out of bounds."""
    return np.zeros((1, N_VIEW)), np.full((1, 1, 1), np.inf), np.full((1, 1, 1), -np.inf)


def light_buffers(light, proxy, *, size=LIGHT_BUFFER_SIZE):
    """Rasterize ``proxy`` (unmerged faces) from ``light``: a `LightBuffers`."""
    from .raster import raster_segments

    t0 = time.perf_counter()
    lo, hi = proxy.bounds
    if not proxy.pc.any():
        return LightBuffers(*no_views(), 0, time.perf_counter() - t0)
    cams = light_views(light, lo, hi)
    check_memory(buffer_bytes(len(cams), size) + _BYTES_PER_PASS_PIXEL * size * size,
                 f"shadow buffers of {size}x{size} pixels from {len(cams)} view{'s' * (len(cams) > 1)}",
                 f": give a smaller light_buffer (the default is {LIGHT_BUFFER_SIZE})")
    near = np.empty((len(cams), size, size))
    far = np.empty((len(cams), size, size))
    for n, cam in enumerate(cams):
        segs = raster_segments(cam, size, size, proxy, pad_px=LIGHT_PAD_PX, face_range=True)
        near[n] = segs.near
        far[n] = segs.far
    return LightBuffers(view_array(cams), near, far, proxy.n_polygons, time.perf_counter() - t0,
                        {"views": len(cams)})
