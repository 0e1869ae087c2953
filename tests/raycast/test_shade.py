"""Blinn-Phong terms (`raycast.shade.blinn_phong`) against the model written out in NumPy.

Truth: diffuse ``kd max(n.l, 0)``, specular ``ks (n.h / |h|)^s`` with the
half vector ``h = l + v``, zero where the light is behind the surface, the
normal turned towards the viewer first (two-sided lighting). Normals: the
gradient over its ``math.hypot`` length; a headlight pixel: the colour times
ambient plus diffuse, plus the highlight, clamped to 1.
"""
import math

import numpy as np
import pytest

from raycast.shade import blinn_phong, headlight_pixel, power, trilinear_gradient, unit_normal

MATERIAL = np.array([0.1, 0.7, 0.5, 8.0])


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def _model(n, v, l, material):
    if n @ v < 0:
        n = -n
    ndl = n @ l
    if ndl <= 0:
        return 0.0, 0.0
    h = _unit(l + v)
    return material[1] * ndl, material[2] * max(n @ h, 0.0) ** material[3]


def test_light_and_eye_along_the_normal_give_full_diffuse_and_specular():
    z = np.array([0.0, 0.0, 1.0])
    assert blinn_phong(*z, *z, *z, MATERIAL) == pytest.approx((0.7, 0.5), rel=1e-15)


def test_the_highlight_lies_halfway_between_light_and_eye():
    # Light and eye mirrored about the normal: the half vector is the normal, a full highlight;
    # turn the normal away from the half vector by 30 degrees and it falls to cos(30)^8.
    v = _unit([1.0, 0.0, 1.0])
    l = _unit([-1.0, 0.0, 1.0])
    diffuse, spec = blinn_phong(0.0, 0.0, 1.0, *v, *l, MATERIAL)
    assert (diffuse, spec) == pytest.approx((0.7 * np.sqrt(0.5), 0.5), rel=1e-14)
    n = _unit([np.sin(np.radians(30)), 0.0, np.cos(np.radians(30))])
    assert blinn_phong(*n, *v, *l, MATERIAL)[1] == pytest.approx(0.5 * np.cos(np.radians(30)) ** 8, rel=1e-13)


def test_a_light_in_the_tangent_plane_gives_no_highlight():
    # n.l = 0 exactly: the light is not in front of the surface, so neither term lights it,
    # though the half vector between that light and the eye still leans towards the normal.
    v = _unit([1.0, 0.0, 1.0])
    assert blinn_phong(0.0, 0.0, 1.0, *v, 1.0, 0.0, 0.0, MATERIAL) == (0.0, 0.0)
    assert blinn_phong(0.0, 0.0, -1.0, *v, 0.0, 1.0, 0.0, MATERIAL) == (0.0, 0.0)


@pytest.mark.parametrize("seed", range(3))
def test_random_directions_match_the_model(seed):
    rng = np.random.default_rng(seed)
    lit = 0
    for _ in range(500):
        n, v, l = (_unit(rng.normal(size=3)) for _ in range(3))
        material = np.array([0.1, rng.uniform(0.2, 1), rng.uniform(0, 1), rng.choice([1.0, 5.0, 32.0, 7.5])])
        want = _model(n, v, l, material)
        lit += want[0] > 0
        assert blinn_phong(*n, *v, *l, material) == pytest.approx(want, rel=1e-12, abs=1e-15)
    assert 100 < lit < 400          # lit and unlit both, from either side


def test_power_is_pow():
    for e in (0.0, 1.0, 2.0, 7.0, 40.0, 1024.0, 2.5, 1025.0):
        for x in (0.0, 0.3, 0.999, 1.0):
            assert power(x, e) == pytest.approx(x ** e, rel=1e-13, abs=1e-300)


@pytest.mark.parametrize("scale", [1.0, 1e-200, 1e-160, 1e150, 1e160, 1e199])
def test_unit_normal_is_the_gradient_over_its_length(scale):
    # math.hypot neither overflows nor underflows, so it is the length at every scale.
    rng = np.random.default_rng(7)
    for _ in range(100):
        g = rng.normal(size=3) * rng.choice([0.01, 1.0, 30.0]) * scale
        want = g / math.hypot(*g)
        np.testing.assert_allclose(unit_normal(*g, 0.0, 0.0, 1.0), want, rtol=1e-15, atol=1e-300)


def test_a_zero_gradient_gives_a_normal_facing_the_viewer():
    d = _unit([0.3, -0.4, 0.8])
    assert unit_normal(0.0, 0.0, 0.0, *d) == tuple(-d)
    assert unit_normal(-0.0, 0.0, -0.0, *d) == tuple(-d)


def test_a_headlight_pixel_is_ambient_and_diffuse_times_the_colour_plus_the_highlight_clamped():
    # A cell of the linear field a.p has the gradient a everywhere (not unit length, on a
    # spacing that is not 1). Headlight: l = v = -d, so h = v and n.l = n.h = |n.v|. The red
    # channel sums past 1 and is clamped; green and blue are not.
    a = np.array([0.6, -1.2, 2.0])
    spc = np.array([0.5, 2.0, 1.5])
    k, j, i = np.mgrid[0:2, 0:2, 0:2].astype(np.float64)
    data = a[0] * i * spc[0] + a[1] * j * spc[1] + a[2] * k * spc[2]
    d = _unit([0.3, -0.2, -1.0])
    color = np.array([0.9, 0.6, 0.2])
    ka, kd, ks, s = material = np.array([0.3, 0.5, 0.8, 1.0])
    ndv = abs(_unit(a) @ -d)
    want = np.minimum(color * (ka + kd * ndv) + ks * ndv ** s, 1.0)
    assert want[0] == 1.0 and want[1] < 1.0
    image = np.zeros((2, 3, 4), np.float32)
    headlight_pixel(data, spc, 0, 0, 0, 0.3, 0.6, 0.2, *d, color, material, image, 1, 2)
    np.testing.assert_allclose(image[1, 2, :3], want, rtol=0, atol=1e-6)
    assert image[1, 2, 3] == 1.0
    image[1, 2] = 0.0
    assert not image.any()


@pytest.mark.parametrize("scale", [1e-200, 1e-160, 1e150, 1e160, 1e199])
def test_a_volume_scaled_by_a_power_of_ten_is_shaded_alike(scale):
    """Normals are directions: float64 samples scaled by 1e160 (their gradient squared past
    float64's range, the normal zero: ambient light alone) or by 1e-200 (squared to 0: a flat
    cell's normal) must light the surface as at scale 1, headlight, lights and shadows, and
    a shaded translucent volume too. (Scaling by a power of ten rounds the samples, so the
    colours agree to a rounding, not bit for bit.)"""
    from data_tools import Volume
    from data_tools.synthetic import make_synthetic
    from parc import Camera, Isosurface, PointLight, Scene, Translucent, TransferFunction, render
    d = make_synthetic("sphere", 12).data.astype(np.float64)
    cam = Camera.framing((0, 0, 0), (11, 11, 11), azimuth=30, elevation=20)
    light = PointLight((30.0, -20.0, 25.0))
    tf = TransferFunction(opacity=[[-3.0, 0.0], [0.0, 0.6], [3.0, 0.0]])
    images = {}
    for s in (1.0, scale):
        vol = Volume(d * s)
        iso = render(Scene(camera=cam, size=(24, 24), volumes=[Isosurface(vol, 0.0)]))
        lit = render(Scene(camera=cam, size=(24, 24), volumes=[Isosurface(vol, 0.0)], lights=[light], shadows=True))
        fog = render(Scene(camera=cam, size=(24, 24),
                           volumes=[Translucent(vol, tf.mapped(-3.0 * s, 3.0 * s, src=(-3.0, 3.0)), shade=True)]))
        images[s] = (iso, lit, fog)
    for ref, got in zip(images[1.0], images[scale]):
        assert np.array_equal(np.isfinite(ref.depth), np.isfinite(got.depth))
        assert np.abs(ref.image - got.image).max() <= 1e-6
    assert np.isfinite(images[1.0][0].depth).sum() > 50


def test_trilinear_gradient_is_the_derivative_of_the_interpolant():
    # Truth: the trilinear interpolant written out as a weighted sum of corners; it is linear in
    # each local coordinate, so a central difference of any width is its partial derivative.
    rng = np.random.default_rng(3)
    data = rng.normal(size=(3, 3, 3))
    spc = np.array([0.7, 1.3, 0.9])

    def f(c, u, v, w):
        return sum(c[z, y, x] * (w if z else 1 - w) * (v if y else 1 - v) * (u if x else 1 - u)
                   for z in (0, 1) for y in (0, 1) for x in (0, 1))

    for _ in range(50):
        i, j, k = (int(a) for a in rng.integers(0, 2, 3))
        u, v, w = rng.uniform(0.0, 1.0, 3)
        c = data[k:k + 2, j:j + 2, i:i + 2]
        want = np.array([(f(c, u + 0.5, v, w) - f(c, u - 0.5, v, w)) / spc[0],
                         (f(c, u, v + 0.5, w) - f(c, u, v - 0.5, w)) / spc[1],
                         (f(c, u, v, w + 0.5) - f(c, u, v, w - 0.5)) / spc[2]])
        np.testing.assert_allclose(trilinear_gradient(data, i, j, k, u, v, w, spc), want, rtol=1e-12, atol=1e-12)
