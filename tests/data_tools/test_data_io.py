"""Every reader reads back what was written: values, dtype, [z, y, x] order, spacing and origin."""
from __future__ import annotations

import bz2
import gzip
import json
import re
import zlib
from decimal import Decimal, localcontext
from fractions import Fraction
from pathlib import Path

import nrrd
import numpy as np
import pytest

from data_tools import InputError, Volume
from data_tools.io import load_volume, save_volume
from data_tools.io._common import REORIENTED_NOTE
from data_tools.io.raw import guess_from_name

DTYPES = ["uint8", "int8", "uint16", "int16", "uint32", "int32", "float32", "float64"]


def make_array(dtype, shape=(3, 4, 5), seed=0):
    """Distinct values in every sample (so axis mix-ups show), spanning the type's sign."""
    rng = np.random.default_rng(seed)
    dt = np.dtype(dtype)
    n = int(np.prod(shape))
    if dt.kind == "f":
        vals = rng.normal(0, 1000, n)
    else:
        info = np.iinfo(dt)
        vals = rng.integers(info.min, info.max, n, endpoint=True)
    return vals.astype(dt).reshape(shape)


def check(vol, arr, spacing=(1, 1, 1), origin=(0, 0, 0)):
    assert isinstance(vol, Volume)
    assert vol.data.dtype == arr.dtype and vol.data.dtype.isnative
    assert vol.shape == arr.shape
    np.testing.assert_array_equal(vol.data, arr)
    assert vol.spacing == pytest.approx(tuple(map(float, spacing)))
    assert vol.origin == pytest.approx(tuple(map(float, origin)))


def test_index_order_is_z_y_x(tmp_path, writers):
    # x varies fastest in the file: byte n sits at x = n % nx.
    arr = np.arange(2 * 3 * 4, dtype=np.uint8).reshape(2, 3, 4)
    p = writers.raw(tmp_path / "v.raw", arr)
    vol = load_volume(p, shape=(4, 3, 2), dtype="uint8")
    assert vol.dims == (4, 3, 2)
    assert vol.data[1, 2, 3] == 1 * 12 + 2 * 4 + 3


# --- npy -------------------------------------------------------------------

def test_npy_without_sidecar(tmp_path):
    arr = make_array("int16")
    np.save(tmp_path / "a.npy", arr)
    check(load_volume(tmp_path / "a.npy"), arr)


def test_npy_roundtrip_with_sidecar(tmp_path):
    arr = make_array("float32")
    p = save_volume(Volume(arr, spacing=(0.5, 1, 2), origin=(-1, 2, 3)), tmp_path / "b.npy")
    assert json.loads((tmp_path / "b.npy.json").read_text())["spacing"] == [0.5, 1.0, 2.0]
    check(load_volume(p), arr, (0.5, 1, 2), (-1, 2, 3))


# --- raw -------------------------------------------------------------------

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("order", ["little", "big"])
def test_raw_roundtrip(tmp_path, writers, dtype, order):
    arr = make_array(dtype, seed=zlib.crc32(f"{dtype} {order}".encode()) % 1000)   # hash() is salted
    p = writers.raw(tmp_path / "vol.bin", arr, big=order == "big")
    vol = load_volume(p, shape=(5, 4, 3), dtype=dtype, byte_order=order, spacing=(1, 2, 3), origin=(4, 5, 6))
    check(vol, arr, (1, 2, 3), (4, 5, 6))


@pytest.mark.parametrize("name,dtype", [("bucky_5x4x3_uint8.raw", "uint8"), ("ct-5x4x3-int16.DAT", "int16"),
                                        ("field_5x4x3_float.raw", "float32"), ("m_5x4x3_ushort.bin", "uint16"),
                                        ("d_5x4x3_double.raw", "float64")])
def test_raw_shape_and_type_from_name(tmp_path, writers, name, dtype):
    arr = make_array(dtype)
    p = writers.raw(tmp_path / name, arr)
    check(load_volume(p), arr)


def test_raw_name_can_state_byte_order(tmp_path, writers):
    assert guess_from_name("x_8x8x8_int16_be.raw") == {"shape": (8, 8, 8), "dtype": "int16", "byte_order": "big"}
    arr = make_array("int16")
    check(load_volume(writers.raw(tmp_path / "x_5x4x3_int16_be.raw", arr, big=True)), arr)


def test_raw_name_giving_both_byte_orders_is_refused_unless_one_is_given(tmp_path, writers):
    # Read by the last word, "_le_be" took the samples big-endian and "_be_le" little, silently.
    arr = make_array("int16")
    for name in ("x_5x4x3_int16_le_be.raw", "x_5x4x3_int16_be_le.raw"):
        p = writers.raw(tmp_path / name, arr)
        assert guess_from_name(p)["byte_orders"] in (["little", "big"], ["big", "little"])
        with pytest.raises(InputError, match="the name gives both byte orders; give --byte-order"):
            load_volume(p)
        check(load_volume(p, byte_order="little"), arr)
    # Single bytes read the same in either order.
    arr = make_array("uint8")
    check(load_volume(writers.raw(tmp_path / "x_5x4x3_uint8_le_be.raw", arr)), arr)


def test_raw_name_giving_two_shapes_is_refused_unless_one_is_given(tmp_path, writers):
    arr = make_array("uint8")
    p = writers.raw(tmp_path / "x_5x4x3_then_3x4x5_uint8.raw", arr)
    assert guess_from_name(p)["shapes"] == [(5, 4, 3), (3, 4, 5)]
    with pytest.raises(InputError, match="the name gives the shapes 5x4x3 and 3x4x5; give --shape"):
        load_volume(p)
    check(load_volume(p, shape=(5, 4, 3)), arr)
    # The same shape twice says one thing.
    assert "shapes" not in guess_from_name("x_5x4x3_5x4x3_uint8.raw")


@pytest.mark.parametrize("name", ["x_5x4x3x2_uint8.raw", "x_5x4x3x1_uint8.raw", "x_1X5x4x3_uint8.raw"])
def test_raw_name_giving_four_sizes_is_refused_unless_a_shape_is_given(tmp_path, writers, name):
    # Its first three had been read as the shape: 5x4x3 of a 5x4x3x2 file's samples, silently.
    arr = make_array("uint8")
    p = writers.raw(tmp_path / name, np.concatenate([arr, arr]) if "x2_" in name else arr)
    sizes = name.split("_")[1]
    with pytest.raises(InputError, match=f"the name gives 4 sizes \\({sizes}\\), where a volume has three; "
                                         "give --shape"):
        load_volume(p)
    assert "shape" not in guess_from_name(p)
    if "x2_" not in name:
        check(load_volume(p, shape=(5, 4, 3)), arr)


@pytest.mark.parametrize("name, said", [("ct_4x3x2_int16_le_be.raw", "both little- and big-endian"),
                                        ("ct_4x3x2_or_2x3x4_int16.raw", "4x3x2 and 2x3x4"),
                                        ("ct_4x3x2x1_int16.raw", "4x3x2x1")])
def test_a_raw_name_read_back_only_with_a_flag_is_not_written(tmp_path, name, said):
    arr = np.zeros((2, 3, 4), np.int16)
    with pytest.raises(InputError, match=f"the name says {said}"):
        save_volume(Volume(arr), tmp_path / name, byte_order="little")
    assert not (tmp_path / name).exists()
    # One byte a sample: either order reads it back.
    save_volume(Volume(arr.astype(np.uint8)), tmp_path / "ct_4x3x2_uint8_le_be.raw")


def test_raw_name_with_a_sized_type_word_beside_a_c_word(tmp_path, writers):
    # "double" here names the helix, not the samples: the word with a width wins.
    assert guess_from_name("double_helix_5x4x3_uint8.raw") == {
        "shape": (5, 4, 3), "dtype": "uint8", "dtypes": ["uint8", "float64"]}
    arr = make_array("uint8")
    check(load_volume(writers.raw(tmp_path / "double_helix_5x4x3_uint8.raw", arr)), arr)
    arr = make_array("float32")
    check(load_volume(writers.raw(tmp_path / "char_map_5x4x3_float32.raw", arr)), arr)


@pytest.mark.parametrize("dtype", ["int16", "float32"])
def test_raw_name_with_two_c_words_takes_the_type_the_size_fits(tmp_path, writers, dtype):
    arr = make_array(dtype)
    p = writers.raw(tmp_path / "float_short_5x4x3.raw", arr)
    assert guess_from_name(p)["dtypes"] == ["float32", "int16"]
    check(load_volume(p), arr)


def test_raw_name_with_two_types_of_one_width_is_refused(tmp_path, writers):
    p = writers.raw(tmp_path / "int_uint_5x4x3.raw", make_array("int32"))
    with pytest.raises(InputError, match="int32 and uint32.*give --dtype"):
        load_volume(p)
    check(load_volume(p, dtype="uint32"), make_array("int32").astype(np.uint32))


def test_raw_name_sized_word_wins_where_a_c_word_of_its_width_fits_too(tmp_path, writers):
    # char (int8) and uint8 both fit 60 bytes: the word with its width says which.
    arr = make_array("uint8")
    check(load_volume(writers.raw(tmp_path / "char_5x4x3_uint8.raw", arr)), arr)
    assert guess_from_name("char_5x4x3_uint8.raw")["dtype"] == "uint8"


@pytest.mark.parametrize("options, message", [
    ({"shape": (5.5, 4, 3)}, "shape must be three integers"),
    ({"shape": "5,4,3.5"}, "shape must be three integers"),
    ({"shape": (5, 4, 3), "offset": 1.5}, "offset must be a byte count"),
    ({"shape": (5, 4, 3), "offset": "-2"}, "offset must not be negative"),
])
def test_raw_fractional_shape_or_offset_is_refused(tmp_path, writers, options, message):
    p = writers.raw(tmp_path / "v.raw", make_array("uint8"))
    with pytest.raises(InputError, match=message):
        load_volume(p, dtype="uint8", **options)
    check(load_volume(p, dtype="uint8", shape=(5.0, "4", np.int64(3)), offset=0.0), make_array("uint8"))


def test_raw_options_override_name_and_accept_strings(tmp_path, writers):
    arr = make_array("uint16", shape=(2, 3, 10))
    p = writers.raw(tmp_path / "wrong_5x4x3_uint8.raw", arr)
    check(load_volume(p, shape="10,3,2", dtype="uint16"), arr)


def test_raw_offset(tmp_path, writers):
    arr = make_array("int32")
    p = writers.raw(tmp_path / "h.raw", arr, header=b"HEADER!!")
    check(load_volume(p, shape=(5, 4, 3), dtype="int32", offset=8), arr)
    with pytest.raises(InputError, match=r"needs 240 bytes after a 10-byte header, "
                                         r"the file has 238 after it \(248 in all\)$"):
        load_volume(p, shape=(5, 4, 3), dtype="int32", offset=10)
    # A header as long as the file: "the file has 0" said the file was empty.
    with pytest.raises(InputError, match=r"the file has 0 after it \(248 in all\)$"):
        load_volume(p, shape=(5, 4, 3), dtype="int32", offset=248)
    # An offset past the end: not "the file has 0", but the file's size.
    with pytest.raises(InputError, match=r"needs 240 bytes after a 400-byte header, "
                                         r"the file has only 248 bytes in all$"):
        load_volume(p, shape=(5, 4, 3), dtype="int32", offset=400)


@pytest.mark.parametrize("ext", [".nrrd", ".nhdr", ".mhd", ".mha", ".vtk", ".npy"])
def test_placement_round_trips_exactly(tmp_path, ext):
    # Values no float32 holds: a writer or reader rounding them to float32 (0.1 to 0.10000000149)
    # would pass a comparison within 1e-6.
    vol = Volume(make_array("uint8"), spacing=(0.1, 1 / 3, 2.7), origin=(-12.345678901, 0.1, 1e-3))
    back = load_volume(save_volume(vol, tmp_path / f"v{ext}"))
    assert back.spacing == vol.spacing and back.origin == vol.origin


def test_raw_writer_roundtrip(tmp_path):
    arr = make_array("float64")
    p = save_volume(Volume(arr), tmp_path / "w_5x4x3_float64.raw")
    check(load_volume(p), arr)


# --- NRRD ------------------------------------------------------------------

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("compress", [True, False])
def test_nrrd_roundtrip(tmp_path, dtype, compress):
    arr = make_array(dtype)
    vol = Volume(arr, spacing=(0.25, 0.5, 3.0), origin=(-10.0, 0.5, 7.0))
    p = save_volume(vol, tmp_path / "v.nrrd", compress=compress)
    check(load_volume(p), arr, vol.spacing, vol.origin)


@pytest.mark.parametrize("name", ["d.nhdr", "d.NHDR", "d.Nhdr"])
def test_nhdr_detached_roundtrip(tmp_path, name):
    # Whatever the case of its ending: pynrrd detached only a lower-case ".nhdr", and d.NHDR
    # held the samples itself.
    arr = make_array("int16")
    p = save_volume(Volume(arr, spacing=(1, 1, 2)), tmp_path / name)
    assert sorted(f.name for f in tmp_path.iterdir()) == sorted(["d.raw", name])
    assert b"data file: d.raw\n" in p.read_bytes() and p.stat().st_size < 1000
    assert (tmp_path / "d.raw").stat().st_size == arr.nbytes
    check(load_volume(p), arr, (1, 1, 2))


@pytest.mark.parametrize("encoding", ["raw", "gzip"])
def test_nrrd_big_endian_and_spacings_field(tmp_path, encoding):
    arr = make_array("int16")
    header = {"spacings": [0.5, 0.75, 2.0], "endian": "big", "encoding": encoding}
    nrrd.write(str(tmp_path / "b.nrrd"), arr.astype(">i2"), header, index_order="C")
    check(load_volume(tmp_path / "b.nrrd"), arr, (0.5, 0.75, 2.0))


@pytest.mark.parametrize("encoding, pack", [("gzip", gzip.compress), ("bzip2", bz2.compress)])
@pytest.mark.parametrize("detached", [False, True])
def test_nrrd_byte_skip_applies_to_the_decompressed_bytes(tmp_path, encoding, pack, detached):
    # NRRD's byte skip counts decompressed bytes (a header the compressed data carry
    # along); the bytes skipped here are text a reader that skipped the stream's own
    # bytes would misread, and a second skip would shift every sample.
    arr = make_array("int16")
    head = (f"NRRD0004\ntype: short\ndimension: 3\nsizes: 5 4 3\nendian: big\nencoding: {encoding}\n"
            f"byte skip: 7\nspacings: 1 1 2\n")
    payload = pack(b"HEADER\n" + arr.astype(">i2").tobytes())
    if detached:
        (tmp_path / "v.raw.gz").write_bytes(payload)
        p = tmp_path / "v.nhdr"
        p.write_bytes((head + "data file: v.raw.gz\n\n").encode())
    else:
        p = tmp_path / "v.nrrd"
        p.write_bytes((head + "\n").encode() + payload)
    check(load_volume(p), arr, (1, 1, 2))


def test_nrrd_line_skip_then_byte_skip_of_compressed_data(tmp_path):
    # The line skip counts lines of the file, the byte skip bytes of the decompressed data.
    arr = make_array("uint8")
    p = tmp_path / "v.nrrd"
    p.write_bytes(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 5 4 3\nencoding: gzip\nline skip: 2\n"
                  b"byte skip: 3\n\nfirst line\nsecond line\n" + gzip.compress(b"abc" + arr.tobytes()))
    check(load_volume(p), arr)


@pytest.mark.parametrize("encoding, pack", [("gzip", gzip.compress), ("bzip2", bz2.compress)])
@pytest.mark.parametrize("skip", [0, 5])
@pytest.mark.parametrize("tail", [b"", b"\0\0\0\0"], ids=["end", "padded"])
def test_nrrd_compressed_data_in_several_members_are_read_whole(tmp_path, encoding, pack, skip, tail):
    # A gzip file may hold several members (cat a.gz b.gz; parallel compressors write one per
    # block) and a bzip2 file several streams (pbzip2): the samples are all of them, as teem
    # reads them, and padding after the last is ignored. The cut falls inside a sample.
    arr = make_array("int16")
    body = b"ABCDE"[:skip] + arr.astype("<i2").tobytes()
    cut = len(body) // 3 + 1
    p = tmp_path / "m.nrrd"
    p.write_bytes(f"NRRD0004\ntype: int16\ndimension: 3\nsizes: 5 4 3\nendian: little\nencoding: {encoding}\n"
                  f"byte skip: {skip}\n\n".encode() + pack(body[:cut]) + pack(body[cut:2 * cut])
                  + pack(body[2 * cut:]) + tail)
    check(load_volume(p), arr)


@pytest.mark.parametrize("skip, size, message", [
    (100, 60, "byte skip 100 passes the end of the 60 decompressed bytes"),
    (4, 4 + 60 + 5, "hold 65 bytes after the byte skip, more than the 60"),
    (-1, 64, "byte skip -1 .* applies to raw data only, not gzip"),    # teem refuses it too
])
def test_nrrd_byte_skip_of_compressed_data_that_does_not_fit_is_one_line(tmp_path, skip, size, message):
    p = tmp_path / "v.nrrd"
    p.write_bytes(f"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 5 4 3\nencoding: gzip\nbyte skip: {skip}\n\n"
                  .encode() + gzip.compress(bytes(size)))
    with pytest.raises(InputError, match=message):
        load_volume(p)


def _hex_lines(data, width=32):
    text = data.hex().upper()
    return "\n".join(text[i:i + width] for i in range(0, len(text), width)).encode() + b"\n"


def _nrrd_with(tmp_path, head, payload, detached):
    """An NRRD of header fields ``head`` and data ``payload``: attached (``v.nrrd``), or detached
    (``v.nhdr`` naming ``v.dat``)."""
    if detached:
        (tmp_path / "v.dat").write_bytes(payload)
        p = tmp_path / "v.nhdr"
        p.write_text(head + "data file: v.dat\n")
    else:
        p = tmp_path / "v.nrrd"
        p.write_bytes((head + "\n").encode() + payload)
    return p


@pytest.mark.parametrize("detached", [False, True])
def test_nrrd_hex_data_are_read(tmp_path, detached):
    # NRRD's hex encoding (two digits a byte, lines of any width), which pynrrd does not
    # read; the line skip counts lines of the file and so does the byte skip its bytes, as
    # for text (teem's reader; only compressed data skip decoded bytes).
    arr = make_array("int16")
    head = "NRRD0004\ntype: short\ndimension: 3\nsizes: 5 4 3\nendian: big\nencoding: hex\nline skip: 1\nbyte skip: 5\n"
    payload = b"a comment line\nJUNK:" + _hex_lines(arr.astype(">i2").tobytes(), width=30)
    check(load_volume(_nrrd_with(tmp_path, head, payload, detached)), arr)


@pytest.mark.parametrize("detached", [False, True])
def test_nrrd_text_takes_every_c_number_form(tmp_path, detached):
    # Text samples as C's strtod (teem's reader) takes them: a bare dot before the exponent,
    # signs, no digits after the dot; NumPy's text reading refused "1.e5".
    words = "1.e5 -1.e+3 2. .5 +3 -0 7E-1 1e0"
    head = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\nline skip: 1\nbyte skip: 3\n"
    p = _nrrd_with(tmp_path, head, ("# a line\nXY " + words + "\n").encode(), detached)
    assert load_volume(p).data.ravel().tolist() == [float(np.float32(w)) for w in words.split()]
    data = tmp_path / "v.dat" if detached else p
    data.write_text(data.read_text().replace(" 2. ", " two "))
    with pytest.raises(InputError, match="the text sample 'two' is not a number"):
        load_volume(p)


def _nearest_float32(text):
    """The float32 nearest the decimal ``text``, ties to even, by exact arithmetic: the truth
    C's ``strtof`` gives (inf past the overflow threshold)."""
    value = Fraction(Decimal(text))
    with np.errstate(over="ignore"):
        guess = np.float32(float(value))
        near = {guess, np.nextafter(guess, np.float32(-np.inf)), np.nextafter(guess, np.float32(np.inf))}
    top = Fraction(float(np.finfo(np.float32).max)) + Fraction(2) ** 103
    def distance(c):
        if np.isinf(c):
            return (abs(value) < top, 0, 0)
        return (False, abs(Fraction(float(c)) - value), int(np.array(c).view(np.uint32)) & 1)
    return min(near, key=distance)


def _around_float32_midpoints(with_overflow):
    """Decimal words just below, on and just above the midpoints between float32 neighbours
    (through a double, all three round to the same double, the midpoint), and with
    ``with_overflow`` one just below the overflow threshold (through a double, infinity)."""
    words = []
    with localcontext() as ctx:
        ctx.prec = 120
        for a in (np.float32(1), np.float32(0.1), np.float32(-3e-41), np.float32(0), np.finfo(np.float32).max):
            with np.errstate(over="ignore"):
                b = np.nextafter(a, np.float32(np.inf))
            gap = Fraction(2) ** 104 if np.isinf(b) else Fraction(float(b)) - Fraction(float(a))
            mid = Fraction(float(a)) + gap / 2
            exact = Decimal(mid.numerator) / Decimal(mid.denominator)
            nudge = Decimal(gap.numerator) / Decimal(gap.denominator) * Decimal("1e-25")
            if np.isinf(b):
                if with_overflow:
                    words.append(str(exact - nudge))
                continue
            words += [str(exact - nudge), str(exact), str(exact + nudge)]
    assert len({float(w) for w in words}) == 4 + with_overflow       # the double cannot tell them apart
    return words


@pytest.mark.parametrize("fmt", ["nrrd", "mha", "vtk"])
def test_float_text_rounds_once_to_float32(tmp_path, fmt):
    # Each reader's own parses float text as strtof does, straight to the nearest float32.
    # Read as a double first, a decimal a hair off a float32 midpoint became the midpoint
    # itself and then rounded to even: 1.00000005960464477539062500001 read as 1.0.
    words = _around_float32_midpoints(with_overflow=True)
    words += ["0.5"] * (-len(words) % 4)
    n = len(words)
    text = (" ".join(words) + "\n").encode()
    p = tmp_path / f"v.{fmt}"
    if fmt == "nrrd":
        p.write_bytes(f"NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 {n // 4}\nencoding: ascii\n\n".encode() + text)
    elif fmt == "mha":
        p.write_bytes(f"NDims = 3\nBinaryData = False\nDimSize = 2 2 {n // 4}\nElementType = MET_FLOAT\n"
                      "ElementDataFile = LOCAL\n".encode() + text)
    else:
        p.write_bytes(f"# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 {n // 4}\n"
                      f"SPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA {n}\nSCALARS v float 1\nLOOKUP_TABLE default\n"
                      .encode() + text)
    got = load_volume(p).data.ravel()
    expected = np.array([_nearest_float32(w) for w in words], np.float32)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, expected)
    with np.errstate(over="ignore"):
        through_double = np.array([np.float64(w) for w in words]).astype(np.float32)
    assert (got != through_double).sum() >= 4          # the cases a double misreads


@pytest.mark.parametrize("body, skip, message", [
    (b"00G1" + b"00" * 58, 0, "hex data: 'G' is not a hex digit"),
    (b"0" * 121, 0, "hex data: an odd number of digits .121."),
    (b"00" * 61, 0, "the hex data hold 61 bytes after the byte skip, more than the 60"),
    (b"00" * 60, 200, "byte skip 200 passes the end of the 120 bytes of hex data"),
])
def test_nrrd_hex_data_that_do_not_fit_are_one_line(tmp_path, body, skip, message):
    p = tmp_path / "v.nrrd"
    p.write_bytes(f"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 5 4 3\nencoding: hex\nbyte skip: {skip}\n\n".encode()
                  + body)
    with pytest.raises(InputError, match=message):
        load_volume(p)


def _split_nrrd(tmp_path, arr, encoding, blocks, data_file, *, lines=0, skip=0, endian="big", header_lines=None):
    """Write ``arr`` (int16, z y x) as one data file per block of its flattened samples, each
    behind ``lines`` lines and ``skip`` bytes of junk (of the file; for gzip, of the decompressed
    data), and a header whose ``data file`` field is ``data_file`` (``LIST ...`` is followed by
    the names); return the header's path."""
    order = ">i2" if endian == "big" else "<i2"
    names = []
    for n, part in enumerate(np.split(arr.ravel(), blocks)):
        body = " ".join(str(v) for v in part).encode() if encoding == "text" else part.astype(order).tobytes()
        body = _hex_lines(body) if encoding == "hex" else body
        body = b"J" * max(skip, 0) + body
        body = gzip.compress(body) if encoding == "gzip" else body
        names.append(f"part{n:02d}.dat")
        (tmp_path / names[-1]).write_bytes(b"line\n" * lines + body)
    lines = lines if header_lines is None else header_lines
    z, y, x = arr.shape
    head = (f"NRRD0004\ntype: int16\ndimension: 3\nsizes: {x} {y} {z}\nendian: {endian}\n"
            f"encoding: {encoding}\nline skip: {lines}\nbyte skip: {skip}\nspacings: 1 1 2\n"
            f"data file: {data_file}\n")
    if data_file.startswith("LIST"):
        head += "".join(n + "\n" for n in names)
    p = tmp_path / "split.nhdr"
    p.write_text(head)
    return p


@pytest.mark.parametrize("encoding, lines, skip", [("raw", 0, 0), ("raw", 2, 3), ("raw", 1, -1), ("gzip", 1, 4),
                                                  ("text", 1, 0), ("hex", 1, 2)])
@pytest.mark.parametrize("data_file, blocks", [
    ("LIST", 3),                        # a file a slice (the default: every axis but the slowest)
    ("part%02d.dat 0 2 1", 3),
    ("part%02d.dat 0 11 1 1", 12),      # a file a row of each slice
    ("LIST 2", 3),
    ("part%02d.dat 0 0 1 3", 1),        # the whole volume in one numbered file
])
def test_nrrd_samples_in_several_data_files_are_joined_in_order(tmp_path, encoding, lines, skip, data_file,
                                                                 blocks):
    # NRRD's two ways of naming several data files, pynrrd reading neither: LIST with the names
    # on the header's last lines, and a printf-style name numbered MIN to MAX by STEP; each file
    # a block of the fastest SUBDIM axes, behind its own line and byte skips (teem's reading).
    arr = make_array("int16")
    p = _split_nrrd(tmp_path, arr, encoding, blocks, data_file, lines=lines, skip=skip)
    vol = load_volume(p)
    check(vol, arr, (1, 1, 2))
    # The command line writes over none of them: the header and each data file, named.
    want = [p] + [tmp_path / f"part{n:02d}.dat" for n in range(blocks)]
    assert sorted(Path(f).resolve() for f in vol.meta["files"]) == sorted(w.resolve() for w in want)


def test_nrrd_numbered_data_files_count_down_and_in_slabs(tmp_path):
    # A negative step names the files in falling order; a SUBDIM equal to the dimension cuts the
    # slowest axis into equal slabs, one a file.
    arr = make_array("int16", shape=(4, 2, 3))
    for n, part in enumerate(np.split(arr.ravel(), 2)):
        (tmp_path / f"s{7 - 2 * n}.raw").write_bytes(part.astype("<i2").tobytes())
    p = tmp_path / "down.nhdr"
    p.write_text("NRRD0004\ntype: int16\ndimension: 3\nsizes: 3 2 4\nendian: little\nencoding: raw\n"
                 "data file: s%d.raw 7 5 -2 3\n")
    check(load_volume(p), arr)


@pytest.mark.parametrize("data_file, blocks, message", [
    ("LIST", 2, "2 data files of 20 samples each .blocks of 2 axes. do not make the header's 60 samples"),
    ("part%02d.dat 1 3 1", 3, r"data file 3 of 3 \(.*part03.dat\) not found"),
    ("part%02d.dat 0 2 0", 3, "numbers 0 to 2 by 0 name no file"),
    ("part%02d.dat 2 0 1", 3, "numbers 2 to 0 by 1 name no file"),
    ("part%s%d.dat 0 2 1", 3, "is not a name with one integer conversion"),
    ("part%02d.dat 0 2 1 4", 3, "the data files' dimension '4' must be 1 to 3"),
    ("LIST 0", 3, "the data files' dimension '0' must be 1 to 3"),
])
def test_nrrd_several_data_files_that_do_not_fit_are_one_line(tmp_path, data_file, blocks, message):
    p = _split_nrrd(tmp_path, make_array("int16"), "raw", blocks, data_file)
    with pytest.raises(InputError, match=message):
        load_volume(p)


def test_nrrd_a_missing_data_file_is_named_as_missing(tmp_path):
    # pynrrd's words were passed on: "cannot read NRRD file: [Errno 2] No such file or directory: 'gone.raw'".
    p = tmp_path / "miss.nhdr"
    p.write_text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: gone.raw\n")
    with pytest.raises(InputError) as exc:
        load_volume(p)
    assert str(exc.value) == f"{p}: data file {tmp_path / 'gone.raw'} not found"


def test_nrrd_a_short_data_file_among_several_is_named(tmp_path):
    p = _split_nrrd(tmp_path, make_array("int16"), "raw", 3, "LIST")
    (tmp_path / "part01.dat").write_bytes(bytes(38))
    with pytest.raises(InputError, match=r"data file 2 of 3 \(.*part01.dat\).*truncated or corrupt"):
        load_volume(p)
    p = _split_nrrd(tmp_path, make_array("int16"), "raw", 3, "LIST", header_lines=10 ** 20)
    with pytest.raises(InputError, match="line skip 1000.* passes the end of data file 1 of 3"):
        load_volume(p)


def test_nrrd_oblique_directions_become_norms_with_note(tmp_path):
    arr = make_array("uint8")
    c, s = np.cos(0.3), np.sin(0.3)
    dirs = np.array([[2 * c, 2 * s, 0], [-s, c, 0], [0, 0, 3]])
    nrrd.write(str(tmp_path / "o.nrrd"), arr, {"space": "left-posterior-superior", "space directions": dirs,
                                               "space origin": [1, 2, 3]}, index_order="C")
    vol = load_volume(tmp_path / "o.nrrd")
    check(vol, arr, (2, 1, 3), (1, 2, 3))
    assert "oblique" in vol.meta["note"] and "(their lengths (2.0, 1.0, 3.0))" in vol.meta["note"]
    # A spacing given replaces the lengths the note spoke of; what still holds is the grid.
    given = load_volume(tmp_path / "o.nrrd", spacing=(5, 6, 7))
    assert given.spacing == (5.0, 6.0, 7.0) and given.meta["note"] == REORIENTED_NOTE


def test_nrrd_mirrored_directions_become_spacings_with_note(tmp_path):
    # The note is the user's only word that the volume is read unmirrored.
    arr = make_array("uint8")
    nrrd.write(str(tmp_path / "m.nrrd"), arr, {"space": "left-posterior-superior",
                                               "space directions": np.diag([-2.0, 1.0, 3.0]),
                                               "space origin": [1, 2, 3]}, index_order="C")
    vol = load_volume(tmp_path / "m.nrrd")
    check(vol, arr, (2, 1, 3), (1, 2, 3))
    assert vol.meta["note"] == "negative space directions (mirrored axes) were reduced to positive spacings"
    assert load_volume(tmp_path / "m.nrrd", spacing=(1, 1, 1)).meta["note"] == REORIENTED_NOTE


def test_nrrd_axis_aligned_has_no_note(tmp_path):
    p = save_volume(Volume(make_array("uint8"), spacing=(1, 2, 3)), tmp_path / "a.nrrd")
    assert "note" not in load_volume(p).meta


# --- MetaImage -------------------------------------------------------------

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("big", [False, True])
@pytest.mark.parametrize("suffix", [".mhd", ".mha"])
def test_metaimage_roundtrip(tmp_path, writers, dtype, big, suffix):
    arr = make_array(dtype)
    p = writers.mhd(tmp_path / f"m{suffix}", arr, spacing=(0.5, 1.5, 2.5), origin=(1, -2, 3), big=big)
    check(load_volume(p), arr, (0.5, 1.5, 2.5), (1, -2, 3))


@pytest.mark.parametrize("suffix", [".mhd", ".mha"])
@pytest.mark.parametrize("dtype", ["uint8", "int16", "float32"])
def test_metaimage_compressed(tmp_path, writers, suffix, dtype):
    arr = make_array(dtype, shape=(6, 7, 8))
    p = writers.mhd(tmp_path / f"c{suffix}", arr, compressed=True, big=dtype == "int16")
    check(load_volume(p), arr)


def test_metaimage_alternative_keys(tmp_path, writers):
    arr = make_array("uint16")
    p = writers.mhd(tmp_path / "k.mhd", arr, spacing=(2, 3, 4), origin=(5, 6, 7),
                    spacing_key="ElementSize", origin_key="Position", extra=["ElementByteOrderMSB = False"])
    check(load_volume(p), arr, (2, 3, 4), (5, 6, 7))


@pytest.mark.parametrize("suffix", [".mhd", ".mha"])
@pytest.mark.parametrize("order", ["little", "big"])
def test_metaimage_writer_roundtrip(tmp_path, suffix, order):
    arr = make_array("int16")
    p = save_volume(Volume(arr, spacing=(1, 2, 3), origin=(0.5, 0, -1)), tmp_path / f"w{suffix}", byte_order=order)
    check(load_volume(p), arr, (1, 2, 3), (0.5, 0, -1))


@pytest.mark.parametrize("etype, stored", [("MET_LONG", "<i4"), ("MET_ULONG", "<u4"), ("MET_LONG_LONG", "<i8"),
                                           ("MET_ULONG_LONG", "<u8"), ("MET_LONG_LONG", ">i8")])
def test_metaimage_long_types_read_at_metaios_sizes(tmp_path, etype, stored):
    # MetaIO's LONG is 4 bytes on every system, LONG_LONG 8; 64-bit samples that fit 32 bits are narrowed.
    values = (np.arange(60).reshape(5, 4, 3) * (-3 if "U" not in etype else 3)).astype(stored)
    (tmp_path / "d.raw").write_bytes(values.tobytes())
    (tmp_path / "l.mhd").write_text(f"NDims = 3\nDimSize = 3 4 5\nElementType = {etype}\n"
                                    f"BinaryDataByteOrderMSB = {stored[0] == '>'}\nElementDataFile = d.raw\n")
    vol = load_volume(tmp_path / "l.mhd")
    np.testing.assert_array_equal(vol.data, values)
    assert vol.dtype.itemsize == 4


def test_metaimage_long_long_samples_beyond_32_bits_are_refused(tmp_path):
    (tmp_path / "d.raw").write_bytes(np.full(8, 1 << 40, "<i8").tobytes())
    (tmp_path / "l.mhd").write_text("NDims = 3\nDimSize = 2 2 2\nElementType = MET_LONG_LONG\n"
                                    "ElementDataFile = d.raw\n")
    with pytest.raises(InputError, match="beyond 32 bits"):
        load_volume(tmp_path / "l.mhd")


@pytest.mark.parametrize("encoding", ["utf-8", "latin-1"])
def test_metaimage_header_text_beyond_ascii(tmp_path, encoding):
    # ITK writes its strings as given: a comment, a name, the data file's name, in the system's encoding.
    values = np.arange(8, dtype=np.uint8).reshape(2, 2, 2)
    data_name = "Schädel 1.raw"
    (tmp_path / data_name.encode(encoding).decode("utf-8", "surrogateescape")).write_bytes(values.tobytes())
    header = ("Comment = Patient Müller, 5 µm\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
              f"ElementDataFile = {data_name}\n")
    (tmp_path / "s.mhd").write_bytes(header.encode(encoding))
    np.testing.assert_array_equal(load_volume(tmp_path / "s.mhd").data, values)


# --- VTK legacy ------------------------------------------------------------

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("ascii", [False, True])
def test_vtk_roundtrip(tmp_path, writers, dtype, ascii):
    arr = make_array(dtype)
    p = writers.vtk(tmp_path / "v.vtk", arr, spacing=(0.5, 2, 3), origin=(-1, -2, -3), ascii=ascii)
    check(load_volume(p), arr, (0.5, 2, 3), (-1, -2, -3))


def test_vtk_aspect_ratio_and_no_lookup_table(tmp_path, writers):
    arr = make_array("int16")
    p = writers.vtk(tmp_path / "a.vtk", arr, spacing=(1, 1, 2), spacing_key="ASPECT_RATIO", lookup=False, ncomp=1)
    check(load_volume(p), arr, (1, 1, 2))


@pytest.mark.parametrize("ascii", [False, True])
def test_vtk_writer_roundtrip(tmp_path, ascii):
    arr = make_array("float32")
    p = save_volume(Volume(arr, spacing=(1, 2, 3), origin=(4, 5, 6)), tmp_path / "w.vtk", ascii=ascii)
    check(load_volume(p), arr, (1, 2, 3), (4, 5, 6))


def _vtk_section(ascii, values, dtype):
    """One block of a VTK legacy file's values: big-endian bytes, or text nine to a line."""
    values = np.asarray(values, dtype=dtype).ravel()
    if ascii:
        rows = [" ".join(repr(v.item()) for v in values[i:i + 9]) for i in range(0, values.size, 9)]
        return ("\n".join(rows) + "\n").encode()
    return values.astype(np.dtype(dtype).newbyteorder(">")).tobytes() + b"\n"


def _vtk_strings(ascii, strings):
    """A string array as vtkDataWriter writes it: a line each (spaces as %20), or each behind
    a big-endian length whose top two bits say its size (11: 1 byte, 10: 2, 01: 4)."""
    if ascii:
        return b"".join(x.replace(" ", "%20").encode() + b"\n" for x in strings)
    out = b""
    for x in strings:
        n = len(x)
        head = ((0b11 << 6) | n).to_bytes(1, "big") if n < 64 else (
            ((0b10 << 14) | n).to_bytes(2, "big") if n < 1 << 14 else ((0b01 << 30) | n).to_bytes(4, "big"))
        out += head + x.encode()
    return out + b"\n"


def _vtk_with_other_arrays(path, arr, ascii, *, points_as_field=False, point_data=True, cut=0):
    """What vtkDataWriter writes for an image with more than one array: the dataset's FIELD
    (a time value), CELL_DATA before POINT_DATA, attributes before the scalars, METADATA
    blocks; written here by the VTK file-format spec, the skipped bytes made to look like
    the keywords a reader scanning lines would stop at."""
    nz, ny, nx = arr.shape
    ncells = (nx - 1) * (ny - 1) * (nz - 1)
    decoy = np.frombuffer((b"\nPOINT_DATA 7\nSCALARS x float\n" * ncells)[:ncells], np.uint8)
    t = lambda text: (text + "\n").encode()   # noqa: E731
    names = ["", "a name", "x" * 70, "y" * 20000]          # lengths behind 1-, 2- and 4-byte fields
    out = [t("# vtk DataFile Version 5.1"), t("written by hand"), t("ASCII" if ascii else "BINARY"),
           t("DATASET STRUCTURED_POINTS"), t("FIELD FieldData 2"), t("TimeValue 1 1 double"),
           _vtk_section(ascii, [2.5], "float64"), t("Names 1 4 string"), _vtk_strings(ascii, names),
           # Components named in part: an empty line for the one without a name.
           t("METADATA"), t("COMPONENT_NAMES"), t(""), t("INFORMATION 0"), t(""),
           t(f"DIMENSIONS {nx} {ny} {nz}"), t("SPACING 1 1 1"),
           t("ORIGIN 0 0 0"), t(f"CELL_DATA {ncells}"), t("SCALARS vtkGhostType unsigned_char 1"),
           t("LOOKUP_TABLE default"), _vtk_section(ascii, decoy, "uint8"),
           t("METADATA"), t("INFORMATION 0"), t(""),
           t("VECTORS flow float"), _vtk_section(ascii, np.arange(3 * ncells), "float32"),
           # vtkDataWriter writes vtkIdType values as 32-bit ints.
           t("GLOBAL_IDS GlobalIds vtkIdType"), _vtk_section(ascii, np.arange(ncells), "int32"),
           t("FIELD FieldData 2"), t(f"ids 2 {ncells} int"), _vtk_section(ascii, np.arange(2 * ncells), "int32"),
           t(f"area 1 {ncells} double"), _vtk_section(ascii, np.linspace(0, 1, ncells), "float64")]
    if point_data:
        out += [t(f"POINT_DATA {arr.size}"), t("NORMALS n double"),
                _vtk_section(ascii, np.ones(3 * arr.size), "float64"), t("TENSORS6 stress float"),
                _vtk_section(ascii, np.ones(6 * arr.size), "float32"), t("EDGE_FLAGS edges unsigned_char"),
                _vtk_section(ascii, np.ones(arr.size), "uint8")]
        vtype = {"uint8": "unsigned_char", "int16": "short", "float32": "float", "int64": "vtktypeint64"}[arr.dtype.name]
        if points_as_field:
            out += [t("FIELD FieldData 2"), t(f"velocity 3 {arr.size} float"),
                    _vtk_section(ascii, np.zeros(3 * arr.size), "float32"),
                    t(f"density 1 {arr.size} {vtype}"), _vtk_section(ascii, arr, arr.dtype)]
        else:
            # A one-component array of field data before the scalars: the scalars win.
            out += [t("FIELD FieldData 1"), t(f"other 1 {arr.size} float"),
                    _vtk_section(ascii, np.zeros(arr.size), "float32"),
                    t(f"SCALARS density {vtype} 1"), t("LOOKUP_TABLE default"), _vtk_section(ascii, arr, arr.dtype)]
    data = b"".join(out)
    path.write_bytes(data[:len(data) - cut])
    return path


@pytest.mark.parametrize("dtype", ["uint8", "int16", "float32", "int64"])
@pytest.mark.parametrize("ascii", [False, True])
@pytest.mark.parametrize("points_as_field", [False, True])
def test_vtk_reads_past_cell_data_and_other_arrays(tmp_path, dtype, ascii, points_as_field):
    # 64-bit integers that fit in 32 bits come back as 32-bit ones, as a Volume keeps them.
    arr = make_array("int32").astype(np.int64) if dtype == "int64" else make_array(dtype)
    p = _vtk_with_other_arrays(tmp_path / "many.vtk", arr, ascii, points_as_field=points_as_field)
    vol = load_volume(p)
    check(vol, arr.astype(np.int32) if dtype == "int64" else arr)
    assert vol.meta["scalars"] == "density"


@pytest.mark.parametrize("ascii", [False, True])
@pytest.mark.parametrize("vtype, dtype, size", [("long", "int64", 8), ("unsigned_long", "uint64", 8),
                                                ("vtkIdType", "int32", 4)])
def test_vtk_scalars_of_every_legal_integer_type_are_read(tmp_path, ascii, vtype, dtype, size):
    # long and unsigned_long as vtkDataWriter writes them on 64-bit Linux and macOS, vtkIdType
    # as a 32-bit int; values that fit in 32 bits come back as 32-bit ones.
    arr = make_array("int32" if dtype != "uint64" else "uint32").astype(dtype)
    assert np.dtype(dtype).itemsize == size
    nz, ny, nx = arr.shape
    head = (f"# vtk DataFile Version 3.0\nt\n{'ASCII' if ascii else 'BINARY'}\nDATASET STRUCTURED_POINTS\n"
            f"DIMENSIONS {nx} {ny} {nz}\nPOINT_DATA {arr.size}\nSCALARS s {vtype} 1\nLOOKUP_TABLE default\n")
    p = tmp_path / "v.vtk"
    p.write_bytes(head.encode() + _vtk_section(ascii, arr, dtype))
    check(load_volume(p), arr.astype("uint32" if dtype == "uint64" else "int32"))


@pytest.mark.parametrize("scalars", ["SCALARS s short 01", "SCALARS s short +1", "SCALARS s short 1.0",
                                     "SCALARS s short LOOKUP_TABLE default", "SCALARS s short 1 LOOKUP_TABLE t"])
def test_vtk_scalars_line_is_read_word_by_word_as_vtk_does(tmp_path, scalars):
    # VTK's reader takes the component count as C's atoi does, and reads words, not lines: the
    # LOOKUP_TABLE keyword may end the SCALARS line itself (then the values follow at once).
    arr = make_array("int16")
    nz, ny, nx = arr.shape
    table = "" if "LOOKUP_TABLE" in scalars else "LOOKUP_TABLE default\n"
    p = tmp_path / "v.vtk"
    p.write_bytes((f"# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS {nx} {ny} {nz}\n"
                   f"POINT_DATA {arr.size}\n{scalars}\n{table}").encode() + _vtk_section(True, arr, "int16"))
    check(load_volume(p), arr)


@pytest.mark.parametrize("ascii", [False, True])
def test_vtk_field_arrays_that_could_be_the_scalars_are_named(tmp_path, ascii):
    # Points whose arrays are all field data: the first of one component is read, and the
    # others of one component are named, as several SCALARS are (a vector array is none).
    arr = make_array("uint8")
    nz, ny, nx = arr.shape
    head = (f"# vtk DataFile Version 3.0\nt\n{'ASCII' if ascii else 'BINARY'}\nDATASET STRUCTURED_POINTS\n"
            f"DIMENSIONS {nx} {ny} {nz}\nPOINT_DATA {arr.size}\nFIELD FieldData 3\n")
    p = tmp_path / "v.vtk"
    p.write_bytes(head.encode() + f"density 1 {arr.size} unsigned_char\n".encode() + _vtk_section(ascii, arr, "uint8")
                  + f"flow 3 {arr.size} float\n".encode() + _vtk_section(ascii, np.zeros(3 * arr.size), "float32")
                  + f"heat 1 {arr.size} float\n".encode() + _vtk_section(ascii, np.ones(arr.size), "float32"))
    vol = load_volume(p)
    check(vol, arr)
    assert vol.meta["note"] == "the points carry 2 scalar arrays (density, heat); the first was read (density)"


def test_vtk_null_arrays_of_field_data_are_read_past(tmp_path):
    # vtkDataWriter writes NULL_ARRAY for an array of field data that is not there.
    arr = make_array("uint8")
    nz, ny, nx = arr.shape
    p = tmp_path / "v.vtk"
    p.write_bytes(("# vtk DataFile Version 3.0\nt\nBINARY\nDATASET STRUCTURED_POINTS\nFIELD FieldData 2\n"
                   "NULL_ARRAY\nTimeValue 1 1 double\n").encode() + _vtk_section(False, [1.5], "float64")
                  + (f"DIMENSIONS {nx} {ny} {nz}\nPOINT_DATA {arr.size}\nFIELD FieldData 2\nNULL_ARRAY\n"
                     f"density 1 {arr.size} unsigned_char\n").encode() + _vtk_section(False, arr, "uint8"))
    check(load_volume(p), arr)


def test_vtk_ascii_color_scalars_scale_as_vtk_reads_them(tmp_path):
    # Truth: what VTK 9's vtkStructuredPointsReader gives for these values (float, then
    # 255 v + 0.5 in double, truncated); 0.7 and 0.01372549 sit at a rounding's edge.
    p = tmp_path / "c.vtk"
    p.write_text("# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 2\n"
                 "POINT_DATA 8\nCOLOR_SCALARS c 1\n0.7 0.9 0.527451 0.1 0.3 0.5 0.01372549 0\n")
    assert load_volume(p).data.ravel().tolist() == [178, 229, 134, 26, 77, 128, 4, 0]


def test_vtk_ascii_integers_past_64_bits_are_one_line(tmp_path):
    p = tmp_path / "big.vtk"
    p.write_text("# vtk DataFile Version 3.0\nbig\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 2\n"
                 "POINT_DATA 8\nSCALARS s vtktypeuint64\nLOOKUP_TABLE default\n1 2 3 4 5 6 7 18446744073709551615\n")
    with pytest.raises(InputError, match=r"integers of 2\*\*63 or more; samples must fit in 32 bits"):
        load_volume(p)


def test_vtk_ascii_floats_beyond_float32_are_one_line(tmp_path):
    p = tmp_path / "big.vtk"
    p.write_text("# vtk DataFile Version 3.0\nbig\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 2\n"
                 "POINT_DATA 8\nSCALARS s float\nLOOKUP_TABLE default\n1 2 3 4 5 6 7 1e39\n")
    with pytest.raises(InputError, match="outside the float32 range"):
        load_volume(p)


@pytest.mark.parametrize("ascii", [False, True])
def test_vtk_cell_data_alone_or_cut_short_is_one_line(tmp_path, ascii):
    arr = make_array("uint8")
    p = _vtk_with_other_arrays(tmp_path / "cells.vtk", arr, ascii, point_data=False)
    with pytest.raises(InputError, match="CELL_DATA and no POINT_DATA"):
        load_volume(p)
    # Cut inside the cells' last array (binary) or before its last values (text).
    p = _vtk_with_other_arrays(tmp_path / "cut.vtk", arr, ascii, point_data=False, cut=40)
    with pytest.raises(InputError, match="the file ends inside (FIELD array area|CELL_DATA)"):
        load_volume(p)


# --- SLC -------------------------------------------------------------------

def test_rle_encoder_sanity(writers):
    code = writers.rle(bytes([5] * 200 + [1, 2, 3]))
    assert code == bytes([127, 5, 73, 5, 0x83, 1, 2, 3, 0])


@pytest.mark.parametrize("compression", [0, 1])
def test_slc_roundtrip(tmp_path, writers, compression):
    rng = np.random.default_rng(5)
    arr = np.zeros((7, 9, 11), dtype=np.uint8)
    arr[2:5, 3:7, 1:9] = rng.integers(0, 256, (3, 4, 8))   # literal runs, with repeats around them
    arr[5] = 200
    p = writers.slc(tmp_path / "s.slc", arr, spacing=(0.5, 1.0, 2.0), compression=compression)
    vol = load_volume(p)
    check(vol, arr, (0.5, 1.0, 2.0))
    assert vol.meta["compression"] == ("rle" if compression else "raw")


# --- dispatch --------------------------------------------------------------

def test_extension_is_case_insensitive(tmp_path):
    arr = make_array("uint8")
    p = save_volume(Volume(arr), tmp_path / "UPPER.nrrd")
    upper = p.rename(tmp_path / "UPPER.NRRD")
    check(load_volume(upper), arr)
    check(load_volume(str(upper)), arr)


def test_spacing_and_origin_options_override_any_format(tmp_path):
    p = save_volume(Volume(make_array("uint8"), spacing=(1, 1, 1)), tmp_path / "s.nrrd")
    vol = load_volume(p, spacing=(2, 3, 4), origin=(1, 1, 1), shape=None)
    assert vol.spacing == (2, 3, 4) and vol.origin == (1, 1, 1)


#: How each header format writes a spacing of 3 and an origin of 7 (`save_volume`), and the same
#: with a value the Volume refuses: a zero spacing ("unknown" to some exporters), or an origin in map
#: coordinates more than 2^32 cells from 0.
_PLACEMENT_TEXT = {
    ".nhdr": ("space directions: (3,0,0)", "space directions: (1e-40,0,0)",
              "space origin: (7,7,7)", "space origin: (1e12,7,7)"),
    ".mhd": ("ElementSpacing = 3.0 3.0 3.0", "ElementSpacing = 0 3.0 3.0",
             "Offset = 7.0 7.0 7.0", "Offset = 1e12 7.0 7.0"),
    ".vtk": ("SPACING 3.0 3.0 3.0", "SPACING 0 3.0 3.0", "ORIGIN 7.0 7.0 7.0", "ORIGIN 1e12 7.0 7.0"),
    ".npy.json": ('"spacing": [3.0, 3.0, 3.0]', '"spacing": [0, 3.0, 3.0]',
                  '"origin": [7.0, 7.0, 7.0]', '"origin": [1e12, 7.0, 7.0]'),
}


@pytest.mark.parametrize("ext", list(_PLACEMENT_TEXT))
@pytest.mark.parametrize("field", ["spacing", "origin"])
def test_given_spacing_and_origin_replace_a_header_value_the_volume_refuses(tmp_path, ext, field):
    arr = make_array("uint8")
    name = tmp_path / ("v" + ext.removesuffix(".json"))
    save_volume(Volume(arr, spacing=(3, 3, 3), origin=(7, 7, 7)), name)
    header = tmp_path / ("v" + ext)
    good_s, bad_s, good_o, bad_o = _PLACEMENT_TEXT[ext]
    old, bad = (good_s, bad_s) if field == "spacing" else (good_o, bad_o)
    text = header.read_bytes()
    assert old.encode() in text
    header.write_bytes(text.replace(old.encode(), bad.encode()))
    with pytest.raises(InputError, match=field):
        load_volume(name)
    vol = load_volume(name, **{field: (1, 2, 3)})
    check(vol, arr, (1, 2, 3) if field == "spacing" else (3, 3, 3),
          (1, 2, 3) if field == "origin" else (7, 7, 7))


@pytest.mark.parametrize("old, bad, field, words", [
    ("space directions: (3,0,0)", "space directions: (nan,0,0)", "spacing",
     "space directions hold values that are not finite numbers; give --spacing"),
    ("space origin: (7,7,7)", "space origin: (nan,7,7)", "origin",
     r"space origin must be three finite numbers, got \(nan,7,7\); give --origin"),
])
def test_an_unreadable_nrrd_placement_names_the_flag_that_replaces_it(tmp_path, old, bad, field, words):
    arr = make_array("uint8")
    name = save_volume(Volume(arr, spacing=(3, 3, 3), origin=(7, 7, 7)), tmp_path / "v.nhdr")
    name.write_text(name.read_text().replace(old, bad))
    with pytest.raises(InputError, match=words):
        load_volume(name)
    vol = load_volume(name, **{field: (1, 2, 3)})
    check(vol, arr, (1, 2, 3) if field == "spacing" else (3, 3, 3), (1, 2, 3) if field == "origin" else (7, 7, 7))


def test_save_unknown_extension(tmp_path):
    with pytest.raises(InputError, match="supported"):
        save_volume(Volume(make_array("uint8")), tmp_path / "v.tiff")


def test_unknown_option_is_a_programming_error(tmp_path):
    with pytest.raises(TypeError):
        load_volume(tmp_path / "v.raw", shpae=(2, 2, 2))


def test_save_leaves_final_names_and_no_temporaries(tmp_path):
    vol = Volume(make_array("int16"), spacing=(1, 2, 3))
    save_volume(vol, tmp_path / "m.mhd")
    save_volume(vol, tmp_path / "n.nhdr")
    save_volume(vol, tmp_path / "a.npy")
    names = sorted(f.name for f in tmp_path.iterdir())
    assert names == ["a.npy", "a.npy.json", "m.mhd", "m.raw", "n.nhdr", "n.raw"]
    assert "ElementDataFile = m.raw" in (tmp_path / "m.mhd").read_text()
    for name in ("m.mhd", "n.nhdr", "a.npy"):
        check(load_volume(tmp_path / name), vol.data, (1, 2, 3))


def test_save_npy_rewrites_an_existing_sidecar(tmp_path):
    save_volume(Volume(make_array("uint8"), spacing=(2, 2, 2)), tmp_path / "s.npy")
    save_volume(Volume(make_array("uint8")), tmp_path / "s.npy")
    assert load_volume(tmp_path / "s.npy").spacing == (1, 1, 1)


def test_failed_save_writes_nothing(tmp_path, monkeypatch):
    from data_tools.io import nrrd_format

    def broken(volume, path, **kw):
        path.write_bytes(b"NRRD0004\npartial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(nrrd_format, "write_nrrd", broken)
    with pytest.raises(InputError, match="No space left"):
        save_volume(Volume(make_array("uint8")), tmp_path / "x.nrrd")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError, match="cannot write"):
        save_volume(Volume(make_array("uint8")), tmp_path / "no" / "such" / "dir.npy")


def test_raw_mmap_maps_the_file_read_only(tmp_path):
    data = (np.arange(5 * 4 * 3, dtype=np.int16) * 37 - 900).reshape(3, 4, 5)
    path = tmp_path / "ct_5x4x3_int16.raw"
    data.astype("<i2").tofile(path)
    vol = load_volume(path, mmap=True)
    assert isinstance(vol.data, np.memmap) and not vol.data.flags.writeable
    np.testing.assert_array_equal(vol.data, data)
    # Loaded into memory, the samples are read-only too (a Volume is fixed once built).
    loaded = load_volume(path, mmap=False).data
    assert not loaded.flags.writeable
    np.testing.assert_array_equal(loaded, data)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("slab_bytes", [None, 1])
def test_a_mapped_float_file_with_non_finite_samples_is_refused(tmp_path, bad, slab_bytes, monkeypatch):
    # The count goes slab by slab; slabs of one z-slice must find the sample too.
    import data_tools.volume
    if slab_bytes is not None:
        real = data_tools.volume._count_non_finite
        monkeypatch.setattr(data_tools.volume, "_count_non_finite", lambda data: real(data, slab_bytes))
    data = np.ones((6, 5, 4), np.float32)
    data[4, 2, 1] = bad
    data[5, 0, 0] = bad
    path = tmp_path / "field_4x5x6_float32.raw"
    data.tofile(path)
    with pytest.raises(InputError, match="2 non-finite samples"):
        load_volume(path, mmap=True)


def test_raw_mmap_refuses_the_other_byte_order(tmp_path):
    path = tmp_path / "ct_5x4x3_int16.raw"
    np.zeros((3, 4, 5), ">i2").tofile(path)
    with pytest.raises(InputError, match="byte order"):
        load_volume(path, mmap=True, byte_order="big")


def test_mmap_is_for_raw_files_only(tmp_path):
    path = save_volume(Volume(np.zeros((3, 4, 5), np.uint8)), tmp_path / "v.nrrd")
    # mmap is no flag of parc's: named as load_volume's keyword, where the others are parc's flags.
    with pytest.raises(InputError, match=r"v\.nrrd: mmap applies only to headerless raw"):
        load_volume(path, mmap=True)
    with pytest.raises(InputError, match=r"v\.nrrd: mmap, --shape apply only to headerless raw"):
        load_volume(path, mmap=True, shape=(5, 4, 3))


# --- fields read as the formats define them -----------------------------------
# An array with a different extent along each axis, so that a transposition shows.
_ZYX = (np.arange(60, dtype=np.int16) * 7 - 100).reshape(3, 4, 5)


@pytest.mark.parametrize("local", [True, False])
def test_metaimage_text_samples(tmp_path, local):
    text = " ".join(map(str, _ZYX.ravel())).encode() + b"\n"
    header = (b"ObjectType = Image\nNDims = 3\nBinaryData = False\nDimSize = 5 4 3\nElementType = MET_SHORT\n"
              b"ElementSpacing = 0.5 1 2\nElementDataFile = " + (b"LOCAL\n" if local else b"samples.txt\n"))
    path = tmp_path / ("text.mha" if local else "text.mhd")
    path.write_bytes(header + (text if local else b""))
    if not local:
        (tmp_path / "samples.txt").write_bytes(text)
    vol = load_volume(path)
    assert np.array_equal(vol.data, _ZYX) and vol.spacing == (0.5, 1.0, 2.0)
    path.write_bytes(header + b"1 2 3\n" if local else header)
    if not local:
        (tmp_path / "samples.txt").write_bytes(b"1 2 3\n")
    with pytest.raises(InputError, match="3 text samples, expected 60"):
        load_volume(path)


def test_metaimage_text_samples_read_as_nrrd_text_is(tmp_path):
    # One reading of text for both formats: numbers as C's strtod takes them (1e2 is an integer),
    # and an integer type takes integers in its range only.
    p = tmp_path / "t.mha"
    head = b"NDims = 3\nBinaryData = False\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n"
    p.write_bytes(head + b"1e2 2. 3 4 5 6 7 +8\n")
    assert load_volume(p).data.ravel().tolist() == [100, 2, 3, 4, 5, 6, 7, 8]
    p.write_bytes(head + b"-1 2 3 4 5 6 7 8\n")
    with pytest.raises(InputError, match="the text sample -1 is outside the sample type uint8 .integers 0 to 255."):
        load_volume(p)


@pytest.mark.parametrize("centers, spacing, origin", [
    ("node node node", (0.5, 1.0, 2.25), (1.0, -1.0, 0.0)),
    ("cell cell cell", (0.4, 0.75, 1.5), (1.2, -0.625, 0.75)),
    (None, (0.4, 0.75, 1.5), (1.2, -0.625, 0.75)),        # NRRD's default centring: cell
])
@pytest.mark.parametrize("spacings", [False, True])
def test_nrrd_axis_mins_and_maxs_give_spacing_and_origin(tmp_path, centers, spacing, origin, spacings):
    # x: 5 samples over [1, 3]; y: 4 over [-1, 2]; z: 3 over [0, 4.5]. The spacings, when
    # given too, agree with the extent: the first sample is where the centring puts it either way.
    lines = ["NRRD0004", "type: short", "dimension: 3", "sizes: 5 4 3", "endian: little", "encoding: raw",
             "axis mins: 1 -1 0", "axis maxs: 3 2 4.5"] + ([f"centers: {centers}"] if centers else [])
    if spacings:
        lines.append("spacings: " + " ".join(map(repr, spacing)))
    path = tmp_path / "extent.nrrd"
    path.write_bytes(("\n".join(lines) + "\n\n").encode() + _ZYX.astype("<i2").tobytes())
    vol = load_volume(path)
    assert np.array_equal(vol.data, _ZYX)
    assert vol.spacing == pytest.approx(spacing) and vol.origin == pytest.approx(origin)


def test_nrrd_colour_axis_is_refused(tmp_path):
    path = tmp_path / "rgb.nrrd"
    path.write_bytes(b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 3 5 4\nkinds: RGB-color space space\n"
                     b"encoding: raw\n\n" + bytes(60))
    with pytest.raises(InputError, match="axis 1 holds RGB-color values"):
        load_volume(path)


def test_nrrd_negative_spacings_are_noted(tmp_path):
    path = tmp_path / "mirror.nrrd"
    path.write_bytes(b"NRRD0004\ntype: short\ndimension: 3\nsizes: 5 4 3\nendian: little\nencoding: raw\n"
                     b"spacings: -0.5 1 2\n\n" + _ZYX.astype("<i2").tobytes())
    vol = load_volume(path)
    assert vol.spacing == (0.5, 1.0, 2.0) and "mirrored" in vol.meta["note"]


@pytest.mark.parametrize("spacings, spacing, words", [
    ("nan 1 2", (1.0, 1.0, 2.0), "spacings gives NaN (unknown) for x: taken as 1"),
    ("-0.5 NaN nan", (0.5, 1.0, 1.0), "mirrored axes) were reduced to positive spacings; spacings gives NaN (unknown) for y, z"),
    ("1e400 1 2", (1.0, 1.0, 2.0), "spacings gives inf for x: taken as 1"),
    ("0.5 -inf nan", (0.5, 1.0, 1.0), "spacings gives -inf and NaN (unknown) for y, z: taken as 1"),
])
def test_nrrd_unknown_spacings_are_1_with_a_note_that_a_given_spacing_drops(tmp_path, spacings, spacing, words):
    # NaN is NRRD's unknown spacing, and an infinite one is none: both were read as 1 without
    # a word (-inf as a mirrored axis). The spacing given replaces them, and the note with them,
    # but for a mirrored axis's word: the volume is still read unmirrored.
    path = tmp_path / "s.nrrd"
    path.write_bytes(b"NRRD0004\ntype: short\ndimension: 3\nsizes: 5 4 3\nendian: little\nencoding: raw\n"
                     + f"spacings: {spacings}\n\n".encode() + _ZYX.astype("<i2").tobytes())
    vol = load_volume(path)
    assert vol.spacing == spacing and words in vol.meta["note"], vol.meta.get("note")
    given = load_volume(path, spacing=(1, 2, 3))
    assert given.spacing == (1.0, 2.0, 3.0)
    assert given.meta.get("note") == (REORIENTED_NOTE if "-0.5" in spacings else None)


@pytest.mark.parametrize("sizes_first, kinds", [
    (True, ["vector", "domain", "domain", "domain"]),      # one sample a voxel, written as a vector of one
    (False, ["domain", "domain", "domain", "time"]),       # one time step
    (False, None),                                         # a trailing axis of one, no kinds
])
def test_nrrd_with_a_fourth_axis_of_one_is_a_volume(tmp_path, sizes_first, kinds):
    data = np.arange(2 * 3 * 4, dtype=np.int16).reshape(2, 3, 4) * 7 - 50      # [z, y, x]
    four = data[..., None] if sizes_first else data[None]                     # the axis of one fastest or slowest
    dirs = np.diag([1.5, 2.0, 3.0])
    dirs = np.vstack([np.full(3, np.nan), dirs] if sizes_first else [dirs, np.full(3, np.nan)])
    header = {"space dimension": 3, "space directions": dirs, "space origin": np.array([1.0, 2.0, 3.0])}
    if kinds:
        header["kinds"] = kinds
    else:
        del header["space directions"]
        header["spacings"] = np.array([1.5, 2.0, 3.0, np.nan])
    nrrd.write(str(tmp_path / "four.nrrd"), four, header, index_order="C")
    vol = load_volume(tmp_path / "four.nrrd")
    assert np.array_equal(vol.data, data) and vol.spacing == (1.5, 2.0, 3.0)
    assert vol.origin == (1.0, 2.0, 3.0)


def test_nrrd_with_a_time_axis_of_two_or_a_flat_space_stays_refused(tmp_path):
    nrrd.write(str(tmp_path / "t.nrrd"), np.zeros((2, 3, 4, 5), np.uint8), {"kinds": ["domain"] * 3 + ["time"]},
               index_order="C")
    with pytest.raises(InputError, match="NRRD has 4 axes"):
        load_volume(tmp_path / "t.nrrd")
    nrrd.write(str(tmp_path / "flat.nrrd"), np.zeros((5, 1, 3, 4), np.uint8), {"kinds": ["domain"] * 3 + ["time"]},
               index_order="C")
    with pytest.raises(InputError, match="NRRD has 4 axes"):
        load_volume(tmp_path / "flat.nrrd")


@pytest.mark.parametrize("steps, ok", [(1, True), (2, False)])
def test_metaimage_with_a_fourth_axis_of_one_is_a_volume(tmp_path, steps, ok):
    # ITK writes a series of one volume so; its TransformMatrix is then 4x4.
    data = np.arange(2 * 3 * 4 * steps, dtype="<i2").reshape(steps, 2, 3, 4) * 9 - 40
    header = ["ObjectType = Image", "NDims = 4", f"DimSize = 4 3 2 {steps}", "ElementType = MET_SHORT",
              "ElementSpacing = 1.5 2 3 1", "Offset = 1 2 3 0",
              "TransformMatrix = 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1", "ElementDataFile = LOCAL"]
    p = tmp_path / "four.mha"
    p.write_bytes(("\n".join(header) + "\n").encode() + data.tobytes())
    if not ok:
        with pytest.raises(InputError, match="NDims = 4, expected a 3-D volume"):
            load_volume(p)
        return
    vol = load_volume(p)
    assert np.array_equal(vol.data, data[0]) and vol.spacing == (1.5, 2.0, 3.0) and vol.origin == (1.0, 2.0, 3.0)
    assert "note" not in vol.meta and "reoriented" not in vol.meta


def test_metaimage_with_a_rotation_says_it_is_read_on_an_axis_aligned_grid(tmp_path):
    data = np.arange(2 * 3 * 4, dtype="<i2").reshape(2, 3, 4)
    header = ["ObjectType = Image", "NDims = 3", "DimSize = 4 3 2", "ElementType = MET_SHORT",
              "TransformMatrix = 0 1 0 -1 0 0 0 0 1", "ElementDataFile = LOCAL"]
    p = tmp_path / "turned.mha"
    p.write_bytes(("\n".join(header) + "\n").encode() + data.tobytes())
    vol = load_volume(p)
    assert np.array_equal(vol.data, data)
    assert vol.meta["note"] == "non-identity TransformMatrix ignored: the volume is read on an axis-aligned grid"
    assert vol.meta["reoriented"]
    # A spacing given leaves the note as it is: it said nothing of the spacing, and not twice.
    assert load_volume(p, spacing=(1, 2, 3)).meta["note"] == vol.meta["note"]


# MetaImage header fields as other writers spell them (the MetaIO documentation), and a raw
# name's type word: the truth is the array and placement written by hand.

def _mhd(tmp_path, lines, raw_bytes, name="v"):
    (tmp_path / f"{name}.raw").write_bytes(raw_bytes)
    (tmp_path / f"{name}.mhd").write_text(
        "ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\n" + "".join(line + "\n" for line in lines)
        + f"ElementDataFile = {name}.raw\n")
    return tmp_path / f"{name}.mhd"


#: [z, y, x]; x fastest on disk, as the files store it.
_A16 = np.arange(24, dtype=np.int16).reshape(2, 3, 4) * 37 - 300


def test_metaimage_attached_header_size_counts_from_the_file_start(tmp_path):
    # MetaIO skips HeaderSize bytes from the start of the data file, which for LOCAL data is
    # the .mha itself, its text header included (ITK reads such a file so).
    def mha(header_size, junk):
        head = ("ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\n"
                f"HeaderSize = {header_size:05d}\nElementDataFile = LOCAL\n").encode()
        p = tmp_path / "v.mha"
        p.write_bytes(head + junk + _A16.astype("<i2").tobytes())
        return p, len(head)
    _, size = mha(0, b"JUNK")
    p, _ = mha(size + 4, b"JUNK")
    np.testing.assert_array_equal(load_volume(p).data, _A16)
    p, _ = mha(size - 1, b"")
    with pytest.raises(InputError, match=f"HeaderSize {size - 1} ends inside the header .{size} bytes."):
        load_volume(p)


@pytest.mark.parametrize("kind", ["BinaryData = False", "CompressedData = True"])
def test_metaimage_header_size_minus_one_is_for_raw_samples(tmp_path, kind):
    # The samples' length is known only for raw binary ones: text or compressed data cannot be
    # found by where they end.
    p = _mhd(tmp_path, ["ElementType = MET_SHORT", "HeaderSize = -1", kind], b"JUNK 1 2 3")
    with pytest.raises(InputError, match="HeaderSize -1 .the samples end the file. applies to raw binary"):
        load_volume(p)


def test_metaimage_list_may_give_its_dimension_as_metaio_writes_it(tmp_path):
    np.testing.assert_array_equal(load_volume(_split_mhd(tmp_path, "LIST 2D", 2)).data, _A16)


def test_metaimage_header_size_minus_one_with_two_byte_samples(tmp_path):
    # HeaderSize = -1: the samples are the file's last nx ny nz itemsize bytes.
    p = _mhd(tmp_path, ["ElementType = MET_SHORT", "HeaderSize = -1"], b"JUNKHDR" + _A16.astype("<i2").tobytes())
    np.testing.assert_array_equal(load_volume(p).data, _A16)


def test_metaimage_origin_key_places_the_volume(tmp_path):
    p = _mhd(tmp_path, ["ElementType = MET_SHORT", "Origin = 1.5 -2 3"], _A16.astype("<i2").tobytes())
    assert load_volume(p).origin == (1.5, -2.0, 3.0)


@pytest.mark.parametrize("lines, origin", [
    (["Position = 1 1 1", "Offset = 2 2 2", "Origin = 3 3 3"], (3.0, 3.0, 3.0)),
    (["Origin = 3 3 3", "Offset = 2 2 2", "Position = 1 1 1"], (3.0, 3.0, 3.0)),
    (["Offset = 2 2 2", "Position = 1 1 1"], (2.0, 2.0, 2.0)),
])
def test_metaimage_origin_fields_rank_as_metaio_ranks_them(tmp_path, lines, origin):
    # MetaIO's MetaObject::M_Read sets the origin from Position, then Offset, then Origin,
    # each overwriting the last, wherever they stand in the header: ITK reads such a file so.
    p = _mhd(tmp_path, ["ElementType = MET_SHORT", *lines], _A16.astype("<i2").tobytes())
    assert load_volume(p).origin == origin


@pytest.mark.parametrize("lines", [["ElementByteOrderMSB = False", "BinaryDataByteOrderMSB = True"],
                                   ["BinaryDataByteOrderMSB = True", "ElementByteOrderMSB = False"]])
def test_metaimage_binary_data_byte_order_wins_over_element_byte_order(tmp_path, lines):
    # M_Read reads ElementByteOrderMSB, then BinaryDataByteOrderMSB into the same flag.
    p = _mhd(tmp_path, ["ElementType = MET_SHORT", *lines], _A16.astype(">i2").tobytes())
    np.testing.assert_array_equal(load_volume(p).data, _A16)


def test_metaimage_element_byte_order_msb_reads_big_endian(tmp_path):
    p = _mhd(tmp_path, ["ElementType = MET_SHORT", "ElementByteOrderMSB = True"], _A16.astype(">i2").tobytes())
    np.testing.assert_array_equal(load_volume(p).data, _A16)


def _split_mhd(tmp_path, data_file, blocks, *, kind="raw", header_size=0, msb=False):
    """`_A16` as one data file per block of its flattened samples (each behind ``header_size``
    bytes of junk; -1: 5 of them) and an .mhd naming them by ``data_file`` (``LIST ...`` is
    followed by the names)."""
    names = []
    for n, part in enumerate(np.split(_A16.ravel(), blocks)):
        body = (" ".join(map(str, part)).encode() if kind == "text"
                else part.astype(">i2" if msb else "<i2").tobytes())
        body = zlib.compress(body) if kind == "zlib" else body
        names.append(f"s{n:02d}.dat")
        (tmp_path / names[-1]).write_bytes(b"J" * (5 if header_size == -1 else header_size) + body)
    lines = ["NDims = 3", "DimSize = 4 3 2", "ElementType = MET_SHORT", f"HeaderSize = {header_size}",
             f"BinaryData = {kind != 'text'}", f"CompressedData = {kind == 'zlib'}", f"BinaryDataByteOrderMSB = {msb}",
             f"ElementDataFile = {data_file}"]
    if data_file.startswith("LIST"):
        lines += names
    p = tmp_path / "split.mhd"
    p.write_text("\n".join(lines) + "\n")
    return p


@pytest.mark.parametrize("kind, header_size, msb", [("raw", 0, False), ("raw", 3, True), ("raw", -1, False),
                                                    ("zlib", 0, False), ("text", 0, False)])
@pytest.mark.parametrize("data_file, blocks", [("LIST", 2), ("s%02d.dat 0 1 1", 2), ("s%02d.dat 0 5 1 1", 6),
                                               ("LIST 3", 1)])
def test_metaimage_samples_in_several_data_files_are_joined_in_order(tmp_path, kind, header_size, msb, data_file,
                                                                     blocks):
    # MetaIO's two ways of naming several data files (as NRRD's): LIST, the names on the header's
    # last lines, and a numbered name; each a block of the fastest SUBDIM axes behind its HeaderSize.
    p = _split_mhd(tmp_path, data_file, blocks, kind=kind, header_size=header_size, msb=msb)
    vol = load_volume(p)
    np.testing.assert_array_equal(vol.data, _A16)
    # The command line writes over none of them: the header and each data file, named.
    want = [p] + [tmp_path / f"s{n:02d}.dat" for n in range(blocks)]
    assert sorted(Path(f).resolve() for f in vol.meta["files"]) == sorted(w.resolve() for w in want)


@pytest.mark.parametrize("data_file, blocks, message", [
    ("LIST", 3, "3 data files of 12 samples each .blocks of 2 axes. do not make DimSize's 24 samples"),
    ("s%02d.dat 1 2 1", 2, r"data file 2 of 2 .*s02.dat \(ElementDataFile\) not found"),
    ("s%02d.dat 0 1 0", 2, "numbers 0 to 1 by 0 name no file"),
    ("s%d%s.dat 0 1 1", 2, "is not a name with one integer conversion"),
    ("LIST 4", 2, "the data files' dimension '4' must be 1 to 3"),
])
def test_metaimage_several_data_files_that_do_not_fit_are_one_line(tmp_path, data_file, blocks, message):
    with pytest.raises(InputError, match=message):
        load_volume(_split_mhd(tmp_path, data_file, blocks))


def test_metaimage_a_long_data_file_among_several_is_named(tmp_path):
    p = _split_mhd(tmp_path, "LIST", 2)
    (tmp_path / "s01.dat").write_bytes(bytes(26))
    with pytest.raises(InputError, match=r"s01.dat: MetaImage data too long: 12x1x1 int16 needs 24 bytes"):
        load_volume(p)


def test_raw_char_in_the_name_is_signed(tmp_path):
    p = tmp_path / "vol_4x3x2_char.raw"
    p.write_bytes(bytes([0xFF]) * 24)
    assert load_volume(p).data.dtype == np.int8 and load_volume(p).data.min() == -1


# --- Details a hand-made change of the readers and writers would break ----------

def test_a_raw_name_saying_be_is_written_big_endian(tmp_path):
    # Truth: the bytes on disk, by NumPy's '>i2' (values whose two bytes differ, so the order shows).
    arr = np.arange(24, dtype=np.int16).reshape(2, 3, 4) + 0x0100
    p = save_volume(Volume(arr), tmp_path / "ct_4x3x2_int16_be.raw")
    assert p.read_bytes() == arr.astype(">i2").tobytes()
    np.testing.assert_array_equal(load_volume(p).data, arr)


def test_a_raw_name_with_two_type_words_takes_a_volume_of_either(tmp_path):
    # guess_from_name gives dtypes [float32, float64] for "float_double"; a float32 volume fits one.
    arr = np.linspace(0, 1, 24, dtype=np.float32).reshape(2, 3, 4)
    p = save_volume(Volume(arr), tmp_path / "ct_float_double.raw")
    assert p.read_bytes() == arr.astype("<f4").tobytes()


def test_a_raw_name_without_byte_order_takes_any_byte_order(tmp_path):
    arr = np.arange(24, dtype=np.int16).reshape(2, 3, 4) + 0x0100
    p = save_volume(Volume(arr), tmp_path / "ct_4x3x2_int16.raw", byte_order="big")
    assert p.read_bytes() == arr.astype(">i2").tobytes()


def test_a_byte_order_the_raw_name_contradicts_is_refused(tmp_path):
    arr = np.zeros((2, 3, 4), np.int16)
    with pytest.raises(InputError, match="the name says big-endian.*little-endian"):
        save_volume(Volume(arr), tmp_path / "ct_4x3x2_int16_be.raw", byte_order="little")
    assert not (tmp_path / "ct_4x3x2_int16_be.raw").exists()


_NRRD_2X2X2 = "NRRD0004\ntype: {type}\ndimension: 3\nsizes: 2 2 2\nencoding: {enc}\n"


@pytest.mark.parametrize("split", [False, True])
def test_nrrd_text_data_refuse_byte_skip_minus_one(tmp_path, split):
    # -1 ("the data end the file") needs a known byte length: raw data only (teem: nrrdEncodingRaw only).
    words = " ".join(map(str, range(8))) + "\n"
    if split:
        for n in range(2):
            (tmp_path / f"p{n}.txt").write_text("junk\n" + " ".join(map(str, range(4 * n, 4 * n + 4))) + "\n")
        data_file = "data file: p%d.txt 0 1 1\nline skip: 1\n"
    else:
        (tmp_path / "p.txt").write_text(words)
        data_file = "data file: p.txt\n"
    p = tmp_path / "t.nhdr"
    p.write_text(_NRRD_2X2X2.format(type="int16", enc="ascii") + "byte skip: -1\n" + data_file)
    with pytest.raises(InputError, match="byte skip -1 .the data end the file. applies to raw data only, not ascii"):
        load_volume(p)


@pytest.mark.parametrize("sample", ["1.5", "-0.25"])
def test_nrrd_text_fractions_are_refused_for_integer_types(tmp_path, sample):
    # An int16 sample must be an integer: 1.5 would otherwise be truncated to 1 unnoticed.
    p = tmp_path / "t.nrrd"
    p.write_text(_NRRD_2X2X2.format(type="int16", enc="ascii") + "\n" + f"0 1 2 3 4 5 6 {sample}\n")
    # ... and called what it is: a fraction, not a value outside the type's range.
    with pytest.raises(InputError, match=f"the text sample {sample} is not a whole number, as the header's type "
                                         "int16 holds"):
        load_volume(p)


def test_nrrd_text_with_more_samples_than_the_header_is_refused(tmp_path):
    p = tmp_path / "t.nrrd"
    p.write_text(_NRRD_2X2X2.format(type="int16", enc="ascii") + "\n" + " ".join(map(str, range(9))) + "\n")
    with pytest.raises(InputError, match="8 text samples expected, 9 found"):
        load_volume(p)


def test_nrrd_hex_digits_of_one_byte_may_be_split_by_white_space(tmp_path):
    # teem's hex reader skips white space between any two digits. Truth: bytes.fromhex of the digits.
    digits = "0001 0203 0405 0607 08090a0b0c0d0e0f"
    text = "\n".join(digits[i:i + 3] for i in range(0, len(digits), 3))     # lines of 3: pairs split
    p = tmp_path / "h.nrrd"
    p.write_text(_NRRD_2X2X2.format(type="int16", enc="hex") + "endian: big\n\n" + text + "\n")
    expect = np.frombuffer(bytes.fromhex(digits), ">i2").reshape(2, 2, 2)
    np.testing.assert_array_equal(load_volume(p).data, expect)


def test_nrrd_hex_byte_skip_one_past_the_end_is_named(tmp_path):
    body = "00" * 16 + "\n"                           # 33 bytes of file after the header
    p = tmp_path / "h.nrrd"
    p.write_text(_NRRD_2X2X2.format(type="int16", enc="hex") + f"byte skip: {len(body) + 1}\n\n" + body)
    with pytest.raises(InputError, match=f"byte skip {len(body) + 1} passes the end of the {len(body)} bytes of hex"):
        load_volume(p)


def test_nrrd_attached_data_that_read_as_a_data_file_list_are_samples(tmp_path):
    # The header ends at its blank line: samples after it that happen to spell "data file: LIST"
    # are samples. Truth: the bytes written, as uint8.
    samples = b"data file: LIST\n"                       # 16 bytes
    p = tmp_path / "u.nrrd"
    p.write_bytes(b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 2 2\nencoding: raw\n\n" + samples)
    np.testing.assert_array_equal(load_volume(p).data, np.frombuffer(samples, np.uint8).reshape(2, 2, 4))


@pytest.mark.parametrize("listed", ["LIST\n# the slices\ns0.raw\n\ns1.raw\n",   # comments and blank lines
                                    "LIST 2d\ns0.raw\ns1.raw\n"])                # the dimension as MetaIO writes it
def test_nrrd_data_file_lists_as_written(tmp_path, listed):
    arr = np.arange(8, dtype="<i2")
    for n in range(2):
        (tmp_path / f"s{n}.raw").write_bytes(arr[4 * n:4 * n + 4].tobytes())
    p = tmp_path / "l.nhdr"
    p.write_text(_NRRD_2X2X2.format(type="int16", enc="raw") + "endian: little\ndata file: " + listed)
    np.testing.assert_array_equal(load_volume(p).data, arr.reshape(2, 2, 2))


def test_nrrd_one_data_file_whose_name_looks_numbered_is_that_file(tmp_path):
    # "a%d 0 1 1" is a numbered list only when no file bears that whole name.
    arr = np.arange(8, dtype="<i2")
    (tmp_path / "a%d 0 1 1").write_bytes(arr.tobytes())
    p = tmp_path / "one.nhdr"
    p.write_text(_NRRD_2X2X2.format(type="int16", enc="raw") + "endian: little\ndata file: a%d 0 1 1\n")
    np.testing.assert_array_equal(load_volume(p).data, arr.reshape(2, 2, 2))


def test_nrrd_an_empty_data_file_list_is_named(tmp_path):
    p = tmp_path / "e.nhdr"
    p.write_text(_NRRD_2X2X2.format(type="int16", enc="raw") + "data file: LIST\n")
    with pytest.raises(InputError, match="data file 'LIST' names no file"):
        load_volume(p)



_A7 = np.arange(24, dtype=np.int16).reshape(2, 3, 4) * 7 - 30


def _mhd_of(tmp_path, lines, data_file):
    p = tmp_path / "v.mhd"
    p.write_text("\n".join(["NDims = 3", "DimSize = 4 3 2", "ElementType = MET_SHORT", *lines,
                            f"ElementDataFile = {data_file}"]) + "\n")
    return p


@pytest.mark.parametrize("kind", ["zlib", "text"])
def test_metaimage_header_size_skips_junk_before_compressed_or_text_data(tmp_path, kind):
    # MetaIO skips HeaderSize bytes of the data file before any samples, compressed or text.
    body = zlib.compress(_A7.astype("<i2").tobytes()) if kind == "zlib" else " ".join(map(str, _A7.ravel())).encode()
    (tmp_path / "d.dat").write_bytes(b"JUNK7" + body)
    flags = ["CompressedData = True"] if kind == "zlib" else ["BinaryData = False"]
    p = _mhd_of(tmp_path, ["HeaderSize = 5", *flags], "d.dat")
    np.testing.assert_array_equal(load_volume(p).data, _A7)


def test_metaimage_too_few_data_files_are_one_line(tmp_path):
    (tmp_path / "s0.dat").write_bytes(_A7[0].astype("<i2").tobytes())
    p = _mhd_of(tmp_path, [], "LIST\ns0.dat")
    with pytest.raises(InputError, match="1 data files of 12 samples each .blocks of 2 axes. do not make DimSize's 24"):
        load_volume(p)


def test_metaimage_header_size_minus_one_on_a_short_file_is_truncation(tmp_path):
    (tmp_path / "d.dat").write_bytes(b"12")
    p = _mhd_of(tmp_path, ["HeaderSize = -1"], "d.dat")
    with pytest.raises(InputError, match="MetaImage data truncated: 4x3x2 int16 needs 48 bytes, the file has 2"):
        load_volume(p)


def _vtk_binary(points_line, dims, body):
    nx, ny, nz = dims
    return (f"# vtk DataFile Version 3.0\nt\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS {nx} {ny} {nz}\n"
            ).encode() + body


@pytest.mark.parametrize("scalars", ["SCALARS s unsigned_char LOOKUP_TABLE default",
                                     "SCALARS s unsigned_char 1 LOOKUP_TABLE default"])
def test_vtk_binary_scalars_after_a_table_on_the_scalars_line_start_at_once(tmp_path, scalars):
    # With LOOKUP_TABLE on the SCALARS line (VTK reads words), the samples follow that line at
    # once, even where their bytes read as another LOOKUP_TABLE line. Truth: the bytes written.
    samples = b"LOOKUP_TABLE t\n\x07"                       # 16 uint8 samples
    p = tmp_path / "v.vtk"
    p.write_bytes(_vtk_binary(None, (4, 2, 2), f"POINT_DATA 16\n{scalars}\n".encode() + samples + b"\n"))
    np.testing.assert_array_equal(load_volume(p).data, np.frombuffer(samples, np.uint8).reshape(2, 2, 4))


def test_vtk_cell_scalars_with_the_table_on_their_line_are_skipped_exactly(tmp_path):
    # Skipping CELL_DATA scalars whose SCALARS line holds LOOKUP_TABLE: their 28 bytes start at once.
    cells = b"LOOKUP_TABLE t\n" + bytes(range(13))            # 7*2*2 cells
    points = np.arange(72, dtype=np.uint8)
    p = tmp_path / "v.vtk"
    p.write_bytes(_vtk_binary(None, (8, 3, 3), b"CELL_DATA 28\nSCALARS c unsigned_char LOOKUP_TABLE default\n" + cells
                       + b"\nPOINT_DATA 72\nSCALARS s unsigned_char 1\nLOOKUP_TABLE default\n"
                       + points.tobytes() + b"\n"))
    np.testing.assert_array_equal(load_volume(p).data, points.reshape(3, 3, 8))


def test_vtk_int32_volumes_are_written_as_int(tmp_path):
    # vtkDataWriter's name for VTK_INT is "int"; vtkIdType is an alias this module only reads.
    p = save_volume(Volume(np.arange(24, dtype=np.int32).reshape(2, 3, 4) - 5), tmp_path / "v.vtk")
    assert b"\nSCALARS " in p.read_bytes()
    line = p.read_bytes().split(b"\nSCALARS ")[1].split(b"\n")[0].split()
    assert line[1] == b"int", line


@pytest.mark.parametrize("name, options, words", [
    ("v.nrrd", {"compress": "no"}, "compress must be True or False, got 'no'"),     # wrote gzip
    ("v.mhd", {"byte_order": "BIG"}, "byte_order must be 'little' or 'big', got 'BIG'"),   # wrote little-endian
    ("v.raw", {"byte_order": "middle"}, "byte_order must be 'little' or 'big' or None"),
    ("v.vtk", {"compress": True}, ".vtk files take the option ascii; got compress"),
])
def test_a_writer_option_it_cannot_honour_is_refused(tmp_path, name, options, words):
    with pytest.raises(InputError, match=re.escape(words)):
        save_volume(Volume(make_array("uint8")), tmp_path / name, **options)
    assert not list(tmp_path.iterdir())


# --- Companion files a reader must find again (links, data file names, sidecars) ----------

def test_a_header_saved_through_a_link_to_another_folder_is_refused(tmp_path):
    # Its data file would go beside the file the link leads to; read through the link, the
    # header looks for it beside the link.
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    for ext in (".mhd", ".nhdr"):
        (tmp_path / "a" / f"link{ext}").symlink_to(f"../b/real{ext}")
        with pytest.raises(InputError, match=f"a link to .*real{ext}.*write to"):
            save_volume(Volume(make_array("int16")), tmp_path / "a" / f"link{ext}")
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == []


def test_a_header_saved_through_a_link_in_its_folder_reads_back_through_the_link(tmp_path):
    arr = make_array("int16")
    (tmp_path / "link.mhd").symlink_to("real.mhd")
    save_volume(Volume(arr, spacing=(0.5, 1, 2)), tmp_path / "link.mhd")
    assert (tmp_path / "link.mhd").is_symlink() and (tmp_path / "real.raw").read_bytes() == arr.astype("<i2").tobytes()
    check(load_volume(tmp_path / "link.mhd"), arr, (0.5, 1, 2))


def test_a_npy_with_placement_saved_through_a_link_is_refused(tmp_path):
    # The sidecar would go beside the target, and the volume read through the link lose its spacing.
    (tmp_path / "link.npy").symlink_to("real.npy")
    with pytest.raises(InputError, match="a link to .*real.npy.*sidecar"):
        save_volume(Volume(make_array("uint8"), spacing=(2, 2, 2)), tmp_path / "link.npy")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.npy"]
    save_volume(Volume(make_array("uint8")), tmp_path / "link.npy")       # nothing to lose: written
    check(load_volume(tmp_path / "link.npy"), make_array("uint8"))


@pytest.mark.parametrize("name", ["list 1.mhd", "List A.nhdr", " lead.mhd", " lead.nhdr", "new\nline.mhd",
                                  "new\nline.nhdr", "esc\x1b.nhdr", "del\x7f.nhdr", "vt\x0b.nhdr"])
def test_a_header_whose_data_file_name_it_cannot_read_back_is_refused(tmp_path, name):
    # Each would be written, then refused by its own reader ("names no file", "not found", "not 'field: value'").
    with pytest.raises(InputError, match="choose another name"):
        save_volume(Volume(make_array("uint8")), tmp_path / name)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["my vol.mhd", "a.b.c.nhdr", "tab\tx.mhd", "LIST.mhd", "list of scans.nhdr",
                                  "#c.nhdr"])
def test_a_header_with_an_unusual_data_file_name_reads_back(tmp_path, name):
    arr = make_array("float32")
    save_volume(Volume(arr, spacing=(0.1, 1 / 3, 7), origin=(-1e-7, 2, 3)), tmp_path / name)
    assert (tmp_path / name).with_suffix(".raw").read_bytes() == arr.astype("<f4").tobytes()
    check(load_volume(tmp_path / name), arr, (0.1, 1 / 3, 7), (-1e-7, 2, 3))


def test_save_npy_without_sidecar_leaves_none_stale_and_loses_no_placement(tmp_path):
    save_volume(Volume(make_array("uint8"), spacing=(2, 2, 2)), tmp_path / "s.npy")
    save_volume(Volume(make_array("uint8")), tmp_path / "s.npy", sidecar=False)
    assert load_volume(tmp_path / "s.npy").spacing == (1, 1, 1)
    with pytest.raises(InputError, match="sidecar=False would lose the spacing"):
        save_volume(Volume(make_array("uint8"), spacing=(3, 3, 3)), tmp_path / "t.npy", sidecar=False)
    assert not (tmp_path / "t.npy").exists()


@pytest.mark.parametrize("name, dtype", [("float_5x4x3_int32.raw", "float32"), ("uint_5x4x3_int32.raw", "uint32"),
                                         ("char_5x4x3_uint8.raw", "int8")])
def test_a_raw_name_that_reads_back_as_another_type_of_its_width_is_refused(tmp_path, name, dtype):
    # The reader takes the type named with its width first (int32 over float): float32 samples
    # saved as float_5x4x3_int32.raw would be read back as int32.
    with pytest.raises(InputError, match="the name says"):
        save_volume(Volume(make_array(dtype)), tmp_path / name)
    assert list(tmp_path.iterdir()) == []


def test_a_npy_is_not_saved_over_a_file_of_another_kind_where_its_sidecar_goes(tmp_path):
    # A run's stats by that name: written over, or, left, read back as the volume's sidecar.
    stats = tmp_path / "t.npy.json"
    stats.write_text('{"method": "brute"}')
    for spacing in ((1, 1, 1), (2, 2, 2)):
        with pytest.raises(InputError, match="a file of another kind; move it or write elsewhere"):
            save_volume(Volume(make_array("uint8"), spacing=spacing), tmp_path / "t.npy")
    assert stats.read_text() == '{"method": "brute"}' and sorted(p.name for p in tmp_path.iterdir()) == [stats.name]
