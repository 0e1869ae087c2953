"""Lights, shadow rays and several volumes: PARC against the unaccelerated caster, and against geometry.

Truth for PARC: ``method="brute"`` on the same scene, whose shadow rays run
the whole way to the light. PARC narrows them with light buffers (four
pixels merged, conservative rasterization), so every pixel must agree:
identical hit masks, depths within 1e-9 of a cell, colours within 1e-6,
including features far smaller than a light-buffer pixel (tiny buffers
below make every supercell sub-pixel).

Truth for the shadows themselves: a sphere over a floor slab under a
vertical sun shadows exactly the floor points below the sphere's disc.
"""
import math
import warnings
import weakref

import numpy as np
import pytest

from data_tools import InputError, Volume
from data_tools.synthetic import blobs, trilinear_field
from parc import Camera, DirectionalLight, Isosurface, PointLight, Scene, TransferFunction, Translucent, render
from parc.scene import DEFAULT_MATERIAL, DEFAULT_SURFACE
from parc.skip import expect_frames

SIZE = (28, 24)
LIGHT_PLACES = ("outside", "on_box", "inside", "sun", "sun_axis")
KINDS = ("blobs", "noise", "sparse", "field")


def _volume(rng, kind, dims=None):
    dims = dims or tuple(int(n) for n in rng.integers(8, 16, 3))
    spacing = tuple(rng.uniform(0.6, 1.6, 3)) if rng.random() < 0.5 else (1.0, 1.0, 1.0)
    origin = tuple(rng.uniform(-5, 5, 3))
    if kind == "blobs":
        data = blobs(dims, seed=int(rng.integers(1 << 30))).data
    elif kind == "noise":
        data = rng.integers(0, 256, dims[::-1]).astype(np.uint8)
    elif kind == "sparse":
        # Isolated bright samples: tiny isosurfaces, far below a light-buffer pixel.
        data = np.zeros(dims[::-1], np.uint8)
        idx = rng.integers(1, np.array(dims[::-1]) - 1, size=(6, 3))
        data[idx[:, 0], idx[:, 1], idx[:, 2]] = 250
    else:
        data = trilinear_field(dims, seed=int(rng.integers(1 << 30)), dtype="float32").data
    return Volume(data, spacing=spacing, origin=origin, name=kind)


def _iso(rng, vol):
    lo, hi = vol.value_range()
    if vol.name == "sparse":
        return Isosurface(vol, value=float(rng.uniform(100, 200)))
    return Isosurface(vol, value=float(rng.uniform(lo + 0.3 * (hi - lo), hi - 0.3 * (hi - lo))),
                      color=tuple(rng.uniform(0.3, 1.0, 3)))


def _light(rng, place, lo, hi):
    lo, hi = np.asarray(lo), np.asarray(hi)
    c = (lo + hi) / 2
    ext = float(np.linalg.norm(hi - lo))
    color = tuple(rng.uniform(0.5, 1.0, 3))
    if place == "outside":
        d = rng.normal(size=3)
        return PointLight(tuple(c + d / np.linalg.norm(d) * ext * rng.uniform(0.8, 3.0)), color=color)
    if place == "on_box":
        p = rng.uniform(lo, hi)
        a = rng.integers(3)
        p[a] = lo[a] if rng.random() < 0.5 else hi[a]
        return PointLight(tuple(p), color=color)
    if place == "inside":
        return PointLight(tuple(rng.uniform(lo, hi)), color=color)
    if place == "sun_axis":
        d = np.zeros(3)
        d[rng.integers(3)] = rng.choice([-1.0, 1.0])
        return DirectionalLight(tuple(d), color=color)
    return DirectionalLight(tuple(rng.normal(size=3)), color=color)


def _camera(rng, lo, hi):
    return Camera.framing(lo, hi, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-70, 70),
                          zoom=rng.uniform(0.9, 1.8), parallel=rng.random() < 0.3)


def _union(vols):
    los, his = zip(*(v.bounds for v in vols))
    return np.min(los, axis=0), np.max(his, axis=0)


def _assert_same(scene, **kw):
    b = render(scene, "brute", **kw)
    p = render(scene, "parc", **kw)
    hit_b = np.isfinite(b.depth)
    assert np.array_equal(hit_b, np.isfinite(p.depth)), "hit masks differ"
    assert np.abs(b.depth[hit_b] - p.depth[hit_b]).max(initial=0.0) <= 1e-9
    err = np.abs(b.image.astype(np.float64) - p.image).max()
    assert err <= 1e-6, f"max colour difference {err:g}"
    return b, p


def _shadow_scene(rng, seed):
    """A random scene of one or two volumes under one or two lights, with shadows. The seed
    picks the first light's place and the volume's kind; everything else is drawn."""
    kind = KINDS[seed % len(KINDS)]
    vol = _volume(rng, kind)
    vols = [_iso(rng, vol)]
    if seed % 3 == 0:
        # A second, overlapping volume shadows the first: translucent or opaque.
        other = _volume(rng, "blobs")
        other = Volume(other.data, spacing=other.spacing, origin=tuple(np.array(vol.center) - 3.0), name="blobs")
        if rng.random() < 0.5:
            # Shaded now and then: its samples lit by the same lights, and shadowed.
            vols.append(Translucent(other, tf="greyscale", shade=seed % 2 == 0))
        else:
            vols.append(_iso(rng, other))
    lo, hi = _union([v.volume for v in vols])
    lights = [_light(rng, LIGHT_PLACES[seed % len(LIGHT_PLACES)], lo, hi)]
    if rng.random() < 0.25:
        lights.append(_light(rng, LIGHT_PLACES[int(rng.integers(len(LIGHT_PLACES)))], lo, hi))
    return Scene(camera=_camera(rng, lo, hi), size=SIZE, volumes=vols, lights=lights, shadows=True)


@pytest.mark.random_scenes(100)
def test_shadow_parc_equals_brute(gl, seed):
    rng = np.random.default_rng(1000 + seed)
    # A scene whose surfaces the camera misses casts no shadow ray: drawn again until it casts some.
    for _ in range(20):
        scene = _shadow_scene(rng, seed)
        if render(scene, "brute").stats["shadow_rays"] > 0:
            break
    supercell = (0.5, 1, 2, 3, 4.5)[int(rng.integers(5))]
    light_buffer = (4, 16, 64, 256)[int(rng.integers(4))]
    # Per-pixel work is mapped for scenes of one kind of volume.
    one_kind = len({isinstance(v, Isosurface) for v in scene.volumes}) == 1
    b, p = _assert_same(scene, supercell=supercell, light_buffer=light_buffer, work=one_kind)
    assert b.stats["shadow_rays"] == p.stats["shadow_rays"] > 0
    assert p.stats["shadow_cells"] <= b.stats["shadow_cells"]
    if one_kind:
        assert b.work.sum() == b.stats["cells_visited"] and p.work.sum() == p.stats["cells_visited"]
        assert (p.work <= b.work).all()


@pytest.mark.parametrize("distance", [1e100, 1e140, 1e150])
def test_a_very_far_point_light_shadows_as_brute_does(gl, distance):
    # The light's view must keep its direction where L + f rounds to L and
    # squared lengths overflow.
    rng = np.random.default_rng(7)
    vol = _volume(rng, "blobs")
    lo, hi = vol.bounds
    scene = Scene(camera=_camera(rng, lo, hi), size=SIZE, volumes=[_iso(rng, vol)],
                  lights=[PointLight(position=(distance, 0.3 * distance, 0.5 * distance))], shadows=True)
    with np.errstate(over="ignore"):      # squared distances to the light overflow, by design
        b, p = _assert_same(scene, supercell=2, light_buffer=16)
    assert b.stats["shadow_rays"] == p.stats["shadow_rays"] > 0
    # Farther (from ~1e154) the shading's squared distance to the light would overflow
    # and the light reach nothing: PointLight refuses it (a DirectionalLight is that light).
    with pytest.raises(InputError, match="a light that far is directional: give its direction \\(DirectionalLight"):
        PointLight(position=(2e150, 0.0, 0.0))


@pytest.mark.parametrize("scale", [1e12, 1e16, 1e20, 1e30])
def test_a_sun_over_a_volume_far_from_the_origin_shadows_as_brute_does(gl, scale):
    # The sun's view starts before the box: a point so large that its plus the unit
    # direction rounds back to it (or turns the direction) past 2^53.
    from parc.lights import light_views
    rng = np.random.default_rng(5)
    vol = _volume(rng, "blobs")
    vol = Volume(vol.data, spacing=tuple(scale * np.array(vol.spacing)), origin=tuple(scale * np.array(vol.origin)))
    sun = DirectionalLight((0.3, -0.8, -0.52))
    f = light_views(sun, *vol.bounds)[0].basis()[0]
    assert np.allclose(f, sun.direction, rtol=0, atol=1e-12)
    scene = Scene(camera=_camera(rng, *vol.bounds), size=SIZE, volumes=[_iso(rng, vol)], lights=[sun],
                  shadows=True)
    b, p = _assert_same(scene, supercell=2, light_buffer=16)
    assert b.stats["shadow_rays"] == p.stats["shadow_rays"] > 0


def test_tiny_features_below_a_light_pixel(gl):
    """Single bright samples, 0.5-cell supercells, a 4x4 light buffer: every occluder still found."""
    data = np.zeros((12, 12, 12), np.uint8)
    data[3:9:2, 3:9:2, 3:9:2] = 255           # 27 specks
    data[0:2, :, :] = 200                     # a floor they shadow
    vol = Volume(data, name="specks")
    scene = Scene(camera=Camera(eye=(5.5, -20, 30), look_at=(5.5, 5.5, 0.5), up=(0, 0, 1), fov=40),
                  size=(48, 48), volumes=[Isosurface(vol, value=120.0)],
                  lights=[PointLight((5.5, 5.5, 60.0)), DirectionalLight((0.1, 0.05, -1.0))], shadows=True)
    b, _ = _assert_same(scene, supercell=0.5, light_buffer=4)
    flat = render(Scene(camera=scene.camera, size=scene.size, volumes=scene.volumes, lights=scene.lights),
                  "brute")
    # The specks do cast shadows on the floor: the shadowed image is darker somewhere.
    assert (b.image[..., :3] < flat.image[..., :3] - 0.05).any()


def test_sphere_shadow_on_floor_matches_geometry(gl):
    """Sun straight down: a floor point is in shadow exactly when its vertical line meets the sphere."""
    n = 40
    z, y, x = np.mgrid[0:n, 0:n, 0:n].astype(np.float64)
    r0, c = 7.0, np.array([19.5, 19.5, 24.0])
    ball = np.sqrt((x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2)
    field = np.maximum(np.clip(r0 - ball, -1, 1), np.clip(5.5 - z, -1, 1))   # sphere and floor top z=5.5
    vol = Volume(field.astype(np.float32), name="sphere_floor")
    cam = Camera(eye=(19.5, -25.0, 45.0), look_at=(19.5, 19.5, 5.5), up=(0, 0, 1), fov=40)
    scene = Scene(camera=cam, size=(64, 64), volumes=[Isosurface(vol, value=0.0)],
                  lights=[DirectionalLight((0.0, 0.0, -1.0))], shadows=True)
    b, _ = _assert_same(scene, supercell=2)
    o, d = cam.rays(64, 64)
    p = o + np.where(np.isfinite(b.depth), b.depth, 0.0)[..., None] * d
    on_floor = np.isfinite(b.depth) & (np.abs(p[..., 2] - 5.5) < 0.05)
    rxy = np.hypot(p[..., 0] - c[0], p[..., 1] - c[1])
    dark = b.image[..., 0] < 0.2
    inside, outside = on_floor & (rxy < r0 - 1.0), on_floor & (rxy > r0 + 1.0)
    assert inside.sum() > 20 and outside.sum() > 100
    # Away from the rim (interpolation blurs the sphere by under a cell), shadow = inside the disc.
    assert dark[inside].all()
    assert not dark[outside].any()


@pytest.mark.parametrize("case", ["iso_in_translucent", "two_translucent", "two_isosurfaces",
                                  "mip_and_composite", "iso_and_average", "shaded_about_a_surface"])
@pytest.mark.parametrize("seed", range(4))
def test_multi_volume_parc_equals_brute(gl, case, seed):
    rng = np.random.default_rng(50 + seed)
    a = _volume(rng, "blobs")
    b = _volume(rng, "field" if seed % 2 else "blobs")
    b = Volume(b.data, spacing=b.spacing, origin=tuple(np.array(a.center) - rng.uniform(1, 4, 3)), name=b.name)
    ramp = "greyscale"
    if case == "iso_in_translucent":
        vols = [Translucent(b, tf=ramp), _iso(rng, a)]
    elif case == "two_translucent":
        vols = [Translucent(a, tf="viridis"), Translucent(b, tf=ramp, shade=bool(seed % 2))]
    elif case == "two_isosurfaces":
        vols = [_iso(rng, a), _iso(rng, b)]
    elif case == "mip_and_composite":
        vols = [Translucent(a, tf="viridis", mode="mip"), Translucent(b, tf=ramp)]
    elif case == "shaded_about_a_surface":
        # Shaded samples of two volumes shadowing each other, and shadowed by a surface inside one.
        vols = [Translucent(a, tf="viridis", shade=True), _iso(rng, b), Translucent(b, tf=ramp, shade=seed < 2)]
    else:
        vols = [_iso(rng, a), Translucent(b, tf=ramp, mode="average")]
    lo, hi = _union([v.volume for v in vols])
    surfaces = any(isinstance(v, Isosurface) for v in vols)
    shaded = any(isinstance(v, Translucent) and v.shade for v in vols)
    lit = (seed % 2 == 0 and surfaces) or shaded
    lights = [_light(rng, LIGHT_PLACES[seed % 5], lo, hi)] if lit else []
    scene = Scene(camera=_camera(rng, lo, hi), size=SIZE, volumes=vols, lights=lights, shadows=bool(lights))
    b, _ = _assert_same(scene, supercell=(1, 2, 3, 0.5)[seed])
    if shaded:
        assert b.stats["shadow_rays"] > 0


@pytest.mark.random_scenes(40)
def test_parc_with_bit_planes_among_several_volumes_equals_brute(gl, seed):
    # Bit planes for every translucent volume of the scene (composite ones merged in one walk,
    # maximum and average ones apart), beside surfaces that keep their depth buffers, lit and
    # shadowed or not; without depth buffers where no surface needs them. Two composite volumes
    # of uint8 samples in every scene: each count and type compiles a merged walk of its own.
    rng = np.random.default_rng(60_000 + seed)
    a = _volume(rng, "blobs")
    b = _volume(rng, "blobs")
    b = Volume(b.data, spacing=b.spacing, origin=tuple(np.array(a.center) - rng.uniform(1, 4, 3)), name=b.name)
    vols = [Translucent(a, tf="viridis", shade=bool(rng.random() < 0.5)), Translucent(b, tf="greyscale")]
    third = ("none", "mip", "average", "surface")[seed % 4]
    if third == "surface":
        vols.append(_iso(rng, a))
    elif third != "none":
        vols.append(Translucent(b, tf="viridis", mode=third))
    lo, hi = _union([v.volume for v in vols])
    surfaces = any(isinstance(v, Isosurface) for v in vols)
    lit = (surfaces or vols[0].shade) and rng.random() < 0.6
    lights = [_light(rng, LIGHT_PLACES[seed % 5], lo, hi)] if lit else []
    scene = Scene(camera=_camera(rng, lo, hi), size=SIZE, volumes=vols, lights=lights,
                  shadows=lit and rng.random() < 0.7)
    buffers = "depth,bits" if surfaces or seed % 3 else "bits"
    supercell = (1, 2, 3, 0.5, 1.5)[seed % 5]
    b = render(scene, "brute")
    p = render(scene, "parc", buffers=buffers, supercell=supercell, work=not surfaces)
    where = f"buffers={buffers} supercell={supercell} third={third} seed={seed}"
    assert np.array_equal(np.isfinite(b.depth), np.isfinite(p.depth)), where
    assert np.abs(b.image.astype(np.float64) - p.image).max() <= 1e-6, where
    assert p.stats["samples"] <= b.stats["samples"], where
    assert all("planes" in v for v, vis in zip(p.stats["volumes"], vols) if isinstance(vis, Translucent)), where
    if not surfaces:
        assert p.work.sum() == p.stats["samples"], where


@pytest.mark.parametrize("shadows", [False, True])
def test_bit_planes_alone_pass_over_the_merged_volumes_transparent_cells(gl, shadows):
    # Neither depth buffers nor skip tables: what the walks pass over, the planes alone clear.
    rng = np.random.default_rng(8)
    a = _volume(rng, "blobs", dims=(14, 12, 13))
    b = _volume(rng, "blobs", dims=(12, 14, 12))
    b = Volume(b.data, spacing=b.spacing, origin=tuple(np.array(a.center) - 2.0), name="b")
    fog = TransferFunction(opacity=[(0.0, 0.0), (120.0, 0.0), (200.0, 0.6), (255.0, 0.6)],
                           color=[(0.0, 1.0, 0.5, 0.2), (255.0, 0.2, 0.6, 1.0)])
    vols = [Translucent(a, tf=fog, shade=shadows), Translucent(b, tf=fog)]
    lo, hi = _union([v.volume for v in vols])
    lights = [_light(rng, "outside", lo, hi)] if shadows else []
    scene = Scene(camera=_camera(rng, lo, hi), size=SIZE, volumes=vols, lights=lights, shadows=shadows)
    b = render(scene, "brute")
    p = render(scene, "parc", buffers="bits", supercell=2, blocks=False)
    assert np.abs(b.image.astype(np.float64) - p.image).max() <= 1e-6
    assert (b.image[..., 3] > 0.05).sum() > 20
    assert p.stats["samples"] < 0.8 * b.stats["samples"], (p.stats["samples"], b.stats["samples"])
    assert p.stats["polygons"] == sum(v["plane_polygons"] for v in p.stats["volumes"]) + p.stats["light_polygons"]


def test_merged_translucent_volumes_skip_transparent_cells(gl):
    """Overlapping composite volumes (the merged walk) with an isosurface inside: the
    skip tables change no pixel and take fewer samples."""
    rng = np.random.default_rng(7)
    skipped = 0
    for seed in range(3):
        a = _volume(rng, "blobs")
        b = _volume(rng, "blobs")
        b = Volume(b.data, spacing=b.spacing, origin=tuple(np.array(a.center) - rng.uniform(1, 4, 3)), name="b")
        vols = [Translucent(a, tf="viridis"), Translucent(b, tf="greyscale"), _iso(rng, b)]
        lo, hi = _union([v.volume for v in vols])
        scene = Scene(camera=_camera(rng, lo, hi), size=SIZE, volumes=vols)
        ref = render(scene, "brute")
        off = render(scene, "parc", blocks=False)
        on = render(scene, "parc")
        assert np.abs(on.image - ref.image).max() <= 1e-6
        assert np.array_equal(on.image, off.image)
        assert on.stats["samples"] <= off.stats["samples"]
        skipped += off.stats["samples"] - on.stats["samples"]
    assert skipped > 0


def test_translucent_in_front_of_surface_is_composited_over_it(gl):
    """One translucent volume in front of an isosurface: the pixel is ``front + (1 - a) surface``."""
    rng = np.random.default_rng(3)
    a = _volume(rng, "blobs", dims=(12, 12, 12))
    far = Volume(a.data, spacing=a.spacing, origin=(0.0, 0.0, 0.0), name="surface")
    near_ = Volume(a.data, spacing=a.spacing, origin=(0.0, 0.0, 40.0), name="fog")
    cam = Camera(eye=(6.0, 6.0, 120.0), look_at=(6.0, 6.0, 0.0), up=(0, 1, 0), fov=20)
    iso = _iso(rng, far)
    fog = Translucent(near_, tf="greyscale")
    both = render(Scene(camera=cam, size=SIZE, volumes=[iso, fog]), "brute")
    surf = render(Scene(camera=cam, size=SIZE, volumes=[iso]), "brute")
    front = render(Scene(camera=cam, size=SIZE, volumes=[fog]), "brute")
    want = front.image + (1.0 - front.image[..., 3:4]) * surf.image
    assert np.abs(both.image - want).max() <= 1e-6
    # The stats describe each volume as a scene of that volume alone does (the threshold too).
    for one, described in zip((surf, front), both.stats["parameters"]["volumes"]):
        assert {k: v for k, v in one.stats["parameters"].items() if k not in ("size", "camera")} == described


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("seed", range(2))
def test_a_volume_stops_at_its_own_threshold_beside_others(gl, method, seed):
    """Each composite volume's samples stop counting at its own threshold: a volume the rays never
    meet, with another threshold, leaves the image as it is alone (the largest threshold ruled)."""
    rng = np.random.default_rng(90 + seed)
    a = _volume(rng, "blobs")
    far = Volume(a.data, spacing=a.spacing, origin=tuple(np.array(a.origin) + 1e4), name="far")
    fog = Translucent(a, tf="greyscale", threshold=0.3)
    cam = _camera(rng, *a.bounds)
    alone = render(Scene(camera=cam, size=SIZE, volumes=[fog]), method)
    beside = render(Scene(camera=cam, size=SIZE, volumes=[fog, Translucent(far, tf="greyscale")]), method)
    assert alone.image[..., 3].max() >= 0.3
    assert np.abs(alone.image - beside.image).max() <= 1e-6


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_scene_cast_in_bands_is_the_scene_cast_whole_with_progress_through_each(gl, method, monkeypatch):
    """Large frames are cast a band of rows at a time (Ctrl-C acts between bands): the image is
    the same, and progress moves through every phase, the translucent one included."""
    import parc.workspace as workspace
    rng = np.random.default_rng(11)
    a = _volume(rng, "blobs")
    b = Volume(a.data, spacing=a.spacing, origin=tuple(np.array(a.origin) + 2.0), name="b")
    lo, hi = _union([a, b])
    vols = [_iso(rng, a), Translucent(b, tf="greyscale"), Translucent(a, tf="viridis", mode="mip")]
    scene = Scene(camera=_camera(rng, lo, hi), size=SIZE, volumes=vols,
                  lights=[_light(rng, "outside", lo, hi)], shadows=True)
    expect_frames(scene)            # both frames with the skip tables, so their counts agree
    whole = render(scene, method)
    monkeypatch.setattr(workspace, "BAND_PIXELS", 4 * SIZE[0])
    seen = []
    banded = render(scene, method, progress=seen.append)
    assert np.array_equal(whole.image, banded.image) and np.array_equal(whole.depth, banded.depth)
    assert {k: whole.stats[k] for k in ("cells_visited", "cubic_solves", "samples")} == \
        {k: banded.stats[k] for k in ("cells_visited", "cubic_solves", "samples")}
    assert seen == sorted(seen) and seen[-1] == 1.0
    assert len(seen) >= 3 * (SIZE[1] // 4) and len({round(f, 6) for f in seen if f > 0.5}) >= SIZE[1] // 4


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_layer_behind_a_ray_stopped_early_still_shows(gl, method):
    """A composite volume that stops rays at threshold 0.5, a maximum-intensity volume behind it:
    the layer goes under the stopped ray as a surface behind would (it was dropped)."""
    z, y, x = np.mgrid[0:9, 0:9, 0:9]
    ball = np.where((x - 4) ** 2 + (y - 4) ** 2 + (z - 4) ** 2 <= 12, 200.0, 10.0).astype(np.float32)
    front = Translucent(Volume(ball), tf="greyscale", threshold=0.5)
    back = Translucent(Volume(ball, origin=(0, 0, 20)), mode="mip",
                       tf=TransferFunction(opacity=[[0, 0], [100, 0], [200, 0.8]], color=[[0, 0.2, 0.9, 0.4]]))
    cam = Camera(eye=(4, 4, -40), look_at=(4, 4, 4), up=(0, 1, 0), parallel_scale=5.0)
    alone = [render(Scene(camera=cam, size=(12, 12), volumes=[v]), method).image for v in (front, back)]
    both = render(Scene(camera=cam, size=(12, 12), volumes=[front, back]), method).image
    assert alone[0][..., 3].max() >= 0.5 and alone[1][..., 3].max() > 0.5
    expect = alone[0] + (1 - alone[0][..., 3:]) * alone[1]
    assert np.abs(both - expect).max() <= 1e-6


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_lamp_standing_on_a_surface_is_not_hidden_by_it(gl, method):
    """A point light exactly on the floor's isosurface lights the ball above it: its shadow rays
    stop short of the light as they start off their surface (rounding hid it from 11 of 14 ball
    pixels, and dimmed a translucent slab's face sample on a third of the floor)."""
    z, y, x = np.mgrid[0:32, 0:32, 0:32].astype(np.float32)
    floor = Isosurface(Volume(z), 5.5, color=(0.5, 0.4, 0.3))
    ball = Isosurface(Volume(np.sqrt((x - 16) ** 2 + (y - 16) ** 2 + (z - 20) ** 2)), 6.0, color=(1, 0, 0))
    cam = Camera(eye=(40, -30, 40), look_at=(16, 16, 8), up=(0, 0, 1), fov=40)
    lamp = PointLight(position=(16, 16, 5.5))
    lit = render(Scene(camera=cam, size=(48, 48), volumes=[floor, ball], lights=[lamp]), method)
    shadowed = render(Scene(camera=cam, size=(48, 48), volumes=[floor, ball], lights=[lamp], shadows=True), method)
    alone = render(Scene(camera=cam, size=(48, 48), volumes=[ball]), method).depth
    under = (lit.depth == alone) & np.isfinite(alone) & (lit.image[..., 0] > 0.1201)   # ball, lit from below
    assert under.sum() > 5
    assert np.array_equal(shadowed.image[under], lit.image[under])


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_tiny_volume_elsewhere_changes_no_shadow(gl, method):
    """Shadow rays leave each surface by a fraction of its own volume's spacing: a volume of
    spacing 1e-11 out of view made the floor and the ball shadow themselves (3631 of 4096 pixels)."""
    z, y, x = np.mgrid[0:32, 0:32, 0:32].astype(np.float32)
    floor = Isosurface(Volume(z), 5.5)
    ball = Isosurface(Volume(np.sqrt((x - 16) ** 2 + (y - 16) ** 2 + (z - 20) ** 2)), 6.0)
    tiny = Isosurface(Volume(np.arange(8, dtype=np.float32).reshape(2, 2, 2), spacing=(1e-11,) * 3,
                             origin=(-0.01,) * 3), 3.5)
    cam = Camera(eye=(16, 16, 60), look_at=(16, 16, 0), up=(0, 1, 0), parallel_scale=16)
    sun = DirectionalLight(direction=(1, 0.5, -2))
    images = [render(Scene(camera=cam, size=(64, 64), volumes=vols, lights=[sun], shadows=True), method).image
              for vols in ([floor, ball], [floor, ball, tiny])]
    assert np.array_equal(images[0], images[1])


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("eye_away, origin, elevation", [(1e10, 0.0, 5.0), (20.0, 4e9, 1.0)])
def test_a_plane_lit_at_a_low_angle_does_not_shadow_itself_far_from_the_origin(gl, method, eye_away, origin,
                                                                                elevation):
    """Nothing stands between a flat isosurface and the sun, so shadows change no pixel. The hit
    point was the far eye plus ``t d``, rounded below the plane by more than its shadow ray's
    start lifted it (148 of 454 pixels darkened); at coordinates of 4e9 the start's lift was
    below their rounding (all 693)."""
    z = np.broadcast_to(np.arange(6.0)[:, None, None], (6, 9, 9))
    plane = Isosurface(Volume(np.ascontiguousarray(z), origin=(origin,) * 3), 2.5)
    centre = np.array([origin + 4.0, origin + 4.0, origin + 2.5])
    way = np.array([3.0, -14.0, 12.0]) / np.linalg.norm([3.0, -14.0, 12.0])
    cam = Camera(eye=tuple(centre + eye_away * way), look_at=tuple(centre), up=(0, 0, 1), parallel_scale=6.0)
    e = np.radians(elevation)
    sun = DirectionalLight(direction=(np.cos(e), 0.0, -np.sin(e)))
    lit, shadowed = (render(Scene(camera=cam, size=(40, 40), volumes=[plane], lights=[sun], shadows=on), method)
                     for on in (False, True))
    assert np.isfinite(lit.depth).sum() > 400
    assert np.array_equal(lit.image, shadowed.image)


def _shadow_kernel_args(kernel, views, near, far, use_seg):
    """Arguments of `raycast.shadow`'s ``kernel`` for three shadow rays through a small field."""
    from parc.lights import KIND_DIRECTIONAL
    from parc.renderer import accumulation_params
    from raycast.iso import NO_SKIP
    vol = trilinear_field(6, seed=2)
    data, org, spc = vol.data, np.array(vol.origin), np.array(vol.spacing)
    points = np.array([[1.0, 1.5, 2.0], [2.5, 2.5, 2.5], [4.0, 1.0, 0.5]])
    light = np.array([KIND_DIRECTIONAL, 0.0, 0.0, -1.0, 1.0, 1.0, 1.0])
    tail = (points, light, 1e-5, views, near, far, use_seg, NO_SKIP, -1, np.ones(3), np.zeros((3, 3), np.int64))
    if kernel == "shadow_iso":
        return (data, org, spc, float(vol.meta["iso"])) + tail
    clear = Translucent(vol, TransferFunction([[-1e9, 0.2], [1e9, 0.2]]))
    return (data, org, spc, accumulation_params(clear), *clear.tf.arrays()) + tail + (0.0,)


@pytest.mark.parametrize("kernel", ["shadow_iso", "shadow_accumulate"])
def test_shadow_kernels_read_only_views_they_are_given(kernel):
    # Numba's parallel loop reads the first view's row before the loop, even for brute (no
    # buffers) or a volume without possibly contributing supercells: an empty array was read
    # out of bounds. Compiled here with bounds checks, which the cached kernels leave out.
    import numba
    from parc.lights import N_VIEW, no_views
    from raycast import shadow
    checked = numba.njit(parallel=True, boundscheck=True)(getattr(shadow, kernel).py_func)
    for use_seg in (False, True):
        checked(*_shadow_kernel_args(kernel, *no_views(), use_seg))
    with pytest.raises((IndexError, SystemError)):     # the arrays passed before
        checked(*_shadow_kernel_args(kernel, np.zeros((0, N_VIEW)), np.zeros((0, 1, 1)), np.zeros((0, 1, 1)), False))


# Kernels brute and parc share, against answers worked out by hand: comparing the methods
# cannot see a mistake in them.

def test_two_mip_layers_compose_near_over_far():
    # Two maximum-intensity volumes one behind the other: the nearer's layer goes over the farther's.
    rng = np.random.default_rng(0)
    red = TransferFunction([[0, 0.3], [255, 0.7]], [[0, 1, 0, 0], [255, 1, 0.2, 0]])
    blue = TransferFunction([[0, 0.3], [255, 0.7]], [[0, 0, 0, 1], [255, 0, 0.2, 1]])
    near = Translucent(Volume(rng.integers(0, 256, (8, 8, 8)).astype(np.uint8), name="near"), red, mode="mip")
    far = Translucent(Volume(rng.integers(0, 256, (8, 8, 8)).astype(np.uint8), origin=(0, 0, -20), name="far"),
                      blue, mode="mip")
    cam = Camera(eye=(3.5, 3.5, 40.0), look_at=(3.5, 3.5, 0.0), up=(0, 1, 0), parallel_scale=3.0)
    a, b = (render(Scene(camera=cam, size=(6, 6), volumes=[v])).image.astype(np.float64) for v in (near, far))
    both = render(Scene(camera=cam, size=(6, 6), volumes=[far, near])).image
    assert (a[..., 3] > 0).all() and (b[..., 3] > 0).all()
    np.testing.assert_allclose(both, a + (1.0 - a[..., 3:4]) * b, atol=1e-5, rtol=0)


@pytest.mark.parametrize("view", ["perspective", "parallel"])
@pytest.mark.parametrize("layer_first", [True, False])
def test_a_layer_and_samples_at_the_same_depth_go_in_the_scene_s_order(view, layer_first):
    # A maximum-intensity volume and a composite one sharing a box: the layer and the first
    # samples are where each ray enters it. The layer's depth came from NumPy's rays and the
    # samples' from the caster's, and their roundings set the order pixel by pixel (up to
    # 0.39 apart in colour); ties now go to the volume listed first, as between samples.
    rng = np.random.default_rng(0)
    data = (rng.random((8, 8, 8)) * 255).astype(np.uint8)
    tf = TransferFunction([[0, 0.6], [255, 0.9]], [[0, 1, 0, 0], [255, 0, 0, 1]])
    kw = dict(fov=35) if view == "perspective" else dict(parallel_scale=6.0)
    cam = Camera(eye=(20.0, -13.0, 11.0), look_at=(3.5, 3.5, 3.5), up=(0, 0, 1), **kw)
    f = cam.basis()[0]

    def image(shift):
        vols = [Translucent(Volume(data, origin=tuple(shift * f)), tf, mode="mip"), Translucent(Volume(data), tf)]
        return render(Scene(camera=cam, size=(32, 32), volumes=vols if layer_first else vols[::-1])).image

    shared, front, back = image(0.0), image(-1e-10), image(1e-10)
    assert (shared[..., 3] > 0).sum() > 300 and np.abs(front - back).max() > 0.1      # the order shows
    np.testing.assert_allclose(shared, front if layer_first else back, atol=1e-5, rtol=0)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_subnormal_ray_direction_orders_layers_without_a_warning(gl, method):
    # The layers' order came from 1 / d, and a direction component of 1e-309 overflowed:
    # "RuntimeWarning: overflow encountered in divide" reached the user.
    rng = np.random.default_rng(0)
    mip = Translucent(Volume(rng.random((6, 6, 6)).astype(np.float32), origin=(1.0, 0.0, 0.0)), "greyscale",
                      mode="mip")
    surface = Isosurface(Volume(rng.random((6, 6, 6)).astype(np.float32)), 0.5)
    cam = Camera(eye=(0.0, 2.5, -20.0), look_at=(2e-308, 2.5, 0.0), up=(0, 1, 0), fov=30.0)
    assert 0.0 < cam.basis()[0][0] < 1e-300                       # the case
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        image = render(Scene(camera=cam, size=(9, 9), volumes=[surface, mip]), method=method).image
    assert image[..., 3].max() > 0.0


def _floor_scene(occluders, material=(0.2, 0.5, 0.5, 4.0)):
    """A white floor (z = 5.5) seen straight down, the sun travelling along (-1, 0, -1): shadow
    rays from the floor in view run up towards +x, through walls at x >= 24 no camera ray meets."""
    z = np.arange(11, dtype=np.float32)[:, None, None]
    floor = Volume(np.broadcast_to(5.5 - z, (11, 11, 21)).copy(), name="floor")
    cam = Camera(eye=(10.0, 5.0, 100.0), look_at=(10.0, 5.0, 0.0), up=(0, 1, 0), parallel_scale=3.0)
    return Scene(camera=cam, size=(8, 8), volumes=[Isosurface(floor, 0.0, color=(1.0, 1.0, 1.0), material=material),
                                                   *occluders],
                 lights=[DirectionalLight((-1.0, 0.0, -1.0))], shadows=True)


def test_a_shadowed_surface_has_no_highlight():
    # In full shadow only the ambient term is left: colour 1 times ambient 0.2, specular included.
    d = np.zeros((81, 21, 5), np.float32)
    d[:, :, 1:4] = 1.0
    wall = Isosurface(Volume(d, origin=(24.0, -5.0, 0.0), name="opaque wall"), 0.5)
    assert render(_floor_scene([])).image[4, 4, 0] > 0.5
    np.testing.assert_allclose(render(_floor_scene([wall])).image[..., :3], 0.2, atol=1e-6)


def test_translucent_occluders_multiply_their_transmittance():
    # Without specular light a floor pixel is 0.2 + visibility x diffuse: the visibility behind two
    # walls is the product of each one's (light passing one and then the other).
    tf = TransferFunction([[0, 0.15], [255, 0.15]])
    walls = [Translucent(Volume(np.full((81, 21, 3), 100, np.uint8), origin=(x0, -5.0, 0.0), name=f"wall {x0}"), tf)
             for x0 in (25.0, 30.0)]
    material = (0.2, 0.8, 0.0, 1.0)
    px = {k: float(render(_floor_scene(v, material)).image[4, 4, 0])
          for k, v in (("none", []), ("one", walls[:1]), ("two", walls[1:]), ("both", walls))}
    vis = {k: (px[k] - 0.2) / (px["none"] - 0.2) for k in ("one", "two", "both")}
    assert 0.05 < vis["one"] < 0.95 and 0.05 < vis["two"] < 0.95
    assert vis["both"] == pytest.approx(vis["one"] * vis["two"], rel=1e-6)


@pytest.mark.parametrize("near_first", [True, False])
def test_disjoint_translucent_volumes_seen_from_afar_composite_near_over_far(near_first):
    # Seen from 1e5 units, each ray is anchored at its entry into each volume, so the volumes'
    # own times differ from the world's: the merged walk must still order them by world distance.
    z, y, x = np.mgrid[0:9, 0:9, 0:9]
    ball = np.where((x - 4) ** 2 + (y - 4) ** 2 + (z - 4) ** 2 <= 12, 200.0, 10.0).astype(np.float32)
    red = TransferFunction(opacity=[[0, 0], [100, 0], [200, 0.05]], color=[[0, 1.0, 0.0, 0.0]])
    blue = TransferFunction(opacity=[[0, 0], [100, 0], [200, 0.05]], color=[[0, 0.0, 0.0, 1.0]])
    near = Translucent(Volume(ball, name="near"), tf=red, threshold=1.0)
    far = Translucent(Volume(ball, origin=(0, 0, 20), name="far"), tf=blue, threshold=1.0)
    cam = Camera(eye=(4, 4, -1.0e5), look_at=(4, 4, 4), up=(0, 1, 0), parallel_scale=5.0)
    a, b = (render(Scene(camera=cam, size=(12, 12), volumes=[v])).image.astype(np.float64) for v in (near, far))
    assert a[..., 3].max() > 0.05 and b[..., 3].max() > 0.05 and a[..., 3].max() < 0.99
    both = render(Scene(camera=cam, size=(12, 12), volumes=[near, far] if near_first else [far, near])).image
    np.testing.assert_allclose(both, a + (1.0 - a[..., 3:4]) * b, atol=1e-5, rtol=0)


def test_stats_parameters_describe_the_volume_as_the_scene_states_it():
    # Truth: the values given to Isosurface/Translucent, not another render's stats.
    vol = Volume(np.asarray(blobs((10, 10, 10)).data, np.float32), spacing=(1, 1, 0.5), origin=(0, -2, 1), name="fog")
    cam = Camera(eye=(5.0, 5.0, 60.0), look_at=(5.0, 5.0, 5.0), up=(0, 1, 0), fov=20)
    camera = {"eye": [5.0, 5.0, 60.0], "look_at": [5.0, 5.0, 5.0], "up": [0.0, 1.0, 0.0], "fov": 20.0}
    placed = {"volume": "fog", "dims": [10, 10, 10], "dtype": "float32", "spacing": [1.0, 1.0, 0.5],
              "origin": [0.0, -2.0, 1.0]}
    tf = TransferFunction([(0.0, 0.0), (1.0, 0.5)])                        # unnamed: "custom"
    for mode, shade in (("mip", False), ("average", False), ("composite", False), ("composite", True)):
        # Only compositing stops at a threshold, and is shaded (the others refuse both): the others
        # take every sample, unlit.
        stops = {"threshold": 0.9, "shade": shade} if mode == "composite" else {}
        fog = Translucent(vol, tf=tf, mode=mode, step=0.25, **stops)
        p = render(Scene(camera=cam, size=(8, 6), volumes=[fog]), "brute").stats["parameters"]
        lit = {"material": list(DEFAULT_MATERIAL)} if shade else {}
        assert p == {"size": [8, 6], **placed, "mode": mode, "step": 0.25, "transfer_function": "custom",
                     "camera": camera, **stops, **lit}
    p = render(Scene(camera=cam, size=(8, 6), volumes=[Isosurface(vol, value=0.3)]), "brute").stats["parameters"]
    assert p == {"size": [8, 6], **placed, "isovalue": 0.3, "color": list(DEFAULT_SURFACE),
                 "material": list(DEFAULT_MATERIAL), "camera": camera}


def test_a_scene_cast_as_several_volumes_records_the_buffers_and_blocks_asked(gl):
    # Lit, or of several volumes, a render's stats had no "buffers" or "blocks": a run with
    # --no-blocks or bit planes read as one without.
    vol = blobs(12, seed=1)
    sun = [DirectionalLight(direction=(0, 0, -1))]
    cam = Camera.framing(*vol.bounds)
    lit = render(Scene(camera=cam, size=(16, 16), volumes=[Isosurface(vol, 100.0)], lights=sun), "parc",
                 blocks=False).stats
    assert lit["buffers"] == ["depth"] and lit["blocks"] is False
    both = [Isosurface(vol, 100.0), Translucent(Volume(vol.data, origin=(3.0, 0, 0)), "greyscale")]
    mixed = render(Scene(camera=cam, size=(16, 16), volumes=both), "parc", buffers=("depth", "bits")).stats
    assert mixed["buffers"] == ["depth", "bits"] and mixed["blocks"] is True
    assert "buffers" not in render(Scene(camera=cam, size=(16, 16), volumes=both), "brute").stats


def test_stats_parameters_tell_apart_renders_that_differ_in_background_lights_or_material():
    """A red background and a sun, and a point light without a background, gave the same
    parameters (a count of lights) and different pictures; so did two surface colours."""
    vol = Volume(np.linspace(0.0, 1.0, 1000, dtype=np.float32).reshape(10, 10, 10))
    cam = Camera(eye=(5.0, 5.0, 60.0), look_at=(5.0, 5.0, 5.0), up=(0, 1, 0), fov=20)
    surface = Isosurface(vol, 0.5)
    scenes = [Scene(camera=cam, size=(8, 6), volumes=[surface], background=(1, 0, 0),
                    lights=[DirectionalLight(direction=(1, 0, 0))]),
              Scene(camera=cam, size=(8, 6), volumes=[surface], lights=[PointLight(position=(100, 0, 0))]),
              Scene(camera=cam, size=(8, 6), volumes=[Isosurface(vol, 0.5, color=(0, 1, 0))],
                    lights=[PointLight(position=(100, 0, 0))]),
              Scene(camera=cam, size=(8, 6), volumes=[surface, Translucent(vol, "greyscale", shade=True)],
                    lights=[PointLight(position=(100, 0, 0), intensity=0.5)])]
    p = [render(scene, "brute").stats["parameters"] for scene in scenes]
    assert p[0]["background"] == [1.0, 0.0, 0.0, 1.0] and "background" not in p[1]
    assert p[0]["lights"] == [{"direction": [1.0, 0.0, 0.0], "color": [1.0, 1.0, 1.0], "intensity": 1.0}]
    assert p[1]["lights"] == [{"position": [100.0, 0.0, 0.0], "color": [1.0, 1.0, 1.0], "intensity": 1.0}]
    assert p[1] != p[2] and p[2]["volumes"][0]["color"] == [0.0, 1.0, 0.0]
    assert p[3]["lights"][0]["intensity"] == 0.5 and p[3]["volumes"][1]["material"] == list(DEFAULT_MATERIAL)


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("light", ["sun", "point"])
def test_a_lit_floor_has_the_shading_the_readme_gives(gl, method, light):
    # c * ambient + colour * intensity * (c * diffuse * n.l + specular * (n.h)^shininess), the
    # README's formula, worked by hand for a flat floor: light intensity and colour scale each
    # channel, the surface's colour only the ambient and diffuse terms.
    c, (ambient, diffuse, specular, shininess) = np.array([1.0, 0.8, 0.6]), (0.2, 0.5, 0.5, 4.0)
    lc, intensity = np.array([1.0, 0.5, 0.25]), 0.8
    z = np.arange(11, dtype=np.float32)[:, None, None]
    floor = Volume(np.broadcast_to(5.5 - z, (11, 11, 21)).copy(), name="floor")
    cam = Camera(eye=(10.0, 5.0, 100.0), look_at=(10.0, 5.0, 0.0), up=(0, 1, 0), parallel_scale=3.0)
    if light == "sun":
        lamp = DirectionalLight((-1.0, 0.0, -1.0), color=tuple(lc), intensity=intensity)
    else:
        lamp = PointLight((1e7, 5.0, 1e7 + 5.5), color=tuple(lc), intensity=intensity)   # far: nearly the sun
    scene = Scene(camera=cam, size=(8, 8), volumes=[Isosurface(floor, 0.0, color=tuple(c),
                                                               material=(ambient, diffuse, specular, shininess))],
                  lights=[lamp])
    n, l, v = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0), np.array([0.0, 0.0, 1.0])
    h = (l + v) / np.linalg.norm(l + v)
    expected = np.minimum(c * ambient + lc * intensity * (c * diffuse * (n @ l) + specular * (n @ h) ** shininess), 1.0)
    image = render(scene, method).image
    assert (image[..., 3] == 1.0).all()
    np.testing.assert_allclose(image[..., :3], np.broadcast_to(expected, (8, 8, 3)), atol=1e-5, rtol=0)


def test_a_scenes_progress_ends_at_exactly_one():
    # Shares summed one by one ended a lit scene of two surfaces at 0.9999999999999999.
    from parc.multivolume import _Report
    for n_iso in range(4):
        for n_trans in range(4):
            for shadows in (False, True):
                if n_iso + n_trans == 0:
                    continue
                seen = []
                report = _Report(seen.append, n_iso, n_trans, shadows)
                for phase in ("buffers", "surfaces", "lighting", "translucent"):
                    report.part(phase, 0.5)
                    report.done(phase)
                assert seen == sorted(seen) and seen[-1] == 1.0, (n_iso, n_trans, shadows, seen[-1])


def _lit_blob(light_place, light_buffer=None):
    vol = Volume(blobs(10, seed=2).data)
    lo, hi = vol.bounds
    cam = Camera.framing(lo, hi, azimuth=30, elevation=25)
    return vol, Scene(camera=cam, size=(16, 12), volumes=[Isosurface(vol, 100.0)],
                      lights=[PointLight(tuple(light_place))], shadows=True)


def test_light_buffers_are_kept_while_only_the_camera_moves(gl):
    from dataclasses import replace

    from parc.classify import VolumeIndex
    vol, scene = _lit_blob((30.0, -20.0, 25.0))
    render(scene, method="parc")
    kept = dict(VolumeIndex.of(vol).kept("light buffers"))
    assert len(kept) == 1
    moved = replace(scene, camera=Camera.framing(*vol.bounds, azimuth=-50, elevation=10))
    again = render(moved, method="parc")
    assert again.stats["seconds"]["raster_lights"] == 0.0
    assert VolumeIndex.of(vol).kept("light buffers") == kept
    ref = render(moved, method="brute")
    assert np.array_equal(np.isfinite(again.depth), np.isfinite(ref.depth))
    assert np.abs(again.image - ref.image).max() <= 1e-6


@pytest.mark.parametrize("change", ["surface", "light_buffer", "supercell", "kind_of_light"])
def test_light_buffers_are_drawn_anew_for_what_they_depend_on(gl, monkeypatch, change):
    # Kept light buffers serve only the proxy and the light they were drawn for: another
    # isovalue, buffer size, supercell size or a sun where a lamp was must draw its own.
    from dataclasses import replace

    import parc.multivolume
    monkeypatch.setattr(parc.multivolume, "_LIT", weakref.WeakSet())
    vol, scene = _lit_blob((0.0, 0.0, 1.0))
    first = render(scene, method="parc", supercell=2, light_buffer=16)
    assert first.stats["light_polygons"] > 0
    kw = dict(supercell=2, light_buffer=16)
    if change == "surface":
        scene = replace(scene, volumes=[Isosurface(vol, 60.0)])
    elif change == "light_buffer":
        kw["light_buffer"] = 8
    elif change == "supercell":
        kw["supercell"] = 3
    else:
        scene = replace(scene, lights=[DirectionalLight((0.0, 0.0, 1.0))])
    again = render(scene, method="parc", **kw)
    assert again.stats["light_polygons"] > 0
    ref = render(scene, method="brute")
    assert np.abs(again.image - ref.image).max() <= 1e-6


def test_kept_light_buffers_are_at_most_so_many_places(gl, monkeypatch):
    from dataclasses import replace

    import parc.multivolume
    from parc.classify import VolumeIndex
    monkeypatch.setattr(parc.multivolume, "_LIT", weakref.WeakSet())
    monkeypatch.setattr(parc.multivolume, "LIGHT_BUFFER_CACHE_SIZE", 2)
    vol, scene = _lit_blob((30.0, -20.0, 25.0))
    for k in range(4):
        render(replace(scene, lights=[DirectionalLight((1.0, float(k), -1.0))]), method="parc", light_buffer=8)
        assert len(VolumeIndex.of(vol).kept("light buffers")) == min(k + 1, 2)


@pytest.mark.parametrize("lamp, views", [((30.0, -20.0, 25.0), 1), ((4.0, 4.5, 4.5), 6)], ids=["outside", "inside"])
def test_polygons_count_the_light_buffers_drawn_this_frame(gl, monkeypatch, lamp, views):
    # The docstring: polygons are all PARC drew. The light buffers' faces were left out. A lamp
    # inside the box draws the proxy once into each of its six cube views.
    from dataclasses import replace

    import parc.multivolume
    monkeypatch.setattr(parc.multivolume, "_LIT", weakref.WeakSet())
    drawn = []
    draw = parc.multivolume.light_buffers

    def counted(light, proxy, size):
        buf = draw(light, proxy, size=size)
        assert len(buf.views) == views
        # Faces of one supercell each, never merged: a buffer's range stays within a supercell.
        f = proxy.faces
        assert len(f) and (f[:, 3] - f[:, 2] == 1).all() and (f[:, 5] - f[:, 4] == 1).all()
        drawn.append(proxy.n_polygons * views)
        return buf
    monkeypatch.setattr(parc.multivolume, "light_buffers", counted)
    vol, scene = _lit_blob(lamp)
    # The camera's merged proxy first, kept; supercells of 2 cells, where faces merge.
    render(replace(scene, lights=(), shadows=False), method="parc", supercell=2)
    first = render(scene, method="parc", supercell=2).stats
    own = sum(v["polygons"] for v in first["volumes"])
    assert len(drawn) == 1 and drawn[0] > 0
    assert first["light_polygons"] == drawn[0] and first["polygons"] == own + drawn[0]
    moved = render(replace(scene, camera=Camera.framing(*vol.bounds, azimuth=-50)), method="parc", supercell=2).stats
    assert len(drawn) == 1 and moved["light_polygons"] == 0         # kept, not drawn again
    assert moved["polygons"] == sum(v["polygons"] for v in moved["volumes"])
    assert render(scene, method="brute").stats["polygons"] == 0


@pytest.mark.parametrize("bound", [8, 12])
def test_kept_light_buffers_stay_within_their_bytes(gl, monkeypatch, bound):
    # A light moved from frame to frame kept each place's buffers, 16 of them: at a light_buffer
    # of 8192 a point light's take 6 GB, and a few moves filled the memory. A bound of 12 views
    # keeps two places, and the third must evict one: near and far buffers count alike.
    from dataclasses import replace

    import data_tools.memory
    import parc.lights
    import parc.multivolume
    from parc.classify import VolumeIndex
    vol, scene = _lit_blob((4.0, 4.5, 4.5))                 # inside: six cube views a place
    one = 2 * 64 * 64 * 8                                   # near and far of one 64x64 view
    monkeypatch.setattr(parc.multivolume, "_LIT", weakref.WeakSet())    # no other test's volumes
    monkeypatch.setattr(parc.lights, "LIGHT_BUFFER_CACHE_BYTES", bound * one)
    monkeypatch.setattr(data_tools.memory, "available_memory", lambda: 20 * one)   # a quarter is less
    for k, x in enumerate((4.0, 4.5, 5.0, 5.5)):
        res = render(replace(scene, lights=[PointLight((x, 4.5, 4.5))]), method="parc", light_buffer=64)
        kept = VolumeIndex.of(vol).kept("light buffers")
        held = sum(b.near.nbytes + b.far.nbytes for b in kept.values())
        # Room for the next light's six views is made before it is drawn: at most `bound` views kept.
        assert len(kept) == min(k + 1, bound // 6) and held <= bound * one, (len(kept), held)
        ref = render(replace(scene, lights=[PointLight((x, 4.5, 4.5))]), method="brute")
        assert np.abs(res.image - ref.image).max() <= 1e-6


def test_light_buffers_too_large_for_the_memory_are_refused_in_one_line(gl, monkeypatch):
    import data_tools.memory
    vol, scene = _lit_blob((4.5, 4.5, 4.5))                 # inside: six cube views
    monkeypatch.setattr(data_tools.memory, "available_memory", lambda: 512 << 20)
    with pytest.raises(InputError, match=r"^shadow buffers of 4096x4096 pixels from 6 views needs about 1.9 GB "
                                         r"of memory; 512 MB is available: give a smaller light_buffer"):
        render(scene, method="parc", light_buffer=4096)
    assert render(scene, method="parc").image.shape == (12, 16, 4)    # the default size fits


def test_several_lights_are_kept_together_where_the_memory_allows(gl, monkeypatch):
    # Three lights inside the volume, six views each, above the fixed bound: a quarter of the
    # memory holds them, so none is drawn again when only the camera moves.
    from dataclasses import replace

    import parc.lights
    import parc.multivolume
    monkeypatch.setattr(parc.multivolume, "_LIT", weakref.WeakSet())    # no other test's volumes
    monkeypatch.setattr(parc.lights, "LIGHT_BUFFER_CACHE_BYTES", 8 * 2 * 64 * 64 * 8)
    vol, scene = _lit_blob((4.0, 4.5, 4.5))
    scene = replace(scene, lights=[PointLight((x, 4.5, 4.5)) for x in (4.0, 4.5, 5.0)])
    render(scene, method="parc", light_buffer=64)
    moved = replace(scene, camera=Camera.framing(*vol.bounds, azimuth=-50, elevation=10))
    assert render(moved, method="parc", light_buffer=64).stats["seconds"]["raster_lights"] == 0.0


def test_room_is_made_for_the_views_the_light_takes_not_six(gl, monkeypatch):
    # Two point lights outside the volume take one perspective view each: a bound of two views
    # keeps both (room for six before each was drawn evicted the first).
    from dataclasses import replace

    import data_tools.memory
    import parc.lights
    import parc.multivolume
    from parc.classify import VolumeIndex
    from parc.lights import light_views
    vol, scene = _lit_blob((30.0, -20.0, 25.0))
    one = 2 * 64 * 64 * 8
    monkeypatch.setattr(parc.multivolume, "_LIT", weakref.WeakSet())    # no other test's volumes
    monkeypatch.setattr(parc.lights, "LIGHT_BUFFER_CACHE_BYTES", 2 * one)
    monkeypatch.setattr(data_tools.memory, "available_memory", lambda: 4 * one)     # a quarter is less
    lights = [PointLight((30.0, -20.0, 25.0)), PointLight((-25.0, 30.0, 20.0))]
    assert all(len(light_views(light, *vol.bounds)) == 1 for light in lights)
    render(replace(scene, lights=lights), method="parc", light_buffer=64)
    assert len(VolumeIndex.of(vol).kept("light buffers")) == 2


def test_a_lamps_single_view_holds_the_whole_box_at_every_width():
    # A point light outside the box takes one perspective view while the box's corners lie
    # within MAX_HALF_ANGLE of its centre: that view's square must hold every corner (the box
    # is convex). A limit past 45 degrees gave a view 1.6% too narrow, and parc lit points brute
    # shadowed. Lights are drawn where the corners lie 40 to 50 degrees off.
    from parc.lights import light_views
    rng = np.random.default_rng(44)
    single = near_limit = 0
    for _ in range(400):
        lo = rng.uniform(-20, 20, 3)
        hi = lo + rng.uniform(1, 30, 3)
        centre = (lo + hi) / 2
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        corners = np.array([[(lo, hi)[(n >> a) & 1][a] for a in range(3)] for n in range(8)])
        light = centre + d * np.linalg.norm(hi - lo) * rng.uniform(0.5, 0.9)
        to = corners - light
        axis = (centre - light) / np.linalg.norm(centre - light)
        half = np.degrees(np.arccos(np.min(to @ axis / np.linalg.norm(to, axis=1))))
        views = light_views(PointLight(tuple(light)), lo, hi)
        if (np.all(light >= lo) and np.all(light <= hi)) or len(views) > 1:
            continue
        single += 1
        f, r, u = views[0].basis()
        depth = to @ f
        reach = math.tan(math.radians(views[0].fov) / 2)
        assert depth.min() > 0, half
        assert np.abs(to @ r / depth).max() <= reach and np.abs(to @ u / depth).max() <= reach, half
        near_limit += 43 <= half
    assert single > 50 and near_limit > 10, (single, near_limit)


def test_a_lamp_outside_the_box_takes_only_the_views_that_see_the_box():
    # Box [0, 10]^3. Beyond the +x face at x = 25 its corners lie within 26 degrees of the
    # centre (cos = 15 / sqrt(275)): one perspective view. Half a unit beyond that face some
    # corners lie 86 degrees off (cos = 0.5 / sqrt(50.25)): cube views, all but those looking
    # away from the whole box (down +x; and +y too half a unit past the +y face). Inside it:
    # all six. (Each view is a buffer drawn and kept.)
    from parc.lights import light_views
    lo, hi = (0.0, 0.0, 0.0), (10.0, 10.0, 10.0)
    far = light_views(PointLight((25.0, 5.0, 5.0)), lo, hi)
    assert len(far) == 1 and not far[0].parallel
    np.testing.assert_allclose(far[0].basis()[0], (-1.0, 0.0, 0.0), atol=1e-15)

    def axes(position):
        return sorted(tuple(int(c) for c in np.round(cam.basis()[0]))
                      for cam in light_views(PointLight(position), lo, hi))
    six = sorted([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)])
    assert axes((10.5, 5.0, 5.0)) == [a for a in six if a != (1, 0, 0)]
    assert axes((10.5, 10.5, 5.0)) == [a for a in six if a not in ((1, 0, 0), (0, 1, 0))]
    assert axes((5.0, 5.0, 5.0)) == six


def test_kept_light_buffers_may_take_a_quarter_of_the_memory_they_and_the_available_make(monkeypatch):
    import data_tools.memory
    import parc.lights
    from parc.lights import LIGHT_BUFFER_CACHE_BYTES, light_cache_bytes
    monkeypatch.setattr(data_tools.memory, "available_memory", lambda: 40 << 30)
    assert light_cache_bytes(0) == 10 << 30
    assert light_cache_bytes(8 << 30) == 12 << 30
    monkeypatch.setattr(data_tools.memory, "available_memory", lambda: 1 << 30)
    assert light_cache_bytes(1 << 30) == LIGHT_BUFFER_CACHE_BYTES
    monkeypatch.setattr(data_tools.memory, "available_memory", lambda: None)
    assert light_cache_bytes(8 << 30) == parc.lights.LIGHT_BUFFER_CACHE_BYTES


def test_a_light_moved_every_frame_evicts_its_own_last_places_not_the_lights_that_stay(gl, monkeypatch):
    # Room for three lights of six views: two stay, one moves each frame. Only the moving one is
    # drawn again, each frame: evicting the oldest kept, not the longest unused, drew the lights
    # that stay again too.
    from dataclasses import replace

    import data_tools.memory
    import parc.lights
    import parc.multivolume
    one = 2 * 64 * 64 * 8
    monkeypatch.setattr(parc.multivolume, "_LIT", weakref.WeakSet())    # no other test's volumes
    monkeypatch.setattr(parc.lights, "LIGHT_BUFFER_CACHE_BYTES", 18 * one)
    monkeypatch.setattr(data_tools.memory, "available_memory", lambda: 40 * one)    # a quarter is less
    drawn = []
    draw = parc.multivolume.light_buffers
    monkeypatch.setattr(parc.multivolume, "light_buffers", lambda light, proxy, size: drawn.append(light)
                        or draw(light, proxy, size=size))
    vol, scene = _lit_blob((4.0, 4.5, 4.5))
    static = [PointLight((4.0, 4.5, 4.5)), PointLight((5.0, 4.5, 4.5))]
    for frame in range(5):
        drawn.clear()
        moving = PointLight((4.5, 4.0 + 0.01 * frame, 4.5))
        render(replace(scene, lights=[*static, moving]), method="parc", light_buffer=64)
        assert drawn == ([*static, moving] if frame == 0 else [moving]), (frame, drawn)


def test_the_bound_on_kept_light_buffers_holds_over_every_volume(gl, monkeypatch):
    # Two volumes, each lit from inside by a light moved every frame: each volume keeping up to
    # the bound would hold twice it together.
    from dataclasses import replace

    import data_tools.memory
    import parc.lights
    import parc.multivolume
    from parc.classify import VolumeIndex
    monkeypatch.setattr(parc.multivolume, "_LIT", weakref.WeakSet())    # no other test's volumes
    one = 2 * 64 * 64 * 8
    monkeypatch.setattr(parc.lights, "LIGHT_BUFFER_CACHE_BYTES", 8 * one)
    monkeypatch.setattr(data_tools.memory, "available_memory", lambda: 20 * one)   # a quarter is less
    (a, scene_a), (b, scene_b) = _lit_blob((4.0, 4.5, 4.5)), _lit_blob((4.0, 4.5, 4.5))
    for frame in range(4):
        for vol, scene in ((a, scene_a), (b, scene_b)):
            lit = replace(scene, lights=[PointLight((4.0 + 0.25 * frame, 4.5, 4.5))])
            render(lit, method="parc", light_buffer=64)
            held = sum(buf.near.nbytes + buf.far.nbytes for v in (a, b)
                       for buf in VolumeIndex.of(v).kept("light buffers").values())
            assert held <= 8 * one, (frame, held)


#: The normal of `_plane_scene`'s plane (unit: 0.2304 + 0.1296 + 0.64 = 1).
N_PLANE = np.array([0.48, 0.36, 0.8])


def _plane_scene(lights):
    # f = n . p - 14 sampled at the grid points: trilinear interpolation of a linear field is the
    # field itself, so the isosurface f = 0 is the exact plane and its normal is exactly n.
    k, j, i = np.mgrid[0:21, 0:21, 0:21].astype(np.float64)
    data = N_PLANE[0] * i + N_PLANE[1] * j + N_PLANE[2] * k - 14.0
    cam = Camera(eye=(10.0, 10.0, 100.0), look_at=(10.0, 10.0, 0.0), up=(0, 1, 0), parallel_scale=3.0)
    surf = Isosurface(Volume(data, name="tilted plane"), 0.0, color=(1.0, 0.8, 0.6), material=(0.2, 0.5, 0.5, 4.0))
    return Scene(camera=cam, size=(8, 8), volumes=[surf], lights=lights)


def _blinn_phong(c, n, l, v, material=(0.2, 0.5, 0.5, 4.0)):
    amb, kd, ks, s = material
    h = (l + v) / np.linalg.norm(l + v)
    return np.minimum(c * amb + c * kd * max(n @ l, 0.0) + ks * max(n @ h, 0.0) ** s, 1.0)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_tilted_plane_under_the_sun_has_the_analytic_shading(gl, method):
    # A sun with x and y components: a wrong sign in any gradient component turns the normal
    # and changes n.l and n.h.
    sun = np.array([-0.3, -0.2, -1.0])
    want = _blinn_phong(np.array([1.0, 0.8, 0.6]), N_PLANE, -sun / np.linalg.norm(sun), np.array([0.0, 0.0, 1.0]))
    res = render(_plane_scene([DirectionalLight(tuple(sun))]), method)
    assert (res.image[..., 3] == 1.0).all()
    np.testing.assert_allclose(res.image[..., :3], np.broadcast_to(want, (8, 8, 3)), atol=1e-5, rtol=0)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_tilted_plane_under_the_headlight_has_the_analytic_shading(gl, method):
    # No lights: a light at the eye, l = v = (0, 0, 1) for this parallel view, so h = v.
    v = np.array([0.0, 0.0, 1.0])
    want = _blinn_phong(np.array([1.0, 0.8, 0.6]), N_PLANE, v, v)
    res = render(_plane_scene([]), method)
    assert (res.image[..., 3] == 1.0).all()
    np.testing.assert_allclose(res.image[..., :3], np.broadcast_to(want, (8, 8, 3)), atol=1e-5, rtol=0)


def _floor_beside_a_wall(wall_data, wall_origin):
    """A white floor (z = 5.5) seen straight down over x in [7, 13], y in [2, 8], and a tall wall
    (an isosurface of ``wall_data`` at 0.5) standing beside the view."""
    z = np.arange(11, dtype=np.float32)[:, None, None]
    floor = Isosurface(Volume(np.broadcast_to(5.5 - z, (11, 11, 21)).copy(), name="floor"), 0.0,
                       color=(1.0, 1.0, 1.0), material=(0.2, 0.5, 0.5, 4.0))
    wall = Isosurface(Volume(wall_data, origin=wall_origin, name="wall"), 0.5)
    cam = Camera(eye=(10.0, 5.0, 100.0), look_at=(10.0, 5.0, 0.0), up=(0, 1, 0), parallel_scale=3.0)
    return cam, [floor, wall]


def _lit_floor(towards_light):
    """The floor's colour lit by one light from ``towards_light``: ambient + diffuse + specular."""
    n = v = np.array([0.0, 0.0, 1.0])
    l = np.asarray(towards_light, float) / np.linalg.norm(towards_light)
    h = (l + v) / np.linalg.norm(l + v)
    return min(0.2 + 0.5 * (n @ l) + 0.5 * (n @ h) ** 4, 1.0)


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("blocked_first", [True, False])
def test_a_wall_hides_one_sun_and_not_the_other(gl, method, blocked_first):
    # A wall at x in [25, 27]: a sun travelling along (-1, 0, -1) comes from +x and is blocked;
    # one along (1, 0, -1) comes from -x and is not. With each light taking the first one's
    # shadow, the free sun counted twice or not at all (scenes of several lights were only
    # checked against brute, which shares that code).
    d = np.zeros((81, 21, 5), np.float32)
    d[:, :, 1:4] = 1.0
    cam, volumes = _floor_beside_a_wall(d, (24.0, -5.0, 0.0))
    blocked, free = DirectionalLight((-1.0, 0.0, -1.0)), DirectionalLight((1.0, 0.0, -1.0))
    scene = Scene(camera=cam, size=(8, 8), volumes=volumes,
                  lights=[blocked, free] if blocked_first else [free, blocked], shadows=True)
    img = render(scene, method).image
    assert (img[..., 3] == 1.0).all()
    np.testing.assert_allclose(img[..., :3], _lit_floor((-1.0, 0.0, 1.0)), atol=1e-5, rtol=0)


@pytest.mark.parametrize("sy", [-1.0, 1.0])
def test_the_sun_shadows_from_the_side_it_shines_from(gl, sy):
    # A wall at y in [12.5, 15.5] up to z = 80: a sun travelling along (0, -1, -1) comes from +y,
    # and every floor ray towards it meets the wall, so the floor shows ambient only; along
    # (0, 1, -1) it comes from -y, where nothing stands, and the floor is lit.
    d = np.zeros((81, 5, 41), np.float32)
    d[:, 1:4, :] = 1.0
    cam, volumes = _floor_beside_a_wall(d, (-10.0, 12.0, 0.0))
    img = render(Scene(camera=cam, size=(8, 8), volumes=volumes, lights=[DirectionalLight((0.0, sy, -1.0))],
                       shadows=True)).image
    assert (img[..., 3] == 1.0).all()
    np.testing.assert_allclose(img[..., :3], 0.2 if sy < 0 else _lit_floor((0.0, -1.0, 1.0)), atol=1e-5)


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_a_convex_body_on_an_anisotropic_grid_casts_no_shadow_on_itself(gl, method):
    # A ball lit by a sun shadows nothing it lights: its lit side faces the sun. Hit points
    # built with one axis's spacing for another's would sit off the surface, inside or out,
    # and their shadow rays would meet the ball. Spacings differ along every axis.
    from dataclasses import replace
    spacing = (1.0, 2.5, 0.7)
    n = (21, 11, 31)
    z, y, x = np.meshgrid(*(np.arange(k) * s for k, s in zip(n[::-1], spacing[::-1])), indexing="ij")
    centre = [(k - 1) * s / 2 for k, s in zip(n, spacing)]
    data = np.sqrt((x - centre[0]) ** 2 + (y - centre[1]) ** 2 + (z - centre[2]) ** 2)
    vol = Volume(data, spacing=spacing)
    for sun in ((1.0, 0.3, 0.2), (0.2, -1.0, 0.4), (-0.3, 0.2, -1.0)):
        scene = Scene(camera=Camera.framing(*vol.bounds, azimuth=35, elevation=20), size=(40, 32),
                      volumes=[Isosurface(vol, 8.0)], lights=[DirectionalLight(sun)])
        lit = render(scene, method=method).image
        shadowed = render(replace(scene, shadows=True), method=method).image
        assert (lit[..., 3] > 0).sum() > 100
        assert np.abs(shadowed - lit).max() <= 1e-6, sun
