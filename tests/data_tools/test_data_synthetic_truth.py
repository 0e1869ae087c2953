"""Synthetic volumes against independent truth: every expected value is computed here from the
documented formula, parameters and layout (axis order [z, y, x], x fastest), not by the generator."""
from __future__ import annotations

import math

import numpy as np
import pytest

from data_tools import InputError
from data_tools.grids import grid_axes, grid_dims
from data_tools.neuron import _blur
from data_tools.synthetic import (DESCRIPTIONS, ISOVALUES, SYNTHETIC, blobs, ct_phantom, ct_phantom_to_disk, floor,
                                  make_synthetic, making_note, marschner_lobb, neuron, sphere, torus,
                                  trilinear_field)

DIMS = (10, 7, 5)     # nx, ny, nz: every axis different, so a swapped axis shows


def _index_grids(dims):
    """Float64 index coordinates i (x), j (y), k (z), each of shape (nz, ny, nx)."""
    nx, ny, nz = dims
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    return i.astype(float), j.astype(float), k.astype(float)


def test_sphere_non_cubic_centre_radius_and_layout():
    vol = sphere(DIMS)
    assert vol.shape == (5, 7, 10) and vol.dtype == np.float32 and vol.name == "sphere 10x7x5"
    assert vol.spacing == (1, 1, 1) and vol.origin == (0, 0, 0)
    centre, radius = (4.5, 3.0, 2.0), 0.35 * (5 - 1)           # radius: a fraction of the smallest extent
    assert tuple(vol.meta["center"]) == centre and vol.meta["radius"] == pytest.approx(radius)
    i, j, k = _index_grids(DIMS)
    exact = np.sqrt((i - centre[0]) ** 2 + (j - centre[1]) ** 2 + (k - centre[2]) ** 2) - radius
    np.testing.assert_allclose(vol.data, exact, atol=1e-5)


def test_torus_non_cubic_default_radii():
    vol = torus((13, 11, 9))
    ext = 9 - 1                                                  # the smallest extent
    big_r, small_r = 0.3 * ext, 0.12 * ext                       # the documented default fractions
    assert vol.meta["major_radius"] == pytest.approx(big_r) and vol.meta["minor_radius"] == pytest.approx(small_r)
    assert tuple(vol.meta["center"]) == (6.0, 5.0, 4.0)
    i, j, k = _index_grids((13, 11, 9))
    exact = np.hypot(np.hypot(i - 6.0, j - 5.0) - big_r, k - 4.0) - small_r   # ring around z
    np.testing.assert_allclose(vol.data, exact, atol=1e-5)


def test_marschner_lobb_every_sample_non_cubic():
    # Marschner & Lobb 1994: rho = (1 - sin(pi z / 2) + alpha (1 + rho_r(r))) / (2 (1 + alpha)),
    # rho_r(r) = cos(2 pi f_M cos(pi r / 2)), r = sqrt(x^2 + y^2), alpha = 1/4, f_M = 6, on [-1, 1]^3.
    nx, ny, nz = 9, 7, 5
    vol = marschner_lobb((nx, ny, nz))
    assert vol.meta["alpha"] == 0.25 and vol.meta["f_m"] == 6 and vol.meta["iso"] == 0.5
    assert vol.origin == (-1, -1, -1)
    assert vol.spacing == pytest.approx((2 / (nx - 1), 2 / (ny - 1), 2 / (nz - 1)))
    i, j, k = _index_grids((nx, ny, nz))
    x, y, z = -1 + 2 * i / (nx - 1), -1 + 2 * j / (ny - 1), -1 + 2 * k / (nz - 1)
    rho_r = np.cos(2 * math.pi * 6 * np.cos(math.pi * np.hypot(x, y) / 2))
    expect = (1 - np.sin(math.pi * z / 2) + 0.25 * (1 + rho_r)) / (2 * 1.25)
    np.testing.assert_allclose(vol.data, expect, atol=1e-6)


@pytest.mark.parametrize("name", sorted(SYNTHETIC))
def test_meta_iso_is_the_registry_level(name):
    # parc make tells the user to render at ISOVALUES; the volume must say the same level.
    vol = make_synthetic(name, 12)
    if ISOVALUES[name]:
        assert vol.meta["iso"] == ISOVALUES[name][0]
        assert all(f"iso {v:g}" in DESCRIPTIONS[name] for v in ISOVALUES[name])
    assert vol.meta["synthetic"] == name


def test_make_synthetic_passes_keywords_through():
    np.testing.assert_array_equal(make_synthetic("blobs", 12, seed=3).data, blobs(12, seed=3).data)
    assert not np.array_equal(make_synthetic("blobs", 12, seed=3).data, blobs(12, seed=0).data)


def test_grid_helpers():
    x, y, z = grid_axes((3, 4, 2), spacing=(0.5, 2.0, 3.0), origin=(1.0, -1.0, 10.0))
    assert x.shape == (1, 1, 3) and y.shape == (1, 4, 1) and z.shape == (2, 1, 1)
    np.testing.assert_array_equal(x.ravel(), [1.0, 1.5, 2.0])
    np.testing.assert_array_equal(y.ravel(), [-1.0, 1.0, 3.0, 5.0])
    np.testing.assert_array_equal(z.ravel(), [10.0, 13.0])
    assert grid_dims(5) == (5, 5, 5) and grid_dims((4, 3, 2)) == (4, 3, 2)
    for bad in ((2, 1, 2), (2, 2), (2, 2, 2, 2), 1):
        with pytest.raises(InputError):
            grid_dims(bad)


def test_blobs_noise_is_the_documented_fraction_of_full_scale_and_clipped():
    nx, ny, nz = 16, 12, 14
    clean, noisy = blobs((nx, ny, nz), seed=5, noise=0.0), blobs((nx, ny, nz), seed=5)
    assert clean.shape == noisy.shape == (nz, ny, nx) and clean.dtype == np.uint8
    # The same blobs, then Gaussian noise of 0.04 of the 215-level span (8.6 levels), rounded.
    diff = noisy.data.astype(float) - clean.data.astype(float)
    keep = clean.data < 215                                      # away from clipping at 255 (the rest is >= 20)
    assert keep.sum() > 1000 and 7.0 < diff[keep].std() < 10.5
    # The dim background of a real stack: 20 levels where no blob reaches.
    assert clean.data.min() == 20
    # Values beyond the uint8 range are clipped, not wrapped around.
    loud = blobs(16, seed=1, noise=2.0).data
    assert (loud == 0).mean() > 0.3 and (loud == 255).mean() > 0.3


def test_trilinear_field_interpolates_exactly_in_world_coordinates():
    # F is trilinear in each cell, so trilinear interpolation of the samples at any world point
    # equals F((p - origin) / spacing), evaluated here from the reported coefficients.
    spacing, origin = (0.5, 2.0, 1.25), (3.0, -1.0, 0.5)
    vol = trilinear_field((5, 4, 3), seed=7, spacing=spacing, origin=origin)
    assert vol.spacing == spacing and vol.origin == origin and vol.meta["exact"]
    c = vol.meta["coeffs"]
    d = vol.data
    rng = np.random.default_rng(0)
    for _ in range(50):
        u = rng.uniform(0, 1, 3) * (np.array([5, 4, 3]) - 1)   # index coordinates x, y, z
        p = np.array(origin) + u * np.array(spacing)           # the world point
        i, j, k = ((p - np.array(origin)) / np.array(spacing))
        f = (c[0] + c[1] * i + c[2] * j + c[3] * k + c[4] * i * j + c[5] * j * k + c[6] * k * i
             + c[7] * i * j * k)
        i0, j0, k0 = (min(int(v), n - 2) for v, n in zip((i, j, k), (5, 4, 3)))
        fx, fy, fz = i - i0, j - j0, k - k0
        interp = sum(d[k0 + b, j0 + a, i0 + e] * (fx if e else 1 - fx) * (fy if a else 1 - fy) * (fz if b else 1 - fz)
                     for e in (0, 1) for a in (0, 1) for b in (0, 1))
        assert interp == pytest.approx(f, abs=1e-9)


def test_trilinear_field_random_coefficients():
    seen = set()
    for seed in range(30):
        vol = trilinear_field(3, seed=seed)
        c = vol.meta["coeffs"]
        assert all(type(v) is int and -4 <= v <= 4 for v in c) and c[7] != 0, (seed, c)
        seen |= {m for m in range(8) if c[m] != 0}
        lo, hi = vol.value_range()
        iso = vol.meta["iso"]
        # A level strictly inside the samples, never equal to one (they are integers).
        assert lo < iso < hi and iso != round(iso), (seed, iso)
    assert seen == set(range(8))                # every term of F occurs


def test_trilinear_field_coefficients_as_given():
    vol = trilinear_field(3, coeffs=np.array([1, 2, 3, 4, 5, 6, 7, 8]))
    assert all(type(v) is int for v in vol.meta["coeffs"])          # Python numbers, as documented
    assert vol.spacing == (1, 1, 1) and vol.origin == (0, 0, 0)      # the defaults
    for n in (7, 9):
        with pytest.raises(InputError, match="8 coefficients"):
            trilinear_field(3, coeffs=range(n))
    # Large integer coefficients: computed in 64 bits, not wrapped (27 * 2**30 > 2**31).
    big = trilinear_field(4, coeffs=(0, 0, 0, 0, 0, 0, 0, 2 ** 30))
    assert big.data[3, 3, 3] == 27 * 2 ** 30 and big.meta["exact"]
    # Fractional coefficients stored in an integer type are not exact.
    assert not trilinear_field(3, coeffs=(0.5, 1, 0, 0, 0, 0, 0, 0), dtype="int16").meta["exact"]


def test_trilinear_field_integer_range_boundaries():
    # Samples -128 and 127 fill int8 exactly: accepted; one more is refused.
    vol = trilinear_field(2, coeffs=(-128, 255, 0, 0, 0, 0, 0, 0), dtype="int8")
    assert vol.value_range() == (-128, 127) and vol.meta["exact"]
    with pytest.raises(InputError, match="do not fit int8"):
        trilinear_field(2, coeffs=(-128, 256, 0, 0, 0, 0, 0, 0), dtype="int8")
    with pytest.raises(InputError, match="do not fit int8"):
        trilinear_field(2, coeffs=(-129, 255, 0, 0, 0, 0, 0, 0), dtype="int8")


def test_ct_phantom_noise_is_per_slice_and_seeded():
    # The noise of slice k is Normal(0, noise) drawn from default_rng((seed, k)) (documented).
    shape = (12, 10, 6)
    clean = ct_phantom(shape, noise=0.0).data.astype(float)
    noisy = ct_phantom(shape, seed=3).data.astype(float)
    for k in range(6):
        draw = np.random.default_rng((3, k)).normal(0.0, 20.0, size=(10, 12))
        body = clean[k] > 200                                       # away from the clip at 0
        if body.any():
            assert np.abs(noisy[k][body] - clean[k][body] - draw[body]).max() <= 1.0 + 1e-9
    assert not np.array_equal(noisy, ct_phantom(shape, seed=4).data)
    # Air is about 0 and never negative, even in a signed type.
    assert noisy.min() == 0
    with pytest.raises(InputError):
        ct_phantom(8, dtype="int32")


def test_neuron_photon_noise_is_poisson():
    clean, noisy = neuron(24, seed=2, noise=False), neuron(24, seed=2)
    d = noisy.data.astype(float) - clean.data.astype(float)
    dark = clean.data == 12                                          # the background: 12 photons
    assert dark.mean() > 0.3
    assert 9.0 < d[dark].var() < 15.0                                # Poisson: variance = mean = 12
    soma = np.array(clean.meta["soma"])
    assert soma[2] < 0.4 * 23 and abs(soma[0] - 11.5) < 2 and abs(soma[1] - 11.5) < 2   # low in the box


def test_blur_sigmas_are_x_y_z_and_keep_the_total():
    delta = np.zeros((21, 23, 25), dtype=np.float32)
    delta[10, 11, 12] = 1.0
    out = _blur(delta, (0.7, 1.0, 1.5))
    assert out.sum() == pytest.approx(1.0, rel=1e-5)
    k, j, i = np.indices(out.shape)
    var = [float((out * (a - c) ** 2).sum()) for a, c in ((i, 12), (j, 11), (k, 10))]
    assert var == pytest.approx([0.7 ** 2, 1.0 ** 2, 1.5 ** 2], rel=0.05)


def _crossing(col, iso):
    """Positions where the linear interpolant of ``col`` crosses ``iso``."""
    col = np.asarray(col, float)
    out = []
    for m in range(len(col) - 1):
        if (col[m] - iso) * (col[m + 1] - iso) < 0:
            out.append(m + (iso - col[m]) / (col[m + 1] - col[m]))
    return out


def test_floor_geometry_and_defaults():
    assert floor(128, relief=0.0).dims == (128, 128, 16)             # n x n x max(8, n // 8)
    assert floor(71, relief=0.0).dims == (71, 71, 8)
    assert floor(12, height=11).dims == (12, 12, 11)
    assert floor(32).meta["relief"] == pytest.approx(0.08 * 7)      # min(1, 8% of the z extent)
    vol = floor((24, 20, 21))
    ext = np.array([23.0, 19.0, 20.0])
    bottom, top = 0.25 * ext[2], 0.25 * ext[2] + 0.35 * ext[2]       # the documented defaults
    assert vol.meta["bottom"] == pytest.approx(bottom) and vol.meta["top"] == pytest.approx(top)
    assert vol.meta["relief"] == pytest.approx(min(1.0, 0.08 * ext[2]))
    assert vol.meta["tile"] == pytest.approx(23 / 8)
    flat = floor((24, 20, 21), relief=0.0)
    d, iso = flat.data, flat.meta["iso"]
    # The 127.5 level lies on the geometric faces: z = bottom, z = top, and the sides inset by
    # min(1.5, 10% of the smaller horizontal extent).
    assert _crossing(d[:, 10, 12], iso) == pytest.approx([bottom, top], abs=0.05)
    margin = min(1.5, 0.1 * 19)
    zc = int(round((bottom + top) / 2))
    assert _crossing(d[zc, :, 12], iso) == pytest.approx([margin, ext[1] - margin], abs=0.05)
    assert _crossing(d[zc, 10, :], iso) == pytest.approx([margin, ext[0] - margin], abs=0.05)
    for bad in ({"thickness": 0}, {"relief": -1}, {"tile": 0}):
        with pytest.raises(InputError):
            floor(16, **bad)


def test_making_note_threshold():
    assert making_note("sphere", None) is None
    assert making_note("sphere", 299) is None
    assert making_note("sphere", 300) == "making sphere 300x300x300 (27,000,000 samples) ..."
    assert making_note("floor", 2400) == "making floor 2400x2400x300 (1,728,000,000 samples) ..."
    assert making_note("sphere", (300, 300, 299)) is None


def test_memory_refusal_amounts(monkeypatch):
    from data_tools import memory
    monkeypatch.setattr(memory, "available_memory", lambda: 100 * 2**20)
    memory.check_memory(100 * 2**20, "x")                          # exactly what is available: fine
    with pytest.raises(InputError, match=r"^x needs about 500 MB of memory; 100 MB is available, try less$"):
        memory.check_memory(500 * 2**20, "x", ", try less")
    with pytest.raises(InputError, match=r"^x needs about 1\.0 GB of memory; 100 MB is available$"):
        memory.check_memory(2**30, "x")
    with pytest.raises(InputError, match=r"^x needs about 1048575\.0 GB of memory"):
        memory.check_memory(2**50 - 2**30, "x")                    # below 2**50 bytes: still fixed-point
    with pytest.raises(InputError, match=r"^x needs about 1\.0e\+06 GB of memory"):
        memory.check_memory(2**50, "x")
    monkeypatch.setattr(memory, "available_memory", lambda: None)  # unknown: not checked
    memory.check_memory(10**30, "x")

def test_trilinear_field_exact_flag_beyond_float64_integers():
    # 27 * 2**53 + 1 has no float64: the samples are not F, and the field must say so.
    vol = trilinear_field(4, coeffs=(1, 0, 0, 0, 0, 0, 0, 2 ** 53))
    assert int(vol.data[3, 3, 3]) != 27 * 2 ** 53 + 1 and not vol.meta["exact"]
    assert trilinear_field(4, coeffs=(1, 0, 0, 0, 0, 0, 0, 2 ** 40)).meta["exact"]


@pytest.mark.parametrize("size", [12.7, 12.0, "12", (8, 8.5, 8), None])
def test_a_size_that_is_not_whole_numbers_is_refused(size):
    # Cut to 12 (or read from text), a size would silently give another grid than the one asked for.
    with pytest.raises(InputError, match="must be an integer or three integers"):
        sphere(size)
    assert sphere(np.int64(12)).data.shape == (12, 12, 12) and sphere((np.uint8(9), 8, 7)).data.shape == (7, 8, 9)


def test_floor_refuses_a_size_that_is_not_whole_as_the_others_do():
    from data_tools.neuron import floor
    with pytest.raises(InputError, match="integer"):
        floor(12.7)
    assert floor(np.int64(16)).dims == (16, 16, 8)


def test_ct_phantom_levels_along_a_row_by_the_formula():
    # Noise-free, along x through the head at v = 1/127, w = 0.2 (the box as [-1, 1]^3): air 0,
    # the skin where the head's ellipsoid (centre (0, 0, 0.15), semi-axes 0.68, 0.8, 0.72) is
    # crossed, bone ~2200 (tissue 1000 and a shell of 1200), brain 1050, a ventricle 40 less.
    # Spacing 1, 1, 8 makes the 16 slices as long as the 128 samples across: edges as sharp as
    # at 128^3, about a voxel.
    row = ct_phantom((128, 128, 16), spacing=(1, 1, 8), noise=0.0).data[9, 64, :].astype(float)
    v, w = -1 + 2 * 64 / 127, -1 + 2 * 9 / 15
    u = 0.68 * math.sqrt(1 - (v / 0.8) ** 2 - ((w - 0.15) / 0.72) ** 2)
    skin = [(1 - u) * 127 / 2, (1 + u) * 127 / 2]
    assert _crossing(row, 500.0) [:1] + _crossing(row, 500.0)[-1:] == pytest.approx(skin, abs=0.15)
    assert row[:15].max() == 0 and row[-15:].max() == 0
    assert 2150 <= row.max() <= 2200
    assert row[40] == row[87] == 1050
    assert row[72] == row[55] == 1010                   # ventricles centred at u = -0.14 and 0.14
    ramp = (row > 100) & (row < 900)
    assert ramp[:64].sum() <= 3 and ramp[64:].sum() <= 3


def test_ct_phantom_to_disk_header_and_samples_byte_by_byte(tmp_path):
    path = ct_phantom_to_disk(tmp_path / "ct.nrrd", (6, 5, 4), seed=2, dtype="uint16", spacing=(0.5, 2, 3))
    header = ("NRRD0004\ntype: uint16\ndimension: 3\nspace dimension: 3\nsizes: 6 5 4\n"
              "space directions: (0.5,0,0) (0,2.0,0) (0,0,3.0)\nkinds: domain domain domain\n"
              "endian: little\nencoding: raw\nspace origin: (0,0,0)\n\n").encode("ascii")
    ref = ct_phantom((6, 5, 4), seed=2, dtype="uint16", spacing=(0.5, 2, 3)).data
    body = b"".join(int(s).to_bytes(2, "little") for s in ref.reshape(-1))     # x fastest
    assert path.read_bytes() == header + body


@pytest.mark.parametrize("spacing", [(0, 1, 1), (1, 1, 0), (1, 1, -2), (1, 1), "abc", (1, "x", 1)])
def test_ct_phantom_refuses_a_bad_spacing_and_writes_nothing(tmp_path, spacing):
    with pytest.raises(InputError, match="spacing must be"):
        ct_phantom(8, spacing=spacing)
    path = tmp_path / "ct.nrrd"
    with pytest.raises(InputError, match="spacing must be"):
        ct_phantom_to_disk(path, (8, 8, 8), spacing=spacing)
    assert not path.exists()


def test_ct_phantom_noise_is_added_before_rounding_to_the_nearest_level():
    # On the brain's plateau (1050) a sample is 1050 plus its slice's documented draw, rounded
    # to the nearest level, not cut toward zero.
    vol = ct_phantom((128, 128, 16), spacing=(1, 1, 8), seed=3)
    draw = np.random.default_rng((3, 9)).normal(0.0, 20.0, size=(128, 128)).astype(np.float32)
    np.testing.assert_array_equal(vol.data[9, 64, 32:47], np.rint(np.float32(1050) + draw[64, 32:47]))


def test_floor_tiles_alternate_along_x_and_y():
    # Tiles 9 voxels wide, from x = y = -0.5: samples 4, 13 and 22 lie in their middles. The top
    # is raised relief / 2 where a tile's column and row numbers are both even or both odd, and
    # lowered as much where they differ (a checkerboard).
    vol = floor((27, 27, 16), tile=9.0, relief=1.0)
    top = vol.meta["top"]
    for a, x in enumerate((4, 13, 22)):
        for b, y in enumerate((4, 13, 22)):
            expected = top + (0.5 if (a + b) % 2 == 0 else -0.5)
            assert _crossing(vol.data[:, y, x], 127.5)[-1] == pytest.approx(expected, abs=0.05), (x, y)


def test_floor_samples_are_the_soft_step_of_the_distance_and_small_floors_are_inset_a_tenth():
    # Away from the sides a column is 255 (0.5 - 0.5 tanh(d / 0.5)) of the distance d to the
    # slab's faces, rounded: a step about half a voxel wide.
    flat = floor((20, 16, 12), relief=0.0)
    z = np.arange(12.0)
    d = np.maximum(flat.meta["bottom"] - z, z - flat.meta["top"])
    np.testing.assert_array_equal(flat.data[:, 8, 10], np.rint(255 * (0.5 - 0.5 * np.tanh(d / 0.5))))
    # 12 x 10 samples across: the sides are a tenth of the smaller extent (0.9) inside the box.
    small = floor((12, 10, 8), relief=0.0)
    assert _crossing(small.data[3, 5, :], 127.5) == pytest.approx([0.9, 10.1], abs=0.1)
    assert _crossing(small.data[3, :, 6], 127.5) == pytest.approx([0.9, 8.1], abs=0.1)


def test_ct_phantom_meta_carries_both_registry_levels():
    # parc make suggests the registry's skin and bone levels; the volume says the same.
    meta = ct_phantom(8).meta
    assert (meta["iso"], meta["bone_iso"]) == ISOVALUES["ct_phantom"] == (600.5, 1500.5)


@pytest.mark.parametrize("name", ["ct.npy", "ct.mhd", "ct"])
def test_ct_phantom_to_disk_refuses_other_formats_and_writes_nothing(tmp_path, name):
    with pytest.raises(InputError, match="makes .nrrd or .raw files"):
        ct_phantom_to_disk(tmp_path / name, (4, 4, 4))
    assert not any(tmp_path.iterdir())


def test_neuron_haze_brightens_the_dark_around_the_soma():
    # Out-of-focus light around the soma: without noise, no sample within 10 voxels of its
    # centre is as dark as the background in the box's corners (12 photons).
    vol = neuron(48, seed=1, noise=False)
    d = vol.data
    k, j, i = np.indices(d.shape)
    sx, sy, sz = vol.meta["soma"]
    near = (i - sx) ** 2 + (j - sy) ** 2 + (k - sz) ** 2 <= 10 ** 2
    assert d[0, 0, 0] == d[-1, -1, -1] == 12
    assert d[near].min() > 12


def test_a_neurite_segment_is_a_soft_tapered_capsule():
    # Radius 2 at (5, 4, 4) tapering to 1 at (15, 4, 4): along the axis the distance to the
    # segment is 0 between its ends and the distance to the nearer end beyond them, less the
    # radius there; across its middle, the distance to the axis less 1.5.
    from data_tools.neuron import _add_tube
    out = np.zeros((9, 9, 21), np.float32)
    _add_tube(out, (21, 9, 9), np.array([5.0, 4.0, 4.0]), np.array([15.0, 4.0, 4.0]), 2.0, 1.0, 0.6)
    x = np.arange(21.0)
    t = np.clip((x - 5) / 10, 0, 1)
    along = np.maximum(5 - x, 0) + np.maximum(x - 15, 0) - (2 - t)
    soft = lambda d: 0.5 - 0.5 * np.tanh(d / 0.6)  # noqa: E731
    np.testing.assert_allclose(out[4, 4, :], soft(along), atol=1e-4)
    np.testing.assert_allclose(out[:, 4, 10], soft(np.abs(np.arange(9.0) - 4) - 1.5), atol=1e-4)
