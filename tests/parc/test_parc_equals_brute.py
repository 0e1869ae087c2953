"""Depth-buffer PARC against the unaccelerated caster on random scenes.

Truth: ``method="brute"`` on the same scene. PARC only narrows each ray to
the segment its OpenGL pass found; the traversal and the cubic are the same
code, so every pixel must agree: identical hit masks, depths within 1e-9
of a cell, colours within 1e-6 (DESIGN.md, "Correctness").
"""
import math

import numpy as np
import pytest

from data_tools import Volume
from data_tools.synthetic import blobs, ct_phantom, trilinear_field
from parc import Camera, Isosurface, Scene, TransferFunction, Translucent, render
from parc.classify import VolumeIndex

SUPERCELLS = (0.5, 1, 2, 3, 4.5, 8, (2, 3, 1.5))
VIEWS = ("perspective", "parallel", "closeup", "axis_perspective", "axis_parallel", "inside", "inside_pc")
SIZE = (40, 32)


def _volume(rng, kind):
    spacing = tuple(rng.uniform(0.5, 2.0, 3)) if rng.random() < 0.6 else (1.0, 1.0, 1.0)
    origin = tuple(rng.uniform(-50, 50, 3)) if rng.random() < 0.5 else (0.0, 0.0, 0.0)
    dims = tuple(int(n) for n in rng.integers(9, 20, 3))
    if kind == "noise_uint8":
        data = rng.integers(0, 256, dims[::-1]).astype(np.uint8)
    elif kind == "noise_float32":
        data = rng.normal(size=dims[::-1]).astype(np.float32)
    elif kind == "blobs":
        data = blobs(dims, seed=int(rng.integers(1 << 30))).data
    elif kind == "ct_int16":
        # Shifted as Hounsfield units are, so that int16's negative samples are cast too.
        data = ct_phantom(dims, seed=int(rng.integers(1 << 30)), dtype="int16").data - np.int16(1024)
    elif kind == "ct_uint16":
        data = ct_phantom(dims, seed=int(rng.integers(1 << 30)), dtype="uint16").data
    else:
        data = trilinear_field(dims, seed=int(rng.integers(1 << 30)), dtype="float32").data
    return Volume(data, spacing=spacing, origin=origin, name=kind)


def _isovalue(rng, vol):
    lo, hi = vol.value_range()
    if rng.random() < 0.25:
        return float(vol.data.flat[rng.integers(vol.data.size)])   # equal to a sample
    return float(rng.uniform(lo, hi))


def _camera(rng, vol, view, iso, supercell):
    lo, hi = vol.bounds
    c = vol.center
    if view in ("perspective", "parallel"):
        return Camera.framing(lo, hi, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-80, 80),
                              zoom=rng.uniform(0.8, 2.5), parallel=view == "parallel",
                              fov=rng.uniform(15, 70))
    if view == "closeup":
        # A few cells across the image, nearly pole-on at times: one supercell
        # face covers many pixels, and rays graze faces at any angle.
        return Camera.framing(lo, hi, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-89.9, 89.9),
                              zoom=rng.uniform(4, 12), parallel=rng.random() < 0.5, fov=rng.uniform(3, 120))
    if view.startswith("axis"):
        axis = rng.integers(3)
        e = np.zeros(3)
        e[axis] = rng.choice([-1.0, 1.0]) * 2.5 * np.linalg.norm(hi - lo)
        up = np.zeros(3)
        up[(axis + 1) % 3] = 1.0
        if rng.random() < 0.5:
            # On a line of samples: with the image's odd size, the middle ray runs along cell edges.
            c = lo + np.round((c - lo) / vol.spacing) * vol.spacing
        if view == "axis_parallel":
            return Camera(eye=tuple(c + e), look_at=tuple(c), up=tuple(up),
                          parallel_scale=0.3 * float(np.linalg.norm(hi - lo)))
        return Camera(eye=tuple(c + e), look_at=tuple(c), up=tuple(up), fov=25.0)
    if view == "inside":
        eye = lo + rng.uniform(0.1, 0.9, 3) * (hi - lo)
    else:
        index = VolumeIndex.of(vol)
        pc = np.argwhere(index.classify(iso, supercell))
        grid = index.grid(supercell)
        edges = grid.world_edges(vol)
        if len(pc) == 0:
            eye = lo + rng.uniform(0.1, 0.9, 3) * (hi - lo)
        else:
            k, j, i = pc[rng.integers(len(pc))]
            cell_lo = np.array([edges[0][i], edges[1][j], edges[2][k]])
            cell_hi = np.array([edges[0][i + 1], edges[1][j + 1], edges[2][k + 1]])
            eye = cell_lo + rng.uniform(0.2, 0.8, 3) * (cell_hi - cell_lo)
    look = eye + rng.normal(size=3)
    if rng.random() < 0.5:
        return Camera(eye=tuple(eye), look_at=tuple(look), up=(0.3, 0.2, 1.0), fov=rng.uniform(30, 90))
    return Camera(eye=tuple(eye), look_at=tuple(look), up=(0.3, 0.2, 1.0),
                  parallel_scale=0.4 * float(np.linalg.norm(hi - lo)))


KINDS = ("noise_uint8", "noise_float32", "blobs", "ct_int16", "ct_uint16", "trilinear")
#: Each test scene shows the surface in at least this many pixels (drawn up to MAX_DRAWS times).
MIN_HITS = 10
MAX_DRAWS = 20


@pytest.mark.random_scenes(216)
def test_parc_equals_brute(seed, gl):
    rng = np.random.default_rng(seed)
    kind = KINDS[seed % len(KINDS)]
    # Every view with every supercell size in each 49 seeds.
    view = VIEWS[(seed // len(SUPERCELLS)) % len(VIEWS)]
    supercell = SUPERCELLS[seed % len(SUPERCELLS)]
    # Odd sizes for the views along an axis: the middle pixel's ray is exactly along it.
    size = (41, 33) if view.startswith("axis") else SIZE
    vol = _volume(rng, kind)
    # A scene that shows nothing cannot show a missed hit, PARC's likeliest fault: another
    # level and view are drawn until brute hits something.
    for _ in range(MAX_DRAWS):
        iso = _isovalue(rng, vol)
        cam = _camera(rng, vol, view, iso, supercell)
        scene = Scene(camera=cam, size=size, volumes=[Isosurface(vol, iso)])
        ref = render(scene, method="brute", work=True)
        if np.isfinite(ref.depth).sum() >= MIN_HITS:
            break
    res = render(scene, method="parc", supercell=supercell, work=True)

    where = f"{kind} {view} supercell={supercell} iso={iso:g}"
    hit_ref, hit = np.isfinite(ref.depth), np.isfinite(res.depth)
    assert hit_ref.sum() >= MIN_HITS, f"no scene of {MAX_DRAWS} drawn shows the surface: {where}"
    assert (hit == hit_ref).all(), f"hit masks differ at {np.argwhere(hit != hit_ref)[:5].tolist()}: {where}"
    cell = min(vol.spacing)
    assert np.abs(res.depth[hit] - ref.depth[hit]).max(initial=0) <= 1e-9 * cell, where
    assert np.abs(res.image - ref.image).max() <= 1e-6, where
    # PARC walks part of each ray brute walks: never more cells at any pixel.
    assert res.work.sum() == res.stats["cells_visited"] and ref.work.sum() == ref.stats["cells_visited"], where
    more = np.argwhere(res.work > ref.work)[:5].tolist()
    assert not more, f"parc visits more cells than brute at {more}: {where}"


def _wide_camera(rng, vol):
    """A perspective view 120 degrees wide to a ten-millionth of a degree short of 180, from
    outside the volume (along an axis half the time: the central ray meets a face head-on) or
    inside it. Across the image the directions reach tan(fov / 2), up to 1e9 times the
    central one, and their float32 roundings in the OpenGL pass can pass its length."""
    lo, hi = vol.bounds
    ext = float(np.linalg.norm(hi - lo))
    fov = float(rng.uniform(120, 179)) if rng.random() < 0.3 else 180.0 - 10.0 ** rng.uniform(-7, -4)
    look = vol.center + rng.normal(size=3) * 0.05 * (hi - lo)
    if rng.random() < 0.2:
        return Camera(eye=tuple(lo + rng.uniform(0.1, 0.9, 3) * (hi - lo)), look_at=tuple(look),
                      up=(0.3, 0.2, 1.0), fov=fov)
    if rng.random() < 0.5:
        axis = rng.integers(3)
        d = np.zeros(3)
        d[axis] = rng.choice([-1.0, 1.0])
        eye = look - d * ((hi - lo)[axis] / 2 + ext * rng.uniform(0.02, 0.5))
    else:
        d = rng.normal(size=3)
        eye = look - d / np.linalg.norm(d) * ext * rng.uniform(0.55, 1.0)
    return Camera(eye=tuple(eye), look_at=tuple(look), up=(0.3, 0.2, 1.0), fov=fov)


#: Draws for a wide view. Nearly 180 degrees wide, every ray of the image but the central one
#: runs almost sideways, so a small surface shows only where that one ray meets it. Of 500
#: isosurface scenes in a soak (`--soak-start 4600000`), one of blobs took 23 draws and every
#: other 8 or fewer.
WIDE_DRAWS = 100


@pytest.mark.random_scenes(30)
def test_parc_equals_brute_in_wide_views(seed, gl):
    rng = np.random.default_rng(seed)
    kind = KINDS[seed % len(KINDS)]
    what = ("iso", "depth", "bits", "depth,bits")[seed % 4]
    supercell = SUPERCELLS[seed % len(SUPERCELLS)]
    vol = _volume(rng, kind)
    lo, hi = vol.value_range()
    for _ in range(WIDE_DRAWS):
        level = _isovalue(rng, vol)
        # Translucent: faint below the level, a jump there (a bright shell), fading above.
        ramp = [[lo, 0.05], [level, 0.05], [level, 0.6], [hi, 0.2]] if lo < level < hi else [[lo, 0.3], [hi, 0.3]]
        vis, kwargs = _shown(vol, what, level, ramp)
        scene = Scene(camera=_wide_camera(rng, vol), size=(25, 19), volumes=[vis])
        ref = render(scene, method="brute")
        if ref.image[..., 3].any():
            break
    res = render(scene, method="parc", supercell=supercell, **kwargs)

    where = f"{kind} {what} supercell={supercell} fov={scene.camera.fov!r} level={level:g}"
    assert ref.image[..., 3].any(), f"no scene of {WIDE_DRAWS} drawn shows the volume: {where}"
    hit_ref, hit = np.isfinite(ref.depth), np.isfinite(res.depth)
    assert (hit == hit_ref).all(), f"hit masks differ at {np.argwhere(hit != hit_ref)[:5].tolist()}: {where}"
    assert np.abs(res.depth[hit] - ref.depth[hit]).max(initial=0) <= 1e-9 * min(vol.spacing), where
    assert np.abs(res.image - ref.image).max() <= 1e-6, where


def _same_hits(scene, supercell):
    """``parc`` hits exactly ``brute``'s pixels, at exactly its depths (and ``brute`` hits some)."""
    ref = render(scene, method="brute")
    res = render(scene, method="parc", supercell=supercell)
    hit_ref, hit = np.isfinite(ref.depth), np.isfinite(res.depth)
    assert hit_ref.any()
    assert (hit == hit_ref).all(), np.argwhere(hit != hit_ref)[:5].tolist()
    assert np.abs(res.depth[hit] - ref.depth[hit]).max() == 0.0


def _turned(v, k):
    """``v`` (x, y, z) with its components moved ``k`` axes on: x to y to z to x. A cyclic turn
    keeps cross products, so a camera and grid turned together round every coordinate as before."""
    return tuple(v[(i - k) % 3] for i in range(3))


@pytest.mark.parametrize("supercell", [1, 2, 0.5])
@pytest.mark.parametrize("face", ["y", "z", "x"])
def test_parallel_origins_a_rounding_outside_a_face(face, supercell, gl):
    """A parallel view whose view plane is the volume's top face: some ray origins lie an ulp
    above the face in world coordinates but exactly on it in index space, where the caster
    walks along the face and hits; PARC must start them at 0 too. The scene is turned so that
    the face is each axis's in turn: each axis has its own test of the origins against the PC
    boxes."""
    k = "yzx".index(face)
    spacing = (0.2732131732465832, 0.1507867643309695, 0.09822305326164066)
    origin = (0.009136035710226587, -1.3579376261686327, -1.2224217394590022)
    nx, ny, nz = 19, 12, 27
    xyz = np.zeros((nx, ny, nz), np.uint8)    # indexed (x, y, z) until turned
    xyz[:, ny - 2, :] = 255                   # every top cell holds the level
    xyz[:6, ny - 1, :] = 255                  # and the face itself, for x index <= 5
    xyz = np.transpose(xyz, [(a - k) % 3 for a in range(3)])
    vol = Volume(np.ascontiguousarray(xyz.transpose(2, 1, 0)), spacing=_turned(spacing, k),
                 origin=_turned(origin, k))
    top = vol.bounds[1][(1 + k) % 3]
    cam = Camera(eye=_turned((3.9858175543691035, top, -0.8885672103796098), k),
                 look_at=_turned((-1.798484276041866, top, -0.8885672103796098), k),
                 up=_turned((0.3, 1.0, -0.2), k), parallel_scale=2.99080141420043)
    o, _ = cam.rays(14, 44)
    assert (o[..., (1 + k) % 3] > top).any()   # the case: origins outside by a rounding
    _same_hits(Scene(camera=cam, size=(14, 44), volumes=[Isosurface(vol, 128.0)]), supercell)


@pytest.mark.parametrize("supercell", [(1e-3, 100, 100), (1e-3, 1, 1)])
def test_parallel_origins_in_supercells_thinner_than_their_rounding(supercell, gl):
    """A volume 2^32 - 16 cells from 0 along x: a parallel view's ray origins count as inside
    the PC boxes within 2^-40 of the scene's scale (0.004 cells) of them, a reach spanning
    several supercells a thousandth of a cell thick. The rays start inside the one holding the
    surface x = 5.0005 and run nearly along its faces (1e-5 cells of x a unit of y), so they
    entered it behind the view plane farther than the pass clips (4 units): PARC must take
    them as starting inside."""
    x0 = 2.0 ** 32 - 16
    data = np.broadcast_to(np.arange(11, dtype=np.float32), (11, 41, 11)).copy()
    vol = Volume(data, origin=(x0, 0.0, 0.0))
    eye = (x0 + 5.00045, 20.0, 5.0)
    cam = Camera(eye=eye, look_at=(eye[0] + 1e-5, 21.0, 5.0), up=(0, 0, 1), parallel_scale=1e-4)
    _same_hits(Scene(camera=cam, size=(9, 3), volumes=[Isosurface(vol, 5.0005)]), supercell)


@pytest.mark.parametrize("buffers", ["depth", "bits"])
@pytest.mark.parametrize("supercell", [1, 2, 0.5])
@pytest.mark.parametrize("look", [(1.45, 0.45, 0.9), (0.45, 0.45, 2.0)])
def test_perspective_eye_a_rounding_outside_a_face(look, supercell, buffers, gl):
    """The same for a perspective eye: 0.9 lies an ulp above the top face (3 x 0.3), and in
    index space, 0.9 / 0.3 = 3, on it. ``brute``'s rays that leave at once take the face's
    samples, or its level, at t = 0; PARC took the eye for outside and gave them no segment."""
    data = np.full((4, 4, 4), 100, np.uint8)
    data[0, 0, 0] = 0
    vol = Volume(data, spacing=(0.3, 0.3, 0.3))
    assert vol.bounds[1][2] < 0.9 and 0.9 / 0.3 == 3.0          # the case
    cam = Camera(eye=(0.45, 0.45, 0.9), look_at=look, up=(0, 1, 0) if look[2] == 2.0 else (0, 0, 1), fov=90)
    if buffers == "depth":
        _same_hits(Scene(camera=cam, size=(16, 16), volumes=[Isosurface(vol, 100.0)]), supercell)
    scene = Scene(camera=cam, size=(16, 16), volumes=[Translucent(vol, TransferFunction([[0, 0.5], [255, 0.5]]))])
    ref = render(scene, method="brute")
    assert ref.image[..., 3].max() > 0.0
    assert np.array_equal(render(scene, method="parc", supercell=supercell, buffers=buffers).image, ref.image)


@pytest.mark.parametrize("supercell", [1, 2, 0.5])
@pytest.mark.parametrize("what", ["iso", "translucent"])
def test_parallel_origins_a_rounding_past_the_face_the_rays_leave_by(what, supercell, gl):
    """The parallel case of the one above, looking away: every origin lies an ulp above the top
    face (0.9), on it in index space, and ``brute``'s rays take its level or samples at t = 0
    as they leave. No face lies ahead of them: PARC must still give them a segment from 0."""
    data = np.full((4, 4, 4), 100, np.uint8)
    data[0, 0, 0] = 0
    vol = Volume(data, spacing=(0.3, 0.3, 0.3))
    cam = Camera(eye=(0.45, 0.45, 0.9), look_at=(0.45, 0.45, 2.0), up=(0, 1, 0), parallel_scale=0.5)
    shown = Isosurface(vol, 100.0) if what == "iso" else Translucent(vol, TransferFunction([[0, 0.5], [255, 0.5]]))
    scene = Scene(camera=cam, size=(16, 16), volumes=[shown])
    ref = render(scene, method="brute")
    assert (ref.image[..., 3] > 0).sum() > 100
    res = render(scene, method="parc", supercell=supercell)
    assert np.array_equal(np.isfinite(res.depth), np.isfinite(ref.depth))
    assert np.abs(res.image - ref.image).max() <= 1e-6


@pytest.mark.parametrize("supercell", [0.5, 0.25, 0.125])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_distant_parallel_eye_and_a_steep_field(seed, supercell, gl):
    """An eye 3e8 units away looking straight down y, float32 samples from -3e38 to 3e38,
    sub-cell supercells: positions measured from the eye round by ~1e-6 cells, which a
    field this steep turns into values past the sub-cell ranges' margins."""
    values = np.array([-3e38, -1e30, -1.0, -1e-45, 0.0, 1e-45, 1e-40, 1.0, 1e30, 3e38], np.float32)
    data = np.random.default_rng(seed).choice(values, (4, 2, 24))
    vol = Volume(data, spacing=(1.0, 0.1, 7.0))
    cam = Camera(eye=(11.5, 311449835.4970588, 10.5), look_at=(11.5, 0.05, 10.5), up=(0.3, 0.2, 1.0),
                 parallel_scale=23.8464957086173)
    _same_hits(Scene(camera=cam, size=(50, 53), volumes=[Isosurface(vol, float(np.float32(1e-40)))]), supercell)


def _shown(vol, what, iso, opacity):
    """The volume as an isosurface (``what`` "iso") or translucent through ``opacity`` with the
    buffers ``what`` names, and the render arguments that go with it."""
    if what == "iso":
        return Isosurface(vol, iso), {}
    return Translucent(vol, TransferFunction(opacity=opacity)), {"buffers": what}


@pytest.mark.parametrize("origin_y, scale", [(1.0, 1e-15), (1e6, 1e-10)])
@pytest.mark.parametrize("what", ["iso", "depth", "bits", "depth,bits"])
def test_parallel_pixels_smaller_than_the_origins_rounding(gl, origin_y, scale, what):
    # The view plane straddles the face y = origin_y with pixels below an ulp of it: the caster's
    # ray origins round onto the face, where the exact pixel centres lie outside it. The OpenGL
    # coverage pad of an eighth of a pixel missed them (brute hit, parc did not).
    data = np.zeros((2, 2, 3), np.uint8)
    data[:, :, 0] = 100
    vol = Volume(data, origin=(0.0, origin_y, 0.0))
    cam = Camera(eye=(1.5, origin_y, 0.5), look_at=(0.5, origin_y, 0.5), up=(0.0, 1.0, 0.0), parallel_scale=scale)
    vis, kwargs = _shown(vol, what, 50.0, [[40.0, 0.0], [60.0, 0.8]])
    scene = Scene(camera=cam, size=(1, 30), volumes=[vis])
    ref = render(scene, method="brute")
    assert ref.image[..., 3].any()
    for supercell in (1, 0.5):
        res = render(scene, method="parc", supercell=supercell, **kwargs)
        assert np.array_equal(np.isfinite(res.depth), np.isfinite(ref.depth))
        assert np.abs(res.image - ref.image).max() <= 1e-6


@pytest.mark.parametrize("supercell", [(0.25, 0.25, 1000), 0.3])
def test_an_origin_millions_of_cells_away_is_walked_from_the_entry(gl, supercell):
    # 16 grid extents of a 200,000-sample grid kept origins 3 million cells away unanchored: the
    # entry cell's cubic was then evaluated a rounding outside it, where this steep field dips
    # below the level, and brute hit a surface that is not there (for y < 0.5 the field is above
    # the level everywhere) while parc's sub-cell ranges excluded it.
    d = 6e-10
    data = np.zeros((200000, 2, 2), np.float32)
    data[:, 0, 0] = np.float32(2 * d)
    data[:, :, 1] = 1.0
    vol = Volume(data)
    cam = Camera(eye=(-3182625.1254714862, 0.20082638177642648, -829725.918505424),
                 look_at=(0.0, 0.20082638177642648, 125061.61913602178), up=(0.0, 1.0, 0.0), parallel_scale=1.0)
    scene = Scene(camera=cam, size=(1, 1), volumes=[Isosurface(vol, float(data[0, 0, 0]) / 2.0)])
    ref = render(scene, method="brute")
    res = render(scene, method="parc", supercell=supercell)
    assert np.isinf(ref.depth).all() and np.isinf(res.depth).all()


@pytest.mark.parametrize("step", [-1, 0, 1])
@pytest.mark.parametrize("what", ["iso", "depth", "bits"])
def test_an_eye_on_a_face_far_from_0_with_a_field_of_view_a_few_roundings_wide(gl, step, what):
    # At 1e7 from 0 world and index space disagree about the eye by an ulp (6e-7 cells here), and
    # with a 1e-8 degree field of view every ray runs within 1e-13 of the face the eye is on: in
    # index space they all stay inside and hit. OpenGL covered half the image from world space.
    data = np.zeros((3, 3, 3), np.uint8)
    data[:, :, 1] = 100
    data[:, :, 2] = 200
    vol = Volume(data, spacing=(0.003, 0.003, 0.003), origin=(1e7, 0.0, 1e7))
    ez = 1e7 + 0.006 + step * 2.0 ** -29          # the face and an ulp either side
    cam = Camera(eye=(1e7 - 0.1, 0.003, ez), look_at=(1e7 + 1.0, 0.003, ez), up=(0.0, 1.0, 0.0), fov=1e-8)
    vis, kwargs = _shown(vol, what, 150.0, [[120.0, 0.0], [200.0, 0.9]])
    scene = Scene(camera=cam, size=(33, 33), volumes=[vis])
    ref = render(scene, method="brute")
    res = render(scene, method="parc", supercell=1, **kwargs)
    assert np.array_equal(np.isfinite(res.depth), np.isfinite(ref.depth))
    assert np.abs(res.image - ref.image).max() <= 1e-6
    if step == 0:
        assert ref.image[..., 3].all()                # every ray stays inside in index space


@pytest.mark.parametrize("what, supercell", [("iso", 16), ("iso", 1), ("bits", 1), ("depth", 16)])
def test_an_eye_on_a_faces_plane_far_from_0_whose_entry_face_reaches_behind_it(gl, what, supercell):
    # The case above seen obliquely: the face the rays enter by has a corner behind the eye, so
    # it is clipped, and its coverage must reach as far from the clip plane.
    nx = 10
    data = np.zeros((3, 3, nx), np.uint8)
    data[:] = np.minimum(100 * np.arange(nx), 250).astype(np.uint8)
    vol = Volume(data, spacing=(0.003, 0.003, 0.003), origin=(1e7, 0.0, 1e7))
    ex, ey, ez = 1e7 + 0.0035, -0.0001, 1e7 + 0.006
    cam = Camera(eye=(ex, ey, ez), look_at=(ex + 3.0, ey + 1.0, ez), up=(0.0, 0.0, 1.0), fov=1e-8)
    vis, kwargs = _shown(vol, what, 150.0, [[0.0, 0.3], [255.0, 0.3]])
    scene = Scene(camera=cam, size=(33, 33), volumes=[vis])
    ref = render(scene, method="brute")
    res = render(scene, method="parc", supercell=supercell, **kwargs)
    assert ref.image[..., 3].all()
    assert np.array_equal(np.isfinite(res.depth), np.isfinite(ref.depth))
    assert np.abs(res.image - ref.image).max() <= 1e-6


@pytest.mark.parametrize("what", ["iso", "depth", "depth,bits"])
def test_a_field_of_view_a_millionth_of_a_degree_short_of_180(gl, what):
    # tan(fov / 2) is 4e7: across the image the ray direction's components reach 4e7, and the
    # bound on their float32 rounding (52) passes the length of the central ray's direction (1). The
    # top face's bound on that ray's t came out negative, the face was discarded, and the ray
    # started at a side face's nearest distance, below the surface and the samples under the top.
    nz = 6
    data = np.broadcast_to(np.arange(nz, dtype=np.float32)[:, None, None], (nz, 7, 9)).copy()
    vol = Volume(data, spacing=(1.0, 1.5, 0.5))
    lo, hi = vol.bounds
    cx, cy = (lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2
    cam = Camera(eye=(cx, cy, hi[2] + 4.0), look_at=(cx, cy, hi[2] + 3.0), up=(0.0, 1.0, 0.0), fov=180.0 - 3e-6)
    assert math.tan(math.radians(cam.fov) / 2) > 1e7                 # the case
    vis, kwargs = _shown(vol, what, nz - 1.5, [[0.0, 0.3], [nz - 1.0, 0.3]])
    scene = Scene(camera=cam, size=(21, 21), volumes=[vis])
    ref = render(scene, method="brute")
    assert ref.image[10, 10, 3] > 0.0                                # the central ray shows it
    for supercell in (1, 2):
        res = render(scene, method="parc", supercell=supercell, **kwargs)
        assert np.array_equal(np.isfinite(res.depth), np.isfinite(ref.depth))
        hit = np.isfinite(ref.depth)
        assert np.abs(res.depth[hit] - ref.depth[hit]).max(initial=0.0) <= 1e-9 * min(vol.spacing)
        assert np.abs(res.image - ref.image).max() <= 1e-6


def test_a_grid_millions_of_samples_long_pads_its_sub_cell_ranges_for_its_length(gl):
    # Positions 2 million cells into a grid round by ~1e-10 of a cell, and this field changes by
    # its whole magnitude per cell: brute (rightly or not) hits where the sub-cell ranges, padded
    # for 40,000 cells, said no supercell could.
    n, d = 2_200_000, 4.8e-10
    data = np.empty((n, 2, 2), np.float32)
    data[0::2, 0, :] = np.float32(2 * d)
    data[0::2, 1, :] = 0.0
    data[1::2] = 1.0
    vol = Volume(data, spacing=(1.0, 1.0, 0.7))
    cam = Camera(eye=(0.5, 0.245, -0.3137), look_at=(0.5, 0.245, 0.7 * n), up=(0.0, 1.0, 0.0), fov=10.0)
    scene = Scene(camera=cam, size=(1, 1), volumes=[Isosurface(vol, float(np.float32(2 * d)) / 2)])
    ref = render(scene, method="brute")
    res = render(scene, method="parc", supercell=(1, 0.25, 64))
    assert np.isfinite(ref.depth).all()                  # the case: brute hits deep in the grid
    assert np.array_equal(res.depth, ref.depth)


def test_a_parallel_eye_as_far_as_a_scene_takes_still_sees_the_volume(gl):
    """Just inside `parc.scene.EYE_RANGE` (0.99 of it) the rays still resolve the volume: the
    picture is the one from nearby, by both methods (far beyond it, an empty picture)."""
    from parc.scene import EYE_RANGE
    vol = blobs(12, seed=4)
    lo, hi = vol.bounds
    size = float(np.linalg.norm(np.subtract(hi, lo)))
    c = 0.5 * (np.asarray(lo) + np.asarray(hi))
    images = []
    for far in (50.0, 0.99 * EYE_RANGE * size):
        cam = Camera(eye=(far, c[1], c[2]), look_at=tuple(c), up=(0, 0, 1), parallel_scale=7.0)
        scene = Scene(camera=cam, size=(24, 24), volumes=[Isosurface(vol, 100.5)])
        ref, res = render(scene), render(scene, method="parc")
        assert np.array_equal(np.isfinite(ref.depth), np.isfinite(res.depth))
        images.append(np.isfinite(ref.depth))
    assert images[0].sum() > 50 and np.array_equal(images[0], images[1])


@pytest.mark.parametrize("k, j", [(515, 0), (-540, 0), (0, -99), (320, -99), (-320, 97), (660, -99)])
def test_samples_and_cells_scaled_by_powers_of_two_give_the_same_hits(gl, k, j):
    # Truth: scale invariance. Samples and isovalue times 2^k, and the grid and camera times 2^j,
    # exactly, move no surface: the depths are 2^j times those at scale 1, bit for bit. Float64
    # samples past 1e153 or below 1e-157, or cells near 1e-30 long, lost hits to the cubic's
    # squares over- or underflowing.
    rng = np.random.default_rng(5)
    base = np.round(rng.normal(size=(10, 10, 10)) * 256) / 256
    cam = Camera(eye=(-8.0, -6.0, 20.0), look_at=(4.5, 4.5, 4.5), up=(0.0, 0.0, 1.0), fov=40.0)

    def scene(k, j):
        two = 2.0 ** j
        vol = Volume(np.ldexp(base, k), spacing=(two, two, two), origin=(two, -two, 0.0))
        view = Camera(eye=tuple(np.ldexp(cam.eye, j) + (two, -two, 0.0)),
                      look_at=tuple(np.ldexp(cam.look_at, j) + (two, -two, 0.0)), up=cam.up, fov=cam.fov)
        return Scene(camera=view, size=(32, 32), volumes=[Isosurface(vol, value=0.0)])

    ref = render(scene(0, 0), method="brute")
    assert 200 < np.isfinite(ref.depth).sum() < 32 * 32 - 100
    for method in ("brute", "parc"):
        got = render(scene(k, j), method=method)
        assert np.array_equal(got.depth, np.ldexp(ref.depth, j)), (method, np.isfinite(got.depth).sum())
        assert np.abs(got.image - ref.image).max() <= 1e-6, method     # normals are directions


@pytest.mark.parametrize("parallel", [True, False])
@pytest.mark.parametrize("what", ["iso", "depth,bits", "bits"])
def test_a_view_reaching_past_float32s_range_is_drawn_by_parc_too(gl, parallel, what):
    # An eye 0.9 * 2^32 volume sizes from a volume 2^93 cells wide (both accepted): ray distances
    # past 3.4e38 came back from the float32 pass infinite, and parc drew nothing.
    rng = np.random.default_rng(5)
    t = 2.0 ** 93
    vol = Volume(np.round(rng.normal(size=(10, 10, 10)) * 256) / 256, spacing=(t, t, t))
    far = 0.9 * 2.0 ** 32 * float(np.linalg.norm(np.subtract(*vol.bounds)))
    view = {"parallel_scale": 6.0 * t} if parallel else {"fov": float(np.degrees(2 * np.arctan(6.0 * t / far)))}
    cam = Camera(eye=(far, 4.5 * t, 4.5 * t), look_at=(4.5 * t, 4.5 * t, 4.5 * t), up=(0, 0, 1), **view)
    shown = Isosurface(vol, 0.0) if what == "iso" else Translucent(vol, "greyscale")
    scene = Scene(camera=cam, size=(16, 16), volumes=[shown])
    ref = render(scene, method="brute")
    got = render(scene, method="parc", **({} if what == "iso" else {"buffers": what}))
    assert (ref.image[..., 3] > 0).sum() > 50
    assert np.array_equal(got.depth, ref.depth) and np.abs(got.image - ref.image).max() <= 1e-6


@pytest.mark.parametrize("buffers", ["bits", "depth,bits"])
def test_a_parallel_view_wider_than_float32s_range_is_drawn_by_parc_too(gl, buffers):
    # A parallel scale of 1e39 puts the outer pixels' ray origins past float32's largest: the
    # view reaches that far though the eye is near the volume, and the passes are skipped
    # (every ray whole): drawn, the bit-plane pass's float32 forms would overflow, and the centre
    # pixel, whose ray starts at the eye, would lose its bits.
    rng = np.random.default_rng(0)
    vol = Volume(np.round(rng.normal(size=(6, 6, 6)) * 256) / 256)
    cam = Camera(eye=(-10.0, 2.5, 2.5), look_at=(0.0, 2.5, 2.5), up=(0, 0, 1), parallel_scale=1e39)
    scene = Scene(camera=cam, size=(3, 3), volumes=[Translucent(vol, TransferFunction([[-3, 0.3], [3, 0.6]]))])
    ref = render(scene, method="brute")
    assert ref.image[1, 1, 3] > 0.5
    got = render(scene, method="parc", supercell=1, buffers=buffers)
    assert np.abs(got.image - ref.image).max() <= 1e-6
