"""Compiled kernels come back from Numba's on-disk cache in a new process.

Numba keys the cache entry of a kernel built in a closure by the pickle of
its closure, and a kernel pickles with an id that is new in every process:
a driver closing over another kernel was compiled again in every process
(2.3 s of each translucent `parc render`), and its cache folder grew by an
entry each time.
"""
import importlib
import json
import pkgutil
import subprocess
import sys
from pathlib import Path

from numba.core.dispatcher import Dispatcher

import parc
import raycast


def kernels():
    """``(name, dispatcher)`` for every kernel in `raycast` and `parc`, those kept in dicts and tuples too."""
    found = {}
    for package in (raycast, parc):
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            module = importlib.import_module(info.name)
            for name, value in vars(module).items():
                values = value.values() if isinstance(value, dict) else (
                    value if isinstance(value, (tuple, list)) else (value,))
                for v in values:
                    if isinstance(v, Dispatcher):
                        found.setdefault(id(v), (f"{info.name}.{name}", v))
    return list(found.values())


def test_no_kernel_closes_over_another():
    ks = kernels()
    assert len(ks) > 50      # the walk found the kernels
    closing = [name for name, k in ks
               if any(isinstance(c.cell_contents, Dispatcher) for c in k.py_func.__closure__ or ())]
    assert closing == []


# Frames that compile the casters' kernels: isosurfaces with shadows, and
# the four translucent drivers (shaded or not, with bit planes or not).
_SCRIPT = """
import json, sys
import numpy as np
from data_tools.synthetic import blobs
from parc import Camera, Isosurface, PointLight, Scene, TransferFunction, Translucent, render
sys.path.insert(0, {tests!r})
from test_kernel_cache import kernels

vol = blobs((14, 12, 10), seed=3)
lo, hi = vol.bounds
cam = Camera.framing(lo, hi)
tf = TransferFunction(opacity=[[0.2, 0.0], [0.6, 0.5]], color=[[0.0, 1.0, 0.5, 0.2], [1.0, 0.2, 0.5, 1.0]])
iso = Scene(camera=cam, size=(12, 10), volumes=[Isosurface(vol, value=0.5)],
            lights=[PointLight(position=hi + 5.0)], shadows=True)
for method in ("brute", "parc"):
    render(iso, method=method)
for shade in (False, True):
    scene = Scene(camera=cam, size=(12, 10), volumes=[Translucent(vol, tf, shade=shade)])
    render(scene, method="brute")
    for buffers in (("depth",), ("depth", "bits")):
        render(scene, method="parc", buffers=buffers)
print(json.dumps(sorted(name for name, k in kernels() if sum(k.stats.cache_misses.values()))))
"""


def test_a_new_process_loads_the_casters_from_the_cache():
    script = _SCRIPT.format(tests=str(Path(__file__).parent))

    def misses():
        run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
        assert run.returncode == 0, run.stderr[-2000:]
        return json.loads(run.stdout.strip().splitlines()[-1])

    misses()                 # compiles what the cache lacks
    assert misses() == []    # ... so that a second process compiles nothing
