"""Render a scene: cast every pixel (unaccelerated, or over PARC's ray segments) and shade it.

One driver per kind of volume: `_render_iso` (opaque isosurface: first hit,
shaded as soon as it is found) and `_render_translucent` (accumulation). Both get their
ray segments from `parc.segments` when the method is ``"parc"`` (a translucent
volume drawn with bit planes alone takes only the proxy, `cached_proxy`); the
casting kernels are the same for both methods. Scenes of several volumes, of
an isosurface with lights, or of shaded samples with shadows go to
`_render_general` (`parc.multivolume`; `_casts_alone` decides).

Also here, shared with `parc.multivolume` and the benchmarks: a translucent volume's
``params`` for the kernels (`accumulation_params`); their work arrays and the bands a frame is
cast in are `parc.workspace`'s, the skip tables `parc.skip`'s.
"""
from __future__ import annotations

import contextlib
import logging
import threading
import time
from dataclasses import dataclass

import numpy as np

from data_tools import InputError
from raycast.composite import (MODE_AVERAGE, MODE_COMPOSITE, MODE_MIP, N_PARAMS, P_AMBIENT, P_HI, P_LIGHT_COUNT,
                               P_LIGHTS, P_LO, P_MODE, P_ORIGIN, P_RATIO, P_SHADE, P_STEP, P_THRESHOLD,
                               cast_accumulate_image, over_background)
from raycast.iso import cast_iso_image

from .gl import release_context
from .lights import light_array
from .scene import Isosurface, Scene, Translucent, describe_view, describe_volume
from .segments import cached_proxy, parc_segments
from .skip import octant_skip_tables, skip_table
from .workspace import (NO_BITS, NO_SEGMENTS, NO_STOP, check_scene_memory, iso_work, row_bands, shadowed_samples,
                        work_array)

METHODS = ("brute", "parc")
#: Held by every render. Re-entrant, so that a render asked for inside a render's
#: progress callback is refused (`_RENDERING`) rather than left waiting for ever.
RENDER_LOCK = threading.RLock()
#: Whether a render is under way: one inside it would overwrite its work arrays and buffers.
_RENDERING = [False]


_MODES = {"composite": MODE_COMPOSITE, "mip": MODE_MIP, "average": MODE_AVERAGE}


@dataclass
class RenderResult:
    """What `render` returns.

    Attributes
    ----------
    image : ndarray (H, W, 4) float32
        Premultiplied RGBA in [0, 1].
    depth : ndarray (H, W) float64
        World distance ``t`` along each pixel's ray to the first isosurface hit, ``inf`` where
        none: a translucent volume has no surface, so a scene of translucent volumes alone is
        ``inf`` everywhere, and so ``hits`` counts isosurface hits only.
    stats : dict
        ``method``, ``seconds`` per phase, ``pixels``, ``rays`` (one per pixel; with PARC,
        ``segment_pixels`` are those whose ray is walked), ``cells_visited``,
        ``cubic_solves``, ``samples``, ``hits``, ``polygons`` (all PARC drew: its proxy's and,
        with bit planes, their ``plane_polygons``; with shadows, the light buffers' faces drawn
        this frame, ``light_polygons``) and the ``parameters`` used: ``size``, ``camera``,
        ``background`` where given, ``lights`` (each one's position or direction, colour and
        intensity) and ``shadows`` where either is given (always, for a scene cast as several
        volumes are, below), and the volume as `parc.scene.describe_volume` gives it (several
        volumes: a list of them, under ``volumes``). With PARC, also ``supercell`` (its size in
        cells, per axis), ``supercells`` and ``pc_supercells`` (those that may contribute),
        ``raster_seconds`` (the OpenGL pass's parts), ``buffers`` and ``blocks`` (as asked),
        with bit planes ``planes`` and ``plane_axis``, and without a ``supercell`` given,
        ``supercell_model`` (the cost model's estimate at each size it weighed, made on the
        first frame of a classification and image size and kept for the next). Cells and
        cubics count isosurfaces' work, samples translucent volumes'; a process's first
        ``seconds["total"]`` also holds loading the casters and making OpenGL's context, beyond
        the phases listed, and the phases of a first render of its kind hold compiling the
        kernels they call (10 to 60 s in all, once on a machine: `compile_notice` in
        `parc.outputs`).
        Every render gives ``shadow_rays``, ``shadow_cells``, ``shadow_solves`` and
        ``shadow_samples`` (0 without shadow rays), and ``light_polygons``, the light
        buffers' faces PARC drew this frame (0 with brute, without shadows, or with the
        buffers kept from an earlier frame). A scene of several
        volumes, of an isosurface with lights or of shaded samples with shadows gives each
        volume's ``polygons``, ``segment_pixels`` and ``supercell`` under ``volumes`` (with
        PARC), not at the top.
    work : ndarray (H, W) int64 or None
        With ``render(..., work=True)``: per pixel, the cells its ray visited
        (isosurfaces) or the samples it took (translucent volumes), so
        that the methods' work can be compared where it is spent. Several
        volumes' work is added; shadow rays' is left out. Sums to
        ``stats["cells_visited"]`` or ``stats["samples"]``.
    """

    image: np.ndarray
    depth: np.ndarray
    stats: dict
    work: np.ndarray | None = None

    def save(self, path):
        """Write the image to ``path``: a ``.png`` of 8-bit straight (not premultiplied) RGBA, or
        a ``.npy`` of the float32 premultiplied array as it is (`parc.outputs.save_image`)."""
        from .outputs import save_image
        return save_image(self.image, path, "RenderResult.save")

    def __repr__(self):
        # The arrays and the stats' nested parameters made the default several kilobytes.
        h, w = self.depth.shape
        s = self.stats
        return (f"RenderResult({w}x{h}, method={s.get('method')!r}, hits={s.get('hits')}, "
                f"seconds={s.get('seconds', {}).get('total', float('nan')):.3g}"
                + (", work" if self.work is not None else "") + ")")


PARC_BUFFERS = ("depth", "bits")

#: Buffers used unless asked: the bit planes are exact, but the per-cell
#: skip table already skips every sample they would, and they cost
#: a raster pass and a test per sample (CT head, ct_skin_bone, 300x300,
#: `parc compare`, 2026-11-28: depth 0.025 s a frame, depth+bits 0.031 s).
DEFAULT_BUFFERS = ("depth",)


def render(scene: Scene, method: str = "brute", *, supercell=None, buffers=DEFAULT_BUFFERS,
           progress=None, light_buffer=None, blocks=True, work=False) -> RenderResult:
    """Ray cast a scene.

    Parameters
    ----------
    scene : Scene
    method : {"brute", "parc"}
        ``"brute"`` casts every ray through the whole volume (the
        unaccelerated reference). ``"parc"`` rasterizes the outer faces of
        the possibly contributing supercells with OpenGL and casts only each
        ray's ``[near, far]`` segment, with the same traversal, intersection
        and sampling code, so the images are the same.
    supercell : float or (m, n, p), optional
        PARC's supercell size in cells (fractional and below 1 allowed).
        Like ``buffers``, ``light_buffer`` and ``blocks``, checked but not
        used by ``"brute"``, so one set of arguments serves both methods.
        Default: chosen by `parc.costmodel.choose_supercell`'s cost model.
    buffers : subset of ("depth", "bits"), or a string, default ("depth",)
        PARC's buffers for translucent volumes (a string names them as
        ``--buffers`` does: ``"depth"``, ``"bits"``, ``"depth,bits"``;
        ``+`` joins them too): near/far ray distances
        (depth-buffer PARC, §3) and planes of supercells the ray meets
        (color-buffer PARC, §4). Bit planes are drawn for translucent
        volumes; isosurfaces use the depth buffers (a scene of
        isosurfaces alone asked for bit planes, or one with isosurfaces
        asked for ``"bits"`` without ``"depth"``, is an error).
    progress : callable(done_fraction) or None
        Called with 0.0 as the render starts, then with the fraction done, rising to 1.0
        (said once), as bands of image rows and runs of shadow rays finish. Raising in it
        stops the render. A first render of a kind (an isosurface, a translucent volume,
        shadows, a new type of samples) compiles its kernels once on a machine, 10 to 60 s,
        most of it before the first fraction (a scene's lighting and shadow kernels compile
        as it reaches them); the command line says so, and the logger ``parc`` at INFO.
    light_buffer : int, optional
        Side in pixels of PARC's light buffers for shadow rays, a whole number from 2 to
        `MAX_LIGHT_BUFFER`, 8192 (default 256, `parc.lights.LIGHT_BUFFER_SIZE`). Any size gives
        the same image; finer buffers give shorter shadow-ray segments for more raster time.
    blocks : bool, default True
        PARC only: inside its segments the caster also jumps across cubes
        of cells that cannot contribute (all above or all below the
        isovalue, or all transparent) and steps over single such cells
        without reading their samples (a skip table with one entry per
        cell, `parc.skip`: by ray octant for an isosurface's camera rays),
        built once per transfer function, and per isovalue for shadow rays;
        the camera rays' tables by octant from an isovalue's second frame on
        (one frame does not repay them; `parc.compare` builds them from its
        first, `parc.skip.expect_frames`).
        The image is the same either way; False measures the OpenGL
        segments alone.
    work : bool, default False
        Also return each pixel's work (`RenderResult.work`), for scenes
        whose volumes are all isosurfaces (cells) or all translucent
        (samples). Copied out after the frame is timed; a scene of several
        volumes, or lit, adds each volume's within the frame (an
        addition over the pixels, per volume).

    Returns
    -------
    RenderResult
        ``image`` (H, W, 4) float32, premultiplied RGBA (`RenderResult.save` writes it as a
        PNG), ``depth``, ``stats`` and, asked for, ``work``.

    Raises
    ------
    InputError
        An unknown method, a scene this renderer cannot show, or an image
        too large for the memory available (`parc.workspace.check_frame_memory`),
        or light buffers too large for it (give a smaller ``light_buffer``).
    OpenGLUnavailable
        ``method="parc"`` without an OpenGL context.

    Notes
    -----
    Any thread may render; renders run one at a time (each uses every
    core already), and a render called from another's progress callback is
    refused. OpenGL work stays on the thread that first did it
    (`parc.gl.get_context`): ``method="parc"`` renders from another thread
    are refused while that thread runs, and move the context once it has ended.

    References
    ----------
    Parker et al. 1998, §2 and Appendix A (traversal, intersection, normals);
    Sobierajski & Avila 1995, §3 (depth-buffer PARC), §4 (color-buffer PARC) and §5 (shadow rays).
    """
    # Renders share work arrays, Numba's thread pool and one OpenGL context: one at a time.
    with RENDER_LOCK, _logging_compiles():
        if _RENDERING[0]:
            raise InputError("render was called while a render is under way (from its progress callback); "
                             "renders share their work arrays: render once it has returned")
        _RENDERING[0] = True
        try:
            return _render(scene, method, supercell, buffers, progress, light_buffer, blocks, work)
        finally:
            _RENDERING[0] = False
            # Let go, so that the context can move to another thread once this one ends.
            release_context()


#: The library's log: a render's first compile is told at INFO (the command line says it itself).
LOG = logging.getLogger("parc")


def _logging_compiles():
    """Log at INFO, once a render, that the render compiles kernels, as it starts to: a first
    render of a kind waits 10 to 60 s for them, silent otherwise. Nothing is installed
    where INFO is not logged."""
    if not LOG.isEnabledFor(logging.INFO):
        return contextlib.nullcontext()
    from raycast.kernel_cache import cache_refused

    from .outputs import on_first_compile

    def log():
        refused = cache_refused()
        LOG.info("compiling the ray casters for this kind of render and sample type (10 to 60 s), "
                 + (f"in every run: {refused} cannot be written" if refused else "once on this machine"))
    return on_first_compile(log)


def check_request(scene, buffers, work, names=("buffers", "work")):
    """The buffers parsed, or what a render of ``scene`` refuses about them and the work map:
    the command line asks before its compile notice, so that a refusal is its only line, and
    names them by its flags (``names``)."""
    buffers = parse_buffers(buffers)
    if "depth" not in buffers and any(isinstance(v, Isosurface) for v in scene.volumes):
        both = any(isinstance(v, Translucent) for v in scene.volumes) and not bits_refused(scene)
        raise InputError(f"{names[0]} {','.join(buffers)} leave out the depth buffers isosurfaces use; "
                         f"bit planes apply to translucent volumes: give {names[0]} "
                         + ("depth,bits for both" if both else "depth"))
    # "depth,bits" for isosurfaces alone would otherwise leave the planes out without a word.
    if "bits" in buffers and (why := bits_refused(scene)):
        raise InputError(f"{names[0]} {','.join(buffers)}: {why}")
    if work and len({isinstance(v, Isosurface) for v in scene.volumes}) > 1:
        # Cells and samples cost unlike amounts: a sum of the two would map neither.
        raise InputError(f"{names[1]}: per-pixel work counts cells visited for isosurfaces and samples taken "
                         "for translucent volumes, and this scene has both; give each kind a scene of its own")
    return buffers


def check_arguments(scene, method="brute", *, supercell=None, buffers=DEFAULT_BUFFERS, progress=None,
                    light_buffer=None, blocks=True, work=False):
    """What `render` refuses about its arguments, checked before any work (`parc.compare` asks for
    each method's options before its first render): ``(buffers, light_buffer)`` as parsed."""
    if not isinstance(scene, Scene):
        raise InputError(f"render takes a Scene, got {type(scene).__name__}")
    if not isinstance(method, str) or method not in METHODS:
        raise InputError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if not isinstance(blocks, (bool, np.bool_)):
        raise InputError(f"blocks must be True or False, got {blocks!r}")
    if not isinstance(work, (bool, np.bool_)):
        raise InputError(f"work must be True or False, got {work!r}")
    if progress is not None and not callable(progress):
        raise InputError(f"progress must be a function of the fraction done, got {progress!r}")
    if supercell is not None:
        # Its grid over each volume too (too many supercells), for brute as well: one set of
        # arguments serves both methods, and either refuses it alike.
        from .classify import VolumeIndex
        for vis in scene.volumes:
            VolumeIndex.of(vis.volume).grid(supercell)
    return check_request(scene, buffers, work), _light_buffer_size(light_buffer)


def _render(scene, method, supercell, buffers, progress, light_buffer, blocks, work):
    buffers, light_buffer = check_arguments(scene, method, supercell=supercell, buffers=buffers, progress=progress,
                                            light_buffer=light_buffer, blocks=blocks, work=work)
    skip_blocks = method == "parc" and bool(blocks)
    check_scene_memory(scene)
    if progress is not None:
        progress(0.0)           # begun: a first render may compile for a minute before its first band
    if not _casts_alone(scene):
        return _render_general(scene, method, supercell, buffers, progress, light_buffer, skip_blocks, work)
    vis = scene.volumes[0]
    timings = {}
    t0 = time.perf_counter()
    seg = NO_SEGMENTS
    use_seg = method == "parc"
    planes = None
    extra = {}
    if method == "parc":
        if isinstance(vis, Isosurface) or "depth" in buffers:
            seg, extra, proxy = parc_segments(scene, vis, supercell, timings)
        else:
            use_seg = False
            proxy, extra = cached_proxy(vis, supercell, scene.size, timings)
        if isinstance(vis, Translucent) and "bits" in buffers:
            from .bitplanes import frame_planes
            planes = frame_planes(scene, vis, proxy, timings, extra)
        extra["buffers"] = list(buffers) if isinstance(vis, Translucent) else ["depth"]
        extra["blocks"] = skip_blocks
    if isinstance(vis, Isosurface):
        image, depth, counts = _render_iso(scene, vis, seg, use_seg, skip_blocks, timings, progress)
    elif isinstance(vis, Translucent):
        image, depth, counts = _render_translucent(scene, vis, seg, use_seg, skip_blocks, timings, progress,
                                                   planes)
    else:
        raise InputError(f"cannot render a {type(vis).__name__}; give an Isosurface or a Translucent")
    if scene.background is not None:
        over_background(image, _premultiplied(scene.background))
    timings["total"] = time.perf_counter() - t0
    w, h = scene.size
    stats = {
        "method": method,
        "seconds": timings,
        "pixels": w * h,
        "rays": w * h,
        "hits": counts["hits"],
        "cells_visited": counts.get("cells", 0),
        "cubic_solves": counts.get("solves", 0),
        "samples": counts.get("samples", 0),
        "polygons": 0,              # brute draws none; parc's count comes with `extra`
        # A volume cast alone casts no shadow rays; the keys are there, as in every render's stats.
        "shadow_rays": 0, "shadow_cells": 0, "shadow_solves": 0, "shadow_samples": 0, "light_polygons": 0,
        "parameters": {**describe_view(scene), **describe_volume(vis)},
    }
    stats.update(extra)
    stats["polygons"] = extra.get("polygons", 0) + extra.get("plane_polygons", 0)
    per_pixel = counts["per_pixel"].reshape(h, w).copy() if work else None
    return RenderResult(image=image, depth=depth, stats=stats, work=per_pixel)


def _render_general(scene, method, supercell, buffers, progress, light_buffer, skip_blocks, work):
    """Several volumes, an isosurface with lights, or shaded samples with shadows
    (`_casts_alone`): `parc.multivolume.render_scene`, with the same stats."""
    from .lights import LIGHT_BUFFER_SIZE
    from .multivolume import render_scene

    n = LIGHT_BUFFER_SIZE if light_buffer is None else light_buffer
    t0 = time.perf_counter()
    image, depth, counts, timings, extra = render_scene(scene, method, supercell=supercell, progress=progress,
                                                        light_buffer=n, blocks=skip_blocks, work=work,
                                                        buffers=buffers)
    if scene.background is not None:
        over_background(image, _premultiplied(scene.background))
    timings["total"] = time.perf_counter() - t0
    w, h = scene.size
    stats = {
        "method": method,
        "seconds": timings,
        "pixels": w * h,
        "rays": w * h,
        "hits": int(np.isfinite(depth).sum()),
        "cells_visited": counts["cells"],
        "cubic_solves": counts["solves"],
        "samples": counts["samples"],
        "shadow_rays": counts["shadow_rays"],
        "shadow_cells": counts["shadow_cells"],
        "shadow_solves": counts["shadow_solves"],
        "shadow_samples": counts["shadow_samples"],
        "light_polygons": counts["light_polygons"],
        "parameters": {"lights": [], **describe_view(scene), "shadows": scene.shadows,
                       "volumes": [describe_volume(v) for v in scene.volumes]},
    }
    stats["polygons"] = (sum(v.get("polygons", 0) for v in extra["volumes"]) + counts["light_polygons"]
                         if method == "parc" else 0)
    if method == "parc":            # as asked, as a volume cast alone records them
        translucent = any(isinstance(v, Translucent) for v in scene.volumes)
        stats.update(buffers=list(buffers) if translucent else ["depth"], blocks=skip_blocks)
    stats.update(extra)
    per_pixel = counts["per_pixel"].reshape(h, w) if work else None
    return RenderResult(image=image, depth=depth, stats=stats, work=per_pixel)


def _render_iso(scene, iso, seg, use_seg, skip_blocks, timings, progress):
    vol = iso.volume
    w, h = scene.size
    t0 = time.perf_counter()
    cam = scene.camera.as_array()
    org = np.array(vol.origin)
    spc = np.array(vol.spacing)
    t = np.empty(w * h)
    cell, uvw, counts = iso_work(w * h)
    skip, jump_min = octant_skip_tables(iso, skip_blocks, scene.camera, w, h)
    image = np.zeros((h, w, 4), np.float32)
    color = np.array(iso.color, dtype=np.float64)
    material = np.array(iso.material, dtype=np.float64)
    timings["setup"] = time.perf_counter() - t0

    # The cast shades each hit as it finds it (the phase holds both).
    t0 = time.perf_counter()
    bands = row_bands(h, w, progress)
    totals = np.zeros(3, np.int64)
    for n, (y0, y1) in enumerate(bands):
        totals += cast_iso_image(vol.data, org, spc, cam, w, h, iso.value, seg, use_seg, skip, jump_min,
                                 t, cell, uvw, counts, y0, y1, True, color, material, image)
        if progress is not None:
            progress((n + 1) / len(bands))
    timings["cast"] = time.perf_counter() - t0
    hits, cells, solves = (int(v) for v in totals)
    return image, t.reshape(h, w), {"hits": hits, "cells": cells, "solves": solves, "per_pixel": counts[:, 0]}


#: Largest side of a light buffer, pixels (a buffer per light and view face).
MAX_LIGHT_BUFFER = 8192


def _light_buffer_size(light_buffer):
    """``light_buffer`` checked: None (the default) or a whole number of pixels, 2 to `MAX_LIGHT_BUFFER`."""
    if light_buffer is None:
        return None
    if (isinstance(light_buffer, (bool, np.bool_)) or not isinstance(light_buffer, (int, np.integer))
            or not 2 <= light_buffer <= MAX_LIGHT_BUFFER):
        raise InputError(f"light buffers take a whole number of pixels from 2 to {MAX_LIGHT_BUFFER}, "
                         f"got {light_buffer!r}")
    return int(light_buffer)


def kernel_samples(scene, methods=("brute",), buffers=DEFAULT_BUFFERS, repeated=False):
    """The Numba kernels rendering ``scene`` with ``methods`` runs whose first compile takes
    seconds, for `parc.outputs.compile_notice`: the casters, and with PARC its own (the
    segments' unpacking, the skip tables), which compile for seconds even once `brute`'s are
    cached. Only kernels this scene compiles: one it never uses would announce a compile every run.
    ``repeated``: the scene is rendered again, as `parc.compare` does (`parc.skip.expect_frames`),
    so its isosurfaces' skip tables by octant are built; a single frame builds them only for an
    isovalue of a volume that the scene shows twice.

    Each comes with the Numba types of the samples it is called with (its first argument),
    one per call it compiles for (none for a kernel that takes no samples): Numba compiles a
    kernel for each, the CT head's int16 after uint8, or four volumes merged after three."""
    pairs = _casters_for(scene, methods, buffers)
    if "parc" in methods:
        from . import raster, skip
        kernels = []
        if len(scene.volumes) > 1 or "depth" in parse_buffers(buffers):
            kernels.append(raster.unpack_segments)
        if _octant_tables_built(scene, repeated):
            kernels += skip.OCTANT_KERNELS          # the camera rays' tables
        if any(isinstance(v, Translucent) for v in scene.volumes) or (scene.shadows and scene.lights):
            kernels += skip.CENTRED_KERNELS         # translucent volumes', shadow rays'
        pairs += [(k, ()) for k in kernels]
    return pairs


def _octant_tables_built(scene, repeated):
    """Whether rendering ``scene`` builds skip tables by octant: they wait for an isovalue's
    second frame (`parc.classify.VolumeIndex.iso_octant_skip`), which one frame gives only to a
    volume shown twice at the same isovalue."""
    asks = [(id(v.volume), float(v.value)) for v in scene.volumes if isinstance(v, Isosurface)]
    return bool(asks) and (repeated or len(set(asks)) < len(asks))


def _casters_for(scene, methods, buffers):
    """The casters alone, with their samples' types, as `kernel_samples` gives them."""
    import numba
    from numba.core import types
    from raycast import composite, iso, merged, shadow

    def of(volumes):
        return tuple({numba.typeof(v.volume.data) for v in volumes})

    bits = "parc" in methods and "bits" in parse_buffers(buffers)
    trans = [v for v in scene.volumes if isinstance(v, Translucent)]
    isos = [v for v in scene.volumes if not isinstance(v, Translucent)]
    if _casts_alone(scene):
        if not trans:
            return [(iso.cast_iso_image, of(isos))]
        return [(composite._IMAGE_CASTERS[bool(trans[0].shade), bits], of(trans))]
    # The frames and shadow rays run only for surfaces that some pixel sees: asked for every
    # volume's samples, a surface out of sight said it compiled on every run. The casters,
    # which run for every volume, are asked for its samples.
    kernels = [(iso.cast_iso_image, of(isos)), (shadow.surface_frames, ())] if isos else []
    if isos and scene.shadows and scene.lights:
        kernels += [(shadow.shadow_iso, ())] + ([(shadow.shadow_accumulate, ())] if trans else [])
    sample_shadows = shadowed_samples(scene)
    if sample_shadows:
        kernels += [(shadow.combine_samples, ()), (shadow.shadow_accumulate, ())]
        kernels += [(shadow.shadow_iso, ())] if isos else []
    layers = [v for v in trans if v.mode != "composite"]
    if layers:
        kernels.append((composite._IMAGE_CASTERS[False, bits], of(layers)))
    comp = [v for v in trans if v.mode == "composite"]
    if comp:
        # One tuple of the volumes' samples, converted to one type (`parc.multivolume`).
        one = np.empty((1, 1, 1), np.result_type(*(v.volume.data.dtype for v in comp)))
        one.flags.writeable = False
        shaded = any(v.shade for v in trans) and not sample_shadows
        kernels.append((merged._MERGED_CASTERS[shaded, sample_shadows, bits],
                        (types.UniTuple(numba.typeof(one), len(comp)),)))
    return list(dict.fromkeys(kernels))


def _premultiplied(background):
    """A scene's background, given as colour and alpha, as the image holds colour: times alpha."""
    r, g, b, a = background
    return np.array([r * a, g * a, b * a, a], np.float32)


def _casts_alone(scene):
    """Whether `render` casts the scene's one volume with its own driver: all but several
    volumes, an isosurface with lights, and shaded samples with shadows (`_render_general`). A
    translucent volume lights its samples in its own walk where they cast no shadow rays."""
    return (len(scene.volumes) == 1 and not (scene.lights and isinstance(scene.volumes[0], Isosurface))
            and not shadowed_samples(scene))


def bits_refused(scene):
    """Why ``scene`` cannot use bit planes, or None: they are drawn for translucent volumes, and
    a scene's isosurfaces keep their depth buffers."""
    if any(isinstance(v, Translucent) for v in scene.volumes):
        return None
    what = "an isosurface" if len(scene.volumes) == 1 else "isosurfaces alone"
    return f"bit planes are drawn for translucent volumes, and this scene has {what}; use depth"


def parse_buffers(buffers):
    """PARC's buffers as a tuple of names from `PARC_BUFFERS`: from a sequence of names, or a
    string naming them as ``--buffers`` does (``"depth"``, ``"depth,bits"``; ``+`` joins too)."""
    parts = buffers.replace("+", ",").split(",") if isinstance(buffers, str) else buffers
    try:
        names = tuple(str(b).strip() for b in parts)
    except TypeError:
        names = ()
    if not names or set(names) - set(PARC_BUFFERS):
        raise InputError(f"PARC buffers must be {', '.join(PARC_BUFFERS)} or both (depth,bits), got {buffers!r}")
    return names


def accumulation_params(vis, lights=()):
    """The ``params`` array of `raycast.composite` for a Translucent volume, its shaded samples
    lit by ``lights`` (a scene's; none: the headlight, `parc.lights.light_array`)."""
    from .transfer import reference_step
    rows = light_array(lights)
    p = np.zeros(N_PARAMS + rows.size)
    p[P_STEP] = vis.step
    p[P_MODE] = _MODES[vis.mode]
    p[P_THRESHOLD] = vis.threshold
    p[P_RATIO] = vis.step / reference_step(vis.volume.spacing)
    p[P_SHADE] = 1.0 if vis.shade else 0.0
    p[P_LO], p[P_HI] = vis.volume.value_range()
    p[P_AMBIENT:P_AMBIENT + 4] = vis.material
    p[P_ORIGIN:P_ORIGIN + 3] = vis.volume.origin
    p[P_LIGHT_COUNT] = len(rows)
    p[P_LIGHTS:] = rows.ravel()
    return p


def _render_translucent(scene, vis, seg, use_seg, skip_blocks, timings, progress, planes=None):
    vol = vis.volume
    w, h = scene.size
    t0 = time.perf_counter()
    cam = scene.camera.as_array()
    org = np.array(vol.origin)
    spc = np.array(vol.spacing)
    params = accumulation_params(vis, scene.lights)
    op_x, op_y, col_x, col_rgb = vis.tf.arrays()
    image = np.empty((h, w, 4), np.float32)
    counts = work_array("samples", (w * h,), np.int64)
    use_bits = planes is not None
    skip, jump_min = skip_table(vis, skip_blocks)
    bits = NO_BITS
    if use_bits:
        planes.set_params(params)
        bits = planes.bits
    timings["setup"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    bands = row_bands(h, w, progress)
    samples = 0
    for n, (y0, y1) in enumerate(bands):
        samples += cast_accumulate_image(vol.data, org, spc, cam, w, h, params, op_x, op_y, col_x, col_rgb,
                                         seg, use_seg, NO_STOP, False, bits, use_bits, skip, jump_min, image,
                                         counts, y0, y1)
        if progress is not None:
            progress((n + 1) / len(bands))
    timings["cast"] = time.perf_counter() - t0
    return image, np.full((h, w), np.inf), {"hits": 0, "samples": int(samples), "per_pixel": counts}
