"""Bricked sample storage (Parker et al. 1998, §2.2 and Appendix B), so its worth can be measured.

Parker et al. reorder the volume into bricks of ``n^3`` samples, grouped
``m^3`` to a macrobrick, so that a cell's eight corners share a cache line
or two and a ray's neighbouring cells share pages; the offset of sample
``(x, y, z)`` is ``Fx[x] + Fy[y] + Fz[z]``, three per-axis tables that
replace the divisions and remainders of the bricked address. Every
caster reads samples through `raycast.traverse.cell_corners` and the
grid's size through `raycast.traverse.grid_shape`, so a `BrickedSamples`
goes wherever a linear ``(nz, ny, nx)`` array does and gives the same
images, bit for bit.

The renderer keeps samples linear: ``benchmarks/bricking.py`` times both
layouts with the same kernels, and on the 2-core machine the project is
measured on, bricks made the unaccelerated caster 1-28% slower (the
tables cost more than the cache lines they save, and the hardware
prefetcher already follows a linear walk); PARC's isosurface cast was
within noise of linear on the real volumes and 4-7% faster only on a
910 MB one, and its translucent cast 4-10% slower (benchmarks/README.md).
"""
from collections import namedtuple

import numpy as np

#: ``flat``: the samples, brick by brick; ``fx``, ``fy``, ``fz``: each axis's
#: offset table (``flat[fz[k] + fy[j] + fx[i]]`` is sample ``(i, j, k)``);
#: ``nz``, ``ny``, ``nx``: the grid's size (`raycast.traverse.grid_shape`).
BrickedSamples = namedtuple("BrickedSamples", "flat fx fy fz nz ny nx")

#: Parker et al.'s sizes for 16-bit samples: 4^3-sample bricks (128 bytes,
#: their cache line) in 5^3-brick macrobricks.
BRICK = 4
MACRO = 5


def brick_tables(shape, n=BRICK, m=MACRO):
    """The per-axis offset tables ``(fz, fy, fx)`` of Appendix B for a ``(nz, ny, nx)`` grid,
    padded to whole macrobricks, and the padded sample count."""
    if not (isinstance(n, int) and isinstance(m, int) and n >= 1 and m >= 1):
        raise ValueError(f"brick sizes must be whole numbers of at least 1, got n={n!r}, m={m!r}")
    side = n * m
    pz, py, px = (-(-int(s) // side) * side for s in shape)
    macro = side ** 3
    brick = n ** 3

    def table(size, macro_stride, brick_stride, sample_stride):
        c = np.arange(size, dtype=np.int64)
        return ((c // side) * macro_stride + ((c // n) % m) * brick_stride + (c % n) * sample_stride)

    # Macrobricks z-major, then bricks within a macrobrick, then samples within a brick.
    fz = table(shape[0], (py // side) * (px // side) * macro, m * m * brick, n * n)
    fy = table(shape[1], (px // side) * macro, m * brick, n)
    fx = table(shape[2], macro, brick, 1)
    return fz, fy, fx, pz * py * px


def brick(data, n=BRICK, m=MACRO):
    """A `BrickedSamples` copy of a ``(nz, ny, nx)`` sample array (the padding holds zeros)."""
    data = np.asarray(data)
    if data.ndim != 3 or min(data.shape) < 2:
        raise ValueError(f"bricks need a 3-D grid of at least 2 samples a side, got shape {data.shape}")
    fz, fy, fx, total = brick_tables(data.shape, n, m)
    flat = np.zeros(total, data.dtype)
    rows = fy[:, None] + fx[None, :]
    for k in range(data.shape[0]):        # a slice at a time: no index array the size of the volume
        flat[fz[k] + rows] = data[k]
    flat.flags.writeable = False
    return BrickedSamples(flat, fx, fy, fz, *(int(s) for s in data.shape))


def bricked_corners(data, i, j, k):
    """`raycast.traverse.cell_corners` for a `BrickedSamples`: six table reads, eight loads."""
    flat, fx, fy, fz = data.flat, data.fx, data.fy, data.fz
    x0, x1, y0, y1, z0, z1 = fx[i], fx[i + 1], fy[j], fy[j + 1], fz[k], fz[k + 1]
    return (np.float64(flat[z0 + y0 + x0]), np.float64(flat[z0 + y0 + x1]),
            np.float64(flat[z0 + y1 + x0]), np.float64(flat[z0 + y1 + x1]),
            np.float64(flat[z1 + y0 + x0]), np.float64(flat[z1 + y0 + x1]),
            np.float64(flat[z1 + y1 + x0]), np.float64(flat[z1 + y1 + x1]))
