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


@pytest.fixture(scope="module")
def study():
    return root_study(n=40)


def test_study_rows(study):
    assert [r["name"] for r in study] == [v[0] for v in VARIANTS]
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
    assert not _aimed_at(b, 0, 9.0, 3.0, roots)         # nearest to the other root
    assert not _aimed_at(b, 0, math.inf, 3.0, roots)


def test_required_rays_are_all_hit_by_the_project_finder(study):
    # The project's finder has no failures, so every ray with a required root is a hit of the
    # caster: `required` can be no more than the caster's hits on the same suite.
    from parc.rootstudy import _suite
    from raycast.hardcases import cast_batch
    hits = sum(int(np.isfinite(cast_batch(b)[0]).sum()) for b in _suite(40, 0))
    assert 0 < study[0]["required"] <= hits
