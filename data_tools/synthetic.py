"""Synthetic volumes: analytic fields, exact-trilinear test fields, noisy blobs, a confocal neuron
and a floor for shadows, and CT-like phantoms."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import InputError
from .volume import Volume

#: Voxels per slab when phantoms are built slab by slab (bounds temporary memory).
_SLAB_VOXELS = 1 << 22


def _dims(size, what="size"):
    """``(nx, ny, nz)`` from an int ``n`` (a cube) or three ints."""
    try:
        dims = (int(size),) * 3 if np.ndim(size) == 0 else tuple(int(s) for s in size)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be an integer or three integers, got {size!r}") from None
    if len(dims) != 3 or min(dims) < 2:
        raise InputError(f"{what} must give at least 2 samples per axis, got {size!r}")
    return dims


def _axes(dims, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)):
    """World coordinates as broadcastable arrays ``x[None,None,:]``, ``y[None,:,None]``, ``z[:,None,None]``."""
    nx, ny, nz = dims
    x = origin[0] + spacing[0] * np.arange(nx, dtype=np.float64)
    y = origin[1] + spacing[1] * np.arange(ny, dtype=np.float64)
    z = origin[2] + spacing[2] * np.arange(nz, dtype=np.float64)
    return x[None, None, :], y[None, :, None], z[:, None, None]


def _label(name, dims):
    return f"{name} {dims[0]}x{dims[1]}x{dims[2]}"


def sphere(size=64, *, radius_fraction=0.35) -> Volume:
    """Signed distance to a sphere centred in the box (float32, negative inside).

    Parameters
    ----------
    size : int or (nx, ny, nz)
    radius_fraction : float
        Radius as a fraction of the smallest box extent ``n - 1``.

    Returns
    -------
    Volume
        Spacing 1, origin 0; ``meta['center']`` (x, y, z), ``meta['radius']``
        and ``meta['iso'] = 0.0`` (the sphere itself).
    """
    dims = _dims(size)
    center = tuple((n - 1) / 2.0 for n in dims)
    radius = radius_fraction * (min(dims) - 1)
    x, y, z = _axes(dims)
    dist = np.sqrt((x - center[0]) ** 2 + (y - center[1]) ** 2 + (z - center[2]) ** 2) - radius
    return Volume(dist.astype(np.float32), name=_label("sphere", dims),
                  meta={"center": center, "radius": radius, "iso": 0.0, "synthetic": "sphere"})


def torus(size=64, *, major_fraction=0.3, minor_fraction=0.12) -> Volume:
    """Signed distance to a torus around the z axis through the box centre (float32).

    Parameters
    ----------
    size : int or (nx, ny, nz)
    major_fraction, minor_fraction : float
        Ring and tube radii as fractions of the smallest box extent.

    Returns
    -------
    Volume
        ``meta['center']``, ``meta['major_radius']``, ``meta['minor_radius']``,
        ``meta['iso'] = 0.0``.
    """
    dims = _dims(size)
    ext = min(dims) - 1
    center = tuple((n - 1) / 2.0 for n in dims)
    big_r, small_r = major_fraction * ext, minor_fraction * ext
    x, y, z = _axes(dims)
    ring = np.sqrt((x - center[0]) ** 2 + (y - center[1]) ** 2) - big_r
    dist = np.sqrt(ring ** 2 + (z - center[2]) ** 2) - small_r
    return Volume(dist.astype(np.float32), name=_label("torus", dims),
                  meta={"center": center, "major_radius": big_r, "minor_radius": small_r,
                        "iso": 0.0, "synthetic": "torus"})


def marschner_lobb(size=64, *, alpha=0.25, f_m=6.0) -> Volume:
    """The Marschner-Lobb test signal on ``[-1, 1]^3`` (float32).

    ``rho(x, y, z) = (1 - sin(pi z / 2) + alpha (1 + rho_r(sqrt(x^2 + y^2))))
    / (2 (1 + alpha))`` with ``rho_r(r) = cos(2 pi f_m cos(pi r / 2))``.

    Parameters
    ----------
    size : int or (nx, ny, nz)
    alpha, f_m : float
        The standard values are 0.25 and 6.

    Returns
    -------
    Volume
        Origin ``(-1, -1, -1)``, spacing ``2 / (n - 1)``, ``meta['iso'] = 0.5``.
    """
    dims = _dims(size)
    spacing = tuple(2.0 / (n - 1) for n in dims)
    x, y, z = _axes(dims, spacing, (-1.0, -1.0, -1.0))
    r = np.sqrt(x ** 2 + y ** 2)
    rho_r = np.cos(2 * np.pi * f_m * np.cos(np.pi * r / 2))
    rho = (1 - np.sin(np.pi * z / 2) + alpha * (1 + rho_r)) / (2 * (1 + alpha))
    return Volume(rho.astype(np.float32), spacing=spacing, origin=(-1.0, -1.0, -1.0),
                  name=_label("marschner_lobb", dims),
                  meta={"alpha": alpha, "f_m": f_m, "iso": 0.5, "synthetic": "marschner_lobb"})


def _gaussians(dims, centers, sigmas, amps):
    """Sum of separable isotropic Gaussians in index coordinates (float32)."""
    nx, ny, nz = dims
    out = np.zeros((nz, ny, nx), dtype=np.float32)
    ix, iy, iz = (np.arange(n, dtype=np.float32) for n in dims)
    for (cx, cy, cz), s, a in zip(centers, sigmas, amps):
        gx = np.exp(-0.5 * ((ix - cx) / s) ** 2).astype(np.float32)
        gy = np.exp(-0.5 * ((iy - cy) / s) ** 2).astype(np.float32)
        gz = (a * np.exp(-0.5 * ((iz - cz) / s) ** 2)).astype(np.float32)
        out += gz[:, None, None] * (gy[:, None] * gx[None, :])[None]
    return out


def blobs(size=64, *, seed=0, count=12, noise=0.04) -> Volume:
    """Noisy Gaussian blobs, like a confocal microscopy stack (uint8).

    Parameters
    ----------
    size : int or (nx, ny, nz)
    seed : int
        Blob placement and noise.
    count : int
        Number of blobs.
    noise : float
        Standard deviation of the additive noise, as a fraction of full scale.

    Returns
    -------
    Volume
        ``meta['iso']`` a level that cuts the blobs (x.5, never a sample value).
    """
    dims = _dims(size)
    rng = np.random.default_rng(seed)
    ext = np.array(dims, dtype=np.float64) - 1
    centers = rng.uniform(0.2, 0.8, size=(count, 3)) * ext
    sigmas = rng.uniform(0.04, 0.10, size=count) * ext.min()
    amps = rng.uniform(0.5, 1.0, size=count)
    field = _gaussians(dims, centers, sigmas, amps)
    field += rng.normal(0.0, noise, size=field.shape).astype(np.float32)
    # A dim constant offset, as in real stacks: the background is not exactly zero.
    data = np.clip(np.rint(20.0 + 215.0 * field), 0, 255).astype(np.uint8)
    return Volume(data, name=_label("blobs", dims),
                  meta={"iso": 100.5, "seed": seed, "synthetic": "blobs"})


def _edge(dist, width):
    """Soft inside indicator of a region with signed distance ``dist`` (negative inside)."""
    return 0.5 - 0.5 * np.tanh(dist / width)

# --- a confocal neuron and a floor (the shadow scene of Sobierajski & Avila 1995, Fig. 13)

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
    val = _edge(d - (r0 + t * (r1 - r0)), width)
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
    dims = _dims(size)
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
        np.maximum(field[box], _edge(q - rs, width), out=field[box])

    # The microscope: a PSF elongated in z, haze, background and photon noise.
    field = _blur(field, (0.7, 0.7, 1.2))
    x, y, z = _axes(dims)
    r2 = ((x - soma[0]) ** 2 + (y - soma[1]) ** 2 + (z - soma[2]) ** 2).astype(np.float32)
    haze = np.exp(-r2 / np.float32(2 * (3.0 * rs) ** 2))
    photons = 12.0 + 225.0 * field + 14.0 * haze
    if noise:
        photons = rng.poisson(photons).astype(np.float32)
    data = np.clip(np.rint(photons), 0, 255).astype(np.uint8)
    return Volume(data, name=_label("neuron", dims),
                  meta={"iso": 80.5, "soma": tuple(float(v) for v in soma), "seed": seed,
                        "synthetic": "neuron"})


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
        Tile edge in voxels; default an eighth of the x extent.
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
            n = int(size)
        except (TypeError, ValueError):
            raise InputError(f"size must be an integer or three integers, got {size!r}") from None
        dims = _dims((n, n, height if height is not None else max(8, n // 8)))
    else:
        dims = _dims(size)
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
    x, y, z = _axes(dims)
    # A smooth square wave per axis (edges about a voxel wide); their product is a checkerboard.
    sharp = tile / (np.pi * 1.0)

    def square(c):
        return np.tanh(sharp * np.sin(np.pi * (c + 0.5) / tile)) / np.tanh(sharp)

    top_xy = top + 0.5 * relief * square(x) * square(y)
    dist = np.maximum(np.maximum(np.abs(x - cx) - hx, np.abs(y - cy) - hy),
                      np.maximum(bottom - z, z - top_xy))
    data = np.clip(np.rint(255.0 * _edge(dist, 0.5)), 0, 255).astype(np.uint8)
    return Volume(data, name=_label("floor", dims),
                  meta={"iso": 127.5, "bottom": float(bottom), "top": float(top), "tile": float(tile),
                        "relief": float(relief),
                        "synthetic": "floor"})



def _ct_slab(k0, k1, dims, spacing, seed, noise):
    """Phantom samples of slices ``k0:k1`` as float32; each slice has its own noise stream."""
    nx, ny, nz = dims
    # Shapes live in normalised box coordinates [-1, 1]; distances are
    # converted to voxels so edges stay about one voxel soft at any size.
    ul = np.linspace(-1.0, 1.0, nx, dtype=np.float32)
    vl = np.linspace(-1.0, 1.0, ny, dtype=np.float32)
    wl = np.linspace(-1.0, 1.0, nz, dtype=np.float32)[k0:k1]
    u, v, w = ul[None, None, :], vl[:, None][None], wl[:, None, None]
    half = min(nx / 2.0, ny / 2.0, nz / 2.0 * spacing[2] / spacing[0])

    def ellipsoid(c, a, s=(slice(None),) * 3):
        q = np.sqrt(((u[..., s[2]] - c[0]) / a[0]) ** 2 + ((v[:, s[1]] - c[1]) / a[1]) ** 2
                    + ((w[s[0]] - c[2]) / a[2]) ** 2)
        return (q - 1.0) * (min(a) * half)

    def box(c, a, pad):
        """Slab index ranges (z, y, x) around a small object; None when it misses the slab."""
        out = []
        for axis, ci, ai in ((wl, c[2], a[2]), (vl, c[1], a[1]), (ul, c[0], a[0])):
            idx = np.flatnonzero(np.abs(axis - ci) <= ai + pad)
            if idx.size == 0:
                return None
            out.append(slice(int(idx[0]), int(idx[-1]) + 1))
        return tuple(out)

    def add_small(val, weight, c, a, width):
        # Small objects are evaluated only in their bounding box: most of the cost otherwise.
        s = box(c, a, 8.0 * width / half)
        if s is not None:
            val[s] += weight * _edge(ellipsoid(c, a, s), width)

    head_c, head_a = (0.0, 0.0, 0.15), (0.68, 0.8, 0.72)
    neck = np.maximum(np.sqrt(u ** 2 + (v - 0.1) ** 2) - 0.36, w + 0.2) * half
    skin = _edge(np.minimum(ellipsoid(head_c, head_a), neck), 1.0)
    skull_out = _edge(ellipsoid(head_c, tuple(0.92 * a for a in head_a)), 0.8)
    skull_in = _edge(ellipsoid(head_c, tuple(0.82 * a for a in head_a)), 0.8)

    val = 1000.0 * skin                       # skin and soft tissue
    val += 1200.0 * (skull_out - skull_in)    # bone shell, ~2200
    val += 50.0 * skull_in                    # brain, slightly denser than tissue
    for cx in (-0.14, 0.14):                  # fluid-filled ventricles
        add_small(val, -40.0, (cx, -0.05, 0.2), (0.08, 0.22, 0.1), 0.8)
    for cx in (-0.25, 0.25):                  # eyes
        add_small(val, -30.0, (cx, -0.62, 0.05), (0.11, 0.11, 0.11), 0.8)
    add_small(val, 1600.0, (0.05, 0.3, 0.35), (0.04, 0.04, 0.04), 0.6)   # a small dense calcification
    s = box((0.0, 0.22, -0.675), (0.11, 0.11, 0.325), 8.0 * 0.8 / half)
    if s is not None:                         # vertebrae below the skull
        uu, vv, ww = u[..., s[2]], v[:, s[1]], w[s[0]]
        spine = _edge(np.maximum(np.sqrt(uu ** 2 + (vv - 0.22) ** 2) - 0.11, ww + 0.35) * half, 0.8)
        val[s] += 1000.0 * spine * (1.0 - skull_out[s])
    val = val.astype(np.float32, copy=False)
    if noise > 0:
        for k in range(k0, k1):
            rng = np.random.default_rng((seed, k))
            val[k - k0] += rng.normal(0.0, noise, size=(ny, nx)).astype(np.float32)
    return val


def _ct_slabs(dims, spacing, seed, noise, dtype):
    """Yield ``(k0, k1, samples)`` slab by slab, already cast to ``dtype``."""
    nx, ny, nz = dims
    step = max(1, _SLAB_VOXELS // (nx * ny))
    info = np.iinfo(dtype)
    for k0 in range(0, nz, step):
        k1 = min(nz, k0 + step)
        slab = _ct_slab(k0, k1, dims, spacing, seed, noise)
        yield k0, k1, np.clip(np.rint(slab), max(info.min, 0), info.max).astype(dtype)


def _ct_dtype(dtype):
    dt = np.dtype(dtype)
    if dt not in (np.dtype("int16"), np.dtype("uint16")):
        raise InputError(f"ct_phantom dtype must be int16 or uint16, got {dtype!r}")
    return dt


def ct_phantom(size=128, *, seed=0, dtype="int16", spacing=(1.0, 1.0, 1.0), noise=20.0) -> Volume:
    """A CT-like head phantom: air ~0, skin and soft tissue ~1000, skull ~2200.

    Edges are about one voxel soft and there is Gaussian noise, so an iso
    value of 600 finds the skin and 1500 the bone. Built slab by slab, so
    large sizes cost little beyond the output array.

    Parameters
    ----------
    size : int or (nx, ny, nz)
    seed : int
        Noise seed; the noise of slice ``k`` depends only on ``(seed, k)``.
    dtype : {'int16', 'uint16'}
    spacing : (sx, sy, sz)
        Anisotropic spacing such as ``(1, 1, 2)`` is fine; the phantom fills
        the box either way.
    noise : float
        Noise standard deviation in sample units.

    Returns
    -------
    Volume
        ``meta['iso'] = 600.5`` (skin), ``meta['bone_iso'] = 1500.5``.
    """
    dims = _dims(size)
    dt = _ct_dtype(dtype)
    nx, ny, nz = dims
    data = np.empty((nz, ny, nx), dtype=dt)
    for k0, k1, slab in _ct_slabs(dims, tuple(spacing), seed, noise, dt):
        data[k0:k1] = slab
    return Volume(data, spacing=spacing, name=_label("ct_phantom", dims),
                  meta={"iso": 600.5, "bone_iso": 1500.5, "seed": seed, "synthetic": "ct_phantom"})


def ct_phantom_to_disk(path, shape=(512, 512, 512), *, seed=0, dtype="int16",
                       spacing=(1.0, 1.0, 1.0), noise=20.0) -> Path:
    """Stream :func:`ct_phantom` samples to a file slab by slab, for sizes too big for memory.

    Parameters
    ----------
    path : str or Path
        ``.nrrd`` (raw-encoded, header written here) or ``.raw`` (samples
        only, little-endian; name it like ``ct_512x512x512_int16.raw`` so it
        loads without options).
    shape : (nx, ny, nz)
    seed, dtype, spacing, noise
        As for :func:`ct_phantom`; the samples are identical.

    Returns
    -------
    Path
    """
    path = Path(path)
    dims = _dims(shape, "shape")
    dt = _ct_dtype(dtype)
    ext = path.suffix.lower()
    if ext not in (".nrrd", ".raw"):
        raise InputError(f"{path}: the streaming phantom writer makes .nrrd or .raw files")
    sx, sy, sz = (float(s) for s in spacing)
    try:
        with open(path, "wb") as f:
            if ext == ".nrrd":
                f.write((
                    "NRRD0004\n"
                    f"type: {dt.name}\n"
                    "dimension: 3\n"
                    "space dimension: 3\n"
                    f"sizes: {dims[0]} {dims[1]} {dims[2]}\n"
                    f"space directions: ({sx!r},0,0) (0,{sy!r},0) (0,0,{sz!r})\n"
                    "kinds: domain domain domain\n"
                    "endian: little\n"
                    "encoding: raw\n"
                    "space origin: (0,0,0)\n\n").encode("ascii"))
            for _, _, slab in _ct_slabs(dims, (sx, sy, sz), seed, noise, dt):
                slab.astype(dt.newbyteorder("<"), copy=False).tofile(f)
    except OSError as exc:
        raise InputError(f"{path}: cannot write: {exc.strerror or exc}") from None
    return path


def trilinear_field(size, coeffs=None, *, seed=0, dtype="float64",
                    spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)) -> Volume:
    """Samples of an exact trilinear function of the sample indices.

    ``F(i, j, k) = c0 + c1 i + c2 j + c3 k + c4 i j + c5 j k + c6 k i + c7 i j k``
    with ``i`` along x, ``j`` along y, ``k`` along z (sample ``data[k, j, i]``).
    Trilinear interpolation reproduces ``F`` exactly inside every cell, so
    isosurfaces of this volume are known in closed form.

    Parameters
    ----------
    size : int or (nx, ny, nz)
    coeffs : sequence of 8 numbers, optional
        ``(c0, ..., c7)``; random small integers (``c7 != 0``) when omitted,
        so that every sample is exactly representable.
    seed : int
        For the random coefficients.
    dtype : str
        Sample type; integer types must hold every value.
    spacing, origin : (x, y, z)

    Returns
    -------
    Volume
        ``meta['coeffs']`` (the 8 coefficients as Python numbers),
        ``meta['exact']`` (whether the stored samples equal ``F`` exactly) and
        ``meta['iso']`` (a level strictly inside the value range).
    """
    dims = _dims(size)
    if coeffs is None:
        rng = np.random.default_rng(seed)
        c = [int(v) for v in rng.integers(-4, 5, size=8)]
        c[7] = int(rng.choice([-2, -1, 1, 2]))
    else:
        c = [v.item() if isinstance(v, np.generic) else v for v in coeffs]
        if len(c) != 8:
            raise InputError(f"trilinear_field needs 8 coefficients, got {len(c)}")
    integral = all(isinstance(v, (int, np.integer)) for v in c)
    work = np.int64 if integral else np.float64
    nx, ny, nz = dims
    i = np.arange(nx, dtype=work)[None, None, :]
    j = np.arange(ny, dtype=work)[None, :, None]
    k = np.arange(nz, dtype=work)[:, None, None]
    f = (c[0] + c[1] * i + c[2] * j + c[3] * k
         + c[4] * i * j + c[5] * j * k + c[6] * k * i + c[7] * i * j * k)
    f = np.broadcast_to(f, (nz, ny, nx))
    dt = np.dtype(dtype)
    if dt.kind in "iu":
        info = np.iinfo(dt)
        if f.min() < info.min or f.max() > info.max:
            raise InputError(f"trilinear_field values {f.min()}..{f.max()} do not fit {dt.name}")
    data = np.ascontiguousarray(f.astype(dt))
    exact = bool(np.array_equal(data.astype(f.dtype) if dt.kind != "f" else data, f))
    lo, hi = float(f.min()), float(f.max())
    iso = lo + 0.5 * (hi - lo) + (0.25 if hi - lo > 1 else 0.0)
    return Volume(data, spacing=spacing, origin=origin, name=_label("trilinear_field", dims),
                  meta={"coeffs": tuple(c), "exact": exact, "iso": iso, "synthetic": "trilinear_field"})


def builtin_volume(size=64) -> Volume:
    """The volume ``parc render`` shows when given none: a soft torus with blobs through it (uint8).

    Parameters
    ----------
    size : int or (nx, ny, nz)

    Returns
    -------
    Volume
        ``meta['iso'] = 127.5``.
    """
    dims = _dims(size)
    ext = min(dims) - 1
    ring = torus(dims).data.astype(np.float32)
    density = _edge(ring, 0.02 * ext + 0.5)
    c = np.array([(n - 1) / 2.0 for n in dims])
    centers = [c + ext * np.array(d) for d in
               ((0.0, 0.0, 0.0), (0.3, 0.0, 0.18), (-0.3, 0.0, -0.18), (0.0, 0.3, -0.18), (0.0, -0.3, 0.18))]
    lumps = _gaussians(dims, centers, [0.09 * ext, 0.06 * ext, 0.06 * ext, 0.06 * ext, 0.06 * ext],
                       [1.0, 0.9, 0.9, 0.9, 0.9])
    data = np.clip(np.rint(255.0 * np.maximum(density, lumps)), 0, 255).astype(np.uint8)
    return Volume(data, name=_label("builtin", dims), meta={"iso": 127.5, "synthetic": "builtin"})


#: ``parc make NAME``: name → function(size=..., ...) returning a Volume.
SYNTHETIC = {
    "sphere": sphere,
    "torus": torus,
    "marschner_lobb": marschner_lobb,
    "blobs": blobs,
    "neuron": neuron,
    "floor": floor,
    "ct_phantom": ct_phantom,
    "trilinear_field": trilinear_field,
    "builtin": builtin_volume,
}

#: One line per registry entry, for ``parc make --help``.
DESCRIPTIONS = {
    "sphere": "float32 signed distance to a centred sphere (iso 0)",
    "torus": "float32 signed distance to a torus around z (iso 0)",
    "marschner_lobb": "float32 Marschner-Lobb signal on [-1,1]^3, alpha 0.25, f_M 6 (iso 0.5)",
    "blobs": "uint8 noisy Gaussian blobs, like confocal microscopy (iso 100.5)",
    "neuron": "uint8 confocal-like pyramidal neuron: soma, branching dendrites, blur, photon noise (iso 80.5)",
    "floor": "uint8 volumetric floor: a closed slab with a checker relief, n x n x max(8, n/8) (iso 127.5)",
    "ct_phantom": "int16 CT-like head phantom: skin iso 600, bone iso 1500",
    "trilinear_field": "float64 exact trilinear function of the indices (random small integer coefficients)",
    "builtin": "uint8 torus with blobs: the default volume of parc render (iso 127.5)",
}


def make_synthetic(name, size=None, **kwargs) -> Volume:
    """Build the registry volume ``name``; ``size=None`` keeps the function's default.

    Raises
    ------
    InputError
        Unknown name (the message lists the known ones).
    """
    if name not in SYNTHETIC:
        raise InputError(f"unknown synthetic volume {name!r}; choose from {', '.join(SYNTHETIC)}")
    fn = SYNTHETIC[name]
    if size is None:
        return fn(16, **kwargs) if fn is trilinear_field else fn(**kwargs)
    return fn(size, **kwargs)
