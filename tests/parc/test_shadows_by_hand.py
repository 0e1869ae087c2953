"""Shadow rays against answers worked out by hand: a white floor (z = 5.5) seen straight down
over x in [7, 13], y in [2, 8], lit by lights whose shadow rays cross occluders standing out of
the camera's view. Each floor pixel is ``0.2 + sum_l T_l c_l (0.8 n.l_l)`` (ambient 0.2, diffuse
0.8, no specular), with ``T_l`` the light's transmittance: 0 behind an opaque surface, and behind
a fog of constant opacity ``a`` (at the reference step) sampled ``N`` times at ``step``,
``(1 - a) ** (N step / reference step)``, ``N`` the lattice points ``t_in + n step`` of the
shadow ray inside the fog's box (anchored where the ray enters it, or at its start inside it),
short of a point light.
"""
import math

import numpy as np
import pytest

from data_tools import Volume
from parc import Camera, DirectionalLight, Isosurface, PointLight, Scene, TransferFunction, Translucent, render

SIZE = (6, 6)
A = 0.15                    # the fogs' opacity at the reference step
CAM = Camera(eye=(10.0, 5.0, 100.0), look_at=(10.0, 5.0, 0.0), up=(0, 1, 0), parallel_scale=3.0)
FLOOR_Z = 5.5


def _floor(material=(0.2, 0.8, 0.0, 1.0)):
    z = np.arange(11, dtype=np.float32)[:, None, None]
    return Isosurface(Volume(np.broadcast_to(FLOOR_Z - z, (11, 11, 21)).copy(), name="floor"), 0.0,
                      color=(1.0, 1.0, 1.0), material=material)


def _floor_points():
    """The floor point each pixel sees: the camera's rays (parallel, straight down) at z = 5.5."""
    o, d = CAM.rays(*SIZE)
    return o + ((FLOOR_Z - o[..., 2]) / d[..., 2])[..., None] * d


def _fog(x0, x1, *, spacing=1.0, step=None, z1=80.0, mode="composite"):
    """A fog of constant opacity `A` filling x in [x0, x1], y in [-5, 15], z in [0, z1]."""
    nx = int(round((x1 - x0) / spacing)) + 1
    data = np.full((int(z1) + 1, 21, nx), 100, np.uint8)
    tf = TransferFunction([[0, A], [255, A]])
    return Translucent(Volume(data, spacing=(spacing, 1.0, 1.0), origin=(x0, -5.0, 0.0), name="fog"), tf,
                       mode=mode, step=step)


def _wall(x0, x1, *, iso=0.5, face_hit=False):
    """An opaque wall over x in [x0, x1] (whole cells), y in [-5, 15], z in [0, 80]: data 1 inside,
    0 on a plane of samples either side; with ``face_hit`` the isovalue is 1, so its surface lies
    exactly on the sample planes x0 and x1 (a root at a cell face)."""
    n = int(round(x1 - x0)) + 1
    d = np.zeros((81, 21, n + 2), np.float32)
    d[:, :, 1:n + 1] = 1.0
    return Isosurface(Volume(d, origin=(x0 - 1.0, -5.0, 0.0), name="wall"), 1.0 if face_hit else iso)


def _render(volumes, lights, method, floor=None):
    """The floor pixels' colours; ``method`` "parc:N" is PARC with light buffers of N pixels (few
    enough that a shadow ray's crossing lies well off their centres, and their merging decides)."""
    method, _, pixels = method.partition(":")
    scene = Scene(camera=CAM, size=SIZE, volumes=[floor or _floor(), *volumes], lights=lights, shadows=True)
    res = render(scene, method, light_buffer=int(pixels) if pixels else None)
    assert (res.image[..., 3] == 1.0).all()
    return res.image[..., :3].astype(np.float64)


def _diffuse(l):
    """0.8 n.l of a floor point for a unit direction ``l`` towards the light (n = +z)."""
    return 0.8 * l[..., 2]


def _towards(light, p):
    """Unit direction from floor points ``p`` towards ``light``, and the distance (inf for a sun)."""
    if isinstance(light, DirectionalLight):
        l = -np.asarray(light.direction, float) / np.linalg.norm(light.direction)
        return np.broadcast_to(l, p.shape), np.full(p.shape[:-1], np.inf)
    v = np.asarray(light.position, float) - p
    d = np.linalg.norm(v, axis=-1)
    return v / d[..., None], d


def _lattice_count(length, step):
    """Lattice points ``n step`` (n >= 0) strictly before ``length``; asserts no point lies within
    1% of a step of the end, where rounding would decide."""
    q = length / step
    assert np.all(np.abs(q - np.round(q)) > 0.01), "a lattice point at the end: move the geometry"
    return np.ceil(q).astype(int)


METHODS = ["brute", "parc", "parc:3"]
SUN = DirectionalLight((-1.0, 0.0, -1.0))            # from +x, 45 degrees up
ROOT2 = math.sqrt(2.0)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("spacing, step, samples", [
    (1.0, None, 12),            # path 2 sqrt 2 = 2.83 in the fog, step 0.25: 12 samples, 12 reference steps
    (1.0, 0.4, 8),              # step 0.4: 8 samples of 1.6 reference steps, 12.8 in all
    (0.5, None, 23),            # spacing 0.5 along x: reference step 0.125, 23 samples
])
def test_a_fog_between_the_sun_and_the_floor_lets_through_its_closed_form_transmittance(gl, method, spacing,
                                                                                        step, samples):
    # Every shadow ray runs along (1, 0, 1)/sqrt 2 and crosses the fog's x in [25, 27] over
    # 2 sqrt 2 (far from the fog's top and sides): N = floor(2 sqrt 2 / step) + 1 lattice points,
    # each of opacity 1 - (1 - A) ** (step / reference step).
    fog = _fog(25.0, 27.0, spacing=spacing, step=step)
    ref = 0.25 * spacing
    st = fog.step
    assert samples == math.floor(2 * ROOT2 / st) + 1
    t = (1.0 - A) ** (samples * st / ref)
    want = 0.2 + t * 0.8 / ROOT2
    np.testing.assert_allclose(_render([fog], [SUN], method), want, atol=2e-6, rtol=0)


@pytest.mark.parametrize("method", METHODS)
def test_a_mip_fog_lets_through_one_minus_its_largest_samples_opacity(gl, method):
    # MIP: a = the transfer function's opacity at the largest sample, uncorrected for the step.
    fog = _fog(25.0, 27.0, mode="mip")
    np.testing.assert_allclose(_render([fog], [SUN], method), 0.2 + (1.0 - A) * 0.8 / ROOT2, atol=2e-6, rtol=0)


@pytest.mark.parametrize("method", METHODS)
def test_a_point_light_inside_a_fog_is_dimmed_only_by_the_fog_before_it(gl, method):
    # The light stands 0.6 inside a fog over x in [25, 40], off its planes of samples (so the
    # fog's cell around it reaches past it): each shadow ray takes the lattice points from its
    # entry at x = 25 up to the light, none of the fog beyond it.
    lamp = PointLight((25.6, 8.6, 30.45))
    p = _floor_points()
    l, dist = _towards(lamp, p)
    inside = dist * 0.6 / (lamp.position[0] - p[..., 0])          # the shadow ray's length in the fog
    t = (1.0 - A) ** _lattice_count(inside, 0.25)
    assert len(np.unique(t)) > 1
    want = 0.2 + t * _diffuse(l)
    img = _render([_fog(25.0, 40.0)], [lamp], method)
    np.testing.assert_allclose(img, np.repeat(want[..., None], 3, -1), atol=2e-6, rtol=0)


@pytest.mark.parametrize("method", METHODS)
def test_nothing_beyond_a_point_light_shadows_it(gl, method):
    # The light at x = 24.2, just before an opaque wall (its surface at x = 24.5, or at 25 on
    # the sample plane) or a fog from x = 25: the shadow rays stop at the light, and the floor
    # is lit as if nothing stood there.
    lamp = PointLight((24.2, 5.0, 9.0))
    l, _ = _towards(lamp, _floor_points())
    want = np.repeat((0.2 + _diffuse(l))[..., None], 3, -1)
    for occluders in ([_wall(25.0, 27.0)], [_fog(25.0, 27.0)], [_wall(25.0, 27.0, face_hit=True)]):
        np.testing.assert_allclose(_render(occluders, [lamp], method), want, atol=2e-6, rtol=0)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("face_hit", [False, True])
def test_an_opaque_wall_before_a_point_light_leaves_only_the_ambient_light(gl, method, face_hit):
    # The light at x = 30 behind a wall over x in [25, 27] (its surface half a cell outside, or,
    # with face_hit, exactly on the sample planes x = 25 and 27): every shadow ray meets it.
    lamp = PointLight((30.0, 5.0, 9.0))
    np.testing.assert_allclose(_render([_wall(25.0, 27.0, face_hit=face_hit)], [lamp], method), 0.2,
                               atol=1e-6, rtol=0)


@pytest.mark.parametrize("method", METHODS)
def test_each_light_takes_its_own_shadow_scaled_by_its_colour_and_intensity(gl, method):
    # The sun from +x crosses the fog (12 samples), a red-ish point light from -x crosses nothing:
    # each channel is 0.2 + sum over lights of radiance x transmittance x 0.8 n.l.
    sun = DirectionalLight((-1.0, 0.0, -1.0), color=(1.0, 0.5, 0.25), intensity=0.6)
    lamp = PointLight((-6.0, 4.0, 12.0), color=(0.25, 1.0, 0.5), intensity=0.7)
    p = _floor_points()
    l2, _ = _towards(lamp, p)
    t1 = (1.0 - A) ** 12
    want = (0.2 + t1 * 0.6 * np.array([1.0, 0.5, 0.25]) * 0.8 / ROOT2
            + 0.7 * np.array([0.25, 1.0, 0.5]) * _diffuse(l2)[..., None])
    for lights in ([sun, lamp], [lamp, sun]):
        np.testing.assert_allclose(_render([_fog(25.0, 27.0)], lights, method), want, atol=2e-6, rtol=0)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("light", [DirectionalLight((-0.3, -0.2, -1.0)), DirectionalLight((1e-3, 0.0, -1.0)),
                                   PointLight((11.3, 4.1, 30.0)), PointLight((10.0, 5.0, 5.5 + 1e-3))])
def test_a_lit_plane_does_not_shadow_itself(gl, method, light):
    # Nothing but the floor: every shadow ray leaves its own surface, so the floor shows the full
    # diffuse light (a ray started on the surface may find it again at t = 0: acne).
    l, _ = _towards(light, _floor_points())
    want = np.repeat((0.2 + _diffuse(l))[..., None], 3, -1)
    np.testing.assert_allclose(_render([], [light], method), np.minimum(want, 1.0), atol=2e-6, rtol=0)


@pytest.mark.parametrize("method", METHODS)
def test_a_highlight_without_a_diffuse_term_is_lit_and_shadowed(gl, method):
    # A material with diffuse 0 and specular 0.5 under the sun from +x: 0.2 + 0.5 (n.h)^4 in the
    # open, 0.2 behind a wall. (A light that faces the surface is told by either term > 0: by the
    # diffuse term alone, such a surface would lose its highlight.)
    floor = _floor((0.2, 0.0, 0.5, 4.0))
    h = np.array([1.0, 0.0, 1.0 + ROOT2]) / np.linalg.norm([1.0, 0.0, 1.0 + ROOT2])     # (l + v) / |l + v|
    for occluders, want in (([], 0.2 + 0.5 * h[2] ** 4), ([_wall(25.0, 27.0)], 0.2)):
        np.testing.assert_allclose(_render(occluders, [SUN], method, floor), want, atol=2e-6, rtol=0)


@pytest.mark.parametrize("method", METHODS)
def test_a_lamp_standing_on_the_floor_adds_nothing_even_at_the_point_it_stands_on(gl, method):
    # The lamp lies in the floor's plane, so every other floor point sees it at n.l = 0; at the
    # pixel whose hit is the lamp's position, exactly, the direction to it is undefined and the
    # lamp gives neither diffuse light nor a highlight (the limit of its neighbours), while the
    # sun from +x still lights that pixel as every other: 0.2 + 0.8 n.l + 0.2 (n.h)^4 throughout.
    lamp = PointLight((10.5, 5.5, FLOOR_Z))
    p = _floor_points()
    at = np.argwhere((p == lamp.position).all(-1))
    assert len(at) == 1
    floor = _floor((0.2, 0.8, 0.2, 4.0))
    h = np.array([1.0, 0.0, 1.0 + ROOT2]) / np.linalg.norm([1.0, 0.0, 1.0 + ROOT2])
    want = 0.2 + 0.8 / ROOT2 + 0.2 * h[2] ** 4
    o, d = CAM.rays(*SIZE)
    (y, x), = at
    name, _, pixels = method.partition(":")
    for lights in ([lamp, SUN], [SUN, lamp]):
        scene = Scene(camera=CAM, size=SIZE, volumes=[floor], lights=lights, shadows=True)
        res = render(scene, name, light_buffer=int(pixels) if pixels else None)
        np.testing.assert_array_equal(o[y, x] + res.depth[y, x] * d[y, x], lamp.position)
        np.testing.assert_allclose(res.image[..., :3], want, atol=2e-6, rtol=0)
    np.testing.assert_allclose(_render([], [lamp], method, floor), 0.2, atol=2e-6, rtol=0)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_shadow_rays_count_the_lights_facing_each_hit_and_the_cells_they_cross(gl, method):
    # A sun overhead and one from below: only the one overhead faces the floor, so one shadow ray a
    # pixel. Each rises from z = 5.5 through the floor's cells k = 5 .. 9 and solves a cubic in
    # the first only, the one the floor lies in; PARC's walk visits no more cells than that.
    for lights in ([DirectionalLight((0.0, 0.0, -1.0))], [DirectionalLight((0.0, 0.0, 1.0)),
                                                          DirectionalLight((0.0, 0.0, -1.0))]):
        stats = render(Scene(camera=CAM, size=SIZE, volumes=[_floor()], lights=lights, shadows=True), method).stats
        pixels = SIZE[0] * SIZE[1]
        assert stats["shadow_rays"] == pixels and stats["shadow_solves"] == pixels
        if method == "brute":
            assert stats["shadow_cells"] == 5 * pixels
        else:
            assert pixels <= stats["shadow_cells"] <= 5 * pixels
