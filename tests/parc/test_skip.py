"""Jumps across empty cells inside ray segments (`raycast.iso`): bit for bit the full walk.

Source of truth: the same caster without a skip table (`NO_SKIP`), which
the hard-ray suite checks against mpmath roots. Tables are built here
directly from the samples of each cell (independent of
`parc.classify.sign_iso`, which `test_sign_iso_*` checks against this one)
and their cube radii by repeated erosion (independent of
`parc.skip.skip_radius`'s separable scans). A jump minimum of 0 or 1
makes nearly every empty cell a jump, landing on the cube's exit faces,
edges and corners; larger ones leave signed cells the walk steps on the
table's sign alone; a small cap cuts the cubes short. Tables by ray
octant (boxes ahead of the cell instead of cubes around it) are built
here by directional erosion, independent of `parc.skip.octant_radius`'s
separable scans, and walked by rays of every direction.
"""
import zlib

import numpy as np
import pytest

from data_tools.synthetic import blobs
from parc.classify import VolumeIndex, sign_iso
from parc.ranges import cell_minmax
from parc.skip import SKIP_CAP, octant_radius, octant_steps, skip_radius
from raycast.hardcases import CATEGORIES, cast, hard_batches
from raycast.hardrays import random_dirs
from raycast.iso import OCTANTS

SHIFTS = (0, 1, 2, 3)
#: (jump minimum, cap) pairs the walks are checked with.
SKIPS = ((0, SKIP_CAP), (1, SKIP_CAP), (2, SKIP_CAP), (4, SKIP_CAP), (1, 3))


def noise(shape, dtype, seed):
    """Smoothed random samples ``(nz, ny, nx)`` in ``dtype``: surfaces in many small pieces."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=shape)
    a = (a + np.roll(a, 1, 0) + np.roll(a, 1, 1) + np.roll(a, 1, 2)) / 4
    if np.dtype(dtype).kind == "f":
        return a.astype(dtype)
    info = np.iinfo(dtype)
    a = (a - a.min()) / (a.max() - a.min())
    return (info.min + a * (float(info.max) - info.min)).astype(dtype)


def block_table(data, iso, shift):
    """+1 / -1 / 0 per block of ``2**shift`` cells: whether every sample of the block
    (its cells' corners) lies above or below ``iso``, as ``float(sample) - iso``."""
    v = data.astype(np.float64) - iso
    b = 1 << shift

    def every_block(a):
        cells = np.ones(tuple(n - 1 for n in a.shape), bool)
        for dz in (0, 1):
            for dy in (0, 1):
                for dx in (0, 1):
                    cells &= a[dz:dz + cells.shape[0], dy:dy + cells.shape[1], dx:dx + cells.shape[2]]
        pad = [(0, -n % b) for n in cells.shape]
        cells = np.pad(cells, pad, constant_values=True)
        cz, cy, cx = (n // b for n in cells.shape)
        return cells.reshape(cz, b, cy, b, cx, b).all(axis=(1, 3, 5))

    return every_block(v > 0).astype(np.int8) - every_block(v < 0).astype(np.int8)


def erode(mask):
    """Cells whose 3x3x3 neighbourhood (outside the grid counting True) is all True."""
    out = mask.copy()
    for axis in range(3):
        p = np.pad(out, [(1, 1) if a == axis else (0, 0) for a in range(3)], constant_values=True)
        n = out.shape[axis]
        out = (p.take(range(0, n), axis) & p.take(range(1, n + 1), axis) & p.take(range(2, n + 2), axis))
    return out


def class_depths(classes, cap, shrink):
    """``c * min(cap, 1 + n)`` per cell of class ``c != 0``, with ``n`` how many times
    ``shrink`` keeps it in the mask of its class; 0 where ``c == 0``."""
    out = np.zeros(classes.shape, np.int64)
    for c in np.unique(classes):
        if c == 0:
            continue
        mask = classes == c
        depth = mask.astype(np.int64)
        for _ in range(cap - 1):
            mask = shrink(mask)
            depth += mask
        out += c * depth * (classes == c)
    return out.astype(np.int8)


def radius_table(classes, cap):
    """``c * min(cap, 1 + r)`` with ``r`` the largest cube radius around a cell of class ``c != 0``
    holding only class ``c`` (outside the grid counts as any class); 0 where ``c == 0``."""
    return class_depths(classes, cap, erode)


def octant_reference(classes, octant, cap):
    """``c * min(cap, q)`` with ``q`` the largest side of a box of class ``c`` starting at the
    cell and growing the way ``octant`` steps (outside the grid counting as any class)."""
    steps = octant_steps(octant)

    def shrink_ahead(mask):
        # A box of side q + 1 at a cell: boxes of side q at it and its 7 neighbours ahead.
        grown = mask.copy()
        for d in range(1, 8):
            shifted = mask
            for axis, bit in ((2, 1), (1, 2), (0, 4)):
                if d & bit:
                    step = steps[2 - axis]
                    n = shifted.shape[axis]
                    pad = np.pad(shifted, [(1, 1) if a == axis else (0, 0) for a in range(3)],
                                 constant_values=True)
                    shifted = pad.take(range(1 + step, n + 1 + step), axis)
            grown &= shifted
        return grown

    return class_depths(classes, cap, shrink_ahead)


def octant_tables(data, iso, cap=SKIP_CAP):
    """The walk's skip tables by ray octant, ``(8, nz, ny, nx)``."""
    classes = block_table(data, iso, 0)
    return np.stack([octant_reference(classes, o, cap) for o in range(OCTANTS)])


def sign_table(data, iso, cap=SKIP_CAP):
    """The walk's per-cell skip table: the cell's sign times one plus its cube radius."""
    return radius_table(block_table(data, iso, 0), cap)


def skip_tables(data, iso):
    """Per cap of `SKIPS`: the centred table and the tables by octant."""
    return {cap: (sign_table(data, iso, cap), octant_tables(data, iso, cap)) for cap in {c for _, c in SKIPS}}


def same_hits(a, b):
    t0, c0, u0, _ = a
    t1, c1, u1, _ = b
    hit = np.isfinite(t0)
    return (np.array_equal(t0, t1) and np.array_equal(c0[hit], c1[hit])
            and np.array_equal(u0[hit], u1[hit]))


def random_segments(rng, n, span):
    """Random ``[near, far]`` per ray, some empty, some unbounded, some of zero length."""
    a, b = np.sort(rng.uniform(-0.2 * span, 1.2 * span, (2, n)), axis=0)
    seg = np.stack([a, b], axis=1)
    kind = rng.integers(0, 5, n)
    seg[kind == 0] = (-np.inf, np.inf)
    seg[kind == 1, 1] = seg[kind == 1, 0]
    seg[kind == 2] = seg[kind == 2][:, ::-1]
    return seg


@pytest.mark.parametrize("category", list(CATEGORIES))
def test_hard_rays_same_with_skip_tables(category):
    """The hard-ray suite (1,500 rays per category), whole rays and random segments."""
    rng = np.random.default_rng(7)
    jumps = 0
    for batch in hard_batches(category, 1500, seed=3):
        sc = batch.scene
        for iso in np.unique(batch.isos):
            m = batch.isos == iso
            o, d = batch.origins[m], batch.dirs[m]
            span = float(np.linalg.norm(sc.hi_world - sc.lo_world)) + 50.0
            tables = skip_tables(sc.data, iso)
            for seg in (None, random_segments(rng, len(o), span)):
                ref = cast(sc, o, d, iso, seg)
                for jump_min, cap in SKIPS:
                    for table in tables[cap]:
                        got = cast(sc, o, d, iso, seg, skip=(table, jump_min))
                        assert same_hits(ref, got), (category, sc.name, iso, jump_min, cap, table.ndim)
                        assert np.array_equal(ref[3][:, 1], got[3][:, 1])      # the same cubics solved
                        jumps += int((got[3][:, 0] < ref[3][:, 0]).sum())
    if category not in ("grazing", "near-double", "face-edge-vertex", "iso-sample"):
        assert jumps > 0       # the tables did skip cells


class _Grid:
    """What `raycast.hardcases.cast` needs of a scene: samples, origin, spacing."""

    def __init__(self, data, origin, spacing):
        self.data = data
        self.origin = np.asarray(origin, np.float64)
        self.spacing = np.asarray(spacing, np.float64)


def _volumes():
    rng = np.random.default_rng(11)
    yield "blobs-uint8", blobs((17, 19, 23), count=4, seed=5).data, (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)
    yield "noise-int16", noise((18, 21, 13), np.int16, 2), (-3.0, 1.5, 2.0), (0.7, 1.3, 2.1)
    smooth = np.cumsum(np.cumsum(rng.normal(size=(15, 16, 20)), axis=2), axis=1).astype(np.float32)
    yield "smooth-float32", smooth, (1.0, -2.0, 0.5), (1.0, 1.0, 1.0)


@pytest.mark.parametrize("name,data,origin,spacing", list(_volumes()), ids=lambda v: v if isinstance(v, str) else "")
def test_random_volumes_same_with_skip_tables(name, data, origin, spacing):
    """Eyes outside and inside, axis-aligned rays on grid planes and edges, random isovalues."""
    rng = np.random.default_rng(zlib.crc32(name.encode()))   # not hash(): salted per process
    sc = _Grid(data, origin, spacing)
    nz, ny, nx = data.shape
    hi = sc.origin + sc.spacing * np.array([nx - 1, ny - 1, nz - 1])
    n = 3000
    centre = (sc.origin + hi) / 2
    eyes = np.concatenate([centre + rng.normal(size=(n // 2, 3)) * 40.0,
                           rng.uniform(sc.origin, hi, (n - n // 2, 3))])
    dirs = random_dirs(rng, n)
    aim = rng.uniform(sc.origin, hi, (n, 3))
    outside = np.arange(n) < n // 2
    dirs[outside] = aim[outside] - eyes[outside]
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    # A fifth of the rays along an axis, through sample planes and edges.
    ax = rng.integers(0, 3, n)
    lattice = rng.random(n) < 0.2
    for m in np.flatnonzero(lattice):
        dirs[m] = 0.0
        dirs[m, ax[m]] = rng.choice((-1.0, 1.0))
        idx = rng.integers(0, (nx, ny, nz))
        eyes[m] = np.where(np.arange(3) == ax[m], eyes[m], sc.origin + idx * sc.spacing)
    lo, hi_v = float(data.min()), float(data.max())
    # A sample value, three anywhere, and one near the bottom of the range, where cubes of
    # cells all on one side are wide enough to jump (noise has few elsewhere).
    isos = ([float(data.flat[rng.integers(data.size)])] + list(rng.uniform(lo, hi_v, 3))
            + [float(np.quantile(data, 0.02))])
    skipped = 0
    for iso in isos:
        seg = random_segments(rng, n, float(np.linalg.norm(hi - sc.origin)) + 80.0)
        tables = skip_tables(data, iso)
        for s in (None, seg):
            ref = cast(sc, eyes, dirs, iso, s)
            for jump_min, cap in SKIPS:
                for table in tables[cap]:
                    got = cast(sc, eyes, dirs, iso, s, skip=(table, jump_min))
                    assert same_hits(ref, got), (name, iso, jump_min, cap, table.ndim)
                    skipped += int(ref[3][:, 0].sum() - got[3][:, 0].sum())
    assert skipped > 0


def test_a_wrong_table_is_caught():
    """Sanity of the comparison: a table that calls surface cells empty loses hits."""
    data = blobs(20, count=3, seed=1).data
    sc = _Grid(data, (0, 0, 0), (1, 1, 1))
    rng = np.random.default_rng(0)
    eyes = np.array([9.5, 9.5, -30.0]) + rng.normal(size=(500, 3)) * 2
    dirs = np.tile([0.0, 0.0, 1.0], (500, 1))
    iso = float(np.percentile(data, 90))
    table = sign_table(data, iso)
    ref = cast(sc, eyes, dirs, iso)
    assert np.isfinite(ref[0]).any()
    wrong = np.where(table == 0, np.int8(-1), table)
    got = cast(sc, eyes, dirs, iso, skip=(wrong, 1))
    assert not same_hits(ref, got)


@pytest.mark.parametrize("shift", SHIFTS)
def test_sign_iso_matches_block_samples(shift):
    rng = np.random.default_rng(shift)
    for dtype in (np.uint8, np.int16, np.float32):
        data = noise((13, 10, 9), dtype, shift)
        mn, mx = cell_minmax(data)
        b = 1 << shift
        for iso in [float(data.flat[rng.integers(data.size)]), float(rng.uniform(data.min(), data.max()))]:
            if b == 1:
                got = sign_iso(mn, mx, iso)
            else:
                from parc.ranges import supercell_grid, supercell_ranges
                grid = supercell_grid(data.shape[::-1], (b, b, b))
                got = sign_iso(*supercell_ranges(data, grid, cell_ranges=(mn, mx)), iso)
            assert np.array_equal(got, block_table(data, iso, shift))


def test_volume_index_skip_tables_follow_the_isovalue():
    vol = blobs((24, 26, 28), count=3, seed=4)
    index = VolumeIndex.of(vol)
    seen = set()
    for iso in (3.5, 40.0, 90.5, 200.0):
        table, jump_min = index.iso_skip(iso)
        assert jump_min >= 0
        assert np.array_equal(table, sign_table(vol.data, iso))
        seen.update(np.sign(np.unique(table)).tolist())
        assert index.iso_skip(iso)[0] is table            # kept for the next frame
    assert seen == {-1, 0, 1}


@pytest.mark.parametrize("cap", [1, 2, 5, 16, 127])
def test_skip_radius_matches_repeated_erosion(cap):
    rng = np.random.default_rng(cap)
    for shape, p_zero in (((9, 11, 13), 0.05), ((20, 7, 31), 0.002), ((1, 1, 40), 0.1), ((6, 30, 2), 0.0),
                          ((3, 4, 205), 0.01)):       # rows of whole vectors and a remainder
        classes = rng.choice(np.array([-1, 1], np.int8), size=shape)
        # Runs and slabs of one class, so that radii grow past a few cells.
        classes[:, :shape[1] // 2] = 1
        classes[rng.random(shape) < p_zero] = 0
        got = skip_radius(classes, cap)
        assert got.dtype == np.int8
        assert np.array_equal(got, radius_table(classes, cap))
        assert (np.abs(got) <= cap).all()
    with pytest.raises(ValueError):
        skip_radius(classes, 128)


@pytest.mark.parametrize("cap", [1, 2, 5, 16, 127])
def test_octant_radius_matches_directional_erosion(cap):
    rng = np.random.default_rng(100 + cap)
    for shape, p_zero in (((9, 11, 13), 0.05), ((20, 7, 31), 0.002), ((1, 1, 40), 0.1), ((6, 30, 2), 0.0),
                          ((3, 4, 205), 0.01)):       # rows of whole vectors and a remainder
        classes = rng.choice(np.array([-1, 1], np.int8), size=shape)
        classes[:, :shape[1] // 2] = 1
        classes[rng.random(shape) < p_zero] = 0
        for o in range(OCTANTS):
            got = np.full(shape, 99, np.int8)
            octant_radius(classes, o, cap, got)
            assert np.array_equal(got, octant_reference(classes, o, cap)), (shape, o)
    with pytest.raises(ValueError):
        octant_radius(classes, 0, 128, got)


def test_octant_boxes_reach_past_centred_cubes():
    """A box ahead is never smaller than the cube around the cell, and near a wall it is larger."""
    classes = np.ones((12, 12, 12), np.int8)
    classes[:, :, 0] = -1                    # a wall of the other class at x = 0
    centred = skip_radius(classes, 8)
    away = np.empty_like(classes)
    octant_radius(classes, 0, 8, away)       # rays stepping +x, away from the wall
    towards = np.empty_like(classes)
    octant_radius(classes, 1, 8, towards)    # stepping -x, towards it
    assert (np.abs(away) >= np.abs(centred)).all() and (np.abs(towards) >= np.abs(centred)).all()
    assert away[6, 6, 1] == 8 and centred[6, 6, 1] == 1 and towards[6, 6, 1] == 1


def test_volume_index_octant_tables_follow_the_isovalue():
    vol = blobs((24, 26, 28), count=3, seed=4)
    index = VolumeIndex.of(vol)
    for iso in (3.5, 90.5):
        index.expect_frames(iso)
        tables, jump_min = index.iso_octant_skip(iso, [2, 5])
        assert jump_min >= 0 and tables.shape == (OCTANTS,) + tuple(n - 1 for n in vol.data.shape)
        want = octant_tables(vol.data, iso)
        for o in range(OCTANTS):
            # Octants not asked for hold 0, "may contribute": exact, only slower.
            assert np.array_equal(tables[o], want[o] if o in (2, 5) else 0 * want[o]), (iso, o)
        again, _ = index.iso_octant_skip(iso, [7])
        assert again is tables and np.array_equal(tables[7], want[7])     # kept, and grown


@pytest.mark.parametrize("parallel", [False, True])
def test_ray_octants_cover_every_pixel(parallel):
    """`parc.skip.ray_octants` names the octant of every camera ray it is asked about."""
    from parc.camera import Camera
    from parc.skip import ray_octants
    from raycast.iso import octant
    from raycast.rays import camera_ray
    rng = np.random.default_rng(int(parallel))
    for _ in range(20):
        eye = rng.normal(size=3) * 30
        look = rng.normal(size=3) * 5
        if rng.random() < 0.3:
            look = eye.copy()
            look[rng.integers(3)] += 10.0           # axis-aligned views: components exactly 0
        fwd = np.abs(look - eye) / np.linalg.norm(look - eye)
        up = (0.0, 0.0, 1.0) if fwd[2] < 0.9 else (0.0, 1.0, 0.0)
        cam = Camera(eye=tuple(eye), look_at=tuple(look), up=up, fov=float(rng.uniform(10, 120)),
                     parallel_scale=5.0 if parallel else None)
        w, h = (int(v) for v in rng.integers(3, 40, 2))
        arr = cam.as_array()
        seen = {octant(*camera_ray(arr, w, h, x, y)[3:]) for x in range(w) for y in range(h)}
        assert seen <= set(ray_octants(cam, w, h)), (eye, look)
        # ... and no more than the signs each axis takes over the image allow: an octant named
        # needlessly costs a table built for no ray.
        bits = [{o & (1 << a) for o in seen} for a in range(3)]
        assert set(ray_octants(cam, w, h)) == {x | y | z for x in bits[0] for y in bits[1] for z in bits[2]}


def test_a_segment_start_takes_the_sign_of_the_cell_before_from_the_table():
    """The table's sign is the one a cell hands on, also to a walk that starts in the next cell.

    Samples ``x - 2.5`` along x: a ray along +x has its root at x = 2.5, in cell 2. A table
    calling cell 1 (all below) above the isovalue makes the walk hand cell 2 a sign it does
    not start with, so cell 2 is hit at its entry, x = 2 (`raycast.iso.cast_iso_ray`'s
    entry-sign rule). A walk started inside cell 2 must take that sign from the table too
    (`raycast.iso._entry_sign`), or a segment start would change the hit.
    """
    x = np.arange(6, dtype=np.float64)
    data = np.broadcast_to(x - 2.5, (3, 3, 6)).copy()
    sc = _Grid(data, (0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    eyes = np.array([[-3.0, 0.5, 0.5], [-3.0, 1.25, 0.75], [-3.0, 2.0, 1.0]])
    dirs = np.tile([1.0, 0.0, 0.0], (len(eyes), 1))
    table = sign_table(data, 0.0, cap=1)
    assert (table[:, :, 1] == -1).all() and (table[:, :, 2] == 0).all()
    lying = table.copy()
    lying[:, :, 1] = 1
    for seg in (None, np.tile([0.0, np.inf], (3, 1)), np.tile([5.2, np.inf], (3, 1)), np.tile([5.5, 7.0], (3, 1))):
        for tab, want_x in ((table, 2.5), (lying, 2.0)):
            for jump_min in (0, 1):
                t, cell, uvw, _ = cast(sc, eyes, dirs, 0.0, seg, skip=(tab, jump_min))
                assert np.array_equal(t, np.full(3, want_x + 3.0)), (seg, want_x, jump_min)
                assert (cell[:, 0] == 2).all() and np.array_equal(uvw[:, 0], np.full(3, want_x - 2.0))


@pytest.mark.parametrize("by_octant", [False, True], ids=["centred", "octant"])
def test_a_cube_holding_the_whole_grid_is_left_at_once_every_way(by_octant):
    """Samples all above the isovalue, and a table giving every cell a cube of radius 126, more
    than the grid: the cube's exit lies past the ray's exit from the grid, whichever way the
    ray goes, so the walk looks at its first cell alone and misses."""
    data = np.ones((6, 7, 8))
    sc = _Grid(data, (0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    rng = np.random.default_rng(5)
    n = 400
    eyes = rng.uniform(0.1, [6.9, 5.9, 4.9], (n, 3))
    dirs = random_dirs(rng, n)
    table = np.full((OCTANTS, 5, 6, 7) if by_octant else (5, 6, 7), 127, np.int8)
    t, _, _, counts = cast(sc, eyes, dirs, 0.0, skip=(table, 1))
    assert np.all(np.isinf(t))
    assert np.all(counts[:, 0] == 1), np.unique(np.sign(dirs[counts[:, 0] != 1]), axis=0)


@pytest.mark.parametrize("axis", [0, 1, 2], ids=["x", "y", "z"])
@pytest.mark.parametrize("step", [1, -1])
def test_a_jump_passes_over_its_whole_cube(axis, step):
    """Ten samples along one axis, all above the isovalue, each cell a cube of radius 2, the
    smallest worth a jump: a ray along that axis looks at cell 0, jumps to the exit of cell 2
    (the cube's far face) and steps on into cell 3, looks at it, jumps to the exit of cell 5,
    steps into cell 6, and from there the cube's exit lies on the grid's last face, where it
    ends. Three cells of nine, the same walking backwards."""
    shape = [3, 3, 3]
    shape[2 - axis] = 10
    data = np.ones(shape)
    sc = _Grid(data, (0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    eye = np.full(3, 0.5)
    eye[axis] = -2.0 if step > 0 else 11.0
    d = np.zeros(3)
    d[axis] = step
    table = np.full([n - 1 for n in shape], 3, np.int8)
    t, _, _, counts = cast(sc, eye[None], d[None], 0.0, skip=(table, 2))
    assert np.isinf(t[0]) and counts[0, 0] == 3, counts


def _octant_tables_kept(vis):
    return ("iso octants", float(vis.value)) in VolumeIndex.of(vis.volume).kept("skip tables")


def test_an_isovalue_s_first_frame_walks_without_octant_tables_and_finds_the_same_hits(gl):
    from parc import Camera, Isosurface, Scene, render
    vol = blobs((30, 28, 26), count=4, seed=21)
    vis = Isosurface(vol, 90.5)
    scene = Scene(camera=Camera.framing(*vol.bounds, azimuth=35.0, elevation=20.0), size=(48, 40), volumes=[vis])
    first = render(scene, "parc")
    assert not _octant_tables_kept(vis)
    second = render(scene, "parc")
    assert _octant_tables_kept(vis)
    brute = render(scene, "brute")
    for run in (first, second):
        assert np.array_equal(run.image, brute.image) and np.array_equal(run.depth, brute.depth)
    # The tables let the second frame step over cells the first read.
    assert second.stats["cells_visited"] < first.stats["cells_visited"]
    # Another isovalue is a first frame again.
    assert not _octant_tables_kept(Isosurface(vol, 120.5))


@pytest.mark.parametrize("warmup", [0, 1])
def test_compare_times_frames_with_the_octant_tables_from_its_first(gl, warmup):
    from parc import Camera, Isosurface, Scene, compare, render
    vol = blobs((30, 28, 26), count=4, seed=22)
    scene = Scene(camera=Camera.framing(*vol.bounds, azimuth=35.0, elevation=20.0), size=(48, 40),
                  volumes=[Isosurface(vol, 90.5)])
    row = compare(scene, repeats=1, warmup=warmup)[1]
    later = render(scene, "parc")
    assert row["method"] == "parc" and row["cells_visited"] == later.stats["cells_visited"]


def test_sign_iso_and_classify_iso_over_several_chunks_of_boxes():
    # Counts either side of whole chunks of boxes, which threads take one at a time.
    from parc.classify import classify_iso
    from raycast.config import RANGE_CHUNK
    rng = np.random.default_rng(3)
    for n in (RANGE_CHUNK - 1, RANGE_CHUNK, RANGE_CHUNK + 1, 3 * RANGE_CHUNK + 7):
        mn = rng.integers(-100, 100, n).astype(np.int16)
        mx = mn + rng.integers(0, 50, n).astype(np.int16)
        for iso in (0.0, 0.5, float(mn[-1]), float(mx[-1]) + 0.5, float(mn[0]) - 0.5):
            want = (mn.astype(np.float64) > iso).astype(np.int8) - (mx.astype(np.float64) < iso).astype(np.int8)
            assert np.array_equal(sign_iso(mn, mx, iso), want), (n, iso)
            pc = (mn.astype(np.float64) <= iso) & (mx.astype(np.float64) >= iso)
            assert np.array_equal(classify_iso(mn, mx, iso), pc), (n, iso)


def test_octant_tables_wait_for_an_isovalue_asked_again_among_the_last_kept():
    from parc.classify import ASKS_KEPT
    from raycast.iso import NO_SKIP_OCTANTS
    vol = blobs((10, 9, 8), count=2, seed=6)

    def built(index, iso):
        return index.iso_octant_skip(iso, [3])[0] is not NO_SKIP_OCTANTS

    # An ask ASKS_KEPT - 1 others ago is remembered: the second frame builds the tables.
    index = VolumeIndex(vol)
    assert not built(index, 50.5)
    for k in range(ASKS_KEPT - 1):
        index.expect_frames(1000.0 + k)
    assert built(index, 50.5)
    # ASKS_KEPT others ago, forgotten: a first frame again.
    index = VolumeIndex(vol)
    assert not built(index, 50.5)
    for k in range(ASKS_KEPT):
        index.expect_frames(1000.0 + k)
    assert not built(index, 50.5)
    # An ask again counts as the latest: the oldest other is forgotten first.
    index = VolumeIndex(vol)
    index.expect_frames(50.5)
    for k in range(ASKS_KEPT - 1):
        index.expect_frames(1000.0 + k)
    index.expect_frames(50.5)
    index.expect_frames(999.0)
    assert built(index, 50.5) and not built(index, 1000.0)
    # Tables kept serve every later frame, however many other isovalues were asked since.
    for k in range(ASKS_KEPT + 1):
        index.expect_frames(2000.0 + k)
    assert built(index, 50.5)


def test_expect_frames_announces_every_isosurface_of_a_scene():
    from parc import Camera, Isosurface, Scene, Translucent
    from parc.skip import expect_frames
    from raycast.iso import NO_SKIP_OCTANTS
    a = blobs((10, 9, 8), count=2, seed=7)
    b = blobs((9, 8, 10), count=2, seed=8)
    isos = [Isosurface(a, 50.5), Isosurface(b, 60.5), Isosurface(a, 70.5)]
    scene = Scene(camera=Camera.framing(*a.bounds), size=(8, 8), volumes=[Translucent(b, "greyscale")] + isos)
    expect_frames(scene)
    for vis in isos:
        tables, _ = VolumeIndex.of(vis.volume).iso_octant_skip(vis.value, [0])
        assert tables is not NO_SKIP_OCTANTS, vis.value
