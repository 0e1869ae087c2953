"""The Volume: samples kept as the kernels read them and checked slab by slab, spacing and origin
checked, its bounds, new volumes made from it (replace, copies, pickles), and samples a caller
can no longer change under it."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from data_tools import InputError, Volume
from data_tools.volume import hand_over


@pytest.mark.parametrize("data", [np.arange(4 * 5 * 12, dtype=np.int16).reshape(4, 5, 12)[:, :, ::2],
                                  np.asfortranarray(np.arange(4 * 5 * 6, dtype=np.float32).reshape(4, 5, 6)),
                                  np.arange(4 * 5 * 6, dtype=">u2").reshape(4, 5, 6)])
def test_samples_are_kept_c_contiguous_in_native_byte_order(data):
    # The kernels read the buffer as x fastest, in this machine's byte order.
    vol = Volume(data)
    assert vol.data.flags.c_contiguous and vol.dtype.isnative
    assert vol.dtype == data.dtype.newbyteorder("=") and np.array_equal(vol.data, data)


def test_samples_in_the_machines_byte_order_spelt_out_are_not_copied(tmp_path):
    # A reader gives '<i2' (the file's order): on a little-endian machine those are int16's own
    # bytes, yet they were copied, and a raw or MetaImage volume took twice its size to load.
    import sys
    import tracemalloc

    from data_tools.io import load_volume
    order = "<" if sys.byteorder == "little" else ">"
    owned = np.arange(64, dtype=np.int16).reshape(4, 4, 4).astype(np.dtype(np.int16).newbyteorder(order))
    owned.flags.writeable = False
    vol = Volume(owned)
    assert np.shares_memory(vol.data, owned) and vol.data.dtype == np.int16 and vol.data.dtype.byteorder == "="
    path = tmp_path / f"v_64x64x256_int16_{'le' if order == '<' else 'be'}.raw"
    np.arange(64 * 64 * 256, dtype=np.int16).astype(owned.dtype).tofile(path)
    tracemalloc.start()
    try:
        vol = load_volume(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert vol.data[1, 2, 3] == 64 * 64 + 2 * 64 + 3 and peak < 1.5 * vol.data.nbytes


def test_non_finite_samples_and_the_largest_are_found_in_every_slab():
    # A volume is checked some z-slices at a time: a NaN in its last slices, or a fill value
    # in its first, counts however the slabs fall.
    from data_tools.volume import _count_non_finite
    late = np.zeros((5, 3, 4))
    late[4, 2, 3], late[3, 0, 0] = np.nan, -np.inf
    early = np.zeros((5, 3, 4))
    early[0, 1, 1] = -3e250
    for slab_bytes in (1, late[0].nbytes, 2 * late[0].nbytes, 64 << 20):
        assert _count_non_finite(late, slab_bytes)[0] == np.count_nonzero(~np.isfinite(late)) == 2
        assert _count_non_finite(early, slab_bytes) == (0, -3e250)        # with its sign


@pytest.mark.parametrize("origin, ok", [((2.0 ** 32 - 9, 0, 0), True), ((2.0 ** 32 - 8, 0, 0), False),
                                        ((-2.0 ** 32, 0, 0), True), ((-2.0 ** 32 - 1, 0, 0), False)])
def test_a_grid_reaching_past_2_32_cells_from_0_is_refused(origin, ok):
    # Ten samples of spacing 2 (extent 18): the far corner may lie 2^32 cells (2^33 units) out.
    data = np.zeros((2, 2, 10), np.uint8)
    origin = tuple(2 * v for v in origin)
    if ok:
        assert Volume(data, spacing=(2, 1, 1), origin=origin).origin == origin
    else:
        with pytest.raises(InputError, match="more than 2\\^32 cells from 0"):
            Volume(data, spacing=(2, 1, 1), origin=origin)


def test_a_volume_made_anew_from_another_keeps_none_of_its_caches():
    # dataclasses.replace passes the old meta on: its cached range belonged to the old samples.
    vol = Volume(np.zeros((2, 2, 2), np.uint8), meta={"note": "kept"})
    assert vol.value_range() == (0.0, 0.0)
    new = dataclasses.replace(vol, data=np.arange(8, dtype=np.uint8).reshape(2, 2, 2))
    assert new.meta == {"note": "kept"} and new.value_range() == (0.0, 7.0)


@pytest.mark.parametrize("spacing", [(0, 1, 1), (1, -0.0, 1), (1, 1, -2)])
def test_a_spacing_not_above_zero_is_refused_as_such(spacing):
    with pytest.raises(InputError, match="spacing must be positive"):
        Volume(np.zeros((2, 2, 2), np.uint8), spacing=spacing)


@pytest.mark.parametrize("lo, hi, kept_as", [(-2 ** 31, 2 ** 31 - 1, np.int32), (0, 2 ** 32 - 1, np.uint32)])
def test_64_bit_integers_at_the_ends_of_a_32_bit_type_are_kept_in_it(lo, hi, kept_as):
    data = np.full((2, 2, 2), lo, np.int64)
    data[1] = hi
    vol = Volume(data)
    assert vol.dtype == kept_as and vol.value_range() == (lo, hi)


def test_bounds_and_centre_by_hand():
    # 6 x 5 x 4 samples of spacing 0.5, 2, 3 from (-1, 10, 100): the far corner 2.5, 8, 9 further.
    vol = Volume(np.zeros((4, 5, 6), np.uint8), spacing=(0.5, 2, 3), origin=(-1, 10, 100))
    lo, hi = vol.bounds
    assert lo.tolist() == [-1, 10, 100] and hi.tolist() == [1.5, 18, 109]
    assert vol.center.tolist() == [0.25, 14, 104.5]


def test_copies_and_pickles_keep_the_name_placement_and_meta():
    import copy
    import pickle
    vol = Volume(np.arange(8, dtype=np.uint8).reshape(2, 2, 2), spacing=(1, 2, 3), origin=(4, 5, 6), name="v",
                 meta={"note": "oblique directions reduced", "iso": 3.5})
    vol.value_range()
    for other in (copy.copy(vol), copy.deepcopy(vol), pickle.loads(pickle.dumps(vol))):
        assert (other.name, other.spacing, other.origin) == ("v", (1, 2, 3), (4, 5, 6))
        assert other.meta == {"note": "oblique directions reduced", "iso": 3.5}


def _layouts():
    """Each layout's samples, and the array through which the caller can still write them."""
    base = np.arange(1000, dtype=np.float32).reshape(10, 10, 10)
    read_only_view = base.view()
    read_only_view.flags.writeable = False
    strided = np.arange(2000, dtype=np.float32).reshape(10, 10, 20)[:, :, ::2]
    fortran, big, wide = np.asfortranarray(base), base.astype(">f4"), base.astype(np.int64)
    # Beneath a read-only array: numpy's object for as_strided, a read-only memoryview of a bytearray.
    behind = base.copy()
    buffer = bytearray(base.tobytes())
    in_buffer = np.frombuffer(buffer, np.float32).reshape(10, 10, 10)
    return {"C order": (base, base), "Fortran order": (fortran, fortran), "strided": (strided, strided),
            "big-endian": (big, big), "int64": (wide, wide),
            "a read-only view of a writeable array": (read_only_view, base),
            "a read-only strided view": (np.lib.stride_tricks.as_strided(behind, writeable=False), behind),
            "a read-only memoryview of a bytearray": (
                np.frombuffer(memoryview(buffer).toreadonly(), np.float32).reshape(10, 10, 10), in_buffer)}


@pytest.mark.parametrize("layout", list(_layouts()))
def test_a_change_to_the_callers_array_never_reaches_the_volume(layout):
    # Rendering caches ranges, proxies and skip tables on a volume: samples that changed under
    # them would be drawn from stale caches, with no error.
    given, writeable = _layouts()[layout]
    vol = Volume(given)
    before = vol.data.copy()
    writeable[...] = -7
    np.testing.assert_array_equal(vol.data, before)
    assert not vol.data.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        vol.data[0, 0, 0] = 1


def test_samples_read_only_all_the_way_down_are_used_without_a_copy():
    owned = np.arange(27, dtype=np.int16).reshape(3, 3, 3).copy()      # not a view: no base
    owned.flags.writeable = False
    assert np.shares_memory(Volume(owned).data, owned)
    made = np.arange(27, dtype=np.int16).reshape(3, 3, 3).copy()
    view = made.view()
    assert hand_over(view) is view and not made.flags.writeable
    assert np.shares_memory(Volume(view).data, made)
    # A volume made anew from another's samples shares them too.
    vol = Volume(made)
    assert np.shares_memory(Volume(vol.data, spacing=(2, 2, 2)).data, made)


def test_a_memory_map_is_used_in_place(tmp_path):
    path = tmp_path / "samples.npy"
    np.save(path, np.arange(64, dtype=np.uint8).reshape(4, 4, 4))
    mapped = np.load(path, mmap_mode="r+")
    vol = Volume(mapped)
    assert np.shares_memory(vol.data, mapped) and not vol.data.flags.writeable


def test_a_copy_too_large_for_the_memory_is_refused_with_the_way_around_it(monkeypatch):
    import data_tools.memory
    monkeypatch.setattr(data_tools.memory, "available_memory", lambda: 100)
    with pytest.raises(InputError, match=r"scan: a copy of the samples needs about .*a.flags.writeable = False"):
        Volume(np.zeros((4, 5, 6), np.float32), name="scan")
    kept = np.zeros((4, 5, 6), np.float32)
    kept.flags.writeable = False
    assert np.shares_memory(Volume(kept).data, kept)


def test_an_objects_own_buffer_is_copied_and_left_writeable():
    # np.asarray hands back an object's own array (as xarray's DataArray does): it is the caller's.
    class Box:
        def __init__(self):
            self.samples = np.zeros((4, 4, 4), np.float32)

        def __array__(self, dtype=None, copy=None):
            return self.samples

    box = Box()
    vol = Volume(box)
    box.samples[0, 0, 0] = 5.0
    assert vol.data[0, 0, 0] == 0.0 and box.samples.flags.writeable


def test_a_read_only_array_over_a_writeable_buffer_is_copied():
    buf = bytearray(np.arange(60, dtype=np.float32).tobytes())
    a = np.frombuffer(buf, np.float32).reshape(3, 4, 5)
    a.flags.writeable = False
    vol = Volume(a)
    buf[:4] = np.float32(9.0).tobytes()
    assert a[0, 0, 0] == 9.0 and vol.data[0, 0, 0] == 0.0


def test_copies_and_pickles_of_a_volume_do_not_copy_its_samples_again(monkeypatch):
    import copy
    import pickle

    import data_tools.memory
    vol = Volume(np.arange(120, dtype=np.float32).reshape(4, 5, 6))
    # No memory left: a copy of the samples by the Volume would be refused.
    monkeypatch.setattr(data_tools.memory, "available_memory", lambda: 0)
    for other in (copy.copy(vol), copy.deepcopy(vol), pickle.loads(pickle.dumps(vol))):
        np.testing.assert_array_equal(other.data, vol.data)
        assert not other.data.flags.writeable
