"""Tunables and JIT flags for every kernel in `raycast` and `parc` (`kernel`), in one place.

Every kernel's module imports this one, so importing it also sets up, before any kernel is
decorated, where compiled kernels are cached (`raycast.kernel_cache`) and how Numba's compiler
runs (`raycast.compiler`); and it keeps the cleanups a process runs at exit, even one ended at
once (`at_exit`).
"""
import atexit
import functools
import importlib
import os


# Numba's OpenMP workers otherwise spin for a while after each parallel
# loop, on the two cores llvmpipe's rasterizer threads need next: a CT head
# frame's raster pass took 6-7 ms right after a cast, 4 ms with them asleep.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numba  # noqa: E402

#: Shares the parallel loops deal their tiles into (`raycast.rays.spread`):
#: the threads Numba starts with. A compile-time constant (asking Numba in
#: a kernel would keep it out of the cache), so the cache folder names it.
SPREAD_WAYS = max(1, int(numba.config.NUMBA_NUM_THREADS))


#: What this process undoes as it ends (`at_exit`), for a run ended at once, which skips `atexit`
#: (`data_tools.signals.end_at_once`).
EXIT_CLEANUPS = []


def at_exit(fn, *args, **kwargs):
    """Call ``fn(*args, **kwargs)`` when the process ends, by `atexit` or at once."""
    atexit.register(fn, *args, **kwargs)
    EXIT_CLEANUPS.append(functools.partial(fn, *args, **kwargs))


# Set up by importing them, after what they take from here and before any kernel is decorated
# (a kernel picks its cache folder then).
for _module in ("compiler", "kernel_cache"):
    importlib.import_module(f"{__package__}.{_module}")


#: Flags shared by all kernels. fastmath stays off: PARC and the
#: unaccelerated caster must round identically, and the root finder relies
#: on IEEE comparisons with inf.
JIT = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
#: The same for an ``@overload``'s implementation, which is compiled into
#: the kernels that call it and cached with them.
OVERLOAD_JIT = {key: value for key, value in JIT.items() if key != "cache"}


def named_for(**flags):
    """Rename a kernel's Python function for the flags its factory closes over, before `kernel`.

    ``accumulate`` made with ``shaded=True, planes=False`` becomes
    ``accumulate_shaded``; with neither, ``accumulate_plain``. Numba names a
    compiled kernel by its qualified name and a counter that starts again in
    every process, and links kernels loaded from the cache by that name: two
    variants of one factory, compiled in different processes, could get the
    same name, and a process that loaded both ran the first one's code for
    both (a shaded image came out unshaded). Distinct names also give each
    variant its own cache index.
    """
    suffix = "_".join(name for name, on in flags.items() if on) or "plain"

    def rename(fn):
        fn.__name__ = f"{fn.__name__}_{suffix}"
        fn.__qualname__ = f"{fn.__qualname__}_{suffix}"
        return fn
    return rename


#: Image tiles, as in Parker et al. §2.2: 32 pixels wide (a cache line of
#: float32 per row) and 4 high.
TILE_W = 32
TILE_H = 4

#: Parallel loops over single rays or pixels hand out runs of this many
#: (`raycast.rays.spread`): spreading item by item cost more than the
#: shading it balanced (an integer division per pixel).
SPREAD_CHUNK = 64

#: Parallel passes over volume-sized arrays of value ranges (`parc.classify`'s isovalue tests,
#: `parc.transfer`'s range query) give each thread runs of this many, one after another.
RANGE_CHUNK = 1 << 16

#: Root finder: bisection/Newton stops when the bracket is this small
#: relative to the cell's t-interval (well below the 1e-9-of-a-cell target).
ROOT_REL_TOL = 1e-15
ROOT_MAX_ITER = 100


def kernel(fn=None, **extra):
    """Decorate a kernel with the project's JIT flags.

    ``@kernel(inline="always")`` marks a small helper that takes arrays and
    runs inside a per-sample or per-ray loop: LLVM left such helpers as
    calls, and each call passes every array as a struct of 7-11 words
    (the per-sample bit-plane test, the transfer function's colour, the
    light-buffer lookup of every shadow ray). Inlining them in Numba's IR
    made PARC's translucent cast 1.3x and its shadow rays 1.8x faster (CT
    head and Fig. 13 scenes). The same goes for what an isosurface ray
    calls once, or once per cubic: `raycast.iso.cast_iso_ray` and
    `raycast.cubic.first_root` inlined took 4% off PARC's CT head bone
    frame (`brute`'s as fast as before) for about 10 s more compiling in a
    cold test run. Not inlined, for compile time: `raycast.iso._walk_iso`
    into the kernels that inline `cast_iso_ray` (their compile time tripled for
    another few percent) and the traversal's `start_index` and
    `entry_anchor` (with them inlined too, the iso, hard-ray, PARC-equals-
    brute and shadow tests took 200 s from a cold cache instead of 150).
    """
    flags = dict(JIT, **extra)
    if fn is None:
        return lambda f: numba.njit(**flags)(f)
    return numba.njit(**flags)(fn)
