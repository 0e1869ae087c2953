"""Transfer functions: lookups, the kernel, the range query, presets and files.

Truth: ``np.interp`` and a scalar ``bisect`` reference written out here for
the lookups; for `nonzero_in`, a brute-force search of each range (every
control point in it, the midpoints between them, and the floats just
outside each end), which no interval table is involved in.
"""
import bisect
import decimal
import json
import math
import re
from fractions import Fraction

import numba
import numpy as np
import pytest

from parc import InputError
from parc import transfer as T
from parc.transfer import (PRESET_DESCRIPTIONS, PRESETS, TransferFunction, correct_opacity,
                           load_transfer_function, preset, save_transfer_function, tf_lookup,
                           tf_opacity)
from raycast.config import RANGE_CHUNK


# --------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------

def random_tf(rng, *, steps=True, zero_prob=0.5, n_max=8, scale=1000.0):
    """A random TF: values with occasional jumps, many zero opacities."""
    def values(n):
        x = np.sort(rng.uniform(-scale, scale, n))
        if steps:
            for i in range(1, n):
                if rng.random() < 0.2 and (i < 2 or x[i - 2] != x[i - 1]):
                    x[i] = x[i - 1]            # a jump; never three equal values
        return x

    n = int(rng.integers(1, n_max + 1))
    m = int(rng.integers(1, n_max + 1))
    ox = values(n)
    oy = np.where(rng.random(n) < zero_prob, 0.0, rng.random(n))
    cx = values(m)
    return TransferFunction(np.column_stack([ox, oy]), np.column_stack([cx, rng.random((m, 3))]))


def scalar_reference(x, y, v):
    """Straight-line reference: bisect for the segment, then the same formula."""
    if math.isnan(v):
        return 0.0
    if v >= x[-1]:
        return y[-1]
    if v < x[0]:
        return y[0]
    i = bisect.bisect_right(list(x), v) - 1
    t = (v - x[i]) / (x[i + 1] - x[i])
    return y[i] + t * (y[i + 1] - y[i])


def probe_values(tf, rng, n=2000):
    """Random values, every control point and its float neighbours, and the specials."""
    op_x, _, col_x, _ = tf.arrays()
    pts = np.concatenate([op_x, col_x])
    lo, hi = pts.min(), pts.max()
    span = max(hi - lo, 1.0)
    v = [rng.uniform(lo - 0.2 * span, hi + 0.2 * span, n), pts,
         np.nextafter(pts, -np.inf), np.nextafter(pts, np.inf),
         [np.nan, np.inf, -np.inf, 0.0, -0.0, 1e300, -1e300]]
    return np.concatenate([np.asarray(a, dtype=np.float64) for a in v])


@numba.njit(cache=True)
def kernel_lookup_all(op_x, op_y, col_x, col_rgb, values):
    out = np.empty((values.shape[0], 4))
    for k in range(values.shape[0]):
        r, g, b, a = tf_lookup(op_x, op_y, col_x, col_rgb, values[k])
        out[k, 0] = r
        out[k, 1] = g
        out[k, 2] = b
        out[k, 3] = a
    return out


@numba.njit(cache=True)
def kernel_opacity_all(op_x, op_y, values):
    out = np.empty(values.shape[0])
    for k in range(values.shape[0]):
        out[k] = tf_opacity(op_x, op_y, values[k])
    return out


def exact_opacity(xs, ys, v):
    """The piecewise-linear opacity in exact rational arithmetic (``xs``, ``ys``, ``v``: Fractions)."""
    if v < xs[0]:
        return ys[0]
    if v >= xs[-1]:
        return ys[-1]
    i = bisect.bisect_right(xs, v) - 1            # last point at or below v; xs[i + 1] > v
    return ys[i] + (v - xs[i]) / (xs[i + 1] - xs[i]) * (ys[i + 1] - ys[i])


def brute_nonzero(tf, mn, mx):
    """Does [mn, mx] meet the closure of {v : opacity(v) > 0}? Exact search, no interval table.

    Between consecutive control points the opacity is linear and >= 0, so it
    is positive somewhere on such an open stretch exactly when it is positive
    at its midpoint. Probes: the ends, the control points inside, midpoints
    between all of these, and the midpoints of the stretches just outside
    each end (positive there means the end is in the closure).
    """
    if math.isnan(mn) or math.isnan(mx):
        return len(tf.support()) > 0
    if mn > mx:
        return False
    op_x, op_y = tf.arrays()[:2]
    xs = [Fraction(x) for x in op_x]
    ys = [Fraction(y) for y in op_y]
    lo, hi = Fraction(mn), Fraction(mx)
    cps = sorted(set(xs))
    pts = sorted({lo, hi} | {c for c in cps if lo <= c <= hi})
    below = [c for c in cps if c < lo]
    above = [c for c in cps if c > hi]
    left = below[-1] if below else lo - 1
    right = above[0] if above else hi + 1
    probes = pts + [(a + b) / 2 for a, b in zip(pts, pts[1:])] + [(left + lo) / 2, (hi + right) / 2]
    return any(exact_opacity(xs, ys, p) > 0 for p in probes)


def random_ranges(tf, rng, n=400):
    """Ranges that start and end on control points, next to them, at random, and degenerate."""
    op_x = tf.arrays()[0]
    span = max(op_x[-1] - op_x[0], 1.0)

    def pick(k):
        kind = rng.integers(0, 4, k)
        cp = rng.choice(op_x, k)
        out = np.where(kind == 0, rng.uniform(op_x[0] - 0.3 * span, op_x[-1] + 0.3 * span, k), cp)
        out = np.where(kind == 1, np.nextafter(cp, -np.inf), out)
        out = np.where(kind == 2, np.nextafter(cp, np.inf), out)
        return out

    a, b = pick(n), pick(n)
    mn, mx = np.minimum(a, b), np.maximum(a, b)
    same = rng.random(n) < 0.25
    mx[same] = mn[same]
    return mn, mx


# --------------------------------------------------------------------------
# Lookups
# --------------------------------------------------------------------------

def test_lookups_match_np_interp():
    rng = np.random.default_rng(1)
    for _ in range(200):
        tf = random_tf(rng, steps=False)
        op_x, op_y, col_x, col_rgb = tf.arrays()
        v = probe_values(tf, rng)
        v = v[np.isfinite(v)]
        got_a = tf.opacity(v)
        got_c = tf.color(v)
        want_a = np.interp(v, op_x, op_y)
        want_c = np.stack([np.interp(v, col_x, col_rgb[:, c]) for c in range(3)], axis=-1)
        np.testing.assert_allclose(got_a, want_a, rtol=0, atol=1e-12)
        np.testing.assert_allclose(got_c, want_c, rtol=0, atol=1e-12)
        # At control points and outside the points np.interp does no arithmetic: exact.
        for x, y, got in ((op_x, op_y, got_a), (col_x, col_rgb, got_c)):
            exact = np.isin(v, x) | (v < x[0]) | (v > x[-1])
            want = np.interp(v[exact], x, y) if y.ndim == 1 else \
                np.stack([np.interp(v[exact], x, y[:, c]) for c in range(3)], axis=-1)
            np.testing.assert_array_equal(got[exact], want)


def test_lookups_with_jumps_match_the_scalar_reference():
    rng = np.random.default_rng(2)
    for _ in range(200):
        tf = random_tf(rng, steps=True)
        op_x, op_y, col_x, col_rgb = tf.arrays()
        v = probe_values(tf, rng, n=300)
        want_a = np.array([scalar_reference(op_x, op_y, x) for x in v])
        np.testing.assert_array_equal(tf.opacity(v), want_a)
        for c in range(3):
            want = np.array([scalar_reference(col_x, col_rgb[:, c], x) for x in v])
            np.testing.assert_array_equal(tf.color(v)[:, c], np.where(np.isnan(v), 0.0, want))


def test_jump_is_continuous_from_the_right():
    tf = TransferFunction([[0.0, 0.0], [1.0, 0.0], [1.0, 0.8], [2.0, 0.8]])
    assert tf.opacity(1.0) == 0.8
    assert tf.opacity(np.nextafter(1.0, 0.0)) == 0.0
    down = TransferFunction([[0.0, 0.5], [1.0, 0.5], [1.0, 0.0]])
    assert down.opacity(1.0) == 0.0 and down.opacity(0.999) == 0.5
    np.testing.assert_array_equal(down.support(), [[-np.inf, 1.0]])


def test_constant_outside_and_nan_is_transparent_black():
    tf = TransferFunction([[10.0, 0.2], [20.0, 0.6]], [[15.0, 0.1, 0.2, 0.3]])
    np.testing.assert_array_equal(tf.opacity([-1e300, 5.0, 10.0, 20.0, 1e300, np.inf, -np.inf]),
                                  [0.2, 0.2, 0.2, 0.6, 0.6, 0.6, 0.2])
    np.testing.assert_array_equal(tf.color([0.0, 100.0]), [[0.1, 0.2, 0.3]] * 2)
    np.testing.assert_array_equal(tf.lookup(np.nan), [0.0, 0.0, 0.0, 0.0])
    assert tf_lookup(*tf.arrays(), np.nan) == (0.0, 0.0, 0.0, 0.0)
    assert tf.opacity(np.int16(15)) == 0.4
    assert tf.lookup(np.zeros((2, 3))).shape == (2, 3, 4)


def test_kernel_equals_numpy_bit_for_bit():
    from raycast.transfer import LINEAR_SEARCH_MAX
    rng = np.random.default_rng(3)
    bisected = 0
    for n in range(300):
        # Every other table may be longer than the kernel scans: it bisects those.
        tf = random_tf(rng, steps=bool(rng.random() < 0.5), n_max=8 if n % 2 else 3 * LINEAR_SEARCH_MAX)
        bisected += len(tf.arrays()[0]) > LINEAR_SEARCH_MAX
        v = probe_values(tf, rng)
        got = kernel_lookup_all(*tf.arrays(), v)
        want = tf.lookup(v)
        np.testing.assert_array_equal(got.view(np.int64), want.view(np.int64))
        op_x, op_y = tf.arrays()[:2]
        np.testing.assert_array_equal(kernel_opacity_all(op_x, op_y, v).view(np.int64),
                                      want[:, 3].view(np.int64))
    assert bisected > 50


def test_arrays_are_float64_contiguous_and_read_only():
    tf = preset("ct_skin_bone")
    op_x, op_y, col_x, col_rgb = tf.arrays()
    assert col_rgb.shape == (len(col_x), 3) and op_y.shape == op_x.shape
    for a in tf.arrays():
        assert a.dtype == np.float64 and a.flags.c_contiguous and not a.flags.writeable


def test_correct_opacity():
    a = np.array([0.0, 1e-12, 0.01, 0.3, 0.9, 0.999999, 1.0])
    with decimal.localcontext() as ctx:
        # 1 - (1 - a) ** ratio in float64 loses the digits of a small a in 1 - a; 50 digits keep them.
        ctx.prec = 50
        for ratio in (0.1, 0.5, 1.0, 2.0, 4.0, 37.5):
            got = np.array([correct_opacity(x, ratio) for x in a])
            want = np.array([float(1 - (1 - decimal.Decimal(x)) ** decimal.Decimal(ratio)) for x in a])
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
    assert correct_opacity(0.3, 1.0) == 0.3
    assert all(correct_opacity(x, 1.0) == x for x in np.random.default_rng(4).random(200))
    assert correct_opacity(0.0, 3.0) == 0.0 and correct_opacity(1.0, 0.25) == 1.0
    # Two half steps are one whole step.
    half = correct_opacity(0.4, 0.5)
    assert abs(1 - (1 - half) ** 2 - 0.4) < 1e-15
    assert T.reference_step((1.0, 0.5, 2.0)) == 0.125


# --------------------------------------------------------------------------
# The range query
# --------------------------------------------------------------------------

def test_nonzero_in_matches_brute_force_on_random_functions():
    rng = np.random.default_rng(4)
    for _ in range(150):
        tf = random_tf(rng, steps=bool(rng.random() < 0.5), zero_prob=0.6)
        mn, mx = random_ranges(tf, rng, n=150)
        got = tf.nonzero_in(mn, mx)
        want = np.array([brute_nonzero(tf, a, b) for a, b in zip(mn, mx)])
        bad = np.flatnonzero(got != want)
        assert len(bad) == 0, (tf.opacity_points, mn[bad[0]], mx[bad[0]], got[bad[0]])


def test_nonzero_in_is_conservative_against_the_kernel():
    # Every float the kernel gives opacity > 0 lies in the support, so a
    # range holding it is never classified empty.
    rng = np.random.default_rng(5)
    for _ in range(200):
        tf = random_tf(rng, zero_prob=0.7)
        v = probe_values(tf, rng)
        a = kernel_opacity_all(*tf.arrays()[:2], v)
        pos = v[a > 0]
        assert tf.nonzero_in(pos, pos).all()
        sup = tf.support()
        inside = ((pos[:, None] >= sup[:, 0]) & (pos[:, None] <= sup[:, 1])).any(axis=1)
        assert inside.all()


@pytest.mark.parametrize("width", [1e-6, 1e-9, 2.0 ** -30])
def test_narrow_spike(width):
    c = 600.5
    tf = TransferFunction([[c, 0.0], [c + width / 2, 0.7], [c + width, 0.0]])
    np.testing.assert_array_equal(tf.support(), [[c, c + width]])
    e = c + width
    cases = [
        ((c - 10, c + 10), True),                   # contains it
        ((c - 10, c), True),                        # touches the left end
        ((e, e + 10), True),                        # touches the right end
        ((c, c), True), ((e, e), True),             # degenerate, on the ends
        ((c + width / 2, c + width / 2), True),     # degenerate, at the peak
        ((c - 10, np.nextafter(c, 0)), False),
        ((np.nextafter(e, np.inf), e + 10), False),
        ((e + 1, e + 1), False),
    ]
    mn = np.array([a for (a, _), _ in cases])
    mx = np.array([b for (_, b), _ in cases])
    np.testing.assert_array_equal(tf.nonzero_in(mn, mx), [w for _, w in cases])
    # A dense sweep of the floats between the ends finds opacity only inside.
    v = np.linspace(c - width, e + width, 10001)
    pos = v[tf.opacity(v) > 0]
    assert pos.min() > c and pos.max() < e
    assert tf.nonzero_in(pos, pos).all()


def test_isolated_triangle_and_boundary_ranges():
    tf = TransferFunction([[0, 0.0], [10, 0.0], [11, 0.5], [12, 0.0], [100, 0.0], [100, 0.3]])
    np.testing.assert_array_equal(tf.support(), [[10, 12], [100, np.inf]])
    mn = np.array([0, 0, 12, 12.5, 13, 50, 100, 99, 200, 5, 11, -np.inf, 13])
    mx = np.array([9.99, 10, 12, 13, 99, 99.999, 100, 99.5, 300, 4, 11, np.inf, np.inf])
    want = [False, True, True, False, False, False, True, False, True, False, True, True, True]
    np.testing.assert_array_equal(tf.nonzero_in(mn, mx), want)


def test_nonzero_in_dtypes_shapes_and_chunks():
    tf = TransferFunction([[500.0, 0.0], [600.0, 0.5], [700.0, 0.0]])
    mn = np.array([[0, 450], [700, 650]], dtype=np.int16)
    mx = np.array([[500, 499], [800, 651]], dtype=np.int16)
    np.testing.assert_array_equal(tf.nonzero_in(mn, mx), [[True, False], [True, True]])
    np.testing.assert_array_equal(tf.nonzero_in(mn.astype(np.uint16), mx.astype(np.float32)),
                                  [[True, False], [True, True]])
    assert tf.nonzero_in(np.zeros((3, 1)), np.full((1, 4), 550.0)).shape == (3, 4)
    assert tf.nonzero_in(550, 560).shape == ()
    assert not tf.nonzero_in(650.0, 550.0)          # reversed: empty
    assert tf.nonzero_in(np.nan, 1.0)               # unknown: conservative
    assert not TransferFunction([[0, 0.0]]).nonzero_in(np.nan, 1.0)
    assert TransferFunction([[0, 0.1]]).nonzero_in(-1e300, -1e300)
    # Over several of the chunks threads take: NumPy's search of the support, and the int16
    # ranges' table lookups against the same ranges in float64.
    rng = np.random.default_rng(6)
    a = rng.uniform(300, 900, 3 * RANGE_CHUNK + 7)
    b = a + rng.uniform(0, 50, a.size)
    lo, hi = tf.support().T
    k = np.searchsorted(hi, a, side="left")
    want = (k < len(lo)) & (lo[np.minimum(k, len(lo) - 1)] <= b)
    np.testing.assert_array_equal(tf.nonzero_in(a, b), want)
    a16, b16 = a.astype(np.int16), b.astype(np.int16)
    np.testing.assert_array_equal(tf.nonzero_in(a16, b16), tf.nonzero_in(a16.astype(float), b16.astype(float)))


def test_nonzero_in_on_cell_ranges_matches_sampling():
    """Cells classified empty really get opacity 0 at every sample of their interpolant."""
    from parc.ranges import cell_minmax
    rng = np.random.default_rng(7)
    k, j, i = np.mgrid[0:6, 0:7, 0:8]
    data = (40 * i + 30 * j + 20 * k + rng.integers(-15, 16, i.shape)).astype(np.int16)
    tf = TransferFunction([[480, 0.0], [500, 0.3], [520, 0.0]])
    mn, mx = cell_minmax(data)
    pc = tf.nonzero_in(mn, mx)
    u = np.linspace(0, 1, 9)
    for k, j, i in zip(*np.nonzero(~pc)):
        c = data[k:k + 2, j:j + 2, i:i + 2].astype(np.float64)
        w = np.stack(np.meshgrid(u, u, u, indexing="ij"), -1)
        z, y, x = w[..., 0], w[..., 1], w[..., 2]
        val = sum(c[a, b, d] * (z if a else 1 - z) * (y if b else 1 - y) * (x if d else 1 - x)
                  for a in (0, 1) for b in (0, 1) for d in (0, 1))
        assert not (tf.opacity(val) > 0).any()
    assert 0 < pc.sum() < pc.size


# --------------------------------------------------------------------------
# Presets
# --------------------------------------------------------------------------

def test_presets_are_valid_and_described():
    assert set(PRESETS) == set(PRESET_DESCRIPTIONS) == {"ct_skin", "ct_bone", "ct_skin_bone",
                                                         "greyscale", "viridis"}
    for name in PRESETS:
        tf = preset(name, (0.0, 3272.0))
        assert isinstance(tf, TransferFunction) and tf.name == name
        assert "\n" not in PRESET_DESCRIPTIONS[name] and PRESET_DESCRIPTIONS[name]
        v = np.linspace(-100, 4000, 4101)
        rgba = tf.lookup(v)
        assert ((rgba >= 0) & (rgba <= 1)).all()
        assert tf.opacity(0.0) == 0.0                 # air / background is empty
        assert len(tf.support()) > 0


def test_ct_presets_classify_the_expected_tissues():
    skin, bone, both = preset("ct_skin"), preset("ct_bone"), preset("ct_skin_bone")
    air, skin_v, tissue, bone_v = 200.0, 700.0, 1050.0, 1800.0
    assert skin.opacity(skin_v) > 0 and skin.opacity(air) == 0 and skin.opacity(tissue) == 0
    assert bone.opacity(bone_v) > 0 and bone.opacity(1150.0) == 0 and bone.opacity(skin_v) == 0
    assert 0 < both.opacity(skin_v) < skin.opacity(skin_v) < both.opacity(bone_v)
    assert both.opacity(tissue) == 0
    r, g, b = skin.color(skin_v)
    assert r > g > b                                  # a warm skin tone
    assert bone.color(bone_v).min() > 0.85            # whitish
    assert not both.nonzero_in(1001, 1199)            # soft tissue interior stays empty
    assert both.nonzero_in(1001, 1200)                # touching the bone's start counts


def test_ramp_presets_follow_the_data_range():
    for name in ("greyscale", "viridis"):
        tf = preset(name, (-50.0, 150.0))
        assert tf.opacity(-50.0) == 0.0 and tf.opacity(-30.0) == 0.0
        assert tf.opacity(150.0) == T.RAMP_OPACITY and tf.opacity(100.0) > tf.opacity(50.0) > 0
        with pytest.raises(InputError, match="data range"):
            preset(name)
    grey = preset("greyscale", (0, 10))
    np.testing.assert_array_equal(grey.color([0, 10]), [[0, 0, 0], [1, 1, 1]])
    vir = preset("viridis", (0, 255))
    np.testing.assert_array_equal(vir.color([0, 255]), [T.VIRIDIS[0][1:], T.VIRIDIS[-1][1:]])
    # Perceptual: luminance rises monotonically along viridis.
    rgb = vir.color(np.linspace(0, 255, 200))
    lum = rgb @ [0.2126, 0.7152, 0.0722]
    assert (np.diff(lum) > 0).all()
    # A one-value range still gives a valid function.
    assert preset("viridis", (7, 7)).opacity(7) == 0.0


@pytest.mark.parametrize("mode", ["mip", "average"])
def test_ramps_end_opaque_for_maximum_and_average_intensity(tmp_path, mode):
    # One value a ray, shown at its opacity: at the compositing ramp's 0.1 the brightest pixel
    # of a maximum-intensity image was 10% grey on black.
    from data_tools import Volume
    from parc import Translucent, load_scene
    for name in ("greyscale", "viridis"):
        tf = preset(name, (-50.0, 150.0), mode)
        assert tf.opacity(150.0) == 1.0 and tf.opacity(-30.0) == 0.0
        assert tf.opacity(50.0) == pytest.approx(preset(name, (-50.0, 150.0)).opacity(50.0) / T.RAMP_OPACITY)
        np.testing.assert_array_equal(tf.color([0, 100]), preset(name, (-50.0, 150.0)).color([0, 100]))
    vol = Volume(np.arange(27, dtype=np.float32).reshape(3, 3, 3))
    assert Translucent(vol, "greyscale", mode=mode).tf.opacity(26.0) == 1.0
    assert Translucent(vol, "greyscale").tf.opacity(26.0) == T.RAMP_OPACITY
    paraview = tmp_path / "map.json"
    paraview.write_text(json.dumps([{"Name": "m", "RGBPoints": [0, 0, 0, 0, 1, 1, 1, 1]}]))
    assert T.load_transfer_function(paraview, (0.0, 26.0), mode).opacity(26.0) == 1.0
    assert T.load_transfer_function(paraview, (0.0, 26.0)).opacity(26.0) == T.RAMP_OPACITY
    np.save(tmp_path / "v.npy", vol.data)
    (tmp_path / "s.toml").write_text(f'[[volume]]\nfile = "v.npy"\ntf = "viridis"\nmode = "{mode}"\n')
    assert load_scene(tmp_path / "s.toml").volumes[0].tf.opacity(26.0) == 1.0


# --------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------

@pytest.mark.parametrize("ext", [".toml", ".json"])
def test_round_trip(tmp_path, ext):
    rng = np.random.default_rng(8)
    for k in range(20):
        made = random_tf(rng)
        tf = TransferFunction(made.opacity_points, made.color_points, name=f"random \"{k}\" é")
        path = tmp_path / f"tf{k}{ext}"
        save_transfer_function(tf, path)
        back = load_transfer_function(path)
        assert back == tf and back.name == tf.name
    for name in PRESETS:
        tf = preset(name, (0, 3272))
        save_transfer_function(tf, tmp_path / f"p{ext}")
        assert load_transfer_function(str(tmp_path / f"p{ext}")) == tf


def test_a_lone_surrogate_is_refused_by_toml_and_kept_by_json(tmp_path):
    # JSON may escape half of a surrogate pair ("\ud800"); TOML and UTF-8 cannot hold it.
    src = tmp_path / "odd.json"
    src.write_text('{"description": "\\ud800 notes", "opacity": [[0, 0], [1, 1]]}')
    tf = load_transfer_function(src)
    assert tf.description == "\ud800 notes"
    with pytest.raises(InputError, match="description holds a lone surrogate.*save it as .json"):
        save_transfer_function(tf, tmp_path / "odd.toml")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["odd.json"]
    save_transfer_function(tf, tmp_path / "back.json")
    assert load_transfer_function(tmp_path / "back.json").description == tf.description


def test_our_format_by_hand(tmp_path):
    p = tmp_path / "skin.toml"
    p.write_text('name = "skin"\nopacity = [[500, 0.0], [650, 0.05], [1000, 0]]\n'
                 'color = [[500, 0.8, 0.5, 0.4], [1000, 1, 0.9, 0.8]]\n')
    tf = load_transfer_function(str(p))
    assert tf.name == "skin" and tf.opacity(650) == 0.05
    np.testing.assert_allclose(tf.color(750), [0.9, 0.7, 0.6], rtol=0, atol=1e-15)
    q = tmp_path / "white.json"
    q.write_text(json.dumps({"opacity": [[3, 0.5]]}))
    np.testing.assert_array_equal(load_transfer_function(q).color([0, 9]), [[1, 1, 1]] * 2)
    n = tmp_path / "norm.toml"
    n.write_text('space = "normalized"\nopacity = [[0, 0], [0.5, 0.2], [1, 0.4]]\n'
                 'color = [[0, 0, 0, 0], [1, 1, 1, 1]]\n')
    tf = load_transfer_function(n, data_range=(100, 300))
    np.testing.assert_array_equal(tf.arrays()[0], [100, 200, 300])
    assert tf.opacity(200) == 0.2


def test_a_byte_order_mark_before_a_transfer_function_file_is_read_past(tmp_path):
    # Editors on Windows write one before TOML and JSON alike; it is no content.
    bom = b"\xef\xbb\xbf"
    (tmp_path / "bom.toml").write_bytes(bom + b"opacity = [[0, 0.0], [10, 0.5]]\n"
                                              b"color = [[0, 1, 0, 0], [10, 0, 0, 1]]\n")
    (tmp_path / "bom.json").write_bytes(bom + json.dumps({"opacity": [[0, 0.0], [10, 0.5]],
                                                          "color": [[0, 1, 0, 0], [10, 0, 0, 1]]}).encode())
    (tmp_path / "pv.json").write_bytes(bom + json.dumps([{"RGBPoints": [0, 1, 0, 0, 10, 0, 0, 1],
                                                          "Points": [0, 0.0, 0.5, 0, 10, 0.5, 0.5, 0]}]).encode())
    for name in ("bom.toml", "bom.json", "pv.json"):
        tf = load_transfer_function(tmp_path / name)
        np.testing.assert_array_equal(tf.opacity_points, [[0, 0.0], [10, 0.5]])
        np.testing.assert_array_equal(tf.lookup(5.0), [0.5, 0.0, 0.5, 0.25])


PARAVIEW = [{
    "ColorSpace": "Diverging", "Name": "Cool to Warm", "NanColor": [1, 1, 0],
    "RGBPoints": [0.0, 0.23, 0.299, 0.754, 0.5, 0.865, 0.865, 0.865, 1.0, 0.706, 0.016, 0.15],
    "Points": [0.0, 0.0, 0.5, 0.0, 0.25, 0.0, 0.5, 0.0, 1.0, 0.8, 0.5, 0.0],
}]


def test_paraview_json(tmp_path):
    p = tmp_path / "cool_warm.json"
    p.write_text(json.dumps(PARAVIEW))
    raw = load_transfer_function(p)
    assert raw.name == "Cool to Warm"
    np.testing.assert_array_equal(raw.opacity_points, [[0, 0], [0.25, 0], [1, 0.8]])
    np.testing.assert_array_equal(raw.color(0.5), [0.865, 0.865, 0.865])
    # Normalized span: stretched onto the data range.
    tf = load_transfer_function(p, data_range=(1000, 2000))
    np.testing.assert_array_equal(tf.arrays()[2], [1000, 1500, 2000])
    np.testing.assert_array_equal(tf.arrays()[0], [1000, 1250, 2000])
    np.testing.assert_allclose(tf.color(1500), [0.865] * 3, atol=1e-15)
    # One object, no opacity points, absolute values: a ramp, not stretched.
    q = tmp_path / "abs.json"
    q.write_text(json.dumps({"Name": "abs", "RGBPoints": [-1000, 0, 0, 0, 3000, 1, 1, 1]}))
    tf = load_transfer_function(q, data_range=(0, 10))
    np.testing.assert_array_equal(tf.arrays()[2], [-1000, 3000])
    assert tf.opacity(-1000) == 0 and tf.opacity(3000) == T.RAMP_OPACITY
    # [-1, 1] is stretched too.
    r = tmp_path / "sym.json"
    r.write_text(json.dumps([{"RGBPoints": [-1, 0, 0, 1, 0, 1, 1, 1, 1, 1, 0, 0]}]))
    tf = load_transfer_function(r, data_range=(-5, 5))
    np.testing.assert_array_equal(tf.arrays()[2], [-5, 0, 5])
    # Spans near those but not them are data values: [0, 0.9], [0.1, 1] and [-1, 0.9] stay put.
    for lo, hi in ((0.0, 0.9), (0.1, 1.0), (-1.0, 0.9), (0.0, 1.0 + 1e-5)):
        near = tmp_path / "near.json"
        near.write_text(json.dumps({"RGBPoints": [lo, 0, 0, 0, hi, 1, 1, 1]}))
        np.testing.assert_array_equal(load_transfer_function(near, data_range=(1000, 2000)).arrays()[2], [lo, hi])


def test_presets_by_name_and_passthrough():
    assert load_transfer_function("ct_bone") == preset("ct_bone")
    tf = preset("ct_skin")
    assert load_transfer_function(tf) is tf


def test_a_preset_mapped_onto_any_range_ends_exactly_at_its_top():
    # lo + (1 - 0) * (hi - lo) rounds past hi for many ranges (this one among them): the last
    # control point then lay beyond the data, and the data's maximum did not get the last colour.
    lo, hi = -1311147.0622629568, 120.15111553890245
    assert lo + (hi - lo) != hi
    tf = preset("viridis", (lo, hi))
    assert tf.opacity_points[-1, 0] == hi and tf.color_points[-1, 0] == hi
    np.testing.assert_array_equal(tf.color(np.array([hi]))[0], tf.color_points[-1, 1:])


def test_a_point_an_ulp_below_the_top_of_its_span_stays_below_the_top_when_mapped():
    # (x - s0) / (s1 - s0) * (hi - lo) carried the point just below s1 past hi, and s1's own point,
    # set to hi, then lay below it: a valid ParaView map over [-1, 1] was refused as descending.
    points = [(-1.0, 0.0), (0.0, 0.5), (0.9999999999999999, 0.5), (1.0, 1.0)]
    lo, hi = -0.0009486494471372439, 2.7770479061531086e-05
    mapped = TransferFunction(points).mapped(lo, hi, src=(-1.0, 1.0))
    xs = mapped.opacity_points[:, 0]
    assert np.all(np.diff(xs) >= 0) and xs[0] == lo and xs[-1] == hi
    # Ranges at random: every mapped function ascends and ends on hi.
    rng = np.random.default_rng(5)
    for lo, hi in np.sort(rng.normal(0, 10.0 ** rng.integers(-6, 6, (200, 1)), (200, 2)), axis=1):
        xs = TransferFunction(points).mapped(lo, hi, src=(-1.0, 1.0)).opacity_points[:, 0]
        assert np.all(np.diff(xs) >= 0) and xs[-1] == hi


@pytest.mark.parametrize("points, words", [
    ([(0.0, 1.000001)], "alpha 1.000001 is outside [0, 1]"),
    ([(1.0000001, 0.0), (1.00000001, 0.5)], "value 1.00000001 is below the previous value 1.0000001"),
])
def test_a_control_points_error_gives_its_numbers_exactly(points, words):
    # Six digits made a refused value look legal, or equal to its neighbour.
    with pytest.raises(InputError) as exc:
        TransferFunction(points)
    _check_error(exc, words)


def _check_error(exc, *parts):
    msg = str(exc.value)
    assert "\n" not in msg, msg
    for p in parts:
        assert p in msg, (p, msg)


BAD_FILES = [
    # (file name, content, parts the message must contain)
    ("bad.toml", "opacity = [[0, 0]", ["bad.toml", "malformed TOML"]),
    ("bad.json", '{"opacity": [[0, 0]', ["bad.json", "malformed JSON"]),
    # JSON keeps the last of a repeated key, silently; TOML refuses it.
    ("twice.json", '{"opacity": [[0, 0], [1, 1]], "opacity": [[0, 1]]}', ["twice.json", "'opacity' is given twice"]),
    ("twice.toml", 'opacity = [[0, 0], [1, 1]]\nopacity = [[0, 1]]', ["twice.toml", "malformed TOML"]),
    ("keys.toml", 'opacty = [[0, 0.1]]\ncolour = [[0, 1, 1, 1]]\nopacity = [[0, 0]]',
     ["keys.toml", "'colour'", "'opacty'", "unknown keys"]),
    ("missing.toml", 'color = [[0, 1, 1, 1]]', ["missing.toml", "opacity", "missing"]),
    ("str.toml", 'opacity = "ramp"', ["str.toml", "opacity:", "list"]),
    ("type.toml", 'opacity = [[0, "a"]]', ["type.toml", "opacity point 1", "alpha", "number"]),
    ("bool.json", '{"opacity": [[0, true]]}', ["bool.json", "opacity point 1", "number"]),
    ("name.toml", 'name = 3\nopacity = [[0, 0]]', ["name.toml", "name", "string"]),
    ("short.toml", 'opacity = [[0, 0]]\ncolor = [[0, 1, 1, 1], [1, 1, 1]]',
     ["short.toml", "color point 2", "[value, r, g, b]"]),
    ("order.toml", 'opacity = [[0, 0], [5, 0.1], [4, 0.2]]', ["order.toml", "opacity point 3", "ascend"]),
    ("triple.toml", 'opacity = [[1, 0], [1, 0.1], [1, 0.2]]', ["triple.toml", "opacity point 3", "third"]),
    ("alpha.toml", 'opacity = [[0, 0], [1, 1.5]]', ["alpha.toml", "opacity point 2", "alpha", "[0, 1]"]),
    ("rgb.json", '{"opacity": [[0, 0]], "color": [[0, 0.5, -0.1, 0]]}',
     ["rgb.json", "color point 1", "g", "[0, 1]"]),
    ("empty.toml", 'opacity = []', ["empty.toml", "opacity", "empty"]),
    ("nan.json", '{"opacity": [[0, NaN]]}', ["nan.json", "opacity point 1", "finite"]),
    ("huge.json", '{"opacity": [[1' + "0" * 400 + ', 0.5]]}', ["huge.json", "opacity point 1", "finite"]),
    ("digits.json", '{"opacity": [[1' + "0" * 5000 + ', 0.5]]}', ["digits.json", "malformed JSON", "too long"]),
    ("digits.toml", 'opacity = [[1' + "0" * 5000 + ', 0.5]]', ["digits.toml", "malformed TOML", "too long"]),
    ("deep.json", "[" * 100000 + "]" * 100000, ["deep.json", "malformed JSON", "nested too deeply"]),
    ("deep.toml", "opacity = " + "[" * 100000 + "]" * 100000, ["deep.toml", "malformed TOML", "nested too deeply"]),
    ("space.toml", 'space = "log"\nopacity = [[0, 0]]', ["space.toml", "space"]),
    ("normout.toml", 'space = "normalized"\nopacity = [[0, 0], [1.5, 0.1]]',
     ["normout.toml", "opacity point 2", "normalized"]),
    ("top.json", '[1, 2, 3]', ["top.json", "the list's first entry"]),
    ("scalar.json", '3', ["scalar.json", "object"]),
    ("pv_len.json", '[{"RGBPoints": [0, 1, 1]}]', ["pv_len.json", "RGBPoints", "multiple of 4"]),
    ("pv_rgb.json", '[{"RGBPoints": [0, 0, 0, 0, 1, 1, 2, 1]}]', ["pv_rgb.json", "RGBPoints number 7 (point 2)", "[0, 1]"]),
    ("pv_order.json", '[{"RGBPoints": [0, 0, 0, 0, 1, 1, 1, 1], "Points": [0, 0, 0.5, 0, -1, 1, 0.5, 0]}]',
     ["pv_order.json", "Points number 5 (point 2)", "ascend"]),
    ("pv_alpha.json", '[{"RGBPoints": [0, 0, 0, 0], "Points": [0, 2, 0.5, 0]}]',
     ["pv_alpha.json", "Points number 2 (point 1)", "alpha"]),
    ("pv_type.json", '[{"RGBPoints": [0, 0, "x", 0]}]', ["pv_type.json", "RGBPoints number 3 (point 1)", "number"]),
    ("pv_none.json", '[{"Name": "x", "IndexedColors": [1, 0, 0]}]', ["pv_none.json", "RGBPoints", "missing"]),
    ("pv_empty.json", '[]', ["pv_empty.json", "empty"]),
    ("pv_object.json", '{"Name": "x", "ColorSpace": "RGB"}', ["pv_object.json", "RGBPoints"]),
    ("null.json", 'null', ["null.json", "object", "got null"]),
    ("pv_name.json", '[{"Name": 5, "RGBPoints": [0, 0, 0, 0]}]', ["pv_name.json", "Name"]),
    ("tf.yaml", "opacity: []", ["tf.yaml", ".yaml", ".toml or .json"]),
    ("both.json", '{"RGBPoints": [0, 0, 0, 0], "opacity": [[0, 1]]}', ["both.json", "keep one kind"]),
    # One check each: a row fails where its check is dropped or loosened.
    ("both_color.json", '{"RGBPoints": [0, 0, 0, 0], "color": [[0, 1, 1, 1]]}', ["both_color.json", "keep one kind"]),
    ("pv_points.json", '{"Points": [0, 0, 0.5, 0]}', ["pv_points.json", "needs RGBPoints"]),
    ("pv_space.json", '{"ColorSpace": "RGB"}', ["pv_space.json", "needs RGBPoints"]),
    ("ours_name.json", '{"Name": "x", "color": [[0, 1, 1, 1]]}', ["ours_name.json", "unknown key 'Name'"]),
    ("desc.json", '{"opacity": [[0, 0]], "description": 5}', ["desc.json", "description: must be a string"]),
    ("normcolor.toml", 'space = "normalized"\nopacity = [[0, 0], [1, 1]]\ncolor = [[0, 0, 0, 0], [2, 1, 1, 1]]',
     ["normcolor.toml", "color point 2", "outside [0, 1]"]),
    ("normneg.toml", 'space = "normalized"\nopacity = [[-0.5, 0], [1, 1]]', ["normneg.toml", "opacity point 1", "outside [0, 1]"]),
    ("pv_indexed.json", '[{"Name": "x", "IndexedColors": [1, 0, 0]}]', ["pv_indexed.json", "indexed/categorical"]),
    ("nullcolor.json", '{"opacity": [[0, 0]], "color": null}', ["nullcolor.json", "color:", "null"]),
    ("pv_points_len.json", '[{"RGBPoints": [0, 0, 0, 0, 1, 1, 1, 1], "Points": [0, 0, 0.5, 0, 1, 1]}]',
     ["pv_points_len.json", "Points: 6 numbers is not a multiple of 4"]),
]


@pytest.mark.parametrize("name,content,parts", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_bad_files(tmp_path, name, content, parts):
    p = tmp_path / name
    p.write_text(content)
    with pytest.raises(InputError) as exc:
        load_transfer_function(str(p))
    _check_error(exc, *parts)


def test_missing_file_unknown_preset_and_needed_range(tmp_path):
    with pytest.raises(InputError) as exc:
        load_transfer_function(str(tmp_path / "nope.toml"))
    _check_error(exc, "nope.toml", "not found")
    with pytest.raises(InputError) as exc:
        load_transfer_function("ct_skinbone")
    _check_error(exc, "'ct_skinbone'", "ct_skin_bone", "viridis")
    p = tmp_path / "norm.toml"
    p.write_text('space = "normalized"\nopacity = [[0, 0], [1, 0.1]]')
    with pytest.raises(InputError) as exc:
        load_transfer_function(p)
    _check_error(exc, "norm.toml", "space", "data range")
    with pytest.raises(InputError) as exc:
        load_transfer_function("greyscale")
    _check_error(exc, "greyscale", "data range")
    with pytest.raises(InputError) as exc:
        load_transfer_function(tmp_path)
    _check_error(exc, str(tmp_path))


def test_constructor_errors_name_key_and_index():
    cases = [
        (dict(opacity=[]), ["opacity", "empty"]),
        (dict(opacity=[[0, 0], [1, np.nan]]), ["opacity point 2", "finite"]),
        (dict(opacity=[[0, 0], [-1, 0]]), ["opacity point 2", "ascend"]),
        (dict(opacity=[[0, -0.1]]), ["opacity point 1", "[0, 1]"]),
        (dict(opacity=[[0, 0]], color=[[0, 1, 1]]), ["color point 1"]),
        (dict(opacity=[[-1e308, 0], [1e308, 0]]), ["opacity point 2", "overflow"]),
        (dict(opacity=None), ["opacity"]),
    ]
    for kwargs, parts in cases:
        with pytest.raises(InputError) as exc:
            TransferFunction(**kwargs)
        _check_error(exc, "transfer function", *parts)


@pytest.mark.parametrize("dtype", [np.uint8, np.int8, np.uint16, np.int16])
def test_nonzero_in_small_integer_table_equals_float_path(dtype):
    rng = np.random.default_rng(9)
    info = np.iinfo(dtype)
    for _ in range(30):
        tf = random_tf(rng, zero_prob=0.6, scale=float(info.max) * 1.2)
        if rng.random() < 0.5:      # control points on integers, to hit the touching case
            op = tf.opacity_points
            op[:, 0] = np.round(op[:, 0])
            op[1:, 0] = np.maximum.accumulate(op[1:, 0])
            try:
                tf = TransferFunction(op)
            except InputError:      # rounding made three equal values
                continue
        a = rng.integers(info.min, info.max + 1, 5000, endpoint=False).astype(dtype)
        b = rng.integers(info.min, info.max + 1, 5000, endpoint=False).astype(dtype)
        a[:50] = b[:50]
        a[50:60] = [info.min, info.max] * 5
        got = tf.nonzero_in(a, b)
        want = tf.nonzero_in(a.astype(np.float64), b.astype(np.float64))
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("dtype", ["float64", "float32", "int16", "uint8"])
def test_nonzero_in_widens_by_the_casters_rounding(dtype):
    """With ``rounding``, a range counts from a few ulps short of a support that starts
    (or ends) just past it: the casters' samples can overshoot a cell's corners that far."""
    from raycast.composite import INTERP_ROUNDING
    m = 200.0
    eps = 8 * 2.0 ** -53 * m
    after = TransferFunction([[m + eps, 0.0], [m + 2 * eps, 0.5], [m + 1.0, 0.5]])      # starts just past m
    before = TransferFunction([[-1.0, 0.5], [m - 2 * eps, 0.5], [m - eps, 0.0]])       # ends just before m
    lo, hi = np.array([100], dtype), np.array([m], dtype)
    assert not after.nonzero_in(lo, hi)[0] and after.nonzero_in(lo, hi, rounding=INTERP_ROUNDING)[0]
    lo, hi = np.array([m], dtype), np.array([250], dtype)
    assert not before.nonzero_in(lo, hi)[0] and before.nonzero_in(lo, hi, rounding=INTERP_ROUNDING)[0]
    # ... and no farther than that.
    far = TransferFunction([[m + 1e-6 * m, 0.0], [m + 1.0, 0.5]])
    assert not far.nonzero_in(np.array([100], dtype), np.array([m], dtype), rounding=INTERP_ROUNDING)[0]


@pytest.mark.parametrize("name, label", [(None, ""), ("line1\nline2\x1b[31mRED", "line1 line2 [31mRED"),
                                         ("ct skin", "ct skin")])
def test_a_name_is_one_line_of_printable_text(name, label):
    # It is printed in notes ("composite of NAME"): None was "None", a newline split the line.
    assert TransferFunction([[0, 1]], name=name).name == label


def test_a_reversed_range_meets_nothing_however_widened():
    tf = TransferFunction([[0, 0], [1, 1]])
    assert not tf.nonzero_in(np.array([0.5]), np.array([0.4999999]), rounding=1e-3)[0]
    assert not tf.nonzero_in(np.array([5], np.uint8), np.array([4], np.uint8), rounding=1e-3)[0]
    assert tf.nonzero_in(np.array([0.5]), np.array([0.5]), rounding=1e-3)[0]


def test_names_that_are_no_file_say_so(tmp_path):
    loop = tmp_path / "loop.toml"
    loop.symlink_to(loop)
    for spec, words in (("", "got an empty name"), ("  ", "got an empty name"),
                        (str(loop), "a link that leads nowhere"),
                        (str(tmp_path / ("a" * 300 + ".toml")), "File name too long")):
        with pytest.raises(InputError) as exc:
            T.load_transfer_function(spec)
        assert words in str(exc.value) and "\n" not in str(exc.value), str(exc.value)


@pytest.mark.parametrize("name", ["greyscale", "viridis", "file"])
def test_normalized_functions_map_onto_a_range_a_few_floats_wide(name, tmp_path):
    # A nearly constant float64 volume: viridis's many colour points fell three on one value,
    # which a file may not say, and the preset was refused. The jump they make is kept.
    lo = 1.0
    hi = lo + 2 * np.finfo(float).eps
    if name == "file":
        name = tmp_path / "n.toml"
        name.write_text('space = "normalized"\nopacity = [[0, 0.1], [0.2, 0.2], [0.3, 0.3], [0.4, 0.4], '
                        '[0.6, 0.5], [1, 0.6]]\n')
    tf = T.load_transfer_function(str(name), data_range=(lo, hi))
    unit = T.load_transfer_function(str(name), data_range=(0.0, 1.0))
    # The points rounded onto the range's floats move by under a float: the opacities still
    # rise from within the function's range to its value at the top, as they do over [0, 1].
    alphas = [float(tf.opacity(v)) for v in (lo, np.nextafter(lo, 2.0), hi)]
    assert alphas == sorted(alphas) and alphas[-1] == unit.opacity(1.0) and alphas[0] >= unit.opacity(0.0)
    assert np.array_equal(tf.color_points[-1, 1:], unit.color_points[-1, 1:])


@pytest.mark.parametrize("lo", [0.0, 5.0, -3.0])
def test_a_one_value_data_range_is_widened_by_one(lo):
    from parc.transfer.presets import data_range_of
    assert data_range_of((lo, lo), "x") == (lo, lo + 1.0)


@pytest.mark.parametrize("name", ["greyscale", "viridis"])
def test_a_reversed_data_range_is_named_as_such(name):
    # Not left to the control points it would make, which "must ascend".
    with pytest.raises(InputError, match=re.escape(f"{name}: data range (10, 0) is reversed")):
        preset(name, (10, 0))


def test_viridis_knots_sit_at_i_over_255_of_the_range():
    # Entry i of the 256-entry table lies at i / 255 of the data range: over (0, 255), at value i.
    from parc.transfer.presets import VIRIDIS
    tf = preset("viridis", (0, 255))
    for i, r, g, b in VIRIDIS:
        assert tuple(tf.color([float(i)])[0]) == pytest.approx((r, g, b), abs=1e-6)


def test_a_transfer_function_takes_points_of_numpy_scalars():
    pts = np.array([[0, 0.0], [10, 1.0]], dtype=np.float32)
    tf = TransferFunction([tuple(p) for p in pts])          # tuples of np.float32
    assert len(tf.support()) == 1                           # built, not refused


def test_paraview_rgb_points_keep_their_channel_order(tmp_path):
    # Truth: the file's own numbers, read as ParaView writes them, [x, r, g, b] per point:
    # Cool to Warm is blue at its low end and red at its high end.
    p = tmp_path / "cool_warm.json"
    p.write_text(json.dumps(PARAVIEW))
    tf = load_transfer_function(p)
    np.testing.assert_array_equal(tf.color([0.0, 1.0]), [[0.23, 0.299, 0.754], [0.706, 0.016, 0.15]])
    low, high = tf.color([0.0, 1.0])
    assert low[2] > low[0] and high[0] > high[2]


def test_file_errors_name_the_file_and_the_fault(tmp_path):
    import os
    # A name with a folder and no suffix is a missing file, not an unknown preset.
    with pytest.raises(InputError, match="transfer function file not found"):
        load_transfer_function(str(tmp_path / "nope"))
    # Not UTF-8.
    (tmp_path / "latin1.toml").write_bytes(b"name = 'caf\xe9'\nopacity = [[0, 0]]\n")
    with pytest.raises(InputError, match="latin1.toml: not a UTF-8 text file"):
        load_transfer_function(tmp_path / "latin1.toml")

    class BytesPath(os.PathLike):
        def __fspath__(self):
            return b"x.toml"
    with pytest.raises(InputError, match="path must be text, got bytes"):
        load_transfer_function(BytesPath())
    with pytest.raises(InputError, match="takes a file's path, got BytesPath"):
        save_transfer_function(TransferFunction([[0, 0]]), BytesPath())
    # Writing: a folder, or a folder that is not there, is an InputError naming the file.
    (tmp_path / "d.toml").mkdir()
    for target in (tmp_path / "d.toml", tmp_path / "no" / "x.json"):
        with pytest.raises(InputError, match=f"{re.escape(str(target))}: cannot write") as exc:
            save_transfer_function(TransferFunction([[0, 0]]), target)
        assert str(exc.value).count("cannot write") == 1, exc.value       # once, not wrapped again


def test_a_description_with_a_control_character_survives_a_toml_round_trip(tmp_path):
    # TOML forbids a raw DEL in a string: the writer escapes it.
    tf = TransferFunction([[0, 0], [1, 1]], description="a\x7fb\tc")
    save_transfer_function(tf, tmp_path / "d.toml")
    assert load_transfer_function(tmp_path / "d.toml").description == "a\x7fb\tc"


def test_a_paraview_ramp_ends_exactly_at_the_last_colour_point(tmp_path):
    # x0 + 1 * (x1 - x0) rounds past x1 here: the ramp's last point must still be x1.
    lo, hi = -1311147.0622629568, 120.15111553890245
    assert lo + (hi - lo) != hi
    p = tmp_path / "abs.json"
    p.write_text(json.dumps({"RGBPoints": [lo, 0, 0, 0, hi, 1, 1, 1]}))
    assert load_transfer_function(p).opacity_points[-1, 0] == hi


def test_a_zero_dimensional_array_or_a_set_is_refused_as_points():
    # A 0-d array has __len__ but no length; a set has no order.
    for bad in (np.array(5.0), [np.array(5.0)], {(0.0, 0.0), (1.0, 1.0)}):
        with pytest.raises(InputError, match="opacity"):
            TransferFunction(bad)


def test_a_description_of_none_is_none():
    assert TransferFunction([[0, 0]], description=None).description == ""


def test_a_saved_file_keeps_its_mode(tmp_path):
    import stat
    target = tmp_path / "tf.toml"
    target.write_text("")
    target.chmod(0o600)
    save_transfer_function(TransferFunction([[0, 0], [1, 1]]), target)
    assert stat.S_IMODE(target.stat().st_mode) == 0o600
    assert load_transfer_function(target) == TransferFunction([[0, 0], [1, 1]])


def test_a_file_type_in_capitals_is_saved_and_read_back(tmp_path):
    # The reader takes .TOML and .JSON as their lower-case selves: so must the writer.
    tf = TransferFunction([[0, 0], [2, 0.5]], [[0, 1, 0, 0], [2, 0, 0, 1]], name="caps")
    for name, first in (("Caps.TOML", b'name = "caps"'), ("Caps.JSON", b"{")):
        save_transfer_function(tf, tmp_path / name)
        assert (tmp_path / name).read_bytes().startswith(first)
        assert load_transfer_function(tmp_path / name) == tf
    assert sorted(p.name for p in tmp_path.iterdir()) == ["Caps.JSON", "Caps.TOML"]


def test_a_save_that_fails_midway_leaves_the_old_file_whole(tmp_path, monkeypatch):
    import errno
    import pathlib
    target = tmp_path / "tf.json"
    save_transfer_function(TransferFunction([[0, 0], [1, 1]]), target)
    before = target.read_bytes()

    def half_then_full(self, data):
        with open(self, "wb") as f:
            f.write(data[:len(data) // 2])
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(pathlib.Path, "write_bytes", half_then_full)
    with pytest.raises(InputError, match=re.escape(f"{target}: cannot write: No space left on device")):
        save_transfer_function(TransferFunction([[0, 0], [5, 1]]), target)
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tf.json"]


def test_a_jump_survives_mapping_onto_the_data_range():
    # Two equal values are a jump, continuous from the right; mapping [0, 1] onto [0, 10] moves it to 5.
    tf = TransferFunction([(0.0, 0.0), (0.5, 0.0), (0.5, 1.0), (1.0, 1.0)]).mapped(0.0, 10.0)
    np.testing.assert_array_equal(tf.opacity([4.999, 5.0, 5.001]), [0.0, 1.0, 1.0])
    np.testing.assert_array_equal(tf.opacity_points[:, 0], [0.0, 5.0, 5.0, 10.0])


def test_mapping_from_a_span_of_one_value_is_refused_by_name():
    tf = TransferFunction([(0.0, 0.5)])
    for src in ((2.0, 2.0), (3.0, 2.0)):
        with pytest.raises(InputError, match="cannot map from an empty value span"):
            tf.mapped(0.0, 1.0, src=src)


@pytest.mark.parametrize("lo, hi, src, words", [
    (None, 1.0, (0.0, 1.0), "mapped takes finite numbers"),
    ("0", 1.0, (0.0, 1.0), "mapped takes finite numbers"),
    (0.0, math.inf, (0.0, 1.0), "mapped takes finite numbers"),
    (0.0, 1.0, (0.0,), "mapped takes finite numbers"),
    (1.0, 0.0, (0.0, 1.0), "cannot map onto [1, 0]: reversed"),
    (-1e308, 1e308, (0.0, 1.0), "a span beyond float64's range"),
])
def test_mapping_onto_what_is_no_span_is_refused(lo, hi, src, words):
    # Each came out as Python's TypeError, an IndexError, or a message about the points' order or a NaN.
    with pytest.raises(InputError, match=re.escape(words)):
        TransferFunction([(0.0, 0.5), (1.0, 1.0)]).mapped(lo, hi, src=src)


@pytest.mark.parametrize("call, words", [
    (lambda tf: tf.lookup("abc"), "lookup takes real numbers"),
    (lambda tf: tf.opacity(["1", "2"]), "opacity takes real numbers"),
    (lambda tf: tf.color(np.array([1 + 1j])), "color takes real numbers"),
    (lambda tf: tf.lookup(np.array(["2020-01-01"], "M8[D]")), "lookup takes real numbers"),
    (lambda tf: tf.opacity([True, False]), "opacity takes real numbers"),
    (lambda tf: tf.nonzero_in("a", "b"), "nonzero_in takes real numbers"),
    (lambda tf: tf.nonzero_in(np.ones(3), np.ones(4)), "of shapes (3,) and (4,) do not broadcast together"),
    (lambda tf: tf.nonzero_in(0, 1, rounding="x"), "rounding must be a fraction from 0 to below 1, got 'x'"),
    (lambda tf: tf.nonzero_in(0, 1, rounding=1.5), "rounding must be a fraction from 0 to below 1, got 1.5"),
])
def test_lookups_and_range_queries_take_real_numbers(call, words):
    # NumPy read text as numbers or raised its own ValueError, dropped an imaginary part, and
    # counted a date's days.
    with pytest.raises(InputError, match=re.escape(words)):
        call(TransferFunction([(0.0, 0.0), (3.0, 0.8), (6.0, 0.1)], [(0.0, 1, 0, 0), (6.0, 0, 0, 1)]))


def test_rounding_widens_a_range_by_its_largest_magnitude():
    # [0, 100] widened by 1e-6 of 100 reaches 100.0001, past the support's start at 100.00005;
    # by 1e-6 of its smaller end (0) it would not.
    tf = TransferFunction([(100.00005, 0.0), (101.0, 0.5)])
    assert not tf.nonzero_in(0.0, 100.0)
    assert tf.nonzero_in(0.0, 100.0, rounding=1e-6)
    # Mirrored: the largest magnitude at the bottom widens the top too (a range from -888 to
    # 0.001 lost samples an interpolation rounded past its top: parc 0.0 where brute drew 0.8).
    tf = TransferFunction([(0.00005, 0.0), (1.0, 0.5)])
    assert not tf.nonzero_in(-100.0, 0.0)
    assert tf.nonzero_in(-100.0, 0.0, rounding=1e-6)


def test_rounding_of_16_bit_ranges_is_a_fraction_of_the_types_largest_magnitude():
    # int16's largest magnitude is 32768: with rounding 1e-3, [0, 100] reaches 132.768, past a
    # support starting at 132.7675; 1e-3 of 32767 (132.767) falls short.
    tf = TransferFunction([(132.7675, 0.0), (133.0, 0.5)])
    assert tf.nonzero_in(np.int16(0), np.int16(100), rounding=1e-3)
    assert not tf.nonzero_in(np.int16(0), np.int16(99), rounding=1e-3)


def test_functions_differing_only_in_colour_are_not_equal():
    op = [(0.0, 0.0), (1.0, 0.5)]
    assert TransferFunction(op, [(0.0, 1, 0, 0)]) == TransferFunction(op, [(0.0, 1, 0, 0)])
    assert TransferFunction(op, [(0.0, 1, 0, 0)]) != TransferFunction(op, [(0.0, 0, 1, 0)])
    assert TransferFunction(op, [(0.0, 1, 0, 0)]) != TransferFunction(op, [(0.5, 1, 0, 0)])


@pytest.mark.parametrize("name", ["greyscale", "viridis"])
def test_the_ramp_presets_end_at_opacity_0_1_for_compositing(name):
    # README: the ramp presets "end at opacity 0.1 for compositing", transparent below 10% of the range.
    tf = preset(name, (0.0, 200.0))
    np.testing.assert_array_equal(tf.opacity([20.0, 200.0, 300.0]), [0.0, 0.1, 0.1])
    assert tf.opacity(110.0) == pytest.approx(0.05, abs=1e-15)


def test_ct_skin_bone_veils_the_skin_at_0_024():
    # The presets' notes: 0.08 makes a few voxels of skin a visible shell, 0.024 (skin in
    # ct_skin_bone) a veil; the bone is the same as ct_bone's.
    for v in (600.0, 700.0, 850.0):
        assert preset("ct_skin").opacity(v) == pytest.approx(0.08, abs=1e-15)
        assert preset("ct_skin_bone").opacity(v) == pytest.approx(0.024, abs=1e-15)
    np.testing.assert_array_equal(preset("ct_skin_bone").opacity([1500.0, 3000.0]),
                                  preset("ct_bone").opacity([1500.0, 3000.0]))


@pytest.mark.parametrize("value", [1e17, -3e20, 0.0])
def test_a_ramp_over_a_one_value_range_keeps_its_ramp(value):
    # A one-value range is widened to a span float64 can hold above the value: at 1e17,
    # value + 1 is the value itself.
    tf = preset("greyscale", (value, value))
    x = tf.opacity_points[:, 0]
    assert x[0] == value and x[-1] > value and len(np.unique(x)) == 3
    assert tf.opacity(value) == 0.0 and tf.opacity(x[-1]) == 0.1


@pytest.mark.parametrize("value", [5.0, 1e17, -3e20, 0.0])
@pytest.mark.parametrize("mode", ["composite", "mip"])
def test_a_paraview_map_of_one_colour_point_ramps_as_a_preset_over_one_value(tmp_path, value, mode):
    # No Points: the ramp over a one-value span, by hand: value + (0, 0.1, 1) * max(1, 1e-9 |value|).
    path = tmp_path / "one.json"
    path.write_text(json.dumps({"RGBPoints": [value, 1, 0, 0]}))
    tf = load_transfer_function(path, mode=mode)
    width = max(1.0, 1e-9 * abs(value))
    top = T.RAMP_OPACITY if mode == "composite" else 1.0
    np.testing.assert_allclose(tf.opacity_points, [[value, 0.0], [value + 0.1 * width, 0.0], [value + width, top]],
                               rtol=1e-15, atol=0)
    assert tf.opacity_points.tolist() == preset("greyscale", (value, value), mode).opacity_points.tolist()


def test_a_paraview_list_uses_its_first_map(tmp_path):
    maps = [{"Name": "first", "RGBPoints": [0, 1, 0, 0, 10, 1, 0, 0], "Points": [0, 0.5, 0.5, 0, 10, 0.5, 0.5, 0]},
            {"Name": "second", "RGBPoints": [0, 0, 0, 1, 10, 0, 0, 1], "Points": [0, 0.2, 0.5, 0, 10, 0.2, 0.5, 0]}]
    path = tmp_path / "two.json"
    path.write_text(json.dumps(maps))
    tf = load_transfer_function(str(path))
    assert tf.name == "first"
    np.testing.assert_array_equal(tf.lookup(5.0), [1.0, 0.0, 0.0, 0.5])


# (value, r, g, b, alpha) worked out by hand from each CT preset's points: opacity (400, 0),
# (600, 0.08), (850, 0.08), (1000, 0) for the skin, (1200, 0), (1500, 0.4), (2000, 0.7) for the
# bone, the skin's times 0.3 in ct_skin_bone; colours (400, .70 .40 .30), (700, .93 .68 .55),
# (1000, 1 .82 .70) and (1200, .90 .80 .65), (1600, 1 .96 .88), (2500, white); constant outside.
CT_BY_HAND = {
    "ct_skin": [(300.0, 0.70, 0.40, 0.30, 0.0), (550.0, 0.815, 0.54, 0.425, 0.06),
                (700.0, 0.93, 0.68, 0.55, 0.08), (925.0, 0.9825, 0.785, 0.6625, 0.04),
                (1000.0, 1.0, 0.82, 0.70, 0.0), (1100.0, 1.0, 0.82, 0.70, 0.0)],
    "ct_bone": [(1100.0, 0.90, 0.80, 0.65, 0.0), (1350.0, 0.9375, 0.86, 0.73625, 0.2),
                (1500.0, 0.975, 0.92, 0.8225, 0.4), (1825.0, 1.0, 0.97, 0.91, 0.595),
                (2000.0, 1.0, 0.96 + 0.04 * 4 / 9, 0.88 + 0.12 * 4 / 9, 0.7),
                (2050.0, 1.0, 0.98, 0.94, 0.7), (3000.0, 1.0, 1.0, 1.0, 0.7)],
    "ct_skin_bone": [(300.0, 0.70, 0.40, 0.30, 0.0), (550.0, 0.815, 0.54, 0.425, 0.018),
                     (925.0, 0.9825, 0.785, 0.6625, 0.012), (1100.0, 0.95, 0.81, 0.675, 0.0),
                     (1350.0, 0.9375, 0.86, 0.73625, 0.2), (1825.0, 1.0, 0.97, 0.91, 0.595),
                     (3000.0, 1.0, 1.0, 1.0, 0.7)],
}


@pytest.mark.parametrize("name", sorted(CT_BY_HAND))
def test_ct_presets_look_up_what_their_points_give_by_hand(name):
    table = np.array(CT_BY_HAND[name])
    np.testing.assert_allclose(preset(name).lookup(table[:, 0]), table[:, 1:], rtol=0, atol=1e-12)


def test_the_viridis_knots_are_32_samples_spread_evenly_over_its_256():
    # Even spacing keeps the linear interpolation between them within 0.0065 of the full table.
    assert [k[0] for k in T.VIRIDIS] == [round(n * 255 / 31) for n in range(32)]


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_a_data_range_whose_span_overflows_is_refused_as_such(name):
    # Each end is finite, their difference is not: mapping onto it would give NaN points, and the
    # CT presets, which do not use the range, would take it.
    with pytest.raises(InputError, match=f"{name}: data range must be finite"):
        preset(name, (-1e308, 1e308))


def test_a_point_with_a_number_too_many_is_refused():
    # [value, alpha, extra] is no opacity point: the extra number would be dropped unsaid.
    for kwargs, part in ((dict(opacity=[[0, 0.5, 0.7]]), "opacity point 1: expected [value, alpha]"),
                         (dict(opacity=[[0, 0.5]], color=[[0, 1, 1, 1, 1]]), "color point 1: expected [value, r, g, b]")):
        with pytest.raises(InputError, match=re.escape(part)):
            TransferFunction(**kwargs)


@pytest.mark.parametrize("name", ["", "CT_SKIN", "ct_skin "])
def test_a_preset_name_that_is_none_of_them_is_refused_with_the_list(name):
    with pytest.raises(InputError, match="unknown transfer function preset .*known: ct_skin, ct_bone"):
        preset(name)


def test_a_transfer_function_is_fixed_once_built():
    # Renderers key their caches (skip tables, classifications) on it, as on volumes and scenes.
    tf = TransferFunction([[0.0, 0.0], [1.0, 0.5]], name="ramp")
    for name, value in (("name", "other"), ("made_from", ("ct_bone", (0.0, 1.0), "composite")),
                        ("_op_y", np.zeros(2))):
        with pytest.raises(AttributeError, match=rf"^TransferFunction\.{name} cannot change once built; "
                                                 r"make a new TransferFunction$"):
            setattr(tf, name, value)
    assert tf.name == "ramp" and tf.made_from is None and tf.opacity(np.array([1.0]))[0] == 0.5
