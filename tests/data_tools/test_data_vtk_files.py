"""VTK legacy files as other tools write them: VTK's own writer, blank lines VTK's reader accepts."""
from __future__ import annotations

import numpy as np
import pytest

from data_tools import InputError
from data_tools.io import load_volume

SPACING, ORIGIN = (0.5, 2.0, 3.0), (-1.0, -2.0, -3.0)


def header(arr, encoding, scalars):
    """The lines up to and including the SCALARS part (``scalars``, already ending in a newline)."""
    nz, ny, nx = arr.shape
    return (
        "# vtk DataFile Version 3.0\nvtk output\n"
        f"{encoding}\nDATASET STRUCTURED_POINTS\nDIMENSIONS {nx} {ny} {nz}\n"
        "SPACING " + " ".join(map(str, SPACING)) + "\nORIGIN " + " ".join(map(str, ORIGIN)) + "\n"
        f"POINT_DATA {arr.size}\n" + scalars
    ).encode("ascii")


def body(arr, ascii, fmt="%d"):
    """The samples: big-endian bytes, or text ``fmt`` values five to a line."""
    if not ascii:
        return arr.astype(arr.dtype.newbyteorder(">")).tobytes() + b"\n"
    flat = [fmt % v for v in arr.ravel()]
    return "".join(" ".join(flat[i:i + 5]) + "\n" for i in range(0, len(flat), 5)).encode("ascii")


def check(path, arr):
    vol = load_volume(path)
    assert vol.data.dtype == arr.dtype
    np.testing.assert_array_equal(vol.data, arr)
    assert vol.spacing == pytest.approx(SPACING)
    assert vol.origin == pytest.approx(ORIGIN)


@pytest.mark.parametrize("ascii", [False, True])
def test_vtk_blank_lines_before_lookup_table(tmp_path, ascii):
    # VTK's reader reads the header as tokens, so blank lines there are harmless.
    arr = np.arange(60, dtype=np.int16).reshape(3, 4, 5) - 20
    p = tmp_path / "b.vtk"
    scalars = "SCALARS s short 1\n\n \r\nLOOKUP_TABLE default\n"
    p.write_bytes(header(arr, "ASCII" if ascii else "BINARY", scalars) + body(arr, ascii))
    check(p, arr)


def test_vtk_no_lookup_table_data_starting_with_newline_bytes(tmp_path):
    # Without LOOKUP_TABLE, samples that look like blank lines are data, not header.
    arr = np.arange(60, dtype=np.uint8).reshape(3, 4, 5)
    arr.flat[:3] = [10, 10, 32]
    p = tmp_path / "n.vtk"
    p.write_bytes(header(arr, "BINARY", "SCALARS s unsigned_char\n") + body(arr, False))
    check(p, arr)


@pytest.mark.parametrize("ascii", [False, True])
def test_vtk_signed_char(tmp_path, ascii):
    arr = (np.arange(60) * 4 - 120).astype(np.int8).reshape(3, 4, 5)
    p = tmp_path / "i8.vtk"
    scalars = "SCALARS ImageScalars signed_char\nLOOKUP_TABLE default\n"
    p.write_bytes(header(arr, "ASCII" if ascii else "BINARY", scalars) + body(arr, ascii))
    check(p, arr)


@pytest.mark.parametrize("ascii", [False, True])
def test_vtk_color_scalars_as_vtk_writes_uint8(tmp_path, ascii):
    # vtkDataWriter: raw bytes in BINARY, value/255 with 6 significant digits in ASCII.
    arr = (np.arange(60) * 255 // 59).astype(np.uint8).reshape(3, 4, 5)
    p = tmp_path / "u8.vtk"
    data = body(arr / 255.0, True, "%g") if ascii else arr.tobytes() + b"\n"
    p.write_bytes(header(arr, "ASCII" if ascii else "BINARY", "COLOR_SCALARS ImageScalars 1\n") + data)
    check(p, arr)


def test_vtk_color_scalars_several_components_refused(tmp_path):
    arr = np.zeros((3, 4, 5), np.uint8)
    p = tmp_path / "rgb.vtk"
    p.write_bytes(header(arr, "BINARY", "COLOR_SCALARS rgb 3\n") + bytes(3 * arr.size))
    with pytest.raises(InputError, match="COLOR_SCALARS with 3 components") as info:
        load_volume(p)
    assert "\n" not in str(info.value) and str(p) in str(info.value)


def test_vtk_ascii_color_scalars_out_of_range_refused(tmp_path):
    arr = np.zeros((3, 4, 5), np.uint8)
    p = tmp_path / "c.vtk"
    p.write_bytes(header(arr, "ASCII", "COLOR_SCALARS c 1\n") + b"1.5 " + b"0 " * (arr.size - 1))
    with pytest.raises(InputError, match=r"outside \[0, 1\]"):
        load_volume(p)


@pytest.mark.parametrize("ascii", [False, True])
@pytest.mark.parametrize("color", [False, True])
def test_vtk_several_scalar_arrays_read_the_first_and_say_so(tmp_path, ascii, color):
    # No way to choose one yet: which was drawn must at least be said.
    arr = (np.arange(60) * 4).astype(np.uint8).reshape(3, 4, 5)
    other = (np.arange(60) * 0.5 - 3).astype(np.float32).reshape(3, 4, 5)
    first = (body(arr / 255.0, True, "%g") if ascii else arr.tobytes() + b"\n") if color else body(arr, ascii)
    text = (header(arr, "ASCII" if ascii else "BINARY",
                   "COLOR_SCALARS density 1\n" if color else "SCALARS density unsigned_char\nLOOKUP_TABLE default\n")
            + first + b"VECTORS flow float\n" + body(np.zeros(180, np.float32), ascii, "%g")
            + b"SCALARS temperature float 1\nLOOKUP_TABLE default\n" + body(other, ascii, "%g"))
    p = tmp_path / "two.vtk"
    p.write_bytes(text)
    check(p, arr)
    assert load_volume(p).meta["note"] == ("the points carry 2 scalar arrays (density, temperature); "
                                           "the first was read (density)")
    one = tmp_path / "one.vtk"
    one.write_bytes(text[:text.index(b"VECTORS")])
    assert "note" not in load_volume(one).meta
