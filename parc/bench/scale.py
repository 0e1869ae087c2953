"""Visible Woman scale: a 512x512x1734 16-bit CT-like phantom, streamed to disk once and memory-mapped.

Parker et al. rendered the Visible Woman CT (1734 slices of 512x512 at 16
bits, 910 MB) at about 10 frames per second on 64 processors. The bench
builds a phantom of the same size and type (`data_tools.synthetic.
ct_phantom_to_disk`, slab by slab, so building it needs little memory),
keeps it in the cache folder for later runs, maps it read-only and renders
its skin and bone isosurfaces at 512x512 with `brute` and `parc`.

It runs in a child process (``python -m parc.bench.scale``) so that the
peak resident memory it reports is this section's alone: the mapped pages
the rays touched, the per-cell min/max (two int16 arrays the size of the
volume) and the proxy.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ..outputs import note

ISOS = (("skin", 600.5), ("bone", 1500.5))


def phantom_path(cache_dir, shape):
    nx, ny, nz = shape
    return Path(cache_dir) / f"vw_phantom_{nx}x{ny}x{nz}_int16.raw"


def visible_woman(suite, progress):
    """Generate (once) and render the phantom in a child process; returns its measurements."""
    if suite.cache_dir is not None:
        return _visible_woman(suite, progress, suite.cache_dir)
    with tempfile.TemporaryDirectory(prefix="parc-vw-") as folder:     # no home folder to keep it in
        return _visible_woman(suite, progress, folder)


def _visible_woman(suite, progress, cache_dir):
    from data_tools.synthetic import ct_phantom_to_disk

    path = phantom_path(cache_dir, suite.vw_shape)
    generated = None
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        nx, ny, nz = suite.vw_shape
        progress(f"Visible Woman scale: writing a {nx}x{ny}x{nz} int16 phantom "
                 f"({nx * ny * nz * 2 / 1e6:.0f} MB) to {path}")
        t0 = time.perf_counter()
        # Hidden until whole, under a name of its own (two runs may write it at once), with
        # the .raw suffix the writer needs; an interrupted write leaves nothing behind.
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".raw", dir=path.parent)
        os.close(fd)
        try:
            ct_phantom_to_disk(tmp, suite.vw_shape)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        generated = time.perf_counter() - t0
    with tempfile.TemporaryDirectory(prefix="parc-vw-") as folder:      # its own: two runs at once
        out = Path(folder) / "scale.json"
        cmd = [sys.executable, "-m", "parc.bench.scale", str(path), "--size", str(suite.vw_size),
               "--repeats", str(suite.repeats), "--json", str(out), "--parent", str(os.getpid())]
        progress(f"Visible Woman scale: rendering in a child process ({' '.join(cmd[1:4])} ...)")
        # A session of its own, out of the terminal's reach: a Ctrl-C stops this process, which
        # kills the child (subprocess.run does on any exception), instead of interrupting both.
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=None, text=True, start_new_session=True)
        if proc.returncode != 0:
            from data_tools import InputError
            raise InputError(f"the Visible Woman section failed in its child process (exit {proc.returncode})"
                             + ("; its own line is above" if proc.returncode > 0 else ""))
        result = json.loads(out.read_text())
    result.update({"path": str(path), "generate_seconds": generated})
    return result


def measure(path, size, repeats, say):
    """Everything the section reports, measured in this process."""
    import numba

    from data_tools import load_volume

    from ..camera import Camera
    from ..classify import VolumeIndex
    from ..comparison import compare
    from ..renderer import render
    from ..scene import Isosurface, Scene

    # Compile (or load) the kernels for read-only int16 samples first, so no
    # frame below pays for it.
    import numpy as np
    from data_tools import Volume
    warm = np.zeros((4, 4, 4), np.int16)
    warm[1:3, 1:3, 1:3] = 2000
    warm.flags.writeable = False
    for method in ("brute", "parc"):
        render(Scene(camera=Camera.framing((0, 0, 0), (3, 3, 3)), size=(8, 8),
                     volumes=[Isosurface(Volume(warm), 600.5)]), method=method)
    t0 = time.perf_counter()
    vol = load_volume(path, mmap=True)
    out = {"shape": list(vol.dims), "dtype": str(vol.dtype), "bytes": int(vol.data.nbytes),
           "map_seconds": time.perf_counter() - t0, "size": size, "threads": numba.get_num_threads()}
    cam = Camera.framing(*vol.bounds, azimuth=30.0, elevation=15.0)
    say("cell min/max (once per volume)")
    t0 = time.perf_counter()
    mn, _ = VolumeIndex.of(vol).cell_minmax()
    out["minmax_seconds"] = time.perf_counter() - t0
    out["minmax_bytes"] = int(2 * mn.nbytes)
    surfaces = []
    for name, iso in ISOS:
        scene = Scene(camera=cam, size=(size, size), volumes=[Isosurface(vol, iso)])
        say(f"{name}: first parc frame (classification, proxy, raster, cast)")
        t0 = time.perf_counter()
        first = render(scene, method="parc")
        first_wall = time.perf_counter() - t0
        ph = first.stats["seconds"]
        say(f"{name}: brute and parc frames, in turn")
        # Timed round by round, as every other section: a drift in the machine's speed reaches both.
        brute, parc = compare(scene, methods=("brute", "parc"), repeats=repeats)
        surfaces.append({
            "surface": name, "isovalue": iso,
            "brute_seconds": brute["seconds"], "parc_seconds": parc["seconds"], "speedup": parc["speedup"],
            "first_frame_seconds": first_wall,
            "proxy_build_seconds": ph.get("classify", 0.0) + ph.get("proxy", 0.0),
            "raster_seconds": parc["phases"].get("raster", 0.0),
            "polygons": parc["polygons"], "supercell": parc["supercell"],
            "brute_cells": brute["cells_visited"], "parc_cells": parc["cells_visited"],
            "ideal_cells": brute["cubic_solves"], "contributing_cells": brute["hits"],
            "hit_mismatches": parc["hit_mismatches"], "max_depth_cells": parc["max_depth_cells"],
            "max_color": parc["max_color"]})
    # Changing the isovalue: the proxy for a new level, from the cached min/max,
    # then the first frame; measured on a third level so no proxy is cached.
    scene = Scene(camera=cam, size=(size, size), volumes=[Isosurface(vol, 1200.5)])
    say("changing the isovalue to 1200.5")
    t0 = time.perf_counter()
    res = render(scene, method="parc")
    ph = res.stats["seconds"]
    out["iso_change"] = {"isovalue": 1200.5, "first_frame_seconds": time.perf_counter() - t0,
                         "reclassify_proxy_seconds": ph.get("classify", 0.0) + ph.get("proxy", 0.0)}
    out["surfaces"] = surfaces
    out["peak_rss_bytes"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return out


def _end_with_parent(parent=None):
    """Exit once the bench that started this process (``parent``, its process id) is gone,
    however it went: in a session of its own, no terminal's Ctrl-C reaches this process, and
    a bench stopped between starting it and waiting for it could not kill it (the full
    suite's renders take minutes). The bench names itself: a parent read here could already
    be the process that adopted this one."""
    import threading

    parent = os.getppid() if parent is None else parent

    def watch():
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(130)
    threading.Thread(target=watch, daemon=True).start()


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m parc.bench.scale",
                                description="Render a memory-mapped phantom; the Visible Woman section of parc bench.")
    p.add_argument("path")
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--json", required=True)
    p.add_argument("--parent", type=int, help="the bench's process id: this one ends when it does")
    a = p.parse_args(argv)
    _end_with_parent(a.parent)

    def say(msg):
        note(f"  {msg}", "parc bench")

    from data_tools import InputError
    try:
        out = measure(a.path, a.size, a.repeats, say)
        Path(a.json).write_text(json.dumps(out, indent=1))
    except (InputError, OSError) as exc:
        # One line, as `parc` gives: the bench names the section that failed.
        note(f"error: {exc}", "parc bench")
        return 1
    except MemoryError:
        note("error: out of memory rendering the Visible Woman phantom", "parc bench")
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
