"""The ideal caster's work, for reports: how close `brute` and `parc` come to it.

About this technique
--------------------
Sobierajski & Avila's ideal caster looks only at the *contributing* cells
of each ray (DESIGN, "Speed: what is measured"): those where the ray meets
the surface, or a value of non-zero opacity. Which cells those are depends
on the ray, so no caster can know them in advance; what it can know is the
*possibly contributing* cells, whose value range holds the isovalue or
meets the non-zero opacity. A benchmark lists two counts next to what each
method took: the bound a caster that classifies whole cells, as PARC does,
can reach, and the paper's contributing work inside it.

- Translucent volumes (`ideal_samples`, `contributing_samples`): the samples of
  the unaccelerated caster's lattice that lie in possibly contributing
  cells (the bound), and those of non-zero opacity, which every caster of
  that lattice must take. Both are walked with the same stopping rules
  (``t >= stop``, early ray termination in composite mode), so each count
  is exactly a subset of ``brute``'s ``samples``, and PARC, with
  supercells of a cell or more, never takes fewer than the bound. The
  definitions and the per-ray kernel are in `raycast.ideal`.
- Isosurfaces: nothing new to count. The bound is the cells whose range
  holds the isovalue, up to the first hit: the unaccelerated caster's own
  ``cubic_solves`` statistic (it solves only in such cells, and stops at
  the hit). PARC with supercells smaller than a cell bounds parts of
  cells, skips a cell whose range holds the isovalue where the ray crosses
  only a part that cannot, and can solve fewer cubics for the same image.
  A ray that hits has one contributing cell, the surface's (the first along
  the ray ends it), and a ray that misses none: the ``hits`` statistic.
"""
from __future__ import annotations

import numpy as np

from data_tools import InputError
from raycast.ideal import ideal_samples_image

from .scene import Translucent
from .workspace import NO_STOP


def possibly_contributing_cells(vis: Translucent) -> np.ndarray:
    """uint8 ``(nz-1, ny-1, nx-1)``: 1 where a cell's corner range meets ``vis``'s non-zero opacity
    (each range widened by `raycast.composite.INTERP_ROUNDING`, as `parc.classify.classify_tf` does)."""
    from .classify import VolumeIndex, classify_tf
    mn, mx = VolumeIndex.of(vis.volume).cell_minmax()
    return np.ascontiguousarray(classify_tf(mn, mx, vis.tf), dtype=np.uint8)


def _counts(scene, vis, stop):
    """int64 ``(H, W, 2)``: per pixel, the bound and the contributing samples (`raycast.ideal`)."""
    from .renderer import accumulation_params

    if not isinstance(vis, Translucent):
        raise InputError(f"ideal samples are defined for a Translucent volume, got {type(vis).__name__}")
    w, h = scene.size
    use_stop = stop is not None
    if use_stop:
        stop = np.ascontiguousarray(stop, dtype=np.float64)
        if stop.shape != (h, w):
            raise InputError(f"stop must be ({h}, {w}) (the image's rows and columns), got {stop.shape}")
    else:
        stop = NO_STOP
    vol = vis.volume
    op_x, op_y, _, _ = vis.tf.arrays()
    counts = np.empty((w * h, 2), np.int64)
    ideal_samples_image(vol.data, np.array(vol.origin, dtype=np.float64),
                        np.array(vol.spacing, dtype=np.float64), scene.camera.as_array(), w, h,
                        accumulation_params(vis), op_x, op_y, possibly_contributing_cells(vis), stop, use_stop,
                        counts)
    return counts.reshape(h, w, 2)


def ideal_sample_counts(scene, vis: Translucent, stop=None) -> np.ndarray:
    """Per-pixel ideal sample counts, int64 ``(H, W)``; see `ideal_samples`."""
    return _counts(scene, vis, stop)[..., 0]


def contributing_sample_counts(scene, vis: Translucent, stop=None) -> np.ndarray:
    """Per-pixel counts of samples of non-zero opacity, int64 ``(H, W)``; see `contributing_samples`."""
    return _counts(scene, vis, stop)[..., 1]


def ideal_samples(scene, vis: Translucent, stop=None) -> int:
    """Samples a caster that classifies whole cells takes at least, for one translucent volume over
    the scene's camera.

    Parameters
    ----------
    scene : Scene
        Its camera and image size are used (``scene.size`` is ``(W, H)``).
    vis : Translucent
        The volume, transfer function, mode, step and threshold.
    stop : ndarray (H, W) of float, optional
        Per-pixel world distance ``t`` at which each ray stops (e.g. an
        isosurface's depth, ``inf`` where none): no sample at ``t >= stop``.

    Returns
    -------
    int
        The number of the unaccelerated caster's samples that lie in
        possibly contributing cells (see `raycast.ideal`): at most
        ``brute``'s ``stats["samples"]``, at least `contributing_samples`, and
        never more than ``parc``'s with supercells of a cell or more.

    Raises
    ------
    InputError
        ``vis`` is not a Translucent, or ``stop`` has the wrong shape.
    """
    return int(ideal_sample_counts(scene, vis, stop).sum())


def contributing_samples(scene, vis: Translucent, stop=None) -> int:
    """Samples of non-zero opacity on the unaccelerated caster's lattice: those every caster of it
    must take to make the same image. Parameters and errors as `ideal_samples`; at most
    `ideal_samples`."""
    return int(contributing_sample_counts(scene, vis, stop).sum())


def ideal_and_contributing_samples(scene, vis: Translucent, stop=None) -> tuple[int, int]:
    """`ideal_samples` and `contributing_samples` from one walk of the lattice."""
    bound, contributing = _counts(scene, vis, stop).sum(axis=(0, 1))
    return int(bound), int(contributing)
