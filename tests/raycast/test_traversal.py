"""Cell traversal: the caster visits exactly the cells the ray passes through.

Source of truth: `raycast.reference.exact_cell_count` -- the box interval and every
integer-plane crossing time of the ray, in exact rational arithmetic from
the float64 inputs. The caster is run with an isovalue above all data (it
does not validate it), so no cell can hold a root, every cell is walked and
``counts[:, 0]`` is the number of cells visited.

Tolerance: an axis-by-axis walk takes one step per plane crossed, so it must
visit exactly ``1 + (plane crossings inside the box)`` cells. That equals the
number of cells passed with positive length, except where the ray passes
exactly through an edge or vertex (the walk then visits a zero-length cell:
the count exceeds the positive-length count by the number of such
coincidences, checked to happen only on rays built to do so). The only
allowed differences: one cell per crossing within rounding (1e-12 plus the
rounding of the index-space ray) of the box ends, where floating point
decides whether the crossing is inside the box.
"""
import numpy as np
import pytest

from raycast.hardcases import cast, long_scenes
from raycast.hardfields import ANISO, DYADIC, UNIT, random_scene
from raycast.hardrays import (axis_rays, diagonal_vertex_rays, in_plane_rays, near_axis_rays, parallel_rays,
                              perspective_rays, plane_hugging_rays)
from raycast.reference import exact_cell_count

KINDS = ["persp-outside", "persp-inside", "parallel", "axis", "near-axis", "plane-hugging",
         "in-plane", "diag-vertex"]


def scenes():
    rng = np.random.default_rng(11)
    return [random_scene(rng, (6, 7, 9), grid=ANISO, name="aniso"),
            random_scene(rng, (7, 6, 8), grid=DYADIC, name="dyadic"),
            random_scene(rng, (6, 6, 6), np.uint16, grid=UNIT, name="unit")]


def check_counts(scene, o, d, label):
    iso = float(scene.data.max()) + 1e6
    t, _, _, counts = cast(scene, o, d, iso)
    assert np.all(np.isinf(t)) and np.all(counts[:, 1] == 0)
    bad, ties = [], 0
    for m in range(len(o)):
        n_cells, n_steps, uncertain = exact_cell_count(scene, o[m], d[m])
        got = int(counts[m, 0])
        ties += n_steps != n_cells
        if abs(got - n_steps) > uncertain:
            bad.append((label, o[m].tolist(), d[m].tolist(), got, n_cells, n_steps, uncertain))
    return bad, ties


@pytest.mark.parametrize("kind", KINDS)
def test_cells_visited_match_exact_enumeration(kind):
    rng = np.random.default_rng(KINDS.index(kind))
    bad, ties = [], 0
    for scene in scenes():
        if kind == "diag-vertex" and not (np.all(scene.spacing == 1) and np.all(scene.origin == 0)):
            continue
        gen = {
            "persp-outside": lambda: perspective_rays(rng, scene, 400),
            "persp-inside": lambda: perspective_rays(rng, scene, 400, inside=True),
            "parallel": lambda: parallel_rays(rng, scene, 400),
            "axis": lambda: axis_rays(rng, scene, 400),
            "near-axis": lambda: near_axis_rays(rng, scene, 400),
            "plane-hugging": lambda: plane_hugging_rays(rng, scene, 400),
            "in-plane": lambda: in_plane_rays(rng, scene, 400),
            "diag-vertex": lambda: diagonal_vertex_rays(rng, scene, 400),
        }[kind]
        o, d = gen()
        b, t = check_counts(scene, o, d, f"{kind}/{scene.name}")
        bad += b
        ties += t
    assert not bad, f"{len(bad)} rays with a wrong cell count " \
        f"(label, o, d, visited, cells, steps, uncertain), e.g. {bad[:5]}"
    if kind in ("persp-outside", "persp-inside", "parallel"):
        assert ties == 0       # generic rays never pass exactly through an edge
    if kind == "diag-vertex":
        assert ties > 0        # ...and these always do


def test_cells_visited_on_a_long_grid():
    rng = np.random.default_rng(3)
    scene = long_scenes(rng)[0]
    h = scene.hi_world - scene.lo_world
    eyes = scene.lo_world + h * rng.uniform([-0.1, -0.5, -0.5], [1.1, 1.5, 1.5], (60, 3))
    tgt = scene.lo_world + h * rng.uniform(0, 1, (60, 3))
    d = tgt - eyes
    d /= np.linalg.norm(d, axis=1)[:, None]
    o2, d2 = near_axis_rays(rng, scene, 40)
    bad, _ = check_counts(scene, np.concatenate([eyes, o2]), np.concatenate([d, d2]), "long")
    assert not bad, bad[:5]


@pytest.mark.parametrize("seed", range(3))
def test_advance_lands_where_start_index_starts(seed):
    """`advance` (the skip-table jump's landing) stepping a cell on to time ``t``
    gives the cell, entry and exit `start_index` and `axis_state` give at ``t``,
    including times exactly on a crossing and rays along grid planes."""
    from raycast.traverse import advance, axis_state, next_exit, start_index
    rng = np.random.default_rng(seed)
    n = 40
    for _ in range(3000):
        O = float(rng.choice([rng.uniform(0, n - 1), float(rng.integers(0, n - 1))]))
        D = float(rng.choice([rng.uniform(-2, 2), rng.choice([-1.0, 1.0]) * 10 ** rng.uniform(-9, 1), 0.0]))
        t0 = float(rng.uniform(0, 5))
        i = start_index(O, D, t0, n)
        step, inv, a0, a1 = axis_state(O, D, i)
        t = t0 + float(rng.uniform(0, 20))
        if rng.uniform() < 0.3 and step != 0:   # exactly on a later crossing
            t = max(t0, next_exit(O, inv, step, i + step * int(rng.integers(0, 5))))
        if step != 0 and not 0.0 <= O + t * D <= n - 1.0:
            continue
        got = advance(O, inv, step, i, a0, a1, t)
        want = start_index(O, D, t, n)
        assert got[0] == want, (O, D, t0, t, got, want)
        assert got[1:] == axis_state(O, D, want)[2:], (O, D, t0, t)


@pytest.mark.parametrize("signs", [(1, 1, 1), (-1, 1, -1), (1, -1, 1), (-1, -1, -1)])
def test_ties_step_x_then_y_then_z(signs):
    """A ray through a row of vertices crosses three planes at once at each: the walk steps
    x, then y, then z (`step_axis`), through two cells it only touches there, whatever the
    ray's octant -- the order `raycast.iso` takes the cell before a segment's start cell by."""
    from raycast.traverse import step_cell, walk_from
    n = 6
    s = np.array(signs, float)
    a = 1.0 / np.sqrt(3.0)
    d = a * s
    o = np.where(s > 0, 0.0, n - 1.0) + 0.5 * s       # a cell centre, half a cell from a vertex
    i, j, k, sx, sy, sz, ix, iy, iz, tx0, tx1, ty0, ty1, tz0, tz1 = walk_from(*o, *d, 0.0, n, n, n)
    cells, lengths = [], []
    inside = True
    while inside:
        cells.append((i, j, k))
        lengths.append(min(tx1, ty1, tz1) - max(tx0, ty0, tz0))
        inside, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1 = step_cell(*o, sx, sy, sz, ix, iy, iz, i, j, k,
                                                                  tx0, tx1, ty0, ty1, tz0, tz1, n, n, n)
    # By hand: from the start cell c, each vertex steps x, y, z in turn.
    start = np.where(s > 0, 0, n - 2)
    want = [tuple(start)]
    for _ in range(n - 2):
        for axis in range(3):
            nxt = list(want[-1])
            nxt[axis] += int(s[axis])
            want.append(tuple(nxt))
    assert cells == want
    assert lengths[1::3] == lengths[2::3] == [0.0] * (n - 2)       # touched at the vertex only
    assert all(length > 0.5 for length in lengths[0::3])


@pytest.mark.parametrize("axis", [0, 1, 2], ids=["x", "y", "z"])
@pytest.mark.parametrize("step", [1, -1])
def test_a_walk_along_an_axis_leaves_the_grid_after_its_last_cell(axis, step):
    """A ray along one axis of a 5 x 6 x 7 grid crosses every cell of its row on that axis, and
    `step_cell` says it is outside as it steps past the last: 4, 5 or 6 cells, in order."""
    from raycast.traverse import step_cell, walk_from
    shape = (5, 6, 7)                                  # samples along x, y, z
    o = np.array([1.5, 2.5, 3.5])
    o[axis] = -1.0 if step > 0 else shape[axis]
    d = np.zeros(3)
    d[axis] = step
    i, j, k, sx, sy, sz, ix, iy, iz, tx0, tx1, ty0, ty1, tz0, tz1 = walk_from(*o, *d, 1.0, *shape)
    cells = []
    inside = True
    while inside:
        cells.append((i, j, k)[axis])
        inside, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1 = step_cell(*o, sx, sy, sz, ix, iy, iz, i, j, k,
                                                                  tx0, tx1, ty0, ty1, tz0, tz1, *shape)
    want = list(range(shape[axis] - 1))
    assert cells == (want if step > 0 else want[::-1])
