"""Slow, obvious references for classification, supercells, proxies and ray segments.

Sources of truth
----------------
- Cell range: min and max of the eight corner samples, by a loop over cells.
- Supercell range: the trilinear interpolant is multilinear inside each
  cell, so over the piece of a cell that a supercell box overlaps, its
  extremes lie at the piece's eight corners. The reference walks every
  cell the box overlaps with positive length, clips it, evaluates the
  interpolant at the piece's corners in float64 (plain Python, one
  corner at a time) and takes min/max.
- Ray segments: for every pixel, the caster's float64 ray (same formula as
  `raycast.rays.camera_ray`) against every PC supercell box by the slab
  test on closed boxes; the exact entry (clamped to the ray start) and
  exit over all boxes the ray meets.

- Open empty space: a breadth-first search from a corner cell through
  faces, edges and corners (`reached`).

Also the smooth random volumes the raster and bit-plane tests share
(`smooth_volume`, `band_classes`): PC regions that are blobs with holes.
"""
import math
from collections import deque

import numpy as np

from data_tools import Volume
from parc.classify import VolumeIndex


def cell_minmax_loop(data):
    nz, ny, nx = data.shape
    mn = np.empty((nz - 1, ny - 1, nx - 1), data.dtype)
    mx = np.empty_like(mn)
    for k in range(nz - 1):
        for j in range(ny - 1):
            for i in range(nx - 1):
                block = data[k:k + 2, j:j + 2, i:i + 2]
                mn[k, j, i] = block.min()
                mx[k, j, i] = block.max()
    return mn, mx


def _pieces(lo, hi):
    """Per axis: the (start, end) of each cell piece inside [lo, hi] with positive length."""
    out = []
    for c in range(int(math.floor(lo)), int(math.ceil(hi))):
        a, b = max(lo, c), min(hi, c + 1)
        if b > a:
            out.append((a, b))
    return out


def box_range(data, lo, hi):
    """Exact range of the interpolant over the index box [lo, hi] ((x, y, z) each)."""
    vals = []
    for (x0, x1) in _pieces(lo[0], hi[0]):
        for (y0, y1) in _pieces(lo[1], hi[1]):
            for (z0, z1) in _pieces(lo[2], hi[2]):
                # Evaluate the piece's corners inside the cell that holds the
                # piece (its midpoint picks the cell).
                i = int(math.floor((x0 + x1) / 2))
                j = int(math.floor((y0 + y1) / 2))
                k = int(math.floor((z0 + z1) / 2))
                for x in (x0, x1):
                    for y in (y0, y1):
                        for z in (z0, z1):
                            vals.append(_in_cell(data, i, j, k, x - i, y - j, z - k))
    return min(vals), max(vals)


def _in_cell(data, i, j, k, u, v, w):
    c = data[k:k + 2, j:j + 2, i:i + 2].astype(np.float64)
    return float(((1 - w) * ((1 - v) * ((1 - u) * c[0, 0, 0] + u * c[0, 0, 1])
                             + v * ((1 - u) * c[0, 1, 0] + u * c[0, 1, 1]))
                  + w * ((1 - v) * ((1 - u) * c[1, 0, 0] + u * c[1, 0, 1])
                         + v * ((1 - u) * c[1, 1, 0] + u * c[1, 1, 1]))))


def smooth_volume(seed, dims=(9, 8, 7), spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)):
    """A smooth random field: PC regions are blobs with holes, not noise."""
    rng = np.random.default_rng(seed)
    nx, ny, nz = dims
    data = rng.standard_normal((nz, ny, nx))
    for axis in range(3):
        data = (np.roll(data, 1, axis) + 2 * data + np.roll(data, -1, axis)) / 4
    return Volume(data.astype(np.float32), spacing=spacing, origin=origin)


def band_classes(vol, size, frac=0.35):
    """``(grid, pc)``: the PC supercells of ``size`` for an isovalue that leaves the top ``frac``
    of supercell maxima PC."""
    idx = VolumeIndex.of(vol)
    mn, mx = idx.ranges(size)
    iso = float(np.quantile(np.asarray(mx, np.float64), 1 - frac))
    pc = idx.classify(iso, size)
    assert pc.any() and not pc.all()
    return idx.grid(size), pc


def caster_rays(camera, width, height):
    """Every pixel's ray exactly as `raycast.rays.camera_ray` computes it: origins, directions (H, W, 3)."""
    f, r, u = camera.basis()
    x = np.arange(width, dtype=np.float64)
    y = np.arange(height, dtype=np.float64)
    sx = (2.0 * (x + 0.5) / width - 1.0) * (width / height)
    sy = 1.0 - 2.0 * (y + 0.5) / height
    sx, sy = np.meshgrid(sx, sy)
    o = np.empty((height, width, 3))
    d = np.empty((height, width, 3))
    if camera.parallel:
        ps = camera.parallel_scale
        for c in range(3):
            o[..., c] = camera.eye[c] + ps * (sx * r[c] + sy * u[c])
            d[..., c] = f[c]
    else:
        th = math.tan(math.radians(camera.fov) / 2.0)
        for c in range(3):
            d[..., c] = f[c] + th * (sx * r[c] + sy * u[c])
            o[..., c] = camera.eye[c]
        inv = 1.0 / np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2])
        d *= inv[..., None]
    return o, d


def pc_boxes(proxy):
    """World corners ``(lo, hi)`` of every PC supercell, each (B, 3)."""
    ex, ey, ez = proxy.world_edges
    kz, ky, kx = np.nonzero(proxy.pc)
    lo = np.stack([ex[kx], ey[ky], ez[kz]], axis=1)
    hi = np.stack([ex[kx + 1], ey[ky + 1], ez[kz + 1]], axis=1)
    return lo, hi


def ray_box_batches(o, d, lo, hi, touch, batch=256):
    """The slab test of rays ``o + t d`` (each (..., 3), R rays) against boxes ``[lo, hi]`` (each (B, 3)),
    ``batch`` boxes at a time: yields ``(b0, enter, leave, meet)``, each (R, boxes in the batch)
    for boxes ``b0 ..``, ``enter`` clamped to ``t >= 0``; ``meet`` where ``enter <= leave + touch``.
    """
    o = o.reshape(-1, 1, 3)
    d = d.reshape(-1, 1, 3)
    for b0 in range(0, len(lo), batch):
        blo, bhi = lo[None, b0:b0 + batch], hi[None, b0:b0 + batch]
        with np.errstate(divide="ignore", invalid="ignore"):
            t0 = (blo - o) / d
            t1 = (bhi - o) / d
        par = d == 0.0
        ins = (o >= blo) & (o <= bhi)
        tmin = np.where(par, np.where(ins, -np.inf, np.inf), np.minimum(t0, t1))
        tmax = np.where(par, np.where(ins, np.inf, -np.inf), np.maximum(t0, t1))
        enter = np.maximum(tmin.max(axis=2), 0.0)
        leave = tmax.min(axis=2)
        yield b0, enter, leave, enter <= leave + touch


def segments_reference(camera, width, height, proxy, *, touch=0.0):
    """Exact first entry and last exit of each pixel's ray over the PC boxes, (H, W) each.

    ``inf`` / ``-inf`` where the ray meets no box. A ray passing within
    ``touch`` (t units) of meeting a box counts as meeting it, so rays
    through box edges and corners are demanded even when the slab test's
    own rounding would call them a miss.
    """
    o, d = caster_rays(camera, width, height)
    lo, hi = pc_boxes(proxy)
    near = np.full(width * height, np.inf)
    far = np.full(width * height, -np.inf)
    for _, enter, leave, meet in ray_box_batches(o, d, lo, hi, touch):
        near = np.minimum(near, np.where(meet, enter, np.inf).min(axis=1))
        far = np.maximum(far, np.where(meet, np.maximum(leave, enter), -np.inf).max(axis=1))
    return near.reshape(height, width), far.reshape(height, width)


def reached(empty):
    """Cells of ``empty`` reachable from ``empty[0, 0, 0]`` through faces, edges or corners (plain BFS)."""
    seen = np.zeros_like(empty)
    if not empty[0, 0, 0]:
        return seen
    seen[0, 0, 0] = True
    todo = deque([(0, 0, 0)])
    while todo:
        z, y, x = todo.popleft()
        for dz in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    q = (z + dz, y + dy, x + dx)
                    if all(0 <= c < s for c, s in zip(q, empty.shape)) and empty[q] and not seen[q]:
                        seen[q] = True
                        todo.append(q)
    return seen
