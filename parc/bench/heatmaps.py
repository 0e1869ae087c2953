"""Heat maps for the benchmark report and `parc render --work`: a count per pixel, e.g. the cells
each ray visited, drawn side by side for several methods on one logarithmic colour scale.

The frame, fonts and number format are those of the charts (`parc.bench.charts`).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from .charts import _INK, _MUTED, _fonts, _height, _put, _save, _width, fmt_number


def _viridis_lut():
    """Viridis as 256 RGB rows (uint8): the ``viridis`` transfer-function preset's colours over 0..255."""
    from ..transfer import load_transfer_function
    return np.rint(255.0 * load_transfer_function("viridis", (0.0, 255.0)).color(np.arange(256.0))).astype(np.uint8)


def _log_ticks(vmax):
    """Values 0, 1, 10, 100, ... up to ``vmax``, and ``vmax`` itself when far from the last decade."""
    ticks = [0.0]
    v = 1.0
    while v <= vmax:
        ticks.append(v)
        v *= 10.0
    if vmax > 0 and math.log1p(vmax) - math.log1p(ticks[-1]) > 0.15 * math.log1p(vmax):
        ticks.append(float(vmax))
    return ticks


#: The colour bar's least height, in pixels, where the panels allow it (beside a map of a wide image).
MIN_BAR = 120


def heat_maps(path, maps, *, title, label, panel=300) -> Path:
    """Count maps side by side on one logarithmic colour scale: e.g. cells visited per pixel, per method.

    A count of 0 is drawn white (no work there), counts from 1 up on
    viridis by ``log(1 + count)``, one scale for every map so that they
    compare; the colour bar on the right gives the counts.

    Parameters
    ----------
    path : str or Path
        PNG to write.
    maps : dict of str -> ndarray (H, W)
        Non-negative counts, all of one shape; each panel is titled with its
        name and its mean per pixel.
    title : str
    label : str
        What is counted, under the colour bar (e.g. "cells per pixel").
    panel : int
        Side of a panel in pixels: each map is scaled to fit it, nearest
        neighbour, its shape kept.

    Returns
    -------
    Path
    """
    if not maps:
        raise ValueError("heat_maps needs at least one map")
    fonts = _fonts()
    font, tfont = fonts
    arrays = {str(k): np.nan_to_num(np.asarray(v, np.float64), nan=0.0, posinf=0.0).clip(min=0.0)
              for k, v in maps.items()}
    h0, w0 = next(iter(arrays.values())).shape
    # Each map fits a panel x panel box, its shape kept: scaled to the width alone, a 1x512 image's
    # map was 153,706 pixels tall. The colour bar keeps a legible height beside a flat map.
    fit = panel / max(w0, h0, 1)
    pw, ph = max(1, int(round(w0 * fit))), max(1, int(round(h0 * fit)))
    bh = max(ph, min(panel, MIN_BAR))
    vmax = max(float(a.max()) if a.size else 0.0 for a in arrays.values())
    scale = math.log1p(vmax) if vmax > 0 else 1.0
    lut = _viridis_lut()
    probe = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    lh, th = _height(probe, font), _height(probe, tfont)
    ticks = _log_ticks(vmax)
    tick_w = max(_width(probe, fmt_number(v), font) for v in ticks)
    top = 16 + th + 14 + lh + 8
    bar_x = 16 + len(arrays) * (panel + 16) + 8
    w = bar_x + 18 + 8 + tick_w + 16
    h = top + bh + 16 + lh + 12
    img = Image.new("RGB", (w, h), "white")
    d = ImageDraw.Draw(img)
    _put(d, w / 2, 12, title, tfont, va=0)
    for i, (name, a) in enumerate(arrays.items()):
        slot = 16 + i * (panel + 16)
        x = slot + (panel - pw) // 2
        rgb = lut[np.rint(255.0 * np.log1p(a) / scale).astype(np.int64).clip(0, 255)]
        rgb[a == 0] = 255
        img.paste(Image.fromarray(np.ascontiguousarray(rgb, np.uint8), "RGB").resize((pw, ph), Image.NEAREST),
                  (x, top))
        d.rectangle((x - 1, top - 1, x + pw, top + ph), outline=_INK)
        _put(d, slot + panel / 2, top - 8, f"{name}: {fmt_number(a.mean())} a pixel", font, va=1)
    # The colour bar: 0 (white) at the bottom, then log(1 + count) upward.
    for y in range(bh):
        f = 1.0 - y / max(bh - 1, 1)
        d.line((bar_x, top + y, bar_x + 18, top + y), fill=tuple(int(c) for c in lut[int(round(255 * f))]))
    d.rectangle((bar_x, top + bh - 6, bar_x + 18, top + bh), fill="white")
    d.rectangle((bar_x - 1, top - 1, bar_x + 18, top + bh), outline=_INK)
    for v in ticks:
        y = top + bh - 3 if v == 0 else top + (bh - 1) * (1.0 - math.log1p(v) / scale)
        d.line((bar_x + 18, y, bar_x + 22, y), fill=_INK)
        _put(d, bar_x + 26, y, fmt_number(v), font, ha=0)
    _put(d, w / 2, h - 8, label, font, va=1, fill=_MUTED)
    return _save(img, path)


def work_heat_maps(path, maps, what, where) -> Path:
    """`heat_maps` of each method's work per pixel (`parc.RenderResult.work`), titled and labelled
    alike wherever they are drawn: ``what`` is counted ("cells visited", "samples taken") in ``where``."""
    return heat_maps(path, maps, title=f"{what.capitalize()} per pixel: {where}",
                     label=f"{what} per pixel (log scale; white: none)")
