"""How the parallel drivers hand out work (`raycast.rays`): every item exactly once, spread out."""
import numpy as np
import pytest

from raycast.config import SPREAD_CHUNK, TILE_H, TILE_W
from raycast.rays import chunk_count, chunk_run, dealt_tile, spread, spread_run, spread_runs, tile_count, tile_rect


@pytest.mark.parametrize("ways", [1, 2, 3, 4, 16])
@pytest.mark.parametrize("n", [1, 2, 3, 7, 64, 100, 1000, 2048, 4096, 8191, 16385])
def test_spread_visits_every_item_once(n, ways):
    ways = min(n, ways)
    order = np.array([spread(it, n, 1, ways) for it in range(n)])
    assert np.array_equal(np.sort(order), np.arange(n))


@pytest.mark.parametrize("ways", [2, 3, 4])
@pytest.mark.parametrize("n", [100, 2048, 16385])
def test_each_thread_share_samples_the_whole_range_in_order(n, ways):
    """The contiguous runs of iterations a static schedule gives each thread
    take items from every part of the range, not one end of it, and walk it
    in order, one item of every ``ways``."""
    order = np.array([spread(it, n, 1, ways) for it in range(n)])
    for share in np.array_split(order, ways):
        counts = np.histogram(share, bins=4, range=(0, n))[0]
        assert counts.min() >= 0.8 * len(share) / 4
        assert (np.diff(share) == ways).all()


@pytest.mark.parametrize("ways", [1, 2, 3, 5])
def test_spread_deals_whole_rows_of_tiles(ways):
    """With ``group`` (tiles in a row), each share takes whole rows, every
    ``ways``-th, in order, and every tile once."""
    across, rows = 16, 37
    n = across * rows
    order = np.array([spread(it, n, across, ways) for it in range(n)])
    assert np.array_equal(np.sort(order), np.arange(n))
    rows_taken = order.reshape(rows, across) // across
    assert (rows_taken == rows_taken[:, :1]).all()
    assert (np.diff(order.reshape(rows, across), axis=1) == 1).all()
    for share in np.array_split(rows_taken[:, 0], ways):
        assert (np.diff(share) == ways).all()


def test_one_way_is_the_natural_order():
    assert [spread(it, 10, 1, 1) for it in range(10)] == list(range(10))
    assert sorted(spread(it, 5) for it in range(5)) == list(range(5))     # more threads than items


def test_chunks_and_tiles_cover_the_items():
    assert chunk_count(0, 64) == 0 and chunk_count(64, 64) == 1 and chunk_count(65, 64) == 2
    for n in (0, 1, 63, 64, 65, 200):
        runs = [chunk_run(c, 64, n) for c in range(chunk_count(n, 64))]
        assert [m for lo, hi in runs for m in range(lo, hi)] == list(range(n))   # each item once, in order
        assert all(0 < hi - lo <= 64 for lo, hi in runs)
    width, row0, row1 = 70, 3, 18
    # A margin past the image: a tile's rectangle running beyond it (pixels the casters
    # would read and write out of bounds) counts there instead of being cut off by the slice.
    seen = np.zeros((row1 + TILE_H, width + TILE_W), int)
    for tile in range(tile_count(width, row0, row1, 32, 4)):
        x0, x1, y0, y1 = tile_rect(tile, width, row0, row1, 32, 4)
        seen[y0:y1, x0:x1] += 1
    assert (seen[row0:row1, :width] == 1).all() and seen.sum() == (row1 - row0) * width
    # The parallel loops' tiles (the project's tile size, dealt to threads) cover them too.
    seen[:] = 0
    tiles = tile_count(width, row0, row1, TILE_W, TILE_H)
    for it in range(tiles):
        x0, x1, y0, y1 = dealt_tile(it, tiles, width, row0, row1)
        seen[y0:y1, x0:x1] += 1
    assert (seen[row0:row1, :width] == 1).all() and seen.sum() == (row1 - row0) * width


@pytest.mark.parametrize("n", [0, 1, 63, 64, 65, 1000])
def test_spread_runs_cover_every_ray_once(n):
    runs = spread_runs(n)
    seen = np.zeros(n + SPREAD_CHUNK, int)      # a run past the last ray shows in the margin
    for it in range(runs):
        lo, hi = spread_run(it, runs, n)
        seen[lo:hi] += 1
    assert (seen[:n] == 1).all() and (seen[n:] == 0).all()
