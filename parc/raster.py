"""OpenGL pass of depth-buffer PARC: per-pixel near and far ray distances of the proxy.

About this technique
--------------------
Sobierajski & Avila (1995, §3) project the proxy's outer faces twice into
z-buffers, with "less than" for the near distance and "greater than" for
the far one. This pass keeps the idea and fixes what a z-buffer gets
wrong for an exact ray caster:

- **Bounds on the caster's own t, not interpolated depth.** For every
  pixel a face covers, the fragment shader finds where the pixel-centre
  ray -- the caster's (`raycast.rays.camera_ray`), whose float64 t the
  caster will compare against -- crosses the face's axis-aligned plane,
  and writes a float32 interval ``[t - e, t + e]`` that provably contains
  that float64 t (see "Error bounds"). Depth precision, the near-plane
  distance and perspective interpolation play no part, and no CPU margin
  is needed afterwards.
- **One pass, no depth test.** Each fragment writes ``(t - e, -(t + e))``
  into an RG32F target under MIN blending: channel 0 ends as the nearest
  near bound, channel 1 as minus the farthest far bound. Pixels without a
  fragment keep the cleared ``(inf, inf)``, i.e. near inf, far -inf.
- **Conservative coverage.** A geometry shader clips each face at the
  near distance and grows its projection, in float64, to contain the
  Minkowski sum with a square of half-size `COVERAGE_PAD_PX` (each edge
  moved out by the square's support, mitred corners; the bounding box for
  slivers, clipped faces and faces reaching off screen), so rasterization
  rules and vertex snapping cannot drop a pixel whose centre ray crosses
  the face. The extra pixels cost fill, not accuracy: the fragment shader
  discards a pixel whose ray surely misses the face. Measured on the CT
  head (skin, 4-cell supercells, 512x512): 1.23M fragments for 1.15M real
  crossings (the screen bounding box alone gave 2.17M).
- **Eye inside the PC region.** Perspective: if the eye lies in (or on) a
  PC supercell, every ray starts inside, so near is 0 for every pixel
  (the paper: "start from the viewing plane"). Otherwise the faces are
  clipped at a forward distance below ``d_min cos(theta_max)``, where
  ``d_min`` is the eye's distance to the nearest PC supercell, so no
  visible part of any face is lost. Parallel: each pixel's ray starts on
  the view plane; a pixel whose start lies in a PC supercell gets near 0
  (tested on the CPU, and skipped when the view plane clears the volume).
- **Faces parallel to the rays are skipped** (a parallel view with
  ``f_a = 0``, or the eye in the face's plane): where a ray enters or
  leaves the PC region it crosses a face it is not parallel to.
- **Cavity faces are skipped** while no ray starts in a cavity (empty
  supercells enclosed by PC ones): a ray's first entry and last exit lie
  on faces bordering the open empty space (`parc.origins.open_faces`).

Error bounds
------------
The fragment shader works in float32 (llvmpipe emulates float64 slowly:
in float64 the shader took 30 ms of a 35 ms pass on the CT head skin).
Over the pixel indices (x, y) the caster's ray is affine: ``sx`` and
``sy`` are affine in x and y, so the perspective direction ``d = f +
tan(fov/2) (sx r + sy u)`` and the parallel origin are too
(`_pixel_affine`). Per face, the geometry shader (float64) hands the
fragment shader three affine forms ``k0 + kx x + ky y`` and bounds that
hold for every ray that really crosses the face; a fragment of a ray that
does not cross it may write anything finite, which can only loosen the
result, never break it.

- Rounding model: ``+ - *`` correctly rounded (2^-24 relative; fused or
  not), division and square root within 2^-20 (GLSL allows 2.5 and about
  4.5 ulp), float64 to float32 conversion within one ulp. An affine form
  evaluated in float32 with rounded coefficients is off by at most
  ``3 * 2^-24 * (|k0| + |kx| x + |ky| y)``; `AFFINE_ERR` is 8/3 of that.
- Perspective: the shader evaluates ``d_a, d_u, d_v`` (face axis a,
  spanning axes u, v), then ``r = w / d_a`` (``w`` = plane - eye), the
  crossing ``p = r (d_u, d_v)`` and ``t = r |d|``. A ray crossing the face
  at t has ``|d_a| / |d| = |w| / t >= |w| / t_max`` and ``|d| >= 1``, so
  ``d_a``'s absolute error bound (`AFFINE_ERR` times its magnitude over
  the image) is a relative one, ``q``, for every crossing ray; from it
  follow relative bounds on r and t and an absolute one on p (using
  ``|r| <= t <= t_max``). ``e = e_rel |t|`` with ``e_rel`` twice the
  derived bound: 8e-6 to 1e-5 in the views timed below, i.e. ``e`` is
  about 0.007 of a cell on the CT head (t ~ 860) and 0.002 on neghip;
  the caster's cells per pixel did not change (`parc compare`).
- Parallel: ``t = (w - o_a) / f_a`` and the crossing point are affine in
  (x, y) themselves, so the shader evaluates them directly; ``e`` is
  absolute, `AFFINE_ERR` times the form's magnitude.
- The face test discards a fragment only if ``p`` lies outside the
  face's rectangle grown by p's error bound (rounded outwards to
  float32), or NaN; a far bound below 0 (a crossing surely behind the ray
  start) is discarded too. `ABS_TOL` adds an absolute slack at the scale
  of the scene (float64 roundings of the caster's ray; rays that only
  touch a box count as meeting it), `FLUSH_TOL` one for float32
  denormals flushed to zero.
- A face whose bound is not tighter than its own range of t (seen nearly
  edge-on, or face-on in a parallel view) writes that range, computed in
  float64 and rounded outwards; a perspective face whose plane passes so
  close to the eye that ``q > 1/4`` writes its range and discards nothing,
  and so does every face of a view whose bound on t is off by more than a
  quarter of t (a field of view within about 1e-4 degree of 180, where the
  float32 directions across the image round by more than the central
  ray's length).

Speed
-----
On the development machine (2 cores, llvmpipe, 512x512, the renderer's
supercells and view, the segments written into a kept array as the
renderer does, `parc.workspace`; median of 30 frames, 2026-11-26;
``benchmarks/raster_speed.py --stages`` times the stages):

================================  ======  ========  ======
scene (faces, of which drawn)     draw    post      total
================================  ======  ========  ======
CT head skin, 600 (1903, 1879)    4.2 ms  0.19 ms   4.5 ms
CT head bone, 1500 (1352, 961)    2.1 ms  0.14 ms   2.5 ms
neghip, 80 (2244, 1286)           2.4 ms  0.16 ms   2.7 ms
================================  ======  ========  ======

Most of the draw is llvmpipe's rasterization of the faces' area, on its
threads (about 2/3 with a constant fragment shader; a depth-only pass
fills as slowly); the geometry shader and triangle setup run on the
calling thread. Parallel views skip the CPU test of ray origins when the
view plane clears the volume. `benchmarks/README.md` has the measurements.

Faces bordering only cavities (the table's faces less those drawn: bone
391 of 1,352, neghip 958 of 2,244) are skipped while no ray starts in one (`parc.origins.open_faces`).
Looseness against the exact segments
(tests/parc/test_raster.py reports it): ~1e-4 cells mean, ~2e-3 max,
except a few pixels next to faces whose plane passes through or next to
the eye (up to a few cells).

The OpenGL context is created once per process (`parc.gl.get_context`),
headless through EGL (llvmpipe on CPU-only machines).
"""
from __future__ import annotations

import math
import time
import weakref
from dataclasses import dataclass, field

import numpy as np
from numba import prange

from raycast.config import kernel

from .gl import check_viewport, get_context, moderngl_module, program, set_uniform
from .origins import distance_to_pc, in_cavity, open_faces, parallel_inside
from .workspace import work_array


#: Coverage growth of each face's projection, in pixels. It only has to
#: exceed the error of the emitted float32 corners (< 1e-3 px up to 16k
#: images) plus vertex snapping (1/256 px with llvmpipe's 8 subpixel bits)
#: so that a pixel centre on the face's exact outline is strictly inside
#: the grown polygon; 1/8 px does that with a wide margin on any GL
#: implementation with at least 4 subpixel bits. (With 0 the axis-aligned
#: tests lose pixels whose rays run along cell edges.)
COVERAGE_PAD_PX = 0.125
#: The caster's positions (its ray origins, the eye in index space) differ from the world
#: coordinates the passes draw from by up to this much of the scene scale (a few ulps): the
#: coverage pad reaches that far (the geometry shaders' ``pos_tol``).
ORIGIN_ROUNDING = 16 * 2.0 ** -52

#: Guard band (pixels) around the viewport: a face reaching past it is
#: drawn as its bounding box cut to the band, keeping emitted coordinates
#: small (float32-exact enough) without cutting anything that reaches a pixel.
GUARD_PX = 2.0

#: Margin of the CPU-side segment adjustments (eye inside the PC region,
#: parallel rays starting inside): ``MARGIN_T * |t| + MARGIN_S * scale``,
#: where ``scale`` bounds the scene's coordinates and distances
#: (`scene_scale`). Those t are float64 and tiny (0 or the clip distance);
#: the margin covers their few roundings many times over. (The shader's
#: own bounds need no CPU margin: see "Error bounds".)
MARGIN_T = 2.0 ** -21
MARGIN_S = 2.0 ** -32

#: Absolute slack of the fragment bounds, times the scene scale: covers
#: the caster's float64 roundings at the scale of the coordinates
#: (2^-52 scale) and the tests' "touching" rays (1e-12 scale from a box)
#: many times over; about 1e-8 of a cell on the CT head.
ABS_TOL = 2.0 ** -36

#: Absolute slack per unit of ``1 + x + y`` against float32 denormals
#: (below 2^-126) flushed to zero in an affine form's terms.
FLUSH_TOL = 2.0 ** -120

#: Error factor of a float32 affine form ``k0 + kx x + ky y`` against its
#: exact value: rounded coefficients and two roundings give at most
#: ``3 * 2^-24 * (|k0| + |kx| x + |ky| y)``; this is 8/3 of it, a power of two
#: above it (with room for the float64 coefficients' own error, ~2^-52 of the
#: same magnitudes).
AFFINE_ERR = 8.0 * 2.0 ** -24

#: Parallel views clip faces at ``-4 * TOL_REL * scale`` (a rounding behind
#: the view plane), so no crossing at t >= 0 is cut away.
TOL_REL = 2.0 ** -32

#: When the eye is inside the PC region (perspective), faces are clipped at
#: this fraction of the scene scale in front of the eye, and every pixel's
#: far is raised past the clipped sliver.
INSIDE_CLIP_REL = 2.0 ** -30


#: The passes hold ray distances in float32: a view reaching further than this many world
#: units from the eye (`view_reach`), 2^8 short of float32's largest, gets no pass: every
#: ray's segment is whole, and the caster walks it as `brute` does.
FLOAT32_REACH = 2.0 ** 120
#: The phases a pass times (`Segments.seconds`, `parc.bitplanes.raster_bits`'s info).
PASS_PHASES = ("prepare", "upload", "draw", "readback", "post", "total")

#: An eye this close to the PC region (times the scene scale) counts as inside it: the caster
#: moves the eye into index space, where one a rounding outside a face in world coordinates
#: can land exactly on it and take samples or a hit at t = 0 that no face in front of the eye
#: would give (`parc.origins.origin_slab`, the same reach for other ray origins; the scale
#: bounds the coordinates it adds).
EYE_ROUNDING = 2.0 ** -39


def perspective_clip(eye, proxy, th, aspect, ndc_limit, scale):
    """Where a perspective pass clips its faces: ``(d_min, cos_max, clip_near)``.

    ``d_min`` is the eye's distance to the PC region (0 inside it, or within
    `EYE_ROUNDING` of it). Every face lies at least ``d_min`` from the eye,
    and a point seen at that distance lies at least ``d_min * cos_max``
    ahead of it, ``cos_max`` the cosine of the widest angle to the view
    direction (the guard band's corner ray); half of that cuts nothing
    visible. An eye inside clips at `INSIDE_CLIP_REL` of the scene scale,
    and the caller covers the sliver.
    """
    d_min = distance_to_pc(eye, proxy)
    if d_min <= EYE_ROUNDING * scale:
        d_min = 0.0
    cos_max = 1.0 / math.sqrt(1.0 + th * th * ((aspect * ndc_limit[0]) ** 2 + ndc_limit[1] ** 2))
    clip_near = INSIDE_CLIP_REL * scale if d_min == 0.0 else 0.5 * d_min * cos_max
    return d_min, cos_max, clip_near


#: Cleared value: "no fragment" in both channels (near inf, far -inf).
EMPTY = math.inf


_UPLOADS = weakref.WeakKeyDictionary()
_SIZED = {}


def _sized(ctx, width, height):
    """The RG32F framebuffer for one image size (kept for the next call)."""
    key = (id(ctx), width, height)
    if key not in _SIZED:
        _SIZED.clear()   # keep one size: sizes rarely alternate
        rb = ctx.renderbuffer((width, height), components=2, dtype="f4")
        _SIZED[key] = ctx.framebuffer(color_attachments=[rb])
    return _SIZED[key]


@dataclass
class _Upload:
    faces: object
    edges: object
    offsets: tuple
    count: int            # faces uploaded
    n_open: int           # of them first: the faces on the open empty space
    cavity_lo: np.ndarray
    cavity_hi: np.ndarray
    vaos: dict = field(default_factory=dict)

    def vao(self, ctx, parallel):
        """The vertex array feeding the faces to the perspective or parallel program."""
        if parallel not in self.vaos:
            self.vaos[parallel] = ctx.vertex_array(program(ctx, "segments", parallel),
                                                   [(self.faces, "4i 2i", "in_face", "in_vrange")])
        return self.vaos[parallel]


def _upload(ctx, proxy):
    """Face records and boundary table of a proxy on the GPU (cached per proxy).

    Faces on the open empty space (`parc.origins.open_faces`) come first, so a
    frame whose rays all start outside the cavities draws only those.
    """
    up = _UPLOADS.get(proxy)
    if up is not None and up.faces.ctx is ctx:
        return up, False
    is_open, cavity = open_faces(proxy)
    order = np.argsort(~is_open, kind="stable")
    faces = np.ascontiguousarray(proxy.faces[order], dtype=np.int32)
    vbo = ctx.buffer(faces.tobytes())
    edges = np.concatenate(proxy.world_edges).astype(np.float64)
    ssbo = ctx.buffer(edges.tobytes())
    n = [len(e) for e in proxy.world_edges]
    offsets = (0, n[0], n[0] + n[1])
    kz, ky, kx = np.nonzero(cavity)
    ex, ey, ez = proxy.world_edges
    up = _Upload(faces=vbo, edges=ssbo, offsets=offsets, count=len(faces), n_open=int(is_open.sum()),
                 cavity_lo=np.stack([ex[kx], ey[ky], ez[kz]], axis=1),
                 cavity_hi=np.stack([ex[kx + 1], ey[ky + 1], ez[kz + 1]], axis=1))
    _UPLOADS[proxy] = up
    return up, True


@dataclass
class Segments:
    """Per-pixel ray segments from the proxy.

    Attributes
    ----------
    near, far : ndarray (H, W) float64
        The caster walks ``[near, far]`` of each pixel's ray; ``near > far``
        (``inf``, ``-inf``) where the ray meets no PC supercell.
    polygons : int
        Proxy faces drawn (``info['drawn']``): the faces bordering cavities
        are left out while no ray starts in one.
    seconds : dict
        ``prepare`` (clipping, which rays start inside), ``upload`` (0 when
        cached), ``draw`` (render + ``ctx.finish()``), ``readback``, ``post``
        (margins, inside tests), and their ``total``.
    info : dict
        ``eye_inside``, ``d_min``, ``clip_near``, ``pixels`` (with a segment),
        ``scale``, ``drawn`` (faces drawn: those bordering cavities are
        skipped while no ray starts in one); and ``whole_rays`` (True) when
        the view reaches too far for the float32 pass and every pixel's
        segment is its whole ray, nothing drawn.
    """

    near: np.ndarray
    far: np.ndarray
    polygons: int
    seconds: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    _seg: np.ndarray = field(default=None, repr=False)

    @property
    def seg(self):
        """``(H, W, 2)`` array ``[..., 0] = near``, ``[..., 1] = far``, as the caster takes it.

        `raster_segments` builds ``near`` and ``far`` as views of this array,
        so it is returned as is (no copy).
        """
        if self._seg is not None and self.near.base is self._seg and self.far.base is self._seg:
            return self._seg
        return np.stack([self.near, self.far], axis=-1)


def margin(t, scale):
    """The conservative widening applied to a read-back distance ``t`` (see `MARGIN_T`)."""
    return MARGIN_T * np.abs(t) + MARGIN_S * scale


def raster_segments(camera, width, height, proxy, *, pad_px=COVERAGE_PAD_PX, face_range=False, out=None):
    """Near and far ray distance of every pixel to the proxy, conservatively.

    Parameters
    ----------
    camera : Camera
    width, height : int
        Image size in pixels.
    proxy : Proxy
        From `parc.proxy.build_proxy`; its GPU buffers are uploaded on the
        first call and reused for later cameras.
    pad_px : float, default `COVERAGE_PAD_PX`
        Growth of each face's projection, pixels (keyword-only; for
        experiments: below ~1/64 rasterization rules can drop pixels).
    face_range : bool, default False
        Every face covering a pixel writes its whole range of ``t`` rather
        than where the pixel's centre ray crosses it. With ``pad_px >= 0.5``
        the bounds then hold for *every* ray through the pixel's square,
        which the light buffers of shadow PARC need (`parc.lights`).

    out : ndarray (H, W, 2) float64, optional
        Where to write the segments (the renderer reuses one from frame to
        frame, `parc.workspace`); default a new array.

    Returns
    -------
    Segments
        For every pixel whose centre ray (as `raycast.rays.camera_ray`
        builds it) meets a PC supercell: ``near <= `` its first entry
        (``>= 0``) and ``far >=`` its last exit.

    Raises
    ------
    OpenGLUnavailable
        No OpenGL context.
    InputError
        An image larger than the GL viewport limit.

    References
    ----------
    Sobierajski & Avila 1995, §3 (depth-buffer PARC, eye inside a PC cell).
    """
    width, height = int(width), int(height)
    check_viewport(width, height)
    ctx = get_context()
    seconds = {}
    lo, hi = proxy.bounds
    eye = np.asarray(camera.eye, dtype=np.float64)
    th = math.tan(math.radians(camera.fov) / 2.0)
    aspect = width / height
    scale = scene_scale(camera, lo, hi, aspect)

    if view_reach(camera, lo, hi, aspect) > FLOAT32_REACH:
        # Distances past float32's range (an eye 2^32 volume sizes from a volume 1e29 wide)
        # would come back infinite: no segment, and an empty picture where brute draws one.
        seg = np.empty((height, width, 2)) if out is None else out
        seg[..., 0] = 0.0
        seg[..., 1] = np.inf
        seconds = dict.fromkeys(PASS_PHASES, 0.0)
        info = {"eye_inside": False, "d_min": None, "clip_near": 0.0, "pixels": width * height,
                "scale": scale, "drawn": 0, "whole_rays": True}
        return Segments(near=seg[..., 0], far=seg[..., 1], polygons=0, seconds=seconds, info=info, _seg=seg)

    # Where the rays start relative to the PC region.
    t0 = time.perf_counter()
    ndc_limit = (1.0 + 2.0 * GUARD_PX / width, 1.0 + 2.0 * GUARD_PX / height)
    inside_px = None
    d_min = None
    if camera.parallel:
        clip_near = -4.0 * TOL_REL * scale   # keep crossings a rounding behind the view plane
        inside_px = parallel_inside(camera, width, height, proxy)
        eye_inside = bool(inside_px.any())
    else:
        d_min, cos_max, clip_near = perspective_clip(eye, proxy, th, aspect, ndc_limit, scale)
        eye_inside = d_min == 0.0
    seconds["prepare"] = time.perf_counter() - t0

    if proxy.n_polygons:
        t0 = time.perf_counter()
        up, fresh = _upload(ctx, proxy)
        if fresh:
            ctx.finish()
        seconds["upload"] = time.perf_counter() - t0 if fresh else 0.0

        t0 = time.perf_counter()
        parallel = camera.parallel
        vao = up.vao(ctx, parallel)
        prog = vao.program
        set_view_uniforms(prog, camera, width, height, up.offsets, clip_near=clip_near,
                          ndc_limit=ndc_limit, pad_px=pad_px, scale=scale)
        set_uniform(prog, "face_range", 1 if face_range else 0)
        fbo = _sized(ctx, width, height)
        fbo.use()
        ctx.viewport = (0, 0, width, height)
        ctx.disable(moderngl_module().DEPTH_TEST | moderngl_module().CULL_FACE)
        ctx.enable(moderngl_module().BLEND)
        ctx.blend_equation = moderngl_module().MIN
        fbo.clear(EMPTY, EMPTY, 0.0, 0.0)
        up.edges.bind_to_storage_buffer(0)
        drawn = up.count if in_cavity(up, camera, width, height, eye) else up.n_open
        vao.render(moderngl_module().POINTS, vertices=drawn)
        ctx.finish()
        seconds["draw"] = time.perf_counter() - t0

        t0 = time.perf_counter()
        rg = work_array("raster_readback", (height, width, 2), np.float32)
        fbo.read_into(rg, components=2, dtype="f4")
        seconds["readback"] = time.perf_counter() - t0
        ctx.blend_equation = moderngl_module().FUNC_ADD
        ctx.disable(moderngl_module().BLEND)

        t0 = time.perf_counter()
        # The shader wrote (near, -far), already conservative and near >= 0;
        # pixels without a fragment kept (inf, inf), i.e. near inf, far -inf.
        seg = np.empty((height, width, 2)) if out is None else out
        pixels = unpack_segments(rg, seg)
    else:
        drawn = 0
        seconds.update(upload=0.0, draw=0.0, readback=0.0)
        t0 = time.perf_counter()
        seg = np.empty((height, width, 2)) if out is None else out
        seg[..., 0] = np.inf
        seg[..., 1] = -np.inf
        pixels = 0
    near, far = seg[..., 0], seg[..., 1]

    if camera.parallel:
        if eye_inside:
            # A ray starting inside the PC region enters it at t = 0; its far
            # comes from the faces ahead (no face is clipped in a parallel
            # view except a rounding's width behind the view plane).
            near[inside_px] = 0.0
            far[inside_px] = np.maximum(far[inside_px], margin(0.0, scale))
    elif eye_inside:
        # Every ray starts inside. Faces were clipped at clip_near; a ray
        # leaving the PC region before then has no fragment, so raise far
        # past the clipped sliver (t <= clip_near / cos(angle)).
        near[:] = 0.0
        np.maximum(far, 2.0 * clip_near / cos_max + margin(0.0, scale), out=far)
    if eye_inside:
        pixels = np.count_nonzero(near <= far)
    seconds["post"] = time.perf_counter() - t0
    seconds["total"] = sum(seconds.values())
    info = {"eye_inside": bool(eye_inside), "d_min": d_min, "clip_near": clip_near,
            "pixels": int(pixels), "scale": scale, "drawn": drawn}
    return Segments(near=near, far=far, polygons=drawn, seconds=seconds, info=info, _seg=seg)


@kernel(parallel=True)
def unpack_segments(rg, seg):
    """``seg[y, x] = (near, far)`` from the read-back ``(near, -far)``; returns the pixels with
    ``near <= far``. One pass: NumPy's copy, negation and count took three (0.45 ms at 512x512)."""
    height, width, _ = seg.shape
    pixels = 0
    for y in prange(height):
        for x in range(width):
            near = rg[y, x, 0]
            far = -rg[y, x, 1]
            seg[y, x, 0] = near
            seg[y, x, 1] = far
            if near <= far:
                pixels += 1
    return pixels


def set_view_uniforms(prog, camera, width, height, edge_offset, *, clip_near, ndc_limit, pad_px, scale):
    """Uniforms of the face-growing geometry shader and the per-pixel ray test, shared by both passes."""
    eye = np.asarray(camera.eye, dtype=np.float64)
    f, r, u = camera.basis()
    th = math.tan(math.radians(camera.fov) / 2.0)
    aff0, affx, affy = _pixel_affine(camera, f, r, u, th, width, height)
    flush = FLUSH_TOL * (width + height)
    err_d = AFFINE_ERR * (np.abs(aff0) + np.abs(affx) * (width - 1) + np.abs(affy) * (height - 1)) + flush
    set_uniform(prog, "edge_offset", edge_offset)
    set_uniform(prog, "eye", tuple(eye))
    set_uniform(prog, "fwd", tuple(f))
    set_uniform(prog, "right", tuple(r))
    set_uniform(prog, "upv", tuple(u))
    set_uniform(prog, "parallel", 1 if camera.parallel else 0)
    set_uniform(prog, "tan_half", th)
    set_uniform(prog, "pscale", float(camera.parallel_scale or 0.0))
    set_uniform(prog, "aspect", width / height)
    set_uniform(prog, "clip_near", clip_near)
    set_uniform(prog, "ndc_limit", ndc_limit)
    set_uniform(prog, "ndc_pad", (2.0 * pad_px / width, 2.0 * pad_px / height))
    set_uniform(prog, "aff0", tuple(aff0))
    set_uniform(prog, "affx", tuple(affx))
    set_uniform(prog, "affy", tuple(affy))
    set_uniform(prog, "err_d", tuple(err_d))
    set_uniform(prog, "pix_max", (width - 1.0, height - 1.0))
    set_uniform(prog, "abs_tol", ABS_TOL * scale + flush)
    set_uniform(prog, "pos_tol", ORIGIN_ROUNDING * scale)


def _pixel_affine(camera, f, r, u, th, width, height):
    """The caster's per-pixel ray as an affine map of the pixel indices, float64.

    `raycast.rays.camera_ray` uses ``sx = (2 (x + 0.5) / W - 1) W / H`` and
    ``sy = 1 - 2 (y + 0.5) / H``, both affine in (x, y). Returns ``(k0, kx,
    ky)``, three 3-vectors with ``k0 + kx x + ky y`` = the direction ``f +
    tan(fov/2) (sx r + sy u)`` (perspective) or the origin's offset from the
    eye ``ps (sx r + sy u)`` (parallel).
    """
    aspect = width / height
    scale, base = (float(camera.parallel_scale), 0.0) if camera.parallel else (th, 1.0)
    r = np.asarray(r, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    k0 = (base * np.asarray(f, dtype=np.float64)
          + scale * (r * (aspect / width - aspect) + u * (1.0 - 1.0 / height)))
    kx = scale * r * (2.0 * aspect / width)
    ky = scale * u * (-2.0 / height)
    return k0, kx, ky


def box_corners(lo, hi):
    """The eight corners of the box ``[lo, hi]``, (8, 3)."""
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def view_reach(camera, lo, hi, aspect):
    """How far from the eye the view of the box ``[lo, hi]`` reaches: its farthest corner, and
    in a parallel view the view plane's half diagonal."""
    eye = np.asarray(camera.eye, dtype=np.float64)
    corners = box_corners(lo, hi)
    with np.errstate(over="ignore"):
        reach = float(np.linalg.norm((corners - eye) / 2.0 ** 512, axis=1).max()) * 2.0 ** 512
    if camera.parallel:
        reach += camera.parallel_scale * math.hypot(aspect, 1.0)
    return reach


def scene_scale(camera, lo, hi, aspect):
    """A bound on coordinates and distances in this view: sizes the margins."""
    eye = np.asarray(camera.eye, dtype=np.float64)
    corners = box_corners(lo, hi)
    s = max(np.abs(eye).max(), np.abs(corners).max(), np.linalg.norm(corners - eye, axis=1).max())
    if camera.parallel:
        s += camera.parallel_scale * math.hypot(aspect, 1.0)
    return float(s)


