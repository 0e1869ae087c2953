"""Slow, obvious high-precision reference for ray/isosurface hits, and the acceptance rule.

The truth for the hard-ray suite (`raycast.hardcases`): used by the
correctness tests and by the root-finder study (`parc.rootstudy`). Needs
mpmath; nothing in the renderer imports this module.

Source of truth
---------------
An *exact-trilinear* field (index coordinates i, j, k)

    F(i, j, k) = c0 + c1 i + c2 j + c3 k + c4 ij + c5 jk + c6 ki + c7 ijk

is reproduced exactly by trilinear interpolation of its samples, so the
caster's isosurface is exactly ``{F = iso}``. With integer or dyadic
coefficients the samples are exact in float64 (and in uint16/int16 when they
fit), the ray ``p(t) = o + t d`` is given by float64 numbers, and along it

    P(t) = F((o - origin + t d) / spacing) - iso

is an exact cubic in ``t``. Everything below is computed from those exact
inputs in mpmath at ``DPS`` = 40 digits (errors ~1e-40 relative, far below
any tolerance used here): the box interval, every real root of ``P`` in it
(the derivative's roots split the interval into monotone pieces; sign
tests; a safeguarded Newton/bisection to ~1e-32; a critical point where
``|P|`` is ~0 is reported as a touching (double) root), and ``P, P'`` at
the caster's answer.

Acceptance rule (`judge`)
-------------------------
Notation: ``h = min(spacing)`` (world units, like ``t``); ``eps = 2**-52``;
for a point on the ray, ``S`` = the largest ``|sample - iso|`` over the
corners of the cell(s) holding the point (the numbers the caster's cubic
is built from), ``g`` = grad F in index units there, and per axis
``dpos_a = 8 eps (|O_a| + n_a + 1)`` bounds the rounding of the caster's
index-space position along that axis (``O = (o - origin)/spacing``, the
cell-local offset ``(O - i) + c0 D`` and ``D`` itself are rounded;
``n_a`` = grid size; the point is in the box, so ``|c0 D_a| <= |O_a| + n_a``).
The float evaluation error scale of the caster's cubic is

    E = 64 eps S + sum_a dpos_a |g_a|.

1. A true root ``r`` is *simple* when its conditioning
   ``dt = E(r) / |P'(r)| <= 1e-10 h``. It is *required* when it is simple,
   ``r > 1e-9 h`` (not at the ray start) and it lies in the box shrunk by
   ``pad_a = 1e-12 + dpos_a`` index units per side (roots within rounding
   of the box may go either way). All other roots in the box grown by
   ``pad`` are *optional* (double and near-double roots, roots at the box
   boundary).
1b. The first root ``r1`` of a pair ``r1 < r2`` that is not simple is
   required too (tolerance ``max(tol, 16 dt(r1))``) when the cubic's
   extremum between them is at least ``100 E`` from zero: floating point
   surely separates the two roots there, so the first must be taken.
2. If a required root exists, the first one ``r*`` must be hit:
   ``t_m`` finite and, if ``t_m >= r* - tol``, ``|t_m - r*| <= tol`` with
   ``tol = 1e-9 h + 4 eps |r*|`` (the last term is the rounding of ``t``
   itself; <= 1e-10 h for the distances used here). A hit later than
   ``r* + tol`` fails (a simple root was skipped).
3. A hit earlier than every required root (or with no required root) must
   be explained by an optional root ``r`` -- ``|t_m - r| <= max(tol,
   min(16 dt(r), 1e-6 h))`` -- or be rounding noise at a near-tangency:
   ``|P(t_m)| <= 10 E(t_m) + 1e-9 h |P'(t_m)|`` (a double root, or a
   near miss within the evaluation error, may be hit anywhere the cubic is
   within its rounding of zero). A missed optional root is fine, so a
   missed double root may be followed by a hit on the next root.
4. A hit must lie in the box grown by ``pad`` (in ``t``, up to ``tol``),
   and, when given, the reported cell and local coordinates must agree with
   the hit point: ``uvw`` in ``[-1e-9, 1 + 1e-9]`` and
   ``|cell + uvw - I(t_m)| <= 1e-9 + 16 dpos_a`` on axis ``a``.

Why this is not weaker than "exact": a required root has a conditioning
10x below its tolerance, so every rounding the caster legitimately does is
covered with margin; whatever falls outside is a real miss, a skipped cell,
a wrong interval or a wrong root. The only freedoms are where floating
point genuinely cannot decide (tangencies, box boundary, ray start). ``S``
is taken over ``|sample - iso|`` (the caster subtracts ``iso`` first, and
that subtraction is correctly rounded), which is smaller, so stricter, than
``max(|iso|, |sample|)``. The position term ``dpos`` matters only far from
the origin of the index space (long grids, far eyes): there the caster's
rounded index-space ray really is ~``eps |O|`` away from the exact one.
Measured on the hard-ray suite, the caster's error on required roots stays
below ~1.2 ``(eps S + dpos |g| / 8) / |P'(r)|``, i.e. under 0.2% of ``tol``.

The cubic and its roots in high precision are `raycast.mpcubic`'s.
`exact_cell_count` is the traversal reference: the number of cells a ray
passes through with positive length, from exact rational plane-crossing
times (see its docstring for the allowed differences).
"""
import math
import os
from collections import Counter, defaultdict
from fractions import Fraction

import numpy as np

from .config import at_exit
from .hardcases import cast_batch
from .hardfields import field_grad
from .mpcubic import _critical_points, box_intervals, index_ray, mpf, pderiv, peval, ray_cubic, real_roots

EPS = 2.0 ** -52
SIMPLE_REL = 1e-10      # dt <= SIMPLE_REL * h  -> simple root
HIT_REL = 1e-9          # |t_m - r| <= HIT_REL * h for a simple root
BOX_PAD = 1e-12         # index units, plus dpos
NONSIMPLE_REL = 1e-6    # cap of the conditioned tolerance of optional roots
NOISE_FACTOR = 10.0     # |P(t_m)| <= NOISE_FACTOR * E(t_m) + ...
RESOLVABLE = 100.0      # |P(e)| >= RESOLVABLE * E(e) between two roots: float sees them apart


# ------------------------------------------------------- acceptance rule

def _cell_span(x, n):
    """Sample-index range [a, b] covering the cell(s) that hold index coordinate x."""
    m = int(math.floor(x))
    cells = {m}
    if x - m < 1e-6:
        cells.add(m - 1)
    if m + 1 - x < 1e-6:
        cells.add(m + 1)
    cells = {min(max(c, 0), n - 2) for c in cells}
    return min(cells), max(cells) + 1


def _local_scale(scene, iso, I):
    """(S, g): largest |sample - iso| over the cell(s) holding index point I, grad F there."""
    nz, ny, nx = scene.shape
    x0, x1 = _cell_span(I[0], nx)
    y0, y1 = _cell_span(I[1], ny)
    z0, z1 = _cell_span(I[2], nz)
    block = scene.data[z0:z1 + 1, y0:y1 + 1, x0:x1 + 1].astype(np.float64)
    S = float(np.max(np.abs(block - iso)))
    return S, field_grad(scene.coeffs, *I)


class Truth:
    """Reference facts about one ray; see the module docstring for the rule."""

    def __init__(self, scene, o, d, iso):
        self.scene, self.iso = scene, float(iso)
        self.h = float(min(scene.spacing))
        O, D = index_ray(scene, o, d)
        self.O, self.D = O, D
        nz, ny, nx = scene.shape
        self.dpos = [8 * EPS * (abs(float(O[a])) + n + 1) for a, n in enumerate((nx, ny, nz))]
        self.pad = [BOX_PAD + x for x in self.dpos]
        self.p = ray_cubic(scene, O, D, iso)
        self.outer, self.inner = box_intervals(scene, O, D, self.pad)
        self.roots = []   # (t, dt, required, tol) as floats, t ascending
        for r, touching in real_roots(self.p, *self.outer):
            rf = float(r)
            E = self.error_scale(rf)
            dP = abs(float(pderiv(self.p, r)))
            dt = math.inf if touching or dP == 0 else E / dP
            tol = HIT_REL * self.h + 4 * EPS * abs(rf)
            required = (dt <= SIMPLE_REL * self.h and rf > HIT_REL * self.h
                        and self.inner[0] <= r <= self.inner[1])
            if not required:
                tol = max(tol, min(16 * dt, NONSIMPLE_REL * self.h))
            self.roots.append((rf, dt, required, tol))
        self._require_a_resolvable_pair()

    def _require_a_resolvable_pair(self):
        """Rule 1b: the first root of a close pair is required too when float evaluation surely
        sees the dip between them (``|P(e)| >= 100 E(e)`` at the critical point ``e``), though
        the pair leaves it too ill-conditioned to be simple: a caster taking the second root
        or neither would pass rule 3, and one did (a search that stepped over shallow dips)."""
        if len(self.roots) < 2 or self.roots[0][2]:
            return
        (r1, dt1, _, _), r2 = self.roots[0], self.roots[1][0]
        # Inside the box by more than its own conditioning: a root within 16 dt of the entry face
        # may lie on either side of it for float (a level set grazing a grid plane there).
        if not (r1 > HIT_REL * self.h and self.inner[0] + 16 * dt1 <= r1 <= self.inner[1] - 16 * dt1):
            return
        between = [e for e in _critical_points(self.p) if r1 < e < r2]
        if between and abs(float(peval(self.p, between[0]))) >= RESOLVABLE * self.error_scale(float(between[0])):
            self.roots[0] = (r1, dt1, True, max(HIT_REL * self.h + 4 * EPS * abs(r1), 16 * dt1))

    def point(self, t):
        return [float(self.O[a] + mpf(t) * self.D[a]) for a in range(3)]

    def error_scale(self, t):
        """E(t) = 64 eps S + sum_a dpos_a |dF/dI_a| at the ray point of parameter t."""
        S, g = _local_scale(self.scene, self.iso, self.point(t))
        return 64 * EPS * S + sum(p * abs(x) for p, x in zip(self.dpos, g))

    def first_required(self):
        for r in self.roots:
            if r[2]:
                return r
        return None


def judge(tr, t_m, cell=None, uvw=None):
    """``(outcome, reason, kind)`` of the answer ``t_m`` (inf = miss) for the ray of `Truth` ``tr``.

    ``outcome`` is 'hit', 'miss', 'optional', 'noise' or 'FAIL':
    'hit'/'miss': agrees with a required root / with no root at all;
    'optional': hit or missed an optional (double, near-double, boundary)
    root; 'noise': a hit explained only as rounding at a near-tangency.
    ``reason`` explains a 'FAIL' (else None), and ``kind`` sorts it (see
    `_hit_kind`): 'missed' (a required root, no hit), 'inaccurate' (a hit
    within a cell of the true root nearest to it, outside its tolerance),
    'wrong' (a hit past the first required root, within a cell of a later
    one: the first was skipped), 'false' (a hit further than a cell from
    every root, or outside the box), 'cell' (the cell or local coordinates
    disagree with ``t_m``).
    """
    req = tr.first_required()
    if not math.isfinite(t_m):
        if req is not None:
            return "FAIL", f"missed simple root r={req[0]!r} (dt={req[1]:.3g})", "missed"
        return ("optional" if tr.roots else "miss"), None, None
    lo_box, hi_box = float(tr.outer[0]), float(tr.outer[1])
    tol0 = HIT_REL * tr.h + 4 * EPS * abs(t_m)
    if not (lo_box - tol0 <= t_m <= hi_box + tol0):
        return "FAIL", f"hit t={t_m!r} outside box interval [{lo_box!r}, {hi_box!r}]", "false"
    outcome = None
    if req is not None and t_m >= req[0] - req[3]:
        if abs(t_m - req[0]) <= req[3]:
            outcome = "hit"
        else:
            return "FAIL", (f"hit t={t_m!r} but the first simple root is r={req[0]!r} "
                            f"(err {t_m - req[0]:.3g}, tol {req[3]:.3g})"), _hit_kind(tr, t_m)
    if outcome is None:
        for r, dt, required, tol in tr.roots:
            if not required and abs(t_m - r) <= tol:
                outcome = "optional"
                break
    if outcome is None:
        P = abs(float(peval(tr.p, mpf(t_m))))
        dP = abs(float(pderiv(tr.p, mpf(t_m))))
        bound = NOISE_FACTOR * tr.error_scale(t_m) + HIT_REL * tr.h * dP
        if P <= bound:
            outcome = "noise"
        else:
            roots = ", ".join(f"{r[0]!r}{'*' if r[2] else ''}" for r in tr.roots) or "none"
            return "FAIL", (f"spurious hit t={t_m!r}: |P|={P:.3g} > {bound:.3g}; "
                            f"true roots: {roots}"), _hit_kind(tr, t_m)
    if cell is not None and uvw is not None:
        I = tr.point(t_m)
        for a in range(3):
            ctol = 1e-9 + 16 * tr.dpos[a]
            if not (-1e-9 <= uvw[a] <= 1 + 1e-9):
                return "FAIL", f"local coordinate {uvw[a]!r} outside the cell (axis {a})", "cell"
            if abs(cell[a] + uvw[a] - I[a]) > ctol:
                return "FAIL", (f"cell {tuple(cell)} + uvw {tuple(uvw)} != hit point {I} "
                                f"(axis {a})"), "cell"
    return outcome, None, None


def _hit_kind(tr, t_m):
    """How a hit that fails rule 2 or 3 is wrong: 'inaccurate', 'wrong' or 'false'.

    Measured against the true root nearest to ``t_m``, in index space: within
    one cell of it (less than 1 on every axis) the finder found that root,
    imprecisely ('inaccurate'), unless it lies past the first required root,
    which was then skipped ('wrong'). Further from every root: 'false'.
    """
    if not tr.roots:
        return "false"
    r = min(tr.roots, key=lambda x: abs(t_m - x[0]))
    if max(abs(a - b) for a, b in zip(tr.point(t_m), tr.point(r[0]))) >= 1.0:
        return "false"
    req = tr.first_required()
    return "wrong" if req is not None and r[0] > req[0] else "inaccurate"


# ------------------------------------------------------- batch checking
# Checks run in a pool of worker processes (one per available core, at most
# 8; set PARC_TEST_WORKERS to override, 1 for none).

def _judge_chunk(args):
    """Per ray: the first required root ``(r, tol)`` or None, all roots, `judge` of each answer."""
    scene, origins, dirs, isos, answers = args
    out = []
    for n in range(len(origins)):
        tr = Truth(scene, origins[n], dirs[n], isos[n])
        req = tr.first_required()
        out.append(((req[0], req[3]) if req is not None else None,
                    tuple(r[0] for r in tr.roots),
                    [judge(tr, float(t[n]), cell[n], uvw[n]) for t, cell, uvw in answers]))
    return out


def _workers():
    env = os.environ.get("PARC_TEST_WORKERS")
    if env:
        return max(1, int(env))
    try:
        return max(1, min(len(os.sched_getaffinity(0)), 8))
    except AttributeError:
        return 1


_POOL = None


def _pool():
    """A process pool shared by all checks of a session (spawned: the
    parent has Numba threads, which must not be forked).

    Its workers start with SIGINT ignored (an ignored signal stays ignored
    through exec, and Python then installs no handler for it): a terminal's
    Ctrl-C reaches the whole process group, and workers interrupted while
    starting or waiting on the task queue printed tracebacks, and could die
    holding the queue's lock, so that terminating the pool at exit waited
    forever. The parent alone stops, and terminates them (SIGTERM)."""
    global _POOL
    if _POOL is None and _workers() > 1:
        import multiprocessing as mpc
        import signal
        try:
            was = signal.signal(signal.SIGINT, signal.SIG_IGN)
        except ValueError:                  # not the main thread: its workers keep Ctrl-C
            was = None
        try:
            _POOL = mpc.get_context("spawn").Pool(_workers())
        finally:
            if was is not None:
                signal.signal(signal.SIGINT, was)
        at_exit(_end_pool, _POOL)
    return _POOL


def _end_pool(pool):
    """Terminate the pool at exit with Ctrl-C ignored: the work is done, and an interrupt in
    its 0.2 s printed the atexit machinery's traceback after a run's last line."""
    import signal
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:          # not the main thread
        pass
    pool.terminate()


def judge_batches(batches, chunk=500):
    """Judge several answers for many rays.

    Parameters
    ----------
    batches : list of (scene, origins, dirs, isos, answers)
        ``answers`` is a list of ``(t, cell, uvw)``, one per caster (or
        root finder) being judged, each with one entry per ray.
    chunk : int, default 500
        Rays per job handed to a worker process.

    Returns
    -------
    list, per batch, of per-ray ``(first, roots, verdicts)``: ``first`` is
    the first required root ``(r, tol)`` or None, ``roots`` the ``t`` of
    every true root in the box (required or optional, ascending),
    ``verdicts`` one `judge` triple per answer. The truth of a ray is computed once whatever the
    number of answers. Rays of the same scene are pooled into chunks for
    the worker processes.
    """
    by_scene = {}
    for b, batch in enumerate(batches):
        by_scene.setdefault(id(batch[0]), []).append(b)
    jobs, where = [], []
    for members in by_scene.values():
        scene = batches[members[0]][0]
        cols = [np.concatenate([np.asarray(batches[b][c]) for b in members]) for c in (1, 2, 3)]
        n_ans = len(batches[members[0]][4])
        answers = [[np.concatenate([np.asarray(batches[b][4][v][c]) for b in members])
                    for c in range(3)] for v in range(n_ans)]
        owner = [(b, m) for b in members for m in range(len(batches[b][1]))]
        for s in range(0, len(owner), chunk):
            part = slice(s, s + chunk)
            jobs.append((scene,) + tuple(x[part] for x in cols)
                        + ([tuple(x[part] for x in ans) for ans in answers],))
            where.append(owner[part])
    pool = _pool()
    results = pool.map(_judge_chunk, jobs, chunksize=1) if pool else map(_judge_chunk, jobs)
    out = [[None] * len(b[1]) for b in batches]
    for owners, res in zip(where, results):
        for (b, m), r in zip(owners, res):
            out[b][m] = r
    return out


def check_batches(batches, chunk=500):
    """Check many rays. ``batches``: list of (scene, origins, dirs, isos, t, cell, uvw).

    Returns a list, per batch, of per-ray ``(outcome, reason)``.
    """
    judged = judge_batches([(sc, o, d, iso, [(t, cell, uvw)]) for sc, o, d, iso, t, cell, uvw in batches],
                           chunk)
    return [[verdicts[0][:2] for _, _, verdicts in rays] for rays in judged]


def run_batches(batches):
    """Cast (unaccelerated) and check every `raycast.hardcases.Batch`.

    Returns ``(stats, failures)``: outcome counts per category, and one
    ``(category, scene name, origin, direction, iso, t, reason)`` per failure.
    """
    results = [cast_batch(b) for b in batches]
    checks = check_batches([(b.scene, b.origins, b.dirs, b.isos, r[0], r[1], r[2])
                            for b, r in zip(batches, results)])
    stats = defaultdict(Counter)
    failures = []
    for b, r, chk in zip(batches, results, checks):
        for m, (outcome, reason) in enumerate(chk):
            stats[b.category][outcome] += 1
            if outcome == "FAIL":
                failures.append((b.category, b.scene.name, b.origins[m].tolist(),
                                 b.dirs[m].tolist(), float(b.isos[m]), float(r[0][m]), reason))
    return stats, failures


# ----------------------------------------------------- traversal reference

def exact_cell_count(scene, o, d, near=1e-12):
    """Cells a ray passes through, from exact rational plane-crossing times.

    Returns ``(n_cells, n_steps, n_uncertain)``:

    * ``n_cells`` = cells the ray passes through with positive length:
      ``1 +`` the number of *distinct* crossing times of integer planes
      strictly inside the box interval ``(t_in, t_out)`` (0 if it is empty);
    * ``n_steps`` = ``1 +`` the number of plane crossings counted once per
      plane. An axis-by-axis walk (Amanatides-Woo) visits one cell per plane
      crossed whatever their order, so it visits ``n_steps`` cells; where the
      ray passes exactly through an edge or vertex it visits a zero-length
      cell, and ``n_steps - n_cells`` is the number of such coincidences;
    * ``n_uncertain`` = plane crossings that floating point may put on
      either side of a box end, each of which may add or remove one visited
      cell. The caster computes a crossing time as ``(m - O') / D'`` from its
      rounded index-space ray ``O' = fl((o - origin) / spacing)``,
      ``D' = fl(d / spacing)``; against the exact ``O, D`` that time is off by
      at most ``w_a(t) = |O' - O| / |D| + |t| |D' - D| / |D| + 4 eps |t|``,
      plus ``near / max|D|`` (``near`` index units along the ray). The box
      ends are slab crossings too, so the caster's ``t_in`` / ``t_out`` lie in
      windows (max / min over the axes of each slab end +- its ``w``). A
      plane crossing within ``2 w`` of such a window is uncertain; if the two
      windows overlap, or a ray parallel to a box face lies in it up to
      rounding, or a direction component is below the caster's
      ``TINY_DIRECTION`` while not zero, anything goes (``n_uncertain``
      infinite).
    """
    from .traverse import TINY_DIRECTION
    nz, ny, nx = scene.shape
    n = (nx, ny, nz)
    o64, d64 = np.asarray(o, np.float64), np.asarray(d, np.float64)
    Ok = (o64 - scene.origin) / scene.spacing          # as the caster rounds them
    Dk = d64 / scene.spacing
    O = [(Fraction(float(o64[a])) - Fraction(float(scene.origin[a])))
         / Fraction(float(scene.spacing[a])) for a in range(3)]
    D = [Fraction(float(d64[a])) / Fraction(float(scene.spacing[a])) for a in range(3)]
    errO = [float(abs(Fraction(float(Ok[a])) - O[a])) for a in range(3)]
    errD = [float(abs(Fraction(float(Dk[a])) - D[a])) for a in range(3)]
    speed = max(abs(float(x)) for x in D)

    def wobble(a, t):
        t = abs(float(t))
        return (errO[a] + t * errD[a]) / abs(float(D[a])) + 4 * EPS * t + near / speed

    # Exact box interval, and the windows the caster's rounded t_in / t_out
    # may fall in (each slab end moves by its own axis's wobble).
    t_in, t_out = Fraction(0), None
    in_lo = in_hi = 0.0
    out_lo = out_hi = math.inf
    for a in range(3):
        if D[a] != 0 and abs(Dk[a]) < TINY_DIRECTION:
            return 0, 0, math.inf
        if D[a] == 0:
            inside = 0 <= O[a] <= n[a] - 1
            if inside != (0 <= Ok[a] <= n[a] - 1):
                return 0, 0, math.inf
            if not inside:
                return 0, 0, 0
            continue
        t0, t1 = (0 - O[a]) / D[a], (n[a] - 1 - O[a]) / D[a]
        t0, t1 = min(t0, t1), max(t0, t1)
        t_in = max(t_in, t0)
        t_out = t1 if t_out is None else min(t_out, t1)
        w0, w1 = wobble(a, t0), wobble(a, t1)
        in_lo, in_hi = max(in_lo, float(t0) - w0), max(in_hi, float(t0) + w0)
        out_lo, out_hi = min(out_lo, float(t1) - w1), min(out_hi, float(t1) + w1)
    if out_hi < in_lo:
        return 0, 0, 0
    if out_lo <= in_hi:
        return 0, 0, math.inf
    times, uncertain = [], 0
    for a in range(3):
        if D[a] == 0:
            continue
        for lo_t, hi_t in ((in_lo, in_hi), (out_lo, out_hi)):
            w = 2 * wobble(a, hi_t)
            x0 = O[a] + Fraction(lo_t - w) * D[a]
            x1 = O[a] + Fraction(hi_t + w) * D[a]
            # interior planes only: the walk never steps across a box face
            top, bottom = min(math.floor(max(x0, x1)), n[a] - 2), max(math.ceil(min(x0, x1)), 1)
            uncertain += max(0, top - bottom + 1)
        x0, x1 = O[a] + t_in * D[a], O[a] + t_out * D[a]
        lo, hi = min(x0, x1), max(x0, x1)
        times.extend((m - O[a]) / D[a] for m in range(math.floor(lo) + 1, math.ceil(hi)))
    return 1 + len(set(times)), 1 + len(times), uncertain
