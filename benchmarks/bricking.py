"""Parker et al.'s bricked sample layout (§2.2, Appendix B) against the linear one, with the same kernels.

An isosurface frame (or, with --tf, a composited translucent one) is cast
twice per method, once with the samples linear (the renderer's layout)
and once bricked (`raycast.bricks`: n^3 samples to a brick, m^3 bricks
to a macrobrick, offsets from per-axis tables): the unaccelerated cast
over whole rays, and PARC's cast over its depth-buffer segments with its
skip table. Layouts are timed in turn round by round (median of
--repeats), the cast only (with shading for isosurfaces); the images
must be identical, and the script exits 1 if they are not.

Run: ./dev.sh python benchmarks/bricking.py [--volume PATH --iso V | --synthetic NAME --n N] [--tf PRESET] [--size 512]
     [--brick 4] [--macro 5] [--azimuth 35 --elevation 25] [--threads T] [--repeats 7]
Without --volume: CThead skin (../shared/data) when present, else a CT-like phantom.
"""
import argparse
import statistics
import time

import numba
import numpy as np

from parc.camera import Camera
from parc.renderer import accumulation_params
from parc.workspace import NO_BITS, NO_SEGMENTS, NO_STOP
from parc.segments import parc_segments
from parc.skip import skip_table
from parc.scene import Isosurface, Scene, Translucent
from raycast.bricks import BRICK, MACRO, brick
from raycast.composite import cast_accumulate_image
from raycast.iso import NO_SKIP, cast_iso_image, empty_outputs

from volumes import add_volume_flags, count, pick_volume, run   # beside this script


def cast_iso(samples, vis, cam, w, h, seg, skip, jump_min):
    """One isosurface cast with shading, as the renderer runs it: seconds, and its outputs."""
    vol = vis.volume
    t, cell, uvw, counts = empty_outputs(w * h)
    image = np.zeros((h, w, 4), np.float32)
    use_seg = seg is not None
    t0 = time.perf_counter()
    cast_iso_image(samples, np.array(vol.origin), np.array(vol.spacing), cam.as_array(), w, h, vis.value,
                   seg if use_seg else NO_SEGMENTS, use_seg, skip, jump_min, t, cell, uvw, counts,
                   0, h, True, np.ones(3), np.array([0.1, 0.7, 0.2, 20.0]), image)
    return time.perf_counter() - t0, (t, image)


def cast_translucent(samples, vis, cam, w, h, seg, skip, jump_min):
    """One translucent cast (the renderer's accumulation over depth segments): seconds, and its outputs."""
    vol = vis.volume
    op_x, op_y, col_x, col_rgb = vis.tf.arrays()
    image = np.zeros((h, w, 4), np.float32)
    counts = np.zeros(w * h, np.int64)
    use_seg = seg is not None
    t0 = time.perf_counter()
    cast_accumulate_image(samples, np.array(vol.origin), np.array(vol.spacing), cam.as_array(), w, h,
                          accumulation_params(vis), op_x, op_y, col_x, col_rgb,
                          seg if use_seg else NO_SEGMENTS, use_seg, NO_STOP, False,
                          NO_BITS, False, skip, jump_min, image, counts, 0, h)
    return time.perf_counter() - t0, (image, counts)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=count, default=512)
    add_volume_flags(ap)
    ap.add_argument("--tf", help="a transfer-function preset or file: cast a translucent volume instead")
    ap.add_argument("--brick", type=count, default=BRICK, help="samples per brick side (n)")
    ap.add_argument("--macro", type=count, default=MACRO, help="bricks per macrobrick side (m)")
    ap.add_argument("--azimuth", type=float, default=35.0)
    ap.add_argument("--elevation", type=float, default=25.0)
    ap.add_argument("--threads", type=count, default=numba.config.NUMBA_NUM_THREADS)
    ap.add_argument("--repeats", type=count, default=7)
    args = ap.parse_args()
    vol, iso = pick_volume(args, need_iso=not args.tf)
    w = h = args.size
    numba.set_num_threads(args.threads)
    cam = Camera.framing(*vol.bounds, azimuth=args.azimuth, elevation=args.elevation)
    linear = vol.data
    bricked = brick(linear, args.brick, args.macro)
    pad = bricked.flat.size / linear.size - 1.0
    if args.tf:
        vis, cast, what = Translucent(vol, args.tf), cast_translucent, f"transfer function {args.tf}"
    else:
        vis, cast, what = Isosurface(vol, iso), cast_iso, f"iso {iso}"
    # The renderer's own classification, proxy and raster pass, for the supercell its cost model picks.
    seg, extra, _ = parc_segments(Scene(camera=cam, size=(w, h), volumes=[vis]), vis, None, {})
    size = extra["supercell"]
    skip, jump_min = skip_table(vis, True)
    print(f"{vol.name}, {vol.dtype}, {what}, {w}x{h}, {args.threads} thread(s); "
          f"bricks of {args.brick}^3 samples in macrobricks of {args.macro}^3 (padding {pad:.1%}); "
          f"parc supercell {size}")
    same_all = True
    for method, s, sk, jm in (("brute", None, NO_SKIP, -1), ("parc", seg, skip, jump_min)):
        layouts = {"linear": linear, "bricked": bricked}
        for samples in layouts.values():          # compile (or load) and warm the caches
            cast(samples, vis, cam, w, h, s, sk, jm)
        times = {name: [] for name in layouts}
        out = {}
        for _ in range(max(1, args.repeats)):
            for name, samples in layouts.items():
                sec, out[name] = cast(samples, vis, cam, w, h, s, sk, jm)
                times[name].append(sec)
        same = all(np.array_equal(a, b) for a, b in zip(out["linear"], out["bricked"]))
        same_all &= same
        lin, bri = (statistics.median(times[k]) for k in ("linear", "bricked"))
        print(f"{method:5}  linear {lin * 1e3:8.2f} ms  bricked {bri * 1e3:8.2f} ms  "
              f"bricked/linear {bri / lin:.2f}  same as linear: {same}")
    return 0 if same_all else 1


if __name__ == "__main__":
    run(main)
