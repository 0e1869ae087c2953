"""PARC's ray segments for one volume: the proxy of its possibly contributing supercells,
classified and built (or taken from the volume's caches), then rasterized.

Shared by `parc.renderer`, `parc.multivolume` (the light buffers take the proxy
alone, unmerged) and the benchmarks.
"""
from __future__ import annotations

import time

import numba

from .scene import Isosurface
from .workspace import work_array

#: Proxies kept per volume (classification, supercell size, faces merged or
#: not: the camera's and the light buffers'), least recently used dropped
#: first, so that only a camera change re-rasterizes: enough for
#: flipping between skin and bone, and for a supercell sweep, whose methods
#: take turns repeat by repeat (with 4 entries, a sweep of five sizes would
#: rebuild every proxy every frame, and time it).
PROXY_CACHE_SIZE = 8


def classifier(index, vis):
    """``(key, classify(size) -> bool array)`` of the possibly contributing supercells."""
    from .classify import classify_tf, tf_key
    if isinstance(vis, Isosurface):
        return ("iso", vis.value), lambda size: index.classify(vis.value, size)
    return tf_key(vis.tf), lambda size: classify_tf(*index.ranges(size), vis.tf)


def parc_segments(scene, vis, supercell, timings, slot=0):
    """The proxy (built or reused) rasterized: per-pixel segments, stats and the proxy.

    The segments are written into a work array (`parc.workspace`); ``slot``
    tells apart the volumes of one frame.
    """
    from .raster import raster_segments

    w, h = scene.size
    proxy, extra = cached_proxy(vis, supercell, scene.size, timings)
    segs = raster_segments(scene.camera, w, h, proxy, out=work_array(("seg", slot), (h, w, 2)))
    timings["raster"] = segs.seconds["total"]
    extra.update({"polygons": segs.polygons,
                  "segment_pixels": segs.info["pixels"],
                  "raster_seconds": dict(segs.seconds)})
    return segs.seg, extra, proxy


def cached_proxy(vis, supercell, size_px, timings, *, merge=True):
    """Classify and build (or reuse) the outer-face proxy of the possibly contributing supercells.

    ``merge=False`` keeps one face per supercell face (the light buffers' proxy, `parc.lights`).
    """
    from .classify import VolumeIndex
    from .ranges import supercell_size
    from .costmodel import choose_supercell
    from .proxy import build_proxy

    vol = vis.volume
    w, h = size_px
    t0 = time.perf_counter()
    index = VolumeIndex.of(vol)
    what, classify = classifier(index, vis)
    extra = {}
    if supercell is None:
        # The model classifies every candidate size: do it once per classification and image size.
        chosen = index.kept("supercell size")
        key = (what, w * h, numba.get_num_threads())
        if key not in chosen:
            chosen[key] = choose_supercell(index, classify=classify, pixels=w * h)
        supercell, table = chosen[key]
        # A copy: the caller's stats are theirs to change, the kept table is not.
        extra["supercell_model"] = [dict(row) for row in table]
    size = supercell_size(supercell)
    proxies = index.kept("proxies")
    key = (size, what, merge)
    proxy = proxies.pop(key, None)
    if proxy is not None:
        proxies[key] = proxy    # now the most recently used
        timings["classify"] = time.perf_counter() - t0
        timings["proxy"] = 0.0
    else:
        pc = classify(size)
        timings["classify"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        grid = index.grid(size)
        proxy = build_proxy(grid, pc, grid.world_edges(vol), merge=merge)
        if len(proxies) >= PROXY_CACHE_SIZE:
            proxies.pop(next(iter(proxies)))
        proxies[key] = proxy
        timings["proxy"] = time.perf_counter() - t0
    extra.update({"supercell": list(size), "pc_supercells": int(proxy.pc.sum()),
                  "supercells": int(proxy.pc.size)})
    return proxy, extra
