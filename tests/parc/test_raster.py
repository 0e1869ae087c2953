"""The OpenGL pass: per-pixel near/far ray distances must be conservative.

Truth: `parc_reference.segments_reference`, the caster's float64 ray of
every pixel against every PC supercell box by the slab test on closed
boxes (rays within 1e-12 of the scene scale of touching a box count as
touching it). Assertion, for every pixel whose ray meets a PC box:
``0 <= near <= first entry`` and ``far >= last exit``; and, so that the
segments narrow the rays at all, no more than a few cells looser than the
reference, and none on pixels beyond the coverage dilation. How much looser
than the reference the segments are is also reported at the end of the run.
"""

import os
import subprocess
import sys

import numpy as np
import pytest

from data_tools import Volume
from parc.camera import Camera
from parc.classify import VolumeIndex
from parc.proxy import build_proxy
from parc.raster import Segments, margin, raster_segments
from parc_reference import band_classes, reached, segments_reference, smooth_volume

SIZES = [1, 0.5, 1.5, (2, 3, 1.5)]
#: How much longer than the reference a segment may be, in cells: at most, and on average.
LOOSE_MAX_CELLS = 10.0
LOOSE_MEAN_CELLS = 1.0


def _proxy(vol, size, frac=0.35):
    grid, pc = band_classes(vol, size, frac)
    return build_proxy(grid, pc, grid.world_edges(vol), merge=True)


def _check(camera, proxy, width, height, label, report, *, cell=1.0):
    seg = raster_segments(camera, width, height, proxy)
    assert isinstance(seg, Segments)
    assert seg.near.shape == seg.far.shape == (height, width)
    assert seg.near.dtype == seg.far.dtype == np.float64
    near_ref, far_ref = segments_reference(camera, width, height, proxy,
                                           touch=1e-12 * seg.info["scale"])
    meet = np.isfinite(near_ref)
    assert meet.any(), "test camera sees no PC supercell"
    bad_near = meet & ~(seg.near <= near_ref)
    bad_far = meet & ~(seg.far >= far_ref)
    assert not bad_near.any(), (
        f"{label}: near too large at {np.argwhere(bad_near)[:5].tolist()}: "
        f"{seg.near[bad_near][:5]} > {near_ref[bad_near][:5]}")
    assert not bad_far.any(), (
        f"{label}: far too small at {np.argwhere(bad_far)[:5].tolist()}: "
        f"{seg.far[bad_far][:5]} < {far_ref[bad_far][:5]}")
    assert (seg.near[meet] >= 0).all()
    extra = (seg.near <= seg.far) & ~meet
    slack = np.concatenate([near_ref[meet] - seg.near[meet], seg.far[meet] - far_ref[meet]]) / cell
    # Conservative is not enough: segments as long as the whole ray would pass the checks
    # above and accelerate nothing. The margins cost a few cells at most (grazing faces,
    # the dilation's neighbours; 6 here), well under one on average (a hundredth, but half
    # a cell with the eye a hair below a face), and a segment reaches no pixel beyond the
    # dilation's two.
    assert slack.max() <= LOOSE_MAX_CELLS and slack.mean() <= LOOSE_MEAN_CELLS, (
        f"{label}: segments loose by up to {slack.max():.3g} cells, {slack.mean():.3g} on average")
    near_px = meet.copy()
    for _ in range(2):
        grown = near_px.copy()
        grown[1:] |= near_px[:-1]
        grown[:-1] |= near_px[1:]
        grown[:, 1:] |= near_px[:, :-1]
        grown[:, :-1] |= near_px[:, 1:]
        near_px = grown
    assert not (extra & ~near_px).any(), f"{label}: segments on pixels far from any PC supercell"
    report(f"{label:<44} px {meet.sum():5d}  loose max {slack.max():.2e} mean {slack.mean():.2e} cells"
           f"  extra px {extra.sum():3d}  polys {seg.polygons}")
    return seg, near_ref, far_ref


@pytest.mark.parametrize("size", SIZES, ids=str)
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("parallel", [False, True], ids=["persp", "parallel"])
def test_random_views(gl, looseness, size, seed, parallel):
    vol = smooth_volume(seed, spacing=(1.0, 0.8, 1.3), origin=(2.0, -1.0, 0.5))
    proxy = _proxy(vol, size)
    rng = np.random.default_rng(100 + seed)
    cam = Camera.framing(*vol.bounds, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-80, 80),
                         parallel=parallel, zoom=rng.uniform(0.8, 1.6), fov=rng.uniform(20, 70))
    _check(cam, proxy, 48, 36, f"random {'par' if parallel else 'per'} s={size} seed={seed}", looseness)


AXES = [((0, 0, -1), (0, 1, 0)), ((0, 0, 1), (0, 1, 0)), ((-1, 0, 0), (0, 0, 1)),
        ((1, 0, 0), (0, 0, 1)), ((0, -1, 0), (1, 0, 0)), ((0, 1, 0), (0, 0, 1))]


@pytest.mark.parametrize("size", [1, 2, 0.5], ids=str)
@pytest.mark.parametrize("view", AXES, ids=lambda v: "f=" + ",".join(map(str, v[0])))
def test_axis_aligned_parallel_rays_on_grid_edges(gl, looseness, size, view):
    """Parallel rays along grid lines: every other pixel's ray runs exactly along cell edges."""
    vol = smooth_volume(7, dims=(9, 9, 9))
    proxy = _proxy(vol, size, frac=0.5)
    f, up = np.array(view[0], float), view[1]
    # With 32 pixels and scale 8, ray origins step by 0.5 from 4.25 -+ 8, so
    # half the rays lie on integer lines (see the module notes).
    eye = np.full(3, 4.25) - 20.0 * f
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + f), up=up, parallel_scale=8.0)
    o = _origins(cam, 32, 32)
    on_lines = np.all(np.abs(o - np.round(o)) * (f == 0) == 0, axis=-1)
    assert on_lines.sum() >= 200
    _check(cam, proxy, 32, 32, f"axis par f={view[0]} s={size}", looseness)


def _origins(cam, w, h):
    from parc_reference import caster_rays
    return caster_rays(cam, w, h)[0]


@pytest.mark.parametrize("size", [1, 1.5], ids=str)
@pytest.mark.parametrize("view", AXES, ids=lambda v: "f=" + ",".join(map(str, v[0])))
def test_axis_aligned_perspective(gl, looseness, size, view):
    """Eye on a grid line looking along an axis: the centre ray runs along cell edges."""
    vol = smooth_volume(8, dims=(9, 9, 9))
    proxy = _proxy(vol, size, frac=0.5)
    f, up = np.array(view[0], float), view[1]
    eye = np.full(3, 4.0) - 14.0 * f
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + f), up=up, fov=50.0)
    _check(cam, proxy, 31, 31, f"axis per f={view[0]} s={size}", looseness)


@pytest.mark.parametrize("parallel", [False, True], ids=["persp", "parallel"])
@pytest.mark.parametrize("offset", [0.0, 1e-7, 1e-3], ids=str)
@pytest.mark.parametrize("tilt", [0.0, 1e-7, 1e-3], ids=str)
def test_grazing_views(gl, looseness, parallel, offset, tilt):
    """Rays nearly parallel to the y faces, from an eye on, next to or near a grid plane y = 4.

    The float32 bounds are weakest here (small ray components along the
    face axis, planes through or next to the eye); they must stay
    conservative.
    """
    vol = smooth_volume(12, dims=(9, 9, 9))
    proxy = _proxy(vol, 1, frac=0.5)
    eye = np.array([-12.0, 4.0 + offset, 4.3])
    look = eye + np.array([1.0, tilt, 0.02])
    if parallel:
        cam = Camera(eye=tuple(eye), look_at=tuple(look), up=(0, 0, 1), parallel_scale=5.0)
    else:
        cam = Camera(eye=tuple(eye), look_at=tuple(look), up=(0, 0, 1), fov=40.0)
    label = f"grazing {'par' if parallel else 'per'} off={offset:g} tilt={tilt:g}"
    _check(cam, proxy, 33, 31, label, looseness)


@pytest.mark.parametrize("size", SIZES, ids=str)
@pytest.mark.parametrize("seed", [0, 1])
def test_eye_inside_volume_empty_supercell(gl, looseness, size, seed):
    vol = smooth_volume(seed)
    proxy = _proxy(vol, size)
    rng = np.random.default_rng(seed)
    kz, ky, kx = _pick(rng, ~proxy.pc)
    eye = _centre(proxy, kx, ky, kz)
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + rng.standard_normal(3)), up=(0.3, 0.2, 1.0), fov=100.0)
    seg, _, _ = _check(cam, proxy, 40, 32, f"eye in empty s={size} seed={seed}", looseness)
    assert not seg.info["eye_inside"] and seg.info["d_min"] > 0


def _pick(rng, mask):
    """A random ``(kz, ky, kx)`` where ``mask`` is true."""
    cand = np.argwhere(mask)
    return cand[rng.integers(len(cand))]


def _centre(proxy, kx, ky, kz):
    ex, ey, ez = proxy.world_edges
    return np.array([(ex[kx] + ex[kx + 1]) / 2, (ey[ky] + ey[ky + 1]) / 2, (ez[kz] + ez[kz + 1]) / 2])


@pytest.mark.parametrize("size", SIZES, ids=str)
@pytest.mark.parametrize("where", ["centre", "corner", "face"])
def test_eye_inside_pc_supercell(gl, looseness, size, where):
    """The paper's special case: every ray starts inside, so near is 0 for every pixel."""
    vol = smooth_volume(3)
    proxy = _proxy(vol, size)
    rng = np.random.default_rng(5)
    kz, ky, kx = _pick(rng, proxy.pc)
    ex, ey, ez = proxy.world_edges
    eye = _centre(proxy, kx, ky, kz)
    if where == "corner":
        eye = np.array([ex[kx + 1], ey[ky], ez[kz + 1]])
    elif where == "face":
        eye[0] = ex[kx]
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + rng.standard_normal(3)), up=(0.1, 1.0, 0.3), fov=120.0)
    seg, _, far_ref = _check(cam, proxy, 40, 32, f"eye in PC ({where}) s={size}", looseness)
    assert seg.info["eye_inside"]
    assert (seg.near == 0).all() and (seg.far >= seg.near).all()


@pytest.mark.parametrize("gap", [1e-9, 1e-4, 0.3])
def test_eye_just_outside_pc(gl, looseness, gap):
    """A PC box a hair in front of the eye: the clip plane must sit below it."""
    vol = smooth_volume(4)
    data = vol.data.copy()
    data[:2, :2, :2] = 0.0
    data[0, 0, 0] = 10.0          # cell (0, 0, 0) spans the isovalue
    vol = Volume(data)
    idx = VolumeIndex.of(vol)
    grid = idx.grid(1)
    pc = idx.classify(5.0, 1)
    assert pc[0, 0, 0]
    proxy = build_proxy(grid, pc, grid.world_edges(vol))
    eye = np.array([-gap, 0.5, 0.5])
    cam = Camera(eye=tuple(eye), look_at=(4.0, 0.9, 0.7), up=(0, 0, 1), fov=90.0)
    seg, near_ref, _ = _check(cam, proxy, 33, 33, f"eye {gap:g} outside PC", looseness)
    assert not seg.info["eye_inside"] and seg.info["d_min"] == pytest.approx(gap)
    assert np.nanmin(np.where(np.isfinite(near_ref), near_ref, np.nan)) < 2 * gap + 1e-12


@pytest.mark.parametrize("size", SIZES, ids=str)
def test_parallel_view_plane_through_volume(gl, looseness, size):
    """Parallel rays start on the view plane: inside a PC box some start at t = 0."""
    vol = smooth_volume(6)
    proxy = _proxy(vol, size, frac=0.5)
    c = vol.center
    cam = Camera(eye=tuple(c), look_at=tuple(c + np.array([0.3, -0.5, 0.8])), up=(0, 1, 0),
                 parallel_scale=6.0)
    seg, near_ref, _ = _check(cam, proxy, 40, 40, f"parallel plane through s={size}", looseness)
    starts_inside = near_ref == 0
    assert starts_inside.any()
    assert (seg.near[starts_inside] == 0).all()


@pytest.mark.parametrize("parallel", [False, True], ids=["persp", "parallel"])
def test_far_from_origin_anisotropic(gl, looseness, parallel):
    """Coordinates ~1e4 with small cells: the margins scale with the scene, not with 1."""
    spacing = (0.05, 0.07, 0.2)
    vol = smooth_volume(9, dims=(10, 9, 8), spacing=spacing, origin=(1.0e4, -2.5e3, 7.7e3))
    proxy = _proxy(vol, 1.5)
    cam = Camera.framing(*vol.bounds, azimuth=200, elevation=35, parallel=parallel, zoom=1.3)
    _check(cam, proxy, 48, 40, f"far origin {'par' if parallel else 'per'}", looseness, cell=min(spacing))


def test_wide_fov_eye_inside_volume(gl, looseness):
    vol = smooth_volume(11, dims=(12, 10, 9))
    proxy = _proxy(vol, 1)
    idx = np.argwhere(~proxy.pc)[len(np.argwhere(~proxy.pc)) // 2]
    eye = _centre(proxy, idx[2], idx[1], idx[0])
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + np.array([1.0, 0.2, -0.1])), up=(0, 0, 1), fov=160.0)
    _check(cam, proxy, 64, 24, "wide fov 160 inside volume", looseness)


# (volume seed, supercell size, eye, axis, offset, view direction, up, fov): the eye's
# coordinate on `axis` is moved onto the nearest supercell boundary plane, then `offset` off
# it. From the first three the PC region is seen from outside (near is at stake), from the
# last two from inside it (far is).
HAIR_OFF_A_PLANE = [
    (0, 1.5, (6.9, 3.3, 6.35), 2, -1e-4, (0.3, 0.7, -0.1), (0, 1, 0), 120.0),
    (0, 1, (3.4, 4.6, 5.3), 1, 1e-3, (0.7, 0.8, -0.6), (0, 0, 1), 130.0),
    (2, 1, (3.0, 3.8, 4.5), 1, -1e-4, (-0.1, 0.5, 0.7), (1, 0, 0), 140.0),
    (2, 1, (6.9, 1.7, 0.5), 2, 1e-4, (-0.1, -0.9, -0.7), (0, 1, 0), 130.0),
    (0, 1.5, (9.0, 0.8, 2.45), 2, -1e-4, (0.4, -0.3, 0.7), (1, 0, 0), 150.0),
]


@pytest.mark.parametrize("seed, size, eye, axis, offset, direction, up, fov", HAIR_OFF_A_PLANE,
                         ids=["near-z", "near-y", "near-xy", "far-z", "far-z2"])
def test_wide_oblique_views_from_a_hair_off_a_grid_plane(gl, looseness, seed, size, eye, axis, offset, direction,
                                                         up, fov):
    """A face whose plane passes a hair from the eye is crossed at ever shallower angles the
    farther out along it: a ray meeting it at distance t has |d_a| / |d| = |w| / t (w the
    eye's distance to the plane), down to |w| over the face's farthest distance. The error
    bound on the float32 direction's component along the face's axis, and so on the
    crossing's t, must be taken at that smallest ratio, from the larger depth: taken from the
    face's nearest distance it is too small, and in these wide views near lands millionths
    past the ray's entry (or, with the eye inside the PC region, far short of its exit)."""
    vol = smooth_volume(seed, spacing=(1.0, 0.8, 1.3), origin=(2.0, -1.0, 0.5))
    proxy = _proxy(vol, size)
    eye = np.array(eye)
    edges = np.asarray(proxy.world_edges[axis])
    eye[axis] = edges[np.argmin(np.abs(edges - eye[axis]))] + offset
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + np.array(direction)), up=up, fov=fov)
    _check(cam, proxy, 48, 36, f"wide fov {fov:g} eye {offset:g} off a plane", looseness)


def _shell_proxy(size):
    """A hollow ball: the PC supercells form a closed shell around empty cavity supercells."""
    n = 14
    z, y, x = np.mgrid[:n, :n, :n].astype(float)
    r = np.sqrt((x - 6.3) ** 2 + (y - 6.6) ** 2 + (z - 6.1) ** 2)
    data = np.exp(-((r - 4.0) / 1.2) ** 2).astype(np.float32)
    vol = Volume(data, spacing=(1.0, 0.9, 1.1), origin=(0.5, -2.0, 1.0))
    idx = VolumeIndex.of(vol)
    grid = idx.grid(size)
    return vol, build_proxy(grid, idx.classify(0.5, size), grid.world_edges(vol))



def _cavity_reference(pc):
    """Empty supercells not reachable from outside through faces, edges or corners."""
    empty = ~np.pad(pc, 1)
    return (empty & ~reached(empty))[1:-1, 1:-1, 1:-1]


def _thin_grids():
    # Two walls one cell apart, as an open_faces grid one supercell thick along x has (a head
    # MR scan, iso 1.5, supercell (47, 1, 1)): more seeds pending than cells, and the fill's
    # stack overran its array (heap corruption, the process aborted).
    walls = np.ones((43, 63, 3), dtype=bool)
    walls[1:-1, 1:-1, 1] = False
    yield walls
    rng = np.random.default_rng(5)
    for _ in range(6):
        shape = tuple(rng.permutation([int(rng.integers(20, 50)), int(rng.integers(20, 50)), 3]))
        grid = rng.random(shape) < 0.8
        grid[0, 0, 0] = True
        yield grid
    yield walls.transpose(2, 0, 1).copy()
    # One-cell runs (found by search) where a run's 8 neighbouring rows push ceil(L/2) seeds each
    # (L = hi - lo + 3) into a nearly full stack: reserving less than 8 * (L // 2 + 1) overruns it.
    bits = bytes.fromhex("8aaba3a28a888a848aaa2aa8eb82da86babae22a8ba2aaee")
    yield np.unpackbits(np.frombuffer(bits, np.uint8)).astype(bool).reshape(4, 6, 8)


@pytest.mark.parametrize("empty", list(_thin_grids()), ids=lambda e: "x".join(map(str, e.shape)))
def test_flood_fill_of_a_thin_grid(empty):
    from parc import origins
    np.testing.assert_array_equal(origins.flood_from_corner(empty), reached(empty))
    # The kernel's Python twin raises where the compiled one would write past its stack.
    nz, ny, nx = (n + 2 for n in empty.shape)
    cells = np.pad(empty, 1).ravel()
    left = cells.copy()
    origins._flood.py_func(left, ny, nx, (ny + 1) * nx + 1)
    cleared = (cells & ~left).reshape(nz, ny, nx)[1:-1, 1:-1, 1:-1]
    np.testing.assert_array_equal(cleared, reached(empty))


@pytest.mark.parametrize("size", [1, 1.5, 2], ids=str)
def test_cavity_faces_found(size):
    """Faces bordering only cavities are told apart from the rest (no GL needed)."""
    from parc.origins import open_faces
    _, proxy = _shell_proxy(size)
    is_open, cavity = open_faces(proxy)
    ref = _cavity_reference(proxy.pc)
    assert ref.any()
    np.testing.assert_array_equal(cavity, ref)
    # A face is open when any of its unit faces has a non-cavity empty supercell behind it.
    shape = proxy.pc.shape
    for q, (a, plane, u0, u1, v0, v1) in enumerate(proxy.faces):
        side = plane if proxy.outward[q] > 0 else plane - 1
        expect = False
        for uu in range(u0, u1):
            for vv in range(v0, v1):
                xyz = [0, 0, 0]
                xyz[a], xyz[(a + 1) % 3], xyz[(a + 2) % 3] = side, uu, vv
                k = (xyz[2], xyz[1], xyz[0])
                outside = not all(0 <= c < n for c, n in zip(k, shape))
                expect |= outside or not ref[k]
        assert is_open[q] == expect, (q, proxy.faces[q])


@pytest.mark.parametrize("size", [1, 1.5], ids=str)
@pytest.mark.parametrize("where", ["outside", "cavity", "cavity corner", "near cavity"])
def test_cavity_views_perspective(gl, looseness, size, where):
    """Cavity faces are skipped only while the eye is outside every cavity box."""
    vol, proxy = _shell_proxy(size)
    cav = np.argwhere(_cavity_reference(proxy.pc))
    kz, ky, kx = cav[len(cav) // 2]
    ex, ey, ez = proxy.world_edges
    if where == "outside":
        cam = Camera.framing(*vol.bounds, azimuth=40, elevation=25, zoom=1.2)
    else:
        eye = _centre(proxy, kx, ky, kz)
        if where == "cavity corner":
            eye = np.array([ex[kx], ey[ky + 1], ez[kz]])
        elif where == "near cavity":
            # In the PC shell a hair outside the cavity box: every ray starts inside.
            eye = np.array([ex[kx] - 1e-9, (ey[ky] + ey[ky + 1]) / 2, (ez[kz] + ez[kz + 1]) / 2])
        cam = Camera(eye=tuple(eye), look_at=tuple(eye + np.array([0.4, 1.0, -0.3])), up=(0, 0, 1), fov=110.0)
    seg, _, _ = _check(cam, proxy, 40, 36, f"cavity per {where} s={size}", looseness)
    skipped = seg.info["drawn"] < proxy.n_polygons
    assert skipped == (where in ("outside", "near cavity"))
    assert seg.polygons == seg.info["drawn"]        # the stats count what was drawn


@pytest.mark.parametrize("through", [False, True], ids=["before", "through"])
def test_cavity_views_parallel(gl, looseness, through):
    """Parallel rays start on the view plane: a plane through a cavity draws every face."""
    vol, proxy = _shell_proxy(1)
    c = vol.center
    f = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    eye = c if through else c - 30.0 * f
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + f), up=(0, 1, 0), parallel_scale=8.0)
    seg, _, _ = _check(cam, proxy, 40, 40, f"cavity par {'through' if through else 'before'}", looseness)
    assert (seg.info["drawn"] == proxy.n_polygons) == through


def test_empty_proxy_has_no_segments(gl):
    vol = smooth_volume(1)
    idx = VolumeIndex.of(vol)
    grid = idx.grid(2)
    pc = idx.classify(1e9, 2)
    proxy = build_proxy(grid, pc, grid.world_edges(vol))
    assert proxy.n_polygons == 0
    seg = raster_segments(Camera.framing(*vol.bounds), 16, 12, proxy)
    assert (seg.near > seg.far).all()


def test_reuses_upload_and_reports_timing(gl):
    vol = smooth_volume(2)
    proxy = _proxy(vol, 1)
    cam = Camera.framing(*vol.bounds)
    a = raster_segments(cam, 20, 10, proxy)
    b = raster_segments(cam, 20, 10, proxy)
    assert b.seconds["upload"] == 0.0
    for key in ("prepare", "upload", "draw", "readback", "post", "total"):
        assert key in a.seconds and a.seconds[key] >= 0
    np.testing.assert_array_equal(a.near, b.near)
    np.testing.assert_array_equal(a.far, b.far)
    assert 0 < a.polygons == a.info["drawn"] <= proxy.n_polygons
    assert a.seg.shape == (10, 20, 2)


def test_margin_is_small_against_cells():
    """The read-back margin is ~1e-6 of the scene scale: far below a cell for sane volumes."""
    assert margin(100.0, 300.0) < 1e-3
    assert margin(1.0, 1.0) > 2.0 ** -24


def test_opengl_unavailable_is_an_input_error(monkeypatch):
    """No EGL: a distinct InputError with one clear line (no GL needed for this test)."""
    import moderngl

    from data_tools import InputError
    from parc import gl

    def fail(**kwargs):
        raise Exception("eglGetDisplay failed\nsecond line of driver noise")

    monkeypatch.setattr(gl, "_CONTEXT", None)
    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    with pytest.raises(gl.OpenGLUnavailable) as err:
        gl.get_context()
    assert issubclass(gl.OpenGLUnavailable, InputError)
    msg = str(err.value)
    assert "\n" not in msg and "OpenGL is not available" in msg and "eglGetDisplay failed" in msg


def test_compare_says_there_is_no_opengl_before_any_render(monkeypatch):
    """Not after brute's warm-up, which on a large scene takes a while."""
    import moderngl

    import parc.comparison as comparison
    from data_tools.synthetic import blobs
    from parc import Isosurface, Scene, gl
    rendered = []

    def fail(**kwargs):
        raise Exception("eglGetDisplay failed")

    monkeypatch.setattr(gl, "_CONTEXT", None)
    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    monkeypatch.setattr(comparison, "render", lambda *args, **kwargs: rendered.append(kwargs))
    vol = blobs(6, seed=1)
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(8, 8), volumes=[Isosurface(vol, 100.5)])
    with pytest.raises(gl.OpenGLUnavailable):
        comparison.compare(scene, methods=("brute", "parc"), repeats=1)
    assert rendered == []


def test_the_drivers_warnings_are_held_back_while_the_context_is_made(monkeypatch):
    """Mesa's EGL warnings would come before the one error line: quiet unless the user set
    EGL_LOG_LEVEL, and the environment is as it was afterwards."""
    import moderngl

    from parc import gl
    seen = []

    def fail(**kwargs):
        seen.append(os.environ.get("EGL_LOG_LEVEL"))
        raise Exception("eglInitialize failed (0x3001)")

    monkeypatch.setattr(gl, "_CONTEXT", None)
    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    monkeypatch.delenv("EGL_LOG_LEVEL", raising=False)
    with pytest.raises(gl.OpenGLUnavailable, match="EGL_LOG_LEVEL=debug shows the driver's own messages"):
        gl.get_context()
    assert seen == ["fatal"] and "EGL_LOG_LEVEL" not in os.environ
    monkeypatch.setenv("EGL_LOG_LEVEL", "debug")
    with pytest.raises(gl.OpenGLUnavailable) as err:
        gl.get_context()
    assert seen == ["fatal", "debug"] and os.environ["EGL_LOG_LEVEL"] == "debug"
    assert "EGL_LOG_LEVEL" not in str(err.value)


def test_no_opengl_is_one_line_on_stderr(tmp_path):
    """With Mesa asked for a driver it lacks, the whole of stderr is the error line (where the
    driver is not Mesa's, the render works, and there is nothing to see)."""
    env = dict(os.environ, GALLIUM_DRIVER="no-such-driver", MESA_LOADER_DRIVER_OVERRIDE="no-such-driver")
    env.pop("EGL_LOG_LEVEL", None)
    # --quiet: no first-compile notice, which a fresh cache would give before the failure.
    p = subprocess.run([sys.executable, "-m", "parc.cli", "render", "--method", "parc", "--size", "8", "8", "--quiet",
                        "-o", str(tmp_path / "a.png")], env=env, capture_output=True, text=True)
    if p.returncode == 0:
        pytest.skip("this machine's EGL does not go through Mesa's drivers")
    assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr
    assert p.stderr.startswith("parc: error: OpenGL is not available"), p.stderr
    assert not (tmp_path / "a.png").exists()


@pytest.mark.parametrize("w, h", [(1, 1), (3, 61), (57, 2)])
def test_extreme_image_shapes(gl, looseness, w, h):
    vol = smooth_volume(5)
    proxy = _proxy(vol, 1, frac=0.6)
    cam = Camera.framing(*vol.bounds, azimuth=10, elevation=30, zoom=3.0)
    seg = raster_segments(cam, w, h, proxy)
    near_ref, far_ref = segments_reference(cam, w, h, proxy, touch=1e-12 * seg.info["scale"])
    meet = np.isfinite(near_ref)
    assert (seg.near[meet] <= near_ref[meet]).all() and (seg.far[meet] >= far_ref[meet]).all()


def _one_box_proxy():
    """A proxy of one PC supercell, the box [0, 4]^3."""
    from parc.ranges import supercell_grid
    vol = Volume(np.zeros((5, 5, 5), np.float32))
    grid = supercell_grid((5, 5, 5), 4)
    return build_proxy(grid, np.ones((1, 1, 1), bool), grid.world_edges(vol))


def _inside_below_the_top_face(width, height, fov, clips):
    """`_one_box_proxy`, and a camera inside it looking along +x with the top face ``clips``
    times ``clip_near`` above the eye, and that gap."""
    from parc.raster import INSIDE_CLIP_REL, scene_scale
    proxy = _one_box_proxy()
    eye = np.array([0.5, 2.0, 4.0])

    def camera(at):
        return Camera(eye=tuple(at), look_at=tuple(at + np.array([1.0, 0.0, 0.0])), up=(0, 0, 1), fov=fov)

    gap = clips * INSIDE_CLIP_REL * scene_scale(camera(eye), *proxy.bounds, width / height)
    eye[2] -= gap
    return proxy, camera(eye), gap


@pytest.mark.parametrize("width, height, fov, clips, band", [(16, 40, 160.0, 3.0, (2.5, 3.5)),
                                                             (4, 64, 170.0, 6.0, (4.0, 8.0))], ids=["wide", "tall"])
def test_eye_inside_a_hair_below_a_face_raises_far_past_the_clipped_sliver(gl, looseness, width, height, fov, clips,
                                                                         band):
    """An eye inside the PC region clips faces at ``clip_near`` ahead of it: a wide-angle ray
    that leaves through a face a few ``clip_near`` away, at a forward distance below it, has
    no fragment, and its far must come from the CPU's raise to ``2 clip_near / cos_max``
    (``cos_max`` the widest ray's cosine), not ``2 clip_near``: here such rays leave at about
    ``clips`` times ``clip_near``. In a tall, narrow image the widest ray leans far up or
    down, not sideways: a cosine from the horizontal extent alone would raise far to only
    ~3.5 ``clip_near`` there. Truth: the reference's exit through the face."""
    proxy, camera, gap = _inside_below_the_top_face(width, height, fov, clips)
    seg, near_ref, far_ref = _check(camera, proxy, width, height, f"eye a hair below a face, {width}x{height}",
                                    looseness)
    clip = seg.info["clip_near"]
    assert seg.info["eye_inside"] and clips - 0.1 < gap / clip < clips + 0.1
    # Rays that leave through the top face before the clip plane, but after 2 clip_near:
    sliver = (far_ref > band[0] * clip) & (far_ref < band[1] * clip)
    assert sliver.sum() >= width
    assert (seg.near[sliver] == 0).all() and (seg.far[sliver] >= far_ref[sliver]).all()
    assert seg.info["pixels"] == np.count_nonzero(seg.near <= seg.far) == width * height


def test_parallel_view_plane_a_hair_before_a_face_keeps_it(gl, looseness):
    """A parallel view clips faces a rounding *behind* its view plane, never in front of it:
    a face a few roundings ahead (two ``TOL_REL`` of the scene scale, far more than the
    origins' own rounding, so no ray starts on the box) bounds near."""
    from parc.raster import TOL_REL, scene_scale
    proxy = _one_box_proxy()
    width, height = 20, 16

    def camera(x):
        return Camera(eye=(x, 2.0, 2.0), look_at=(x + 1.0, 2.0, 2.0), up=(0, 0, 1), parallel_scale=3.0)

    gap = 2.0 * TOL_REL * scene_scale(camera(0.0), *proxy.bounds, width / height)
    seg, near_ref, _ = _check(camera(-gap), proxy, width, height, "parallel plane a hair before a face", looseness)
    assert not seg.info["eye_inside"]
    face = np.isfinite(near_ref)
    assert face.sum() > width and (near_ref[face] > 0).all() and (near_ref[face] < 2 * gap).all()
    assert seg.info["pixels"] == np.count_nonzero(seg.near <= seg.far)


# Tightness on generic views. `_check` allows 10 cells of slack (1 on average) and extra pixels
# within a 2-pixel dilation because grazing and eye-inside views need it; on generic views the
# segments are within 2e-3 cells of the truth and no pixel without a PC box gets one, so a
# loosened bound (extra work only, invisible in the image) is caught here.
# Truth: `parc_reference.segments_reference` -- the caster's float64 ray of every pixel against
# every PC supercell box by the slab test, in plain NumPy.

@pytest.mark.parametrize("size", SIZES, ids=str)
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("parallel", [False, True], ids=["persp", "parallel"])
def test_generic_views_are_tight_to_a_hundredth_of_a_cell(gl, size, seed, parallel):
    vol = smooth_volume(seed, spacing=(1.0, 0.8, 1.3), origin=(2.0, -1.0, 0.5))
    proxy = _proxy(vol, size)
    rng = np.random.default_rng(100 + seed)
    cam = Camera.framing(*vol.bounds, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-80, 80),
                         parallel=parallel, zoom=rng.uniform(0.8, 1.6), fov=rng.uniform(20, 70))
    seg = raster_segments(cam, 48, 36, proxy)
    near_ref, far_ref = segments_reference(cam, 48, 36, proxy, touch=1e-12 * seg.info["scale"])
    meet = np.isfinite(near_ref)
    assert meet.sum() > 100
    # Conservative (as `_check`) ...
    assert (seg.near[meet] <= near_ref[meet]).all() and (seg.far[meet] >= far_ref[meet]).all()
    # ... and tight: a pixel has a segment exactly where its ray meets a PC box, and its ends
    # are within 1/100 of the smallest spacing (0.8) of the box crossings.
    assert np.array_equal(seg.near <= seg.far, meet)
    cell = 0.8
    assert (near_ref[meet] - seg.near[meet]).max() <= 0.01 * cell
    assert (seg.far[meet] - far_ref[meet]).max() <= 0.01 * cell


def _rays_through_squares(camera, width, height, jx, jy):
    """The caster's ray formula through point ``(x + jx, y + jy)`` of every pixel's square instead of
    its centre ``(x + 0.5, y + 0.5)``: origins, directions (H, W, 3)."""
    f, r, u = camera.basis()
    sx = (2.0 * (np.arange(width) + jx) / width - 1.0) * (width / height)
    sy = 1.0 - 2.0 * (np.arange(height) + jy) / height
    sx, sy = np.meshgrid(sx, sy)
    side = sx[..., None] * np.asarray(r) + sy[..., None] * np.asarray(u)
    if camera.parallel:
        o = np.asarray(camera.eye) + camera.parallel_scale * side
        d = np.broadcast_to(np.asarray(f, dtype=np.float64), o.shape)
    else:
        d = np.asarray(f) + np.tan(np.radians(camera.fov) / 2.0) * side
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        o = np.broadcast_to(np.asarray(camera.eye, dtype=np.float64), d.shape)
    return o, d


@pytest.mark.parametrize("parallel", [False, True], ids=["persp", "parallel"])
@pytest.mark.parametrize("seed", [0, 1])
def test_face_ranges_bound_every_ray_through_the_pixel(gl, parallel, seed):
    """The light buffers' mode (``face_range``, a pad over half a pixel): a pixel's segment holds the
    entry and exit of every ray through its square, not only of its centre ray. Truth: rays through
    the square's corners, its centre and random points, each against every PC box by the slab test."""
    from parc.lights import LIGHT_PAD_PX
    from parc_reference import pc_boxes, ray_box_batches
    vol = smooth_volume(20 + seed, dims=(10, 9, 8), spacing=(1.0, 0.8, 1.3))
    grid, pc = band_classes(vol, 1)
    proxy = build_proxy(grid, pc, grid.world_edges(vol), merge=False)
    rng = np.random.default_rng(seed)
    cam = Camera.framing(*vol.bounds, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-60, 60),
                         parallel=parallel, zoom=1.2, fov=40.0)
    w, h = 24, 20
    seg = raster_segments(cam, w, h, proxy, pad_px=LIGHT_PAD_PX, face_range=True)
    lo, hi = pc_boxes(proxy)
    points = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5), *rng.uniform(0, 1, (6, 2))]
    met = 0
    for jx, jy in points:
        o, d = _rays_through_squares(cam, w, h, jx, jy)
        near = np.full(w * h, np.inf)
        far = np.full(w * h, -np.inf)
        for _, enter, leave, meet in ray_box_batches(o, d, lo, hi, 1e-12 * seg.info["scale"]):
            near = np.minimum(near, np.where(meet, enter, np.inf).min(axis=1))
            far = np.maximum(far, np.where(meet, np.maximum(leave, enter), -np.inf).max(axis=1))
        near, far = near.reshape(h, w), far.reshape(h, w)
        meet = np.isfinite(near)
        met += meet.sum()
        bad = meet & ~((seg.near <= near) & (seg.far >= far))
        assert not bad.any(), (f"ray through ({jx:.2f}, {jy:.2f}) of pixels {np.argwhere(bad)[:4].tolist()}: "
                               f"[{near[bad][:4]}, {far[bad][:4]}] not in [{seg.near[bad][:4]}, {seg.far[bad][:4]}]")
    assert met > 100 * len(points)


@pytest.mark.parametrize("view", AXES, ids=lambda v: "f=" + ",".join(map(str, v[0])))
def test_a_wide_short_image_keeps_rays_on_grid_edges_along_its_rows(gl, looseness, view):
    """The coverage pad is a fraction of a pixel on each axis: an image 256 times wider than high has
    pixels as tall as wide, so its vertical pad must come from the height, not the width. Half the
    rows of this parallel view run along grid lines (as `test_axis_aligned_parallel_rays_on_grid_edges`)."""
    vol = smooth_volume(7, dims=(9, 9, 9))
    proxy = _proxy(vol, 1, frac=0.5)
    f, up = np.array(view[0], float), view[1]
    eye = np.full(3, 4.25) - 20.0 * f
    w, h = 2048, 8
    # Pixels 0.5 wide: origins step by 0.5 from 4.25, every other row and column on integer lines.
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + f), up=up, parallel_scale=2.0)
    o = _origins(cam, w, h)
    across = np.abs(o - np.round(o)) * (f == 0) == 0
    assert across.all(axis=-1).sum() >= 30
    _check(cam, proxy, w, h, f"wide short par f={view[0]}", looseness)


def test_parallel_view_plane_closer_to_a_face_than_its_bound_gives_near_0(gl, looseness):
    """A face ahead of the view plane by less than the bound's own width (``t - e < 0``, though
    ``t > 0`` and no ray starts on the box): near is 0, never before the ray's start."""
    from parc.raster import ABS_TOL, scene_scale
    proxy = _one_box_proxy()
    width, height = 20, 16

    def camera(x):
        return Camera(eye=(x, 2.0, 2.0), look_at=(x + 1.0, 2.0, 2.0), up=(0, 0, 1), parallel_scale=3.0)

    gap = 0.5 * ABS_TOL * scene_scale(camera(0.0), *proxy.bounds, width / height)
    seg, near_ref, _ = _check(camera(-gap), proxy, width, height, "parallel plane within the bound of a face",
                              looseness)
    face = np.isfinite(near_ref)
    assert not seg.info["eye_inside"] and face.sum() > width and (near_ref[face] > 0).all()
    assert (seg.near[face] == 0).all()
