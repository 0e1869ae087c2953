"""The real volumes in ../shared/data load with the documented sizes, types, spacings and sane values."""
from __future__ import annotations

import numpy as np
import pytest

from data_tools.info import suggest_isovalues, volume_info
from data_tools.io import load_volume

# file, dims (x, y, z), dtype, spacing (None: only approximately 1)
TABLE = [
    ("neghip.slc", (66, 66, 66), "uint8", (1, 1, 1)),
    ("poship.slc", (66, 66, 66), "uint8", (1, 1, 1)),
    ("ironProt.vtk", (68, 68, 68), "uint8", (1, 1, 1)),
    ("CThead.nrrd", (256, 256, 113), "int16", (1, 1, 2)),
    ("FLAIR.nrrd", (124, 160, 140), "uint8", None),
    ("HeadMRVolume.mhd", (48, 62, 42), "uint8", (4, 4, 4)),
    ("bucky_32x32x32_uint8.raw", (32, 32, 32), "uint8", (1, 1, 1)),
]


@pytest.mark.parametrize("name,dims,dtype,spacing", TABLE, ids=[t[0] for t in TABLE])
def test_real_file_loads(data_dir, name, dims, dtype, spacing):
    vol = load_volume(data_dir / name)
    assert vol.dims == dims
    assert vol.shape == dims[::-1]
    assert vol.dtype == np.dtype(dtype)
    if spacing is None:
        assert vol.spacing == pytest.approx((1, 1, 1), abs=1e-3)
    else:
        assert vol.spacing == pytest.approx(spacing)
    lo, hi = vol.value_range()
    assert hi > lo
    iso = suggest_isovalues(vol)
    assert iso and all(lo < v < hi for v in iso)


def test_ironprot_is_poship_with_a_zero_border(data_dir):
    vtk = load_volume(data_dir / "ironProt.vtk").data
    pos = load_volume(data_dir / "poship.slc").data
    np.testing.assert_array_equal(vtk[1:-1, 1:-1, 1:-1], pos)
    border = np.ones(vtk.shape, bool)
    border[1:-1, 1:-1, 1:-1] = False
    assert not vtk[border].any()


def test_slc_proteins_differ_and_have_structure(data_dir):
    neg = load_volume(data_dir / "neghip.slc")
    pos = load_volume(data_dir / "poship.slc")
    assert not np.array_equal(neg.data, pos.data)
    assert neg.meta["compression"] == "rle"
    for vol in (neg, pos):
        # The paper's levels 30, 80, 160 all cut the data.
        for level in (30, 80, 160):
            assert (vol.data > level).any() and (vol.data < level).any()


def test_cthead_values(data_dir):
    vol = load_volume(data_dir / "CThead.nrrd")
    assert vol.data.max() > 1500          # bone
    assert vol.data[0, 0, 0] < 100         # air in the corner
    assert ((vol.data > 600) & (vol.data < 1500)).any()   # soft tissue


def test_flair_oblique_note(data_dir):
    vol = load_volume(data_dir / "FLAIR.nrrd")
    assert "oblique" in vol.meta["note"]
    assert vol.origin == pytest.approx((64.898239, 110.431145, -27.925539), abs=1e-5)
    assert "note" in volume_info(vol)


def test_headmr_metaimage(data_dir):
    vol = load_volume(data_dir / "HeadMRVolume.mhd")
    assert vol.spacing == (4.0, 4.0, 4.0)
    assert vol.extent == (47 * 4.0, 61 * 4.0, 41 * 4.0)
    assert (vol.data > 20).any() and (vol.data < 20).any()


def test_bucky_density(data_dir):
    vol = load_volume(data_dir / "bucky_32x32x32_uint8.raw")
    assert vol.meta["format"] == "raw"
    assert (vol.data > 128).any() and (vol.data < 128).any()
    # Sixty carbon atoms on a sphere: the centre of the cage is empty.
    assert vol.data[16, 16, 16] < vol.data.max() / 4
