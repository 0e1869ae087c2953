"""The camera: one object yields the caster's rays, the OpenGL passes' view and conventional matrices.

Conventions (DESIGN.md): VTK-style ``eye``, ``look_at``, ``up``; vertical
``fov`` in degrees, or a parallel projection with ``parallel_scale`` (half
the view height in world units). With ``f = normalize(look_at - eye)``,
``r = normalize(f x up)``, ``u = r x f``, pixel ``(x, y)`` (y down) of a
``W x H`` image has ``sx = (2 (x + 0.5) / W - 1) W/H``,
``sy = 1 - 2 (y + 0.5) / H``; perspective rays start at the eye with
direction ``normalize(f + tan(fov/2) (sx r + sy u))``; parallel rays start at
``eye + parallel_scale (sx r + sy u)`` with direction ``f``.
"""
from __future__ import annotations

import math
import operator
from dataclasses import dataclass

import numpy as np

from data_tools import InputError
from data_tools.memory import check_memory
from data_tools.volume import text_or_flag, three_numbers


def up_across(f):
    """The axis least along the direction ``f``, as floats: an up a view along ``f`` can take
    (of axes as little along it, +z, then +y: a view down z gets y up)."""
    along = np.abs(np.asarray(f, dtype=np.float64))
    up = [0.0, 0.0, 0.0]
    up[min((2, 1, 0), key=lambda a: along[a])] = 1.0
    return up


@dataclass(frozen=True)
class Camera:
    """A pinhole or parallel camera.

    Parameters
    ----------
    eye, look_at, up : (x, y, z), default (0, 0, 1), (0, 0, 0), (0, 1, 0)
        Position, point looked at, and the up hint (need not be orthogonal
        to the view direction, but must not be parallel to it). The defaults
        are OpenGL's: down -z with +y up. `framing`, scene files and the
        command line take +z up instead (``--up``'s default: (0, 0, 1), or
        (0, 1, 0) for a view along z), so a camera given an eye and a point
        to look at, and no ``up``, is turned from the command line's with
        the same two, and one looking along y needs an ``up``.
    fov : float, default 30
        Vertical field of view in degrees, in (0, 180); perspective only.
    parallel_scale : float or None
        Half the view height in world units; when given, the projection is
        parallel and ``fov`` is ignored.

    Raises
    ------
    InputError
        ``eye`` equal to ``look_at``, ``up`` parallel to the view direction,
        a field of view outside (0, 180), a non-positive parallel scale.
    """

    eye: tuple = (0.0, 0.0, 1.0)
    look_at: tuple = (0.0, 0.0, 0.0)
    up: tuple = (0.0, 1.0, 0.0)
    fov: float = 30.0
    parallel_scale: float | None = None

    def __post_init__(self):
        for name in ("eye", "look_at", "up"):
            v = three_numbers(getattr(self, name))
            if v is None or len(v) != 3 or not np.isfinite(v).all():
                raise InputError(f"camera {name} must be three finite numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)
        with np.errstate(over="ignore"):
            view = np.subtract(self.look_at, self.eye)
        if not np.isfinite(view).all():
            raise InputError(f"camera eye {self.eye} and look-at {self.look_at} are too far apart: "
                             "their difference overflows")
        f = unit_vector(view)
        if f is None:
            raise InputError(f"camera eye equals look-at {self.look_at}: no view direction")
        up = unit_vector(self.up)
        if up is None:
            raise InputError(f"camera up {self.up} is zero: give a direction")
        if np.linalg.norm(np.cross(f, up)) < 1e-9:
            raise InputError(f"camera up {self.up} is parallel to the view direction "
                             f"{tuple(round(float(c), 6) for c in f)}: give one across it, such as "
                             f"{tuple(up_across(f))}")
        if self.parallel_scale is None:
            check_fov(self.fov)
            object.__setattr__(self, "fov", float(self.fov))
        else:
            try:
                check_fov(self.fov)
            except InputError:
                # Ignored by a parallel projection, whatever was given: a number it can hold.
                object.__setattr__(self, "fov", 30.0)
            object.__setattr__(self, "fov", float(self.fov))
            object.__setattr__(self, "parallel_scale", check_parallel_scale(self.parallel_scale))

    @property
    def parallel(self) -> bool:
        return self.parallel_scale is not None

    def basis(self):
        """Orthonormal ``(f, r, u)``: forward, right, up, each shape (3,), read-only.

        Computed once per camera (it is frozen): a frame asked for it five
        times, at 40 us each in NumPy's small-array calls.
        """
        cached = self.__dict__.get("_basis")
        if cached is None:
            f = unit_vector(np.subtract(self.look_at, self.eye))
            r = unit_vector(np.cross(f, unit_vector(self.up)))
            u = np.cross(r, f)
            for v in (f, r, u):
                v.setflags(write=False)
            cached = self.__dict__["_basis"] = (f, r, u)
        return cached

    def settings(self):
        """The camera as `Camera` takes it (and as the command line's view flags give it), for a
        render's stats: a view chosen by default can be given again, or moved from."""
        view = {"eye": list(self.eye), "look_at": list(self.look_at), "up": list(self.up)}
        if self.parallel:
            view["parallel_scale"] = self.parallel_scale
        else:
            view["fov"] = self.fov
        return view

    def as_array(self):
        """The kernels' camera: ``[eye, f, r, u, tan(fov/2), parallel_scale, parallel]`` (a new array)."""
        cached = self.__dict__.get("_array")
        if cached is None:
            f, r, u = self.basis()
            th = math.tan(math.radians(self.fov) / 2.0)
            ps = self.parallel_scale or 0.0
            cached = self.__dict__["_array"] = np.concatenate(
                [self.eye, f, r, u, [th, ps, 1.0 if self.parallel else 0.0]]).astype(np.float64)
        return cached.copy()

    def rays(self, width, height, rows=None):
        """World rays through every pixel centre: origins, directions, each ``(H, W, 3)``.

        Vectorized NumPy version of `raycast.rays.camera_ray`, for the Parker bench and
        tests. ``rows=(y0, y1)``: only those rows, ``(y1 - y0, W, 3)``.
        """
        width, height = _image_size(width, height)
        f, r, u = self.basis()
        y0, y1 = (0, height) if rows is None else rows
        # Twelve float64 values a pixel at the peak: the grid, the offsets, origins and directions.
        check_memory(12 * 8 * width * max(y1 - y0, 0), f"camera rays for {width}x{y1 - y0} pixels")
        x = np.arange(width) + 0.5
        y = np.arange(y0, y1) + 0.5
        sx = (2.0 * x / width - 1.0) * (width / height)
        sy = 1.0 - 2.0 * y / height
        sx, sy = np.meshgrid(sx, sy)
        off = sx[..., None] * r + sy[..., None] * u
        if self.parallel:
            o = np.asarray(self.eye) + self.parallel_scale * off
            d = np.broadcast_to(f, o.shape).copy()
        else:
            d = f + math.tan(math.radians(self.fov) / 2.0) * off
            d /= np.linalg.norm(d, axis=-1, keepdims=True)
            o = np.broadcast_to(np.asarray(self.eye, dtype=np.float64), d.shape).copy()
        return o, d

    def view_matrix(self):
        """World -> eye 4x4 (OpenGL convention: the camera looks down -z).

        For OpenGL code of one's own; PARC's passes place their faces with the
        same basis through per-pixel forms (`parc.raster.set_view_uniforms`).
        """
        f, r, u = self.basis()
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = r, u, -f
        m[:3, 3] = -m[:3, :3] @ np.asarray(self.eye)
        return m

    def projection_matrix(self, width, height, near, far):
        """Eye -> clip 4x4 for an image of ``width x height`` and depth range [near, far]."""
        width, height = _image_size(width, height)
        try:
            near, far = float(near), float(far)
        except (TypeError, ValueError, OverflowError):
            near = far = math.nan
        # A perspective divides by the distances themselves; a parallel view only by their difference.
        if not (math.isfinite(near) and math.isfinite(far) and near < far and (self.parallel or near > 0.0)):
            raise InputError(f"depth range must be finite numbers near < far{'' if self.parallel else ', near > 0'}, "
                             f"got near {near}, far {far}")
        a = width / height
        m = np.zeros((4, 4))
        if self.parallel:
            h = self.parallel_scale
            m[0, 0] = 1.0 / (h * a)
            m[1, 1] = 1.0 / h
            m[2, 2] = -2.0 / (far - near)
            m[2, 3] = -(far + near) / (far - near)
            m[3, 3] = 1.0
        else:
            th = math.tan(math.radians(self.fov) / 2.0)
            m[0, 0] = 1.0 / (th * a)
            m[1, 1] = 1.0 / th
            m[2, 2] = -(far + near) / (far - near)
            m[2, 3] = -2.0 * far * near / (far - near)
            m[3, 2] = -1.0
        return m

    @classmethod
    def framing(cls, lo, hi, *, fov=30.0, azimuth=35.0, elevation=25.0, up=(0.0, 0.0, 1.0),
                parallel=False, zoom=1.0, aspect=1.0):
        """A three-quarter view that frames the box ``[lo, hi]`` whole.

        The eye looks at the box centre from ``azimuth`` degrees around ``up``
        (0 = from the front: -y with +z up) and ``elevation`` degrees above the
        plane across ``up`` (`_view_from`), far
        enough that the bounding sphere fits the field of view ``fov``
        (vertical) across an image ``aspect`` = width / height wide: a
        tall image fits it across. ``parallel=True`` gives a parallel
        projection whose view holds the sphere instead. ``zoom`` above 1
        frames a sphere that many times smaller (closer in; a parallel view
        only magnifies), below 1 a larger one.
        """
        try:
            corners = three_numbers(lo), three_numbers(hi)
            if None in corners or any(text_or_flag(x) for x in (zoom, azimuth, elevation, aspect)):
                raise TypeError
            lo, hi = (np.array(c, dtype=np.float64) for c in corners)
            zoom, azimuth, elevation = float(zoom), float(azimuth), float(elevation)
            aspect = float(aspect)
        except (TypeError, ValueError, OverflowError):
            raise InputError("framing needs two corners of three numbers and numeric zoom, azimuth, "
                             "elevation and aspect") from None
        if not (math.isfinite(aspect) and aspect > 0.0):
            raise InputError(f"aspect (width / height) must be positive, got {aspect}")
        if lo.shape != (3,) or hi.shape != (3,) or not (np.isfinite(lo).all() and np.isfinite(hi).all()):
            raise InputError(f"framing needs two corners of three finite numbers, got {lo} and {hi}")
        if not (math.isfinite(zoom) and zoom > 0.0):
            raise InputError(f"zoom must be positive, got {zoom}")
        if not (math.isfinite(azimuth) and math.isfinite(elevation)):
            raise InputError(f"azimuth and elevation must be finite angles in degrees, got {azimuth} and {elevation}")
        if not isinstance(parallel, (bool, np.bool_)):
            raise InputError(f"parallel must be True or False, got {parallel!r}")
        c = 0.5 * lo + 0.5 * hi
        # hypot, not the norm's dot product: corners near float64's range overflowed it.
        whole = 0.5 * math.hypot(*(float(h) - float(l) for l, h in zip(lo, hi)))
        if whole == 0.0:
            raise InputError(f"framing needs a box with some size; its corners are one point {tuple(lo.tolist())}")
        radius = whole / zoom
        u = three_numbers(up)
        u = unit_vector(u) if u is not None and len(u) == 3 else None     # else Camera refuses it below
        back = _view_from(azimuth, elevation, np.array([0.0, 0.0, 1.0]) if u is None else u)
        if u is not None and np.linalg.norm(np.cross(back, u)) < 1e-9:
            raise InputError(f"an elevation of {elevation:g} degrees looks along up {tuple(up)}: "
                             f"give another elevation or up")
        if parallel:
            # The eye stays outside the whole box: in a parallel view, zoom only magnifies.
            return cls(eye=tuple(c + back * max(radius, whole) * 3.0), look_at=tuple(c), up=up,
                       parallel_scale=radius * 1.02 / min(1.0, aspect))
        check_fov(fov)
        # The narrower of the vertical half-angle and the horizontal one (a tall image).
        half = math.sin(min(math.radians(fov) / 2.0, math.atan(aspect * math.tan(math.radians(fov) / 2.0))))
        if not half >= 2.0 ** -32:
            # The eye would stand over 2^32 box sizes away: float64's resolution at the eye
            # is then over 2^-20 of the box size, and rays through it are ill defined.
            raise InputError(f"a field of view of {fov:g} degrees is too narrow to frame the volume "
                             f"(the eye would stand over 2^32 volume sizes away)")
        dist = radius / half * 1.02
        if not math.isfinite(float(np.max(np.abs(c + back * dist)))):
            raise InputError(f"cannot frame the volume with a {fov:g}-degree field of view: "
                             "the eye would lie beyond float64's range")
        if np.array_equal(c + back * dist, c):
            raise InputError(f"a zoom of {zoom:g} brings the eye onto the point it looks at; give a smaller zoom")
        return cls(eye=tuple(c + back * dist), look_at=tuple(c), up=up, fov=fov)


def _image_size(width, height):
    """``(width, height)`` as ints, refused unless whole numbers from 1."""
    try:
        w, h = operator.index(width), operator.index(height)
    except TypeError:
        w = h = 0
    # Bounded as OpenGL and the kernels' int32 pixel indices are (10**400 / 1 overflows a float).
    if (isinstance(width, (bool, np.bool_)) or isinstance(height, (bool, np.bool_))
            or not (1 <= w < 2 ** 31 and 1 <= h < 2 ** 31)):
        raise InputError(f"image size must be two positive integers, got {width!r:.40} x {height!r:.40}")
    return w, h


def _view_from(azimuth, elevation, up):
    """Unit vector from the look-at point towards the eye: ``elevation`` degrees above the plane
    across ``up`` (towards it), ``azimuth`` degrees round ``up`` from the front.

    The front is -y, as seen with +z up (x to the right), or with another up the
    nearest direction to -y across it (+z where up lies along y): with up
    (0, 0, 1) the eye stands at ``(cos el sin az, -cos el cos az, sin el)``,
    and with up (0, 0, -1) the same view of a volume stored upside down,
    from above its top, not below it.
    """
    az, el = math.radians(azimuth), math.radians(elevation)
    # -y less its part along up, -y + up_y up, written without the cancellation in its y
    # (1 - up_y^2 = up_x^2 + up_z^2): near up along y the front turns with up's tilt however
    # small it is. Only with up exactly along y is there none, and +z is taken.
    front = unit_vector([up[1] * up[0], -(up[0] * up[0] + up[2] * up[2]), up[1] * up[2]])
    if front is None:
        front = np.array([0.0, 0.0, 1.0])
    side = np.cross(up, front)
    return math.cos(el) * (math.cos(az) * front + math.sin(az) * side) + math.sin(el) * up


def check_fov(fov, what="field of view"):
    """Refuse a field of view (degrees) that is not a number strictly between 0 and 180;
    ``what`` names it in the message (``--fov`` on the command line)."""
    try:
        ok = not text_or_flag(fov) and 0.0 < float(fov) < 180.0
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        raise InputError(f"{what} must be a number of degrees between 0 and 180, got {fov!r}")


def check_parallel_scale(scale, what="parallel scale"):
    """``scale`` as a float, refused unless a positive, finite number; ``what`` as for `check_fov`."""
    try:
        value = math.nan if text_or_flag(scale) else float(scale)
    except (TypeError, ValueError, OverflowError):
        value = math.nan
    if not (math.isfinite(value) and value > 0.0):
        raise InputError(f"{what} must be positive and finite, got {scale!r}")
    return value


def unit_vector(v):
    """``v`` scaled to length 1, or None if it is zero; huge and tiny vectors (1e300, 1e-300)
    are scaled towards 1 first, so that they neither overflow nor vanish, by a power of two,
    so that the direction is that of ``v`` times any power of two, to the last bit."""
    v = np.asarray(v, dtype=np.float64)
    m = float(np.max(np.abs(v)))
    if m == 0.0 or not math.isfinite(m):
        return None
    if not 1e-150 < m < 1e150:
        v = np.ldexp(v, -math.frexp(m)[1])
    return v / np.linalg.norm(v)
