"""Depth-buffer PARC's OpenGL pass: time per polygon, and what the segments save the caster.

For each supercell size: proxy build time, polygons, rasterization time
(best of several; upload, draw + ctx.finish(), read-back, post-processing),
then the Numba caster over the segments: cells walked and time, against
the unaccelerated caster, whose hits and depths the segments must not
change. The last lines fit a per-polygon raster cost and a per-ray, per-cell
cast cost to the sizes measured: a first look at where the costs lie. The
renderer's own model (`parc.costmodel`) counts face strips and was fitted to
`parc compare` frames, as its constants' comment says.

With --stages: only the raster pass, for the supercell size the renderer
would choose (or --supercell), every stage's best and median over
--repeats frames (prepare, draw, readback, post, total; upload for the first frame only), and the
faces drawn (faces bordering only cavities are skipped while no ray
starts in one). The machine's load varies: compare runs made together.

Run: ./dev.sh python benchmarks/raster_speed.py [--size 512] [--volume PATH --iso V | --synthetic NAME --n N]
     [--parallel] [--stages [--supercell M]]
Without --volume: CThead skin (../shared/data) when present, else a CT-like phantom.
"""
import argparse
import os
import time

import numba
import numpy as np

from parc.camera import Camera
from parc.classify import VolumeIndex
from parc.costmodel import count_outer_faces
from parc.proxy import build_proxy
from parc.gl import get_context
from parc.raster import raster_segments
from raycast.iso import NO_SHADING, NO_SKIP, cast_iso_image, empty_outputs

from volumes import add_volume_flags, count, pick_volume, run   # beside this script

SIZES = (1, 2, 3, 4, 6, 8)


def cast(vol, cam, w, h, iso, seg=None):
    t, cell, uvw, counts = empty_outputs(w * h)
    s = seg if seg is not None else np.empty((1, 1, 2))
    t0 = time.perf_counter()
    cast_iso_image(vol.data, np.array(vol.origin), np.array(vol.spacing), cam.as_array(), w, h, iso,
                   s, seg is not None, NO_SKIP, -1, t, cell, uvw, counts, 0, h, *NO_SHADING)
    return time.perf_counter() - t0, t, counts


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=count, default=512)
    add_volume_flags(ap)
    ap.add_argument("--zoom", type=float, default=1.6)
    ap.add_argument("--repeats", type=count, default=5)
    ap.add_argument("--parallel", action="store_true", help="a parallel view (default: perspective)")
    ap.add_argument("--stages", action="store_true", help="time the raster stages only (see above)")
    ap.add_argument("--supercell", type=float,
                    help="with --stages: this size instead of the renderer's choice")
    args = ap.parse_args()
    if args.supercell is not None and not args.stages:
        # The full run times every size the renderer weighs: one size would be ignored there.
        raise ValueError("--supercell applies with --stages")
    vol, iso = pick_volume(args)
    w = h = args.size
    ctx = get_context()
    print(f"{vol.name} {vol.dims} {vol.dtype}, iso {iso}, {w}x{h}, GL: {ctx.info['GL_RENDERER']}, "
          f"caster threads {numba.get_num_threads()}, load {os.getloadavg()[0]:.2f}")
    cam = Camera.framing(*vol.bounds, azimuth=30, elevation=20, zoom=args.zoom, parallel=args.parallel)
    idx = VolumeIndex.of(vol)
    if args.stages:
        stages(idx, vol, iso, cam, w, h, args)
        return
    t0 = time.perf_counter()
    idx.cell_minmax()
    print(f"cell min/max: {time.perf_counter() - t0:.3f} s")

    cast(vol, cam, 8, 8, iso)  # compile
    tb, tbrute, cbrute = min((cast(vol, cam, w, h, iso) for _ in range(2)), key=lambda r: r[0])
    hits = np.isfinite(tbrute)
    print(f"brute: {tb:.3f} s, {cbrute[:, 0].sum() / 1e6:.2f} M cells, {hits.sum()} hits")
    rows = []
    out = np.empty((h, w, 2))
    for m in SIZES:
        for merge in (False, True):
            t0 = time.perf_counter()
            grid = idx.grid(m)
            idx.ranges(m)
            t_ranges = time.perf_counter() - t0
            t0 = time.perf_counter()
            pc = idx.classify(iso, m)
            t_class = time.perf_counter() - t0
            t0 = time.perf_counter()
            proxy = build_proxy(grid, pc, grid.world_edges(vol), merge=merge)
            t_proxy = time.perf_counter() - t0
            # Every frame writes the same segments into one array, as in the renderer (`stages`).
            runs = [raster_segments(cam, w, h, proxy, out=out) for _ in range(args.repeats)]
            best = min(runs[1:] or runs, key=lambda s: s.seconds["draw"])
            seg = best.seg
            tc, tpar, cpar = min((cast(vol, cam, w, h, iso, seg) for _ in range(2)), key=lambda r: r[0])
            same = np.array_equal(np.isfinite(tpar), hits) and np.array_equal(tpar[hits], tbrute[hits])
            s = best.seconds
            rows.append(dict(m=m, merge=merge, polys=proxy.n_polygons, unit=count_outer_faces(pc),
                             draw=s["draw"], total=s["total"], cells=cpar[:, 0].sum(), cast=tc,
                             px=best.info["pixels"]))
            print(f"m={m} merge={merge!s:5}: ranges {t_ranges * 1e3:6.1f} ms, classify {t_class * 1e3:5.1f} ms, "
                  f"proxy {t_proxy * 1e3:6.1f} ms, {proxy.n_polygons:7d} polys | raster: upload "
                  f"{runs[0].seconds['upload'] * 1e3:5.1f} draw {s['draw'] * 1e3:6.1f} read "
                  f"{s['readback'] * 1e3:4.1f} post {s['post'] * 1e3:4.1f} prep {s['prepare'] * 1e3:4.1f} ms "
                  f"| cast {tc:.3f} s, {cpar[:, 0].sum() / 1e6:6.2f} M cells, "
                  f"{cpar[:, 0].sum() / max(1, best.info['pixels']):5.1f} cells/px | same as brute: {same}")
    # Cost model fit (merged proxies: what the renderer uses).
    mr = [r for r in rows if r["merge"]]
    a = np.array([[1.0, r["polys"]] for r in mr])
    fixed, per_poly = np.linalg.lstsq(a, np.array([r["draw"] for r in mr]), rcond=None)[0]
    b = np.array([[1.0, r["unit"]] for r in mr if r["m"] >= 2])
    fixed_u, per_face = np.linalg.lstsq(b, np.array([r["draw"] for r in mr if r["m"] >= 2]), rcond=None)[0]
    walk = np.array([r["cells"] / max(1, r["px"]) for r in mr])
    base, per_cell = np.polyfit([r["m"] for r in mr], walk, 1)
    c = np.array([[r["px"], r["cells"]] for r in mr], float)
    per_ray_s, per_cell_s = np.linalg.lstsq(c, np.array([r["cast"] for r in mr]), rcond=None)[0]
    cores = numba.get_num_threads()
    print(f"fit: draw = {fixed * 1e3:.1f} ms + {per_poly * 1e6:.2f} us/merged polygon "
          f"= {fixed_u * 1e3:.1f} ms + {per_face * 1e6:.2f} us/unit face (m >= 2)")
    print(f"fit: cells per covered pixel = {base:.2f} + {per_cell:.2f} m; cast = "
          f"{per_ray_s * cores * 1e6:.2f} us/ray + {per_cell_s * cores * 1e9:.1f} ns/cell, per core")


def stages(idx, vol, iso, cam, w, h, args):
    """Per-stage raster times (best and median of --repeats frames after a first one)."""
    from parc.ranges import supercell_size
    from parc.costmodel import choose_supercell
    size = args.supercell if args.supercell is not None else choose_supercell(idx, iso, pixels=w * h)[0]
    size = supercell_size(size)
    grid = idx.grid(size)
    proxy = build_proxy(grid, idx.classify(iso, size), grid.world_edges(vol))
    # One segment array for every frame, as the renderer keeps one (`parc.workspace`): a fresh
    # 4 MB array each frame faulted its pages in during "post", 0.8-1.1 ms against 0.15 ms.
    out = np.empty((h, w, 2))
    first = raster_segments(cam, w, h, proxy, out=out)
    runs = [raster_segments(cam, w, h, proxy, out=out) for _ in range(max(1, args.repeats))]
    print(f"supercell {size}, {proxy.n_polygons} faces, {first.info['drawn']} drawn, "
          f"{first.info['pixels']} pixels with a segment; first frame: upload "
          f"{first.seconds['upload'] * 1e3:.1f} ms, total {first.seconds['total'] * 1e3:.1f} ms")
    for key in ("prepare", "draw", "readback", "post", "total"):
        t = np.array([r.seconds[key] for r in runs]) * 1e3
        print(f"  {key:9} best {t.min():7.2f} ms   median {np.median(t):7.2f} ms")


if __name__ == "__main__":
    run(main)
