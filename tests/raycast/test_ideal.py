"""The ideal caster's sample counts (`raycast.ideal`, `parc.ideal`).

Truth: a slow plain-Python walk of the unaccelerated caster's lattice,
written from the definition (its own ray, clipping, lattice, cell walk,
cell ranges and opacities), which must give the kernel's per-pixel counts
exactly; and the order ``contributing <= ideal <= parc <= brute`` of
``stats["samples"]`` on random scenes, which must hold without tolerance. The reference repeats
the kernels' floating-point operations in the same order (Python floats
are IEEE doubles, and the kernels run without fastmath), because samples
on cell faces, which the axis-aligned view produces on purpose, belong
to the cell the walk enters there and a rounding difference would move
them.
"""
import math

import numpy as np
import pytest

from data_tools import Volume
from data_tools.synthetic import blobs, trilinear_field
from parc import Camera, Scene, TransferFunction, Translucent, render
from parc.ideal import (contributing_sample_counts, contributing_samples, ideal_and_contributing_samples,
                        ideal_sample_counts, ideal_samples, possibly_contributing_cells)
from parc.renderer import accumulation_params
from raycast.composite import MODE_COMPOSITE, P_MODE, P_THRESHOLD, cast_accumulate_image
from raycast.iso import NO_SKIP

SIZE = (9, 7)
TINY_DIRECTION = 1e-200     # as raycast.traverse: a direction component below it counts as zero


# --------------------------------------------------------------------------
# The slow reference
# --------------------------------------------------------------------------

def _pixel_ray(cam, width, height, x, y):
    """The world ray through pixel (x, y), DESIGN's formula (as `raycast.rays.camera_ray` computes it)."""
    eye, f, r, u = cam[0:3], cam[3:6], cam[6:9], cam[9:12]
    sx = (2.0 * (x + 0.5) / width - 1.0) * (width / height)
    sy = 1.0 - 2.0 * (y + 0.5) / height
    if cam[14] != 0.0:
        o = [eye[a] + cam[13] * (sx * r[a] + sy * u[a]) for a in range(3)]
        return o, [f[0], f[1], f[2]]
    d = [f[a] + cam[12] * (sx * r[a] + sy * u[a]) for a in range(3)]
    inv = 1.0 / math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    return [eye[0], eye[1], eye[2]], [d[0] * inv, d[1] * inv, d[2] * inv]


def _clip(O, D, dims):
    """``(t_in, t_out)`` of the index-space ray in the box ``[0, n-1]^3``, ``t_in >= 0``."""
    t_in, t_out = 0.0, math.inf
    for o, d, n in zip(O, D, dims):
        if abs(d) < TINY_DIRECTION:
            if o < 0.0 or o > n - 1.0:
                return math.inf, -math.inf
            continue
        inv = 1.0 / d
        t0, t1 = sorted(((0.0 - o) * inv, (n - 1.0 - o) * inv))
        t_in, t_out = max(t_in, t0), min(t_out, t1)
    return t_in, t_out


def _value(data, O, D, t, cell):
    """Trilinear value at the ray's point ``O + t D`` in ``cell``, local coordinates clamped to [0, 1]."""
    i, j, k = cell
    u, v, w = (min(max((O[a] - cell[a]) + t * D[a], 0.0), 1.0) for a in range(3))
    c = data[k:k + 2, j:j + 2, i:i + 2].astype(np.float64)
    # Nested lerps along x, then y, then z, as the kernel rounds them.
    cx = [[float(c[b, a, 0]) + u * (float(c[b, a, 1]) - float(c[b, a, 0])) for a in range(2)] for b in range(2)]
    cy = [cx[b][0] + v * (cx[b][1] - cx[b][0]) for b in range(2)]
    return cy[0] + w * (cy[1] - cy[0])


def _lattice_cells(O, D, dims, t_in, t_out, step):
    """``(n, cell)`` for the lattice points ``t_in + n step``, cell by cell along the ray.

    A cell's interval runs from the latest of its entry crossings to the
    earliest of its exits (each ``(plane - O) / D``), and holds the lattice
    points in ``[c0, c1)``; the last cell keeps its end.
    """
    n_last = int(math.floor((t_out - t_in) / step))
    idx, steps, inv, t0, t1 = [], [], [], [], []
    for o, d, n in zip(O, D, dims):
        i = min(max(int(math.floor(o + t_in * d)), 0), n - 2)
        if abs(d) < TINY_DIRECTION:
            idx.append(i), steps.append(0), inv.append(0.0), t0.append(-math.inf), t1.append(math.inf)
            continue
        iv = 1.0 / d
        # The cell entered at or before t_in and left after it, by the crossing times.
        if d > 0.0:
            while i > 0 and (i - o) * iv >= t_in:
                i -= 1
            while i < n - 2 and (i + 1.0 - o) * iv < t_in:
                i += 1
        else:
            while i < n - 2 and (i + 1.0 - o) * iv >= t_in:
                i += 1
            while i > 0 and (i - o) * iv < t_in:
                i -= 1
        s = 1 if d > 0.0 else -1
        lo, hi = (i - o) * iv, (i + 1.0 - o) * iv
        idx.append(i), steps.append(s), inv.append(iv)
        t0.append(lo if s > 0 else hi), t1.append(hi if s > 0 else lo)
    while True:
        c0, c1 = max(t_in, *t0), min(t_out, *t1)
        n_lo = int(math.ceil((c0 - t_in) / step))
        n_hi = n_last if c1 >= t_out else int(math.ceil((c1 - t_in) / step)) - 1
        for n in range(n_lo, n_hi + 1):
            yield n, tuple(idx)
        if c1 >= t_out:
            return
        a = t1.index(min(t1))                 # ties: x, then y, then z
        idx[a] += steps[a]
        if not 0 <= idx[a] <= dims[a] - 2:
            return
        t0[a] = t1[a]
        t1[a] = ((idx[a] + 1.0 - O[a]) if steps[a] > 0 else (idx[a] - O[a])) * inv[a]


def _possibly_contributing(data, tf):
    """Cells whose 8-corner range has non-zero opacity somewhere, one cell at a time."""
    nz, ny, nx = data.shape
    out = np.zeros((nz - 1, ny - 1, nx - 1), bool)
    for k in range(nz - 1):
        for j in range(ny - 1):
            for i in range(nx - 1):
                c = data[k:k + 2, j:j + 2, i:i + 2]
                out[k, j, i] = tf.nonzero_in(c.min(), c.max())
    return out


def _slow_counts(vis, cam, width, height, stop=None, every=False, contributing=False):
    """Per-pixel ideal counts: brute's lattice walked in plain Python, counting the samples in
    possibly contributing cells (``every``: every sample, as the unaccelerated caster's
    ``samples``; ``contributing``: the samples of non-zero opacity)."""
    vol, tf = vis.volume, vis.tf
    data = vol.data
    contrib = _possibly_contributing(data, tf)
    org, spc = vol.origin, vol.spacing
    dims = vol.dims
    # Opacities refer to a slab a quarter of the smallest spacing thick (`parc.transfer`),
    # worked out here and not read from the kernel's parameters, which a wrong ratio would pass.
    ratio = vis.step / (0.25 * min(vol.spacing))
    cam = [float(c) for c in cam]
    out = np.zeros((height, width), np.int64)
    for y in range(height):
        for x in range(width):
            o, d = _pixel_ray(cam, width, height, x, y)
            O = [(o[a] - org[a]) / spc[a] for a in range(3)]
            D = [d[a] / spc[a] for a in range(3)]
            t_in, t_out = _clip(O, D, dims)
            if not t_in <= t_out:
                continue
            t_stop = math.inf if stop is None else stop[y, x]
            acc = 0.0
            for n, (i, j, k) in _lattice_cells(O, D, dims, t_in, t_out, vis.step):
                t = t_in + n * vis.step
                if t >= t_stop:
                    break
                v = _value(data, O, D, t, (i, j, k))
                a = float(tf.opacity(np.array([v]))[0])
                out[y, x] += 1 if every else (a > 0.0) if contributing else contrib[k, j, i]
                if vis.mode != "composite":
                    continue
                if a > 0.0:
                    a = a if a >= 1.0 or ratio == 1.0 else -math.expm1(ratio * math.log1p(-a))
                    acc += (1.0 - acc) * a
                    if acc >= vis.threshold:
                        break
    return out


# --------------------------------------------------------------------------
# Scenes
# --------------------------------------------------------------------------

def _tiny_volume(dtype):
    # A ramp along x and z plus noise (nx=6, ny=5, nz=7): cell ranges narrow
    # enough that the low corner holds non-contributing cells, with
    # contributing neighbours across x and z faces.
    rng = np.random.default_rng(11)
    data = (25 * np.arange(6) + 12 * np.arange(7)[:, None, None] + rng.integers(0, 20, (7, 5, 6))).astype(dtype)
    # Binary-exact spacing, origin and step (0.125) put the axis-aligned view's
    # samples exactly on z faces every fourth step.
    return Volume(data, spacing=(1.0, 1.25, 0.5), origin=(-2.0, 1.5, 0.25))


#: Opacity zero below 90 and between 170 and 200: many cells are not contributing.
TINY_TF = TransferFunction(opacity=[[90, 0.0], [130, 0.35], [170, 0.0], [200, 0.0], [230, 0.5]],
                           color=[[0, 1.0, 0.5, 0.0], [255, 0.0, 0.5, 1.0]])


def _tiny_cameras(vol):
    lo, hi = vol.bounds
    c = vol.center
    return {
        "perspective": Camera.framing(lo, hi, azimuth=37.0, elevation=23.0, zoom=1.3),
        # Down the z axis: two direction components exactly zero, samples every
        # fourth step exactly on a z face between cells.
        "parallel-z": Camera(eye=(c[0], c[1], c[2] + 40.0), look_at=tuple(c), up=(0.0, 1.0, 0.0),
                             parallel_scale=0.55 * float(hi[1] - lo[1])),
    }


def _kernel_counts(vis, cam, size, stop=None):
    scene = Scene(camera=cam, size=size, volumes=[vis])
    return ideal_sample_counts(scene, vis, stop)


def _set_threshold(vis, threshold):
    """A Translucent whose params carry ``threshold`` (1.01 is refused by Translucent, but not by the kernels)."""
    object.__setattr__(vis, "threshold", threshold)   # past the check, on purpose
    return vis


CASES = [("mip", None), ("average", None), ("composite", 1.01), ("composite", 0.5)]


@pytest.mark.parametrize("dtype", ["uint8", "float32"])
@pytest.mark.parametrize("view", ["perspective", "parallel-z"])
@pytest.mark.parametrize("mode,threshold", CASES)
def test_kernel_matches_slow_reference(dtype, view, mode, threshold):
    vol = _tiny_volume(dtype)
    cam = _tiny_cameras(vol)[view]
    vis = Translucent(vol, TINY_TF, mode=mode, step=None if view == "parallel-z" else 0.29)
    if threshold is not None:
        _set_threshold(vis, threshold)
    w, h = SIZE
    got = _kernel_counts(vis, cam, SIZE)
    want = _slow_counts(vis, cam.as_array(), w, h)
    np.testing.assert_array_equal(got, want)
    scene = Scene(camera=cam, size=SIZE, volumes=[vis])
    seen = contributing_sample_counts(scene, vis)
    np.testing.assert_array_equal(seen, _slow_counts(vis, cam.as_array(), w, h, contributing=True))
    # Not vacuous: some samples are counted and some are not, and some in
    # possibly contributing cells have zero opacity.
    assert 0 < want.sum()
    assert (possibly_contributing_cells(vis) == 0).any()
    assert 0 < seen.sum() < want.sum() and (seen <= got).all()

    # Per pixel against the unaccelerated caster itself: a subset of its
    # samples, and no pixel with opacity lacks counted samples.
    params = accumulation_params(vis)
    assert params[P_THRESHOLD] == vis.threshold and (params[P_MODE] == MODE_COMPOSITE) == (mode == "composite")
    image = np.empty((h, w, 4), np.float32)
    brute = np.empty(w * h, np.int64)
    cast_accumulate_image(vol.data, np.array(vol.origin), np.array(vol.spacing), cam.as_array(), w, h, params,
                          *vis.tf.arrays(), np.empty((1, 1, 2)), False, np.empty((1, 1)), False,
                          np.zeros((1, 1, 1), np.uint32), False, NO_SKIP, -1, image, brute, 0, h)
    brute = brute.reshape(h, w)
    assert (got <= brute).all()
    assert (got[image[..., 3] > 0] > 0).all()
    # The pixels with colour are exactly those with samples of non-zero opacity.
    np.testing.assert_array_equal(image[..., 3] > 0, seen > 0)


def test_composite_with_stop_matches_slow_reference():
    vol = _tiny_volume("float32")
    cam = _tiny_cameras(vol)["perspective"]
    vis = Translucent(vol, TINY_TF, step=0.29, threshold=0.8)
    w, h = SIZE
    stop = np.random.default_rng(3).uniform(0.0, 60.0, (h, w))
    want = _slow_counts(vis, cam.as_array(), w, h, stop)
    np.testing.assert_array_equal(_kernel_counts(vis, cam, SIZE, stop), want)
    scene = Scene(camera=cam, size=SIZE, volumes=[vis])
    assert ideal_samples(scene, vis, stop) == want.sum() < ideal_samples(scene, vis)
    seen = _slow_counts(vis, cam.as_array(), w, h, stop, contributing=True).sum()
    assert contributing_samples(scene, vis, stop) == seen < contributing_samples(scene, vis)
    assert ideal_and_contributing_samples(scene, vis, stop) == (want.sum(), seen)


@pytest.mark.parametrize("view", ["perspective", "parallel-z"])
def test_a_stop_exactly_on_a_lattice_point_takes_no_sample_there(view):
    # Samples at t >= stop are not taken: a stop on a sample's very t (an opaque surface there) ends before it.
    vol = _tiny_volume("float32")
    cam = _tiny_cameras(vol)[view]
    vis = _set_threshold(Translucent(vol, TINY_TF, step=0.125), 1.01)     # no early termination
    w, h = SIZE
    arr = [float(c) for c in cam.as_array()]
    rng = np.random.default_rng(9)
    stop = np.full((h, w), np.inf)
    for y in range(h):
        for x in range(w):
            o, d = _pixel_ray(arr, w, h, x, y)
            O = [(o[a] - vol.origin[a]) / vol.spacing[a] for a in range(3)]
            D = [d[a] / vol.spacing[a] for a in range(3)]
            t_in, t_out = _clip(O, D, vol.dims)
            if t_in <= t_out:
                stop[y, x] = t_in + int(rng.integers(0, int(math.floor((t_out - t_in) / vis.step)) + 1)) * vis.step
    assert np.isfinite(stop).sum() > 20
    np.testing.assert_array_equal(_kernel_counts(vis, cam, SIZE, stop), _slow_counts(vis, cam.as_array(), w, h, stop))
    image = np.empty((h, w, 4), np.float32)
    brute = np.empty(w * h, np.int64)
    cast_accumulate_image(vol.data, np.array(vol.origin), np.array(vol.spacing), cam.as_array(), w, h,
                          accumulation_params(vis), *vis.tf.arrays(), np.empty((1, 1, 2)), False, stop, True,
                          np.zeros((1, 1, 1), np.uint32), False, NO_SKIP, -1, image, brute, 0, h)
    np.testing.assert_array_equal(brute.reshape(h, w), _slow_counts(vis, cam.as_array(), w, h, stop, every=True))


def test_a_composite_ray_stops_at_the_sample_that_reaches_the_threshold_exactly():
    # Opacity 1/2 everywhere and a step of a quarter spacing (no step correction): the
    # accumulated opacity is 1/2 after one sample and exactly 3/4, the threshold, after two.
    vol = Volume(np.full((5, 6, 7), 100.0, np.float32))
    tf = TransferFunction(opacity=[[0, 0.5], [255, 0.5]], color=[[0, 1.0, 1.0, 1.0], [255, 1.0, 1.0, 1.0]])
    vis = Translucent(vol, tf, step=0.25, threshold=0.75)
    cam = Camera.framing(*vol.bounds, azimuth=30.0, elevation=20.0, zoom=1.6)
    w, h = SIZE
    arr = [float(c) for c in cam.as_array()]
    want = np.zeros((h, w), np.int64)
    for y in range(h):
        for x in range(w):
            o, d = _pixel_ray(arr, w, h, x, y)
            t_in, t_out = _clip(o, d, vol.dims)
            if t_in <= t_out:
                want[y, x] = min(2, math.floor((t_out - t_in) / 0.25) + 1)
    assert (want == 2).sum() > 20
    np.testing.assert_array_equal(_kernel_counts(vis, cam, SIZE), want)
    image = np.empty((h, w, 4), np.float32)
    brute = np.empty(w * h, np.int64)
    cast_accumulate_image(vol.data, np.array(vol.origin), np.array(vol.spacing), cam.as_array(), w, h,
                          accumulation_params(vis), *vis.tf.arrays(), np.empty((1, 1, 2)), False,
                          np.empty((1, 1)), False, np.zeros((1, 1, 1), np.uint32), False, NO_SKIP, -1,
                          image, brute, 0, h)
    np.testing.assert_array_equal(brute.reshape(h, w), want)


def test_an_isosurface_has_no_ideal_samples_and_is_refused():
    from data_tools import InputError
    from parc import Isosurface
    vol = _tiny_volume("float32")
    surf = Isosurface(vol, 150.0)
    scene = Scene(camera=_tiny_cameras(vol)["perspective"], size=SIZE, volumes=[surf])
    with pytest.raises(InputError, match="Translucent volume, got Isosurface"):
        ideal_samples(scene, surf)


# --------------------------------------------------------------------------
# Against brute and parc on random scenes
# --------------------------------------------------------------------------

def _random_tf(rng, lo, hi):
    """One or two opacity bumps over a zero background, some narrow."""
    pts = []
    span = hi - lo
    for c in np.sort(rng.uniform(lo + 0.1 * span, hi - 0.1 * span, rng.integers(1, 3))):
        width = span * (1e-3 if rng.random() < 0.3 else rng.uniform(0.02, 0.2))
        pts += [[c - width, 0.0], [c, float(rng.uniform(0.05, 0.9))], [c + width, 0.0]]
    pts = sorted(pts)
    for i in range(1, len(pts)):      # keep the values non-decreasing after overlaps
        pts[i][0] = max(pts[i][0], pts[i - 1][0])
    return TransferFunction(opacity=pts, color=[[lo, 0.9, 0.4, 0.2], [hi, 0.3, 0.6, 1.0]])


def _random_scene(seed):
    rng = np.random.default_rng(500 + seed)
    dims = tuple(int(n) for n in rng.integers(8, 16, 3))
    spacing = tuple(rng.uniform(0.6, 1.6, 3)) if seed % 2 else (1.0, 1.0, 1.0)
    origin = tuple(rng.uniform(-10, 10, 3))
    if seed % 3 == 0:
        data = blobs(dims, seed=seed).data
    elif seed % 3 == 1:
        data = rng.normal(size=dims[::-1]).astype(np.float32)       # noise
    else:
        data = trilinear_field(dims, seed=seed, dtype="float32").data
    vol = Volume(data, spacing=spacing, origin=origin)
    vis = Translucent(vol, _random_tf(rng, *vol.value_range()), shade=bool(seed % 2))
    lo, hi = vol.bounds
    cam = Camera.framing(lo, hi, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-70, 70),
                         parallel=seed % 4 == 3, zoom=1.4)
    return Scene(camera=cam, size=(24, 18), volumes=[vis]), vis


@pytest.mark.parametrize("seed", range(10))
def test_ideal_at_most_parc_at_most_brute(seed, gl):
    scene, vis = _random_scene(seed)
    brute = render(scene, method="brute")
    parc = render(scene, method="parc", supercell=1)
    ideal = ideal_samples(scene, vis)
    seen = contributing_samples(scene, vis)
    assert seen <= ideal <= parc.stats["samples"] <= brute.stats["samples"], seed
    if (brute.image[..., 3] > 0).any():
        assert seen > 0, seed


@pytest.mark.parametrize("seed", range(3))
def test_stop_only_removes_samples(seed):
    scene, vis = _random_scene(seed)
    w, h = scene.size
    free = ideal_sample_counts(scene, vis)
    rng = np.random.default_rng(seed)
    dist = float(np.linalg.norm(np.asarray(scene.camera.eye) - vis.volume.center))
    stop = rng.uniform(0.5 * dist, 1.5 * dist, (h, w))
    stop[rng.random((h, w)) < 0.2] = np.inf
    stopped = ideal_sample_counts(scene, vis, stop)
    assert (stopped <= free).all()
    assert stopped.sum() < free.sum()            # the stops cut through the volume
    np.testing.assert_array_equal(ideal_sample_counts(scene, vis, np.full((h, w), np.inf)), free)
    assert ideal_sample_counts(scene, vis, np.zeros((h, w))).sum() == 0
