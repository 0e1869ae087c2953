"""VTK legacy ``.vtk`` files holding STRUCTURED_POINTS scalars (binary or ASCII)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ..volume import Volume
from ._common import parse_dims, parse_numbers, read_samples, reading

EXTENSIONS = (".vtk",)

VTK_TYPES = {
    "unsigned_char": "uint8", "char": "int8", "signed_char": "int8", "unsigned_short": "uint16",
    "short": "int16",
    "unsigned_int": "uint32", "int": "int32", "float": "float32", "double": "float64",
    "vtktypeuint8": "uint8", "vtktypeint8": "int8", "vtktypeuint16": "uint16",
    "vtktypeint16": "int16", "vtktypeuint32": "uint32", "vtktypeint32": "int32",
    "vtktypefloat32": "float32", "vtktypefloat64": "float64",
}
# Alternative names this module reads but does not write ("char" is the one every reader knows).
_READ_ONLY_TYPES = ("signed_char",)
_MAX_HEADER_LINES = 200


class _Lines:
    """Reads newline-terminated ASCII header lines from a binary file, keeping the offset."""

    def __init__(self, f, path):
        self.f, self.path = f, path

    def next(self, what):
        while True:
            raw = self.f.readline(4096)
            if not raw:
                raise InputError(f"{self.path}: VTK header ends before {what}")
            try:
                line = raw.decode("ascii").strip()
            except UnicodeDecodeError:
                raise InputError(f"{self.path}: binary bytes in the VTK header where {what} was expected") from None
            if line:
                return line


def _skip_lookup_table(f) -> bool:
    """Move past a LOOKUP_TABLE line, blank lines allowed before it; False if there is none."""
    for _ in range(_MAX_HEADER_LINES):
        line = f.readline(4096).strip()
        if line:
            return line.upper().startswith(b"LOOKUP_TABLE")
    return False


def read_vtk(path) -> Volume:
    """Read a VTK legacy STRUCTURED_POINTS volume of point scalars.

    ``COLOR_SCALARS`` with one component (how VTK itself writes uint8 data)
    are read as uint8.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    Volume

    Raises
    ------
    InputError
        Not a VTK legacy file, another dataset kind, vector or multi-component
        data, an unknown type, or too few samples.
    """
    path = Path(path)
    with reading(path, "VTK"):
        with open(path, "rb") as f:
            first = f.readline(256)
            if not first.lower().startswith(b"# vtk datafile"):
                raise InputError(f"{path}: not a VTK legacy file (no '# vtk DataFile' first line)")
            f.readline(4096)  # title: free text, may be anything
            lines = _Lines(f, path)
            encoding = lines.next("ASCII or BINARY").upper()
            if encoding not in ("ASCII", "BINARY"):
                raise InputError(f"{path}: expected ASCII or BINARY on line 3, got {encoding[:40]!r}")
            words = lines.next("DATASET").split()
            if words[0].upper() != "DATASET" or len(words) < 2:
                raise InputError(f"{path}: expected a DATASET line, got {' '.join(words)[:60]!r}")
            if words[1].upper() != "STRUCTURED_POINTS":
                raise InputError(f"{path}: VTK dataset {words[1]} is not supported; only STRUCTURED_POINTS volumes")
            dims = spacing = None
            origin = (0.0, 0.0, 0.0)
            for _ in range(_MAX_HEADER_LINES):
                words = lines.next("POINT_DATA").split()
                key = words[0].upper()
                if key == "DIMENSIONS":
                    dims = parse_dims(words[1:], path, "DIMENSIONS")
                elif key in ("SPACING", "ASPECT_RATIO"):
                    spacing = parse_numbers(words[1:], 3, float, path, key)
                elif key == "ORIGIN":
                    origin = parse_numbers(words[1:], 3, float, path, key)
                elif key == "POINT_DATA":
                    break
                elif key == "CELL_DATA":
                    raise InputError(f"{path}: CELL_DATA is not supported; a volume needs POINT_DATA scalars")
                elif key != "FIELD" and not key.startswith("#"):
                    raise InputError(f"{path}: unexpected VTK header line {' '.join(words)[:60]!r}")
            else:
                raise InputError(f"{path}: no POINT_DATA in the VTK header")
            if dims is None:
                raise InputError(f"{path}: VTK header has no DIMENSIONS")
            npoints = parse_numbers(words[1:], 1, int, path, "POINT_DATA")[0]
            if npoints != dims[0] * dims[1] * dims[2]:
                raise InputError(f"{path}: POINT_DATA {npoints} does not match DIMENSIONS {dims[0]}x{dims[1]}x{dims[2]}")
            words = lines.next("SCALARS").split()
            color = words[0].upper() == "COLOR_SCALARS"
            if color:
                # vtkDataWriter stores unsigned_char scalars this way, with no LOOKUP_TABLE line.
                ncomp = parse_numbers(words[2:], 1, int, path, "COLOR_SCALARS")[0]
                if ncomp != 1:
                    raise InputError(f"{path}: COLOR_SCALARS with {ncomp} components; only one per sample is supported")
                dtype = "uint8"
            else:
                if words[0].upper() != "SCALARS" or len(words) < 3:
                    raise InputError(f"{path}: expected SCALARS name type after POINT_DATA, "
                                     f"got {' '.join(words)[:60]!r}")
                vtype = words[2].lower()
                if vtype not in VTK_TYPES:
                    raise InputError(f"{path}: unsupported VTK scalar type {words[2]}")
                if len(words) > 3 and words[3] != "1":
                    raise InputError(f"{path}: scalars with {words[3]} components; only one per sample is supported")
                dtype = VTK_TYPES[vtype]
                pos = f.tell()
                if not _skip_lookup_table(f):
                    # LOOKUP_TABLE is optional; the data start right after SCALARS, even
                    # where their first bytes look like blank lines.
                    f.seek(pos)
            offset = f.tell()
            if encoding == "ASCII" and color:
                data = _read_ascii_colors(f, dims, path)
            elif encoding == "ASCII":
                data = _read_ascii(f, dims, dtype, path)
        if encoding == "BINARY":
            # Legacy binary VTK is big-endian by definition; trailing sections are ignored.
            data = read_samples(path, offset, dims, dtype, True, exact=False, kind="VTK")
    meta = {"format": "vtk", "scalars": words[1]}
    return Volume(data, spacing=spacing or (1.0, 1.0, 1.0), origin=origin, name=str(path), meta=meta)


def _read_ascii(f, dims, dtype, path):
    count = dims[0] * dims[1] * dims[2]
    tokens = f.read().split()
    if len(tokens) < count:
        raise InputError(f"{path}: ASCII VTK data truncated: {count} samples needed, found {len(tokens)}")
    dt = np.dtype(dtype)
    try:
        values = np.array(tokens[:count]).astype(np.float64 if dt.kind == "f" else np.int64)
    except ValueError:
        raise InputError(f"{path}: ASCII VTK data holds a value that is not a {dt.name} number") from None
    if dt.kind in "iu":
        info = np.iinfo(dt)
        if values.min() < info.min or values.max() > info.max:
            raise InputError(f"{path}: ASCII VTK values outside the {dt.name} range")
    return values.astype(dt).reshape(dims[2], dims[1], dims[0])


def _read_ascii_colors(f, dims, path):
    # VTK writes uint8 COLOR_SCALARS in ASCII as value/255 (6 digits) and its reader
    # scales them back the same way; so do we: it restores the exact bytes, and the
    # ASCII and BINARY forms of one volume give the same uint8 data.
    values = _read_ascii(f, dims, "float64", path)
    if not (values.min() >= 0 and values.max() <= 1):  # NaN fails here too
        raise InputError(f"{path}: ASCII VTK COLOR_SCALARS values outside [0, 1]")
    return np.floor(values * 255 + 0.5).astype(np.uint8)


def write_vtk(volume: Volume, path, *, ascii: bool = False) -> Path:
    """Write a VTK legacy STRUCTURED_POINTS file (big-endian binary, or ASCII)."""
    path = Path(path)
    vtype = {v: k for k, v in VTK_TYPES.items()
             if not k.startswith("vtktype") and k not in _READ_ONLY_TYPES}[volume.dtype.name]
    nx, ny, nz = volume.dims
    # The title is one ASCII line of at most 256 characters; a volume's name may be neither.
    title = "".join(c if " " <= c <= "~" else "?" for c in Path(volume.name).name)[:255] or "volume"
    header = (
        "# vtk DataFile Version 3.0\n"
        f"{title}\n"
        f"{'ASCII' if ascii else 'BINARY'}\n"
        "DATASET STRUCTURED_POINTS\n"
        f"DIMENSIONS {nx} {ny} {nz}\n"
        "SPACING " + " ".join(repr(v) for v in volume.spacing) + "\n"
        "ORIGIN " + " ".join(repr(v) for v in volume.origin) + "\n"
        f"POINT_DATA {nx * ny * nz}\n"
        f"SCALARS scalars {vtype} 1\n"
        "LOOKUP_TABLE default\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        if ascii:
            fmt = "%.17g" if volume.dtype.kind == "f" else "%d"
            np.savetxt(f, volume.data.reshape(-1, nx), fmt=fmt)
        else:
            volume.data.astype(volume.dtype.newbyteorder(">"), copy=False).tofile(f)
            f.write(b"\n")
    return path
