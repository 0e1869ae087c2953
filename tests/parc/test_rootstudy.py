"""The root-finder study (`parc.rootstudy`) and the alternative finders it measures.

Sources of truth: for the finders on single cubics, cubics built from known
roots (numpy, well separated, so float64 reproduces them to ~1e-12); for the
study, `raycast.reference` (mpmath truth and the acceptance rule on the
hard-ray suite). The project's finder must have no failures (as in
`test_hard_rays`); the alternatives are only required to be plausible:
mostly right, and within a cell when they hit near a root. Timings are
reported, never judged beyond being positive.
"""
import math

import numpy as np
import pytest

from parc.rootstudy import FAILURE_KINDS, VARIANTS, format_table, root_study
from raycast.roots_alt import first_root_closed_form, first_root_isolating, first_root_marmitt


def _cubics(seed, n=300):
    """``(a, b, c, d, first root in [0, 1] or -1)`` from random real roots in [-1, 2]."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        roots = np.sort(rng.uniform(-1.0, 2.0, 3))
        if np.min(np.diff(roots)) < 0.05 or np.min(np.abs(roots - 1.0)) < 0.01 or np.min(np.abs(roots)) < 0.01:
            continue
        a, b, c, d = np.poly(roots) * rng.choice([-1.5, -0.5, 0.5, 2.0])
        inside = roots[(roots >= 0) & (roots <= 1)]
        out.append((a, b, c, d, float(inside[0]) if inside.size else -1.0))
    return out


def test_closed_form_on_plain_cubics():
    for a, b, c, d, r in _cubics(0):
        s = first_root_closed_form(a, b, c, d, 1.0)
        assert (s == -1.0) if r < 0 else abs(s - r) < 1e-9, (a, b, c, d, r, s)


def test_closed_form_degrades_to_quadratic_and_linear():
    assert first_root_closed_form(0.0, 0.0, 2.0, -1.0, 1.0) == 0.5            # 2s - 1
    assert first_root_closed_form(0.0, 1.0, 0.0, -0.25, 1.0) == 0.5           # s^2 - 1/4
    assert first_root_closed_form(0.0, 1.0, -1.0, 0.25, 1.0) == 0.5           # (s - 1/2)^2
    assert first_root_closed_form(0.0, 0.0, 0.0, 1.0, 1.0) == -1.0            # constant
    assert first_root_closed_form(1.0, 0.0, 0.0, -0.125, 1.0) == pytest.approx(0.5)   # triple-ish
    assert first_root_closed_form(1.0, 0.0, 0.0, 1.0, 10.0) == -1.0           # root at -1 only


def test_marmitt_isolates_then_interpolates():
    for a, b, c, d, r in _cubics(1):
        s2 = first_root_marmitt(a, b, c, d, 1.0)
        if r < 0:
            assert s2 == -1.0
            continue
        # Two regula falsi steps land in the root's monotone piece, not on it;
        # iterated on, the same bracket converges to the root.
        assert 0.0 <= s2 <= 1.0
        assert abs(first_root_isolating(a, b, c, d, 1.0, 400) - r) < 1e-6
    assert first_root_marmitt(1.0, -1.5, 0.5, 0.0, 1.0) == 0.0                 # root at the start
    assert first_root_marmitt(0.0, 0.0, 1.0, -1.0, 1.0) == 1.0                 # root at the end


STAGES = []


@pytest.fixture(scope="module")
def study():
    return root_study(n=40, progress=STAGES.append)


def test_study_rows(study):
    assert [r["name"] for r in study] == [v[0] for v in VARIANTS]
    # Each stage said as it starts: a first run's walks compile, and the truth takes a while.
    assert STAGES == ["walking 400 rays with each finder", f"timing {study[0]['solves']:,} cubics with each finder",
                      "the mpmath truth of every ray"]
    for r in study:
        assert r["ns_per_solve"] > 0 and r["rays"] == 400 and r["solves"] > 100
        assert 0 < r["required"] < r["rays"]
        assert r["failures"] == sum(r[k] for k in FAILURE_KINDS) == sum(r["failures_by_category"].values())
        assert 0 <= r["median_err_cells"] <= r["max_err_cells"] and math.isfinite(r["max_err_cells"])
    text = format_table(study)
    assert all(r["name"] in text for r in study)


def test_project_finder_has_no_failures(study):
    project = study[0]
    assert project["name"] == "project" and project["failures"] == 0
    assert project["max_err_cells"] < 1e-9                 # the acceptance tolerance


def test_closed_form_is_plausible(study):
    closed = next(r for r in study if r["name"] == "closed-form")
    # Right on the bulk of the suite: its failures are concentrated in the
    # degenerate categories, and where it hits a root it is precise.
    assert closed["failures"] < 0.25 * closed["rays"]
    assert closed["median_err_cells"] < 1e-9


def test_the_check_pool_workers_ignore_a_terminals_ctrl_c():
    # A terminal's Ctrl-C reaches the whole process group: workers interrupted mid-task
    # printed tracebacks and could leave the pool's lock held, hanging the exit.
    import multiprocessing
    import signal
    from pathlib import Path

    from raycast import reference
    before = signal.getsignal(signal.SIGINT)            # SIG_IGN already where started in the background
    pool = reference._pool()
    if pool is None or not Path("/proc/self/status").exists():
        pytest.skip("no worker processes here, or no /proc to read their signals from")
    pool.map(abs, range(4))                         # every worker started
    for child in multiprocessing.active_children():
        fields = dict(line.split(":\t") for line in Path(f"/proc/{child.pid}/status").read_text().splitlines()
                      if ":\t" in line)
        assert int(fields["SigIgn"], 16) >> (signal.SIGINT - 1) & 1, child
    assert signal.getsignal(signal.SIGINT) == before


def test_the_check_pool_ends_at_exit_without_a_ctrl_c_traceback():
    # Its termination takes about 0.2 s after a run's last line: a Ctrl-C then printed the
    # atexit machinery's traceback. Here the Ctrl-C comes 0.1 s into a termination made slower.
    import os
    import subprocess
    import sys
    code = ("import os, signal, threading, time; import multiprocessing.pool as mp\n"
            "real = mp.Pool.terminate; mp.Pool.terminate = lambda self: (time.sleep(0.5), real(self))\n"
            "from raycast import reference; p = reference._pool()\n"
            "if p is None: os._exit(3)\n"
            "p.map(abs, range(4))\n"
            "ctrl_c = threading.Timer(0.1, os.kill, (os.getpid(), signal.SIGINT)); ctrl_c.daemon = True\n"
            "ctrl_c.start(); print('done')\n")
    env = dict(os.environ, PARC_TEST_WORKERS="2")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert (p.returncode, p.stdout, p.stderr) == (0, "done\n", "")


def _from_roots(lead, *roots):
    """Float coefficients (a, b, c, d) of ``lead * prod(s - r)``; exact for dyadic roots."""
    coef = [1.0]
    for r in roots:
        coef = [x - r * y for x, y in zip(coef + [0.0], [0.0] + coef)]
    coef = [0.0] * (4 - len(coef)) + [lead * x for x in coef]
    return tuple(coef)


def test_closed_form_takes_the_smaller_of_two_roots_and_roots_at_the_ends():
    # Analytic: (s - 1/4)(s - 3/4), exact coefficients; the smaller root is -sqrt(disc) - p.
    assert first_root_closed_form(*_from_roots(1.0, 0.25, 0.75), 1.0) == 0.25
    assert first_root_closed_form(*_from_roots(-2.0, 0.75, 0.25), 1.0) == 0.25
    # A root exactly at the interval's end is in [0, length].
    assert first_root_closed_form(0.0, 0.0, 1.0, -1.0, 1.0) == 1.0
    assert first_root_closed_form(*_from_roots(1.0, 1.0, 3.0, 5.0), 1.0) == 1.0


def test_closed_form_double_and_triple_roots_with_exact_zero_discriminant():
    # (s - 1/2)^2 (s - 2): the discriminant comes out exactly 0 (the double-root branch);
    # the first root in [0, 1] is the double root 1/2.
    assert first_root_closed_form(*_from_roots(1.0, 0.5, 0.5, 2.0), 1.0) == 0.5
    assert first_root_closed_form(*_from_roots(1.0, 0.25, 0.25, -0.5), 1.0) == 0.25
    # (s - r)^3: discriminant and q exactly 0 (the triple-root branch).
    for r in (0.25, 0.5, 0.75):
        assert first_root_closed_form(*_from_roots(1.0, r, r, r), 1.0) == r


def test_closed_form_zero_test_is_parkers_1e_30():
    # Parker et al. set EQN_EPS to 1e-30: a cubic of coefficients near 1e-10 is a cubic, not a constant.
    a, b, c, d = (1e-10 * x for x in _from_roots(1.0, 0.25, 0.5, 0.75))
    assert abs(first_root_closed_form(a, b, c, d, 1.0) - 0.25) < 1e-12


def test_isolating_splits_a_quadratic_at_its_vertex():
    # (s - 1/4)(s - 3/4): two roots in [0, 1], the vertex 1/2 between them.
    assert abs(first_root_isolating(*_from_roots(1.0, 0.25, 0.75), 1.0, 400) - 0.25) < 1e-12
    assert abs(first_root_isolating(*_from_roots(-3.0, 0.75, 0.25), 1.0, 400) - 0.25) < 1e-12


def test_marmitt_takes_exactly_two_regula_falsi_steps():
    # Truth: the same two steps in exact rationals on the isolating bracket [0, 1/2] of
    # (s - 1/4)(s - 3/4) (its vertex splits [0, 1]): 0 -> 3/8 -> 3/10.
    from fractions import Fraction as Fr

    def p(s):
        return (s - Fr(1, 4)) * (s - Fr(3, 4))
    s0, s1 = Fr(0), Fr(1, 2)
    for _ in range(2):
        s = s0 + (s1 - s0) * p(s0) / (p(s0) - p(s1))
        if (p(s) < 0) == (p(s0) < 0):
            s0 = s
        else:
            s1 = s
    assert s == Fr(3, 10)
    assert abs(first_root_marmitt(*_from_roots(1.0, 0.25, 0.75), 1.0) - float(s)) < 1e-15


def test_aimed_at_means_the_nearest_true_root_less_than_a_cell_away():
    # Analytic: a ray along x on a grid of spacing (2, 1, 1); roots at t = 3 and t = 10.
    from types import SimpleNamespace

    from parc.rootstudy import _aimed_at
    b = SimpleNamespace(dirs=np.array([[1.0, 0.0, 0.0]]), scene=SimpleNamespace(spacing=np.array([2.0, 1.0, 1.0])))
    roots = [3.0, 10.0]
    assert _aimed_at(b, 0, 3.0, 3.0, roots)
    assert _aimed_at(b, 0, 4.9, 3.0, roots)             # 0.95 of a cell past it
    assert _aimed_at(b, 0, 1.2, 3.0, roots)             # 0.9 of a cell before it
    assert not _aimed_at(b, 0, 5.1, 3.0, roots)         # more than a cell (2 units) away
    assert not _aimed_at(b, 0, 5.0, 3.0, roots)         # exactly a cell away is not less than one
    assert not _aimed_at(b, 0, 1.0, 3.0, roots)
    assert not _aimed_at(b, 0, 9.0, 3.0, roots)         # nearest to the other root
    assert not _aimed_at(b, 0, math.inf, 3.0, roots)


def test_required_rays_are_all_hit_by_the_project_finder(study):
    # The project's finder has no failures, so every ray with a required root is a hit of the
    # caster: `required` can be no more than the caster's hits on the same suite.
    from parc.rootstudy import _suite
    from raycast.hardcases import cast_batch
    cast = [cast_batch(b) for b in _suite(40, 0)]
    hits = sum(int(np.isfinite(t).sum()) for t, _, _, _ in cast)
    assert 0 < study[0]["required"] <= hits
    # The cubics timed are the project's walk's, once: the caster's own count of them, less
    # at most one per hit (it counts the cell where the predecessor's sign decides the hit
    # before any root finder is called).
    solves = sum(int(counts[:, 1].sum()) for _, _, _, counts in cast)
    assert solves - hits <= study[0]["solves"] <= solves


def test_table_columns_hold_their_rows_numbers():
    # Every number a row holds differs from the others, so a column showing another's is seen.
    def row(name, ns, errs, kinds, cats):
        return dict(name=name, description=f"{name} finder", ns_per_solve=ns, solves=12345, rays=400,
                    required=321, failures=sum(kinds), **dict(zip(FAILURE_KINDS, kinds)),
                    max_err_cells=errs[0], median_err_cells=errs[1], failures_by_category=cats)
    rows = [row("project", 61.25, (3.5e-12, 1.25e-14), (0, 0, 0, 0, 0), {}),
            row("marmitt", 17.5, (0.375, 0.0625), (1, 2, 3, 40, 5), {"grazing": 30, "faces": 21})]
    lines = format_table(rows).splitlines()
    assert lines[0].startswith("hard-ray suite: 400 rays (321 with a required root), 12,345 cubics timed")
    assert lines[1].split() == ["finder", "ns/solve", "max", "err", "med", "err", "fail", "missed", "false",
                                "wrong", "inacc", "cell"]
    for r, line in zip(rows, lines[2:4]):
        cols = line.split()
        assert cols[0] == r["name"]
        assert [float(c) for c in cols[1:4]] == pytest.approx(
            [r["ns_per_solve"], r["max_err_cells"], r["median_err_cells"]], rel=1e-2)
        assert [int(c) for c in cols[4:]] == [r["failures"], r["missed"], r["false"], r["wrong"],
                                              r["inaccurate"], r["cell"]]
    assert lines[4] == "failures by category:"
    assert lines[5].split() == ["project", "none"]
    assert lines[6].split() == ["marmitt", "faces", "21,", "grazing", "30"]


def test_solve_times_are_the_best_repeat_per_solve(monkeypatch):
    # A clock whose intervals are set here: variant v's r-th timing lasts durations[r][v] ns.
    from types import SimpleNamespace

    from parc import rootstudy
    durations = [[900, 1800, 2700], [300, 600, 900], [600, 1500, 1200]]
    ticks, now = [], 0
    for per_variant in durations:
        for d in per_variant:
            ticks += [now, now + d]
            now += d
    clock = iter(ticks)
    monkeypatch.setattr(rootstudy, "time", SimpleNamespace(perf_counter_ns=lambda: next(clock)))
    monkeypatch.setattr(rootstudy, "TIMED_SOLVES", 40)
    rec = np.array([_from_roots(1.0, 0.25, 0.5, 0.75) + (1.0,)] * 8)
    ns = rootstudy._time_solves(rec)
    # 40 solves of 8 cubics: 5 passes; each variant's best of 3 over the 40 solves.
    assert ns == {code: min(d[v] for d in durations) / 40 for v, (_, code, _) in enumerate(VARIANTS)}


def test_each_variant_walks_and_times_its_own_finder():
    # The walk's switch gives the named finder's root; the checksum of each timed loop is the
    # sum of its finder's roots, called one by one.
    from parc.rootstudy import CLOSED_FORM, MARMITT, PROJECT, _solve, solve_all
    from raycast.cubic import first_root
    rec = np.array([c[:4] + (1.0,) for c in _cubics(5, 40)])
    for code, finder in ((PROJECT, first_root), (CLOSED_FORM, first_root_closed_form),
                         (MARMITT, first_root_marmitt)):
        roots = [finder(*row) for row in rec]
        assert [_solve(code, *row) for row in rec] == roots, code
        assert solve_all(rec, code, 2) == pytest.approx(2 * sum(roots), rel=1e-12), code
    assert solve_all(rec, MARMITT, 1) != pytest.approx(solve_all(rec, CLOSED_FORM, 1), rel=1e-9)


def test_error_columns_are_distances_to_the_true_root_in_smallest_spacings(monkeypatch):
    # The columns by their definition, from each ray's answer and its mpmath roots: |t - r| over
    # the scene's smallest spacing, where r is the first required root, the true root nearest
    # the hit and less than a cell away along every axis. On scenes of unequal spacings.
    from parc import rootstudy
    from raycast.reference import judge_batches
    batches = [b for b in rootstudy._suite(25, 0) if len(set(b.scene.spacing)) == 3][:40]
    monkeypatch.setattr(rootstudy, "_suite", lambda n, seed: batches)
    monkeypatch.setattr(rootstudy, "TIMED_SOLVES", 1)
    rows = root_study(n=25)
    for row, (_, code, _) in zip(rows, rootstudy.VARIANTS):
        answers = [rootstudy._walk(b, code)[:3] for b in batches]
        judged = judge_batches([(b.scene, b.origins, b.dirs, b.isos, [a]) for b, a in zip(batches, answers)])
        errs = []
        for b, (t, _, _), res in zip(batches, answers, judged):
            for m, (first, roots, _) in enumerate(res):
                if first is None or not np.isfinite(t[m]):
                    continue
                r = first[0]
                cells = np.abs((t[m] - r) * np.asarray(b.dirs[m]) / np.asarray(b.scene.spacing))
                if roots[int(np.argmin(np.abs(np.asarray(roots) - t[m])))] == r and cells.max() < 1.0:
                    errs.append(abs(float(t[m]) - r) / float(np.min(b.scene.spacing)))
        assert errs, row["name"]
        assert row["max_err_cells"] == max(errs), row["name"]
        assert row["median_err_cells"] == pytest.approx(float(np.median(errs)), rel=1e-12), row["name"]
    assert rows[2]["name"] == "marmitt" and rows[2]["max_err_cells"] > 1e-9       # not all zeros


@pytest.mark.parametrize("n", [1, 5, 24])
def test_a_study_of_few_rays_has_that_many_per_category(n):
    # `--n` is rays per category; a small one leaves some of a category's batches without
    # rays, which must still be (0, 3) arrays for the walk and the truth.
    from collections import Counter

    from parc.rootstudy import _suite
    from raycast.hardcases import CATEGORIES
    per = Counter()
    for b in _suite(n, 0):
        assert b.origins.shape == b.dirs.shape == (len(b.isos), 3)
        per[b.category] += len(b.origins)
    assert per == {c: n for c in CATEGORIES}


def test_a_walk_that_drifts_from_the_caster_is_refused(monkeypatch):
    # The project's finder must give the caster's hits bit for bit, or the comparison is not of
    # root finders alone: one ulp off on one ray stops the study.
    from parc import rootstudy
    real = rootstudy._walk

    def drifted(batch, variant, record=False):
        t, cell, uvw, rec = real(batch, variant, record)
        hit = np.flatnonzero(np.isfinite(t))
        if variant == rootstudy.PROJECT and hit.size:
            t = t.copy()
            t[hit[0]] = np.nextafter(t[hit[0]], np.inf)
        return t, cell, uvw, rec
    monkeypatch.setattr(rootstudy, "_walk", drifted)
    with pytest.raises(RuntimeError, match="no longer matches"):
        root_study(n=25)


def test_the_cubics_recorded_are_each_rays_own_in_ray_order():
    # Walked one ray at a time, a ray's cubics start the record: no offsets to get wrong.
    # Grazing rays solve several cubics each.
    from parc.rootstudy import PROJECT, walk
    from raycast.hardcases import hard_batches
    for b in hard_batches("grazing", 100, 0)[:2]:
        grid = (b.scene.data, b.scene.origin, b.scene.spacing)
        rec = walk(*grid, b.origins, b.dirs, b.isos, PROJECT, record=True)[3]
        alone = [walk(*grid, b.origins[m:m + 1], b.dirs[m:m + 1], b.isos[m:m + 1], PROJECT, record=True)[3]
                 for m in range(len(b.origins))]
        assert sum(len(r) > 1 for r in alone) > 3
        np.testing.assert_array_equal(rec, np.concatenate(alone))


def test_the_project_walk_is_the_casters_over_a_whole_category():
    # The study checks its walk against the caster on the suite it runs; the suite above is a
    # small sample, and the whole suite's 16-bit category holds rays that enter the box on a
    # face lying in the level set, which the walk must decide as the caster does.
    from parc.rootstudy import FULL_RAYS_PER_CATEGORY, PROJECT, _walk
    from raycast.hardcases import cast_batch, hard_batches
    for b in hard_batches("mag16", FULL_RAYS_PER_CATEGORY, 0):
        t, cell, uvw, _ = _walk(b, PROJECT)
        ref_t, ref_cell, ref_uvw, _ = cast_batch(b)
        hit = np.isfinite(ref_t)
        np.testing.assert_array_equal(t, ref_t)
        np.testing.assert_array_equal(cell[hit], ref_cell[hit])
        np.testing.assert_array_equal(uvw[hit], ref_uvw[hit])


@pytest.mark.parametrize("big", [2.0 ** 60, 1e28])
@pytest.mark.parametrize("side", [1.0, -1.0], ids=["above", "below"])
def test_the_study_s_walk_hits_a_root_within_rounding_of_a_face_as_the_caster_does(side, big):
    """The case of `tests/raycast/test_iso_exact.py`'s test of that name, walked by the study
    with the project's finder: two cells along y, samples -big on the face y = 0 and 1 elsewhere,
    so that the surface lies on the face y = 1, where the first cell's value rounds to either
    sign. Without the caster's rule for a rounded sign carried into a one-signed cell, a third
    of these rays missed it, and the study's check against the caster could fail."""
    from parc.rootstudy import PROJECT, walk_rays
    data = np.ones((2, 3, 2))
    data[:, 0, :] = -big
    data *= side
    rng = np.random.default_rng(3)
    n = 400
    o = np.stack([rng.uniform(0.05, 0.95, n), np.full(n, -0.5), rng.uniform(0.05, 0.95, n)], 1)
    d = np.stack([rng.uniform(-0.02, 0.02, n), np.ones(n), rng.uniform(-0.02, 0.02, n)], 1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t, cell, uvw = np.empty(n), np.empty((n, 3), np.int64), np.empty((n, 3))
    solves, offsets = np.empty(n, np.int64), np.zeros(n, np.int64)
    walk_rays(data, np.zeros(3), np.ones(3), o, d, np.zeros(n), PROJECT, t, cell, uvw, solves, np.empty((0, 5)),
              offsets)
    face = (1.0 - o[:, 1]) / d[:, 1]
    assert np.all(np.isfinite(t)), f"{np.sum(~np.isfinite(t))} of {n} rays miss the surface"
    assert np.max(np.abs(t - face)) <= 1e-9
    assert np.max(np.abs(cell + uvw - (o + t[:, None] * d))) <= 1e-9
