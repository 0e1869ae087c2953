"""The truth itself (`raycast.mpcubic`, `raycast.hardfields`, `raycast.reference`) on rays and
fields whose answers are known by hand: planes, a hyperbola, hand-factored cubics, exact
differences of a multilinear field.

The caster tests compare the casters with this truth, so a truth that drifts with its casters
(both wrong the same way) or a judge grown loose would pass them all; these pin it to
something simpler still.
"""
import math
from fractions import Fraction

import numpy as np
import pytest

from raycast.hardfields import Scene, field_grad, field_value, sample_field
from raycast.mpcubic import box_intervals, index_ray, mpf, peval, ray_cubic, real_roots
from raycast.reference import EPS, Truth, exact_cell_count, judge


def unit_scene(coeffs, shape=(4, 4, 4)):
    return Scene(coeffs, shape, np.float64, origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0))


def plain(roots):
    return [(float(t), touching) for t, touching in roots]


# ---------------------------------------------------------------- roots

@pytest.mark.parametrize("p, lo, hi, expected", [
    ([3, -4, 1, 0], 0, 4, [(1.0, False), (3.0, False)]),          # (t - 1)(t - 3)
    ([-3, 7, -5, 1], 0, 4, [(1.0, True), (3.0, False)]),          # (t - 1)^2 (t - 3)
    ([-1, 3, -3, 1], 0, 2, [(1.0, True)]),                        # (t - 1)^3
    ([0, 0, 0, 0], 2, 5, [(2.0, True)]),                          # P = 0 everywhere
    ([-1, 1, 0, 0], 0, 1e40, [(1.0, False)]),                     # a long interval's far end
])
def test_real_roots_of_hand_factored_cubics(p, lo, hi, expected):
    assert plain(real_roots([mpf(x) for x in p], mpf(lo), mpf(hi))) == expected


def test_a_triple_root_along_a_diagonal_is_one_root():
    # F = (i - 1)(j - 1)(k - 1) along i = j = k = t: P(t) = (t - 1)^3.
    tr = Truth(unit_scene([-1.0, 1, 1, 1, -1, -1, -1, 1]), np.array([0.0, 0.0, 0.0]), np.array([1.0, 1.0, 1.0]), 0.0)
    assert [(x[0], x[2]) for x in tr.roots] == [(1.0, False)]


def test_box_intervals_of_a_box_longer_on_x_than_on_z():
    # x in [0, 8] on t in [2, 10]; y in [0, 4] and z in [0, 2] hold the ray longer. Pads of 1/2, 1/4
    # and 1/8 cell move the ends by 0.5, 1 and 1 in t: x still sets both.
    sc = unit_scene([0.0, 1, 0, 0, 0, 0, 0, 0], shape=(3, 5, 9))
    O, D = [mpf(-2), mpf(0.5), mpf(0.5)], [mpf(1), mpf(0.25), mpf(0.125)]
    grown, shrunk = box_intervals(sc, O, D, (0.5, 0.25, 0.125))
    assert [float(x) for x in grown] == [1.5, 10.5]
    assert [float(x) for x in shrunk] == [2.5, 9.5]
    grown, shrunk = box_intervals(sc, O, D, (0.0, 0.0, 0.0))
    assert [float(x) for x in grown] == [float(x) for x in shrunk] == [2.0, 10.0]


@pytest.mark.parametrize("y, grown_empty", [(4.75, True), (4.25, False)])
def test_box_intervals_of_a_ray_parallel_to_a_face_outside_the_box(y, grown_empty):
    sc = unit_scene([0.0, 1, 0, 0, 0, 0, 0, 0], shape=(3, 5, 9))
    grown, shrunk = box_intervals(sc, [mpf(-2), mpf(y), mpf(0.5)], [mpf(1), mpf(0), mpf(0.125)],
                                  (0.5, 0.5, 0.5))
    assert (grown[0] > grown[1]) == grown_empty
    assert shrunk[0] > shrunk[1]


def test_a_plane_beside_a_ray_parallel_to_the_box_has_no_root():
    # The ray runs along x at y = -1, outside the box; F = i meets 1.5 at t = 2.5 out there.
    tr = Truth(unit_scene([0.0, 1, 0, 0, 0, 0, 0, 0]), np.array([-1.0, -1.0, 0.5]), np.array([1.0, 0.0, 0.0]), 1.5)
    assert tr.roots == []
    assert judge(tr, math.inf)[0] == "miss"


# ------------------------------------------------------------ the field

def test_the_gradient_is_the_exact_difference_of_the_field():
    # F is linear in each index, so its partial derivative is F(i + 1) - F(i), exactly.
    c = [Fraction(x) for x in (3, -2, 5, 7, -11, 13, 17, -19)]
    rng = np.random.default_rng(1)
    for _ in range(20):
        i, j, k = (Fraction(int(n), 16) for n in rng.integers(-64, 64, 3))
        F = field_value(c, i, j, k)
        diff = (field_value(c, i + 1, j, k) - F, field_value(c, i, j + 1, k) - F, field_value(c, i, j, k + 1) - F)
        assert field_grad(c, i, j, k) == diff


def test_samples_agree_with_the_ray_cubic_through_them():
    # The caster interpolates `data`; the truth builds its cubic from the coefficients. At a
    # sample point both must give the same number.
    sc = Scene([3.0, -2, 5, 7, -11, 13, 17, -19], (4, 5, 6), np.float64, origin=(-4.0, 2.5, 8.0),
               spacing=(0.5, 1.0, 2.0))
    d = np.array([0.25, -0.5, 1.0])
    for i, j, k in [(0, 0, 0), (5, 0, 0), (0, 4, 0), (0, 0, 3), (2, 3, 1), (5, 4, 3), (1, 2, 3)]:
        o = sc.index_to_world((i, j, k))
        O, D = index_ray(sc, o, d)
        assert peval(ray_cubic(sc, O, D, 0.5), mpf(0)) == mpf(float(sc.data[k, j, i])) - mpf(0.5)
        assert sc.data[k, j, i] == 3 - 2 * i + 5 * j + 7 * k - 11 * i * j + 13 * j * k + 17 * k * i - 19 * i * j * k


def test_hi_world_is_the_last_sample():
    sc = Scene([0.0, 1, 0, 0, 0, 0, 0, 0], (4, 5, 6), np.float64, origin=(-4.0, 2.5, 8.0), spacing=(0.5, 1.0, 2.0))
    assert sc.hi_world.tolist() == [-4.0 + 5 * 0.5, 2.5 + 4 * 1.0, 8.0 + 3 * 2.0]


@pytest.mark.parametrize("coeffs", [
    [1 + Fraction(1, 2 ** 60), 1, 0, 0, 0, 0, 0, 0],     # rounds to a float64 whose samples are fine
    [0, 2.0 ** 52, 0, 0, 0, 0, 0, 0],                   # samples past 2^53
])
def test_fields_the_truth_cannot_hold_exactly_are_refused(coeffs):
    with pytest.raises(ValueError):
        Scene(coeffs, (4, 4, 4))


def test_samples_of_a_field_with_a_non_dyadic_coefficient_are_refused():
    with pytest.raises(ValueError):
        sample_field([Fraction(1, 3), 1, 0, 0, 0, 0, 0, 0], (4, 4, 4), np.float64)


# ------------------------------------------------------------ the judge

PLANE = [0.0, 1, 0, 0, 0, 0, 0, 0]                     # F = i, level 1.5: the plane x = 1.5
O_PLANE, D_PLANE = np.array([-1.0, 0.5, 0.75]), np.array([1.0, 0.25, 0.125])   # hits it at t = 2.5


def test_a_plane_hit_is_judged_to_its_tolerance():
    tr = Truth(unit_scene(PLANE), O_PLANE, D_PLANE, 1.5)
    assert len(tr.roots) == 1 and tr.roots[0][0] == 2.5 and tr.roots[0][2]
    assert tr.roots[0][3] == 1e-9 + 4 * EPS * 2.5
    assert judge(tr, 2.5)[0] == "hit"
    assert judge(tr, 2.5 + 1e-7)[::2] == ("FAIL", "inaccurate")       # 100 tolerances late
    assert judge(tr, 2.5 - 2e-9)[0] == "FAIL"                          # early, |P| = 2e-9 > 1e-9 + 10 E
    assert judge(tr, 3.9)[::2] == ("FAIL", "false")                    # 1.4 cells past the root
    assert judge(tr, math.inf)[::2] == ("FAIL", "missed")


def test_the_error_scale_on_a_grid_plane_takes_the_samples_of_both_cells():
    # At t = 2 the ray is at the vertex (1, 1, 1): the cells on both sides hold i = 0, 1, 2, so the
    # largest |sample - 1.5| is 1.5, not the 0.5 of the cell above alone. Just below the plane
    # x = 1 both cells count too.
    tr = Truth(unit_scene(PLANE), O_PLANE, D_PLANE, 1.5)
    assert tr.point(2.0) == [1.0, 1.0, 1.0]
    assert tr.error_scale(2.0) == 64 * EPS * 1.5 + tr.dpos[0]
    assert tr.error_scale(2.0 - 2.0 ** -24) == 64 * EPS * 1.5 + tr.dpos[0]


def test_a_plane_hit_names_its_cell_and_local_coordinates():
    # At t = 2.5 the point is (1.5, 1.125, 1.0625) in index space.
    tr = Truth(unit_scene(PLANE), O_PLANE, D_PLANE, 1.5)
    assert judge(tr, 2.5, (1, 1, 1), (0.5, 0.125, 0.0625))[0] == "hit"
    assert judge(tr, 2.5, (1, 1, 1), (0.5, 0.125 + 1e-6, 0.0625))[::2] == ("FAIL", "cell")
    assert judge(tr, 2.5, (2, 1, 1), (-0.5, 0.125, 0.0625))[::2] == ("FAIL", "cell")


def test_a_root_beyond_the_box_is_no_hit():
    # The ray leaves through y = 3 at t = 0.625; the plane x = 1.5 is crossed at t = 1.
    tr = Truth(unit_scene(PLANE), np.array([0.5, 0.5, 1.0]), np.array([1.0, 4.0, 0.0]), 1.5)
    assert tr.roots == []
    assert judge(tr, 1.0)[::2] == ("FAIL", "false")


def test_roots_at_the_ray_start_and_on_the_box_face_are_optional():
    sc = unit_scene(PLANE)
    at_start = Truth(sc, np.array([1.5, 0.5, 0.5]), D_PLANE, 1.5)
    on_face = Truth(sc, O_PLANE, D_PLANE, 0.0)                     # x = 0 at t = 1, the entry face
    for tr, r in ((at_start, 0.0), (on_face, 1.0)):
        assert [(x[0], x[2]) for x in tr.roots] == [(r, False)]
        assert judge(tr, math.inf)[0] == "optional"
        assert judge(tr, r)[0] == "optional"


def test_a_root_seen_at_a_shallow_angle_far_from_zero_is_required():
    # F = 1000 + i, level 1001.5; the ray climbs x by 0.003 per unit of t, crossing x = 1.5 at
    # t = 2: |P'| = 0.003 against a float error E ~ 64 eps |sample - iso| ~ 3e-14, so dt ~ 1e-11.
    # Measuring |sample| instead of |sample - iso| would be 600 times larger.
    sc = unit_scene([1000.0, 1, 0, 0, 0, 0, 0, 0])
    tr = Truth(sc, np.array([1.5 - 2 * 0.00299072265625, 0.0, 1.25]),
               np.array([0.00299072265625, 1.0, 0.0]), 1001.5)
    (r, dt, required, _), = tr.roots
    assert r == 2.0 and 1e-12 < dt < 1e-10 and required
    assert judge(tr, math.inf)[::2] == ("FAIL", "missed")


def test_the_first_root_of_a_close_resolvable_pair_is_required():
    # F = i j, level 9/4: along this ray P(t) = (0.5 + t)(2.5 + e - t) - 9/4
    # = 1.5 e + e^2 / 4 - (t - 1 - e / 2)^2. With e = 2^-30: two roots 7.5e-5 apart around t = 1,
    # P' ~ 7.5e-5 there (too ill-conditioned to be simple), and a dip of ~1.4e-9 between them, far
    # above float's error: the first must be taken, not the second.
    e = 2.0 ** -30
    tr = Truth(unit_scene([0.0, 0, 0, 0, 1, 0, 0, 0]), np.array([0.5, 2.5 + e, 1.5]), np.array([1.0, -1.0, 0.0]), 2.25)
    (r1, dt1, required, _), (r2, _, _, _) = tr.roots
    u = math.sqrt(e * e / 4 + 1.5 * e)
    assert abs(r1 - (1 + e / 2 - u)) < 1e-12 and abs(r2 - (1 + e / 2 + u)) < 1e-12
    assert dt1 > 1e-10 and required
    assert judge(tr, r1)[0] == "hit"
    assert judge(tr, r2)[::2] == ("FAIL", "wrong")


def test_a_tangency_excuses_hits_near_it_only():
    # F = i j, level 9/4: P(t) = (0.5 + t)(2.5 - t) - 9/4 = -(t - 1)^2, an exact double root.
    tr = Truth(unit_scene([0.0, 0, 0, 0, 1, 0, 0, 0]), np.array([0.5, 2.5, 1.5]), np.array([1.0, -1.0, 0.0]), 2.25)
    assert [(x[0], x[2]) for x in tr.roots] == [(1.0, False)]
    assert judge(tr, 1.0)[0] == "optional"
    assert judge(tr, math.inf)[0] == "optional"
    assert judge(tr, 2.0)[0] == "FAIL"                   # |P| = 1 there


def test_a_plane_seen_from_far_away_is_uncertain_to_float():
    # From 1e7 cells away the float index-space ray is ~1e-9 cells off the exact one: the crossing
    # is not sharp to 1e-10 cells, so a caster may miss it.
    d = np.array([1.0, 0.25, 0.125]) / np.linalg.norm([1.0, 0.25, 0.125])
    tr = Truth(unit_scene(PLANE), np.array([1.5, 1.5, 1.5]) - 1e7 * d, d, 1.5)
    (r, dt, required, _), = tr.roots
    assert dt > 1e-10 and not required
    assert judge(tr, math.inf)[0] == "optional"


# ------------------------------------------------------------ traversal

def test_a_diagonal_through_vertices_counts_each_vertex_once():
    # Enters at the corner (0, 0, 0) at t = 0.5 and crosses the planes 1 and 2 of all three axes
    # together at t = 1.5 and 2.5: 3 cells, 7 steps, nothing near a box end.
    sc = unit_scene(PLANE)
    assert exact_cell_count(sc, np.array([-0.5, -0.5, -0.5]), np.array([1.0, 1.0, 1.0])) == (3, 7, 0)


def test_a_crossing_just_inside_the_entry_is_certain():
    # Enters through x = 0 at t = 0.5; y crosses 1 at 0.5 + 2^-35, x 1 and 2 at 1.5 and 2.5,
    # y 2 at 2.5 + 2^-35, z 1 at 2.8. 2^-35 is far above the 1e-12 rounding of the ends.
    sc = unit_scene(PLANE)
    o = np.array([-0.5, 0.75 - 2.0 ** -36, 0.3])
    assert exact_cell_count(sc, o, np.array([1.0, 0.5, 0.25])) == (6, 6, 0)
