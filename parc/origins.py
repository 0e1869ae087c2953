"""Where a view's rays start relative to the PC region, for the rasterization passes.

A face projected from behind the eye, or a ray starting inside a PC
supercell, would be lost to a plain rasterization: `parc.raster` and
`parc.bitplanes` clip the faces in front of the eye at a distance below
the eye's distance to the PC region (`distance_to_pc`), give near 0 to the
parallel rays that start inside it (`parallel_inside`), and draw the faces
bordering cavities (empty supercells enclosed by PC ones) only when a ray
may start in one (`open_faces`, `in_cavity`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import prange

from raycast.config import kernel
from raycast.rays import camera_ray


def open_faces(proxy):
    """Which faces border the open empty space; and the cavities.

    The open empty space is the set of empty (not PC) supercells connected
    to the outside of the volume through empty supercells sharing a face,
    an edge or a corner; the other empty supercells are cavities. A ray
    starting outside every (closed) cavity box first meets the PC region
    at a point all of whose empty neighbour boxes are open: up to that
    point it ran through empty boxes, each sharing at least a point with
    the next, from an open one; and every empty box holding the entry
    point shares that point with the last of them. So the faces there
    border open supercells; the same holds for the last exit, after which
    the ray runs to infinity. Faces bordering only cavities are never
    needed for such rays (a ray merely passing within the tests' touching
    distance of a box behaves the same: that distance is far below a
    supercell).

    Returns
    -------
    is_open : ndarray of bool, shape (Q,)
        Per face of ``proxy.faces``: some unit face of it has an open
        supercell on its empty side.
    cavity : ndarray of bool, shape ``proxy.pc.shape``
    """
    padded = np.pad(proxy.pc, 1)
    open_ = flood_from_corner(~padded)
    f = proxy.faces.astype(np.int64)
    q = len(f)
    idx, du, dv = proxy.unit_index()
    a = f[idx, 0]
    # Padded index of the empty side of each unit face: the face at
    # boundary p lies between supercells p-1 and p, i.e. padded p and p+1.
    side = f[idx, 1] + (proxy.outward[idx] > 0)
    uu = f[idx, 2] + du + 1
    vv = f[idx, 4] + dv + 1
    xyz = [np.where(a == ax, side, np.where((a + 1) % 3 == ax, uu, vv)) for ax in range(3)]
    unit_open = open_[xyz[2], xyz[1], xyz[0]]
    is_open = np.zeros(q, dtype=bool)
    np.logical_or.at(is_open, idx, unit_open)
    cavity = ~padded[1:-1, 1:-1, 1:-1] & ~open_[1:-1, 1:-1, 1:-1]
    return is_open, cavity


@kernel
def _flood(cells, ny, nx, start):
    """Clear the cells of ``cells`` (flat (z, y, x), a border of False, so neighbours need
    no bounds test) connected to ``start`` through 26-neighbours.

    Scanline fill: clear the whole run along x around a seed, then seed
    every run in the 8 neighbouring rows that touches it (x - 1 to x + 1:
    neighbours through faces, edges and corners).
    """
    # A run is cleared when popped, not when pushed, so several popped runs can push it: the
    # pending seeds can outnumber the cells (a grid one cell thick along x, all runs of
    # one cell), and the stack grows as needed: before a run's neighbours are scanned, by
    # as many seeds as they can hold (a run starts at most every other cell of a window).
    # Grown inside the scan, the stack was an array reassigned in the inner loop, and Numba
    # counted its references at every cell: 125 ns a cell, 7 s for the CT head's
    # half-cell supercells, against 6-11 ns.
    stack = np.empty(max(64, cells.size // 8), dtype=np.int64)
    stack[0] = start
    top = 1
    while top > 0:
        top -= 1
        i = stack[top]
        if not cells[i]:
            continue
        lo = i
        while cells[lo - 1]:
            lo -= 1
        hi = i
        while cells[hi + 1]:
            hi += 1
        for j in range(lo, hi + 1):
            cells[j] = False
        need = top + 8 * ((hi - lo + 3) // 2 + 1)
        if need > stack.size:
            grown = np.empty(max(need, 2 * stack.size), dtype=np.int64)
            grown[:top] = stack[:top]
            stack = grown
        for dz in (-1, 0, 1):
            for dy in (-1, 0, 1):
                if dz == 0 and dy == 0:
                    continue
                off = (dz * ny + dy) * nx
                inrun = False
                for j in range(lo - 1 + off, hi + 2 + off):
                    if cells[j]:
                        if not inrun:
                            stack[top] = j
                            top += 1
                            inrun = True
                    else:
                        inrun = False


def flood_from_corner(empty):
    """Cells of ``empty`` (3-D bool) connected to ``empty[0, 0, 0]`` through 26-neighbours."""
    nz, ny, nx = (n + 2 for n in empty.shape)
    cells = np.pad(empty, 1).ravel()
    start = (ny + 1) * nx + 1
    if not cells[start]:
        return np.zeros_like(empty)
    left = cells.copy()
    _flood(left, ny, nx, start)
    return (cells & ~left).reshape(nz, ny, nx)[1:-1, 1:-1, 1:-1]


def in_cavity(up, camera, width, height, eye):
    """Whether a ray of this view may start in (or on) a cavity box (``up.cavity_lo``,
    ``up.cavity_hi``: their corners); then every face is drawn."""
    if not len(up.cavity_lo):
        return False
    if not camera.parallel:
        # Within a rounding counts: the caster's index-space eye may lie on a box it misses in world space.
        tol = origin_slab(camera, width, height, eye, up.cavity_lo, up.cavity_hi)
        return bool(np.all((up.cavity_lo - tol <= eye) & (eye <= up.cavity_hi + tol), axis=1).any())
    # Parallel: ray origins lie within a rounding of the view plane; does
    # that slab meet a cavity box?
    f = np.asarray(camera.basis()[0], dtype=np.float64)
    centre = (up.cavity_lo + up.cavity_hi) / 2.0
    half = (up.cavity_hi - up.cavity_lo) / 2.0 @ np.abs(f)
    dist = (centre - eye) @ f
    slab = origin_slab(camera, width, height, eye, up.cavity_lo, up.cavity_hi) + 2.0 ** -40 * half
    return bool(np.any((dist - half <= slab) & (dist + half >= -slab)))


def origin_slab(camera, width, height, eye, lo, hi):
    """How far from the view plane (parallel) or the eye (perspective) a ray origin may
    lie as the caster rounds it: 2^-40 of the scene's coordinates."""
    spread = camera.parallel_scale * (width / height + 1.0) if camera.parallel else 0.0
    return 2.0 ** -40 * (np.abs(eye).max() + max(np.abs(lo).max(), np.abs(hi).max()) + spread)


def distance_to_pc(point, proxy):
    """Euclidean distance from ``point`` to the nearest PC supercell box (0 if inside or on one)."""
    ex, ey, ez = (np.asarray(e, dtype=np.float64) for e in proxy.world_edges)
    px, py, pz = (float(c) for c in point)
    return math.sqrt(_nearest_box_sq(proxy.pc, ex, ey, ez, px, py, pz))


@kernel
def _gap(lo, hi, p):
    """Distance from ``p`` to ``[lo, hi]`` along one axis."""
    return max(max(lo - p, 0.0), p - hi)


@kernel
def _nearest_box_sq(pc, ex, ey, ez, px, py, pz):
    """Smallest squared distance from ``(px, py, pz)`` to a box ``pc[k, j, i]`` (edges ``ex, ey, ez``), inf for none.

    One pass that skips slabs and rows already farther than the best: the
    NumPy version, a plane of gaps per slab, took 0.15 ms of each frame.
    """
    nz, ny, nx = pc.shape
    best = math.inf
    for k in range(nz):
        gz = _gap(ez[k], ez[k + 1], pz) ** 2
        if gz >= best:
            continue
        for j in range(ny):
            gy = _gap(ey[j], ey[j + 1], py) ** 2
            if gz + gy >= best:
                continue
            for i in range(nx):
                if pc[k, j, i]:
                    d = gz + (gy + _gap(ex[i], ex[i + 1], px) ** 2)
                    if d < best:
                        best = d
    return best


def parallel_inside(camera, width, height, proxy):
    """Pixels of a parallel view whose ray starts inside, on or next to a PC supercell, (H, W) bool.

    Ray origins by the caster's own formula (`raycast.rays.camera_ray`).
    "Next to": within `origin_slab` (a rounding at the scene's scale), as
    the caster converts the origin to index space, where one a rounding
    outside a face in world coordinates can land exactly on it and walk
    along it.
    """
    f = camera.basis()[0]
    eye = np.asarray(camera.eye, dtype=np.float64)
    lo, hi = proxy.bounds
    inside = np.zeros((height, width), dtype=bool)
    # Every origin lies within a rounding of the view plane (2^-52 of the
    # coordinates): if the volume box is clear of that slab, no origin is
    # in it -- the usual case, a view plane in front of the volume.
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    dist = (corners - eye) @ np.asarray(f, dtype=np.float64)
    slab = origin_slab(camera, width, height, eye, lo, hi)
    if (dist > slab).all() or (dist < -slab).all():
        return inside
    ex, ey, ez = (np.ascontiguousarray(e, dtype=np.float64) for e in proxy.world_edges)
    _parallel_inside(camera.as_array(), width, height, np.asarray(lo, dtype=np.float64),
                     np.asarray(hi, dtype=np.float64), float(slab), ex, ey, ez,
                     np.ascontiguousarray(proxy.pc, dtype=np.bool_), inside)
    return inside


@kernel
def _boxes_along(e, v, slab):
    """The first and last boxes along one axis (edges ``e``, sorted) whose closed interval, grown
    by ``slab``, holds ``v``: a point on or next to a boundary belongs to both neighbours."""
    n = len(e) - 1
    # The first edge at v - slab or beyond, by bisection; the slab is a rounding, so the last
    # box is found by stepping on from there.
    a, b = 0, n + 1
    while a < b:
        m = (a + b) // 2
        if e[m] >= v - slab:
            b = m
        else:
            a = m + 1
    last = a - 1
    while last < n and e[last + 1] <= v + slab:
        last += 1
    return min(max(a - 1, 0), n - 1), min(max(last, 0), n - 1)


@kernel(parallel=True)
def _parallel_inside(cam, width, height, lo, hi, slab, ex, ey, ez, pc, inside):
    """`parallel_inside`'s test of each pixel's ray origin against the PC boxes, a row a thread."""
    for y in prange(height):
        for x in range(width):
            ox, oy, oz, _, _, _ = camera_ray(cam, width, height, x, y)
            if not (lo[0] - slab <= ox <= hi[0] + slab and lo[1] - slab <= oy <= hi[1] + slab
                    and lo[2] - slab <= oz <= hi[2] + slab):
                continue
            x0, x1 = _boxes_along(ex, ox, slab)
            y0, y1 = _boxes_along(ey, oy, slab)
            z0, z1 = _boxes_along(ez, oz, slab)
            # Every box from the first to the last, not these two alone: supercells thinner than
            # the slab (a thousandth of a cell in a volume 2^32 cells from 0) lie between them,
            # the one holding the origin among them.
            hit = False
            for k in range(z0, z1 + 1):
                for j in range(y0, y1 + 1):
                    for i in range(x0, x1 + 1):
                        if pc[k, j, i]:
                            hit = True
            inside[y, x] = hit
