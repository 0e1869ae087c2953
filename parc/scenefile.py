"""Scene files: a whole scene (volumes, camera, lights, image size) in one TOML file.

``parc render scene.toml -o out.png`` and ``parc compare scene.toml`` read
them; in Python, ``parc.load_scene("scene.toml")`` returns the `Scene`.

Schema
------
Every key is optional unless marked required; each ``[[volume]]`` needs
one of ``file`` and ``synthetic``, and one of ``iso`` and ``tf``::

    size = [600, 600]               # image width, height (default 512 x 512)
    background = [0, 0, 0]          # r, g, b (or r, g, b, a) in [0, 1]; default transparent
    shadows = true                  # shadow rays towards every light (default false)

    [camera]                        # the whole table is optional
    eye = [120, -90, 80]            # default: a three-quarter view framing all volumes
    look_at = [32, 32, 32]          # default: the centre of all volumes' boxes
    up = [0, 0, 1]                  # default +z (+y when +z is along the view)
    fov = 30                        # vertical field of view, degrees (default 30)
    # parallel = 40                 # instead of fov: parallel projection, half the view height
    # zoom = 1.5                    # without eye: the default eye that much closer (default 1)

    [[volume]]                      # required, one table per volume, drawn together
    file = "neuron.nrrd"            # relative to this file's folder; or
    # synthetic = "sphere"          #   a synthetic volume (see `parc make --help`),
    # size = 32                     #   with its samples per axis (one or three integers)
    # seed = 1                      #   and seed (random volumes only)
    # shape = [64, 64, 32]          # headerless .raw/.bin/.dat files: samples along x, y, z,
    # dtype = "uint8"               #   sample type, byte_order = "little"|"big", offset (bytes)
    spacing = [1, 1, 2]             # placement: replaces the file's spacing and
    origin = [0, 0, 0]              #   origin (world position of the first sample)
    iso = 80                        # an opaque isosurface at this value, with
    color = [0.9, 0.8, 0.7]         #   its colour in [0, 1]
    material = [0.12, 0.78, 0.25, 40]   # ambient, diffuse, specular, shininess

    [[volume]]
    file = "ct.nrrd"
    tf = "ct_skin_bone"             # instead of iso: a translucent volume through a transfer
                                    #   function, a preset or a .toml/.json file (relative here)
    mode = "composite"              # composite | mip | average
    step = 0.25                     # world distance between samples (default: spacing / 4)
    threshold = 0.99                # early ray termination opacity (composite)
    shade = false                   # gradient shading of composite samples; with true,
                                    #   material as for an isosurface

    [[light]]                       # none: a headlight at the eye; lights shine on isosurfaces and shaded samples
    position = [0, -200, 150]       # a point light; or
    # direction = [-1, 1, -1]       #   a directional light travelling along this vector
    color = [1, 1, 1]
    intensity = 1.0

Errors
------
Every mistake raises `InputError` with one line naming the file and the
key, e.g. ``scene.toml: volume[2].iso: isovalue 5000 is outside the data
range [0, 255] of foo.nrrd`` or ``scene.toml: camera.fvo: unknown key; did
you mean fov? (known: eye, look_at, up, fov, parallel, zoom)``. Tables of an
array are counted from 1 in file order: ``volume[1]`` is the first
``[[volume]]``.
"""
from __future__ import annotations

import itertools
import os
from pathlib import Path

import numpy as np

from data_tools import InputError, Volume
from data_tools.volume import text_or_flag

from .camera import Camera, check_fov, check_parallel_scale, unit_vector, up_across
from .scene import DirectionalLight, Isosurface, PointLight, Scene, Translucent, check_eye_resolves
from .tomltables import Table, Where, array_tables, construct
from .transfer.files import holds_a_transfer_function

TOP_KEYS = ("size", "background", "shadows", "camera", "volume", "light")
CAMERA_KEYS = ("eye", "look_at", "up", "fov", "parallel", "zoom")
SOURCE_KEYS = ("file", "synthetic")
SYNTHETIC_KEYS = ("size", "seed")
RAW_KEYS = ("shape", "dtype", "byte_order", "offset")
PLACEMENT_KEYS = ("spacing", "origin")
ISO_KEYS = ("iso", "color")
TF_KEYS = ("tf", "mode", "step", "threshold", "shade")
VOLUME_KEYS = SOURCE_KEYS + SYNTHETIC_KEYS + RAW_KEYS + PLACEMENT_KEYS + ISO_KEYS + TF_KEYS + ("material",)
LIGHT_KEYS = ("position", "direction", "color", "intensity")

#: Image size when the file (and the command line) give none, as ``parc render``.
DEFAULT_SIZE = (512, 512)
DEFAULT_FOV = 30.0
DEFAULT_UP = (0.0, 0.0, 1.0)


def load_scene(path, *, view=None, size=None, progress=None, replaced_by="given to load_scene") -> Scene:
    """Read a scene file (see the module notes for the schema).

    Parameters
    ----------
    path : str or Path
        The TOML file. Volume and transfer-function files named in it are
        found relative to its folder (the folder of ``path`` as given, also
        when ``path`` is a link).
    view : dict, optional
        Camera settings that replace the file's, keyed as in ``[camera]``
        (``eye``, ``look_at``, ``up``, ``fov``, ``parallel``, ``zoom``); None values
        are ignored. Giving ``parallel`` drops the file's ``fov`` and giving
        ``fov`` drops its ``parallel``. For the command line's view flags.
    size : (width, height), optional
        Replaces the file's image size.
    progress : callable(str), optional
        Told, in a line, before a synthetic volume that takes seconds to make.
    replaced_by : str
        How messages about ``view`` and ``size`` say where they came from, after the key they
        replace (``parc render`` says "given on the command line").

    Returns
    -------
    Scene

    Raises
    ------
    InputError
        One line naming the file and the key: a missing or unreadable file,
        malformed TOML (with its line), an unknown key, a missing required
        key, a value of the wrong type or out of range, a missing volume or
        transfer-function file, an isovalue outside the data range.
    """
    if not isinstance(replaced_by, str):
        raise InputError(f"replaced_by takes text, got {type(replaced_by).__name__}")
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"load_scene takes the path of a scene file, got {type(path).__name__}")
    if progress is not None and not callable(progress):
        raise InputError(f"progress must be a function of a line of text, got {progress!r}")
    if view is not None and (not isinstance(view, dict) or set(view) - set(CAMERA_KEYS)):
        raise InputError(f"view takes camera settings keyed {', '.join(CAMERA_KEYS)}, got {view!r}")
    for key, value in (view or {}).items():
        if value is None:
            continue
        if key in ("fov", "parallel", "zoom"):
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise InputError(f"view: {key} must be a number, got {value!r}")
        elif not (np.ndim(value) == 1 and len(value) == 3
                  and all(isinstance(c, (int, float, np.integer, np.floating))
                          and not isinstance(c, (bool, np.bool_)) and np.isfinite(c) for c in value)):
            raise InputError(f"view: {key} must be three finite numbers, got {value!r}")
    where = Where(path, progress)
    doc = where.read()
    if holds_a_transfer_function(doc):
        raise where.error("", "a transfer function, not a scene (it has no [[volume]] tables): give it with --tf, "
                              "or as a [[volume]] table's tf in a scene file")
    top = Table(where, "", doc, TOP_KEYS)

    volumes = _load_volumes(where, doc.get("volume"))
    lights = _load_lights(where, doc.get("light"))
    # The file's own values are checked even where the command line replaces them: a
    # mistake in the file should not wait for a run without the flag to show.
    image_size = top.integers("size", 2, default=DEFAULT_SIZE, minimum=1)
    if size is not None:
        with where.key(f"size ({replaced_by})"):
            image_size = _check_size(size)
    # Before the camera's aspect divides one by the other: a size of 10**400 overflows a float.
    from .workspace import check_frame_memory
    check_frame_memory(*image_size)
    camera_table = Table(where, "camera", doc.get("camera", {}), CAMERA_KEYS)
    camera = _load_camera(where, camera_table, volumes, {k: v for k, v in (view or {}).items() if v is not None},
                          image_size[0] / image_size[1], replaced_by)
    background = top.numbers("background", (3, 4), default=None)
    if background is not None and not all(0.0 <= c <= 1.0 for c in background):
        raise where.error("background", f"must be numbers in [0, 1], got {list(background)}")
    shadows = top.boolean("shadows", default=False)
    with where.key(None):
        return Scene(camera=camera, size=image_size, volumes=volumes, lights=lights,
                     background=background, shadows=shadows)


def resolve_view(lo, hi, *, eye=None, look_at=None, up=None, fov=None, parallel=None, aspect=1.0, zoom=None):
    """The camera settings for a view of the box ``[lo, hi]``, with defaults filled in.

    The command line and scene files frame volumes the same way: with
    neither ``eye`` nor ``look_at``, `Camera.framing`'s three-quarter view;
    otherwise ``look_at`` defaults to the box centre and ``eye`` to the
    framing view's offset from it.

    Parameters
    ----------
    lo, hi : (x, y, z)
        World corners of the box to show.
    eye, look_at, up : (x, y, z) or None
    fov : float or None
        Vertical field of view in degrees (default 30).
    parallel : float or None
        Parallel scale: a parallel projection when given.
    aspect : float
        The image's width / height: a tall image is framed across.
    zoom : float or None
        Without ``eye``: the framing eye that many times closer (`Camera.framing`);
        refused with ``eye`` and with ``parallel``, whose scale sets the view.

    Returns
    -------
    dict
        `Camera`'s keyword arguments: ``eye``, ``look_at``, ``up``, ``fov``,
        ``parallel_scale``. Not checked: `Camera` does that.
    """
    fov = DEFAULT_FOV if fov is None else fov
    explicit_up = up is not None
    up = tuple(up) if explicit_up else DEFAULT_UP
    if zoom is not None:
        if eye is not None:
            raise InputError("zoom moves the default eye closer; with an eye given, move the eye")
        if parallel is not None:
            raise InputError("zoom applies to a perspective view; a parallel view's scale sets its size")
    zoom = 1.0 if zoom is None else zoom
    if eye is None and look_at is None:
        framed = Camera.framing(lo, hi, fov=fov, up=up, parallel=parallel is not None, aspect=aspect, zoom=zoom)
        return {"eye": framed.eye, "look_at": framed.look_at, "up": up, "fov": fov,
                "parallel_scale": parallel}
    look_at = tuple(look_at) if look_at is not None else tuple(0.5 * (np.asarray(lo) + np.asarray(hi)))
    if eye is None:
        # The default eye's offset, as the view without look_at has it (a parallel view's is its own):
        # naming the default centre must change nothing, the depths included.
        framed = Camera.framing(lo, hi, fov=fov, up=up, parallel=parallel is not None, aspect=aspect, zoom=zoom)
        eye = tuple(np.asarray(look_at) + np.subtract(framed.eye, framed.look_at))
    if not explicit_up:
        # The default up must not be parallel to the view: fall back to +y.
        f = unit_vector(np.subtract(look_at, eye))
        if f is not None and np.linalg.norm(np.cross(f, up)) < 1e-6:
            up = (0.0, 1.0, 0.0)
    return {"eye": tuple(eye), "look_at": look_at, "up": up, "fov": fov, "parallel_scale": parallel}


def _check_size(size):
    """``size`` (any iterable of two) as a tuple, refused unless two positive integers (an
    infinite float overflows ``int``; a lone number is not iterable)."""
    try:
        # At most three taken: an endless iterator (itertools.count) or a range of 10**10 is refused, not drawn out.
        pair = () if text_or_flag(size) else tuple(itertools.islice(size, 3))
        ok = len(pair) == 2 and all(not text_or_flag(v) and int(v) == v and v >= 1 for v in pair)
    except (TypeError, ValueError, OverflowError, np.ma.MAError):      # MAError: a masked value
        ok = False
    if not ok:
        raise InputError(f"image size must be two positive integers, got {size!r}")
    return pair


# --- volumes --------------------------------------------------------------

def _load_volumes(where, raw):
    # Tables naming the same data and placement share one Volume, so the
    # renderer computes its cell min/max once and holds the samples once.
    cache = {}
    return [_load_volume(where, Table(where, prefix, t, VOLUME_KEYS), cache)
            for prefix, t in array_tables(where, "volume", raw, required=True)]


def _load_volume(where, t, cache):
    # What to show is checked before the data is read: a typo should not wait for a large file.
    has_iso, has_tf = "iso" in t, "tf" in t
    if has_iso == has_tf:
        raise where.error(t.prefix, "give iso (an isosurface) or tf (a translucent volume)"
                          + (", not both" if has_iso else ""))
    material = t.material("material")
    if has_iso:
        for name in TF_KEYS:
            if name in t:
                raise t.error(name, "applies to a translucent volume (tf), not to an isosurface (iso)")
        value = t.number("iso")
        color = t.numbers("color", 3)
        vol = _volume_data(where, t, cache)
        keyed = [("iso", "value", value)]
        if color is not None:
            keyed.append(("color", "color", color))
        if material is not None:
            keyed.append(("material", "material", material))
        return construct(where, t.prefix, Isosurface, {"volume": vol}, keyed)

    if "color" in t:
        raise t.error("color", "applies to an isosurface (iso); a translucent volume's colours "
                               "come from its transfer function (tf)")
    from .transfer import PRESETS, load_for_volume
    from .transfer.files import unknown_preset
    from .transfer.presets import MODES
    spec = t.string("tf")
    mode = t.string("mode")
    if mode is not None and mode not in MODES:
        raise t.error("mode", f"unknown mode {mode!r}; choose one of {', '.join(MODES)}")
    step, threshold, shade = t.number("step"), t.number("threshold"), t.boolean("shade")
    if threshold is not None and mode not in (None, "composite"):
        raise t.error("threshold", f"applies to mode composite; {mode} does not stop rays early")
    if material is not None and not shade:
        # Lit or not, an unshaded volume's samples take their transfer function's colours alone.
        raise t.error("material", "applies to an isosurface, or to a translucent volume with shade = true")
    vol = _volume_data(where, t, cache)
    with where.key(t.key("tf")):
        if spec not in PRESETS:
            path = where.resolve(spec)
            # A bare word that is no file beside the scene is meant as a preset, and refused as an
            # unknown one here: the loader would read a working folder's file of that name.
            # (exists() raises for a name too long: named with the file and key, as the loader's.)
            if path.exists() or Path(spec).suffix or os.sep in spec or "/" in spec:
                spec = os.fspath(path)
            else:
                raise unknown_preset(spec)
        tf = load_for_volume(spec, vol, mode or "composite")
    given = {"mode": mode, "step": step, "threshold": threshold, "shade": shade, "material": material}
    keyed = [(name, name, value) for name, value in given.items() if value is not None]
    return construct(where, t.prefix, Translucent, {"volume": vol, "tf": tf}, keyed)


def _volume_data(where, t, cache):
    """The Volume a ``[[volume]]`` table names, placed as it says."""
    has_file, has_synthetic = "file" in t, "synthetic" in t
    if has_file == has_synthetic:
        raise where.error(t.prefix, "give file (a volume file) or synthetic (a built-in volume)"
                          + (", not both" if has_file else ""))
    spacing = t.numbers("spacing", 3)
    origin = t.numbers("origin", 3)
    if has_file:
        for name in SYNTHETIC_KEYS:
            if name in t:
                raise t.error(name, "applies to synthetic volumes, not to a volume file")
        vol, source = _read_file(where, t, cache, spacing, origin)
    else:
        for name in RAW_KEYS:
            if name in t:
                raise t.error(name, "applies to headerless raw volume files, not to synthetic volumes")
        vol, source = _make_synthetic(where, t, cache)
    key = (source, spacing, origin)
    if spacing is None and origin is None or vol is cache.get(key):
        return vol
    if key not in cache:
        with where.key(t.key("spacing" if spacing is not None else "origin")):
            # Same samples, new placement: the array is shared, not copied.
            cache[key] = Volume(vol.data, spacing=spacing or vol.spacing, origin=origin or vol.origin,
                                name=vol.name, meta=dict(vol.meta))
    return cache[key]


def _read_file(where, t, cache, spacing, origin):
    """The volume a file holds, placed as the file says; or, where the file's own spacing or
    origin is refused and the table replaces it, as the table says."""
    from data_tools.io import load_volume, raw
    name = t.string("file")
    with where.key(t.key("file")):
        path = where.resolve(name)
    options = {"shape": t.integers("shape", 3, minimum=2), "dtype": t.string("dtype"),
               "byte_order": t.string("byte_order"), "offset": None}
    if "offset" in t:
        offset = t.raw["offset"]
        if not isinstance(offset, int) or isinstance(offset, bool) or offset < 0:
            raise t.wrong("offset", "an integer >= 0 (bytes before the samples)")
        options["offset"] = offset
    if options["byte_order"] not in (None, "little", "big"):
        raise t.error("byte_order", f"must be \"little\" or \"big\", got {options['byte_order']!r}")
    given = [name for name in RAW_KEYS if options[name] is not None]
    if given and path.suffix.lower() not in raw.EXTENSIONS:
        raise t.error(given[0], f"applies only to headerless raw files ({', '.join(raw.EXTENSIONS)}); "
                                f"{path.name} has a header")
    if options["dtype"] is not None:
        with where.key(t.key("dtype")):
            raw.parse_dtype(options["dtype"], path)
    if path.suffix.lower() in raw.EXTENSIONS:
        # Said in this table's keys: the reader's own message names the command line's flags.
        guess = raw.guess_from_name(path)
        hints = {"shape": "shape = [NX, NY, NZ]", "dtype": 'dtype (e.g. "uint8")'}
        missing = [key for key in hints if options[key] is None and key not in guess]
        if missing:
            raise t.error(missing[0], f"{path.name} is a raw file, which has no header; give "
                          f"{' and '.join(hints[key] for key in missing)}, or name it like vol_64x64x64_uint8.raw")
    source = ("file", os.fspath(path)) + tuple(options[name] for name in RAW_KEYS)
    placed, refused = (source, spacing, origin), ("refused",) + source
    if source not in cache and placed not in cache:
        if refused not in cache:
            with where.key(t.key("file")):
                try:
                    cache[source] = load_volume(path, **options)
                except InputError as exc:
                    if spacing is None and origin is None:
                        raise
                    cache[refused] = str(exc)       # read placed by each table from now on
        if source not in cache:
            # A header value the table replaces (spacing 0, an origin far from a fine grid)
            # must not stop the read: placed by the table; refused again, the same error is
            # the file's, another the table's values'.
            try:
                cache[placed] = load_volume(path, **options, spacing=spacing, origin=origin)
            except InputError as exc:
                # The Volume's refusals begin with the field they refuse, after the file's name.
                field = str(exc).partition(": ")[2].split(" ", 1)[0]
                blame = ("file" if str(exc) == cache[refused] else field if field in ("spacing", "origin")
                         else "spacing" if spacing is not None else "origin")
                with where.key(t.key(blame)):
                    raise
    return cache.get(source, cache.get(placed)), source


def _make_synthetic(where, t, cache):
    from data_tools.synthetic import SYNTHETIC, check_synthetic_size, make_synthetic, making_note
    name = t.string("synthetic")
    if name not in SYNTHETIC:
        raise t.error("synthetic", f"unknown synthetic volume {name!r}; choose from {', '.join(SYNTHETIC)}")
    size = None
    if "size" in t:
        size = t.raw["size"]
        if isinstance(size, list):
            size = t.integers("size", 3, minimum=2)
        elif not isinstance(size, int) or isinstance(size, bool):
            raise t.wrong("size", "an integer or an array of 3 integers (samples per axis)")
        elif size < 2:
            raise t.error("size", f"must be at least 2 samples per axis, got {size}")
    if size is not None:
        with where.key(t.key("size")):
            check_synthetic_size(size, str(size), name)
    kwargs = {}
    if "seed" in t:
        seed = t.raw["seed"]
        if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
            raise t.wrong("seed", "an integer >= 0")
        kwargs["seed"] = seed
    source = ("synthetic", name, size, kwargs.get("seed"))
    if source not in cache:
        making = making_note(name, size)
        if making:
            where.progress(making)
        try:
            with where.key(t.key("synthetic")):
                cache[source] = make_synthetic(name, size, **kwargs)
        except TypeError:
            raise t.error("seed", f"synthetic volume {name!r} takes no seed") from None
    return cache[source], source


# --- lights and camera ------------------------------------------------------

def _load_lights(where, raw):
    lights = []
    for prefix, raw_table in array_tables(where, "light", raw, required=False):
        t = Table(where, prefix, raw_table, LIGHT_KEYS)
        if ("position" in t) == ("direction" in t):
            raise where.error(prefix, "give position (a point light) or direction (a directional light)"
                              + (", not both" if "position" in t else ""))
        kind, cls = ("position", PointLight) if "position" in t else ("direction", DirectionalLight)
        keyed = [(kind, kind, t.numbers(kind, 3))]
        if "color" in t:
            keyed.append(("color", "color", t.numbers("color", 3)))
        if "intensity" in t:
            keyed.append(("intensity", "intensity", t.number("intensity")))
        lights.append(construct(where, prefix, cls, {}, keyed))
    return lights


def _check_view(where, settings, label):
    """Refuse a field of view, parallel scale or zoom out of range, or a zero up vector."""
    for name, check in (("fov", check_fov), ("parallel", check_parallel_scale)):
        if settings[name] is not None:
            with where.key(label(name)):
                check(settings[name])
    if settings["zoom"] is not None and not settings["zoom"] > 0.0:
        raise where.error(label("zoom"), f"zoom must be positive, got {settings['zoom']:g}")
    if settings["up"] is not None and unit_vector(settings["up"]) is None:
        raise where.error(label("up"), f"up {list(settings['up'])} is zero: give a direction")


def _load_camera(where, t, volumes, view, aspect, replaced_by):
    settings = {"eye": t.numbers("eye", 3), "look_at": t.numbers("look_at", 3), "up": t.numbers("up", 3),
                "fov": t.number("fov"), "parallel": t.number("parallel"), "zoom": t.number("zoom")}
    if settings["fov"] is not None and settings["parallel"] is not None:
        raise t.error("parallel", "give fov (perspective) or parallel (a parallel projection), not both")
    _check_view(where, settings, t.key)
    # A view given in place of the file's wins; its projection replaces the file's, and an eye or
    # a parallel view the file's zoom, which applies to neither.
    if "parallel" in view:
        settings["fov"] = None
    if "fov" in view:
        settings["parallel"] = None
    if ("eye" in view or "parallel" in view) and "zoom" not in view:
        settings["zoom"] = None
    settings.update(view)

    def label(name):
        return t.key(name) + (f" ({replaced_by})" if name in view else "")

    _check_view(where, settings, label)

    lo = np.min([v.volume.bounds[0] for v in volumes], axis=0)
    hi = np.max([v.volume.bounds[1] for v in volumes], axis=0)
    # Framing fails on the zoom (with an eye or a parallel view), or on a field of view too
    # narrow: the message says which, and the key follows it.
    try:
        cam = resolve_view(lo, hi, **settings, aspect=aspect)
    except InputError as exc:
        name = "fov" if "field of view" in str(exc) and settings["fov"] is not None else "zoom"
        raise where.error(label(name) if settings[name] is not None else "camera", str(exc)) from None
    f = unit_vector(np.subtract(cam["look_at"], cam["eye"]))
    if f is None:
        if settings["look_at"] is None:
            raise where.error(label("eye"), f"eye {list(cam['eye'])} is the centre of the volumes, where the "
                                            "camera looks by default: move it or give look_at")
        # The one the command line gave, if either: the file's was fine without it.
        name = next((k for k in ("look_at", "eye") if k in view), "eye" if settings["eye"] is not None else "look_at")
        raise where.error(label(name), f"eye and look_at are the same point {list(cam['eye'])}: no view direction")
    up = unit_vector(cam["up"])
    if up is None:
        raise where.error(label("up"), f"up {list(cam['up'])} is zero: give a direction")
    if np.linalg.norm(np.cross(f, up)) < 1e-9:
        raise where.error(label("up"), f"up {list(cam['up'])} is parallel to the view direction: give one "
                                       f"across it, such as {[int(c) for c in up_across(f)]}")
    with where.key("camera"):
        camera = Camera(**cam)
    # Checked by the scene too, here with the key that placed the eye.
    with where.key(label("eye") if settings["eye"] is not None else "camera"):
        check_eye_resolves(camera, [v.volume for v in volumes])
    return camera
