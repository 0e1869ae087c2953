"""Per-pixel work arrays reused from one frame to the next, the memory a frame needs, and the
bands of rows a frame is cast in (`row_bands`).

A 512x512 frame fills about 25 MB of per-pixel arrays (the raster
read-back and segments, the caster's cells, local coordinates and counts).
Allocated anew each frame, every page of them is faulted in again: 4 ms of
a 20 ms PARC frame on the iron protein at 512x512 (measured against the
same process with glibc told to keep freed memory), and part of every
`brute` frame. Arrays that never leave a render are taken from here
instead; what a render returns (image, depth) is always new.

The contents of a work array are undefined when it is handed out. Only
the arrays of recent frames are kept, up to `KEEP_BYTES`.
"""
from __future__ import annotations

import numpy as np

from data_tools.memory import check_memory

#: Bytes of work arrays kept between frames; a frame needing more gets fresh ones.
KEEP_BYTES = 256 << 20

#: Memory a frame takes per pixel, beyond the volume, with room to spare:
#: peak resident size of ``parc render`` at 4096x4096 less a 16x16 render's,
#: per pixel: isosurface 90 (brute) and 105 bytes (PARC), CT head
#: translucent with depth buffers and bit planes 170 bytes.
FRAME_BYTES_PER_PIXEL = 200
#: ... and each volume beyond the first: its segments, their stacked copy, a MIP or average
#: layer's depth and colour (measured 20 to 48 bytes a pixel, 2026-12-01), with room. Charged the
#: first volume's whole, 20 isosurfaces at 3000x3000 were refused as needing 33 GB; they took 0.9.
EXTRA_VOLUME_BYTES_PER_PIXEL = 96

_ARRAYS: dict = {}


def work_array(name, shape, dtype=np.float64):
    """A C-contiguous array for ``name``, reused by later calls with the same name, shape and dtype.

    Parameters
    ----------
    name : hashable
        What the array holds in its frame, e.g. ``("seg", 0)``; two arrays
        alive at once need two names.
    shape : tuple of int
    dtype : numpy dtype, default float64

    Returns
    -------
    ndarray
        Uninitialized contents.
    """
    shape = tuple(int(s) for s in shape)
    dtype = np.dtype(dtype)
    arr = _ARRAYS.get(name)
    if arr is not None and arr.shape == shape and arr.dtype == dtype:
        return arr
    arr = np.empty(shape, dtype)
    _ARRAYS.pop(name, None)
    if arr.nbytes <= KEEP_BYTES:
        while _ARRAYS and sum(a.nbytes for a in _ARRAYS.values()) + arr.nbytes > KEEP_BYTES:
            _ARRAYS.pop(next(iter(_ARRAYS)))
        _ARRAYS[name] = arr
    return arr


def release():
    """Drop every kept work array (their memory goes back once nothing else holds them)."""
    _ARRAYS.clear()


#: Memory of an image a caller keeps per pixel (RGBA float32 and float64 depth, with room).
KEPT_IMAGE_BYTES_PER_PIXEL = 32


#: Memory a frame takes per pixel and light source: the diffuse, specular and visibility terms of
#: every lit pixel (float64 each, `parc.multivolume`), the visibility's copy in the samples' order
#: and a mask, with room (32 fell short: 100 suns on shadowed samples took over 40 a sample).
LIGHT_BYTES_PER_PIXEL = 56

#: Memory of a recorded translucent sample (`raycast.merged.SampleRecord`, its material and the
#: copies its shadow rays take), with room; and of its terms per light, as for a pixel.
SAMPLE_BYTES = 192

#: Stand-ins for a kernel's arguments that a render does not use (its flag says so): no segments
#: (`brute`), no surface to stop at, no bit planes. Never written, and writable as the used ones
#: are, so that the kernels compile once for both.
NO_SEGMENTS = np.empty((1, 1, 2))
NO_STOP = np.empty((1, 1))
NO_BITS = np.zeros((1, 1, 1), np.uint32)


def check_frame_memory(width, height, layers=1, kept_images=0, lights=0, samples=0, sample_lights=0):
    """Refuse, with one line, a frame whose per-pixel arrays would not fit in memory.

    ``layers`` counts the volumes whose per-pixel arrays are alive at once;
    ``lights`` the scene's light sources, whose shading terms take
    `LIGHT_BYTES_PER_PIXEL` each; ``kept_images`` the finished images held
    meanwhile (a comparison keeps one per method); ``samples`` the
    translucent samples recorded at once, each `SAMPLE_BYTES` and
    `LIGHT_BYTES_PER_PIXEL` per light of ``sample_lights``. Without the check a huge
    image stops on NumPy's allocation error, or the system kills the process
    once the pages are touched.

    Raises
    ------
    InputError
        The estimate (`FRAME_BYTES_PER_PIXEL` per pixel, and
        `EXTRA_VOLUME_BYTES_PER_PIXEL` for each further layer,
        `LIGHT_BYTES_PER_PIXEL` per pixel and light) exceeds the memory
        available.
    """
    need = int(width) * int(height) * (FRAME_BYTES_PER_PIXEL + EXTRA_VOLUME_BYTES_PER_PIXEL * max(0, int(layers) - 1)
                                       + LIGHT_BYTES_PER_PIXEL * int(lights)
                                       + KEPT_IMAGE_BYTES_PER_PIXEL * int(kept_images))
    need += int(samples) * (SAMPLE_BYTES + LIGHT_BYTES_PER_PIXEL * int(sample_lights))
    fewer = " or with fewer lights" if lights or sample_lights else ""
    check_memory(need, f"a {width}x{height} image",
                 f": render a smaller image (--size, or size in a scene file){fewer}")


def check_scene_memory(scene, kept_images=0):
    """`check_frame_memory` for a scene's image size, volumes and lights: the lights' shading
    terms are kept for isosurface hits, and for the translucent samples lit at once
    (`parc.multivolume.SAMPLES_AT_ONCE`) when they are shadowed (a row holding more is checked
    once its samples are counted); without shadows translucent samples are lit as they are taken."""
    from .multivolume import SAMPLES_AT_ONCE
    from .scene import Isosurface
    lit = any(isinstance(v, Isosurface) for v in scene.volumes)
    check_frame_memory(*scene.size, layers=len(scene.volumes), kept_images=kept_images,
                       lights=len(scene.lights) if lit else 0,
                       samples=SAMPLES_AT_ONCE if shadowed_samples(scene) else 0, sample_lights=len(scene.lights))


def shadowed_samples(scene):
    """Whether ``scene``'s translucent samples cast shadow rays: shaded composite samples under
    the scene's lights, with shadows on."""
    from .scene import Translucent
    return bool(scene.shadows and scene.lights and any(
        isinstance(v, Translucent) and v.shade and v.mode == "composite" for v in scene.volumes))


def iso_work(n, slot=0):
    """The isosurface caster's per-ray ``cell``, ``uvw`` and ``counts`` arrays for ``n`` rays,
    reused from frame to frame; ``slot`` tells apart sets alive at once."""
    return (work_array(("iso_cell", slot), (n, 3), np.int32), work_array(("iso_uvw", slot), (n, 3)),
            work_array(("iso_counts", slot), (n, 2), np.int64))


def column_totals(counts):
    """Column sums of an ``(n, k)`` per-ray counter array, as Python ints.

    Summed column by column: NumPy's axis-0 reduction over a narrow
    C-ordered array is about ten times slower (6 ms at 600x600, per frame).
    """
    return tuple(int(counts[:, c].sum()) for c in range(counts.shape[1]))


#: Most pixels a cast covers in one call: Ctrl-C (and SIGTERM) act between calls, not
#: within a Numba kernel, so a large frame is cast in bands of about this many.
BAND_PIXELS = 1 << 18


def row_bands(h, w, progress):
    """Row ranges cast one call at a time: bands of at most about `BAND_PIXELS` (one for a
    frame up to 512 x 512), and ~16 when progress is reported (`parc.outputs.Progress`
    shows it only for a render that takes a while). Whole tiles of 4 rows."""
    step = max(4, BAND_PIXELS // max(w, 1))
    if progress is not None:
        step = min(step, max(4, -(-h // 16)))
    step += (-step) % 4
    return [(y, min(h, y + step)) for y in range(0, h, step)]
