"""The OpenGL context's settings, each way in a process of its own: `parc compare`'s OpenGL pass and speedup.

--setting threads (default): llvmpipe's rasterizer threads pinned one to a
CPU, as `parc.gl` leaves them when it makes the context
(`spread_rasterizer_threads`), or left where the scheduler puts them. On a
GPU driver there are no such threads and the two ways are the same.

--setting wait: how NVIDIA's driver waits for the GPU (``__GL_YIELD``):
its default (``sched_yield()``), as `parc.gl` leaves it, ``USLEEP``
(``usleep(0)``) or ``NOTHING`` (spin). Other drivers ignore it.

Either is settled when the context is made and lasts the process, so every
run is a process of its own, the ways alternated --rounds times. Printed:
the OpenGL pass's time in the median parc frame, and the speedup.

Run: ./dev.sh python benchmarks/context_settings.py [--setting threads|wait]
     [--volume PATH --iso V | --synthetic NAME --n N] [--size 512] [--repeats 21] [--rounds 3]
Without --volume: CThead skin (../shared/data) when present, else a CT-like phantom.
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np

from volumes import add_volume_flags, count, pick_volume, run   # beside this script

WAYS = {"threads": ("pinned", "unpinned"), "wait": ("default", "USLEEP", "NOTHING")}

#: NVIDIA's variable for how its driver waits for the GPU.
DRIVER_WAIT = "__GL_YIELD"


def one_run(args):
    """One process's `parc.compare`: a JSON line with the parc row's figures."""
    import parc.gl
    from parc import Camera, Isosurface, Scene, compare
    if args.one == "unpinned":
        parc.gl.spread_rasterizer_threads = dict
    elif args.one == "default":
        os.environ.pop(DRIVER_WAIT, None)
    elif args.one in WAYS["wait"]:
        os.environ[DRIVER_WAIT] = args.one
    vol, iso = pick_volume(args)
    scene = Scene(Camera.framing(*vol.bounds), (args.size, args.size), [Isosurface(vol, iso)])
    brute, fast = compare(scene, repeats=args.repeats)
    same = fast["hit_mismatches"] == 0 and fast["max_depth_cells"] == 0.0 and fast["max_color"] == 0.0
    print(json.dumps({"raster_ms": fast["phases"]["raster"] * 1e3, "parc_s": fast["seconds"],
                      "brute_s": brute["seconds"], "speedup": fast["speedup"], "same": bool(same),
                      "renderer": parc.gl.get_context().info["GL_RENDERER"]}))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--setting", choices=sorted(WAYS), default="threads",
                    help="the context setting to vary (default threads; see above)")
    add_volume_flags(ap)
    ap.add_argument("--size", type=count, default=512, help="image side in pixels (default 512)")
    ap.add_argument("--repeats", type=count, default=21, help="timed frames a method in each run (default 21)")
    ap.add_argument("--rounds", type=count, default=3, help="runs each way, alternated (default 3)")
    ap.add_argument("--one", choices=[w for ways in WAYS.values() for w in ways], help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        one_run(args)
        return
    pick_volume(args)           # bad input refused here, not in every child
    ways = WAYS[args.setting]
    runs = {way: [] for way in ways}
    for _ in range(args.rounds):
        for way in ways:
            child = subprocess.run([sys.executable, __file__, *sys.argv[1:], "--one", way],
                                   capture_output=True, text=True)
            if child.returncode:
                sys.stderr.write(child.stderr)
                return child.returncode
            row = json.loads(child.stdout.strip().splitlines()[-1])
            runs[way].append(row)
            print(f"  {way:9s} OpenGL pass {row['raster_ms']:6.2f} ms  parc {row['parc_s'] * 1e3:7.2f} ms  "
                  f"brute {row['brute_s'] * 1e3:7.2f} ms  {row['speedup']:5.2f}x  ({row['renderer']})", flush=True)
    for way in ways:
        r = runs[way]
        raster = [x["raster_ms"] for x in r]
        speed = [x["speedup"] for x in r]
        print(f"{way:9s} OpenGL pass {min(raster):.2f}-{max(raster):.2f} ms (median {np.median(raster):.2f}), "
              f"speedup {min(speed):.2f}-{max(speed):.2f}x (median {np.median(speed):.2f})")
    print(f"same as brute: {all(x['same'] for way in ways for x in runs[way])}")


if __name__ == "__main__":
    run(main)
