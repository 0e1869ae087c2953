"""The Scene that `parc render` and `parc compare` flags describe.

A volume file (or the built-in volume) with --iso or --tf and the view
flags, or a scene file (``.toml``) whose camera and size the view flags
override; then the lights of --light and --sun. Flags that cannot apply
(a volume flag with a scene file, a translucent flag with an isosurface)
are refused in one line, not ignored.
"""
from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from data_tools import InputError
from data_tools.info import exact_text

from .camera import check_fov, check_parallel_scale, unit_vector
from .outputs import note
from .scene import (DEFAULT_THRESHOLD, HEADLIGHT_SHADOWS, ShowsNothingWarning, check_eye_resolves, check_step,
                    check_threshold)


def load_volume_flags(args):
    """The volume file the flags name, read with the raw-format flags (`parc info`, `parc convert`)."""
    from data_tools.io import load_volume

    from .arguments import TRIPLE, one_flag_a_light
    flag = next((f"--{f}" for f in ("light", "sun") if getattr(args, f, None)), None)
    if flag and args.volume and TRIPLE.fullmatch(args.volume) and not os.path.exists(args.volume):
        # "--light x,y,z x,y,z" with no volume before it: argparse takes the second light for one.
        raise InputError(f"{args.volume}: no such file{one_flag_a_light(flag)}")
    if args.volume and (role := _not_a_volume(args.volume)):
        raise InputError(f"{args.volume}: {role}")
    if _is_scene_file(args):
        raise InputError(f"{args.volume}: a scene file; parc {args.command} reads one volume file "
                         "(parc render and parc compare read scenes)")
    return load_volume(args.volume, **{name: getattr(args, name) for name in _READING_FLAGS})


def _not_a_volume(name):
    """What the file ``name`` is, where it is a file parc reads in another role than a volume's:
    a volume's sidecar, or a transfer function (TOML, JSON, ParaView's colour maps); else None."""
    lower = name.lower()
    if not lower.endswith((".json", ".toml")) or not os.path.isfile(name):
        return None
    if lower.endswith(".npy.json"):
        return f"the spacing and origin of {name[:-5]} (its sidecar): give {name[:-5]}"
    import json

    from .tomltables import tomllib
    from .transfer.files import holds_a_transfer_function
    try:
        doc = (json.loads if lower.endswith(".json") else tomllib.loads)(Path(name).read_text())
    except (OSError, ValueError):       # the reader's own error says more
        return None
    if holds_a_transfer_function(doc):
        return "a transfer function, not a volume: parc render and parc compare take it with --tf"
    return None


#: Flags that say how to read the volume file: `load_volume`'s options, under the same names.
_READING_FLAGS = ("shape", "dtype", "byte_order", "offset", "spacing", "origin")

#: Flags that describe the one volume on the command line; a scene file sets
#: these per volume, in its [[volume]] tables (under the same names).
_VOLUME_FLAGS = ("iso", "tf", "mode", "step", "threshold", "shade") + _READING_FLAGS


def _is_scene_file(args):
    return args.volume is not None and args.volume.lower().endswith(".toml")


def scene_from_flags(args, say):
    """The Scene the arguments describe: a scene file or one volume, with the flags' lights."""
    if args.fov is not None and args.parallel is not None:
        raise InputError("give --fov (a perspective view) or --parallel (a parallel projection), not both")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ShowsNothingWarning)
        scene = _file_scene(args) if _is_scene_file(args) else _volume_scene(args, say)
        scene = _add_flag_lights(scene, args, say)
    said = set()
    for w in caught:
        if issubclass(w.category, ShowsNothingWarning):
            # Each dataclasses.replace of the scene (--background, --light) checks it again; the
            # headlight's shadows are said below, with the flags that give lights.
            if str(w.message) not in said and not str(w.message).startswith(HEADLIGHT_SHADOWS):
                said.add(str(w.message))
                say(str(w.message))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    _say_what_shows_faintly(scene, say)
    if (scene.background is None and getattr(args, "command", "render") == "render"
            and any(getattr(v, "mode", None) == "average" for v in scene.volumes)):
        # Its grey level is white at that opacity: over a white page or viewer, nothing shows.
        # (Said where an image is written: parc compare writes none.)
        say("average intensity draws white at the grey level's opacity; on the default transparent "
            "background it reads as an X-ray over black: add --background 0,0,0 for an opaque image")
    return scene


def scene_and_notes(args):
    """`scene_from_flags` and its notes, for the caller to say once the run's checks have passed
    and before its work: a refused run gets its error line alone."""
    notes = []
    scene = scene_from_flags(args, notes.append)
    return scene, notes


def _given(value):
    """Whether a flag was given: not its default None, nor a switch left off. (Not a test by
    membership: ``0.0 in (None, False)`` is true, which would take ``--iso 0`` for no flag.)"""
    return value is not None and value is not False


def _file_scene(args):
    """The scene file's Scene, with the view flags given replacing its camera settings and size."""
    from dataclasses import replace

    from .scenefile import load_scene
    for name in _VOLUME_FLAGS:
        if _given(getattr(args, name, None)):
            flag = "--" + name.replace("_", "-")
            raise InputError(f"{flag} does not apply to a scene file ({args.volume}); "
                             f"set {name} in its [[volume]] tables")
    view = {"eye": args.eye, "look_at": args.look_at, "up": args.up, "fov": args.fov, "parallel": args.parallel,
            "zoom": args.zoom}
    scene = load_scene(args.volume, view=view, size=args.size, progress=None if args.quiet else note,
                       replaced_by="given on the command line")
    if getattr(args, "background", None) is not None:
        scene = replace(scene, background=args.background)
    return scene


def _add_flag_lights(scene, args, say):
    """``scene`` with the --light and --sun lights added, and shadows on with --shadows."""
    import parc
    from dataclasses import replace
    lights = []
    for p in args.light or ():
        try:
            lights.append(parc.PointLight(position=p))
        except InputError as exc:
            raise InputError(f"--light: {exc}") from None
    for d in args.sun or ():
        try:
            lights.append(parc.DirectionalLight(direction=d))
        except InputError as exc:
            raise InputError(f"--sun: {exc}") from None
    if lights or args.shadows:
        try:
            scene = replace(scene, lights=[*scene.lights, *lights], shadows=scene.shadows or args.shadows)
        except InputError as exc:
            flag = "light" if args.light else "sun" if args.sun else "shadows"
            raise InputError(f"--{flag}: {exc}") from None
    lit = any(isinstance(v, parc.Isosurface) or (v.shade and v.mode == "composite") for v in scene.volumes)
    if scene.shadows and not scene.lights and lit:
        say(f"{HEADLIGHT_SHADOWS}; add --light or --sun"
            + (", or a [[light]] table to the scene file" if _is_scene_file(args) else ""))
    return scene


# Below this peak opacity a maximum-intensity image is said to be faint.
FAINT_MIP = 0.5


def _volume_scene(args, say):
    """The volume, isovalue and camera the flags describe, as a Scene."""
    import parc
    from data_tools.synthetic import builtin_volume

    w, h = args.size or (512, 512)
    if w < 1 or h < 1:
        raise InputError(f"--size must be two positive integers, got {w} {h}")
    # Before the camera divides one by the other: --size 10**400 8 overflows a float.
    from .workspace import check_frame_memory
    check_frame_memory(w, h)
    if args.volume is None:
        for name in _READING_FLAGS:
            if getattr(args, name, None) is not None:
                raise InputError(f"--{name.replace('_', '-')} applies to a volume file; "
                                 "the built-in volume takes none")
        vol = builtin_volume()
        iso = vol.meta["iso"] if args.iso is None and args.tf is None else args.iso
    else:
        vol = load_volume_flags(args)
        iso = args.iso
    if "note" in vol.meta:
        say(vol.meta["note"])
    if args.tf is not None:
        if args.iso is not None:
            raise InputError("give --iso (an isosurface) or --tf (a translucent volume), not both")
        if args.mode not in (None, "composite"):
            for flag in ("threshold", "shade"):
                if _given(getattr(args, flag)):
                    raise InputError(f"--{flag} applies to --mode composite; {args.mode} neither shades samples "
                                     "nor stops rays early")
        # The scene's own checks, named by the flag.
        if args.step is not None:
            check_step(args.step, vol, "--step")
        if args.threshold is not None:
            check_threshold(args.threshold, "--threshold")
        vis = parc.Translucent(vol, args.tf, mode=args.mode or "composite", step=args.step,
                               threshold=DEFAULT_THRESHOLD if args.threshold is None else args.threshold,
                               shade=args.shade)
        return parc.Scene(camera=_camera(args, vol, (w, h)), size=(w, h), volumes=[vis],
                          background=getattr(args, "background", None))
    for flag in ("mode", "step", "threshold", "shade"):
        if _given(getattr(args, flag)):
            raise InputError(f"--{flag} applies to translucent volumes (--tf)")
    if iso is None:
        from data_tools.info import default_isovalue, suggest_isovalues
        levels = suggest_isovalues(vol)
        if not levels:
            lo, hi = vol.value_range()
            raise InputError(f"{vol.name}: every sample is {lo:g}; there is no isosurface to show" if lo == hi else
                             f"{vol.name}: no level lies strictly between its samples' values, "
                             f"{exact_text(lo)} and {exact_text(hi)}; there is no isosurface to show")
        iso = default_isovalue(levels)
        say(f"no --iso given; using {exact_text(iso)}, suggested from the histogram "
            f"(others: {', '.join(exact_text(v) for v in levels if v != iso) or 'none'})")
    return parc.Scene(camera=_camera(args, vol, (w, h)), size=(w, h), volumes=[parc.Isosurface(vol, iso)],
                      background=getattr(args, "background", None))


def _say_what_shows_faintly(scene, say):
    """Notes on volumes that show other than a user may expect: an isosurface at an end of its
    data, a maximum-intensity projection through a table that stays faint over the data."""
    import parc
    for k, vis in enumerate(scene.volumes, 1):
        lo, hi = vis.volume.value_range()
        # A scene file's volumes by their tables, as its errors name them.
        whose = "the data" if len(scene.volumes) == 1 else f"volume[{k}]"
        if isinstance(vis, parc.Isosurface) and vis.value in (lo, hi):
            # The walk takes a cell flat at the isovalue for surface: its whole extent is hit.
            end, past = ("smallest", "above") if vis.value == lo else ("largest", "below")
            say(f"isovalue {exact_text(vis.value)} is {whose}'s {end} value: cells whose samples all equal it "
                f"are surface throughout and show as solid; a level just {past} it shows the shapes they bound")
        elif isinstance(vis, parc.Translucent) and vis.mode == "mip":
            # The table's peak over the data alone: one past the largest value never shows.
            points = vis.tf.opacity_points
            reached = points[(points[:, 0] >= lo) & (points[:, 0] <= hi), 1]
            peak = float(max(vis.tf.opacity(np.array([lo, hi])).max(), reached.max(initial=0.0)))
            if 0.0 < peak < FAINT_MIP:
                # A MIP pixel is one value at its own opacity: a table made for compositing stays faint.
                say(f"{vis.tf.title} is at most {peak:g} opaque over {whose}'s values: a MIP shows "
                    "each ray's largest visible value at its own opacity, so the image is faint "
                    "(greyscale and viridis end opaque for mip)")


def _camera(args, vol, size):
    import parc

    from .scenefile import resolve_view
    lo, hi = vol.bounds
    if args.zoom is not None and not (np.isfinite(args.zoom) and args.zoom > 0.0):
        raise InputError(f"--zoom must be positive and finite, got {args.zoom:g}")
    if args.fov is not None:
        check_fov(args.fov, "--fov")
    if args.parallel is not None:
        check_parallel_scale(args.parallel, "--parallel")
    view = resolve_view(lo, hi, eye=args.eye, look_at=args.look_at, up=args.up, fov=args.fov,
                        parallel=args.parallel, aspect=size[0] / size[1], zoom=args.zoom)
    if args.look_at is None and unit_vector(np.subtract(view["look_at"], view["eye"])) is None:
        raise InputError(f"--eye {','.join(f'{c:g}' for c in view['eye'])} is the centre of the volume, "
                         "where the camera looks by default: move it or give --look-at")
    camera = parc.Camera(**view)
    try:
        check_eye_resolves(camera, [vol], [vol] if args.iso is not None else ())
    except InputError as exc:
        raise InputError(f"--eye: {exc}" if args.eye is not None else str(exc)) from None
    return camera
