"""The hard-ray suite's inputs are the hard cases they are named for.

`test_hard_rays` checks the caster on the rays `raycast.hardcases` builds; these check that
the rays are what their category says. A generator that drifted (grazing rays no longer
tangent, rays no longer through the dyadic point whose value is the isovalue) would leave
`test_hard_rays` green while the suite no longer tested its hard case.

Truth: analytic. The scenes are exact-trilinear fields ``F`` with known coefficients
(`raycast.hardfields.field_value`, `field_grad`); the point each batch is aimed at is
recovered as the least-squares meeting point of its rays, independently of the generator.
"""
import numpy as np
import pytest

from raycast.hardcases import hard_batches
from raycast.hardfields import field_grad, field_value


def _meeting_point(o, d):
    """The point nearest to every line ``o + t d`` (least squares), and its largest distance to them."""
    eye = np.eye(3)
    a = sum(eye - np.outer(x, x) for x in d)
    b = sum((eye - np.outer(x, x)) @ p for p, x in zip(o, d))
    q = np.linalg.solve(a, b)
    off = [np.linalg.norm((eye - np.outer(x, x)) @ (q - p)) for p, x in zip(o, d)]
    return q, max(off)


def _batches(category, n=600):
    out = [b for b in hard_batches(category, n, seed=3) if len(b) >= 2]
    assert out
    return out


@pytest.mark.parametrize("category", ["grazing", "face-edge-vertex"])
def test_rays_of_a_batch_meet_at_a_point_on_the_level_set(category):
    checked = 0
    for b in _batches(category):
        if np.linalg.matrix_rank(np.array(b.dirs)) < 2:
            continue                                    # parallel rays meet nowhere in particular
        q, spread = _meeting_point(b.origins, b.dirs)
        h = float(np.min(b.scene.spacing))
        assert spread <= 1e-9 * h, (b.scene.name, spread)
        idx = (q - b.scene.origin) / b.scene.spacing
        value = field_value(b.scene.coeffs, *idx)
        g = np.array(field_grad(b.scene.coeffs, *idx)) / b.scene.spacing
        scale = np.abs(b.scene.data.astype(np.float64) - b.isos[0]).max() + abs(b.isos[0])
        assert abs(value - b.isos[0]) <= 1e-9 * scale + 1e-9 * h * np.linalg.norm(g), (b.scene.name, value, b.isos[0])
        checked += 1
    assert checked > 20


def test_grazing_rays_are_tangent_to_the_level_set():
    checked = 0
    for b in _batches("grazing"):
        if np.linalg.matrix_rank(np.array(b.dirs)) < 2:
            continue
        q, _ = _meeting_point(b.origins, b.dirs)
        idx = (q - b.scene.origin) / b.scene.spacing
        g = np.array(field_grad(b.scene.coeffs, *idx)) / b.scene.spacing     # world gradient
        gn = np.linalg.norm(g)
        assert gn > 0
        for d in b.dirs:
            assert abs(g @ d) <= 1e-9 * gn, (b.scene.name, g @ d / gn)
            checked += 1
    assert checked > 100
