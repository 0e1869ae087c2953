"""The supercell size PARC uses when none is given: a measured cost model.

About this technique
--------------------
Sobierajski & Avila (1995, §3) group cells into supercells so that the
proxy has fewer polygons; the price is a longer walk through the empty
cells inside possibly contributing supercells. Which size is best depends
on the surface and on the machine, so `choose_supercell` estimates the
render time of each candidate size from what it costs here:

- **Rasterization** pays a fixed cost per frame (clear, fill, read-back)
  and a cost per polygon drawn (geometry shader, triangle setup on
  llvmpipe). The proxy merges coplanar faces (`parc.proxy.build_proxy`),
  so the polygons drawn are far fewer than the supercell faces: the model
  counts the strips the merge's first stage makes (`count_face_strips`),
  an upper bound on the rectangles that costs a few array operations
  instead of a merge. On a flat surface the difference decides the size:
  the Fig. 13 floor at 2-cell supercells has 16,876 supercell faces, 508
  strips and 12 rectangles.
- **Casting** pays per ray that reaches the PC region and per cell
  walked; the cells walked grow with the supercell edge.
"""
from __future__ import annotations

import math
import os

import numpy as np

from .classify import MAX_SUPERCELLS, _axis_edges, _size_triple
from .proxy import outer_face_masks

#: Cost model constants, measured on this project's development machine
#: (2 x86 cores, Mesa llvmpipe 22.3 / LLVM 15). Rasterization
#: (`parc.raster.raster_segments`, median of 5): least squares over the CT
#: head skin and bone, neghip, and the Fig. 13 neuron and floor, supercells
#: 1-8, at 300^2, 512^2 and 800^2 (90 frames; median error 21%): 2.0 ms per
#: 512x512 frame plus 0.43 us per strip (`count_face_strips`). The
#: per-frame cost is the same for every size and does not change the choice.
RASTER_FIXED_S = 2.0e-3
RASTER_PER_STRIP_S = 0.43e-6
#: Numba caster with segments, per core: per ray that reaches the PC region
#: (setup, the cubic at the hit) and per cell walked. Fitted to the CT head
#: skin at 512x512 (`parc compare --sweep-supercell 2,3,4,6`: cast 14.1,
#: 15.5, 17.3, 19.1 ms on 2 cores), with the model's rays (half the pixels)
#: and cells per ray.
CAST_PER_RAY_S = 0.16e-6
CAST_PER_CELL_S = 6.4e-9
#: Cells walked per ray that reaches a PC supercell: ``WALK_BASE +
#: WALK_PER_CELL * m`` for supercells of ``m`` cells: the walk from the
#: supercell's boundary to the surface grows with the supercell. Fitted:
#: sphere 3.2 + 1.7 m, CT head skin 3.5 + 4.3 m (noisier, many layers).
WALK_BASE = 3.3
WALK_PER_CELL = 3.0

#: Supercell sizes `choose_supercell` considers by default.
CANDIDATE_SIZES = (1, 2, 3, 4, 6, 8)


def count_outer_faces(pc):
    """Faces between a PC supercell and an empty one or the volume boundary."""
    return face_counts(pc)[0]


def face_counts(pc):
    """``(faces, strips)``: the outer faces (`count_outer_faces`) and their strips (`count_face_strips`), in one pass."""
    faces = strips = 0
    for a, below, above in outer_face_masks(pc):
        uax = 2 - (a + 1) % 3
        rest = tuple(slice(1, None) if d == uax else slice(None) for d in range(3))
        prev = tuple(slice(None, -1) if d == uax else slice(None) for d in range(3))
        for mask in (below, above):
            n = int(np.count_nonzero(mask))
            # Every face starts a strip unless its neighbour before it along u is a face too.
            faces += n
            strips += n - int(np.count_nonzero(mask[rest] & mask[prev]))
    return faces, strips


def count_face_strips(pc):
    """Strips of outer faces: runs along each face's ``u`` axis, as `parc.proxy` merges them first.

    Faces perpendicular to axis ``a`` run along ``u = (a + 1) % 3``; a strip
    is a maximal run of faces of one orientation in one plane and row. The
    proxy then merges equal strips into rectangles, so its polygon count is
    at most this.
    """
    return face_counts(pc)[1]


def choose_supercell(index, iso=None, *, pixels=512 * 512, rays=None, cores=None,
                     candidates=CANDIDATE_SIZES, classify=None):
    """Pick a supercell size for an isovalue (or any classification) by estimated render time.

    Parameters
    ----------
    index : VolumeIndex
    iso : float, optional
        The isovalue; or give ``classify``.
    classify : callable(size) -> bool array, optional
        The possibly contributing supercells of a size (e.g. for a transfer
        function), used instead of ``index.classify(iso, size)``.
    pixels : int, default 512*512
        Image size in pixels.
    rays : int or None
        Rays expected to reach the PC region; default half the pixels.
    cores : int or None
        Cores the caster runs on; default ``os.cpu_count()``.
    candidates : sequence of sizes
        Cubic sizes (cells per supercell edge) to compare.

    Returns
    -------
    size : float
        The candidate with the least estimated time, among those that give
        at most `parc.classify.MAX_SUPERCELLS` supercells for this volume.
    table : list of dict
        Per candidate: ``size``, ``supercells``, ``pc_supercells``,
        ``faces`` (outer faces before merging), ``strips``, ``raster_s``,
        ``cells``, ``cast_s``, ``total_s``.

    Notes
    -----
    ``raster_s = RASTER_FIXED_S * pixels / 512^2 + RASTER_PER_STRIP_S *
    strips``; ``cast_s = rays * (CAST_PER_RAY_S + (WALK_BASE +
    WALK_PER_CELL m) CAST_PER_CELL_S) / cores``. Small supercells cost
    polygons, large ones cells walked through their empty parts. The
    constants were measured on one machine (see the module constants); the
    model ranks sizes, it does not predict times elsewhere. Measured there
    (raster + cast, 2 cores, median of 5): CT head skin at 512x512 picks 6
    (2: 37 ms, 3: 30, 4: 29, 6: 26); the Fig. 13 floor at 600x600 picks 2,
    where counting unmerged faces had picked 3 (floor alone: 2: 27.5 ms,
    3: 31-35).
    """
    cores = cores or os.cpu_count() or 1
    rays = pixels // 2 if rays is None else rays
    table = []
    dims = index.volume.dims
    for m in candidates:
        if math.prod(len(_axis_edges(n, c)) - 1 for n, c in zip(dims, _size_triple(m))) > MAX_SUPERCELLS:
            continue        # too fine to classify for this volume (a 1734-slice CT at 1 cell)
        pc = classify(m) if classify is not None else index.classify(iso, m)
        faces, strips = face_counts(pc)
        raster = RASTER_FIXED_S * pixels / (512 * 512) + RASTER_PER_STRIP_S * strips
        cells = rays * (WALK_BASE + WALK_PER_CELL * float(np.mean(_size_triple(m))))
        cast = (rays * CAST_PER_RAY_S + cells * CAST_PER_CELL_S) / cores
        table.append({"size": float(m), "supercells": int(pc.size), "pc_supercells": int(pc.sum()),
                      "faces": faces, "strips": strips, "raster_s": raster,
                      "cells": cells, "cast_s": cast, "total_s": raster + cast})
    best = min(table, key=lambda r: r["total_s"])
    return best["size"], table
