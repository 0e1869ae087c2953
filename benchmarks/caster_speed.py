"""Unaccelerated caster speed: cell visits per second per core in empty space, and a CT frame.

Run: ./dev.sh python benchmarks/caster_speed.py [--size 256]
"""
import argparse
import time

import numba
import numpy as np

from data_tools.synthetic import ct_phantom
from parc import Camera, Isosurface, Scene, render
from raycast.iso import NO_SHADING, NO_SKIP, cast_iso_image, empty_outputs
from volumes import count, run   # beside this script


def empty_space_rate(n, threads, width=512, repeats=3):
    """Cells per second with every cell empty (isovalue above all samples)."""
    data = np.zeros((n, n, n), np.uint8)
    cam = Camera.framing((0, 0, 0), (n - 1,) * 3, zoom=1.8)
    arr = cam.as_array()
    numba.set_num_threads(threads)
    best = np.inf
    for _ in range(repeats + 1):
        t, cell, uvw, counts = empty_outputs(width * width)
        t0 = time.perf_counter()
        cast_iso_image(data, np.zeros(3), np.ones(3), arr, width, width, 1.0,
                       np.empty((1, 1, 2)), False, NO_SKIP, -1, t, cell, uvw, counts, 0, width, *NO_SHADING)
        best = min(best, time.perf_counter() - t0)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return counts[:, 0].sum() / best, best


def ct_frame(n, size=512, repeats=3):
    """Each level's best stats, or None for a level the phantom's samples do not reach (bone at
    the smallest sizes, where blurring leaves no sample that dense)."""
    vol = ct_phantom(n)
    low, high = vol.value_range()
    out = {}
    for name, iso in (("skin", 600.0), ("bone", 1500.0)):
        if not low <= iso <= high:
            out[name] = (iso, None)
            continue
        scene = Scene(camera=Camera.framing(*vol.bounds, zoom=1.3), size=(size, size),
                      volumes=[Isosurface(vol, iso)])
        render(scene)
        runs = [render(scene) for _ in range(repeats)]
        best = min(runs, key=lambda r: r.stats["seconds"]["total"])
        out[name] = (iso, best.stats)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--size", type=count, default=256)
    a = ap.parse_args()
    print(f"threads available: {numba.config.NUMBA_NUM_THREADS}")
    for th in sorted({1, numba.config.NUMBA_NUM_THREADS}):
        rate, sec = empty_space_rate(a.size, th)
        print(f"empty space, {a.size}^3 uint8, 512x512, {th} thread(s): "
              f"{rate / 1e6:.1f} M cells/s ({rate / th / 1e6:.1f} M/s per core), {sec:.3f} s")
    for name, (iso, s) in ct_frame(a.size).items():
        if s is None:
            print(f"CT phantom {a.size}^3 {name} iso {iso:g}: not timed, no sample reaches it at this size")
            continue
        print(f"CT phantom {a.size}^3 {name} iso {iso:g}, 512x512: "
              f"{s['seconds']['total']:.3f} s/frame (cast and shading {s['seconds']['cast']:.3f}), "
              f"{s['cells_visited'] / 1e6:.1f} M cells, {s['cubic_solves']:,} cubics, {s['hits']:,} hits")


if __name__ == "__main__":
    run(main)
