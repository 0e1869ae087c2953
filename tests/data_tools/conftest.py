"""Fixtures for the data_tools tests: independent little writers for each file format, and the real-data folder."""
from __future__ import annotations

import zlib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]
DATA_DIR = REPO_ROOT.parent / "shared" / "data"

MET_TYPES = {"uint8": "MET_UCHAR", "int8": "MET_CHAR", "uint16": "MET_USHORT", "int16": "MET_SHORT",
             "uint32": "MET_UINT", "int32": "MET_INT", "float32": "MET_FLOAT", "float64": "MET_DOUBLE"}
VTK_TYPES = {"uint8": "unsigned_char", "int8": "char", "uint16": "unsigned_short", "int16": "short",
             "uint32": "unsigned_int", "int32": "int", "float32": "float", "float64": "double"}


def _bytes(arr, big):
    return arr.astype(arr.dtype.newbyteorder(">" if big else "<")).tobytes()


def write_raw(path, arr, big=False, header=b""):
    """Samples of ``arr`` ([z, y, x]) after an optional header, x fastest."""
    Path(path).write_bytes(header + _bytes(arr, big))
    return Path(path)


def write_mhd(path, arr, *, spacing=(1, 1, 1), origin=(0, 0, 0), big=False, compressed=False,
              local=None, spacing_key="ElementSpacing", origin_key="Offset", extra=()):
    """A MetaImage header; ``.mha`` (or ``local=True``) attaches the data, else a ``.raw`` beside it."""
    path = Path(path)
    local = path.suffix.lower() == ".mha" if local is None else local
    nz, ny, nx = arr.shape
    payload = _bytes(arr, big)
    if compressed:
        payload = zlib.compress(payload)
    data_name = path.stem + "_data.raw"
    lines = ["ObjectType = Image", "NDims = 3", f"DimSize = {nx} {ny} {nz}",
             f"ElementType = {MET_TYPES[arr.dtype.name]}",
             f"{spacing_key} = " + " ".join(map(str, spacing)),
             f"{origin_key} = " + " ".join(map(str, origin)),
             f"BinaryDataByteOrderMSB = {'True' if big else 'False'}",
             f"CompressedData = {'True' if compressed else 'False'}", *extra,
             f"ElementDataFile = {'LOCAL' if local else data_name}"]
    head = ("\n".join(lines) + "\n").encode()
    if local:
        path.write_bytes(head + payload)
    else:
        path.write_bytes(head)
        (path.parent / data_name).write_bytes(payload)
    return path


def write_vtk(path, arr, *, spacing=(1, 1, 1), origin=(0, 0, 0), ascii=False,
              spacing_key="SPACING", lookup=True, ncomp=None, dataset="STRUCTURED_POINTS"):
    """A VTK legacy STRUCTURED_POINTS file (binary samples big-endian)."""
    nz, ny, nx = arr.shape
    scal = f"SCALARS density {VTK_TYPES[arr.dtype.name]}" + (f" {ncomp}" if ncomp else "")
    head = ["# vtk DataFile Version 3.0", "test volume", "ASCII" if ascii else "BINARY",
            f"DATASET {dataset}", f"DIMENSIONS {nx} {ny} {nz}",
            f"{spacing_key} " + " ".join(map(str, spacing)), "ORIGIN " + " ".join(map(str, origin)),
            f"POINT_DATA {arr.size}", scal]
    if lookup:
        head.append("LOOKUP_TABLE default")
    text = ("\n".join(head) + "\n").encode()
    if ascii:
        body = ("\n".join(" ".join(repr(v.item()) for v in row) for row in arr.reshape(-1, nx)) + "\n").encode()
    else:
        body = _bytes(arr, True) + b"\n"
    Path(path).write_bytes(text + body)
    return Path(path)


def rle_encode(plane: bytes) -> bytes:
    """VolVis run-length code: high bit = literal run, else repeat the next byte; 0 ends."""
    out, i, n = bytearray(), 0, len(plane)
    while i < n:
        j = i
        while j < n and j - i < 127 and plane[j] == plane[i]:
            j += 1
        if j - i >= 3:
            out += bytes((j - i, plane[i]))
            i = j
            continue
        j = i
        while j < n and j - i < 127 and not (j + 2 < n and plane[j] == plane[j + 1] == plane[j + 2]):
            j += 1
        out += bytes((0x80 | (j - i),)) + plane[i:j]
        i = j
    return bytes(out + b"\x00")


def write_slc(path, arr, *, spacing=(1.0, 1.0, 1.0), compression=1, icon=(4, 3)):
    """A VolVis SLC file of uint8 ``arr`` with a small icon."""
    nz, ny, nx = arr.shape
    w, h = icon
    out = bytearray(f"11111\n{nx} {ny} {nz} 8\n{spacing[0]:f} {spacing[1]:f} {spacing[2]:f}\n"
                    f"1 6 0 {compression}\n{w} {h} X".encode())
    out += bytes(range(256))[: 3 * w * h].ljust(3 * w * h, b"\x07")
    for k in range(nz):
        plane = arr[k].tobytes()
        if compression:
            code = rle_encode(plane)
            out += f"{len(code)} X".encode() + code
        else:
            out += plane
    Path(path).write_bytes(bytes(out))
    return Path(path)


@pytest.fixture
def writers():
    """The independent test writers, as ``writers.raw``, ``.mhd``, ``.vtk``, ``.slc``."""
    return SimpleNamespace(raw=write_raw, mhd=write_mhd, vtk=write_vtk, slc=write_slc, rle=rle_encode)


@pytest.fixture
def data_dir():
    """``../shared/data`` beside the checkout; skips the test when it is absent."""
    if not DATA_DIR.is_dir():
        pytest.skip(f"real data folder {DATA_DIR} not present")
    return DATA_DIR


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
