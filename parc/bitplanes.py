"""OpenGL pass of colour-buffer PARC: per-pixel bits of the supercell planes each ray meets.

About this technique
--------------------
Sobierajski & Avila (1995, §4) number the planes of (super)cells along the
major viewing axis, draw each possibly contributing (PC) cell of plane
``i`` in colour ``2^i`` with a bitwise-OR logic op, and read the colour
buffer back ``P`` bits at a time: bit ``i`` of a pixel tells whether its
ray meets a PC cell of plane ``i``, and the caster skips the samples of
planes whose bit is clear. This pass keeps the idea and makes it exact
for this project's caster:

- **One pass for any number of planes.** The fragment shader ORs its bits
  with ``atomicOr`` into a shader storage buffer laid out exactly as the
  caster reads them, ``bits[y, x, word]`` (uint32 words, bit ``q & 31`` of
  word ``q >> 5`` for plane ``first + q``), so the read-back is the
  caster's array with no reordering. (An ``imageAtomicOr`` into a
  ``uimage2DArray`` works too but needs a transpose after read-back.)
  OpenGL 4.3; a memory barrier before the read-back.
- **Faces, not boxes.** A ray that meets the PC region ``U_p`` of plane
  ``p`` (at ``t >= 0``) leaves it again at some ``t* >= 0``: at that point
  some PC box of plane ``p`` borders, across a face the ray crosses
  properly (the ray's component along the face's axis is non-zero), a box
  outside ``U_p`` -- empty, outside the volume, or PC in another plane.
  So it suffices to draw the outer faces (carrying their PC side's plane)
  and the faces perpendicular to the plane axis between PC supercells of
  two planes (carrying both): `parc.proxy.build_plane_proxy`. Faces
  inside one plane's PC region are not drawn. This holds wherever the ray
  starts, so the eye inside the volume or inside a PC supercell needs no
  special case beyond the near-plane clipping below.
- **Conservative coverage and face test**, exactly as the depth pass
  (`parc.raster`, whose geometry shader `bitplanes.geom` follows): faces
  clipped at a near distance, their projection grown by `COVERAGE_PAD_PX`,
  and per fragment the pixel-centre ray (the caster's, as affine forms of
  the pixel indices) tested against the face's rectangle grown by the
  float32 error bound of the crossing point; borderline fragments are
  kept. No ``t`` is needed: a crossing behind the ray start can only add
  bits, and the crossings the clipping cuts are out of view or, with the
  eye inside a PC supercell, the eye rule's (below).
- **Clipping.** Perspective, eye outside the PC region: faces are clipped
  below ``d_min cos(theta_max) / 2`` (`parc.raster.perspective_clip`, shared
  with the depth pass); every face lies at least ``d_min`` from the eye, so
  nothing visible is cut. Eye inside (or on) a PC supercell: faces are
  clipped a tiny distance in front of the eye and every pixel gets the bits
  of the planes whose slabs come within that distance (plus the boundary
  band) of the eye: the only crossings the clip can cut lie there. Parallel:
  faces are clipped a little behind the view plane (a rounding, plus the
  band's width over ``|f_a|`` in halo mode, see below).

Boundaries: strict bits (the default) and halo mode
---------------------------------------------------
The caster (`raycast.composite.clear_planes`) maps the span of index
coordinates ``pos`` a ray covers in a cell to the planes ``floor(pos / m_a)``
it meets, and where an end of the span lies within its tolerance of a
boundary (``PLANE_TOL`` planes plus the rounding of ``pos`` itself,
``POS_ROUNDING`` of its terms: large when the eye is far away; plus the
grid's snapping, ``BOUNDARY_SNAP`` cells: large against planes of 1e-4 cells) it tests
the bit of the plane across as well. For that caster
the strict bits suffice (``halo=False``, the default): the planes
whose PC boxes the ray meets (closed boxes, ``t >= 0``), plus the float32
margins, which grow as a face is seen more nearly edge-on (past a limit
its fragments are kept untested). Some pixels get more,
never fewer: those within the bounding box drawn for a face reaching past
the near clip (beside or behind the eye), whose ray's line may cross that
face behind the eye. (An independent check, 2026-11-30, 340 random scenes:
3.7% more bits than a plain ray-box reference, none missing.) Halo mode
(``halo=True``) serves a caster that tests only ``floor(pos / m_a)``, and
is kept, tested, for one. The grid's boundaries
are ``s m_a`` snapped to integers within `parc.ranges.SNAP`, and the
division rounds, so a sample *strictly inside* a PC box of plane ``p`` but
within ``delta`` (about 1e-9 cells) of its boundary with plane ``p + 1``
may be mapped to ``p + 1`` (and likewise to ``p - 1``); the sample can
have non-zero opacity while the box across is empty, so bit ``p + 1``
must be set too. A sample exactly on the boundary of two boxes is safe
(the empty box's closed range holds its value). Halo mode therefore sets,
besides the PC planes:

- for a face perpendicular to the plane axis at boundary ``b``, both
  planes ``b - 1`` and ``b`` (whichever side is PC);
- for a face parallel to it (plane ``p``), plane ``p - 1`` / ``p + 1``
  when the crossing's coordinate along the axis comes within `BAND_CELLS`
  (in world units, plus its float32 error bound) of the slab's ends.

A ray holding such a sample runs, inside ``U_p``, through the band along
the boundary; where it enters or leaves that band inside ``U_p`` it either
crosses the boundary face (first rule) or an outer face parallel to the
axis within the band (second rule), or starts there (the eye rule above,
or, parallel, a crossing at most ``band / |f_a|`` behind the view plane,
which the parallel clip keeps). ``first`` and ``count`` then cover one
plane beyond the PC planes at each end (``pos`` a rounding below 0 gives
plane -1). The price is that each run of PC planes along a ray is
sampled one plane further at each end.

Cost
----
Measured on this project's development machine (2 cores, llvmpipe;
`parc compare` on the CT head, ``ct_skin_bone``, 300x300, the renderer's
supercells, 2026-11-28): 2,022 faces drawn for both passes against 725
for the depth pass alone, and the OpenGL passes 13% of a 0.031 s frame
against 5% of 0.025 s: the bit planes cost more than the samples they
save beyond the skip table's (`parc.renderer.DEFAULT_BUFFERS`). Fragments are
about one per PC plane a pixel's ray crosses (1.4M at 512x512 with 4-cell
supercells), and
llvmpipe runs fragment shaders with storage-buffer side effects on a slow
path: the same shader writing a colour instead takes ~40% less, and
OR-ing ``uvec4`` colours into an RGBA32UI target with ``glLogicOp(GL_OR)``
(reachable through ``eglGetProcAddress``; moderngl has no setting) was
~15% faster than the atomics, for a ctypes dependency; not used.

The OpenGL context is `parc.gl.get_context`'s, and the view helpers (the
pixel rays as affine maps, the scene scale, the eye's distance to the PC
region) are the depth pass's own, so both passes see the same rays.
"""
from __future__ import annotations

import math
import time
import weakref
from dataclasses import dataclass, field

import numpy as np

from data_tools import InputError
from data_tools.memory import check_memory

from .gl import check_viewport, get_context, moderngl_module, program, set_uniform
from .raster import (ABS_TOL, COVERAGE_PAD_PX, FLOAT32_REACH, GUARD_PX, PASS_PHASES, TOL_REL, perspective_clip,
                     scene_scale, set_view_uniforms, view_reach)
# `plane_buffers` keeps as many proxies as the renderer, so that a supercell sweep keeps its planes' too.
from .segments import PROXY_CACHE_SIZE

#: Width of the boundary band (halo mode), in cells along the plane axis:
#: far above the caster's mismatch between ``floor(pos / m)`` and the
#: grid's boundaries (`parc.ranges.SNAP` = 1e-9 cells, plus roundings),
#: far below a sample step.
BAND_CELLS = 1e-7

#: Largest bits buffer, in bytes: Mesa's llvmpipe cannot map one of 4 GiB or more.
MAX_BITS_BYTES = (1 << 32) - 4


_UPLOADS = weakref.WeakKeyDictionary()
_BUFFERS = {}
_FBOS = {}
_PROXIES = []


def major_axis(camera, volume_box):
    """The volume axis most aligned with the viewing direction: 0, 1 or 2 (x, y, z).

    Parameters
    ----------
    camera : Camera
    volume_box : (lo, hi)
        World corners of the volume (``volume.bounds``).

    Returns
    -------
    int

    Notes
    -----
    Parallel views: the view direction ``f``. Perspective: the direction
    from the eye to the box centre when the eye is outside the box (the
    rays that matter point roughly that way), else ``f``. The choice only
    affects efficiency (how many samples share a plane bit), never
    correctness: every sample tests its own plane's bit. Ties go to the
    lower axis.
    """
    f = np.asarray(camera.basis()[0], dtype=np.float64)
    lo, hi = (np.asarray(b, dtype=np.float64) for b in volume_box)
    if not camera.parallel:
        eye = np.asarray(camera.eye, dtype=np.float64)
        centre = 0.5 * (lo + hi)
        if not np.all((lo <= eye) & (eye <= hi)) and np.any(centre != eye):
            f = centre - eye
    return int(np.argmax(np.abs(f)))


@dataclass
class PlaneBits:
    """Per-pixel plane bits for the caster.

    Attributes
    ----------
    bits : ndarray (H, W, nwords) uint32
        Bit ``q & 31`` of word ``q >> 5``: the pixel's ray may have a
        sample of non-zero opacity in plane ``first + q``.
    axis : int
        The plane axis (0, 1, 2 = x, y, z).
    size_along_axis : float
        Supercell size along it, in cells (``m_a``).
    first, count : int
        Plane number of bit 0, and the number of bits. ``count = 0`` when
        nothing is possibly contributing (every sample is skipped).
    polygons : int
        Faces drawn (the plane proxy's, re-merged for the mode).
    seconds : dict
        ``proxy`` (0 when cached), then `raster_bits`' ``prepare``,
        ``upload``, ``draw``, ``readback``, ``post``, ``total``.
    info : dict
        `raster_bits`' info, plus ``halo``.
    """

    bits: np.ndarray
    axis: int
    size_along_axis: float
    first: int
    count: int
    polygons: int
    seconds: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    def set_params(self, params):
        """Write ``P_PLANE_AXIS``, ``P_PLANE_SIZE``, ``P_PLANE_FIRST``, ``P_PLANE_COUNT`` into ``params``."""
        from raycast.composite import P_PLANE_AXIS, P_PLANE_COUNT, P_PLANE_FIRST, P_PLANE_SIZE
        params[P_PLANE_AXIS] = self.axis
        params[P_PLANE_SIZE] = self.size_along_axis
        params[P_PLANE_FIRST] = self.first
        params[P_PLANE_COUNT] = self.count
        return params


def plane_range(pc, axis):
    """``(lo, hi)``: the first and last plane along ``axis`` holding a PC supercell, or None."""
    arr_axis = 2 - int(axis)
    other = tuple(d for d in range(3) if d != arr_axis)
    occupied = np.flatnonzero(np.asarray(pc, dtype=bool).any(axis=other))
    if not len(occupied):
        return None
    return int(occupied[0]), int(occupied[-1])


def plane_buffers(camera, width, height, volume, pc, grid, *, axis=None, halo=False):
    """Choose the axis, build (or reuse) the plane proxy and rasterize the bits.

    Parameters
    ----------
    camera : Camera
    width, height : int
    volume : Volume
    pc : ndarray of bool, ``grid.shape``
        The possibly contributing supercells.
    grid : SupercellGrid
    axis : int or None
        The plane axis; default `major_axis`.
    halo : bool, default False
        False: the strict bits, for the caster here, which is tolerant at
        plane boundaries; True: the halo bits, for a caster that is not
        (see "Boundaries").

    Returns
    -------
    PlaneBits
        Pass ``bits`` and, through `PlaneBits.set_params`, ``P_PLANE_AXIS``,
        ``P_PLANE_SIZE``, ``P_PLANE_FIRST``, ``P_PLANE_COUNT`` to
        `raycast.composite`.
    """
    from .proxy import build_plane_proxy
    if axis is None:
        axis = major_axis(camera, volume.bounds)
    axis = int(axis)
    m_a = float(grid.size[axis])
    span = plane_range(pc, axis)
    if span is None:
        bits = np.zeros((int(height), int(width), 1), np.uint32)
        return PlaneBits(bits=bits, axis=axis, size_along_axis=m_a, first=0, count=0, polygons=0,
                         seconds={"proxy": 0.0, "total": 0.0}, info={"halo": bool(halo)})
    t0 = time.perf_counter()
    proxy = None
    for n, entry in enumerate(_PROXIES):
        if entry[0] is grid and entry[1] is pc and entry[2] == axis and entry[3] is volume:
            proxy = entry[4]
            _PROXIES.append(_PROXIES.pop(n))
            break
    if proxy is None:
        proxy = build_plane_proxy(grid, pc, grid.world_edges(volume), axis)
        if len(_PROXIES) >= PROXY_CACHE_SIZE:
            _PROXIES.pop(0)
        _PROXIES.append((grid, pc, axis, volume, proxy))
        t_proxy = time.perf_counter() - t0
    else:
        t_proxy = 0.0
    lo, hi = span
    first, count = (lo - 1, hi - lo + 3) if halo else (lo, hi - lo + 1)
    bits, info = raster_bits(camera, width, height, proxy, first=first, count=count, halo=halo,
                             spacing=volume.spacing)
    seconds = {"proxy": t_proxy, **info["seconds"]}
    seconds["total"] = t_proxy + info["seconds"]["total"]
    return PlaneBits(bits=bits, axis=axis, size_along_axis=m_a, first=first, count=count,
                     polygons=info["polygons"], seconds=seconds, info={**info, "halo": bool(halo)})


def frame_planes(scene, vis, proxy, timings, extra):
    """`plane_buffers` for one translucent volume of ``scene``, its proxy's supercells given
    (`parc.segments.cached_proxy`): the plane proxy's time (built once per classification) is
    added to ``timings["proxy"]``, the pass's to ``timings["raster_bits"]``, and the planes'
    count, axis and polygons are written into ``extra``."""
    planes = plane_buffers(scene.camera, *scene.size, vis.volume, proxy.pc, proxy.grid)
    proxy_seconds = planes.seconds.get("proxy", 0.0)
    timings["proxy"] = timings.get("proxy", 0.0) + proxy_seconds
    timings["raster_bits"] = (timings.get("raster_bits", 0.0)
                              + planes.seconds.get("total", sum(planes.seconds.values())) - proxy_seconds)
    extra.update({"planes": planes.count, "plane_axis": "xyz"[planes.axis], "plane_polygons": planes.polygons})
    return planes


def raster_bits(camera, width, height, plane_proxy, *, first, count, halo=False, spacing=None,
                pad_px=COVERAGE_PAD_PX):
    """OR every plane bit of every pixel in one OpenGL pass.

    Parameters
    ----------
    camera : Camera
    width, height : int
    plane_proxy : PlaneProxy
        From `parc.proxy.build_plane_proxy`; its GPU buffers are uploaded
        on the first call and reused for later cameras.
    first, count : int
        Bit ``q`` stands for plane ``first + q``, ``0 <= q < count``;
        planes outside are dropped.
    halo : bool, default False
        Also the neighbour planes of slab boundaries (module notes), as
        `plane_buffers`' ``halo``.
    spacing : (sx, sy, sz) or None
        The volume's spacing, for the boundary band's world width; default
        the supercell boundaries' own scale (the band is then wider than
        needed, never narrower, unless supercells are far larger than cells:
        pass it).
    pad_px : float
        Coverage growth in pixels (as `parc.raster.raster_segments`).

    Returns
    -------
    bits : ndarray (H, W, nwords) uint32, ``nwords = max(1, ceil(count / 32))``
        For every pixel whose centre ray (`raycast.rays.camera_ray`) meets
        a PC supercell of plane ``p`` (closed box, ``t >= 0``), bit
        ``p - first`` is set (if in range); in halo mode also the boundary
        neighbours (module notes).
    info : dict
        ``seconds`` (``prepare``, ``upload`` (0 when cached), ``draw``
        (render + ``ctx.finish()``), ``readback`` (barrier + read),
        ``post``, ``total``), ``polygons`` (faces drawn: the proxy's,
        re-merged for the mode), ``proxy_faces``, ``nwords``,
        ``eye_inside``, ``d_min``, ``clip_near``, ``eye_planes`` (set for
        every pixel), ``scale``, ``band``; and ``every_plane`` (True) when
        the view reaches too far for the float32 pass and every pixel has
        every plane's bit set without drawing.

    Raises
    ------
    OpenGLUnavailable
    InputError
        An image larger than the GL viewport limit.
    """
    width, height = int(width), int(height)
    first, count = int(first), int(count)
    nwords = max(1, -(-count // 32))
    check_viewport(width, height)
    ctx = get_context()
    seconds = {}
    t0 = time.perf_counter()
    proxy = plane_proxy
    axis = int(proxy.plane_axis)
    _check_bits_size(width, height, count, nwords, axis)
    lo, hi = proxy.bounds
    eye = np.asarray(camera.eye, dtype=np.float64)
    f = camera.basis()[0]
    th = math.tan(math.radians(camera.fov) / 2.0)
    aspect = width / height
    scale = scene_scale(camera, lo, hi, aspect)
    if spacing is None:
        e = proxy.world_edges[axis]
        spacing_a = float(np.max(np.abs(np.diff(e)))) if len(e) > 1 else 1.0
    else:
        spacing_a = abs(float(spacing[axis]))
    band = BAND_CELLS * spacing_a + ABS_TOL * scale if halo else 0.0
    if view_reach(camera, lo, hi, aspect) > FLOAT32_REACH:
        # As `parc.raster.raster_segments`: no float32 pass so far out; every plane's bit is set.
        bits = np.zeros((height, width, nwords), np.uint32)
        for w in range(nwords):
            bits[..., w] = np.uint32((1 << min(32, count - 32 * w)) - 1) if count > 32 * w else 0
        seconds = dict.fromkeys(PASS_PHASES, 0.0)
        return bits, {"seconds": seconds, "polygons": 0, "proxy_faces": proxy.n_polygons, "nwords": nwords,
                      "eye_inside": False, "d_min": None, "clip_near": 0.0, "eye_planes": [], "scale": scale,
                      "band": band, "every_plane": True}
    ndc_limit = (1.0 + 2.0 * GUARD_PX / width, 1.0 + 2.0 * GUARD_PX / height)
    d_min = None
    eye_inside = False
    cos_max = 1.0
    if camera.parallel:
        # Keep crossings a rounding behind the view plane, and in halo mode
        # those up to band / |f_a| behind (a ray starting in the band).
        back = 4.0 * TOL_REL * scale
        if halo and f[axis] != 0.0:
            back += 4.0 * band / abs(f[axis])
        clip_near = -back
    else:
        d_min, cos_max, clip_near = perspective_clip(eye, proxy, th, aspect, ndc_limit, scale)
        eye_inside = d_min == 0.0
    seconds["prepare"] = time.perf_counter() - t0

    bits = np.zeros((height, width, nwords), np.uint32)
    drawn = 0
    if proxy.n_polygons and count > 0:
        t0 = time.perf_counter()
        up, fresh = _upload(ctx, proxy, halo)
        if fresh:
            ctx.finish()
        seconds["upload"] = time.perf_counter() - t0 if fresh else 0.0

        t0 = time.perf_counter()
        parallel = camera.parallel
        vao = up.vao(ctx, parallel)
        prog = vao.program
        set_view_uniforms(prog, camera, width, height, up.offsets, clip_near=clip_near,
                          ndc_limit=ndc_limit, pad_px=pad_px, scale=scale)
        set_uniform(prog, "plane_axis", axis)
        set_uniform(prog, "first", first)
        set_uniform(prog, "halo", 1 if halo else 0)
        set_uniform(prog, "band", band)
        set_uniform(prog, "width", width)
        set_uniform(prog, "nwords", nwords)
        set_uniform(prog, "count", count)
        fbo, out = _sized(ctx, width, height, nwords)
        out.clear()
        fbo.use()
        ctx.viewport = (0, 0, width, height)
        mgl = moderngl_module()
        ctx.disable(mgl.DEPTH_TEST | mgl.CULL_FACE | mgl.BLEND)
        up.edges.bind_to_storage_buffer(0)
        out.bind_to_storage_buffer(1)
        drawn = up.count
        vao.render(mgl.POINTS, vertices=drawn)
        ctx.finish()
        seconds["draw"] = time.perf_counter() - t0

        t0 = time.perf_counter()
        ctx.memory_barrier(mgl.SHADER_STORAGE_BARRIER_BIT | mgl.BUFFER_UPDATE_BARRIER_BIT)
        out.read_into(bits)
        seconds["readback"] = time.perf_counter() - t0
    else:
        seconds.update(upload=0.0, draw=0.0, readback=0.0)

    t0 = time.perf_counter()
    eye_planes = []
    if eye_inside and count > 0:
        # Crossings cut by the clip lie within rho of the eye: set, for
        # every pixel, the planes whose slabs come that close (plus the band).
        rho = 2.0 * clip_near / cos_max + ABS_TOL * scale
        reach = rho + (band if halo else 0.0)
        # Planes -1 and n (beyond the volume, [-inf, e_0] and [e_n, inf])
        # stand for samples a rounding outside it (halo mode).
        e = np.concatenate([[-np.inf], proxy.world_edges[axis], [np.inf]])
        near = np.flatnonzero((e[:-1] <= eye[axis] + reach) & (e[1:] >= eye[axis] - reach)) - 1
        q = near - first
        q = q[(q >= 0) & (q < count)]
        for qq in q:
            bits[..., qq >> 5] |= np.uint32(1 << (int(qq) & 31))
        eye_planes = [int(p) for p in q + first]
    seconds["post"] = time.perf_counter() - t0
    seconds["total"] = sum(seconds.values())
    info = {"seconds": seconds, "polygons": drawn, "proxy_faces": proxy.n_polygons, "nwords": nwords,
            "eye_inside": bool(eye_inside), "d_min": d_min, "clip_near": clip_near,
            "eye_planes": eye_planes, "scale": scale, "band": band}
    return bits, info


# --------------------------------------------------------------------------
# GPU resources
# --------------------------------------------------------------------------

@dataclass
class _Upload:
    faces: object
    edges: object
    offsets: tuple
    count: int
    vaos: dict = field(default_factory=dict)

    def vao(self, ctx, parallel):
        if parallel not in self.vaos:
            self.vaos[parallel] = ctx.vertex_array(
                program(ctx, "bitplanes", parallel),
                [(self.faces, "4i 2i 2i", "in_face", "in_vrange", "in_bits")])
        return self.vaos[parallel]


def _face_records(proxy, halo):
    """Per face ``(axis, plane, u0, u1, v0, v1, base, strict_mask)``, int32 (Q, 8).

    ``base`` is the absolute plane number of bit 0 of the face's
    three-plane window (boundary ``b``: ``b - 1``; a face parallel to the
    plane axis in plane ``p``: ``p - 1``); ``strict_mask`` the window bits
    of the face's PC neighbours. The proxy's faces are re-merged by what
    the pass draws: in halo mode every face at one boundary carries the
    same bits, whichever side is PC (CT head skin and bone, 4-cell
    supercells: 14.9k faces -> 11.3k); faces parallel to the axis merge
    within their plane whatever their orientation.
    """
    from .proxy import merge_grouped
    uf = proxy.unit_faces()
    up = proxy.unit_planes()
    a, p, u, v = (uf[:, k] for k in range(4))
    perp = a == proxy.plane_axis
    base = np.where(perp, p - 1, up[:, 0] - 1)
    mask = np.where(perp, 0, 2)
    for q in (up[:, 0], up[:, 1]):
        mask = np.where(perp & (q >= 0), mask | (1 << np.clip(q - base, 0, 2)), mask)
    if halo:
        mask = np.where(perp, 3, mask)
    if not len(a):
        return np.zeros((0, 8), np.int32)
    faces, (base1, mask) = merge_grouped(a, p, u, v, (base + 1, mask))
    return np.ascontiguousarray(np.column_stack([faces, base1 - 1, mask]), dtype=np.int32)


def _upload(ctx, proxy, halo):
    """Face records and boundary table of a plane proxy on the GPU (cached per proxy and mode)."""
    ups = _UPLOADS.setdefault(proxy, {})
    up = ups.get(bool(halo))
    if up is not None and up.faces.ctx is ctx:
        return up, False
    recs = _face_records(proxy, halo)
    vbo = ctx.buffer(recs.tobytes())
    edges = np.concatenate(proxy.world_edges).astype(np.float64)
    ssbo = ctx.buffer(edges.tobytes())
    n = [len(e) for e in proxy.world_edges]
    up = _Upload(faces=vbo, edges=ssbo, offsets=(0, n[0], n[0] + n[1]), count=len(recs))
    ups[bool(halo)] = up
    return up, True


def _check_bits_size(width, height, count, nwords, axis):
    """Refuse a bits buffer OpenGL cannot map, or memory cannot hold with its read-back copy."""
    need = width * height * nwords * 4
    what = f"a bits buffer of {count} planes along {'xyz'[axis]} at {width}x{height}"
    hint = f"; use larger supercells along {'xyz'[axis]}, a smaller image, or --buffers depth"
    if need > MAX_BITS_BYTES:
        raise InputError(f"{what} needs {need / 2**30:.1f} GB in one OpenGL buffer, over the 4 GB it can map{hint}")
    check_memory(2 * need, what, hint)


def _sized(ctx, width, height, nwords):
    """An attachment-less framebuffer of the image size and the bits buffer (kept for the next call).

    Framebuffers are kept per size (they hold no memory; releasing the
    bound one makes moderngl's next framebuffer creation fail); the bits
    buffer only for the last size.
    """
    fkey = (id(ctx), width, height)
    if fkey not in _FBOS:
        _FBOS[fkey] = ctx.empty_framebuffer((width, height))
    key = (id(ctx), width, height, nwords)
    if key not in _BUFFERS:
        for buf in _BUFFERS.values():
            buf.release()
        _BUFFERS.clear()
        _BUFFERS[key] = ctx.buffer(reserve=width * height * nwords * 4)
    return _FBOS[fkey], _BUFFERS[key]


__all__ = ["BAND_CELLS", "PlaneBits", "frame_planes", "major_axis", "plane_buffers", "plane_range", "raster_bits"]
