"""Speed against error: supercell size, sample step, cubic root finder, sample storage precision.

Each sweep varies one choice on one scene and reports what it costs and
what it changes in the image, so a choice is read off a chart rather than
argued:

* *supercell size*: polygons, OpenGL time, cells walked and total time of
  `parc`, and its error against `brute` (zero: PARC is exact at any size);
* *sample step*: time of `brute` and `parc` against the error to a
  reference at a quarter of the finest step (`parc.comparison.step_sweep`);
* *root finder*: `parc.rootstudy` on the hard-ray suite: nanoseconds per
  solve against the largest error to mpmath, and failures;
* *storage precision*: the caster computes in float64 whatever the
  volume's type; what a volume stored as float32 instead of float64 (or
  its native integers) costs and changes, on a CT and on a float64
  exact-trilinear field.
"""
from __future__ import annotations

import numpy as np

from data_tools import Volume
from data_tools.volume import hand_over
from data_tools.synthetic import trilinear_field

from ..camera import Camera
from ..comparison import compare, image_error, step_sweep
from ..renderer import render
from ..rootstudy import root_study
from ..scene import Isosurface, Scene
from . import scenes
from .tables import work_maps


def supercell_sweep(suite, progress):
    """`parc` at each supercell size (and the cost model's choice) on the CT skin isosurface."""
    scene, source = scenes.ct_iso(suite.parker_size, 600.0, suite.data_dir, suite.small_volumes)
    labels = [f"parc:{s:g}" for s in suite.supercells]
    options = {lab: {"supercell": s} for lab, s in zip(labels, suite.supercells)}
    rows = compare(scene, methods=["brute", "parc"] + labels, options=options, repeats=suite.repeats,
                   progress=lambda m: progress(f"supercell sweep: {m}"))
    out = []
    for r in rows:
        ph = r["phases"]
        sc = r["supercell"]
        out.append({"method": r["method"], "supercell": "x".join(f"{v:g}" for v in sc) if sc else "-",
                    "model": r["method"] == "parc", "polygons": r["polygons"],
                    "opengl_seconds": sum(ph.get(k, 0.0) for k in ("classify", "proxy", "raster")),
                    "raster_seconds": ph.get("raster", 0.0),
                    "cells_per_pixel": r["cells_visited"] / max(r["pixels"], 1),
                    "seconds": r["seconds"], "speedup": r["speedup"],
                    "hit_mismatches": r["hit_mismatches"], "max_depth_cells": r["max_depth_cells"],
                    "max_color": r["max_color"]})
    progress("supercell sweep: cells visited per pixel")
    return {"source": source, "size": suite.parker_size, "isovalue": 600.0, "rows": out,
            "work": work_maps(scene, "cells_visited")}


def step_size_sweep(suite, progress):
    """`brute` and `parc` per sample step on the CT translucent, against a fine-step reference."""
    scene, source = scenes.ct_translucent(suite.sizes[0], suite.data_dir, suite.small_volumes)
    h = float(min(scene.volumes[0].volume.spacing))
    steps = [f * h for f in suite.steps]
    rows = step_sweep(scene, steps, repeats=suite.repeats, progress=lambda m: progress(f"step sweep: {m}"))
    return {"source": source, "size": suite.sizes[0], "reference_step": min(steps) / 4, "rows": rows}


def root_finders(suite, progress):
    """`parc.rootstudy` rows: ns per solve, max error to mpmath, failures, per finder."""
    progress("root finders: hard-ray suite and its mpmath truth")
    rows = root_study(quick=suite.roots_quick, n=suite.roots_n, progress=lambda m: progress(f"root finders: {m}"))
    return {"rows": rows}


def _as(vol, dtype):
    return Volume(hand_over(vol.data.astype(dtype)), spacing=vol.spacing, origin=vol.origin,
                  name=f"{vol.name} as {dtype}")


def precision(suite, progress):
    """Each volume stored natively, as float64 and as float32: time, and error against the float64 image."""
    n = suite.parker_size
    ct, ct_source = scenes.ct_volume(suite.data_dir, suite.small_volumes)
    # A float64 field whose samples float32 cannot hold exactly: an exact-trilinear one.
    field = trilinear_field(12 if suite.small_volumes else 48, coeffs=(0.3, 1.1, -0.7, 0.9, 0.013, -0.021, 0.017, 7e-4),
                            dtype="float64")
    iso = float(field.meta["iso"])
    cases = [("CT skin 600", ct, 600.0, scenes.ct_iso(n, 600.0, suite.data_dir, suite.small_volumes)[0].camera),
             (f"trilinear field {iso:.4g}", field, iso, Camera.framing(*field.bounds))]
    rows = []
    for name, vol, iso, cam in cases:
        stored = {str(vol.dtype): vol}
        stored.setdefault("float64", _as(vol, np.float64))
        stored.setdefault("float32", _as(vol, np.float32))

        def scene(v):
            return Scene(camera=cam, size=(n, n), volumes=[Isosurface(v, iso)])

        reference = render(scene(stored["float64"]), method="brute")
        for dtype, v in stored.items():
            progress(f"precision: {name}, {dtype}")
            res = compare(scene(v), methods=("brute", "parc"), repeats=suite.repeats)
            run = render(scene(v), method="brute")
            err = image_error(run, reference, float(min(vol.spacing)))
            rows.append({"volume": name, "dtype": dtype, "bytes": int(v.data.nbytes),
                         "brute_seconds": res[0]["seconds"], "parc_seconds": res[1]["seconds"],
                         "parc_vs_brute": res[1]["max_color"],
                         "hit_mismatches": err["hit_mismatches"], "max_depth_cells": err["max_depth_cells"],
                         "max_color": err["max_color"]})
    return {"source": ct_source, "size": n, "rows": rows}
