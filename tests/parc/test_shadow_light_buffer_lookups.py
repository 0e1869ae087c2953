"""How a PARC shadow ray finds its segment in a light's buffers (`raycast.shadow.light_segment`).

By hand: buffers whose every pixel holds its own values, so the pixels a lookup merged can be
read off its answer, against the four pixels around the crossing (clamped to the image) that
the docstring promises, from the image's edges to just past them. Against brute: occluders
whose shadows are cast through the light buffers' edges (the box's outline for a sun, the
cube views' seams for a point light inside the box, a box wider than one view can hold) and
by a rod moved through the places of a 2-pixel buffer's pixels, where only some of the four
pixels bound it; the image must be brute's, and the shadow must be there.
"""
import numba
import numpy as np
import pytest

from data_tools import Volume
from parc import Camera, DirectionalLight, Isosurface, PointLight, Scene, render
from parc.lights import N_VIEW, V_EYE, V_FWD, V_KIND, V_RIGHT, V_SCALE, V_UP


def _checked_light_segment():
    # Compiled with bounds checks, which the cached kernels leave out: an unclamped
    # neighbour past the image's last row or column raises instead of reading past it.
    from raycast import shadow
    return numba.njit(boundscheck=True)(shadow.light_segment.py_func)


def _view(kind, eye, fwd, right, up, scale):
    row = np.zeros(N_VIEW)
    row[V_KIND] = kind
    row[V_EYE:V_EYE + 3] = eye
    row[V_FWD:V_FWD + 3] = fwd
    row[V_RIGHT:V_RIGHT + 3] = right
    row[V_UP:V_UP + 3] = up
    row[V_SCALE] = scale
    return row


def _numbered(views, n):
    """Buffers whose pixel (v, row j, column i) holds near ``v n n + j n + i`` and far ``10^6 + near``."""
    near = np.arange(views * n * n, dtype=np.float64).reshape(views, n, n)
    return near, near + 1e6


def _four(near, far, v, cx, cy):
    """Smallest near and largest far of the four pixels around the crossing ``(cx, cy)`` (pixel units
    from the image's left and top edges), clamped to the image."""
    n = near.shape[1]
    cols = np.clip(np.floor(cx - 0.5) + np.array([0, 1]), 0, n - 1).astype(int)
    rows = np.clip(np.floor(cy - 0.5) + np.array([0, 1]), 0, n - 1).astype(int)
    return near[v][np.ix_(rows, cols)].min(), far[v][np.ix_(rows, cols)].max()


@pytest.mark.parametrize("n", [1, 2, 3, 4, 7])
def test_a_sun_s_lookup_merges_the_four_pixels_around_the_crossing(n):
    # A parallel view looking down -z from z = 50 over x, y in [-2, 2] (scale 2): image row 0 at
    # the top (+y), column 0 at the left (-x). A point at (x, y) crosses it at column (x + 2) n / 4
    # and row (2 - y) n / 4; crossings from the edges inwards, and just past them (no pixel).
    seg = _checked_light_segment()
    views = _view(1.0, (0.0, 0.0, 50.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), 2.0)[None]
    near, far = _numbered(1, n)
    rng = np.random.default_rng(n)
    px = 4.0 / n                                   # a pixel's width
    edges = [-2.0, -2.0 + 0.2 * px, -2.0 + 0.6 * px, -2.0 + 0.99 * px, 2.0 - 0.99 * px, 2.0 - 0.6 * px,
             2.0 - 0.2 * px, 2.0, 0.0, 0.3 * px]
    pts = [(x, y) for x in edges for y in edges] + [tuple(p) for p in rng.uniform(-2, 2, (200, 2))]
    for x, y in pts:
        z = rng.uniform(-10, 40)                   # the depth changes nothing of a parallel view's crossing
        got = seg(views, near, far, x, y, z)
        assert got == _four(near, far, 0, (x + 2.0) * n / 4.0, (2.0 - y) * n / 4.0), (n, x, y)
    for x, y in [(2.0 + 1e-3, 0.0), (-2.0 - 1e-3, 1.0), (0.5, 2.0 + 1e-3), (-1.0, -2.0 - 1e-3), (5.0, 5.0)]:
        assert seg(views, near, far, x, y, 0.0) == (np.inf, -np.inf), (x, y)


def test_a_point_light_s_lookup_takes_the_views_that_hold_the_direction():
    # Two 90-degree views from the origin, looking down +x and +z (right, up as `light_views`
    # makes them: up along the axis farthest from the forward one); a direction on their seam
    # merges four pixels of each, one past it only those of the view that holds it, and one
    # behind a view (qf <= 0) nothing of it.
    from parc.lights import light_views, view_array
    seg = _checked_light_segment()
    n = 4
    cams = [c for c in light_views(PointLight((0.0, 0.0, 0.0)), (-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))
            if abs(c.basis()[0][0] - 1.0) < 1e-12 or abs(c.basis()[0][2] - 1.0) < 1e-12]
    views = view_array(cams)
    near, far = _numbered(len(cams), n)
    rng = np.random.default_rng(1)
    dirs = [(1.0, 0.3, 1.0), (1.0, -0.99, 1.0), (1.0, 0.0, 0.999), (0.999, 0.5, 1.0), (1.0, 1.0, 1.0),
            (1.0, -1.0, -1.0)] + [tuple(d) for d in rng.uniform(-1, 1, (300, 3))]
    for d in dirs:
        d = np.asarray(d)
        want_lo, want_hi = np.inf, -np.inf
        for v in range(len(cams)):
            row = views[v]
            qf, qr, qu = d @ row[V_FWD:V_FWD + 3], d @ row[V_RIGHT:V_RIGHT + 3], d @ row[V_UP:V_UP + 3]
            if qf <= 0.0:
                continue
            sx, sy = qr / (qf * row[V_SCALE]), qu / (qf * row[V_SCALE])
            if abs(sx) > 1.0 + 1e-7 or abs(sy) > 1.0 + 1e-7:
                continue
            lo, hi = _four(near, far, v, (sx + 1.0) * 0.5 * n, (1.0 - sy) * 0.5 * n)
            want_lo, want_hi = min(want_lo, lo), max(want_hi, hi)
        for r in (0.5, 3.0):                       # the distance along it changes nothing
            assert seg(views, near, far, *(r * d)) == (want_lo, want_hi), d


# Against brute: PARC may only narrow a shadow ray to what its buffers bound, so a lookup
# that reads the wrong pixels, or none, shows as a shadow lost.

def _floor():
    """A floor (z = 5.5) over x in [0, 40], y in [0, 30], in its own volume."""
    z = np.arange(11, dtype=np.float32)[:, None, None]
    return Isosurface(Volume(np.broadcast_to(5.5 - z, (11, 31, 41)).copy(), name="floor"), 0.0,
                      color=(1.0, 1.0, 1.0), material=(0.2, 0.8, 0.0, 1.0))


def _plate():
    """An opaque plate over x, y in [8, 18] (the whole of its volume's box), z in [12.5, 14.5]:
    seen from a sun, its shadow's outline is its box's, the light buffer's edge."""
    d = np.zeros((4, 11, 11), np.float32)
    d[1:3] = 1.0
    return Isosurface(Volume(d, origin=(8.0, 8.0, 12.0), name="plate"), 0.5)


def _ball(centre, radius=2.5, box=21):
    """A ball in a box of ``box`` samples from the origin (a linear distance field: its surface is
    the sphere up to interpolation)."""
    k, j, i = np.mgrid[0:box, 0:box, 0:box].astype(np.float32)
    r = np.sqrt((i - centre[0]) ** 2 + (j - centre[1]) ** 2 + (k - centre[2]) ** 2)
    return Isosurface(Volume((radius - r).astype(np.float32), name="ball"), 0.0)


def _assert_parc_is_brute(scene, light_buffer, supercell=1):
    b = render(scene, "brute")
    p = render(scene, "parc", light_buffer=light_buffer, supercell=supercell)
    assert np.array_equal(np.isfinite(b.depth), np.isfinite(p.depth))
    lit = render(Scene(camera=scene.camera, size=scene.size, volumes=scene.volumes, lights=scene.lights),
                 "brute")
    shadowed = (b.image[..., :3] < lit.image[..., :3] - 0.05).any(-1)
    lost = (np.abs(b.image - p.image) > 1e-6).any(-1)
    assert not lost.any(), f"{lost.sum()} pixels differ from brute ({shadowed.sum()} shadowed)"
    return shadowed


@pytest.mark.parametrize("light_buffer", [3, 16])
@pytest.mark.parametrize("sun", [(1.0, 0.0, -1.0), (0.0, 1.0, -1.0)])
def test_a_plate_s_shadow_cast_through_the_sun_buffer_s_edges_is_brute_s(gl, sun, light_buffer):
    # Seen from the sun, the plate fills its buffer to the edges across the sun's way (y for the
    # first, x for the second): the shadow's sides are cast by crossings at the buffer's edges.
    # The camera's pixels, 0.45 apart, put rows (columns) of floor points 0.05 inside both sides
    # (at 8.05 and 17.95), whose shadow rays cross the buffer within 1% of its edges.
    across = 1 if sun[0] else 0
    centre = [21.0, 21.0]
    centre[across] = 13.225
    cam = Camera(eye=(*centre, 100.0), look_at=(*centre, 0.0), up=(0, 1, 0), parallel_scale=9.0)
    o, _ = cam.rays(40, 40)
    assert np.isclose(o[..., across], 8.05).any() and np.isclose(o[..., across], 17.95).any()
    scene = Scene(camera=cam, size=(40, 40), volumes=[_floor(), _plate()], lights=[DirectionalLight(sun)],
                  shadows=True)
    shadowed = _assert_parc_is_brute(scene, light_buffer)
    near_edge = np.isclose(o[..., across], 8.05) | np.isclose(o[..., across], 17.95)
    assert (shadowed & near_edge).sum() >= 20


@pytest.mark.parametrize("light_buffer", [3, 8, 64])
@pytest.mark.parametrize("lamp", [(13.0, 13.0, 15.0), (10.0, 13.0, 15.0), (10.7, 9.6, 16.0)])
def test_a_ball_s_shadow_across_the_cube_views_seams_is_brute_s(gl, lamp, light_buffer):
    # A point light inside the ball's box takes six cube views; the ball stands where their
    # seams meet (the first lamp on a corner's diagonal, the second on an edge's plane), or
    # straight below (the third), and shadows the floor.
    cam = Camera(eye=(8.0, 8.0, 100.0), look_at=(8.0, 8.0, 0.0), up=(0, 1, 0), parallel_scale=8.0)
    scene = Scene(camera=cam, size=(40, 40), volumes=[_floor(), _ball((10.0, 10.0, 12.0))],
                  lights=[PointLight(lamp)], shadows=True)
    assert _assert_parc_is_brute(scene, light_buffer).sum() > 100


def _rod(k):
    """An opaque rod along x (x in [5, 15]) at y = k / 2, z = 13, half a unit thick, in a box 10
    across it: a 2-pixel light buffer's pixel is about 5 units wide there, so the faces of its
    supercells, grown by the pad, reach some pixels' centres and not others."""
    d = np.zeros((3, 21, 11), np.float32)
    d[1, k, :] = 1.0
    return Isosurface(Volume(d, spacing=(1.0, 0.5, 1.0), origin=(5.0, 0.0, 12.0), name="rod"), 0.5)


@pytest.mark.parametrize("sun, look", [((0.0, 0.5, -1.0), (10.0, 3.5)),      # the buffer's columns across y
                                       ((0.5, 0.0, -1.0), (17.0, 0.0))])     # its rows across y
def test_a_thin_rod_s_shadow_through_a_two_pixel_sun_buffer_is_brute_s(gl, sun, look):
    # The rod, moved half a unit (a tenth of a light pixel) at a time, is bounded by one or two
    # pixels of a row or a column: every crossing lies between two pixel centres a pixel apart,
    # and for some places of the rod only one of them is within the pad of its faces (a lookup
    # of only the lower, or only the upper, of the two loses all of the shadow at 4 of these
    # places). The camera looks down beside the rod, at its shadow.
    for k in range(1, 20):
        centre = (look[0], 0.5 * k + look[1])
        cam = Camera(eye=(*centre, 100.0), look_at=(*centre, 0.0), up=(0, 1, 0), parallel_scale=3.0)
        scene = Scene(camera=cam, size=(24, 24), volumes=[_floor(), _rod(k)], lights=[DirectionalLight(sun)],
                      shadows=True)
        assert _assert_parc_is_brute(scene, 2).sum() > 20, k


def test_a_long_plate_s_shadow_from_a_lamp_close_above_it_is_brute_s(gl):
    # A plate 30 long, 6 wide (x in [0, 30], y in [10, 16], z in [12.5, 14.5]) under a lamp 12
    # above its box's middle: the box spans 52 degrees from the lamp, its ends 51 along x, past a
    # single 90-degree view's 45 (the lamp takes cube views). The shadow rays through the plate's
    # ends reach the floor at x > 36.5, where the camera looks.
    from parc.lights import light_views
    d = np.zeros((4, 7, 31), np.float32)
    d[1:3] = 1.0
    plate = Isosurface(Volume(d, origin=(0.0, 10.0, 12.0), name="long plate"), 0.5)
    lamp = PointLight((15.0, 13.0, 27.0))
    assert len(light_views(lamp, *plate.volume.bounds)) > 1
    cam = Camera(eye=(36.0, 13.0, 100.0), look_at=(36.0, 13.0, 0.0), up=(0, 1, 0), parallel_scale=4.0)
    scene = Scene(camera=cam, size=(32, 32), volumes=[_floor(), plate], lights=[lamp], shadows=True)
    o, dirs = cam.rays(32, 32)
    p = o + ((5.5 - o[..., 2]) / dirs[..., 2])[..., None] * dirs          # the floor points in view
    steep = np.abs(p[..., 0] - 15.0) > np.abs(p[..., 2] - 27.0)           # more than 45 degrees along x
    shadowed = _assert_parc_is_brute(scene, 8)
    assert (shadowed & steep).sum() > 20
