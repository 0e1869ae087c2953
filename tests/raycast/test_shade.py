"""Blinn-Phong terms (`raycast.shade.blinn_phong`) against the model written out in NumPy.

Truth: diffuse ``kd max(n.l, 0)``, specular ``ks (n.h / |h|)^s`` with the
half vector ``h = l + v``, zero where the light is behind the surface, the
normal turned towards the viewer first (two-sided lighting).
"""
import numpy as np
import pytest

from raycast.shade import blinn_phong, power

MATERIAL = np.array([0.1, 0.7, 0.5, 8.0])


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def _model(n, v, l, material):
    if n @ v < 0:
        n = -n
    ndl = n @ l
    if ndl <= 0:
        return 0.0, 0.0
    h = _unit(l + v)
    return material[1] * ndl, material[2] * max(n @ h, 0.0) ** material[3]


def test_light_and_eye_along_the_normal_give_full_diffuse_and_specular():
    z = np.array([0.0, 0.0, 1.0])
    assert blinn_phong(*z, *z, *z, MATERIAL) == pytest.approx((0.7, 0.5), rel=1e-15)


def test_the_highlight_lies_halfway_between_light_and_eye():
    # Light and eye mirrored about the normal: the half vector is the normal, a full highlight;
    # turn the normal away from the half vector by 30 degrees and it falls to cos(30)^8.
    v = _unit([1.0, 0.0, 1.0])
    l = _unit([-1.0, 0.0, 1.0])
    diffuse, spec = blinn_phong(0.0, 0.0, 1.0, *v, *l, MATERIAL)
    assert (diffuse, spec) == pytest.approx((0.7 * np.sqrt(0.5), 0.5), rel=1e-14)
    n = _unit([np.sin(np.radians(30)), 0.0, np.cos(np.radians(30))])
    assert blinn_phong(*n, *v, *l, MATERIAL)[1] == pytest.approx(0.5 * np.cos(np.radians(30)) ** 8, rel=1e-13)


@pytest.mark.parametrize("seed", range(3))
def test_random_directions_match_the_model(seed):
    rng = np.random.default_rng(seed)
    lit = 0
    for _ in range(500):
        n, v, l = (_unit(rng.normal(size=3)) for _ in range(3))
        material = np.array([0.1, rng.uniform(0.2, 1), rng.uniform(0, 1), rng.choice([1.0, 5.0, 32.0, 7.5])])
        want = _model(n, v, l, material)
        lit += want[0] > 0
        assert blinn_phong(*n, *v, *l, material) == pytest.approx(want, rel=1e-12, abs=1e-15)
    assert 100 < lit < 400          # lit and unlit both, from either side


def test_power_is_pow():
    for e in (0.0, 1.0, 2.0, 7.0, 40.0, 1024.0, 2.5, 1025.0):
        for x in (0.0, 0.3, 0.999, 1.0):
            assert power(x, e) == pytest.approx(x ** e, rel=1e-13, abs=1e-300)
