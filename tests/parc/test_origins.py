"""Where rays start relative to the PC region (`parc.origins`), without OpenGL.

Truth: plain NumPy over every supercell box -- the Euclidean distance to
the nearest PC box, a breadth-first search through faces, edges and
corners for the open empty space, closed boxes for the ray origins of a
parallel view (`parc_reference.caster_rays`) -- and boxes placed by hand
for the cavity tests.
"""
from types import SimpleNamespace

import numpy as np
import pytest

from data_tools import Volume
from parc import origins
from parc.camera import Camera
from parc.ranges import supercell_grid
from parc.proxy import build_proxy
from parc_reference import caster_rays, reached

#: Random grids' shapes (supercells along z, y, x): unequal, so that one axis taken for
#: another shows.
SHAPES = [(3, 5, 4), (5, 3, 6), (6, 4, 3)]


def _grid_proxy(pc, *, seed=0):
    """A proxy of the PC grid ``pc`` ([z, y, x]), its supercell boundaries unevenly spaced."""
    rng = np.random.default_rng(seed)
    nz, ny, nx = pc.shape
    grid = supercell_grid((nx + 1, ny + 1, nz + 1), 1)
    vol = Volume(np.zeros((nz + 1, ny + 1, nx + 1), np.float32),
                 spacing=tuple(rng.uniform(0.5, 2.0, 3)), origin=tuple(rng.uniform(-5.0, 5.0, 3)))
    proxy = build_proxy(grid, pc, grid.world_edges(vol))
    # Boundaries at uneven steps: the same boxes in index space, no two gaps alike.
    edges = tuple(np.cumsum(np.concatenate([[e[0]], rng.uniform(0.3, 3.0, len(e) - 1)])) for e in proxy.world_edges)
    return build_proxy(grid, pc, edges)


def _random_pc(shape, seed, fill=0.35):
    return np.random.default_rng(seed).random(shape) < fill


def _boxes(proxy, mask):
    ex, ey, ez = proxy.world_edges
    kz, ky, kx = np.nonzero(mask)
    return np.stack([ex[kx], ey[ky], ez[kz]], axis=1), np.stack([ex[kx + 1], ey[ky + 1], ez[kz + 1]], axis=1)



@pytest.mark.parametrize("axes", [(0, 1, 2), (1, 2, 0), (2, 0, 1)], ids=str)
def test_the_fill_passes_through_single_edges_and_corners(axes):
    """Empty cells in a chain whose links are each one edge or one corner, along every pair of axes."""
    chain = [(0, 0, 0), (1, 1, 0), (2, 1, 1), (3, 2, 2), (3, 3, 3), (2, 4, 4), (2, 5, 3), (1, 6, 2)]
    empty = np.zeros((4, 7, 5), bool)
    for c in chain:
        empty[c] = True
    empty[3, 0, 4] = empty[0, 6, 0] = True       # two cells on their own
    empty = empty.transpose(axes).copy()
    want = empty.copy()
    want[tuple(np.array([(3, 0, 4), (0, 6, 0)]).T[list(axes)])] = False
    assert want.sum() == len(chain)
    np.testing.assert_array_equal(origins.flood_from_corner(empty), want)
    np.testing.assert_array_equal(reached(empty), want)


@pytest.mark.parametrize("shape", SHAPES, ids=str)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_distance_to_pc_is_the_distance_to_the_nearest_pc_box(shape, seed):
    pc = _random_pc(shape, seed, fill=0.15)
    proxy = _grid_proxy(pc, seed=seed)
    lo, hi = _boxes(proxy, pc)
    blo, bhi = proxy.bounds
    rng = np.random.default_rng(100 + seed)
    points = [blo + rng.uniform(-0.3, 1.3, 3) * (bhi - blo) for _ in range(150)]
    # On box faces, edges and corners too, where the distance is exactly 0.
    points += [np.where(rng.random(3) < 0.5, lo[b], hi[b]) for b in rng.integers(len(lo), size=20)]
    for p in points:
        gap = np.maximum(np.maximum(lo - p, 0.0), p - hi)
        want = float(np.sqrt((gap * gap).sum(axis=1)).min())
        assert origins.distance_to_pc(p, proxy) == pytest.approx(want, rel=1e-12, abs=1e-12), p


def test_distance_to_pc_of_no_pc_box_is_infinite():
    proxy = SimpleNamespace(pc=np.zeros((2, 3, 4), bool), world_edges=(np.arange(5.0), np.arange(4.0), np.arange(3.0)))
    assert origins.distance_to_pc((1.0, 1.0, 1.0), proxy) == np.inf


def _walled_pc(shape, seed):
    """PC walls round the grid with one hole, random PC supercells within: cavities of many shapes
    beside empty supercells open to the outside through the hole."""
    rng = np.random.default_rng(seed)
    pc = rng.random(shape) < 0.75
    pc[[0, -1]] = pc[:, [0, -1]] = pc[:, :, [0, -1]] = True
    pc[rng.integers(1, shape[0] - 1), rng.integers(1, shape[1] - 1), 0] = False
    return pc


@pytest.mark.parametrize("shape, seed", [((8, 6, 9), 1), ((8, 6, 9), 2), ((8, 6, 9), 3), ((9, 7, 6), 2)], ids=str)
def test_open_faces_of_random_grids(shape, seed):
    pc = _walled_pc(shape, seed)
    proxy = _grid_proxy(pc, seed=seed)
    is_open, cavity = origins.open_faces(proxy)
    empty = ~np.pad(pc, 1)
    ref = (empty & ~reached(empty))[1:-1, 1:-1, 1:-1]
    assert ref.sum() >= 3 and (~pc & ~ref).sum() >= 3
    np.testing.assert_array_equal(cavity, ref)
    # Unit face by unit face: open where its empty supercell (or the outside) is not a cavity.
    want = np.zeros(len(proxy.faces), bool)
    for q, (a, plane, u0, u1, v0, v1) in enumerate(proxy.faces):
        side = plane if proxy.outward[q] > 0 else plane - 1
        for uu in range(u0, u1):
            for vv in range(v0, v1):
                xyz = [0, 0, 0]
                xyz[a], xyz[(a + 1) % 3], xyz[(a + 2) % 3] = side, uu, vv
                k = (xyz[2], xyz[1], xyz[0])
                want[q] |= not all(0 <= c < n for c, n in zip(k, pc.shape)) or not ref[k]
    np.testing.assert_array_equal(is_open, want)
    assert 0 < want.sum() < len(want)


def _one_cavity():
    """A 3x3x3 block of PC supercells round one empty one, in unit boxes from 0 to 3."""
    pc = np.ones((3, 3, 3), bool)
    pc[1, 1, 1] = False
    edges = (np.arange(4.0), np.arange(4.0), np.arange(4.0))
    return SimpleNamespace(cavity_lo=np.array([[1.0, 1.0, 1.0]]), cavity_hi=np.array([[2.0, 2.0, 2.0]]),
                           pc=pc, world_edges=edges)


@pytest.mark.parametrize("eye, inside", [
    ((1.5, 1.5, 1.5), True), ((1.0, 1.5, 1.5), True), ((2.0, 2.0, 2.0), True), ((1.0, 2.0, 1.5), True),
    ((0.999, 1.5, 1.5), False), ((1.5, 2.001, 1.5), False), ((2.5, 2.5, 2.5), False),
    # A rounding outside: the caster's eye, in index space, may lie on the box.
    ((1.5, 1.5, float(np.nextafter(2.0, 3.0))), True), ((float(np.nextafter(1.0, 0.0)), 1.5, 1.5), True)])
def test_a_perspective_eye_on_a_cavity_box_is_in_it(eye, inside):
    up = _one_cavity()
    cam = Camera(eye=eye, look_at=(5.0, 7.0, 3.0), up=(0, 0, 1), fov=60.0)
    assert origins.in_cavity(up, cam, 16, 16, np.asarray(eye)) == inside


@pytest.mark.parametrize("offset, inside", [(0.0, True), (0.8, True), (-0.8, True), (0.9, False), (-0.9, False)])
def test_a_parallel_view_plane_through_any_part_of_a_cavity_box_meets_it(offset, inside):
    # f = (1, -2, 2) / 3: the unit box [1, 2]^3 reaches 5/6 along f either side of its centre.
    f = np.array([1.0, -2.0, 2.0]) / 3.0
    eye = np.array([1.5, 1.5, 1.5]) + offset * f
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + f), up=(0, 0, 1), parallel_scale=4.0)
    assert origins.in_cavity(_one_cavity(), cam, 16, 16, eye) == inside


def test_no_cavity_box_no_cavity():
    up = SimpleNamespace(cavity_lo=np.empty((0, 3)), cavity_hi=np.empty((0, 3)))
    for cam in (Camera(eye=(1.5, 1.5, 1.5), look_at=(3, 4, 5), fov=60.0),
                Camera(eye=(1.5, 1.5, 1.5), look_at=(3, 4, 5), parallel_scale=2.0)):
        assert not origins.in_cavity(up, cam, 8, 8, np.array([1.5, 1.5, 1.5]))


def _parallel_inside_reference(cam, width, height, proxy, far):
    """``(inside, outside)``: pixels whose ray origin lies in or on a PC box, and those farther than
    ``far`` from every one."""
    o = caster_rays(cam, width, height)[0].reshape(-1, 1, 3)
    lo, hi = _boxes(proxy, proxy.pc)
    gap = np.maximum(np.maximum(lo - o, 0.0), o - hi)
    dist = np.sqrt((gap * gap).sum(axis=-1)).min(axis=1).reshape(height, width)
    return dist == 0.0, dist > far


@pytest.mark.parametrize("shape", SHAPES, ids=str)
@pytest.mark.parametrize("seed", [0, 1])
def test_parallel_ray_origins_inside_pc_boxes(shape, seed):
    pc = _random_pc(shape, seed)
    proxy = _grid_proxy(pc, seed=seed)
    lo, hi = proxy.bounds
    rng = np.random.default_rng(seed)
    f = rng.normal(size=3)
    eye = lo + rng.uniform(0.3, 0.7, 3) * (hi - lo)
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + f), up=(0.2, 0.3, 1.0),
                 parallel_scale=0.6 * float(np.linalg.norm(hi - lo)))
    got = origins.parallel_inside(cam, 37, 29, proxy)
    inside, outside = _parallel_inside_reference(cam, 37, 29, proxy, 1e-9)
    assert inside.sum() > 20 and outside.sum() > 20
    assert got[inside].all() and not got[outside].any()


def _parallel_inside_numpy(cam, width, height, proxy):
    """`origins.parallel_inside` by NumPy's searchsorted over every pixel at once: origins in a box
    grown by `origins.origin_slab`, each axis's first and last such box, any PC box between."""
    lo, hi = proxy.bounds
    eye = np.asarray(cam.eye, dtype=np.float64)
    slab = origins.origin_slab(cam, width, height, eye, lo, hi)
    o = caster_rays(cam, width, height)[0].reshape(-1, 3)
    ranges = []
    for axis, e in enumerate(proxy.world_edges):
        n = len(e) - 1
        ranges.append((np.clip(np.searchsorted(e, o[:, axis] - slab, "left") - 1, 0, n - 1),
                       np.clip(np.searchsorted(e, o[:, axis] + slab, "right") - 1, 0, n - 1)))
    (x0, x1), (y0, y1), (z0, z1) = ranges
    hit = np.array([proxy.pc[z0[p]:z1[p] + 1, y0[p]:y1[p] + 1, x0[p]:x1[p] + 1].any() for p in range(len(o))])
    near = np.all((o >= lo - slab) & (o <= hi + slab), axis=1)
    return (hit & near).reshape(height, width)


@pytest.mark.parametrize("seed", range(6))
def test_parallel_ray_origins_next_to_pc_boxes_by_the_slab(seed):
    """Pixel for pixel the NumPy rule, the slab's band included, on views whose plane lies on grid
    planes (origins on faces and edges) and in volumes far from the origin (a wide slab)."""
    rng = np.random.default_rng(seed)
    pc = _random_pc((4, 5, 6), seed, fill=0.3)
    nz, ny, nx = pc.shape
    grid = supercell_grid((nx + 1, ny + 1, nz + 1), 1)
    far = (2.0 ** 30 if seed % 2 else 0.0) * np.ones(3)
    vol = Volume(np.zeros((nz + 1, ny + 1, nx + 1), np.float32), origin=tuple(far))
    proxy = build_proxy(grid, pc, grid.world_edges(vol))
    axis = seed % 3
    f = np.zeros(3)
    f[axis] = 1.0 if seed < 3 else -1.0
    if seed >= 4:
        f = f + rng.normal(scale=0.2, size=3)      # a slanted view plane
    up = np.zeros(3)
    up[(axis + 1) % 3] = 1.0
    eye = far + np.array([3.125, 2.625, 2.125])
    eye[axis] = far[axis] + 2.0
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + f), up=tuple(up), parallel_scale=4.0)
    got = origins.parallel_inside(cam, 32, 32, proxy)
    want = _parallel_inside_numpy(cam, 32, 32, proxy)
    assert want.any() and not want.all()
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("plane", ["within", "on the volume's face"])
@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_parallel_ray_origins_on_supercell_boundaries(axis, side, plane):
    """A view plane on a grid plane, with some origins on grid lines across it: an origin on a PC
    box's face, edge or corner starts inside, whichever box it is counted in, and so does one on
    the volume's own face, the volume all ahead of the view plane."""
    pc = _random_pc((4, 5, 6), 7, fill=0.3)
    nz, ny, nx = pc.shape
    grid = supercell_grid((nx + 1, ny + 1, nz + 1), 1)
    proxy = build_proxy(grid, pc, grid.world_edges(Volume(np.zeros((nz + 1, ny + 1, nx + 1), np.float32))))
    f = np.zeros(3)
    f[axis] = side
    up = np.zeros(3)
    up[(axis + 1) % 3] = 1.0
    eye = np.array([3.125, 2.625, 2.125])
    eye[axis] = 2.0 if plane == "within" else (0.0 if side > 0 else (nx, ny, nz)[axis])
    # 4 pixels a unit, centres an eighth off the eye: every fourth one on a grid line.
    cam = Camera(eye=tuple(eye), look_at=tuple(eye + f), up=tuple(up), parallel_scale=4.0)
    got = origins.parallel_inside(cam, 32, 32, proxy)
    inside, outside = _parallel_inside_reference(cam, 32, 32, proxy, 1e-9)
    o = caster_rays(cam, 32, 32)[0]
    on_lines = (np.abs(o - np.round(o)) == 0).sum(axis=-1) >= 2
    assert (inside & on_lines).sum() > 10 and outside.sum() > 10
    assert got[inside].all() and not got[outside].any()
