"""The supercell size PARC uses when none is given: a measured cost model.

About this technique
--------------------
Sobierajski & Avila (1995, §3) group cells into supercells so that the
proxy has fewer polygons; the price is a longer walk through the empty
cells inside possibly contributing supercells. Which size is best depends
on the surface and on the machine, so `choose_supercell` estimates the
render time of each candidate size from what it costs here:

- **Rasterization** pays a fixed cost per frame (clear, fill, read-back)
  and a cost per polygon drawn (geometry shader, triangle setup), each
  measured for two kinds of OpenGL: a software rasterizer (Mesa llvmpipe,
  where a polygon costs about 0.3 us on the calling thread) and a GPU
  (about 40 ns), told apart by the context's renderer string. On a GPU
  polygons are cheap enough that finer supercells win. The proxy merges
  coplanar faces (`parc.proxy.build_proxy`), so the polygons drawn are
  far fewer than the supercell faces: the model counts the strips the
  merge's first stage makes (`count_face_strips`), an upper bound on the
  rectangles that costs a few array operations instead of a merge. On a
  flat surface the difference decides the size: the Fig. 13 floor at
  2-cell supercells has 16,876 supercell faces, 508 strips and 12
  rectangles.
- **Casting** pays per ray that reaches the PC region and per cell
  walked. Coarser supercells reach more rays (the PC region's projection
  grows: `projected_share`), and each walks a little further from the
  supercell's boundary to the surface, levelling off after a few cells
  because the skip tables jump across the empty cubes in between. Where
  PC cells are strewn through the volume (a level in its noise) a ray
  meets one sooner whatever the size: the walk is then at most their
  mean free path, `free_path`.
"""
from __future__ import annotations

import numba
import numpy as np
from numba import prange

from data_tools import InputError
from raycast.config import kernel

from .ranges import supercell_size

#: Cost model constants, measured on this project's development machine
#: (2 x86 cores, Mesa llvmpipe 22.3 / LLVM 15) with the skip tables on:
#: least squares over the CT head skin (600) and bone (1500), neghip (80)
#: and the CT head under ``ct_skin_bone``, supercells 1.5-16, at 512^2
#: (300^2 translucent), median of 5 (`parc compare`'s default view).
#: Rasterization (`parc.raster.raster_segments`): 2.6 ms per 512x512
#: frame plus 0.325 us per strip (`count_face_strips`); the per-frame cost
#: is the same for every size and does not change the choice.
RASTER_FIXED_S = 2.6e-3
RASTER_PER_STRIP_S = 0.325e-6
#: The same on a GPU: an NVIDIA H100 (driver 580.159, EGL), the caster on
#: 2 threads; least squares over `parc compare --sweep-supercell` on the
#: CT head skin (2-8), bone (2-8) and neghip (1-4), median of 5: 1.14 ms
#: per frame plus 42.5 ns per strip. There the sweeps' fastest sizes were
#: 2 (skin: 6.9x against brute, 4.9x at 8), 2-4 (bone: 11.9x, 10.1x at 8)
#: and 1.5 (neghip: 7.5x, 6.4x at 2).
GPU_RASTER_FIXED_S = 1.14e-3
GPU_RASTER_PER_STRIP_S = 42.5e-9
#: Renderer strings (GL_RENDERER, lower case) of software rasterizers.
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "software", "swiftshader")
#: Rays that reach the PC region: ``RAY_COVER * pixels * share``, where
#: ``share`` is the part of the volume box's projected area that the PC
#: supercells cover (`projected_share`, along the three axes). Coarser
#: supercells cover more of the screen: neghip's PC region grows from 39%
#: to 83% of the box's projection between sizes 1.5 and 16, and the rays
#: with a segment from 16% to 35% of the pixels. Measured: segment pixels
#: over ``pixels * share`` is 0.29-0.42 over all four scenes and sizes.
RAY_COVER = 0.36
#: Numba caster with segments, per core: per ray that reaches the PC
#: region (setup, the cubic at the hit) and per cell walked.
CAST_PER_RAY_S = 0.22e-6
CAST_PER_CELL_S = 14.4e-9
#: Cells walked per ray that reaches a PC supercell: ``WALK_CELLS * (1 -
#: 2^-m)`` for supercells of ``m`` cells. The skip tables jump across the
#: empty cubes inside a supercell, so the walk from its boundary to the
#: surface levels off after a few cells instead of growing with ``m``:
#: per segment ray, CT skin 7.2 cells at 1.5, 12.5 at 4, 13.7 at 10-16;
#: bone 11.4, 17.6, 16-18; neghip 6.5, 9.9, 8.5-9.8.
WALK_CELLS = 13.0

#: Supercell sizes `choose_supercell` considers by default.
CANDIDATE_SIZES = (1, 2, 3, 4, 6, 8, 12)


def free_path(pc_cells):
    """Cells a ray crosses before a PC cell, were the PC cells strewn evenly through the
    volume: one over their share of its cells (``pc_cells``, the classification at one
    cell; inf for none).

    Where they gather on a surface, as on the CT head (under 4% of its cells at the
    skin or the bone: 26-27 cells) or the iron protein of ``neghip.slc`` (4.6%: 22),
    a ray's walk to them ends long before this bound; a level in a volume's noise
    puts them everywhere: bucky at 5, 29% of its cells, 3.5, where a ray meets one
    after 3.4 cells (1-cell supercells) to 3.7 (8-cell), measured. The bound caps
    the model's walk wherever PC cells are over 1/13 of the cells (7.7%), a
    surface in a small volume too (a sphere in 20^3 samples: 12%, 8.1 cells),
    where the walks inside its few supercells are short either way.
    """
    share = float(np.count_nonzero(pc_cells)) / pc_cells.size if pc_cells.size else 0.0
    return 1.0 / share if share > 0.0 else np.inf


def count_outer_faces(pc):
    """Faces between a PC supercell and an empty one or the volume boundary."""
    return face_counts(pc)[0]


def face_counts(pc):
    """``(faces, strips)``: the outer faces (`count_outer_faces`) and their strips (`count_face_strips`).

    One parallel pass over the mask (`_face_counts`), row by row with no
    branches and no temporaries: the cost model counts the faces of every
    size it weighs, the CT head's 7.3 million cells among them, in 2.6 ms
    against 17.5 ms for NumPy's padded masks (a kernel testing each face
    with branches took 31 ms).
    """
    pc = np.ascontiguousarray(pc, dtype=np.bool_).view(np.uint8)
    if not pc.size:
        return 0, 0
    faces, strips = _face_counts(pc)
    return int(faces), int(strips)


@kernel(parallel=True)
def _face_counts(pc):
    """Outer faces of the 0/1 mask ``pc`` and the strips they make: faces across x run along y,
    across y along z, across z along x; a face starts a strip unless the face of the same
    orientation before it along that axis is one too. Rows outside the mask read as zeros."""
    nz, ny, nx = pc.shape
    zero = np.zeros(nx, np.uint8)
    faces = 0
    strips = 0
    for k in prange(nz + 1):
        for j in range(ny + 1):
            # Faces across z (between slices k - 1 and k), strips along x.
            if j < ny:
                lo = pc[k - 1, j] if k >= 1 else zero
                hi = pc[k, j] if k < nz else zero
                pb = 0
                pa = 0
                for i in range(nx):
                    b = np.int64(lo[i] > hi[i])
                    a = np.int64(hi[i] > lo[i])
                    faces += b + a
                    strips += np.int64(b > pb) + np.int64(a > pa)
                    pb = b
                    pa = a
            if k >= nz:
                continue
            # Faces across y (between rows j - 1 and j of slice k), strips along z.
            lo = pc[k, j - 1] if j >= 1 else zero
            hi = pc[k, j] if j < ny else zero
            qlo = pc[k - 1, j - 1] if k >= 1 and j >= 1 else zero
            qhi = pc[k - 1, j] if k >= 1 and j < ny else zero
            for i in range(nx):
                b = np.int64(lo[i] > hi[i])
                a = np.int64(hi[i] > lo[i])
                faces += b + a
                strips += np.int64(b > np.int64(qlo[i] > qhi[i])) + np.int64(a > np.int64(qhi[i] > qlo[i]))
            if j >= ny:
                continue
            # Faces across x (between samples i - 1 and i of row j), strips along y.
            row = pc[k, j]
            prev = pc[k, j - 1] if j >= 1 else zero
            for i in range(nx + 1):
                lo_ = row[i - 1] if i >= 1 else 0
                hi_ = row[i] if i < nx else 0
                plo = prev[i - 1] if i >= 1 else 0
                phi = prev[i] if i < nx else 0
                b = np.int64(lo_ > hi_)
                a = np.int64(hi_ > lo_)
                faces += b + a
                strips += np.int64(b > np.int64(plo > phi)) + np.int64(a > np.int64(phi > plo))
    return faces, strips


def count_face_strips(pc):
    """Strips of outer faces: runs along each face's ``u`` axis, as `parc.proxy` merges them first.

    Faces perpendicular to axis ``a`` run along ``u = (a + 1) % 3``; a strip
    is a maximal run of faces of one orientation in one plane and row. The
    proxy then merges equal strips into rectangles, so its polygon count is
    at most this.
    """
    return face_counts(pc)[1]


def projected_share(pc, edges):
    """Part of the volume box's projected area that the PC supercells cover.

    The three axis-aligned projections, each weighted by its area: the
    box's mean projected area over all directions is proportional to that
    sum (Cauchy), so this stands in for any view. ``pc`` is ``[z, y, x]``;
    ``edges`` the supercell boundaries along x, y, z (any consistent units).
    """
    dx, dy, dz = (np.diff(np.asarray(e, dtype=np.float64)) for e in edges)
    covered = (float((pc.any(axis=0) * np.outer(dy, dx)).sum()) + float((pc.any(axis=1) * np.outer(dz, dx)).sum())
               + float((pc.any(axis=2) * np.outer(dz, dy)).sum()))
    x, y, z = dx.sum(), dy.sum(), dz.sum()
    return covered / float(x * y + z * x + z * y)


def raster_costs(renderer=None):
    """``(seconds per 512x512 frame, seconds per strip)`` of the OpenGL pass.

    ``renderer``: an OpenGL renderer string (``GL_RENDERER``); default the
    process's context's, or a software rasterizer's costs where there is
    no OpenGL (the model then only ranks sizes for a renderer to come).
    """
    if renderer is None:
        from .gl import OpenGLUnavailable, context_info
        try:
            renderer = context_info()["GL_RENDERER"]
        except OpenGLUnavailable:
            renderer = "software"
    if any(name in renderer.lower() for name in SOFTWARE_RENDERERS):
        return RASTER_FIXED_S, RASTER_PER_STRIP_S
    return GPU_RASTER_FIXED_S, GPU_RASTER_PER_STRIP_S


def choose_supercell(index, iso=None, *, pixels=512 * 512, rays=None, cores=None,
                     candidates=CANDIDATE_SIZES, classify=None, renderer=None):
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
        Rays expected to meet the volume's box, of which the PC region
        takes its `projected_share`; default ``RAY_COVER * pixels``.
    cores : int or None
        Threads the caster runs on; default Numba's (``numba.get_num_threads()``,
        which ``NUMBA_NUM_THREADS`` and ``numba.set_num_threads`` set; the
        machine's core count would overrate a caster held to fewer).
    candidates : sequence of sizes
        Cubic sizes (cells per supercell edge) to compare. Size 1 is
        classified in any case, for `free_path`, unless too fine for the
        volume.
    renderer : str or None
        The OpenGL renderer string the costs of rasterization are chosen
        by (`raster_costs`); default the process's context's.

    Returns
    -------
    size : float
        The candidate with the least estimated time, among those that give
        at most `parc.ranges.MAX_SUPERCELLS` supercells for this volume.
    table : list of dict
        Per candidate: ``size``, ``supercells``, ``pc_supercells``,
        ``faces`` (outer faces before merging), ``strips``, ``share``
        (`projected_share`), ``rays`` (reaching the PC region),
        ``raster_s``, ``cells``, ``cast_s``, ``total_s``.

    Notes
    -----
    ``raster_s = fixed * pixels / 512^2 + per_strip * strips``, the costs
    of this kind of rasterizer (`raster_costs`); ``cast_s = rays_pc *
    (CAST_PER_RAY_S + walk CAST_PER_CELL_S) / cores`` with ``rays_pc =
    rays * share`` and ``walk = min(WALK_CELLS (1 - 2^-m), free_path)``
    (`free_path` of the classification at one cell; inf where one cell is
    too fine for the volume). Small supercells cost polygons; large
    ones cover more of the screen and walk a little further. The constants
    were measured on two machines (see the module constants); the model
    ranks sizes, it does not predict times elsewhere. Measured with
    llvmpipe (raster + cast, 2 cores, 512x512, median of 5; the model's
    pick in bold): CT head skin 4: 20.5 ms, 6: 18.8, **8: 18.6**, 10:
    20.3; bone 4: 16.7, 6: 17.0, **8: 14.0**, 10: 13.6; neghip **2:
    9.2**, 3: 9.0, 4: 8.7, 8: 10.2.
    """
    cores = cores or numba.get_num_threads()
    fixed, per_strip = raster_costs(renderer)
    rays = RAY_COVER * pixels if rays is None else rays
    table = []
    vol = index.volume

    def classified(m):
        return classify(m) if classify is not None else index.classify(iso, m)
    try:
        index.grid(1)
        cells_pc = classified(1)
    except InputError:
        cells_pc = None     # too fine to classify for this volume: the walk as measured
    bound = np.inf if cells_pc is None else free_path(cells_pc)
    for m in candidates:
        try:
            grid = index.grid(m)
        except InputError:
            continue        # too fine to classify for this volume (a 1734-slice CT at 1 cell)
        one_cell = cells_pc is not None and supercell_size(m) == supercell_size(1)
        pc = cells_pc if one_cell else classified(m)
        faces, strips = face_counts(pc)
        share = projected_share(pc, grid.world_edges(vol))
        raster = fixed * pixels / (512 * 512) + per_strip * strips
        rays_pc = rays * share
        cells = rays_pc * min(WALK_CELLS * (1.0 - 2.0 ** -float(np.mean(supercell_size(m)))), bound)
        cast = (rays_pc * CAST_PER_RAY_S + cells * CAST_PER_CELL_S) / cores
        table.append({"size": float(m), "supercells": int(pc.size), "pc_supercells": int(pc.sum()),
                      "faces": faces, "strips": strips, "share": share, "rays": rays_pc, "raster_s": raster,
                      "cells": cells, "cast_s": cast, "total_s": raster + cast})
    best = min(table, key=lambda r: r["total_s"])
    return best["size"], table
