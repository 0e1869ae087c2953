"""An isosurface lying on the volume's own outer face (isovalue = data min or max, attained on a face).

Truth: analytic. The bottom face (index 0 along the axis, x, y or z) holds
the data minimum, the top face (the last index) the maximum, every other
sample lies strictly between,
so the isosurface at the minimum (maximum) is exactly that face: the
interpolant equals the isovalue all over it and nowhere else. A ray that
crosses the face hits it first, at the plane's ``t``; a ray that does not
misses. Seen from either side the same face is where the ray enters the
volume (near face) or leaves it (far face), where no neighbouring cell can
settle the rounding of the cell's cubic, as it does inside (`raycast.iso`).
"""
import numpy as np
import pytest

from data_tools import Volume
from parc import Camera, Isosurface, Scene, render

SIZE = (24, 20)
#: Rays crossing the face closer than this (in cells) to its edges are not judged.
EDGE = 1e-6


def _volume(dtype, axis):
    rng = np.random.default_rng(7)
    nx, ny, nz = 7, 6, 5
    data = rng.uniform(101, 899, (nz, ny, nx)).round()
    first, last = [slice(None)] * 3, [slice(None)] * 3
    first[2 - axis], last[2 - axis] = 0, -1          # array axes are [z, y, x]
    data[tuple(first)], data[tuple(last)] = 100, 900
    return Volume(data.astype(dtype), spacing=(0.7, 1.3, 0.9), origin=(-2.0, 1.0, 5.0))


def _along(axis, on_axis, u, v):
    """A vector with ``on_axis`` along ``axis`` and ``u``, ``v`` along the next two axes (cyclically)."""
    out = np.zeros(3)
    out[axis], out[(axis + 1) % 3], out[(axis + 2) % 3] = on_axis, u, v
    return out


def _camera(vol, axis, below, view):
    c = vol.center
    # Oblique and off-centre, so no ray is aligned with the grid. "parallel_far": an eye
    # 1e5 units away, past `raycast.traverse.FAR_ORIGIN`, so the caster moves each ray's
    # origin to where it enters the volume, and only to within a rounding.
    far = 1e5 / 11.0 if view == "parallel_far" else 1.0
    eye = c + far * _along(axis, (-1 if below else 1) * 11.0, 1.9, -1.3)
    look = c + _along(axis, 0.0, 0.3, 0.2)
    up = tuple(_along(axis, 0.2, 0.1, 1.0))
    if view == "perspective":
        return Camera(eye=tuple(eye), look_at=tuple(look), up=up, fov=45)
    return Camera(eye=tuple(eye), look_at=tuple(look), up=up, parallel_scale=4.0)


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("view", ["perspective", "parallel", "parallel_far"])
@pytest.mark.parametrize("below", [True, False], ids=["eye_below", "eye_above"])
@pytest.mark.parametrize("top", [False, True], ids=["min_bottom_face", "max_top_face"])
@pytest.mark.parametrize("dtype", [np.float32, np.uint16])
@pytest.mark.parametrize("axis", [0, 1, 2], ids=["x", "y", "z"])
def test_isosurface_on_the_volume_face_is_hit_by_every_ray_through_it(axis, dtype, top, below, view, method, request):
    if method == "parc":
        request.getfixturevalue("gl")
    vol = _volume(dtype, axis)
    iso = 900.0 if top else 100.0
    cam = _camera(vol, axis, below, view)
    res = render(Scene(camera=cam, size=SIZE, volumes=[Isosurface(vol, iso)]), method=method)

    lo, hi = np.array(vol.bounds[0]), np.array(vol.bounds[1])
    face = hi[axis] if top else lo[axis]
    o, d = cam.rays(*SIZE)
    t = (face - o[..., axis]) / d[..., axis]
    p = o + t[..., None] * d
    sp = np.array(vol.spacing)
    across = [a for a in range(3) if a != axis]             # the face's own two axes
    p, lo, hi, sa = p[..., across], lo[across], hi[across], sp[across]
    inner = ((p > lo + EDGE * sa) & (p < hi - EDGE * sa)).all(-1) & (t > 0)
    outer = ((p >= lo - EDGE * sa) & (p <= hi + EDGE * sa)).all(-1) & (t > 0)
    assert inner.sum() > 30 and (~outer).sum() > 20        # not vacuous: hits and misses both

    hit = np.isfinite(res.depth)
    near = (top != below)                                   # the face is where rays enter the volume
    where = f"{'near' if near else 'far'} face, iso={iso}"
    assert hit[inner].all(), f"{(~hit[inner]).sum()} of {inner.sum()} rays through the face miss it ({where})"
    assert not hit[~outer].any(), f"rays missing the face hit at {np.argwhere(hit & ~outer)[:5].tolist()}"
    err = np.abs(res.depth[inner] - t[inner]).max()
    assert err <= 1e-9 * sp.min(), f"depth off the face's plane by {err:g} ({where})"
    if method == "parc":                                    # and bit for bit the unaccelerated caster's
        ref = render(Scene(camera=cam, size=SIZE, volumes=[Isosurface(vol, iso)]), method="brute")
        assert np.array_equal(res.depth, ref.depth)


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("view", ["parallel", "perspective"])
@pytest.mark.parametrize("last", [False, True], ids=["first_face", "last_face"])
@pytest.mark.parametrize("dtype", [np.uint8, np.float32])
@pytest.mark.parametrize("axis", [0, 1, 2], ids=["x", "y", "z"])
def test_rays_lying_in_a_face_at_the_isovalue_hit_where_they_enter(axis, dtype, last, view, method, request):
    # The interpolant is the isovalue all over the face and each ray of the middle image row
    # runs inside it, so the first root is where the ray enters the volume. In the last face
    # (local coordinate 1 in the cells below it) the cell's cubic reached the face's zero
    # only to within a rounding: 3% of such rays were hit up to 3 cells late, or missed.
    if method == "parc":
        request.getfixturevalue("gl")
    n = 6
    rng = np.random.default_rng(axis + 3 * last)
    plane = n - 1 if last else 0
    idx = np.indices((n, n, n))[2 - axis]                   # the axis's sample index, array order [z, y, x]
    data = np.abs(idx - plane) * rng.integers(2, 9, (n, n, n))
    spacing = np.array([0.5, 1.0, 0.75])
    origin = np.array([-2.0, 1.0, 3.0])
    vol = Volume(data.astype(dtype), spacing=tuple(spacing), origin=tuple(origin))
    c = np.array(vol.center)
    c[axis] = origin[axis] + plane * spacing[axis]          # exact: dyadic spacing and origin
    b, e = (axis + 1) % 3, (axis + 2) % 3
    eye = c.copy()
    eye[b] -= 7.3
    eye[e] -= 2.9
    up = np.zeros(3)
    up[axis] = 1.0                                          # rows step along the axis; the middle row stays in the face
    size = (64, 33)
    cam = (Camera(eye=tuple(eye), look_at=tuple(c), up=tuple(up), parallel_scale=3.0) if view == "parallel"
           else Camera(eye=tuple(eye), look_at=tuple(c), up=tuple(up), fov=40))
    o, d = cam.rays(*size)
    o, d = o[16], d[16]
    assert (o[:, axis] == c[axis]).all() and (d[:, axis] == 0.0).all()      # in the face's plane, exactly
    lo, hi = np.array(vol.bounds[0]), np.array(vol.bounds[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - o) / d, (hi - o) / d
    across = [b, e]
    t_in = np.minimum(t0, t1)[:, across].max(-1)
    t_out = np.maximum(t0, t1)[:, across].min(-1)
    through = (t_in < t_out - 1e-3) & (t_in > 0)
    assert through.sum() > 10
    res = render(Scene(camera=cam, size=size, volumes=[Isosurface(vol, 0.0)]), method=method)
    depth = res.depth[16]
    assert np.isfinite(depth[through]).all(), f"{(~np.isfinite(depth[through])).sum()} in-face rays miss"
    err = np.abs(depth[through] - t_in[through]).max()
    assert err <= 1e-9, f"in-face rays hit {err:g} past their entry"
