"""Scene, Isosurface, Translucent and lights: the limits their docstrings give, at and past each bound.

Truth: the documented ranges and formulas (``size`` both at least 1, components in [0, 1],
intensity >= 0, shininess > 0, a light's coordinates up to 1e150, the eye within 2^32 volume
sizes, ``radiance = colour * intensity``) and the data range computed with NumPy.
"""
import math

import warnings

import numpy as np
import pytest

import parc
from data_tools import InputError
from data_tools.synthetic import blobs
from parc.scene import describe_volume

VOL = blobs(12, seed=3)
ISO = float(VOL.data.mean())
CAM = parc.Camera.framing(*VOL.bounds)


def _scene(**kw):
    args = dict(camera=CAM, size=(8, 8), volumes=[parc.Isosurface(VOL, ISO)])
    args.update(kw)
    return parc.Scene(**args)


def test_an_isovalue_at_either_end_of_the_data_range_is_taken_and_one_past_it_refused():
    lo, hi = float(np.min(VOL.data)), float(np.max(VOL.data))
    assert parc.Isosurface(VOL, lo).value == lo
    assert parc.Isosurface(VOL, hi).value == hi
    for past in (np.nextafter(lo, -math.inf), np.nextafter(hi, math.inf)):
        with pytest.raises(InputError, match="outside the data range"):
            parc.Isosurface(VOL, past)


@pytest.mark.parametrize("size", [(8, 0), (0, 8), (-1, 8)])
def test_an_image_without_pixels_is_refused(size):
    with pytest.raises(InputError, match="image size must be two positive integers"):
        _scene(size=size)


def test_a_one_pixel_image_is_a_scene():
    assert _scene(size=(1, 1)).size == (1, 1)


@pytest.mark.parametrize("bg", [(-0.1, 0.0, 0.0), (0.0, 0.0, 0.0, -1e-9), (0.0, 1.5, 0.0)])
def test_background_components_outside_zero_to_one_are_refused(bg):
    with pytest.raises(InputError, match=r"background components must be in \[0, 1\]"):
        _scene(background=bg)


def test_a_scene_without_volumes_is_refused():
    with pytest.raises(InputError, match="give at least one volume"):
        _scene(volumes=[])


def test_more_composite_volumes_than_one_walk_merges_are_refused_and_other_modes_do_not_count():
    from raycast.merged import MAX_MERGED
    fog = parc.Translucent(VOL, "greyscale")
    layers = [parc.Translucent(VOL, "greyscale", mode=m) for m in ("mip", "average")]
    assert len(_scene(volumes=[fog] * MAX_MERGED + layers).volumes) == MAX_MERGED + 2
    with pytest.raises(InputError, match=f"at most {MAX_MERGED} translucent volumes together.*has "
                                         f"{MAX_MERGED + 1} in composite mode"):
        _scene(volumes=[fog] * (MAX_MERGED + 1))


@pytest.mark.parametrize("shade, given, said", [
    (False, {"shadows": True}, ["shadows fall"]),
    (False, {"lights": [parc.PointLight((1, 2, 3))]}, ["lights shine"]),
    (False, {"lights": [parc.DirectionalLight((0, 0, -1))], "shadows": True}, ["lights shine", "shadows fall"])])
def test_lights_and_shadows_that_fall_on_nothing_are_taken_and_said_to_change_nothing(shade, given, said):
    # The contract's scene gives lights to an isosurface or a translucent volume alike. They light
    # and shadow shaded translucent samples and nothing else there.
    volumes = [parc.Translucent(VOL, "greyscale", shade=shade)]
    with pytest.warns(parc.ShowsNothingWarning) as caught:
        scene = _scene(volumes=volumes, **given)
    assert [" ".join(str(w.message).split()[:2]) for w in caught] == said
    assert all("the image is the same without them" in str(w.message) for w in caught)
    # How to shade, in each of the three places a scene is written:
    assert all("shade=True, --shade, a scene file's shade = true" in str(w.message) for w in caught)
    assert all(w.filename == __file__ for w in caught)
    plain = _scene(volumes=volumes, lights=scene.lights if shade else [])
    for method in ("brute", "parc"):
        assert (parc.render(scene, method=method).image == parc.render(plain, method=method).image).all()


@pytest.mark.parametrize("volume", [parc.Translucent(VOL, "greyscale", shade=True), parc.Isosurface(VOL, ISO)])
def test_lights_on_what_they_light_are_taken_without_a_word(volume):
    with warnings.catch_warnings():
        warnings.simplefilter("error", parc.ShowsNothingWarning)
        scene = _scene(volumes=[volume], lights=[parc.PointLight((1, 2, 3))])
    assert (parc.render(scene).image != parc.render(_scene(volumes=[volume])).image).any()


@pytest.mark.parametrize("volume", [parc.Translucent(VOL, "greyscale", shade=True), parc.Isosurface(VOL, ISO)])
def test_shadows_on_what_they_fall_on_are_taken_without_a_word(volume):
    # A sun beside the volume: the far side's samples and hits are in the near side's shadow.
    sun = [parc.DirectionalLight((1, 0.3, 0.2))]
    with warnings.catch_warnings():
        warnings.simplefilter("error", parc.ShowsNothingWarning)
        scene = _scene(volumes=[volume], lights=sun, shadows=True)
    assert (parc.render(scene).image != parc.render(_scene(volumes=[volume], lights=sun)).image).any()


@pytest.mark.parametrize("volume", [parc.Translucent(VOL, "greyscale", shade=True), parc.Isosurface(VOL, ISO)])
def test_shadows_under_the_headlight_alone_are_taken_and_said_to_change_nothing(volume):
    # The headlight sits at the eye: nothing it lights is in shadow. The command line said so; Python did not.
    with pytest.warns(parc.ShowsNothingWarning, match="shadows with only the headlight show nothing") as caught:
        scene = _scene(volumes=[volume], shadows=True)
    assert len(caught) == 1 and caught[0].filename == __file__
    for method in ("brute", "parc"):
        assert (parc.render(scene, method=method).image
                == parc.render(_scene(volumes=[volume]), method=method).image).all()


@pytest.mark.parametrize("make", [
    lambda c: parc.PointLight((1, 2, 3), color=c),
    lambda c: parc.DirectionalLight((1, 2, 3), color=c),
    lambda c: parc.Isosurface(VOL, ISO, color=c),
])
def test_colour_components_below_zero_are_refused(make):
    with pytest.raises(InputError, match=r"colour must be three numbers in \[0, 1\]"):
        make((-0.25, 0.5, 0.5))


def test_a_material_needs_a_positive_shininess_and_takes_zero_weights():
    with pytest.raises(InputError, match="shininess above 0"):
        parc.Isosurface(VOL, ISO, material=(0.1, 0.7, 0.2, 0.0))
    assert parc.Isosurface(VOL, ISO, material=(0, 0, 0, 1)).material == (0.0, 0.0, 0.0, 1.0)


@pytest.mark.parametrize("light", [parc.PointLight, parc.DirectionalLight])
def test_a_lights_radiance_is_its_colour_times_its_intensity(light):
    assert light((1, 2, 3), color=(0.5, 0.25, 1.0), intensity=2.0).radiance == (1.0, 0.5, 2.0)
    assert light((1, 2, 3), intensity=0).radiance == (0.0, 0.0, 0.0)
    with pytest.raises(InputError, match="intensity must be a finite number >= 0"):
        light((1, 2, 3), intensity=-1e-12)


def test_a_point_light_may_stand_up_to_1e150_away_and_no_further():
    assert parc.PointLight((-1e150, 0, 1e150)).position == (-1e150, 0.0, 1e150)
    with pytest.raises(InputError, match="a light that far is directional: give its direction \\(DirectionalLight"):
        parc.PointLight((0, 1.0000001e150, 0))


@pytest.mark.parametrize("view", [dict(fov=30.0), dict(parallel_scale=5.0)])
def test_the_eye_may_stand_up_to_2_to_the_32_volume_sizes_from_the_origin(view):
    lo, hi = VOL.bounds
    size = float(np.linalg.norm(np.subtract(hi, lo)))
    centre = tuple(0.5 * (np.asarray(lo) + np.asarray(hi)))
    near = parc.Camera(eye=(2.0 ** 31 * size, centre[1], centre[2]), look_at=centre, up=(0, 0, 1), **view)
    assert _scene(camera=near).camera is near
    far = parc.Camera(eye=(2.0 ** 33 * size, centre[1], centre[2]), look_at=centre, up=(0, 0, 1), **view)
    with pytest.raises(InputError, match="over 2\\^32 times the volumes' size"):
        _scene(camera=far)


@pytest.mark.parametrize("step", [math.inf, math.nan, -0.5, 0.0])
def test_a_step_that_is_no_positive_finite_distance_is_refused(step):
    with pytest.raises(InputError, match="step must be a positive, finite distance"):
        parc.Translucent(VOL, "greyscale", step=step)


@pytest.mark.parametrize("mode", ["mip", "average"])
def test_a_volume_described_for_the_stats_has_a_threshold_only_where_rays_stop_early(mode):
    composite = describe_volume(parc.Translucent(VOL, "greyscale", threshold=0.5))
    assert composite["threshold"] == 0.5 and composite["mode"] == "composite"
    other = describe_volume(parc.Translucent(VOL, "greyscale", mode=mode))
    assert other["mode"] == mode and "threshold" not in other
    assert describe_volume(parc.Isosurface(VOL, ISO))["isovalue"] == ISO


def test_a_scene_without_a_size_is_512_by_512_as_on_the_command_line():
    # `parc render --help`: "image size in pixels (default 512 512)"; a scene file's default too.
    from parc.scenefile import DEFAULT_SIZE
    scene = parc.Scene(camera=CAM, volumes=[parc.Isosurface(VOL, ISO)])
    assert scene.size == (512, 512) == tuple(DEFAULT_SIZE)
    assert parc.render(scene, method="brute").image.shape == (512, 512, 4)


def test_a_surface_of_default_colour_and_material_shades_as_computed_by_hand():
    # A plane 3x + 4z = 20 (the interpolant of a linear field is that field) seen from above in a
    # parallel view: normal (0.6, 0, 0.8), the headlight along the view, so n.l = n.h = 0.8. The
    # default warm off-white (0.93, 0.86, 0.74) with ambient 0.12, diffuse 0.78, specular 0.25,
    # shininess 40 gives c (0.12 + 0.78 * 0.8) + 0.25 * 0.8^40 in every pixel.
    k, _, i = np.mgrid[0:8, 0:4, 0:8]
    vol = parc.Volume((3.0 * i + 4.0 * k).astype(np.float32))
    cam = parc.Camera(eye=(3.5, 1.5, 50.0), look_at=(3.5, 1.5, 0.0), up=(0.0, 1.0, 0.0), parallel_scale=1.0)
    image = parc.render(parc.Scene(camera=cam, size=(4, 4), volumes=[parc.Isosurface(vol, 20.0)]),
                        method="brute").image
    want = np.array([0.93, 0.86, 0.74]) * (0.12 + 0.78 * 0.8) + 0.25 * 0.8 ** 40
    np.testing.assert_allclose(image[..., :3], np.broadcast_to(want, (4, 4, 3)), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(image[..., 3], 1.0)
