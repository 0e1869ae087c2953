"""A confocal neuron and a floor: the shadow scene of Sobierajski & Avila 1995, Fig. 13.

The paper's neuron (a confocal microscope volume) is not distributed; these
are synthetic stand-ins of the same character: a soma with tapering,
branching dendrites, blurred like a microscope's point-spread function and
noisy, and a tiled slab to cast shadows on.
"""
from __future__ import annotations

import operator

import numpy as np

from .errors import InputError
from .grids import grid_axes, grid_dims, soft_inside, volume_label
from .volume import Volume, hand_over


def _blur(field, sigmas):
    """Separable Gaussian blur with per-axis sigmas ``(sx, sy, sz)`` in voxels (edges clamped)."""
    out = field
    for axis, sigma in zip((2, 1, 0), sigmas):
        if sigma <= 0 or out.shape[axis] < 2:
            continue
        r = max(1, int(np.ceil(3.0 * sigma)))
        w = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
        w = (w / w.sum()).astype(np.float32)
        pad = [(0, 0)] * 3
        pad[axis] = (r, r)
        padded = np.pad(out, pad, mode="edge")
        n = out.shape[axis]
        acc = np.zeros_like(out)
        for m in range(2 * r + 1):
            acc += w[m] * np.take(padded, np.arange(m, m + n), axis=axis)
        out = acc
    return out


def _bbox(lo, hi, dims):
    """Index slices ``(z, y, x)`` of the samples in the world box ``[lo, hi]`` (x, y, z), or None."""
    s = []
    for a in (2, 1, 0):
        a0 = max(0, int(np.floor(lo[a])))
        a1 = min(dims[a] - 1, int(np.ceil(hi[a])))
        if a1 < a0:
            return None
        s.append(slice(a0, a1 + 1))
    return tuple(s)


def _add_tube(out, dims, p0, p1, r0, r1, width):
    """``out = max(out, soft tube)`` for the tapered segment ``p0 -> p1`` (index units, x, y, z)."""
    pad = max(r0, r1) + 3.0 * width
    s = _bbox(np.minimum(p0, p1) - pad, np.maximum(p0, p1) + pad, dims)
    if s is None:
        return
    z = np.arange(s[0].start, s[0].stop, dtype=np.float32)[:, None, None]
    y = np.arange(s[1].start, s[1].stop, dtype=np.float32)[None, :, None]
    x = np.arange(s[2].start, s[2].stop, dtype=np.float32)[None, None, :]
    seg = (p1 - p0).astype(np.float32)
    ll = float(seg @ seg)
    vx, vy, vz = x - p0[0], y - p0[1], z - p0[2]
    t = np.clip((vx * seg[0] + vy * seg[1] + vz * seg[2]) / ll, 0.0, 1.0) if ll > 0 else 0.0 * vx
    d = np.sqrt((vx - t * seg[0]) ** 2 + (vy - t * seg[1]) ** 2 + (vz - t * seg[2]) ** 2)
    val = soft_inside(d - (r0 + t * (r1 - r0)), width)
    np.maximum(out[s], val, out=out[s])


def _turn(rng, d, angle):
    """``d`` turned by ``angle`` radians about a random axis perpendicular to it."""
    q = np.cross(d, rng.normal(size=3))
    q /= np.linalg.norm(q) + 1e-12
    return np.cos(angle) * d + np.sin(angle) * q


def _dendrite(rng, start, direction, radius, length, *, step, taper, branch_rate, depth, lo, hi,
              bias=(0.0, 0.0, 0.0), wiggle=0.22):
    """Segments ``(p0, p1, r0, r1)`` of a tapering random-walk dendrite and its branches.

    The walk keeps its heading (persistence), drifts along ``bias``, turns
    away from the box walls ``lo``/``hi`` and forks with probability
    ``branch_rate`` per step while ``depth`` allows; a child is thinner
    and leaves at 25-55 degrees.
    """
    segs = []
    todo = [(np.asarray(start, float), np.asarray(direction, float), float(radius), float(length), depth)]
    bias = np.asarray(bias, float)
    while todo:
        p, d, r, length, depth_left = todo.pop()
        d = d / np.linalg.norm(d)
        n = max(1, int(round(length / step)))
        r_end = max(taper * r, 0.6)
        for m in range(n):
            inward = np.where(p < lo + 3 * step, 1.0, 0.0) - np.where(p > hi - 3 * step, 1.0, 0.0)
            d = d + wiggle * rng.normal(size=3) + bias + 0.8 * inward
            d /= np.linalg.norm(d)
            q = p + step * d
            ra = r + (r_end - r) * m / n
            rb = r + (r_end - r) * (m + 1) / n
            segs.append((p, q, ra, rb))
            if depth_left > 0 and m < n - 2 and rng.random() < branch_rate:
                child = _turn(rng, d, rng.uniform(np.radians(25), np.radians(55)))
                todo.append((q, child, 0.75 * rb, 0.65 * (n - m) * step, depth_left - 1))
            p = q
    return segs


def neuron(size=128, *, seed=0, noise=True) -> Volume:
    """A hippocampal pyramidal neuron as a confocal microscope sees it (uint8).

    The test object of Sobierajski & Avila (1995), Fig. 13. A teardrop soma
    low in the box; a thick apical dendrite rising along +z with oblique
    branches and a tuft; five or six basal dendrites spreading downwards; a
    thin straight axon. Dendrites are random walks with persistence that
    taper and fork, drawn as soft tubes. Then what the microscope adds: a
    point spread function longer in z than in x and y (Gaussian blur), a
    faint out-of-focus haze around the soma, a dim background and photon
    (Poisson) noise. The walk runs over segments, the fields over arrays:
    a 128^3 volume takes well under a second.

    Parameters
    ----------
    size : int or (nx, ny, nz)
        Feature sizes scale with the smallest extent; radii never drop
        below about half a voxel, so small volumes still hold a surface.
    seed : int
        Branching, wiggle and noise.
    noise : bool
        Photon noise on (the default) or off.

    Returns
    -------
    Volume
        Spacing 1, origin 0; ``meta['iso'] = 80.5`` (a clean membrane:
        the background and its noise stay below 40), ``meta['soma']`` the
        soma centre ``(x, y, z)`` in index units.
    """
    dims = grid_dims(size)
    nx, ny, nz = dims
    rng = np.random.default_rng(seed)
    ext = np.array(dims, dtype=np.float64) - 1
    s = ext.min() / 127.0                     # feature scale: 1 at 128^3
    lo, hi = np.zeros(3), ext
    soma = ext * np.array([0.5, 0.5, 0.3]) + rng.uniform(-0.04, 0.04, 3) * ext
    rs = max(9.0 * s, 1.5)                    # soma radius (voxels)

    # Neurites as tapering tubes.
    segs = []
    step = max(2.0 * s, 0.5)
    up = np.array([0.0, 0.0, 1.0])
    apical = _turn(rng, up, rng.uniform(0.0, 0.15))
    trunk = _dendrite(rng, soma + 1.2 * rs * apical, apical, max(3.0 * s, 0.9), 0.5 * ext[2],
                      step=step, taper=0.45, branch_rate=0.18, depth=1, lo=lo, hi=hi,
                      bias=0.08 * up, wiggle=0.12)
    segs += trunk
    tip = trunk[0][1] if len(trunk) == 1 else max((q for _, q, _, _ in trunk), key=lambda q: q[2])
    for _ in range(int(rng.integers(3, 5))):  # the apical tuft
        d = _turn(rng, up, rng.uniform(np.radians(20), np.radians(60)))
        segs += _dendrite(rng, tip, d, max(1.4 * s, 0.6), rng.uniform(0.12, 0.2) * ext.min(),
                          step=step, taper=0.5, branch_rate=0.15, depth=1, lo=lo, hi=hi)
    for m in range(int(rng.integers(5, 7))):  # basal dendrites, fanning out below the soma
        phi = 2 * np.pi * (m + rng.uniform(-0.2, 0.2)) / 6
        d = np.array([np.cos(phi), np.sin(phi), -rng.uniform(0.4, 1.1)])
        d /= np.linalg.norm(d)
        segs += _dendrite(rng, soma + 0.8 * rs * d, d, max(1.9 * s, 0.7), rng.uniform(0.25, 0.38) * ext.min(),
                          step=step, taper=0.4, branch_rate=0.14, depth=1, lo=lo, hi=hi, bias=-0.03 * up)
    axon = _turn(rng, -up, rng.uniform(0.2, 0.4))
    segs += _dendrite(rng, soma + rs * axon, axon, max(0.8 * s, 0.5), 0.28 * ext[2],
                      step=step, taper=0.8, branch_rate=0.0, depth=0, lo=lo, hi=hi, wiggle=0.05)

    width = 0.6
    field = np.zeros((nz, ny, nx), dtype=np.float32)
    for p0, p1, r0, r1 in segs:
        _add_tube(field, dims, p0, p1, r0, r1, width)
    field *= np.float32(0.93)                 # neurites a little dimmer than the soma
    # Teardrop soma: an ellipsoid, taller than wide, narrowing upwards into the apical trunk.
    box = _bbox(soma - 2.5 * rs, soma + 2.5 * rs, dims)
    if box is not None:
        z = np.arange(box[0].start, box[0].stop, dtype=np.float32)[:, None, None] - soma[2]
        y = np.arange(box[1].start, box[1].stop, dtype=np.float32)[None, :, None] - soma[1]
        x = np.arange(box[2].start, box[2].stop, dtype=np.float32)[None, None, :] - soma[0]
        narrowing = 1.0 - 0.3 * np.clip(z / (1.4 * rs), 0.0, 1.0)
        q = np.sqrt((x / narrowing) ** 2 + (y / narrowing) ** 2 + (z / 1.4) ** 2)
        np.maximum(field[box], soft_inside(q - rs, width), out=field[box])

    # The microscope: a PSF elongated in z, haze, background and photon noise.
    field = _blur(field, (0.7, 0.7, 1.2))
    x, y, z = grid_axes(dims)
    r2 = ((x - soma[0]) ** 2 + (y - soma[1]) ** 2 + (z - soma[2]) ** 2).astype(np.float32)
    haze = np.exp(-r2 / np.float32(2 * (3.0 * rs) ** 2))
    photons = 12.0 + 225.0 * field + 14.0 * haze
    if noise:
        photons = rng.poisson(photons).astype(np.float32)
    data = np.clip(np.rint(photons), 0, 255).astype(np.uint8)
    return Volume(hand_over(data), name=volume_label("neuron", dims),
                  meta={"iso": 80.5, "soma": tuple(float(v) for v in soma), "seed": seed,
                        "synthetic": "neuron"})


def floor_height(n):
    """Samples along z of an ``n`` x ``n`` floor: a slab is thin, but has room for its relief."""
    return max(8, n // 8)


def floor(size=128, *, height=None, thickness=None, tile=None, relief=None) -> Volume:
    """A volumetric floor: a closed slab with a gentle checkerboard relief on top (uint8).

    The floor the neuron of Sobierajski & Avila (1995), Fig. 13 casts its
    shadows on, voxelized from a geometric description: the slab is the
    set where the box-like distance ``max(|x - cx| - hx, |y - cy| - hy,
    bottom - z, z - top(x, y))`` is negative, sampled through a soft step
    about half a voxel wide, so the sample value 127.5 lies on the
    geometric surface (antialiased, and the isosurface at 127.5 is flat
    where the description is). ``top(x, y)`` raises alternate tiles by
    ``relief`` voxels with smooth one-voxel transitions.

    Parameters
    ----------
    size : int or (nx, ny, nz)
        An int ``n`` gives an ``n x n x height`` floor: a floor is thin.
    height : int, optional
        Samples along z when ``size`` is an int; default ``max(8, n // 8)``.
    thickness : float, optional
        Slab thickness in voxels; default 35% of the z extent.
    tile : float, optional
        Tile edge in voxels; default an eighth of the x extent, at least 2.
    relief : float, optional
        Height difference between neighbouring tiles in voxels; default
        ``min(1, 8% of the z extent)``. 0 makes the top flat.

    Returns
    -------
    Volume
        Spacing 1, origin 0; ``meta['iso'] = 127.5``, ``meta['bottom']``
        and ``meta['top']`` (the z of the slab faces, top without relief),
        ``meta['tile']``, ``meta['relief']``.
    """
    if np.ndim(size) == 0:
        try:
            n = operator.index(size)      # as grid_dims: 12.7 is refused, not cut to 12
        except TypeError:
            raise InputError(f"size must be an integer or three integers, got {size!r}") from None
        dims = grid_dims((n, n, height if height is not None else floor_height(n)))
    else:
        dims = grid_dims(size)
    ext = np.array(dims, dtype=np.float64) - 1
    thickness = 0.35 * ext[2] if thickness is None else float(thickness)
    tile = max(2.0, ext[0] / 8.0) if tile is None else float(tile)
    relief = min(1.0, 0.08 * ext[2]) if relief is None else float(relief)
    if not (thickness > 0 and tile > 0 and relief >= 0):
        raise InputError("floor thickness and tile must be positive, relief not negative")
    bottom = 0.25 * ext[2]
    top = bottom + thickness
    margin = min(1.5, 0.1 * ext[:2].min())   # sides inset from the box: the slab is closed
    cx, cy = ext[0] / 2, ext[1] / 2
    hx, hy = cx - margin, cy - margin
    x, y, z = grid_axes(dims)
    # A smooth square wave per axis (edges about a voxel wide); their product is a checkerboard.
    sharp = tile / (np.pi * 1.0)

    def square(c):
        return np.tanh(sharp * np.sin(np.pi * (c + 0.5) / tile)) / np.tanh(sharp)

    top_xy = top + 0.5 * relief * square(x) * square(y)
    dist = np.maximum(np.maximum(np.abs(x - cx) - hx, np.abs(y - cy) - hy),
                      np.maximum(bottom - z, z - top_xy))
    data = np.clip(np.rint(255.0 * soft_inside(dist, 0.5)), 0, 255).astype(np.uint8)
    return Volume(hand_over(data), name=volume_label("floor", dims),
                  meta={"iso": 127.5, "bottom": float(bottom), "top": float(top), "tile": float(tile),
                        "relief": float(relief),
                        "synthetic": "floor"})
