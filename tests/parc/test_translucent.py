"""Translucent volumes: PARC against the unaccelerated caster, and accumulation against a slow reference.

Truth: ``method="brute"`` on the same scene (every pixel within 1e-6; PARC,
with depth bounds, bit planes or both, skips only samples of exactly zero
opacity, so equality is expected), and a
plain-Python reimplementation of the sample lattice and compositing for a
handful of rays.
"""
import math
import warnings

import numpy as np
import pytest

from data_tools import InputError, Volume
from data_tools.synthetic import blobs, ct_phantom, trilinear_field
from parc import (Camera, DirectionalLight, PointLight, Scene, ShowsNothingWarning, TransferFunction, Translucent,
                  load_transfer_function, render)
from parc.classify import VolumeIndex, classify_tf

MODES = ("composite", "mip", "average")
SUPERCELLS = (0.5, 1, 2, 3, 4.5, 8, (2, 3, 1.5))
SIZE = (36, 28)
BUFFERS = (("depth",), ("bits",), ("depth", "bits"))
#: Each random scene shows at least MIN_VISIBLE pixels of alpha above VISIBLE_ALPHA (drawn
#: up to MAX_DRAWS times).
MIN_VISIBLE = 10
VISIBLE_ALPHA = 0.01
MAX_DRAWS = 20


def _random_tf(rng, lo, hi):
    """Piecewise-linear opacity with one or two bumps, sometimes a narrow spike."""
    pts = []
    span = hi - lo
    centres = np.sort(rng.uniform(lo + 0.1 * span, hi - 0.1 * span, rng.integers(1, 3)))
    for c in centres:
        width = span * (1e-4 if rng.random() < 0.3 else rng.uniform(0.02, 0.2))
        pts += [[c - width, 0.0], [c, float(rng.uniform(0.05, 0.9))], [c + width, 0.0]]
    pts = sorted(pts)
    for i in range(1, len(pts)):      # keep the values non-decreasing after overlaps
        pts[i][0] = max(pts[i][0], pts[i - 1][0])
    color = [[lo, 0.9, 0.4, 0.2], [hi, 0.3, 0.6, 1.0]]
    return TransferFunction(opacity=pts, color=color)


def _volume(rng, seed):
    kind = seed % 4
    dims = tuple(int(n) for n in rng.integers(9, 18, 3))
    spacing = tuple(rng.uniform(0.6, 1.8, 3)) if rng.random() < 0.5 else (1.0, 1.0, 1.0)
    origin = tuple(rng.uniform(-20, 20, 3))
    if kind == 0:
        data = blobs(dims, seed=seed).data
    elif kind == 1:
        data = ct_phantom(dims, seed=seed, dtype=str(rng.choice(["uint16", "int16"]))).data
        if data.dtype == np.int16:
            data = data - np.int16(1024)          # as Hounsfield units: negative samples too
    elif kind == 2:
        data = rng.normal(size=dims[::-1]).astype(np.float32)
    else:
        data = trilinear_field(dims, seed=seed, dtype="float32").data
    return Volume(data, spacing=spacing, origin=origin)


def _size(seed):
    """Odd for the views along an axis (`_camera`'s view 2): the middle pixel's ray is exactly along it."""
    return (37, 29) if seed % 5 == 2 else SIZE


def _camera(rng, vol, seed, vis=None, supercell=None):
    """View ``seed % 5``; an eye inside the volume is, half the time with ``vis`` and ``supercell``
    given, inside one of the supercells that may contribute."""
    lo, hi = vol.bounds
    view = seed % 5
    if view == 0:
        return Camera.framing(lo, hi, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-70, 70), zoom=1.5)
    if view == 1:
        return Camera.framing(lo, hi, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-70, 70),
                              parallel=True, zoom=1.3)
    if view == 2:     # exactly along an axis
        axis = int(rng.integers(3))
        e = np.zeros(3)
        e[axis] = 3.0 * np.linalg.norm(hi - lo)
        up = np.zeros(3)
        up[(axis + 1) % 3] = 1.0
        c = vol.center
        if rng.random() < 0.5:
            # On a line of samples: the middle ray runs along cell edges.
            c = lo + np.round((c - lo) / vol.spacing) * vol.spacing
        if rng.random() < 0.5:
            return Camera(eye=tuple(c + e), look_at=tuple(c), up=tuple(up),
                          parallel_scale=0.6 * float(np.linalg.norm(hi - lo)))
        return Camera(eye=tuple(c + e), look_at=tuple(c), up=tuple(up), fov=30.0)
    eye = lo + rng.uniform(0.2, 0.8, 3) * (hi - lo)       # inside the volume
    if vis is not None and rng.random() < 0.5:
        index = VolumeIndex.of(vol)
        pc = np.argwhere(classify_tf(*index.ranges(supercell), vis.tf))
        if len(pc):
            edges = index.grid(supercell).world_edges(vol)
            k, j, i = pc[rng.integers(len(pc))]
            cell_lo = np.array([edges[0][i], edges[1][j], edges[2][k]])
            cell_hi = np.array([edges[0][i + 1], edges[1][j + 1], edges[2][k + 1]])
            eye = cell_lo + rng.uniform(0.2, 0.8, 3) * (cell_hi - cell_lo)
    look = eye + rng.normal(size=3)
    if view == 3:
        return Camera(eye=tuple(eye), look_at=tuple(look), up=(0.2, 0.3, 1.0), fov=70.0)
    return Camera(eye=tuple(eye), look_at=tuple(look), up=(0.2, 0.3, 1.0),
                  parallel_scale=0.4 * float(np.linalg.norm(hi - lo)))


def _random_lights(rng, vol):
    """One or two lights of random colours: point lights outside, inside or on the volume's
    box, or directional."""
    lo, hi = (np.asarray(b) for b in vol.bounds)
    lights = []
    for _ in range(int(rng.integers(1, 3))):
        color = tuple(rng.uniform(0.4, 1.0, 3))
        place = rng.integers(4)
        if place == 0:
            d = rng.normal(size=3)
            p = (lo + hi) / 2 + d / np.linalg.norm(d) * np.linalg.norm(hi - lo) * rng.uniform(0.8, 3.0)
            lights.append(PointLight(tuple(p), color=color))
        elif place == 1:
            lights.append(PointLight(tuple(rng.uniform(lo, hi)), color=color))
        elif place == 2:
            p = rng.uniform(lo, hi)
            a = rng.integers(3)
            p[a] = lo[a] if rng.random() < 0.5 else hi[a]
            lights.append(PointLight(tuple(p), color=color, intensity=float(rng.uniform(0.5, 1.5))))
        else:
            lights.append(DirectionalLight(tuple(rng.normal(size=3)), color=color))
    return lights


@pytest.mark.random_scenes(210)
def test_parc_equals_brute_translucent(seed, gl):
    rng = np.random.default_rng(1000 + seed)
    vol = _volume(rng, seed)
    lo, hi = vol.value_range()
    mode = MODES[seed % 3]
    # Drawn from the generator, not the seed, which already chose the volume and the view.
    shade = mode == "composite" and bool(rng.random() < 0.5)
    step = 0.37 if rng.random() < 0.25 else None
    # A scene that shows nothing cannot show a skipped sample: another transfer function and
    # view are drawn until brute's image shows something.
    # Half the shaded scenes are lit by lights of their own, drawn apart so that the
    # volume, transfer function and view stay the seed's.
    lights = _random_lights(np.random.default_rng(5000 + seed), vol) if shade and seed % 4 < 2 else []
    supercell = SUPERCELLS[seed % len(SUPERCELLS)]
    for _ in range(MAX_DRAWS):
        vis = Translucent(vol, _random_tf(rng, lo, hi), mode=mode, shade=shade, step=step)
        scene = Scene(camera=_camera(rng, vol, seed, vis, supercell), size=_size(seed), volumes=[vis], lights=lights)
        ref = render(scene, method="brute", work=True)
        if (ref.image[..., 3] > VISIBLE_ALPHA).sum() >= MIN_VISIBLE:
            break
    assert (ref.image[..., 3] > VISIBLE_ALPHA).sum() >= MIN_VISIBLE, f"no scene of {MAX_DRAWS} shows anything"
    buffers = BUFFERS[(seed // 3) % len(BUFFERS)]
    res = render(scene, method="parc", supercell=supercell, buffers=buffers, work=True)
    where = f"{mode} supercell={supercell} buffers={buffers} lights={len(lights)} seed={seed}"
    assert np.abs(res.image - ref.image).max() <= 1e-6, where
    # PARC takes a subset of each ray's lattice points: never more samples at any pixel.
    assert res.work.sum() == res.stats["samples"] and ref.work.sum() == ref.stats["samples"], where
    assert (res.work <= ref.work).all(), where


@pytest.mark.random_scenes(60)
def test_parc_equals_brute_with_shadows_on_shaded_samples(seed, gl):
    # Each sample that adds colour casts a shadow ray to each light: through the volume itself,
    # whole for brute, within the light buffers' segments for PARC.
    rng = np.random.default_rng(7000 + seed)
    vol = _volume(rng, seed)
    lo, hi = vol.value_range()
    step = 0.37 if rng.random() < 0.25 else None
    lights = _random_lights(np.random.default_rng(9000 + seed), vol)
    for _ in range(MAX_DRAWS):
        vis = Translucent(vol, _random_tf(rng, lo, hi), shade=True, step=step)
        scene = Scene(camera=_camera(rng, vol, seed), size=_size(seed), volumes=[vis], lights=lights, shadows=True)
        ref = render(scene, method="brute", work=True)
        if (ref.image[..., 3] > VISIBLE_ALPHA).sum() >= MIN_VISIBLE:
            break
    unshadowed = render(Scene(camera=scene.camera, size=scene.size, volumes=[vis], lights=lights), method="brute",
                        work=True)
    assert np.array_equal(ref.image[..., 3], unshadowed.image[..., 3])
    assert (ref.image[..., :3] <= unshadowed.image[..., :3] + 1e-6).all()
    # The camera rays take the same samples, recorded for their shadow rays or lit at once.
    assert np.array_equal(ref.work, unshadowed.work)
    supercell = SUPERCELLS[seed % len(SUPERCELLS)]
    light_buffer = (4, 16, 64, 256)[int(rng.integers(4))]
    res = render(scene, method="parc", supercell=supercell, light_buffer=light_buffer, work=True)
    where = f"supercell={supercell} light_buffer={light_buffer} lights={len(lights)} seed={seed}"
    assert np.abs(res.image - ref.image).max() <= 1e-6, where
    assert res.work.sum() == res.stats["samples"] and (res.work <= ref.work).all(), where
    assert res.stats["shadow_rays"] == ref.stats["shadow_rays"], where
    assert res.stats["shadow_samples"] <= ref.stats["shadow_samples"], where
    if seed % 4 < 2:
        return      # bit planes below for float32 samples: each type compiles its own walk, for 20 s
    # The same camera rays bounded by bit planes too, or by them alone.
    buffers = ("depth,bits", "bits")[seed % 2]
    planes = render(scene, method="parc", supercell=supercell, light_buffer=light_buffer, buffers=buffers,
                    work=True)
    assert np.abs(planes.image - ref.image).max() <= 1e-6, f"{where} buffers={buffers}"
    assert planes.work.sum() == planes.stats["samples"] and (planes.work <= ref.work).all(), where
    assert "planes" in planes.stats["volumes"][0] and planes.stats["shadow_rays"] == ref.stats["shadow_rays"], where


def _slow_lattice(vol, o, d, step):
    """The trilinear values at the sample lattice ``t_in + n step`` of one ray through the
    volume's box, in plain Python."""
    lo, hi = vol.bounds
    t_in, t_out = 0.0, math.inf
    for a in range(3):
        if d[a] == 0:
            continue
        t0, t1 = sorted(((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]))
        t_in, t_out = max(t_in, t0), min(t_out, t1)
    n = 0
    while t_in <= t_out and t_in + n * step <= t_out:
        p = (o + (t_in + n * step) * d - np.array(vol.origin)) / np.array(vol.spacing)
        idx = np.clip(np.floor(p).astype(int), 0, np.array(vol.dims) - 2)
        f = p - idx
        cube = vol.data[idx[2]:idx[2] + 2, idx[1]:idx[1] + 2, idx[0]:idx[0] + 2].astype(float)
        wz, wy, wx = np.array([1 - f[2], f[2]]), np.array([1 - f[1], f[1]]), np.array([1 - f[0], f[0]])
        yield float(np.einsum("kji,k,j,i->", cube, wz, wy, wx))
        n += 1


def _slow_composite(vol, tf, o, d, step, threshold):
    """Front-to-back compositing of the lattice's samples, one ray."""
    ref_step = 0.25 * min(vol.spacing)
    c = np.zeros(3)
    acc = 0.0
    for v in _slow_lattice(vol, o, d, step):
        a = float(tf.opacity(np.array([v]))[0])
        if a > 0:
            a = 1 - (1 - a) ** (step / ref_step)
            c += (1 - acc) * a * tf.color(np.array([v]))[0]
            acc += (1 - acc) * a
            if acc >= threshold:
                break
    return np.append(c, acc)


def _slow_mip(vol, tf, o, d, step):
    """The transfer function at the largest visible (non-zero opacity) sample, premultiplied."""
    visible = [v for v in _slow_lattice(vol, o, d, step) if tf.opacity(np.array([v]))[0] > 0]
    if not visible:
        return np.zeros(4)
    top = np.array([max(visible)])
    a = float(tf.opacity(top)[0])
    return np.append(a * tf.color(top)[0], a)


def _slow_average(vol, tf, o, d, step):
    """The visible samples' heights above the data's minimum, over all lattice samples and the range."""
    lo, hi = vol.value_range()
    values = list(_slow_lattice(vol, o, d, step))
    if not values:
        return np.zeros(4)
    total = sum(v - lo for v in values if tf.opacity(np.array([v]))[0] > 0)
    return np.full(4, min(max(total / len(values) / (hi - lo), 0.0), 1.0))


def test_composite_matches_a_slow_reference():
    rng = np.random.default_rng(7)
    vol = Volume(blobs(12, seed=3).data.astype(np.float32), spacing=(1.0, 1.2, 0.8), origin=(2.0, -1.0, 0.5))
    tf = TransferFunction(opacity=[[40, 0.0], [120, 0.3], [255, 0.6]], color=[[0, 1, 0.5, 0], [255, 0, 0.5, 1]])
    cam = Camera.framing(*vol.bounds, azimuth=40, elevation=20, zoom=1.4)
    scene = Scene(camera=cam, size=(16, 12), volumes=[Translucent(vol, tf, step=0.3, threshold=0.95)])
    res = render(scene)
    o, d = cam.rays(16, 12)
    seen = 0
    # Random pixels, and as many among those the render shows, so that most compared are not background.
    shown = np.argwhere(res.image[..., 3] > 0.05)
    picks = [(int(y), int(x)) for y, x in zip(rng.integers(0, 12, 15), rng.integers(0, 16, 15))]
    picks += [tuple(map(int, p)) for p in shown[rng.permutation(len(shown))[:15]]]
    for y, x in picks:
        want = _slow_composite(vol, tf, o[y, x], d[y, x], 0.3, 0.95)
        np.testing.assert_allclose(res.image[y, x], want, atol=1e-6)
        seen += want[3] > 0.05
    assert seen >= 10           # most pixels compared show the volume, not empty background


def test_a_composite_volume_replaced_into_another_mode_keeps_its_default_threshold():
    import dataclasses
    vis = Translucent(Volume(blobs(6, seed=1).data), "greyscale")
    assert dataclasses.replace(vis, mode="mip").threshold == vis.threshold == 0.99
    with pytest.raises(InputError, match="threshold applies to mode composite"):
        dataclasses.replace(vis, threshold=0.5, mode="mip")
    # The default read back from a float32 array is the default, not another threshold.
    assert Translucent(vis.volume, "greyscale", mode="mip", threshold=np.float32(0.99)).threshold == 0.99
    with pytest.raises(InputError, match="threshold applies to mode composite"):
        Translucent(vis.volume, "greyscale", mode="average", threshold=np.nextafter(np.float32(0.99), 1))


def test_a_preset_named_follows_a_replaced_mode_or_volume_as_when_named_anew():
    # README: make a new one with dataclasses.replace. A ramp preset is made for the volume's
    # range and the mode (it ends opaque for mip and average, `ramp_opacity`); kept as made for
    # the old range and mode, a mip of greyscale would peak at 0.1.
    import dataclasses
    data = np.broadcast_to(np.arange(8, dtype=np.float32)[:, None, None] * 10, (8, 8, 8)).copy()
    vis = Translucent(Volume(data), "greyscale")
    assert vis.tf.opacity_points[-1].tolist() == [70.0, 0.1]
    mip = dataclasses.replace(vis, mode="mip")
    assert mip.tf.opacity_points[-1].tolist() == [70.0, 1.0]
    assert mip.tf == Translucent(vis.volume, "greyscale", mode="mip").tf
    other = dataclasses.replace(vis, volume=Volume(data * 3))
    assert other.tf.opacity_points[-1].tolist() == [210.0, 0.1]
    # Only what was named is made again: a TransferFunction given as such is kept as it is.
    tf = TransferFunction([(0, 0.0), (70, 0.1)])
    assert dataclasses.replace(Translucent(vis.volume, tf), mode="mip", volume=Volume(data * 3)).tf is tf
    assert dataclasses.replace(vis, step=0.5).tf is vis.tf
    # A scene file's name is the volume's own as well.
    assert Translucent(Volume(data * 3), vis.tf).tf.opacity_points[-1].tolist() == [210.0, 0.1]


def test_a_default_step_follows_a_replaced_volume_and_a_given_step_stays():
    # As a named preset does: the default is the new volume's, a quarter of its smallest
    # spacing; a step given as a number is the caller's, whatever the volume.
    import dataclasses
    import pickle
    data = blobs(6, seed=1).data
    vis = Translucent(Volume(data), "greyscale")
    finer = Volume(data, spacing=(0.5, 0.2, 0.4))
    assert vis.step == 0.25
    assert dataclasses.replace(vis, volume=finer).step == Translucent(finer, "greyscale").step == 0.05
    assert dataclasses.replace(dataclasses.replace(vis, volume=finer), volume=vis.volume).step == 0.25
    assert dataclasses.replace(Translucent(Volume(data), "greyscale", step=0.25), volume=finer).step == 0.25
    assert dataclasses.replace(vis, volume=finer, step=0.3).step == 0.3
    # Pickled (as parc bench's children send scenes), still the default.
    assert dataclasses.replace(pickle.loads(pickle.dumps(vis)), volume=finer).step == 0.05


def test_a_transfer_function_given_is_kept_whatever_it_was_loaded_for(tmp_path):
    # A window the caller chose (a numpy one too) is no stale range, and a file loaded once is
    # the function given: not read again when the Translucent is made or replaced.
    import dataclasses
    data = np.broadcast_to(np.arange(8, dtype=np.float32)[:, None, None] * 10, (8, 8, 8)).copy()
    vol = Volume(data)
    for window in (load_transfer_function("greyscale", data_range=(20.0, 50.0)),
                   load_transfer_function("greyscale", data_range=np.array([20.0, 50.0]))):
        assert Translucent(vol, window).tf is window and Translucent(vol, window, mode="mip").tf is window
        assert dataclasses.replace(Translucent(vol, window), volume=Volume(data * 3)).tf is window
        assert window.opacity_points[-1].tolist() == [50.0, 0.1]
    path = tmp_path / "tf.toml"
    path.write_text("opacity = [[0, 0.0], [70, 0.5]]\n")
    loaded = load_transfer_function(path)
    path.unlink()
    assert dataclasses.replace(Translucent(vol, loaded), mode="mip").tf is loaded


@pytest.mark.parametrize("mode, slow", [("mip", _slow_mip), ("average", _slow_average)])
def test_mip_and_average_match_a_slow_reference(mode, slow):
    # Opacity zero below 40: the largest visible sample is often not the last one on the ray
    # (the blobs peak inside), and transparent samples count in the average's N only.
    rng = np.random.default_rng(11)
    vol = Volume(blobs(12, seed=3).data.astype(np.float32), spacing=(1.0, 1.2, 0.8), origin=(2.0, -1.0, 0.5))
    tf = TransferFunction(opacity=[[40, 0.0], [40.5, 0.2], [255, 0.7]], color=[[0, 1, 0.5, 0], [255, 0, 0.5, 1]])
    cam = Camera.framing(*vol.bounds, azimuth=40, elevation=20, zoom=1.4)
    scene = Scene(camera=cam, size=(16, 12), volumes=[Translucent(vol, tf, mode=mode, step=0.3)])
    res = render(scene)
    o, d = cam.rays(16, 12)
    peaked = 0
    for y, x in zip(rng.integers(0, 12, 40), rng.integers(0, 16, 40)):
        want = slow(vol, tf, o[y, x], d[y, x], 0.3)
        np.testing.assert_allclose(res.image[y, x], want, atol=1e-6)
        visible = [v for v in _slow_lattice(vol, o[y, x], d[y, x], 0.3) if v > 40]
        peaked += bool(visible) and max(visible) > visible[-1]
    assert peaked >= 5


def test_opacity_correction_keeps_brightness_across_steps():
    vol = Volume(np.full((6, 6, 6), 100.0, np.float32))
    tf = TransferFunction(opacity=[[0, 0.02], [200, 0.02]])
    cam = Camera(eye=(2.5, 2.5, -50.0), look_at=(2.5, 2.5, 0.0), up=(0, 1, 0), parallel_scale=1.0)
    alphas = []
    for step in (0.25, 0.1, 0.05):
        img = render(Scene(camera=cam, size=(3, 3), volumes=[Translucent(vol, tf, step=step, threshold=1.0)])).image
        alphas.append(img[1, 1, 3])
    # 5 units of a medium with 0.02 opacity per quarter unit, as a continuum: 1 - 0.98^20 (to a step).
    want = 1 - 0.98 ** 20
    assert all(abs(a - want) < 0.02 for a in alphas)


@pytest.mark.parametrize("kwargs, words", [
    (dict(mode="xray"), "unknown mode"),
    (dict(step=0.0), "step"),
    (dict(threshold=1.5), "threshold"),
    (dict(tf="no_such_preset"), "no_such_preset"),
])
def test_bad_translucent_settings(kwargs, words):
    vol = Volume(np.zeros((4, 4, 4), np.uint8))
    args = dict(tf="greyscale")
    args.update(kwargs)
    with pytest.raises(InputError, match=words):
        Translucent(vol, **args)



@pytest.mark.parametrize("text, names", [("depth", ("depth",)), ("bits", ("bits",)),
                                         ("depth,bits", ("depth", "bits")), ("depth+bits", ("depth", "bits")),
                                         (" bits , depth ", ("bits", "depth"))])
def test_buffers_named_by_a_string_as_on_the_command_line(text, names, gl):
    from parc.renderer import parse_buffers

    assert parse_buffers(text) == names
    vol = Volume(blobs(10, seed=2).data)
    scene = Scene(camera=Camera.framing(*vol.bounds, azimuth=30), size=(12, 10),
                  volumes=[Translucent(vol, "greyscale")])
    by_text = render(scene, "parc", buffers=text)
    by_names = render(scene, "parc", buffers=names)
    assert by_text.stats["buffers"] == list(names)
    assert np.array_equal(by_text.image, by_names.image)
    assert np.abs(by_text.image - render(scene).image).max() <= 1e-6


@pytest.mark.parametrize("bad", ["deep", "", ",", ("depth", "colour"), (), 3])
def test_unknown_buffers_get_one_clear_error(bad):
    vol = Volume(blobs(8, seed=1).data)
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(4, 4), volumes=[Translucent(vol, "greyscale")])
    with pytest.raises(InputError, match="PARC buffers must be depth, bits or both"):
        render(scene, "parc", buffers=bad)

# Transparent cells and cubes (`parc.classify.VolumeIndex.tf_skip`, skipped by `raycast.composite.accumulate_ray`)

def transparent_table(data, tf, shift):
    """1 per block of ``2**shift`` cells whose samples' whole range has zero opacity, else 0:
    the opacity sampled densely over the block's [min, max] (plus both ends)."""
    b = 1 << shift
    cz, cy, cx = (n - 1 for n in data.shape)
    out = np.zeros((-(-cz // b), -(-cy // b), -(-cx // b)), np.int8)
    for k in range(out.shape[0]):
        for j in range(out.shape[1]):
            for i in range(out.shape[2]):
                v = data[k * b:min(cz, (k + 1) * b) + 1, j * b:min(cy, (j + 1) * b) + 1,
                         i * b:min(cx, (i + 1) * b) + 1].astype(np.float64)
                lo, hi = v.min(), v.max()
                xs = np.concatenate([np.linspace(lo, hi, 2001), tf.opacity_points[:, 0]])
                xs = xs[(xs >= lo) & (xs <= hi)]
                out[k, j, i] = 0 if (tf.opacity(xs) > 0).any() else 1
    return out


def _spiky_tf(lo, hi):
    span = hi - lo
    c1, c2 = lo + 0.55 * span, lo + 0.8 * span
    return TransferFunction(opacity=[(c1 - 1e-3 * span, 0.0), (c1, 0.6), (c1 + 1e-3 * span, 0.0),
                                     (c2 - 0.05 * span, 0.0), (c2, 0.3), (c2 + 0.05 * span, 0.0)],
                            color=[(lo, 0.9, 0.4, 0.2), (hi, 0.3, 0.6, 1.0)])


def test_tf_skip_table_matches_a_dense_check():
    """Zero where the cell may contribute, else one plus the radius of its cube of transparent cells."""
    from parc.classify import VolumeIndex
    from parc.skip import SKIP_CAP
    from raycast.composite import MAY_CONTRIBUTE
    vol = blobs((17, 14, 12), count=5, seed=3)
    tf = _spiky_tf(float(vol.data.min()), float(vol.data.max()))
    table, jump_min = VolumeIndex.of(vol).tf_skip(tf)
    clear = transparent_table(vol.data, tf, 0).astype(bool)
    assert table.shape == clear.shape
    assert np.array_equal(table == MAY_CONTRIBUTE, ~clear)
    cz, cy, cx = clear.shape
    for k, j, i in np.argwhere(clear):
        r = 0
        while r + 1 < SKIP_CAP and clear[max(0, k - r - 1):k + r + 2, max(0, j - r - 1):j + r + 2,
                                         max(0, i - r - 1):i + r + 2].all():
            r += 1
        assert table[k, j, i] == r + 1, (k, j, i)
    assert len(np.unique(table)) >= 4          # cubes of several radii
    assert jump_min >= 0


@pytest.mark.parametrize("mode", ["composite", "mip", "average"])
def test_translucent_same_image_with_and_without_blocks(mode, gl):
    """Transparent blocks skipped inside PARC's segments: the same pixels, fewer samples."""
    rng = np.random.default_rng(5)
    skipped = 0
    for seed in range(4):
        data = blobs((21, 18, 16), count=6, seed=seed).data
        vol = Volume(data, spacing=tuple(rng.uniform(0.7, 1.5, 3)), origin=tuple(rng.uniform(-5, 5, 3)))
        tf = _spiky_tf(float(data.min()), float(data.max()))
        lo, hi = vol.bounds
        cams = [Camera.framing(lo, hi, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-60, 60)),
                Camera(eye=tuple(rng.uniform(lo, hi)), look_at=tuple(rng.uniform(lo, hi)), fov=70.0),
                Camera.framing(lo, hi, azimuth=90.0, elevation=0.0)]
        for cam in cams:
            scene = Scene(camera=cam, size=(40, 32), volumes=[Translucent(vol, tf, mode=mode)])
            ref = render(scene, "brute")
            off = render(scene, "parc", blocks=False, buffers=("depth", "bits"))
            on = render(scene, "parc", buffers=("depth", "bits"))
            assert np.abs(on.image - ref.image).max() <= 1e-6
            assert np.array_equal(on.image, off.image)
            assert on.stats["samples"] <= off.stats["samples"]
            skipped += off.stats["samples"] - on.stats["samples"]
    assert skipped > 0


# Values where the caster's arithmetic, not the data, decides: a transfer
# function opaque only just past the data's range must show nothing.

def _past_the_range_scenes(data, tf_points, cam):
    vol = Volume(data)
    tf = TransferFunction(opacity=tf_points)
    for mode in MODES:
        yield Scene(camera=cam, size=(8, 8), volumes=[Translucent(vol, tf, mode=mode, step=0.05)])


@pytest.mark.filterwarnings("ignore::parc.ShowsNothingWarning")      # so it should
@pytest.mark.parametrize("case", ["float32 rounding", "float32 overflow"])
def test_float32_samples_stay_in_their_cells_range(case, gl):
    """float32 corners are differenced in float64: in float32, 1 - (-0.6 2^-23)
    rounds up and a sample overshoots 1.0; 3e38 - (-3e38) overflows to inf."""
    if case == "float32 rounding":
        rng = np.random.default_rng(5)
        data = rng.choice(np.array([1.0, -0.6 * 2.0 ** -23], np.float32), (6, 6, 6))
        points = [[1.0 + 1e-9, 0.0], [1.0 + 2e-9, 1.0]]            # opaque only above the maximum
    else:
        data = np.zeros((2, 2, 2), np.float32)
        data[1, 1, 0], data[1, 1, 1] = -3e38, 3e38
        hi = float(np.float32(3e38))
        points = [[hi, 0.0], [hi, 0.8]]                              # opaque only at the maximum
    lo_, hi_ = np.array([0.0, 0.0, 0.0]), np.array(data.shape[::-1], float) - 1
    cam = Camera.framing(lo_, hi_, azimuth=30, elevation=20, zoom=1.2)
    for scene in _past_the_range_scenes(data, points, cam):
        ref = render(scene, method="brute")
        assert ref.image[..., 3].max() == 0.0, scene.volumes[0].mode
        for buffers in BUFFERS:
            res = render(scene, method="parc", supercell=0.5, buffers=buffers)
            assert np.abs(res.image - ref.image).max() <= 1e-6, (scene.volumes[0].mode, buffers)


@pytest.mark.parametrize("mode", MODES)
def test_distant_parallel_eye_and_a_steep_field(mode, gl):
    """An eye 3e8 units away, float32 samples from -3e38 to 3e38, sub-cell supercells, and
    opacity only above zero: samples placed from the eye round by ~1e-6 cells, which a
    field this steep turns into values past the sub-cell ranges' margins."""
    values = np.array([-3e38, -1e30, -1.0, 0.0, 1e-40, 1.0, 1e30, 3e38], np.float32)
    data = np.random.default_rng(4).choice(values, (4, 3, 20))
    vol = Volume(data, spacing=(1.0, 0.1, 7.0))
    tf = TransferFunction(opacity=[[0.0, 0.0], [1e-38, 0.6]])
    cam = Camera(eye=(9.5, 311449835.4970588, 10.5), look_at=(9.5, 0.1, 10.5), up=(0.3, 0.2, 1.0),
                 parallel_scale=23.8)
    scene = Scene(camera=cam, size=(40, 44), volumes=[Translucent(vol, tf, mode=mode, step=0.05)])
    ref = render(scene, method="brute")
    assert ref.image[..., 3].max() > 0.0
    for supercell in (0.5, 0.125):
        for buffers in BUFFERS:
            res = render(scene, method="parc", supercell=supercell, buffers=buffers)
            assert np.abs(res.image - ref.image).max() <= 1e-6, (supercell, buffers)


@pytest.mark.parametrize("background", [(0.2, 0.4, 0.6, 0.5), (1.0, 1.0, 1.0, 0.0), (0.1, 0.7, 0.3)])
@pytest.mark.parametrize("two", [False, True])
def test_background_goes_under_the_image_as_colour_times_alpha(background, two):
    """The background is given as seen; the image's premultiplied pixels hold it times its alpha
    (one volume, and several through the general path), and colour never exceeds alpha."""
    from parc import Isosurface
    vol = blobs(12, seed=3)
    lo, hi = vol.value_range()
    volumes = [Translucent(vol, "greyscale")] + ([Isosurface(vol, 0.8 * lo + 0.2 * hi)] if two else [])
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(20, 16), volumes=volumes)
    bare = render(scene).image
    r, g, b, *a = background
    a = a[0] if a else 1.0
    with_bg = render(Scene(camera=scene.camera, size=scene.size, volumes=volumes, background=background)).image
    expect = bare + (1 - bare[..., 3:]) * np.array([r * a, g * a, b * a, a], np.float32)
    assert np.abs(with_bg - expect).max() < 1e-6
    assert (with_bg[..., :3] <= with_bg[..., 3:] + 1e-6).all()
    assert (bare[..., 3] < 1).any()


@pytest.mark.parametrize("offset", [0.0, 1000.0, -1000.0])
def test_average_is_the_visible_samples_height_above_the_minimum(offset):
    """Average intensity: the visible samples' heights above the data's minimum, over all N
    lattice samples and the range; the same picture whatever constant the data carry (with
    the raw values summed, +1000 made the ball vanish and -1000 saturated it)."""
    z, y, x = np.mgrid[0:9, 0:9, 0:9]
    data = np.where((x - 4) ** 2 + (y - 4) ** 2 + (z - 4) ** 2 <= 6, 80.0, 5.0).astype(np.float32) + offset
    data[0, 0, 0] = 100 + offset
    tf = TransferFunction(opacity=[[offset + 40, 0], [offset + 50, 0.5]])      # shows the ball only
    cam = Camera(eye=(4, 4, -40), look_at=(4, 4, 4), up=(0, 1, 0), parallel_scale=5.0)
    scene = Scene(camera=cam, size=(9, 9), volumes=[Translucent(Volume(data), tf, mode="average")])
    img = render(scene).image
    # The centre pixel's ray runs along z through x = y = 4: samples every 0.25 from z = 0 to 8.
    zs = np.arange(33) * 0.25
    v = np.interp(zs, np.arange(9), data[:, 4, 4].astype(np.float64))
    lo, hi = float(data.min()), float(data.max())
    grey = np.where(tf.opacity(v) > 0, v - lo, 0.0).sum() / len(zs) / (hi - lo)
    assert grey > 0.3 and img[4, 4] == pytest.approx([grey] * 4, abs=1e-6)
    assert img[0, 8, 3] == 0.0                  # a ray that meets only the transparent shell


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_average_of_a_constant_volume_is_black(method, request):
    """Every sample lies at the data's minimum, over an empty range: grey 0, not 0 / 0."""
    if method == "parc":
        request.getfixturevalue("gl")
    tf = TransferFunction(opacity=[[0, 0.5], [10, 0.5]])
    vis = Translucent(Volume(np.full((5, 5, 5), 7.0, np.float32)), tf, mode="average")
    cam = Camera(eye=(2.0, 2.0, -20.0), look_at=(2.0, 2.0, 2.0), up=(0, 1, 0), parallel_scale=1.5)
    img = render(Scene(camera=cam, size=(4, 4), volumes=[vis]), method).image
    assert (img == 0.0).all(), img


def test_an_average_rounded_past_the_range_stays_within_it():
    # Samples at the minimum may interpolate an ulp below it (`INTERP_ROUNDING`), and at the
    # maximum an ulp above: the grey level stays in [0, 1] all the same.
    from raycast.composite import N_PARAMS, P_HI, P_LO, average_grey
    params = np.zeros(N_PARAMS)
    params[P_LO], params[P_HI] = 2.0, 6.0
    assert average_grey(8.0, 4, params) == 0.5
    assert average_grey(-1e-15, 4, params) == 0.0
    assert average_grey(16.0 + 1e-14, 4, params) == 1.0


def test_shaded_samples_keep_colour_within_opacity():
    """Specular light passes 1: clamped per sample, a shaded composite stays premultiplied in [0, 1]."""
    data = np.broadcast_to(np.arange(9, dtype=np.float32)[:, None, None] * 10, (9, 9, 9)).copy()
    tf = TransferFunction(opacity=[[0, 0.05], [80, 0.05]])
    cam = Camera(eye=(4, 4, -40), look_at=(4, 4, 4), up=(0, 1, 0), parallel_scale=5.0)
    for background in (None, (1, 1, 1)):
        img = render(Scene(camera=cam, size=(9, 9), volumes=[Translucent(Volume(data), tf, shade=True)],
                           background=background)).image
        assert img[4, 4, 3] > 0.5 and (img[..., :3] <= img[..., 3:] + 1e-6).all() and img.max() <= 1.0


@pytest.mark.parametrize("ramp", [0.0, 1e-9])
def test_a_flat_region_is_shaded_as_facing_the_viewer(ramp):
    # No gradient, no normal: the sample faces the viewer, as a flat isosurface cell does, so a
    # constant volume and one rising a hair towards the eye look the same (they were 0.35 and 0.54
    # apart: the flat one lost its highlight). Headlight on a facing normal: ambient + diffuse
    # times the colour, plus the specular, per sample, clamped to 1.
    z = np.arange(6, dtype=np.float64)[:, None, None]
    data = np.broadcast_to(0.5 - ramp * z, (6, 6, 6)).astype(np.float64)
    tf = TransferFunction(opacity=[[0, 0.4], [1, 0.4]], color=[[0, 0.3, 0.2, 0.1], [1, 0.3, 0.2, 0.1]])
    material = (0.2, 0.5, 0.25, 8.0)
    cam = Camera(eye=(2.5, 2.5, -30), look_at=(2.5, 2.5, 2.5), up=(0, 1, 0), parallel_scale=2.0)
    img = render(Scene(camera=cam, size=(4, 4), volumes=[Translucent(Volume(data), tf, shade=True,
                                                                       material=material)])).image
    alpha = img[1, 1, 3]
    colour = np.minimum(np.array([0.3, 0.2, 0.1]) * (0.2 + 0.5) + 0.25, 1.0)
    assert alpha > 0.9
    np.testing.assert_allclose(img[1, 1, :3], colour * alpha, atol=1e-6)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_the_lattice_takes_the_sample_on_the_exit_face(method, request):
    """Rays along x through a 5-sample ramp, step 1: the lattice from the entry face holds 5
    points, the last one on the exit face, where the ramp peaks. Both methods dropping it
    (a strict test at the volume's exit) would still agree with each other."""
    if method == "parc":
        request.getfixturevalue("gl")
    data = np.broadcast_to(np.arange(5, dtype=np.float32) * 10.0, (5, 5, 5)).copy()
    tf = TransferFunction(opacity=[[0, 0.0], [5, 0.0], [40, 1.0]])
    cam = Camera(eye=(-10.0, 2.0, 2.0), look_at=(2.0, 2.0, 2.0), up=(0, 0, 1), parallel_scale=1.5)
    scene = Scene(camera=cam, size=(4, 4), volumes=[Translucent(Volume(data), tf, mode="mip", step=1.0)])
    res = render(scene, method=method, work=True)
    assert (res.image[..., 3] == 1.0).all(), res.image[..., 3]           # the peak's opacity
    np.testing.assert_allclose(res.image[..., :3], np.broadcast_to(tf.color(np.array([40.0]))[0], (4, 4, 3)))
    if method == "brute":
        assert (res.work == 5).all(), res.work


@pytest.mark.parametrize("buffers, supercell", [("depth", None), ("bits", 2), ("depth,bits", 2)])
def test_a_new_transfer_function_on_the_same_volume_is_classified_anew(buffers, supercell, gl):
    """Transfer functions in turn on one Volume, with the same opacity control values and other
    opacities: the skip tables and the bit planes' proxy cached for the first must not serve
    the second (each key must hold the opacities, not only where they change)."""
    vol = blobs(12, seed=5)
    lo, hi = vol.value_range()
    mid = 0.5 * (lo + hi)
    cam = Camera.framing(*vol.bounds, azimuth=30, elevation=25)
    shows_high = TransferFunction(opacity=[[lo, 0.0], [mid, 0.0], [hi, 0.8]])
    shows_low = TransferFunction(opacity=[[lo, 0.8], [mid, 0.0], [hi, 0.0]])
    for tf in (shows_high, shows_low, shows_high):
        scene = Scene(camera=cam, size=(24, 24), volumes=[Translucent(vol, tf, mode="mip")])
        ref = render(scene)
        assert (ref.image[..., 3] > 0).sum() >= 20
        res = render(scene, method="parc", buffers=buffers, supercell=supercell)
        assert np.abs(res.image - ref.image).max() <= 1e-6, (buffers, tf.opacity_points)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_shaded_linear_field_has_the_analytic_headlight_colour(gl, method):
    # A linear field has one gradient n everywhere: every sample gets the same headlight
    # Blinn-Phong colour c_s, and compositing one colour gives rgb = c_s * alpha. (A flat
    # region, the only shaded case checked before, has no gradient: a wrong sign passed.)
    n = np.array([0.48, 0.36, 0.8])
    k, j, i = np.mgrid[0:13, 0:13, 0:13].astype(np.float64)
    data = n[0] * i + n[1] * j + n[2] * k
    c = np.array([0.9, 0.6, 0.3])
    tf = TransferFunction(opacity=[[-100.0, 0.05], [100.0, 0.05]], color=[[0.0, *c]])
    ka, kd, ks, s = 0.2, 0.5, 0.3, 8.0
    d = np.array([-0.3, -0.2, -1.0]) / np.linalg.norm([-0.3, -0.2, -1.0])
    cam = Camera(eye=tuple(np.array([6.0, 6.0, 6.0]) - 50.0 * d), look_at=(6.0, 6.0, 6.0), up=(0, 1, 0),
                 parallel_scale=2.0)
    vis = Translucent(Volume(data), tf, shade=True, material=(ka, kd, ks, s))
    img = render(Scene(camera=cam, size=(6, 6), volumes=[vis]), method).image.astype(np.float64)
    ndv = abs(n @ -d)                       # headlight: l = v = -d, so h = v
    want = np.minimum(c * (ka + kd * ndv) + ks * ndv ** s, 1.0)
    alpha = img[..., 3]
    assert (alpha > 0.3).all()
    np.testing.assert_allclose(img[..., :3], want * alpha[..., None], atol=1e-5, rtol=0)


def test_a_transfer_function_transparent_over_the_data_warns_the_caller():
    # Zero up to above the largest sample, 10: the volume shows nothing.
    vol = Volume(np.linspace(0, 10, 27, dtype=np.float32).reshape(3, 3, 3))
    above = TransferFunction(opacity=[[10.5, 0], [20, 1]])
    with pytest.warns(ShowsNothingWarning, match=r"transparent over the data range \[0, 10\]") as caught:
        fog = Translucent(vol, above)
    assert [w.filename for w in caught] == [__file__]        # the caller's line, not the library's
    assert not render(Scene(camera=Camera.framing(*vol.bounds), size=(8, 8), volumes=[fog])).image[..., 3].any()
    # Non-zero just below the largest sample: it shows, without a word.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Translucent(vol, TransferFunction(opacity=[[9.5, 0], [10, 1]]))


def test_a_ct_preset_on_8_bit_data_says_which_presets_fit():
    # A CT preset (values 400 and up) over uint8 samples shows nothing: the note names the ramps.
    vol = Volume(np.arange(27, dtype=np.uint8).reshape(3, 3, 3) * 9)
    with pytest.warns(ShowsNothingWarning, match=r"greyscale or viridis span any data range"):
        Translucent(vol, "ct_skin")
    # A file's function that is transparent there gets no preset hint.
    with pytest.warns(ShowsNothingWarning) as caught:
        Translucent(vol, TransferFunction(opacity=[[300, 0], [400, 1]]))
    assert "viridis" not in str(caught[0].message)


def _linear_field(n=13):
    """Samples of the linear field 0.48 i + 0.36 j + 0.8 k: one gradient everywhere, so every
    shaded sample under a light with one direction has one colour."""
    k, j, i = np.mgrid[0:n, 0:n, 0:n].astype(np.float64)
    return 0.48 * i + 0.36 * j + 0.8 * k


def _blinn_phong_colour(c, g, v, lights, material):
    """The README's shading of a point with gradient ``g`` seen from ``v`` (unit, towards the
    eye), its colour ``c``, under ``(l, radiance)`` pairs (``l`` unit, towards the light)."""
    ka, kd, ks, s = material
    n = np.asarray(g) / np.linalg.norm(g)
    n = n if n @ v >= 0 else -n                     # two-sided: turned to face the eye
    out = np.asarray(c) * ka
    for l, radiance in lights:
        if n @ l > 0:
            h = (l + v) / np.linalg.norm(l + v)
            out = out + np.asarray(radiance) * (np.asarray(c) * kd * (n @ l) + ks * max(n @ h, 0.0) ** s)
    return np.minimum(out, 1.0)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_shaded_linear_field_has_the_analytic_colour_under_coloured_lights(gl, method):
    # Two directional lights, coloured, one on each side of the field's gradient: only the one
    # the samples face lights them, each channel by its own colour, with no headlight.
    c = np.array([0.9, 0.6, 0.3])
    tf = TransferFunction(opacity=[[-100.0, 0.05], [100.0, 0.05]], color=[[0.0, *c]])
    material = (0.2, 0.5, 0.3, 8.0)
    d = np.array([-0.3, -0.2, -1.0]) / np.linalg.norm([-0.3, -0.2, -1.0])
    cam = Camera(eye=tuple(np.array([6.0, 6.0, 6.0]) - 50.0 * d), look_at=(6.0, 6.0, 6.0), up=(0, 1, 0),
                 parallel_scale=2.0)
    front, back = np.array([0.5, -0.4, -1.0]), np.array([-0.2, 0.9, 1.0])
    lights = [DirectionalLight(tuple(front), color=(1.0, 0.5, 0.25), intensity=0.8),
              DirectionalLight(tuple(back), color=(0.3, 1.0, 1.0))]
    vis = Translucent(Volume(_linear_field()), tf, shade=True, material=material)
    img = render(Scene(camera=cam, size=(6, 6), volumes=[vis], lights=lights), method).image.astype(np.float64)
    g = np.array([0.48, 0.36, 0.8])
    pairs = [(-f / np.linalg.norm(f), np.array(light.radiance)) for f, light in zip((front, back), lights)]
    want = _blinn_phong_colour(c, g, -d, pairs, material)
    alpha = img[..., 3]
    assert (alpha > 0.3).all()
    np.testing.assert_allclose(img[..., :3], want * alpha[..., None], atol=1e-5, rtol=0)
    # The two lights light differently from the headlight, or the check shows nothing.
    head = _blinn_phong_colour(c, g, -d, [(-d, np.ones(3))], material)
    assert np.abs(want - head).min() > 0.05


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("view", ["perspective", "parallel"])
def test_a_light_where_the_headlight_shines_from_lights_as_the_headlight(gl, method, view):
    # The headlight shines along each pixel's ray: from a point light at the eye in a
    # perspective view, from a directional light along the view direction in a parallel one.
    vol = blobs(14, seed=5)
    lo, hi = vol.value_range()
    tf = TransferFunction(opacity=[[lo, 0.0], [hi, 0.7]], color=[[lo, 1.0, 0.5, 0.2], [hi, 0.2, 0.6, 1.0]])
    eye, look = (40.0, -25.0, 30.0), (7.0, 6.0, 7.5)
    if view == "perspective":
        cam = Camera(eye=eye, look_at=look, up=(0, 0, 1), fov=25.0)
        light = PointLight(eye)
    else:
        cam = Camera(eye=eye, look_at=look, up=(0, 0, 1), parallel_scale=9.0)
        light = DirectionalLight(tuple(np.subtract(look, eye)))
    vis = Translucent(vol, tf, shade=True)
    head = render(Scene(camera=cam, size=(20, 16), volumes=[vis]), method).image
    lit = render(Scene(camera=cam, size=(20, 16), volumes=[vis], lights=[light]), method).image
    assert (head[..., 3] > 0.1).sum() > 50
    assert np.abs(lit - head).max() <= 1e-6
    # Another light lights them otherwise.
    aside = render(Scene(camera=cam, size=(20, 16), volumes=[vis], lights=[PointLight((7.0, 40.0, 7.5))]),
                   method).image
    assert np.abs(aside - head).max() > 0.05


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_each_channel_of_a_sample_is_lit_by_that_channel_of_the_light(gl, method):
    # A red light leaves green and blue as no light would: the ambient term alone, which is the
    # headlight with no diffuse or specular term; red as a white light gives it.
    vol = blobs(14, seed=9)
    lo, hi = vol.value_range()
    tf = TransferFunction(opacity=[[lo, 0.0], [hi, 0.7]], color=[[lo, 0.9, 0.8, 0.7], [hi, 0.6, 0.9, 1.0]])
    cam = Camera(eye=(40.0, -25.0, 30.0), look_at=(7.0, 6.0, 7.5), up=(0, 0, 1), fov=25.0)
    at = (-10.0, 30.0, 20.0)

    def image(color=None, material=(0.3, 0.6, 0.4, 10.0)):
        lights = [] if color is None else [PointLight(at, color=color)]
        vis = Translucent(vol, tf, shade=True, material=material)
        return render(Scene(camera=cam, size=(20, 16), volumes=[vis], lights=lights), method).image

    red, white, ambient = image((1.0, 0.0, 0.0)), image((1.0, 1.0, 1.0)), image(None, (0.3, 0.0, 0.0, 10.0))
    assert (red[..., 3] > 0.1).sum() > 50
    np.testing.assert_allclose(red[..., 1:], ambient[..., 1:], atol=1e-6, rtol=0)
    np.testing.assert_allclose(red[..., 0], white[..., 0], atol=1e-6, rtol=0)
    assert np.abs(white[..., 1:] - ambient[..., 1:]).max() > 0.05


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_point_light_lights_each_sample_from_the_sample_s_own_world_point(gl, method):
    # A linear field placed off the origin with unequal spacings: every sample has one gradient,
    # but the direction to a point light inside the box (and to one on a face) changes from
    # sample to sample. Samples lie every step from where each ray enters the box, at world
    # points found here from the ray alone, and are composited front to back.
    from parc.transfer import reference_step
    org, spc, n = np.array([-3.2, 5.1, 2.4]), np.array([0.7, 1.3, 0.9]), np.array([6, 5, 7])
    g = np.array([0.8, -0.5, 1.1])
    k, j, i = np.mgrid[0:n[2], 0:n[1], 0:n[0]].astype(np.float64)
    data = g[0] * (org[0] + i * spc[0]) + g[1] * (org[1] + j * spc[1]) + g[2] * (org[2] + k * spc[2])
    lo, hi = org, org + spc * (n - 1)
    mid = (lo + hi) / 2
    c, alpha, step, material = np.array([0.9, 0.6, 0.3]), 0.12, 0.37, (0.15, 0.55, 0.4, 12.0)
    tf = TransferFunction(opacity=[[-100.0, alpha], [100.0, alpha]], color=[[0.0, *c]])
    vis = Translucent(Volume(data, spacing=tuple(spc), origin=tuple(org)), tf, shade=True, material=material,
                      step=step, threshold=1.0)
    lights = [PointLight(tuple(mid + [0.4, -0.3, 0.2]), color=(1.0, 0.5, 0.2)),
              PointLight((lo[0], mid[1], mid[2]), color=(0.3, 1.0, 0.6), intensity=0.7)]
    cam = Camera(eye=tuple(mid + 25.0 * np.array([-0.2, 0.5, 0.8])), look_at=tuple(mid), up=(0, 1, 0), fov=15.0)
    img = render(Scene(camera=cam, size=(7, 6), volumes=[vis], lights=lights), method).image.astype(np.float64)

    a = 1.0 - (1.0 - alpha) ** (step / reference_step(spc))
    want = np.zeros_like(img)
    ambient = np.zeros_like(img)
    origins, directions = cam.rays(7, 6)
    for y, x in np.ndindex(6, 7):
        o, d = origins[y, x], directions[y, x]
        with np.errstate(divide="ignore"):
            t0, t1 = (lo - o) / d, (hi - o) / d
        t_in, t_out = max(0.0, np.minimum(t0, t1).max()), np.maximum(t0, t1).min()
        for out, lit in ((want, True), (ambient, False)):
            for m in range(int(np.floor((t_out - t_in) / step)) + 1 if t_in <= t_out else 0):
                p = o + (t_in + m * step) * d
                pairs = [((np.array(light.position) - p) / np.linalg.norm(np.array(light.position) - p),
                          np.array(light.radiance)) for light in lights] if lit else []
                out[y, x, :3] += (1.0 - out[y, x, 3]) * a * _blinn_phong_colour(c, g, -d, pairs, material)
                out[y, x, 3] += (1.0 - out[y, x, 3]) * a
    assert (want[..., 3] > 0.5).sum() >= 10
    np.testing.assert_allclose(img, want, atol=1e-6, rtol=0)
    assert np.abs(want - ambient).max() > 0.3
