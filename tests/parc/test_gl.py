"""The OpenGL context's set-up: llvmpipe's rasterizer threads spread over the CPUs."""
import gc
import os
import subprocess
import sys
import threading
import types

import pytest

from data_tools import InputError

import parc.gl as glmod
from parc.gl import RASTERIZER_START_WAIT, rasterizer_cpus, rasterizer_start_wait, spread_rasterizer_threads


def test_each_rasterizer_thread_gets_its_own_cpu():
    threads = [(100, "python"), (103, "llvmpipe-1"), (102, "llvmpipe-0"), (104, "python:disk$0")]
    assert rasterizer_cpus(threads, {5, 3}) == {102: 3, 103: 5}


def test_more_rasterizer_threads_than_cpus_go_round():
    threads = [(10 + n, f"llvmpipe-{n}") for n in range(5)]
    assert rasterizer_cpus(threads, [0, 1]) == {10: 0, 11: 1, 12: 0, 13: 1, 14: 0}


@pytest.mark.parametrize("threads, cpus", [
    ([(2, "llvmpipe-0")], [0, 1]),                                  # fewer threads than CPUs
    ([(2, "llvmpipe-0"), (3, "llvmpipe-1")], [0]),                  # one CPU: nothing to spread
    ([(2, "python"), (3, "llvmpipe-x"), (4, "llvmpipe-0 ")], [0, 1]),  # not rasterizer threads
    ([], [0, 1, 2]),                                                 # a GPU driver
])
def test_rasterizer_threads_left_alone(threads, cpus):
    assert rasterizer_cpus(threads, cpus) == {}


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="thread affinity is Linux's")
def test_the_context_leaves_llvmpipe_threads_one_to_a_cpu(gl):
    if "llvmpipe" not in gl.info["GL_RENDERER"]:
        pytest.skip(f"not llvmpipe: {gl.info['GL_RENDERER']}")
    cpus = os.sched_getaffinity(0)
    names = {int(t): open(f"/proc/self/task/{t}/comm").read().strip() for t in os.listdir("/proc/self/task")}
    raster = [tid for tid, name in names.items() if name.startswith("llvmpipe-")]
    if len(cpus) < 2 or len(raster) < len(cpus):
        pytest.skip(f"{len(raster)} rasterizer threads on {len(cpus)} CPUs: left as they are")
    given = {tid: os.sched_getaffinity(tid) for tid in raster}
    assert all(len(c) == 1 for c in given.values()), given
    assert set().union(*given.values()) == cpus
    # Asking again changes nothing and pins the same way.
    assert spread_rasterizer_threads() == {tid: next(iter(c)) for tid, c in given.items()}


@pytest.mark.parametrize("renderer, environ, wait", [
    ("llvmpipe (LLVM 15.0.6, 256 bits)", {}, RASTERIZER_START_WAIT),
    ("llvmpipe (LLVM 15.0.6, 256 bits)", {"LP_NUM_THREADS": "2"}, RASTERIZER_START_WAIT),
    ("llvmpipe (LLVM 15.0.6, 256 bits)", {"LP_NUM_THREADS": "1"}, 0.0),     # fewer threads than CPUs: none pinned
    ("llvmpipe (LLVM 15.0.6, 256 bits)", {"LP_NUM_THREADS": "many"}, 0.0),
    ("NVIDIA H100 80GB HBM3/PCIe/SSE2", {}, 0.0),                           # no rasterizer threads to wait for
])
def test_only_llvmpipe_waits_for_its_rasterizer_threads(monkeypatch, renderer, environ, wait):
    monkeypatch.setattr(glmod, "_cpus", lambda: {0, 1})
    assert rasterizer_start_wait(renderer, environ) == wait
    # More CPUs than llvmpipe starts threads: none is pinned, so none is waited for.
    monkeypatch.setattr(glmod, "_cpus", lambda: set(range(glmod.LLVMPIPE_MAX_THREADS + 1)))
    assert rasterizer_start_wait(renderer, {}) == 0.0
    # No thread affinity (macOS): nothing is pinned, and nothing asked of the system.
    monkeypatch.delattr(glmod.os, "sched_getaffinity", raising=False)
    assert rasterizer_start_wait(renderer, {}) == 0.0


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="thread affinity is Linux's")
def test_rasterizer_threads_that_name_themselves_late_are_pinned(monkeypatch):
    # A thread carries its creator's name until it runs; on a busy machine the
    # context can be made before then, and the pass ran unpinned in that process.
    looks = [[(1, "python"), (2, "python"), (3, "python")],
             [(1, "python"), (2, "llvmpipe-0"), (3, "python")],
             [(1, "python"), (2, "llvmpipe-0"), (3, "llvmpipe-1")]]
    seen = []

    def threads():
        seen.append(1)
        return looks[min(len(seen), len(looks)) - 1]
    pinned = {}
    monkeypatch.setattr(glmod, "_threads", threads)
    monkeypatch.setattr(glmod, "_cpus", lambda: {0, 1})
    monkeypatch.setattr(glmod.os, "sched_setaffinity", lambda tid, cpus: pinned.update({tid: set(cpus)}))
    assert spread_rasterizer_threads(wait=5.0) == {2: 0, 3: 1}
    assert pinned == {2: {0}, 3: {1}} and len(seen) == 3
    # Without waiting, the first look finds nothing to pin; one that never fills up gives up.
    seen.clear()
    pinned.clear()
    assert spread_rasterizer_threads() == {} and len(seen) == 1
    looks[:] = looks[:1]
    seen.clear()
    assert spread_rasterizer_threads(wait=0.5) == {} and len(seen) > 1 and pinned == {}   # polled again


def test_a_wait_for_as_many_cpus_as_llvmpipe_starts_threads(monkeypatch):
    # At LLVMPIPE_MAX_THREADS CPUs there is a thread for each, and each is pinned: worth the wait.
    monkeypatch.setattr(glmod, "_cpus", lambda: set(range(glmod.LLVMPIPE_MAX_THREADS)))
    assert rasterizer_start_wait("llvmpipe (LLVM 15.0.6, 256 bits)", {}) == RASTERIZER_START_WAIT


def test_shaders_the_driver_cannot_compile_are_one_line(monkeypatch):
    # A driver without float64 or geometry shaders: its compiler's log is many lines.
    class Context:
        info = {"GL_VERSION": "4.1 Metal"}

        def program(self, **shaders):
            raise Exception("GLSL Compiler failed\n\ngeometry_shader\n===============\n"
                            "0:12(3): error: `double' not supported\n0:40(1): warning: unused\n")
    monkeypatch.setattr(glmod, "_PROGRAMS", {})
    with pytest.raises(glmod.OpenGLUnavailable) as err:
        glmod.program(Context(), "segments", parallel=True)
    msg = str(err.value)
    assert "\n" not in msg, msg
    assert msg == "OpenGL 4.1 Metal cannot compile PARC's segments shaders: 0:12(3): error: `double' not supported"


def _ended_thread(name):
    t = threading.Thread(target=lambda: None, name=name)
    t.start()
    t.join()
    return t


class _RaisingMove:
    """A context the driver cannot make current in another thread: it says so."""
    def __enter__(self):
        raise Exception("eglMakeCurrent failed\nsecond line")


class _SilentMove:
    """Mesa's EGL keeps a context current in the thread that ended with it: making it current
    elsewhere fails without raising, and every OpenGL call there does nothing."""
    def __enter__(self):
        pass

    def buffer(self, reserve):
        raise Exception("cannot create buffer")


@pytest.mark.parametrize("context, reason", [(_RaisingMove, "(eglMakeCurrent failed)"),
                                             (_SilentMove, "(cannot create buffer)")], ids=["raises", "silent"])
def test_a_context_the_driver_cannot_move_to_another_thread_is_one_line(monkeypatch, context, reason):
    first = _ended_thread("worker-1")
    monkeypatch.setattr(glmod, "_CONTEXT", context())
    monkeypatch.setattr(glmod, "_OWNER", first)
    monkeypatch.setattr(glmod, "_CURRENT", False)
    with pytest.raises(InputError) as err:
        glmod.get_context()
    msg = str(err.value)
    assert "\n" not in msg and "worker-1, which has ended" in msg and reason in msg, msg
    assert "method='brute' renders on any" in msg and glmod._OWNER is first and not glmod._CURRENT


def test_the_thread_that_takes_the_context_over_keeps_it_while_it_runs(monkeypatch):
    entered = []

    class Context:
        def __enter__(self):
            entered.append(threading.current_thread().name)

        def buffer(self, reserve):
            return types.SimpleNamespace(release=lambda: None)
    ctx = Context()
    monkeypatch.setattr(glmod, "_CONTEXT", ctx)
    monkeypatch.setattr(glmod, "_OWNER", _ended_thread("worker-1"))
    monkeypatch.setattr(glmod, "_CURRENT", False)
    took, hold = threading.Event(), threading.Event()

    def taker():
        glmod.get_context()
        took.set()
        hold.wait(30)
    t = threading.Thread(target=taker, name="taker")
    t.start()
    try:
        assert took.wait(30)
        # The context is current in "taker" now: another thread may not use it meanwhile.
        with pytest.raises(InputError, match=r"the thread that first did it \(taker\)"):
            glmod.get_context()
    finally:
        hold.set()
        t.join()
    assert glmod.get_context() is ctx and entered == ["taker", threading.current_thread().name]


def test_a_thread_python_did_not_start_lets_the_context_go_when_it_ends():
    """A thread started outside `threading` (``_thread``, a Qt thread, a C library's callback) is
    kept as a dummy whose ``is_alive()`` stays true: once it had made the context, every other
    thread was refused for good. In a process of its own: here the context is this thread's."""
    script = """if True:
        import _thread, time
        import numpy as np
        from data_tools.synthetic import blobs
        from parc import Camera, Isosurface, Scene, render
        vol = blobs(12, seed=1)
        scene = Scene(camera=Camera.framing(*vol.bounds), size=(16, 16), volumes=[Isosurface(vol, 100.0)])
        done = []
        _thread.start_new_thread(lambda: done.append(render(scene, "parc").image), ())
        while not done:
            time.sleep(0.01)
        time.sleep(0.5)                                         # the thread has returned
        print(np.array_equal(render(scene, "parc").image, done[0]), np.count_nonzero(done[0][..., 3]))
    """
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    same, hits = run.stdout.split()
    assert same == "True" and int(hits) > 0


@pytest.mark.parametrize("ask", ["cost model", "bench machine"])
def test_a_thread_that_only_reads_the_renderer_lets_the_context_go(monkeypatch, ask):
    # Mesa's EGL refuses to move a context that a thread ended holding: a worker that only
    # picked a supercell size (or described the machine) would leave no thread able to render.
    from parc import costmodel
    from parc.bench import machine
    made_current, let_go = [], []

    class Context:
        info = {"GL_RENDERER": "llvmpipe (LLVM 15.0.7, 256 bits)", "GL_VERSION": "4.5"}

        def __enter__(self):
            made_current.append(threading.current_thread().name)

        def __exit__(self, *exc):
            let_go.append(threading.current_thread().name)

        def buffer(self, reserve):
            return types.SimpleNamespace(release=lambda: None)
    monkeypatch.setattr(glmod, "_CONTEXT", Context())
    monkeypatch.setattr(glmod, "_OWNER", _ended_thread("worker-1"))
    monkeypatch.setattr(glmod, "_CURRENT", False)
    t = threading.Thread(target=costmodel.raster_costs if ask == "cost model" else machine, name="asker")
    t.start()
    t.join()
    assert made_current == ["asker"] and let_go == ["asker"] and not glmod._CURRENT


def test_a_uniform_the_compiler_left_out_is_not_set():
    kept = types.SimpleNamespace(value=0.0)
    prog = {"kept": kept}
    glmod.set_uniform(prog, "optimized_away", 1.0)
    glmod.set_uniform(prog, "kept", 2.0)
    assert kept.value == 2.0


def _is_buffer():
    """OpenGL's own glIsBuffer, asked of the current context."""
    import ctypes
    for name in ("libOpenGL.so.0", "libGL.so.1"):
        try:
            lib = ctypes.CDLL(name)
        except OSError:
            continue
        lib.glIsBuffer.restype, lib.glIsBuffer.argtypes = ctypes.c_ubyte, [ctypes.c_uint]
        return lambda buffer: bool(lib.glIsBuffer(buffer))
    pytest.skip("no libOpenGL here to ask whether a buffer is deleted")


def test_buffers_are_released_with_what_holds_them(gl):
    is_buffer = _is_buffer()
    held = glmod.get_context().buffer(reserve=64)
    name = held.glo
    assert is_buffer(name)
    del held
    gc.collect()
    glmod.get_context()
    assert not is_buffer(name)


def test_a_proxy_dropped_between_renders_has_its_buffers_deleted(gl):
    # A render lets the context go as it ends; a delete made then, in no context, does nothing,
    # and the proxy's buffers would stay for the rest of the process.
    import parc
    import parc.raster as raster
    from data_tools.synthetic import blobs
    is_buffer = _is_buffer()
    vol = blobs(12, seed=3, count=2)
    scene = parc.Scene(camera=parc.Camera.framing(*vol.bounds), size=(16, 12),
                       volumes=[parc.Isosurface(vol, float(vol.data.mean()))])
    before = list(raster._UPLOADS.values())
    parc.render(scene, "parc")
    names = [n for up in raster._UPLOADS.values() if all(up is not b for b in before)
             for n in (up.faces.glo, up.edges.glo)]
    assert names
    del scene, vol, before
    gc.collect()
    glmod.get_context()
    assert not any(is_buffer(n) for n in names)


def test_brute_renders_where_there_is_no_opengl(monkeypatch):
    import moderngl

    import parc
    from data_tools.synthetic import blobs

    def fail(**kwargs):
        raise Exception("eglGetDisplay failed")
    monkeypatch.setattr(glmod, "_CONTEXT", None)
    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    vol = blobs(8, seed=2)
    cam = parc.Camera.framing(*vol.bounds)
    iso = parc.Isosurface(vol, float(vol.data.mean()))
    for scene in (parc.Scene(camera=cam, size=(8, 8), volumes=[iso]),
                  parc.Scene(camera=cam, size=(8, 8), volumes=[parc.Translucent(vol, "greyscale")]),
                  parc.Scene(camera=cam, size=(8, 8), volumes=[iso], lights=[parc.PointLight((30, 30, 30))],
                             shadows=True)):
        assert parc.render(scene, "brute").image.shape == (8, 8, 4)
        with pytest.raises(parc.OpenGLUnavailable):
            parc.render(scene, "parc")
    assert [r["method"] for r in parc.compare(scene, methods=("brute",), repeats=1, warmup=0)] == ["brute"]


@pytest.mark.parametrize("over", ["width", "height"])
def test_an_image_past_the_viewport_limit_on_either_side_is_refused(gl, over):
    # Truth: the driver's own GL_MAX_VIEWPORT_DIMS; a side one past it is refused in one line, by the
    # check `compare` makes before any render and by the pass itself.
    import numpy as np

    from data_tools import Volume
    from parc.camera import Camera
    from parc.ranges import supercell_grid
    from parc.proxy import build_proxy
    from parc.raster import raster_segments
    max_w, max_h = gl.info["GL_MAX_VIEWPORT_DIMS"]
    size = (max_w + 1, 2) if over == "width" else (2, max_h + 1)
    with pytest.raises(InputError, match="exceeds this OpenGL's limit") as err:
        glmod.check_viewport(*size)
    assert "\n" not in str(err.value) and "--method brute has no such limit" in str(err.value)
    grid = supercell_grid((3, 3, 3), 2)
    proxy = build_proxy(grid, np.ones((1, 1, 1), bool), grid.world_edges(Volume(np.zeros((3, 3, 3), np.float32))))
    with pytest.raises(InputError, match="exceeds this OpenGL's limit"):
        raster_segments(Camera.framing(*proxy.bounds), *size, proxy)
    assert max(size) > 1000


@pytest.mark.parametrize("home, environ, unwritable", [
    ("{tmp}/nonexistent", {}, True),            # as nobody's: Mesa warned "Failed to create ..." every run
    ("{tmp}", {}, False),
    ("/nonexistent", {"XDG_CACHE_HOME": "/tmp"}, False),
    ("/nonexistent", {"MESA_SHADER_CACHE_DIR": "/tmp/m"}, False),
])
def test_mesas_shader_cache_is_turned_off_only_where_it_cannot_be_made(monkeypatch, tmp_path, home, environ,
                                                                       unwritable):
    import pwd
    from types import SimpleNamespace

    from parc.gl import _shader_cache_unwritable
    monkeypatch.setattr(pwd, "getpwuid", lambda uid: SimpleNamespace(pw_dir=home.format(tmp=tmp_path)))
    assert _shader_cache_unwritable(environ) is unwritable
