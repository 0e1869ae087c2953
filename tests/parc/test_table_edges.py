"""Edges of the classification, proxy and skip tables: limits met exactly, and rarely taken paths.

Truths: hand-made volumes whose classes are known cell by cell, the documented contracts
(`raycast.composite.INTERP_ROUNDING`, `MAX_SUPERCELLS`), `build_proxy` without merging, and
`sign_iso` against `classify_iso` (a box is signed exactly when it is not possibly contributing).
"""
import numpy as np
import pytest

from data_tools import InputError, Volume
from parc.classify import VolumeIndex, classify_iso, classify_tf, sign_iso
from parc.proxy import build_plane_proxy, build_proxy
from parc.ranges import MAX_SUPERCELLS, supercell_grid
from parc.transfer import TransferFunction


def test_transfer_function_tables_count_a_support_starting_a_rounding_past_a_cells_range():
    """A cell whose corners reach ``m``, and opacity starting 8 ulps of ``m`` past it: the casters'
    samples can overshoot the corners by `INTERP_ROUNDING` of their magnitude (brute would show
    them), so the cell may contribute in every table built for a transfer function; a cell whose
    corners stay at 100 does not."""
    m = 200.0
    eps = 8 * 2.0 ** -53 * m
    tf = TransferFunction([[m + eps, 0.0], [m + 2 * eps, 0.5], [m + 1.0, 0.5]])
    data = np.full((5, 5, 5), 100.0)
    data[2, 2, 2] = m                       # a corner of the 8 cells around sample (2, 2, 2)
    index = VolumeIndex.of(Volume(data))
    want = np.zeros((4, 4, 4), bool)
    want[1:3, 1:3, 1:3] = True
    np.testing.assert_array_equal(classify_tf(*index.cell_minmax(), tf), want)
    table, _ = index.tf_skip(tf)
    np.testing.assert_array_equal(table == 0, want)
    np.testing.assert_array_equal(classify_tf(*index.ranges(2), tf), np.ones((2, 2, 2), bool))
    np.testing.assert_array_equal(classify_tf(*index.ranges(4), tf), np.ones((1, 1, 1), bool))
    sub = classify_tf(*index.ranges(0.5), tf)          # sub-cells: those touching sample (2, 2, 2)
    want_sub = np.zeros((8, 8, 8), bool)
    want_sub[3:5, 3:5, 3:5] = True
    np.testing.assert_array_equal(sub, want_sub)
    # ... and no farther: a support a millionth past m leaves every table empty.
    far = TransferFunction([[m * (1 + 1e-6), 0.0], [m + 1.0, 0.5]])
    assert not classify_tf(*index.cell_minmax(), far).any()
    assert not classify_tf(*index.ranges(0.5), far).any()


def test_the_supercell_count_guard_is_exact_at_its_limit():
    """`MAX_SUPERCELLS` (2^28) supercells are allowed, one plane more is not."""
    assert MAX_SUPERCELLS == 1 << 28
    assert supercell_grid((1025, 1025, 257), 1).counts == (1024, 1024, 256)
    with pytest.raises(InputError, match="supercells"):
        supercell_grid((1025, 1025, 258), 1)
    # The same at a fractional size: 2048 x 2048 x 64 half cells.
    assert supercell_grid((1025, 1025, 33), 0.5).counts == (2048, 2048, 64)
    with pytest.raises(InputError, match="supercells"):
        supercell_grid((1025, 1025, 33), (0.5, 0.5, 0.49))


def test_skip_tables_for_isovalues_an_ulp_apart_are_kept_apart():
    """Samples 0..4 along x: at iso 2 the cells touching x = 2 may contribute; an ulp above 2 the
    cell [1, 2] lies wholly below. A table kept under a rounded key would serve the other one."""
    x = np.arange(5, dtype=np.float32)
    vol = Volume(np.broadcast_to(x, (3, 3, 5)).copy())
    index = VolumeIndex.of(vol)
    up = float(np.nextafter(2.0, 3.0))
    for iso, col in ((2.0, [-1, 0, 0, 1]), (up, [-2, -1, 0, 1]), (2.0, [-1, 0, 0, 1])):
        table, _ = index.iso_skip(iso)
        np.testing.assert_array_equal(table[0, 0], col, err_msg=repr(iso))
        index.expect_frames(iso)
        tables, _ = index.iso_octant_skip(iso, [0])
        np.testing.assert_array_equal(np.sign(tables[0][0, 0]), np.sign(col), err_msg=repr(iso))


def test_sign_iso_signs_exactly_the_boxes_classify_iso_leaves_out():
    """On float32 ranges, with isovalues a float32 holds and ones it does not (compared in float64,
    as the caster does): never both signed and possibly contributing, never neither."""
    rng = np.random.default_rng(12)
    data = rng.normal(size=(7, 8, 9)).astype(np.float32)
    index = VolumeIndex.of(Volume(data))
    mn, mx = index.cell_minmax()
    isos = []
    for v in data.flat[rng.integers(data.size, size=20)]:
        v = float(v)
        isos += [v, v + abs(v) * 2.0 ** -30, v - abs(v) * 2.0 ** -30]   # between float32 neighbours
    for iso in isos:
        pc = classify_iso(mn, mx, iso)
        sign = sign_iso(mn, mx, iso)
        np.testing.assert_array_equal(sign == 0, pc, err_msg=repr(iso))
        np.testing.assert_array_equal(sign > 0, mn.astype(np.float64) > iso, err_msg=repr(iso))


@pytest.mark.parametrize("plane_axis", [None, 0, 2])
def test_merging_a_grid_too_long_for_a_packed_key(plane_axis):
    """40,000 supercells in a row make the merge's sort keys exceed 2^62 (`parc.proxy._pack`
    ranks them instead): the merged rectangles still cover exactly the unit faces, and a box
    of supercells still merges into its six sides (twelve with a gap across it)."""
    rng = np.random.default_rng(5)
    n = 40_000
    grid = supercell_grid((n + 1, 4, 3), 1)
    world = tuple(e.astype(np.float64) for e in grid.edges)

    def build(mask, merge=True):
        if plane_axis is None:
            return build_proxy(grid, mask, world, merge=merge)
        return build_plane_proxy(grid, mask, world, plane_axis, merge=merge)

    def rows(p):
        cols = [p.unit_faces()] + ([] if plane_axis is None else [p.unit_planes()])
        return {tuple(r) for r in np.column_stack(cols).tolist()}

    box = np.ones((2, 3, n), bool)
    gap = box.copy()
    gap[:, :, n // 2] = False
    if plane_axis is None:
        assert build(box).n_polygons == 6 and build(gap).n_polygons == 12
    elif plane_axis == 2:
        # Per plane of the two along z: its x and y sides (4 rectangles); the bottom, the top and
        # the boundary between the planes: 11. A gap across the row doubles each.
        assert build(box).n_polygons == 11 and build(gap).n_polygons == 22
    mask = np.zeros((2, 3, n), bool)
    mask[0, 1] = rng.random(n) < 0.5
    mask[1, :, n // 3:] = True
    merged, unit = build(mask), build(mask, merge=False)
    assert rows(merged) == rows(unit) and len(rows(unit)) == unit.n_polygons
    assert merged.n_polygons < unit.n_polygons


@pytest.mark.parametrize("slices", [2, 3, 5])
def test_ranges_in_slabs_of_several_slices(monkeypatch, slices):
    """Slabs of 2, 3 and 5 z-slices (a large volume's case: 64 slices for 256 x 256 samples), a
    last one short: every cell and supercell gets its range (the loop's, and one slab's)."""
    import parc.ranges as cl
    from parc.ranges import cell_minmax, supercell_ranges
    from parc_reference import cell_minmax_loop
    rng = np.random.default_rng(slices)
    data = rng.integers(-3000, 3000, (12, 7, 8)).astype(np.int16)
    grid = supercell_grid((8, 7, 12), (1.5, 0.5, 1.25))
    whole = supercell_ranges(data, grid)
    monkeypatch.setattr(cl, "CHUNK_VALUES", slices * 7 * 8)
    for got, want in zip(cell_minmax(data), cell_minmax_loop(data)):
        np.testing.assert_array_equal(got, want)
    monkeypatch.setattr(cl, "CHUNK_VALUES", slices * len(np.union1d(np.arange(7), grid.edges[1]))
                        * len(np.union1d(np.arange(8), grid.edges[0])))
    for got, want in zip(supercell_ranges(data, grid), whole):
        np.testing.assert_array_equal(got, want)
