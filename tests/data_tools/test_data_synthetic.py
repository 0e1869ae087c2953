"""Synthetic volumes: shapes, types, analytic values, exact trilinear fields, phantom streaming."""
from __future__ import annotations

import numpy as np
import pytest

from data_tools import InputError, Volume, phantom
from data_tools.io import load_volume
from data_tools.synthetic import (DESCRIPTIONS, SYNTHETIC, builtin_volume, ct_phantom, ct_phantom_to_disk,
                                  floor, make_synthetic, marschner_lobb, neuron, sphere, torus,
                                  trilinear_field)

EXPECTED_DTYPE = {"sphere": "float32", "torus": "float32", "marschner_lobb": "float32", "blobs": "uint8",
                  "neuron": "uint8", "floor": "uint8", "ct_phantom": "int16", "trilinear_field": "float64",
                  "builtin": "uint8"}
#: An int size is a cube, except for the floor, which is thin: n x n x max(8, n // 8).
EXPECTED_SHAPE_12 = {"floor": (8, 12, 12)}


@pytest.mark.parametrize("name", sorted(SYNTHETIC))
def test_registry_entries(name):
    assert DESCRIPTIONS[name] and "\n" not in DESCRIPTIONS[name]
    vol = SYNTHETIC[name](size=12)
    assert isinstance(vol, Volume)
    assert vol.shape == EXPECTED_SHAPE_12.get(name, (12, 12, 12))
    assert vol.dtype == np.dtype(EXPECTED_DTYPE[name])
    lo, hi = vol.value_range()
    assert lo < vol.meta["iso"] < hi


@pytest.mark.parametrize("name", ["sphere", "torus", "marschner_lobb", "blobs", "neuron", "floor", "ct_phantom",
                                  "builtin"])
def test_non_cubic_size_is_x_y_z(name):
    vol = SYNTHETIC[name](size=(10, 7, 5))
    assert vol.dims == (10, 7, 5) and vol.shape == (5, 7, 10)


def test_default_sizes_are_sensible():
    assert sphere().dims == (64, 64, 64)
    assert builtin_volume().dims == (64, 64, 64)


def test_make_synthetic_unknown_name_lists_names():
    with pytest.raises(InputError, match="sphere"):
        make_synthetic("cube")
    assert make_synthetic("torus", 9).dims == (9, 9, 9)


@pytest.mark.parametrize("size", [1, (4, 4), "big", (4, 0, 4)])
def test_bad_sizes(size):
    with pytest.raises(InputError, match="^size must (give at least 2 samples per axis|be an integer or three integers)"):
        sphere(size)


def test_sphere_is_the_analytic_signed_distance():
    vol = sphere(33)
    c, r = np.array(vol.meta["center"]), vol.meta["radius"]
    assert tuple(c) == (16.0, 16.0, 16.0) and r == pytest.approx(0.35 * 32)
    k, j, i = np.indices(vol.shape)
    exact = np.sqrt((i - c[0]) ** 2 + (j - c[1]) ** 2 + (k - c[2]) ** 2) - r
    np.testing.assert_allclose(vol.data, exact, atol=1e-5)
    assert vol.data[16, 16, 16] == pytest.approx(-r)
    # Along +x from the centre the zero crossing lies at the radius.
    row = vol.data[16, 16, 16:]
    n = np.argmax(row > 0)
    t = n - 1 + row[n - 1] / (row[n - 1] - row[n])
    assert t == pytest.approx(r, abs=1e-4)


def test_torus_is_the_analytic_signed_distance():
    vol = torus(41)
    (cx, cy, cz), big_r, small_r = vol.meta["center"], vol.meta["major_radius"], vol.meta["minor_radius"]
    k, j, i = np.indices(vol.shape)
    exact = np.hypot(np.hypot(i - cx, j - cy) - big_r, k - cz) - small_r
    np.testing.assert_allclose(vol.data, exact, atol=1e-5)
    assert vol.data[20, 20, 20] > 0       # the hole is outside
    assert vol.data.min() == pytest.approx(-small_r, abs=0.5)


def test_marschner_lobb_formula():
    vol = marschner_lobb(41)
    assert vol.origin == (-1, -1, -1) and vol.spacing == pytest.approx((0.05, 0.05, 0.05))
    x, y, z = 0.25, -0.5, 0.75
    i, j, k = (round((v + 1) / 0.05) for v in (x, y, z))
    r = np.hypot(x, y)
    expect = (1 - np.sin(np.pi * z / 2) + 0.25 * (1 + np.cos(2 * np.pi * 6 * np.cos(np.pi * r / 2)))) / 2.5
    assert vol.data[k, j, i] == pytest.approx(expect, abs=1e-6)
    assert 0 <= vol.data.min() and vol.data.max() <= 1


def test_blobs_seeded():
    a, b, c = SYNTHETIC["blobs"](size=20, seed=1), SYNTHETIC["blobs"](size=20, seed=1), SYNTHETIC["blobs"](size=20, seed=2)
    np.testing.assert_array_equal(a.data, b.data)
    assert not np.array_equal(a.data, c.data)
    assert (a.data > 100.5).any() and (a.data < 100.5).any()



def test_neuron_seeded_sparse_with_a_clean_surface():
    a, b, c = neuron(48, seed=1), neuron(48, seed=1), neuron(48, seed=2)
    np.testing.assert_array_equal(a.data, b.data)
    assert not np.array_equal(a.data, c.data)
    iso = a.meta["iso"]
    assert a.dtype == np.uint8 and a.dims == (48, 48, 48) and iso % 1 == 0.5
    for vol in (a, c):
        d = vol.data
        assert 0.001 < (d > iso).mean() < 0.05          # a thin cell in a mostly dark stack
        x, y, z = (int(round(v)) for v in vol.meta["soma"])
        assert d[z, y, x] > iso + 60                       # the soma is bright
        # The background with its noise stays well below the surface level.
        assert d[:6, :6, :6].max() < iso - 30 and d[-6:, -6:, -6:].max() < iso - 30
        assert np.median(d) < 30


def test_neuron_big_enough():
    vol = neuron(128)
    d = vol.data
    # Dendrites reach far from the soma: the bright voxels span most of the box in z.
    z = np.nonzero((d > vol.meta["iso"]).any(axis=(1, 2)))[0]
    assert z.max() - z.min() > 0.6 * 127


def test_floor_is_a_thin_closed_slab_with_relief():
    vol = floor(32)
    d, iso = vol.data, vol.meta["iso"]
    assert vol.dims == (32, 32, 8) and d.dtype == np.uint8
    assert (d[0] < iso).all() and (d[-1] < iso).all()    # closed below and above
    assert (d[:, 0] < iso).all() and (d[:, :, -1] < iso).all()   # and at the sides
    top, relief, tile = vol.meta["top"], vol.meta["relief"], vol.meta["tile"]

    def surface_z(col):                                   # upper iso crossing, linear in z
        k = np.nonzero(col > iso)[0].max()
        return k + (float(col[k]) - iso) / (float(col[k]) - float(col[k + 1]))

    heights = np.array([[surface_z(d[:, j, i]) for i in range(4, 28)] for j in range(4, 28)])
    # Tiles alternate between top + relief/2 and top - relief/2 (within sampling).
    assert heights.max() == pytest.approx(top + relief / 2, abs=0.1)
    assert heights.min() == pytest.approx(top - relief / 2, abs=0.1)
    assert tile == pytest.approx(31 / 8)
    flat = floor((20, 16, 10), relief=0.0).data
    inner = flat[:, 3:-3, 3:-3]
    assert (inner == inner[:, :1, :1]).all()              # relief 0: every inner column the same
    with pytest.raises(InputError):
        floor(16, tile=0)

def test_ct_phantom_levels():
    vol = ct_phantom(48, spacing=(1, 1, 2))
    d = vol.data
    assert d.dtype == np.int16 and vol.spacing == (1, 1, 2)
    assert d[0, 0, 0] < 100                       # air
    assert (d > 1500).sum() > 100                 # bone
    tissue = (d > 800) & (d < 1300)
    assert tissue.sum() > 1000
    assert 0.05 < (d > 600).mean() < 0.8          # the skin surface encloses a real body
    # Along a ray through the head centre from the side: air, skin, bone, brain.
    row = d[d.shape[0] * 11 // 20, 24, :]
    assert row[0] < 600 and (row > 1500).any() and 900 < row[24] < 1300
    assert ct_phantom(16, dtype="uint16").dtype == np.uint16
    with pytest.raises(InputError):
        ct_phantom(8, dtype="float32")


@pytest.mark.parametrize("ext", [".nrrd", ".raw"])
def test_ct_phantom_streams_the_same_samples(tmp_path, monkeypatch, ext):
    monkeypatch.setattr(phantom, "_SLAB_VOXELS", 3 * 20 * 18)   # several slabs, a short last one
    shape = (20, 18, 16)
    path = tmp_path / f"ct_20x18x16_int16{ext}"
    ct_phantom_to_disk(path, shape, seed=4, spacing=(1, 1, 2))
    vol = load_volume(path)
    monkeypatch.setattr(phantom, "_SLAB_VOXELS", 1 << 22)
    ref = ct_phantom(shape, seed=4, spacing=(1, 1, 2))
    np.testing.assert_array_equal(vol.data, ref.data)
    if ext == ".nrrd":
        assert vol.spacing == (1, 1, 2)


def test_trilinear_field_random_is_exact():
    vol = trilinear_field((7, 5, 4), seed=3)
    c = vol.meta["coeffs"]
    assert len(c) == 8 and all(isinstance(v, int) for v in c) and c[7] != 0
    assert vol.meta["exact"]
    for k in range(4):
        for j in range(5):
            for i in range(7):
                f = c[0] + c[1] * i + c[2] * j + c[3] * k + c[4] * i * j + c[5] * j * k + c[6] * k * i + c[7] * i * j * k
                assert vol.data[k, j, i] == f


def test_trilinear_field_axes_and_given_coefficients():
    vol = trilinear_field((4, 3, 2), coeffs=(0, 1, 10, 100, 0, 0, 0, 0), dtype="int16",
                          spacing=(1, 2, 3), origin=(1, 1, 1))
    assert vol.dtype == np.int16 and vol.spacing == (1, 2, 3)
    assert vol.data[1, 2, 3] == 3 + 20 + 100


def test_trilinear_field_float_coefficients_and_float32():
    coeffs = (0.5, -0.25, 1.5, 2.0, 0.125, -1.0, 0.75, 0.0625)
    vol = trilinear_field(6, coeffs=coeffs, dtype="float32")
    assert vol.dtype == np.float32 and vol.meta["exact"]
    i, j, k = 5, 3, 4
    f = (coeffs[0] + coeffs[1] * i + coeffs[2] * j + coeffs[3] * k + coeffs[4] * i * j + coeffs[5] * j * k
         + coeffs[6] * k * i + coeffs[7] * i * j * k)
    assert float(vol.data[k, j, i]) == f


def test_trilinear_field_refuses_overflowing_integers():
    with pytest.raises(InputError):
        trilinear_field(40, coeffs=(0, 0, 0, 0, 0, 0, 0, 2), dtype="int16")
    # float32 cannot hold every odd integer above 2**24: the field says it is not exact.
    assert not trilinear_field(30, coeffs=(1, 0, 0, 0, 0, 0, 0, 1000), dtype="float32").meta["exact"]


def test_builtin_volume_has_a_surface():
    vol = builtin_volume(32)
    iso = vol.meta["iso"]
    assert vol.dtype == np.uint8 and iso % 1 == 0.5
    assert 0.02 < (vol.data > iso).mean() < 0.5


@pytest.mark.parametrize("name, fits", [("floor", True), ("ct_phantom", True), ("sphere", False)])
def test_make_refuses_by_what_the_volume_needs_while_made(name, fits, monkeypatch):
    # A floor is n x n x n/8 samples, and the CT phantom is made slab by slab: neither needs
    # the 48 bytes a sample of a whole n^3 float64 grid that the other volumes do.
    from data_tools import memory
    from data_tools.synthetic import check_synthetic_size
    monkeypatch.setattr(memory, "available_memory", lambda: 4 * 2**30)
    if fits:
        check_synthetic_size(800, "--size 800", name)
    else:
        with pytest.raises(InputError, match="--size 800 needs about 22.9 GB of memory; 4.0 GB is available"):
            check_synthetic_size(800, "--size 800", name)


# By hand: 48 bytes a sample, 4 GiB: 447^3 (sphere), 895^2 x 111 (a floor 895 wide is 895 // 8 high); the
# phantom, made in slabs, 6 bytes a sample: 894^3.
@pytest.mark.parametrize("name, most", [("sphere", 447), ("floor", 895), ("ct_phantom", 894)])
def test_a_size_too_large_to_make_is_told_the_largest_that_fits(name, most, monkeypatch):
    from data_tools import memory
    from data_tools.synthetic import check_synthetic_size
    monkeypatch.setattr(memory, "available_memory", lambda: 4 * 2**30)
    with pytest.raises(InputError, match=f"4.0 GB is available: give a size of at most {most} here$"):
        check_synthetic_size(10**5, "--size 100000", name)
    check_synthetic_size(most, f"--size {most}", name)            # it fits
    with pytest.raises(InputError):
        check_synthetic_size(most + 1, f"--size {most + 1}", name)


def test_a_need_past_all_memory_reads_as_a_power_of_ten(monkeypatch):
    # 99999999^3 samples (a header's claim) needed a 32-digit number of GB.
    from data_tools import memory
    monkeypatch.setattr(memory, "available_memory", lambda: 4 * 2**30)
    with pytest.raises(InputError, match=r"x needs about 9\.3e\+14 GB of memory; 4\.0 GB is available$"):
        memory.check_memory(10**24, "x")
