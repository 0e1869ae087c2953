"""Shadows on translucent samples against answers worked out by hand.

A slab of constant value fills z in [10, 20] of a 21 x 21 x 40 grid and is seen straight down
(parallel) over x, y in [7, 13]. Its transfer function is a jump to opacity ``A`` at 99.5 (the
slab's value is 100, 0 outside it) in one colour ``C``, sampled every 0.4 from the top face
(z = 39), so a camera ray takes 25 samples in the slab, at z = 19.8, 19.4, ... 10.2, none within
0.2 of its faces. Inside the slab the data are flat, so each sample's normal faces the eye (+z).

A sample's shadow ray starts at the sample and takes its lattice points a step along (0.4, 0.8,
...), so under a sun straight overhead sample ``s`` (counted from the top) has exactly ``s`` slab
samples between it and the light: its light is ``T_s = (1 - a) ** s``, ``a`` the opacity corrected
for the step. Lit as a surface is (ambient ``ka``, diffuse ``kd``, specular ``ks``, n.l = n.h = 1),
its colour is ``min(1, C (ka + T_s kd) + T_s ks)``, composited with weight ``(1 - a) ** s a``.
"""
import dataclasses

import numpy as np
import pytest

from data_tools import Volume
from parc import Camera, DirectionalLight, Isosurface, PointLight, Scene, TransferFunction, Translucent, render

SIZE = (6, 6)
A = 0.05
STEP = 0.4
C = np.array([0.9, 0.6, 0.3])
MATERIAL = (0.2, 0.6, 0.3, 8.0)
CAM = Camera(eye=(10.0, 10.0, 100.0), look_at=(10.0, 10.0, 0.0), up=(0, 1, 0), parallel_scale=3.0)
SAMPLES = 25                    # z = 19.8 - 0.4 s, s = 0 .. 24
METHODS = ["brute", "parc", "parc:4"]


def _slab():
    data = np.zeros((40, 21, 21), np.uint8)
    data[10:21] = 100
    tf = TransferFunction([[99.5, 0.0], [99.5, A]], [[0.0, *C]])
    return Translucent(Volume(data, name="slab"), tf, step=STEP, shade=True, material=MATERIAL)


def _wall():
    """An opaque wall across x = 29.5 (isovalue 0.5 between a plane of zeros and ones), far out of
    the camera's view, standing in the way of every shadow ray towards a sun up and to the right."""
    data = np.zeros((81, 31, 6), np.float32)
    data[:, :, 1:5] = 1.0
    return Isosurface(Volume(data, origin=(29.0, -5.0, -20.0), name="wall"), 0.5)


def _render(volumes, lights, method, shadows=True, **kw):
    method, _, pixels = method.partition(":")
    scene = Scene(camera=CAM, size=SIZE, volumes=volumes, lights=lights, shadows=shadows)
    return render(scene, method, light_buffer=int(pixels) if pixels else None, **kw)


def _a():
    """The opacity of one sample: ``A`` at the reference step (a quarter of the spacing), for ``STEP``."""
    return 1.0 - (1.0 - A) ** (STEP / 0.25)


def _expected(light_of):
    """Premultiplied RGBA of a pixel whose sample ``s`` gets ``light_of(s)`` of the sun."""
    a = _a()
    rgb = np.zeros(3)
    ka, kd, ks, _ = MATERIAL
    for s in range(SAMPLES):
        t = light_of(s)
        rgb += (1.0 - a) ** s * a * np.minimum(1.0, C * (ka + t * kd) + t * ks)
    return np.append(rgb, 1.0 - (1.0 - a) ** SAMPLES)


@pytest.mark.parametrize("method", METHODS)
def test_a_slab_under_a_sun_overhead_shadows_each_sample_by_the_samples_above_it(gl, method):
    res = _render([_slab()], [DirectionalLight((0.0, 0.0, -1.0))], method)
    want = _expected(lambda s: (1.0 - _a()) ** s)
    assert np.abs(res.image - want).max() <= 1e-6
    unshadowed = _render([_slab()], [DirectionalLight((0.0, 0.0, -1.0))], method, shadows=False).image
    assert np.abs(unshadowed - _expected(lambda s: 1.0)).max() <= 1e-6
    # One shadow ray for each sample that adds colour, towards the one light, which faces them all.
    assert res.stats["shadow_rays"] == SIZE[0] * SIZE[1] * SAMPLES


@pytest.mark.parametrize("method", METHODS)
def test_the_work_map_of_shadowed_samples_counts_the_camera_rays_samples(gl, method):
    # A camera ray crosses z = 39 .. 0: lattice points z = 39 - 0.4 n, n = 0 .. 97, all taken
    # by brute (the slab's 25 samples leave the opacity below the stopping threshold); PARC
    # takes the slab's at least.
    res = _render([_slab()], [DirectionalLight((0.0, 0.0, -1.0))], method, work=True)
    assert res.work.shape == SIZE[::-1] and res.work.sum() == res.stats["samples"]
    if method == "brute":
        assert (res.work == 98).all(), res.work
    else:
        assert ((res.work >= SAMPLES) & (res.work < 98)).all(), res.work


@pytest.mark.parametrize("method", METHODS)
def test_a_wall_between_the_sun_and_the_slab_leaves_its_samples_the_ambient_light(gl, method):
    sun = [DirectionalLight((-1.0, 0.0, -1.0))]
    walled = _render([_slab(), _wall()], sun, method).image
    assert np.abs(walled - _expected(lambda s: 0.0)).max() <= 1e-6
    # Without the wall the sun reaches the top samples at least (n.l = 0.71).
    assert (_render([_slab()], sun, method).image[..., :3] > walled[..., :3] + 0.01).all()


def _fog(step, opacity):
    """A layer of uniform black fog over z in [20.5, 21.5], wider than the view, just above the slab."""
    data = np.full((2, 31, 31), 50, np.uint8)
    tf = TransferFunction([[0.0, opacity], [255.0, opacity]], [[0.0, 0.0, 0.0, 0.0]])
    return Translucent(Volume(data, origin=(-5.0, -5.0, 20.5), name="fog"), tf, step=step)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("fog_step", [0.25, 2.0])
def test_a_fog_layer_above_the_slab_dims_the_sun_on_every_sample_alike(gl, method, fog_step):
    # The whole layer lies between the sun overhead and every sample, so each gets its ``T_s``
    # times the layer's ``T_f``: ``n`` lattice points from where a ray enters the layer, as the
    # camera's ray takes them too. A step longer than the gap above the top samples must not
    # carry their shadow rays past the layer (the step skipped is the sample's own volume's).
    n = int(1.0 / fog_step) + 1
    t_f = (1.0 - 0.05) ** (fog_step / 0.25 * n)
    res = _render([_slab(), _fog(fog_step, 0.05)], [DirectionalLight((0.0, 0.0, -1.0))], method)
    want = _expected(lambda s: (1.0 - _a()) ** s * t_f)
    want = np.append(t_f * want[:3], 1.0 - t_f * (1.0 - want[3]))
    assert np.abs(res.image - want).max() <= 1e-6


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_samples_lit_a_few_rows_at_a_time_are_those_lit_at_once(gl, method, monkeypatch):
    import parc.multivolume as mv
    sun = [DirectionalLight((-1.0, 0.3, -1.0))]
    at_once = []
    whole = _render([_slab(), _wall()], sun, method, progress=at_once.append).image
    monkeypatch.setattr(mv, "SAMPLES_AT_ONCE", 2 * SIZE[0] * SAMPLES)      # two rows a band
    seen = []
    parts = _render([_slab(), _wall()], sun, method, progress=seen.append).image
    assert np.array_equal(whole, parts)
    assert seen == sorted(seen) and seen[-1] == 1.0
    # The bar moves on as each of the three bands is lit, not only once all are.
    start = mv._Report(None, 0, 2, True, True).spans["sample shadows"][0]
    assert len([f for f in seen if f > start]) >= len([f for f in at_once if f > start]) + 2


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_progress_rises_through_the_shadow_rays_and_ends_once(gl, method, monkeypatch):
    # The shadow rays, most of such a frame, sent no report until the end, which came twice.
    import parc.multivolume as mv
    sun = [DirectionalLight((-1.0, 0.3, -1.0))]
    whole = _render([_slab(), _wall()], sun, method).image
    monkeypatch.setattr(mv, "SHADOW_RUN", 8)
    seen = []
    parts = _render([_slab(), _wall()], sun, method, progress=seen.append).image
    assert np.array_equal(whole, parts)                     # the rays cast in runs are the same rays
    assert all(a < b for a, b in zip(seen, seen[1:])) and seen[-1] == 1.0
    start = mv._Report(None, 0, 2, True, True).spans["sample shadows"][0]
    assert len([f for f in seen if f > start]) >= 8          # runs of shadow rays report as they go


def test_sample_bands_hold_at_most_so_many_samples_unless_one_row_holds_more():
    from parc.multivolume import _sample_bands
    assert _sample_bands(np.array([3, 3, 3, 3]), 6) == [(0, 2), (2, 4)]
    assert _sample_bands(np.array([3, 9, 0, 2, 5]), 6) == [(0, 1), (1, 2), (2, 4), (4, 5)]
    assert _sample_bands(np.array([0, 0, 0]), 6) == [(0, 3)]
    assert _sample_bands(np.array([9, 1]), 6) == [(0, 1), (1, 2)]


def _expected_lit(volumes, light):
    """Premultiplied RGBA of a pixel whose ray meets the slabs ``volumes`` (samples, colour,
    material), one below the other, under a sun of colour ``light`` overhead: each sample is
    shadowed by every sample above it, its own slab's and those of the slabs above."""
    a = _a()
    rgb = np.zeros(3)
    s = 0
    for samples, color, (ka, kd, ks, _) in volumes:
        for _ in range(samples):
            t = (1.0 - a) ** s
            rgb += (1.0 - a) ** s * a * np.minimum(1.0, color * ka + t * np.asarray(light) * (color * kd + ks))
            s += 1
    return np.append(rgb, 1.0 - (1.0 - a) ** s)


def _lower(color, material, shade=True):
    """A second volume on the slab's grid holding a thinner slab below it, z in [2, 8]: 15 samples
    (z = 7.8 ... 2.2), whose shadow rays take all 25 of the slab's on their way up."""
    data = np.zeros((40, 21, 21), np.uint8)
    data[2:9] = 100
    tf = TransferFunction([[99.5, 0.0], [99.5, A]], [[0.0, *color]])
    return Translucent(Volume(data, name="lower"), tf, step=STEP, shade=shade, material=material)


@pytest.mark.parametrize("method", METHODS)
def test_two_slabs_one_over_the_other_each_lit_in_its_own_colour_and_material_by_a_coloured_sun(gl, method):
    # Recorded pixel by pixel, the samples come from one volume, then the other, and again: each
    # must keep its own volume's colour and material.
    color, material = np.array([0.2, 0.5, 0.8]), (0.1, 0.5, 0.6, 20.0)
    light = (1.0, 0.5, 0.25)
    res = _render([_slab(), _lower(color, material)], [DirectionalLight((0.0, 0.0, -1.0), color=light)], method)
    want = _expected_lit([(SAMPLES, C, MATERIAL), (15, color, material)], light)
    assert np.abs(res.image - want).max() <= 1e-6
    assert res.stats["shadow_rays"] == SIZE[0] * SIZE[1] * (SAMPLES + 15)


@pytest.mark.parametrize("method", METHODS)
def test_an_unshaded_slab_below_a_shaded_one_keeps_its_own_colour_unlit(gl, method):
    color = np.array([0.2, 0.5, 0.8])
    res = _render([_slab(), _lower(color, MATERIAL, shade=False)], [DirectionalLight((0.0, 0.0, -1.0))], method)
    a = _a()
    want = _expected_lit([(SAMPLES, C, MATERIAL)], (1.0, 1.0, 1.0))
    want[:3] += sum((1.0 - a) ** (SAMPLES + r) * a for r in range(15)) * color
    want[3] = 1.0 - (1.0 - a) ** (SAMPLES + 15)
    assert np.abs(res.image - want).max() <= 1e-6
    assert res.stats["shadow_rays"] == SIZE[0] * SIZE[1] * SAMPLES


@pytest.mark.parametrize("method", METHODS)
def test_a_sun_behind_the_samples_leaves_them_the_ambient_light_and_casts_no_shadow_ray(gl, method):
    # Their normals face the eye (+z), away from a sun shining up from below.
    res = _render([_slab()], [DirectionalLight((0.0, 0.0, 1.0))], method)
    assert np.abs(res.image - _expected(lambda s: 0.0)).max() <= 1e-6
    assert res.stats["shadow_rays"] == 0


@pytest.mark.parametrize("method", METHODS)
def test_a_lamp_inside_the_slab_shadows_each_sample_by_the_lattice_points_short_of_it(gl, method):
    # A sample's shadow ray takes the points a step, two steps ... along it, all in the slab, up to
    # the lamp and none beyond: ceil(d / step) - 1 of them at a distance d. The samples above the
    # lamp face away from it. No specular term: n.h needs no working out.
    lamp = np.array([10.0, 10.0, 15.1])
    material = (0.2, 0.6, 0.0, 8.0)
    res = _render([dataclasses.replace(_slab(), material=material)], [PointLight(tuple(lamp))], method)
    a = _a()
    ka, kd, _, _ = material
    offsets = np.arange(SIZE[0]) + 0.5 - SIZE[0] / 2       # pixel centres about the lamp, either way
    want = np.zeros(SIZE + (4,))
    for r, dy in enumerate(offsets):
        for c, dx in enumerate(offsets):
            for s in range(SAMPLES):
                up = lamp[2] - (19.8 - STEP * s)
                lit = 0.0
                if up > 0.0:
                    d = np.sqrt(dx * dx + dy * dy + up * up)
                    lit = (1.0 - a) ** (np.ceil(d / STEP) - 1) * kd * up / d
                want[r, c, :3] += (1.0 - a) ** s * a * np.minimum(1.0, C * (ka + lit))
    want[..., 3] = 1.0 - (1.0 - a) ** SAMPLES
    assert np.abs(res.image - want).max() <= 1e-6


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_sheet_on_a_grid_of_unequal_spacings_is_lit_from_each_samples_own_point(method):
    # A thin sheet (field = world z, opacity only near 5) in a volume of spacing (1, 2, 1),
    # seen straight down, under a point lamp above, shadows on. Each ray takes one sample, at
    # z = 5 (lattice from the top face, step 0.25), of opacity 0.5, whose shadow ray leaves the
    # sheet at once: rgb = 0.5 (0.2 + 0.8 l_z), with l from the sample's own point to the lamp.
    # A recorded sample placed with x's spacing along y passed every other test.
    cam = Camera(eye=(10.0, 10.0, 100.0), look_at=(10.0, 10.0, 0.0), up=(0, 1, 0), parallel_scale=3.0)
    z = np.arange(11, dtype=np.float64)[:, None, None]
    vol = Volume(np.broadcast_to(z, (11, 11, 21)).copy(), spacing=(1.0, 2.0, 1.0))
    tf = TransferFunction(opacity=[[4.95, 0.0], [5.0, 0.5], [5.05, 0.0]], color=[[0.0, 1.0, 1.0, 1.0]])
    sheet = Translucent(vol, tf, shade=True, material=(0.2, 0.8, 0.0, 1.0), step=0.25, threshold=1.0)
    lamp = PointLight((10.0, 4.0, 9.0))
    o, d = cam.rays(6, 6)
    p = o + ((5.0 - o[..., 2]) / d[..., 2])[..., None] * d
    v = np.asarray(lamp.position) - p
    want = 0.5 * (0.2 + 0.8 * v[..., 2] / np.linalg.norm(v, axis=-1))
    img = render(Scene(camera=cam, size=(6, 6), volumes=[sheet], lights=[lamp], shadows=True), method).image
    np.testing.assert_allclose(img[..., 3], 0.5, atol=1e-6)
    np.testing.assert_allclose(img[..., 0], want, atol=2e-6)
