"""PNG charts for the benchmark report: speed against error, timings, time breakdowns.

Pillow only (no matplotlib), so the report can be built wherever the renderer
runs. The charts are plain on purpose: white background, the Okabe-Ito
colour-blind-friendly palette with a marker shape per series (four, cycling),
and every scatter point and bar labelled. Two cases that generic plotting handles badly
are handled here because the report meets them all the time: an error of
exactly 0 on a log axis (PARC's error against `brute` is usually 0), drawn at
a marked "0" past an axis break below the smallest positive value instead of
being dropped; and degenerate data (one point, all-equal values, nothing
finite), which still gives a readable chart rather than an exception.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

#: Okabe-Ito, ordered so the first colours are the most distinct on white (yellow last).
PALETTE = [(0, 114, 178), (213, 94, 0), (0, 158, 115), (230, 159, 0), (86, 180, 233),
           (204, 121, 167), (0, 0, 0), (240, 228, 66)]
_INK, _GRID, _MUTED = (40, 40, 40), (228, 228, 228), (110, 110, 110)
_PAD = 12          # data inset from the frame (scatter/line), so no marker sits on it
_ZERO_GAP = 0.07   # share of a log axis given to its "0" slot and the break mark
_SUFFIXES = [(1e12, "T"), (1e9, "G"), (1e6, "M"), (1e3, "k")]


def fmt_number(v, digits=3) -> str:
    """Compact text for a number: ``0``, ``0.5``, ``12.5``, ``1.23k``, ``4M``, ``1e-12``.

    Parameters
    ----------
    v : float
        The value; NaN and infinities give ``"nan"``, ``"inf"``, ``"-inf"``.
    digits : int, optional
        Significant digits kept (trailing zeros dropped).

    Returns
    -------
    str
    """
    v = float(v)
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if v == 0:
        return "0"
    sign = "-" if v < 0 else ""
    a = float(f"{abs(v):.{digits}g}")  # round first, so 999999 reads 1M and not 1000k
    if a >= 1e15 or a < 1e-4:
        mantissa, exp = f"{a:.{max(digits - 1, 0)}e}".split("e")
        if "." in mantissa:
            mantissa = mantissa.rstrip("0").rstrip(".")
        return f"{sign}{mantissa}e{int(exp)}"
    for scale, suffix in _SUFFIXES:
        if a >= scale:
            return f"{sign}{a / scale:.{digits}g}{suffix}"
    return f"{sign}{a:.{digits}g}"


def _num(v):
    # Benchmark records carry None for "not measured": treat it like NaN.
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def _shown(v, log):
    return math.isfinite(v) and (v >= 0 or not log)


@dataclass(frozen=True)
class _Axis:
    """Data-to-pixel mapping along one axis: ``lo`` lands on ``px0``, ``hi`` on ``px1``.

    On a log axis with ``zero`` set, 0 lands on ``px0`` and the positive
    range starts a gap further on, where the break mark goes.
    """
    lo: float
    hi: float
    log: bool = False
    px0: float = 0.0
    px1: float = 1.0
    zero: bool = False
    ticks: tuple = ()

    @property
    def start(self):
        return self.px0 + (self.px1 - self.px0) * _ZERO_GAP if self.log and self.zero else self.px0

    def __call__(self, v):
        a, b = self.lo, self.hi
        if self.log:
            if v <= 0:
                return float(self.px0) if self.zero and v == 0 else math.nan
            v, a, b = math.log10(v), math.log10(a), math.log10(b)
        return self.start + (v - a) / (b - a) * (self.px1 - self.start)

    def placed(self, px0, px1):
        return replace(self, px0=px0, px1=px1)

    def labels(self):
        """``[(value, text)]`` for the ticks, with ``(0, "0")`` first on a log axis with a zero slot."""
        digits = 3
        if not self.log and len(self.ticks) > 1:
            # Enough digits that neighbouring ticks (10.02, 10.04) never read the same.
            step, big = self.ticks[1] - self.ticks[0], max(abs(t) for t in self.ticks)
            digits = max(3, math.floor(math.log10(big)) - math.floor(math.log10(step)) + 1)
        out = [(t, fmt_number(t, digits)) for t in self.ticks]
        return [(0.0, "0")] + out if self.log and self.zero else out


def axis_mapping(lo, hi, log, px0, px1, zero=False):
    """The data-to-pixel mapping of an axis from ``lo`` (at ``px0``) to ``hi`` (at ``px1``).

    Parameters
    ----------
    lo, hi : float
        Data range; both positive when ``log``.
    log : bool
        Logarithmic axis.
    px0, px1 : float
        Pixel coordinates of ``lo`` and ``hi``; ``px0 > px1`` for a y axis.
    zero : bool, optional
        On a log axis, map 0 to ``px0`` and start the positive range a gap after it.

    Returns
    -------
    callable
        ``f(value) -> pixel`` (NaN for values a log axis cannot show).
    """
    return _Axis(float(lo), float(hi), bool(log), px0, px1, bool(zero))


def _nice_step(raw):
    e = math.floor(math.log10(raw))
    f = raw / 10.0 ** e
    return (1 if f <= 1.5 else 2 if f <= 3 else 5 if f <= 7 else 10) * 10.0 ** e


def _data_axis(values, log, include_zero=False):
    """An unplaced axis spanning ``values`` (already finite; non-negative if ``log``), widened to ticks."""
    if log:
        pos = [v for v in values if v > 0]
        lo, hi = (min(pos), max(pos)) if pos else (1.0, 10.0)
        e0, e1 = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
        every = max(1, math.ceil((e1 - e0) / 6))  # at most ~7 decade ticks
        e1 = e0 + every * max(1, math.ceil((e1 - e0) / every))
        ticks = tuple(10.0 ** e for e in range(e0, e1 + 1, every))
        return _Axis(ticks[0], ticks[-1], True, zero=any(v == 0 for v in values), ticks=ticks)
    lo, hi = (min(values), max(values)) if values else (0.0, 1.0)
    if include_zero:
        lo, hi = min(lo, 0.0), max(hi, 0.0)
    if not hi - lo > 0:
        pad = abs(lo) * 0.1 or 1.0
        lo, hi = (lo, hi + pad) if include_zero and lo == 0 else (lo - pad, hi + pad)
    step = _nice_step((hi - lo) / 4)
    if values and all(float(v).is_integer() for v in values):
        step = max(step, 1.0)       # counts (threads, sizes) get no ticks between whole numbers
    k0, k1 = math.floor(lo / step + 1e-9), math.ceil(hi / step - 1e-9)
    ticks = tuple(float(f"{k * step:.12g}") for k in range(k0, k1 + 1))
    return _Axis(ticks[0], ticks[-1], False, ticks=ticks)


def stack_segments(parts):
    """Bottom-up ``(part, start %, end %)`` of one stacked bar, normalised to 100.

    Parameters
    ----------
    parts : dict
        Part name -> value; NaN, infinite, negative or missing values count as 0.

    Returns
    -------
    list of tuple
        All zeros when the parts sum to 0.
    """
    vals = {k: (x if _shown(x, True) else 0.0) for k, x in ((k, _num(v)) for k, v in parts.items())}
    total, acc, out = sum(vals.values()), 0.0, []
    for k, v in vals.items():
        share = 100.0 * v / total if total > 0 else 0.0
        out.append((k, acc, acc + share))
        acc += share
    return out


# --------------------------------------------------------------------------
# Drawing
# --------------------------------------------------------------------------

def _fonts():
    try:
        return ImageFont.load_default(size=14), ImageFont.load_default(size=17)
    except (TypeError, AttributeError, ImportError, OSError):  # Pillow < 10.1 or no FreeType
        font = ImageFont.load_default()
        return font, font


def _put(d, x, y, s, font, ha=0.5, va=0.5, fill=_INK):
    # Aligned by hand (anchors are not available for the bitmap fallback font), vertically
    # by the font's "Ag" box so that neighbouring labels share a baseline.
    l, _, r, _ = d.textbbox((0, 0), s, font=font)
    _, t, _, b = d.textbbox((0, 0), "Ag", font=font)
    d.text((x - l - ha * (r - l), y - t - va * (b - t)), s, font=font, fill=fill)


def _width(d, s, font):
    l, _, r, _ = d.textbbox((0, 0), s, font=font)
    return r - l


def _height(d, font):
    _, t, _, b = d.textbbox((0, 0), "Ag", font=font)
    return b - t


def _marker(d, x, y, i, colour, r=5):
    # A shape per series as well as a colour, so series stay apart in greyscale prints.
    shape = i % 4
    if shape == 0:
        d.ellipse((x - r, y - r, x + r, y + r), fill=colour)
    elif shape == 1:
        d.rectangle((x - r + 1, y - r + 1, x + r - 1, y + r - 1), fill=colour)
    elif shape == 2:
        d.polygon([(x, y - r - 1), (x + r + 1, y + r), (x - r - 1, y + r)], fill=colour)
    else:
        d.polygon([(x, y - r - 1), (x + r + 1, y), (x, y + r + 1), (x - r - 1, y)], fill=colour)


def _layout(size, fonts, *, title, x_label, y_label, y_labels, legend, note=None):
    """White canvas with title, axis labels and legend drawn; returns (image, draw, plot box)."""
    font, tfont = fonts
    w, h = int(size[0]), int(size[1])
    img = Image.new("RGB", (w, h), "white")
    d = ImageDraw.Draw(img)
    lh = _height(d, font)
    top = 28 + _height(d, tfont) if title else 16
    left = 10 + (lh + 10 if y_label else 0) + max((_width(d, s, font) for s in y_labels), default=0) + 10
    bottom = h - (18 + lh + (lh + 8 if x_label else 0) + (lh + 8 if note else 0))
    lw = max(_width(d, name or "(none)", font) for name, _, _ in legend) + 34 if legend else 0
    right = max(w - 16 - lw, left + 20)
    bottom = max(bottom, top + 20)
    if title:
        _put(d, w / 2, 12, title, tfont, va=0)
    if x_label:
        _put(d, (left + right) / 2, h - 8 - (lh + 8 if note else 0), x_label, font, va=1)
    if note:
        _put(d, 8, h - 8, note, font, ha=0, va=1, fill=_MUTED)
    if y_label:  # drawn sideways on a scratch image, since Pillow cannot rotate text itself
        l, t, r, b = d.textbbox((0, 0), y_label, font=font)
        scratch = Image.new("L", (r - l + 4, b - t + 4), 0)
        ImageDraw.Draw(scratch).text((2 - l, 2 - t), y_label, font=font, fill=255)
        scratch = scratch.rotate(90, expand=True)
        img.paste(_INK, (10, int((top + bottom - scratch.height) / 2)), scratch)
    for i, (name, colour, shape) in enumerate(legend):
        x, y = right + 14, top + 6 + 20 * i
        if shape is None:
            d.rectangle((x, y - 5, x + 10, y + 5), fill=colour)
        else:
            _marker(d, x + 5, y, shape, colour)
        _put(d, x + 18, y, name or "(none)", font, ha=0)
    return img, d, (left, top, right, bottom)


def _break_mark(d, axis, box, vertical):
    l, _, _, b = box
    m = (axis.px0 + axis.start) / 2
    if vertical:
        d.line((l, m - 4, l, m + 4), fill="white")
        d.line((l - 5, m - 1, l + 5, m - 5), fill=_INK)
        d.line((l - 5, m + 5, l + 5, m + 1), fill=_INK)
    else:
        d.line((m - 4, b, m + 4, b), fill="white")
        d.line((m - 5, b + 5, m - 1, b - 5), fill=_INK)
        d.line((m + 1, b + 5, m + 5, b - 5), fill=_INK)


def _axes(d, box, ax, ay, font):
    l, t, r, b = box
    for v, s in ay.labels():
        p = ay(v)
        d.line((l, p, r, p), fill=_GRID)
        d.line((l - 4, p, l, p), fill=_INK)
        _put(d, l - 7, p, s, font, ha=1)
    for v, s in ax.labels() if ax is not None else ():
        p = ax(v)
        d.line((p, t, p, b), fill=_GRID)
        d.line((p, b, p, b + 4), fill=_INK)
        _put(d, p, b + 7, s, font, va=0)
    d.rectangle(box, outline=_INK)
    for axis, vertical in ((ax, False), (ay, True)):
        if axis is not None and axis.log and axis.zero:
            _break_mark(d, axis, box, vertical)


def _save(img, path):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # Same folder, so os.replace is atomic: a reader never sees half a PNG.
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{id(img):x}.tmp")
    try:
        img.save(tmp, format="PNG")
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def _xy_chart(path, groups, *, connect, min_legend, title, x_label, y_label, x_log, y_log, size):
    """Scatter and line charts: ``groups`` is ``[(series, [(x, y, label), ...])]``."""
    fonts = _fonts()
    every = [(x, y) for _, pts in groups for x, y, _ in pts]
    shown = [(x, y) for x, y in every if _shown(x, x_log) and _shown(y, y_log)]
    ax = _data_axis([x for x, _ in shown], x_log)
    ay = _data_axis([y for _, y in shown], y_log)
    legend = [(n, PALETTE[i % len(PALETTE)], i) for i, (n, _) in enumerate(groups)]
    hidden = len(every) - len(shown)
    img, d, box = _layout(size, fonts, title=title, x_label=x_label, y_label=y_label,
                          y_labels=[s for _, s in ay.labels()],
                          legend=legend if len(groups) >= min_legend else [],
                          note=f"{hidden} not shown (NaN/inf, or < 0 on a log axis)"
                          if shown and hidden else None)
    l, t, r, b = box
    ax, ay = ax.placed(l + _PAD, r - _PAD), ay.placed(b - _PAD, t + _PAD)
    _axes(d, box, ax, ay, fonts[0])
    if not shown:
        _put(d, (l + r) / 2, (t + b) / 2, "no finite data", fonts[0], fill=_MUTED)
    for i, (_, pts) in enumerate(groups):
        colour = PALETTE[i % len(PALETTE)]
        # A point that cannot be shown breaks the line rather than being bridged over.
        placed = [(ax(x), ay(y), s) if _shown(x, x_log) and _shown(y, y_log) else None
                  for x, y, s in pts]
        if connect:
            run = []
            for p in placed + [None]:
                if p is None:
                    if len(run) > 1:
                        d.line(run, fill=colour, width=2)
                    run = []
                else:
                    run.append(p[:2])
        for p in filter(None, placed):
            _marker(d, p[0], p[1], i, colour)
            if p[2]:  # right of the marker, or left where it would run off the plot
                left = p[0] + 8 + _width(d, p[2], fonts[0]) > r
                _put(d, p[0] + (-8 if left else 8), p[1] - 8, p[2], fonts[0], ha=1 if left else 0)
    return _save(img, path)


def scatter_chart(path, points, *, title, x_label, y_label, x_log=False, y_log=False,
                  size=(720, 480)) -> Path:
    """Labelled points coloured by series: e.g. each method's speed against its error.

    Parameters
    ----------
    path : str or Path
        PNG to write (parent folders are created; written atomically).
    points : list of dict
        ``{"x", "y", "label", "series"}``; ``series`` defaults to ``""``. NaN,
        inf and None are skipped (and counted in a note); 0 on a log axis is
        drawn at a marked "0" below the smallest positive value.
    title, x_label, y_label : str
    x_log, y_log : bool, optional
        Logarithmic axes (decade ticks).
    size : (int, int), optional
        Image width and height in pixels.

    Returns
    -------
    Path
        The file written. A legend is drawn when there are two or more series.
    """
    groups = {}
    for p in points:
        groups.setdefault(str(p.get("series", "")), []).append(
            (_num(p.get("x")), _num(p.get("y")), str(p.get("label", ""))))
    return _xy_chart(path, list(groups.items()), connect=False, min_legend=2, title=title,
                     x_label=x_label, y_label=y_label, x_log=x_log, y_log=y_log, size=size)


def line_chart(path, series, *, title, x_label, y_label, x_log=False, y_log=False,
               size=(720, 480)) -> Path:
    """Lines with markers, one per series: e.g. time against image size or supercell size.

    Parameters
    ----------
    path : str or Path
        PNG to write.
    series : dict
        Series name -> list of ``(x, y)``, drawn in order; a point that cannot
        be shown (NaN, inf, < 0 on a log axis) breaks its line.
    title, x_label, y_label, x_log, y_log, size
        As for `scatter_chart`.

    Returns
    -------
    Path
    """
    groups = [(str(name), [(_num(x), _num(y), "") for x, y in pts]) for name, pts in series.items()]
    return _xy_chart(path, groups, connect=True, min_legend=1, title=title, x_label=x_label,
                     y_label=y_label, x_log=x_log, y_log=y_log, size=size)


def stacked_bar_chart(path, bars, *, title, y_label="share of time (%)", size=(720, 480)) -> Path:
    """Bars stacked to 100%: e.g. where the time of each render goes (raster, cast, shading).

    Parameters
    ----------
    path : str or Path
        PNG to write.
    bars : list of (str, dict)
        ``(bar label, {part: value})``; each bar is normalised to 100% (see
        `stack_segments`), percentages are written in segments tall enough.
    title, y_label, size
        As for `scatter_chart`.

    Returns
    -------
    Path
    """
    fonts = _fonts()
    bars = [(str(label), stack_segments(parts)) for label, parts in bars]
    names = list(dict.fromkeys(k for _, segs in bars for k, _, _ in segs))
    colour = {n: PALETTE[i % len(PALETTE)] for i, n in enumerate(names)}
    ay = _Axis(0.0, 100.0, ticks=(0.0, 20.0, 40.0, 60.0, 80.0, 100.0))
    # Legend top-down, to read in the same order as the stacks.
    legend = [(n, colour[n], None) for n in reversed(names)]
    img, d, box = _layout(size, fonts, title=title, x_label=None, y_label=y_label,
                          y_labels=[s for _, s in ay.labels()], legend=legend)
    l, t, r, b = box
    ay = ay.placed(b, t)
    _axes(d, box, None, ay, fonts[0])
    slot, lh = (r - l) / max(len(bars), 1), _height(d, fonts[0])
    for i, (label, segs) in enumerate(bars):
        x0, x1 = l + slot * (i + 0.2), l + slot * (i + 0.8)
        _put(d, (x0 + x1) / 2, b + 7, label, fonts[0], va=0)
        if not any(e > s for _, s, e in segs):
            _put(d, (x0 + x1) / 2, b - 3, "no data", fonts[0], va=1, fill=_MUTED)
        for name, s, e in segs:
            if e <= s:
                continue
            y0, y1 = ay(e), ay(s)
            d.rectangle((x0, y0, x1, y1), fill=colour[name], outline="white")
            if y1 - y0 >= lh + 4 and x1 - x0 >= 30:
                rr, gg, bb = colour[name]
                ink = "white" if 0.299 * rr + 0.587 * gg + 0.114 * bb < 140 else _INK
                _put(d, (x0 + x1) / 2, (y0 + y1) / 2, f"{e - s:.0f}%", fonts[0], fill=ink)
    return _save(img, path)

