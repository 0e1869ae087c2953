"""Accumulation and merging against answers worked out by hand (independent of brute)."""
import numpy as np
import pytest

from data_tools import Volume
from parc import Camera, DirectionalLight, Isosurface, PointLight, Scene, TransferFunction, Translucent, render

N = 9
CAM = Camera(eye=(4.0, 4.0, -40.0), look_at=(4.0, 4.0, 4.0), up=(0, 1, 0), parallel_scale=3.0)


def _const(value=100.0, origin=(0.0, 0.0, 0.0), name="fog"):
    return Volume(np.full((N, N, N), value, np.float32), origin=origin, name=name)


def _ramp_z(scale=1.0, origin=(0.0, 0.0, 0.0), name="ramp"):
    z = np.arange(N, dtype=np.float32)[:, None, None] * scale
    return Volume(np.broadcast_to(z, (N, N, N)).copy(), origin=origin, name=name)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_composite_fog_stops_at_a_surface_inside_it(gl, method):
    # Rays along +z from z = 0, samples every 0.25 (the reference step: no correction): the
    # surface z = 4.6 leaves the 19 samples z = 0 .. 4.5 in front of it, and none behind.
    a = 0.1
    fog = Translucent(_const(), TransferFunction([[0, a], [200, a]], [[0, 1.0, 1.0, 1.0]]), threshold=1.0)
    wall = Isosurface(_ramp_z(name="wall"), 4.6)
    surf = render(Scene(camera=CAM, size=(4, 4), volumes=[wall]), method).image.astype(np.float64)
    both = render(Scene(camera=CAM, size=(4, 4), volumes=[fog, wall]), method).image.astype(np.float64)
    alpha = 1.0 - (1.0 - a) ** 19
    assert (surf[..., 3] == 1.0).all()
    np.testing.assert_allclose(both, alpha + (1.0 - alpha) * surf, atol=1e-5, rtol=0)


@pytest.mark.parametrize("mode", ["mip", "average"])
@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_layer_stops_at_a_surface_inside_it(gl, method, mode):
    # A ramp v = 10 z: before the surface z = 4.6 the largest sample is 45 (z = 4.5); the
    # average sums 10 z - 0 over those 19 samples, over all 33 lattice samples and the range 80.
    tf = TransferFunction([[-1, 0.5], [100, 0.5]], [[0, 0.0, 0.0, 0.0], [80, 1.0, 0.5, 0.25]])
    layer = Translucent(_ramp_z(10.0), tf, mode=mode)
    wall = Isosurface(_ramp_z(name="wall"), 4.6)
    surf = render(Scene(camera=CAM, size=(4, 4), volumes=[wall]), method).image.astype(np.float64)
    both = render(Scene(camera=CAM, size=(4, 4), volumes=[layer, wall]), method).image.astype(np.float64)
    if mode == "mip":
        rgba = np.array([*(0.5 * np.array([1.0, 0.5, 0.25]) * 45 / 80), 0.5])
    else:
        grey = sum(10 * 0.25 * n for n in range(19)) / 33 / 80
        rgba = np.full(4, grey)
    np.testing.assert_allclose(both, rgba + (1.0 - rgba[3]) * surf, atol=1e-5, rtol=0)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_three_coincident_composite_volumes_take_tied_samples_in_the_scene_s_order(gl, method):
    # Sample k of the m-th listed has (1 - a) to the power 3k + m in front of it.
    a = 0.1
    rgb = np.eye(3)
    fogs = [Translucent(_const(name=f"fog{m}"), TransferFunction([[0, a], [200, a]], [[0, *rgb[m]]]), threshold=1.0)
            for m in range(3)]
    img = render(Scene(camera=CAM, size=(4, 4), volumes=fogs), method).image.astype(np.float64)
    n = 33                                      # z = 0 .. 8 every 0.25
    for m in range(3):
        np.testing.assert_allclose(img[..., m], sum(a * (1 - a) ** (3 * k + m) for k in range(n)), atol=1e-5)
    np.testing.assert_allclose(img[..., 3], 1 - (1 - a) ** (3 * n), atol=1e-5)


def test_coincident_composite_volumes_take_tied_samples_in_the_scene_s_order():
    # Two volumes sharing one box and lattice: at every depth the first listed goes first.
    a = 0.1
    red = Translucent(_const(name="red"), TransferFunction([[0, a], [200, a]], [[0, 1.0, 0.0, 0.0]]), threshold=1.0)
    blue = Translucent(_const(name="blue"), TransferFunction([[0, a], [200, a]], [[0, 0.0, 0.0, 1.0]]),
                       threshold=1.0)
    img = render(Scene(camera=CAM, size=(4, 4), volumes=[red, blue])).image.astype(np.float64)
    n = 33                                      # z = 0 .. 8 every 0.25
    first = sum(a * (1 - a) ** (2 * k) for k in range(n))
    second = sum(a * (1 - a) ** (2 * k + 1) for k in range(n))
    np.testing.assert_allclose(img[..., 0], first, atol=1e-5)
    np.testing.assert_allclose(img[..., 2], second, atol=1e-5)
    np.testing.assert_allclose(img[..., 3], 1 - (1 - a) ** (2 * n), atol=1e-5)


def test_merged_volumes_are_shaded_each_by_its_own_setting():
    # A shaded and an unshaded composite volume one behind the other: each looks as it does alone.
    k, j, i = np.mgrid[0:N, 0:N, 0:N].astype(np.float32)
    data = 0.48 * i + 0.36 * j + 0.8 * k
    tf = TransferFunction([[-100, 0.05], [100, 0.05]], [[0, 0.9, 0.6, 0.3]])
    near = Translucent(Volume(data, name="near"), tf, shade=False)
    far = Translucent(Volume(data, origin=(0, 0, 20), name="far"), tf, shade=True)
    for vols in ([near, far], [far, near]):
        a, b = (render(Scene(camera=CAM, size=(4, 4), volumes=[v])).image.astype(np.float64) for v in (near, far))
        both = render(Scene(camera=CAM, size=(4, 4), volumes=vols)).image
        np.testing.assert_allclose(both, a + (1.0 - a[..., 3:4]) * b, atol=1e-5, rtol=0)
    # The two differ, or the check shows nothing.
    assert np.abs(a[..., :3] / a[..., 3:] - b[..., :3] / b[..., 3:]).max() > 0.05


def _shaded_pair():
    """Both shaded, one linear field, spacings 1 and 2 along z: the field has one gradient,
    (0.48, 0.36, 0.8) over the spacing, so each volume has one shaded colour under a light
    of one direction, set by its own spacing."""
    k, j, i = np.mgrid[0:N, 0:N, 0:N].astype(np.float32)
    data = 0.48 * i + 0.36 * j + 0.8 * k
    tf = TransferFunction([[-100, 0.05], [100, 0.05]], [[0, 0.9, 0.6, 0.3]])
    near = Translucent(Volume(data, name="near"), tf, shade=True, threshold=1.0)
    far = Translucent(Volume(data, spacing=(1.0, 1.0, 2.0), origin=(0, 0, 20), name="far"), tf, shade=True,
                      threshold=1.0)
    return near, far


#: A point light and a coloured sun.
LIGHTS = [PointLight((30.0, -10.0, -5.0)), DirectionalLight((0.3, 0.2, 1.0), color=(1.0, 0.4, 0.2))]


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("lights", [[], LIGHTS], ids=["headlight", "lights"])
def test_merged_volumes_are_shaded_each_with_its_own_spacing_as_each_is_alone(gl, method, lights):
    # Together, each looks as it does alone: one volume lights its samples in its own walk,
    # several in the merged one.
    near, far = _shaded_pair()

    def image(vols):
        return render(Scene(camera=CAM, size=(4, 4), volumes=vols, lights=lights), method).image.astype(np.float64)

    a, b = image([near]), image([far])
    for vols in ([near, far], [far, near]):
        np.testing.assert_allclose(image(vols), a + (1.0 - a[..., 3:4]) * b, atol=1e-5, rtol=0)
    assert np.abs(a[..., :3] / a[..., 3:] - b[..., :3] / b[..., 3:]).max() > 0.05


def test_the_scene_s_lights_change_merged_shaded_volumes():
    near, far = _shaded_pair()
    head, lit = (render(Scene(camera=CAM, size=(4, 4), volumes=[near, far], lights=lights)).image
                 for lights in ([], LIGHTS))
    assert np.abs(head - lit).max() > 0.05


@pytest.mark.parametrize("order", [0, 1])
def test_a_layer_and_a_composite_volume_seen_from_afar_go_near_over_far(order):
    # From 1e5 units away each ray is anchored at its entry: the layer's depth must still be a
    # world distance, ordered against the other volume's samples (and layers).
    tf = TransferFunction([[0, 0.02], [200, 0.02]], [[0, 1.0, 0.0, 0.0]])
    blue = TransferFunction([[0, 0.3], [200, 0.3]], [[0, 0.0, 0.0, 1.0]])
    cam = Camera(eye=(4.0, 4.0, -1.0e5), look_at=(4.0, 4.0, 4.0), up=(0, 1, 0), parallel_scale=3.0)
    for near_mode in ("composite", "mip"):
        near = Translucent(_const(name="near"), tf, mode=near_mode)
        far = Translucent(_const(origin=(0, 0, 20), name="far"), blue, mode="mip")
        a, b = (render(Scene(camera=cam, size=(4, 4), volumes=[v])).image.astype(np.float64) for v in (near, far))
        vols = [near, far] if order == 0 else [far, near]
        both = render(Scene(camera=cam, size=(4, 4), volumes=vols)).image
        assert a[..., 3].min() > 0.01 and a[..., 3].max() < 0.99
        np.testing.assert_allclose(both, a + (1.0 - a[..., 3:4]) * b, atol=1e-5, rtol=0)


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("view", ["parallel", "perspective"])
def test_an_eye_inside_a_fog_takes_the_samples_from_the_eye_to_the_exit(gl, method, view):
    # Eye at z = 2.1 inside a constant fog, looking along +z: the lattice starts at the eye
    # (t = 0) and takes floor(t_out / step) + 1 samples, none behind the eye.
    a = 0.05
    fog = Translucent(_const(), TransferFunction([[0, a], [200, a]], [[0, 1.0, 1.0, 1.0]]), threshold=1.0)
    kw = dict(parallel_scale=2.0) if view == "parallel" else dict(fov=30.0)
    cam = Camera(eye=(4.1, 3.9, 2.1), look_at=(4.1, 3.9, 8.0), up=(0, 1, 0), **kw)
    img = render(Scene(camera=cam, size=(5, 5), volumes=[fog]), method).image.astype(np.float64)
    o, d = cam.rays(5, 5)
    with np.errstate(divide="ignore"):
        t_out = np.min(np.where(d > 0, (8.0 - o) / d, np.where(d < 0, (0.0 - o) / d, np.inf)), axis=-1)
    n = np.floor(t_out / 0.25) + 1
    np.testing.assert_allclose(img[..., 3], 1 - (1 - a) ** n, atol=1e-5, rtol=0)


def test_specks_under_a_two_pixel_light_buffer_shadow_as_brute_does(gl):
    # Each face's projection grows by over half a light pixel, so that a shadow ray crossing a
    # pixel's square off its centre still finds the face; a growth of 0.3 pixel missed occluders here.
    from parc import DirectionalLight, PointLight
    data = np.zeros((12, 12, 12), np.uint8)
    idx = np.array([[3, 2, 4], [6, 2, 2], [5, 7, 2], [4, 6, 9], [7, 6, 3], [3, 6, 9], [8, 5, 7], [2, 5, 4],
                    [9, 5, 4], [2, 5, 3], [5, 4, 5], [5, 2, 5], [7, 4, 3], [4, 2, 6], [9, 5, 7], [8, 10, 9],
                    [10, 2, 2], [3, 3, 2], [2, 5, 7], [5, 2, 8]])
    data[idx[:, 2], idx[:, 1], idx[:, 0]] = 255
    data[0:2] = 200
    lights = [PointLight((8.101751086619698, 16.875330432781972, 29.123267731511444)),
              DirectionalLight((0.7533603495211348, -0.11189376142374594, -1.3419935332355504))]
    scene = Scene(camera=Camera(eye=(5.5, -20, 30), look_at=(5.5, 5.5, 0.5), up=(0, 0, 1), fov=40), size=(48, 48),
                  volumes=[Isosurface(Volume(data, name="specks"), 120.0)], lights=lights, shadows=True)
    b = render(scene, "brute")
    p = render(scene, "parc", supercell=0.5, light_buffer=2)
    assert np.abs(b.image - p.image).max() <= 1e-6


def test_merged_volumes_correct_opacity_each_for_its_own_step():
    # Two composite volumes of other spacings and steps (each its own opacity correction), one
    # behind the other: together they look as each does alone, near over far.
    tf = TransferFunction([[0, 0.03], [200, 0.03]], [[0, 1.0, 0.5, 0.0]])
    near = Translucent(Volume(np.full((N, N, N), 100.0, np.float32), spacing=(1.0, 1.0, 0.5), name="near"), tf,
                       step=0.4)
    far = Translucent(Volume(np.full((N, N, N), 100.0, np.float32), spacing=(1.0, 1.0, 2.0), origin=(0, 0, 20),
                             name="far"), tf, step=0.1)
    a, b = (render(Scene(camera=CAM, size=(4, 4), volumes=[v])).image.astype(np.float64) for v in (near, far))
    for vols in ([near, far], [far, near]):
        both = render(Scene(camera=CAM, size=(4, 4), volumes=vols)).image
        np.testing.assert_allclose(both, a + (1.0 - a[..., 3:4]) * b, atol=1e-5, rtol=0)


def _over(*rgbas):
    """Front-to-back ``over`` of premultiplied RGBA colours, nearest first."""
    out = np.zeros(4)
    for c in rgbas:
        out += (1.0 - out[3]) * np.asarray(c, np.float64)
    return out


@pytest.mark.parametrize("case", ["aside, red, fog", "aside, fog, red", "red, blue, fog"])
def test_layers_tied_with_samples_go_by_their_place_in_the_scene(case):
    # Every volume shares one box (one aside, out of every ray): each ray meets the layers and
    # the fog's first sample at one depth, and the volume listed first goes first; later fog
    # samples come after. A constant field makes each layer one colour and the fog 33 samples of a.
    a = 0.1
    fog = Translucent(_const(name="fog"), TransferFunction([[0, a], [200, a]], [[0, 0.0, 1.0, 0.0]]), threshold=1.0)
    red = Translucent(_const(name="red"), TransferFunction([[0, 0.3], [200, 0.3]], [[0, 1.0, 0.0, 0.0]]), mode="mip")
    blue = Translucent(_const(name="blue"), TransferFunction([[0, 0.5], [200, 0.5]], [[0, 0.0, 0.0, 1.0]]),
                       mode="mip")
    aside = Translucent(_const(origin=(100.0, 0.0, 0.0), name="aside"),
                        TransferFunction([[0, a], [200, a]], [[0, 1.0, 1.0, 1.0]]), threshold=1.0)
    fog_alpha = 1.0 - (1.0 - a) ** 33
    fog_rgba = [0.0, fog_alpha, 0.0, fog_alpha]
    if case == "aside, red, fog":
        vols, want = [aside, red, fog], _over([0.3, 0, 0, 0.3], fog_rgba)
    elif case == "aside, fog, red":
        rest = 1.0 - (1.0 - a) ** 32
        vols, want = [aside, fog, red], _over([0, a, 0, a], [0.3, 0, 0, 0.3], [0, rest, 0, rest])
    else:
        vols, want = [red, blue, fog], _over([0.3, 0, 0, 0.3], [0, 0, 0.5, 0.5], fog_rgba)
    img = render(Scene(camera=CAM, size=(4, 4), volumes=vols)).image.astype(np.float64)
    np.testing.assert_allclose(img, np.broadcast_to(want, img.shape), atol=1e-5, rtol=0)


@pytest.mark.parametrize("near_first", [True, False])
def test_merged_volumes_of_other_sample_types_and_tables_keep_their_values(near_first):
    # 8-bit samples beside float ones below 1 (the merged walk reads one sample type, and pads
    # the shorter transfer function's tables): the float volume's samples keep their fractions,
    # each volume its own table, and each looks as it does alone.
    near = Translucent(Volume(np.full((N, N, N), 100, np.uint8), name="near"),
                       TransferFunction([[0, 0.05], [50, 0.05], [150, 0.05], [255, 0.05]],
                                        [[0, 1.0, 0.0, 0.0], [100, 1.0, 0.0, 0.0], [255, 1.0, 0.0, 0.0]]),
                       threshold=1.0)
    far = Translucent(Volume(np.full((N, N, N), 0.75, np.float32), origin=(0, 0, 20), name="far"),
                      TransferFunction([[0, 0.0], [1, 0.04]], [[0, 0.0, 0.0, 1.0]]), threshold=1.0)
    a, b = (render(Scene(camera=CAM, size=(4, 4), volumes=[v])).image.astype(np.float64) for v in (near, far))
    np.testing.assert_allclose(b[..., 3], 1 - (1 - 0.03) ** 33, atol=1e-5)
    both = render(Scene(camera=CAM, size=(4, 4), volumes=[near, far] if near_first else [far, near])).image
    np.testing.assert_allclose(both, a + (1.0 - a[..., 3:4]) * b, atol=1e-5, rtol=0)


def test_a_merged_volume_adds_nothing_once_the_opacity_reaches_its_own_threshold():
    # Two overlapping volumes, the first stopping at 0.5, the second (from z = 0.3) at 1: the
    # first's sample at z = 0 takes the opacity to exactly 0.5, so its next one, at z = 0.25 and
    # before any of the second's, adds nothing, as alone; the second takes all 33 of its samples,
    # in either order (the rays end at the largest threshold, whichever volume has it).
    red = Translucent(_const(name="red"), TransferFunction([[0, 0.5], [200, 0.5]], [[0, 1.0, 0.0, 0.0]]),
                      threshold=0.5, shade=False)
    blue = Translucent(_const(origin=(0.0, 0.0, 0.3), name="blue"),
                       TransferFunction([[0, 0.1], [200, 0.1]], [[0, 0.0, 0.0, 1.0]]), threshold=1.0, shade=False)
    alone = render(Scene(camera=CAM, size=(4, 4), volumes=[red])).image.astype(np.float64)
    np.testing.assert_allclose(alone, np.broadcast_to([0.5, 0.0, 0.0, 0.5], alone.shape), atol=1e-6, rtol=0)
    blue_alpha = 1.0 - (1.0 - 0.1) ** 33
    want = _over([0.5, 0.0, 0.0, 0.5], [0.0, 0.0, blue_alpha, blue_alpha])
    for vols in ([red, blue], [blue, red]):
        img = render(Scene(camera=CAM, size=(4, 4), volumes=vols)).image.astype(np.float64)
        np.testing.assert_allclose(img, np.broadcast_to(want, img.shape), atol=1e-5, rtol=0)


def test_layers_behind_the_point_where_the_samples_reach_the_threshold_still_show():
    # The fog (threshold 0.5, 0.1 a sample) stops at its 7th sample, z = 1.5, while it still has
    # samples to take; a maximum-intensity layer entered at z = 4, behind that, is finished, so it
    # still shows under the fog, as a surface behind it would.
    a = 0.1
    fog = Translucent(_const(name="fog"), TransferFunction([[0, a], [200, a]], [[0, 0.0, 1.0, 0.0]]),
                      threshold=0.5, shade=False)
    red = Translucent(_const(origin=(0.0, 0.0, 4.0), name="red"),
                      TransferFunction([[0, 0.3], [200, 0.3]], [[0, 1.0, 0.0, 0.0]]), mode="mip")
    fog_alpha = 1.0 - (1.0 - a) ** 7
    for vols in ([fog, red], [red, fog]):
        img = render(Scene(camera=CAM, size=(4, 4), volumes=vols)).image.astype(np.float64)
        want = _over([0.0, fog_alpha, 0.0, fog_alpha], [0.3, 0.0, 0.0, 0.3])
        np.testing.assert_allclose(img, np.broadcast_to(want, img.shape), atol=1e-5, rtol=0)


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("view", ["edge", "eye on a face"])
def test_a_ray_meeting_a_merged_volume_at_one_point_takes_its_one_sample(gl, method, view):
    # A ray that enters and leaves the box at the same t still has one lattice point there
    # (N = floor(0 / step) + 1): parallel rays along (1, -1, 0) through the edge x = y = 0 (the
    # middle column), or rays from an eye on the exit face z = 8 looking out. That eye sits on
    # the corner of four cells, which every ray leaves at t = 0 too: the walk ends with the box,
    # not in those cells. The volume aside, which no ray meets, makes the walk the merged one;
    # alone, the volume looks the same.
    a = 0.1
    tf = TransferFunction([[0, a], [200, a]], [[0, 1.0, 1.0, 1.0]])
    fog = Translucent(_const(), tf, threshold=1.0)
    aside = Translucent(_const(origin=(100.0, 0.0, 0.0), name="aside"), tf, threshold=1.0)
    if view == "edge":
        cam = Camera(eye=(-4.0, 4.0, 4.0), look_at=(4.0, -4.0, 4.0), up=(0, 0, 1), parallel_scale=3.0)
    else:
        cam = Camera(eye=(4.0, 4.0, 8.0), look_at=(4.0, 4.0, 20.0), up=(0, 1, 0), fov=60.0)
    alone = render(Scene(camera=cam, size=(5, 5), volumes=[fog]), method).image.astype(np.float64)
    img = render(Scene(camera=cam, size=(5, 5), volumes=[fog, aside]), method).image.astype(np.float64)
    touched = img[:, 2] if view == "edge" else img.reshape(-1, 4)
    np.testing.assert_allclose(touched, a, atol=1e-6, rtol=0)
    np.testing.assert_allclose(img, alone, atol=1e-6, rtol=0)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_merged_walks_take_the_samples_each_volume_takes_alone(gl, method):
    # A slab seen for 3 <= z <= 5 only, and a volume aside that no ray meets: brute takes every
    # lattice point, 33 a ray (z = 0 .. 8 every 0.25); PARC, without the skip tables, the lattice
    # points of the cells its segments meet, as the volume's own walk does alone, and fewer.
    z = np.arange(N, dtype=np.float32)[:, None, None]
    slab = np.broadcast_to(np.where((z >= 3) & (z <= 5), 100.0, 0.0), (N, N, N)).astype(np.float32)
    tf = TransferFunction([[0, 0.0], [50, 0.0], [100, 0.1], [200, 0.1]], [[0, 1.0, 1.0, 1.0]])
    fog = Translucent(Volume(slab.copy(), name="slab"), tf, threshold=1.0)
    aside = Translucent(Volume(slab.copy(), origin=(100.0, 0.0, 0.0), name="aside"), tf, threshold=1.0)
    alone = render(Scene(camera=CAM, size=(4, 4), volumes=[fog]), method, supercell=1, blocks=False)
    both = render(Scene(camera=CAM, size=(4, 4), volumes=[fog, aside]), method, supercell=1, blocks=False)
    ref = render(Scene(camera=CAM, size=(4, 4), volumes=[fog]), "brute")
    np.testing.assert_allclose(both.image, ref.image, atol=1e-6, rtol=0)
    assert both.stats["samples"] == alone.stats["samples"]
    if method == "brute":
        assert both.stats["samples"] == 16 * 33
    else:
        assert both.stats["samples"] < 16 * 33


@pytest.mark.parametrize("near_first", [True, False])
def test_layers_at_two_depths_go_near_over_far_over_the_samples_behind(near_first):
    # Two maximum-intensity layers entered at z = 0 and z = 2, a fog from z = 4: each layer one
    # colour (a constant field), the fog 33 samples of a; near over far, whatever their order.
    a = 0.1
    near = Translucent(_const(name="near"), TransferFunction([[0, 0.3], [200, 0.3]], [[0, 1.0, 0.0, 0.0]]),
                       mode="mip")
    far = Translucent(_const(origin=(0.0, 0.0, 2.0), name="far"),
                      TransferFunction([[0, 0.5], [200, 0.5]], [[0, 0.0, 0.0, 1.0]]), mode="mip")
    fog = Translucent(_const(origin=(0.0, 0.0, 4.0), name="fog"),
                      TransferFunction([[0, a], [200, a]], [[0, 0.0, 1.0, 0.0]]), threshold=1.0)
    fog_alpha = 1.0 - (1.0 - a) ** 33
    want = _over([0.3, 0, 0, 0.3], [0, 0, 0.5, 0.5], [0, fog_alpha, 0, fog_alpha])
    img = render(Scene(camera=CAM, size=(4, 4), volumes=[near, far, fog] if near_first else [far, near, fog])).image
    np.testing.assert_allclose(img.astype(np.float64), np.broadcast_to(want, img.shape), atol=1e-5, rtol=0)


def test_a_surface_and_a_layer_over_half_the_picture_act_there_only():
    # A wall at z = 4.6 and a maximum-intensity layer, both over x >= 4 only (the two left
    # columns: the camera's right is -x): there the layer goes first (listed first, tied with the
    # fog's first sample) and the fog takes its 19 samples before the wall; elsewhere all 33.
    a = 0.1
    fog = Translucent(_const(), TransferFunction([[0, a], [200, a]], [[0, 1.0, 1.0, 1.0]]), threshold=1.0)
    red = Translucent(_const(origin=(4.0, 0.0, 0.0), name="red"),
                      TransferFunction([[0, 0.3], [200, 0.3]], [[0, 1.0, 0.0, 0.0]]), mode="mip")
    wall = Isosurface(_ramp_z(origin=(4.0, 0.0, 0.0), name="wall"), 4.6)
    surf = render(Scene(camera=CAM, size=(4, 4), volumes=[wall])).image.astype(np.float64)
    img = render(Scene(camera=CAM, size=(4, 4), volumes=[red, fog, wall])).image.astype(np.float64)
    assert (surf[:, :2, 3] == 1.0).all() and not surf[:, 2:].any()
    fog19, fog33 = 1.0 - (1.0 - a) ** 19, 1.0 - (1.0 - a) ** 33
    for x in range(4):
        for y in range(4):
            if x >= 2:
                want = _over([fog33] * 4)
            else:
                want = _over([0.3, 0.0, 0.0, 0.3], [fog19] * 4, surf[y, x])
            np.testing.assert_allclose(img[y, x], want, atol=1e-5, rtol=0)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_layer_met_at_one_point_goes_where_the_ray_meets_it(gl, method):
    # Parallel rays along (1, -1, 0) through the edge x = y = 0 (the middle column) meet the box
    # at one point, where the layer (listed first) and the fog each have their one sample: the
    # layer goes first there, as on every other ray, not behind the fog.
    a = 0.1
    red = Translucent(_const(name="red"), TransferFunction([[0, 0.3], [200, 0.3]], [[0, 1.0, 0.0, 0.0]]), mode="mip")
    fog = Translucent(_const(name="fog"), TransferFunction([[0, a], [200, a]], [[0, 0.0, 1.0, 0.0]]), threshold=1.0)
    cam = Camera(eye=(-4.0, 4.0, 4.0), look_at=(4.0, -4.0, 4.0), up=(0, 0, 1), parallel_scale=3.0)
    img = render(Scene(camera=cam, size=(5, 5), volumes=[red, fog]), method).image.astype(np.float64)
    want = _over([0.3, 0.0, 0.0, 0.3], [0.0, a, 0.0, a])
    np.testing.assert_allclose(img[:, 2], np.broadcast_to(want, (5, 4)), atol=1e-6, rtol=0)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_mip_layer_takes_the_colour_of_its_largest_sample_away_from_zero(gl, method):
    # A ramp v = 1000 + 10 z seen along z: the largest sample is 1080, on the exit face, and the
    # pixel is the transfer function there (opacity 0.56, colour (0.9, 0.45, 0.1)), whatever the
    # data's minimum.
    ramp = _ramp_z(10.0)
    tf = TransferFunction([[900, 0.2], [1100, 0.6]], [[900, 0.0, 0.0, 1.0], [1100, 1.0, 0.5, 0.0]])
    layer = Translucent(Volume(ramp.data + 1000.0, name="ramp"), tf, mode="mip")
    img = render(Scene(camera=CAM, size=(4, 4), volumes=[layer]), method).image.astype(np.float64)
    want = [0.9 * 0.56, 0.45 * 0.56, 0.1 * 0.56, 0.56]
    np.testing.assert_allclose(img, np.broadcast_to(want, img.shape), atol=1e-6, rtol=0)


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("lights", [[], LIGHTS], ids=["headlight", "lights"])
def test_surfaces_side_by_side_are_each_lit_in_their_own_colour_and_material(gl, method, lights):
    # A wall at z = 4.6 over x in [0, 8] and one at z = 3.6 over x in [4, 12], nearer where both
    # are: the two left columns (the camera's right is -x) show the second, the right ones the
    # first, each as it looks alone, whichever is listed first.
    first = Isosurface(_ramp_z(name="first"), 4.6, color=(1.0, 0.2, 0.1), material=(0.3, 0.6, 0.0, 1.0))
    second = Isosurface(_ramp_z(origin=(4.0, 0.0, 0.0), name="second"), 3.6, color=(0.1, 0.4, 1.0),
                        material=(0.1, 0.4, 0.5, 8.0))

    def image(vols):
        return render(Scene(camera=CAM, size=(4, 4), volumes=vols, lights=lights), method).image.astype(np.float64)

    a, b = image([first]), image([second])
    assert (a[..., 3] == 1.0).all() and (b[:, :2, 3] == 1.0).all() and not b[:, 2:].any()
    for vols in ([first, second], [second, first]):
        both = image(vols)
        np.testing.assert_allclose(both[:, :2], b[:, :2], atol=1e-6, rtol=0)
        np.testing.assert_allclose(both[:, 2:], a[:, 2:], atol=1e-6, rtol=0)
    assert np.abs(a[:, :2, :3] - b[:, :2, :3]).min() > 0.05


@pytest.mark.parametrize("mode", ["mip", "average"])
@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_layer_beside_a_surface_counts_the_samples_it_takes_alone(gl, method, mode):
    # A surface no ray meets sends the layer through the scene's caster: its samples still count,
    # 33 a ray for brute (z = 0 .. 8 every 0.25), as many as alone for PARC.
    tf = TransferFunction([[-1, 0.5], [100, 0.5]], [[0, 1.0, 1.0, 1.0]])
    layer = Translucent(_ramp_z(10.0), tf, mode=mode)
    aside = Isosurface(_ramp_z(origin=(100.0, 0.0, 0.0), name="aside"), 4.6)
    alone = render(Scene(camera=CAM, size=(4, 4), volumes=[layer]), method)
    both = render(Scene(camera=CAM, size=(4, 4), volumes=[layer, aside]), method)
    np.testing.assert_allclose(both.image, alone.image, atol=1e-6, rtol=0)
    assert both.stats["samples"] == alone.stats["samples"] > 0
    if method == "brute":
        assert both.stats["samples"] == 16 * 33
