"""Transfer functions: data value -> colour and opacity, for translucent volumes.

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
on which the opacity is non-zero; one ``np.searchsorted`` per range finds
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
continuous from the right). The kernel `tf_lookup` finds the segment by
binary search and interpolates ``y0 + t (y1 - y0)`` with
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

File formats
------------
Our own format, TOML or JSON with the same keys::

    name = "skin and bone"            # optional
    description = "..."               # optional
    space = "data"                    # optional: "data" (default) or "normalized"
    opacity = [[500, 0.0], [650, 0.05], [1000, 0.0]]      # [value, alpha], required
    color = [[500, 0.8, 0.5, 0.4], [1000, 1.0, 0.9, 0.8]]  # [value, r, g, b], optional (white)

With ``space = "normalized"`` the values lie in [0, 1] and map linearly
onto the data range ``(lo, hi)`` given to `load_transfer_function`.

ParaView colour-map JSON (File > Export in the colour map editor): a list
of objects (the first is used) or one object, with ``"RGBPoints": [x, r, g,
b, ...]`` and optionally ``"Points": [x, alpha, midpoint, sharpness, ...]``
(only ``x, alpha`` are used: opacity is linear between points). Without
``"Points"`` the opacity is the ramp the range presets use. Other keys
(``"Name"``, ``"ColorSpace"``, ``"NanColor"``...) are read or ignored. When
the colour points span [0, 1] or [-1, 1] (a preset meant to be stretched)
and a data range is given, both point lists are mapped onto it.
"""
from __future__ import annotations

import json
import math
import numbers
import os
import tomllib
from pathlib import Path

import numpy as np

from data_tools import InputError
from raycast.transfer import _locate, correct_opacity, tf_lookup, tf_opacity  # noqa: F401  (re-exported)

__all__ = [
    "PRESETS", "PRESET_DESCRIPTIONS", "RAMP_OPACITY", "REFERENCE_STEP_FRACTION",
    "TransferFunction", "correct_opacity", "load_transfer_function", "preset",
    "reference_step", "save_transfer_function", "tf_lookup", "tf_opacity",
]

#: Opacities are per reference step: this fraction of the smallest spacing.
REFERENCE_STEP_FRACTION = 0.25

#: Opacity at the top of the data range for the ramp presets (``greyscale``,
#: ``viridis``) and for ParaView maps without opacity points.
RAMP_OPACITY = 0.1

#: The ramp presets are transparent over this bottom fraction of the data
#: range, so the background and its noise stay empty cells.
RAMP_START = 0.1

#: Ranges tested per chunk in `TransferFunction.nonzero_in` (bounds the
#: float64 temporaries for volume-sized range arrays).
_CHUNK = 1 << 20

_OUR_KEYS = ("color", "description", "name", "opacity", "space")


def reference_step(spacing):
    """The step opacities refer to: `REFERENCE_STEP_FRACTION` of the smallest spacing."""
    return REFERENCE_STEP_FRACTION * float(min(spacing))


# --------------------------------------------------------------------------
# NumPy versions of the kernels (same operations, same order)
# --------------------------------------------------------------------------

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


# --------------------------------------------------------------------------
# The transfer function
# --------------------------------------------------------------------------

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
        op = _points(opacity, "opacity", ("alpha",), where)
        if color is None:
            col = np.array([[op[0, 0], 1.0, 1.0, 1.0]])
        else:
            col = _points(color, "color", ("r", "g", "b"), where)
        self.name = str(name)
        self.description = str(description)
        self.source = str(source)
        self._op_x = _frozen(op[:, 0])
        self._op_y = _frozen(op[:, 1])
        self._col_x = _frozen(col[:, 0])
        self._col_rgb = _frozen(col[:, 1:])
        sup = _support(self._op_x, self._op_y)
        self._sup_lo = _frozen(sup[:, 0])
        self._sup_hi = _frozen(sup[:, 1])

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
        return _interp(self._op_x, self._op_y, np.asarray(values, dtype=np.float64))

    def color(self, values):
        """Straight RGB at ``values``: shape ``values.shape + (3,)``, bit for bit as `tf_lookup`."""
        return _interp(self._col_x, self._col_rgb, np.asarray(values, dtype=np.float64))

    def lookup(self, values):
        """Straight RGBA at ``values``: shape ``values.shape + (4,)``."""
        v = np.asarray(values, dtype=np.float64)
        return np.concatenate([self.color(v), self.opacity(v)[..., None]], axis=-1)

    # -- classification ---------------------------------------------------

    def support(self):
        """Where the opacity may be non-zero: ``(K, 2)`` float64 ``[lo, hi]`` rows.

        Sorted, disjoint maximal closed intervals (``lo == hi`` for an isolated
        point; ``-inf``/``inf`` where a constant end is non-zero). Every value
        at which `tf_opacity` returns more than 0 lies in one of them.
        """
        return np.column_stack([self._sup_lo, self._sup_hi])

    def nonzero_in(self, mn, mx):
        """Whether the opacity is non-zero somewhere in each closed range ``[mn, mx]``.

        Parameters
        ----------
        mn, mx : array_like
            Range bounds, any real dtype (compared in float64, as the kernels
            read samples), broadcast together; e.g. `parc.classify.cell_minmax`.

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
        Per range, one ``np.searchsorted`` in the support's interval ends,
        done in chunks so volume-sized inputs need little extra memory. For
        8- and 16-bit integer ranges (CT, most scanned data) the search is
        done once per possible value instead, and each range costs one
        table lookup (CThead's 7.3M cells: ~35 ms against ~180 ms).
        """
        mn = np.asarray(mn)
        mx = np.asarray(mx)
        shape = np.broadcast_shapes(mn.shape, mx.shape)
        if mn.shape != shape or mx.shape != shape:
            mn, mx = np.broadcast_arrays(mn, mx)
        a_all = mn.reshape(-1)
        b_all = mx.reshape(-1)
        out = np.zeros(a_all.shape, dtype=bool)
        if len(self._sup_lo) == 0:
            return out.reshape(shape)
        small_int = (a_all.dtype == b_all.dtype and a_all.dtype.kind in "iu"
                     and a_all.dtype.itemsize <= 2)
        test = self._small_int_test(a_all.dtype) if small_int else self._float_test
        for s in range(0, len(a_all), _CHUNK):
            out[s:s + _CHUNK] = test(a_all[s:s + _CHUNK], b_all[s:s + _CHUNK])
        return out.reshape(shape)

    def _float_test(self, a, b):
        """`nonzero_in` for one chunk, in float64."""
        a = a.astype(np.float64, copy=False)
        b = b.astype(np.float64, copy=False)
        lo, hi = self._sup_lo, self._sup_hi
        k = np.searchsorted(hi, a, side="left")          # first interval with hi >= mn
        hit = k < len(lo)
        hit &= lo[np.minimum(k, len(lo) - 1)] <= b       # ... starts at or below mx
        hit &= a <= b
        hit |= np.isnan(a) | np.isnan(b)
        return hit

    def _small_int_test(self, dtype):
        """`nonzero_in` for 8- and 16-bit integer ranges: one table lookup per range.

        For every value ``m`` of the dtype, ``need[m]`` is the least integer
        ``mx`` for which ``[m, mx]`` meets the support: the ceiling of the
        start of the first interval ending at or above ``m`` (the same
        float64 search as `_float_test`, done once per value, not per range).
        The table is indexed by the bit pattern (``view`` as unsigned), so
        signed data needs no widened copy.
        """
        info = np.iinfo(dtype)
        values = np.arange(info.min, info.max + 1, dtype=np.float64)
        lo, hi = self._sup_lo, self._sup_hi
        k = np.searchsorted(hi, values, side="left")
        start = np.where(k < len(lo), np.ceil(lo[np.minimum(k, len(lo) - 1)]), np.inf)
        need = np.clip(start, info.min, info.max + 1).astype(np.int32)
        udtype = np.dtype(f"u{dtype.itemsize}")
        if info.min < 0:                                  # bit pattern order: 0..max, then min..-1
            need = np.concatenate([need[-info.min:], need[:-info.min]])

        def test(a, b):
            hit = need[a.view(udtype)] <= b
            hit &= a <= b
            return hit
        return test

    # -- conversions ------------------------------------------------------

    def mapped(self, lo, hi, *, src=(0.0, 1.0)):
        """The same function with values mapped affinely from ``src`` onto ``[lo, hi]``.

        ``src = (0, 1)`` turns a normalized function into one over the data range.
        """
        s0, s1 = float(src[0]), float(src[1])
        lo, hi = float(lo), float(hi)
        if not s1 > s0:
            raise InputError(f"transfer function {self.name or self.source}: cannot map from "
                             f"an empty value span [{s0:g}, {s1:g}]")

        def f(x):
            y = lo + (x - s0) / (s1 - s0) * (hi - lo)
            y[x == s1] = hi               # land on hi exactly despite rounding
            return y

        op = self.opacity_points
        col = self.color_points
        op[:, 0] = f(op[:, 0])
        col[:, 0] = f(col[:, 0])
        return TransferFunction(op, col, name=self.name, description=self.description,
                                source=self.source)

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


def _short(x, limit=40):
    r = repr(x)
    return r if len(r) <= limit else r[:limit - 3] + "..."


def _is_number(x):
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_))


def _points(raw, key, fields, where, label=None):
    """Validated ``(n, 1 + len(fields))`` float64 control points from user input.

    ``label(i, j)`` names field ``j`` of point ``i`` in messages; default
    ``key[i]`` (ParaView's flat lists pass ``key[4 i + j]``).
    """
    if label is None:
        def label(i, j):
            return f"{key}[{i}]"
    width = 1 + len(fields)
    shape = "[value, " + ", ".join(fields) + "]"
    if isinstance(raw, (str, bytes, dict)) or not hasattr(raw, "__len__"):
        raise InputError(f"{where}: {key}: expected a list of {shape} points, got {_short(raw)}")
    if len(raw) == 0:
        raise InputError(f"{where}: {key}: the list is empty; give at least one {shape} point")
    out = np.empty((len(raw), width), dtype=np.float64)
    for i, p in enumerate(raw):
        if isinstance(p, (str, bytes, dict)) or not hasattr(p, "__len__") or len(p) != width:
            raise InputError(f"{where}: {label(i, 0)}: expected {shape}, got {_short(p)}")
        for j, (name, x) in enumerate(zip(("value",) + fields, p)):
            if not _is_number(x):
                raise InputError(f"{where}: {label(i, j)}: {name} must be a number, got {_short(x)}")
            try:
                x = float(x)
            except OverflowError:
                x = math.inf
            if not math.isfinite(x):
                raise InputError(f"{where}: {label(i, j)}: {name} must be finite, got {x}")
            if j > 0 and not 0.0 <= x <= 1.0:
                raise InputError(f"{where}: {label(i, j)}: {name} {x:g} is outside [0, 1]")
            out[i, j] = x
        if i > 0:
            v, prev = float(out[i, 0]), float(out[i - 1, 0])
            if v < prev:
                raise InputError(f"{where}: {label(i, 0)}: value {v:g} is below the previous "
                                 f"value {prev:g}; values must ascend")
            if i > 1 and v == prev == out[i - 2, 0]:
                raise InputError(f"{where}: {label(i, 0)}: value {v:g} appears a third time; "
                                 "a value may repeat once (a jump)")
            if not math.isfinite(v - prev):
                raise InputError(f"{where}: {label(i, 0)}: value {v:g} is too far from the previous "
                                 f"value {prev:g} (their difference overflows)")
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


# --------------------------------------------------------------------------
# Presets
# --------------------------------------------------------------------------

#: Viridis (matplotlib; van der Walt, Smith, Firing; CC0): 32 of its 256
#: colours, ``(position in [0, 1], r, g, b)``, sample ``i`` at ``i / 255``.
#: Linear interpolation between them stays within 0.0065 of the full table.
VIRIDIS = (
    (0, 0.267004, 0.004874, 0.329415), (8, 0.277018, 0.050344, 0.375715),
    (16, 0.282327, 0.094955, 0.417331), (25, 0.282623, 0.140926, 0.457517),
    (33, 0.278012, 0.180367, 0.486697), (41, 0.269308, 0.218818, 0.509577),
    (49, 0.257322, 0.256130, 0.526563), (58, 0.241237, 0.296485, 0.539709),
    (66, 0.225863, 0.330805, 0.547314), (74, 0.210503, 0.363727, 0.552206),
    (82, 0.195860, 0.395433, 0.555276), (90, 0.182256, 0.426184, 0.557120),
    (99, 0.168126, 0.459988, 0.558082), (107, 0.156270, 0.489624, 0.557936),
    (115, 0.144759, 0.519093, 0.556572), (123, 0.133743, 0.548535, 0.553541),
    (132, 0.123463, 0.581687, 0.547445), (140, 0.119423, 0.611141, 0.538982),
    (148, 0.124780, 0.640461, 0.527068), (156, 0.143303, 0.669459, 0.511215),
    (165, 0.180653, 0.701402, 0.488189), (173, 0.226397, 0.728888, 0.462789),
    (181, 0.281477, 0.755203, 0.432552), (189, 0.344074, 0.780029, 0.397381),
    (197, 0.412913, 0.803041, 0.357269), (206, 0.496615, 0.826376, 0.306377),
    (214, 0.575563, 0.844566, 0.256415), (222, 0.657642, 0.860219, 0.203082),
    (230, 0.741388, 0.873449, 0.149561), (239, 0.835270, 0.886029, 0.102646),
    (247, 0.916242, 0.896091, 0.100717), (255, 0.993248, 0.906157, 0.143936),
)

# CT presets are in the units of 16-bit CT like the Stanford CThead (not
# Hounsfield: air 0-300, skin and soft tissue ~1000-1100, bone 1200-3000;
# the air/skin boundary passes 500-900, the tissue/bone one 1100-1300).
# Opacities are per reference step (a quarter voxel): 0.08 makes a few
# voxels of skin a visible shell, 0.024 (skin in ct_skin_bone) a veil, and
# 0.5 is opaque within a voxel.
_SKIN_OPACITY = ((400.0, 0.0), (600.0, 0.08), (850.0, 0.08), (1000.0, 0.0))
_SKIN_COLOR = ((400.0, 0.70, 0.40, 0.30), (700.0, 0.93, 0.68, 0.55), (1000.0, 1.0, 0.82, 0.70))
_BONE_OPACITY = ((1200.0, 0.0), (1500.0, 0.4), (2000.0, 0.7))
_BONE_COLOR = ((1200.0, 0.90, 0.80, 0.65), (1600.0, 1.0, 0.96, 0.88), (2500.0, 1.0, 1.0, 1.0))


def _ct_skin(data_range=None):
    return TransferFunction(_SKIN_OPACITY, _SKIN_COLOR, name="ct_skin",
                            description=PRESET_DESCRIPTIONS["ct_skin"], source="preset ct_skin")


def _ct_bone(data_range=None):
    return TransferFunction(_BONE_OPACITY, _BONE_COLOR, name="ct_bone",
                            description=PRESET_DESCRIPTIONS["ct_bone"], source="preset ct_bone")


def _ct_skin_bone(data_range=None):
    skin = tuple((v, 0.3 * a) for v, a in _SKIN_OPACITY)   # a veil: bone shows through
    return TransferFunction(skin + _BONE_OPACITY, _SKIN_COLOR + _BONE_COLOR, name="ct_skin_bone",
                            description=PRESET_DESCRIPTIONS["ct_skin_bone"],
                            source="preset ct_skin_bone")


def _ramp_opacity():
    """The ramp presets' opacity over a normalized [0, 1] range."""
    return ((0.0, 0.0), (RAMP_START, 0.0), (1.0, RAMP_OPACITY))


def _greyscale(data_range=None):
    lo, hi = _data_range(data_range, "greyscale")
    tf = TransferFunction(_ramp_opacity(), ((0.0, 0.0, 0.0, 0.0), (1.0, 1.0, 1.0, 1.0)),
                          name="greyscale", description=PRESET_DESCRIPTIONS["greyscale"],
                          source="preset greyscale")
    return tf.mapped(lo, hi)


def _viridis(data_range=None):
    lo, hi = _data_range(data_range, "viridis")
    col = [(i / 255.0, r, g, b) for i, r, g, b in VIRIDIS]
    tf = TransferFunction(_ramp_opacity(), col, name="viridis",
                          description=PRESET_DESCRIPTIONS["viridis"], source="preset viridis")
    return tf.mapped(lo, hi)


def _data_range(data_range, who):
    """``(lo, hi)`` floats with ``hi > lo`` (a one-value range is widened to ``(lo, lo + 1)``)."""
    if data_range is None:
        raise InputError(f"{who} spans the data range: give the data range (lo, hi)")
    try:
        lo, hi = (float(v) for v in data_range)
    except (TypeError, ValueError):
        raise InputError(f"{who}: data range must be two numbers, got {_short(data_range)}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and math.isfinite(hi - lo)):
        raise InputError(f"{who}: data range must be finite, got ({lo:g}, {hi:g})")
    if hi < lo:
        raise InputError(f"{who}: data range ({lo:g}, {hi:g}) is reversed")
    if hi == lo:
        hi = lo + max(1.0, abs(lo) * 1e-9)
    return lo, hi


#: One line per preset, for ``--help`` and listings.
PRESET_DESCRIPTIONS = {
    "ct_skin": "CThead-like CT: translucent skin-toned shell at the air/skin boundary (500-900)",
    "ct_bone": "CThead-like CT: whitish, nearly opaque bone (1200 and up)",
    "ct_skin_bone": "CThead-like CT: faint skin over opaque bone, the classic CT look",
    "greyscale": "black to white over the data range, opacity ramping up from 10% of it",
    "viridis": "viridis colours over the data range, opacity ramping up from 10% of it",
}

#: Preset name -> factory ``f(data_range=None) -> TransferFunction``. The
#: CT presets use absolute values and ignore the range; the others need it.
PRESETS = {
    "ct_skin": _ct_skin,
    "ct_bone": _ct_bone,
    "ct_skin_bone": _ct_skin_bone,
    "greyscale": _greyscale,
    "viridis": _viridis,
}


def preset(name, data_range=None):
    """The preset ``name`` for data in ``data_range = (lo, hi)``; see `PRESETS`."""
    if name not in PRESETS:
        raise InputError(f"unknown transfer function preset {name!r}; known: {', '.join(PRESETS)}")
    return PRESETS[name](data_range)


# --------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------

def load_transfer_function(spec, data_range=None):
    """A transfer function from a preset name or a file.

    Parameters
    ----------
    spec : str, path or TransferFunction
        A name in `PRESETS`, or a ``.toml`` / ``.json`` file in our format or
        ParaView's (see the module notes). A TransferFunction is returned as is.
    data_range : (lo, hi), optional
        The volume's value range: needed by the ramp presets and
        ``space = "normalized"`` files, and used to stretch normalized
        ParaView maps.

    Returns
    -------
    TransferFunction

    Raises
    ------
    InputError
        One line naming the file (or preset) and the offending key.
    """
    if isinstance(spec, TransferFunction):
        return spec
    text = os.fspath(spec)
    if text in PRESETS:
        return preset(text, data_range)
    path = Path(text)
    ext = path.suffix.lower()
    if not path.exists():
        if ext in (".toml", ".json") or os.sep in text or "/" in text:
            raise InputError(f"transfer function file not found: {text}")
        raise InputError(f"unknown transfer function preset {text!r}; known: {', '.join(PRESETS)}; "
                         "or give a .toml or .json file")
    where = f"transfer function {text}"
    if ext not in (".toml", ".json"):
        raise InputError(f"{where}: unknown file type {ext or '(none)'!r}; use .toml or .json")
    if path.is_dir():
        raise InputError(f"{where}: is a directory, not a file")
    try:
        raw = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{where}: not a UTF-8 text file") from None
    except OSError as exc:
        raise InputError(f"{where}: cannot read: {exc.strerror or exc}") from None
    if ext == ".toml":
        try:
            doc = tomllib.loads(raw)
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"{where}: malformed TOML: {exc}") from None
    else:
        try:
            doc = json.loads(raw)
        except json.JSONDecodeError as exc:
            raise InputError(f"{where}: malformed JSON: {exc}") from None
        if isinstance(doc, list) or (isinstance(doc, dict) and "RGBPoints" in doc):
            return _from_paraview(doc, where, text, data_range)
    if not isinstance(doc, dict):
        raise InputError(f"{where}: expected an object with 'opacity' and 'color' keys, "
                         f"got a {type(doc).__name__}")
    return _from_ours(doc, where, text, data_range)


def _from_ours(doc, where, source, data_range):
    unknown = sorted(set(doc) - set(_OUR_KEYS))
    if unknown:
        raise InputError(f"{where}: unknown key{'s' if len(unknown) > 1 else ''} "
                         f"{', '.join(repr(k) for k in unknown)}; known: {', '.join(_OUR_KEYS)}")
    for key in ("name", "description", "space"):
        if key in doc and not isinstance(doc[key], str):
            raise InputError(f"{where}: {key}: must be a string, got {_short(doc[key])}")
    if "opacity" not in doc:
        raise InputError(f"{where}: opacity: missing; give opacity = [[value, alpha], ...]")
    space = doc.get("space", "data")
    if space not in ("data", "normalized"):
        raise InputError(f"{where}: space: must be \"data\" or \"normalized\", got {space!r}")
    tf = TransferFunction(doc["opacity"], doc.get("color"), name=doc.get("name", ""),
                          description=doc.get("description", ""), source=source)
    if space == "normalized":
        for key, xs in (("opacity", tf.arrays()[0]), ("color", tf.arrays()[2])):
            bad = np.flatnonzero((xs < 0.0) | (xs > 1.0))
            if len(bad):
                raise InputError(f"{where}: {key}[{bad[0]}]: value {xs[bad[0]]:g} is outside [0, 1] "
                                 "(space = \"normalized\")")
        if data_range is None:
            raise InputError(f"{where}: space: \"normalized\" needs the data range (lo, hi)")
        lo, hi = _data_range(data_range, where)
        tf = tf.mapped(lo, hi)
    return tf


def _from_paraview(doc, where, source, data_range):
    if isinstance(doc, list):
        if not doc:
            raise InputError(f"{where}: the ParaView colour-map list is empty")
        doc = doc[0]
        if not isinstance(doc, dict):
            raise InputError(f"{where}: [0]: expected a ParaView colour-map object, got {_short(doc)}")
    name = doc.get("Name", "")
    if not isinstance(name, str):
        raise InputError(f"{where}: Name: must be a string, got {_short(name)}")
    if "RGBPoints" not in doc:
        extra = " (indexed/categorical maps are not supported)" if "IndexedColors" in doc else ""
        raise InputError(f"{where}: RGBPoints: missing{extra}")
    col = _points(_flat_groups(doc["RGBPoints"], "RGBPoints", 4, 4, where), "RGBPoints",
                  ("r", "g", "b"), where, label=lambda i, j: f"RGBPoints[{4 * i + j}]")
    if "Points" in doc:
        op = _points(_flat_groups(doc["Points"], "Points", 4, 2, where), "Points", ("alpha",),
                     where, label=lambda i, j: f"Points[{4 * i + j}]")
    else:
        x0, x1 = col[0, 0], col[-1, 0]
        span = x1 - x0 if x1 > x0 else 1.0
        op = np.array(_ramp_opacity())
        op[:, 0] = x0 + op[:, 0] * span
        op[-1, 0] = x0 + span
    tf = TransferFunction(op, col, name=name, source=source)
    x0, x1 = col[0, 0], col[-1, 0]
    normalized = x1 > x0 and abs(x1 - 1.0) <= 1e-6 and (abs(x0) <= 1e-6 or abs(x0 + 1.0) <= 1e-6)
    if normalized and data_range is not None:
        lo, hi = _data_range(data_range, where)
        tf = tf.mapped(lo, hi, src=(x0, x1))
    return tf


def _flat_groups(raw, key, group, keep, where):
    """``[[x, ...], ...]`` from a flat ParaView list in groups of ``group``, first ``keep`` of each."""
    shape = "[x, r, g, b, ...]" if key == "RGBPoints" else "[x, alpha, midpoint, sharpness, ...]"
    if not isinstance(raw, list):
        raise InputError(f"{where}: {key}: expected a flat list {shape}, got {_short(raw)}")
    if not raw:
        raise InputError(f"{where}: {key}: the list is empty")
    if len(raw) % group:
        raise InputError(f"{where}: {key}: {len(raw)} numbers is not a multiple of {group} {shape}")
    for i, x in enumerate(raw):
        if not _is_number(x):
            raise InputError(f"{where}: {key}[{i}]: must be a number, got {_short(x)}")
    return [raw[i:i + keep] for i in range(0, len(raw), group)]


def save_transfer_function(tf, path):
    """Write ``tf`` to ``path`` (``.toml`` or ``.json``) in our format; `load_transfer_function` reads it back equal."""
    path = Path(path)
    ext = path.suffix.lower()
    d = tf.to_dict()
    if ext == ".json":
        text = json.dumps(d, indent=2) + "\n"
    elif ext == ".toml":
        lines = []
        for key in ("name", "description", "space"):
            if key in d:
                # A JSON string is a TOML basic string, once DEL is escaped too.
                value = json.dumps(d[key], ensure_ascii=False).replace("\x7f", "\\u007f")
                lines.append(f"{key} = {value}")
        for key in ("opacity", "color"):
            lines.append(f"{key} = [")
            lines += ["    [" + ", ".join(repr(float(x)) for x in p) + "]," for p in d[key]]
            lines.append("]")
        text = "\n".join(lines) + "\n"
    else:
        raise InputError(f"transfer function {path}: unknown file type {ext or '(none)'!r}; "
                         "use .toml or .json")
    path.write_text(text, encoding="utf-8")
