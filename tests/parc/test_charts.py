"""Benchmark-report charts: the number formatter, the axis mapping, the stacking, and the PNGs.

Truth for the images: the palette colour of a series appears only in its
markers, bars or legend swatch, so its pixels are located by exact colour
and their positions compared with the data (higher value -> smaller row).
"""
import math
import os

import numpy as np
import pytest
from PIL import Image

from parc.bench.charts import (_GRID, _INK, _MUTED, PALETTE, _data_axis, axis_mapping, fmt_number, line_chart,
                               scatter_chart, stack_segments, stacked_bar_chart)
from parc.bench.heatmaps import _viridis_lut, heat_maps

KW = dict(title="t", x_label="x", y_label="y")


def _rgb_of(path):
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def load(path, size=(720, 480)):
    """The PNG as an RGB array, after checking it is a whole PNG of ``size``."""
    with Image.open(path) as im:
        assert im.format == "PNG" and im.size == size
        im.verify()
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def blobs(img, colour):
    """Groups of pixels of exactly ``colour``, split where whole columns have none, left to right.

    Returns ``[(first column, last column, mean row, row count of the tallest column)]``.
    """
    mask = np.all(img == np.array(colour, np.uint8), axis=2)
    cols = np.flatnonzero(mask.any(axis=0))
    if cols.size == 0:
        return []
    out = []
    for run in np.split(cols, np.flatnonzero(np.diff(cols) > 1) + 1):
        sub = mask[:, run[0]:run[-1] + 1]
        rows = np.nonzero(sub)[0]
        out.append((run[0], run[-1], rows.mean(), int(sub.sum(axis=0).max())))
    return out


# --------------------------------------------------------------------------
# Pure helpers
# --------------------------------------------------------------------------

@pytest.mark.parametrize("v, text", [
    (0, "0"), (0.0, "0"), (1234, "1.23k"), (3000, "3k"), (999999, "1M"), (2.5e9, "2.5G"),
    (1e-12, "1e-12"), (2.5e-7, "2.5e-7"), (0.5, "0.5"), (12.5, "12.5"), (0.001, "0.001"),
    (123.456, "123"), (-0.25, "-0.25"), (-1500, "-1.5k"), (math.nan, "nan"),
    (math.inf, "inf"), (-math.inf, "-inf"),
])
def test_fmt_number(v, text):
    assert fmt_number(v) == text


def test_fmt_number_digits_keep_close_ticks_apart():
    assert fmt_number(10.02, 4) != fmt_number(10.04, 4)
    assert _data_axis([10.02, 10.1], False).labels()[1][1] == "10.04"


def test_linear_mapping_endpoints_and_monotone():
    f = axis_mapping(-3.0, 7.0, False, 50, 650)
    assert f(-3.0) == pytest.approx(50) and f(7.0) == pytest.approx(650)
    px = [f(v) for v in np.linspace(-3, 7, 21)]
    assert all(b > a for a, b in zip(px, px[1:]))
    # A y axis runs from the bottom row up: larger values get smaller rows.
    g = axis_mapping(0.0, 1.0, False, 400, 40)
    assert g(0.0) == pytest.approx(400) and g(1.0) == pytest.approx(40) and g(0.9) < g(0.1)


def test_log_mapping_puts_decades_evenly():
    f = axis_mapping(1.0, 100.0, True, 0, 200)
    assert f(1.0) == pytest.approx(0) and f(100.0) == pytest.approx(200)
    assert f(10.0) == pytest.approx(100)
    assert math.isnan(f(-1.0)) and math.isnan(f(0.0))  # no zero slot: 0 cannot be shown


@pytest.mark.parametrize("px0, px1", [(400, 40), (60, 660)])
def test_log_zero_slot_is_beyond_the_smallest_positive(px0, px1):
    f = axis_mapping(1e-3, 1.0, True, px0, px1, zero=True)
    assert f(0.0) == px0
    assert f(1.0) == pytest.approx(px1)
    # Zero, then a gap, then the positive range: all on the same side, in order.
    assert (f(0.0) - f(1e-3)) * (px0 - px1) > 0 and abs(f(1e-3) - f(0.0)) > 10
    assert (f(1e-3) - f(1e-2)) * (px0 - px1) > 0


def test_whole_numbers_get_whole_ticks():
    # Threads 1 and 2 were ticked at 1.2, 1.4, 1.6.
    assert _data_axis([1, 2], False).ticks == (1.0, 2.0)
    assert all(float(t).is_integer() for t in _data_axis([1, 2, 4, 8], False).ticks)
    assert not all(float(t).is_integer() for t in _data_axis([1.0, 1.5], False).ticks)


def test_data_axis_degenerate_ranges_are_padded():
    for values, log in [([5.0, 5.0], False), ([0.0], False), ([], False), ([-2.0], False),
                        ([7.0], True), ([], True), ([0.0, 0.0], True)]:
        ax = _data_axis(values, log)
        assert ax.lo < ax.hi and len(ax.ticks) >= 2, (values, log)
        assert all(ax.lo <= v <= ax.hi for v in values if not log or v > 0)
    ax = _data_axis([0.0, 2e-3, 0.5], True)
    assert ax.zero and ax.labels()[0] == (0.0, "0")
    assert all(math.log10(t) == pytest.approx(round(math.log10(t))) for t in ax.ticks)


def test_linear_ticks_are_nice_and_cover_the_data():
    ax = _data_axis([0.13, 9.7], False)
    steps = np.diff(ax.ticks)
    assert np.allclose(steps, steps[0]) and 3 <= len(ax.ticks) <= 8
    mant = steps[0] / 10 ** math.floor(math.log10(steps[0]))
    assert min(abs(mant - m) for m in (1, 2, 5)) < 1e-9
    assert ax.lo <= 0.13 and ax.hi >= 9.7


def test_stack_segments_normalise_to_100():
    segs = stack_segments({"raster": 1, "cast": 3, "shade": 0})
    assert [s[0] for s in segs] == ["raster", "cast", "shade"]
    assert segs[0][1:] == pytest.approx((0, 25)) and segs[1][1:] == pytest.approx((25, 100))
    assert segs[2][2] - segs[2][1] == 0
    odd = stack_segments({"a": math.nan, "b": -5, "c": 2.0, "d": None, "e": math.inf})
    assert [round(e - s, 9) for _, s, e in odd] == [0, 0, 100, 0, 0]
    assert all(s == e == 0 for _, s, e in stack_segments({"a": 0, "b": 0}))


# --------------------------------------------------------------------------
# Images
# --------------------------------------------------------------------------

def test_scatter_markers_where_the_data_says(tmp_path):
    pts = [{"x": 1, "y": 1, "label": "low"}, {"x": 2, "y": 3, "label": "high"},
           {"x": 3, "y": 2, "label": "mid"}]
    out = scatter_chart(tmp_path / "deep" / "er" / "s.png", pts, **KW)
    assert out == tmp_path / "deep" / "er" / "s.png"
    b = blobs(load(out), PALETTE[0])
    assert len(b) == 3  # one series: no legend, so only the three markers carry the colour
    low, high, mid = (row for _, _, row, _ in b)
    assert high < mid < low
    assert os.listdir(out.parent) == ["s.png"]  # no temporary file left behind


def test_scatter_zero_error_on_log_axis_is_drawn_below(tmp_path):
    pts = [{"x": 1.0, "y": 0.0, "label": "parc", "series": "parc"},
           {"x": 2.0, "y": 1e-3, "label": "step 1", "series": "brute"},
           {"x": 4.0, "y": 1.0, "label": "step 2", "series": "brute"}]
    img = load(scatter_chart(tmp_path / "z.png", pts, x_log=True, y_log=True, **KW))
    zero = blobs(img, PALETTE[0])[0][2]  # marker first, legend swatch last
    brute = [b[2] for b in blobs(img, PALETTE[1])][:2]
    assert zero > brute[0] > brute[1]


def test_scatter_zero_on_log_x_is_left_of_smallest(tmp_path):
    pts = [{"x": 0.0, "y": 1, "label": "a"}, {"x": 1e-6, "y": 2, "label": "b"},
           {"x": 1e-2, "y": 3, "label": "c"}]
    b = blobs(load(scatter_chart(tmp_path / "zx.png", pts, x_log=True, **KW)), PALETTE[0])
    assert len(b) == 3 and b[0][2] > b[1][2] > b[2][2]  # left to right: y = 1, 2, 3


@pytest.mark.parametrize("pts, log", [
    ([{"x": math.nan, "y": 1, "label": "a"}, {"x": 1, "y": math.inf, "label": "b"}], False),
    ([{"x": None, "y": None, "label": "a"}], False),
    ([{"x": -1, "y": -2, "label": "neg"}], True),
    ([], False),
    ([{"x": 3, "y": 3, "label": "one"}], True),
    ([{"x": 5, "y": 5, "label": "a"}, {"x": 5, "y": 5, "label": "b"}], False),
])
def test_scatter_degenerate_input_renders(tmp_path, pts, log):
    img = load(scatter_chart(tmp_path / "d.png", pts, x_log=log, y_log=log, size=(400, 300), **KW),
               size=(400, 300))
    finite = [p for p in pts if p["x"] is not None and math.isfinite(p["x"])
              and math.isfinite(p["y"]) and (not log or p["x"] >= 0)]
    assert bool(blobs(img, PALETTE[0])) == bool(finite)


def test_line_chart_legend_and_order(tmp_path):
    series = {"brute": [(64, 0.5), (128, 2.0), (256, 8.0)],
              "parc": [(64, 0.05), (128, math.nan), (256, 0.8)]}
    img = load(line_chart(tmp_path / "l.png", series, x_log=True, y_log=True, **KW))
    brute, parc = blobs(img, PALETTE[0]), blobs(img, PALETTE[1])
    # brute: one unbroken line, then the legend swatch; parc is broken at the NaN, so its
    # two markers stand alone (no line bridges the gap), then its swatch.
    assert len(brute) == 2 and len(parc) == 3
    c0, c1 = brute[0][:2]
    mask = np.all(img == np.array(PALETTE[0], np.uint8), axis=2)
    assert np.flatnonzero(mask[:, c0]).mean() > np.flatnonzero(mask[:, c1]).mean()  # rises
    assert parc[1][0] - parc[0][1] > 100


def test_stacked_bars_fill_the_axis_in_proportion(tmp_path):
    bars = [("one", {"raster": 1.0, "cast": 3.0}), ("two", {"raster": 1.0, "cast": 1.0}),
            ("none", {"raster": 0.0})]
    img = load(stacked_bar_chart(tmp_path / "st.png", bars, title="t"))
    raster, cast = blobs(img, PALETTE[0]), blobs(img, PALETTE[1])
    # Bars first, legend swatch last; white segment outlines cost a pixel or two each.
    assert cast[0][3] / raster[0][3] == pytest.approx(3.0, rel=0.05)
    assert cast[1][3] / raster[1][3] == pytest.approx(1.0, rel=0.05)
    assert raster[0][3] + cast[0][3] == pytest.approx(raster[1][3] + cast[1][3], abs=2)


def test_write_replaces_existing_file(tmp_path):
    path = tmp_path / "same.png"
    path.write_bytes(b"not a png")
    load(stacked_bar_chart(str(path), [("g", {"s": 1.0})], title="t", size=(320, 240)), size=(320, 240))
    assert sorted(os.listdir(tmp_path)) == ["same.png"]


def _cell_colours(img, panel_x, cells, size):
    """The colour at the centre of each of ``cells`` x ``cells`` blocks of a square panel at column ``panel_x``,
    found below the title by the panel's frame (the first dark row of its left edge)."""
    col = img[:, panel_x - 1]
    top = int(np.argmax(col.sum(axis=1) < 200)) + 1
    step = size / cells
    return [[tuple(img[int(top + (r + 0.5) * step), int(panel_x + (c + 0.5) * step)]) for c in range(cells)]
            for r in range(cells)]


def test_heat_maps_share_one_log_scale(tmp_path):
    a = np.array([[100, 1], [10, 0]])
    b = np.array([[100, 0], [0, 1]])
    out = heat_maps(tmp_path / "h.png", {"brute": a, "parc": b}, title="t", label="cells", panel=100)
    with Image.open(out) as im:
        img = np.asarray(im.convert("RGB"))
    lut = _viridis_lut()
    ca, cb = _cell_colours(img, 16, 2, 100), _cell_colours(img, 16 + 116, 2, 100)
    white = (255, 255, 255)
    assert ca[0][0] == cb[0][0] == tuple(lut[255])          # the largest count, in both maps
    assert ca[1][1] == cb[0][1] == cb[1][0] == white          # no work
    assert ca[0][1] == cb[1][1] == tuple(lut[round(255 * math.log(2) / math.log(101))])   # 1, on log(1 + n)
    assert ca[1][0] == tuple(lut[round(255 * math.log(11) / math.log(101))])


@pytest.mark.parametrize("maps, colour", [({"zeros": np.zeros((2, 2))}, "white"), ({"one": np.ones((1, 1))}, "top"),
                                          ({"nan": np.full((2, 2), np.nan), "inf": np.full((2, 2), np.inf)}, None)])
def test_heat_maps_degenerate_input_renders(tmp_path, maps, colour):
    # No work at all is white, one count alone the top of the scale; maps of no number still draw.
    out = heat_maps(tmp_path / "h.png", maps, title="t", label="cells", panel=100)
    with Image.open(out) as im:
        im.verify()
    with Image.open(out) as im:
        img = np.asarray(im.convert("RGB"))
    assert img.shape[1] >= 100 * len(maps)
    if colour is not None:
        n = next(iter(maps.values())).shape[0]
        want = (255, 255, 255) if colour == "white" else tuple(_viridis_lut()[255])
        assert {c for row in _cell_colours(img, 16, n, 100) for c in row} == {want}


def test_heat_maps_need_a_map(tmp_path):
    with pytest.raises(ValueError, match="needs at least one map"):
        heat_maps(tmp_path / "h.png", {}, title="t", label="cells")


def _frame(img):
    """The plot's frame ``(left, top, right, bottom)``: the rows and columns long runs of ink make."""
    ink = np.all(img == np.array(_INK, np.uint8), axis=2)
    cols, rows = np.flatnonzero(ink.sum(axis=0) > 100), np.flatnonzero(ink.sum(axis=1) > 100)
    return cols[0], rows[0], cols[-1], rows[-1]


def test_stacked_bars_stack_bottom_up_and_the_legend_reads_top_down(tmp_path):
    img = load(stacked_bar_chart(tmp_path / "st.png", [("one", {"raster": 1.0, "cast": 3.0})], title="t"))
    raster, cast = blobs(img, PALETTE[0]), blobs(img, PALETTE[1])
    assert raster[0][2] > cast[0][2]                  # the first part at the bottom, on the axis's 0
    _, _, _, bottom = _frame(img)
    mask = np.all(img == np.array(PALETTE[0], np.uint8), axis=2)
    assert bottom - np.flatnonzero(mask[:, raster[0][0] + 5]).max() <= 2
    assert cast[-1][2] < raster[-1][2]                # the top part's swatch first


def test_markers_at_tick_values_sit_on_their_grid_lines(tmp_path):
    # Integer data get integer ticks, so each marker's centre is on a tick of both axes.
    pts = [(1, 1), (2, 3), (3, 2), (4, 4)]
    img = load(scatter_chart(tmp_path / "g.png", [{"x": x, "y": y} for x, y in pts], **KW))
    grid = np.all(img == np.array(_GRID, np.uint8), axis=2)
    grid_cols, grid_rows = np.flatnonzero(grid.sum(axis=0) > 50), np.flatnonzero(grid.sum(axis=1) > 50)
    assert len(grid_cols) == len(grid_rows) == 4
    mask = np.all(img == np.array(PALETTE[0], np.uint8), axis=2)
    for x, y in pts:
        col, row = grid_cols[x - 1], grid_rows[::-1][y - 1]           # y grows upward
        rows, cols = np.nonzero(mask[row - 8:row + 9, col - 8:col + 9])
        assert rows.size and abs(rows.mean() - 8) <= 0.5 and abs(cols.mean() - 8) <= 0.5, (x, y)


def test_markers_keep_off_the_frame(tmp_path):
    pts = [{"x": 1, "y": 1, "label": ""}, {"x": 3, "y": 2, "label": ""}]
    img = load(scatter_chart(tmp_path / "f.png", pts, **KW))
    l, t, r, b = _frame(img)
    cols = np.flatnonzero(np.all(img == np.array(PALETTE[0], np.uint8), axis=2).any(axis=0))
    rows = np.flatnonzero(np.all(img == np.array(PALETTE[0], np.uint8), axis=2).any(axis=1))
    assert l < cols.min() - 2 and cols.max() + 2 < r and t < rows.min() - 2 and rows.max() + 2 < b


def test_a_label_near_the_right_edge_stays_inside_the_plot(tmp_path):
    pts = [{"x": 1, "y": 1, "label": ""}, {"x": 3, "y": 2, "label": "a rather long label"}]
    img = load(scatter_chart(tmp_path / "lab.png", pts, **KW))
    l, t, r, b = _frame(img)
    ink = np.any(img[t:b, r + 1:] != 255, axis=2)
    assert not ink.any()


@pytest.mark.parametrize("pts, noted", [([{"x": 1, "y": 1}, {"x": 2, "y": math.nan}], True),
                                        ([{"x": 1, "y": 1}, {"x": 2, "y": 2}], False)])
def test_points_left_out_are_counted_in_a_note(tmp_path, pts, noted):
    img = load(scatter_chart(tmp_path / "n.png", pts, **KW))
    assert np.all(img == np.array(_MUTED, np.uint8), axis=2).any() == noted


def test_log_axes_tick_every_decade_up_to_six():
    assert _data_axis([1e-6, 1.0], True).ticks == tuple(10.0 ** e for e in range(-6, 1))
    assert len(_data_axis([1e-12, 1.0], True).ticks) <= 7


def _heat_layout(img, panel, n):
    """Top row of the panels (below their frame) and the colour bar's left column."""
    top = int(np.argmax(img[:, 15].sum(axis=1) < 200)) + 1
    return top, 16 + n * (panel + 16) + 8


def test_heat_map_panels_keep_the_maps_shape_cell_for_cell(tmp_path):
    a = np.arange(1, 9).reshape(2, 4)
    img = _rgb_of(heat_maps(tmp_path / "h.png", {"m": a}, title="t", label="cells", panel=100))
    top, _ = _heat_layout(img, 100, 1)
    lut = _viridis_lut()
    want = np.repeat(np.repeat(lut[np.rint(255 * np.log1p(a) / np.log1p(8)).astype(int)], 25, axis=0), 25, axis=1)
    assert (img[top:top + 50, 16:116] == want).all()
    assert (img[top + 50, 16:116] == _INK).all()                    # the frame: the panel is 50 rows tall


@pytest.mark.parametrize("shape, map_size", [((512, 1), (1, 300)), ((2, 96), (300, 6)), ((3, 3), (300, 300))])
def test_a_heat_map_fits_its_panel_whatever_the_images_shape(tmp_path, shape, map_size):
    # Scaled to the panel's width alone, a 1x512 image's map was 300x153,600 pixels (half a GB
    # drawn), and a 96x2 one's colour bar 6 pixels tall, its tick labels on top of each other.
    counts = np.arange(1, shape[0] * shape[1] + 1).reshape(shape)
    out = heat_maps(tmp_path / "h.png", {"brute": counts, "parc": counts}, title="t", label="cells")
    img = _rgb_of(out)
    assert img.shape[0] < 600 and img.shape[1] < 1000
    lut = {tuple(c) for c in _viridis_lut()}
    coloured = np.array([[tuple(p) in lut for p in row] for row in img[:, :16 + 300]])   # the first panel's map
    rows, cols = np.flatnonzero(coloured.any(axis=1)), np.flatnonzero(coloured.any(axis=0))
    assert (cols[-1] - cols[0] + 1, rows[-1] - rows[0] + 1) == map_size
    bar_x = 16 + 2 * (300 + 16) + 8
    bar = np.flatnonzero(np.all(img[:, bar_x - 1] == np.array(_INK, np.uint8), axis=1))
    assert bar[-1] - bar[0] - 1 == max(map_size[1], 120)


def test_heat_map_colour_bar_runs_up_the_log_scale_with_its_ticks(tmp_path):
    img = _rgb_of(heat_maps(tmp_path / "h.png", {"m": np.array([[0, 50], [3, 7]])}, title="t", label="cells",
                            panel=100))
    top, bar_x = _heat_layout(img, 100, 1)
    ph, lut = 100, _viridis_lut()
    column = img[top:top + ph, bar_x + 9]
    for y in range(ph - 6):
        assert tuple(column[y]) == tuple(lut[round(255 * (1 - y / (ph - 1)))]), y
    assert (column[ph - 6:] == 255).all()                             # 0: white, as in the maps
    ticks = np.flatnonzero(np.all(img[:, bar_x + 20] == np.array(_INK, np.uint8), axis=1))
    want = [top + ph - 3] + [top + (ph - 1) * (1 - math.log1p(v) / math.log1p(50)) for v in (1, 10, 50)]
    assert len(ticks) == 4 and np.abs(np.sort(ticks) - np.sort(want)).max() <= 1


def test_heat_map_panels_are_titled_with_the_mean_count(tmp_path, monkeypatch):
    import parc.bench.heatmaps as hm
    said = []
    put = hm._put
    monkeypatch.setattr(hm, "_put", lambda d, x, y, s, *a, **kw: said.append(s) or put(d, x, y, s, *a, **kw))
    heat_maps(tmp_path / "h.png", {"brute": np.array([[10, 20], [30, 45]]), "parc": np.array([[0, 2], [0, 0]])},
              title="t", label="cells")
    assert "brute: 26.2 a pixel" in said and "parc: 0.5 a pixel" in said


def test_tick_labels_are_centred_on_their_grid_lines(tmp_path, monkeypatch):
    import parc.bench.charts as ch
    said = []
    put = ch._put

    def spy(d, x, y, s, font, ha=0.5, va=0.5, fill=_INK):
        said.append((x, y, s, ha, va))
        put(d, x, y, s, font, ha, va, fill)
    monkeypatch.setattr(ch, "_put", spy)
    img = load(line_chart(tmp_path / "t.png", {"s": [(1, 1), (2, 3), (3, 2), (4, 4)]}, title="", x_label="",
                          y_label=""))
    grid = np.all(img == np.array(_GRID, np.uint8), axis=2)
    rows, cols = np.flatnonzero(grid.sum(axis=1) > 50), np.flatnonzero(grid.sum(axis=0) > 50)
    y_ticks = sorted((float(s), y) for x, y, s, ha, va in said if ha == 1)
    x_ticks = sorted((float(s), x) for x, y, s, ha, va in said if va == 0)
    assert [v for v, _ in y_ticks] == [v for v, _ in x_ticks] == [1.0, 2.0, 3.0, 4.0]
    assert np.abs(np.array([y for _, y in y_ticks]) - rows[::-1]).max() <= 1
    assert np.abs(np.array([x for _, x in x_ticks]) - cols).max() <= 1


def test_heat_maps_scale_every_panel_by_the_largest_count_of_all(tmp_path):
    out = heat_maps(tmp_path / "h.png", {"brute": np.array([[100]]), "parc": np.array([[10]])}, title="t",
                    label="cells", panel=100)
    img = _rgb_of(out)
    lut = _viridis_lut()
    assert _cell_colours(img, 16, 1, 100)[0][0] == tuple(lut[255])
    assert _cell_colours(img, 16 + 116, 1, 100)[0][0] == tuple(lut[round(255 * math.log(11) / math.log(101))])
    assert np.all(img[-30:] == np.array(_MUTED, np.uint8), axis=2).any()         # the colour bar's label
