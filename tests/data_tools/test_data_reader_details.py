"""The readers' finer rules (run-length codes, skipped VTK sections, MetaImage and NRRD field
precedence, detached files): each file is written byte by byte here, per its format's spec,
never by the reader's own writer."""
from __future__ import annotations

import zlib

import numpy as np
import pytest

from data_tools.io import load_volume

from load_errors import fails


# --- SLC run-length edge cases ---------------------------------------------

def _slc(slices, nx=2, ny=2):
    """An SLC file of run-length ``slices`` (each the code bytes of one slice), no icon."""
    out = bytearray(b"11111\n%d %d %d 8\n1 1 1\n0 0 0 1\n0 0 X" % (nx, ny, len(slices)))
    for code in slices:
        out += b"%d X" % len(code) + code
    return bytes(out)


def test_slc_bytes_after_a_slices_end_code_are_ignored(tmp_path):
    # A count of 0 ends the slice: what its stated size holds after it is not decoded.
    p = tmp_path / "t.slc"
    p.write_bytes(_slc([b"\x04\x07\x00\x05\x09", b"\x84\x01\x02\x03\x04\x00"]))
    np.testing.assert_array_equal(load_volume(p).data.ravel(), [7, 7, 7, 7, 1, 2, 3, 4])


def test_slc_repeat_run_without_its_value_is_an_input_error(tmp_path):
    # The slice's bytes end after a repeat count: no value byte to repeat.
    p = tmp_path / "r.slc"
    p.write_bytes(_slc([b"\x03\x05\x01", b"\x04\x06\x00"]))
    fails(p, "SLC slice 0 decodes to 3 samples, expected 4")


def test_slc_run_past_the_slice_is_refused_as_it_decodes(tmp_path):
    p = tmp_path / "o.slc"
    p.write_bytes(_slc([b"\x7f\x05\x00", b"\x04\x06\x00"]))
    fails(p, "SLC slice 0 decodes to more than its 4 samples")


# --- MetaImage compressed data holding more than DimSize -------------------

def test_mha_compressed_data_longer_than_dimsize_is_refused(tmp_path):
    arr = np.arange(2 * 3 * 4, dtype=np.uint8).reshape(4, 3, 2)
    head = (b"ObjectType = Image\nNDims = 3\nDimSize = 2 3 4\nElementType = MET_UCHAR\n"
            b"CompressedData = True\nElementDataFile = LOCAL\n")
    p = tmp_path / "c.mha"
    p.write_bytes(head + zlib.compress(arr.tobytes() + b"\x00"))
    fails(p, "holds more than the 24 bytes the header states")


# --- VTK: a bit array before the scalars takes (n + 7) // 8 bytes ---------

def test_vtk_binary_bit_field_array_before_the_scalars_is_read_past(tmp_path):
    arr = np.arange(24, dtype=np.uint8).reshape(4, 3, 2)
    head = (b"# vtk DataFile Version 3.0\nbits\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 3 4\n"
            b"SPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA 24\nFIELD FieldData 1\nmask 1 24 bit\n")
    p = tmp_path / "b.vtk"
    p.write_bytes(head + b"\xff\x00\xff\n" + b"SCALARS s unsigned_char 1\nLOOKUP_TABLE default\n" + arr.tobytes())
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, arr)
    assert vol.meta["scalars"] == "s"


# --- MetaImage: ElementSpacing wins over ElementSize -----------------------

def test_mha_element_spacing_wins_over_element_size(tmp_path):
    arr = np.arange(24, dtype=np.uint8).reshape(4, 3, 2)
    head = (b"NDims = 3\nDimSize = 2 3 4\nElementType = MET_UCHAR\nElementSize = 7 8 9\n"
            b"ElementSpacing = 1 2 3\nElementDataFile = LOCAL\n")
    p = tmp_path / "s.mha"
    p.write_bytes(head + arr.tobytes())
    assert load_volume(p).spacing == (1.0, 2.0, 3.0)
    p.write_bytes(head.replace(b"ElementSpacing = 1 2 3\n", b"") + arr.tobytes())
    assert load_volume(p).spacing == (7.0, 8.0, 9.0)


# --- NRRD: space origin wins over axis mins --------------------------------

def _nrrd(fields, data: bytes) -> bytes:
    return b"NRRD0004\n" + b"".join(f + b"\n" for f in fields) + b"\n" + data


NRRD_SHORT = [b"type: short", b"dimension: 3", b"sizes: 2 3 4", b"endian: big", b"encoding: raw"]
ARR16 = (np.arange(24, dtype=np.int16).reshape(4, 3, 2) * 1000 - 5000)


def test_nrrd_space_origin_wins_over_axis_mins(tmp_path):
    p = tmp_path / "o.nrrd"
    p.write_bytes(_nrrd(NRRD_SHORT + [b"space: LPS", b"space directions: (1,0,0) (0,2,0) (0,0,3)",
                                      b"space origin: (4,5,6)", b"axis mins: 100 100 100"],
                        ARR16.astype(">i2").tobytes()))
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR16)
    assert vol.spacing == (1.0, 2.0, 3.0) and vol.origin == (4.0, 5.0, 6.0)


# --- raw: every byte-order word a name may hold ----------------------------

@pytest.mark.parametrize("word, big", [("be", True), ("bigendian", True), ("msb", True),
                                       ("le", False), ("littleendian", False), ("lsb", False)])
def test_raw_byte_order_words_in_the_name(tmp_path, word, big):
    p = tmp_path / f"v_2x3x4_int16_{word}.raw"
    p.write_bytes(ARR16.astype(">i2" if big else "<i2").tobytes())
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR16)
    assert vol.meta["byte_order"] == ("big" if big else "little")


# --- VTK: the file type line in any case (vtkDataReader lower-cases it) ----

@pytest.mark.parametrize("kind", [b"binary", b"ascii", b"Binary"])
def test_vtk_file_type_line_in_any_case(tmp_path, kind):
    arr = np.arange(24, dtype=np.uint16).reshape(4, 3, 2) * 1000
    head = (b"# vtk DataFile Version 3.0\nlower\n" + kind + b"\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 3 4\n"
            b"SPACING 1 2 3\nORIGIN 0 0 0\nPOINT_DATA 24\nSCALARS s unsigned_short 1\nLOOKUP_TABLE default\n")
    body = (" ".join(map(str, arr.ravel())).encode() + b"\n" if kind.lower() == b"ascii"
            else arr.astype(">u2").tobytes())
    p = tmp_path / "l.vtk"
    p.write_bytes(head + body)
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, arr)
    assert vol.spacing == (1.0, 2.0, 3.0)


# --- NRRD: header end, compressed stream kind, extent, detached file -------

def test_nrrd_header_with_crlf_lines_ends_at_its_blank_line(tmp_path):
    p = tmp_path / "c.nrrd"
    p.write_bytes(_nrrd(NRRD_SHORT, b"").replace(b"\n", b"\r\n") + ARR16.astype(">i2").tobytes())
    np.testing.assert_array_equal(load_volume(p).data, ARR16)


def test_nrrd_gzip_encoding_refuses_a_bare_zlib_stream(tmp_path):
    # NRRD's gzip encoding is a gzip stream; a zlib stream is not one (teem's gzread would
    # take its bytes as they are).
    p = tmp_path / "z.nrrd"
    fields = [f.replace(b"raw", b"gzip") for f in NRRD_SHORT]
    p.write_bytes(_nrrd(fields, zlib.compress(ARR16.astype(">i2").tobytes())))
    fails(p, "cannot read NRRD file")


def test_nrrd_detached_data_file_is_among_the_files_read(tmp_path):
    (tmp_path / "d.raw").write_bytes(ARR16.astype(">i2").tobytes())
    p = tmp_path / "d.nhdr"
    p.write_bytes(_nrrd(NRRD_SHORT + [b"data file: d.raw"], b""))
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR16)
    assert vol.meta["data_file"] == str(tmp_path / "d.raw")
    assert str(tmp_path / "d.raw") in vol.meta["files"]


def test_slc_header_numbers_with_digit_separators_are_refused(tmp_path):
    # VolVis and VTK read "1_0" as 1 (fscanf %d), Python as 10: neither is the writer's meaning.
    p = tmp_path / "u.slc"
    p.write_bytes(b"11111\n2 2 2 8\n1 1_0 1\n0 0 0 0\n0 0 X" + bytes(8))
    fails(p, "y spacing should be a number, got b'1_0'")


def test_slc_icon_and_slices_must_follow_an_x(tmp_path):
    p = tmp_path / "m.slc"
    p.write_bytes(b"11111\n2 2 2 8\n1 1 1\n0 0 0 0\n0 0 Y" + bytes(8))
    fails(p, "expected 'X' before the icon")
    p.write_bytes(_slc([b"\x04\x07\x00", b"\x04\x05\x00"]).replace(b"3 X\x04\x05", b"3 Y\x04\x05"))
    fails(p, "expected 'X' before slice 1")


def test_slc_header_fields_are_kept(tmp_path):
    p = tmp_path / "h.slc"
    p.write_bytes(b"11111\n2 2 2 8\n1 1 1\n3 4 5 0\n0 0 X" + bytes(8))
    meta = load_volume(p).meta
    assert (meta["unit_type"], meta["data_origin"], meta["data_modification"]) == (3, 4, 5)


# --- VTK binary attributes read past before the scalars --------------------

def _vtk_binary(sections: bytes, arr) -> bytes:
    return (b"# vtk DataFile Version 3.0\nattrs\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 3 4\n"
            b"SPACING 1 1 1\nORIGIN 0 0 0\n" + sections + b"SCALARS s unsigned_char 1\nLOOKUP_TABLE default\n"
            + arr.tobytes())


ARR8 = np.arange(24, dtype=np.uint8).reshape(4, 3, 2)


@pytest.mark.parametrize("name, sections", [
    # 2-D texture coordinates: 2 floats a point, big-endian.
    ("tcoords", b"POINT_DATA 24\nTEXTURE_COORDINATES tc 2 float\n" + np.full(48, 0.5, ">f4").tobytes() + b"\n"),
    # A lookup table of 2 entries: 4 unsigned chars each in binary.
    ("table", b"POINT_DATA 24\nLOOKUP_TABLE mine 2\n" + bytes([10, 20, 30, 255, 40, 50, 60, 255]) + b"\n"),
    # Colours of the 6 cells, 3 components: unsigned chars in binary.
    ("colors", b"CELL_DATA 6\nCOLOR_SCALARS c 3\n" + bytes(range(100, 118)) + b"\nPOINT_DATA 24\n"),
], ids=["tcoords", "table", "colors"])
def test_vtk_binary_attributes_before_the_scalars(tmp_path, name, sections):
    p = tmp_path / f"{name}.vtk"
    p.write_bytes(_vtk_binary(sections, ARR8))
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR8)
    assert vol.meta["scalars"] == "s"


# --- MetaImage text samples and comments -----------------------------------

MHA_HEAD = b"NDims = 3\nDimSize = 2 3 4\nElementType = MET_UCHAR\n"


def test_mha_text_samples_must_be_exactly_dimsize(tmp_path):
    p = tmp_path / "t.mha"
    words = " ".join(map(str, ARR8.ravel())).encode()
    p.write_bytes(MHA_HEAD + b"BinaryData = False\nElementDataFile = LOCAL\n" + words + b" 24\n")
    fails(p, "25 text samples, expected 24")
    p.write_bytes(MHA_HEAD + b"BinaryData = False\nElementDataFile = LOCAL\n" + words + b"\n")
    np.testing.assert_array_equal(load_volume(p).data, ARR8)


def test_mha_compressed_text_samples_are_refused(tmp_path):
    p = tmp_path / "ct.mha"
    words = " ".join(map(str, ARR8.ravel())).encode()
    p.write_bytes(MHA_HEAD + b"BinaryData = False\nCompressedData = True\nElementDataFile = LOCAL\n"
                  + zlib.compress(words))
    fails(p, "CompressedData with text samples (BinaryData = False) is not supported")


def test_mha_comment_lines_in_the_header_are_skipped(tmp_path):
    p = tmp_path / "c.mha"
    p.write_bytes(b"# written by hand\n" + MHA_HEAD + b"# no = field\nElementDataFile = LOCAL\n" + ARR8.tobytes())
    np.testing.assert_array_equal(load_volume(p).data, ARR8)


# --- NRRD geometry fallbacks, detached data that is no file ----------------

def test_nrrd_space_directions_for_fewer_axes_are_refused(tmp_path):
    p = tmp_path / "d.nrrd"
    p.write_bytes(_nrrd(NRRD_SHORT + [b"space: LPS", b"space directions: (1,0,0) (0,1,0)"],
                        ARR16.astype(">i2").tobytes()))
    fails(p, "space directions must give one vector per axis (3 axes)")


def test_nrrd_axis_of_no_extent_gets_spacing_1(tmp_path):
    p = tmp_path / "e.nrrd"
    p.write_bytes(_nrrd(NRRD_SHORT + [b"axis mins: 5 0 0", b"axis maxs: 5 6 12"], ARR16.astype(">i2").tobytes()))
    vol = load_volume(p)
    assert vol.spacing == (1.0, 2.0, 3.0)
    assert vol.meta["note"] == ("axis mins and axis maxs give x no length: spacing 1 was used for it "
                                "(give --spacing SX,SY,SZ)")


def test_nrrd_spacings_beside_space_directions_are_said_to_be_unused(tmp_path):
    # NRRD allows one or the other; teem refuses both.
    p = tmp_path / "b.nrrd"
    p.write_bytes(_nrrd(NRRD_SHORT + [b"space: LPS", b"space directions: (1,0,0) (0,2,0) (0,0,3)",
                                      b"spacings: 7 7 7"], ARR16.astype(">i2").tobytes()))
    vol = load_volume(p)
    assert vol.spacing == (1.0, 2.0, 3.0)
    assert vol.meta["note"] == ("the header gives spacings beside space directions, which NRRD does not allow: "
                                "the space directions were used")


def test_nrrd_detached_data_file_that_is_a_folder(tmp_path):
    (tmp_path / "d.raw").mkdir()
    p = tmp_path / "d.nhdr"
    p.write_bytes(_nrrd(NRRD_SHORT + [b"data file: d.raw"], b""))
    fails(p, "is not a regular file")


def test_nifti_affine_axis_of_no_length_gets_spacing_1(tmp_path):
    nib = pytest.importorskip("nibabel")
    affine = np.diag([0.0, 2.0, 3.0, 1.0])
    img = nib.Nifti1Image(ARR16.T.copy(), None)      # [x, y, z] as NIfTI stores it
    img.header.set_sform(affine, 1)
    img.header["qform_code"] = 0
    p = tmp_path / "z.nii"
    nib.save(img, str(p))
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, ARR16)
    assert vol.spacing == (1.0, 2.0, 3.0)
    assert "no length" in vol.meta["note"]
