"""The supercell size chooser and the face counts it is built on.

Truth: slow loops over every supercell boundary, and the proxy itself
(`parc.proxy.build_proxy` merges the faces the counts count).
"""
import math
from pathlib import Path

import numpy as np
import pytest

from parc import costmodel
from parc.classify import VolumeIndex
from parc.ranges import supercell_grid
from parc.costmodel import choose_supercell, count_face_strips, count_outer_faces, face_counts, projected_share
from parc.proxy import build_proxy


def _faces_loop(pc):
    """Every outer unit face as ``(axis, orientation, plane, u, v)``, by a loop over boundaries."""
    nz, ny, nx = pc.shape
    n = (nx, ny, nz)

    def is_pc(x, y, z):
        return 0 <= x < nx and 0 <= y < ny and 0 <= z < nz and bool(pc[z, y, x])

    out = set()
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        for p in range(n[a] + 1):
            for iu in range(n[u]):
                for iv in range(n[v]):
                    below = [0, 0, 0]
                    below[a], below[u], below[v] = p - 1, iu, iv
                    above = list(below)
                    above[a] = p
                    lo, hi = is_pc(*below), is_pc(*above)
                    if lo != hi:
                        out.add((a, int(lo), p, iu, iv))
    return out


def _strips_loop(pc):
    """Maximal runs along u of faces with the same axis, orientation, plane and v."""
    faces = _faces_loop(pc)
    return sum(1 for (a, o, p, iu, iv) in faces if (a, o, p, iu - 1, iv) not in faces)


def test_count_outer_faces():
    pc = np.zeros((3, 4, 5), bool)
    assert count_outer_faces(pc) == 0
    pc[1, 1, 1] = True
    assert count_outer_faces(pc) == 6
    pc[1, 1, 2] = True
    assert count_outer_faces(pc) == 10
    assert count_outer_faces(np.ones((2, 3, 4), bool)) == 2 * (6 + 8 + 12)


@pytest.mark.parametrize("seed", range(24))
def test_face_counts_match_a_loop_and_bound_the_merged_proxy(seed):
    rng = np.random.default_rng(seed)
    shape = tuple(int(s) for s in rng.integers(1, 7, 3))
    pc = rng.random(shape) < rng.uniform(0.1, 0.9)
    faces = _faces_loop(pc)
    assert count_outer_faces(pc) == len(faces)
    strips = count_face_strips(pc)
    assert strips == _strips_loop(pc)
    assert face_counts(pc) == (len(faces), strips)
    grid = supercell_grid((shape[2] + 1, shape[1] + 1, shape[0] + 1), 1)
    proxy = build_proxy(grid, pc, grid.world_edges(_Box()))
    assert proxy.n_polygons <= strips <= len(faces)


class _Box:
    """A stand-in volume at the origin with unit spacing, for `SupercellGrid.world_edges`."""

    def __init__(self):
        self.origin = (0.0, 0.0, 0.0)
        self.spacing = (1.0, 1.0, 1.0)


def test_strips_of_a_slab_are_its_rows():
    # A slab one supercell thick, full in x and y.
    pc = np.zeros((5, 7, 9), bool)
    pc[2] = True
    assert count_outer_faces(pc) == 2 * 7 * 9 + 2 * 9 + 2 * 7
    # z faces run along x (u = x): 7 rows each; x faces run along y: one per
    # side; y faces run along z: one per column of the side (9 each).
    assert count_face_strips(pc) == 2 * 7 + 2 * 1 + 2 * 9


def test_choose_supercell_reports_its_model():
    from data_tools.synthetic import sphere
    vol = sphere(40)
    size, table = choose_supercell(VolumeIndex.of(vol), 0.0, rays=200 * 200, cores=2)
    assert size in [r["size"] for r in table]
    best = min(table, key=lambda r: r["total_s"])
    assert best["size"] == size
    polys = [r["faces"] for r in table]
    assert polys[0] > polys[-1] > 0
    for r in table:
        assert r["strips"] <= r["faces"]
        assert r["total_s"] == pytest.approx(r["raster_s"] + r["cast_s"])


def test_cast_cost_divides_by_the_casters_threads():
    # The caster runs on Numba's threads, which NUMBA_NUM_THREADS or
    # set_num_threads may hold below the machine's core count.
    import numba
    from data_tools.synthetic import sphere
    index = VolumeIndex.of(sphere(24))
    saved = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        _, held = choose_supercell(index, 0.0, rays=100 * 100)
    finally:
        numba.set_num_threads(saved)
    _, one = choose_supercell(index, 0.0, rays=100 * 100, cores=1)
    _, two = choose_supercell(index, 0.0, rays=100 * 100, cores=2)
    assert [r["cast_s"] for r in held] == [r["cast_s"] for r in one]
    assert [r["cast_s"] for r in one] == pytest.approx([2.0 * r["cast_s"] for r in two])


@pytest.mark.parametrize("renderer, software", [
    ("llvmpipe (LLVM 15.0.6, 256 bits)", True), ("softpipe", True), ("Mesa Software Rasterizer", True),
    ("Google SwiftShader", True), ("Mesa DRI swrast", True),
    ("NVIDIA H100 80GB HBM3/PCIe/SSE2", False), ("AMD Radeon RX 7900 XTX (radeonsi, navi31, LLVM 17.0.6)", False)])
def test_raster_costs_by_renderer(renderer, software):
    # Both costs of a frame are the ones measured on that kind of rasterizer, 2.6 ms and
    # 0.325 us per strip with llvmpipe, 1.14 ms and 42.5 ns on the H100.
    want = (2.6e-3, 0.325e-6) if software else (1.14e-3, 42.5e-9)
    assert costmodel.raster_costs(renderer) == pytest.approx(want, rel=1e-12)


def test_without_opengl_the_costs_are_a_software_rasterizers(monkeypatch):
    import parc.gl

    def unavailable():
        raise parc.gl.OpenGLUnavailable("no EGL display here")
    monkeypatch.setattr(parc.gl, "context_info", unavailable)
    assert costmodel.raster_costs() == costmodel.raster_costs("llvmpipe")


def test_cheap_polygons_choose_finer_supercells():
    # With a GPU's cost per polygon, the rasterization term shrinks most for
    # the finest sizes: llvmpipe's pick here is 3, the GPU's 1.
    from data_tools.synthetic import blobs
    index = VolumeIndex.of(blobs(96, seed=3))
    soft, soft_table = choose_supercell(index, 100.0, cores=2, renderer="llvmpipe")
    gpu, gpu_table = choose_supercell(index, 100.0, cores=2, renderer="NVIDIA H100")
    assert gpu < soft
    fixed, per_strip = costmodel.raster_costs("NVIDIA H100")
    for row in gpu_table:
        assert row["raster_s"] == pytest.approx(fixed + per_strip * row["strips"])
    assert [r["cast_s"] for r in gpu_table] == [r["cast_s"] for r in soft_table]


def test_flat_surfaces_pay_for_merged_polygons_not_faces():
    # A floor: the slab's faces merge into a few rectangles at every size, so
    # the model must not charge small supercells for their many unit faces.
    from data_tools.synthetic import floor
    vol = floor(64, relief=0.0)
    index = VolumeIndex.of(vol)
    size, table = choose_supercell(index, 127.5, pixels=600 * 600, cores=2)
    by_size = {r["size"]: r for r in table}
    assert by_size[1.0]["strips"] * 10 < by_size[1.0]["faces"]
    assert size <= 2.0


def test_cost_model_skips_sizes_too_fine_for_the_volume(monkeypatch):
    import parc.ranges
    import parc.costmodel as costmodel
    from data_tools.synthetic import blobs
    index = VolumeIndex(blobs(17))
    # 16^3 cells: size 1 gives 4096 supercells, size 2 gives 512, size 4 gives 64.
    monkeypatch.setattr(parc.ranges, "MAX_SUPERCELLS", 600)
    size, table = costmodel.choose_supercell(index, 0.5, candidates=(1, 2, 4))
    assert [r["size"] for r in table] == [2.0, 4.0]
    assert size in (2.0, 4.0)


def test_projected_share_of_one_box_and_of_a_column():
    # Supercell boundaries along x, y, z; the volume box is 10 x 5 x 5.
    edges = ([0.0, 1.0, 3.0, 6.0, 10.0], [0.0, 2.0, 3.0, 5.0], [0.0, 4.0, 5.0])
    box = 10 * 5 + 5 * 10 + 5 * 5
    pc = np.zeros((2, 3, 4), bool)
    assert projected_share(pc, edges) == 0.0
    pc[1, 2, 3] = True          # x in [6, 10], y in [3, 5], z in [4, 5]
    assert projected_share(pc, edges) == pytest.approx((4 * 2 + 1 * 4 + 1 * 2) / box)
    pc[0, 2, 3] = True          # the same column along z: its shadow along z counts once
    assert projected_share(pc, edges) == pytest.approx((4 * 2 + 5 * 4 + 5 * 2) / box)
    assert projected_share(np.ones((2, 3, 4), bool), edges) == pytest.approx(1.0)


@pytest.mark.parametrize("seed", range(4))
def test_projected_share_is_the_share_of_axis_rays_that_meet_the_pc_region(seed):
    # Truth: rays along each axis through random points of the box's faces,
    # each face weighted by its area, counted as hits when a PC supercell
    # lies on their column.
    rng = np.random.default_rng(seed)
    shape = tuple(int(s) for s in rng.integers(1, 6, 3))
    pc = rng.random(shape) < 0.2
    edges = [np.concatenate([[0.0], np.cumsum(rng.uniform(0.3, 2.0, n))]) for n in shape[::-1]]
    size = [e[-1] for e in edges]
    n = 40_000
    hits = weight = 0.0
    for a in range(3):
        u, v = [b for b in range(3) if b != a]
        pu = rng.uniform(0, size[u], n)
        pv = rng.uniform(0, size[v], n)
        iu = np.searchsorted(edges[u], pu, side="right") - 1
        iv = np.searchsorted(edges[v], pv, side="right") - 1
        # pc is [z, y, x]: with axis a moved last, the others stay in that order, v (> u) first.
        met = np.moveaxis(pc, 2 - a, -1)[iv, iu].any(axis=-1)
        area = size[u] * size[v]
        hits += area * met.mean()
        weight += area
    assert projected_share(pc, edges) == pytest.approx(hits / weight, abs=0.01)


def _model_expected(index, iso, m, *, pixels, rays, cores, renderer):
    """One row of the cost model by its documented formulas, the counts by the slow loops above."""
    pc = index.classify(iso, m)
    share = projected_share(pc, index.grid(m).world_edges(index.volume))
    fixed, per_strip = costmodel.raster_costs(renderer)
    rays_pc = (costmodel.RAY_COVER * pixels if rays is None else rays) * share
    pc1 = index.classify(iso, 1)
    cells_pc = sum(1 for k, j, i in np.ndindex(pc1.shape) if pc1[k, j, i])
    free = pc1.size / cells_pc if cells_pc else math.inf
    cells = rays_pc * min(costmodel.WALK_CELLS * (1.0 - 2.0 ** -m), free)
    return {"faces": len(_faces_loop(pc)), "strips": _strips_loop(pc), "share": share, "rays": rays_pc,
            "raster_s": fixed * pixels / 512 ** 2 + per_strip * _strips_loop(pc), "cells": cells,
            "cast_s": (rays_pc * costmodel.CAST_PER_RAY_S + cells * costmodel.CAST_PER_CELL_S) / cores,
            "supercells": pc.size, "pc_supercells": int(pc.sum())}


@pytest.mark.parametrize("renderer", ["llvmpipe", "NVIDIA H100"])
@pytest.mark.parametrize("pixels, rays, cores", [(300 * 200, None, 3), (512 * 512, 5000, 1)])
@pytest.mark.parametrize("spacing", [(1.0, 1.0, 1.0), (0.5, 1.0, 3.0)])
def test_model_rows_follow_the_documented_formulas(renderer, pixels, rays, cores, spacing):
    """`choose_supercell`'s Notes: rasterization scales with the image and the strips,
    casting with the rays that reach the PC region and the cells they walk, over the cores.
    The share is of the box in world units: with unequal spacings, as a CT's slices, a
    supercell's shadow is not its shadow in cells."""
    from data_tools import Volume
    from data_tools.synthetic import blobs
    index = VolumeIndex.of(Volume(blobs(20, seed=2, count=3).data, spacing=spacing))
    size, table = choose_supercell(index, 100.0, pixels=pixels, rays=rays, cores=cores,
                                   candidates=(1, 2, 3, 5), renderer=renderer)
    assert [r["size"] for r in table] == [1.0, 2.0, 3.0, 5.0]
    for r in table:
        want = _model_expected(index, 100.0, int(r["size"]), pixels=pixels, rays=rays, cores=cores,
                               renderer=renderer)
        for key, value in want.items():
            assert r[key] == pytest.approx(value, rel=1e-12), (r["size"], key)
        assert r["total_s"] == pytest.approx(want["raster_s"] + want["cast_s"], rel=1e-12)
    assert size == min(table, key=lambda r: r["total_s"])["size"]


def test_the_pick_trades_polygons_against_cells_walked(monkeypatch):
    """Free polygons leave only casting, which the finest supercells minimise (their PC region
    lies inside every coarser one's, and their walks are shortest); free casting leaves only
    the strips, and the pick is the size with the fewest."""
    from data_tools.synthetic import blobs
    index = VolumeIndex.of(blobs(24, seed=5, count=4))
    candidates = (1, 2, 4, 8)
    fewest = min(candidates, key=lambda m: (_strips_loop(index.classify(90.0, m)), m))
    assert fewest != 1
    size, _ = choose_supercell(index, 90.0, cores=10 ** 12, candidates=candidates, renderer="llvmpipe")
    assert size == fewest
    monkeypatch.setattr(costmodel, "RASTER_PER_STRIP_S", 0.0)
    size, table = choose_supercell(index, 90.0, cores=2, candidates=candidates, renderer="llvmpipe")
    assert size == 1.0
    casts = [r["cast_s"] for r in table]
    assert casts == sorted(casts) and casts[0] < casts[-1]


DATA = Path(__file__).parents[2].parent / "shared" / "data"


def test_the_picks_the_notes_report_on_the_measured_volumes():
    """`choose_supercell`'s Notes: with llvmpipe on 2 cores at 512^2 the model picks 8 for the
    CT head's skin and bone among 4, 6, 8, 10, and 2 for neghip among 2, 3, 4, 8."""
    from data_tools import load_volume
    if not (DATA / "CThead.nrrd").is_file() or not (DATA / "neghip.slc").is_file():
        pytest.skip(f"the CT head and neghip are not in {DATA}")
    head = VolumeIndex.of(load_volume(DATA / "CThead.nrrd"))
    neghip = VolumeIndex.of(load_volume(DATA / "neghip.slc"))
    picks = [choose_supercell(index, iso, cores=2, renderer="llvmpipe", candidates=sizes)[0]
             for index, iso, sizes in ((head, 600.0, (4, 6, 8, 10)), (head, 1500.0, (4, 6, 8, 10)),
                                       (neghip, 80.0, (2, 3, 4, 8)))]
    assert picks == [8.0, 8.0, 2.0]


def test_the_renderer_models_its_own_image_size():
    """Without a supercell size the renderer asks the model for the frame's pixels and
    builds the proxy at the size with the least estimated time."""
    from data_tools.synthetic import blobs
    from parc.segments import cached_proxy
    from parc.scene import Isosurface
    vol = blobs(20, seed=2, count=3)
    fixed, per_strip = costmodel.raster_costs()
    for w, h in ((64, 48), (800, 600)):
        _, extra = cached_proxy(Isosurface(vol, 100.0), None, (w, h), {})
        table = extra["supercell_model"]
        for r in table:
            assert r["raster_s"] == pytest.approx(fixed * w * h / 512 ** 2 + per_strip * r["strips"], rel=1e-12)
            assert r["rays"] == pytest.approx(costmodel.RAY_COVER * w * h * r["share"], rel=1e-12)
        best = min(table, key=lambda r: r["total_s"])["size"]
        assert extra["supercell"] == [best] * 3


def test_a_caller_changing_the_reported_model_changes_no_later_report():
    """The model's table is kept per classification; what a render reports is the caller's."""
    from data_tools.synthetic import blobs
    from parc.segments import cached_proxy
    from parc.scene import Isosurface
    vol = blobs(20, seed=2, count=3)
    _, first = cached_proxy(Isosurface(vol, 100.0), None, (64, 48), {})
    expected = [dict(r) for r in first["supercell_model"]]
    first["supercell_model"][0]["total_s"] = -1.0
    first["supercell_model"].clear()
    _, again = cached_proxy(Isosurface(vol, 100.0), None, (64, 48), {})
    assert again["supercell_model"] == expected


def test_a_grid_of_possibly_contributing_supercells_costs_what_the_constants_give_by_hand():
    """Every supercell possibly contributing: the share is 1 and each outer plane's faces
    make one strip per row (6 n of them for n supercells a side), so each row follows
    from the measured constants alone: 13 (1 - 2^-m) cells walked per ray through m-cell
    supercells, at 14.4 ns a cell and 0.22 us a ray; 2.6 ms a 512^2 frame and 0.325 us a
    strip (llvmpipe). One cell in 13,824 is possibly contributing, so the walk is the
    measured one; with every cell so, a ray meets one at once."""
    from data_tools import Volume
    index = VolumeIndex.of(Volume(np.zeros((25, 25, 25), np.float32)))

    def one_cell(m):
        pc = np.ones(index.grid(m).shape, bool)
        if m == 1:
            pc[:] = False
            pc[3, 4, 5] = True          # a free path of 13,824 cells
        return pc
    size, table = choose_supercell(index, classify=one_cell, rays=1000, cores=1, candidates=(2, 4, 8),
                                   renderer="llvmpipe")
    # 24 cells a side: 12, 6 and 3 supercells; 72, 36 and 18 strips.
    by_hand = [(2.0, 72, 9750.0, 3.604e-4, 2.6234e-3), (4.0, 36, 12187.5, 3.955e-4, 2.6117e-3),
               (8.0, 18, 12949.21875, 4.0646875e-4, 2.60585e-3)]
    for r, (m, strips, cells, cast_s, raster_s) in zip(table, by_hand, strict=True):
        assert (r["size"], r["strips"], r["share"], r["rays"]) == (m, strips, 1.0, 1000.0)
        assert r["cells"] == pytest.approx(cells, rel=1e-12)
        assert r["cast_s"] == pytest.approx(cast_s, rel=1e-12)
        assert r["raster_s"] == pytest.approx(raster_s, rel=1e-12)
    assert size == 2.0                              # 2.9838 ms against 3.0072 and 3.01232

    size, table = choose_supercell(index, classify=lambda m: np.ones(index.grid(m).shape, bool), rays=1000,
                                   cores=1, candidates=(1, 2, 4), renderer="llvmpipe")
    assert [r["strips"] for r in table] == [144, 72, 36]
    for r in table:                                 # one cell a ray: 0.2344 ms each
        assert r["cells"] == pytest.approx(1000.0, rel=1e-12)
        assert r["cast_s"] == pytest.approx(2.344e-4, rel=1e-12)
    assert size == 4.0                              # the fewest strips: 2.8461 ms against 2.8578 and 2.8812


def test_free_path_is_one_over_the_share_of_possibly_contributing_cells():
    pc = np.zeros((4, 5, 6), bool)
    assert costmodel.free_path(pc) == math.inf
    pc.flat[[0, 7, 30]] = True
    assert costmodel.free_path(pc) == pytest.approx(120 / 3, rel=1e-15)
    assert costmodel.free_path(np.ones((2, 2, 2), bool)) == 1.0
    assert costmodel.free_path(np.zeros((0, 3, 3), bool)) == math.inf


def test_a_level_in_noise_walks_its_free_path_and_a_surface_the_measured_walk():
    """Noise at its median: half the samples above, so nearly every cell holds the level, and
    a ray meets a PC cell within a cell or two whatever the size; the walk is then the free
    path, the same for every size, and only the strips tell them apart. A sphere's surface
    in 40^3 samples gathers its cells (6% of them: a free path of 17 cells, above every
    measured walk), and keeps the measured walk, growing with the size."""
    from data_tools import Volume
    from data_tools.synthetic import sphere
    rng = np.random.default_rng(3)
    noise = VolumeIndex.of(Volume(rng.integers(0, 256, (33, 33, 33)).astype(np.uint8)))
    pc1 = noise.classify(127.5, 1)
    assert pc1.mean() > 0.9
    size, table = choose_supercell(noise, 127.5, rays=1000, cores=1, candidates=(1, 2, 4, 8), renderer="llvmpipe")
    for r in table:
        assert r["cells"] == pytest.approx(r["rays"] * pc1.size / np.count_nonzero(pc1), rel=1e-12)
    assert size == 8.0
    ball = VolumeIndex.of(sphere(40))
    _, table = choose_supercell(ball, 0.0, rays=1000, cores=1, candidates=(1, 2, 4, 8), renderer="llvmpipe")
    for r in table:
        assert r["cells"] == pytest.approx(r["rays"] * costmodel.WALK_CELLS * (1 - 2 ** -r["size"]), rel=1e-12)
