"""Primary rays from the camera, one pixel at a time, and how the parallel loops deal out their
work: image tiles of `TILE_W` x `TILE_H` pixels (`tile_rect`, `dealt_tile`), spread over the
threads so that each takes tiles from all over the image (`spread`), and runs of cells or values
for the passes over a volume (`chunk_count`, `chunk_run`).

The camera is unpacked at the boundary (`parc.camera.Camera.as_array`) into
``cam = [eye(3), f(3), r(3), u(3), tan(fov/2), parallel_scale, parallel]``
(15 numbers); this is DESIGN's ray formula for the kernels, and
`parc.camera.Camera.rays` its NumPy twin.
"""
import math

from .config import SPREAD_CHUNK, SPREAD_WAYS, TILE_H, TILE_W, kernel


@kernel(inline="always")
def camera_ray(cam, width, height, x, y):
    """World ray ``(ox, oy, oz, dx, dy, dz)`` through the centre of pixel (x, y), y down."""
    sx = (2.0 * (x + 0.5) / width - 1.0) * (width / height)
    sy = 1.0 - 2.0 * (y + 0.5) / height
    if cam[14] != 0.0:
        ps = cam[13]
        ox = cam[0] + ps * (sx * cam[6] + sy * cam[9])
        oy = cam[1] + ps * (sx * cam[7] + sy * cam[10])
        oz = cam[2] + ps * (sx * cam[8] + sy * cam[11])
        return ox, oy, oz, cam[3], cam[4], cam[5]
    th = cam[12]
    dx = cam[3] + th * (sx * cam[6] + sy * cam[9])
    dy = cam[4] + th * (sx * cam[7] + sy * cam[10])
    dz = cam[5] + th * (sx * cam[8] + sy * cam[11])
    inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
    return cam[0], cam[1], cam[2], dx * inv, dy * inv, dz * inv


@kernel
def spread(it, n, group=1, ways=SPREAD_WAYS):
    """The work item (``0 .. n-1``) iteration ``it`` of a parallel loop over ``n`` items takes.

    Numba's ``prange`` gives each thread one contiguous run of iterations
    (``numba.parallel_chunksize`` did not change that on the OpenMP or
    workqueue layers), and costly work clusters: the tiles where the
    volume is, the hits of one surface. So the items, in runs of ``group``
    (a row of tiles; ``n`` a multiple of it), are dealt like cards into
    ``ways`` shares, one per thread: share ``q`` (the ``q``-th run of iterations) takes
    runs ``q, q + ways, q + 2 ways, ...``. Each thread then gets an even
    sample of the image, as a golden-ratio stride over single tiles also
    gave (casting the Fig. 13 floor: no gain from two threads before
    either), and, unlike it, walks the image in order, next to the tiles
    it just cast, whose cells and skip-table entries are still in its
    caches (PARC's CT head cast at 512x512 on two threads: 14 ms instead
    of 17; `brute`'s translucent CT head at 300x300: 0.15 s instead of 0.26).
    """
    g = it // group
    return _deal(g, n // group, ways) * group + (it - g * group)


@kernel
def _deal(it, n, ways):
    """Item ``it`` of ``0 .. n-1`` read share by share, share ``q`` holding ``q, q + ways, ...``."""
    m = (n + ways - 1) // ways
    full = n - (m - 1) * ways          # shares of m items; the rest have m - 1
    if it < full * m:
        q = it // m
        r = it - q * m
    else:
        rest = it - full * m
        q = full + rest // (m - 1)
        r = rest - (q - full) * (m - 1)
    return r * ways + q


@kernel
def chunk_count(n, size):
    """Runs of ``size`` items covering ``n`` items (the last may be shorter)."""
    return (n + size - 1) // size


@kernel
def chunk_run(c, size, n):
    """Items ``lo <= m < hi`` of run ``c`` of `chunk_count(n, size)` runs."""
    lo = c * size
    return lo, min(n, lo + size)


@kernel
def spread_runs(n):
    """Runs of `SPREAD_CHUNK` items covering ``n`` single rays or pixels."""
    return chunk_count(n, SPREAD_CHUNK)


@kernel
def spread_run(it, runs, n):
    """Items ``lo <= m < hi`` that iteration ``it`` of a loop over `spread_runs(n)` runs takes."""
    lo = spread(it, runs) * SPREAD_CHUNK
    return lo, min(n, lo + SPREAD_CHUNK)


@kernel
def tiles_across(width, tile_w):
    """Tiles in one row of tiles of an image ``width`` wide."""
    return (width + tile_w - 1) // tile_w


@kernel
def tile_count(width, row0, row1, tile_w, tile_h):
    """Tiles covering rows ``row0 <= y < row1`` of an image ``width`` wide."""
    return tiles_across(width, tile_w) * ((row1 - row0 + tile_h - 1) // tile_h)


@kernel
def tile_rect(tile, width, row0, row1, tile_w, tile_h):
    """Pixel rectangle ``(x0, x1, y0, y1)`` (ends exclusive) of tile number ``tile``."""
    tiles_x = tiles_across(width, tile_w)
    ty = tile // tiles_x
    tx = tile - ty * tiles_x
    y0 = row0 + ty * tile_h
    x0 = tx * tile_w
    return x0, min(width, x0 + tile_w), y0, min(row1, y0 + tile_h)


@kernel
def dealt_tile(it, tiles, width, row0, row1):
    """Pixel rectangle ``(x0, x1, y0, y1)`` that iteration ``it`` of a parallel loop over the
    ``tiles = tile_count(width, row0, row1, TILE_W, TILE_H)`` image tiles casts: whole rows
    of tiles dealt to the threads (`spread`)."""
    return tile_rect(spread(it, tiles, tiles_across(width, TILE_W)), width, row0, row1, TILE_W, TILE_H)
