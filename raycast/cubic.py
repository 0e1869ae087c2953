"""The ray/trilinear-cell intersection: a cubic in t per cell, and its first root.

About this technique (Parker et al. 1998, Appendix A). Inside a cell the
field is the trilinear interpolant of the eight corners. Along a ray the
local coordinates are linear in the ray parameter, ``u = u0 + s du`` (same
for v, w), so ``rho(s) - iso`` is a cubic ``A s^3 + B s^2 + C s + D``. We
write the interpolant in its monomial form

    rho = a0 + ax u + ay v + az w + axy uv + ayz vw + azx wu + axyz uvw,

which expands to the same cubic as Parker's ``sum u_i v_j w_k rho_ijk`` form
but is cheaper to set up, and measure ``s`` from the ray's entry into the
cell so the coefficients stay small (no ``t^3`` with ``t`` in the hundreds)
whatever the cell's distance from the eye or the origin. (The appendix as
printed indexes its sums ``u_i v_i w_i``, and gives ``b_0`` and ``b_1`` each
other's sign: ``u_0 = (x_1 - x) / (x_1 - x_0)`` falls as the ray moves along
+x, so ``b_0 = -x_b / (x_1 - x_0)``.)

The first root in ``[0, L]`` is found robustly rather than in closed form.
The cubic's Bernstein coefficients on the interval come first: when their
signs are sure (beyond a rounding margin) and never change, there is no
root (most cells the ray misses); when they change once, there is exactly
one, bracketed by the ends (most hits). Otherwise the derivative's roots
split the interval into pieces on which the cubic is monotone, and the
first piece whose ends differ in sign (or end on zero) holds the first
root. Either way safeguarded Newton iteration, started at the secant's
root, finds it. This handles a
leading coefficient near zero (the derivative's roots use the stable
quadratic formula, so a tiny ``A`` sends one root far away instead of
dividing by it), roots on faces, edges and vertices (an exact zero at an end
is taken), and close root pairs (each lies in its own monotone piece).
A double root (a grazing ray) touches zero without a sign change; it counts
as a hit only when rounding puts the extremum at or below zero.
"""
import math

from .config import ROOT_MAX_ITER, ROOT_REL_TOL, kernel


@kernel
def trilinear_coefficients(v000, v100, v010, v110, v001, v101, v011, v111):
    """Monomial coefficients (a0, ax, ay, az, axy, ayz, azx, axyz) of a cell.

    Corner ``vIJK`` is the sample at local ``(u, v, w) = (I, J, K)``.
    """
    a0 = v000
    ax = v100 - v000
    ay = v010 - v000
    az = v001 - v000
    axy = v110 - v100 - v010 + v000
    ayz = v011 - v010 - v001 + v000
    azx = v101 - v100 - v001 + v000
    axyz = (v111 - v011) - (v110 - v010) - (v101 - v001) + (v100 - v000)
    return a0, ax, ay, az, axy, ayz, azx, axyz


@kernel
def cubic_along_ray(a0, ax, ay, az, axy, ayz, azx, axyz, u0, v0, w0, du, dv, dw):
    """Coefficients (A, B, C, D) of rho(u0 + s du, v0 + s dv, w0 + s dw)."""
    d_ = (a0 + ax * u0 + ay * v0 + az * w0 + axy * u0 * v0 + ayz * v0 * w0
          + azx * w0 * u0 + axyz * u0 * v0 * w0)
    c_ = (ax * du + ay * dv + az * dw
          + axy * (u0 * dv + du * v0) + ayz * (v0 * dw + dv * w0) + azx * (w0 * du + dw * u0)
          + axyz * (du * v0 * w0 + u0 * dv * w0 + u0 * v0 * dw))
    b_ = (axy * du * dv + ayz * dv * dw + azx * dw * du
          + axyz * (du * dv * w0 + du * v0 * dw + u0 * dv * dw))
    a_ = axyz * du * dv * dw
    return a_, b_, c_, d_


@kernel
def eval_cubic(a, b, c, d, s):
    return ((a * s + b) * s + c) * s + d


@kernel(inline="always")
def _bracketed_root(a, b, c, d, lo, hi, flo, fhi):
    """The root of a cubic with exactly one root in [lo, hi], where its ends differ in sign."""
    tol = ROOT_REL_TOL * (hi - lo)
    if tol <= 0.0:
        return lo
    # Orient so that f(xl) < 0 < f(xh).
    if flo < 0.0:
        xl, xh = lo, hi
    else:
        xl, xh = hi, lo
    # Start from the secant's root (the false position of the ends): a cell's
    # cubic is close to linear, so Newton starts within rounding of the root.
    s = lo + (hi - lo) * (flo / (flo - fhi))
    if not (s > min(lo, hi) and s < max(lo, hi)):
        s = 0.5 * (lo + hi)
    dx_old = hi - lo
    dx = dx_old
    f = eval_cubic(a, b, c, d, s)
    if f == 0.0:
        return s
    df = (3.0 * a * s + 2.0 * b) * s + c
    for _ in range(ROOT_MAX_ITER):
        # Newton when it stays inside the bracket and halves the step, else bisect. (The two
        # ends' signs compared, not their product's: that over- or underflowed for cubics of
        # coefficients near 1e154 or 1e-157, and Newton left the bracket.)
        ph = (s - xh) * df - f
        pl = (s - xl) * df - f
        if ((ph > 0.0 and pl > 0.0) or (ph < 0.0 and pl < 0.0)
                or abs(2.0 * f) > abs(dx_old * df)):
            dx_old = dx
            dx = 0.5 * (xh - xl)
            s = xl + dx
            if s == xl:
                return s
        else:
            dx_old = dx
            dx = f / df
            prev = s
            s -= dx
            if s == prev:
                return s
        if abs(dx) < tol:
            return s
        f = eval_cubic(a, b, c, d, s)
        if f == 0.0:
            return s
        df = (3.0 * a * s + 2.0 * b) * s + c
        if f < 0.0:
            xl = s
        else:
            xh = s
    return s


#: Margin of the Bernstein sign tests, relative to the cubic's scale on the
#: interval: a thousand times the rounding error of its Bernstein
#: coefficients and of `eval_cubic` (a few units in 2**-53 of that scale).
HULL_MARGIN = 1e-13
_THIRD = 1.0 / 3.0
#: The largest coefficient's bounds beyond which `first_root` rescales the cubic: their
#: squares, and a square times the 1e90 that separates a tiny cell's coefficients, stay normal.
_LARGE = 2.0 ** 128
_SMALL = 2.0 ** -128


@kernel
def bernstein(a, b, c, d, length):
    """The cubic's Bernstein coefficients on ``[0, length]``, and the margin their signs are sure beyond.

    ``(b0, b1, b2, b3, m)``: ``b0`` and ``b3`` are its values at the ends;
    a coefficient with ``|bi| > m`` (`HULL_MARGIN` times the scale
    ``|d| + |c| L + |b| L^2 + |a| L^3``) has the sign the exact one has,
    and so does every value `eval_cubic` computes where they all agree.
    """
    cl = c * length
    bl = b * length * length
    al = a * length * length * length
    m = HULL_MARGIN * (abs(d) + abs(cl) + abs(bl) + abs(al))
    return d, d + cl * _THIRD, d + (2.0 * cl + bl) * _THIRD, d + cl + bl + al, m


@kernel
def sign_changes(b0, b1, b2, b3, m):
    """Sign changes along ``b0 .. b3``, or -1 where one of them is within ``m`` of zero."""
    if not (abs(b0) > m and abs(b1) > m and abs(b2) > m and abs(b3) > m):
        return -1
    return int((b0 < 0.0) != (b1 < 0.0)) + int((b1 < 0.0) != (b2 < 0.0)) + int((b2 < 0.0) != (b3 < 0.0))


@kernel
def _scaled_by(e, a, b, c, d):
    """``a .. d`` times ``2^e``: apart, so that the walk that inlines `first_root` carries none
    of the rare rescaling's code."""
    return math.ldexp(a, e), math.ldexp(b, e), math.ldexp(c, e), math.ldexp(d, e)


@kernel(inline="always")
def first_root(a, b, c, d, length):
    """Smallest root of ``a s^3 + b s^2 + c s + d`` in ``[0, length]``, or -1.

    See the module docstring for how the hard cases are handled.
    """
    if not length >= 0.0:
        return -1.0
    if d == 0.0:
        return 0.0
    b0, b1, b2, b3, m = bernstein(a, b, c, d, length)
    changes = sign_changes(b0, b1, b2, b3, m)
    if changes == 0:
        # The coefficients bound the cubic (convex hull property): one sign all over the
        # interval, beyond rounding. Most cells whose range holds the isovalue but that the
        # ray misses end here (135,261 of the 135,309 such solves of a CT head frame), at a
        # third of the cost of the search.
        return -1.0
    if changes == 1:
        # Exactly one root in the interval (Descartes' rule for the
        # Bernstein basis), bracketed by the ends: no critical points needed.
        return _bracketed_root(a, b, c, d, 0.0, length, b0, b3)
    top = max(max(abs(a), abs(b)), max(abs(c), abs(d)))
    if (top > _LARGE or top < _SMALL) and top < math.inf:
        # The derivative's discriminant squares the coefficients: it over- or underflowed
        # where samples are extreme (past 1e153 or below 1e-157 in unit cells) or cells tiny
        # (index-space directions near 1e30). Scaled by a power of two the cubic is exactly
        # the same search. (Here, past the common case above, which squares nothing: the
        # walk's hits pay nothing for it.)
        a, b, c, d = _scaled_by(-math.frexp(top)[1], a, b, c, d)
    # Critical points in (0, length) from 3a s^2 + 2b s + c = 0.
    qa = 3.0 * a
    qb = 2.0 * b
    qc = c
    e1 = math.inf
    e2 = math.inf
    if qa == 0.0:
        if qb != 0.0:
            e1 = -qc / qb
    else:
        disc = qb * qb - 4.0 * qa * qc
        if disc >= 0.0:
            q = -0.5 * (qb + math.copysign(math.sqrt(disc), qb))
            if q != 0.0:
                e1 = q / qa
                e2 = qc / q
            else:
                e1 = 0.0
    if e2 < e1:
        e1, e2 = e2, e1
    lo = 0.0
    flo = d
    for piece in range(3):
        if piece == 0:
            hi = e1
        elif piece == 1:
            hi = e2
        else:
            hi = length
        if not (hi > lo and hi < length) and piece < 2:
            continue
        fhi = eval_cubic(a, b, c, d, hi)
        if fhi == 0.0:
            return hi
        if (flo < 0.0) != (fhi < 0.0):
            return _bracketed_root(a, b, c, d, lo, hi, flo, fhi)
        lo = hi
        flo = fhi
    return -1.0
