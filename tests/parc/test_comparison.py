"""`parc.comparison.image_error`: the error figures `parc compare` prints, on images small enough to work out by hand.

Truth: the definitions in the function's docstring, evaluated here on
2x2 renders whose differences are chosen to give round numbers.
"""
import math

import numpy as np
import pytest

from parc import RenderResult
from parc.comparison import image_error


def _result(depth, image):
    return RenderResult(image=np.asarray(image, np.float32), depth=np.asarray(depth, np.float64), stats={})


def test_image_error_by_hand():
    inf = math.inf
    image = np.zeros((2, 2, 4))
    ref = _result([[1.0, 2.0], [inf, 5.0]], image)
    changed = image.copy()
    changed[1, 1, 2] = 0.5            # one channel of sixteen differs by 0.5
    res = _result([[1.5, inf], [3.0, 5.0]], changed)
    err = image_error(res, ref, 0.25)
    # Hit in one image and not in the other: pixel (0, 1) in the reference only, (1, 0) in the result only.
    assert err["hit_mismatches"] == 2
    # Hit in both: |1.5 - 1| = 0.5 world units, two cells of 0.25; |5 - 5| = 0.
    assert err["max_depth_cells"] == 2.0
    assert err["max_color"] == 0.5
    rmse = math.sqrt(0.25 / 16)       # 0.125
    assert err["rmse"] == pytest.approx(rmse, rel=1e-12)
    assert err["psnr"] == pytest.approx(20 * math.log10(1 / rmse), rel=1e-12)     # 18.06 dB


def test_identical_images_have_no_error():
    ref = _result([[1.0, math.inf]], np.full((1, 2, 4), 0.3))
    err = image_error(ref, ref, 1.0)
    assert err == {"hit_mismatches": 0, "max_depth_cells": 0.0, "max_color": 0.0, "rmse": 0.0, "psnr": math.inf}


def test_no_pixel_hit_in_both_has_no_depth_error():
    image = np.zeros((1, 2, 4))
    err = image_error(_result([[1.0, math.inf]], image), _result([[math.inf, 7.0]], image), 1.0)
    assert err["hit_mismatches"] == 2 and err["max_depth_cells"] == 0.0
