"""Scenes with several volumes, lights and shadows: per-volume casting, then depth-ordered compositing.

How a pixel is made
-------------------
1. Every isosurface volume is cast on its own (`raycast.iso.cast_iso_image`,
   over its PARC segments with ``method="parc"``); the nearest hit wins
   (ties: the volume listed first) and gives the pixel's depth.
2. The hit is lit by every light (the headlight when there is none):
   ambient plus, per light, Blinn-Phong diffuse and specular times the
   light's colour and the light's visibility. With ``scene.shadows``, a
   shadow ray from the hit towards each light that faces it finds that
   visibility: 0 behind any isosurface of any volume, else the product of
   ``1 - a`` over the translucent volumes it crosses
   (`raycast.shadow`). With ``method="parc"`` the shadow rays walk only the
   segments the light buffers give (`parc.lights`).
3. Translucent volumes are sampled up to the depth (nothing behind an
   opaque surface shows): composite volumes together, their samples merged
   in order of ``t`` so that overlapping volumes interleave
   (`raycast.merged.cast_merged_image`); a maximum- or average-intensity
   volume is a finished layer placed where the ray enters its box (before
   samples there of volumes listed after it, behind those of volumes
   listed before). The result goes over the lit surface.
4. With shadows, the shaded samples of composite volumes are lit last: the
   walk records them (their weights in the pixel depend on opacities
   alone), a shadow ray from each towards each light finds its visibility
   as a hit's does, and their lit colours are added to their pixels
   (`_light_samples`).

Both methods run exactly this code; ``"parc"`` only narrows the segments
(primary rays from the camera's buffers, shadow rays from the lights'),
so the images are the same.
"""
from __future__ import annotations

import time
import weakref

import numpy as np

from data_tools.memory import check_memory
from raycast.composite import box_entry_image, cast_accumulate_image
from raycast.merged import SampleRecord, cast_merged_image
from raycast.iso import NO_SHADING, cast_iso_image, keep_nearest
from raycast.shadow import (combine_lights, combine_samples, light_terms, shadow_accumulate, shadow_iso,
                            surface_frames)

from .lights import (LIGHT_BUFFER_CACHE_SIZE, LIGHT_BUFFER_SIZE, buffer_bytes, light_array, light_buffers,
                     light_cache_bytes, light_views, no_views)
from .scene import DirectionalLight, Isosurface
from .workspace import (LIGHT_BYTES_PER_PIXEL, NO_BITS, NO_SEGMENTS, SAMPLE_BYTES, column_totals, iso_work, row_bands,
                        shadowed_samples, work_array)

#: Shadow rays start this far (times the smallest spacing of the surface they leave) from their hit point.
SHADOW_EPS = 1e-5
#: ... or this far times the largest coordinate of that volume, where that is more: a hit point far
#: from the world's origin is only known to its coordinates' rounding (4.8e-7 at 4e9).
SHADOW_EPS_OF_COORDINATES = 2.0 ** -40


def shadow_eps(volume):
    """How far from a hit point on ``volume`` its shadow rays start, and end short of a point light."""
    lo, hi = volume.bounds
    return max(SHADOW_EPS * min(volume.spacing),
               SHADOW_EPS_OF_COORDINATES * float(np.max(np.maximum(np.abs(lo), np.abs(hi)))))



def render_scene(scene, method, *, supercell=None, progress=None, light_buffer=LIGHT_BUFFER_SIZE, blocks=True,
                 work=False, buffers=("depth",)):
    """Render any scene (`parc.render` calls this for several volumes, an isosurface with lights, or
    shaded samples with shadows: `parc.renderer._casts_alone`).

    Returns ``(image, depth, counts, timings, extra)``: the float32 RGBA
    image (without background), the ``(H, W)`` depth, the counters
    (cells, solves, samples, shadow_cells, shadow_solves, shadow_samples,
    shadow_rays, and light_polygons: the faces of the light buffers drawn
    this frame), seconds per phase and per-volume PARC details. ``blocks``:
    PARC's walks and shadow rays skip the volumes' empty cells
    (`parc.renderer.render`). With ``work``, ``counts["per_pixel"]`` holds
    each pixel's camera-ray work, every volume's added: the cells its
    isosurfaces' walks visited and the samples its translucent volumes'
    walks took (shadow rays' work is in the totals only). ``buffers``: PARC's buffers for the
    translucent volumes, as `parc.renderer.render` takes them (parsed); isosurfaces use their
    depth buffers.

    The frame goes through the module docstring's steps, a function each:
    the camera's buffers (`_camera_buffers`), the surfaces (`_cast_surfaces`),
    their lighting (`_light_hits`), the translucent volumes in front of them
    (`_cast_translucent`).
    """
    frame = _Frame(scene, method, supercell, progress, light_buffer, blocks, work)
    h, w = frame.h, frame.w
    segs, planes, extra = _camera_buffers(frame, buffers)
    frame.report.done("buffers")
    depth, hits = _cast_surfaces(frame, segs)
    frame.report.done("surfaces")
    image = _light_hits(frame, depth, *hits)
    frame.report.done("lighting")
    if frame.trans:
        image = _cast_translucent(frame, segs, planes, depth.reshape(h, w), image)
    frame.report.done("sample shadows")          # the last phase: its end is 1
    return image, depth.reshape(h, w), frame.counts, frame.timings, extra


class _Frame:
    """What every step of one `render_scene` frame reads, and the counts and seconds they add to."""

    def __init__(self, scene, method, supercell, progress, light_buffer, blocks, work):
        self.scene = scene
        self.parc = method == "parc"
        self.supercell = supercell
        self.light_buffer = light_buffer
        self.blocks = blocks
        self.w, self.h = scene.size
        self.npx = self.w * self.h
        self.cam = scene.camera.as_array()
        self.bands = row_bands(self.h, self.w, progress)
        self.isos = [(n, v) for n, v in enumerate(scene.volumes) if isinstance(v, Isosurface)]
        self.trans = [(n, v) for n, v in enumerate(scene.volumes) if not isinstance(v, Isosurface)]
        self.timings = {"raster": 0.0, "classify": 0.0, "proxy": 0.0}
        self.counts = dict.fromkeys(("cells", "solves", "samples", "shadow_cells", "shadow_solves",
                                     "shadow_samples", "shadow_rays", "light_polygons"), 0)
        self.per_pixel = np.zeros(self.npx, np.int64) if work else None
        self.counts["per_pixel"] = self.per_pixel
        self.sizes = {}             # each volume's supercell size, from its camera buffers
        self.report = _Report(progress, len(self.isos), len(self.trans), scene.shadows and bool(scene.lights),
                              shadowed_samples(scene))

    def add_work(self, cnt):
        if self.per_pixel is not None:
            self.per_pixel += cnt


def _camera_buffers(frame, buffers):
    """PARC's buffers from the camera, one volume at a time: depth buffers, and for translucent
    volumes bit planes too, or instead (segments then spanning every ray).

    Returns ``(segs, planes, extra)``: the segments and the bit planes of each volume by its
    index in the scene (none with ``method="brute"``), and the volumes' PARC details.
    """
    from .segments import cached_proxy, parc_segments

    h, w = frame.h, frame.w
    segs = {}
    planes = {}
    extra = {"volumes": []}
    if not frame.parc:
        return segs, planes, extra
    for n, vis in enumerate(frame.scene.volumes):
        phase = {}
        translucent = not isinstance(vis, Isosurface)
        if "depth" in buffers or not translucent:
            seg, info, proxy = parc_segments(frame.scene, vis, frame.supercell, phase, slot=n)
        else:
            proxy, info = cached_proxy(vis, frame.supercell, frame.scene.size, phase)
            seg = work_array(("seg", n), (h, w, 2))
            seg[..., 0] = -np.inf
            seg[..., 1] = np.inf
        shown = {k: info[k] for k in ("supercell", "polygons", "pc_supercells", "segment_pixels") if k in info}
        if translucent and "bits" in buffers:
            from .bitplanes import frame_planes
            planes[n] = frame_planes(frame.scene, vis, proxy, phase, shown)
            shown["polygons"] = shown.get("polygons", 0) + shown["plane_polygons"]
        for key in ("raster", "classify", "proxy", "raster_bits"):
            if key in phase:
                frame.timings[key] = frame.timings.get(key, 0.0) + phase[key]
        segs[n] = seg
        frame.sizes[n] = info["supercell"]
        extra["volumes"].append(shown)
    return segs, planes, extra


def _cast_surfaces(frame, segs):
    """Every isosurface cast on its own; the nearest hit wins.

    Returns the depth (flat, ``inf`` where nothing is hit) and ``(winner, cell, uvw)``: per pixel
    the scene index of the volume hit (-1 for none), and the hit's cell and local coordinates,
    read only where ``winner >= 0``.
    """
    from .skip import octant_skip_tables

    w, h, npx = frame.w, frame.h, frame.npx
    t0 = time.perf_counter()
    depth = np.full(npx, np.inf)
    winner = work_array("winner", (npx,), np.int64)
    winner.fill(-1)
    cell, uvw, _ = iso_work(npx, slot="nearest")
    bands = frame.bands
    for q, (n, iso) in enumerate(frame.isos):
        vol = iso.volume
        t = work_array("iso_t", (npx,))
        c, uv, cnt = iso_work(npx)
        seg = segs.get(n, NO_SEGMENTS)
        skip, jump_min = octant_skip_tables(iso, frame.parc and frame.blocks, frame.scene.camera, w, h)
        for b, (y0, y1) in enumerate(bands):
            _, cells, solves = cast_iso_image(vol.data, np.array(vol.origin), np.array(vol.spacing), frame.cam, w, h,
                                              iso.value, seg, frame.parc, skip, jump_min, t, c, uv, cnt, y0, y1,
                                              *NO_SHADING)
            frame.counts["cells"] += int(cells)
            frame.counts["solves"] += int(solves)
            frame.report.part("surfaces", (q + (b + 1) / len(bands)) / len(frame.isos))
        frame.add_work(cnt[:, 0])
        keep_nearest(t, c, uv, n, depth, cell, uvw, winner)
    frame.timings["cast"] = time.perf_counter() - t0
    return depth, (winner, cell, uvw)


def _light_hits(frame, depth, winner, cell, uvw):
    """The surfaces' hits lit by every light, shadowed where the scene asks: the ``(H, W, 4)`` image
    of the surfaces alone."""
    w, h, npx = frame.w, frame.h, frame.npx
    timings = frame.timings
    image = np.zeros((h, w, 4), np.float32)
    hit = np.flatnonzero(winner >= 0)
    # Hits grouped by volume (pixel order kept within each), so each volume's
    # surface frames are written in place into one slice of the hit arrays.
    hit = hit[np.argsort(winner[hit], kind="stable")]
    timings["shade"] = 0.0
    timings["shadow"] = 0.0
    timings["raster_lights"] = 0.0
    if not len(hit):
        return image
    t0 = time.perf_counter()
    nh = len(hit)
    points = np.empty((nh, 3))
    normals = np.empty((nh, 3))
    views = np.empty((nh, 3))
    colors = np.empty((nh, 3))
    materials = np.empty((nh, 4))
    owner = winner[hit]
    groups = []                 # (first, end, volume, n) of each surface's hits
    for n, iso in frame.isos:
        a, b = np.searchsorted(owner, n, "left"), np.searchsorted(owner, n, "right")
        if a == b:
            continue
        groups.append((a, b, iso.volume, n))
        surface_frames(iso.volume.data, np.array(iso.volume.origin), np.array(iso.volume.spacing), frame.cam, w, h,
                       hit[a:b], cell, uvw, points[a:b], normals[a:b], views[a:b])
        colors[a:b] = iso.color
        materials[a:b] = iso.material
    lights = light_array(frame.scene.lights)
    diffuse, specular, visible = _light_terms(points, normals, views, materials, lights)
    timings["shade"] = time.perf_counter() - t0
    if frame.scene.shadows and frame.scene.lights:
        _shadows(frame, lights, points, groups, visible, lambda f: frame.report.part("lighting", f))
    t0 = time.perf_counter()
    combine_lights(colors, materials, lights, diffuse, specular, visible, hit, image.reshape(npx, 4))
    timings["shade"] += time.perf_counter() - t0
    return image


def _cast_translucent(frame, segs, planes, stop, image):
    """The translucent volumes sampled up to the surfaces' depth ``stop``, and put over ``image``:
    maximum- and average-intensity volumes as layers, composite ones merged (and, with shadows,
    their shaded samples lit: `_light_samples`)."""
    from .renderer import accumulation_params
    from .skip import skip_table

    w, h, npx = frame.w, frame.h, frame.npx
    cam, bands, parc, blocks, report = frame.cam, frame.bands, frame.parc, frame.blocks, frame.report
    trans = frame.trans
    t0 = time.perf_counter()
    comp = [(n, v) for n, v in trans if v.mode == "composite"]
    layers = [(n, v) for n, v in trans if v.mode != "composite"]
    layer_t = np.empty((len(layers), h, w))
    layer_rgba = np.empty((len(layers), h, w, 4), np.float32)
    for j, (n, v) in enumerate(layers):
        vol = v.volume
        op_x, op_y, col_x, col_rgb = v.tf.arrays()
        cnt = np.empty(npx, np.int64)
        params = accumulation_params(v)
        if n in planes:
            planes[n].set_params(params)
        for b, (y0, y1) in enumerate(bands):
            cast_accumulate_image(vol.data, np.array(vol.origin), np.array(vol.spacing), cam, w, h,
                                  params, op_x, op_y, col_x, col_rgb,
                                  segs.get(n, NO_SEGMENTS), parc, stop, True,
                                  planes[n].bits if n in planes else NO_BITS, n in planes,
                                  *skip_table(v, parc and blocks), layer_rgba[j], cnt, y0, y1)
            report.part("translucent", (j + (b + 1) / len(bands)) / len(trans))
        frame.counts["samples"] += int(cnt.sum())
        frame.add_work(cnt)
        box_entry_image(vol.data, np.array(vol.origin), np.array(vol.spacing), cam, w, h, layer_t[j])
    front = np.zeros((h, w, 4), np.float32)
    if comp:
        datas, orgs, spcs, params, tables, tf_len = _packed(comp, lambda v: accumulation_params(v, frame.scene.lights))
        seg = (np.stack([segs[n] for n, _ in comp]) if parc else np.empty((1, 1, 1, 2)))
        for k, (n, _) in enumerate(comp):
            if n in planes:
                planes[n].set_params(params[k])
        bits = [planes[n].bits if n in planes else None for n, _ in comp]
        skips = [skip_table(v, parc and blocks) for _, v in comp]
        cnt = np.empty(npx, np.int64)
        # With shadows, the shaded samples are counted here, recorded and lit below.
        record = SampleRecord(0, npx) if report.sample_shadows else None

        def merged(y0, y1, record):
            cast_merged_image(datas, orgs, spcs, cam, w, h, params, *tables, tf_len, seg, parc,
                              tuple(c for c, _ in skips), np.array([m for _, m in skips], np.int64), stop,
                              np.array([n for n, _ in comp], np.int64), layer_t,
                              np.array([n for n, _ in layers], np.int64), layer_rgba, front, cnt, y0, y1,
                              record, bits)

        for b, (y0, y1) in enumerate(bands):
            merged(y0, y1, record)
            report.part("translucent", (len(layers) + len(comp) * (b + 1) / len(bands)) / len(trans))
        frame.counts["samples"] += int(cnt.sum())
        frame.add_work(cnt)
        if record is not None:
            frame.timings["cast"] += time.perf_counter() - t0
            _light_samples(frame, comp, record.counts, merged, front.reshape(npx, 4))
            t0 = time.perf_counter()
    else:
        _composite_layers(layer_t, layer_rgba, front)
    image = front + (1.0 - front[..., 3:4]) * image
    frame.timings["cast"] += time.perf_counter() - t0
    return image


class _Report:
    """`render_scene`'s progress: each phase a share of the bar by its expected work (a
    translucent volume's samples take longer than a surface's cells), filled as its bands finish."""

    def __init__(self, progress, n_iso, n_trans, shadows, sample_shadows=False):
        self.progress = progress
        self.said = 0.0
        self.sample_shadows = sample_shadows
        # Shadow rays from a translucent volume's samples outnumber its samples that add colour.
        weights = {"buffers": 0.3 * (n_iso + n_trans), "surfaces": n_iso,
                   "lighting": (0.2 + (n_iso if shadows else 0.0)) if n_iso else 0.0, "translucent": 3.0 * n_trans,
                   "sample shadows": 12.0 * n_trans if sample_shadows else 0.0}
        total = sum(weights.values())
        # Spans from running sums over the total: the last ends at exactly 1 (summed
        # shares ended a render at 0.9999999999999999).
        self.spans, before = {}, 0.0
        for phase, weight in weights.items():
            self.spans[phase] = (before / total, (before + weight) / total)
            before += weight

    def part(self, phase, fraction):
        if self.progress is not None:
            a, b = self.spans[phase]
            value = b if fraction >= 1.0 else min(b, a + (b - a) * fraction)
            if value > self.said:           # each fraction once, rising: a phase of no weight adds none
                self.said = value
                self.progress(value)

    def done(self, phase):
        self.part(phase, 1.0)


def _light_terms(points, normals, views, materials, lights):
    """Each light's unshadowed diffuse and specular terms at each point (`raycast.shadow.light_terms`),
    and its visibility to be found by shadow rays: 1 where it lights the point (a highlight with
    no diffuse term too), else 0."""
    diffuse = np.empty((len(lights), len(points)))
    specular = np.empty((len(lights), len(points)))
    light_terms(points, normals, views, materials, lights, diffuse, specular)
    return diffuse, specular, ((diffuse > 0.0) | (specular > 0.0)).astype(np.float64)


def _shadows(frame, lights, points, groups, visible, report=None):
    """Shadow rays from every hit to every light, volume by volume; ``visible`` (each light's
    visibility at each point) scaled in place; ``report(fraction)``, if given, told how far.

    ``groups``: ``(first, end, volume, n)``, the hits ``points[first:end]`` on the surface of
    ``volume`` (the scene's volume ``n``), or its translucent samples. A shadow ray starts and
    ends `shadow_eps` of its own surface off, from its spacing (the smallest in the scene let a
    tiny volume anywhere make surfaces shadow themselves) and the size of its coordinates.
    A translucent sample's shadow ray takes its own volume's lattice from one step along
    (`raycast.shadow.shadow_accumulate`); other volumes it crosses, it samples as a hit's does.
    """
    from .renderer import accumulation_params
    from .segments import cached_proxy
    from .skip import skip_table

    scene, sizes, timings, counts = frame.scene, frame.sizes, frame.timings, frame.counts
    nh = len(points)
    cnt = np.zeros((nh, 3), np.int64)
    # The rays in about 16 runs a light and volume, for progress between them (and a Ctrl-C).
    run = max(SHADOW_RUN, -(-nh // 16))
    passes, done = len(scene.lights) * len(scene.volumes) * max(nh, 1), 0
    for l, light in enumerate(scene.lights):
        row = lights[l]
        v_l = visible[l]
        counts["shadow_rays"] += int(np.count_nonzero(v_l))
        for n, v in enumerate(scene.volumes):
            vol = v.volume
            views, near, far = no_views()
            if frame.parc:
                phase = {}
                proxy, _ = cached_proxy(v, sizes[n], scene.size, phase, merge=False)
                buf = None          # the last light's buffers, if evicted, are freed before these are drawn
                buf = _cached_light_buffers(light, v, proxy, sizes[n], frame.light_buffer)
                if buf.seconds:         # drawn this frame (kept ones report no time, and no faces)
                    counts["light_polygons"] += buf.polygons * len(buf.views)
                timings["raster_lights"] += buf.seconds
                buf.seconds = 0.0
                views, near, far = buf.views, buf.near, buf.far
            t0 = time.perf_counter()
            org = np.array(vol.origin)
            spc = np.array(vol.spacing)
            skip, jump_min = skip_table(v, frame.parc and frame.blocks)
            if not isinstance(v, Isosurface):
                params, (op_x, op_y, col_x, col_rgb) = accumulation_params(v), v.tf.arrays()
            for first, end, surface, owner in groups:
                eps = shadow_eps(surface)
                for a in range(first, end, run):
                    b = min(end, a + run)
                    if isinstance(v, Isosurface):
                        shadow_iso(vol.data, org, spc, v.value, points[a:b], row, eps, views, near, far,
                                   frame.parc, skip, jump_min, v_l[a:b], cnt[a:b])
                    else:
                        shadow_accumulate(vol.data, org, spc, params, op_x, op_y, col_x, col_rgb,
                                          points[a:b], row, eps, views, near, far, frame.parc, skip, jump_min,
                                          v_l[a:b], cnt[a:b], v.step if owner == n else 0.0)
                    done += b - a
                    if report is not None:
                        report(done / passes)
            timings["shadow"] += time.perf_counter() - t0
    cells, solves, samples = column_totals(cnt)[:3]
    counts["shadow_cells"] += cells
    counts["shadow_solves"] += solves
    counts["shadow_samples"] += samples


#: Shadow rays are cast in runs of this many, or a sixteenth of the points if more (`_shadows`):
#: a call costs little beside so many rays. A run holds one volume's points, so the last of each
#: volume's, and a volume with fewer points, is shorter.
SHADOW_RUN = 4096

#: Most translucent samples lit at once (`_light_samples`), each taking `parc.workspace.SAMPLE_BYTES`
#: and `parc.workspace.LIGHT_BYTES_PER_PIXEL` a light.
SAMPLES_AT_ONCE = 1 << 19


def _light_samples(frame, comp, per_pixel, merged, front):
    """Light the shaded samples of the composite volumes ``comp`` with shadows, and add them to ``front``.

    ``per_pixel``: the samples each pixel records (`raycast.merged`'s counting walk); ``merged(y0, y1,
    record)`` walks rows ``y0 <= y < y1`` again, recording them. Bands of whole rows holding at most
    `SAMPLES_AT_ONCE` samples (one row, whatever it holds, where memory holds it) are recorded, their
    samples' shadow rays cast (`_shadows`) and their lit colours added
    (`raycast.shadow.combine_samples`) one at a time.
    """
    w, h = frame.w, frame.h
    timings = frame.timings
    lights = light_array(frame.scene.lights)
    materials_of = np.array([v.material for _, v in comp], np.float64)
    per_row = per_pixel.reshape(h, w).sum(axis=1)
    bands = _sample_bands(per_row, SAMPLES_AT_ONCE)
    done = 0
    for y0, y1 in bands:
        t0 = time.perf_counter()
        n = int(per_row[y0:y1].sum())
        if n > SAMPLES_AT_ONCE:
            # One row holding more than the check before the frame counted on.
            check_memory(n * (SAMPLE_BYTES + LIGHT_BYTES_PER_PIXEL * len(lights)),
                         f"row {y0} of the image, its {n:,} shaded samples lit with shadows,",
                         ": use a larger step, or a narrower image")
        record = SampleRecord(n, w * h)
        record.slots[y0 * w:y1 * w] = np.cumsum(per_pixel[y0 * w:y1 * w]) - per_pixel[y0 * w:y1 * w]
        merged(y0, y1, record)
        timings["cast"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        materials = materials_of[record.volumes]
        diffuse, specular, visible = _light_terms(record.points, record.normals, record.views, materials, lights)
        timings["shade"] += time.perf_counter() - t0
        # Grouped by volume for their shadow rays' offsets, then put back in pixel order.
        order = np.argsort(record.volumes, kind="stable")
        owner = record.volumes[order]
        groups = []
        for q, (m, v) in enumerate(comp):
            a, b = np.searchsorted(owner, q, "left"), np.searchsorted(owner, q, "right")
            if a < b:
                groups.append((a, b, v.volume, m))
        grouped = np.ascontiguousarray(visible[:, order])
        _shadows(frame, lights, record.points[order], groups, grouped,
                 lambda f, rows=y1 - y0: frame.report.part("sample shadows", (done + rows * f) / h))
        visible[:, order] = grouped
        t0 = time.perf_counter()
        combine_samples(record.slots, record.counts, record.colors, record.weights, materials, lights, diffuse,
                        specular, visible, y0 * w, y1 * w, front)
        timings["shade"] += time.perf_counter() - t0
        done += y1 - y0
        frame.report.part("sample shadows", done / h)


def _sample_bands(per_row, most):
    """Row ranges ``(y0, y1)`` covering every row, each holding at most ``most`` of ``per_row``'s
    counts where a single row does not hold more."""
    bands = []
    y0 = 0
    total = 0
    for y, n in enumerate(per_row):
        if y > y0 and total + n > most:
            bands.append((y0, y))
            y0 = y
            total = 0
        total += int(n)
    if y0 < len(per_row):
        bands.append((y0, len(per_row)))
    return bands


def _cached_light_buffers(light, vis, proxy, size, n):
    """Light buffers of one volume's proxy from one light, kept while only the camera moves."""
    from .classify import VolumeIndex
    from .segments import classifier

    index = VolumeIndex.of(vis.volume)
    what, _ = classifier(index, vis)
    kind = "sun" if isinstance(light, DirectionalLight) else "point"
    where = light.direction if isinstance(light, DirectionalLight) else light.position
    key = (kind, tuple(where), what, tuple(size), n)
    cache = index.kept("light buffers")
    _LIT.add(index)
    # Taken out and put back last: the oldest kept is then the longest unused (a light moved
    # every frame evicts its own last places, not the lights that stay).
    buf = cache.pop(key, None)
    if buf is None:
        # Room made before the new buffers are drawn, for the views this light takes (six at most):
        # made after, the buffers of the light's last place and its new one were held at once.
        # The bound is on every volume's buffers together: this volume's go first, the longest
        # unused first, then other volumes'.
        views = len(light_views(light, *proxy.bounds)) if proxy.pc.any() else 0
        room = light_cache_bytes(_held()) - buffer_bytes(views, n)
        while len(cache) >= LIGHT_BUFFER_CACHE_SIZE:
            cache.pop(next(iter(cache)))
        for kept in [cache] + [i.kept("light buffers") for i in _LIT if i is not index]:
            while kept and _held() > room:
                kept.pop(next(iter(kept)))
        buf = light_buffers(light, proxy, size=n)
    cache[key] = buf
    return buf


#: The volume indexes keeping light buffers, for the bound on all of them (`_cached_light_buffers`).
_LIT = weakref.WeakSet()


def _held():
    """Bytes of the light buffers every volume keeps."""
    return sum(b.near.nbytes + b.far.nbytes for i in _LIT for b in i.kept("light buffers").values())


def _read_only(a):
    """``a`` marked read-only, like every Volume's samples: the kernels index a tuple of
    arrays of one Numba type, and a writable array is another type."""
    a.flags.writeable = False
    return a


def _packed(comp, params_of):
    """The merged walk's inputs: data of one dtype, placements, params (``params_of(volume)``, each
    of one length: the scene's lights are every volume's) and padded transfer tables."""
    dtype = np.result_type(*(v.volume.data.dtype for _, v in comp))
    datas = tuple(v.volume.data if v.volume.data.dtype == dtype else _read_only(v.volume.data.astype(dtype))
                  for _, v in comp)
    orgs = np.array([v.volume.origin for _, v in comp], dtype=np.float64)
    spcs = np.array([v.volume.spacing for _, v in comp], dtype=np.float64)
    params = np.stack([params_of(v) for _, v in comp])
    arrs = [v.tf.arrays() for _, v in comp]
    no = max(len(a[0]) for a in arrs)
    nc = max(len(a[2]) for a in arrs)
    op_x = np.zeros((len(comp), no))
    op_y = np.zeros((len(comp), no))
    col_x = np.zeros((len(comp), nc))
    col_rgb = np.zeros((len(comp), nc, 3))
    tf_len = np.zeros((len(comp), 2), np.int64)
    for k, (ox, oy, cx, crgb) in enumerate(arrs):
        op_x[k, :len(ox)], op_y[k, :len(oy)] = ox, oy
        col_x[k, :len(cx)], col_rgb[k, :len(cx)] = cx, crgb
        tf_len[k] = len(ox), len(cx)
    return datas, orgs, spcs, params, (op_x, op_y, col_x, col_rgb), tf_len


def _composite_layers(layer_t, layer_rgba, out):
    """Front-to-back ``over`` of per-pixel layers in order of ``layer_t``."""
    order = np.argsort(layer_t, axis=0, kind="stable")
    for j in range(layer_t.shape[0]):
        rgba = np.take_along_axis(layer_rgba, order[j][None, ..., None], axis=0)[0]
        out += (1.0 - out[..., 3:4]) * rgba
