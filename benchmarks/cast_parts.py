"""Where PARC's cast spends its time: the casting kernel alone, timed with parts of its work taken away.

The proxy is built and rasterized once (the renderer's own segments for
the view); then the isosurface kernel (`raycast.iso.cast_iso_image`) is
timed, best of --repeats, on the same rays:

- ``brute``: whole rays, no skip table, hits shaded (the unaccelerated cast);
- ``parc``: the segments and the renderer's skip tables (by ray octant), hits shaded (PARC's cast);
- ``parc, unshaded``: the same without shading, so the difference is the shading;
- ``parc, rays started only``: every segment cut to its first point, so each ray
  is set up and its first cell visited, and the walk stops there;
- ``parc, no skip table``: the segments walked cell by cell, every cell's corners read.

With --tf the volume is translucent instead (`raycast.composite.cast_accumulate_image`,
depth buffers): ``brute`` and ``parc`` with their samples and the time per sample.
Both runs check that PARC's result equals the unaccelerated one (``same as brute``).

Run: ./dev.sh python benchmarks/cast_parts.py [--volume PATH --iso V | --synthetic NAME --n N] [--tf PRESET]
     [--size 512] [--threads 1] [--repeats 15]
Without --volume: CThead skin (../shared/data) when present, else a CT-like phantom.
"""
import argparse
import time

import numba
import numpy as np

from volumes import add_volume_flags, count, pick_volume, run


def best_ms(cast, repeats):
    """Best of ``repeats`` calls of ``cast()``, in milliseconds (after one untimed call)."""
    cast()
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        cast()
        best = min(best, time.perf_counter() - t0)
    return best * 1e3


def frame(vis, size):
    """What the casting kernels take for ``vis`` seen from the default view at ``size``x``size``:
    ``(cam, org, spc, seg, skip, jump_min, extra)``, the segments PARC's OpenGL pass finds and its stats,
    and the skip tables the renderer gives these rays (by ray octant for an isosurface)."""
    from parc import Camera, Isosurface, Scene
    from parc.segments import parc_segments
    from parc.skip import expect_frames, octant_skip_tables, skip_table

    vol = vis.volume
    scene = Scene(Camera.framing(*vol.bounds), (size, size), [vis])
    seg, extra, _ = parc_segments(scene, vis, None, {})
    if isinstance(vis, Isosurface):
        expect_frames(scene)        # the tables of a frame after the first, which every timed one is
        skip, jump_min = octant_skip_tables(vis, True, scene.camera, size, size)
    else:
        skip, jump_min = skip_table(vis, True)
    return (scene.camera.as_array(), np.array(vol.origin), np.array(vol.spacing), seg.copy(), skip, jump_min,
            extra)


def iso_parts(vol, iso, size, repeats):
    from parc import Isosurface
    from parc.workspace import iso_work
    from raycast.iso import NO_SKIP_OCTANTS as NO_SKIP, cast_iso_image

    vis = Isosurface(vol, iso)
    cam, org, spc, seg, skip, jump_min, extra = frame(vis, size)
    n = size * size
    t = np.empty(n)
    cell, uvw, counts = (a.copy() for a in iso_work(n))
    image = np.zeros((size, size, 4), np.float32)
    color, material = np.array(vis.color, np.float64), np.array(vis.material, np.float64)
    started = seg.copy()
    has = seg[..., 0] <= seg[..., 1]
    started[..., 1] = np.where(has, seg[..., 0], seg[..., 1])

    def cast(segs, use_seg, table, jm, shade):
        return cast_iso_image(vol.data, org, spc, cam, size, size, float(iso), segs, use_seg, table, jm,
                              t, cell, uvw, counts, 0, size, shade, color, material, image)

    hits, cells_brute, solves = cast(seg, False, NO_SKIP, -1, True)
    t_brute, image_brute = t.copy(), image.copy()
    rows = [("brute", best_ms(lambda: cast(seg, False, NO_SKIP, -1, True), repeats), cells_brute)]
    image[:] = 0.0
    _, cells_parc, _ = cast(seg, True, skip, jump_min, True)
    same = bool(np.array_equal(t, t_brute) and np.array_equal(image, image_brute))
    rows.append(("parc", best_ms(lambda: cast(seg, True, skip, jump_min, True), repeats), cells_parc))
    rows.append(("parc, unshaded", best_ms(lambda: cast(seg, True, skip, jump_min, False), repeats), cells_parc))
    _, cells_started, _ = cast(started, True, skip, jump_min, False)
    rows.append(("parc, rays started only",
                 best_ms(lambda: cast(started, True, skip, jump_min, False), repeats), cells_started))
    _, cells_noskip, _ = cast(seg, True, NO_SKIP, -1, False)
    rows.append(("parc, no skip table, unshaded",
                 best_ms(lambda: cast(seg, True, NO_SKIP, -1, False), repeats), cells_noskip))
    rays = int(has.sum())
    print(f"isovalue {iso:g}, {size}x{size}, supercell {extra['supercell']}: {rays:,} rays with a segment, "
          f"{hits:,} hits, {solves:,} cubics")
    for name, ms, cells in rows:
        per = ms * 1e6 / (n if name == "brute" else max(rays, 1))
        print(f"  {name:32s} {ms:8.2f} ms  {cells / max(rays, 1) if name != 'brute' else cells / n:6.1f} cells a ray"
              f"  {per:6.0f} ns a ray")
    print(f"  speedup of the cast: {rows[0][1] / rows[1][1]:.2f}x; same as brute: {same}")


def translucent_parts(vol, tf_name, size, repeats):
    from parc import Translucent, load_transfer_function
    from parc.renderer import accumulation_params
    from parc.workspace import NO_BITS, NO_STOP
    from raycast.composite import cast_accumulate_image
    from raycast.iso import NO_SKIP

    tf = load_transfer_function(tf_name, vol.value_range())
    vis = Translucent(vol, tf)
    cam, org, spc, seg, skip, jump_min, extra = frame(vis, size)
    params = accumulation_params(vis)
    op_x, op_y, col_x, col_rgb = tf.arrays()
    image = np.empty((size, size, 4), np.float32)
    counts = np.empty(size * size, np.int64)
    bits = NO_BITS

    def cast(use_seg, table, jm):
        return cast_accumulate_image(vol.data, org, spc, cam, size, size, params, op_x, op_y, col_x, col_rgb,
                                     seg, use_seg, NO_STOP, False, bits, False, table, jm, image, counts, 0, size)

    samples_brute = cast(False, NO_SKIP, -1)
    reference = image.copy()
    samples_parc = cast(True, skip, jump_min)
    same = bool(np.array_equal(image, reference))
    print(f"transfer function {tf_name}, {size}x{size}, supercell {extra['supercell']}")
    ms = {}
    for name, use_seg, table, jm, samples in (("brute", False, NO_SKIP, -1, samples_brute),
                                              ("parc", True, skip, jump_min, samples_parc)):
        ms[name] = best_ms(lambda: cast(use_seg, table, jm), repeats)
        print(f"  {name:8s} {ms[name]:8.2f} ms  {samples:12,} samples  {ms[name] * 1e6 / max(samples, 1):6.1f} ns a sample")
    print(f"  speedup of the cast: {ms['brute'] / ms['parc']:.2f}x; same as brute: {same}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_volume_flags(ap)
    ap.add_argument("--tf", help="a transfer-function preset or file: time the translucent cast instead")
    ap.add_argument("--size", type=count, default=512, help="image side in pixels (default 512)")
    ap.add_argument("--threads", type=count, default=1, help="Numba threads (default 1: no scheduling noise)")
    ap.add_argument("--repeats", type=count, default=15)
    a = ap.parse_args()
    numba.set_num_threads(a.threads)
    volume, level = pick_volume(a, need_iso=a.tf is None)
    print(f"{volume.name}: {'x'.join(map(str, volume.dims))} {volume.dtype}, {a.threads} thread(s)")
    if a.tf:
        translucent_parts(volume, a.tf, a.size, a.repeats)
    else:
        iso_parts(volume, level, a.size, a.repeats)


if __name__ == "__main__":
    run(main)
