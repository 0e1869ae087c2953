"""Trilinear sampling (`raycast.composite.interpolate`) against exact rational arithmetic, and the
shading normals' gradient (`raycast.shade.trilinear_gradient`) against a field's own.

The exact interpolant of a cell never leaves its corners' range, and the
classification of cells for a transfer function relies on that: the
float64 nested lerps may leave it only by the rounding the classification
widens ranges by (`INTERP_ROUNDING` of the corners' magnitude).
"""
from fractions import Fraction

import numpy as np

from raycast.composite import INTERP_ROUNDING, interpolate


def _exact(c, u, v, w):
    """Trilinear value of corners ``c[k, j, i]`` at (u, v, w), in exact fractions."""
    u, v, w = Fraction(u), Fraction(v), Fraction(w)
    total = Fraction(0)
    for k, wk in ((0, 1 - w), (1, w)):
        for j, wj in ((0, 1 - v), (1, v)):
            for i, wi in ((0, 1 - u), (1, u)):
                total += Fraction(float(c[k, j, i])) * wk * wj * wi
    return total


def test_samples_stay_within_the_rounding_of_the_corner_range():
    # Corners mixing 1, tiny negatives and others, sampled on faces and
    # inside: the recipe for lerps whose inexact differences overshoot
    # (about 1 sample in 1,000 does, by a few 2^-53).
    rng = np.random.default_rng(11)
    outside = 0
    for n in range(20000):
        pick = rng.random(8)
        c = np.where(pick < 0.3, -rng.random(8) * 2.0 ** -50,
                     np.where(pick < 0.6, 1.0, rng.random(8))).reshape(2, 2, 2)
        u, v, w = (1.0 if rng.random() < p else float(rng.random()) for p in (0.5, 0.3, 0.1))
        val = interpolate(c, u, v, w, 0, 0, 0)[0]
        pad = INTERP_ROUNDING * np.abs(c).max()
        assert c.min() - pad <= val <= c.max() + pad, (n, c.ravel().tolist(), u, v, w, val)
        assert abs(Fraction(val) - _exact(c, u, v, w)) <= Fraction(2.0 ** -50), n
        outside += not c.min() <= val <= c.max()
    assert outside > 0          # the case the widening is for does occur


def test_float32_corners_are_read_in_float64():
    c = np.array([-0.6 * 2.0 ** -23, 1.0] * 4, np.float32).reshape(2, 2, 2)   # x = 0 and x = 1
    val = interpolate(c, 1.0, 0.5, 0.5, 0, 0, 0)[0]
    assert val == 1.0                     # in float32, 1 - c[0] rounds up and the sample overshoots
    big = np.zeros((2, 2, 2), np.float32)
    big[1, 1, 0], big[1, 1, 1] = -3e38, 3e38
    val = interpolate(big, 0.3, 1.0, 1.0, 0, 0, 0)[0]
    assert val == _exact(big, 0.3, 1.0, 1.0) or abs(val - float(_exact(big, 0.3, 1.0, 1.0))) <= 1e23
    assert np.isfinite(val)


def test_a_cell_away_from_the_origin_interpolates_from_its_own_corners():
    # F = 0.3 x - 1.1 y + 2 z + 0.05 x y z is trilinear, so its samples give it back exactly
    # anywhere, with local coordinates measured from the cell's own corner.
    z, y, x = np.mgrid[0:4, 0:5, 0:6].astype(np.float64)
    data = 0.3 * x - 1.1 * y + 2.0 * z + 0.05 * x * y * z
    rng = np.random.default_rng(3)
    for _ in range(50):
        i, j, k = int(rng.integers(5)), int(rng.integers(4)), int(rng.integers(3))
        px, py, pz = i + rng.random(), j + rng.random(), k + rng.random()
        val, u, v, w = interpolate(data, px, py, pz, i, j, k)
        assert (u, v, w) == (px - i, py - j, pz - k)
        assert abs(val - (0.3 * px - 1.1 * py + 2.0 * pz + 0.05 * px * py * pz)) <= 1e-12


def test_gradient_is_the_world_gradient_of_a_trilinear_field_on_an_anisotropic_grid():
    # F(X, Y, Z) = 0.3 X - 1.1 Y + 2 Z + 0.05 X Y Z is trilinear in world coordinates, hence in
    # each cell's local ones: the interpolant is F itself, and its gradient F's, whatever the spacing.
    from raycast.shade import trilinear_gradient
    spc = np.array([1.0, 2.0, 0.5])
    z, y, x = np.mgrid[0:4, 0:5, 0:6].astype(np.float64)
    X, Y, Z = x * spc[0], y * spc[1], z * spc[2]
    data = 0.3 * X - 1.1 * Y + 2.0 * Z + 0.05 * X * Y * Z
    rng = np.random.default_rng(5)
    for _ in range(200):
        i, j, k = int(rng.integers(5)), int(rng.integers(4)), int(rng.integers(3))
        u, v, w = rng.random(3)
        X, Y, Z = (i + u) * spc[0], (j + v) * spc[1], (k + w) * spc[2]
        want = (0.3 + 0.05 * Y * Z, -1.1 + 0.05 * X * Z, 2.0 + 0.05 * X * Y)
        np.testing.assert_allclose(trilinear_gradient(data, i, j, k, u, v, w, spc), want, rtol=1e-12, atol=1e-12)
