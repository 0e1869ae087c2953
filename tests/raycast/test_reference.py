"""The tests' judge itself (`raycast.reference`): rays whose truth is known without it.

Every caster test trusts its verdicts, so a judge too strict fails good casters and one too
loose passes bad ones; these rays were found judged wrongly by a fuzz against an independent
piecewise truth in mpmath.
"""
import numpy as np
import pytest

from raycast.hardfields import Scene
from raycast.reference import Truth, judge


@pytest.mark.parametrize("distance", [1e3, 1e5, 1e6, 1e7])
def test_a_ray_from_far_away_through_a_box_without_the_level_has_no_root(distance):
    # F = i j >= 0 in the box, the level -1: no root anywhere. From 1e7 cells away the truth
    # reported one at every critical point (its zero test scaled an eye's distance twice),
    # and a caster's hit there was judged optional.
    sc = Scene([0.0, 0, 0, 0, 1.0, 0, 0, 0], (4, 4, 4), np.float64, origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0))
    d = np.array([1.0, -1.0, 0.3]) / np.linalg.norm([1.0, -1.0, 0.3])
    tr = Truth(sc, np.array([1.5, 1.5, 1.5]) - distance * d, d, -1.0)
    assert tr.roots == []
    t_inside = float(tr.outer[0] + tr.outer[1]) / 2
    assert judge(tr, np.inf)[0] == "miss" and judge(tr, t_inside)[0] == "FAIL"


def test_a_close_pair_at_the_entry_face_leaves_its_first_root_optional():
    # F - iso = (i - 2)(1 - 4j - 3k - 3jk): the grid plane x = 2 is part of the level set, and
    # this ray grazes it (dx ~ 1e-8) just where it enters the box. The first root lies 1.3e-9
    # inside the entry face, within its own conditioning (dt 2.2e-6): float cannot tell on
    # which side of the face it is, yet the close-pair rule required it, and a caster taking
    # the second root failed.
    sc = Scene([-6.0, 1.0, 8.0, 6.0, -4.0, 6.0, -3.0, -3.0], (6, 4, 6), np.float64,
               origin=(-5.5, 3.25, 100.0), spacing=(0.7, 1.3, 2.1))
    h = float.fromhex
    o = np.array([h('-0x1.0666655ee1072p+2'), h('0x1.31660a8dc3031p+4'), h('0x1.f655843864fb3p+6')])
    d = np.array([h('-0x1.73d2117b534eep-27'), h('-0x1.0d7e5a3ac8449p-1'), h('-0x1.b355f3fb2c2dap-1')])
    tr = Truth(sc, o, d, -4.0)
    (r1, dt1, required, _), (r2, _, _, _) = tr.roots[:2]
    assert r1 - float(tr.outer[0]) < 16 * dt1            # the situation: the root within its conditioning
    assert not required
    assert judge(tr, r2)[0] == judge(tr, r1)[0] == "optional"
