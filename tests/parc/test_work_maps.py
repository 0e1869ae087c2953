"""Per-pixel work (`render(..., work=True)`) of lit scenes and of several volumes.

Such scenes go through the several-volume driver (`parc.multivolume`); a
scene of one volume without lights goes through the one-volume driver,
which counts its own. The camera rays are the same either way, so the
driver's map must be the sum of each volume's map rendered alone and
unlit, wherever the volumes cannot cut each other's rays short.
"""
import numpy as np
import pytest

from data_tools import Volume
from data_tools.synthetic import blobs
from parc import Camera, DirectionalLight, Isosurface, PointLight, Scene, TransferFunction, Translucent, render
from parc.skip import expect_frames

SIZE = (26, 22)
CAM = Camera(eye=(40.0, 31.0, -25.0), look_at=(8.0, 7.0, 9.0), up=(0, 1, 0), fov=35.0)
LIGHTS = [PointLight((30.0, 30.0, 30.0)), DirectionalLight((0.3, 1.0, -0.2))]
METHODS = ["brute", "parc"]


def _volumes():
    a = blobs((14, 13, 15), seed=11)
    b = blobs((12, 15, 13), seed=12)
    return a, Volume(b.data, spacing=(0.9, 1.1, 1.0), origin=(3.0, -1.0, 4.0), name="b")


@pytest.fixture(params=METHODS)
def method(request):
    """Each method in turn; PARC with the OpenGL context."""
    if request.param == "parc":
        request.getfixturevalue("gl")
    return request.param


def _alone(vis, method, **kw):
    return render(Scene(camera=CAM, size=SIZE, volumes=[vis]), method, work=True, **kw).work


def _mid(vol, f=0.5):
    lo, hi = vol.value_range()
    return lo + f * (hi - lo)


def test_two_shadowed_surfaces_map_their_camera_rays_cells(method):
    a, b = _volumes()
    isos = [Isosurface(a, _mid(a)), Isosurface(b, _mid(b, 0.4))]
    scene = Scene(camera=CAM, size=SIZE, volumes=isos, lights=LIGHTS, shadows=True)
    expect_frames(scene)            # every frame with the skip tables, so their cells agree
    res = render(scene, method, supercell=2, work=True)
    assert res.stats["shadow_rays"] > 0
    assert res.work.shape == SIZE[::-1] and res.work.dtype == np.int64
    # Each surface's rays run whole through its volume (the nearest hit is chosen afterwards).
    expected = sum(_alone(v, method, supercell=2) for v in isos)
    assert expected.sum() > 0 and np.array_equal(res.work, expected)
    assert res.work.sum() == res.stats["cells_visited"]


def test_parc_maps_no_more_work_than_brute_in_a_lit_scene(gl):
    a, b = _volumes()
    scene = Scene(camera=CAM, size=SIZE, volumes=[Isosurface(a, _mid(a)), Isosurface(b, _mid(b, 0.4))],
                  lights=LIGHTS, shadows=True)
    p, q = render(scene, "parc", work=True), render(scene, "brute", work=True)
    assert (p.work <= q.work).all() and p.work.sum() < q.work.sum()


def test_faint_translucent_volumes_map_the_samples_of_each(method):
    # Faint enough that no ray reaches the stopping opacity: each volume's walk then takes
    # the samples it takes alone, whatever the other holds in front of it.
    a, b = _volumes()
    faint = TransferFunction([[_mid(a, 0.3), 0.0], [_mid(a, 0.9), 0.004]], [[0.0, 1.0, 0.5, 0.2]])
    vols = [Translucent(a, faint), Translucent(b, "greyscale", mode="mip"),
            Translucent(b, faint, shade=True, step=0.7)]
    scene = Scene(camera=CAM, size=SIZE, volumes=vols, lights=LIGHTS)
    res = render(scene, method, work=True)
    assert res.image[..., 3].max() < 0.99
    expected = sum(_alone(v, method) for v in vols)
    assert expected.sum() > 0 and np.array_equal(res.work, expected)
    assert res.work.sum() == res.stats["samples"]


@pytest.mark.parametrize("buffers, supercell", [("bits", 3), ("depth,bits", 2)])
def test_faint_volumes_bounded_by_bit_planes_take_the_samples_each_takes_alone(gl, buffers, supercell):
    # The merged walk's plane test is the one-volume walk's: with the planes (and no skip
    # tables, so that they decide), each volume takes the samples it takes alone. At this
    # size a walk that kept the last pixel's stretch in a set plane took more.
    a, b = _volumes()
    faint = TransferFunction([[_mid(a, 0.3), 0.0], [_mid(a, 0.9), 0.004]], [[0.0, 1.0, 0.5, 0.2]])
    vols = [Translucent(a, faint), Translucent(b, "greyscale", mode="mip"),
            Translucent(b, faint, shade=True, step=0.7)]
    size = (64, 56)
    scene = Scene(camera=CAM, size=size, volumes=vols, lights=LIGHTS)
    kw = dict(buffers=buffers, blocks=False, supercell=supercell, work=True)
    res = render(scene, "parc", **kw)
    assert res.image[..., 3].max() < 0.99
    alone = [render(Scene(camera=CAM, size=size, volumes=[v]), "parc", **kw).work for v in vols]
    assert np.array_equal(res.work, sum(alone))
    # The planes cut samples: fewer than whole rays take, and with the depth buffers no more
    # than those take alone.
    assert res.stats["samples"] < render(scene, "brute").stats["samples"]
    if "depth" in buffers:
        assert res.stats["samples"] <= render(scene, "parc", blocks=False, supercell=supercell).stats["samples"]


def test_shadows_on_shaded_samples_leave_the_camera_rays_work_as_it_is(method):
    # Shadowed samples are walked by the several-volume driver, twice over (counted, then
    # recorded); unshadowed, by the one-volume driver.
    a, _ = _volumes()
    tf = TransferFunction([[_mid(a, 0.3), 0.0], [_mid(a, 0.7), 0.3]], [[0.0, 0.9, 0.7, 0.6]])
    vis = Translucent(a, tf, shade=True)
    shadowed = render(Scene(camera=CAM, size=SIZE, volumes=[vis], lights=LIGHTS, shadows=True), method,
                      work=True)
    unshadowed = render(Scene(camera=CAM, size=SIZE, volumes=[vis], lights=LIGHTS), method, work=True)
    assert shadowed.stats["shadow_rays"] > 0
    assert unshadowed.work.sum() > 0 and np.array_equal(shadowed.work, unshadowed.work)
    assert shadowed.work.sum() == shadowed.stats["samples"]


def test_maps_cast_and_lit_in_bands_count_each_band_once(method, monkeypatch):
    # A progress callback casts the rows in bands, and shadowed samples are recorded and lit
    # in bands of at most SAMPLES_AT_ONCE: the map must not depend on either.
    import parc.multivolume as multivolume
    a, b = _volumes()
    tf = TransferFunction([[_mid(a, 0.3), 0.0], [_mid(a, 0.7), 0.3]], [[0.0, 0.9, 0.7, 0.6]])
    surfaces = Scene(camera=CAM, size=SIZE, volumes=[Isosurface(a, _mid(a)), Isosurface(b, _mid(b, 0.4))],
                     lights=LIGHTS, shadows=True)
    translucent = Scene(camera=CAM, size=SIZE, lights=LIGHTS, shadows=True,
                        volumes=[Translucent(a, tf, shade=True), Translucent(b, "greyscale", mode="mip"),
                                 Translucent(b, "greyscale", mode="average", step=0.8)])
    for scene, total in ((surfaces, "cells_visited"), (translucent, "samples")):
        expect_frames(scene)
        whole = render(scene, method, supercell=2, work=True)
        monkeypatch.setattr(multivolume, "SAMPLES_AT_ONCE", 7)
        banded = render(scene, method, supercell=2, work=True, progress=lambda f: None)
        monkeypatch.undo()
        assert whole.work.sum() == whole.stats[total] > 0
        assert np.array_equal(banded.work, whole.work) and banded.work.sum() == banded.stats[total]
