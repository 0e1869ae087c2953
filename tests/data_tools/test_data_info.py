"""volume_info, format_info and suggest_isovalues."""
from __future__ import annotations

import numpy as np
import pytest

from data_tools import Volume
from data_tools.info import PERCENTILES, SAMPLE_LIMIT, format_info, suggest_isovalues, volume_info
from data_tools.synthetic import blobs, ct_phantom, sphere


def test_volume_info_fields():
    data = np.zeros((4, 5, 6), dtype=np.uint16)
    data[:2] = 1000
    data[0, 0, 0] = 3000
    vol = Volume(data, spacing=(1, 2, 3), origin=(0, 0, 5), name="test")
    info = volume_info(vol)
    assert info["dims"] == (6, 5, 4) and info["dtype"] == "uint16"
    assert info["spacing"] == (1, 2, 3) and info["origin"] == (0, 0, 5)
    assert info["extent"] == (5, 8, 9)
    assert info["min"] == 0 and info["max"] == 3000
    assert info["zero_fraction"] == pytest.approx(0.5)
    assert list(info["percentiles"]) == list(PERCENTILES)
    assert info["percentiles"][25] == 0 and info["percentiles"][75] == 1000
    assert info["nbytes"] == data.nbytes
    text = format_info(info)
    assert "6 x 5 x 4" in text and "uint16" in text and "50.0%" in text
    assert len(text.splitlines()) >= 9


def test_percentiles_monotone_and_subsampled_for_large():
    vol = ct_phantom(160)
    info = volume_info(vol)
    p = list(info["percentiles"].values())
    assert p == sorted(p)
    assert info["sampled"] < 160 ** 3
    # A regular subsample of the whole volume: each percentile near the full data's, within a
    # tenth of the range (the first slabs alone, the phantom's air, missed most of them).
    full = np.percentile(vol.data, list(PERCENTILES))
    span = float(vol.data.max()) - float(vol.data.min())
    assert np.abs(np.array(p, dtype=float) - full).max() <= 0.1 * span, (p, full)
    assert "subsample" in format_info(info)
    assert info["min"] == float(vol.data.min())   # the range stays exact


@pytest.mark.parametrize("make", [lambda: blobs(40), lambda: sphere(30), lambda: ct_phantom(40)])
def test_suggestions_inside_range_sorted(make):
    vol = make()
    lo, hi = vol.value_range()
    iso = suggest_isovalues(vol, k=3)
    assert 1 <= len(iso) <= 3
    assert iso == sorted(set(iso))
    assert all(lo < v < hi for v in iso)
    if vol.dtype.kind in "iu":
        assert all(v % 1 == 0.5 for v in iso)


def test_ct_phantom_suggestions_find_skin_and_bone():
    iso = suggest_isovalues(ct_phantom(64))
    assert any(100 < v < 1000 for v in iso)       # between air and tissue
    assert any(1000 < v < 2200 for v in iso)      # between tissue and bone


def test_two_level_data_gives_the_gap_middle():
    data = np.full((6, 6, 6), 10, dtype=np.uint8)
    data[2:4, 2:4, 2:4] = 200
    iso = suggest_isovalues(Volume(data), k=3)
    assert len(iso) == 1 and abs(iso[0] - 105) == 0.5   # x.5 next to the middle of 10..200


@pytest.mark.parametrize("scale", [1.0, 1e-200, 1e100, 1e160, 1e200])
def test_two_level_data_gives_the_gap_middle_at_any_scale(scale):
    # The middle of 0 and `scale`, however large its square.
    data = np.zeros((8, 8, 8))
    data[2:6, 2:6, 2:6] = scale
    assert suggest_isovalues(Volume(data)) == [pytest.approx(0.5 * scale, rel=1e-12)]


@pytest.mark.parametrize("dtype, fill", [(np.float32, -3.4e38), (np.float32, -9999.0), (np.int16, -32768),
                                         (np.float32, 3.4e38), (np.float32, 1e9)])
def test_a_fill_value_at_the_minimum_does_not_take_the_cuts(dtype, fill):
    # Tissue near 100 and bone near 1000, outside the scan a fill value far below or above both:
    # the cut between the two belongs between them, not in the gap to the fill.
    rng = np.random.default_rng(5)
    data = rng.normal(100.0, 5.0, (24, 24, 24))
    data[8:16, 8:16, 8:16] = rng.normal(1000.0, 5.0, (8, 8, 8))
    data = np.round(data).astype(dtype)
    data[:, :, :4] = fill
    iso = suggest_isovalues(Volume(data))
    assert iso and all(80 < v < 1020 for v in iso), iso
    assert any(130 < v < 970 for v in iso), iso
    # The samples kept are whole numbers, a float32 CT's: cut at x.5, as without the fill.
    assert all(v % 1 == 0.5 for v in iso), iso


def test_a_fill_value_beside_two_adjacent_values_suggests_their_middle():
    # Too narrow a range to bin: the middle of the samples kept, not of the fill and the data.
    data = np.full((4, 4, 4), np.float32(1.0))
    data[2:] = np.nextafter(np.float32(1.0), np.float32(2.0))
    data[0] = -3.4e38
    iso = suggest_isovalues(Volume(data))
    assert len(iso) == 1 and 1.0 < iso[0] < float(np.nextafter(np.float32(1.0), np.float32(2.0))), iso


def test_constant_volume_has_no_suggestion():
    assert suggest_isovalues(Volume(np.full((3, 3, 3), 7, np.int16))) == []
    assert "none" in format_info(volume_info(Volume(np.zeros((3, 3, 3), np.float32))))


def test_large_uint8_volume():
    rng = np.random.default_rng(0)
    data = rng.integers(0, 50, (256, 256, 256), dtype=np.uint8)
    data[100:150, 100:150, 100:150] += 150
    iso = suggest_isovalues(Volume(data))
    assert any(49 < v < 150 for v in iso)
    assert all(v % 1 == 0.5 for v in iso)


def test_extreme_float_ranges_do_not_break():
    wide = np.zeros((3, 3, 3))
    wide[0, 0, 0], wide[1, 1, 1] = 1e200, -1e200        # the largest samples a Volume takes
    iso = suggest_isovalues(Volume(wide))
    assert len(iso) == 1 and iso[0] in (-5e199, 5e199)  # a gap's middle, computed without overflow
    narrow = np.ones((3, 3, 3))
    narrow[0, 0, 0] = np.nextafter(1.0, 2.0)
    assert suggest_isovalues(Volume(narrow)) == []     # no float lies strictly between


def _listed(text, label):
    line = next(s for s in text.splitlines() if s.startswith(label))
    return [float(v) for v in line[len(label):].replace("..", ",").split(",") if "mean" not in v]


@pytest.mark.parametrize("data", [
    1.0 + 1e-6 * np.cos(np.arange(4096).reshape(16, 16, 16) / 40.0),     # six digits cannot tell them apart
    np.linspace(1073741800, 1073741823, 4096).reshape(16, 16, 16),
    np.where(np.arange(4096).reshape(16, 16, 16) % 3, 1000, 1000.001).astype(np.float32),
])
def test_printed_range_and_isovalues_are_the_values(data):
    # Pasted back as --iso they must give the same surface, and the range the same refusal.
    info = volume_info(Volume(data))
    text = format_info(info)
    assert _listed(text, "suggested isovalues:") == info["suggested_isovalues"]
    assert _listed(text, "range:")[:2] == [info["min"], info["max"]]


@pytest.mark.parametrize("data", [np.arange(4096, dtype=np.int16).reshape(16, 16, 16) % 700,
                                  np.linspace(-1, 1, 4096).reshape(16, 16, 16) ** 3,
                                  np.full((4, 4, 4), 7, dtype=np.uint8)])
def test_histogram_counts_every_sample_between_the_range(data):
    info = volume_info(Volume(data))
    hist, text = info["histogram"], format_info(info)
    if data.min() == data.max():
        assert hist is None and "histogram" not in text
        return
    counts, edges = np.array(hist["counts"]), np.array(hist["edges"])
    assert counts.sum() == info["sampled"] and len(edges) == len(counts) + 1
    assert edges[0] <= info["min"] and info["max"] <= edges[-1] and (np.diff(edges) > 0).all()
    inside = [((data >= a) & (data < b)).sum() for a, b in zip(edges[:-2], edges[1:-1])]
    assert list(counts[:-1]) == inside
    if data.dtype.kind == "i":
        assert all(e % 1 == 0.5 for e in edges)
    bars = [s for s in text.splitlines() if s.startswith("  ") and "%" in s]
    assert len(bars) == len(counts)
    lengths = [b.count("#") for b in bars]
    assert all(lengths[i] <= lengths[j] for i in range(len(counts)) for j in range(len(counts))
               if counts[i] < counts[j])
    assert all((n == 0) == (c == 0) for n, c in zip(lengths, counts))


def test_isovalue_refusal_shows_the_range_exactly():
    from data_tools import InputError
    from parc import Isosurface
    vol = Volume(np.linspace(0, 0.7, 64, dtype=np.float32).reshape(4, 4, 4))
    with pytest.raises(InputError) as exc:
        Isosurface(vol, 0.7)                      # above float32(0.7), which :g wrote as 0.7
    assert "isovalue 0.7 is outside the data range [0, 0.699999988079071]" in str(exc.value)


def test_float_suggestions_are_short_and_within_half_a_bin_of_the_cut():
    # 7.3 splits a sphere's distance field as 7.340737462043762 does, and reads and pastes better.
    from data_tools.info import _shortest
    assert _shortest(7.340737462043762, 7.24, 7.44, -21.0, 32.0) == 7.3
    assert _shortest(1000.1234, 1000.1230, 1000.1238, 999.0, 1001.0) == 1000.123
    assert _shortest(0.5, 0.0, 1.0, 0.0, 1.0) == 0.5
    assert _shortest(2.0, 1.0, 3.0, 1.5, 2.5) == 2.0          # "2" is shortest, and inside
    assert _shortest(1.25, 1.2, 1.3, 1.24, 1.26) == 1.25       # 1 and 1.2 lie outside the data range
    iso = suggest_isovalues(sphere(30))
    assert iso and all(len(f"{v:.15g}") <= 5 for v in iso), iso


def test_float_suggestions_avoid_the_sample_values():
    # Whole-number float samples (a CT stored as float32) are cut at x.5, as integer ones are;
    # other float data keep their shortest numbers off the samples themselves.
    from data_tools.info import _shortest
    ct = ct_phantom(40)
    as_float = suggest_isovalues(Volume(ct.data.astype(np.float32)))
    assert len(as_float) == 3 and all(v % 1 == 0.5 for v in as_float)      # were 190, 720, 1600 on the CT head
    assert _shortest(7.34, 7.2, 7.4, 0.0, 10.0, np.array([7.0, 7.3])) == 7.4      # the next at that precision
    assert _shortest(7.34, 7.2, 7.4, 0.0, 10.0, np.array([7.0, 7.25])) == 7.3
    assert _shortest(25.0, 24.9, 25.1, 0.0, 100.0, np.array([24.9, 25.0, 25.1])) in (24.99, 25.01)
    assert _shortest(25.0, 25.0, 25.0, 0.0, 100.0, np.array([24.0, 25.0, 26.0])) == 25.5  # the middle to the next
    for data in (np.resize(np.arange(0, 100.1, 0.1), (20, 20, 20)),                    # cuts on sample values
                 np.resize(2.0 ** 60 + 2.0 ** 20 * np.arange(257), (8, 8, 8)),         # whole, past 2^53
                 1.0 + np.linspace(-1e-12, 1e-12, 512).reshape(8, 8, 8)):
        iso = suggest_isovalues(Volume(data))
        assert iso and not np.isin(iso, data).any(), iso
    big = suggest_isovalues(Volume(np.linspace(1e8, 1e9, 8000).astype(np.float32).reshape(20, 20, 20)))
    assert all(float(f"{v:.3g}") == v for v in big), big                               # not 325138488.5


def test_mean_percentiles_and_their_text_by_hand():
    # The values 0..198 and 1199: mean 99.5 + 1000 / 200 = 104.5 (the median stays 99.5); the p-th
    # percentile (linear, NumPy's default) p * 1.99 up to 99%, which lies between 197 and 198.
    data = np.arange(200, dtype=np.float64)
    data[-1] = 1199.0
    info = volume_info(Volume(data.reshape(2, 10, 10)))
    assert info["mean"] == 104.5
    for p, v in info["percentiles"].items():
        assert abs(v - p * 1.99) <= 1.0, (p, v)          # within one sample step of the linear value
    text = format_info(info)
    assert "mean 104.5" in text
    assert "1%: 1.99, 5%: 9.95, 25%: 49.75, 50%: 99.5, 75%: 149.25, 95%: 189.05, 99%: 197.01" in text


def test_mean_of_float32_samples_is_summed_in_double():
    # 2^24 and 255 ones: (2^24 + 255) / 256 = 65536.99609375 exactly. Summed in float32, each
    # one added to 2^24 is lost, and the mean printed 65536.9.
    data = np.ones((4, 8, 8), np.float32)
    data[0, 0, 0] = 2.0 ** 24
    info = volume_info(Volume(data))
    assert info["mean"] == 65536.99609375
    assert "mean 65537" in format_info(info)


def test_zero_fraction_counts_every_sample_of_a_subsampled_volume():
    # 130^3 samples is past SAMPLE_LIMIT (2^21): the other statistics use every other sample,
    # which here are all zeros. Zeros are counted over the whole volume: exactly half.
    data = np.ones((130, 130, 130), np.uint8)
    data[:, :, ::2] = 0
    info = volume_info(Volume(data))
    assert info["sampled"] < data.size
    assert info["zero_fraction"] == 0.5
    assert "zeros:       50.0%" in format_info(info)


def test_histogram_shares_are_of_all_samples():
    # Three quarters at 0 and one quarter at 200: the bars say 75.0% and 25.0%, the rest 0.0%.
    data = np.zeros((4, 4, 4), np.uint8)
    data[3] = 200
    info = volume_info(Volume(data))
    bars = [s for s in format_info(info).splitlines() if s.startswith("  ") and s.endswith("%")]
    shares = [float(s.split()[-1].rstrip("%")) for s in bars]
    assert shares[0] == 75.0 and shares[-1] == 25.0 and sum(shares[1:-1]) == 0.0


@pytest.mark.parametrize("lo, levels", [(0, 17), (100, 40), (-40, 5)])
def test_integer_histogram_bins_by_hand(lo, levels):
    # Values lo .. lo + levels - 1: bins `ceil(levels / 16)` values wide, edges at x.5 from lo - 0.5,
    # at most HISTOGRAM_BINS of them, each counting the samples between its edges.
    from data_tools.info import HISTOGRAM_BINS
    data = (lo + np.arange(4096) % levels).astype(np.int16).reshape(16, 16, 16)
    hist = volume_info(Volume(data))["histogram"]
    width = -(-levels // HISTOGRAM_BINS)
    nb = -(-levels // width)
    assert len(hist["counts"]) == nb <= HISTOGRAM_BINS
    assert hist["edges"] == [lo - 0.5 + width * m for m in range(nb + 1)]
    assert hist["counts"] == [int(((data > a) & (data < b)).sum()) for a, b in zip(hist["edges"], hist["edges"][1:])]


def test_float_histogram_is_numpys_sixteen_equal_bins():
    data = np.linspace(-1, 1, 4096).reshape(16, 16, 16) ** 3
    hist = volume_info(Volume(data))["histogram"]
    counts, edges = np.histogram(data, bins=16)
    assert hist["counts"] == counts.tolist()
    np.testing.assert_allclose(hist["edges"], edges, rtol=0, atol=1e-15)


def test_a_range_of_one_float_step_has_no_histogram_of_empty_bins():
    # Sixteen bins between 1 and the next double would share edges: none is drawn.
    data = np.ones((4, 4, 4))
    data[2:] = np.nextafter(1.0, 2.0)
    info = volume_info(Volume(data))
    assert info["histogram"] is None and "histogram" not in format_info(info)


def test_size_and_subsample_lines_by_hand():
    # 64^3 float64 samples are 2 MiB (2 * 2^20 bytes), and few enough that every one is counted.
    info = volume_info(Volume(np.zeros((64, 64, 64)) + np.arange(64)))
    text = format_info(info)
    assert "dimensions:  64 x 64 x 64 (x, y, z), 262144 samples" in text
    assert "type:        float64, 2.0 MiB" in text
    assert info["sampled"] == 64 ** 3 and "subsample" not in text
    # Edges at multiples of 63/16 = 3.9375 are printed with the digits they need.
    assert "  3.9375 .. 7.875 " in text


@pytest.mark.parametrize("shape, dtype, nbytes, size", [((32, 32, 32), np.uint8, 32768, "32.0 KiB"),
                                                         ((66, 66, 66), np.uint8, 287496, "280.8 KiB"),
                                                         ((4, 4, 4), np.int16, 128, "128 bytes"),
                                                         ((64, 64, 128), np.uint16, 2 ** 20, "1.0 MiB")])
def test_a_small_volume_has_a_size_above_zero(shape, dtype, nbytes, size):
    # 32^3 uint8 (the bucky ball) is 32,768 bytes: "0.0 MiB" read as an empty file.
    data = np.zeros(shape, dtype)
    data.flat[0] = 1
    assert data.nbytes == nbytes
    assert f"type:        {np.dtype(dtype).name}, {size}" in format_info(volume_info(Volume(data)))


def _thin():
    data = np.zeros((2, 1100, 1100), np.uint8)       # past SAMPLE_LIMIT in two slices
    data[1, 300:800, 300:800] = 200
    return data


def _odd_slices():
    data = np.zeros((40, 600, 600), np.uint8)        # content in every other slice only
    data[1::2, 100:500, 100:500] = 200
    return data


def _every_third_column():
    data = np.zeros((160, 256, 256), np.uint8)
    data[:, :, 1::3] = 1
    return data


@pytest.mark.parametrize("make", [_thin, _odd_slices, _every_third_column])
def test_the_subsample_reaches_every_slice(make):
    # A stride of 2 along each axis read slice 0 of the thin volume alone, and only the even
    # slices of the other: "mean 0", and no isovalue at all (a constant volume, it said).
    data = make()
    info = volume_info(Volume(data))
    assert info["sampled"] <= SAMPLE_LIMIT < data.size
    assert info["mean"] == pytest.approx(data.mean(), rel=0.02)
    top = float(data.max())
    assert [v for v in info["suggested_isovalues"] if 0 < v < top]
    counts = info["histogram"]["counts"]
    assert counts[-1] / info["sampled"] == pytest.approx(np.count_nonzero(data) / data.size, rel=0.02)


def test_a_lone_voxel_the_subsample_misses_still_gets_an_isovalue():
    data = np.zeros((140, 140, 140), np.int16)
    data[70, 70, 71] = 1000
    assert suggest_isovalues(Volume(data)) == [499.5]


def test_two_adjacent_doubles_are_not_called_constant():
    data = np.ones((6, 6, 6))
    data[2:4, 2:4, 2:4] = np.nextafter(1.0, 2.0)
    text = format_info(volume_info(Volume(data)))
    assert "suggested isovalues: none (no level lies strictly between the samples' values)" in text
    assert "constant" not in text


def test_whole_percentiles_keep_every_digit():
    data = np.full((4, 4, 4), 30000000.0, np.float32)
    data[2:] = 30000002.0
    assert "95%: 30000002," in format_info(volume_info(Volume(data)))


@pytest.mark.parametrize("dtype", [np.int32, np.uint32, np.int16])
def test_percentiles_of_integers_spanning_their_type_lie_within_the_range(dtype):
    # NumPy interpolated int32 samples in int32: the 5th percentile of -2^31 .. 2^31-1 came out
    # at -2.9e9, below the minimum. Each must be the value between its two nearest samples.
    top = np.iinfo(dtype)
    data = np.array([top.min, top.max, 0, 5, 6, 7, 8, 9], dtype).reshape(2, 2, 2)
    info = volume_info(Volume(data))
    exact = np.percentile(np.sort(data.reshape(-1)).astype(object), PERCENTILES)
    for p in PERCENTILES:
        assert top.min <= info["percentiles"][p] <= top.max
        assert info["percentiles"][p] == pytest.approx(float(exact[PERCENTILES.index(p)]), rel=1e-12)
    # The range as integers, every digit: pasted back as an isovalue it is the same number.
    assert f"range:       {top.min} .. {top.max}," in format_info(info)


def test_a_saturated_top_level_next_to_the_data_keeps_its_surface():
    # Tissue 100..200 and a saturated level 250, nearer the tissue than the tissue spans: not a
    # fill value. The cut between them lies in the middle of the gap, 225, at x.5.
    data = np.zeros((16, 16, 16), np.int16)
    data[4:12] = (100 + np.arange(8 * 256) % 101).reshape(8, 16, 16)
    data[8:12, 4:12] = 250
    iso = suggest_isovalues(Volume(data))
    assert any(abs(v - 225) == 0.5 for v in iso), iso


@pytest.mark.parametrize("first, background", [(100, 0), (-107, -200)])
def test_uniform_levels_are_cut_into_equal_classes(first, background):
    # Eight equally common levels first .. first + 7 above a background at the minimum: Otsu's
    # cuts split a uniform histogram into equal classes, at the x.5 between two levels.
    data = np.full((8, 8, 8), background, np.int16)
    data[2:6] = (first + np.arange(256) % 8).reshape(4, 8, 8)
    assert suggest_isovalues(Volume(data), k=1) == [first + 3.5]
    assert suggest_isovalues(Volume(data)) == [first + 1.5, first + 3.5, first + 5.5]


def test_histogram_bars_grow_with_the_log_of_the_count():
    # 48 samples at 0 and 16 at 200: the longest bar is 40 characters, the other 40 ln(17) / ln(49)
    # = 29.1 of them (a bar by the count itself would be 13).
    data = np.zeros((4, 4, 4), np.uint8)
    data[3] = 200
    bars = [s for s in format_info(volume_info(Volume(data))).splitlines() if s.startswith("  ")]
    assert [b.count("#") for b in bars] == [40] + [0] * (len(bars) - 2) + [29]


def test_a_float_suggestion_is_never_the_data_minimum_or_maximum():
    # 1 and 2 are the shortest numbers near these cuts, but the data's range ends there: no
    # surface lies at either.
    from data_tools.info import _shortest
    assert _shortest(1.0, 0.5, 1.5, 1.0, 2.0) == 1.1
    assert _shortest(2.0, 1.5, 2.5, 1.0, 2.0) == 1.9
