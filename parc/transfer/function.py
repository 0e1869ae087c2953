"""The transfer function: data value -> colour and opacity, piecewise linear.

About this technique
--------------------
A translucent volume is shown by sampling each ray at regular steps and
compositing the colour and opacity the *transfer function* assigns to the
sampled data value. PARC uses *post-classification*: the ray samples the
trilinear interpolant of the data first, then looks the interpolated value
up. (Pre-classification, interpolating colours and opacities classified at
the grid points, blurs the sharp features a transfer function draws.)

Post-classification is also what makes PARC's cell classification
(Sobierajski & Avila 1995, §2 and §4) a *range query*. Inside a cell the
interpolant is a convex combination of the eight corners and continuous,
so it takes every value in ``[min, max]`` of its corners and no other. A
cell is *possibly contributing* exactly when the opacity is non-zero
somewhere on that interval, and empty otherwise: no ray can pick up colour
there. `TransferFunction.nonzero_in` answers this for millions of cells at
once from a small table: the *support*, the sorted maximal closed intervals
on which the opacity is non-zero; one binary search per range finds
the first interval ending at or above ``mn`` and checks it starts at or
below ``mx``. The table is built from the control points, and it is
conservative with respect to the kernel's floating-point lookup: where
both ends of a segment have opacity 0 the kernel returns exactly 0, and
every segment with a non-zero end contributes its *closed* interval, so a
range that only touches the support (``mx`` equal to the control point
where the opacity starts to rise) still counts.

The function
------------
Opacity and colour are separate piecewise-linear functions, each given by
control points with non-decreasing values; outside the first and last
point each is constant. A value may appear twice in a row, which makes a
jump; at the jump the function takes the second point's value (it is
continuous from the right). The kernel `tf_lookup` finds the segment (a
forward scan up to `raycast.transfer.LINEAR_SEARCH_MAX` points, else binary
search) and interpolates ``y0 + t (y1 - y0)`` with
``t = (v - x0) / (x1 - x0)``; the NumPy methods do the same operations in
the same order, so they agree with it bit for bit. A NaN value is fully
transparent and black.

Opacity and step size
---------------------
An opacity is the opacity of a slab one *reference step* thick:
``reference_step(spacing) = REFERENCE_STEP_FRACTION * min(spacing)``, a
quarter of the smallest sample spacing. A caster sampling every ``step``
corrects each looked-up opacity with

    a_corrected = 1 - (1 - a) ** (step / reference_step)

(`correct_opacity`), so images do not change brightness with the step.
Colours are straight (not premultiplied); the caster premultiplies.
"""
from __future__ import annotations

import math

import numpy as np
from numba import prange

from data_tools import InputError
from data_tools.info import exact_text
from data_tools.volume import is_number, settled, three_numbers
from raycast.config import RANGE_CHUNK, kernel
from raycast.rays import chunk_count, chunk_run


#: Opacities are per reference step: this fraction of the smallest spacing.
REFERENCE_STEP_FRACTION = 0.25

def reference_step(spacing):
    """The step opacities refer to: `REFERENCE_STEP_FRACTION` of the smallest spacing."""
    return REFERENCE_STEP_FRACTION * float(min(spacing))


def _real_values(values, who, dtype=None):
    """``values`` as an array of real numbers (integers or floats, NaN and inf among them; in
    ``dtype`` where given, copied only to convert), or an InputError naming ``who``: NumPy turns
    text into numbers, drops an imaginary part, and counts a date's days."""
    try:
        a = np.asarray(values)
    except ValueError:                              # ragged nesting
        a = np.asarray(None)
    if a.dtype.kind not in "iuf":
        raise InputError(f"{who} takes real numbers (integers or floats), got {short_repr(values)}")
    return a if dtype is None else a.astype(dtype, copy=False)


def _interp(x, y, v):
    """Piecewise-linear ``y`` (shape (n,) or (n, k)) at float64 ``v``, as the kernels compute it."""
    shape = v.shape + y.shape[1:]
    n = len(x)
    i = np.searchsorted(x, v, side="right") - 1      # largest i with x[i] <= v; NaN sorts last
    out = np.where((i < 0).reshape(v.shape + (1,) * (y.ndim - 1)), y[0], y[n - 1])
    out = np.array(np.broadcast_to(out, shape), dtype=np.float64)
    inside = (i >= 0) & (i < n - 1)
    if inside.any():
        j = i[inside]
        vi = v[inside]
        t = (vi - x[j]) / (x[j + 1] - x[j])
        if y.ndim > 1:
            t = t[:, None]
        y0 = y[j]
        out[inside] = y0 + t * (y[j + 1] - y0)
    out[np.isnan(v)] = 0.0
    return out


@settled
class TransferFunction:
    """Piecewise-linear opacity and colour over data values.

    Parameters
    ----------
    opacity : sequence of (value, alpha)
        At least one point; values non-decreasing (a value may repeat once:
        a jump), alpha in [0, 1].
    color : sequence of (value, r, g, b), optional
        Values non-decreasing as above, components in [0, 1]; need not share
        the opacity's values. Default: white.
    name : str
        For messages and files.
    description : str
        One line, optional.
    source : str
        Where it came from (a file path, ``"preset ct_bone"``), prefixed to
        error messages.

    Attributes
    ----------
    made_from : (name, data_range, mode) or None
        Set for one `parc.Translucent` or a scene file made from a preset or
        file name for its volume's range (`load_for_volume`); None otherwise.

    Raises
    ------
    InputError
        Empty lists, malformed points, non-finite numbers, alpha or colour
        outside [0, 1], values that descend or repeat three times; the
        message names the key and index.

    Notes
    -----
    Both functions are constant outside their first and last points. NaN
    data values are transparent black.
    """

    def __init__(self, opacity, color=None, *, name="", description="", source=""):
        where = f"transfer function {source}" if source else "transfer function"
        op = control_points(opacity, "opacity", ("alpha",), where)
        if color is None:
            col = np.array([[op[0, 0], 1.0, 1.0, 1.0]])
        else:
            col = control_points(color, "color", ("r", "g", "b"), where)
        # A label for notes and reports: one line of printable text (a file's name may hold
        # newlines or terminal escapes), "" for none.
        self.name = " ".join("".join(c if c.isprintable() else " " for c in str(name or "")).split())
        self.description = "" if description is None else str(description)
        self.source = str(source)
        self.made_from = None
        self._op_x = _frozen(op[:, 0])
        self._op_y = _frozen(op[:, 1])
        self._col_x = _frozen(col[:, 0])
        self._col_rgb = _frozen(col[:, 1:])
        sup = _support(self._op_x, self._op_y)
        self._sup_lo = _frozen(sup[:, 0])
        self._sup_hi = _frozen(sup[:, 1])

    @property
    def title(self):
        """How notes and table headings name it: its name, else where it came from."""
        return self.name or self.source.removeprefix("preset ") or "the transfer function"

    # -- the kernels' view -------------------------------------------------

    def arrays(self):
        """``(op_x, op_y, col_x, col_rgb)``: the float64 arrays `tf_lookup` takes (read-only)."""
        return self._op_x, self._op_y, self._col_x, self._col_rgb

    @property
    def opacity_points(self):
        """``(n, 2)`` float64 copy of the opacity control points."""
        return np.column_stack([self._op_x, self._op_y])

    @property
    def color_points(self):
        """``(m, 4)`` float64 copy of the colour control points."""
        return np.column_stack([self._col_x, self._col_rgb])

    # -- lookups ----------------------------------------------------------

    def opacity(self, values):
        """Opacity at ``values`` (any shape, compared in float64), bit for bit as `tf_opacity`."""
        return _interp(self._op_x, self._op_y, _real_values(values, "opacity", np.float64))

    def color(self, values):
        """Straight RGB at ``values``: shape ``values.shape + (3,)``, bit for bit as `tf_lookup`."""
        return _interp(self._col_x, self._col_rgb, _real_values(values, "color", np.float64))

    def lookup(self, values):
        """Straight RGBA at ``values``: shape ``values.shape + (4,)``."""
        v = _real_values(values, "lookup", np.float64)
        return np.concatenate([_interp(self._col_x, self._col_rgb, v), _interp(self._op_x, self._op_y, v)[..., None]],
                              axis=-1)

    # -- classification ---------------------------------------------------

    def support(self):
        """Where the opacity may be non-zero: ``(K, 2)`` float64 ``[lo, hi]`` rows.

        Sorted, disjoint maximal closed intervals (``lo == hi`` for an isolated
        point; ``-inf``/``inf`` where a constant end is non-zero). Every value
        at which `tf_opacity` returns more than 0 lies in one of them.
        """
        return np.column_stack([self._sup_lo, self._sup_hi])

    def nonzero_in(self, mn, mx, *, rounding=0.0):
        """Whether the opacity is non-zero somewhere in each closed range ``[mn, mx]``.

        Parameters
        ----------
        mn, mx : array_like
            Range bounds, any real dtype (compared in float64, as the kernels
            read samples), broadcast together; e.g. `parc.ranges.cell_minmax`.
        rounding : float, default 0
            Widen each range by this fraction of its largest magnitude (for
            8- and 16-bit integers, of the type's): the casters' samples
            leave a cell's corner range by up to
            `raycast.composite.INTERP_ROUNDING` of it, which `parc.classify.classify_tf`
            passes here.

        Returns
        -------
        ndarray of bool
            True where ``[mn, mx]`` meets the `support`: conservative, so a
            value the kernel gives opacity > 0 is never missed (ranges that
            only touch a support interval count). False for ``mn > mx``. A
            NaN bound means an unknown range: True, unless the opacity is 0
            everywhere.

        Notes
        -----
        Per range, one binary search in the support's interval ends, in one
        parallel pass with no temporaries (`_nonzero_by_search`). For 8- and
        16-bit integer ranges (CT, most scanned data) the search is done
        once per possible value instead, and each range costs one table
        lookup (`_nonzero_by_table`).
        """
        mn, mx = _real_values(mn, "nonzero_in"), _real_values(mx, "nonzero_in")
        if not is_number(rounding) or not 0.0 <= rounding < 1.0:
            raise InputError(f"nonzero_in: rounding must be a fraction from 0 to below 1, got {rounding!r}")
        try:
            shape = np.broadcast_shapes(mn.shape, mx.shape)
        except ValueError:
            raise InputError(f"nonzero_in: range bounds of shapes {mn.shape} and {mx.shape} do not broadcast together") from None
        if mn.shape != shape or mx.shape != shape:
            mn, mx = np.broadcast_arrays(mn, mx)
        a_all = mn.reshape(-1)
        b_all = mx.reshape(-1)
        if len(self._sup_lo) == 0:
            return np.zeros(shape, dtype=bool)
        out = np.empty(a_all.shape, dtype=bool)
        small_int = (a_all.dtype == b_all.dtype and a_all.dtype.kind in "iu"
                     and a_all.dtype.itemsize <= 2)
        if small_int:
            need = self._small_int_table(a_all.dtype, rounding)
            _nonzero_by_table(a_all, a_all.view(f"u{a_all.dtype.itemsize}"), b_all, need, out)
        else:
            # The kernel reads any NumPy integer or float32/64; others (bool, float16) as float64.
            a_all, b_all = (v if v.dtype.kind in "iu" or v.dtype in (np.float32, np.float64)
                            else v.astype(np.float64) for v in (a_all, b_all))
            _nonzero_by_search(a_all, b_all, self._sup_lo, self._sup_hi, float(rounding), out)
        return out.reshape(shape)

    def _small_int_table(self, dtype, rounding=0.0):
        """For 8- and 16-bit integer ranges: ``need``, indexed by a range's low end's bit pattern.

        For every value ``m`` of the dtype, ``need[m]`` is the least integer
        ``mx`` for which ``[m, mx]``, widened by ``p`` (``rounding`` times
        the type's largest magnitude, below 1), meets the support: the
        ceiling of ``start - p`` for the first interval ending at or above
        ``m - p`` (the same float64 search as `_nonzero_by_search`, done once
        per value, not per range). The table is indexed by the bit pattern
        (``view`` as unsigned), so signed data needs no widened copy.
        """
        info = np.iinfo(dtype)
        p = rounding * max(-float(info.min), float(info.max))
        values = np.arange(info.min, info.max + 1, dtype=np.float64)
        lo, hi = self._sup_lo, self._sup_hi
        k = np.searchsorted(hi, values - p, side="left")
        start = np.where(k < len(lo), np.ceil(lo[np.minimum(k, len(lo) - 1)] - p), np.inf)
        need = np.clip(start, info.min, info.max + 1).astype(np.int32)
        if info.min < 0:                                  # bit pattern order: 0..max, then min..-1
            need = np.concatenate([need[-info.min:], need[:-info.min]])
        return need

    # -- conversions ------------------------------------------------------

    def mapped(self, lo, hi, *, src=(0.0, 1.0)):
        """The same function with values mapped affinely from ``src`` onto ``[lo, hi]``.

        ``src = (0, 1)`` turns a normalized function into one over the data range.
        """
        spans = three_numbers(src), three_numbers((lo, hi))
        if any(p is None or len(p) != 2 or not all(math.isfinite(v) for v in p) for p in spans):
            raise InputError(f"transfer function {self.name or self.source}: mapped takes finite numbers lo, hi "
                             f"and a source span of two, got {short_repr((lo, hi))} and {short_repr(src)}")
        (s0, s1), (lo, hi) = spans
        if hi < lo or not math.isfinite(hi - lo):
            raise InputError(f"transfer function {self.name or self.source}: cannot map onto "
                             f"[{exact_text(lo)}, {exact_text(hi)}]: reversed, or a span beyond float64's range")
        if not s1 > s0:
            raise InputError(f"transfer function {self.name or self.source}: cannot map from "
                             f"an empty value span [{exact_text(s0)}, {exact_text(s1)}]")

        def f(x):
            y = lo + (x - s0) / (s1 - s0) * (hi - lo)
            # Rounding may carry a point just below s1 past hi, and one past s1 short of it: each is
            # held to its side, or s1's own point, set to hi, would lie below its neighbour.
            y = np.where(x <= s1, np.minimum(y, hi), np.maximum(y, hi))
            y[x == s1] = hi               # land on hi exactly despite rounding
            return y

        op = self.opacity_points
        col = self.color_points
        op[:, 0] = f(op[:, 0])
        col[:, 0] = f(col[:, 0])
        return TransferFunction(_jumps_kept(op), _jumps_kept(col), name=self.name,
                                description=self.description, source=self.source)

    def to_dict(self):
        """Our file format as a dict (``space = "data"``): what `save_transfer_function` writes."""
        d = {}
        if self.name:
            d["name"] = self.name
        if self.description:
            d["description"] = self.description
        d["space"] = "data"
        d["opacity"] = [[float(x), float(a)] for x, a in zip(self._op_x, self._op_y)]
        d["color"] = [[float(x)] + [float(c) for c in rgb] for x, rgb in zip(self._col_x, self._col_rgb)]
        return d

    def __eq__(self, other):
        if not isinstance(other, TransferFunction):
            return NotImplemented
        return all(np.array_equal(p, q) for p, q in zip(self.arrays(), other.arrays()))

    __hash__ = None

    def __repr__(self):
        label = f" {self.name!r}" if self.name else ""
        return (f"<TransferFunction{label}: {len(self._op_x)} opacity points, "
                f"{len(self._col_x)} colour points, support {_fmt_support(self.support())}>")

def _frozen(a):
    a = np.ascontiguousarray(a, dtype=np.float64)
    a.setflags(write=False)
    return a

def _fmt_support(sup):
    if len(sup) == 0:
        return "empty"
    return " ".join(f"[{lo:g}, {hi:g}]" for lo, hi in sup[:4]) + (" ..." if len(sup) > 4 else "")

def short_repr(x, limit=40):
    r = repr(x)
    return r if len(r) <= limit else r[:limit - 3] + "..."

def _sized(x):
    """Whether ``x`` is a sequence of points or numbers: not text, a mapping or a set (no order),
    and ``len`` works (a NumPy 0-d array has ``__len__`` but no length)."""
    if isinstance(x, (str, bytes, dict, set, frozenset)):
        return False
    try:
        len(x)
    except TypeError:
        return False
    return True

def control_points(raw, key, fields, where, label=None):
    """Validated ``(n, 1 + len(fields))`` float64 control points from user input.

    ``label(i, j)`` names field ``j`` of point ``i`` (from 0) in messages; default
    ``key point i + 1``, counted from 1 as a scene file's tables are (ParaView's flat
    lists pass ``key number 4 i + j + 1 (point i + 1)``).
    """
    if label is None:
        def label(i, j):
            return f"{key} point {i + 1}"
    width = 1 + len(fields)
    shape = "[value, " + ", ".join(fields) + "]"
    if not _sized(raw):
        raise InputError(f"{where}: {key}: expected a list of {shape} points, got {short_repr(raw)}")
    if len(raw) == 0:
        raise InputError(f"{where}: {key}: the list is empty; give at least one {shape} point")
    out = np.empty((len(raw), width), dtype=np.float64)
    for i, p in enumerate(raw):
        if not _sized(p) or len(p) != width:
            raise InputError(f"{where}: {label(i, 0)}: expected {shape}, got {short_repr(p)}")
        for j, (name, x) in enumerate(zip(("value",) + fields, p)):
            if not is_number(x):
                raise InputError(f"{where}: {label(i, j)}: {name} must be a number, got {short_repr(x)}")
            try:
                x = float(x)
            except OverflowError:
                x = math.inf
            if not math.isfinite(x):
                raise InputError(f"{where}: {label(i, j)}: {name} must be finite, got {x}")
            if j > 0 and not 0.0 <= x <= 1.0:
                raise InputError(f"{where}: {label(i, j)}: {name} {exact_text(x)} is outside [0, 1]")
            out[i, j] = x
        if i > 0:
            v, prev = float(out[i, 0]), float(out[i - 1, 0])
            if v < prev:
                raise InputError(f"{where}: {label(i, 0)}: value {exact_text(v)} is below the previous "
                                 f"value {exact_text(prev)}; values must ascend")
            if i > 1 and v == prev == out[i - 2, 0]:
                raise InputError(f"{where}: {label(i, 0)}: value {exact_text(v)} appears a third time; "
                                 "a value may repeat once (a jump)")
            if not math.isfinite(v - prev):
                raise InputError(f"{where}: {label(i, 0)}: value {exact_text(v)} is too far from the "
                                 f"previous value {exact_text(prev)} (their difference overflows)")
    return out

def _support(x, y):
    """Maximal closed intervals containing every value with non-zero opacity, ``(K, 2)``."""
    n = len(x)
    iv = []
    if y[0] > 0.0:
        iv.append((-math.inf, x[0]))
    if y[n - 1] > 0.0:
        iv.append((x[n - 1], math.inf))
    for i in range(n):
        if y[i] > 0.0:
            iv.append((x[i], x[i]))
    for i in range(n - 1):
        if x[i] < x[i + 1] and (y[i] > 0.0 or y[i + 1] > 0.0):
            iv.append((x[i], x[i + 1]))
    iv.sort()
    merged = []
    for lo, hi in iv:
        if merged and lo <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    return np.array(merged, dtype=np.float64).reshape(-1, 2)


def _jumps_kept(points):
    """Control points with each run of equal values cut to its first and last (one jump).

    Mapped onto a range a few floats wide (a nearly constant volume), several
    points of a preset land on one value; the function jumps there from the
    first's value to the last's, and the points between say nothing more.
    """
    x = points[:, 0]
    inner = np.zeros(len(x), dtype=bool)
    inner[1:-1] = (x[1:-1] == x[:-2]) & (x[1:-1] == x[2:])
    return points[~inner]


# --------------------------------------------------------------------------
# The range query's kernels
# --------------------------------------------------------------------------
# One parallel pass each, with no temporaries: a 512x512x1734 volume's 455
# million int16 cell ranges take 0.26-0.36 s so (two threads), and took
# 0.86 s in NumPy (a lookup and two comparisons, chunk by chunk).

@kernel(parallel=True)
def _nonzero_by_table(a, a_bits, b, need, out):
    """``need[a] <= b`` and ``a <= b`` for each range (`TransferFunction._small_int_table`)."""
    n = out.shape[0]
    for c in prange(chunk_count(n, RANGE_CHUNK)):
        m0, m1 = chunk_run(c, RANGE_CHUNK, n)
        for m in range(m0, m1):
            out[m] = (need[a_bits[m]] <= b[m]) & (a[m] <= b[m])


@kernel(parallel=True)
def _nonzero_by_search(a, b, lo, hi, rounding, out):
    """Whether ``[a, b]``, widened by ``rounding`` of its largest magnitude, meets a support
    interval ``[lo, hi]``: the first interval with ``hi >= a`` starts at or below ``b``. In
    float64; a NaN end is an unknown range, met; ``a > b`` before widening, none."""
    n = out.shape[0]
    k_end = hi.shape[0]
    for c in prange(chunk_count(n, RANGE_CHUNK)):
        m0, m1 = chunk_run(c, RANGE_CHUNK, n)
        for m in range(m0, m1):
            x = np.float64(a[m])
            y = np.float64(b[m])
            if np.isnan(x) or np.isnan(y):
                out[m] = True
                continue
            ordered = x <= y
            if rounding != 0.0:
                pad = rounding * max(abs(x), abs(y))
                if np.isfinite(pad):
                    x -= pad
                    y += pad
            # The first interval ending at or above x (NumPy's searchsorted, side "left").
            first = 0
            last = k_end
            while first < last:
                mid = (first + last) >> 1
                if hi[mid] < x:
                    first = mid + 1
                else:
                    last = mid
            out[m] = ordered and first < k_end and lo[first] <= y
