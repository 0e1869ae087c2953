"""Valid files in spellings other writers use (NRRD's other field names, SLC counts against
their X, long numbers); each written by hand."""
from __future__ import annotations

import numpy as np
import pytest

from data_tools import InputError
from data_tools.io import load_volume

ARR16 = np.arange(24, dtype=np.int16).reshape(4, 3, 2) * 1000 - 5000


def _nrrd(fields, data: bytes) -> bytes:
    return b"NRRD0004\n" + b"".join(f + b"\n" for f in fields) + b"\n" + data


BASE = [b"type: short", b"dimension: 3", b"sizes: 2 3 4", b"endian: big", b"encoding: raw"]


@pytest.mark.parametrize("fields", [
    [b"centerings: node node node", b"axis mins: 0 0 0", b"axis maxs: 1 4 9"],   # NRRD's other name for centers
    [b"centers: node node node", b"axismins: 0 0 0", b"axismaxs: 1 4 9"],       # teem's names without spaces
    [b"centerings: node node node", b"spacings: 1 2 3", b"axis mins: 0 0 0"],
])
def test_nrrd_other_spellings_of_centers_and_axis_extremes(tmp_path, fields):
    # Node centring: the extremes are the first and last samples, (n - 1) spacings apart.
    p = tmp_path / "e.nrrd"
    p.write_bytes(_nrrd(BASE + fields, ARR16.astype(">i2").tobytes()))
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR16)
    assert vol.spacing == (1.0, 2.0, 3.0) and vol.origin == (0.0, 0.0, 0.0)



@pytest.mark.parametrize("icon, size", [(b"0 0X", b" X"), (b"0 0 X", b"X")])
def test_slc_counts_written_against_their_x(tmp_path, icon, size):
    # VolVis and VTK read these with fscanf("%d X"), which takes "4X" as well as "4 X".
    p = tmp_path / "x.slc"
    p.write_bytes(b"11111\n2 2 2 8\n1 1 1\n0 0 0 1\n" + icon
                  + b"2" + size + b"\x04\x07" + b"5" + size + b"\x84\x01\x02\x03\x04")
    np.testing.assert_array_equal(load_volume(p).data.ravel(), [7, 7, 7, 7, 1, 2, 3, 4])


def test_slc_spacing_written_with_many_digits(tmp_path):
    # fscanf("%f") reads a number of any length; the reader cut words at 32 bytes and then
    # said "expected 'X' before the icon".
    p = tmp_path / "d.slc"
    p.write_bytes(b"11111\n2 2 2 8\n1 1 0.5000000000000000000000000000000000000\n0 0 0 0\n0 0 X" + bytes(range(8)))
    vol = load_volume(p)
    assert vol.spacing == (1.0, 1.0, 0.5)
    np.testing.assert_array_equal(vol.data.ravel(), range(8))


def test_an_slc_count_missing_before_its_x_is_named(tmp_path):
    # The word ends at the X now, so an X where the count should be is a missing number, not the end.
    p = tmp_path / "m.slc"
    p.write_bytes(b"11111\n2 2 2 8\n1 1 1\n0 0 0 1\n0 X")
    with pytest.raises(InputError, match=r"bad SLC header: icon height should be a number, got b'X'$"):
        load_volume(p)


def test_metaimage_integers_are_read_as_metaio_reads_them(tmp_path):
    # MetaIO reads counts with atoi-like rules: "03" is 3, and "1_0" is not Python's 10.
    def mha(*lines):
        p = tmp_path / "m.mha"
        p.write_bytes(("\n".join(["ObjectType = Image", *lines, "DimSize = 2 3 4", "ElementType = MET_SHORT",
                                   "ElementDataFile = LOCAL"]) + "\n").encode() + ARR16.astype("<i2").tobytes())
        return p
    assert np.array_equal(load_volume(mha("NDims = 03")).data, ARR16)
    with pytest.raises(InputError, match=r"NDims is not an integer: '3\.0'"):
        load_volume(mha("NDims = 3.0"))
    with pytest.raises(InputError, match=r"HeaderSize is not an integer: '1_0'"):
        load_volume(mha("NDims = 3", "HeaderSize = 1_0"))


def test_an_nrrd_extent_that_runs_backwards_is_said_like_a_negative_spacing(tmp_path):
    # axis mins above axis maxs on x: the same mirrored axis as "spacings: -1 2 3", said the same way.
    p = tmp_path / "r.nrrd"
    p.write_bytes(_nrrd(BASE + [b"centers: node node node", b"axis mins: 1 0 0", b"axis maxs: 0 4 9"],
                        ARR16.astype(">i2").tobytes()))
    vol = load_volume(p)
    assert vol.spacing == (1.0, 2.0, 3.0) and vol.origin == (0.0, 0.0, 0.0)
    assert vol.meta["reoriented"] and "mirrored axes" in vol.meta["note"]
    forwards = p.with_name("f.nrrd")
    forwards.write_bytes(p.read_bytes().replace(b"axis mins: 1 0 0", b"axis mins: 0 0 0")
                         .replace(b"axis maxs: 0 4 9", b"axis maxs: 1 4 9"))
    assert "note" not in load_volume(forwards).meta and "reoriented" not in load_volume(forwards).meta


def test_attached_nrrd_data_without_the_blank_line_before_it_is_named(tmp_path):
    # The samples (2000 * i + 58: a ':' and a NUL in the first) are read as a header line; tabs
    # within a real header line are not what sets it apart.
    p = tmp_path / "b.nrrd"
    header = [b"type: short", b"dimension:\t3", b"sizes: 2 3 4", b"endian: little", b"encoding: raw"]
    samples = (np.arange(24, dtype="<i2") * 2000 + 58).tobytes()
    p.write_bytes(b"NRRD0004\n" + b"".join(f + b"\n" for f in header) + samples)
    with pytest.raises(InputError, match="an attached header ends at a blank line before the data"):
        load_volume(p)
    p.write_bytes(b"NRRD0004\n" + b"".join(f + b"\n" for f in header) + b"\n" + samples)
    assert np.array_equal(load_volume(p).data.ravel(), np.frombuffer(samples, "<i2"))


def test_an_empty_metaimage_header_size_is_no_header_size(tmp_path):
    p = tmp_path / "e.mha"
    p.write_bytes(b"ObjectType = Image\nNDims = 3\nHeaderSize =\nDimSize = 2 3 4\nElementType = MET_SHORT\n"
                  b"ElementDataFile = LOCAL\n" + ARR16.astype("<i2").tobytes())
    assert np.array_equal(load_volume(p).data, ARR16)
