"""NRRD headers as teem reads them: lines read whole up to the blank line that ends them,
each checked (a line that is no field, a field NRRD does not have, whole numbers), field
names and enums in any case, then parsed by pynrrd, whose errors are named by their field."""
from __future__ import annotations

import re

import nrrd

from ..errors import InputError
from ._common import one_line, several_data_files


#: Bytes of header read before giving up on finding its end: lines of any length and number
#: up to it (pynrrd reads them all), and a file of another kind named .nrrd is refused at its
#: first line.
_MAX_HEADER_BYTES = 1 << 26


def header_lines(fh, path):
    """The header's lines as read, whole, the magic first, up to and with the blank line that
    ends it (or the end of the file); ``fh`` is then at the data."""
    if fh.read(4) != b"NRRD":
        fh.seek(0)
        parse_header([fh.readline(256)], path)       # pynrrd's own word on the magic line
    fh.seek(0)
    used = 0
    while True:
        line = fh.readline(_MAX_HEADER_BYTES - used + 1)
        used += len(line)
        if used > _MAX_HEADER_BYTES:
            raise InputError(f"{path}: no end to the NRRD header in its first {_MAX_HEADER_BYTES >> 20} MiB")
        yield line
        if not line.decode("ascii", "ignore").strip():
            return


def read_header(fh, path):
    """``(header, files)``: the header as pynrrd parses it, with ``fh`` at the data, and the
    data files of a header that splits its samples over several (`several_data_files`), as
    ``(paths, subdim)``, else None. pynrrd reads neither way of naming them, and takes the
    names after ``data file: LIST`` for malformed fields."""
    taken = []
    for line in header_lines(fh, path):
        taken.append(line)
        # Non-ASCII bytes kept (as U+FFFD): dropped, "data file: LIST\xff" was a list and its line
        # never checked (`_check_line`).
        text = line.decode("ascii", "replace").strip()
        m = re.fullmatch(r"(?i:data ?file)\s*:\s*(LIST.*)", text)
        if m and len(taken) > 1:
            header = parse_header(taken[:-1], path)
            rest = [n.decode("utf-8", "replace") for n in fh.read().splitlines()]
            files = several_data_files(path, "data file", m.group(1), lambda: rest, int(header.get("dimension", 0)))
            if files is not None:
                return header, files
            fh.seek(sum(map(len, taken)))
    header = parse_header(taken, path)
    value = header.get("data file", header.get("datafile"))
    if not isinstance(value, str):
        return header, None
    files = several_data_files(path, "data file", value, list, int(header.get("dimension", 0)))
    if files is not None:
        for key in ("data file", "datafile"):
            header.pop(key, None)
    return header, files


#: NRRD's fields, as pynrrd parses them (and ``centers``, ``number`` and ``block size``, which
#: teem's reader takes and this one ignores or reads itself). A free-form key/value pair is
#: written ``key:=value``.
_FIELDS = frozenset((
    "dimension", "type", "sizes", "endian", "encoding", "content", "number", "block size", "blocksize",
    "min", "max", "old min", "oldmin", "old max", "oldmax", "data file", "datafile", "line skip", "lineskip",
    "byte skip", "byteskip", "sample units", "space", "space dimension", "space units", "space origin",
    "space directions", "measurement frame", "spacings", "thicknesses", "axis mins", "axismins", "axis maxs",
    "axismaxs", "centers", "centerings", "kinds", "labels", "units"))

#: teem's spellings without spaces that pynrrd does not parse (`_as_pynrrd`).
_SPELLED_APART = {"spacedimension": "space dimension", "spaceunits": "space units", "spaceorigin": "space origin",
                  "spacedirections": "space directions", "measurementframe": "measurement frame",
                  "sampleunits": "sample units",
                  # pynrrd parses these too, but under the name as written; the reader looks each
                  # field up by one name.
                  "axismins": "axis mins", "axismaxs": "axis maxs", "centerings": "centers"}


def parse_header(lines, path):
    """`nrrd.read_header` of the header's ``lines`` (the magic first), read as teem reads them
    (`_as_pynrrd`), with a field it cannot parse named (pynrrd's message alone, "could not
    convert string to float: 'x'", does not say where), each line checked first
    (`_check_line`)."""
    # NRRD00.01, the format's first magic, which teem still reads, is version 1 to pynrrd.
    magic = b"NRRD0001\n" if lines[0].rstrip() == b"NRRD00.01" else lines[0]
    lines = [magic] + [_as_pynrrd(line) for line in lines[1:]]
    for line in lines[1:]:
        _check_line(line, path)
    try:
        header = nrrd.read_header(lines)
    except Exception as exc:  # noqa: BLE001 - pynrrd raises many kinds
        try:
            nrrd.read_header(lines[:1])
        except Exception:  # noqa: BLE001 - the magic line itself: no field is at fault
            raise exc from None
        for line in lines[1:]:
            field = line.decode("ascii", "ignore").split(":", 1)[0].strip()
            try:
                nrrd.read_header(lines[:1] + [line])
            except Exception as one:  # noqa: BLE001 - as above
                raise InputError(f"{path}: field {field!r}: {explain(one)}") from None
        raise exc
    return header


def _as_pynrrd(line):
    """A header line as pynrrd parses it, meaning what it means to teem's reader: field names
    and the values of ``type``, ``endian`` and ``encoding`` in any case (teem's enums ignore
    it; pynrrd took ``Sizes`` for an unknown field and ``type: Short`` for no type), and
    teem's spellings without spaces (``spacedirections``, which pynrrd ignored, and the
    spacing with it) spelt as pynrrd spells them. Comments, key/value pairs and lines
    naming no field of NRRD's pass as they are."""
    head, colon, value = line.partition(b":")
    if not colon or line.startswith(b"#") or b":=" in line:
        return line
    # A name with non-ASCII bytes is no field's ("ty\xffpe" was type, the bytes dropped).
    field = head.decode("ascii", "replace").strip().lower()
    field = _SPELLED_APART.get(field, field)
    if field not in _FIELDS:
        return line
    if field in ("type", "endian", "encoding"):
        value = value.lower()
    return field.encode() + colon + value


#: Fields of free text, which the reader does not parse: their non-ASCII bytes (a content
#: or units in UTF-8 or Latin-1) are dropped by pynrrd, harmlessly.
_FREE_TEXT = frozenset(("content", "sample units", "space units", "labels", "units"))

#: Fields of whole numbers, which pynrrd reads through float ("1e3" was 1000, "1e400" a
#: negative size) or reports in Python's words ("invalid literal for int() with base 10").
_WHOLE_FIELDS = frozenset(("dimension", "sizes", "byte skip", "byteskip", "line skip", "lineskip",
                           "space dimension"))


def _check_line(line, path):
    """Refuse, in words that name them, a header line that is no field, a field NRRD does not
    have (as teem's reader refuses it: a misspelt ``spacngs`` was ignored, and the spacing
    with it), a whole-number field holding anything else, and non-ASCII bytes in a field the
    reader parses."""
    text = line.decode("ascii", "replace").strip()
    # A key/value pair's key may hold colons (ITK writes "ITK_like:colon:=x"), not ":=".
    if not text or text.startswith("#") or ":=" in text:
        return
    field, colon, value = text.partition(":")
    if not colon or not text.replace("\t", " ").isprintable():
        # Binary samples read as a header line: the blank line before them is missing.
        raise InputError(f"{path}: header line {text[:60]!r} is not 'field: value' (an attached "
                         "header ends at a blank line before the data)")
    field = field.strip()
    if field not in _FIELDS:
        raise InputError(f"{path}: unknown field {field!r} (NRRD has no such field; a free-form key/value "
                         "pair is written key:=value)")
    if not line.isascii() and field not in _FREE_TEXT:
        # pynrrd reads the line as ASCII, dropping the rest: "type: uint8\xff" was uint8, and a
        # data file's name in UTF-8 another name. Comments and key/value pairs may hold any text.
        shown = line.partition(b":")[2].decode("ascii", "backslashreplace").strip()[:40]
        raise InputError(f"{path}: field {field!r}: non-ASCII bytes in '{shown}' (NRRD's fields are ASCII; "
                         "only comments, key:=value pairs and free-text fields may hold other text)")
    if field in _WHOLE_FIELDS:
        for word in value.split():
            if not re.fullmatch(r"[-+]?\d+", word):
                raise InputError(f"{path}: field {field!r}: expected whole numbers, got {word[:30]!r}")
            if field == "sizes" and abs(int(word)) >= 1 << 62:       # pynrrd keeps sizes in int64
                raise InputError(f"{path}: field 'sizes': {word[:30]} samples along an axis is more than "
                                 "any file holds")


def explain(exc) -> str:
    if isinstance(exc, KeyError) and exc.args:
        # pynrrd looks field values up in tables: a KeyError names the value it does not know.
        return f"unsupported value {exc.args[0]!r} in the header (e.g. an unknown type or encoding)"
    text = one_line(exc)
    if text == "negative dimensions are not allowed":
        return "data do not match the header (truncated or corrupt?)"
    m = re.search(r"dimensions: (\d+)-(\d+)=", text)
    if m:
        return (f"data do not match the header (truncated or corrupt?): "
                f"{m.group(1)} samples expected, {m.group(2)} found")
    return text or type(exc).__name__
