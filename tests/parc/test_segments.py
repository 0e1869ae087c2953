"""The proxies PARC keeps per volume (`parc.segments.cached_proxy`) and the segments drawn from them.

Truth: ``method="brute"`` on the same scene, and the proxy objects themselves (one built is kept
and handed out again; one dropped is built anew).
"""
import numpy as np

from data_tools.synthetic import blobs
from parc import Camera, Isosurface, Scene, render
from parc.segments import PROXY_CACHE_SIZE, cached_proxy


def test_each_level_of_one_volume_draws_its_own_proxy(gl):
    # Two levels of one volume, one supercell size: the second must not walk the first's supercells.
    vol = blobs(16, seed=4, count=4)
    cam = Camera.framing(*vol.bounds, azimuth=30, elevation=20)
    lo, hi = vol.value_range()
    levels = [lo + 0.4 * (hi - lo), lo + 0.1 * (hi - lo)]
    for iso in levels + levels[::-1]:
        scene = Scene(camera=cam, size=(32, 24), volumes=[Isosurface(vol, float(iso))])
        ref = render(scene, method="brute")
        res = render(scene, method="parc", supercell=2)
        hit_ref, hit = np.isfinite(ref.depth), np.isfinite(res.depth)
        assert hit_ref.sum() > 20, iso
        assert np.array_equal(hit, hit_ref), (iso, np.argwhere(hit != hit_ref)[:5].tolist())
        assert np.array_equal(res.depth[hit], ref.depth[hit]), iso


def test_proxies_are_kept_and_the_least_recently_used_is_dropped():
    vol = blobs(12, seed=2, count=3)
    lo, hi = vol.value_range()
    levels = [Isosurface(vol, float(lo + (k + 1) * (hi - lo) / (PROXY_CACHE_SIZE + 2)))
              for k in range(PROXY_CACHE_SIZE + 1)]
    first = [cached_proxy(v, 2, (16, 16), {})[0] for v in levels[:PROXY_CACHE_SIZE]]
    # Asked again, each is the one built: kept, and now the most recently used in turn from the second on.
    assert all(cached_proxy(v, 2, (16, 16), {})[0] is p for v, p in zip(levels[1:], first[1:]))
    assert cached_proxy(levels[0], 2, (16, 16), {})[0] is first[0]
    # One more level: the cache is full, and the least recently used (the second level) goes. Asked
    # in this order, the kept ones come back without dropping another.
    cached_proxy(levels[-1], 2, (16, 16), {})
    order = [0, *range(2, PROXY_CACHE_SIZE), 1]
    kept = [cached_proxy(levels[k], 2, (16, 16), {})[0] is first[k] for k in order]
    assert kept == [True] * (PROXY_CACHE_SIZE - 1) + [False]
