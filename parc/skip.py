"""Skip tables: per cell, how far around it the walk may jump without missing anything.

About this technique
--------------------
Inside PARC's ray segments the casters still cross cells that cannot
contribute (all above or all below an isovalue, or transparent under a
transfer function). A table with one int8 per cell tells the walk so
without reading the cell's samples, and also how large a cube of such
cells surrounds it: its Chebyshev radius, so a walk can jump to the
cube's exit in one step (`raycast.iso`, `raycast.composite`). The classes
come from the cell ranges of `parc.classify` (`VolumeIndex.iso_skip`,
`VolumeIndex.tf_skip`); the radii from `skip_radius`. For the camera
rays of an isosurface, a table per ray octant holds the side of the box
ahead of each cell instead (`octant_radius`, `VolumeIndex.iso_octant_skip`).
A frame takes its tables through `skip_table` and `octant_skip_tables`; the
tables by octant wait for an isovalue's second frame (`expect_frames`).
"""
import numpy as np
from numba import prange

from raycast.config import kernel
from raycast.iso import NO_SKIP, NO_SKIP_OCTANTS, octant
from raycast.rays import camera_ray

from .scene import Isosurface

#: Skip tables (`skip_radius`): ``1 + radius`` is capped at this many
#: cells, which bounds the table's build (a pass per radius over each
#: column): CT head skin cells walked at 512x512 with caps 2/4/8/16:
#: 1.78M/0.92M/0.897M/0.895M; 454M cells built in 0.59 s with 8, 1.8-2.1 s with 16.
SKIP_CAP = 8
#: The smallest radius worth a jump (each costs a few divisions; stepping
#: a cell costs a table lookup). Cast only, PARC segments, fastest of 25
#: in one process, CT head at 512x512: skin 15.1 ms with 2 against 15.7
#: (1), 15.7 (4) and 16.2 (6); bone 10.7 ms with 2 against 11.5 (1) and
#: 11.0 (4); neghip within 2% for all. Transfer functions, CT head
#: ``ct_skin_bone`` at 600x600: 134 ms with 2 against 142 ms (1) and 133 ms (4).
ISO_JUMP_MIN = 2
TF_JUMP_MIN = 2


def skip_radius(classes, cap):
    """Per cell, its class times ``1 +`` the Chebyshev radius of the cube around it of that class.

    Parameters
    ----------
    classes : int8 ndarray (nz, ny, nx)
        0 for a cell that may contribute, else the class of an empty one
        (an isosurface's sign, ±1; 1 for a transparent cell).
    cap : int
        Largest ``1 + radius`` stored (at most 127).

    Returns
    -------
    int8 ndarray, same shape
        ``c * min(cap, d)`` for a cell of class ``c != 0``, where ``d`` is
        the Chebyshev distance (``max(|di|, |dj|, |dk|)``) to the nearest
        cell of another class; cells outside the grid count as the same
        class (a walk never enters them). 0 where ``c == 0``.

    Notes
    -----
    The distance is separable: the distance along x to another class in
    the row, then ``min over dj of max(|dj|, d_x)`` over the cells of the
    same class in the column, then the same along z (a cell of another
    class contributes ``|dj|`` itself). Three int8 arrays of the grid's size.
    """
    classes = np.ascontiguousarray(classes, dtype=np.int8)
    if not 1 <= cap <= 127:
        raise ValueError(f"cap must be in 1..127, got {cap}")
    along_x = np.empty_like(classes)
    _radius_rows(classes, cap, along_x)
    along_y = np.empty_like(classes)
    _radius_columns(classes, along_x, 1, cap, along_y)
    _radius_columns(classes, along_y, 0, cap, along_x)
    along_x *= classes
    return along_x


@kernel(parallel=True)
def _radius_rows(c, cap, out):
    """Distance along x to a cell of another class in the row, capped (0 for class 0).

    One pass over the row per distance and side, each a loop LLVM vectorizes (the scans that
    carry the distance from cell to cell do not: a 512x512x1734 volume's rows took 0.39 s so,
    0.095 s this way, with the cap of 8).
    """
    nz, ny, _ = c.shape
    for k in prange(nz):
        for j in range(ny):
            _other_class_along_row(c[k, j], cap, True, True, out[k, j])


@kernel(inline="always")
def _other_class_along_row(row, cap, ahead, behind, dist):
    """``dist[i]``: the distance from cell ``i`` of ``row`` to the nearest cell of another
    class ahead of it (larger ``i``), behind it, or either way, capped at ``cap``; 0 for class
    0. Cells t apart whose classes differ are each at most t from another class. Over slices,
    so that no index is ``i - t``: Numba's test of a negative index kept LLVM from vectorizing."""
    n = row.shape[0]
    far = np.int8(cap)
    for i in range(n):
        dist[i] = far if row[i] != 0 else np.int8(0)
    for t in range(1, min(cap, n)):
        d = np.int8(t)
        first = row[:n - t]
        second = row[t:]
        if ahead:
            near = dist[:n - t]
            for i in range(n - t):
                near[i] = min(near[i], d if first[i] != second[i] else far)
        if behind:
            near = dist[t:]
            for i in range(n - t):
                near[i] = min(near[i], d if first[i] != second[i] else far)


@kernel(parallel=True)
def _radius_columns(c, inner, axis, cap, out):
    """``min over dm of max(|dm|, inner at m + dm)`` along array axis ``axis`` (0: z, 1: y),
    a cell of another class counting 0.

    Row by row along x, so that the loop over ``dm`` (up to the cap)
    runs over whole rows: a scan per cell that stopped once ``|dm|``
    reached its best built a 454M-cell table in ~19 s (the whole table now
    takes 0.59 s, `SKIP_CAP`).
    """
    nz, ny, nx = c.shape
    n = nz if axis == 0 else ny
    for kk in prange(nz):
        k = np.int64(kk)
        for j in range(ny):
            m = k if axis == 0 else j
            for i in range(nx):
                out[k, j, i] = inner[k, j, i]
            for d in range(1, cap):
                for q in (m - d, m + d):
                    if q < 0 or q >= n:
                        continue
                    qk = q if axis == 0 else k
                    qj = j if axis == 0 else q
                    dd = np.int8(d)
                    for i in range(nx):
                        v = inner[qk, qj, i] if c[qk, qj, i] == c[k, j, i] else np.int8(0)
                        v = max(v, dd)
                        if v < out[k, j, i]:
                            out[k, j, i] = v


def octant_steps(octant):
    """``(sx, sy, sz)``, each +1 or -1: the directions octant ``octant`` walks."""
    return -1 if octant & 1 else 1, -1 if octant & 2 else 1, -1 if octant & 4 else 1


def octant_radius(classes, octant, cap, out):
    """Per cell, its class times the side of the largest box of its class that starts at it
    and grows the way rays of ``octant`` walk, capped at ``cap``; written into ``out``.

    A walk that jumps from cell ``c`` with a table entry of ``s * (r + 1)``
    goes to where the ray leaves the cells ``c + (di, dj, dk) * steps``
    with ``0 <= di, dj, dk <= r``: the far faces of the centred cube of
    radius ``r`` (`raycast.traverse.cube_exit`), which a ray of this octant
    reaches without leaving that box. So only the box ahead has to be of
    one class, not the whole cube around the cell, and near a surface the
    box is larger: CT head bone at 512², 11.1 cells stepped and 3.4 jumps
    a ray with `skip_radius`, 5.9 and 3.1 with these. Cells outside the
    grid are no limit, as in `skip_radius`.

    Separable, like `skip_radius`: the run of the cell's class along x,
    then the largest square in x and y from the runs of the rows ahead,
    then the largest cube from the squares of the slices ahead; each pass
    parallel over slices.
    """
    classes = np.ascontiguousarray(classes, dtype=np.int8)
    if not 1 <= cap <= 127:
        raise ValueError(f"cap must be in 1..127, got {cap}")
    sx, sy, sz = octant_steps(octant)
    runs = np.empty_like(classes)
    _octant_runs(classes, sx, cap, runs)
    squares = np.empty_like(classes)
    _octant_grow(classes, runs, 1, sy, cap, squares)
    _octant_grow(classes, squares, 0, sz, cap, out)
    out *= classes


@kernel(parallel=True)
def _octant_runs(c, sx, cap, out):
    """Cells of the same class from each cell on, stepping ``sx`` along x, capped; 0 for class 0.

    One pass over the row per distance, as in `_radius_rows` and for the same reason: a
    512x512x1734 volume's runs took 0.46-0.52 s with a scan from cell to cell, 0.05-0.06 s so.
    """
    nz, ny, _ = c.shape
    for k in prange(nz):
        for j in range(ny):
            # A run ends at the first cell of another class the way the rays step.
            _other_class_along_row(c[k, j], cap, sx > 0, sx < 0, out[k, j])


@kernel(parallel=True)
def _octant_grow(c, inner, axis, step, cap, out):
    """The largest side ``q`` with ``inner >= q`` at every cell ``0 .. q - 1`` steps ahead along
    array axis ``axis`` (0: z, 1: y) that lies in the grid and has the cell's class.

    Row by row along x, as `_radius_columns` and for the same reason: the
    smallest ``inner`` so far only falls as the steps grow and the side
    they allow only rises, so each step adds one to the side of the cells
    still growing, a branch-free pass over the row.
    """
    nz, ny, nx = c.shape
    n = nz if axis == 0 else ny
    for kk in prange(nz):
        k = np.int64(kk)
        low = np.empty(nx, np.int8)
        for j in range(ny):
            m0 = k if axis == 0 else j
            for i in range(nx):
                low[i] = inner[k, j, i]
                out[k, j, i] = min(low[i], np.int8(1))
            for d in range(1, cap):
                q = m0 + d * step
                if q >= 0 and q < n:
                    qk = q if axis == 0 else k
                    qj = j if axis == 0 else q
                    for i in range(nx):
                        v = inner[qk, qj, i] if c[qk, qj, i] == c[k, j, i] else np.int8(0)
                        low[i] = min(low[i], v)
                dd = np.int8(d + 1)
                for i in range(nx):
                    out[k, j, i] += np.int8(low[i] >= dd)


def skip_table(vis, use):
    """``(table, jump_min)`` for the casting kernels: the per-cell skip table of an
    Isosurface (`raycast.iso`) or Translucent (`raycast.composite`) volume and
    the smallest radius worth a jump when ``use``, else none (the unaccelerated caster)."""
    from .classify import VolumeIndex      # which imports this module
    if not use:
        return NO_SKIP, -1
    index = VolumeIndex.of(vis.volume)
    if isinstance(vis, Isosurface):
        return index.iso_skip(vis.value)
    return index.tf_skip(vis.tf)


def octant_skip_tables(iso, use, camera, width, height):
    """``(tables, jump_min)`` for an isosurface's camera rays: its skip tables by ray octant
    (`parc.classify.VolumeIndex.iso_octant_skip`), built for the octants of the view's rays, when
    ``use``, else none."""
    from .classify import VolumeIndex
    if not use:
        return NO_SKIP_OCTANTS, -1
    return VolumeIndex.of(iso.volume).iso_octant_skip(iso.value, ray_octants(camera, width, height))


def expect_frames(scene):
    """Say that ``scene`` will be rendered again, as `parc.compare` does: its isosurfaces' skip
    tables by octant, which a single frame is not worth (`parc.classify.VolumeIndex.iso_octant_skip`),
    are then built from its first frame on."""
    from .classify import VolumeIndex
    for vis in scene.volumes:
        if isinstance(vis, Isosurface):
            VolumeIndex.of(vis.volume).expect_frames(vis.value)


def ray_octants(camera, width, height):
    """The octants (`raycast.iso.octant`) of the camera's pixel rays.

    Before it is normalized, a pixel's ray direction is affine in the
    pixel's indices (`raycast.rays.camera_ray`), so each component's sign
    over the image is one of those at its corners; a ray that rounding puts
    in another octant walks with no skip table there, slower but exact.
    """
    cam = camera.as_array()
    signs = [set(), set(), set()]
    for x in (0, width - 1):
        for y in (0, height - 1):
            o = octant(*camera_ray(cam, width, height, x, y)[3:])
            for a in range(3):
                signs[a].add(o & (1 << a))
    return sorted(sx + sy + sz for sx in signs[0] for sy in signs[1] for sz in signs[2])


#: The kernels each kind of table compiles on its first use (`parc.renderer.kernel_samples`).
CENTRED_KERNELS = (_radius_rows, _radius_columns)
OCTANT_KERNELS = (_octant_runs, _octant_grow)
