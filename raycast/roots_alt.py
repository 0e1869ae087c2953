"""Two published alternatives to `raycast.cubic.first_root`, for the root-finder study.

Same contract as `first_root`: ``f(a, b, c, d, length)`` returns the
smallest root of ``a s^3 + b s^2 + c s + d`` in ``[0, length]``, or -1.
They are not used by the renderer; `parc.rootstudy` measures them against
the project's finder on the hard-ray suite.

About these techniques.

* Closed form (Parker et al. 1998, Appendix A): the cubic is solved with
  Schwarze's Graphics Gems code (Cardano's formula on the depressed cubic,
  the trigonometric form when there are three real roots), with Parker's two
  changes: special cases for a quadratic or linear equation when the leading
  coefficients vanish, and the zero test ``EQN_EPS`` set to 1e-30. All real
  roots come out; the smallest one in ``[0, length]`` is the hit. Nothing
  guards against cancellation: the normal form divides by ``a``, so a tiny
  but nonzero ``a`` (a nearly axis-aligned ray) blows the other coefficients
  up, and a root computed just outside ``[0, length]`` (on a cell face) is
  lost.
* Root isolation and repeated linear interpolation (Marmitt et al. 2004,
  "Fast and accurate ray-voxel intersection techniques for iso-surface ray
  tracing"): the roots of the derivative (textbook quadratic formula) split
  ``[0, length]`` into pieces on which the cubic is monotone; the first
  piece whose ends differ in sign holds the first root, which is refined by
  a fixed number ``MARMITT_ITER`` of regula falsi steps (linear
  interpolation between the bracket ends, keeping the sign change), not
  iterated to convergence. The project's finder first counts the sign
  changes of the cubic's Bernstein coefficients (none: no root; one: a root
  bracketed by the ends); otherwise it isolates the same way (with the
  cancellation-free quadratic formula). Either way safeguarded Newton then
  runs to 1e-15 of the bracket.
"""
import math

from .config import kernel
from .cubic import eval_cubic

#: Schwarze's zero test, set as Parker et al. did ("maximum stability for
#: large coefficients").
EQN_EPS = 1e-30

#: Regula falsi steps after isolation (Marmitt et al. stop after a small
#: fixed number; two is their fast setting).
MARMITT_ITER = 2


@kernel
def _is_zero(x):
    return x > -EQN_EPS and x < EQN_EPS


@kernel
def _cbrt(x):
    """Real cube root, as Graphics Gems defines it (``pow`` of the magnitude)."""
    if x > 0.0:
        return x ** (1.0 / 3.0)
    if x < 0.0:
        return -((-x) ** (1.0 / 3.0))
    return 0.0


@kernel
def _keep(best, s, length):
    """The smaller of ``best`` and ``s`` when ``s`` lies in ``[0, length]``."""
    if s >= 0.0 and s <= length and s < best:
        return s
    return best


@kernel
def first_root_closed_form(a, b, c, d, length):
    """Smallest root in ``[0, length]`` from the closed-form roots (Parker et al. 1998), or -1."""
    if not length >= 0.0:
        return -1.0
    best = math.inf
    if _is_zero(a):
        if _is_zero(b):
            # Linear: c s + d = 0.
            if not _is_zero(c):
                best = _keep(best, -d / c, length)
        else:
            # Schwarze's SolveQuadric on the normal form s^2 + 2p s + q.
            p = c / (2.0 * b)
            q = d / b
            disc = p * p - q
            if _is_zero(disc):
                best = _keep(best, -p, length)
            elif disc > 0.0:
                sq = math.sqrt(disc)
                best = _keep(best, sq - p, length)
                best = _keep(best, -sq - p, length)
    else:
        # Schwarze's SolveCubic: normal form s^3 + A s^2 + B s + C, then
        # s = y - A/3 gives the depressed cubic y^3 + 3p y + 2q.
        A = b / a
        B = c / a
        C = d / a
        sq_a = A * A
        p = (1.0 / 3.0) * (-(1.0 / 3.0) * sq_a + B)
        q = 0.5 * ((2.0 / 27.0) * A * sq_a - (1.0 / 3.0) * A * B + C)
        cb_p = p * p * p
        disc = q * q + cb_p
        sub = (1.0 / 3.0) * A
        if _is_zero(disc):
            if _is_zero(q):                      # one triple root
                best = _keep(best, -sub, length)
            else:                                # a single and a double root
                u = _cbrt(-q)
                best = _keep(best, 2.0 * u - sub, length)
                best = _keep(best, -u - sub, length)
        elif disc < 0.0:                         # casus irreducibilis: three real roots
            # Clamped: rounding can push the cosine a hair past 1 (Schwarze does not clamp).
            phi = (1.0 / 3.0) * math.acos(min(1.0, max(-1.0, -q / math.sqrt(-cb_p))))
            t = 2.0 * math.sqrt(-p)
            best = _keep(best, t * math.cos(phi) - sub, length)
            best = _keep(best, -t * math.cos(phi + math.pi / 3.0) - sub, length)
            best = _keep(best, -t * math.cos(phi - math.pi / 3.0) - sub, length)
        else:                                    # one real root
            sqrt_d = math.sqrt(disc)
            u = _cbrt(sqrt_d - q)
            v = -_cbrt(sqrt_d + q)
            best = _keep(best, u + v - sub, length)
    return best if best < math.inf else -1.0


@kernel
def _regula_falsi(a, b, c, d, s0, s1, f0, f1, iters):
    """``iters`` steps of repeated linear interpolation on a bracket with ``f0``, ``f1`` of opposite sign."""
    s = s0
    for _ in range(iters):
        s = s0 + (s1 - s0) * (f0 / (f0 - f1))
        f = eval_cubic(a, b, c, d, s)
        if f == 0.0:
            return s
        if (f < 0.0) == (f0 < 0.0):
            s0 = s
            f0 = f
        else:
            s1 = s
            f1 = f
    return s


@kernel
def first_root_isolating(a, b, c, d, length, iters):
    """Marmitt et al. (2004): isolate with the derivative's roots, refine by ``iters`` regula falsi steps."""
    if not length >= 0.0:
        return -1.0
    if d == 0.0:
        return 0.0
    # Extrema from 3a s^2 + 2b s + c = 0, by the textbook formula.
    e1 = math.inf
    e2 = math.inf
    if a != 0.0:
        disc = 4.0 * b * b - 12.0 * a * c
        if disc >= 0.0:
            sq = math.sqrt(disc)
            e1 = (-2.0 * b - sq) / (6.0 * a)
            e2 = (-2.0 * b + sq) / (6.0 * a)
    elif b != 0.0:
        e1 = -c / (2.0 * b)
    if e2 < e1:
        e1, e2 = e2, e1
    s0 = 0.0
    f0 = d
    for piece in range(3):
        if piece == 0:
            s1 = e1
        elif piece == 1:
            s1 = e2
        else:
            s1 = length
        if piece < 2 and not (s1 > s0 and s1 < length):
            continue
        f1 = eval_cubic(a, b, c, d, s1)
        if f1 == 0.0:
            return s1
        if (f0 < 0.0) != (f1 < 0.0):
            return _regula_falsi(a, b, c, d, s0, s1, f0, f1, iters)
        s0 = s1
        f0 = f1
    return -1.0


@kernel
def first_root_marmitt(a, b, c, d, length):
    """`first_root_isolating` with the fixed ``MARMITT_ITER`` refinement steps."""
    return first_root_isolating(a, b, c, d, length, MARMITT_ITER)
