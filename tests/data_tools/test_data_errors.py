"""Bad input of every kind raises InputError with one line naming the file, never a raw exception."""
from __future__ import annotations

import bz2
import gzip
import os
import re
import stat
import struct
import tracemalloc
import zlib

import nrrd
import numpy as np
import pytest

from data_tools import InputError, Volume, memory
from data_tools.io import READ_EXTENSIONS, load_volume, save_volume
from data_tools.volume import is_number, three_numbers

from load_errors import fails

SMALL = np.arange(4 * 5 * 6, dtype=np.uint8).reshape(4, 5, 6)


@pytest.mark.parametrize("ext", READ_EXTENSIONS)
def test_missing_file(tmp_path, ext):
    fails(tmp_path / f"nothere{ext}", "no such file")


def test_unknown_extension_lists_supported(tmp_path):
    p = tmp_path / "v.png"
    p.write_bytes(b"\x89PNG\r\n\x1a\n")
    msg = fails(p, "unknown")
    assert ".nrrd" in msg and ".slc" in msg and ".raw" in msg


def test_directory(tmp_path):
    d = tmp_path / "dir.nrrd"
    d.mkdir()
    fails(d, "is a folder")         # "folder", as every message says


@pytest.mark.parametrize("ext", [".nrrd", ".nhdr", ".mhd", ".mha", ".vtk", ".slc", ".npy"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_bytes_with_a_volume_extension(tmp_path, ext, seed):
    p = tmp_path / f"garbage{ext}"
    p.write_bytes(np.random.default_rng(seed).integers(0, 256, 3000, dtype=np.uint8).tobytes())
    fails(p)


@pytest.mark.parametrize("ext", [".nrrd", ".mhd", ".vtk", ".slc", ".npy"])
def test_empty_file(tmp_path, ext):
    p = tmp_path / f"empty{ext}"
    p.write_bytes(b"")
    fails(p)


@pytest.mark.parametrize("ext", [".nrrd", ".mhd", ".vtk", ".slc"])
def test_text_that_is_not_the_format(tmp_path, ext):
    p = tmp_path / f"prose{ext}"
    p.write_text("This is a letter, not a volume.\nRegards.\n")
    fails(p)


# --- raw ---------------------------------------------------------------------

def test_raw_without_shape_or_type_names_the_flags(tmp_path):
    p = tmp_path / "plain.raw"
    p.write_bytes(bytes(64))
    msg = fails(p)
    assert "--shape" in msg and "--dtype" in msg
    msg = fails(p, shape=(4, 4, 4))
    assert "--dtype" in msg and "--shape NX" not in msg


@pytest.mark.parametrize("ext", [".mhd", ".nhdr"])
def test_raw_samples_of_a_header_pair_point_at_the_header(tmp_path, ext):
    header = save_volume(Volume(np.zeros((2, 3, 4), np.uint8)), tmp_path / f"pair{ext}")
    msg = fails(tmp_path / "pair.raw")
    assert f"open {header.name} instead" in msg and "--shape" not in msg
    (tmp_path / "lone.raw").write_bytes(bytes(24))          # headers beside naming other samples
    (tmp_path / "lone.mhd").write_text("NDims = 3\n# from lone.raw\nElementDataFile = lone.raw.gz\n")
    (tmp_path / "lone.nhdr").write_text("NRRD0004\n# converted from lone.raw\ndata file: other.raw\n")
    assert "--shape" in fails(tmp_path / "lone.raw")
    (tmp_path / "long.raw").write_bytes(bytes(24))          # a long comment before the line
    (tmp_path / "long.mhd").write_text("Comment = " + "x" * 100000 + "\nElementDataFile = long.raw\n")
    assert "open long.mhd instead" in fails(tmp_path / "long.raw")


def test_raw_size_mismatch_states_both_sizes(tmp_path):
    p = tmp_path / "v_4x4x4_uint16.raw"
    p.write_bytes(bytes(100))
    msg = fails(p, "truncated")
    assert "128" in msg and "100" in msg
    p.write_bytes(bytes(130))
    msg = fails(p, "too long")
    assert "128" in msg and "130" in msg


@pytest.mark.parametrize("opts,match", [({"dtype": "complex64"}, "unsupported"), ({"dtype": "int64"}, "unsupported"),
                                        ({"shape": (4, 4)}, "three"), ({"shape": "4,x,4"}, "three"),
                                        ({"shape": (0, 4, 4)}, "positive"), ({"byte_order": "middle"}, "byte order"),
                                        ({"offset": -3}, "offset")])
def test_raw_bad_options(tmp_path, opts, match):
    p = tmp_path / "v_4x4x4_uint8.raw"
    p.write_bytes(bytes(64))
    fails(p, match, **opts)


def test_raw_nonfinite_floats_refused(tmp_path):
    a = np.ones((3, 3, 3), dtype=np.float32)
    a[1, 1, 1] = np.nan
    p = tmp_path / "n_3x3x3_float32.raw"
    a.tofile(p)
    fails(p, "non-finite")


def test_dimension_below_two(tmp_path):
    p = tmp_path / "flat_4x4x1_uint8.raw"
    p.write_bytes(bytes(16))
    fails(p, "at least 2")


def test_raw_only_options_rejected_for_headed_formats(tmp_path):
    p = save_volume(Volume(SMALL), tmp_path / "v.nrrd")
    fails(p, "raw", dtype="uint8")


# --- npy -------------------------------------------------------------------

@pytest.mark.parametrize("shape", [(10, 10, 10), (100000, 100000, 100000)])
@pytest.mark.parametrize("version", [(1, 0), (2, 0)])
def test_npy_shorter_than_its_header_says_is_truncated(tmp_path, shape, version):
    # Said before NumPy allocates the array: a huge one failed as out of memory.
    p = tmp_path / "t.npy"
    with open(p, "wb") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "<f4", "fortran_order": False, "shape": shape}) \
            if version == (1, 0) else \
            np.lib.format.write_array_header_2_0(f, {"descr": "<f4", "fortran_order": False, "shape": shape})
        f.write(bytes(64))
    fails(p, f"truncated: its header's {'x'.join(map(str, shape))} float32 array needs")


def test_npy_nan_and_wrong_rank(tmp_path):
    a = np.zeros((3, 3, 3))
    a[0, 0, 0] = np.inf
    np.save(tmp_path / "inf.npy", a)
    fails(tmp_path / "inf.npy", "non-finite")
    np.save(tmp_path / "flat.npy", np.zeros((3, 3)))
    fails(tmp_path / "flat.npy", "3 dimensions")
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    fails(tmp_path / "obj.npy")


@pytest.mark.parametrize("header, words", [
    (b"{'descr': '<f4', 'fortran_order': False, 'shape': (3, 4, 5, }", "its header is not a python dictionary literal"),
    (b"{'descr': '<02', 'fortran_order': False, 'shape': (3, 4, 5), }", "its header is not a python dictionary literal"),
    (b"{'descr': '<f4', 'fortran_order': False, 'shape': range(3), }", "its header is not a python dictionary literal"),
    (b"{'descr': '<f4', 'fortran_order': False, 'shape': (-4, 4, 4), }", "the shape (-4, 4, 4), with a negative size"),
])
def test_npy_with_a_header_python_cannot_parse(tmp_path, header, words):
    # NumPy reads the header as a Python literal: these failed in the tokenizer's, the parser's
    # ("malformed node or string ... <ast.Call object at 0x...>") or NumPy's words.
    header = header.ljust(117) + b"\n"
    p = tmp_path / "bad.npy"
    p.write_bytes(b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header + bytes(240))
    fails(p, words)


@pytest.mark.parametrize("text, match", [("{not json", "bad sidecar"),
                                         ('{"spacing": "123"}', "spacing must be an array of three numbers"),
                                         ('{"spacing": [true, true, true]}', "spacing must be"),
                                         ('{"origin": [1, 2]}', "origin must be"),
                                         ('{"spacng": [1, 2, 3]}', "unknown keys 'spacng'"),
                                         ("[1, 2]", "the sidecar holds [1, 2]; expected a JSON object")])
def test_npy_bad_sidecar(tmp_path, text, match):
    np.save(tmp_path / "s.npy", SMALL)
    (tmp_path / "s.npy.json").write_text(text)
    with pytest.raises(InputError, match="s.npy.json") as exc:
        load_volume(tmp_path / "s.npy")
    assert match in str(exc.value)
    with pytest.raises(InputError, match="s.npy.json"):
        load_volume(tmp_path / "s.npy", spacing=(2, 3, 4))           # the origin would come from it
    # Spacing and origin both given: nothing would be taken from the sidecar, so it is not read.
    vol = load_volume(tmp_path / "s.npy", spacing=(2, 3, 4), origin=(1, 1, 1))
    assert (vol.spacing, vol.origin) == ((2.0, 3.0, 4.0), (1.0, 1.0, 1.0))
    np.testing.assert_array_equal(vol.data, SMALL)


@pytest.mark.parametrize("text, key", [('{"spacing": [1, 1, 1], "spacing": [4, 4, 4]}', "spacing"),
                                       ('{"origin": [0, 0, 0], "spacing": [2, 2, 2], "origin": [9, 9, 9]}', "origin")])
def test_npy_sidecar_key_given_twice_is_refused(tmp_path, text, key):
    # JSON keeps the last without a word: the first was read at 4, whatever the writer meant.
    np.save(tmp_path / "s.npy", SMALL)
    (tmp_path / "s.npy.json").write_text(text)
    fails(tmp_path / "s.npy", f"s.npy.json: key '{key}' is given twice in the sidecar")


# --- NRRD ------------------------------------------------------------------

def test_nrrd_truncated_gzip(tmp_path):
    p = save_volume(Volume(np.random.default_rng(0).integers(0, 255, (20, 20, 20), dtype=np.uint8)),
                    tmp_path / "t.nrrd")
    p.write_bytes(p.read_bytes()[:-500])
    fails(p)


def test_nrrd_truncated_raw(tmp_path):
    p = save_volume(Volume(SMALL), tmp_path / "t.nrrd", compress=False)
    p.write_bytes(p.read_bytes()[:-7])
    fails(p, "truncated")


def test_nrrd_detached_data_missing(tmp_path):
    p = save_volume(Volume(SMALL), tmp_path / "d.nhdr")
    for f in tmp_path.iterdir():
        if f.name != "d.nhdr":
            f.unlink()
    fails(p)


def test_nrrd_2d_and_4d(tmp_path):
    nrrd.write(str(tmp_path / "two.nrrd"), np.zeros((4, 5), np.uint8), index_order="C")
    fails(tmp_path / "two.nrrd", "3-D")
    nrrd.write(str(tmp_path / "four.nrrd"), np.zeros((2, 3, 4, 5), np.uint8), index_order="C")
    fails(tmp_path / "four.nrrd", "3-D")


def test_nrrd_unsupported_type(tmp_path):
    nrrd.write(str(tmp_path / "i64.nrrd"), np.full((3, 3, 3), 2**40, np.int64), index_order="C")
    fails(tmp_path / "i64.nrrd", "unsupported sample type int64 with values beyond 32 bits")
    nrrd.write(str(tmp_path / "small.nrrd"), np.arange(27, dtype=np.int64).reshape(3, 3, 3), index_order="C")
    assert load_volume(tmp_path / "small.nrrd").dtype == np.int32     # every value fits


def test_nrrd_unknown_type_is_named(tmp_path):
    p = tmp_path / "q.nrrd"
    p.write_bytes(b"NRRD0004\ntype: quux\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n" + bytes(8))
    fails(p, "unsupported value 'quux' in the header")


def test_nrrd_corrupt_header_field(tmp_path):
    p = tmp_path / "h.nrrd"
    p.write_bytes(b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 two 2\nencoding: raw\n\n" + bytes(8))
    fails(p)


def _nrrd_text(path, fields, data=b""):
    path.write_bytes(b"NRRD0004\n" + "".join(f"{k}: {v}\n" for k, v in fields.items()).encode() + b"\n" + data)
    return path


@pytest.mark.parametrize("kind, value", [("uchar", -1), ("uint8", 256), ("signed char", 200), ("short", 70000),
                                         ("ushort", -5), ("int", 3000000000)])
def test_nrrd_text_sample_outside_its_type_is_named(tmp_path, kind, value):
    # pynrrd parses text straight into the type: -1 became 255.
    p = _nrrd_text(tmp_path / "t.nrrd", {"type": kind, "dimension": 3, "sizes": "2 2 2", "encoding": "ascii"},
                   f"{value} 1 2 3 4 5 6 7\n".encode())
    fails(p, f"the text sample {value} is outside the header's type {kind}")
    ok = _nrrd_text(tmp_path / "ok.nrrd", {"type": kind, "dimension": 3, "sizes": "2 2 2", "encoding": "ascii"},
                    b"0 1 2 3 4 5 6 7\n")
    assert load_volume(ok).data.ravel().tolist() == list(range(8))


@pytest.mark.parametrize("lines", [9, 10**20])
def test_nrrd_line_skip_past_the_data_is_refused_at_once(tmp_path, lines):
    # pynrrd reads that many lines, even past the end: 1e20 never returned.
    p = _nrrd_text(tmp_path / "s.nrrd", {"type": "uchar", "dimension": 3, "sizes": "2 2 2", "encoding": "raw",
                                         "line skip": lines}, bytes(8))
    fails(p, f"line skip {lines} passes the end of the data (8 bytes)")


@pytest.mark.parametrize("spacings", ["2 3", "2 3 4 5"])
def test_nrrd_spacings_for_another_number_of_axes_are_refused(tmp_path, spacings):
    p = _nrrd_text(tmp_path / "s.nrrd", {"type": "uchar", "dimension": 3, "sizes": "2 2 2", "encoding": "raw",
                                         "spacings": spacings}, bytes(8))
    fails(p, f"spacings gives {len(spacings.split())} values for 3 axes")


@pytest.mark.parametrize("fields, match", [
    ("kinds: domain", "kinds gives 1 value for 3 axes"),
    ("kinds: domain domain domain domain", "kinds gives 4 values for 3 axes"),
    ("centers: node", "centers gives 1 value for 3 axes"),
    ("axismaxs: 1 1 1 1", "axis maxs gives 4 values for 3 axes"),
    ("axis mins: 0 0\naxis maxs: 1 1", "axis mins gives 2 values for 3 axes"),
    ("space dimension: 2\nspace directions: (1,0,0) (0,1,0) (0,0,1)",
     "space directions gives vectors of 3 values where the space dimension is 2"),
    ("space dimension: 3\nspace directions: (1,0) (0,1) (1,1)",
     "space directions gives vectors of 2 values where the space dimension is 3"),
    # A named space states its dimension as well.
    ("space: RAS\nspace directions: (1,0) (0,1) (1,1)",
     "space directions gives vectors of 2 values where space RAS is 3-D"),
    ("space: left-posterior-superior-time\nspace directions: (1,0,0) (0,1,0) (0,0,1)",
     "space directions gives vectors of 3 values where space left-posterior-superior-time is 4-D"),
])
def test_nrrd_per_axis_fields_and_space_vectors_of_another_count_are_refused(tmp_path, fields, match):
    # pynrrd takes any count: "kinds: domain" was read as the kind of x alone, "centers: node"
    # as x's centring, mins and maxs of two axes were dropped for (0, 0, 0), and the space
    # dimension was never compared with the directions.
    p = tmp_path / "c.nrrd"
    p.write_bytes(f"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n{fields}\nencoding: raw\n\n".encode()
                  + bytes(8))
    fails(p, match)


@pytest.mark.parametrize("head, match", [
    (b"type: uchar\xff\n\n" + bytes(8), "field 'type': non-ASCII bytes in 'uchar\\xff'"),
    (b"type: uchar\nspacings: 1 2 \xb53\n\n" + bytes(8), "field 'spacings': non-ASCII bytes in '1 2 \\xb53'"),
    (b"ty\xffpe: uchar\n\n" + bytes(8), "unknown field 'ty\ufffdpe'"),
    (b"type: uchar\ndata file: d\xe9.raw\n\n", "field 'data file': non-ASCII bytes in 'd\\xe9.raw'"),
    (b"type: uchar\ndata file: LIST\xff\nd.raw\n", "field 'data file': non-ASCII bytes in 'LIST\\xff'"),
])
def test_nrrd_non_ascii_bytes_in_a_field_read_are_refused(tmp_path, head, match):
    # pynrrd reads each line as ASCII, dropping other bytes: "uchar\xff" was uchar, "1 2 \xb53"
    # 1 2 3, "d\xe9.raw" the data file d.raw, and "LIST\xff" a list of files.
    (tmp_path / "d.raw").write_bytes(bytes(8))
    p = tmp_path / "a.nrrd"
    p.write_bytes(b"NRRD0004\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n" + head)
    fails(p, match)
    # Comments, key/value pairs and free text may hold any text: they change nothing read.
    ok = tmp_path / "ok.nrrd"
    ok.write_bytes(b"NRRD0004\n# caf\xc3\xa9, caf\xe9\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
                   b"content: caf\xc3\xa9\nspace units: \"\xb5m\" \"\xb5m\" \"\xb5m\"\nnote:=caf\xe9\n\n"
                   + bytes(range(8)))
    np.testing.assert_array_equal(load_volume(ok).data.ravel(), np.arange(8))


@pytest.mark.parametrize("field, match", [
    ("space origin: (1,2)", "space origin must be three finite numbers, got (1,2)"),
    ("space origin: (inf,2,3)", "space origin must be three finite numbers, got (inf,2,3)"),
    ("spacngs: 1 1 5", "unknown field 'spacngs' (NRRD has no such field; a free-form key/value pair is written"),
    ("spacings: 1 x 5", "field 'spacings': could not convert string to float: 'x'"),
    ("space origin: 1 2 3", "field 'space origin': Vector should be enclosed by parentheses"),
    ("byte skip: 1000", "byte skip 1000 passes the end of the data (8 bytes)"),
    ("byte skip: 1e3", "field 'byte skip': expected whole numbers, got '1e3'"),
    ("sizes: 2 1e3 2", "field 'sizes': expected whole numbers, got '1e3'"),       # was 1000 samples
    ("sizes: 2 0x4 2", "field 'sizes': expected whole numbers, got '0x4'"),
    ("sizes: 2 2 1e400", "field 'sizes': expected whole numbers, got '1e400'"),   # was -2^63
    ("sizes: 2 2 " + "9" * 30, "samples along an axis is more than any file holds"),
    ("ABCDEFGH", "header line 'ABCDEFGH' is not 'field: value' (an attached header ends at a blank line"),
])
def test_nrrd_header_faults_are_named(tmp_path, field, match):
    # Each was read without a word (the origin moved to 0, the spacing lost) or with a
    # message that named no field ("could not convert string to float: 'x'").
    p = tmp_path / "f.nrrd"
    p.write_bytes(f"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspace dimension: 3\n{field}\n"
                  "encoding: raw\n\n".encode() + bytes(8))
    fails(p, match)


def test_nrrd_key_value_pairs_comments_and_known_fields_are_read(tmp_path):
    p = tmp_path / "f.nrrd"
    p.write_bytes(b"NRRD0005\n# a comment: with a colon\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n"
                  b"my key:=any: value\ncontent: x\nmin: 0\nmax: 7\nold min: 0\nthicknesses: 1 1 1\n"
                  b"spacings: 1 2 3\ncenters: cell cell cell\nlabels: \"x\" \"y\" \"z\"\nencoding: raw\n\n"
                  + bytes(range(8)))
    vol = load_volume(p)
    assert vol.spacing == (1.0, 2.0, 3.0) and vol.data.ravel().tolist() == list(range(8))


@pytest.mark.parametrize("field", ["dimension: 3", "type: uchar", "sizes: 2 2 2", "endian: little", "encoding: raw",
                                   "content: x", "number: 8", "block size: 1", "blocksize: 1", "min: 0", "max: 7",
                                   "old min: 0", "oldmin: 0", "old max: 7", "oldmax: 7", "line skip: 0",
                                   "lineskip: 0", "byte skip: 0", "byteskip: 0", "sample units: mm", "space: 3D-right-handed",
                                   "space dimension: 3", "space units: \"mm\" \"mm\" \"mm\"",
                                   "space origin: (1,2,3)", "space directions: (1,0,0) (0,2,0) (0,0,3)",
                                   "measurement frame: (1,0,0) (0,1,0) (0,0,1)", "spacings: 1 2 3",
                                   "thicknesses: 1 1 1", "axis mins: 0 0 0", "axismins: 0 0 0", "axis maxs: 2 4 6",
                                   "axismaxs: 2 4 6", "centers: cell cell cell", "centerings: cell cell cell",
                                   "kinds: domain domain domain", "labels: \"x\" \"y\" \"z\"",
                                   "units: \"mm\" \"mm\" \"mm\"", "  spacings :  1 2 3"])
def test_nrrd_every_field_of_the_format_is_read(tmp_path, field):
    # Each field NRRD has is taken, whether this reader uses it or not (the unknown ones are refused).
    p = tmp_path / "f.nrrd"
    base = {"dimension": "3", "type": "uchar", "sizes": "2 2 2", "encoding": "raw"}
    name = field.split(":")[0].strip()
    lines = [f"{k}: {v}" for k, v in base.items() if k != name] + [field]
    p.write_bytes(("NRRD0005\n" + "\n".join(lines) + "\n\n").encode() + bytes(range(8)))
    vol = load_volume(p)
    assert vol.data.ravel().tolist() == list(range(8))
    if "spacings" in field:
        assert vol.spacing == (1.0, 2.0, 3.0)


@pytest.mark.parametrize("pair", ["ITK_like:colon:=x", "DICOM:0008,0060:=CT", "a b:= c: d"])
def test_nrrd_key_value_pairs_whose_key_holds_a_colon_are_read(tmp_path, pair):
    # NRRD forbids ":=" in a key, not ":"; ITK writes such keys (SetMetaData("ITK_like:colon", ...)),
    # and they were refused as the unknown field before the first colon.
    p = tmp_path / "f.nrrd"
    p.write_bytes(f"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n{pair}\nencoding: raw\n\n".encode()
                  + bytes(range(8)))
    assert load_volume(p).data.ravel().tolist() == list(range(8))


def test_nrrd_magic_line_pynrrd_refuses_is_not_blamed_on_a_field(tmp_path):
    p = tmp_path / "f.nrrd"
    p.write_bytes(b"NRRD00.02\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n" + bytes(8))
    msg = fails(p, "cannot read NRRD file: Invalid NRRD magic line: NRRD00.02")
    assert "field" not in msg


def test_nrrd_first_magic_line_is_read(tmp_path):
    # "NRRD00.01", the magic of the format's first version, which teem's reader still takes.
    p = tmp_path / "f.nrrd"
    p.write_bytes(b"NRRD00.01\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n" + bytes(range(8)))
    assert load_volume(p).data.ravel().tolist() == list(range(8))


@pytest.mark.parametrize("fields", [
    ["spacedimension: 3", "spacedirections: (1,0,0) (0,2,0) (0,0,5)", "spaceorigin: (1,2,3)",
     "spaceunits: \"mm\" \"mm\" \"mm\"", "measurementframe: (1,0,0) (0,1,0) (0,0,1)", "sampleunits: HU"],
    ["SPACE DIMENSION: 3", "Space Directions: (1,0,0) (0,2,0) (0,0,5)", "Space Origin: (1,2,3)"],
    ["space dimension: 3", "SpaceDirections: (1,0,0) (0,2,0) (0,0,5)", "SPACEORIGIN: (1,2,3)"],
])
def test_nrrd_fields_are_read_as_teem_reads_them(tmp_path, fields):
    # teem's field names ignore case and take spellings without spaces; pynrrd parses
    # neither, and "spacedirections" or "Space Origin" left the volume unspaced at 0.
    p = tmp_path / "f.nrrd"
    p.write_bytes(("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n" + "\n".join(fields)
                   + "\nencoding: raw\n\n").encode() + bytes(range(8)))
    vol = load_volume(p)
    assert vol.spacing == (1.0, 2.0, 5.0) and vol.origin == (1.0, 2.0, 3.0)
    assert vol.data.ravel().tolist() == list(range(8))


def test_nrrd_field_names_and_enumerated_values_are_read_in_any_case(tmp_path):
    # teem reads "Type: Short", "ENDIAN: BIG" and "Encoding: RAW" as their lower-case spellings.
    p = tmp_path / "f.nrrd"
    samples = (np.arange(8) - 3).astype(">i2")
    p.write_bytes(b"NRRD0004\nType: Short\nDIMENSION: 3\nSizes: 2 2 2\nSpacings: 1 2 3\nENDIAN: BIG\n"
                  b"Encoding: RAW\n\n" + samples.tobytes())
    vol = load_volume(p)
    assert vol.dtype == np.int16 and vol.spacing == (1.0, 2.0, 3.0)
    assert vol.data.ravel().tolist() == samples.tolist()


def test_nrrd_data_file_list_is_found_in_any_case(tmp_path):
    for n in range(2):
        (tmp_path / f"s{n}.raw").write_bytes(bytes(range(4 * n, 4 * n + 4)))
    p = tmp_path / "f.nhdr"
    p.write_text("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nData File: LIST\ns0.raw\ns1.raw\n")
    assert load_volume(p).data.ravel().tolist() == list(range(8))


def test_raw_floats_read_in_the_wrong_byte_order_are_said_to_be_perhaps_misread(tmp_path):
    # Little-endian floats from 0 to 1 read as big-endian: some come out NaN or inf.
    p = tmp_path / "mine.raw"
    np.linspace(0.0, 1.0, 60 * 50 * 40, dtype="<f4").tofile(p)
    msg = fails(p, "non-finite samples (NaN or inf)", shape=(60, 50, 40), dtype="float32", byte_order="big")
    assert msg.endswith("unless they are misread: check --byte-order, --dtype and --offset "
                        "(byte_order, dtype, offset in Python and scene files)")
    assert load_volume(p, shape=(60, 50, 40), dtype="float32").data.max() == 1.0


@pytest.mark.parametrize("options, said", [({}, " (shape and type from the file's name; --shape and --dtype give "
                                                "others, shape, dtype in Python and scene files)"),
                                           ({"shape": (64, 64, 64)}, " (type from the file's name; --dtype gives "
                                                                     "another, dtype in Python and scene files)"),
                                           ({"shape": (64, 64, 64), "dtype": "uint8"}, "")])
def test_a_raw_file_of_another_size_than_its_name_says_is_said_to_be_read_by_its_name(tmp_path, options, said):
    p = tmp_path / "bucky_64x64x64_uint8.raw"
    p.write_bytes(bytes(32 ** 3))
    msg = fails(p, "raw data truncated: 64x64x64 uint8 needs 262144 bytes, the file has 32768", **options)
    assert msg.endswith("the file has 32768" + said)


def test_nrrd_float_text_that_is_not_finite_is_refused_as_such(tmp_path):
    p = tmp_path / "f.nrrd"
    p.write_bytes(b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\ninf -inf 1 2 3 4 5 nan\n")
    fails(p, "3 non-finite samples (NaN or inf)")


@pytest.mark.parametrize("fields, match", [
    ("type: uchar\ndimension: 3\nsizes: -2 2 2", "sizes must be positive, got -2 2 2"),
    ("type: uchar\ndimension: 3\nsizes: 0 2 2", "sizes must be positive, got 0 2 2"),
    ("type: uchar\ndimension: 3\nsizes: 3037000500 3037000500 1",
     "sizes 3037000500 3037000500 1 make 9.22e+18 samples, more than any file holds"),
    ("type: BLOCK\nblock size: 1\ndimension: 3\nsizes: 2 2 2", "type block (opaque blocks of bytes) holds no numbers"),
    ("type: block\nblock size: 1\ndimension: 3\nsizes: 2 2 2", "type block (opaque blocks of bytes) holds no numbers"),
])
def test_nrrd_layout_that_names_no_array_of_numbers(tmp_path, fields, match):
    # pynrrd answered "product of all the dimensions: -8-8=-16" and "negative dimensions are not allowed".
    p = tmp_path / "f.nrrd"
    p.write_bytes(f"NRRD0004\n{fields}\nencoding: raw\n\n".encode() + bytes(8))
    fails(p, match)


def _fails_within(path, words, most):
    """`fails`, holding at most ``most`` bytes of Python memory at its peak."""
    tracemalloc.start()
    try:
        fails(path, words)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < most, peak


@pytest.mark.parametrize("kind", ["nrrd", "mhd"])
def test_numbered_data_files_that_cannot_match_are_refused_before_naming_them(tmp_path, kind):
    # A header of a few bytes numbering 1 to 2,000,000 files for 8 samples: every name was
    # built before the count was checked (4 million took 18 s and 1.2 GB).
    if kind == "nrrd":
        p = tmp_path / "f.nhdr"
        p.write_text("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
                     "data file: s%07d.raw 1 2000000 1\n")
    else:
        p = tmp_path / "f.mhd"
        p.write_text("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = s%07d.raw 1 2000000 1\n")
    _fails_within(p, "2000000 data files of", 20e6)


@pytest.mark.parametrize("empty", ["", b""])
def test_empty_volume_path_is_not_the_current_folder(tmp_path, monkeypatch, empty):
    # Path("") is ".": a folder of .tif slices there was read, with no word of it.
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match="^the volume path is empty; give a volume file$"):
        load_volume(empty)


@pytest.mark.parametrize("name", ["loop.nrrd", "loop.xyz"])
def test_a_link_in_a_loop_is_named(tmp_path, name):
    (tmp_path / name).symlink_to(tmp_path / ("b" + name))
    (tmp_path / ("b" + name)).symlink_to(tmp_path / name)
    fails(tmp_path / name, "a link that leads nowhere (or in a loop)")


@pytest.mark.parametrize("folder", ["h.raw", "h.mhd"])
def test_a_folder_where_a_file_goes_is_refused_before_any_file_moves(tmp_path, folder):
    # h.raw was moved into place, then h.mhd refused: the data file left without its header;
    # and the message named the header for its data file's failure.
    (tmp_path / folder).mkdir()
    (tmp_path / folder / "x").write_bytes(b"")
    with pytest.raises(InputError, match=f"^{tmp_path / folder}: is a folder; {tmp_path / 'h.mhd'} cannot be written$"):
        save_volume(Volume(SMALL), tmp_path / "h.mhd")
    assert sorted(p.name for p in tmp_path.iterdir()) == [folder]


def test_a_volume_saved_through_a_link_lands_where_it_leads(tmp_path):
    (tmp_path / "link.nrrd").symlink_to(tmp_path / "real.nrrd")
    assert save_volume(Volume(SMALL), tmp_path / "link.nrrd") == tmp_path / "link.nrrd"
    assert (tmp_path / "link.nrrd").is_symlink()
    np.testing.assert_array_equal(load_volume(tmp_path / "real.nrrd").data, SMALL)


@pytest.mark.parametrize("ext", [".nrrd", ".nhdr", ".npy", ".raw"])
def test_a_volume_saved_onto_a_pipe_is_refused_and_the_pipe_kept(tmp_path, ext):
    # Renamed onto, a pipe (or, for root, a device such as /dev/null) became a plain file.
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / ("link" + ext)).symlink_to(tmp_path / "fifo")
    with pytest.raises(InputError, match="a link to .*fifo, not a regular file"):
        save_volume(Volume(SMALL), tmp_path / ("link" + ext))
    assert stat.S_ISFIFO(os.stat(tmp_path / "fifo").st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fifo", "link" + ext]


# --- MetaImage -------------------------------------------------------------

def test_mhd_data_file_missing(tmp_path, writers):
    p = writers.mhd(tmp_path / "m.mhd", SMALL)
    (tmp_path / "m_data.raw").unlink()
    fails(p, "not found")


@pytest.mark.parametrize("delta", [-1, 5])
def test_mhd_data_size_mismatch(tmp_path, writers, delta):
    p = writers.mhd(tmp_path / "m.mhd", SMALL)
    data = tmp_path / "m_data.raw"
    data.write_bytes(data.read_bytes()[:SMALL.size + delta] + bytes(max(delta, 0)))
    msg = str(pytest.raises(InputError, load_volume, p).value)
    assert str(SMALL.size) in msg and "m_data.raw" in msg


def test_mha_truncated(tmp_path, writers):
    p = writers.mhd(tmp_path / "m.mha", SMALL.astype(np.int16))
    p.write_bytes(p.read_bytes()[:-10])
    fails(p, "truncated")


@pytest.mark.parametrize("cut", [True, False])
def test_mha_compressed_truncated_or_corrupt(tmp_path, writers, cut):
    arr = np.random.default_rng(1).integers(0, 255, (10, 10, 10), dtype=np.uint8)
    p = writers.mhd(tmp_path / "c.mha", arr, compressed=True)
    raw = bytearray(p.read_bytes())
    if cut:
        raw = raw[:-100]
    else:
        start = raw.index(b"LOCAL\n") + 6
        raw[start + 20:start + 40] = b"\xff" * 20
    p.write_bytes(bytes(raw))
    fails(p)


@pytest.mark.parametrize("line,match", [("NDims = 2", "NDims"), ("ElementType = MET_STRING", "ElementType"),
                                        ("DimSize = 6 5", "DimSize"), ("ElementSpacing = 1 x 1", "ElementSpacing"),
                                        ("ElementNumberOfChannels = 3", "channels")])
def test_mhd_bad_fields(tmp_path, writers, line, match):
    p = writers.mhd(tmp_path / "m.mha", SMALL)
    key = line.split(" =")[0]
    text = p.read_bytes()
    head, _, data = text.partition(b"ElementDataFile = LOCAL\n")
    lines = [ln for ln in head.decode().splitlines() if not ln.startswith(key)] + [line]
    p.write_bytes(("\n".join(lines) + "\nElementDataFile = LOCAL\n").encode() + data)
    fails(p, match)


@pytest.mark.parametrize("line", ["ElementSize = 1 x 1", "Position = 1 2", "Origin = 1 2 z", "Offset = "])
def test_mhd_bad_numbers_are_named_by_their_own_field(tmp_path, line):
    p = tmp_path / "n.mhd"
    p.write_text(f"NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n{line}\nElementDataFile = LOCAL\n" + "x" * 8)
    assert "3 numbers" in fails(p, f": {line.split(' =')[0]} ")


@pytest.mark.parametrize("data_line, extra, match", [
    ("ElementDataFile = ", "", "ElementDataFile is empty"),
    ("ElementDataFile = n.mhd", "", "names this header itself"),
    ("ElementDataFile = LOCAL", "HeaderSize = -5\n", "HeaderSize must be -1"),
    ("ElementDataFile = LOCAL", "HeaderSize = abc\n", "HeaderSize is not an integer"),
])
def test_mhd_bad_data_location(tmp_path, data_line, extra, match):
    p = tmp_path / "n.mhd"
    p.write_text(f"NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n{extra}{data_line}\n" + "x" * 8)
    fails(p, match)


@pytest.mark.parametrize("value, big", [("True", True), ("true", True), ("1", True), ("T", True),
                                        ("False", False), ("0", False), ("f", False), ("Maybe", None), ("yes", None)])
def test_mhd_true_false_fields_read_as_metaio_reads_them(tmp_path, value, big):
    # MetaIO takes a first letter T, t or 1 for true, anything else for false: "Maybe" was
    # read as little-endian without a word, and "yes" as big-endian where MetaIO reads it little.
    p = tmp_path / "b.mha"
    p.write_bytes(f"NDims = 3\nDimSize = 2 2 2\nElementType = MET_USHORT\nElementByteOrderMSB = {value}\n"
                  "ElementDataFile = LOCAL\n".encode() + np.arange(8, dtype=">u2").tobytes())
    if big is None:
        fails(p, f"ElementByteOrderMSB must be True or False, got '{value}'")
    else:
        raw = np.arange(8, dtype=">u2").tobytes()
        np.testing.assert_array_equal(load_volume(p).data.ravel(), np.frombuffer(raw, ">u2" if big else "<u2"))


def test_mhd_with_a_byte_order_mark_reads(tmp_path):
    p = tmp_path / "b.mhd"
    p.write_bytes(b"\xef\xbb\xbfNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n"
                  + bytes(range(8)))
    np.testing.assert_array_equal(load_volume(p).data.ravel(), np.arange(8))


def test_mha_with_a_long_comment_reads(tmp_path, monkeypatch):
    # A header is read to its ElementDataFile line however long (up to NRRD's limit), not 64 KiB.
    p = tmp_path / "c.mha"
    head = b"Comment = " + b"x" * 70000 + b"\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
    p.write_bytes(head + b"ElementDataFile = LOCAL\n" + bytes(range(8)))
    np.testing.assert_array_equal(load_volume(p).data.ravel(), np.arange(8))
    from data_tools.io import metaimage
    monkeypatch.setattr(metaimage, "_MAX_HEADER", 4096)
    fails(p, "no ElementDataFile line in the MetaImage header's first")


def test_mhd_without_data_file_line(tmp_path):
    p = tmp_path / "n.mhd"
    p.write_text("NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n")
    fails(p, "ElementDataFile")


@pytest.mark.parametrize("head", [b"\x89PNG\r\n\x1a\n\x00\x00", b"NDims = 3\nDimSize = 2 2 2\x00\x01\n"])
def test_a_file_of_binary_bytes_is_no_mhd_header(tmp_path, head):
    # Text beyond ASCII is a header's; control bytes are not text.
    p = tmp_path / "b.mha"
    p.write_bytes(head + b"ElementDataFile = LOCAL\n" + bytes(8))
    fails(p, "not a MetaImage header")


def test_mhd_data_file_key_in_another_case_is_named(tmp_path):
    # Read past, it let the samples after it be parsed as header lines: the error quoted their bytes.
    p = tmp_path / "l.mha"
    p.write_bytes(b"NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nelementdatafile = LOCAL\n"
                  + bytes([0, 0, 1, 0, 200, 3, 7, 9]))
    fails(p, "MetaImage keys are case-sensitive: write 'elementdatafile' as 'ElementDataFile'")


def _mha(path, *lines, data=bytes(range(8))):
    """A 2x2x2 MET_UCHAR .mha with ``lines`` after a base header, each key given replacing the base's."""
    keys = {line.split("=")[0].strip() for line in lines}
    base = [b for b in ("NDims = 3", "DimSize = 2 2 2", "ElementType = MET_UCHAR") if b.split(" =")[0] not in keys]
    path.write_bytes(("\n".join(base + list(lines)) + "\nElementDataFile = LOCAL\n").encode() + data)
    return path


@pytest.mark.parametrize("lines", [("DimSize = 2 2 2", "DimSize = 1 2 4"),
                                   ("ElementSpacing = 1 1 1", "ElementSpacing = 2 2 2"),
                                   ("Offset = 0 0 0", "NDims = 3", "Offset = 5 5 5"),
                                   ("BinaryDataByteOrderMSB = False", "BinaryDataByteOrderMSB = True")])
def test_mhd_key_given_twice_is_refused(tmp_path, lines):
    # MetaIO keeps the last without a word: a header edited by appending a line read as its last.
    key = lines[-1].split(" =")[0]
    fails(_mha(tmp_path / "t.mha", *lines), f"MetaImage key {key} is given twice ('")
    # A repeated Comment changes nothing read; keys are case-sensitive (MetaIO compares them so):
    # "dimsize" is no DimSize, to MetaIO or here.
    vol = load_volume(_mha(tmp_path / "ok.mha", "Comment = a", "Comment = b", "dimsize = 1 2 4"))
    assert vol.dims == (2, 2, 2)
    np.testing.assert_array_equal(vol.data.ravel(), np.arange(8))


@pytest.mark.parametrize("line, match", [
    ("DimSize = 2 2 2 7", "DimSize gives 4 values for 3 axes"),
    ("DimSize = 2 2 2 1", "DimSize gives 4 values for 3 axes"),        # NDims = 3: no fourth axis
    ("ElementSpacing = 1 2 3 4", "ElementSpacing gives 4 values for 3 axes"),
    ("ElementSize = 1 2 3 4", "ElementSize gives 4 values for 3 axes"),
    ("Offset = 1 2 3 4", "Offset gives 4 values for 3 axes"),
    ("Origin = 1 2 3 4 5", "Origin gives 5 values for 3 axes"),
    ("Position = 1 2 3 4", "Position gives 4 values for 3 axes"),
    ("TransformMatrix = 1 0 0 0 1 0 0 0 1 0", "TransformMatrix gives 10 values for a 3x3 matrix"),
    ("Rotation = 1 0 0 0 1 0 0 0 1 0", "Rotation gives 10 values for a 3x3 matrix"),
    ("HeaderSize = 0 5", "HeaderSize gives 2 values where one is expected"),
    ("NDims = 3 3", "NDims gives 2 values where one is expected"),
])
def test_mhd_more_values_than_its_axes_are_refused(tmp_path, line, match):
    # MetaIO reads NDims values and drops the rest of the line: "DimSize = 12 12 12 7" was 12^3.
    fails(_mha(tmp_path / "v.mha", line), match)


def test_mhd_missing_required(tmp_path):
    p = tmp_path / "n.mhd"
    p.write_text("NDims = 3\nElementDataFile = x.raw\n")
    fails(p, "DimSize")


# --- VTK -------------------------------------------------------------------

def test_vtk_other_dataset(tmp_path, writers):
    p = writers.vtk(tmp_path / "u.vtk", SMALL, dataset="UNSTRUCTURED_GRID")
    fails(p, "UNSTRUCTURED_GRID")


def test_vtk_vector_data(tmp_path, writers):
    p = writers.vtk(tmp_path / "v.vtk", SMALL, ncomp=3)
    fails(p, "components")


@pytest.mark.parametrize("ascii", [False, True])
def test_vtk_truncated(tmp_path, writers, ascii):
    p = writers.vtk(tmp_path / "t.vtk", SMALL.astype(np.float32), ascii=ascii)
    p.write_bytes(p.read_bytes()[:-60])
    fails(p, "truncated")


def test_vtk_ascii_junk_value(tmp_path, writers):
    p = writers.vtk(tmp_path / "j.vtk", SMALL, ascii=True)
    p.write_bytes(p.read_bytes().replace(b" 7 ", b" seven "))
    fails(p, "not a uint8")


def test_vtk_ascii_out_of_range(tmp_path, writers):
    p = writers.vtk(tmp_path / "r.vtk", SMALL, ascii=True)
    p.write_bytes(p.read_bytes().replace(b" 7 ", b" 700 "))
    fails(p, "range")


def test_vtk_point_count_mismatch(tmp_path, writers):
    p = writers.vtk(tmp_path / "c.vtk", SMALL)
    p.write_bytes(p.read_bytes().replace(b"POINT_DATA 120", b"POINT_DATA 121"))
    fails(p, "POINT_DATA")


def test_vtk_unknown_type(tmp_path, writers):
    p = writers.vtk(tmp_path / "b.vtk", SMALL)
    p.write_bytes(p.read_bytes().replace(b"unsigned_char", b"bit"))
    fails(p, "type")


def test_vtk_dimension_one(tmp_path, writers):
    p = writers.vtk(tmp_path / "d.vtk", SMALL[:1])
    fails(p, "at least 2")


@pytest.mark.parametrize("old, new, match", [
    (b"DIMENSIONS 6 5 4\n", b"DIMENSIONS 6 5 4\nDIMENSIONS 3 10 4\n",
     "VTK header gives DIMENSIONS twice (the second: 'DIMENSIONS 3 10 4')"),
    (b"SPACING 1 1 1\n", b"SPACING 1 1 1\nSPACING 2 2 2\n", "VTK header gives SPACING twice"),
    (b"SPACING 1 1 1\n", b"SPACING 1 1 1\nASPECT_RATIO 2 2 2\n", "VTK header gives both SPACING and ASPECT_RATIO"),
    (b"ORIGIN 0 0 0\n", b"ORIGIN 0 0 0\norigin 5 5 5\n", "VTK header gives ORIGIN twice (the second: 'origin 5 5 5')"),
    (b"DIMENSIONS 6 5 4\n", b"DIMENSIONS 6 5 4 9\n", "DIMENSIONS gives 4 values for 3 axes"),
    (b"SPACING 1 1 1\n", b"SPACING 1 1 1 7\n", "SPACING gives 4 values for 3 axes"),
    (b"ORIGIN 0 0 0\n", b"ORIGIN 0 0 0 7\n", "ORIGIN gives 4 values for 3 axes"),
])
def test_vtk_geometry_line_given_twice_or_with_more_values_is_refused(tmp_path, writers, old, new, match):
    # The last of two was read (3x10x4 has the 120 points of 6x5x4), and a fourth number dropped.
    p = writers.vtk(tmp_path / "g.vtk", SMALL)
    assert old in p.read_bytes()
    p.write_bytes(p.read_bytes().replace(old, new))
    fails(p, match)


# --- SLC -------------------------------------------------------------------

def test_slc_truncated(tmp_path, writers):
    p = writers.slc(tmp_path / "t.slc", SMALL)
    p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2])
    fails(p)


def test_slc_raw_truncated(tmp_path, writers):
    p = writers.slc(tmp_path / "t.slc", SMALL, compression=0)
    p.write_bytes(p.read_bytes()[:-3])
    fails(p, "truncated")


def test_slc_bad_magic_and_bits(tmp_path, writers):
    p = writers.slc(tmp_path / "m.slc", SMALL)
    good = p.read_bytes()
    p.write_bytes(b"22222" + good[5:])
    fails(p, "magic")
    p.write_bytes(good.replace(b" 4 8\n", b" 4 16\n", 1))
    fails(p, "16-bit")
    p.write_bytes(good.replace(b"1 6 0 1\n", b"1 6 0 2\n", 1))
    fails(p, "unknown SLC compression 2 (0 raw, 1 run-length)")


@pytest.mark.parametrize("icon", [(-1, 3), (-1, -1), (4, -3)])
def test_slc_negative_icon_size_is_named(tmp_path, writers, icon):
    # -1 x -1 had skipped 3 bytes without a word; -1 x 3 was "truncated: -9 bytes needed".
    p = writers.slc(tmp_path / "i.slc", SMALL)
    p.write_bytes(p.read_bytes().replace(b"\n4 3 X", f"\n{icon[0]} {icon[1]} X".encode(), 1))
    fails(p, f"bad SLC icon size {icon[0]}x{icon[1]}")


def test_slc_negative_slice_size_is_named(tmp_path, writers):
    p = writers.slc(tmp_path / "s.slc", SMALL)
    code = writers.rle(SMALL[0].tobytes())
    head = f"{len(code)} X".encode() + code
    assert head in p.read_bytes()
    p.write_bytes(p.read_bytes().replace(head, b"-5 X" + code, 1))
    fails(p, "slice 0 has -5 bytes")


def test_slc_claiming_more_samples_than_memory_holds(tmp_path, writers):
    # Run-length samples need not be in the file: numpy's "array is too big" was the message.
    p = writers.slc(tmp_path / "h.slc", SMALL)
    head = b" ".join(str(n).encode() for n in SMALL.shape[::-1]) + b" 8\n"
    assert p.read_bytes().count(head) == 1
    p.write_bytes(p.read_bytes().replace(head, b"99999999 99999999 99999999 8\n", 1))
    fails(p, "99999999x99999999x99999999 samples needs about")


def test_slc_corrupt_runs(tmp_path, writers):
    p = writers.slc(tmp_path / "c.slc", np.zeros((4, 5, 6), np.uint8))
    # Every slice is "3 X" + (30 zeros as one run) + end; claim 31 repeats instead.
    data = p.read_bytes()
    assert data.count(b"3 X\x1e\x00\x00") == 4
    p.write_bytes(data.replace(b"3 X\x1e\x00\x00", b"3 X\x1f\x00\x00", 1))
    fails(p, "slice 0")


# --- nothing but InputError, whatever the damage ---------------------------

@pytest.mark.parametrize("name", ["v.nrrd", "v.nhdr", "v.mhd", "v.mha", "v.vtk", "a.vtk", "v.slc", "r.slc",
                                  "c.mha", "v.npy"])
def test_damaged_files_give_only_input_errors(tmp_path, writers, name):
    arr = np.random.default_rng(3).integers(0, 40, (4, 5, 6), dtype=np.uint8)
    p = tmp_path / name
    if name in ("v.nrrd", "v.nhdr", "v.npy"):
        save_volume(Volume(arr), p)
    elif name.endswith(".vtk"):
        writers.vtk(p, arr, ascii=name.startswith("a"))
    elif name.endswith(".slc"):
        writers.slc(p, arr, compression=0 if name.startswith("r") else 1)
    else:
        writers.mhd(p, arr, compressed=name.startswith("c"))
    good = p.read_bytes()
    rng = np.random.default_rng(7)
    cuts = sorted(set(np.linspace(0, len(good) - 1, 25).astype(int)) | {1, 10, 30})
    variants = [good[:c] for c in cuts]
    for _ in range(25):
        bad = bytearray(good)
        pos = int(rng.integers(0, len(good)))
        bad[pos] = int(rng.integers(0, 256))
        variants.append(bytes(bad))
    outcomes = set()
    for v in variants:
        p.write_bytes(v)
        try:
            vol = load_volume(p)
            outcomes.add("ok")
            assert vol.data.shape[0] >= 2
        except InputError as exc:
            outcomes.add("error")
            assert "\n" not in str(exc)
    assert "error" in outcomes


@pytest.mark.parametrize("data, kept_as", [
    (np.arange(64).reshape(4, 4, 4), np.int32),                       # NumPy's default whole numbers
    (np.arange(64).reshape(4, 4, 4) % 2 == 0, np.uint8),              # a mask
    (np.linspace(-2, 2, 64, dtype=np.float16).reshape(4, 4, 4), np.float32),
    (np.arange(64, dtype=np.uint64).reshape(4, 4, 4) + 4_000_000_000, np.uint32),
    (-np.arange(64, dtype=np.int64).reshape(4, 4, 4) - 2**31 + 64, np.int32),
])
def test_samples_of_other_types_are_kept_exactly_in_one_the_kernels_read(data, kept_as):
    vol = Volume(data)
    assert vol.dtype == kept_as and np.array_equal(vol.data, data)


@pytest.mark.parametrize("data", [np.arange(64, dtype=np.int64).reshape(4, 4, 4) * 2**40,
                                  np.ones((4, 4, 4), np.complex64)])
def test_samples_no_kernel_type_holds_are_refused_naming_the_types(data):
    with pytest.raises(InputError, match=r"unsupported sample type .*; use one of uint8, .*float64$"):
        Volume(data)


def test_saving_an_array_asks_for_a_volume(tmp_path):
    from data_tools.io import save_volume
    with pytest.raises(InputError, match="save_volume takes a Volume, got ndarray"):
        save_volume(np.zeros((4, 4, 4), np.uint8), tmp_path / "v.nrrd")
    assert not any(tmp_path.iterdir())


def test_a_short_write_names_the_full_disk(tmp_path, monkeypatch):
    # NumPy reports a write cut short (a full disk) with counts of values, not bytes, and no reason.
    from data_tools.io import raw

    def short(volume, path, **k):
        raise OSError("1440000 requested and 153568 written")     # what ndarray.tofile raises
    monkeypatch.setattr(raw, "write_raw", short)
    with pytest.raises(InputError) as exc:
        save_volume(Volume(np.zeros((4, 4, 4), np.uint8)), tmp_path / "v.raw")
    assert str(exc.value).endswith("v.raw: cannot write: only 153,568 of 1,440,000 values were written; "
                                   "is the disk full?")
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("fill, ok", [(-1e308, False), (-np.finfo(np.float64).max, False), (1e200, True),
                                      (-3.4e38, True)])
def test_samples_a_cubic_cannot_hold_are_refused(fill, ok):
    # The cubic's coefficients (differences of 8 samples, over spacing^3) overflow near 1e308:
    # the surface quietly vanished.
    data = np.linspace(0.0, 1.0, 64).reshape(4, 4, 4)
    data[0, 0, 0] = fill
    if ok:
        assert fill in Volume(data).value_range()
    else:
        with pytest.raises(InputError, match=re.escape(f"samples reach {fill:.3g}, beyond the ±1e+200 a cell's cubic "
                                                       "holds without overflow")):
            Volume(data)


@pytest.mark.parametrize("top, ok", [(1e-300, False), (5e-324, False), (1e-200, True), (0.0, True)])
def test_samples_too_small_for_a_normal_are_refused(top, ok):
    # Over a spacing of 1e30, the gradient of samples of 1e-300 underflowed to zero: every hit was
    # lit as if it faced the eye. A volume of zeros holds no surface to shade, and is kept.
    data = np.linspace(0.0, top, 64).reshape(4, 4, 4)
    if ok:
        assert Volume(data).value_range() == (0.0, top)
    else:
        with pytest.raises(InputError, match=re.escape(f"samples reach only {top:.3g} in magnitude, below the "
                                                       "1e-200 under which")):
            Volume(data)


@pytest.mark.parametrize("spacing, ok", [((1e-30, 1, 1), True), ((1, 1e30, 1), True), ((1, 1, 1e-31), False),
                                         ((2.0 ** 400, 1, 1), False)])
def test_spacings_a_cubic_cannot_hold_are_refused(spacing, ok):
    data = np.zeros((2, 2, 2), np.float32)
    if ok:
        assert Volume(data, spacing=spacing).spacing == spacing
    else:
        with pytest.raises(InputError, match="spacing must lie between 1e-30 and 1e\\+30"):
            Volume(data, spacing=spacing)


def test_a_raw_file_without_shape_or_type_names_the_options_everywhere(tmp_path):
    # load_volume serves the command line, Python and scene files: the message names the
    # option in each spelling, not the command line's alone.
    p = tmp_path / "scan.raw"
    p.write_bytes(bytes(60))
    fails(p, "give --shape NX,NY,NZ and --dtype TYPE (and --byte-order, --offset, --spacing if needed; "
             "in Python and scene files shape, dtype, byte_order, offset, spacing)")


@pytest.mark.parametrize("value", [np.float32(0.5), np.int64(3), np.uint8(7), np.int32(-2)])
def test_numpy_scalars_are_numbers(value):
    # numbers.Real counts every NumPy integer and float; np.float32 and np.int64 subclass neither
    # float nor int, and a transfer function taken from an array's rows holds them.
    assert is_number(value)


@pytest.mark.parametrize("value", [b"123", b"\x01\x02\x03"])
def test_bytes_are_not_three_numbers(value):
    # Iterating bytes gives ints: b"123" would read as (49, 50, 51).
    assert three_numbers(value) is None
    with pytest.raises(InputError, match="spacing must be three numbers"):
        Volume(np.zeros((2, 2, 2), np.uint8), spacing=value)


@pytest.mark.parametrize("kind", ["slc header", "mhd header", "vtk header", "vtk data", "nrrd text", "mhd text"])
def test_numbers_with_digit_separators_are_refused(tmp_path, writers, kind):
    # Python and NumPy read "1_0" as 10; the formats' own readers (teem, MetaIO, VTK's, VolVis's)
    # refuse it. Before, an SLC header's "1_0" made a volume 10 samples wide.
    arr = np.arange(24, dtype=np.uint8).reshape(2, 3, 4)
    if kind == "slc header":
        p = writers.slc(tmp_path / "v.slc", arr, compression=0)
        p.write_bytes(p.read_bytes().replace(b"4 3 2 8", b"4 3 2_0 8", 1))
    elif kind.startswith("mhd"):
        text = kind == "mhd text"
        (tmp_path / "v.dat").write_bytes(b"0 1 2_0 3 " + b"5 " * 20 if text else arr.tobytes())
        p = tmp_path / "v.mhd"
        p.write_text(f"NDims = 3\nDimSize = {'4 3 2' if text else '4 3 0_2'}\nElementType = MET_UCHAR\n"
                     f"BinaryData = {not text}\nElementDataFile = v.dat\n")
    elif kind.startswith("vtk"):
        values = " ".join(map(str, arr.ravel())) + "\n"
        p = tmp_path / "v.vtk"
        p.write_text("# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\n"
                     f"DIMENSIONS {'4 3 2' if kind == 'vtk data' else '4 3 0_2'}\nPOINT_DATA 24\n"
                     "SCALARS s unsigned_char 1\nLOOKUP_TABLE default\n"
                     + (values.replace(" 7 ", " 7_0 ") if kind == "vtk data" else values))
    else:
        p = tmp_path / "v.nrrd"
        p.write_text("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 3 2\nencoding: ascii\n\n"
                     + " ".join(map(str, arr.ravel())).replace(" 7 ", " 7_0 ") + "\n")
    with pytest.raises(InputError, match="_") as exc:
        load_volume(p)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("encoding, body", [("ascii", b"0 1 2 3 4 5 6 7\n"), ("raw", bytes(range(8)))])
def test_nrrd_detached_data_file_is_found_in_any_case(tmp_path, encoding, body):
    (tmp_path / "d.dat").write_bytes(body)
    p = tmp_path / "h.nhdr"
    p.write_text(f"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: {encoding}\nDATA FILE: d.dat\n")
    assert load_volume(p).data.ravel().tolist() == list(range(8))


@pytest.mark.parametrize("filler", [b"note:=" + b"v" * 65530 + b"\n",            # a line of 65,536 bytes
                                    b"#" + b"c" * 65535 + b"\n",                 # the same, a comment
                                    b"# c\n" * 10_001])                           # more lines than 10,000
def test_nrrd_headers_of_long_lines_or_many_lines_are_read_whole(tmp_path, filler):
    # Read 64 KiB and 10,000 lines at most, such headers ended early: the rest of the header was
    # read as data, or (with byte skip -1) its spacing and origin were lost without a word.
    a = np.arange(24, dtype=np.int16).reshape(2, 3, 4)
    for skip in (b"", b"byte skip: -1\n"):
        head = b"NRRD0004\ntype: short\ndimension: 3\nsizes: 4 3 2\nencoding: raw\nendian: little\n" + skip
        tail = b"spacings: 2 3 4\naxis mins: 5 6 7\n\n" + a.tobytes()
        (tmp_path / "f.nrrd").write_bytes(head + filler + tail)
        (tmp_path / "plain.nrrd").write_bytes(head + tail)
        vol, plain = load_volume(tmp_path / "f.nrrd"), load_volume(tmp_path / "plain.nrrd")
        np.testing.assert_array_equal(vol.data, a)
        assert vol.spacing == (2.0, 3.0, 4.0) and vol.origin == plain.origin != (0.0, 0.0, 0.0)


def test_a_file_that_is_not_nrrd_is_refused_at_its_first_line(tmp_path, monkeypatch):
    # Not after reading as much header as a header may hold (64 MiB of a raw file renamed).
    from data_tools.io import nrrd_header
    monkeypatch.setattr(nrrd_header, "_MAX_HEADER_BYTES", 1024)
    p = tmp_path / "f.nrrd"
    p.write_bytes(b"\x00" * 4096)
    fails(p, "magic")
    p.write_bytes(b"NRRD0004\n" + b"#" * 4096)
    fails(p, "no end to the NRRD header in its first")


# --- a header that does not match its data ------------------------------------

def test_npy_sidecar_nested_too_deep_is_an_input_error(tmp_path):
    # json.loads raises RecursionError (neither OSError nor ValueError), in load_volume and in
    # save_volume's check of what lies where the sidecar goes.
    p = tmp_path / "v.npy"
    np.save(p, SMALL)
    (tmp_path / "v.npy.json").write_text("[" * 5000)
    fails(p, "nested too deep")
    with pytest.raises(InputError, match="a file of another kind"):
        save_volume(Volume(SMALL), p)


@pytest.mark.parametrize("edit", [
    lambda b: b.replace(b"}", b"} #", 1),              # the header one byte longer than it says
    lambda b: b.replace(b"(4, 5, 6)", b"(4, 5, +6)"),
    lambda b: b.replace(b"(4, 5, 6)", b"(4, 5, 6)\t"),
])
def test_npy_header_longer_than_its_stated_length_is_refused(tmp_path, edit):
    # NumPy's reader would take the first samples from the header's last bytes, shifted, and
    # ignore the bytes left at the end.
    p = tmp_path / "v.npy"
    np.save(p, SMALL)
    p.write_bytes(edit(p.read_bytes()))
    fails(p)


@pytest.mark.parametrize("extra", [b"\x00", bytes(8), bytes(120)])
def test_npy_bytes_after_the_array_are_refused(tmp_path, extra):
    p = tmp_path / "v.npy"
    np.save(p, SMALL)
    p.write_bytes(p.read_bytes() + extra)
    fails(p, f"{len(extra)} bytes after its header's 4x5x6 uint8 array")
    p.write_bytes(p.read_bytes().replace(b"(4, 5, 6)", b"(3, 5, 6)")[:-len(extra)])   # a size edited down
    fails(p, "30 bytes after")


@pytest.mark.parametrize("encoding, pack", [("gzip", gzip.compress), ("bzip2", bz2.compress)])
def test_nrrd_compressed_data_are_not_inflated_past_the_header_sizes(tmp_path, encoding, pack):
    # 64 MB of zeros in a few kB, inflated whole, would be held in memory before being refused
    # as more than the 60 bytes the header states (1 GB in 1 MB: 3 GB at the peak, 11 s).
    p = tmp_path / "bomb.nrrd"
    p.write_bytes(f"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 5 4 3\nencoding: {encoding}\n\n".encode()
                  + pack(bytes(64 << 20)))
    _fails_within(p, "more than the 60 bytes the header states", 8 << 20)


def _compressed_zeros(path, shape):
    """A file of zeros of ``shape`` (x, y, z) in the compressed form its suffix names."""
    nx, ny, nz = shape
    if path.suffix == ".mha":
        path.write_bytes(f"NDims = 3\nDimSize = {nx} {ny} {nz}\nElementType = MET_UCHAR\nCompressedData = True\n"
                         "ElementDataFile = LOCAL\n".encode() + zlib.compress(bytes(nx * ny * nz)))
    elif path.suffix == ".gz":
        nib = pytest.importorskip("nibabel")
        nib.save(nib.Nifti1Image(np.zeros(shape, np.uint8), np.eye(4)), str(path))
    else:
        encoding, pack = (("bzip2", bz2.compress) if path.stem.endswith("bz2") else ("gzip", gzip.compress))
        path.write_bytes(f"NRRD0004\ntype: uint8\ndimension: 3\nsizes: {nx} {ny} {nz}\nencoding: {encoding}\n\n"
                         .encode() + pack(bytes(nx * ny * nz)))
    return path


@pytest.mark.parametrize("name", ["v.nrrd", "v_bz2.nrrd", "v.mha", "v.nii.gz"])
def test_compressed_volume_larger_than_the_memory_available_is_refused_before_it_is_held(tmp_path, monkeypatch, name):
    # A few kB of stream state gigabytes: inflated block by block, the memory would all be
    # taken before any refusal (the system's out-of-memory killer ends the process). A .nii.gz is
    # inflated a piece at a time first, to tell a truncated stream, and then refused.
    p = _compressed_zeros(tmp_path / name, (200, 200, 200))
    monkeypatch.setattr(memory, "available_memory", lambda: 1 << 20)
    # Twice the samples: the inflated bytes and the array read from them are held at once.
    words = ("200x200x200 uint8 volume its header states, inflated and then read, needs about 15 MB of memory; "
             "1 MB is available")
    if name.endswith(".gz"):
        fails(p, words)
    else:
        _fails_within(p, words, 4 << 20)
    monkeypatch.setattr(memory, "available_memory", lambda: 16 << 20)
    import tracemalloc
    tracemalloc.start()
    try:
        assert load_volume(p).dims == (200, 200, 200)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    if name.endswith(".nrrd"):          # the members were gathered, and copied, four times over
        assert peak < 2.2 * 200 ** 3, peak


def test_slc_bytes_after_the_last_slice_are_refused(tmp_path):
    # A repeated header line or an icon size edited shifts every sample, and leaves bytes over
    # at the end.
    arr = np.arange(60, dtype=np.uint8).reshape(3, 4, 5)
    head = b"11111\n5 4 3 8\n1 1 1\n0 0 0 0\n2 2 X" + bytes(12)
    p = tmp_path / "v.slc"
    p.write_bytes(head + arr.tobytes())
    np.testing.assert_array_equal(load_volume(p).data, arr)
    p.write_bytes(head.replace(b"2 2 X", b"1 2 X") + arr.tobytes())
    fails(p, "6 bytes after the last of its 3 slices")
    p.write_bytes(head + arr.tobytes() + b"\n")
    fails(p, "1 bytes after")


@pytest.mark.parametrize("suffix, edit", [
    (".mha", lambda b: b.replace(b"ElementDataFile = LOCAL\n", b"ElementDataFile = LOCAL\n" * 2)),  # repeated
    (".mha", lambda b: b.replace(b"DimSize = 6 5 4", b"DimSize = 5 5 4")),                          # edited down
    (".mha", lambda b: b + b"\x07"),
    (".vtk", lambda b: b.replace(b"LOOKUP_TABLE default", b"LOOKUP_TA LE default")),                # garbled
    (".vtk", lambda b: b.replace(b"LOOKUP_TABLE default\n", b"CELL_DATA default\n")),
    (".vtk", lambda b: b.replace(b"unsigned_char 1\n", b"unsigned_char 1\nSCALARS s unsigned_char 1\n")),
    (".vtk", lambda b: b + b"\x07\x08"),
])
def test_bytes_after_attached_samples_that_begin_no_section_are_refused(tmp_path, suffix, edit):
    # A header misread by a line moves where the samples start: they would take the header's
    # last bytes as their first, and leave bytes over at the end (with no LOOKUP_TABLE line
    # recognised, VTK's would start at the line after SCALARS).
    p = save_volume(Volume(SMALL), tmp_path / f"v{suffix}")
    p.write_bytes(edit(p.read_bytes()))
    fails(p, f"bytes after the {'MetaImage' if suffix == '.mha' else 'VTK'} samples")


@pytest.mark.parametrize("suffix, tail", [
    (".mha", b"\n"),
    (".vtk", b"\nCELL_DATA 60\nSCALARS c unsigned_char 1\nLOOKUP_TABLE default\n" + bytes(60)),
])
def test_white_space_or_a_section_after_attached_samples_is_read_past(tmp_path, suffix, tail):
    p = save_volume(Volume(SMALL), tmp_path / f"v{suffix}")
    p.write_bytes(p.read_bytes() + tail)
    np.testing.assert_array_equal(load_volume(p).data, SMALL)


@pytest.mark.parametrize("stated", [b"[4, 5, 6]", b"[9, 5, 6]"])
def test_tiff_description_stating_more_slices_than_pages_is_refused(tmp_path, stated):
    # tifffile reads the stated samples on from the first page's data, through the tags after
    # them: garbage slices.
    tifffile = pytest.importorskip("tifffile")
    p = tmp_path / "s.tif"
    tifffile.imwrite(p, SMALL[:3], photometric="minisblack")
    p.write_bytes(p.read_bytes().replace(b"[3, 5, 6]", stated))
    fails(p, "more samples than its 3 pages hold")


def test_tiff_truncated_by_tifffile_is_read(tmp_path):
    tifffile = pytest.importorskip("tifffile")
    p = tmp_path / "t.tif"
    tifffile.imwrite(p, SMALL, photometric="minisblack", truncate=True)
    np.testing.assert_array_equal(load_volume(p).data, SMALL)


@pytest.mark.parametrize("where", ["samples", "check"])
def test_nifti_gz_with_a_corrupt_stream_is_refused(tmp_path, where):
    # nibabel inflates up to the samples' end and stops: a damaged byte among the samples would
    # come back as a wrong sample, and gzip's CRC-32 after them is never read.
    nib = pytest.importorskip("nibabel")
    plain = tmp_path / "v.nii"
    arr = np.arange(20 * 20 * 20, dtype=np.uint16).reshape(20, 20, 20)   # more than nibabel's first look
    nib.save(nib.Nifti1Image(arr.T, np.eye(4)), plain)
    blob = bytearray(gzip.compress(plain.read_bytes(), compresslevel=0))    # stored: bytes as they are
    at = len(blob) // 2 if where == "samples" else len(blob) - 6             # a sample; the CRC-32
    blob[at] ^= 0xFF
    p = tmp_path / "v.nii.gz"
    p.write_bytes(bytes(blob))
    fails(p, "corrupt compressed data")


def test_nrrd_raw_bytes_after_the_samples_are_refused(tmp_path):
    # A second blank line after the header: teem and pynrrd take it for the first sample's
    # byte, and the samples' last byte is left over.
    arr = np.arange(60, dtype=np.float32).reshape(3, 4, 5)
    p = save_volume(Volume(arr), tmp_path / "v.nrrd", compress=False)
    good = p.read_bytes()
    p.write_bytes(good.replace(b"\n\n", b"\n\n\n", 1))
    fails(p, "1 bytes after the NRRD samples")
    p.write_bytes(good + b"\n")                 # a final newline is read past
    np.testing.assert_array_equal(load_volume(p).data, arr)


def test_nifti_gz_of_several_members_is_read(tmp_path):
    # ``cat a.gz b.gz``, bgzip: Python's gzip reader (nibabel's) reads on into the next member.
    nib = pytest.importorskip("nibabel")
    arr = np.arange(20 * 20 * 20, dtype=np.uint16).reshape(20, 20, 20)
    plain = tmp_path / "v.nii"
    nib.save(nib.Nifti1Image(arr.T, np.eye(4)), plain)
    blob = plain.read_bytes()
    p = tmp_path / "v.nii.gz"
    for cut in (352, 5000):
        p.write_bytes(gzip.compress(blob[:cut]) + gzip.compress(blob[cut:]))
        np.testing.assert_array_equal(load_volume(p).data, arr)


def test_vtk_binary_symmetric_tensors_after_the_samples_are_read_past(tmp_path):
    p = save_volume(Volume(SMALL), tmp_path / "v.vtk")
    p.write_bytes(p.read_bytes() + b"TENSORS6 t float\n" + bytes(SMALL.size * 24) + b"\n")
    np.testing.assert_array_equal(load_volume(p).data, SMALL)


def test_tiff_stack_with_a_page_after_it_without_the_description_is_read(tmp_path):
    # tifffile drops to "generic" series (the stack, then the page), the first of the stated shape.
    tifffile = pytest.importorskip("tifffile")
    p = tmp_path / "s.tif"
    with tifffile.TiffWriter(p) as w:
        w.write(SMALL, photometric="minisblack")
        w.write(SMALL[0, ::2, ::2], photometric="minisblack", metadata=None)
    np.testing.assert_array_equal(load_volume(p).data, SMALL)


def test_tiff_pages_of_two_sizes_taking_turns_are_refused(tmp_path):
    # tifffile's first series holds the pages like the first, wherever they lie: half the slices.
    tifffile = pytest.importorskip("tifffile")
    p = tmp_path / "s.tif"
    with tifffile.TiffWriter(p) as w:
        for k in range(6):
            w.write(np.full((4, 5) if k % 2 == 0 else (2, 3), k, np.uint8), photometric="minisblack", metadata=None)
    fails(p, "page 2 of 6 is not like page 1")


@pytest.mark.parametrize("odd, how, every", [
    (np.zeros((10, 6), np.uint8), {}, {}),
    (np.full((5, 6), 1000, np.uint16), {}, {}),
    (np.full((5, 6), 7, np.uint8), {"compression": "zlib"}, {}),
    (np.full((5, 6), -7, np.int8), {}, {}),
    (np.full((5, 6), 7, np.uint8), {"compression": "zlib", "predictor": True}, {"compression": "zlib"}),
], ids=["taller", "16-bit", "deflated", "signed", "predictor"])
def test_tiff_page_unlike_the_others_away_from_those_tifffile_compares_is_refused(tmp_path, odd, how, every):
    # tifffile compares pages 2, 8 and the last with the first, and reads the others as the first
    # is: the taller page's first rows, the 16-bit page's bytes, the deflated page's stream, the
    # signed page's samples or the predicted page's differences as unsigned 8-bit samples.
    tifffile = pytest.importorskip("tifffile")
    p = tmp_path / "s.tif"
    with tifffile.TiffWriter(p) as w:
        for k in range(10):
            w.write(odd if k == 3 else np.full((5, 6), k, np.uint8), photometric="minisblack", metadata=None,
                    **(how if k == 3 else every))
    fails(p, "page 4 of 10 is not like page 1")


def test_tiff_page_whose_tags_differ_but_read_alike_is_read(tmp_path):
    # RowsPerStrip left at TIFF's default, 2**32 - 1: all the rows in one strip, as the other pages.
    tifffile = pytest.importorskip("tifffile")
    arr = np.arange(10 * 5 * 6, dtype=np.uint8).reshape(10, 5, 6)
    p = tmp_path / "s.tif"
    tifffile.imwrite(p, arr, photometric="minisblack", metadata=None)
    with tifffile.TiffFile(p) as tif:
        at = tif.pages[3].tags["RowsPerStrip"].valueoffset
    raw = bytearray(p.read_bytes())
    assert struct.unpack_from("<I", raw, at)[0] == 5
    struct.pack_into("<I", raw, at, 2 ** 32 - 1)
    p.write_bytes(bytes(raw))
    np.testing.assert_array_equal(load_volume(p).data, arr)


def _ome_image(number, shape, ifds):
    z, y, x = shape
    planes = "".join(f'<TiffData IFD="{ifd}" FirstZ="{k}" PlaneCount="1"/>' for k, ifd in enumerate(ifds))
    return (f'<Image ID="Image:{number}"><Pixels ID="Pixels:{number}" DimensionOrder="XYZCT" Type="uint8" '
            f'SizeX="{x}" SizeY="{y}" SizeZ="{z}" SizeC="1" SizeT="1">'
            f'<Channel ID="Channel:{number}:0" SamplesPerPixel="1"/>{planes}</Pixels></Image>')


@pytest.mark.parametrize("other, subfiletype", [((2, 3), 0), ((5, 6), 0), ((2, 3), 1)])
def test_ome_tiff_images_taking_turns_are_each_read(tmp_path, other, subfiletype):
    # OME's TiffData names each image's pages: the first image's slices are pages 1, 3 and 5,
    # whatever lies between them (another image of any size, or its thumbnails).
    tifffile = pytest.importorskip("tifffile")
    p = tmp_path / "s.ome.tif"
    first, second = SMALL[:3], np.full((3, *other), 7, np.uint8)
    xml = ('<?xml version="1.0" encoding="UTF-8"?>'
           '<OME xmlns="http://www.openmicroscopy.org/Schemas/OME/2016-06">'
           + _ome_image(0, first.shape, [0, 2, 4]) + _ome_image(1, second.shape, [1, 3, 5]) + "</OME>")
    with tifffile.TiffWriter(p) as w:
        for k in range(3):
            w.write(first[k], description=xml if k == 0 else None, photometric="minisblack", metadata=None)
            w.write(second[k], photometric="minisblack", metadata=None, subfiletype=subfiletype)
    np.testing.assert_array_equal(load_volume(p).data, first)


_THUMB, _MASK = (1, np.zeros((2, 3), np.uint8)), (4, np.ones(SMALL.shape[1:], bool))


@pytest.mark.parametrize("subfiletype, between, described", [
    (*_THUMB, ""), (*_MASK, ""), (*_THUMB, "slices"), (*_THUMB, "all"), (*_MASK, "all"),
], ids=["thumbnails", "masks", "thumbnails after described slices", "described thumbnails", "described masks"])
def test_tiff_thumbnails_and_masks_between_the_slices_are_left_out(tmp_path, subfiletype, between, described):
    # NewSubfileType 1: a reduced-size copy of the page before it; 4: a page that masks it, of
    # its full size. Neither is a slice, whether tifffile's own description (each page stating
    # its own shape) is on no page, on the slices as tifffile writes them between thumbnails
    # another writer added (the first alone: one series of the slices, the thumbnails its
    # reduced level), or on every page.
    tifffile = pytest.importorskip("tifffile")
    p = tmp_path / "s.tif"
    with tifffile.TiffWriter(p) as w:
        for k in range(4):
            w.write(SMALL[k], photometric="minisblack", **({} if described else {"metadata": None}))
            w.write(between, photometric="minisblack", subfiletype=subfiletype,
                    **({} if described == "all" else {"metadata": None}))
    with tifffile.TiffFile(p) as tif:
        stated = [bool(page.description) for page in tif.pages]
    assert stated[0] == bool(described) and all(stated) == (described == "all")
    np.testing.assert_array_equal(load_volume(p).data, SMALL)


@pytest.mark.parametrize("name, words", [("a" * 300 + ".nrrd", "File name too long"),
                                         ("b" * 300 + "/v.npy", "File name too long"),
                                         ("x\0y.nrrd", "a file's path cannot hold a NUL character"),
                                         ("x\0y/v.npy", "a file's path cannot hold a NUL character")])
def test_a_path_the_system_cannot_name_a_file_by_is_refused(tmp_path, name, words):
    # The system's OSError (a name too long) and Python's ValueError (a NUL) came out raw.
    path = tmp_path / name
    for act in (lambda: load_volume(path), lambda: save_volume(Volume(SMALL), path)):
        with pytest.raises(InputError, match=re.escape(words)) as info:
            act()
        assert str(info.value).isprintable()
    assert list(tmp_path.iterdir()) == []
