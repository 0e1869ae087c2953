"""Cell ranges, supercell grids and ranges, isovalue classification.

Truth: slow loops over cells, and an exact per-piece reference for
supercell ranges (`parc_reference.box_range`: the interpolant's extremes
over the part of a cell a box overlaps are at the part's corners).
Tolerances: whole-cell ranges are compared exactly (native dtype);
ranges that interpolate are float64 widened by `RANGE_PAD` of the data's
magnitude, and must contain the reference and exceed it by no more than
that pad plus rounding.
"""
import math

import numpy as np
import pytest

from data_tools import InputError, Volume
from data_tools.volume import SUPPORTED_DTYPES
from parc.classify import VolumeIndex, classify_iso
from parc.ranges import RANGE_PAD, cell_minmax, supercell_grid, supercell_ranges
from parc_reference import box_range, cell_minmax_loop

DTYPES = ["uint8", "int16", "uint16", "float32", "float64"]


def _random(shape, dtype, seed):
    rng = np.random.default_rng(seed)
    if np.dtype(dtype).kind == "f":
        return (rng.standard_normal(shape) * 100).astype(dtype)
    info = np.iinfo(dtype)
    return rng.integers(max(info.min, -30000), min(info.max, 30000), shape, endpoint=True).astype(dtype)


@pytest.mark.parametrize("dtype", [t.name for t in SUPPORTED_DTYPES])
@pytest.mark.parametrize("shape", [(2, 2, 2), (3, 5, 4), (7, 6, 9), (2, 9, 2), (5, 2, 3)])
def test_cell_minmax_matches_loop(dtype, shape):
    data = _random(shape, dtype, seed=sum(shape))
    # The type's own extremes too, where a wrong conversion would wrap or round.
    info = np.finfo(dtype) if np.dtype(dtype).kind == "f" else np.iinfo(dtype)
    data.flat[::7] = info.min
    data.flat[3::11] = info.max
    mn, mx = cell_minmax(data)
    rmn, rmx = cell_minmax_loop(data)
    assert mn.dtype == data.dtype and mn.shape == rmn.shape
    np.testing.assert_array_equal(mn, rmn)
    np.testing.assert_array_equal(mx, rmx)


@pytest.mark.parametrize("dtype", DTYPES)
def test_classify_matches_per_cell_loop(dtype):
    data = _random((6, 7, 8), dtype, seed=11)
    mn, mx = cell_minmax(data)
    # Isovalues at sample values (boundaries of ranges), between them, outside.
    isos = [float(data.flat[5]), float(data.flat[77]), float(np.median(data)) + 0.5,
            float(data.min()), float(data.max()), float(data.max()) + 1.0]
    for iso in isos:
        pc = classify_iso(mn, mx, iso)
        nz, ny, nx = data.shape
        for k in range(nz - 1):
            for j in range(ny - 1):
                for i in range(nx - 1):
                    c = data[k:k + 2, j:j + 2, i:i + 2].astype(np.float64) - iso
                    assert pc[k, j, i] == (c.min() <= 0.0 <= c.max()), (iso, k, j, i)


def test_classify_compares_in_float64():
    """A float32 range that ends between float32(iso) and iso must follow the float64 comparison."""
    mn = np.array([0.1], np.float32)        # float32(0.1) = 0.10000000149... > 0.1
    mx = np.array([0.2], np.float32)
    assert not classify_iso(mn, mx, 0.1)[0]
    assert classify_iso(mn, mx, float(np.float32(0.1)))[0]


def test_grid_edges_and_counts():
    g = supercell_grid((10, 7, 5), (3, 2.5, 0.5))
    assert g.counts == (3, 3, 8)
    np.testing.assert_array_equal(g.edges[0], [0, 3, 6, 9])
    np.testing.assert_array_equal(g.edges[1], [0, 2.5, 5, 6])
    np.testing.assert_array_equal(g.edges[2], np.arange(9) * 0.5)
    assert g.shape == (8, 3, 3)
    assert not g.integral and supercell_grid((10, 7, 5), 2).integral
    # A size larger than the volume: one supercell.
    assert supercell_grid((4, 4, 4), 10).counts == (1, 1, 1)
    # A last supercell thinner than SNAP joins its neighbour (no zero-width box).
    g = supercell_grid((2, 2, 2), 1.0 / (3 + 2e-9))
    assert g.counts == (3, 3, 3) and np.all(np.diff(g.edges[0]) > 0.3)
    # 10 * 0.1 is 1.0000000000000002: snapped, no sliver supercell.
    g = supercell_grid((2, 2, 2), 0.1)
    assert g.counts == (10, 10, 10)
    assert g.edges[0][-1] == 1.0 and np.all(np.diff(g.edges[0]) > 0.09)


def test_near_integer_size_is_that_integer():
    """3 - 1e-10 cells per supercell: the same boundaries and ranges as 3 (no sliver)."""
    data = _random((5, 8, 7), "int16", seed=8)
    a = supercell_grid((7, 8, 5), 3 - 1e-10)
    b = supercell_grid((7, 8, 5), 3)
    for ea, eb in zip(a.edges, b.edges):
        np.testing.assert_array_equal(ea, eb)
    cells = cell_minmax(data)
    for x, y in zip(supercell_ranges(data, a, cell_ranges=cells), supercell_ranges(data, b)):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("size", [0, -1, math.inf, math.nan, "x", (1, 2)])
def test_grid_rejects_bad_sizes(size):
    with pytest.raises(InputError, match="^supercell size must be "):
        supercell_grid((5, 5, 5), size)


def test_grid_rejects_too_many_supercells():
    with pytest.raises(InputError, match="supercells"):
        supercell_grid((512, 512, 512), 0.01)


@pytest.mark.parametrize("size", [1, 2, 3, 4.0, (2, 3, 1), (5, 1, 2)])
@pytest.mark.parametrize("dtype", ["uint8", "int16", "float32"])
def test_whole_cell_ranges_exact(size, dtype):
    data = _random((7, 8, 9), dtype, seed=5)
    grid = supercell_grid((9, 8, 7), size)
    mn, mx = supercell_ranges(data, grid)
    mn2, mx2 = supercell_ranges(data, grid, cell_ranges=cell_minmax(data))
    assert mn.dtype == data.dtype and mn2.dtype == data.dtype
    ex, ey, ez = grid.edges
    for c in range(grid.shape[0]):
        for b in range(grid.shape[1]):
            for a in range(grid.shape[2]):
                block = data[int(ez[c]):int(ez[c + 1]) + 1, int(ey[b]):int(ey[b + 1]) + 1,
                             int(ex[a]):int(ex[a + 1]) + 1]
                assert mn[c, b, a] == block.min() == mn2[c, b, a]
                assert mx[c, b, a] == block.max() == mx2[c, b, a]


@pytest.mark.parametrize("sizes", [(2, 4, 8), (3, 6, 12), (2, 3, 6, 12), ((2, 3, 1), (4, 6, 3), (6, 3, 2)),
                                   (2.5, 5, 10, 20), (4, 2, 40), (3, 7), ((1, 1, 5), (1, 1, 8))])
def test_ranges_reduced_from_coarser_ones_are_those_of_the_samples(sizes):
    # The index reduces a whole-cell size from ranges it already keeps whose blocks tile it:
    # after 2, a size 4 from the 2s, whose last block along an axis of 8 cells (9 samples)
    # holds a lone cell; fractional sizes (2.5) are never the source. Blocks of 5 along z's
    # 10 cells do not tile 8s there, though 8 is the last boundary along x.
    data = _random((11, 10, 9), "int16", seed=9)
    index = VolumeIndex(Volume(data))
    for size in sizes:
        grid = supercell_grid((9, 10, 11), size)
        got = index.ranges(size)
        want = supercell_ranges(data, grid)
        for g, w in zip(got, want):
            assert g.dtype == w.dtype and np.array_equal(g, w), size


@pytest.mark.parametrize("dtype", DTYPES)
def test_ranges_of_long_rows_reduced_from_cells_and_blocks(dtype):
    # Rows of 100-odd cells, so the vectorized loops over blocks of 2 and 3 run whole vectors and
    # a remainder, and an odd last block; every size from the cells, then from the index's blocks.
    for seed, nx in ((1, 131), (2, 100), (3, 98)):
        data = _random((4, 5, nx), dtype, seed=seed)
        cells = cell_minmax(data)
        index = VolumeIndex(Volume(data))
        for size in (2, 3, 4, 6, 12, 5, (3, 2, 1), (2, 1, 3)):
            grid = supercell_grid((nx, 5, 4), size)
            want = supercell_ranges(data, grid)            # from the samples, in NumPy
            for got in (supercell_ranges(data, grid, cell_ranges=cells), index.ranges(size)):
                for g, w in zip(got, want):
                    assert g.dtype == w.dtype and np.array_equal(g, w), (nx, size)


@pytest.mark.parametrize("size", [0.5, 1.5, 4.5, 0.3, 2.25, (2, 3, 1.5), (0.5, 1, 2.5), (1.5, 1.5, 1)])
@pytest.mark.parametrize("dtype", ["uint8", "float64", "negative"])
def test_fractional_ranges_against_exact_reference(size, dtype):
    data = _random((6, 7, 8), "float64" if dtype == "negative" else dtype, seed=17)
    if dtype == "negative":
        data -= data.max() + 1.0        # the largest magnitude is the minimum's (HU-like data)
    grid = supercell_grid((8, 7, 6), size)
    mn, mx = supercell_ranges(data, grid)
    assert mn.dtype == np.float64
    pad = RANGE_PAD * float(np.abs(data.astype(np.float64)).max())
    slack = pad + 1e-13 * float(np.abs(data.astype(np.float64)).max())
    ex, ey, ez = grid.edges
    for c in range(grid.shape[0]):
        for b in range(grid.shape[1]):
            for a in range(grid.shape[2]):
                rmn, rmx = box_range(data, (ex[a], ey[b], ez[c]), (ex[a + 1], ey[b + 1], ez[c + 1]))
                # Widened by the pad, of the data's largest magnitude, whichever sign it has.
                assert mn[c, b, a] <= rmn - pad / 2 and rmn <= mn[c, b, a] + 2 * slack, (size, c, b, a)
                assert mx[c, b, a] - 2 * slack <= rmx and rmx + pad / 2 <= mx[c, b, a], (size, c, b, a)


def test_fractional_ranges_in_slabs(monkeypatch):
    import parc.ranges as cl
    data = _random((9, 6, 7), "int16", seed=2)
    grid = supercell_grid((7, 6, 9), (1.5, 0.5, 2.5))
    whole = supercell_ranges(data, grid)
    monkeypatch.setattr(cl, "CHUNK_VALUES", 1)
    sliced = supercell_ranges(data, grid)
    for a, b in zip(whole, sliced):
        np.testing.assert_array_equal(a, b)


def test_a_thin_supercell_refined_beyond_a_chunk_splits_along_y_and_x(monkeypatch):
    # One z-slab of supercells 0.0001 cells wide in x and 64 in y and z had refined into
    # billions of points at once: 23 GB, and the process killed. Chunks now split along y
    # and x too; here a slab of 9 x 9 x 801 points, in chunks of at most 4096.
    import tracemalloc

    import parc.ranges as cl
    data = _random((9, 9, 9), "float32", seed=6)
    grid = supercell_grid((9, 9, 9), (0.01, 8, 8))
    whole = supercell_ranges(data, grid)
    monkeypatch.setattr(cl, "CHUNK_VALUES", 1 << 12)
    tracemalloc.start()
    try:
        sliced = supercell_ranges(data, grid)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    for a, b in zip(whole, sliced):
        np.testing.assert_array_equal(a, b)
    assert peak < 12 * 8 * (1 << 12) + 4 * whole[0].nbytes + (64 << 10), peak
    for size in ((8, 0.01, 8), (1.5, 0.25, 2.5)):
        grid = supercell_grid((9, 9, 9), size)
        monkeypatch.setattr(cl, "CHUNK_VALUES", 1 << 22)
        whole = supercell_ranges(data, grid)
        monkeypatch.setattr(cl, "CHUNK_VALUES", 1 << 6)
        for a, b in zip(whole, supercell_ranges(data, grid)):
            np.testing.assert_array_equal(a, b)


def test_subcell_ranges_tighter_than_cells():
    """Sub-cells of a linear ramp: each half-cell sees half the cell's range."""
    x = np.arange(5, dtype=np.float64)
    data = np.broadcast_to(x * 10.0, (3, 3, 5)).copy()
    grid = supercell_grid((5, 3, 3), 0.5)
    mn, mx = supercell_ranges(data, grid)
    pad = RANGE_PAD * 40.0                        # the widening, of the data's largest magnitude
    np.testing.assert_allclose(mn[0, 0, :], np.arange(8) * 5.0, rtol=0, atol=2 * pad)
    np.testing.assert_allclose(mx[0, 0, :], np.arange(1, 9) * 5.0, rtol=0, atol=2 * pad)
    assert (mn[0, 0, :] <= np.arange(8) * 5.0).all() and (mx[0, 0, :] >= np.arange(1, 9) * 5.0).all()


def test_volume_index_caches():
    vol = Volume(_random((6, 7, 8), "int16", seed=9))
    idx = VolumeIndex.of(vol)
    assert VolumeIndex.of(vol) is idx
    assert idx.cell_minmax() is idx.cell_minmax()
    assert idx.ranges(2) is idx.ranges((2, 2, 2))
    assert idx.ranges(1) is idx.cell_minmax()
    pc = idx.classify(float(np.median(vol.data)), 2)
    assert pc.shape == idx.grid(2).shape and pc.dtype == bool


@pytest.mark.parametrize("size", [0.5, 1.5, 2.25, (2, 3, 1.5)])
def test_fractional_ranges_are_widened_by_a_billionth_at_most(size):
    # The module's notes: 2^-32 (~2.3e-10) of the largest magnitude for grids under RANGE_PAD_CELLS.
    data = _random((6, 7, 8), "float64", seed=23)
    grid = supercell_grid((8, 7, 6), size)
    mn, mx = supercell_ranges(data, grid)
    bound = 1e-9 * float(np.abs(data).max())
    ex, ey, ez = grid.edges
    for c in range(grid.shape[0]):
        for b in range(grid.shape[1]):
            for a in range(grid.shape[2]):
                rmn, rmx = box_range(data, (ex[a], ey[b], ez[c]), (ex[a + 1], ey[b + 1], ez[c + 1]))
                assert rmn - bound <= mn[c, b, a] <= rmn and rmx <= mx[c, b, a] <= rmx + bound, (size, c, b, a)
