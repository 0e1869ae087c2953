"""The unaccelerated caster on a sphere's distance field, against the analytic sphere.

Truth: the sphere |p - c| = r. The trilinear interpolant of the distance
field differs from the true distance by at most ``h^2 / (8 rho)`` per axis
summed (second derivatives of |p - c| are below ``1 / rho`` at distance
``rho`` from the centre), so a hit point's distance from the centre is
within ``bound = 3 h^2 / (8 rho_min)`` of r (``h`` the largest spacing,
``rho_min = r - 2 h`` a lower bound on ``rho`` in the cells the surface
crosses), and only rays passing within ``bound`` of the sphere may disagree
on hit or miss.
"""
import numpy as np
import pytest

from data_tools import Volume
from parc import Camera, Isosurface, Scene, render


def _sphere(n, spacing, origin, radius_cells):
    spacing = np.asarray(spacing)
    origin = np.asarray(origin)
    ext = (n - 1) * spacing
    c = origin + ext / 2
    r = radius_cells * spacing.min()
    k, j, i = np.mgrid[0:n, 0:n, 0:n]
    p = np.stack([origin[0] + i * spacing[0], origin[1] + j * spacing[1], origin[2] + k * spacing[2]], -1)
    data = np.linalg.norm(p - c, axis=-1) - r
    return Volume(data.astype(np.float64), spacing=tuple(spacing), origin=tuple(origin)), c, r


@pytest.mark.parametrize("parallel", [False, True])
@pytest.mark.parametrize("spacing, origin", [((1, 1, 1), (0, 0, 0)), ((0.5, 0.7, 0.9), (-3.0, 12.0, 5.5))])
def test_sphere_silhouette_and_depth(parallel, spacing, origin):
    vol, c, r = _sphere(40, spacing, origin, radius_cells=13.0)
    rho_min = r - 2.0 * max(spacing)
    bound = 3 * max(spacing) ** 2 / (8 * rho_min)
    cam = Camera.framing(*vol.bounds, azimuth=28.0, elevation=17.0, parallel=parallel, zoom=1.6)
    scene = Scene(camera=cam, size=(96, 80), volumes=[Isosurface(vol, 0.0)])
    res = render(scene, method="brute")
    o, d = cam.rays(96, 80)

    hit = np.isfinite(res.depth)
    # Analytic ray/sphere: distance of closest approach tells hit or miss.
    oc = o - c
    b = (oc * d).sum(-1)
    closest = np.sqrt(np.maximum((oc * oc).sum(-1) - b * b, 0.0))
    sure_hit = closest < r - bound
    sure_miss = closest > r + bound
    assert hit[sure_hit].all(), "rays clearly through the sphere missed it"
    assert not hit[sure_miss].any(), "rays clearly past the sphere hit something"
    assert sure_hit.sum() > 500

    p = o[hit] + res.depth[hit][:, None] * d[hit]
    dist = np.linalg.norm(p - c, axis=-1)
    assert np.abs(dist - r).max() <= bound
    # The first hit, not a later one: the near side of the sphere (a hit point
    # may sit past the silhouette plane only by the grazing slack sqrt(2 r bound)).
    assert ((p - c) * d[hit]).sum(-1).max() <= np.sqrt(2 * r * bound)
    # Depth against the analytic near root, where the ray meets the sphere at
    # a slope: a surface error of `bound` moves t by at most bound / cos(angle).
    steep = sure_hit & (closest < 0.8 * r)
    t_true = -b - np.sqrt(np.maximum(r * r - closest ** 2, 0.0))
    cos = np.sqrt(np.maximum(1 - (closest / r) ** 2, 1e-12))
    assert (np.abs(res.depth - t_true)[steep] <= (bound / cos)[steep]).all()


def test_sphere_image_is_lit_where_it_is_hit():
    vol, c, r = _sphere(24, (1, 1, 1), (0, 0, 0), radius_cells=8.0)
    cam = Camera.framing(*vol.bounds, zoom=1.5)
    res = render(Scene(camera=cam, size=(48, 48), volumes=[Isosurface(vol, 0.0)]))
    hit = np.isfinite(res.depth)
    assert res.image.dtype == np.float32 and res.image.shape == (48, 48, 4)
    assert (res.image[..., 3][hit] == 1.0).all() and (res.image[~hit] == 0).all()
    # Headlight: the pixel nearest the sphere's centre faces the eye, so it is brightest.
    lum = res.image[..., :3].sum(-1)
    y, x = np.unravel_index(np.argmax(np.where(hit, -res.depth, -np.inf)), hit.shape)
    assert lum[y, x] >= np.percentile(lum[hit], 95)
    s = res.stats
    assert s["cells_visited"] > s["cubic_solves"] >= s["hits"] == hit.sum() > 0


@pytest.mark.parametrize("seed", range(4))
def test_shading_in_the_cast_equals_the_shading_pass(seed):
    # The render shades each hit inside its cast; the separate pass over the
    # hits (the Parker bench's) must give the very same colours.
    from raycast.iso import NO_SHADING, NO_SKIP, cast_iso_image, empty_outputs
    from raycast.shade import shade_headlight

    rng = np.random.default_rng(seed)
    data = rng.normal(size=(14, 17, 12)).cumsum(axis=0).astype(np.float32)
    vol = Volume(data, spacing=tuple(rng.uniform(0.5, 2.0, 3)), origin=tuple(rng.uniform(-5, 5, 3)))
    iso = Isosurface(vol, float(np.quantile(data, rng.uniform(0.3, 0.7))), color=tuple(rng.uniform(0, 1, 3)))
    cam = Camera.framing(*vol.bounds, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-60, 60),
                         parallel=bool(seed % 2))
    w, h = 45, 37
    args = (vol.data, np.array(vol.origin), np.array(vol.spacing), cam.as_array(), w, h, iso.value,
            np.empty((1, 1, 2)), False, NO_SKIP, -1)
    color, material = np.array(iso.color, dtype=np.float64), np.array(iso.material, dtype=np.float64)
    fused = np.zeros((h, w, 4), np.float32)
    t, cell, uvw, counts = empty_outputs(w * h)
    cast_iso_image(*args, t, cell, uvw, counts, 0, h, True, color, material, fused)
    apart = np.zeros((h, w, 4), np.float32)
    t2, cell2, uvw2, counts2 = empty_outputs(w * h)
    cast_iso_image(*args, t2, cell2, uvw2, counts2, 0, h, *NO_SHADING)
    shade_headlight(vol.data, np.array(vol.spacing), cam.as_array(), w, h, t2, cell2, uvw2, color, material, apart)
    assert np.isfinite(t).sum() > 20
    np.testing.assert_array_equal(t, t2)
    np.testing.assert_array_equal(fused, apart)
    assert render(Scene(camera=cam, size=(w, h), volumes=[iso]), method="brute").image.tobytes() == fused.tobytes()


@pytest.mark.parametrize("seed", range(3))
def test_cast_totals_are_the_sums_of_the_per_pixel_outputs(seed):
    # The stats take the totals the kernels return: band by band (as with
    # progress), they must add up to what the per-pixel outputs hold.
    from parc.renderer import accumulation_params
    from parc.scene import Translucent
    from parc.skip import skip_table
    from parc.transfer import load_transfer_function
    from raycast.composite import cast_accumulate_image
    from raycast.iso import NO_SHADING, cast_iso_image, empty_outputs

    rng = np.random.default_rng(seed)
    data = rng.normal(size=(13, 15, 11)).cumsum(axis=1).astype(np.float32)
    vol = Volume(data, spacing=tuple(rng.uniform(0.5, 2.0, 3)))
    cam = Camera.framing(*vol.bounds, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-60, 60))
    w, h = 33, 29
    bands = [(0, 8), (8, 9), (9, h)]
    iso = Isosurface(vol, float(np.quantile(data, 0.6)))
    skip, jump_min = skip_table(iso, bool(seed % 2))
    t, cell, uvw, counts = empty_outputs(w * h)
    totals = sum(np.asarray(cast_iso_image(vol.data, np.array(vol.origin), np.array(vol.spacing), cam.as_array(),
                                           w, h, iso.value, np.empty((1, 1, 2)), False, skip, jump_min,
                                           t, cell, uvw, counts, y0, y1, *NO_SHADING)) for y0, y1 in bands)
    assert totals.tolist() == [np.isfinite(t).sum(), counts[:, 0].sum(), counts[:, 1].sum()]
    assert totals[0] > 0

    tf = load_transfer_function("greyscale", data_range=(float(data.min()), float(data.max())))
    vis = Translucent(vol, tf)
    op_x, op_y, col_x, col_rgb = tf.arrays()
    image = np.zeros((h, w, 4), np.float32)
    samples = np.zeros(w * h, np.int64)
    skip, jump_min = skip_table(vis, bool(seed % 2))
    total = sum(cast_accumulate_image(vol.data, np.array(vol.origin), np.array(vol.spacing), cam.as_array(), w, h,
                                      accumulation_params(vis), op_x, op_y, col_x, col_rgb, np.empty((1, 1, 2)),
                                      False, np.empty((1, 1)), False, np.zeros((1, 1, 1), np.uint32), False,
                                      skip, jump_min, image, samples, y0, y1) for y0, y1 in bands)
    assert total == samples.sum() > 0


@pytest.mark.parametrize("lit", [False, True])
def test_stats_hold_the_documented_keys(lit):
    # RenderResult's docstring: brute draws no polygons and says so.
    from parc import PointLight
    vol, c, r = _sphere(12, (1, 1, 1), (0, 0, 0), radius_cells=4.0)
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(8, 8), volumes=[Isosurface(vol, 0.0)],
                  lights=[PointLight(position=(30.0, 30.0, 30.0))] if lit else [])
    stats = render(scene, method="brute").stats
    for key in ("method", "seconds", "pixels", "rays", "cells_visited", "cubic_solves", "samples", "hits",
                "polygons", "parameters", "shadow_rays", "shadow_cells", "shadow_solves", "shadow_samples",
                "light_polygons"):
        assert key in stats, key
    assert stats["polygons"] == 0 and stats["cells_visited"] > 0
    # The same keys however the scene is cast: alone (unlit) or with the others (lit).
    assert all(stats[k] == 0 for k in ("shadow_rays", "shadow_cells", "shadow_solves", "shadow_samples"))


def test_a_result_saves_its_image_as_png_or_npy(tmp_path):
    # The PNG holds straight colour (the image is premultiplied), the .npy the array as it is.
    from PIL import Image

    from data_tools import InputError
    from parc import Translucent
    vol, c, r = _sphere(16, (1, 1, 1), (0, 0, 0), radius_cells=5.0)
    res = render(Scene(camera=Camera.framing(*vol.bounds), size=(24, 20), volumes=[Translucent(vol, "greyscale")]))
    assert res.save(tmp_path / "a.png") == tmp_path / "a.png"
    res.save(tmp_path / "a.npy")
    assert np.array_equal(np.load(tmp_path / "a.npy"), res.image)
    png = np.asarray(Image.open(tmp_path / "a.png")).astype(np.float64) / 255.0
    a = res.image[..., 3].astype(np.float64)
    faint = a > 0.2                                         # where straight colour is rounded finely
    assert png.shape == (20, 24, 4) and faint.any() and np.abs(png[..., 3] - a).max() <= 0.5 / 255 + 1e-9
    straight = res.image[..., :3][faint] / a[faint][:, None]
    assert np.abs(png[..., :3][faint] - straight).max() <= 0.5 / 255 + 1e-6
    for bad in ("a.jpg", "nofolder/a.png"):
        with pytest.raises(InputError):
            res.save(tmp_path / bad)
    for bad in (None, b"a.png"):
        with pytest.raises(InputError, match="RenderResult.save takes a file's path, got "):
            res.save(bad)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npy", "a.png"]


@pytest.mark.parametrize("lit", [False, True])
def test_progress_starts_at_zero_and_rises_to_one_once(lit):
    from parc import DirectionalLight
    vol, c, r = _sphere(16, (1, 1, 1), (0, 0, 0), radius_cells=5.0)
    seen = []
    render(Scene(camera=Camera.framing(*vol.bounds), size=(24, 24), volumes=[Isosurface(vol, 0.0)],
                 lights=[DirectionalLight((1.0, 0.0, 0.0))] if lit else [], shadows=lit), progress=seen.append)
    assert seen[0] == 0.0 and seen[-1] == 1.0 and seen.count(1.0) == 1
    assert all(a < b for a, b in zip(seen, seen[1:]))


def test_a_render_that_compiles_logs_it_once_at_info(caplog, monkeypatch):
    # A first render of a kind compiled for up to a minute with no word to a library user.
    import logging

    import numba
    import parc.renderer as renderer
    vol, c, r = _sphere(8, (1, 1, 1), (0, 0, 0), radius_cells=2.0)
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(8, 8), volumes=[Isosurface(vol, 0.0)])
    real = renderer._render

    def compiling(*args):
        for x in (1, 2.0):                  # two compiles, one line
            numba.njit(lambda v: 2 * v)(x)
        return real(*args)
    monkeypatch.setattr(renderer, "_render", compiling)
    with caplog.at_level(logging.INFO, logger="parc"):
        render(scene)
    said = [rec.getMessage() for rec in caplog.records if rec.name == "parc"]
    assert len(said) == 1 and said[0].startswith("compiling the ray casters for this kind of render")
    assert said[0].endswith("once on this machine")
    # Where the cache folder cannot be written, every run compiles: not "once".
    import raycast.kernel_cache
    monkeypatch.setattr(raycast.kernel_cache, "_REFUSED", "/nowhere/cache")
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="parc"):
        render(scene)
    said = [rec.getMessage() for rec in caplog.records if rec.name == "parc"]
    assert len(said) == 1 and said[0].endswith("in every run: /nowhere/cache cannot be written")
    caplog.clear()
    monkeypatch.setattr(renderer, "_render", real)
    with caplog.at_level(logging.INFO, logger="parc"):
        render(scene)                       # cached: nothing compiles, nothing is said
    assert [rec for rec in caplog.records if rec.name == "parc"] == []


@pytest.mark.parametrize("spacing", [1e30, 1e-30])
def test_the_smallest_samples_a_volume_takes_shade_as_the_same_samples_scaled_up(spacing):
    """Samples and isovalue times 2^600 (exact) have the same surface, normals and shadows. Below
    `MIN_SAMPLE`, the gradient underflowed over a spacing of 1e30 and every normal faced the eye."""
    from parc import DirectionalLight
    z, y, x = np.meshgrid(*[np.linspace(-1, 1, 10)] * 3, indexing="ij")
    small = (x * x + y * y + z * z) * 1e-200
    images = []
    for k in (0, 600):
        vol = Volume(np.ldexp(small, k), spacing=(spacing,) * 3)
        scene = Scene(camera=Camera.framing(*vol.bounds), size=(32, 32), shadows=True,
                      volumes=[Isosurface(vol, float(np.ldexp(0.5e-200, k)))],
                      lights=[DirectionalLight(direction=(1.0, -0.5, -2.0))])
        images.append(render(scene, "brute"))
    assert np.isfinite(images[0].depth).sum() > 100
    assert np.array_equal(images[0].depth, images[1].depth)
    assert np.array_equal(images[0].image, images[1].image)
