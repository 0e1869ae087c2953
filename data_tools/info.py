"""Summaries of a volume (``parc info``): sizes, value statistics and suggested isovalues."""
from __future__ import annotations

import math

import numpy as np

from .volume import Volume

PERCENTILES = (1, 5, 25, 50, 75, 95, 99)
#: Bins of the histogram ``parc info`` draws between the data's min and max.
HISTOGRAM_BINS = 16
#: Characters of the longest histogram bar.
BAR_WIDTH = 40
#: Statistics beyond min/max and zeros use a subsample of at most this many samples.
SAMPLE_LIMIT = 1 << 21


def _subsample(data: np.ndarray, limit: int = SAMPLE_LIMIT) -> np.ndarray:
    """At most ``limit`` samples of ``data``, flattened: one at a random place in each of
    ``limit`` equal runs of the samples in memory order, the same places every time (all of
    them when they are few). A regular stride along each axis missed whole slices: those of a
    volume two slices thick, or every other one, where a scan's content was interleaved."""
    flat = data.reshape(-1)
    if flat.size <= limit:
        return flat
    run = flat.size / limit
    picks = ((np.arange(limit) + np.random.default_rng(0).random(limit)) * run).astype(np.int64)
    return flat[np.minimum(picks, flat.size - 1)]


def volume_info(vol: Volume) -> dict:
    """Facts about a volume for ``parc info`` and reports.

    Parameters
    ----------
    vol : Volume

    Returns
    -------
    dict
        ``name``, ``dims`` (nx, ny, nz), ``dtype``, ``spacing``, ``origin``,
        ``extent``, ``nbytes``, ``min``, ``max``, ``mean``, ``percentiles``
        ({1: v, 5: v, ..., 99: v}), ``zero_fraction``, ``sampled`` (how many
        samples the percentiles, mean and histogram came from),
        ``histogram`` (``counts`` in at most `HISTOGRAM_BINS` bins from min
        to max, and their ``edges``, at ``x.5`` for integer data; None for
        a constant volume),
        ``suggested_isovalues`` and, when the reader left one, ``note``.
    """
    lo, hi = vol.value_range()
    sample = _subsample(vol.data)
    flat = sample.reshape(-1)
    # In float64: NumPy interpolates integer samples in their own type, and a 32-bit range wrapped
    # (int32 data from -2^31 to 2^31-1 gave a 5th percentile of -2.9e9).
    pct = np.percentile(flat.astype(np.float64) if flat.dtype.kind in "iu" else flat, PERCENTILES)
    info = {
        "name": vol.name,
        "dims": vol.dims,
        "dtype": vol.dtype.name,
        "spacing": vol.spacing,
        "origin": vol.origin,
        "extent": vol.extent,
        "nbytes": int(vol.data.nbytes),
        "min": lo,
        "max": hi,
        "mean": float(flat.mean(dtype=np.float64)),
        "percentiles": {p: float(v) for p, v in zip(PERCENTILES, pct)},
        "zero_fraction": 1.0 - np.count_nonzero(vol.data) / vol.data.size,
        "sampled": int(flat.size),
        "histogram": _shown_histogram(flat, lo, hi),
        "suggested_isovalues": suggest_isovalues(vol),
    }
    for key in ("format", "note"):
        if key in vol.meta:
            info[key] = vol.meta[key]
    return info


def _shown_histogram(flat, lo, hi):
    if not hi > lo:
        return None
    counts, edges = _histogram(flat, lo, hi, np.issubdtype(flat.dtype, np.integer), HISTOGRAM_BINS)
    if counts is None:
        return None
    return {"edges": [float(e) for e in edges], "counts": [int(c) for c in counts]}


def exact_text(value) -> str:
    """A data value as short as ``:g`` writes it where that is exact, else in full: pasted
    back as an isovalue it must give the same surface (``:g`` wrote 1073741823.5 as
    1.07374e+09, and 0.9999994 as 0.999999, below the data's minimum)."""
    short = f"{value:g}"
    if float(short) == value:
        return short
    if float(value).is_integer() and abs(value) < 2.0 ** 53:
        return str(int(value))              # an int32 range: 2147483647, not 2147483647.0
    return repr(float(value))


def _fmt(v) -> str:
    """Six digits, but every digit of a whole number (a percentile of 30000002 is no 3e+07)."""
    if isinstance(v, float) and v.is_integer() and abs(v) < 1e16:
        return str(int(v))
    return f"{v:.6g}" if isinstance(v, float) else str(v)


def _histogram_lines(hist, sampled):
    """One line per bin: its range, a bar whose length grows with the log of its count (a CT's
    air would flatten every other bar), and its share of the samples."""
    counts = hist["counts"]
    top = math.log1p(max(counts))
    # Enough digits to tell the edges apart (a range of 1e-6 about 1 needs more than six).
    for digits in range(6, 18):
        edges = [f"{e:.{digits}g}" for e in hist["edges"]]
        if len(set(edges)) == len(edges):
            break
    wide = max(len(e) for e in edges)
    lines = [f"histogram:   {len(counts)} bins, bars by the log of the count"]
    for i, count in enumerate(counts):
        bar = "#" * round(BAR_WIDTH * math.log1p(count) / top) if count else ""
        lines.append(f"  {edges[i]:>{wide}} .. {edges[i + 1]:<{wide}}  {bar:<{BAR_WIDTH}} "
                     f"{100 * count / sampled:5.1f}%")
    return lines


def _size_text(nbytes) -> str:
    """Bytes in the largest unit (up to MiB) that leaves a small volume's size above 0.0."""
    if nbytes < 1024:
        return f"{nbytes} bytes"
    if nbytes < 2**20:
        return f"{nbytes / 1024:.1f} KiB"
    return f"{nbytes / 2**20:.1f} MiB"


def format_info(info: dict) -> str:
    """Human-readable multi-line text of a :func:`volume_info` dict."""
    nx, ny, nz = info["dims"]
    triple = lambda t: ", ".join(_fmt(float(v)) for v in t)  # noqa: E731
    lines = [
        f"volume:      {info['name']}" + (f" ({info['format']})" if "format" in info else ""),
        f"dimensions:  {nx} x {ny} x {nz} (x, y, z), {nx * ny * nz} samples",
        f"type:        {info['dtype']}, {_size_text(info['nbytes'])}",
        f"spacing:     {triple(info['spacing'])}",
        f"origin:      {triple(info['origin'])}",
        f"extent:      {triple(info['extent'])}",
        f"range:       {exact_text(info['min'])} .. {exact_text(info['max'])}, mean {_fmt(info['mean'])}",
        "percentiles: " + ", ".join(f"{p}%: {_fmt(v)}" for p, v in info["percentiles"].items()),
        f"zeros:       {100 * info['zero_fraction']:.1f}%",
    ]
    if info.get("histogram"):
        lines += _histogram_lines(info["histogram"], info["sampled"])
    none = ("none (constant volume)" if info["min"] == info["max"]
            else "none (no level lies strictly between the samples' values)")
    lines.append("suggested isovalues: " + (", ".join(exact_text(v) for v in info["suggested_isovalues"]) or none))
    if info["sampled"] < nx * ny * nz:
        lines.append(f"(mean, percentiles and histogram from a subsample of {info['sampled']} samples)")
    if "note" in info:
        lines.append(f"note:        {info['note']}")
    return "\n".join(lines)


def _histogram(values: np.ndarray, lo: float, hi: float, integer: bool, bins: int):
    """Counts and bin edges; integer data get integer-wide bins with edges at x.5."""
    if integer:
        width = max(1, math.ceil((hi - lo + 1) / bins))
        nb = math.ceil((hi - lo + 1) / width)
        edges = lo - 0.5 + width * np.arange(nb + 1, dtype=np.float64)
        idx = ((values.astype(np.int64) - int(lo)) // width)
        counts = np.bincount(idx, minlength=nb)[:nb]
    else:
        with np.errstate(all="ignore"):
            edges = np.linspace(lo, hi, bins + 1)
        if not (np.isfinite(edges).all() and np.all(np.diff(edges) > 0)):
            return None, None
        counts, edges = np.histogram(values, bins=edges)
    return counts.astype(np.float64), edges


def _multi_otsu(counts: np.ndarray, centers: np.ndarray, k: int) -> list:
    """Edge indices of the ``k`` thresholds maximising between-class variance (non-empty classes)."""
    nb = counts.size
    p0 = np.concatenate(([0.0], np.cumsum(counts)))
    s0 = np.concatenate(([0.0], np.cumsum(counts * centers)))
    # gain[i, j]: the class holding bins i..j-1 contributes S^2 / P; empty classes are forbidden.
    dp_ = p0[None, :] - p0[:, None]
    ds_ = s0[None, :] - s0[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.where(dp_ > 0, ds_ * ds_ / np.where(dp_ > 0, dp_, 1.0), -np.inf)
    gain[np.tril_indices(nb + 1)] = -np.inf
    best = gain[0].copy()            # best[j]: one class over bins 0..j-1
    choice = []
    for _ in range(k):
        total = best[:, None] + gain  # last class i..j-1 after the best split of 0..i-1
        arg = np.argmax(total, axis=0)
        best = total[arg, np.arange(nb + 1)]
        choice.append(arg)
    cuts, j = [], nb
    for arg in reversed(choice):
        j = int(arg[j])
        cuts.append(j)
    return sorted(cuts)


def default_isovalue(levels):
    """The level a render without ``--iso`` takes from :func:`suggest_isovalues`' ``levels``, and
    ``parc make`` names for a volume made for none: the middle one; None where there is none."""
    return levels[len(levels) // 2] if levels else None


def suggest_isovalues(vol: Volume, k: int = 3, *, bins: int = 256) -> list:
    """Isovalues likely to show distinct surfaces, from the value histogram.

    Multi-level Otsu thresholds (``k`` thresholds, ``k + 1`` non-empty
    classes) on a subsample of the volume, leaving out samples equal to the
    minimum (padding, clipped air and fill values would otherwise dominate), and to the
    maximum where it lies farther from the rest than they span (a fill value), binned over
    the range of the samples kept. A threshold
    that falls in a gap of the histogram moves to the gap's middle. For
    integer data every value is at ``x.5``, so it never equals a sample.

    Parameters
    ----------
    vol : Volume
    k : int
        How many values to suggest at most.
    bins : int
        Histogram resolution.

    Returns
    -------
    list of float
        Sorted, distinct, strictly between the data minimum and maximum;
        fewer than ``k`` when the data have too few distinct levels, empty
        for a constant volume.
    """
    lo, hi = vol.value_range()
    if not hi > lo or k < 1:
        return []
    values = _subsample(vol.data).reshape(-1)
    fg = values[values != vol.data.dtype.type(lo)]
    if fg.size == 0 or fg.min() == fg.max():
        fg = values  # background removal left one level: split the full data instead
    top = fg.max()
    rest = fg[fg != top]
    if rest.size and rest.min() < rest.max() and float(top) - float(rest.max()) > float(rest.max()) - float(rest.min()):
        # A value at the maximum farther from the others than they span is a fill too (a float32
        # 3.4e38 outside a scan); a saturated top level (a CT's 4095 beside 4094) is kept.
        fg = rest
    integer = vol.dtype.kind in "iu"
    # Float samples that are all whole numbers (a CT stored as float32) are cut at x.5 too, the
    # shortest number near a cut being often a sample value; from 2^24 on, x.5 is long to read
    # and no float32 sample, and the shortest number off the samples is taken.
    whole = integer or (bool(np.all(np.mod(fg, 1.0) == 0.0)) and float(np.abs(fg).max()) < 2.0 ** 24)
    seen = None if whole else np.unique(values)         # sorted, for `_shortest`
    # Binned over the samples kept, not the whole range: a fill value at the minimum (a float32
    # -3.4e38 outside a scan) left every other sample in the top bin, and the cut in the gap.
    counts, edges = _histogram(fg, float(fg.min()), float(fg.max()), integer, bins)
    if counts is None:
        # A float range too narrow (or too wide) to split into bins: offer its middle.
        return _middle(fg.min(), fg.max(), lo, hi, whole)
    nonempty = int(np.count_nonzero(counts))
    if nonempty < 2:
        counts, edges = _histogram(values, lo, hi, integer, bins)
        nonempty = int(np.count_nonzero(counts))
    k = min(k, nonempty - 1)
    if k < 1:
        # The subsample holds one level, and the range more (a lone voxel the subsample missed):
        # the range's middle shows what is there.
        return _middle(lo, hi, lo, hi, whole)
    centers = 0.5 * (edges[:-1] + edges[1:])
    # Scaled to at most 1: the class sums are squared, and values past 1e154
    # overflowed (the cut fell to the first bin). Otsu's cuts do not change
    # when the values are scaled.
    cuts = _multi_otsu(counts, centers / max(float(np.abs(centers).max()), 1e-300), k)
    result = []
    for j in cuts:
        left, right = j, j
        while left > 0 and counts[left - 1] == 0:
            left -= 1
        while right < counts.size and counts[right] == 0:
            right += 1
        j_mid = (left + right) // 2
        j_mid = min(max(j_mid, 1), counts.size - 1)
        v = float(edges[j_mid])
        if whole:
            v = math.floor(v) + 0.5
        else:
            # Any value near the cut splits the histogram alike: take the shortest, within half a
            # bin of it or inside the gap it lies in (a sphere's distance field: 7.3, not 7.340737462043762).
            if left < right:            # empty bins left .. right - 1
                a, b = float(edges[left]), float(edges[right])
            else:
                half = 0.5 * float(edges[1] - edges[0])
                a, b = v - half, v + half
            v = _shortest(v, a, b, lo, hi, seen)
        if lo < v < hi:
            result.append(v)
    return sorted(set(result))


def _middle(a, b, lo, hi, whole):
    """The middle of ``a`` and ``b`` (at x.5 for ``whole`` samples) as the one level suggested,
    where it lies strictly inside the data's range ``(lo, hi)``."""
    mid = float(0.5 * float(a) + 0.5 * float(b))
    mid = math.floor(mid) + 0.5 if whole else mid
    return [mid] if lo < mid < hi else []


def _shortest(v, a, b, lo, hi, seen=()):
    """The number of fewest significant digits in ``[a, b]``, strictly inside ``(lo, hi)`` and
    not among the sorted sample values ``seen``, rounded from ``v``; when ``v`` itself is one
    of them, and none shorter will do, the middle between it and the next sample value."""
    seen = np.asarray(seen, dtype=np.float64)

    def fits(r):
        k = np.searchsorted(seen, r)
        return a <= r <= b and lo < r < hi and not (k < seen.size and seen[k] == r)

    for digits in range(1, 18):
        # v rounded to so many digits, and its neighbours at that precision, nearest first.
        r = float(f"{v:.{digits}g}")
        step = 10.0 ** (math.floor(math.log10(abs(r))) - digits + 1) if r != 0.0 else 0.0
        near = {r, float(f"{r - step:.{digits}g}"), float(f"{r + step:.{digits}g}")}
        for c in sorted(near, key=lambda c: abs(c - v)):
            if fits(c):
                return c
    k = np.searchsorted(seen, v)
    if k < seen.size and seen[k] == v:
        for other in ((seen[k + 1],) if k + 1 < seen.size else ()) + ((seen[k - 1],) if k > 0 else ()):
            mid = float(v + (other - v) / 2.0)
            if lo < mid < hi and mid != v and mid != other:
                return mid
    return v
