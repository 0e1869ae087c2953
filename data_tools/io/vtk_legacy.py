"""VTK legacy ``.vtk`` files holding STRUCTURED_POINTS scalars (binary or ASCII)."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..volume import Volume
from ._common import (file_volume, float32_from_text, no_digit_separators, no_extra_values, parse_dims, parse_numbers,
                      read_samples, reading)

EXTENSIONS = (".vtk",)

VTK_TYPES = {
    "unsigned_char": "uint8", "char": "int8", "signed_char": "int8", "unsigned_short": "uint16",
    "short": "int16",
    "unsigned_int": "uint32", "int": "int32", "float": "float32", "double": "float64",
    "vtktypeuint8": "uint8", "vtktypeint8": "int8", "vtktypeuint16": "uint16",
    "vtktypeint16": "int16", "vtktypeuint32": "uint32", "vtktypeint32": "int32",
    "vtktypefloat32": "float32", "vtktypefloat64": "float64",
    # 64-bit integers: a Volume keeps them as 32-bit ones where every value fits.
    "vtktypeint64": "int64", "vtktypeuint64": "uint64",
    # As vtkDataWriter writes them: C's long of a 64-bit Linux or macOS build, vtkIdType as int.
    "long": "int64", "unsigned_long": "uint64", "vtkidtype": "int32",
}
# Alternative names this module reads but does not write ("char" is the one every reader knows).
_READ_ONLY_TYPES = ("signed_char", "long", "unsigned_long", "vtkidtype")
_MAX_HEADER_LINES = 200


class _Lines:
    """Reads newline-terminated ASCII header lines from a binary file, keeping the offset."""

    def __init__(self, f, path):
        self.f, self.path = f, path

    def next(self, what, required=True):
        """The next line that is not blank; at the end of the file an InputError, or None
        when not ``required``."""
        while True:
            raw = self.f.readline(4096)
            if not raw:
                if not required:
                    return None
                raise InputError(f"{self.path}: VTK header ends before {what}")
            try:
                line = raw.decode("ascii").strip()
            except UnicodeDecodeError:
                raise InputError(f"{self.path}: binary bytes in the VTK header where {what} was expected") from None
            if line:
                return line


#: The keywords that may begin what follows a binary file's samples: another attribute,
#: dataset section or field, or the array's metadata.
_SECTIONS = frozenset(("SCALARS", "COLOR_SCALARS", "LOOKUP_TABLE", "VECTORS", "NORMALS", "TEXTURE_COORDINATES",
                       "TENSORS", "TENSORS6", "FIELD", "POINT_DATA", "CELL_DATA", "METADATA", "INFORMATION",
                       "NAME", "DATA", "GLOBAL_IDS", "PEDIGREE_IDS", "EDGE_FLAGS", "HIGHER_ORDER_DEGREES"))


def _skip_lookup_table(f) -> bool:
    """Move past a LOOKUP_TABLE line, blank lines allowed before it; False if there is none."""
    for _ in range(_MAX_HEADER_LINES):
        line = f.readline(4096).strip()
        if line:
            return line.upper().startswith(b"LOOKUP_TABLE")
    return False


#: Bytes a value of each type takes in a binary section another reader skips.
_SKIP_SIZES = {name: np.dtype(dt).itemsize for name, dt in VTK_TYPES.items()}

#: String arrays: one a line in ASCII, each behind its length in binary (`_skip_strings`).
_STRING_TYPES = ("string", "utf8_string")

#: Attributes a section holds besides scalars, with the values each point or cell has.
_ATTRIBUTE_VALUES = {"VECTORS": 3, "NORMALS": 3, "TENSORS": 9, "TENSORS6": 6, "GLOBAL_IDS": 1,
                     "PEDIGREE_IDS": 1, "EDGE_FLAGS": 1}


def _skip_values(f, encoding, count, vtype, path, what):
    """Move past ``count`` values of VTK type ``vtype``: big-endian bytes, or ASCII words."""
    vtype = vtype.lower()
    if vtype in _STRING_TYPES:
        _skip_strings(f, encoding, count, path, what)
    elif encoding == "ASCII":
        left = count
        while left > 0:
            line = f.readline()
            if not line:
                raise InputError(f"{path}: the file ends inside {what}")
            left -= len(line.split())
        if left < 0:
            raise InputError(f"{path}: {what} holds more values than its header states")
    else:
        if vtype == "bit":
            size = (count + 7) // 8
        elif vtype in _SKIP_SIZES:
            size = count * _SKIP_SIZES[vtype]
        else:
            raise InputError(f"{path}: cannot read past {what} of VTK type {vtype}")
        end = f.tell() + size
        if end > Path(path).stat().st_size:
            raise InputError(f"{path}: the file ends inside {what}")
        f.seek(end)


#: A binary string's length field: its first byte's top two bits give the field's size in bytes.
_LENGTH_BYTES = {3: 1, 2: 2, 1: 4, 0: 8}


def _skip_strings(f, encoding, count, path, what):
    """Move past ``count`` strings as vtkDataWriter writes them: in ASCII one a line (an empty
    string an empty line); in binary each behind its length, a big-endian field whose first
    byte's top bits give its size (`_LENGTH_BYTES`) and the rest the length."""
    size = Path(path).stat().st_size
    for _ in range(count):
        if encoding == "ASCII":
            if not f.readline():
                raise InputError(f"{path}: the file ends inside {what}")
            continue
        head = f.read(1)
        width = _LENGTH_BYTES[head[0] >> 6] if head else 0
        field = head + f.read(width - 1) if head else b""
        end = f.tell() + (int.from_bytes(field, "big") & ((1 << (8 * width - 2)) - 1) if head else 0)
        if not head or len(field) < width or end > size:
            raise InputError(f"{path}: the file ends inside {what}")
        f.seek(end)


def _skip_metadata(f, path, ncomp):
    """Move past a METADATA block (VTK 8 and later) of an array of ``ncomp`` components: its
    COMPONENT_NAMES (a line each, empty for one without a name) and INFORMATION entries, up
    to the blank line that ends it."""
    for _ in range(_MAX_HEADER_LINES):
        line = f.readline(4096)
        if not line:
            raise InputError(f"{path}: the file ends inside a METADATA block")
        word = line.strip().upper()
        if not word:
            return
        if word == b"COMPONENT_NAMES":
            for _ in range(ncomp):
                f.readline(4096)
    raise InputError(f"{path}: a METADATA block without its closing blank line")


def _after_array(f, path, ncomp):
    """Move past the METADATA block that may follow an array's values."""
    pos = f.tell()
    for _ in range(_MAX_HEADER_LINES):
        line = f.readline(4096)
        if not line:
            break
        if line.strip():
            if line.strip().upper() == b"METADATA":
                _skip_metadata(f, path, ncomp)
                return
            break
    f.seek(pos)


def _field_arrays(f, lines, encoding, words, path, want=None):
    """Move past a FIELD's arrays. With ``want`` (a point count), the first array of one
    component and ``want`` numeric values, ``(name, dtype, offset)`` where its values start
    (None when there is none), and the names of every such array."""
    n = parse_numbers(words[2:], 1, int, path, "FIELD")[0]
    found = None
    names = []
    for _ in range(n):
        line = lines.next("a FIELD array")
        parts = line.split()
        if len(parts) == 1 and parts[0].upper() == "NULL_ARRAY":
            continue                # how vtkDataWriter writes an array that is not there
        if len(parts) != 4:
            raise InputError(f"{path}: expected a FIELD array line 'name components tuples type', got {line[:60]!r}")
        ncomp, ntuples = parse_numbers(parts[1:3], 2, int, path, f"FIELD array {parts[0]}")
        vtype = parts[3].lower()
        if want is not None and ncomp == 1 and ntuples == want and vtype in VTK_TYPES:
            names.append(parts[0])
            if found is None:
                found = parts[0], VTK_TYPES[vtype], f.tell()
        _skip_values(f, encoding, ncomp * ntuples, vtype, path, f"FIELD array {parts[0]}")
        _after_array(f, path, ncomp)
    return found, names


def _components(words, path):
    """``(ncomp, table_here)`` of a SCALARS or COLOR_SCALARS line, read as VTK's reader reads
    it, word by word: the component count as C's ``atoi`` takes it (``01``, ``+1`` and ``1.0``
    are 1; absent from SCALARS, 1), and whether the SCALARS line holds its LOOKUP_TABLE too."""
    key = words[0].upper()
    at = 3 if key == "SCALARS" else 2
    if key == "SCALARS" and (len(words) <= 3 or words[3].upper() == "LOOKUP_TABLE"):
        return 1, len(words) > 3
    m = re.match(r"[+-]?\d+", words[at]) if len(words) > at else None
    if m is None:
        raise InputError(f"{path}: expected the number of components on the {key} line, "
                         f"got {' '.join(words)[:60]!r}")
    return int(m.group()), key == "SCALARS" and len(words) > 4 and words[4].upper() == "LOOKUP_TABLE"


def _skip_attribute(f, lines, encoding, words, count, path, section):
    """Move past one attribute of a POINT_DATA or CELL_DATA section of ``count`` points or cells."""
    key = words[0].upper()
    what = f"{section} {key}"
    ncomp = 1
    if key == "SCALARS":
        if len(words) < 3:
            raise InputError(f"{path}: expected SCALARS name type, got {' '.join(words)[:60]!r}")
        ncomp, table_here = _components(words, path)
        pos = f.tell()
        if not table_here and not _skip_lookup_table(f):
            f.seek(pos)
        _skip_values(f, encoding, count * ncomp, words[2], path, what)
    elif key == "COLOR_SCALARS":
        ncomp = _components(words, path)[0]
        _skip_values(f, encoding, count * ncomp, "float" if encoding == "ASCII" else "unsigned_char", path, what)
    elif key == "LOOKUP_TABLE":
        size = parse_numbers(words[2:3], 1, int, path, "LOOKUP_TABLE")[0]
        _skip_values(f, encoding, 4 * size, "float" if encoding == "ASCII" else "unsigned_char", path, what)
    elif key == "TEXTURE_COORDINATES":
        ncomp = parse_numbers(words[2:3], 1, int, path, "TEXTURE_COORDINATES")[0]
        _skip_values(f, encoding, count * ncomp, words[3] if len(words) > 3 else "?", path, what)
    elif key in _ATTRIBUTE_VALUES:
        ncomp = _ATTRIBUTE_VALUES[key]
        _skip_values(f, encoding, count * ncomp, words[2] if len(words) > 2 else "?", path, what)
    elif key == "FIELD":
        _field_arrays(f, lines, encoding, words, path)
        return
    else:
        raise InputError(f"{path}: unexpected line in the VTK {section}: {' '.join(words)[:60]!r}")
    _after_array(f, path, ncomp)


def _past_cell_data(f, lines, encoding, ncells, path):
    """Move past a CELL_DATA section's attributes; the words of the POINT_DATA line after them."""
    for _ in range(_MAX_HEADER_LINES):
        line = lines.next("POINT_DATA", required=False)
        if line is None:
            raise InputError(f"{path}: the VTK file has CELL_DATA and no POINT_DATA; a volume needs "
                             "scalars on its points")
        words = line.split()
        if words[0].upper() == "POINT_DATA":
            return words
        _skip_attribute(f, lines, encoding, words, ncells, path, "CELL_DATA")
    raise InputError(f"{path}: no POINT_DATA after the VTK CELL_DATA")


def read_vtk(path, *, spacing=None, origin=None) -> Volume:
    """Read a VTK legacy STRUCTURED_POINTS volume of point scalars.

    ``COLOR_SCALARS`` with one component (how VTK itself writes uint8 data)
    are read as uint8. What vtkDataWriter writes beside the scalars is read
    past: the dataset's own FIELD data (a time value), the cells' arrays
    (CELL_DATA, which it writes first), point attributes before the scalars
    (VECTORS, NORMALS...) and METADATA blocks. Points whose arrays were all
    written as FIELD data (none marked as the scalars) give the first of
    one component.

    Parameters
    ----------
    path : str or Path
    spacing, origin : (x, y, z), optional
        Replace the file's, before the Volume checks them (`data_tools.io._common.file_volume`).

    Returns
    -------
    Volume

    Raises
    ------
    InputError
        Not a VTK legacy file, another dataset kind, no point data, vector or
        multi-component data, an unknown type, or too few samples.
    """
    given = {"spacing": spacing, "origin": origin}     # the names are the file's own below
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
            given_as = {}           # each geometry line as first written: a second is refused
            for _ in range(_MAX_HEADER_LINES):
                words = lines.next("POINT_DATA").split()
                key = words[0].upper()
                if key in ("DIMENSIONS", "SPACING", "ASPECT_RATIO", "ORIGIN"):
                    # VTK's reader keeps the last of two such lines, and reads a fourth number as the
                    # next keyword: such a header states two grids, or a fourth axis, for one volume.
                    same = "SPACING" if key == "ASPECT_RATIO" else key
                    if same in given_as:
                        twice = f"{key} twice" if given_as[same] == key else f"both {given_as[same]} and {key}"
                        raise InputError(f"{path}: VTK header gives {twice} (the second: {' '.join(words)[:60]!r})")
                    given_as[same] = key
                    no_extra_values(words[1:], 3, path, key)
                if key == "DIMENSIONS":
                    dims = parse_dims(words[1:], path, "DIMENSIONS")
                elif key in ("SPACING", "ASPECT_RATIO"):
                    spacing = parse_numbers(words[1:], 3, float, path, key)
                elif key == "ORIGIN":
                    origin = parse_numbers(words[1:], 3, float, path, key)
                elif key == "POINT_DATA":
                    break
                elif key == "CELL_DATA":
                    # vtkDataWriter writes the cells' arrays first (ParaView's vtkGhostType, say):
                    # read past them to the points'.
                    ncells = parse_numbers(words[1:], 1, int, path, "CELL_DATA")[0]
                    words = _past_cell_data(f, lines, encoding, ncells, path)
                    break
                elif key == "FIELD":
                    _field_arrays(f, lines, encoding, words, path)     # the dataset's own (a time value)
                elif not key.startswith("#"):
                    raise InputError(f"{path}: unexpected VTK header line {' '.join(words)[:60]!r}")
            else:
                raise InputError(f"{path}: no POINT_DATA in the VTK header")
            if dims is None:
                raise InputError(f"{path}: VTK header has no DIMENSIONS")
            npoints = parse_numbers(words[1:], 1, int, path, "POINT_DATA")[0]
            if npoints != dims[0] * dims[1] * dims[2]:
                raise InputError(f"{path}: POINT_DATA {npoints} does not match DIMENSIONS {dims[0]}x{dims[1]}x{dims[2]}")
            # The scalars, past the attributes before them; else the first array of one
            # component written as field data (none marked as the scalars).
            field = key = None
            field_names = []            # every array of field data the scalars could be
            for _ in range(_MAX_HEADER_LINES):
                line = lines.next("SCALARS", required=field is None)
                words = line.split() if line is not None else []
                key = words[0].upper() if words else None
                if key in ("SCALARS", "COLOR_SCALARS"):
                    break
                if key is None or key in ("CELL_DATA", "POINT_DATA"):
                    if field is None:
                        raise InputError(f"{path}: no scalars in the VTK POINT_DATA")
                    break
                if key == "FIELD":
                    found, names = _field_arrays(f, lines, encoding, words, path, want=npoints)
                    field = field or found
                    field_names += names
                    continue
                _skip_attribute(f, lines, encoding, words, npoints, path, "POINT_DATA")
            else:
                raise InputError(f"{path}: no scalars in the VTK POINT_DATA")
            if key not in ("SCALARS", "COLOR_SCALARS"):
                f.seek(field[2])
            else:
                field = None
            color = field is None and key == "COLOR_SCALARS"
            if field is not None:
                words = ["FIELD", field[0]]
                dtype = field[1]
            elif color:
                # vtkDataWriter stores unsigned_char scalars this way, with no LOOKUP_TABLE line.
                ncomp = _components(words, path)[0]
                if ncomp != 1:
                    raise InputError(f"{path}: COLOR_SCALARS with {ncomp} components; only one per sample is supported")
                dtype = "uint8"
            else:
                if len(words) < 3:
                    raise InputError(f"{path}: expected SCALARS name type after POINT_DATA, "
                                     f"got {' '.join(words)[:60]!r}")
                vtype = words[2].lower()
                if vtype not in VTK_TYPES:
                    raise InputError(f"{path}: unsupported VTK scalar type {words[2]}")
                ncomp, table_here = _components(words, path)
                if ncomp != 1:
                    raise InputError(f"{path}: scalars with {ncomp} components; only one per sample is supported")
                dtype = VTK_TYPES[vtype]
                pos = f.tell()
                if not table_here and not _skip_lookup_table(f):
                    # LOOKUP_TABLE is optional; the data start right after SCALARS, even
                    # where their first bytes look like blank lines.
                    f.seek(pos)
            offset = f.tell()
            others = field_names[1:] if field is not None else []
            if field is None and encoding == "BINARY":
                others = _later_scalars(f, lines, npoints, "unsigned_char" if color else words[2], path)
                f.seek(offset)
            rest = []
            if encoding == "ASCII" and color:
                data = _read_ascii_colors(f, dims, path, rest)
            elif encoding == "ASCII":
                data = _read_ascii(f, dims, dtype, path, rest)
            if field is None and rest and rest[0].decode("ascii", "replace").upper() not in _SECTIONS:
                # As after binary samples (`check_tail`): values left over mean the header states
                # fewer samples than were written, and every row was read shifted.
                raise InputError(f"{path}: {len(rest)} words after the ASCII VTK samples the header states, "
                                 "and they do not begin a further section: the header does not match the data "
                                 "(corrupt?)")
            if field is None and rest:
                # The words after the samples, read with them: a SCALARS word is no number.
                others = [rest[n + 1].decode("ascii", "replace") for n in range(len(rest) - 1)
                          if rest[n].upper() in (b"SCALARS", b"COLOR_SCALARS")]
        if encoding == "BINARY":
            # Legacy binary VTK is big-endian by definition. Further sections may follow the
            # samples; a field's next array begins with its own name, whatever it is.
            data = read_samples(path, offset, dims, dtype, True, exact=False,
                                follows=_SECTIONS if field is None else None, kind="VTK")
    meta = {"format": "vtk", "scalars": words[1]}
    if others:
        meta["note"] = (f"the points carry {len(others) + 1} scalar arrays ({', '.join([words[1]] + others)}); "
                        f"the first was read ({words[1]})")
    return file_volume(data, spacing or (1.0, 1.0, 1.0), origin, path, meta, given)


def _later_scalars(f, lines, npoints, vtype, path):
    """The names of the point scalars of a binary file after the ones read, which start at
    ``f``'s position (an ASCII file's are among the words `_read_ascii` reads past its samples).

    Only a note depends on them: a file whose rest cannot be read past gives none.
    """
    names = []
    try:
        _skip_values(f, "BINARY", npoints, vtype, path, "the scalars")
        _after_array(f, path, 1)
        for _ in range(_MAX_HEADER_LINES):
            line = lines.next("", required=False)
            words = line.split() if line is not None else []
            if not words or words[0].upper() in ("CELL_DATA", "POINT_DATA"):
                break
            if words[0].upper() in ("SCALARS", "COLOR_SCALARS") and len(words) > 1:
                names.append(words[1])
            _skip_attribute(f, lines, "BINARY", words, npoints, path, "POINT_DATA")
    except InputError:
        return names                # the names before what could not be read past
    return names


def _read_ascii(f, dims, dtype, path, rest=None):
    """The samples as text words; ``rest`` (a list) is given the words after them."""
    count = dims[0] * dims[1] * dims[2]
    tokens = f.read().split()
    if rest is not None:
        rest.extend(tokens[count:])
    if len(tokens) < count:
        raise InputError(f"{path}: ASCII VTK data truncated: {count} samples needed, found {len(tokens)}")
    no_digit_separators(tokens[:count], path, "the ASCII VTK data")
    dt = np.dtype(dtype)
    try:
        values = np.array(tokens[:count]).astype(np.float64 if dt.kind == "f" else np.int64)
    except ValueError:
        raise InputError(f"{path}: ASCII VTK data holds a value that is not a {dt.name} number") from None
    except OverflowError:
        raise InputError(f"{path}: ASCII VTK data holds integers of 2**63 or more; samples must fit in 32 bits") from None
    info = np.iinfo(dt) if dt.kind in "iu" else np.finfo(dt)
    if dt == np.float32:
        # Text past float32's largest value by less than half a step (its shortest form,
        # 3.4028235e+38) rounds to it, as strtof rounds it; only what rounds to infinity is out.
        single = float32_from_text(tokens[:count], values)
        if (np.isinf(single) & (np.abs(values) > info.max)).any():
            raise InputError(f"{path}: ASCII VTK values outside the {dt.name} range")
        return single.reshape(dims[2], dims[1], dims[0])
    if values.min() < info.min or values.max() > info.max:
        raise InputError(f"{path}: ASCII VTK values outside the {dt.name} range")
    return values.astype(dt).reshape(dims[2], dims[1], dims[0])


def _read_ascii_colors(f, dims, path, rest=None):
    # VTK writes uint8 COLOR_SCALARS in ASCII as value/255 (6 digits) and its reader
    # scales them back the same way; so do we: it restores the exact bytes, and the
    # ASCII and BINARY forms of one volume give the same uint8 data. As its reader: each
    # value read as a float, then 255 v + 0.5 in double, truncated (0.7 gives 178, where
    # 0.7 in double would round up to 179).
    values = _read_ascii(f, dims, "float32", path, rest)
    if not (values.min() >= 0 and values.max() <= 1):  # NaN fails here too
        raise InputError(f"{path}: ASCII VTK COLOR_SCALARS values outside [0, 1]")
    return np.floor(values.astype(np.float64) * 255.0 + 0.5).astype(np.uint8)


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
