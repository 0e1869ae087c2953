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
