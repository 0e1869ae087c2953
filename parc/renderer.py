"""Render a scene: cast every pixel (unaccelerated, or over PARC's ray segments), then shade."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from data_tools import InputError
from raycast.iso import cast_iso_image, empty_outputs
from raycast.shade import shade_headlight

from .scene import Isosurface, Scene

METHODS = ("brute", "parc")

#: Proxies kept per volume (isovalue, supercell size) so that only a camera
#: change re-rasterizes; a few entries cover flipping between skin and bone.
PROXY_CACHE_SIZE = 4


@dataclass
class RenderResult:
    """What `render` returns.

    Attributes
    ----------
    image : ndarray (H, W, 4) float32
        Premultiplied RGBA in [0, 1].
    depth : ndarray (H, W) float64
        World distance ``t`` along each pixel's ray to the first opaque hit, ``inf`` where none.
    stats : dict
        ``method``, ``seconds`` per phase, ``pixels``, ``rays``, ``cells_visited``,
        ``cubic_solves``, ``hits`` and the parameters used.
    """

    image: np.ndarray
    depth: np.ndarray
    stats: dict


def render(scene: Scene, method: str = "brute", *, supercell=None, progress=None) -> RenderResult:
    """Ray cast a scene.

    Parameters
    ----------
    scene : Scene
    method : {"brute", "parc"}
        ``"brute"`` walks every cell along every ray inside the volume
        (the unaccelerated reference). ``"parc"`` rasterizes the outer faces
        of the possibly contributing supercells with OpenGL and walks only
        each ray's ``[near, far]`` segment, with the same traversal and
        intersection code, so the images are the same.
    supercell : float or (m, n, p), optional
        PARC's supercell size in cells (fractional and below 1 allowed).
        Default: chosen by `parc.classify.choose_supercell`'s cost model.
    progress : callable(done_fraction) or None
        Called as bands of image rows finish, for long renders.

    Returns
    -------
    RenderResult

    Raises
    ------
    InputError
        An unknown method or a scene this renderer cannot show.

    References
    ----------
    Parker et al. 1998, §2 and Appendix A (traversal, intersection, normals);
    Sobierajski & Avila 1995, §3 (depth-buffer PARC).
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if len(scene.volumes) != 1 or not isinstance(scene.volumes[0], Isosurface):
        raise InputError("this renderer shows one isosurface per scene")
    iso = scene.volumes[0]
    vol = iso.volume
    w, h = scene.size
    timings = {}
    t0 = time.perf_counter()
    cam = scene.camera.as_array()
    org = np.array(vol.origin)
    spc = np.array(vol.spacing)
    t, cell, uvw, counts = empty_outputs(w * h)
    seg = np.empty((1, 1, 2))
    timings["setup"] = time.perf_counter() - t0
    extra = {}
    if method == "parc":
        seg, extra = _parc_segments(scene, iso, supercell, timings)

    t0 = time.perf_counter()
    bands = _row_bands(h, w, progress)
    for n, (y0, y1) in enumerate(bands):
        cast_iso_image(vol.data, org, spc, cam, w, h, iso.value,
                       seg, method == "parc", t, cell, uvw, counts, y0, y1)
        if progress is not None:
            progress((n + 1) / len(bands))
    timings["cast"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    image = np.zeros((h, w, 4), np.float32)
    shade_headlight(vol.data, spc, cam, w, h, t, cell, uvw,
                    np.array(iso.color), np.array(iso.material, dtype=np.float64), image)
    if scene.background is not None:
        bg = np.asarray(scene.background, np.float32)
        image += (1.0 - image[..., 3:4]) * bg
    timings["shade"] = time.perf_counter() - t0
    timings["total"] = sum(timings.values())

    stats = {
        "method": method,
        "seconds": timings,
        "pixels": w * h,
        "rays": w * h,
        "hits": int(np.isfinite(t).sum()),
        "cells_visited": int(counts[:, 0].sum()),
        "cubic_solves": int(counts[:, 1].sum()),
        "parameters": {"isovalue": iso.value, "size": [w, h], "volume": vol.name,
                       "dims": list(vol.dims), "dtype": str(vol.dtype)},
    }
    stats.update(extra)
    return RenderResult(image=image, depth=t.reshape(h, w), stats=stats)


def _parc_segments(scene, iso, supercell, timings):
    """Classify, build (or reuse) the proxy and rasterize it: the per-pixel segments and stats."""
    from .classify import VolumeIndex, _size_triple, choose_supercell
    from .proxy import build_proxy
    from .raster import raster_segments

    vol = iso.volume
    w, h = scene.size
    t0 = time.perf_counter()
    index = VolumeIndex.of(vol)
    extra = {}
    if supercell is None:
        # The model classifies every candidate size: do it once per isovalue and image size.
        chosen = index.__dict__.setdefault("_chosen", {})
        if (iso.value, w * h) not in chosen:
            chosen[(iso.value, w * h)] = choose_supercell(index, iso.value, pixels=w * h)
        supercell, table = chosen[(iso.value, w * h)]
        extra["supercell_model"] = table
    size = _size_triple(supercell)
    key = (size, iso.value)
    proxies = index.__dict__.setdefault("_proxies", {})
    proxy = proxies.get(key)
    if proxy is None:
        pc = index.classify(iso.value, size)
        timings["classify"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        grid = index.grid(size)
        proxy = build_proxy(grid, pc, grid.world_edges(vol))
        if len(proxies) >= PROXY_CACHE_SIZE:
            proxies.pop(next(iter(proxies)))
        proxies[key] = proxy
        timings["proxy"] = time.perf_counter() - t0
    else:
        timings["classify"] = time.perf_counter() - t0
        timings["proxy"] = 0.0
    segs = raster_segments(scene.camera, w, h, proxy)
    timings["raster"] = segs.seconds["total"]
    extra.update({
        "supercell": list(size),
        "polygons": segs.polygons,
        "pc_supercells": int(proxy.pc.sum()),
        "supercells": int(proxy.pc.size),
        "segment_pixels": int((segs.near <= segs.far).sum()),
        "raster_seconds": dict(segs.seconds),
    })
    return segs.seg, extra


def _row_bands(h, w, progress):
    """Row ranges cast one call at a time: one band, or ~16 when progress is reported."""
    if progress is None or w * h < 250_000:
        return [(0, h)]
    step = max(4, -(-h // 16))
    step += (-step) % 4
    return [(y, min(h, y + step)) for y in range(0, h, step)]
