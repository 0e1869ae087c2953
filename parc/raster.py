"""OpenGL pass of depth-buffer PARC: per-pixel near and far ray distances of the proxy.

About this technique
--------------------
Sobierajski & Avila (1995, §3) project the proxy's outer faces twice into
z-buffers, with "less than" for the near distance and "greater than" for
the far one. This pass keeps the idea and fixes what a z-buffer gets
wrong for an exact ray caster:

- **Exact t, not interpolated depth.** The fragment shader rebuilds the
  pixel-centre ray from ``gl_FragCoord`` with the caster's formula
  (`raycast.rays.camera_ray`, in float64) and intersects it with the
  face's axis-aligned plane. Depth precision, the near-plane distance and
  perspective interpolation play no part.
- **One pass, no depth test.** Each fragment writes ``(t, -t)`` into an
  RG32F target under MIN blending: channel 0 ends as the nearest
  crossing, channel 1 as minus the farthest.
- **Conservative coverage.** A geometry shader clips each face at the
  near distance and grows its projection, in float64, to contain the
  Minkowski sum with a square of half-size `COVERAGE_PAD_PX` (each edge
  moved out by the square's support, mitred corners; the bounding box
  for slivers and faces reaching off screen), so rasterization rules and
  vertex snapping cannot drop a pixel whose centre ray crosses the face.
  The extra pixels cost fill, not accuracy: the fragment shader discards
  a pixel whose own ray misses the face. Measured on the CT head (skin,
  4-cell supercells, 512x512): 1.23M fragments for 1.15M real crossings
  (the screen bounding box alone gave 2.17M).
- **Margins in float64 on the CPU.** After read-back, ``near -=`` and
  ``far +=`` `margin` (see `MARGIN_T`) cover the float32 storage and
  the float64 arithmetic; the price is at most one extra cell per ray.
- **Eye inside the PC region.** Perspective: if the eye lies in (or on) a
  PC supercell, every ray starts inside, so near is 0 for every pixel
  (the paper: "start from the viewing plane"). Otherwise the faces are
  clipped at a forward distance below ``d_min cos(theta_max)``, where
  ``d_min`` is the eye's distance to the nearest PC supercell, so no
  visible part of any face is lost. Parallel: each pixel's ray starts on
  the view plane; a pixel whose start lies in a PC supercell gets near 0.

The OpenGL context is created once per process (`get_context`), headless
through EGL (llvmpipe on CPU-only machines).
"""
from __future__ import annotations

import math
import time
import weakref
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from data_tools import InputError

#: Where the GLSL sources live; `load_shader` reads them by name.
SHADER_DIR = Path(__file__).with_name("shaders")

#: Coverage growth of each face's projection, in pixels. It only has to
#: exceed the error of the emitted float32 corners (< 1e-3 px up to 16k
#: images) plus vertex snapping (1/256 px with llvmpipe's 8 subpixel bits)
#: so that a pixel centre on the face's exact outline is strictly inside
#: the grown polygon; 1/8 px does that with a wide margin on any GL
#: implementation with at least 4 subpixel bits. (With 0 the axis-aligned
#: tests lose pixels whose rays run along cell edges.)
COVERAGE_PAD_PX = 0.125

#: Guard band (pixels) around the viewport: a face reaching past it is
#: drawn as its bounding box cut to the band, keeping emitted coordinates
#: small (float32-exact enough) without cutting anything that reaches a pixel.
GUARD_PX = 2.0

#: Margin applied after read-back: ``MARGIN_T * |t| + MARGIN_S * scale``,
#: where ``scale`` bounds the scene's coordinates and distances
#: (`_scene_scale`). Error budget of a read-back t against the exact
#: crossing of the caster's own float64 ray with the face's float64 plane:
#: the fragment shader forms the caster's direction bit for bit, and each
#: of its few float64 roundings is relative to the quantity rounded
#: (``c - o_a``, the division, the norm), ~1e-15 |t| in all, with no
#: amplification for rays nearly parallel to the face; float32 storage then
#: rounds t by 2^-24 |t|. MARGIN_T = 2^-21 covers that 8 times. MARGIN_S
#: = 2^-32 (~2e-10) covers rounding at the scale of the coordinates
#: (2^-52 scale per operation) with room for drivers whose float64
#: division is not correctly rounded. Both are far below a cell for any
#: sane volume, so the price is at most one extra cell at each end.
MARGIN_T = 2.0 ** -21
MARGIN_S = 2.0 ** -32

#: Face test tolerance in the fragment shader, ``TOL_REL * (scale + |t|)``:
#: it must exceed the float64 error of the crossing point (~2e-16 scale +
#: 4e-16 |t|, as above) so that rays through face edges and corners keep
#: their fragment; a ray missing a face by less than it gets a harmless
#: extra fragment.
TOL_REL = 2.0 ** -32

#: When the eye is inside the PC region (perspective), faces are clipped at
#: this fraction of the scene scale in front of the eye, and every pixel's
#: far is raised past the clipped sliver.
INSIDE_CLIP_REL = 2.0 ** -30

#: Pixels per band when parallel-view ray origins are tested on the CPU.
_BAND_PIXELS = 1 << 18

#: Cleared value: "no fragment" in both channels.
EMPTY = float(np.finfo(np.float32).max)


class OpenGLUnavailable(InputError):
    """No usable OpenGL 4.3 context (headless EGL) on this machine."""


_CONTEXT = None
_PROGRAMS = {}
_UPLOADS = weakref.WeakKeyDictionary()
_SIZED = {}


def get_context():
    """The process-wide headless OpenGL context, created on first call.

    Returns
    -------
    moderngl.Context
        OpenGL 4.3 core or later through EGL.

    Raises
    ------
    OpenGLUnavailable
        moderngl or EGL is missing, or the driver cannot give 4.3 with
        float64 shaders (the message is one line).
    """
    global _CONTEXT
    if _CONTEXT is not None:
        return _CONTEXT
    try:
        import moderngl
    except ImportError as exc:  # pragma: no cover - moderngl is a dependency
        raise OpenGLUnavailable(f"OpenGL is not available: cannot import moderngl ({exc})") from None
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=430)
    except Exception as exc:  # moderngl raises plain Exceptions from the driver
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise OpenGLUnavailable(f"OpenGL is not available: no headless EGL context with "
                                f"OpenGL 4.3 ({reason})") from None
    # Buffers uploaded for a proxy are released when the proxy goes away.
    ctx.gc_mode = "auto"
    _CONTEXT = ctx
    return ctx


def load_shader(name):
    """Source text of ``parc/shaders/<name>``."""
    return (SHADER_DIR / name).read_text()


def _program(ctx, name):
    """The compiled program ``parc/shaders/<name>.{vert,geom,frag}`` (cached per context)."""
    key = (id(ctx), name)
    if key not in _PROGRAMS:
        try:
            _PROGRAMS[key] = ctx.program(vertex_shader=load_shader(f"{name}.vert"),
                                         geometry_shader=load_shader(f"{name}.geom"),
                                         fragment_shader=load_shader(f"{name}.frag"))
        except Exception as exc:
            # A driver without float64 shaders or geometry shaders ends up here.
            lines = [ln.strip() for ln in str(exc).splitlines() if "error" in ln.lower()]
            raise OpenGLUnavailable(f"OpenGL {ctx.info['GL_VERSION']} cannot compile PARC's "
                                    f"{name} shaders: {(lines or [str(exc)])[-1]}") from None
    return _PROGRAMS[key]


def _sized(ctx, width, height):
    """Per image size: an RG32F framebuffer and the table of screen offsets (kept for the next call).

    The table holds the caster's ``sx`` per column, then ``sy`` per row, in
    float64, computed with `raycast.rays.camera_ray`'s formula and operation
    order so that the fragment shader's rays are the caster's bit for bit.
    """
    key = (id(ctx), width, height)
    if key not in _SIZED:
        _SIZED.clear()   # keep one size: sizes rarely alternate
        rb = ctx.renderbuffer((width, height), components=2, dtype="f4")
        x = np.arange(width, dtype=np.float64)
        y = np.arange(height, dtype=np.float64)
        sx = (2.0 * (x + 0.5) / width - 1.0) * (width / height)
        sy = 1.0 - 2.0 * (y + 0.5) / height
        _SIZED[key] = (ctx.framebuffer(color_attachments=[rb]),
                       ctx.buffer(np.concatenate([sx, sy]).tobytes()))
    return _SIZED[key]


@dataclass
class _Upload:
    vao: object
    faces: object
    edges: object
    offsets: tuple
    count: int


def _upload(ctx, proxy):
    """Face records and boundary table of a proxy on the GPU (cached per proxy)."""
    up = _UPLOADS.get(proxy)
    if up is not None and up.vao.ctx is ctx:
        return up, False
    faces = np.ascontiguousarray(proxy.faces, dtype=np.int32)
    vbo = ctx.buffer(faces.tobytes())
    edges = np.concatenate(proxy.world_edges).astype(np.float64)
    ssbo = ctx.buffer(edges.tobytes())
    n = [len(e) for e in proxy.world_edges]
    offsets = (0, n[0], n[0] + n[1])
    vao = ctx.vertex_array(_program(ctx, "segments"), [(vbo, "4i 2i", "in_face", "in_vrange")])
    up = _Upload(vao=vao, faces=vbo, edges=ssbo, offsets=offsets, count=len(faces))
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
        Proxy faces drawn.
    seconds : dict
        ``upload`` (0 when cached), ``draw`` (render + ``ctx.finish()``),
        ``readback``, ``post`` (margins, inside tests).
    info : dict
        ``eye_inside``, ``d_min``, ``clip_near``, ``pixels`` (with a segment),
        ``scale``.
    """

    near: np.ndarray
    far: np.ndarray
    polygons: int
    seconds: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    @property
    def seg(self):
        """``(H, W, 2)`` array ``[..., 0] = near``, ``[..., 1] = far``, as the caster takes it."""
        return np.stack([self.near, self.far], axis=-1)


def margin(t, scale):
    """The conservative widening applied to a read-back distance ``t`` (see `MARGIN_T`)."""
    return MARGIN_T * np.abs(t) + MARGIN_S * scale


def raster_segments(camera, width, height, proxy, *, pad_px=COVERAGE_PAD_PX):
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
    ctx = get_context()
    max_w, max_h = ctx.info["GL_MAX_VIEWPORT_DIMS"]
    if width > max_w or height > max_h:
        raise InputError(f"image {width}x{height} exceeds this OpenGL's limit {max_w}x{max_h}")
    seconds = {}
    lo, hi = proxy.bounds
    eye = np.asarray(camera.eye, dtype=np.float64)
    f, r, u = camera.basis()
    th = math.tan(math.radians(camera.fov) / 2.0)
    aspect = width / height
    scale = _scene_scale(camera, lo, hi, aspect)

    # Where the rays start relative to the PC region.
    t0 = time.perf_counter()
    ndc_limit = (1.0 + 2.0 * GUARD_PX / width, 1.0 + 2.0 * GUARD_PX / height)
    inside_px = None
    d_min = None
    if camera.parallel:
        clip_near = -4.0 * TOL_REL * scale   # keep crossings a rounding behind the view plane
        inside_px = _parallel_inside(camera, width, height, proxy)
        eye_inside = bool(inside_px.any())
    else:
        d_min = _distance_to_pc(eye, proxy)
        eye_inside = d_min == 0.0
        # Visible points have forward distance >= d * cos(angle to f) and
        # the guard band's corner ray has the largest angle.
        cos_max = 1.0 / math.sqrt(1.0 + th * th * ((aspect * ndc_limit[0]) ** 2 + ndc_limit[1] ** 2))
        clip_near = INSIDE_CLIP_REL * scale if eye_inside else 0.5 * d_min * cos_max
    seconds["prepare"] = time.perf_counter() - t0

    if proxy.n_polygons:
        t0 = time.perf_counter()
        up, fresh = _upload(ctx, proxy)
        if fresh:
            ctx.finish()
        seconds["upload"] = time.perf_counter() - t0 if fresh else 0.0

        t0 = time.perf_counter()
        prog = _program(ctx, "segments")
        _set(prog, "edge_offset", up.offsets)
        _set(prog, "eye", tuple(eye))
        _set(prog, "fwd", tuple(f))
        _set(prog, "right", tuple(r))
        _set(prog, "upv", tuple(u))
        _set(prog, "parallel", 1 if camera.parallel else 0)
        _set(prog, "tan_half", th)
        _set(prog, "pscale", float(camera.parallel_scale or 0.0))
        _set(prog, "aspect", aspect)
        _set(prog, "clip_near", clip_near)
        _set(prog, "ndc_limit", ndc_limit)
        _set(prog, "ndc_pad", (2.0 * pad_px / width, 2.0 * pad_px / height))
        _set(prog, "width", width)
        _set(prog, "scale", scale)
        _set(prog, "tol_rel", TOL_REL)
        _set(prog, "t_min", -TOL_REL * scale)
        fbo, offsets = _sized(ctx, width, height)
        fbo.use()
        ctx.viewport = (0, 0, width, height)
        ctx.disable(_moderngl().DEPTH_TEST | _moderngl().CULL_FACE)
        ctx.enable(_moderngl().BLEND)
        ctx.blend_equation = _moderngl().MIN
        fbo.clear(EMPTY, EMPTY, 0.0, 0.0)
        up.edges.bind_to_storage_buffer(0)
        offsets.bind_to_storage_buffer(1)
        up.vao.render(_moderngl().POINTS, vertices=up.count)
        ctx.finish()
        seconds["draw"] = time.perf_counter() - t0

        t0 = time.perf_counter()
        rg = np.frombuffer(fbo.read(components=2, dtype="f4"), dtype=np.float32)
        rg = rg.reshape(height, width, 2)
        seconds["readback"] = time.perf_counter() - t0
        ctx.blend_equation = _moderngl().FUNC_ADD
        ctx.disable(_moderngl().BLEND)

        t0 = time.perf_counter()
        # Whole-image float64 arithmetic (cheaper than gathering the hit
        # pixels), then the empty ones reset. margin(t) = MARGIN_T |t| + MARGIN_S scale.
        empty = rg[..., 0] == EMPTY
        near = rg[..., 0].astype(np.float64)
        near -= MARGIN_T * np.abs(near) + MARGIN_S * scale
        np.maximum(near, 0.0, out=near)
        far = rg[..., 1].astype(np.float64)
        np.negative(far, out=far)
        far += MARGIN_T * np.abs(far) + MARGIN_S * scale
        near[empty] = np.inf
        far[empty] = -np.inf
    else:
        seconds.update(upload=0.0, draw=0.0, readback=0.0)
        t0 = time.perf_counter()
        near = np.full((height, width), np.inf)
        far = np.full((height, width), -np.inf)

    if camera.parallel:
        # A ray starting inside the PC region enters it at t = 0; its far
        # comes from the faces ahead (no face is clipped in a parallel view
        # except a rounding's width behind the view plane).
        near[inside_px] = 0.0
        far[inside_px] = np.maximum(far[inside_px], margin(0.0, scale))
    elif eye_inside:
        # Every ray starts inside. Faces were clipped at clip_near; a ray
        # leaving the PC region before then has no fragment, so raise far
        # past the clipped sliver (t <= clip_near / cos(angle)).
        near[:] = 0.0
        np.maximum(far, 2.0 * clip_near / cos_max + margin(0.0, scale), out=far)
    seconds["post"] = time.perf_counter() - t0
    seconds["total"] = sum(seconds.values())
    info = {"eye_inside": bool(eye_inside), "d_min": d_min, "clip_near": clip_near,
            "pixels": int(np.count_nonzero(near <= far)), "scale": scale}
    return Segments(near=near, far=far, polygons=proxy.n_polygons, seconds=seconds, info=info)


def _moderngl():
    import moderngl
    return moderngl


def _set(prog, name, value):
    """Set a uniform the compiler kept (unused ones are optimized away)."""
    if name in prog:
        prog[name].value = value


def _scene_scale(camera, lo, hi, aspect):
    """A bound on coordinates and distances in this view: sizes the margins."""
    eye = np.asarray(camera.eye, dtype=np.float64)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    s = max(np.abs(eye).max(), np.abs(corners).max(), np.linalg.norm(corners - eye, axis=1).max())
    if camera.parallel:
        s += camera.parallel_scale * math.hypot(aspect, 1.0)
    return float(s)


def _distance_to_pc(point, proxy):
    """Euclidean distance from ``point`` to the nearest PC supercell box (0 if inside or on one)."""
    ex, ey, ez = proxy.world_edges
    if not proxy.pc.any():
        return math.inf

    def axis_gap(e, p):
        # Per supercell along one axis: distance from p to [e[a], e[a+1]].
        return np.maximum(np.maximum(e[:-1] - p, 0.0), p - e[1:])

    gx, gy, gz = (axis_gap(e, p) ** 2 for e, p in zip((ex, ey, ez), point))
    plane = gy[:, None] + gx[None, :]
    best = math.inf
    # Slab by slab in z keeps memory at one (Ay, Ax) plane per slice.
    for k in np.flatnonzero(proxy.pc.any(axis=(1, 2))):
        best = min(best, gz[k] + float(plane[proxy.pc[k]].min()))
        if best == 0.0:
            break
    return math.sqrt(best)


def _parallel_inside(camera, width, height, proxy):
    """Pixels of a parallel view whose ray starts inside (or on) a PC supercell, (H, W) bool.

    Ray origins by the caster's formula, a band of rows at a time (memory).
    """
    f, r, u = camera.basis()
    ps = camera.parallel_scale
    eye = np.asarray(camera.eye, dtype=np.float64)
    sx = (2.0 * (np.arange(width) + 0.5) / width - 1.0) * (width / height)
    lo, hi = proxy.bounds
    inside = np.zeros((height, width), dtype=bool)
    band = max(1, _BAND_PIXELS // width)
    for y0 in range(0, height, band):
        sy = 1.0 - 2.0 * (np.arange(y0, min(height, y0 + band)) + 0.5) / height
        o = eye + ps * (sx[None, :, None] * r + sy[:, None, None] * u)
        o = o.reshape(-1, 3)
        cand = np.flatnonzero(np.all((o >= lo) & (o <= hi), axis=1))
        if not len(cand):
            continue
        p = o[cand]
        idx = []
        for axis, e in enumerate(proxy.world_edges):
            n = len(e) - 1
            # Closed boxes: a point on a boundary belongs to both neighbours.
            right = np.clip(np.searchsorted(e, p[:, axis], "right") - 1, 0, n - 1)
            left = np.clip(np.searchsorted(e, p[:, axis], "left") - 1, 0, n - 1)
            idx.append((left, right))
        (x0, x1), (y0_, y1_), (z0, z1) = idx
        hit = np.zeros(len(cand), dtype=bool)
        for zz in (z0, z1):
            for yy in (y0_, y1_):
                for xx in (x0, x1):
                    hit |= proxy.pc[zz, yy, xx]
        flat = inside[y0:y0 + band].reshape(-1)
        flat[cand] = hit
    return inside
