"""MetaImage volumes: ``.mhd`` with a detached data file, ``.mha`` with the data attached."""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..volume import Volume
from ._common import (check_inflatable, file_volume, data_file_block, decompress, no_extra_values, parse_dims,
                      parse_numbers, read_samples, reading, several_data_files, text_values, to_native)

EXTENSIONS = (".mhd", ".mha")

#: The sample types written, and read.
ELEMENT_TYPES = {
    "MET_UCHAR": "uint8", "MET_CHAR": "int8", "MET_USHORT": "uint16", "MET_SHORT": "int16",
    "MET_UINT": "uint32", "MET_INT": "int32", "MET_FLOAT": "float32", "MET_DOUBLE": "float64",
}
#: Read as well, at MetaIO's sizes (a LONG is 4 bytes on every system): ITK writes an image of
#: ``long`` as LONG_LONG on Linux, LONG on Windows. 64-bit samples are narrowed as a Volume takes them.
_READ_TYPES = {**ELEMENT_TYPES, "MET_LONG": "int32", "MET_ULONG": "uint32",
               "MET_LONG_LONG": "int64", "MET_ULONG_LONG": "uint64"}
#: Bytes no text line holds: a header line with one is the data, or no header.
_CONTROL = re.compile(rb"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")
#: Headers are read up to this many bytes (as NRRD's), comments and all.
_MAX_HEADER = 1 << 26

#: The keys this reader reads. One given twice is refused: MetaIO keeps the last without a word,
#: and a header with two DimSize lines states two shapes. Keys are case-sensitive, as MetaIO
#: compares them (``dimsize`` is no DimSize to either). Others (Comment, a writer's own
#: metadata) may repeat: they change nothing read.
_KEYS_READ = frozenset((
    "NDims", "DimSize", "ElementType", "ElementNumberOfChannels", "ElementSpacing", "ElementSize", "Origin",
    "Offset", "Position", "BinaryDataByteOrderMSB", "ElementByteOrderMSB", "CompressedData", "HeaderSize",
    "TransformMatrix", "Rotation", "Orientation", "BinaryData", "ElementDataFile"))


def _first(fields, keys):
    """The first of ``keys`` the header gives, or None: MetaIO reads some fields under several
    names, one winning over the others."""
    return next((k for k in keys if k in fields), None)


def _flag(path, fields, keys, default: bool) -> bool:
    """A True/False field (the first of ``keys`` present), read as MetaIO reads it: true when
    its first letter is T, t or 1, false when F, f or 0. Anything else is refused: MetaIO
    would take ``Maybe`` or ``yes`` for false, whatever the writer meant."""
    key = _first(fields, keys)
    if key is None:
        return default
    value = fields[key].strip()
    if value[:1] in ("T", "t", "1"):
        return True
    if value[:1] in ("F", "f", "0"):
        return False
    raise InputError(f"{path}: {key} must be True or False, got {value!r}")


def _numbers(path, fields, keys, default, axes):
    """Three numbers from the first of ``keys`` present (an error names that one), else ``default``;
    more than the header's ``axes`` refused (`no_extra_values`)."""
    key = _first(fields, keys)
    if key is None:
        return default
    words = fields[key].split()
    no_extra_values(words, axes, path, key)
    return parse_numbers(words, 3, float, path, key)


def _parse_header(path: Path):
    """Key/value pairs up to ElementDataFile, and the byte offset just after that line."""
    fields, pos = {}, 0
    with open(path, "rb") as f:
        while True:
            # Read line by line: a comment may run long, and the header's end is not known before.
            raw = f.readline(_MAX_HEADER - pos + 1)
            first = pos == 0
            pos += len(raw)
            if pos > _MAX_HEADER:
                raise InputError(f"{path}: no ElementDataFile line in the MetaImage header's first "
                                 f"{_MAX_HEADER >> 20} MiB")
            if not raw:
                raise InputError(f"{path}: MetaImage header has no ElementDataFile line")
            if first and raw.startswith(b"\xef\xbb\xbf"):
                raw = raw[3:]   # a UTF-8 byte-order mark, as some editors write: not part of the first key
            if _CONTROL.search(raw):
                raise InputError(f"{path}: not a MetaImage header (binary bytes before ElementDataFile)")
            # Values are text in any language (ITK writes them as given: a comment, a name, the data
            # file's); bytes not in UTF-8 stay as they are, so a data file's name still finds its file.
            line = raw.decode("utf-8", "surrogateescape").strip()
            if line and not line.startswith("#"):
                key, eq, value = (part.strip() for part in line.partition("="))
                if not eq:
                    raise InputError(f"{path}: not a MetaImage header: expected 'Key = Value', got {line[:60]!r}")
                if key in fields and key in _KEYS_READ:
                    raise InputError(f"{path}: MetaImage key {key} is given twice "
                                     f"({fields[key][:40]!r}, then {value[:40]!r})")
                fields[key] = value
                # The data file entry ends the header; binary data may follow (LOCAL).
                if key == "ElementDataFile":
                    return fields, pos
                if key.lower() == "elementdatafile":
                    # Read on, the data that follows it was taken for header lines.
                    raise InputError(f"{path}: MetaImage keys are case-sensitive: write {key!r} "
                                     "as 'ElementDataFile'")


def read_metaimage(path, *, spacing=None, origin=None) -> Volume:
    """Read a 3-D scalar MetaImage volume.

    Handles ``DimSize``, ``ElementType`` (MET_UCHAR ... MET_ULONG_LONG, MET_FLOAT, MET_DOUBLE),
    ``ElementSpacing`` (or ``ElementSize``), ``Offset``/``Origin``/``Position``,
    ``BinaryDataByteOrderMSB``/``ElementByteOrderMSB``, ``HeaderSize``,
    zlib ``CompressedData`` and text samples (``BinaryData = False``).
    The data file is ``LOCAL`` (attached) or a path relative to the header,
    or several of them (``LIST`` or a numbered name, `several_data_files`).

    Parameters
    ----------
    path : str or Path
    spacing, origin : (x, y, z), optional
        Replace the file's, before the Volume checks them (`data_tools.io._common.file_volume`).

    Returns
    -------
    Volume
    """
    given = {"spacing": spacing, "origin": origin}     # the names are the file's own below
    path = Path(path)
    with reading(path, "MetaImage"):
        fields, data_start = _parse_header(path)
        return _build(path, fields, data_start, given)


def _build(path, fields, data_start, given):
    def get(*keys):
        key = _first(fields, keys)
        return None if key is None else fields[key]

    ndims = get("NDims")
    if ndims is None or get("DimSize") is None or get("ElementType") is None:
        raise InputError(f"{path}: MetaImage header lacks NDims, DimSize or ElementType")
    # A fourth axis of length 1 (one time step, as ITK writes a series of one) is the volume itself.
    # Integers as MetaIO reads them: "03" is 3; "1_0" (which Python would take for 10) is refused.
    no_extra_values(ndims.split(), 1, path, "NDims", "where one is expected")
    ndims = parse_numbers(ndims.split(), 1, int, path, "NDims")[0]
    sizes = get("DimSize").split()
    if ndims == 4 and len(sizes) == 4 and parse_numbers(sizes[3:], 1, int, path, "DimSize")[0] == 1:
        ndims = 3
        axes = 4                                        # the file's: TransformMatrix is 4x4, its top left ours
    else:
        axes = 3
    if ndims != 3:
        raise InputError(f"{path}: MetaImage has NDims = {ndims}, expected a 3-D volume")
    # Per-axis keys hold a value an axis of the file (four with a fourth axis of one); fewer than
    # three are refused as they are parsed.
    no_extra_values(sizes, axes, path, "DimSize")
    dims = parse_dims(sizes, path, "DimSize")
    etype = get("ElementType").upper()
    if etype not in _READ_TYPES:
        raise InputError(f"{path}: unsupported ElementType {etype} (supported: {', '.join(_READ_TYPES)})")
    dtype = _READ_TYPES[etype]
    channels = get("ElementNumberOfChannels")
    if channels is not None and channels.strip() != "1":
        raise InputError(f"{path}: {channels} channels per sample; only scalar volumes are supported")
    spacing = _numbers(path, fields, ("ElementSpacing", "ElementSize"), (1.0, 1.0, 1.0), axes)
    # MetaIO sets the origin from Position, then Offset, then Origin, each overwriting the one
    # before, wherever they stand in the header.
    origin = _numbers(path, fields, ("Origin", "Offset", "Position"), (0.0, 0.0, 0.0), axes)
    big = _flag(path, fields, ("BinaryDataByteOrderMSB", "ElementByteOrderMSB"), False)
    compressed = _flag(path, fields, ("CompressedData",), False)
    header_size = (get("HeaderSize") or "").split()           # given empty, as absent: 0
    no_extra_values(header_size, 1, path, "HeaderSize", "where one is expected")
    header_size = parse_numbers(header_size, 1, int, path, "HeaderSize")[0] if header_size else 0
    if header_size < -1:
        raise InputError(f"{path}: HeaderSize must be -1 (data at the end) or a byte count, got {header_size}")
    meta = {"format": "metaimage", "byte_order": "big" if big else "little"}
    key = _first(fields, ("TransformMatrix", "Rotation", "Orientation"))
    if key is not None and fields[key]:
        words = fields[key].split()
        no_extra_values(words, axes * axes, path, key, f"for a {axes}x{axes} matrix")
        m = np.asarray(parse_numbers(words, axes * axes, float, path, key))
        m = m.reshape(axes, axes)[:3, :3]
        if np.abs(m - np.eye(3)).max() > 1e-6:
            meta["note"] = "non-identity TransformMatrix ignored: the volume is read on an axis-aligned grid"
            meta["reoriented"] = True

    data_name = get("ElementDataFile").strip()
    if not data_name:
        raise InputError(f"{path}: ElementDataFile is empty; give LOCAL or a data file name")
    text = not _flag(path, fields, ("BinaryData",), True)
    if text and compressed:
        raise InputError(f"{path}: CompressedData with text samples (BinaryData = False) is not supported")
    if header_size == -1 and (text or compressed):
        raise InputError(f"{path}: HeaderSize -1 (the samples end the file) applies to raw binary samples only, "
                         f"not {'text' if text else 'compressed'} ones")
    nx, ny, nz = dims
    if compressed:
        check_inflatable(path, dims, dtype)
    files = several_data_files(path, "ElementDataFile", data_name, lambda: _lines_after(path, data_start), len(dims))
    if files is not None:
        paths, subdim = files
        block = data_file_block(path, paths, subdim, dims, "DimSize's")
        meta["data_files"] = tuple(str(p) for p in paths)
        parts = []
        for number, data_path in enumerate(paths, 1):
            _check_data_file(path, data_path, f"data file {number} of {len(paths)}")
            parts.append(_samples(data_path, 0, header_size, (block, 1, 1), dtype, big, text, compressed, True))
        data = np.concatenate(parts).reshape(nz, ny, nx)
        return file_volume(data, spacing, origin, path, meta, given)
    if data_name.upper() == "LOCAL":
        data_path, offset = path, data_start
        if header_size > 0:
            # MetaIO skips HeaderSize bytes from the start of the data file, here this file,
            # its header included (ITK reads such .mha files so).
            if header_size < data_start:
                raise InputError(f"{path}: HeaderSize {header_size} ends inside the header ({data_start} bytes); "
                                 "with LOCAL data it counts from the file's start")
            offset, header_size = header_size, 0
    else:
        data_path = Path(data_name)
        if not data_path.is_absolute():
            data_path = path.parent / data_path
        _check_data_file(path, data_path, "data file")
        if os.path.realpath(data_path) == os.path.realpath(path):
            raise InputError(f"{path}: ElementDataFile names this header itself; write LOCAL for attached data")
        meta["data_file"] = str(data_path)
        offset = 0
    data = _samples(data_path, offset, header_size, dims, dtype, big, text, compressed, data_path != path)
    return file_volume(data.reshape(nz, ny, nx), spacing, origin, path, meta, given)


def _lines_after(path, start):
    """The lines of ``path`` from byte ``start`` on (the names of an ElementDataFile LIST)."""
    with open(path, "rb") as f:
        f.seek(start)
        return [n.decode("utf-8", "replace") for n in f.read().splitlines()]


def _check_data_file(path, data_path, what):
    if not data_path.exists():
        raise InputError(f"{path}: {what} {data_path} (ElementDataFile) not found")
    if not data_path.is_file():
        raise InputError(f"{path}: {what} {data_path} (ElementDataFile) is not a regular file")


def _samples(data_path, offset, header_size, dims, dtype, big, text, compressed, exact):
    """The ``nx*ny*nz`` samples of one data file, flat: text, compressed or raw, from byte
    ``offset`` past ``header_size`` more (-1: raw samples end the file)."""
    count = int(np.prod(dims, dtype=np.int64))
    if text or compressed:
        with open(data_path, "rb") as f:
            f.seek(offset + max(header_size, 0))
            blob = f.read()
    if text:
        return _text_samples(blob, count, dtype, data_path)
    itemsize = np.dtype(dtype).itemsize
    if compressed:
        raw = decompress(blob, count * itemsize, data_path, "MetaImage")
        dt = np.dtype(dtype).newbyteorder(">" if big else "<") if itemsize > 1 else np.dtype(dtype)
        return to_native(np.frombuffer(raw, dtype=dt).copy())
    if header_size == -1:
        # -1: the data are the last bytes of the file, whatever precedes them.
        offset = max(data_path.stat().st_size - count * itemsize, 0)
    else:
        offset += max(header_size, 0)
    return read_samples(data_path, offset, dims, dtype, big, exact=exact, kind="MetaImage").ravel()


def _text_samples(blob, count, dtype, path):
    """``count`` samples written as text (``BinaryData = False``), in ``dtype``."""
    words = blob.split()
    if len(words) != count:
        raise InputError(f"{path}: {len(words)} text samples, expected {count} (DimSize)")
    return text_values(words, dtype, path, f"the sample type {np.dtype(dtype).name}")


def write_metaimage(volume: Volume, path, *, byte_order: str = "little") -> Path:
    """Write ``.mha`` (data attached) or ``.mhd`` plus a ``.raw`` beside it."""
    path = Path(path)
    etype = {v: k for k, v in ELEMENT_TYPES.items()}[volume.dtype.name]
    big = byte_order == "big"
    local = path.suffix.lower() == ".mha"
    data_file = path.with_suffix(".raw")
    lines = [
        "ObjectType = Image", "NDims = 3", "BinaryData = True",
        f"BinaryDataByteOrderMSB = {'True' if big else 'False'}", "CompressedData = False",
        "Offset = " + " ".join(repr(v) for v in volume.origin),
        "ElementSpacing = " + " ".join(repr(v) for v in volume.spacing),
        "DimSize = " + " ".join(str(n) for n in volume.dims),
        f"ElementType = {etype}",
        f"ElementDataFile = {'LOCAL' if local else data_file.name}",
    ]
    samples = volume.data.astype(volume.dtype.newbyteorder(">" if big else "<"), copy=False)
    with open(path, "wb") as f:
        f.write(("\n".join(lines) + "\n").encode("ascii"))
        if local:
            samples.tofile(f)
    if not local:
        samples.tofile(data_file)
    return path
