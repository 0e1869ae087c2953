"""The headless OpenGL context and PARC's shader programs.

One context per process, created on first use through EGL (Mesa llvmpipe
on CPU-only machines, the vendor driver where there is a GPU), with the
programs compiled from ``parc/shaders`` once per context. The passes that
draw with them: `parc.raster` (near and far ray distances), `parc.bitplanes`
(planes of supercells), `parc.lights` (light buffers, through `parc.raster`).
"""
from __future__ import annotations

from pathlib import Path

from data_tools import InputError

#: Where the GLSL sources live; `load_shader` reads them by name.
SHADER_DIR = Path(__file__).with_name("shaders")

_CONTEXT = None
_PROGRAMS = {}


class OpenGLUnavailable(InputError):
    """No usable OpenGL 4.3 context (headless EGL) on this machine."""


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


def program(ctx, name, parallel=False):
    """The compiled program ``parc/shaders/<name>.{vert,geom,frag}`` (cached per context).

    With ``parallel``, the fragment shader is compiled with ``PARALLEL``
    defined (its parallel-view path).
    """
    key = (id(ctx), name, bool(parallel))
    if key not in _PROGRAMS:
        frag = load_shader(f"{name}.frag")
        if parallel:
            head, _, rest = frag.partition("\n")
            frag = f"{head}\n#define PARALLEL 1\n{rest}"
        try:
            _PROGRAMS[key] = ctx.program(vertex_shader=load_shader(f"{name}.vert"),
                                         geometry_shader=load_shader(f"{name}.geom"),
                                         fragment_shader=frag)
        except Exception as exc:
            # A driver without float64 shaders or geometry shaders ends up here.
            lines = [ln.strip() for ln in str(exc).splitlines() if "error" in ln.lower()]
            raise OpenGLUnavailable(f"OpenGL {ctx.info['GL_VERSION']} cannot compile PARC's "
                                    f"{name} shaders: {(lines or [str(exc)])[-1]}") from None
    return _PROGRAMS[key]


def moderngl_module():
    import moderngl
    return moderngl


def set_uniform(prog, name, value):
    """Set a uniform the compiler kept (unused ones are optimized away)."""
    if name in prog:
        prog[name].value = value

