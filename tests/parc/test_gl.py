"""The OpenGL context's set-up: llvmpipe's rasterizer threads spread over the CPUs."""
import os

import pytest

from parc.gl import rasterizer_cpus, spread_rasterizer_threads


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
