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


def test_an_image_darker_and_nearer_than_the_reference_has_the_same_error():
    # Errors are magnitudes: a result below the reference counts as much as one above it.
    inf = math.inf
    image = np.full((2, 2, 4), 0.75)
    ref = _result([[1.0, 2.0], [inf, 5.0]], image)
    darker = image.copy()
    darker[1, 1, 2] = 0.25
    err = image_error(_result([[0.5, 2.0], [inf, 5.0]], darker), ref, 0.25)
    assert err["max_depth_cells"] == 2.0 and err["max_color"] == 0.5
    assert err["rmse"] == pytest.approx(math.sqrt(0.25 / 16), rel=1e-12)


def test_identical_images_have_no_error():
    ref = _result([[1.0, math.inf]], np.full((1, 2, 4), 0.3))
    err = image_error(ref, ref, 1.0)
    assert err == {"hit_mismatches": 0, "max_depth_cells": 0.0, "max_color": 0.0, "rmse": 0.0, "psnr": math.inf}


def test_no_pixel_hit_in_both_has_no_depth_error():
    image = np.zeros((1, 2, 4))
    err = image_error(_result([[1.0, math.inf]], image), _result([[math.inf, 7.0]], image), 1.0)
    assert err["hit_mismatches"] == 2 and err["max_depth_cells"] == 0.0


def test_a_rows_timings_come_from_its_median_run(monkeypatch):
    """Renders of scripted lengths on a clock of their own: the row's time is each method's
    median, its phases and OpenGL share the median run's (raster and raster_bits both), the
    rounds' ratios give the spread, and a scene whose volumes have different supercells has
    no one size."""
    import parc.comparison as comparison
    from data_tools.synthetic import blobs
    from parc import Camera, Isosurface, Scene
    clock = [0.0]

    class Clock:
        @staticmethod
        def perf_counter():
            return clock[0]

    walls = {"brute": [9.0, 4.0, 2.0, 3.0], "parc": [9.0, 1.0, 0.25, 0.5]}     # a warm-up, then 3 rounds

    def scripted(scene, method="brute", **options):
        wall = walls[method].pop(0)
        clock[0] += wall
        seconds = {"total": wall, "cast": wall / 2, "raster": wall / 4, "raster_bits": wall / 8}
        stats = {"seconds": seconds, "cells_visited": 1, "cubic_solves": 0, "hits": 0, "pixels": 64,
                 "polygons": 0, "supercell": None, "volumes": [{"supercell": 2.0}, {"supercell": 4.0}]}
        return RenderResult(image=np.zeros((8, 8, 4), np.float32), depth=np.full((8, 8), np.inf), stats=stats)

    monkeypatch.setattr(comparison, "time", Clock)
    monkeypatch.setattr(comparison, "render", scripted)
    vol = blobs(6, seed=1)
    scene = Scene(camera=Camera.framing(*vol.bounds), size=(8, 8), volumes=[Isosurface(vol, 100.5)])
    brute, parc_row = comparison.compare(scene, methods=("brute", "parc"), repeats=3)
    assert brute["seconds"] == 3.0 and parc_row["seconds"] == 0.5
    assert parc_row["phases"]["total"] == 0.5 and parc_row["phases"]["raster_bits"] == 0.0625
    assert parc_row["opengl_share"] == pytest.approx(0.375)
    assert parc_row["speedup"] == 6.0
    assert (parc_row["speedup_low"], parc_row["speedup_high"]) == (4.0, 8.0)       # 4/1, 2/0.25, 3/0.5
    assert parc_row["supercell"] is None and parc_row["supercells"] == [2.0, 4.0]
