"""Camera: DESIGN's ray formula, its OpenGL matrices, and its errors.

Truth: the formula written out independently here, and geometric facts
(the centre ray looks at look_at, parallel rays share one direction).
"""
import math
import re
import warnings

import numpy as np
import pytest

from parc import Camera, InputError
from raycast.rays import camera_ray


@pytest.mark.parametrize("projection", [dict(fov=40.0), dict(parallel_scale=2.5)])
def test_kernel_rays_match_numpy_rays(projection):
    cam = Camera(eye=(3.0, -7.0, 2.0), look_at=(0.5, 0.25, -1.0), up=(0.0, 0.0, 1.0), **projection)
    o, d = cam.rays(7, 5)
    arr = cam.as_array()
    for y in range(5):
        for x in range(7):
            r = camera_ray(arr, 7, 5, x, y)
            np.testing.assert_allclose(r[:3], o[y, x], rtol=0, atol=1e-12)
            np.testing.assert_allclose(r[3:], d[y, x], rtol=0, atol=1e-12)


def test_perspective_rays_follow_the_design_formula():
    cam = Camera(eye=(1.0, 2.0, 3.0), look_at=(4.0, 2.0, 3.0), up=(0.0, 0.0, 1.0), fov=90.0)
    o, d = cam.rays(4, 2)
    # f = +x, r = f x up = -y, u = r x f = +z; tan(45 deg) = 1; aspect 2.
    x, y = 3, 0
    sx = (2 * (x + 0.5) / 4 - 1) * 2.0
    sy = 1 - 2 * (y + 0.5) / 2
    want = np.array([1.0, -sx, sy])
    np.testing.assert_allclose(d[y, x], want / np.linalg.norm(want), atol=1e-15)
    assert np.allclose(o, (1.0, 2.0, 3.0))


def test_centre_ray_hits_look_at_and_parallel_rays_share_direction():
    cam = Camera(eye=(0.0, -10.0, 0.0), look_at=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), fov=30.0)
    o, d = cam.rays(5, 5)
    np.testing.assert_allclose(d[2, 2], (0.0, 1.0, 0.0), atol=1e-15)
    par = Camera(eye=(0.0, -10.0, 0.0), look_at=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), parallel_scale=2.0)
    o, d = par.rays(4, 4)
    assert np.allclose(d, (0.0, 1.0, 0.0))
    # Top row is parallel_scale * (1 - 1/4) above the eye; left column at -(1 - 1/4) * 2.
    np.testing.assert_allclose(o[0, 0], (-1.5, -10.0, 1.5), atol=1e-14)


def test_projection_puts_pixel_centres_where_the_rays_go():
    cam = Camera(eye=(2.0, -6.0, 3.0), look_at=(0.5, 0.5, 0.5), up=(0.0, 0.0, 1.0), fov=35.0)
    w, h = 8, 6
    o, d = cam.rays(w, h)
    mvp = cam.projection_matrix(w, h, 0.1, 100.0) @ cam.view_matrix()
    p = np.concatenate([o[2, 5] + 4.0 * d[2, 5], [1.0]])
    clip = mvp @ p
    ndc = clip[:3] / clip[3]
    px = (ndc[0] + 1) / 2 * w
    py_down = h - (ndc[1] + 1) / 2 * h
    assert abs(px - 5.5) < 1e-9 and abs(py_down - 2.5) < 1e-9


@pytest.mark.parametrize("kwargs, words", [
    (dict(eye=(1, 1, 1), look_at=(1, 1, 1)), "eye equals look-at"),
    (dict(eye=(0, 0, 5), look_at=(0, 0, 0), up=(0, 0, 2)), "parallel"),
    (dict(eye=(0, 0, 5), look_at=(0, 0, 0), fov=0.0), "field of view"),
    (dict(eye=(0, 0, 5), look_at=(0, 0, 0), fov=180.0), "field of view"),
    (dict(eye=(0, 0, 5), look_at=(0, 0, 0), parallel_scale=-1.0), "parallel scale"),
    (dict(eye=(0, 0, 5), look_at=(0, 0, 0), parallel_scale=math.inf), "parallel scale must be positive and finite"),
    (dict(eye=(0, 0, math.nan), look_at=(0, 0, 0)), "finite"),
    (dict(eye=(0, 0, 5), look_at=(0, 0, 0), up=(0, 0, 0)), "is zero"),
    (dict(eye=(0, 0, 5), look_at=(0, 0, 0), fov=math.nan), "field of view"),
    (dict(eye=(1e308, 0, 0), look_at=(-1e308, 0, 0), up=(0, 0, 1)), "too far apart: their difference overflows"),
])
def test_bad_cameras_are_refused(kwargs, words):
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # one clear error, no NumPy warning before it
        with pytest.raises(InputError, match=words):
            Camera(**kwargs)


@pytest.mark.parametrize("fov", [0.0, 5e-324, math.inf, math.nan, 1e-320])
def test_framing_refuses_a_field_of_view_it_cannot_frame_with(fov):
    with pytest.raises(InputError, match="field of view"):
        Camera.framing((0, 0, 0), (10, 10, 10), fov=fov)


def test_framing_a_point_names_the_box_not_the_zoom():
    with pytest.raises(InputError, match="box with some size; its corners are one point"):
        Camera.framing((2, 2, 2), (2, 2, 2))


def test_framing_a_box_near_float64s_range_warns_of_nothing():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cam = Camera.framing((0, 0, 0), (1e300, 1e300, 1e300))
    np.testing.assert_allclose(cam.look_at, (5e299, 5e299, 5e299), rtol=1e-15)
    assert np.linalg.norm(np.subtract(cam.eye, cam.look_at) / 1e300) > 0.866 / math.sin(math.radians(15))


@pytest.mark.parametrize("k", [-95, -40, 40, 95])
def test_a_view_scaled_by_a_power_of_two_has_the_same_basis_to_the_last_bit(k):
    # An eye 1e-125 from the point it looks at is scaled past 1e-150 at 2^-95: divided by its
    # largest component (not a power of two) its direction moved by an ulp, and 379 of 696
    # depths of a scene scaled so were no longer 2^k times the unscaled ones.
    eye, look = np.array([3.0, -4.0, 2.0]) * 1e-125, np.array([0.7, 0.2, -0.1]) * 1e-125
    up = (0.3, 0.1, 1.0)
    ref = Camera(eye=tuple(eye), look_at=tuple(look), up=up).basis()
    got = Camera(eye=tuple(np.ldexp(eye, k)), look_at=tuple(np.ldexp(look, k)), up=tuple(np.ldexp(up, k))).basis()
    for a, b in zip(ref, got):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("scale", [1e-300, 1e300])
def test_huge_and_tiny_vectors_give_the_basis_of_their_direction(scale):
    # Their lengths under- or overflow; their directions are ordinary.
    ref = Camera(eye=(3.0, -4.0, 2.0), look_at=(0.0, 0.0, 0.0), up=(1.0, 0.0, 1.0))
    cam = Camera(eye=(3.0, -4.0, 2.0), look_at=(0.0, 0.0, 0.0), up=(scale, 0.0, scale))
    for a, b in zip(ref.basis(), cam.basis()):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)
    far = Camera(eye=(3e200, -4e200, 2e200), look_at=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0))
    np.testing.assert_allclose(far.basis()[0], -np.array([3.0, -4.0, 2.0]) / math.sqrt(29.0), atol=1e-15)


@pytest.mark.parametrize("size", [(64, 64), (96, 64), (32, 96), (10, 200)])
@pytest.mark.parametrize("parallel", [False, True])
@pytest.mark.parametrize("zoom", [1.0, 4.0])
def test_framing_keeps_the_whole_box_in_view(size, parallel, zoom):
    # A tall image is framed across (only the vertical angle was fitted: the box's ends were cut),
    # and a parallel view zoomed in keeps its eye outside the box (it clipped the front away).
    lo, hi = np.array([-3.0, 2.0, 10.0]), np.array([40.0, 30.0, 25.0])
    w, h = size
    cam = Camera.framing(lo, hi, parallel=parallel, aspect=w / h, zoom=zoom)
    eye = np.array(cam.eye)
    assert not ((lo <= eye) & (eye <= hi)).all()
    if zoom != 1.0:
        return
    mvp = cam.projection_matrix(w, h, 0.01, 1e4) @ cam.view_matrix()
    for corner in np.array(np.meshgrid(*zip(lo, hi))).T.reshape(-1, 3):
        clip = mvp @ np.append(corner, 1.0)
        assert np.all(np.abs(clip[:2] / clip[3]) <= 1.0)


def test_a_parallel_camera_ignores_its_field_of_view():
    rays = []
    for fov in (None, 10.0, 170.0):
        cam = Camera(eye=(8, -40, 8), look_at=(8, 8, 8), up=(0, 0, 1), fov=fov, parallel_scale=10)
        assert cam.parallel and np.isfinite(cam.as_array()).all()
        rays.append(cam.rays(7, 5))
    for o, d in rays[1:]:
        np.testing.assert_array_equal(o, rays[0][0])
        np.testing.assert_array_equal(d, rays[0][1])
    # Half the view's height is the scale, whatever the field of view.
    o, d = rays[0]
    assert np.ptp(o[:, 0, 2]) == pytest.approx(2 * 10 * (1 - 1 / 5))


def test_the_cached_basis_and_kernel_array_cannot_be_changed_through_a_caller():
    import copy
    import dataclasses
    import pickle

    cam = Camera(eye=(3.0, -4.0, 2.0), look_at=(0.5, 0.25, 0.0), up=(0, 0, 1), fov=40.0)
    f, r, u = cam.basis()
    with pytest.raises(ValueError):
        f[0] = 1.0
    arr = cam.as_array()
    arr[:] = 0.0                          # the caller's copy only
    assert np.isfinite(cam.as_array()).all() and cam.as_array()[12] == pytest.approx(math.tan(math.radians(20)))
    # A camera built from this one (replace, copy, pickle) has its own view.
    moved = dataclasses.replace(cam, eye=(-3.0, 4.0, 2.0))
    assert not np.allclose(moved.basis()[0], f)
    for other in (copy.copy(cam), pickle.loads(pickle.dumps(cam))):
        assert other == cam
        np.testing.assert_array_equal(other.as_array(), cam.as_array())


def test_framing_azimuth_zero_looks_from_minus_y_and_ninety_from_plus_x():
    # The documented convention, worked out by hand for a cube centred at (5, 5, 5).
    cam = Camera.framing((0, 0, 0), (10, 10, 10), azimuth=0.0, elevation=0.0)
    assert cam.eye[1] < 5.0 and cam.eye[0] == pytest.approx(5.0, abs=1e-9) and cam.eye[2] == pytest.approx(5.0)
    cam = Camera.framing((0, 0, 0), (10, 10, 10), azimuth=90.0, elevation=0.0)
    assert cam.eye[0] > 5.0 and cam.eye[1] == pytest.approx(5.0, abs=1e-9)
    cam = Camera.framing((0, 0, 0), (10, 10, 10), azimuth=0.0, elevation=60.0)
    assert cam.eye[2] > 5.0 and cam.eye[1] < 5.0


@pytest.mark.parametrize("up, above, front", [((0, 0, 1), (2, 1), (1, -1)), ((0, 0, -1), (2, -1), (1, -1)),
                                              ((0, 1, 0), (1, 1), (2, 1)), ((0, -1, 0), (1, -1), (2, 1)),
                                              ((1, 0, 0), (0, 1), (1, -1))])
def test_framing_raises_the_eye_towards_up(up, above, front):
    # Elevation is towards the up given: with up (0, 0, -1), for a volume stored upside down,
    # the eye stood below it and saw it from underneath. The front is -y, or +z with up along y.
    cam = Camera.framing((0, 0, 0), (10, 10, 10), azimuth=0.0, elevation=30.0, up=up)
    back = (np.array(cam.eye) - 5.0) / np.linalg.norm(np.array(cam.eye) - 5.0)
    assert back[above[0]] * above[1] == pytest.approx(0.5)              # sin 30 degrees towards up
    assert back[front[0]] * front[1] == pytest.approx(math.sqrt(0.75))  # the rest towards the front
    f, r, u = cam.basis()
    assert np.dot(u, up) > 0.8                                           # and up stays up in the image


@pytest.mark.parametrize("up_y", [1.0, -1.0])
def test_framing_turns_smoothly_as_up_nears_y(up_y):
    # Up (0, -1, 1e-5) and (0, -1, 1e-7) framed the box from opposite sides: the front jumped to +z
    # within 1e-6 of y. It now follows up's tilt down to rounding.
    for sign in (1.0, -1.0):
        eyes = [np.array(Camera.framing((0, 0, 0), (10, 20, 5), up=(0.0, up_y, sign * tilt), azimuth=30,
                                        elevation=20).eye) for tilt in (1e-3, 1e-5, 1e-7, 1e-9, 1e-12, 9e-13, 1e-200)]
        assert max(np.linalg.norm(e - eyes[0]) for e in eyes) < 0.1


def test_parallel_projection_puts_pixel_centres_where_the_rays_go():
    # As the perspective test: the parallel matrices must send a point on a pixel's ray to that pixel.
    cam = Camera(eye=(2.0, -6.0, 3.0), look_at=(0.5, 0.5, 0.5), up=(0.0, 0.0, 1.0), parallel_scale=2.5)
    w, h = 8, 6
    o, d = cam.rays(w, h)
    mvp = cam.projection_matrix(w, h, 0.1, 100.0) @ cam.view_matrix()
    for y, x in ((0, 0), (2, 5), (5, 7)):
        clip = mvp @ np.append(o[y, x] + 4.0 * d[y, x], 1.0)
        ndc = clip[:3] / clip[3]
        assert (ndc[0] + 1) / 2 * w == pytest.approx(x + 0.5, abs=1e-9)
        assert h - (ndc[1] + 1) / 2 * h == pytest.approx(y + 0.5, abs=1e-9)


@pytest.mark.parametrize("fov", [20.0, 30.0, 60.0])
@pytest.mark.parametrize("aspect", [0.25, 1.0, 2.0])
def test_framing_fits_the_bounding_sphere_snugly(fov, aspect):
    # Whole in view (the existing test) is not enough: an eye twice as far keeps it in view at a
    # quarter of the area. The sphere's angular radius is the narrower half-angle less the 2% margin.
    lo, hi = np.array([-3.0, 2.0, 10.0]), np.array([40.0, 30.0, 25.0])
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    centre = 0.5 * (lo + hi)
    cam = Camera.framing(lo, hi, fov=fov, aspect=aspect)
    dist = float(np.linalg.norm(np.array(cam.eye) - centre))
    vertical = math.radians(fov) / 2
    horizontal = math.atan(aspect * math.tan(vertical))
    seen = math.asin(radius / dist)
    assert seen <= min(vertical, horizontal)
    assert seen >= 0.95 * min(vertical, horizontal)
    par = Camera.framing(lo, hi, parallel=True, aspect=aspect)
    half_height, half_width = par.parallel_scale, par.parallel_scale * aspect
    assert radius <= min(half_height, half_width) <= 1.05 * radius


def test_rays_of_some_rows_are_those_rows_of_the_whole_image():
    # rows=(y0, y1) (several volumes' box entries, parallel origins) must be rows y0..y1-1, not 0..
    for cam in (Camera(eye=(3.0, -7.0, 2.0), look_at=(0.5, 0.25, -1.0), up=(0, 0, 1), fov=40.0),
                Camera(eye=(3.0, -7.0, 2.0), look_at=(0.5, 0.25, -1.0), up=(0, 0, 1), parallel_scale=3.0)):
        o, d = cam.rays(7, 9)
        ob, db = cam.rays(7, 9, rows=(3, 7))
        np.testing.assert_array_equal(ob, o[3:7])
        np.testing.assert_array_equal(db, d[3:7])


@pytest.mark.parametrize("parallel", [False, True])
def test_projection_maps_the_depth_range_to_minus_one_to_one(parallel):
    # OpenGL's convention, which x and y alone do not show: a point ``near`` ahead of the eye goes to
    # z = -1, one ``far`` ahead to +1, in every pixel, with w > 0 in front of the eye.
    view = {"parallel_scale": 2.5} if parallel else {"fov": 35.0}
    cam = Camera(eye=(2.0, -6.0, 3.0), look_at=(0.5, 0.5, 0.5), up=(0.0, 0.0, 1.0), **view)
    w, h, near, far = 8, 6, 0.5, 40.0
    mvp = cam.projection_matrix(w, h, near, far) @ cam.view_matrix()
    f = cam.basis()[0]
    o, d = cam.rays(w, h)
    for y, x in ((0, 0), (2, 5), (5, 7)):
        for ahead, z in ((near, -1.0), (far, 1.0), (0.5 * (near + far), None)):
            clip = mvp @ np.append(o[y, x] + ahead / np.dot(d[y, x], f) * d[y, x], 1.0)
            assert clip[3] > 0.0
            if z is not None:
                assert clip[2] / clip[3] == pytest.approx(z, abs=1e-9)
            else:
                assert -1.0 < clip[2] / clip[3] < 1.0


def test_default_framing_stands_where_its_documented_angles_and_margin_put_it():
    # By hand for the cube [0, 10]^3: azimuth 35 and elevation 25 degrees round +z put the eye along
    # (cos 25 sin 35, -cos 25 cos 35, sin 25) from the centre, at the distance where the bounding
    # sphere (radius 5 sqrt 3) fills half the 30-degree field of view, plus 2%; zoom 2 halves it.
    centre, radius = np.array([5.0, 5.0, 5.0]), 5.0 * math.sqrt(3.0)
    el, az = math.radians(25.0), math.radians(35.0)
    back = np.array([math.cos(el) * math.sin(az), -math.cos(el) * math.cos(az), math.sin(el)])
    dist = radius / math.sin(math.radians(15.0)) * 1.02
    for zoom in (1.0, 2.0):
        cam = Camera.framing((0, 0, 0), (10, 10, 10), zoom=zoom)
        np.testing.assert_allclose(cam.eye, centre + back * dist / zoom, rtol=0, atol=1e-12)
        np.testing.assert_allclose(cam.look_at, centre, rtol=0, atol=1e-12)
        assert cam.fov == 30.0 and not cam.parallel
    for zoom in (1.0, 2.0):
        par = Camera.framing((0, 0, 0), (10, 10, 10), parallel=True, zoom=zoom)
        assert par.parallel_scale == pytest.approx(radius * 1.02 / zoom, rel=1e-15)


def test_a_zoomed_parallel_framing_keeps_its_eye_outside_the_bounding_sphere():
    # Zoom only magnifies a parallel view: the eye must not move in among the box's corners,
    # whichever way it looks (a cube's corners lie all round its centre, at the sphere's radius).
    lo, hi = np.zeros(3), np.full(3, 10.0)
    for az in (0.0, 35.0, 45.0, 120.0):
        cam = Camera.framing(lo, hi, parallel=True, zoom=4.0, azimuth=az)
        assert np.linalg.norm(np.array(cam.eye) - 5.0) >= 5.0 * math.sqrt(3.0) * (1.0 - 1e-12)


@pytest.mark.parametrize("view", [dict(fov=40.0), dict(parallel_scale=2.5)])
def test_a_cameras_settings_make_the_same_camera_again(view):
    cam = Camera(eye=(3.0, -7.0, 2.0), look_at=(0.5, 0.25, -1.0), up=(0.0, 0.0, 1.0), **view)
    settings = cam.settings()
    assert set(settings) == {"eye", "look_at", "up"} | set(view)
    again = Camera(**settings)
    assert again == cam and again.parallel == cam.parallel
    np.testing.assert_array_equal(again.as_array(), cam.as_array())


def test_a_parallel_framing_looks_from_the_documented_angles_from_three_radii_back():
    # As the perspective framing above, by hand for the cube [0, 10]^3: the eye lies along
    # (cos 25 sin 35, -cos 25 cos 35, sin 25) from the centre, three bounding radii (5 sqrt 3)
    # back, well outside the box, at every zoom (a parallel view's zoom only magnifies); depths
    # are measured from the view plane through it.
    centre, radius = np.array([5.0, 5.0, 5.0]), 5.0 * math.sqrt(3.0)
    el, az = math.radians(25.0), math.radians(35.0)
    back = np.array([math.cos(el) * math.sin(az), -math.cos(el) * math.cos(az), math.sin(el)])
    for zoom in (1.0, 2.0, 4.0):
        par = Camera.framing((0, 0, 0), (10, 10, 10), parallel=True, zoom=zoom)
        np.testing.assert_allclose(par.eye, centre + back * 3.0 * radius, rtol=0, atol=1e-12)
        np.testing.assert_allclose(par.look_at, centre, rtol=0, atol=1e-12)


@pytest.mark.parametrize("eye, up, across", [((0.0, 0.0, 10.0), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
                                             ((0.0, -10.0, 0.0), (0.0, 2.0, 0.0), (0.0, 0.0, 1.0)),
                                             ((3.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 0.0, 1.0))])
def test_an_up_along_the_view_is_refused_with_one_across_it(eye, up, across):
    with pytest.raises(InputError, match=re.escape(f"give one across it, such as {across}")):
        Camera(eye=eye, look_at=(0.0, 0.0, 0.0), up=up)
    Camera(eye=eye, look_at=(0.0, 0.0, 0.0), up=across)
