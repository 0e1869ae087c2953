"""Readers against files written byte by byte here (header text and samples built with NumPy),
each checked against the samples, spacing and origin written, or refused in one line."""
from __future__ import annotations

import zlib
from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest

from data_tools import Volume
from data_tools.io import load_volume, save_volume

from load_errors import fails

#: Samples [z, y, x] of a volume whose three sizes differ, so that any axis swapped shows.
ARR = (np.arange(24, dtype=np.uint16).reshape(4, 3, 2) * 1000 + 7)


def _vtk_head(encoding, dims=(2, 3, 4), scalars="SCALARS s unsigned_short 1\nLOOKUP_TABLE default\n"):
    nx, ny, nz = dims
    return (f"# vtk DataFile Version 3.0\nby hand\n{encoding}\nDATASET STRUCTURED_POINTS\n"
            f"DIMENSIONS {nx} {ny} {nz}\nSPACING 1 2 3\nORIGIN 4 5 6\nPOINT_DATA {nx * ny * nz}\n"
            f"{scalars}").encode()


def _words(values):
    return (" ".join(str(int(v)) for v in np.ravel(values)) + "\n").encode()


# --- VTK -------------------------------------------------------------------

@pytest.mark.parametrize("section", [b"SCALARS t unsigned_short 1\nLOOKUP_TABLE default\n",
                                     b"scalars t unsigned_short 1\nlookup_table default\n"])
def test_ascii_vtk_samples_with_a_section_after_them_are_read(tmp_path, section):
    # VTK's reader takes its keywords in any case.
    p = tmp_path / "a.vtk"
    p.write_bytes(_vtk_head("ASCII") + _words(ARR) + section + _words(ARR + 1))
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR)
    assert (vol.spacing, vol.origin) == ((1.0, 2.0, 3.0), (4.0, 5.0, 6.0))


@pytest.mark.parametrize("tail", [_words(range(6)), b"garbage here\n"])
def test_ascii_vtk_values_past_the_samples_stated_are_refused(tmp_path, tail):
    # Written as 2x3x5 under a header saying 2x3x4: read as stated, every row after the first
    # would be shifted. Binary samples with bytes over are refused alike.
    p = tmp_path / "a.vtk"
    p.write_bytes(_vtk_head("ASCII") + _words(ARR) + tail)
    fails(p, "after the ASCII VTK samples the header states")
    p.write_bytes(_vtk_head("BINARY") + ARR.astype(">u2").tobytes() + tail)
    fails(p, "after the VTK samples the header states")


@pytest.mark.parametrize("word", ["3.4028235e+38", "-3.4028235e+38", "3.40282347e+38"])
def test_ascii_vtk_float32_largest_value_written_short_is_read(tmp_path, word):
    # float32's largest value as VTK 9 and NumPy write it (shortest round trip) or as %.9g does:
    # above it as a double, below the overflow threshold (half a step past it), so C's strtof
    # rounds it to that value, as NRRD's and MetaImage's text samples are read.
    top = Fraction(float(np.finfo(np.float32).max))
    assert top < abs(Fraction(Decimal(word))) < top + Fraction(2) ** 103
    p = tmp_path / "m.vtk"
    p.write_bytes(_vtk_head("ASCII", scalars="SCALARS s float 1\nLOOKUP_TABLE default\n")
                  + (f"{word} " + "1.5 " * 23 + "\n").encode())
    data = load_volume(p).data.ravel()
    assert data.dtype == np.float32
    assert data[0] == np.copysign(np.finfo(np.float32).max, float(word)) and (data[1:] == 1.5).all()


@pytest.mark.parametrize("word", ["3.4028236e+38", "-1e39", "inf"])
def test_ascii_vtk_float32_text_past_the_overflow_threshold_is_refused(tmp_path, word):
    p = tmp_path / "o.vtk"
    p.write_bytes(_vtk_head("ASCII", scalars="SCALARS s float 1\nLOOKUP_TABLE default\n")
                  + (f"{word} " + "1.5 " * 23 + "\n").encode())
    fails(p, "ASCII VTK values outside the float32 range")


def test_vtk_dimensions_of_zero_are_named(tmp_path):
    p = tmp_path / "z.vtk"
    p.write_bytes(_vtk_head("ASCII", dims=(0, 3, 4)))
    fails(p, "DIMENSIONS must be positive")


def test_vtk_encoding_other_than_ascii_or_binary_is_named(tmp_path):
    p = tmp_path / "e.vtk"
    p.write_bytes(_vtk_head("BINRAY") + ARR.astype(">u2").tobytes())
    fails(p, "expected ASCII or BINARY on line 3, got 'BINRAY'")


def test_vtk_first_candidate_among_several_field_blocks_is_read(tmp_path):
    # vtkDataReader adds the arrays of every FIELD block to the points; the first array of
    # one component is the one read, whichever block holds it.
    n = ARR.size
    p = tmp_path / "f.vtk"
    p.write_bytes(_vtk_head("BINARY", scalars=f"FIELD One 1\ndensity 1 {n} unsigned_short\n")
                  + ARR.astype(">u2").tobytes() + f"\nFIELD Two 1\nheat 1 {n} float\n".encode()
                  + np.ones(n, ">f4").tobytes() + b"\n")
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR)
    assert vol.meta["scalars"] == "density"
    assert vol.meta["note"] == "the points carry 2 scalar arrays (density, heat); the first was read (density)"


def test_vtk_written_for_a_volume_named_outside_ascii_reads_back(tmp_path):
    # The title line is ASCII: a name such as "schädel.nrrd" goes in with ? for what is not.
    vol = Volume(ARR, spacing=(1.0, 2.0, 3.0), origin=(4.0, 5.0, 6.0), name="/data/schädel.nrrd")
    p = save_volume(vol, tmp_path / "s.vtk")
    assert p.read_bytes().split(b"\n")[1] == b"sch?del.nrrd"
    back = load_volume(p)
    np.testing.assert_array_equal(back.data, ARR)
    assert (back.spacing, back.origin) == (vol.spacing, vol.origin)


# --- NRRD ------------------------------------------------------------------

def test_nrrd_text_samples_keep_their_axis_order(tmp_path):
    p = tmp_path / "t.nrrd"
    p.write_bytes(b"NRRD0004\ntype: ushort\ndimension: 3\nsizes: 2 3 4\nspacings: 1 2 3\n"
                  b"encoding: ascii\n\n" + _words(ARR))
    vol = load_volume(p)
    assert vol.data.dtype == np.uint16
    np.testing.assert_array_equal(vol.data, ARR)
    assert vol.spacing == (1.0, 2.0, 3.0)


def test_nrrd_space_is_kept_in_the_meta(tmp_path):
    p = tmp_path / "s.nrrd"
    p.write_bytes(b"NRRD0004\ntype: ushort\ndimension: 3\nsizes: 2 3 4\nspace: left-posterior-superior\n"
                  b"space directions: (1,0,0) (0,2,0) (0,0,3)\nspace origin: (4,5,6)\nendian: little\n"
                  b"encoding: raw\n\n" + ARR.astype("<u2").tobytes())
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR)
    assert (vol.spacing, vol.origin) == ((1.0, 2.0, 3.0), (4.0, 5.0, 6.0))
    assert vol.meta["space"] == "left-posterior-superior"


def test_nrrd_data_file_whose_name_begins_with_list_is_one_file(tmp_path):
    # Only the word LIST (a dimension may follow it) names a list of data files: LISTING.raw is
    # one, among the files read, and the fields after its line are read too.
    (tmp_path / "LISTING.raw").write_bytes(ARR.astype(">u2").tobytes())
    p = tmp_path / "scan.nhdr"
    p.write_bytes(b"NRRD0004\ntype: ushort\ndimension: 3\nsizes: 2 3 4\nendian: big\nencoding: raw\n"
                  b"data file: LISTING.raw\nspacings: 1 2 3\n")
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR)
    assert vol.spacing == (1.0, 2.0, 3.0)
    assert vol.meta["files"] == (str(p), str(tmp_path / "LISTING.raw"))


def test_nrrd_time_axis_holds_positions(tmp_path):
    # NRRD's kind "time" is a domain kind: samples along it are positions, not values.
    p = tmp_path / "k.nrrd"
    p.write_bytes(b"NRRD0004\ntype: ushort\ndimension: 3\nsizes: 2 3 4\nkinds: domain domain time\n"
                  b"endian: big\nencoding: raw\n\n" + ARR.astype(">u2").tobytes())
    np.testing.assert_array_equal(load_volume(p).data, ARR)


# --- MetaImage -------------------------------------------------------------

def test_metaimage_element_type_in_lower_case_is_read(tmp_path):
    p = tmp_path / "m.mha"
    p.write_bytes(b"NDims = 3\nDimSize = 2 3 4\nElementType = met_ushort\nElementSpacing = 1 2 3\n"
                  b"BinaryDataByteOrderMSB = True\nElementDataFile = LOCAL\n" + ARR.astype(">u2").tobytes())
    vol = load_volume(p)
    assert vol.data.dtype == np.uint16
    np.testing.assert_array_equal(vol.data, ARR)


def test_metaimage_data_file_is_among_the_files_read(tmp_path):
    (tmp_path / "d.dat").write_bytes(ARR.astype("<u2").tobytes())
    p = tmp_path / "h.mhd"
    p.write_bytes(b"NDims = 3\nDimSize = 2 3 4\nElementType = MET_USHORT\nElementDataFile = d.dat\n")
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR)
    assert vol.meta["files"] == (str(p), str(tmp_path / "d.dat"))


def test_metaimage_compressed_data_cut_short_are_named_truncated(tmp_path):
    head = (b"NDims = 3\nDimSize = 2 3 4\nElementType = MET_USHORT\nCompressedData = True\n"
            b"ElementDataFile = LOCAL\n")
    p = tmp_path / "c.mha"
    stream = zlib.compress(ARR.astype("<u2").tobytes())
    p.write_bytes(head + stream)
    np.testing.assert_array_equal(load_volume(p).data, ARR)
    cut = zlib.decompressobj().decompress(stream[:-12])
    assert 0 < len(cut) < ARR.nbytes
    p.write_bytes(head + stream[:-12])
    fails(p, f"compressed MetaImage data truncated: expected 48 bytes, inflated {len(cut)}")


# --- SLC -------------------------------------------------------------------

def test_slc_header_number_longer_than_64_characters_is_named(tmp_path):
    p = tmp_path / "l.slc"
    p.write_bytes(b"11111\n" + b"0" * 70 + b"2 3 4 8\n1 1 1\n0 0 0 0\n0 0 X" + bytes(24))
    fails(p, "bad SLC header: xsize is not a number (over 64 characters)")
    p.write_bytes(b"11111\n2 3 4 8\n1 1 1\n0 0 0 0\n0 0 X" + bytes(range(24)))
    np.testing.assert_array_equal(load_volume(p).data, np.arange(24, dtype=np.uint8).reshape(4, 3, 2))


# --- NumPy -----------------------------------------------------------------

def test_npy_sidecar_with_spacing_alone_leaves_the_origin_at_zero(tmp_path):
    p = tmp_path / "s.npy"
    np.save(p, ARR)
    (tmp_path / "s.npy.json").write_text('{"spacing": [1.5, 2, 3]}')
    vol = load_volume(p)
    assert (vol.spacing, vol.origin) == ((1.5, 2.0, 3.0), (0.0, 0.0, 0.0))
    (tmp_path / "s.npy.json").write_text('{"origin": [-1, 0.5, 7]}')
    vol = load_volume(p)
    assert (vol.spacing, vol.origin) == ((1.0, 1.0, 1.0), (-1.0, 0.5, 7.0))


# NumPy parses the header taken with a sample byte only on a second try, and says so.
@pytest.mark.filterwarnings("ignore:Reading `.npy`")
def test_npy_header_that_does_not_end_where_it_says_is_refused(tmp_path):
    # A header one byte shorter than its stated length (a space of its padding removed) and a
    # byte added at the end: NumPy reads the first sample byte (a blank) as header, the rest
    # shifted.
    data = np.full((4, 3, 2), 32, dtype=np.uint8)
    data[0, 0, 1] = 200
    text = "{'descr': '|u1', 'fortran_order': False, 'shape': (4, 3, 2), }"
    stated = 128 - 10
    header = text.ljust(stated - 1) + "\n"
    good = b"\x93NUMPY\x01\x00" + stated.to_bytes(2, "little") + header.encode() + data.tobytes()
    p = tmp_path / "h.npy"
    p.write_bytes(good)
    np.testing.assert_array_equal(load_volume(p).data, data)
    p.write_bytes(good.replace(b" \n", b"\n", 1) + b"\x00")
    shifted = np.load(p)
    assert shifted.shape == data.shape and not np.array_equal(shifted, data)
    fails(p, "its header does not end where its stated length says")


# --- TIFF ------------------------------------------------------------------

def test_ome_tiff_axes_without_a_unit_are_in_micrometres(tmp_path):
    # OME's default unit is the micrometre: z given in nm is converted to it, 2000 nm = 2 µm.
    tifffile = pytest.importorskip("tifffile")
    p = tmp_path / "u.ome.tif"
    tifffile.imwrite(p, ARR, ome=True, metadata={"axes": "ZYX", "PhysicalSizeX": 0.5, "PhysicalSizeY": 0.25,
                                                 "PhysicalSizeZ": 2000, "PhysicalSizeZUnit": "nm"})
    assert b"PhysicalSizeXUnit" not in p.read_bytes()
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR)
    assert vol.spacing == (0.5, 0.25, 2.0) and vol.meta["unit"] == "µm"


def test_imagej_slice_spacing_that_is_not_positive_is_taken_as_absent(tmp_path):
    tifffile = pytest.importorskip("tifffile")
    p = tmp_path / "n.tif"
    tifffile.imwrite(p, ARR, imagej=True, resolution=(4.0, 2.0),
                     metadata={"spacing": -2.0, "unit": "um", "axes": "ZYX"})
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR)
    assert vol.spacing == (0.25, 0.5, 1.0)
    assert vol.meta["note"] == "the TIFF gives no voxel size along z: 1 was used (give --spacing SX,SY,SZ)"
