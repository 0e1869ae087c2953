"""The ray/cell cubic in high precision: exact coefficients, real roots in mpmath.

The truth `raycast.reference` judges the caster against. For an
exact-trilinear scene (`raycast.hardfields`) and a float64 ray, the cubic
``P(t) = F(O + t D) - iso`` along the ray has exactly representable
coefficients once the ray is taken as given; `ray_cubic` builds them in
exact fractions, and `real_roots` finds every real root on an interval in
mpmath at `DPS` digits, telling simple roots from touching ones
(a double root within `ZERO_REL` of zero at a critical point).
"""
import math

import mpmath

DPS = 40
MP = mpmath.MPContext()
MP.dps = DPS
mpf = MP.mpf
ZERO = mpf(0)
INF = mpf("inf")
ZERO_REL = mpf(10) ** (6 - DPS)     # |P| below this (relative) at a critical point: touching
SOLVE_REL = mpf(10) ** (8 - DPS)    # root solves stop at this relative width


# ----------------------------------------------------------- exact cubic

def mp_grid(scene):
    """``(origin, spacing)`` of a `raycast.hardfields.Scene` as mpf triples (kept on the scene)."""
    if getattr(scene, "_mp_grid", None) is None:
        scene._mp_grid = ([mpf(float(x)) for x in scene.origin],
                          [mpf(float(x)) for x in scene.spacing])
    return scene._mp_grid


def mp_coeffs(scene):
    """The scene's field coefficients as mpf (kept on the scene)."""
    if getattr(scene, "_mp_coeffs", None) is None:
        scene._mp_coeffs = [mpf(x) for x in scene.coeffs]
    return scene._mp_coeffs


def index_ray(scene, o, d):
    """(O, D) of the exact ray in index space, as mpf triples."""
    org, spc = mp_grid(scene)
    O = [(mpf(float(o[a])) - org[a]) / spc[a] for a in range(3)]
    D = [mpf(float(d[a])) / spc[a] for a in range(3)]
    return O, D


def _mul(p, q):
    r = [ZERO] * (len(p) + len(q) - 1)
    for a, x in enumerate(p):
        for b, y in enumerate(q):
            r[a + b] += x * y
    return r


def ray_cubic(scene, O, D, iso):
    """Coefficients ``[p0, p1, p2, p3]`` of ``P(t) = F(O + t D) - iso``."""
    c = mp_coeffs(scene)
    X, Y, Z = ([O[0], D[0]], [O[1], D[1]], [O[2], D[2]])
    XY, YZ, ZX = _mul(X, Y), _mul(Y, Z), _mul(Z, X)
    XYZ = _mul(XY, Z)
    p = [c[0] - mpf(float(iso)), ZERO, ZERO, ZERO]
    for coef, poly in ((c[1], X), (c[2], Y), (c[3], Z), (c[4], XY), (c[5], YZ),
                       (c[6], ZX), (c[7], XYZ)):
        if coef:
            for n, v in enumerate(poly):
                p[n] += coef * v
    return p


def peval(p, t):
    return ((p[3] * t + p[2]) * t + p[1]) * t + p[0]


def pderiv(p, t):
    return (3 * p[3] * t + 2 * p[2]) * t + p[1]


def box_intervals(scene, O, D, pad):
    """``([t_in, t_out] grown, [t_in, t_out] shrunk)``: the ray in the box grown /
    shrunk by ``pad[a]`` index units per side of axis ``a``, as mpf, clipped
    to ``t >= 0``. An empty interval has ``t_in > t_out``.
    """
    nz, ny, nx = scene.shape
    n = (nx, ny, nz)
    grown, shrunk = [ZERO, INF], [ZERO, INF]
    for a in range(3):
        pa = mpf(pad[a])
        if D[a] == 0:
            if O[a] < -pa or O[a] > (n[a] - 1) + pa:
                grown = [mpf(1), mpf(-1)]
            if O[a] < pa or O[a] > (n[a] - 1) - pa:
                shrunk = [mpf(1), mpf(-1)]
            continue
        inv = 1 / D[a]
        t0, t1 = -O[a] * inv, ((n[a] - 1) - O[a]) * inv
        if t0 > t1:
            t0, t1 = t1, t0
        w = pa * abs(inv)
        grown = [max(grown[0], t0 - w), min(grown[1], t1 + w)]
        shrunk = [max(shrunk[0], t0 + w), min(shrunk[1], t1 - w)]
    return grown, shrunk


def _critical_points(p):
    """Real roots of P' = p1 + 2 p2 t + 3 p3 t^2, sorted."""
    a, b, c = 3 * p[3], 2 * p[2], p[1]
    if a == 0:
        return [] if b == 0 else [-c / b]
    disc = b * b - 4 * a * c
    if disc < 0:
        return []
    if disc == 0:           # one (double) point, listed once: listed twice, a triple root there would come out twice
        return [-b / (2 * a)]
    q = -(b + MP.sqrt(disc)) / 2 if b >= 0 else -(b - MP.sqrt(disc)) / 2
    if q == 0:
        return [ZERO]
    return sorted([q / a, c / q])


def _float_guess(p, a, b, fa_neg):
    """A float64 estimate of the root of monotone P in (a, b), to start Newton."""
    p0, p1, p2, p3 = (float(x) for x in p)
    xl, xh = (float(a), float(b)) if fa_neg else (float(b), float(a))
    x = 0.5 * (xl + xh)
    for _ in range(200):
        f = ((p3 * x + p2) * x + p1) * x + p0
        if f == 0.0 or not math.isfinite(f):
            break
        if f < 0.0:
            xl = x
        else:
            xh = x
        df = (3.0 * p3 * x + 2.0 * p2) * x + p1
        lo, hi = min(xl, xh), max(xl, xh)
        xn = x - f / df if df != 0.0 else math.nan
        if not lo < xn < hi:
            xn = 0.5 * (xl + xh)
        if xn == x:
            break
        x = xn
    return x


def _solve_monotone(p, a, b, fa):
    """Root of P in (a, b), P monotone there with a sign change.

    Safeguarded Newton in mpf (bisection whenever Newton leaves the bracket),
    started from a float64 estimate; stops at ~1e-32 relative.
    """
    if fa < 0:
        xl, xh = a, b
    else:
        xl, xh = b, a
    tol = SOLVE_REL * max(1, abs(a), abs(b))
    x = mpf(_float_guess(p, a, b, fa < 0))
    if not min(a, b) < x < max(a, b):
        x = (a + b) / 2
    for _ in range(400):
        f = peval(p, x)
        if f == 0:
            return x
        if f < 0:
            xl = x
        else:
            xh = x
        df = pderiv(p, x)
        lo, hi = min(xl, xh), max(xl, xh)
        xn = x - f / df if df != 0 else None
        if xn is None or not (lo < xn < hi):
            xn = (xl + xh) / 2
        if abs(xn - x) <= tol or hi - lo <= tol:
            return xn
        x = xn
    return x


def real_roots(p, lo, hi):
    """All real roots of P in ``[lo, hi]`` (sorted), each ``(t, touching)``.

    The critical points split ``[lo, hi]`` into pieces on which P is
    monotone. A piece end where P is exactly 0 is a root; an interior
    critical point where ``|P|`` is ~0 (at the 1e-34 level of the
    terms summed) is a *touching* (double or triple) root; a piece
    whose ends differ in sign holds one root, solved to ~1e-32.
    """
    if not lo <= hi:
        return []
    if p[3] == 0 and p[2] == 0 and p[1] == 0:
        return [(lo, True)] if p[0] == 0 else []
    # Relative to the terms summed at the interval's ends: the largest coefficient times the
    # largest t cubed counted an eye's distance twice (p0 holds it already), and for an eye 1e7
    # cells away made every critical point a touching root.
    ztol = max(sum(abs(c) * abs(x) ** k for k, c in enumerate(p)) for x in (lo, hi)) * ZERO_REL
    pts = [lo] + [e for e in _critical_points(p) if lo < e < hi] + [hi]
    vals = [peval(p, x) for x in pts]
    interior = [0 < n < len(pts) - 1 for n in range(len(pts))]
    zero = [f == 0 or (inner and abs(f) <= ztol) for f, inner in zip(vals, interior)]
    roots = [(x, inner) for x, z, inner in zip(pts, zero, interior) if z]
    for n in range(len(pts) - 1):
        if not zero[n] and not zero[n + 1] and (vals[n] < 0) != (vals[n + 1] < 0):
            roots.append((_solve_monotone(p, pts[n], pts[n + 1], vals[n]), False))
    roots.sort(key=lambda r: r[0])
    return roots
