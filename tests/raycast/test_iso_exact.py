"""The unaccelerated isosurface caster against exact-trilinear fields.

Source of truth: `raycast.reference` -- the exact cubic along each ray from the float64
inputs, its real roots in mpmath (40 digits). Tolerance: its
acceptance rule -- a simple first root (conditioning ``dt <= 1e-10 h``) must
be hit within ``1e-9 h`` (h = smallest spacing); double/near-double roots
and roots within rounding of the box may be hit or missed; a hit with no
root nearby is allowed only where the cubic is within its float evaluation
error of zero. Zero failures are allowed, so the caster's hit/miss mask
equals the true one except on those rays; for generic rays (perspective,
parallel, aimed at vertices) at most 1% may fall in these loose cases.

Scenes: random fields (float64 with dyadic coefficients, uint16 with 16-bit
magnitudes) on anisotropic spacing (0.7, 1.3, 2.1) with origin
(-5.5, 3.25, 100), and on dyadic grids where grid planes are exact in world
coordinates. Rays (about 43,000): perspective (eye outside and inside),
parallel bundles, exactly and nearly axis-aligned, hugging a grid plane,
aimed at and starting on grid vertices, lying in grid planes, and diagonal
rays through rows of vertices. Also: a walk started from a segment (as PARC
does) anywhere before the hit gives bit-identical answers, and so does one
started past the hit in a cell entered through an edge.
"""
from types import SimpleNamespace

import numpy as np
import pytest

from raycast.hardcases import Batch, cast, report
from raycast.hardfields import ANISO, DYADIC, UNIT, random_isos, random_scene
from raycast.hardrays import (aimed_rays, axis_rays, diagonal_vertex_rays, in_plane_rays, near_axis_rays,
                              parallel_rays, perspective_rays, plane_hugging_rays, random_dirs, vertex_world)
from raycast.reference import Truth, run_batches

SCENES = [
    # (seed, shape (nz, ny, nx), dtype, terms, grid, denominator)
    (0, (6, 7, 9), np.float64, "full", ANISO, 8),
    (1, (6, 7, 9), np.float64, "no_xyz", ANISO, 4),
    (2, (5, 8, 6), np.uint16, "full", ANISO, 1),
    (3, (5, 8, 6), np.uint16, "full", ANISO, 1),
    (4, (7, 6, 8), np.float64, "full", DYADIC, 2),
    (5, (7, 6, 8), np.uint16, "full", DYADIC, 1),
    (6, (6, 6, 6), np.float64, "full", UNIT, 1),
    (7, (6, 6, 6), np.uint16, "saddle_xy", UNIT, 1),
]


def make_scene(seed, shape, dtype, terms, grid, den):
    rng = np.random.default_rng(1000 + seed)
    return random_scene(rng, shape, dtype, terms, grid=grid, denominator=den,
                        name=f"s{seed}-{np.dtype(dtype).name}-{terms}")


def scene_batches(scene, seed):
    rng = np.random.default_rng(seed)
    batches = []
    for iso in random_isos(rng, scene, 3):
        gens = {
            "persp-outside": perspective_rays(rng, scene, 400),
            "persp-inside": perspective_rays(rng, scene, 200, inside=True),
            "parallel": parallel_rays(rng, scene, 256),
            "axis": axis_rays(rng, scene, 200),
            "near-axis": near_axis_rays(rng, scene, 100),
            "plane-hugging": plane_hugging_rays(rng, scene, 150),
            "vertex-aimed": aimed_rays(rng, scene, vertex_world(rng, scene, 150), 150),
            "vertex-start": (vertex_world(rng, scene, 100), random_dirs(rng, 100)),
            "in-plane": in_plane_rays(rng, scene, 200),
        }
        if np.all(scene.spacing == 1.0) and np.all(scene.origin == 0.0):
            gens["diag-vertex"] = diagonal_vertex_rays(rng, scene, 200)
        for cat, (o, d) in gens.items():
            batches.append(Batch(cat, scene, o, d, iso))
    return batches


@pytest.mark.parametrize("spec", SCENES, ids=[f"seed{s[0]}" for s in SCENES])
def test_exact_trilinear_fields(spec):
    scene = make_scene(*spec)
    stats, failures = run_batches(scene_batches(scene, spec[0]))
    msg = report(stats, failures)
    assert not failures, msg
    total = sum(sum(c.values()) for c in stats.values())
    required = sum(c["hit"] for c in stats.values())
    # Not vacuous: many rays have a required root, and generic rays (not built
    # to lie on grid or box planes) rarely fall into the rule's loose cases.
    generic = [stats[c] for c in ("persp-outside", "persp-inside", "parallel", "vertex-aimed")]
    loose = sum(c["optional"] + c["noise"] for c in generic)
    assert required > 0.1 * total, msg
    assert loose <= 0.01 * sum(sum(c.values()) for c in generic), msg


@pytest.mark.parametrize("spec", SCENES[:6], ids=[f"seed{s[0]}" for s in SCENES[:6]])
def test_segment_start_gives_identical_hits(spec):
    """PARC starts the same walk at its segment's near end: for any start at or
    before the hit (even inside the hit cell) the answer must be bit-identical."""
    scene = make_scene(*spec)
    rng = np.random.default_rng(77 + spec[0])
    bad = []
    for iso in random_isos(rng, scene, 2):
        for o, d in (perspective_rays(rng, scene, 300), near_axis_rays(rng, scene, 300),
                     plane_hugging_rays(rng, scene, 300),
                     axis_rays(rng, scene, 200), perspective_rays(rng, scene, 200, True)):
            t, cell, uvw, _ = cast(scene, o, d, iso)
            hit = np.isfinite(t)
            if not hit.any():
                continue
            o, d, t, cell, uvw = o[hit], d[hit], t[hit], cell[hit], uvw[hit]
            frac = rng.uniform(0, 1, len(t))
            frac[::7] = 1.0                       # start exactly at the hit
            s0 = frac * t
            for seg in (np.stack([s0, np.full_like(t, np.inf)], 1),
                        np.stack([s0, t + rng.uniform(0, 1, len(t))], 1)):
                t2, cell2, uvw2, _ = cast(scene, o, d, iso, seg)
                diff = (t2 != t) | np.any(cell2 != cell, 1) | np.any(uvw2 != uvw, 1)
                for m in np.nonzero(diff)[0][:5]:
                    bad.append((o[m].tolist(), d[m].tolist(), iso, seg[m].tolist(), t[m], t2[m]))
    assert not bad, f"{len(bad)} rays differ with a segment start, e.g. {bad[:5]}"


def test_truth_agrees_with_a_plain_sample_scan():
    """Guard on the reference itself: scan P(t) on a fine grid in mpmath; the
    first sign change must bracket Truth's first root."""
    from raycast.mpcubic import mpf, peval
    scene = make_scene(*SCENES[0])
    rng = np.random.default_rng(5)
    iso = float(np.median(scene.data)) + 0.123
    o, d = perspective_rays(rng, scene, 30)
    checked = 0
    for n in range(30):
        tr = Truth(scene, o[n], d[n], iso)
        lo, hi = tr.outer
        if not lo < hi:
            continue
        steps = 1000
        ts = [lo + (hi - lo) * mpf(k) / steps for k in range(steps + 1)]
        vals = [peval(tr.p, x) for x in ts]
        first = next((k for k in range(steps) if (vals[k] < 0) != (vals[k + 1] < 0)), None)
        if first is None:
            continue           # no sign change on the grid (roots may still pair up)
        assert tr.roots, n
        # a sign change in [ts[first], ts[first+1]] holds a root; earlier ones
        # can only be root pairs between two grid points
        assert tr.roots[0][0] <= float(ts[first + 1]) + 1e-12
        assert any(float(ts[first]) - 1e-12 <= r[0] <= float(ts[first + 1]) + 1e-12
                   for r in tr.roots)
        checked += 1
    assert checked >= 5


def _edge_scene(rng, n, p, edge):
    """Integer samples of an exact-trilinear field that is zero all along the grid line
    through index point ``p`` in direction ``edge``, with both signs around it."""
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float64)
    xyz = (x, y, z)
    b, c = [a for a in range(3) if a != edge]
    e, yb, yc = xyz[edge], xyz[b] - p[b], xyz[c] - p[c]
    k = rng.integers(-3, 4, 6).astype(np.float64)
    k[0] = k[0] or 1.0
    data = (k[0] + k[1] * e) * yb + (k[2] + k[3] * e) * yc + (k[4] + k[5] * e) * yb * yc
    return SimpleNamespace(data=data, origin=np.zeros(3), spacing=np.ones(3))


def _cell_exit(o, d, cell):
    """When the ray leaves ``cell`` (x, y, z), by the walk's own crossing times ``(plane - O) * (1 / D)``."""
    return min((c + (di > 0) - oi) * (1.0 / di) for oi, di, c in zip(o, d, cell) if di != 0.0)


@pytest.mark.parametrize("edge", [0, 1, 2], ids=["x-edge", "y-edge", "z-edge"])
def test_segment_start_past_the_hit_in_a_cell_entered_through_an_edge(edge):
    """A ray through a cell edge crosses two planes at one time: the walk steps the lower axis
    first, through a cell it only touches there (`raycast.traverse.step_axis`: ties go to x,
    then y, then z), and a surface through the edge is often hit at the entry of the next
    cell, by the sign that zero-length cell ends with. A walk started anywhere in the hit
    cell -- even past the hit -- solves the same cubic from the same entry and must take the
    same sign from the same neighbour (`raycast.iso._entry_sign`), so it gives the full
    walk's hit bit for bit: a wrong neighbour misses a hit at the entry or makes one up."""
    rng = np.random.default_rng(40 + edge)
    n = 6
    b, c = [a for a in range(3) if a != edge]
    rays = 0
    at_entry = 0
    bad = []
    for _ in range(60):
        p = rng.integers(1, n - 1, 3).astype(np.float64)
        sc = _edge_scene(rng, n, p, edge)
        m = 400
        d = np.zeros((m, 3))
        s = rng.choice([-1.0, 1.0], (m, 3))
        q = rng.uniform(0.2, 1.0, m)
        d[:, b] = s[:, b] * q          # the same magnitude on the two crossing axes:
        d[:, c] = s[:, c] * q          # both planes are crossed at exactly one time
        d[:, edge] = rng.uniform(-1.0, 1.0, m)
        steps = rng.integers(1, 4, m).astype(np.float64)
        o = np.empty((m, 3))
        o[:, b] = p[b] - s[:, b] * steps
        o[:, c] = p[c] - s[:, c] * steps
        o[:, edge] = rng.uniform(0.2, n - 1.2, m)
        t, cell, uvw, _ = cast(sc, o, d, 0.0)
        keep, s0 = [], []
        for r in np.flatnonzero(np.isfinite(t)):
            c1 = _cell_exit(o[r], d[r], cell[r])
            start = t[r] + 0.5 * (c1 - t[r])
            if t[r] < start < c1:
                keep.append(r)
                s0.append(start)
                tie = steps[r] * (1.0 / q[r])
                at_entry += bool(t[r] == tie and _cell_exit(o[r], -d[r], cell[r]) == -tie)
        keep = np.array(keep, int)
        seg = np.stack([np.array(s0), np.full(len(keep), np.inf)], axis=1)
        t2, cell2, uvw2, _ = cast(sc, o[keep], d[keep], 0.0, seg)
        diff = (t2 != t[keep]) | np.any(cell2 != cell[keep], 1) | np.any(uvw2 != uvw[keep], 1)
        bad += [(o[r].tolist(), d[r].tolist(), t[r], t2[q2]) for q2, r in enumerate(keep) if diff[q2]]
        rays += len(keep)
    assert not bad, f"{len(bad)} of {rays} rays differ with a start past the hit, e.g. {bad[:3]}"
    # Not vacuous: many hits lie at the entry of a cell entered through the edge.
    assert at_entry > 0.05 * rays


@pytest.mark.parametrize("far", [0.0, 2.0 ** 20], ids=["near-eye", "far-eye"])
def test_a_segment_bounds_the_walk_to_its_cells(far):
    """``[seg0, seg1]`` limits the walk to the cells it meets: a surface in cells wholly before
    ``seg0`` or wholly after ``seg1`` is not hit. Analytic: samples ``f(i) = 0, 2, 2, 2, 2, 0``
    along x (constant in y, z) at isovalue 1 cross it at x = 0.5 and x = 4.5 exactly; the ray
    runs along x from x = -1 - ``far``, so at t = 1.5 and t = 5.5 past ``far``. An eye that far
    is walked from where its ray enters the volume (`raycast.traverse.entry_anchor`), and the
    segment, measured from the eye, with it."""
    f = np.array([0.0, 2.0, 2.0, 2.0, 2.0, 0.0])
    sc = SimpleNamespace(data=np.broadcast_to(f, (4, 4, 6)).copy(), origin=np.zeros(3), spacing=np.ones(3))
    o = np.array([[-1.0 - far, 1.5, 1.5]] * 5)
    d = np.array([[1.0, 0.0, 0.0]] * 5)
    seg = far + np.array([[-np.inf, np.inf],      # the whole ray: the first crossing
                          [2.2, np.inf],          # from inside cell 1: the second
                          [0.0, 2.4],             # cells 0 and 1 only: the first
                          [2.2, 3.4],             # cells 1 and 2 only: none
                          [2.2, 5.0]])            # cells 1 to 3, ending on cell 4's face: none
    t, cell, uvw, counts = cast(sc, o, d, 1.0, seg)
    assert t[0] == far + 1.5 and t[1] == far + 5.5 and t[2] == far + 1.5 and t[3] == t[4] == np.inf, t
    assert cell[0].tolist() == [0, 1, 1] and cell[1].tolist() == [4, 1, 1], cell
    # The cells walked: 1 to 4 (the hit), 0 (the hit), 1 and 2 (x = 1.2 to 2.4), 1 to 3.
    assert counts[1:, 0].tolist() == [4, 1, 2, 3], counts


@pytest.mark.parametrize("table", [False, True], ids=["corners", "skip-table"])
@pytest.mark.parametrize("big", [2.0 ** 60, 1e28])
@pytest.mark.parametrize("side", [1.0, -1.0], ids=["above", "below"])
def test_a_root_within_rounding_of_a_face_into_a_cell_of_one_sign(side, big, table):
    """Two cells along y: samples -big on the face y = 0, 1 everywhere else, isovalue 0. The
    first cell is -big + (big + 1) v, 1e-18 short of 1 at the face y = 1, where the second
    cell (all corners 1) begins, so the surface lies on that face to well within 1e-9. The
    first cell's value there rounds to either sign (its terms are 1e18); where it rounds below
    zero, the one-signed cell after it must still be hit at its entry, with or without a skip
    table signing it, not missed. The same with every sample negated (the second cell below
    the isovalue)."""
    data = np.ones((2, 3, 2))
    data[:, 0, :] = -big
    data *= side
    sc = SimpleNamespace(data=data, origin=np.zeros(3), spacing=np.ones(3))
    rng = np.random.default_rng(3)
    n = 400
    o = np.stack([rng.uniform(0.05, 0.95, n), np.full(n, -0.5), rng.uniform(0.05, 0.95, n)], 1)
    d = np.stack([rng.uniform(-0.02, 0.02, n), np.ones(n), rng.uniform(-0.02, 0.02, n)], 1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    skip = (np.array([[[0], [int(side)]]], np.int8), 1) if table else None
    t, cell, uvw, _ = cast(sc, o, d, 0.0, skip=skip)
    face = (1.0 - o[:, 1]) / d[:, 1]
    assert np.all(np.isfinite(t)), f"{np.sum(~np.isfinite(t))} of {n} rays miss the surface"
    assert np.max(np.abs(t - face)) <= 1e-9
    # The hit's cell and local coordinates, which shading reads, are the same point.
    assert np.max(np.abs(cell + uvw - (o + t[:, None] * d))) <= 1e-9


@pytest.mark.parametrize("corner", range(8))
def test_a_face_with_one_corner_off_the_isovalue_is_no_level_face(corner):
    """One cell, samples 0 but for one corner at 1 (bit 0 of ``corner``: x = 1, bit 1: y, bit 2:
    z), isovalue 0. Analytic: the interpolant is the product over the axes of the distance from
    the face away from that corner, so it is zero on those three faces and positive everywhere
    else in the cell, also on the three faces at the corner, whose other three corners are at
    the isovalue. A ray entering through a zero face hits it there; one entering through a face
    at the corner hits where it leaves through a zero face, or misses. Either way the hit's
    cell and local coordinates are the point ``o + t d``."""
    data = np.zeros((2, 2, 2))
    bits = np.array([corner & 1, (corner >> 1) & 1, (corner >> 2) & 1])
    data[bits[2], bits[1], bits[0]] = 1.0
    sc = SimpleNamespace(data=data, origin=np.zeros(3), spacing=np.ones(3))
    rng = np.random.default_rng(corner)
    n = 600
    o = 0.5 + 3.0 * random_dirs(rng, n)
    d = rng.uniform(0.05, 0.95, (n, 3)) - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    with np.errstate(divide="ignore"):
        near = np.where(d > 0, 0.0, 1.0)
        t_near, t_far = (near - o) / d, (1.0 - near - o) / d
    entry, leave = np.argmax(t_near, 1), np.argmin(t_far, 1)
    t_in, t_out = t_near.max(1), t_far.min(1)
    # Through a face's edge or corner, the face a ray enters or leaves by is a tie: not judged.
    clear = (np.sort(t_near, 1)[:, -2] < t_in - 1e-6) & (np.sort(t_far, 1)[:, 1] > t_out + 1e-6)
    rows = np.arange(n)
    zero_in = near[rows, entry] != bits[entry]
    zero_out = 1.0 - near[rows, leave] != bits[leave]
    want = np.where(zero_in, t_in, np.where(zero_out, t_out, np.inf))
    t, cell, uvw, _ = cast(sc, o, d, 0.0)
    got, want = t[clear], want[clear]
    wrong = np.flatnonzero(np.isfinite(got) != np.isfinite(want))
    assert not wrong.size, f"{wrong.size} rays hit where they should miss or miss where they should hit"
    hit = np.isfinite(want)
    assert np.max(np.abs(got[hit] - want[hit])) <= 1e-12
    assert np.max(np.abs(cell + uvw - (o + t[:, None] * d))[np.isfinite(t)]) <= 1e-12
    # Not vacuous: rays of all three kinds.
    kinds = [zero_in, zero_out & ~zero_in, ~zero_in & ~zero_out]
    assert min(k[clear].sum() for k in kinds) > 20


@pytest.mark.parametrize("flat", [0, 1], ids=["no-x", "no-y"])
def test_a_level_face_seen_from_afar_by_rays_with_a_zero_component(flat):
    """Samples at 100 on the face z = 0, the volume's minimum, and strictly above it elsewhere:
    the isosurface at 100 is that face. Eyes 1e5 cells below it, so each ray is walked from where
    it enters the volume, and only to within a rounding (`raycast.traverse.entry_anchor`), with
    no x (or y) component, so the ray never crosses a plane of that axis: every ray hits the
    face where it enters, ``z = 0``."""
    rng = np.random.default_rng(17 + flat)
    data = rng.uniform(101, 899, (5, 6, 7)).round()
    data[0] = 100.0
    sc = SimpleNamespace(data=data, origin=np.zeros(3), spacing=np.ones(3))
    n = 300
    d = np.stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(0.3, 1, n)], 1)
    d[:, flat] = 0.0
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    target = np.stack([rng.uniform(0.05, 5.95, n), rng.uniform(0.05, 4.95, n), np.zeros(n)], 1)
    o = target - 1e5 * d
    t, _, _, _ = cast(sc, o, d, 100.0)
    face = -o[:, 2] / d[:, 2]
    assert np.all(np.isfinite(t)), f"{np.sum(~np.isfinite(t))} of {n} rays miss the face"
    assert np.max(np.abs(t - face)) <= 1e-6


def test_a_ray_grazing_an_edge_of_a_level_face_hits_it_there():
    """Samples at 100 on the face z = 0, the volume's minimum, and above it elsewhere, so the
    isosurface at 100 is that face. Rays at 45 degrees in the planes y = const touch the volume
    only on the face's edges x = 0 and x = 6 (entering and leaving at one time): the volume is
    closed, so each hits the face there, at ``t = sqrt(2)`` from one cell away."""
    rng = np.random.default_rng(23)
    data = rng.uniform(101, 899, (5, 6, 7)).round()
    data[0] = 100.0
    sc = SimpleNamespace(data=data, origin=np.zeros(3), spacing=np.ones(3))
    y = rng.uniform(0.0, 5.0, 40)
    a = 1.0 / np.sqrt(2.0)
    o = np.concatenate([np.stack([np.full(20, -1.0), y[:20], np.full(20, 1.0)], 1),
                        np.stack([np.full(20, 7.0), y[20:], np.full(20, 1.0)], 1)])
    d = np.concatenate([np.tile([a, 0.0, -a], (20, 1)), np.tile([-a, 0.0, -a], (20, 1))])
    t, cell, _, _ = cast(sc, o, d, 100.0)
    assert np.all(np.abs(t - np.sqrt(2.0)) <= 1e-12), t
    assert set(cell[:, 0]) == {0, 5} and np.all(cell[:, 2] == 0)


def test_a_segment_starting_past_a_crossing_takes_the_sign_the_cell_before_ends_with():
    """Samples ``0, 2, 0`` along x (constant in y, z) at isovalue 1 cross it at x = 0.5 and
    x = 1.5 exactly. A ray along x from x = -1 whose segment starts at x = 1.2, in the second
    cell, past the first crossing, hits the second at t = 2.5: the sign that cell is entered
    with is the first cell's at its exit (above), the same as its own there, not the one the
    first cell starts with (below), which would make a hit of its entry."""
    f = np.array([0.0, 2.0, 0.0])
    sc = SimpleNamespace(data=np.broadcast_to(f, (3, 3, 3)).copy(), origin=np.zeros(3), spacing=np.ones(3))
    o = np.array([[-1.0, 0.5, 0.5], [-1.0, 1.25, 1.5]])
    d = np.array([[1.0, 0.0, 0.0]] * 2)
    t, cell, _, _ = cast(sc, o, d, 1.0, np.array([[2.2, np.inf]] * 2))
    assert t.tolist() == [2.5, 2.5] and cell[:, 0].tolist() == [1, 1], (t, cell)
