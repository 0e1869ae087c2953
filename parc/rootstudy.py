"""Root-finder study: the project's cubic solver against two published ones on the hard-ray suite.

About this study. Inside a cell the isosurface along a ray is the first
root of a cubic (Parker et al. 1998, Appendix A); how that root is found
decides both speed and whether the hard cases (grazing rays, roots on cell
faces, nearly axis-aligned rays, 16-bit magnitudes, far cells) come out
right. Three finders with the same contract ``f(A, B, C, D, L) -> s`` in
``[0, L]`` or -1 are compared:

* ``project``: `raycast.cubic.first_root`: the Bernstein coefficients' sign
  changes, else isolation by the derivative's roots (cancellation-free),
  then safeguarded Newton to 1e-15 of the bracket.
* ``closed-form``: `raycast.roots_alt.first_root_closed_form`: Cardano /
  trigonometric roots as Parker et al. 1998 used them (Schwarze's Graphics
  Gems code, quadratic/linear special cases, ``EQN_EPS = 1e-30``).
* ``marmitt``: `raycast.roots_alt.first_root_marmitt`: isolation as Marmitt
  et al. 2004, then a fixed two steps of repeated linear interpolation.

How it is measured, and why it is a fair comparison:

* **Accuracy and failures, per ray.** Every ray of the hard-ray suite
  (`raycast.hardcases`) is walked by the project's own caster walk (cell
  traversal, corner reads, the cell's cubic in its own frame, the
  predecessor-sign rule at shared faces), with only the root finder
  swapped: `walk_iso_ray` is `raycast.iso.cast_iso_ray` over the whole ray
  with a ``variant`` switch where it calls ``first_root``. Each run checks
  that the ``project`` variant reproduces the caster bit for bit, so the
  walk has not drifted from the renderer's. Each answer is judged against
  the mpmath truth of that ray by the project's acceptance rule
  (`raycast.reference.judge`), and failures are sorted: ``missed`` (a
  required root, no hit), ``inaccurate`` (within a cell of the true root
  nearest to it but outside its tolerance, 1e-9 of a cell plus the
  rounding of ``t``: what a fixed-iteration method costs), ``wrong`` (the
  first root skipped, a later one hit), ``false`` (no root within a cell),
  ``cell`` (cell or local coordinates inconsistent with ``t``). The error
  columns are ``|t - r| / h`` (``h`` the smallest spacing, so cell units)
  over the rays with a first required root ``r`` whose hit is an answer for
  it (``r`` the true root nearest to the hit, less than a cell away),
  accepted or not; misses and hits elsewhere (on an earlier optional root,
  say) are counted, not measured.
* **Speed, per solve.** The cubics ``(A, B, C, D, L)`` the ``project``
  walk hands to its root finder over the whole suite (most have no root in
  the cell: the caster solves every cell whose corner range holds the
  isovalue) are recorded once; each finder then solves the same array in a
  compiled single-thread loop, interleaved, best of 3, so the figure is
  nanoseconds per call on identical inputs, measured in one run. The suite
  is built to be hard: its mix of degenerate cubics is not a typical
  image's.

References: Parker et al. 1998, Appendix A; Marmitt, Kleer, Wald, Friedrich,
Slusallek, "Fast and Accurate Ray-Voxel Intersection Techniques for
Iso-Surface Ray Tracing", VMV 2004; Schwarze, "Cubic and quartic roots",
Graphics Gems, 1990.

Run ``python -m parc.rootstudy`` (the whole suite, a few minutes) or with
``--quick`` (under half a minute).
"""
from __future__ import annotations

import math
import statistics
import time
from collections import Counter

import numpy as np

from raycast.config import kernel
from raycast.cubic import eval_cubic, first_root
from raycast.iso import cell_cubic, corners, entry_face_time, on_level_face
from raycast.roots_alt import MARMITT_ITER, first_root_closed_form, first_root_marmitt
from raycast.traverse import clip_box, entry_anchor, step_cell, to_index_space, walk_from

#: Variant codes of the kernels' switch.
PROJECT, CLOSED_FORM, MARMITT = 0, 1, 2

#: ``(name, code, description)`` of each finder, in table order.
VARIANTS = (
    ("project", PROJECT, "Bernstein sign test, else isolate by the derivative's roots; safeguarded "
                         "Newton to 1e-15 (raycast.cubic.first_root)"),
    ("closed-form", CLOSED_FORM, "Cardano/trigonometric roots, quadratic/linear special cases, "
                                 "EQN_EPS 1e-30 (Parker et al. 1998, after Schwarze)"),
    ("marmitt", MARMITT, f"isolate by the derivative's roots, {MARMITT_ITER} regula falsi steps "
                         "(Marmitt et al. 2004)"),
)

#: Rays per category of the hard-ray suite: everything the tests cast, or a
#: sample for ``quick`` (seconds of mpmath truth instead of minutes).
FULL_RAYS_PER_CATEGORY = 10_500
QUICK_RAYS_PER_CATEGORY = 150

#: Solves per timing: enough that one timing lasts ~10-100 ms, well above
#: timer and scheduling noise.
TIMED_SOLVES = 2_000_000

FAILURE_KINDS = ("missed", "false", "wrong", "inaccurate", "cell")


# ---------------------------------------------------------------- kernels

@kernel
def _solve(variant, a, b, c, d, length):
    if variant == CLOSED_FORM:
        return first_root_closed_form(a, b, c, d, length)
    if variant == MARMITT:
        return first_root_marmitt(a, b, c, d, length)
    return first_root(a, b, c, d, length)


@kernel
def walk_iso_ray(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, variant, rec, n0):
    """`raycast.iso.cast_iso_ray` over the whole ray, with the root finder ``variant``.

    Returns ``(t, i, j, k, u, v, w, solves)``; ``solves`` counts the calls
    to the root finder. When ``rec`` has rows, call ``m`` of this ray
    stores its ``(A, B, C, D, L)`` in ``rec[n0 + m]``.
    """
    nz, ny, nx = data.shape
    ta, Ox, Oy, Oz = entry_anchor(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz)     # as cast_iso_ray
    t, i, j, k, u, v, w, solves = _walk_anchored(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, variant, rec, n0, ta > 0.0)
    return ta + t, i, j, k, u, v, w, solves


@kernel
def _walk_anchored(data, Ox, Oy, Oz, Dx, Dy, Dz, iso, variant, rec, n0, anchored):
    """`walk_iso_ray` on an anchored ray."""
    nz, ny, nx = data.shape
    t_in, t_out = clip_box(Ox, Oy, Oz, Dx, Dy, Dz, nx, ny, nz)
    solves = 0
    if not t_in <= t_out:
        return math.inf, -1, -1, -1, 0.0, 0.0, 0.0, solves
    i, j, k, sx, sy, sz, ix, iy, iz, tx0, tx1, ty0, ty1, tz0, tz1 = walk_from(Ox, Oy, Oz, Dx, Dy, Dz, t_in,
                                                                             nx, ny, nz)
    prev = 0.0
    rounded = False         # as in `raycast.iso._walk_iso`: prev is a cubic rounded at its exit
    record = rec.shape[0] > 0
    while True:
        c0 = max(t_in, max(tx0, max(ty0, tz0)))
        c1 = min(t_out, min(tx1, min(ty1, tz1)))
        v000, v100, v010, v110, v001, v101, v011, v111, lo, hi = corners(data, iso, i, j, k)
        if lo > 0.0 or hi < 0.0:
            sign = 1.0 if lo > 0.0 else -1.0
            if rounded and prev * sign < 0.0:
                return c0, i, j, k, (Ox - i) + c0 * Dx, (Oy - j) + c0 * Dy, (Oz - k) + c0 * Dz, solves
            prev = sign
            rounded = False
        elif c0 <= c1:
            A, B, C, D, u0, v0, w0 = cell_cubic(v000, v100, v010, v110, v001, v101, v011, v111,
                                                Ox, Oy, Oz, Dx, Dy, Dz, i, j, k, c0)
            if c0 > t_in:
                if prev != 0.0 and D != 0.0 and (D < 0.0) != (prev < 0.0):
                    return c0, i, j, k, u0, v0, w0, solves
            elif on_level_face(v000, v100, v010, v110, v001, v101, v011, v111, tx0, ty0, tz0,
                               entry_face_time(tx0, ty0, tz0, c0, anchored), sx, sy, sz, False):
                return c0, i, j, k, u0, v0, w0, solves
            L = c1 - c0
            if record:
                m = n0 + solves
                rec[m, 0] = A
                rec[m, 1] = B
                rec[m, 2] = C
                rec[m, 3] = D
                rec[m, 4] = L
            solves += 1
            s = _solve(variant, A, B, C, D, L)
            if s >= 0.0:
                return c0 + s, i, j, k, u0 + s * Dx, v0 + s * Dy, w0 + s * Dz, solves
            if c1 == t_out and on_level_face(v000, v100, v010, v110, v001, v101, v011, v111,
                                             tx1, ty1, tz1, c1, sx, sy, sz, True):
                return c1, i, j, k, u0 + L * Dx, v0 + L * Dy, w0 + L * Dz, solves
            f = eval_cubic(A, B, C, D, L)
            prev = 1.0 if f > 0.0 else (-1.0 if f < 0.0 else 0.0)
            rounded = True
        if c1 >= t_out:
            break
        inside, i, j, k, tx0, tx1, ty0, ty1, tz0, tz1 = step_cell(Ox, Oy, Oz, sx, sy, sz, ix, iy, iz, i, j, k,
                                                                  tx0, tx1, ty0, ty1, tz0, tz1, nx, ny, nz)
        if not inside:
            break
    return math.inf, -1, -1, -1, 0.0, 0.0, 0.0, solves


@kernel
def walk_rays(data, org, spc, origins, dirs, isos, variant, t, cell, uvw, solves, rec, offsets):
    """`walk_iso_ray` for world rays ``origins[n] + t dirs[n]`` at isovalue ``isos[n]`` (one thread)."""
    for n in range(origins.shape[0]):
        Ox, Oy, Oz, Dx, Dy, Dz = to_index_space(
            origins[n, 0], origins[n, 1], origins[n, 2], dirs[n, 0], dirs[n, 1], dirs[n, 2], org, spc)
        res = walk_iso_ray(data, Ox, Oy, Oz, Dx, Dy, Dz, isos[n], variant, rec, offsets[n])
        t[n] = res[0]
        cell[n, 0] = res[1]
        cell[n, 1] = res[2]
        cell[n, 2] = res[3]
        uvw[n, 0] = res[4]
        uvw[n, 1] = res[5]
        uvw[n, 2] = res[6]
        solves[n] = res[7]


@kernel
def solve_all(rec, variant, reps):
    """Solve every recorded cubic ``reps`` times with ``variant``; returns a checksum.

    One loop per finder, so the timed inner loop holds nothing but the call.
    """
    acc = 0.0
    n = rec.shape[0]
    for _ in range(reps):
        if variant == CLOSED_FORM:
            for m in range(n):
                acc += first_root_closed_form(rec[m, 0], rec[m, 1], rec[m, 2], rec[m, 3], rec[m, 4])
        elif variant == MARMITT:
            for m in range(n):
                acc += first_root_marmitt(rec[m, 0], rec[m, 1], rec[m, 2], rec[m, 3], rec[m, 4])
        else:
            for m in range(n):
                acc += first_root(rec[m, 0], rec[m, 1], rec[m, 2], rec[m, 3], rec[m, 4])
    return acc


# ---------------------------------------------------------------- drivers

def walk(data, org, spc, origins, dirs, isos, variant, record=False):
    """``(t, cell, uvw, rec)`` of world rays walked with ``variant``; ``rec`` the cubics solved, in ray order, if asked."""
    n = len(origins)
    t, cell, uvw = np.empty(n), np.empty((n, 3), np.int32), np.zeros((n, 3))
    solves, offsets = np.zeros(n, np.int64), np.zeros(n, np.int64)
    args = (data, org, spc, origins, dirs, isos, variant, t, cell, uvw, solves)
    walk_rays(*args, np.empty((0, 5)), offsets)
    rec = None
    if record:
        offsets[1:] = np.cumsum(solves)[:-1]
        rec = np.empty((int(solves.sum()), 5))
        walk_rays(*args, rec, offsets)
    return t, cell, uvw, rec


def _walk(batch, variant, record=False):
    """`walk` over one batch of the hard-ray suite."""
    return walk(batch.scene.data, batch.scene.origin, batch.scene.spacing, batch.origins, batch.dirs,
                batch.isos, variant, record)


def _aimed_at(batch, m, t, r, roots):
    """Whether the hit ``t`` of ray ``m`` is an answer for the root ``r``: ``r`` is the
    true root nearest to it, less than a cell away on every axis."""
    if not np.isfinite(t) or min(roots, key=lambda x: abs(t - x)) != r:
        return False
    step = (float(t) - r) * batch.dirs[m] / batch.scene.spacing
    return float(np.max(np.abs(step))) < 1.0


def _suite(n, seed):
    from raycast.hardcases import CATEGORIES, hard_batches
    return [b for c in CATEGORIES for b in hard_batches(c, n, seed)]


def _time_solves(rec, repeats=3):
    """Best-of-``repeats`` nanoseconds per solve of each variant on the cubics ``rec``, interleaved."""
    reps = max(1, math.ceil(TIMED_SOLVES / max(1, len(rec))))
    for _, code, _ in VARIANTS:                 # compile or load, and warm the caches
        solve_all(rec[:16], code, 1)
    best = {code: math.inf for _, code, _ in VARIANTS}
    for _ in range(repeats):
        for _, code, _ in VARIANTS:
            t0 = time.perf_counter_ns()
            solve_all(rec, code, reps)
            best[code] = min(best[code], time.perf_counter_ns() - t0)
    return {code: best[code] / (reps * len(rec)) for code in best}


def root_study(quick=False, n=None, *, seed=0, progress=None):
    """Speed, accuracy and failures of three cubic root finders on the hard-ray suite.

    Parameters
    ----------
    quick : bool, default False
        Use ``QUICK_RAYS_PER_CATEGORY`` rays per category (under half a
        minute) instead of the whole suite, ``FULL_RAYS_PER_CATEGORY``
        (a few minutes, mostly the mpmath truth on 2 cores).
    n : int, optional
        Rays per category; overrides ``quick``.
    seed : int, default 0
        Suite seed (0 is the suite the tests check).
    progress : callable(message) or None
        Told as each stage starts (walking the suite, timing, the mpmath truth): a first run
        compiles the finders' walks, and the truth takes tens of seconds.

    Returns
    -------
    list of dict
        One row per finder, in `VARIANTS` order, with ``name``,
        ``description``, ``ns_per_solve`` (best of 3, single thread),
        ``solves`` (cubics in the timed set), ``rays``, ``required`` (rays
        with a required root), ``failures`` and its parts ``missed``,
        ``false``, ``wrong``, ``inaccurate``, ``cell``, ``max_err_cells`` and
        ``median_err_cells`` (see the module docstring), and
        ``failures_by_category`` (a dict).

    Raises
    ------
    RuntimeError
        If the study's walk with the project's finder does not reproduce
        `raycast.iso.cast_iso_rays` bit for bit (the walk has drifted from
        the caster's; the comparison would not be honest).

    Notes
    -----
    See the module docstring for what is measured and why.
    """
    from raycast.hardcases import cast_batch
    from raycast.reference import judge_batches

    per_cat = n if n is not None else (QUICK_RAYS_PER_CATEGORY if quick else FULL_RAYS_PER_CATEGORY)
    say = progress or (lambda message: None)
    batches = _suite(per_cat, seed)
    say(f"walking {sum(len(b.origins) for b in batches):,} rays with each finder")
    answers, recs = [], []
    for b in batches:
        row = []
        for _, code, _ in VARIANTS:
            t, cell, uvw, rec = _walk(b, code, record=code == PROJECT)
            row.append((t, cell, uvw))
            if rec is not None:
                recs.append(rec)
        ref_t, ref_cell, ref_uvw, _ = cast_batch(b)
        t, cell, uvw = row[0]
        hit = np.isfinite(ref_t)
        if not (np.array_equal(t, ref_t) and np.array_equal(cell[hit], ref_cell[hit])
                and np.array_equal(uvw[hit], ref_uvw[hit])):
            raise RuntimeError("parc.rootstudy: the study's walk no longer matches "
                               "raycast.iso.cast_iso_ray; update walk_iso_ray")
        answers.append(row)
    rec = np.ascontiguousarray(np.concatenate(recs))
    say(f"timing {len(rec):,} cubics with each finder")
    ns = _time_solves(rec)
    say("the mpmath truth of every ray")

    judged = judge_batches([(b.scene, b.origins, b.dirs, b.isos, row)
                            for b, row in zip(batches, answers)])
    rows = []
    for v, (name, code, desc) in enumerate(VARIANTS):
        kinds, by_cat, errs = Counter(), Counter(), []
        rays = required = 0
        for b, row, res in zip(batches, answers, judged):
            h = float(np.min(b.scene.spacing))
            t = row[v][0]
            for m, (first, roots, verdicts) in enumerate(res):
                rays += 1
                outcome, _, kind = verdicts[v]
                if first is not None:
                    required += 1
                    if _aimed_at(b, m, t[m], first[0], roots):
                        errs.append(abs(float(t[m]) - first[0]) / h)
                if outcome == "FAIL":
                    kinds[kind] += 1
                    by_cat[b.category] += 1
        rows.append(dict(
            name=name, description=desc, ns_per_solve=ns[code], solves=len(rec),
            rays=rays, required=required, failures=sum(kinds.values()),
            **{k: kinds[k] for k in FAILURE_KINDS},
            max_err_cells=max(errs, default=0.0),
            median_err_cells=statistics.median(errs) if errs else 0.0,
            failures_by_category=dict(by_cat)))
    return rows


def format_table(rows):
    """The study's rows as a text table (one line per finder, then the failures per category)."""
    head = (f"{'finder':12s} {'ns/solve':>9s} {'max err':>9s} {'med err':>9s} {'fail':>6s} "
            f"{'missed':>6s} {'false':>6s} {'wrong':>6s} {'inacc':>6s} {'cell':>5s}")
    lines = [f"hard-ray suite: {rows[0]['rays']:,} rays ({rows[0]['required']:,} with a required "
             f"root), {rows[0]['solves']:,} cubics timed; errors |t - r| in smallest spacings", head]
    for r in rows:
        lines.append(f"{r['name']:12s} {r['ns_per_solve']:9.1f} {r['max_err_cells']:9.2e} "
                     f"{r['median_err_cells']:9.2e} {r['failures']:6d} {r['missed']:6d} "
                     f"{r['false']:6d} {r['wrong']:6d} {r['inaccurate']:6d} {r['cell']:5d}")
    lines.append("failures by category:")
    for r in rows:
        cats = ", ".join(f"{k} {v}" for k, v in sorted(r["failures_by_category"].items())) or "none"
        lines.append(f"  {r['name']:12s} {cats}")
    for r in rows:
        lines.append(f"  {r['name']}: {r['description']}")
    return "\n".join(lines)


def main(argv=None):
    import argparse
    import json
    p = argparse.ArgumentParser(prog="python -m parc.rootstudy",
                                description="Cubic root finders on the hard-ray suite.")
    p.add_argument("--quick", action="store_true", help=f"{QUICK_RAYS_PER_CATEGORY} rays per category")
    p.add_argument("--n", type=int, help="rays per category (overrides --quick)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    rows = root_study(args.quick, args.n, seed=args.seed)
    print(json.dumps(rows, indent=1) if args.json else format_table(rows))
    print(f"({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
