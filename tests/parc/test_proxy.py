"""Proxy geometry: the outer faces of the PC supercells.

Truth: topology and the mask itself. The faces must be closed (every edge
of the split-back unit faces used as often in each direction as in the
other, so the surface is closed and consistently oriented), each face
must separate a PC supercell (inside) from an empty one or the outside,
and every such PC/empty pair must have its face. Together these say the
faces bound exactly the union of the PC supercells.
"""
import numpy as np
import pytest

from data_tools import Volume
from parc.ranges import supercell_grid
from parc.proxy import build_proxy, proxy_for_iso


def _masks():
    rng = np.random.default_rng(4)
    yield "random30", rng.random((5, 6, 7)) < 0.3
    yield "random70", rng.random((4, 5, 3)) < 0.7
    yield "full", np.ones((3, 4, 5), bool)
    yield "empty", np.zeros((3, 4, 5), bool)
    one = np.zeros((3, 3, 3), bool)
    one[1, 1, 1] = True
    yield "single", one
    # Two supercells touching only along an edge, and only at a corner.
    edge = np.zeros((2, 2, 2), bool)
    edge[0, 0, 0] = edge[0, 1, 1] = True
    yield "edge-touch", edge
    corner = np.zeros((2, 2, 2), bool)
    corner[0, 0, 0] = corner[1, 1, 1] = True
    yield "corner-touch", corner
    yield "line", np.ones((1, 1, 6), bool)


MASKS = list(_masks())


def _grid_for(mask, size=(1.5, 2, 1)):
    """A grid with the mask's shape; x has a partial last supercell."""
    az, ay, ax = mask.shape
    dims = tuple(int(np.floor(n * s)) + 1 for n, s in zip((ax, ay, az), size))
    g = supercell_grid(dims, size)
    assert g.shape == mask.shape, (g.shape, mask.shape)
    return g


def _proxy(mask, merge):
    grid = _grid_for(mask)
    world = tuple(o + e * s for o, e, s in zip((10.0, -3.0, 0.5), grid.edges, (0.7, 1.0, 1.3)))
    return build_proxy(grid, mask, world, merge=merge)


def _directed_edges(proxy):
    """Every unit face's four boundary edges, as directed pairs of grid vertices."""
    f = proxy.unit_faces()
    a, p, u, v, s = f.T
    corners = []
    for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
        c = np.zeros((len(f), 3), np.int64)
        c[np.arange(len(f)), a] = p
        c[np.arange(len(f)), (a + 1) % 3] = u + du
        c[np.arange(len(f)), (a + 2) % 3] = v + dv
        corners.append(c)
    corners = np.stack(corners, 1)                   # (N, 4, 3), CCW around +e_axis
    corners[s < 0] = corners[s < 0][:, ::-1]         # CCW seen from outside
    start = corners.reshape(-1, 3)
    end = np.roll(corners, -1, axis=1).reshape(-1, 3)
    return start, end


@pytest.mark.parametrize("merge", [False, True])
@pytest.mark.parametrize("name, mask", MASKS, ids=[m[0] for m in MASKS])
def test_faces_closed_and_oriented(name, mask, merge):
    proxy = _proxy(mask, merge)
    start, end = _directed_edges(proxy)
    if len(start) == 0:
        assert not mask.any()
        return
    fwd = np.concatenate([start, end], 1)
    rev = np.concatenate([end, start], 1)
    keys, counts = np.unique(fwd, axis=0, return_counts=True)
    rkeys, rcounts = np.unique(rev, axis=0, return_counts=True)
    # Every directed edge is matched by as many opposite ones: closed and
    # consistently oriented, hence every undirected edge has even multiplicity.
    np.testing.assert_array_equal(keys, rkeys)
    np.testing.assert_array_equal(counts, rcounts)


@pytest.mark.parametrize("merge", [False, True])
@pytest.mark.parametrize("name, mask", MASKS, ids=[m[0] for m in MASKS])
def test_faces_bound_exactly_the_pc_union(name, mask, merge):
    proxy = _proxy(mask, merge)
    f = proxy.unit_faces()
    padded = np.pad(mask, 1)

    def pc_at(ix, iy, iz):
        return padded[iz + 1, iy + 1, ix + 1]

    seen = set()
    for a, p, u, v, s in f:
        idx_lo = [0, 0, 0]
        idx_lo[a] = p - 1
        idx_lo[(a + 1) % 3] = u
        idx_lo[(a + 2) % 3] = v
        idx_hi = list(idx_lo)
        idx_hi[a] = p
        inside, outside = (idx_lo, idx_hi) if s > 0 else (idx_hi, idx_lo)
        assert pc_at(*inside) and not pc_at(*outside)
        key = (a, p, u, v)
        assert key not in seen
        seen.add(key)
    # Completeness: one face per PC/non-PC neighbour pair (outside counts as non-PC).
    pairs = sum(np.count_nonzero(np.diff(padded.astype(np.int8), axis=ax)) for ax in range(3))
    assert len(seen) == pairs


@pytest.mark.parametrize("name, mask", MASKS, ids=[m[0] for m in MASKS])
def test_merged_covers_the_same_faces(name, mask):
    a = _proxy(mask, merge=False)
    b = _proxy(mask, merge=True)
    ua = {tuple(r) for r in a.unit_faces()}
    ub = {tuple(r) for r in b.unit_faces()}
    assert ua == ub and len(ua) == a.n_polygons
    assert b.n_polygons <= a.n_polygons


def test_a_box_of_supercells_merges_into_its_six_sides():
    # Any rectangular block's outer faces are six rectangles: a merge that joined the unit faces
    # into strips only (one pass of two) leaves more.
    rng = np.random.default_rng(3)
    for _ in range(100):
        shape = tuple(int(n) for n in rng.integers(1, 7, 3))
        mask = np.zeros(shape, bool)
        lo = [int(rng.integers(0, n)) for n in shape]
        hi = [int(rng.integers(a + 1, n + 1)) for a, n in zip(lo, shape)]
        mask[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = True
        assert _proxy(mask, merge=True).n_polygons == 6, (shape, lo, hi)


@pytest.mark.parametrize("merge", [False, True])
def test_world_quads(merge):
    mask = MASKS[0][1]
    proxy = _proxy(mask, merge)
    q = proxy.quads()
    assert q.shape == (proxy.n_polygons, 4, 3)
    # Planar, axis-aligned, on the stated plane.
    for k in range(proxy.n_polygons):
        a = proxy.axis[k]
        assert np.all(q[k, :, a] == proxy.plane[k])
    # Winding gives the outward normal.
    n = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 1])
    expect = np.zeros_like(n)
    expect[np.arange(len(n)), proxy.axis] = proxy.outward
    assert np.all(np.sign(n) == expect)
    # Corners are supercell boundaries in world coordinates.
    for a in range(3):
        assert np.isin(q[..., a], proxy.world_edges[a]).all()
    # Closed surface: the outward-oriented quads enclose the PC volume
    # (divergence theorem, once per axis: sum over faces of p_a n_a area = 3 V).
    area = np.linalg.norm(n, axis=1)
    centroid = q.mean(axis=1)
    vol_faces = np.sum(centroid[np.arange(len(n)), proxy.axis] * proxy.outward * area)
    ex, ey, ez = proxy.world_edges
    cell_vol = np.diff(ez)[:, None, None] * np.diff(ey)[None, :, None] * np.diff(ex)[None, None, :]
    assert vol_faces == pytest.approx(3 * cell_vol[mask].sum(), rel=1e-12)


def test_proxy_for_iso():
    rng = np.random.default_rng(0)
    vol = Volume(rng.random((6, 7, 8)).astype(np.float32), spacing=(0.5, 1, 2), origin=(1, 2, 3))
    p = proxy_for_iso(vol, 0.5, 2)
    assert p.grid.size == (2.0, 2.0, 2.0)
    lo, hi = p.bounds
    np.testing.assert_array_equal(lo, [1, 2, 3])
    np.testing.assert_array_equal(hi, np.array([1, 2, 3]) + np.array([7, 6, 5]) * np.array([0.5, 1, 2]))
    assert p.n_polygons > 0


def test_proxy_for_iso_marks_the_supercells_holding_the_isovalue():
    # Samples equal to their x index: 4.5 lies between samples 4 and 5 only, in the third
    # column of 2-cell supercells (cells 4..5, samples 4..6), whatever y and z.
    k, j, i = np.mgrid[0:6, 0:7, 0:9]
    p = proxy_for_iso(Volume(i.astype(np.float32), spacing=(0.5, 1, 2), origin=(1, 2, 3)), 4.5, 2)
    want = np.zeros(p.grid.shape, bool)
    want[:, :, 2] = True
    np.testing.assert_array_equal(p.pc, want)
    assert p.n_polygons == 6


@pytest.mark.parametrize("iso", [100.5, 140.0])
def test_a_render_draws_exactly_the_supercells_holding_the_isovalue(iso, gl):
    from data_tools.synthetic import blobs
    from parc import Camera, Isosurface, Scene, render
    vol = blobs(13, seed=4)
    d = vol.data.astype(np.float64)
    nz, ny, nx = d.shape
    want = 0
    for k in range(0, nz - 1, 2):
        for j in range(0, ny - 1, 2):
            for i in range(0, nx - 1, 2):
                block = d[k:k + 3, j:j + 3, i:i + 3]     # a supercell of 2 cells: 3 samples a side
                want += bool(block.min() <= iso <= block.max())
    assert 0 < want < (nx // 2) * (ny // 2) * (nz // 2)      # some supercells, not all
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(16, 16), volumes=[Isosurface(vol, iso)])
    stats = render(scene, method="parc", supercell=2).stats
    assert stats["pc_supercells"] == want
    assert stats["supercells"] == len(range(0, nx - 1, 2)) * len(range(0, ny - 1, 2)) * len(range(0, nz - 1, 2))
