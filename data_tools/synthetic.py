"""Synthetic volumes by name (`parc make NAME`): analytic fields, exact-trilinear test fields,
noisy blobs here; a confocal neuron and a floor for shadows (`data_tools.neuron`) and CT-like
phantoms (`data_tools.phantom`), all importable from here."""
from __future__ import annotations

import math

import numpy as np

from .errors import InputError
from . import memory
from .memory import check_memory
from .grids import grid_axes, grid_dims, soft_inside, volume_label
from .neuron import floor, floor_height, neuron
from .phantom import ct_phantom, ct_phantom_to_disk
from .volume import Volume, hand_over

__all__ = ["DESCRIPTIONS", "ISOVALUES", "SYNTHETIC", "blobs", "builtin_volume", "ct_phantom", "ct_phantom_to_disk", "floor",
           "make_synthetic", "marschner_lobb", "neuron", "sphere", "torus", "trilinear_field"]
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
    dims = grid_dims(size)
    center = tuple((n - 1) / 2.0 for n in dims)
    radius = radius_fraction * (min(dims) - 1)
    x, y, z = grid_axes(dims)
    dist = np.sqrt((x - center[0]) ** 2 + (y - center[1]) ** 2 + (z - center[2]) ** 2) - radius
    return Volume(hand_over(dist.astype(np.float32)), name=volume_label("sphere", dims),
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
    dims = grid_dims(size)
    ext = min(dims) - 1
    center = tuple((n - 1) / 2.0 for n in dims)
    big_r, small_r = major_fraction * ext, minor_fraction * ext
    x, y, z = grid_axes(dims)
    ring = np.sqrt((x - center[0]) ** 2 + (y - center[1]) ** 2) - big_r
    dist = np.sqrt(ring ** 2 + (z - center[2]) ** 2) - small_r
    return Volume(hand_over(dist.astype(np.float32)), name=volume_label("torus", dims),
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
    dims = grid_dims(size)
    spacing = tuple(2.0 / (n - 1) for n in dims)
    x, y, z = grid_axes(dims, spacing, (-1.0, -1.0, -1.0))
    r = np.sqrt(x ** 2 + y ** 2)
    rho_r = np.cos(2 * np.pi * f_m * np.cos(np.pi * r / 2))
    rho = (1 - np.sin(np.pi * z / 2) + alpha * (1 + rho_r)) / (2 * (1 + alpha))
    return Volume(hand_over(rho.astype(np.float32)), spacing=spacing, origin=(-1.0, -1.0, -1.0),
                  name=volume_label("marschner_lobb", dims),
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
    dims = grid_dims(size)
    rng = np.random.default_rng(seed)
    ext = np.array(dims, dtype=np.float64) - 1
    centers = rng.uniform(0.2, 0.8, size=(count, 3)) * ext
    sigmas = rng.uniform(0.04, 0.10, size=count) * ext.min()
    amps = rng.uniform(0.5, 1.0, size=count)
    field = _gaussians(dims, centers, sigmas, amps)
    field += rng.normal(0.0, noise, size=field.shape).astype(np.float32)
    # A dim constant offset, as in real stacks: the background is not exactly zero.
    data = np.clip(np.rint(20.0 + 215.0 * field), 0, 255).astype(np.uint8)
    return Volume(hand_over(data), name=volume_label("blobs", dims),
                  meta={"iso": 100.5, "seed": seed, "synthetic": "blobs"})


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
        ``meta['iso']`` (a level strictly inside the value range; for a constant field, its value).
    """
    dims = grid_dims(size)
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
    # Compare in the type of F: comparing float samples with int64 F would round F the same way.
    exact = bool(np.array_equal(data.astype(f.dtype), f))
    lo, hi = float(f.min()), float(f.max())
    iso = lo + 0.5 * (hi - lo) + (0.25 if hi - lo > 1 else 0.0)
    return Volume(hand_over(data), spacing=spacing, origin=origin, name=volume_label("trilinear_field", dims),
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
    dims = grid_dims(size)
    ext = min(dims) - 1
    ring = torus(dims).data.astype(np.float32)
    density = soft_inside(ring, 0.02 * ext + 0.5)
    c = np.array([(n - 1) / 2.0 for n in dims])
    centers = [c + ext * np.array(d) for d in
               ((0.0, 0.0, 0.0), (0.3, 0.0, 0.18), (-0.3, 0.0, -0.18), (0.0, 0.3, -0.18), (0.0, -0.3, 0.18))]
    lumps = _gaussians(dims, centers, [0.09 * ext, 0.06 * ext, 0.06 * ext, 0.06 * ext, 0.06 * ext],
                       [1.0, 0.9, 0.9, 0.9, 0.9])
    data = np.clip(np.rint(255.0 * np.maximum(density, lumps)), 0, 255).astype(np.uint8)
    return Volume(hand_over(data), name=volume_label("builtin", dims), meta={"iso": 127.5, "synthetic": "builtin"})


#: Peak memory of a generator per sample, with room (measured 13-34 bytes at
#: 48 and 96 samples a side): float64 coordinate grids and field before conversion.
SYNTHETIC_BYTES_PER_SAMPLE = 48
#: The same for generators built slab by slab, whose peak is little beyond the
#: output (ct_phantom: about 4.4 bytes a sample at 600 and 700 a side).
SLAB_BYTES_PER_SAMPLE = {"ct_phantom": 6}

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
    "ct_phantom": "int16 CT-like head phantom: skin iso 600.5, bone iso 1500.5",
    "trilinear_field": "float64 exact trilinear function of the indices (random small integer coefficients)",
    "builtin": "uint8 torus with blobs: the default volume of parc render (iso 127.5)",
}


#: The isovalues each registry entry is made for (`DESCRIPTIONS` names them): ``parc make``
#: says how to render what it wrote.
ISOVALUES = {"sphere": (0.0,), "torus": (0.0,), "marschner_lobb": (0.5,), "blobs": (100.5,), "neuron": (80.5,),
             "floor": (127.5,), "ct_phantom": (600.5, 1500.5), "trilinear_field": (), "builtin": (127.5,)}


def check_synthetic_size(size, what, name=None):
    """Refuse a size (samples per axis: one number or three) whose volume ``name`` would not
    fit in memory while it is made."""
    try:
        dims = np.broadcast_to(np.asarray(size, dtype=float), 3).copy()
    except OverflowError:           # an integer past float's range (--size 10**400): no memory holds it
        dims = np.full(3, np.inf)
    if name == "floor" and np.ndim(size) == 0 and np.isfinite(dims).all():
        dims[2] = floor_height(int(size))
    per_sample = SLAB_BYTES_PER_SAMPLE.get(name, SYNTHETIC_BYTES_PER_SAMPLE)
    have = memory.available_memory()
    need = per_sample * float(np.prod(dims))
    if have is None or need <= have:
        return
    hint = ""
    if np.ndim(size) == 0:
        # The largest size that fits, for one number a side (a floor's height follows its side).
        def fits(n):
            return per_sample * n * n * (floor_height(n) if name == "floor" else n) <= have
        lo, hi = 1, 2
        while fits(hi):
            lo, hi = hi, hi * 2
        while hi - lo > 1:
            mid = (lo + hi) // 2
            lo, hi = (mid, hi) if fits(mid) else (lo, mid)
        if lo >= 2:
            hint = f": give a size of at most {lo} here"
    check_memory(need, what, hint)


#: Synthetic volumes from this many samples up take seconds to make (neuron at 300: 4 s, at 600:
#: 25 s), which a run says first (`making_note`) so that it does not look hung.
LARGE_SYNTHETIC_SAMPLES = 300 ** 3


def making_note(name, size):
    """``making NAME NxNxN (S samples) ...`` for a volume of at least `LARGE_SYNTHETIC_SAMPLES`
    samples (``size`` one number or three), else None."""
    if size is None:
        return None
    dims = [int(size)] * 3 if np.ndim(size) == 0 else [int(n) for n in size]
    if name == "floor" and np.ndim(size) == 0:
        dims[2] = floor_height(int(size))
    samples = math.prod(dims)
    if samples < LARGE_SYNTHETIC_SAMPLES:
        return None
    return f"making {name} {'x'.join(map(str, dims))} ({samples:,} samples) ..."


def default_size(name):
    """The samples per axis `make_synthetic` gives the volume ``name`` without a size."""
    import inspect
    fn = SYNTHETIC[name]
    return 16 if fn is trilinear_field else inspect.signature(fn).parameters["size"].default


def make_synthetic(name, size=None, **kwargs) -> Volume:
    """Build the registry volume ``name``; ``size=None`` keeps the function's default (16 for
    `trilinear_field`, which has none).

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
