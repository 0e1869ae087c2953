"""NRRD volumes (attached ``.nrrd`` and detached ``.nhdr``): the header as `nrrd_header` reads
it, raw data through pynrrd; text data, concatenated compressed streams and data split over
several files here; the spacing and origin the header gives."""
from __future__ import annotations

import bz2
import contextlib
import io
import math
import os
import sys
import zlib
from pathlib import Path

import numpy as np
import nrrd

from ..errors import InputError
from ..volume import Volume
from ._common import check_inflatable, check_tail, file_volume, data_file_block, text_values
from .nrrd_header import explain, header_lines, parse_header, read_header

EXTENSIONS = (".nrrd", ".nhdr")


def read_nrrd(path, *, spacing=None, origin=None) -> Volume:
    """Read a 3-D NRRD volume.

    Spacing comes from ``space directions`` (the length of each axis
    vector) or ``spacings``; origin from ``space origin`` or ``axis mins``.
    With ``axis mins`` and ``axis maxs`` alone, both come from the extent
    and the axes' ``centers`` (cell, NRRD's default, or node). An axis
    whose ``kinds`` entry holds values rather than positions (RGB-color,
    vector...) is refused; one of length 1 (one sample a voxel, one time
    step) is dropped, as NIfTI's trailing ones are.
    Oblique or mirrored directions cannot be kept on an axis-aligned grid:
    they are reduced to their lengths and ``meta['note']`` says so.

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
    data_file = _check_data_file(path)
    try:
        data, header = _read(path, data_file)
    except InputError:
        raise
    except MemoryError:
        raise InputError(f"{path}: not enough memory to load this NRRD volume") from None
    except Exception as exc:  # noqa: BLE001 - pynrrd raises many kinds (even StopIteration) on bad files
        raise InputError(f"{path}: cannot read NRRD file: {explain(exc)}") from None
    _check_counts(header, path)
    data, header = _one_volume(data, header)
    if data.ndim != 3:
        raise InputError(f"{path}: NRRD has {data.ndim} axes, expected a 3-D scalar volume")
    kinds = _per_axis(header.get("kinds"))
    for axis, kind in enumerate(kinds or ()):
        if kind.lower() not in _DOMAIN_KINDS:
            raise InputError(f"{path}: axis {axis + 1} holds {kind} values, not positions; "
                             "only scalar volumes are supported")
    meta = {"format": "nrrd", "encoding": header.get("encoding")}
    if data_file is not None:
        meta["data_file"] = str(data_file)
    if "data files" in header:
        meta["data_files"] = tuple(str(p) for p in header["data files"][0])
    try:
        spacing, note, reoriented = _spacing(header, path)
    except InputError:
        if given["spacing"] is None:
            raise
        # Directions the header cannot give (NaN) are what a spacing given replaces.
        spacing, note, reoriented = given["spacing"], None, False
    # An origin given replaces the header's, which is then not read: it may be unreadable (NaN).
    origin = _origin(header, spacing, path) if given["origin"] is None else given["origin"]
    if spacing is None:
        spacing, origin, reoriented, flat = _from_extent(header, data.shape[::-1])
        notes = []
        if reoriented:
            notes.append("axis mins above axis maxs (mirrored axes) were reduced to positive spacings")
        if flat:
            notes.append(f"axis mins and axis maxs give {', '.join(flat)} no length: spacing 1 was used for it "
                         "(give --spacing SX,SY,SZ)")
        note = "; ".join(notes) or None
    if note:
        meta["spacing_note"] = note         # `file_volume` says it, or what holds with a spacing given
    if reoriented:
        meta["reoriented"] = True           # a file written from it is no longer in the same place
    if "space" in header:
        meta["space"] = header["space"]
    return file_volume(data, spacing, origin, path, meta, given)


#: The encodings pynrrd reads as text.
_TEXT = ("ascii", "text", "txt")


def _read(path, data_file):
    """``(data, header)`` as `nrrd.read` gives them, with a line skip past the end of the
    data refused first (it calls ``readline`` that many times: a header's 1e20 never
    returned); text, hex and compressed data read here (`_read_text`, `_read_decoded`), and
    the samples of a header that names several data files, which pynrrd does not read
    (`_joined`)."""
    with open(path, "rb") as fh:
        header, files = read_header(fh, path)
        _check_layout(header, path)
        start = fh.tell()
        lines = header.get("lineskip", header.get("line skip", 0))
        size = (data_file.stat().st_size if data_file is not None and data_file.is_file()
                else path.stat().st_size - start)
        if files is None and isinstance(lines, int) and lines > size:
            raise InputError(f"{path}: line skip {lines} passes the end of the data ({size} bytes)")
        skip = header.get("byteskip", header.get("byte skip", 0))
        encoding = str(header.get("encoding")).lower()
        if (encoding in _DECODED or encoding in _TEXT) and skip == -1:
            raise InputError(f"{path}: byte skip -1 (the data end the file) applies to raw data only, "
                             f"not {encoding}")
        if encoding in _DECODED and encoding != "hex" and header.get("sizes") is not None:
            check_inflatable(path, np.atleast_1d(header["sizes"]), _sample_type(header))
        if files is not None:
            return _joined(header, files, path, encoding, lines, skip), dict(header, **{"data files": files})
        if encoding == "raw" and isinstance(skip, int) and skip > size:
            raise InputError(f"{path}: byte skip {skip} passes the end of the data ({size} bytes)")
        if encoding in _DECODED and isinstance(skip, int) and skip >= 0:
            data = _read_decoded(header, encoding, fh, path, data_file, lines, skip)
        elif encoding in _TEXT and isinstance(skip, int) and skip >= 0 and isinstance(lines, int) and lines >= 0:
            with open(data_file, "rb") if data_file is not None else contextlib.nullcontext(fh) as src:
                data = _read_text(header, src, path, lines, skip)
        else:
            data = nrrd.read_data(header, fh, str(path), index_order="C")
            if data_file is None and encoding == "raw" and skip != -1:
                check_tail(path, fh.tell(), "NRRD")
    return data, header


#: More samples than this (2^60: an exabyte of bytes) no file holds, and counting bytes in int64 overflows.
_MOST_SAMPLES = 2 ** 60


def _check_layout(header, path):
    """Refuse sizes and a sample type that name no array of numbers, before pynrrd reads by
    them (it answered ``sizes: -4 4 4`` with "product of all the dimensions: -64-64=-128"
    and ``type: block`` with "negative dimensions are not allowed")."""
    sizes = header.get("sizes")
    if sizes is not None:
        sizes = [int(n) for n in np.atleast_1d(sizes)]
        if not all(n > 0 for n in sizes):
            raise InputError(f"{path}: sizes must be positive, got {' '.join(map(str, sizes))}")
        if math.prod(sizes) >= _MOST_SAMPLES:
            # Their product in int64 wrapped round, and pynrrd's message with it.
            raise InputError(f"{path}: sizes {' '.join(map(str, sizes))} make {math.prod(sizes):.3g} samples, "
                             "more than any file holds")
    if str(header.get("type", "")).lower() == "block":
        raise InputError(f"{path}: type block (opaque blocks of bytes) holds no numbers; a volume needs a "
                         "scalar type such as uint8, short or float")


def _joined(header, files, path, encoding, lines, skip):
    """The samples of several data files (`read_header`), read in order and joined, shaped
    as the header's. The line and byte skips apply to each file, as in teem's reader (for
    compressed data, to the decompressed bytes; for hex and text data, to the file's)."""
    paths, subdim = files
    sizes = [int(n) for n in header["sizes"]]
    block = data_file_block(path, paths, subdim, sizes, "the header's")
    one = {key: header[key] for key in ("type", "endian", "encoding") if key in header}
    one.update(dimension=1, sizes=np.array([block]))
    parts = []
    for number, data_path in enumerate(paths, 1):
        what = f"data file {number} of {len(paths)} ({data_path})"
        if not data_path.exists():
            raise InputError(f"{path}: {what} not found")
        if not data_path.is_file():
            raise InputError(f"{path}: {what} is not a regular file")
        if isinstance(lines, int) and lines > data_path.stat().st_size:
            raise InputError(f"{path}: line skip {lines} passes the end of {what}")
        try:
            if encoding in _DECODED:
                parts.append(_read_decoded(one, encoding, None, path, data_path, lines, skip))
                continue
            with open(data_path, "rb") as src:
                if encoding in _TEXT:
                    parts.append(_read_text(one, src, data_path, lines, skip))
                else:
                    parts.append(nrrd.read_data(dict(one, **{"line skip": lines, "byte skip": skip}), src,
                                                str(path), index_order="C"))
        except InputError as exc:
            reason = str(exc).removeprefix(f"{path}: ").removeprefix(f"{data_path}: ")
            raise InputError(f"{path}: {what}: {reason}") from None
        except MemoryError:
            raise
        except Exception as exc:  # noqa: BLE001 - as in read_nrrd
            raise InputError(f"{path}: {what}: {explain(exc)}") from None
    return np.concatenate(parts).reshape(sizes[::-1])


def _read_text(header, fh, path, lines, skip):
    """The samples of text data in ``fh``, past ``lines`` lines and then ``skip`` bytes, shaped
    as the header's.

    Read here, not by pynrrd: NumPy's text reading, which it uses, refused numbers such as
    ``1.e5`` (C's and teem's ``strtod`` take them), and parsed text into the header's integer
    type directly, so that -1 became 255 (`text_values`).
    """
    for _ in range(lines):
        fh.readline()
    fh.seek(skip, io.SEEK_CUR)
    words = fh.read().split()
    sizes = [int(n) for n in header["sizes"]]
    count = math.prod(sizes)
    if len(words) != count:
        raise InputError(f"{path}: data do not match the header (truncated or corrupt?): {count} text samples "
                         f"expected, {len(words)} found")
    values = text_values(words, _sample_type(header), path, f"the header's type {header.get('type')}")
    return values.reshape(sizes[::-1])


def _sample_type(header):
    """The native NumPy type of the header's samples, by pynrrd's own table of NRRD's type names."""
    probe = {"type": header.get("type"), "endian": header.get("endian", "little"), "dimension": 1,
             "sizes": np.array([0]), "encoding": "raw"}
    return nrrd.read_data(probe, io.BytesIO(b""), index_order="C").dtype.newbyteorder("=")


#: The encodings decoded here and given to pynrrd as raw data: the compressed ones, which pynrrd
#: reads differently from teem (`_read_decoded`), and hex, which it does not read.
_DECODED = ("gzip", "gz", "bzip2", "bz2", "hex")


def _read_decoded(header, encoding, fh, path, data_file, lines, skip):
    """`nrrd.read_data` for compressed or hex data, decoded here and given to pynrrd as raw
    data, with pynrrd's own checks (a gzip stream, not bare zlib; no negative line skip; no
    bytes past the samples). Two things pynrrd does differently from teem's reader: it
    applied a byte skip to both the stream and the decompressed bytes, failing on the
    stream's cut start (NRRD applies it to the decompressed bytes), and it read only the
    first member of a gzip file or stream of a bzip2 one (`_decode`)."""
    if not isinstance(lines, int) or lines < 0:
        raise InputError(f"{path}: line skip must be 0 or more, got {lines}")
    with open(data_file, "rb") if data_file is not None else contextlib.nullcontext(fh) as src:
        for _ in range(lines):
            src.readline()
        blob = src.read()
    if encoding == "hex":
        # As for text, the byte skip counts bytes of the file (teem's reader): only compressed
        # data skip decoded bytes.
        if skip > len(blob):
            raise InputError(f"{path}: byte skip {skip} passes the end of the {len(blob)} bytes of hex data")
        blob, skip = blob[skip:], 0
    if not blob:
        raise InputError(f"{path}: no {encoding} data after the header (line skip {lines})")
    # Inflate no further than the header's samples (and a little past, to say by how much they
    # overrun): a 1 MB stream of zeros inflated to 1 GB, held in memory, before being refused.
    wanted = skip + math.prod(int(n) for n in np.atleast_1d(header["sizes"])) * _sample_type(header).itemsize
    limit = min(wanted + _OVERRUN, sys.maxsize - 1)     # zlib's bound on an output length
    raw = _decode(blob, encoding, path, limit)
    if len(raw) > limit and encoding != "hex":
        raise InputError(f"{path}: the {encoding} data inflate to more than the {wanted - skip} bytes the header "
                         f"states{' after the byte skip' if skip else ''}")
    if skip > len(raw):
        raise InputError(f"{path}: byte skip {skip} passes the end of the {len(raw)} decompressed bytes")
    plain = {key: value for key, value in header.items()
             if key not in ("data file", "datafile", "byte skip", "byteskip", "line skip", "lineskip")}
    plain["encoding"] = "raw"
    data = nrrd.read_data(plain, io.BytesIO(raw[skip:]), str(path), index_order="C")
    if len(raw) - skip > data.nbytes:
        raise InputError(f"{path}: the {encoding} data hold {len(raw) - skip} bytes after the byte skip, "
                         f"more than the {data.nbytes} the header states")
    return data


_GZIP_MAGIC = b"\x1f\x8b"


#: Bytes inflated past a header's samples before compressed data are refused as too long.
_OVERRUN = 1 << 16


def _decode(blob, encoding, path, limit):
    """The bytes of every member of a gzip file (as ``cat a.gz b.gz`` or a parallel
    compressor writes them; teem's reader, through zlib's ``gzread``, reads them all) or
    every stream of a bzip2 one (``pbzip2``). What follows the last member and is not
    another is ignored, as both readers ignore it. Hex data: two digits a byte, any white
    space between them."""
    if encoding == "hex":
        digits = b"".join(blob.split())
        try:
            return bytes.fromhex(digits.decode("ascii"))
        except (UnicodeDecodeError, ValueError):
            bad = next((chr(c) for c in digits if chr(c) not in "0123456789abcdefABCDEF"), None)
            why = f"{bad!r} is not a hex digit" if bad is not None else f"an odd number of digits ({len(digits)})"
            raise InputError(f"{path}: hex data: {why}") from None
    gz = encoding in ("gzip", "gz")
    # Each member's bytes, joined only where there are several: gathered in one bytearray, the
    # samples were held twice over as they inflated, and copied again to be read.
    parts, size = [], 0
    while True:
        # At most ``limit`` bytes in all (and one more, to tell that there are more).
        member = zlib.decompressobj(zlib.MAX_WBITS | 16) if gz else bz2.BZ2Decompressor()
        room = limit + 1 - size
        parts.append(member.decompress(blob, room) if gz else member.decompress(blob, max_length=room))
        size += len(parts[-1])
        if size > limit:
            break
        if not gz and not member.eof:
            raise InputError(f"{path}: bzip2 data truncated (the stream ends early)")
        blob = member.unused_data
        if not (member.eof and blob.startswith(_GZIP_MAGIC if gz else b"BZh")):
            break
    return parts[0] if len(parts) == 1 else b"".join(parts)


#: Per-axis header fields: an axis dropped takes its entry in each.
_PER_AXIS = ("sizes", "kinds", "centers", "centerings", "labels", "units", "spacings", "thicknesses",
             "axis mins", "axismins", "axis maxs", "axismaxs", "space directions")


#: Per-axis fields the reader reads besides the sizes (`_check_counts`), as `nrrd_header` names
#: them (``centerings`` and ``axismins`` are read as ``centers`` and ``axis mins``).
_READ_PER_AXIS = ("kinds", "centers", "spacings", "axis mins", "axis maxs")


#: The dimension each named space has (NRRD's ``space``, in either spelling), which its
#: directions' vectors give.
_SPACE_DIMENSIONS = {name.lower(): 3 for name in (
    "RAS", "LAS", "LPS", "right-anterior-superior", "left-anterior-superior", "left-posterior-superior",
    "scanner-xyz", "3D-right-handed", "3D-left-handed")}
_SPACE_DIMENSIONS.update({name.lower(): 4 for name in (
    "RAST", "LAST", "LPST", "right-anterior-superior-time", "left-anterior-superior-time",
    "left-posterior-superior-time", "scanner-xyz-time", "3D-right-handed-time", "3D-left-handed-time")})


def _check_counts(header, path):
    """Refuse a per-axis field read here that does not give one value an axis, and space
    directions whose vectors do not have the space dimension's length; pynrrd takes any count.
    ``kinds: domain`` for three axes was read as the kind of x alone, and ``space dimension: 2``
    beside 3-vectors as a 3-D space."""
    axes = int(header.get("dimension", 0))
    for key in _READ_PER_AXIS:
        values = _per_axis(header.get(key))
        if values is not None and len(values) != axes:
            raise InputError(f"{path}: {key} gives {len(values)} value{'s' * (len(values) != 1)} for {axes} axes")
    stated = header.get("space dimension")
    by = f"the space dimension is {stated}"
    if stated is None and str(header.get("space", "")).lower() in _SPACE_DIMENSIONS:
        stated = _SPACE_DIMENSIONS[str(header["space"]).lower()]
        by = f"space {header['space']} is {stated}-D"
    dirs = header.get("space directions")
    if stated is not None and dirs is not None:
        dirs = np.asarray(dirs)
        if dirs.ndim == 2 and dirs.shape[1] != int(stated):
            raise InputError(f"{path}: space directions gives vectors of {dirs.shape[1]} values where {by}")


def _one_volume(data, header):
    """``(data, header)`` with the axes of length 1 that hold no position dropped, as a NIfTI
    file's trailing ones are: one sample a voxel (kind vector, list...), one time step. Without
    ``kinds``, trailing axes. A file left with other than three axes is the caller's to refuse."""
    if data.ndim <= 3:
        return data, header
    sizes = [int(n) for n in header["sizes"]]                   # file order: x fastest
    kinds = _per_axis(header.get("kinds"))
    if kinds is not None and len(kinds) == len(sizes):
        keep = [a for a, n in enumerate(sizes) if n != 1 or kinds[a].lower() in ("domain", "space")]
    else:
        keep = list(range(len(sizes)))
        while len(keep) > 3 and sizes[keep[-1]] == 1:
            keep.pop()
    if len(keep) != 3:
        return data, header
    header = dict(header)
    for key in _PER_AXIS:
        value = header.get(key)
        if isinstance(value, str):
            value = value.split()
        if value is not None and len(value) == len(sizes):
            header[key] = np.asarray(value)[keep] if isinstance(value, np.ndarray) else [value[a] for a in keep]
    return data.reshape([sizes[a] for a in reversed(keep)]), header


def _check_data_file(path):
    """The detached data file a header names, or None; refuse one that is not a regular file
    (a pipe or a device would block the read or never end it). Other header faults, and
    headers naming several data files (`_joined` checks each), are left to the read."""
    try:
        with open(path, "rb") as fh:
            header = parse_header(list(header_lines(fh, path)), path)
    except Exception:  # noqa: BLE001 - reported by the read itself
        return None
    name = header.get("data file") or header.get("datafile")
    if not isinstance(name, str):
        return None
    words = name.split()
    if words and words[0].upper() == "LIST" and len(words) <= 2:
        # A list of files, as `several_data_files` takes one: LISTING.raw is a file's name.
        return None
    data = Path(name) if Path(name).is_absolute() else path.parent / name
    if " " in name.strip() and not data.exists():
        return None             # numbered files ("slice%03d.raw 1 40 1"), checked as the read takes them
    if not data.exists():
        # pynrrd's own words named the file as the header gives it, beside "[Errno 2]".
        raise InputError(f"{path}: data file {data} not found")
    if not data.is_file():
        raise InputError(f"{path}: data file {data} is not a regular file")
    return data


#: NRRD's kinds of an axis of positions; any other (RGB-color, vector, list...) holds
#: several values a sample, which a scalar volume cannot show.
_DOMAIN_KINDS = {"domain", "space", "time", "none", "???"}


def _per_axis(value):
    """A per-axis field as a list of words (pynrrd leaves some as one string)."""
    if value is None:
        return None
    return value.split() if isinstance(value, str) else [str(v) for v in value]


def _from_extent(header, sizes):
    """``(spacing, origin, mirrored, flat)`` from ``axis mins`` and ``axis maxs`` (no spacings
    given); ``flat``: the names of the axes they give no length, spaced 1.

    With node centring the extremes are the first and last samples; with
    cell centring, NRRD's default, the outer edges of the first and last
    cells, the samples half a spacing inside them. An axis whose min lies
    above its max runs the other way: mirrored, placed from its smaller end.
    """
    lo = np.asarray(header["axis mins"], dtype=np.float64)
    hi = np.asarray(header["axis maxs"], dtype=np.float64)
    centers = _per_axis(header.get("centers")) or ["cell"] * 3
    spacing, origin, flat = [], [], []
    for axis, n, a, b, c in zip("xyz", sizes, lo, hi, centers):
        node = c.lower() == "node"
        step = abs(b - a) / (n - 1 if node else n)
        if not (np.isfinite(step) and step > 0):
            # Min equal to max, or node-centred along an axis of one sample (0 / 0).
            step = 1.0
            if not (node and n == 1):
                flat.append(axis)
        spacing.append(float(step))
        origin.append(float(min(a, b) + (0.0 if node else step / 2)))
    return tuple(spacing), tuple(origin), bool((lo > hi).any()), flat


def _spacing(header, path):
    """``(spacing, note, reoriented)``: the spacing the header gives (None where ``axis
    mins`` and ``axis maxs`` give it with the origin), a note on what was made of it (NaN or
    infinite spacings are taken as 1 and said; a header giving no spacing at all gets 1, unsaid),
    and whether oblique or mirrored axes were laid on the axis-aligned grid."""
    dirs = header.get("space directions")
    if dirs is not None:
        try:
            dirs = np.asarray(dirs, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"{path}: unreadable space directions {dirs!r}") from None
        if dirs.shape[0] != 3:
            raise InputError(f"{path}: space directions must give one vector per axis (3 axes)")
        if not np.isfinite(dirs).all():
            raise InputError(f"{path}: space directions hold values that are not finite numbers; "
                             "give --spacing SX,SY,SZ")
        # Rows are the per-axis vectors, in file axis order (x, y, z).
        norms = np.linalg.norm(dirs, axis=1)
        off = dirs.copy()
        if off.shape[1] >= 3:
            off[np.arange(3), np.arange(3)] = 0.0
        oblique = np.abs(off).max() > 1e-6 * norms.max() or dirs.shape[1] != 3
        mirrored = not oblique and (np.diag(dirs) < 0).any()
        note = None
        if oblique:
            note = ("oblique space directions were reduced to axis-aligned spacings "
                    f"(their lengths {tuple(round(float(n), 6) for n in norms)}); orientation is ignored")
        elif mirrored:
            note = "negative space directions (mirrored axes) were reduced to positive spacings"
        if header.get("spacings") is not None:
            # Teem refuses such a header; the spacings of another tool's reading would be a guess.
            note = "; ".join(n for n in (note, "the header gives spacings beside space directions, which NRRD "
                                         "does not allow: the space directions were used") if n)
        return tuple(float(n) for n in norms), note, oblique or mirrored
    spacings = header.get("spacings")
    if spacings is not None:
        sp = np.asarray(spacings, dtype=np.float64)
        if sp.shape != (3,):
            raise InputError(f"{path}: spacings gives {sp.size} values for 3 axes")
        notes = []
        mirrored = bool((np.isfinite(sp) & (sp < 0)).any())
        if mirrored:
            notes.append("negative spacings (mirrored axes) were reduced to positive spacings")
        unknown = ~np.isfinite(sp)
        if unknown.any():
            # NaN is NRRD's word for a spacing the writer did not know; an infinite one is no
            # spacing either. Either is 1, said (and the note dropped when --spacing is given).
            axes = ", ".join("xyz"[i] for i in np.flatnonzero(unknown))
            words = " and ".join(sorted({"NaN (unknown)" if np.isnan(v) else f"{v:g}" for v in sp[unknown]}))
            notes.append(f"spacings gives {words} for {axes}: taken as 1 (give --spacing SX,SY,SZ)")
        sp = np.where(unknown, 1.0, np.abs(sp))
        return tuple(float(s) for s in sp), "; ".join(notes) or None, mirrored
    if _has_extent(header):
        return None, None, False     # from axis mins and maxs (`_from_extent`), with the origin
    return (1.0, 1.0, 1.0), None, False


def _has_extent(header):
    try:
        lo = np.asarray(header.get("axis mins"), dtype=np.float64)
        hi = np.asarray(header.get("axis maxs"), dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return lo.shape == hi.shape == (3,) and np.isfinite(lo).all() and np.isfinite(hi).all()


def _origin(header, spacing, path):
    """The first sample's position: ``space origin`` is it; ``axis mins`` is the lower edge of
    the first cell with cell centring (NRRD's default), the sample half a spacing inside, as in
    `_from_extent`. A ``space origin`` other than three finite numbers is refused: taken as
    absent, it moved the volume to (0, 0, 0) without a word."""
    given = header.get("space origin")
    if given is not None:
        arr = np.asarray(given, dtype=np.float64)
        if arr.shape != (3,) or not np.isfinite(arr).all():
            raise InputError(f"{path}: space origin must be three finite numbers, got "
                             f"({','.join(f'{v:g}' for v in arr.ravel())}); give --origin OX,OY,OZ")
    for key in ("space origin", "axis mins", "axismins"):
        val = header.get(key)
        if val is not None:
            arr = np.asarray(val, dtype=np.float64)
            if arr.shape == (3,) and np.isfinite(arr).all():
                if key != "space origin" and spacing is not None:
                    centers = _per_axis(header.get("centers")) or ["cell"] * 3
                    arr = arr + [0.0 if c.lower() == "node" else s / 2 for s, c in zip(spacing, centers)]
                return tuple(float(v) for v in arr)
    return (0.0, 0.0, 0.0)


def write_nrrd(volume: Volume, path, *, compress: bool = True) -> Path:
    """Write an attached NRRD (gzip, or raw with ``compress=False``), or a ``.nhdr`` + ``.raw`` pair.

    Spacing and origin go to ``space directions`` (diagonal) and ``space origin``.
    """
    path = Path(path)
    header = {
        "space dimension": 3,
        "space directions": np.diag(np.asarray(volume.spacing, dtype=np.float64)),
        "space origin": np.asarray(volume.origin, dtype=np.float64),
        "kinds": ["domain", "domain", "domain"],
        "encoding": "gzip" if compress else "raw",
        "endian": "little",
    }
    detached = path.suffix.lower() == ".nhdr"
    if detached:
        header["encoding"] = "raw"
    # pynrrd detaches the header by the name's ending in lower-case ".nhdr" alone: an
    # "m.NHDR" got the samples attached. Such a header is written under a lower-case
    # name and moved, with the data file named beside it.
    target = path if path.suffix == ".nhdr" or not detached else path.with_name(path.name + ".nhdr")
    # Level 1: gzip's higher levels cost several times the time for a few percent.
    nrrd.write(str(target), np.ascontiguousarray(volume.data), header,
               detached_header=str(path.with_suffix(".raw")) if detached else False,
               compression_level=1, index_order="C")
    if target != path:
        os.replace(target, path)
    return path


