"""What to show: volumes with their rendering mode, the camera, lights, image size."""
from __future__ import annotations

import math
import os
import sys
import warnings
from dataclasses import dataclass, field

import numpy as np

from data_tools import InputError, Volume
from data_tools.info import exact_text
from data_tools.volume import settled, text_or_flag, three_numbers

from .camera import Camera, unit_vector

#: Default surface colour: a warm off-white that reads as tissue or bone.
DEFAULT_SURFACE = (0.93, 0.86, 0.74)
#: ambient, diffuse, specular, shininess.
DEFAULT_MATERIAL = (0.12, 0.78, 0.25, 40.0)
#: The largest material weight, shininess and light intensity taken. A lit colour is clipped to 1
#: long before; beyond, the shading's products overflow (weights and intensities of 1e200 made
#: an infinite term, and times a colour channel of 0 a NaN pixel).
MAX_SHADING_FACTOR = 1e6


@settled
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
            if text_or_flag(self.value):
                raise TypeError
            self.value = float(self.value)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"isovalue must be a number, got {self.value!r}") from None
        if not math.isfinite(self.value):
            raise InputError(f"isovalue must be finite, got {self.value}")
        lo, hi = self.volume.value_range()
        if not lo <= self.value <= hi:
            raise InputError(f"isovalue {exact_text(self.value)} is outside the data range "
                             f"[{exact_text(lo)}, {exact_text(hi)}] of {self.volume.name}")
        self.color = _unit_triple(self.color, "surface colour")
        self.material = _material(self.material)


class ShowsNothingWarning(UserWarning):
    """Part of a scene adds nothing to the image: a translucent volume whose transfer function is
    transparent over all of its data, lights in a scene with no isosurface or shaded
    translucent volume, or shadows in one with neither (`parc render` says so in a note)."""


#: What a scene of shadows and no lights but the headlight is told (the command line names its flags).
HEADLIGHT_SHADOWS = "shadows with only the headlight show nothing (the light sits at the eye)"

#: The composite mode's early-termination opacity, unless another is given.
DEFAULT_THRESHOLD = 0.99


@settled
@dataclass(eq=False)
class Translucent:
    """A volume shown through a transfer function: composite, maximum or average intensity.

    Parameters
    ----------
    volume : Volume
    tf : TransferFunction or str
        A transfer function, a preset name or a file (see
        `parc.transfer.load_transfer_function`). A name is made into a function for this
        volume's range and mode (its ``made_from`` says so), which is made again from the
        name for another volume or mode (``dataclasses.replace(tr, mode="mip")``), and so
        is ``tr.tf`` given to a Translucent of another volume (it takes that volume's own
        range; for the same mapping, pass ``load_transfer_function(name, data_range=...)``);
        any other TransferFunction is kept as it is.
    mode : {"composite", "mip", "average"}, default "composite"
    step : float or None
        World distance between samples; default a quarter of the smallest
        spacing (Sobierajski & Avila 1995, §6, took 0.25 world units, on
        volumes of spacing near 1), worked out again for another
        volume (``dataclasses.replace(tr, volume=finer)``). Refused below 1e-4
        of the smallest spacing, and where it would put more than
        `MAX_RAY_SAMPLES` (1e8) samples on a ray across the volume's box
        diagonal: the default too, for a spacing tiny against the volume's extent.
    threshold : float, default 0.99
        Early ray termination once the accumulated opacity reaches it;
        composite only (another value is refused with mip and average,
        which take every sample).
    shade : bool, default False
        Shade composite samples with the gradient (Blinn-Phong, as an
        isosurface hit is: lit by the scene's lights, shadowed when the
        scene has shadows, or by a headlight where it has none); refused
        with mip and average, which do not shade.
    material : (ambient, diffuse, specular, shininess)

    Raises
    ------
    InputError
        An unknown mode, a step or threshold out of range, a bad transfer function.

    Warns
    -----
    ShowsNothingWarning
        The transfer function is transparent over the volume's whole data range.
    """

    volume: Volume
    tf: object = "greyscale"
    mode: str = "composite"
    step: float | None = None
    threshold: float = DEFAULT_THRESHOLD
    shade: bool = False
    material: tuple = DEFAULT_MATERIAL

    def __post_init__(self):
        from .transfer import TransferFunction, load_for_volume, reference_step
        from .transfer.presets import check_mode
        if not isinstance(self.volume, Volume):
            raise InputError(f"Translucent needs a Volume, got {type(self.volume).__name__}")
        if not isinstance(self.tf, TransferFunction):
            if not isinstance(self.tf, (str, os.PathLike)):
                raise InputError(f"a transfer function must be a TransferFunction, a preset name or a file, "
                                 f"got {type(self.tf).__name__}")
        check_mode(self.mode)
        made_from = self.tf.made_from if isinstance(self.tf, TransferFunction) else None
        if made_from is not None and made_from[1:] != (self.volume.value_range(), self.mode):
            # Made from a name for another volume's range or another mode (`dataclasses.replace(tr,
            # mode="mip")`): made again from that name, as `Translucent(vol, name, mode=...)` makes it.
            self.tf = made_from[0]
        if not isinstance(self.tf, TransferFunction):
            self.tf = load_for_volume(self.tf, self.volume, self.mode)
        default = self.step is None or isinstance(self.step, _SpacingStep)
        step = reference_step(self.volume.spacing) if default else self.step
        step = check_step(step, self.volume, "the default step" if default else "step")
        self.step = _SpacingStep(step) if default else step
        self.threshold = check_threshold(self.threshold)
        if self.mode != "composite":
            # The default given back in float32 (a value read from an array) is still the default.
            if np.float32(self.threshold) != np.float32(DEFAULT_THRESHOLD):
                raise InputError(f"threshold applies to mode composite; {self.mode} does not stop rays early")
            self.threshold = DEFAULT_THRESHOLD
        self.shade = _flag(self.shade, "shade")
        if self.shade and self.mode != "composite":
            raise InputError(f"shade applies to mode composite; {self.mode} does not shade samples")
        self.material = _material(self.material)
        lo, hi = self.volume.value_range()
        if not self.tf.nonzero_in(lo, hi):
            # Legal (another volume of the scene may show), but a blank image is no way to learn it.
            # Said at the caller's line: past __post_init__, the dataclass's __init__, `settled`'s,
            # and any of PARC's or dataclasses' own (load_scene, dataclasses.replace, step_sweep).
            hint = ""
            if self.tf.source.startswith("preset ct_"):
                # A newcomer's likeliest mistake: a CT preset on 8-bit or MRI data.
                hint = ("; the ct_ presets are for CThead-like CT values (skin 400-1000, bone 1200 and up):"
                        " greyscale or viridis span any data range")
            warnings.warn(f"{self.tf.title} is transparent over the data range [{exact_text(lo)}, "
                          f"{exact_text(hi)}] of {self.volume.name}: that volume shows nothing{hint}",
                          ShowsNothingWarning, stacklevel=_callers_level())


def _callers_level():
    """The ``stacklevel`` that, for a warning given by this function's caller, names the first
    line outside PARC, data_tools and dataclasses (a user's call, however deep inside it is made)."""
    frame, level = sys._getframe(1), 1
    while frame.f_back is not None and (frame.f_globals.get("__name__", "").partition(".")[0]
                                        in ("parc", "data_tools", "dataclasses")):
        frame, level = frame.f_back, level + 1
    return level


#: Largest coordinate of a point light's position.
MAX_LIGHT_DISTANCE = 1e150


@settled
@dataclass(eq=False)
class PointLight:
    """A light at a point, shining equally in every direction (no fall-off with distance).

    Parameters
    ----------
    position : (x, y, z)
        World position; may lie inside a volume, or on a surface (its shadow
        rays stop just short of it); coordinates up to 1e150.
    color : (r, g, b) in [0, 1]
    intensity : float, 0 to `MAX_SHADING_FACTOR` (1e6)
        Scales the colour.
    """

    position: tuple
    color: tuple = (1.0, 1.0, 1.0)
    intensity: float = 1.0

    def __post_init__(self):
        self.position = _finite_triple(self.position, "light position")
        if max(abs(c) for c in self.position) > MAX_LIGHT_DISTANCE:
            # Its direction's length would overflow in the shading; from there it is the sun.
            # Said in every caller's words: a DirectionalLight, --sun, a scene file's direction.
            raise InputError(f"light position {self.position} is beyond {MAX_LIGHT_DISTANCE:g}; a light that "
                             "far is directional: give its direction (DirectionalLight, --sun DX,DY,DZ, or a "
                             "scene file's direction) instead of a position")
        self.color = _unit_triple(self.color, "light colour")
        self.intensity = _non_negative(self.intensity, "light intensity", MAX_SHADING_FACTOR)

    @property
    def radiance(self):
        return tuple(c * self.intensity for c in self.color)


@settled
@dataclass(eq=False)
class DirectionalLight:
    """A light infinitely far away (the sun): parallel rays travelling along ``direction``.

    Parameters
    ----------
    direction : (dx, dy, dz)
        The direction the light travels in (from the light into the scene);
        normalized here, must not be zero.
    color : (r, g, b) in [0, 1]
    intensity : float, 0 to `MAX_SHADING_FACTOR` (1e6)
    """

    direction: tuple
    color: tuple = (1.0, 1.0, 1.0)
    intensity: float = 1.0

    def __post_init__(self):
        d = unit_vector(_finite_triple(self.direction, "light direction"))
        if d is None:
            raise InputError(f"light direction must not be zero, got {self.direction!r}")
        self.direction = tuple(float(c) for c in d)
        self.color = _unit_triple(self.color, "light colour")
        self.intensity = _non_negative(self.intensity, "light intensity", MAX_SHADING_FACTOR)

    @property
    def radiance(self):
        return tuple(c * self.intensity for c in self.color)


LIGHTS = (PointLight, DirectionalLight)


@settled
@dataclass(eq=False)
class Scene:
    """A camera, an image size and what to show.

    Parameters
    ----------
    camera : Camera
    size : (width, height)
        Image size in pixels, both at least 1.
    volumes : list of Isosurface or Translucent
        At least one (required, though it has a default); kept as a tuple. At most
        `raycast.merged.MAX_MERGED` (32) of them translucent in composite mode.
    lights : list of PointLight or DirectionalLight
        Kept as a tuple.
        Light sources for isosurfaces and shaded translucent samples (in a scene with
        neither they change nothing, which warns `ShowsNothingWarning`);
        empty means a headlight at the eye, shining along each pixel's ray (in a parallel
        view, along the view direction, as `DirectionalLight` would, not `PointLight(eye)`).
    background : (r, g, b), (r, g, b, a) or None
        Composited under the image, each component in [0, 1]; three are
        opaque (a = 1). The colour is as seen, not yet multiplied by alpha
        (the image's premultiplied pixels hold ``(a r, a g, a b, a)``).
        None leaves it transparent.
    shadows : bool, default False
        Cast shadow rays from every isosurface hit and every shaded
        translucent sample (``shade=True``) to every light: blocked by any
        isosurface, attenuated by translucent volumes on the way. In a
        scene with neither, or lit by the headlight alone, this changes
        nothing, which warns `ShowsNothingWarning`.
    """

    camera: Camera
    size: tuple = (512, 512)
    volumes: list = field(default_factory=list)
    lights: list = field(default_factory=list)
    background: tuple | None = None
    shadows: bool = False

    def __post_init__(self):
        if not isinstance(self.camera, Camera):
            raise InputError(f"Scene needs a Camera, got {type(self.camera).__name__}")
        try:
            # bytes iterate as integers: b"\x08\x08" is no size.
            w, h = (int(v) for v in self.size)
            ok = (w, h) == tuple(self.size) and not any(text_or_flag(v) for v in (self.size, *self.size))
        except (TypeError, ValueError, OverflowError, np.ma.MAError):      # MAError: a masked value
            ok = False
        if not ok or w < 1 or h < 1:
            raise InputError(f"image size must be two positive integers, got {self.size!r}")
        self.size = (w, h)
        self.volumes = _sequence(self.volumes, "volumes")
        if not self.volumes:
            raise InputError("the scene shows nothing: give at least one volume")
        if self.background is not None:
            bg = three_numbers(self.background)
            if bg is None or len(bg) not in (3, 4):
                raise InputError(f"background must be 3 or 4 numbers in [0, 1], got {self.background!r}")
            if not all(0.0 <= c <= 1.0 for c in bg):
                raise InputError(f"background components must be in [0, 1], got {self.background!r}")
            self.background = bg + ((1.0,) if len(bg) == 3 else ())
        for v in self.volumes:
            if not isinstance(v, (Isosurface, Translucent)):
                raise InputError(f"a scene shows Isosurface or Translucent volumes, got {type(v).__name__}")
        merged = sum(isinstance(v, Translucent) and v.mode == "composite" for v in self.volumes)
        if merged > 1:
            from raycast.merged import MAX_MERGED
            if merged > MAX_MERGED:
                raise InputError(f"a scene composites at most {MAX_MERGED} translucent volumes together (their "
                                 f"samples merge along each ray); this one has {merged} in composite mode")
        check_eye_resolves(self.camera, [v.volume for v in self.volumes],
                           [v.volume for v in self.volumes if isinstance(v, Isosurface)])
        self.lights = _sequence(self.lights, "lights")
        for light in self.lights:
            if not isinstance(light, LIGHTS):
                raise InputError(f"a light must be a PointLight or a DirectionalLight, got {type(light).__name__}")
        self.shadows = _flag(self.shadows, "shadows")
        # Lights shine on, and shadows fall on, isosurface hits and shaded translucent samples.
        # Given where they change nothing, they are legal (the contract's scenes give lights to
        # either kind of volume) but said.
        lit = any(isinstance(v, Isosurface) or (v.shade and v.mode == "composite") for v in self.volumes)
        for given, what in ((self.lights, "lights shine on"), (self.shadows, "shadows fall on")):
            if given and not lit:
                warnings.warn(f"{what} isosurfaces and shaded translucent volumes (shade=True, --shade, a scene "
                              "file's shade = true), and this scene has neither: the image is the same without them",
                              ShowsNothingWarning, stacklevel=_callers_level())
        if self.shadows and not self.lights and lit:
            warnings.warn(f"{HEADLIGHT_SHADOWS}: give the scene lights", ShowsNothingWarning,
                          stacklevel=_callers_level())

    @property
    def width(self):
        return self.size[0]

    @property
    def height(self):
        return self.size[1]


def describe_volume(vis):
    """A volume of a scene (an `Isosurface` or a `Translucent`), as a render's stats give it."""
    vol = vis.volume
    d = {"volume": vol.name, "dims": list(vol.dims), "dtype": str(vol.dtype),
         "spacing": list(vol.spacing), "origin": list(vol.origin)}
    if isinstance(vis, Isosurface):
        d.update({"isovalue": vis.value, "color": list(vis.color), "material": list(vis.material)})
    else:
        d.update({"mode": vis.mode, "step": vis.step, "transfer_function": vis.tf.name or "custom"})
        if vis.mode == "composite":         # the others take every sample, unshaded: neither applies
            d["threshold"] = vis.threshold
            d["shade"] = vis.shade
            if vis.shade:
                d["material"] = list(vis.material)
    return d


def describe_view(scene):
    """What a render's stats give of a scene beside its volumes: size, camera, and the background,
    lights and shadows where it has them (two renders that differ in any of them must not read
    alike)."""
    d = {"size": list(scene.size), "camera": scene.camera.settings()}
    if scene.background is not None:
        d["background"] = list(scene.background)
    if scene.lights or scene.shadows:
        d["lights"] = [{**({"position": list(light.position)} if isinstance(light, PointLight)
                           else {"direction": list(light.direction)}),
                        "color": list(light.color), "intensity": light.intensity} for light in scene.lights]
        d["shadows"] = scene.shadows
    return d


class _SpacingStep(float):
    """A default step (a quarter of the smallest spacing), marked as such: a Translucent made
    again with it for another volume (``dataclasses.replace``) takes that volume's default."""
    __slots__ = ()


#: The most lattice points a translucent volume's step may put on a ray across its box.
MAX_RAY_SAMPLES = 1e8


def check_step(step, volume, what="step"):
    """``step`` as a float, refused unless a positive, finite distance of at least 1e-4 of the
    ``volume``'s smallest spacing and of at most `MAX_RAY_SAMPLES` steps across its box's
    diagonal; ``what`` names it in messages (``--step`` on the command line)."""
    try:
        if text_or_flag(step):
            raise TypeError
        value = float(step)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{what} must be a number, got {step!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise InputError(f"{what} must be a positive, finite distance, got {value}")
    spacing = volume.spacing
    if value < 1e-4 * min(spacing):
        raise InputError(f"{what} {value:g} is below 1e-4 of the smallest spacing ({min(spacing):g}); "
                         "that is too many samples per ray")
    across = math.dist(*volume.bounds)
    if across / value > MAX_RAY_SAMPLES:
        # The rule above bounds samples per cell: spacings (1e-6, 1, 1) and the default step put
        # 1e7 on a ray crossing the unit cells, and past 2^63 a lattice's count wraps.
        # The smallest step allowed, rounded up at its third digit so that it passes itself.
        least = across / MAX_RAY_SAMPLES
        unit = 10.0 ** (math.floor(math.log10(least)) - 2)
        raise InputError(f"{what} {value:g} puts {across / value:.2g} samples on a ray across the volume's "
                         f"diagonal ({across:g}), more than {MAX_RAY_SAMPLES:.0e}: give a step of at least "
                         f"{math.ceil(least / unit) * unit:.3g}")
    return value


def check_threshold(threshold, what="opacity threshold"):
    """``threshold`` as a float, refused unless an opacity in (0, 1]; ``what`` as for `check_step`."""
    try:
        value = math.nan if text_or_flag(threshold) else float(threshold)
    except (TypeError, ValueError, OverflowError):
        value = math.nan
    if not 0.0 < value <= 1.0:
        raise InputError(f"{what} must be an opacity in (0, 1], got {threshold!r}")
    return value


#: How many times the volumes' size the eye's coordinates may reach: as `Camera.framing`'s
#: narrowest field of view, float64's resolution at the eye stays below 2^-20 of the volumes' size.
EYE_RANGE = 2.0 ** 32
#: ... and how many times each volume's thinnest extent: beyond, float64 places at most 256
#: rays' worth of points across it, and a volume of spacing 1e-16 along x lost 2/3 of its hits.
THIN_RANGE = 2.0 ** 44


def check_eye_resolves(camera, volumes, surfaces=()):
    """Refuse an eye so far out that float64 cannot place rays across ``volumes`` (the scene's
    `Volume`s): a parallel view's ray origins, rounded to the eye's resolution (16384 units
    at 1e20), all missed, and the picture came out empty without a word. ``surfaces``, the
    volumes of isosurfaces, must also be thick enough along each axis for rays to find their
    cells: at a spacing of 1e-16 along x, two thirds of a surface's hits were lost."""
    lo = np.min([v.bounds[0] for v in volumes], axis=0)
    hi = np.max([v.bounds[1] for v in volumes], axis=0)
    size = float(np.linalg.norm(np.subtract(hi, lo)))
    far = float(np.max(np.abs(camera.eye)))
    if not far <= EYE_RANGE * size:
        raise InputError(f"the eye {tuple(float(c) for c in camera.eye)} is over 2^32 times the volumes' size "
                         f"({size:.6g}) from the origin, where float64 cannot place rays across them; bring the "
                         "eye closer" + (" (a parallel view's picture does not change with the eye's distance)"
                                         if camera.parallel else ": give it nearer, or frame with a wider field of "
                                                                 "view or a larger zoom"))
    for v in surfaces:
        thin = min(v.extent)
        axis = "xyz"[int(np.argmin(v.extent))]
        reach = max(far, float(np.max(np.abs(v.bounds))))
        if not reach <= THIN_RANGE * thin:
            # Seen from a few times its own size (a default eye), is it the eye that is too far?
            own = 16.0 * max(float(np.max(np.abs(v.bounds))), max(v.extent))
            fix = "bring the eye closer" if own <= THIN_RANGE * thin else f"check its spacing along {axis}"
            raise InputError(f"a volume {thin:.6g} thick along {axis} is over 2^44 times thinner than the scene's "
                             f"coordinates reach ({reach:.6g}, the eye's or its own), where float64 cannot place "
                             f"rays across it (most of its surface would be lost); {fix}")


def _finite_triple(v, what):
    t = three_numbers(v)
    if t is None or len(t) != 3 or not np.isfinite(t).all():
        raise InputError(f"{what} must be three finite numbers, got {v!r}")
    return t


def _non_negative(v, what, top=math.inf):
    try:
        x = math.nan if text_or_flag(v) else float(v)
    except (TypeError, ValueError, OverflowError):
        x = math.nan
    if not (math.isfinite(x) and x >= 0.0):
        raise InputError(f"{what} must be a finite number >= 0, got {v!r}")
    if x > top:
        raise InputError(f"{what} must be at most {top:g}, got {x:g}")
    return x


def _unit_triple(v, what):
    t = three_numbers(v)
    if t is None or len(t) != 3 or not all(0.0 <= c <= 1.0 for c in t):
        raise InputError(f"{what} must be three numbers in [0, 1], got {v!r}")
    return t


def _flag(v, what):
    """A yes/no setting: a bool (or NumPy's, or 0/1); "false" is not False, so strings are refused."""
    if isinstance(v, (bool, np.bool_)) or (isinstance(v, (int, np.integer)) and v in (0, 1)):
        return bool(v)
    raise InputError(f"{what} must be True or False, got {v!r}")


def _material(v):
    """``(ambient, diffuse, specular, shininess)``: the weights from 0 and shininess above 0, each
    up to `MAX_SHADING_FACTOR`."""
    a = three_numbers(v)
    if (a is None or len(a) != 4 or not all(math.isfinite(c) and c <= MAX_SHADING_FACTOR for c in a)
            or min(a[:3]) < 0 or not a[3] > 0):
        raise InputError(f"material must be (ambient, diffuse, specular, shininess): numbers, the weights "
                         f"from 0 and shininess above 0, each at most {MAX_SHADING_FACTOR:g}; got {v!r}")
    return a


def _sequence(v, what):
    """A tuple from a list or tuple (fixed, as the scene is); a lone volume or light (or None) is
    refused, not iterated."""
    if not isinstance(v, (list, tuple)):
        raise InputError(f"Scene {what} must be a list, got {type(v).__name__}")
    return tuple(v)
