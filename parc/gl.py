"""The headless OpenGL context and PARC's shader programs.

One context per process, created on first use through EGL (Mesa llvmpipe
on CPU-only machines, the vendor driver where there is a GPU), with the
programs compiled from ``parc/shaders`` once per context; llvmpipe's
rasterizer threads are pinned one to a CPU (`spread_rasterizer_threads`).
The passes that draw with them: `parc.raster` (near and far ray
distances), `parc.bitplanes` (planes of supercells), `parc.lights` (light
buffers, through `parc.raster`).
"""
from __future__ import annotations

import os
import re
import sys
import threading
import time
from pathlib import Path

from data_tools import InputError

#: Where the GLSL sources live; `load_shader` reads them by name.
SHADER_DIR = Path(__file__).with_name("shaders")

_CONTEXT = None
#: The thread the context was made on (or last moved to), the only one it is made current in.
_OWNER = None
#: Whether the context is current in `_OWNER` now: each render lets it go as it ends
#: (`release_context`), and the next call makes it current again.
_CURRENT = False
_PROGRAMS = {}

class OpenGLUnavailable(InputError):
    """No usable OpenGL 4.3 context (headless EGL) on this machine."""


def check_viewport(width, height):
    """Refuse an image larger than this OpenGL's viewport limit (creating the context if need be),
    so that `render` and `compare` refuse it before any note, warm-up or frame."""
    max_w, max_h = get_context().info["GL_MAX_VIEWPORT_DIMS"]
    if int(width) > max_w or int(height) > max_h:
        raise InputError(f"image {int(width)}x{int(height)} exceeds this OpenGL's limit {max_w}x{max_h} for parc's "
                         "buffers; --method brute has no such limit")


def get_context():
    """The process-wide headless OpenGL context, created on first call.

    An OpenGL context is current in one thread: the one that first called,
    the only one that may call again while it runs. Once it has ended, the
    context is made current in the next thread that calls. Renders let it go
    as they end (`release_context`), and this makes it current again.

    Returns
    -------
    moderngl.Context
        OpenGL 4.3 core or later through EGL.

    Raises
    ------
    OpenGLUnavailable
        moderngl or EGL is missing, or the driver cannot give 4.3 with
        float64 shaders (the message is one line).
    InputError
        A call from another thread while the first still runs.
    """
    global _CONTEXT, _OWNER, _CURRENT
    if _CONTEXT is not None:
        # The thread itself, not its id: a new thread may get the id of one that has ended,
        # and the context is not current in it.
        here = threading.current_thread()
        if here is not _OWNER:
            if _running(_OWNER):
                raise InputError(f"OpenGL work runs on the thread that first did it ({_OWNER.name}), and this is "
                                 f"{here.name}; render with method='parc' from that thread "
                                 "(method='brute' renders on any)")
            _adopt(here)
        elif not _CURRENT:
            _CONTEXT.__enter__()
            _CURRENT = True
        _delete_dropped()
        return _CONTEXT
    try:
        import moderngl
    except ImportError as exc:  # pragma: no cover - moderngl is a dependency
        raise OpenGLUnavailable(f"OpenGL is not available: cannot import moderngl ({exc})") from None
    # Mesa's EGL prints its warnings ("failed to create dri2 screen", one per device tried)
    # on stderr, ahead of the one line a failure is; a user who sets the level sees them.
    quiet = "EGL_LOG_LEVEL" not in os.environ
    uncached = _shader_cache_unwritable(os.environ)
    if quiet:
        os.environ["EGL_LOG_LEVEL"] = "fatal"
    if uncached:
        os.environ["MESA_SHADER_CACHE_DISABLE"] = "true"
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=430)
    except Exception as exc:  # moderngl raises plain Exceptions from the driver
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        hint = "; EGL_LOG_LEVEL=debug shows the driver's own messages" if quiet else ""
        raise OpenGLUnavailable(f"OpenGL is not available: no headless EGL context with "
                                f"OpenGL 4.3 ({reason}){hint}") from None
    finally:
        if quiet:
            del os.environ["EGL_LOG_LEVEL"]
        if uncached:
            del os.environ["MESA_SHADER_CACHE_DISABLE"]
    # Buffers uploaded for a proxy are released when the proxy goes away; kept until the context
    # is current again, not released at once: a proxy dropped between renders (the context let
    # go) would have its buffers deleted in no context, which does nothing, and kept them for good.
    ctx.gc_mode = "context_gc"
    spread_rasterizer_threads(wait=rasterizer_start_wait(ctx.info.get("GL_RENDERER", ""), os.environ))
    _CONTEXT, _OWNER, _CURRENT = ctx, threading.current_thread(), True
    return ctx


def _running(thread):
    """Whether ``thread`` still runs. Python keeps a thread it did not start (``_thread``'s, a Qt
    thread or a C library's callback) as a dummy that reads as alive for good: the first to render
    would have kept every other thread from it after it ended."""
    if isinstance(thread, threading._DummyThread):
        return thread.ident in sys._current_frames()
    return thread.is_alive()


def _shader_cache_unwritable(environ):
    """Whether Mesa would fail to make its shader cache, and say so on every run: it keeps it in
    the account's home folder from the password file, not HOME (``nobody``'s is ``/nonexistent``),
    where no folder of its own nor XDG_CACHE_HOME is given. PARC's few shaders compile at once."""
    if any(key in environ for key in ("MESA_SHADER_CACHE_DIR", "MESA_SHADER_CACHE_DISABLE", "XDG_CACHE_HOME")):
        return False
    try:
        import pwd
        home = Path(pwd.getpwuid(os.getuid()).pw_dir)
    except (ImportError, KeyError):
        return True
    cache = home / ".cache"
    return not os.access(cache if cache.exists() else home, os.W_OK)


def release_context():
    """Make the context current in no thread, if it is current in this one (`render` calls this as
    it ends). A thread that ends with the context current keeps it: Mesa's EGL then refuses
    to make it current in another, without a word, and that thread's OpenGL calls do
    nothing (a pass would read back the last frame's buffers, and draw that frame's segments)."""
    global _CURRENT
    if _current_here():
        _delete_dropped()
        _CONTEXT.__exit__(None, None, None)
        _CURRENT = False


def context_info():
    """The context's ``info`` (`get_context`), leaving it current only where it already was: a
    thread that asks for no more than that (the cost model's renderer, a report's machine)
    would otherwise end holding the context, and no other thread could take it over."""
    held = _current_here()
    info = get_context().info
    if not held:
        release_context()
    return info


def _current_here():
    return _CONTEXT is not None and _CURRENT and threading.current_thread() is _OWNER


def _delete_dropped():
    """Delete the OpenGL objects dropped since the last call (the context current in this thread)."""
    dropped = getattr(_CONTEXT, "objects", None)
    while dropped:
        # One released by hand is left as moderngl's InvalidObject, with nothing to release.
        release = getattr(dropped.popleft(), "release", None)
        if release is not None:
            release()


def _adopt(thread):
    """Make the context current in ``thread``, its first thread having ended (a worker's, say).

    The driver may refuse without raising (the context still current in the ended thread):
    a buffer made there tells, and the move is refused rather than drawn with no context."""
    global _OWNER, _CURRENT
    try:
        _CONTEXT.__enter__()
        _CONTEXT.buffer(reserve=4).release()
    except Exception as exc:  # moderngl raises plain Exceptions from the driver
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise InputError(f"OpenGL work ran on thread {_OWNER.name}, which has ended, and the driver cannot "
                         f"move its context to {thread.name} ({reason}); method='brute' renders on any") from None
    _OWNER, _CURRENT = thread, True


#: Mesa's CPU rasterizer names its threads ``llvmpipe-0``, ``llvmpipe-1``, ...
_RASTERIZER_THREAD = re.compile(r"llvmpipe-(\d+)")


def rasterizer_cpus(threads, cpus):
    """Which CPU each rasterizer thread gets: ``{tid: cpu}``, or ``{}`` to leave them be.

    ``threads``: ``(tid, name)`` of the process's threads; ``cpus``: the
    CPUs it may run on. Thread ``llvmpipe-n`` gets the n-th CPU, and only
    where there are at least as many of those threads as CPUs (llvmpipe's
    default: one a CPU), so that no CPU is favoured over another when
    several processes render at once; and only with two CPUs or more.
    """
    cpus = sorted(cpus)
    numbered = sorted((int(m.group(1)), tid) for tid, name in threads
                      if (m := _RASTERIZER_THREAD.fullmatch(name)))
    if len(cpus) < 2 or len(numbered) < len(cpus):
        return {}
    return {tid: cpus[n % len(cpus)] for n, tid in numbered}


#: Longest a new llvmpipe context waits for its rasterizer threads to be named, seconds.
RASTERIZER_START_WAIT = 0.25

#: The most rasterizer threads llvmpipe starts (Mesa's ``LP_MAX_THREADS``): with more
#: CPUs than that, `rasterizer_cpus` pins none, and there is nothing to wait for.
LLVMPIPE_MAX_THREADS = 32


def rasterizer_start_wait(renderer, environ):
    """How long `spread_rasterizer_threads` may wait for the threads of a context whose
    ``GL_RENDERER`` is ``renderer``: `RASTERIZER_START_WAIT` for llvmpipe, 0 for another
    driver (which starts no such threads) or where ``LP_NUM_THREADS`` asks for fewer
    threads than there are CPUs, or there are more CPUs than it starts threads
    (`rasterizer_cpus` leaves those alone)."""
    if "llvmpipe" not in renderer or not hasattr(os, "sched_getaffinity"):
        return 0.0
    try:
        cpus = len(_cpus())
        threads = int(environ.get("LP_NUM_THREADS", "").strip() or cpus)
    except (OSError, ValueError):
        return 0.0
    if threads < cpus or cpus > LLVMPIPE_MAX_THREADS:
        return 0.0
    return RASTERIZER_START_WAIT


def _cpus():
    return os.sched_getaffinity(0)


def _threads():
    """``(tid, name)`` of the process's threads."""
    threads = []
    for task in Path("/proc/self/task").iterdir():
        try:
            threads.append((int(task.name), (task / "comm").read_text().strip()))
        except (OSError, ValueError):   # a thread that ended meanwhile
            continue
    return threads


def spread_rasterizer_threads(wait=0.0):
    """Pin llvmpipe's rasterizer threads one to a CPU (`rasterizer_cpus`); Linux only, best effort.

    An OpenGL pass is a burst of a few milliseconds. The scheduler can
    start both of a 2-core machine's rasterizer threads on one core and
    leave them there: the burst is over before it moves one, and the pass
    runs at one thread's speed in that process. Pinned, a CT head skin
    pass at 512x512 took 2.6-2.9 ms, against 2.6-4.3 ms unpinned
    (``benchmarks/context_settings.py``). A GPU driver has no such
    threads, and nothing changes.

    Each rasterizer thread names itself once it runs, which on a busy
    machine can be after the context is made: until then it carries its
    creator's name and would be left unpinned. So the threads are looked
    for again, up to ``wait`` seconds, until there are enough to pin.

    Returns
    -------
    dict
        ``{tid: cpu}`` of the threads pinned.
    """
    if not hasattr(os, "sched_setaffinity"):
        return {}
    deadline = time.monotonic() + wait
    while True:
        try:
            plan = rasterizer_cpus(_threads(), _cpus())
        except OSError:
            return {}
        if plan or time.monotonic() >= deadline:
            break
        time.sleep(0.002)
    pinned = {}
    for tid, cpu in plan.items():
        try:
            os.sched_setaffinity(tid, {cpu})
        except OSError:
            continue
        pinned[tid] = cpu
    return pinned


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

