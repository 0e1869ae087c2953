"""Unit tests of `raycast.cubic.first_root` on known cubics, against mpmath.

Source of truth: the real roots of ``a s^3 + b s^2 + c s + d`` in ``[0, L]``
computed in mpmath (40 digits) from the exact float64 coefficients
(`raycast.mpcubic.real_roots`). The cubic is the caster's own input, so the only
legitimate error is the float evaluation of the cubic, bounded by
``e(s) = 8 eps (|a| s^3 + |b| s^2 + |c| s + |d|)`` (Horner). Tolerance:

* a root ``r`` is *simple* when ``dr = e(r) / |P'(r)| <= 1e-8 L``; the first
  root, if simple, must be returned with ``|s - r| <= 1e-14 L + 4 dr``
  (the root finder stops at 1e-15 of the interval);
* other roots (double, triple, close pairs) are optional: returning one
  means ``|s - r| <= 1e-14 L + 4 dr`` with ``dr`` capped at 1e-6 L, or
  ``|P(s)| <= 4 e(s)`` (the cubic is within its rounding of zero there);
  missing one is allowed, so a missed double root may be followed by the
  next root;
* "no root" (-1) is right only when there is no simple root.
"""
import math

import numpy as np
import pytest

from raycast.mpcubic import mpf, pderiv, peval, real_roots
from raycast.reference import EPS
from raycast.cubic import bernstein, eval_cubic, first_root, sign_changes


def _eval_bound(a, b, c, d, s):
    s = abs(s)
    return 8 * EPS * (abs(a) * s ** 3 + abs(b) * s ** 2 + abs(c) * s + abs(d))


def judge(a, b, c, d, L, s_m):
    """None if ``first_root(a, b, c, d, L) == s_m`` is acceptable, else the reason."""
    p = [mpf(d), mpf(c), mpf(b), mpf(a)]
    roots = []
    for r, touching in real_roots(p, mpf(0), mpf(L)):
        rf = float(r)
        dP = abs(float(pderiv(p, r)))
        dr = math.inf if touching or dP == 0 else _eval_bound(a, b, c, d, rf) / dP
        roots.append((rf, dr, dr <= 1e-8 * L))
    if s_m < 0:
        simple = [r for r in roots if r[2]]
        return f"missed simple root {simple[0][0]!r}; roots {roots}" if simple else None
    if not 0 <= s_m <= L:
        return f"returned {s_m!r} outside [0, {L!r}]"
    for r, dr, simple in roots:
        tol = 1e-14 * L + 4 * min(dr, 1e-6 * L)
        if abs(s_m - r) <= tol:
            return None
        if simple and s_m > r:
            return f"skipped simple root {r!r} (returned {s_m!r}); roots {roots}"
        if s_m < r:
            break
    if abs(float(peval(p, mpf(s_m)))) <= 4 * _eval_bound(a, b, c, d, s_m):
        return None
    return f"returned {s_m!r}, not a root; roots {roots}"


def poly_from_roots(lead, *roots):
    """Float coefficients (a, b, c, d) of lead * prod(s - r); exact for dyadic inputs."""
    coef = [1.0]
    for r in roots:
        coef = [x - r * y for x, y in zip(coef + [0.0], [0.0] + coef)]
    coef = [lead * x for x in coef]
    while len(coef) < 4:
        coef = [0.0] + coef
    return tuple(coef)


def call(a, b, c, d, L):
    return first_root(float(a), float(b), float(c), float(d), float(L))


def assert_ok(a, b, c, d, L):
    s = call(a, b, c, d, L)
    reason = judge(a, b, c, d, L, s)
    assert reason is None, f"first_root({a!r}, {b!r}, {c!r}, {d!r}, {L!r}) = {s!r}: {reason}"
    return s


# ------------------------------------------------------------ exact cases

def test_root_at_zero_is_returned_exactly():
    assert call(1.0, -2.0, 3.0, 0.0, 1.0) == 0.0
    assert call(0.0, 0.0, 5.0, 0.0, 1.0) == 0.0
    assert call(0.0, 0.0, 0.0, 0.0, 1.0) == 0.0      # identically zero: hit at once


def test_root_at_L_is_returned_exactly():
    a, b, c, d = poly_from_roots(1.0, 1.0, 5.0, -3.0)
    assert call(a, b, c, d, 1.0) == 1.0
    a, b, c, d = poly_from_roots(-2.5, 0.75, 3.0)     # quadratic, root at L = 0.75
    assert call(a, b, c, d, 0.75) == 0.75


def test_root_just_beyond_L_is_not_reported():
    a, b, c, d = poly_from_roots(1.0, 1.0 + 2.0 ** -40)
    assert call(a, b, c, d, 1.0) == -1.0
    a, b, c, d = poly_from_roots(1.0, 1.0 - 2.0 ** -40)
    assert abs(call(a, b, c, d, 1.0) - (1.0 - 2.0 ** -40)) <= 1e-15


def test_exact_double_root_is_hit():
    # (s - 0.5)^2 (s - 2): the critical point 0.5 and its value 0 are exact.
    a, b, c, d = poly_from_roots(1.0, 0.5, 0.5, 2.0)
    assert call(a, b, c, d, 1.0) == 0.5
    assert call(-a, -b, -c, -d, 3.0) == 0.5


def test_exact_triple_root_is_hit():
    a, b, c, d = poly_from_roots(1.0, 0.25, 0.25, 0.25)
    assert call(a, b, c, d, 1.0) == 0.25
    assert call(-4 * a, -4 * b, -4 * c, -4 * d, 1.0) == 0.25


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("r", [0.3, 0.1, 0.7, 1 / 3])
def test_inexact_double_root_hit_or_next_root(sign, r):
    # The double root may be hit (to ~sqrt(eps)) or missed; then the simple root at 2.
    a, b, c, d = poly_from_roots(sign, r, r, 2.0)
    s = assert_ok(a, b, c, d, 3.0)
    assert abs(s - r) < 1e-6 or abs(s - 2.0) < 1e-12
    s = assert_ok(a, b, c, d, 1.0)
    assert s == -1.0 or abs(s - r) < 1e-6


@pytest.mark.parametrize("r", [0.3, 0.1, 0.7, 1 / 3, 0.999])
def test_inexact_triple_root_is_found(r):
    # Odd multiplicity: a sign change, so the root must be found (cbrt-conditioned).
    a, b, c, d = poly_from_roots(1.0, r, r, r)
    s = assert_ok(a, b, c, d, 1.0)
    assert abs(s - r) < 1e-4
    s = assert_ok(-1e6 * a, -1e6 * b, -1e6 * c, -1e6 * d, 1.0)
    assert abs(s - r) < 1e-4


# ---------------------------------------------- degenerate leading terms

@pytest.mark.parametrize("roots,L,first", [
    ((0.2, 0.7), 1.0, 0.2), ((0.7, 0.2), 0.5, 0.2), ((-0.5, 0.25), 1.0, 0.25),
    ((1.5, 2.5), 1.0, -1.0), ((0.375, 0.375), 1.0, 0.375)])
def test_quadratic_A_zero(roots, L, first):
    for lead in (1.0, -3.0, 2.0 ** -30, 2.0 ** 30, 1e-9, 1e9):
        a, b, c, d = poly_from_roots(lead, *roots)
        assert a == 0.0
        s = assert_ok(a, b, c, d, L)
        if roots[0] == roots[1] and lead in (1e-9, 1e9):
            continue       # inexact coefficients: the double root may be missed
        assert (s == -1.0) if first < 0 else abs(s - first) <= 1e-14
    # an inexact double root: hit near 0.4 or missed
    a, b, c, d = poly_from_roots(1.0, 0.4, 0.4)
    s = assert_ok(a, b, c, d, 1.0)
    assert s == -1.0 or abs(s - 0.4) < 1e-7
    # no real roots at all
    assert call(0.0, 1.0, 0.0, 1.0, 10.0) == -1.0


def test_linear_A_B_zero():
    assert abs(call(0.0, 0.0, 2.0, -1.0, 1.0) - 0.5) <= 1e-16
    assert abs(call(0.0, 0.0, -1e10, 3e9, 1.0) - 0.3) <= 1e-15
    assert call(0.0, 0.0, 2.0, 1.0, 10.0) == -1.0        # root at -0.5
    assert call(0.0, 0.0, 1.0, -2.0, 1.0) == -1.0        # root beyond L
    assert call(0.0, 0.0, 0.0, 1.0, 1.0) == -1.0         # constant, no root
    assert call(0.0, 0.0, 0.0, -1e-300, 1.0) == -1.0


@pytest.mark.parametrize("a", [1e-300, -1e-300, 5e-324, 1e-18, -1e-18, 1e-12, -1e-9])
@pytest.mark.parametrize("roots", [(0.2, 0.7), (0.45, 0.45000001), (0.9, 3.0), (-1.0, 0.6)])
def test_tiny_leading_coefficient(a, roots):
    _, b, c, d = poly_from_roots(1.0, *roots)
    assert_ok(a, b, c, d, 1.0)
    assert_ok(a, 1e4 * b, 1e4 * c, 1e4 * d, 1.0)      # a tiny relative to the rest
    assert_ok(a * 1e4, b, c, d, 1.0)


def test_tiny_leading_coefficient_keeps_the_quadratic_root():
    # a = 1e-18 relative: the far critical point (~1e17) must not disturb 0.2.
    _, b, c, d = poly_from_roots(1.0, 0.2, 0.7)
    for a in (1e-18, -1e-18, 1e-300):
        assert abs(call(a, b, c, d, 1.0) - 0.2) <= 1e-15


# -------------------------------------------------------- magnitudes

@pytest.mark.parametrize("scale", [1e5, 1e7, 1e10, 6.5535e4, 1e-5])
def test_huge_and_tiny_magnitudes(scale):
    for roots, L in (((0.3, 0.6, 5.0), 1.0), ((0.125, 0.5, 0.875), 1.0),
                     ((0.3, 0.3000001, 2.0), 1.0), ((-2.0, 0.999, 7.0), 1.0),
                     ((2.0, 3.0, 4.0), 1.0), ((0.5, 0.5, 0.9), 1.0)):
        a, b, c, d = poly_from_roots(scale, *roots)
        assert_ok(a, b, c, d, L)
        assert_ok(-a, -b, -c, -d, L)
    # mixed magnitudes: large cubic term, small constant
    assert_ok(1e10, -1e5, 1.0, -1e-5, 1.0)
    assert_ok(-1e10, 3e10, -2e10, 1e5, 1.0)


def _random_cubic(rng, n):
    """A cubic of `test_random_cubics_against_mpmath`'s kinds, but for the tiny leading ones."""
    kind = n % 4
    if kind == 0:
        return poly_from_roots(rng.choice([-1, 1]) * 10 ** rng.uniform(-3, 6), *rng.uniform(-0.5, 1.5, 3))
    if kind == 1:
        r = rng.uniform(0, 1)
        return poly_from_roots(rng.choice([-1, 1]), r, r + 10 ** rng.uniform(-14, -2), rng.uniform(-1, 2))
    if kind == 2:
        return tuple(rng.normal(size=4) * 10.0 ** rng.uniform(-6, 6, 4))
    r = rng.uniform(0, 1)
    a, b, c, d = poly_from_roots(1.0, r, r, rng.uniform(1, 3))
    return a, b, c, d + rng.choice([-1, 1]) * 10 ** rng.uniform(-17, -6)


@pytest.mark.parametrize("k", [-560, -530, -300, 300, 515, 530])
def test_a_cubic_scaled_by_a_power_of_two_has_the_same_first_root(k):
    # Scaled by 2^k, exactly, a cubic keeps its roots. Its squares over- or underflowed past
    # 2^±510: the derivative's roots came out infinite or zero and Newton left its bracket, so
    # cells of float64 samples past 1e153 or below 1e-157 lost their first hits.
    rng = np.random.default_rng(abs(k))
    for n in range(2000):
        a, b, c, d = (float(x) for x in _random_cubic(rng, n))
        L = float(rng.choice([1.0, rng.uniform(0.01, 2.0)]))
        scaled = [math.ldexp(x, k) for x in (a, b, c, d)]
        if any(x != 0.0 and not 2.0 ** -1000 < abs(x) < 2.0 ** 1000 for x in scaled):
            continue                    # not exactly representable scaled
        assert call(*scaled, L) == call(a, b, c, d, L), (a, b, c, d, L, k)


@pytest.mark.parametrize("j", [-99, -60, 60, 99])
def test_a_cubic_in_a_cell_2_to_the_j_as_large_has_its_first_root_2_to_the_j_as_far(j):
    # Spacing times 2^j: the index-space direction is 2^-j times as long, so the cubic in the
    # ray's distance is a s^3 2^-3j + b s^2 2^-2j + c s 2^-j + d on an interval 2^j long. At
    # spacings near 1e-30 its leading coefficients reach 1e90 times the samples'.
    # With samples near 2^-400 (1e-120) the largest coefficient is below 2^-128 but above the
    # discriminant's own underflow: the rescaling must start at 2^-128, not later.
    rng = np.random.default_rng(abs(j) + 7)
    for n in range(2000):
        a, b, c, d = (float(x) for x in _random_cubic(rng, n))
        L = float(rng.choice([1.0, rng.uniform(0.01, 2.0)]))
        for v in (1.0, 2.0 ** 300, 2.0 ** -300, 2.0 ** -400):
            want = call(a * v, b * v, c * v, d * v, L)
            got = call(math.ldexp(a * v, -3 * j), math.ldexp(b * v, -2 * j), math.ldexp(c * v, -j), d * v,
                       math.ldexp(L, j))
            assert got == (want if want < 0 else math.ldexp(want, j)), (a, b, c, d, L, v, j)


def test_no_root():
    assert call(1.0, 0.0, 1.0, 1.0, 1.0) == -1.0           # positive on [0, 1]
    a, b, c, d = poly_from_roots(1.0, 2.0, 3.0, -1.0)
    assert call(a, b, c, d, 1.0) == -1.0
    a, b, c, d = poly_from_roots(-1.0, 1.5, 1.5, -0.5)       # touches at 1.5 > L
    assert call(a, b, c, d, 1.0) == -1.0
    assert call(1.0, 2.0, 3.0, 4.0, -1.0) == -1.0            # empty interval
    assert call(1.0, 2.0, 3.0, 4.0, math.nan) == -1.0
    assert call(1.0, -1.0, 0.0, 1.0, 0.0) == -1.0            # zero-length interval, D != 0


def test_zero_length_interval_holds_a_root_at_zero():
    # [0, 0] holds s = 0 when d == 0: a cell the ray only touches (through an edge or a vertex,
    # c0 == c1) with the surface there. Analytic: P(0) = d = 0 exactly.
    assert call(1.0, 2.0, 3.0, 0.0, 0.0) == 0.0
    assert call(0.0, 0.0, -1.0, 0.0, 0.0) == 0.0


# --------------------------------------------------------- random cubics

@pytest.mark.parametrize("seed", range(4))
def test_random_cubics_against_mpmath(seed):
    rng = np.random.default_rng(seed)
    fails = []
    for n in range(1500):
        kind = n % 5
        if kind == 0:        # three real roots around [0, 1]
            a, b, c, d = poly_from_roots(rng.choice([-1, 1]) * 10 ** rng.uniform(-3, 6),
                                         *rng.uniform(-0.5, 1.5, 3))
        elif kind == 1:      # close pairs
            r = rng.uniform(0, 1)
            gap = 10 ** rng.uniform(-14, -2)
            a, b, c, d = poly_from_roots(rng.choice([-1, 1]), r, r + gap, rng.uniform(-1, 2))
        elif kind == 2:      # raw random coefficients of mixed magnitude
            a, b, c, d = rng.normal(size=4) * 10.0 ** rng.uniform(-6, 6, 4)
        elif kind == 3:      # near-zero leading coefficient
            _, b, c, d = poly_from_roots(1.0, *rng.uniform(-0.5, 1.5, 2))
            a = rng.choice([-1, 1]) * 10 ** rng.uniform(-300, -8)
        else:                # near-tangent: double root shifted by a tiny offset
            r = rng.uniform(0, 1)
            a, b, c, d = poly_from_roots(1.0, r, r, rng.uniform(1, 3))
            d += rng.choice([-1, 1]) * 10 ** rng.uniform(-17, -6)
        L = float(rng.choice([1.0, rng.uniform(0.01, 2.0)]))
        s = call(a, b, c, d, L)
        reason = judge(float(a), float(b), float(c), float(d), L, s)
        if reason:
            fails.append((kind, (a, b, c, d, L), s, reason))
    assert not fails, f"{len(fails)} failures, e.g. {fails[:3]}"


@pytest.mark.parametrize("seed", range(2))
def test_the_hull_test_says_no_root_only_where_the_cubic_keeps_its_sign(seed):
    """`first_root`'s shortcut (no sign change among the Bernstein coefficients, beyond their
    margin) answers "no root" only for cubics with no root in [0, L] whose float values (as
    `first_root` computes them) all keep the sign of ``d``."""
    rng = np.random.default_rng(100 + seed)
    said = 0
    for n in range(1500):
        r = rng.uniform(-0.2, 1.2)
        if n % 3 == 0:       # near-tangent: a double root lifted by a tiny offset, just clear or just through
            a, b, c, d = poly_from_roots(rng.choice([-1, 1]) * 10 ** rng.uniform(-3, 3), r, r, rng.uniform(1, 3))
            d += rng.choice([-1, 1]) * 10 ** rng.uniform(-17, -3) * max(1.0, abs(d))
        elif n % 3 == 1:     # a root just outside the interval
            a, b, c, d = poly_from_roots(rng.choice([-1, 1]), rng.choice([-1, 1]) * 10 ** rng.uniform(-15, -1),
                                         *rng.uniform(-3, 3, 2))
        else:                # raw coefficients of mixed magnitude
            a, b, c, d = rng.normal(size=4) * 10.0 ** rng.uniform(-6, 6, 4)
        a, b, c, d = float(a), float(b), float(c), float(d)
        L = float(rng.choice([1.0, rng.uniform(0.01, 2.0)]))
        if sign_changes(*bernstein(a, b, c, d, L)) != 0:
            continue
        said += 1
        p = [mpf(d), mpf(c), mpf(b), mpf(a)]
        assert not real_roots(p, mpf(0), mpf(L)), (a, b, c, d, L)
        vals = np.array([eval_cubic(a, b, c, d, s) for s in np.linspace(0.0, L, 257)])
        assert np.all(np.sign(vals) == np.sign(d)), (a, b, c, d, L)
        assert first_root(a, b, c, d, L) == -1.0
    assert said > 300


@pytest.mark.parametrize("seed", range(2))
def test_one_bernstein_sign_change_means_one_simple_root(seed):
    """Where `first_root` takes its shortcut (the Bernstein coefficients change sign
    exactly once beyond their margin), mpmath finds exactly one root in [0, L],
    and the root returned is it; cubics with three roots around the interval
    (some inside, some just outside) make the count matter."""
    rng = np.random.default_rng(200 + seed)
    said = 0
    for n in range(1500):
        lead = rng.choice([-1, 1]) * 10 ** rng.uniform(-3, 3)
        if n % 2:
            roots = rng.uniform(-0.3, 1.3, 3)
        else:            # a close pair straddling an end: one root in, one just out
            e = rng.choice([0.0, 1.0])
            gap = 10 ** rng.uniform(-9, -1)
            roots = (e - gap * rng.uniform(0.1, 1), e + gap * rng.uniform(0.1, 1), rng.uniform(-1, 2))
        a, b, c, d = (float(v) for v in poly_from_roots(lead, *roots))
        L = 1.0
        if sign_changes(*bernstein(a, b, c, d, L)) != 1:
            continue
        said += 1
        p = [mpf(d), mpf(c), mpf(b), mpf(a)]
        found = real_roots(p, mpf(0), mpf(L))
        assert len(found) == 1 and not found[0][1], ((a, b, c, d), found)
        assert_ok(a, b, c, d, L)
    assert said > 300
