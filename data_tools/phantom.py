"""CT-like phantoms: a head-like body of soft tissue, skull and inner structures, at any size.

Built slab by slab (bounded memory), in memory or straight to a raw file
(`ct_phantom_to_disk`, for the Visible Woman-scale benchmark).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import InputError, os_reason
from .grids import grid_dims, soft_inside, volume_label
from .volume import Volume, _triple, hand_over


#: Voxels per slab when phantoms are built slab by slab (bounds temporary memory).
_SLAB_VOXELS = 1 << 22


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
            val[s] += weight * soft_inside(ellipsoid(c, a, s), width)

    head_c, head_a = (0.0, 0.0, 0.15), (0.68, 0.8, 0.72)
    neck = np.maximum(np.sqrt(u ** 2 + (v - 0.1) ** 2) - 0.36, w + 0.2) * half
    skin = soft_inside(np.minimum(ellipsoid(head_c, head_a), neck), 1.0)
    skull_out = soft_inside(ellipsoid(head_c, tuple(0.92 * a for a in head_a)), 0.8)
    skull_in = soft_inside(ellipsoid(head_c, tuple(0.82 * a for a in head_a)), 0.8)

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
        spine = soft_inside(np.maximum(np.sqrt(uu ** 2 + (vv - 0.22) ** 2) - 0.11, ww + 0.35) * half, 0.8)
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
    dims = grid_dims(size)
    dt = _ct_dtype(dtype)
    # Checked here, not by the Volume at the end: the slabs divide by it.
    spacing = _triple(spacing, "spacing", volume_label("ct_phantom", dims), positive=True)
    nx, ny, nz = dims
    data = np.empty((nz, ny, nx), dtype=dt)
    for k0, k1, slab in _ct_slabs(dims, spacing, seed, noise, dt):
        data[k0:k1] = slab
    return Volume(hand_over(data), spacing=spacing, name=volume_label("ct_phantom", dims),
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
    dims = grid_dims(shape, "shape")
    dt = _ct_dtype(dtype)
    ext = path.suffix.lower()
    if ext not in (".nrrd", ".raw"):
        raise InputError(f"{path}: the streaming phantom writer makes .nrrd or .raw files")
    # Checked before the file is opened: a spacing refused halfway would leave a header without
    # its samples.
    sx, sy, sz = _triple(spacing, "spacing", str(path), positive=True)
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
        raise InputError(f"{path}: cannot write: {os_reason(exc)}") from None
    return path
