"""Transfer-function lookups for the casters: data value -> straight colour and opacity.

The functions they evaluate are built, validated and loaded in
`parc.transfer` (which also holds NumPy twins of these kernels that agree
bit for bit); here are only the kernels, so `raycast` needs nothing from `parc`.
"""
import math

from .config import kernel

#: Control-point tables up to this long are searched by a forward scan.
LINEAR_SEARCH_MAX = 16


@kernel
def _locate(x, v):
    """Where ``v`` falls among the control values ``x`` (non-decreasing, not NaN).

    Returns ``(i, t)``: with ``t >= 0`` the value lies at fraction ``t`` of
    segment ``[x[i], x[i+1]]`` (``x[i] <= v < x[i+1]``); with ``t < 0`` it is
    outside the points (or at the last) and the function is constant ``y[i]``.
    """
    n = x.shape[0]
    if v >= x[n - 1]:
        return n - 1, -1.0
    if v < x[0]:
        return 0, -1.0
    lo = 0
    hi = n - 1
    if n <= LINEAR_SEARCH_MAX:
        # Few points (every preset): a forward scan mispredicts one branch,
        # a bisection about half of its own. Same segment either way.
        hi = 1
        while x[hi] <= v:
            hi += 1
        lo = hi - 1
    while hi - lo > 1:          # invariant: x[lo] <= v < x[hi]
        mid = (lo + hi) >> 1
        if x[mid] <= v:
            lo = mid
        else:
            hi = mid
    return lo, (v - x[lo]) / (x[hi] - x[lo])


@kernel
def tf_opacity(op_x, op_y, v):
    """Opacity at data value ``v`` (0 for NaN); see `TransferFunction.opacity`."""
    if v != v:
        return 0.0
    i, t = _locate(op_x, v)
    if t < 0.0:
        return op_y[i]
    return op_y[i] + t * (op_y[i + 1] - op_y[i])


@kernel
def tf_lookup(op_x, op_y, col_x, col_rgb, v):
    """Straight (not premultiplied) ``(r, g, b, a)`` at data value ``v``.

    Parameters
    ----------
    op_x, op_y : float64 (n,)
        Opacity control points (`TransferFunction.arrays`).
    col_x : float64 (m,)
    col_rgb : float64 (m, 3)
        Colour control points.
    v : float
        The interpolated data value.

    Returns
    -------
    r, g, b, a : float
        ``(0, 0, 0, 0)`` for NaN.
    """
    if v != v:
        return 0.0, 0.0, 0.0, 0.0
    r, g, b = tf_color(col_x, col_rgb, v)
    return r, g, b, tf_opacity(op_x, op_y, v)


@kernel(inline="always")
def tf_color(col_x, col_rgb, v):
    """Straight ``(r, g, b)`` at a data value ``v`` that is not NaN (see `tf_lookup`)."""
    i, t = _locate(col_x, v)
    if t < 0.0:
        return col_rgb[i, 0], col_rgb[i, 1], col_rgb[i, 2]
    r = col_rgb[i, 0] + t * (col_rgb[i + 1, 0] - col_rgb[i, 0])
    g = col_rgb[i, 1] + t * (col_rgb[i + 1, 1] - col_rgb[i, 1])
    b = col_rgb[i, 2] + t * (col_rgb[i + 1, 2] - col_rgb[i, 2])
    return r, g, b


@kernel
def correct_opacity(a, ratio):
    """Opacity of a step ``ratio`` reference steps long: ``1 - (1 - a) ** ratio``.

    Computed as ``-expm1(ratio * log1p(-a))``, accurate for small ``a``;
    ``a`` itself when ``ratio == 1``, 0 for ``a <= 0``, 1 for ``a >= 1``.
    """
    if a <= 0.0:
        return 0.0
    if a >= 1.0:
        return 1.0
    if ratio == 1.0:
        return a
    return -math.expm1(ratio * math.log1p(-a))
