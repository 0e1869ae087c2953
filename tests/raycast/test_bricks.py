"""Bricked samples (`raycast.bricks`, Parker et al. Appendix B): the same samples, the same images.

The linear array is the truth: every sample must land at its own offset,
and a caster given the bricks must produce the linear cast's image bit
for bit, since only the address of each load changes.
"""
import numpy as np
import pytest

from parc import Camera, Translucent, Volume
from parc.renderer import accumulation_params
from raycast.bricks import BrickedSamples, brick, brick_tables
from raycast.composite import cast_accumulate_image
from raycast.iso import NO_SKIP, NO_SKIP_OCTANTS, cast_iso_image, empty_outputs
from raycast.traverse import cell_corners, grid_shape


@pytest.mark.parametrize("shape", [(2, 2, 2), (5, 7, 3), (17, 9, 30)])
@pytest.mark.parametrize("n, m", [(1, 1), (2, 3), (4, 5), (3, 2)])
def test_offsets_are_distinct_and_inside_the_padded_array(shape, n, m):
    fz, fy, fx, total = brick_tables(shape, n, m)
    q = fz[:, None, None] + fy[None, :, None] + fx[None, None, :]
    assert q.shape == shape
    assert len(np.unique(q)) == q.size
    assert q.min() >= 0 and q.max() < total
    side = n * m
    assert total == np.prod([-(-s // side) * side for s in shape])


def test_one_brick_is_contiguous():
    """The samples of one n^3 brick fill n^3 consecutive offsets (what makes a cell's corners share lines)."""
    fz, fy, fx, _ = brick_tables((8, 8, 8), 4, 2)
    q = fz[4:8, None, None] + fy[None, 0:4, None] + fx[None, None, 4:8]
    assert sorted(q.ravel()) == list(range(q.min(), q.min() + 64))


def test_offsets_are_appendix_bs_expression():
    """Parker et al.'s example: a 40 x 20 x 19 volume in 2^3-brick macrobricks of 5^3-sample bricks,
    padded to 40 x 20 x 20. Their x runs slowest; here the array's last axis runs fastest, so the
    expression is theirs with x and z exchanged, and with two misprints mended: the sample's own
    term is ``(x mod n) n^2``, not ``(x mod n × n) n^2``, and the macrobrick counts
    ``(N ÷ n) ÷ m`` are of the padded sizes (rounded down, they make offsets collide)."""
    n, m = 5, 2
    shape = (40, 20, 19)
    fz, fy, fx, total = brick_tables(shape, n, m)
    pz, py, px = 40, 20, 20
    assert total == pz * py * px == 4 * 2 * 2 * (n * m) ** 3
    for z in range(shape[0]):
        for y in range(shape[1]):
            for x in range(shape[2]):
                q = ((z // n // m) * n**3 * m**3 * (py // n // m) * (px // n // m)
                     + (y // n // m) * n**3 * m**3 * (px // n // m)
                     + (x // n // m) * n**3 * m**3
                     + (z // n % m) * n**3 * m**2 + (y // n % m) * n**3 * m + (x // n % m) * n**3
                     + (z % n) * n**2 + (y % n) * n + x % n)
                assert fz[z] + fy[y] + fx[x] == q, (x, y, z)


def test_brick_keeps_every_sample():
    rng = np.random.default_rng(3)
    data = rng.integers(-3000, 3000, (9, 11, 6)).astype(np.int16)
    b = brick(data, 2, 2)
    assert isinstance(b, BrickedSamples) and b.flat.dtype == np.int16 and not b.flat.flags.writeable
    assert grid_shape(b) == grid_shape(data) == data.shape
    q = b.fz[:, None, None] + b.fy[None, :, None] + b.fx[None, None, :]
    assert np.array_equal(b.flat[q], data)
    for i, j, k in [(0, 0, 0), (4, 9, 7), (2, 3, 1)]:
        assert cell_corners(b, i, j, k) == cell_corners(data, i, j, k)


def test_the_padding_holds_zeros():
    data = np.full((9, 11, 6), 7, np.int16)
    total = brick_tables(data.shape, 2, 2)[3]
    freed = np.full(total, -1, np.int16)    # memory a new array of the same size may reuse
    del freed
    b = brick(data, 2, 2)
    q = (b.fz[:, None, None] + b.fy[None, :, None] + b.fx[None, None, :]).ravel()
    pad = np.ones(total, bool)
    pad[q] = False
    assert pad.sum() == total - data.size > 0
    assert (b.flat[pad] == 0).all() and (b.flat[q] == 7).all()


@pytest.mark.parametrize("bad", [dict(n=0), dict(m=0), dict(n=2.5), dict(m=2.5)])
def test_bad_brick_sizes_are_refused(bad):
    with pytest.raises(ValueError, match="brick sizes"):
        brick(np.zeros((4, 4, 4)), **bad)


@pytest.mark.parametrize("shape", [(4, 4), (1, 4, 4), (4, 4, 1)])
def test_a_grid_too_small_is_refused(shape):
    # A grid one sample thick has no cells.
    with pytest.raises(ValueError, match="3-D grid"):
        brick(np.zeros(shape))


def _noise(seed, shape=(14, 19, 11)):
    # Read-only, as a Volume holds its samples: the casts are then the kernels a render compiles.
    rng = np.random.default_rng(seed)
    return Volume(rng.integers(0, 1000, shape).astype(np.int16)).data


@pytest.mark.parametrize("seed", range(4))
def test_isosurface_cast_from_bricks_is_the_linear_cast(seed):
    data = _noise(seed)
    rng = np.random.default_rng(100 + seed)
    nz, ny, nx = data.shape
    org, spc = np.array([-2.0, 1.0, 0.5]), np.array([1.0, 0.7, 1.3])
    lo, hi = org, org + spc * (np.array([nx, ny, nz]) - 1)
    # A framed view, and an eye inside the volume.
    cams = [Camera.framing(lo, hi, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-60, 60)),
            Camera(eye=lo + rng.uniform(0.2, 0.8, 3) * (hi - lo), look_at=hi, up=(0, 0, 1), fov=70.0)]
    iso = float(rng.uniform(300, 700))
    for cam in cams:
        out = []
        for samples in (data, brick(data, 2, 3)):
            t, cell, uvw, counts = empty_outputs(48 * 40)
            image = np.zeros((40, 48, 4), np.float32)
            cast_iso_image(samples, org, spc, cam.as_array(), 48, 40, iso, np.empty((1, 1, 2)), False,
                           NO_SKIP_OCTANTS, -1, t, cell, uvw, counts, 0, 40, True, np.ones(3),
                           np.array([0.1, 0.7, 0.2, 20.0]), image)
            out.append((t, image, counts))
        assert np.isfinite(out[0][0]).sum() > 100
        for a, b in zip(*out):
            assert np.array_equal(a, b)


def test_translucent_cast_from_bricks_is_the_linear_cast():
    data = _noise(7)
    vis = Translucent(Volume(data), "greyscale")
    params = accumulation_params(vis)
    op_x, op_y, col_x, col_rgb = vis.tf.arrays()
    cam = Camera.framing(*vis.volume.bounds, azimuth=20.0, elevation=30.0)
    out = []
    for samples in (data, brick(data, 4, 1)):
        image = np.zeros((32, 32, 4), np.float32)
        counts = np.zeros(32 * 32, np.int64)
        cast_accumulate_image(samples, np.zeros(3), np.ones(3), cam.as_array(), 32, 32, params,
                              op_x, op_y, col_x, col_rgb, np.empty((1, 1, 2)), False, np.empty((1, 1)), False,
                              np.zeros((1, 1, 1), np.uint32), False, NO_SKIP, -1, image, counts, 0, 32)
        out.append((image, counts))
    assert out[0][1].sum() > 0 and out[0][0][..., 3].max() > 0.1
    for a, b in zip(*out):
        assert np.array_equal(a, b)
