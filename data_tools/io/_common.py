"""Helpers shared by the format readers: file checks, error wrapping, sample reading."""
from __future__ import annotations

import contextlib
import decimal
import importlib
import logging
import math
import os
import struct
import zlib
from collections.abc import Sequence
from fractions import Fraction
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..memory import check_memory
from ..volume import Volume, hand_over

#: Exceptions a reader may meet on bad input; all become one-line InputErrors.
READ_ERRORS = (OSError, ValueError, TypeError, KeyError, IndexError, EOFError,
               OverflowError, UnicodeError, struct.error, zlib.error)


def one_line(text) -> str:
    """Collapse a message to a single line (library messages may hold newlines)."""
    return " ".join(str(text).split())


def check_file(path: Path, what: str = "file") -> Path:
    """Return ``path`` if it is a readable regular file, else raise InputError."""
    if not path.exists():
        if path.is_symlink():
            raise InputError(f"{path}: a link that leads nowhere (or in a loop)")
        raise InputError(f"{path}: no such {what}")
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a volume {what}")
    if not path.is_file():
        # A pipe or a device would block the read or never end it.
        raise InputError(f"{path}: not a regular file")
    if not os.access(path, os.R_OK):
        raise InputError(f"{path}: permission denied")
    return path


@contextlib.contextmanager
def silenced(logger):
    """The library logger named ``logger`` disabled: what it writes to stderr would come
    before our one error line, or beside a good read."""
    log = logging.getLogger(logger)
    was = log.disabled
    log.disabled = True
    try:
        yield
    finally:
        log.disabled = was


def optional_library(name, path, kind, extra):
    """The module ``name`` of an optional extra, or an InputError telling how to install it."""
    try:
        return importlib.import_module(name)
    except ImportError:
        raise InputError(f"{path}: reading {kind} files needs the {name} package: "
                         f"pip install {name} (or the extra: pip install 'parc[{extra}]')") from None


def file_volume(data, spacing, origin, path, meta, place):
    """The Volume a reader returns: the file's ``spacing`` and ``origin``, or those of ``place``
    (`load_volume`'s ``spacing`` and ``origin`` options) in their stead.

    They replace the file's before the Volume checks them, so a header whose
    own values it refuses (spacing 0 from an exporter that means "unknown",
    an origin in map coordinates far from its fine grid) opens with the
    caller's. A reader's note on where its spacing came from
    (``meta['spacing_note']``: none given, or the lengths of rotated or
    mirrored axes) becomes ``meta['note']`` with the file's spacing; with a
    spacing given, only what still holds is said: a reoriented file's grid
    is axis-aligned.
    """
    meta = dict(meta)
    said = meta.pop("spacing_note", None)
    if place.get("spacing") is not None:
        spacing = place["spacing"]
        # What still holds of a note on reoriented axes; a reader that said so itself (MetaImage's
        # TransformMatrix note, in meta['note']) says it already.
        said = REORIENTED_NOTE if said and meta.get("reoriented") else None
    if said:
        meta["note"] = f"{meta['note']}; {said}" if meta.get("note") else said
    if place.get("origin") is not None:
        origin = place["origin"]
    return Volume(hand_over(data), spacing=spacing, origin=origin, name=str(path), meta=meta)


#: What a rotated or mirrored file's spacing note still says once a spacing is given.
REORIENTED_NOTE = ("the file's axes are rotated or mirrored in space; they are read on an axis-aligned grid "
                   "with the spacing given, and their orientation is ignored")


@contextlib.contextmanager
def reading(path, kind: str):
    """Turn any low-level failure while reading ``path`` into one InputError line."""
    try:
        yield
    except InputError:
        raise
    except MemoryError:
        raise InputError(f"{path}: not enough memory to load this {kind} volume") from None
    except READ_ERRORS as exc:
        detail = one_line(exc) or type(exc).__name__
        raise InputError(f"{path}: cannot read {kind} file: {detail}") from None


def file_order_dtype(dtype, big_endian: bool) -> np.dtype:
    """``dtype`` with the byte order of the file."""
    dt = np.dtype(dtype)
    if dt.itemsize == 1:
        return dt
    return dt.newbyteorder(">" if big_endian else "<")


def to_native(arr: np.ndarray) -> np.ndarray:
    """Swap to native byte order, in place when the array allows it (no extra copy)."""
    dt = arr.dtype
    if dt.isnative or dt.itemsize == 1:
        return arr
    if arr.flags.writeable:
        arr.byteswap(inplace=True)
        return arr.view(dt.newbyteorder("="))
    return arr.astype(dt.newbyteorder("="))


def read_samples(path: Path, offset: int, dims, dtype, big_endian: bool, *,
                 exact: bool = True, follows=(), kind: str = "raw", mmap: bool = False) -> np.ndarray:
    """Read ``nx*ny*nz`` samples from ``path`` at byte ``offset`` as ``[z, y, x]``.

    With ``exact`` the data must end the file; otherwise what follows them
    must be white space (a final newline) or begin with a word of
    ``follows`` (a format's further sections), `check_tail`; ``follows=None``
    takes anything. A short file is an InputError stating the expected and
    actual byte counts. With ``mmap`` the samples are a read-only memory
    map of the file (pages are read as rays touch them), which needs the
    machine's byte order.
    """
    nx, ny, nz = (int(n) for n in dims)
    dt = file_order_dtype(dtype, big_endian)
    count = nx * ny * nz
    expected = count * dt.itemsize
    actual = path.stat().st_size - offset
    if actual < expected or (exact and actual != expected):
        where = f" after a {offset}-byte header" if offset else ""
        state = "truncated" if actual < expected else "too long"
        # Counted after the header ("has 0" of a file with 4096 bytes read as empty), and a
        # header past the end leaves no bytes after it: the file's own size says more.
        has = (f"only {actual + offset} bytes in all" if actual < 0 else
               f"{actual} after it ({actual + offset} in all)" if offset else actual)
        raise InputError(
            f"{path}: {kind} data {state}: {nx}x{ny}x{nz} {np.dtype(dtype).name} needs "
            f"{expected} bytes{where}, the file has {has}")
    if not exact and follows is not None:
        check_tail(path, offset + expected, kind, follows)
    if mmap:
        if not (dt.isnative or dt.itemsize == 1):
            raise InputError(f"{path}: cannot memory-map {kind} data in the other byte order; "
                             "load it without mmap")
        return np.memmap(path, dtype=dt.newbyteorder("="), mode="r", offset=offset, shape=(nz, ny, nx))
    arr = np.fromfile(path, dtype=dt, count=count, offset=offset)
    return to_native(arr).reshape(nz, ny, nx)


def check_tail(path: Path, end: int, kind: str, follows=()):
    """Refuse bytes after a header's samples (which end at byte ``end``) other than white space
    or, for a format with further sections, a line whose first word is one of ``follows``.

    A header misread by a line (one repeated, a keyword garbled) moves the samples' start:
    they take bytes of the header, and their own last bytes are left over."""
    with open(path, "rb") as f:
        f.seek(end)
        tail = f.read(4096).lstrip()
    if not tail:
        return
    word = tail.split(None, 1)[0]
    if word.isascii() and word.decode("ascii").upper() in follows:
        return
    size = path.stat().st_size
    what = "a further section" if follows else "white space"
    raise InputError(f"{path}: {size - end} bytes after the {kind} samples the header states, and they are not "
                     f"{what}: the header does not match the data (corrupt?)")


def check_inflatable(path, dims, dtype):
    """Refuse compressed samples (``dims`` x, y, z of ``dtype``, as the header states them) that
    the memory cannot hold, before inflating them: a few kB of stream state gigabytes, and
    inflated block by block they would fill the memory before any refusal."""
    dims = [int(n) for n in dims]
    # Twice the samples: the inflated bytes are held while the array is read from them (counting
    # them once let a volume a third of the memory past the check, to run out as it loaded).
    check_memory(2 * math.prod(dims) * np.dtype(dtype).itemsize,
                 f"{path}: the {'x'.join(map(str, dims))} {np.dtype(dtype).name} volume its header states, "
                 "inflated and then read,", " (or the header's sizes are wrong)")


def decompress(blob: bytes, expected: int, path, kind: str) -> bytes:
    """Inflate zlib or gzip data and check it yields exactly ``expected`` bytes."""
    dec = zlib.decompressobj(zlib.MAX_WBITS | 32)  # 32: accept zlib and gzip headers
    try:
        out = dec.decompress(blob, expected + 1)
    except zlib.error as exc:
        raise InputError(f"{path}: corrupt compressed {kind} data ({one_line(exc)})") from None
    if len(out) < expected:
        raise InputError(
            f"{path}: compressed {kind} data truncated: expected {expected} bytes, inflated {len(out)}")
    if len(out) > expected:
        raise InputError(f"{path}: compressed {kind} data holds more than the {expected} bytes the header states")
    return out


def no_digit_separators(words, path, what: str):
    """Refuse numbers written with underscores (``1_000``) among ``words`` (bytes): Python and
    NumPy read them, the formats' own readers (C's ``strtod`` and ``atoi``: teem, MetaIO,
    VTK) do not. One search over all the words joined: text data hold millions."""
    if b"_" in b"".join(words):
        bad = next(w for w in words if b"_" in w)
        raise InputError(f"{path}: {bad[:40].decode('ascii', 'replace')!r} in {what} is not a number")


def parse_numbers(words, count: int, cast, path, what: str):
    """``count`` numbers from ``words`` (strings), or InputError naming ``what``."""
    kind = "integer" if cast is int else "number"
    wanted = ("an " if kind == "integer" else "a ") + kind if count == 1 else f"{count} {kind}s"
    if len(words) < count:
        raise InputError(f"{path}: {what} needs {wanted}, got {' '.join(words)!r}")
    try:
        if any("_" in w for w in words[:count]):
            raise ValueError        # Python reads 1_000; the formats' readers do not (`no_digit_separators`)
        return tuple(cast(w) for w in words[:count])
    except ValueError:
        raise InputError(f"{path}: {what} is not {wanted}: {' '.join(words)!r}") from None


def no_extra_values(words, count: int, path, what: str, tail: str = ""):
    """Refuse more than ``count`` ``words`` for ``what`` (``tail`` ends the message; by default
    "for N axes"). The formats' own readers read ``count`` numbers and leave the rest (MetaIO
    drops them, VTK takes the next for a keyword): ``12 12 12 7`` was read as 12 12 12, from a
    header that states another shape than its writer meant."""
    if len(words) > count:
        raise InputError(f"{path}: {what} gives {len(words)} values {tail or f'for {count} axes'}")


def parse_dims(words, path, what: str):
    """Three positive integer sample counts ``(nx, ny, nz)``."""
    dims = parse_numbers(words, 3, int, path, what)
    if min(dims) < 1:
        raise InputError(f"{path}: {what} must be positive, got {dims}")
    return dims


def several_data_files(path: Path, field: str, value: str, rest, ndims: int):
    """``(paths, subdim)`` when a header's data-file ``field`` names several files, else None.

    NRRD and MetaIO name them alike: ``LIST [subdim]`` (MetaIO: ``LIST 2D``), with the names on the header's
    remaining lines (``rest()`` returns those lines), and ``FORMAT MIN MAX STEP [subdim]``, a
    printf-style name numbered from MIN to MAX (inclusive) by STEP. Each file holds a
    ``subdim``-dimensional block of the fastest axes (by default every axis but the slowest:
    a file a slice), in order (`data_file_block`). Names are relative to the header's folder.
    """
    words = value.split()
    place = (lambda name: Path(name) if Path(name).is_absolute() else path.parent / name)
    if words and words[0].upper() == "LIST" and len(words) <= 2:
        names = [n.strip() for n in rest()]
        paths = [place(n) for n in names if n and not n.startswith("#")]
        if not paths:
            raise InputError(f"{path}: {field} {value!r} names no file")
    elif (len(words) in (4, 5) and "%" in words[0] and all(w.lstrip("+-").isdigit() for w in words[1:4])
          and not place(value).exists()):           # not one file whose name has spaces and a %
        first, last, step = (int(w) for w in words[1:4])
        if step == 0 or (last - first) * step < 0:
            raise InputError(f"{path}: {field} {value!r}: numbers {first} to {last} by {step} name no file")
        paths = NumberedFiles(words[0], range(first, last + (1 if step > 0 else -1), step), place)
        try:
            paths[0]
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"{path}: {field} {value!r}: {words[0]!r} is not a name with one integer "
                             "conversion (such as slice%03d.raw)") from None
    else:
        return None
    subdim = words[-1] if len(words) in (2, 5) else str(ndims - 1)
    if subdim[-1:] in ("D", "d"):
        subdim = subdim[:-1]        # MetaIO's documents write LIST 2D
    if not subdim.isdigit() or not 1 <= int(subdim) <= ndims:
        raise InputError(f"{path}: {field} {value!r}: the data files' dimension {subdim!r} must be 1 to {ndims}")
    return paths, int(subdim)


class NumberedFiles(Sequence):
    """The files of a numbered data-file name (``slice%03d.raw 1 40 1``), each named when it is
    taken: their count is known at once, so a header's numbers that do not match its sizes are
    refused before any file is named (`data_file_block`; the names of 1 to 400,000,000 took
    minutes and gigabytes)."""

    def __init__(self, pattern: str, numbers: range, place):
        self.pattern, self.numbers, self.place = pattern, numbers, place

    def __len__(self):
        return len(self.numbers)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        return self.place(self.pattern % self.numbers[index])


def data_file_block(path, paths, subdim, sizes, stated: str) -> int:
    """Samples each of ``paths`` holds (`several_data_files`): a block of the fastest ``subdim``
    of ``sizes`` (fastest first); with ``subdim`` the dimension, an equal slab of the slowest
    axis each. ``stated`` names what states the sizes, for the message when they do not add up."""
    total = math.prod(sizes)
    block = math.prod(sizes[:subdim])
    if subdim == len(sizes) and sizes[-1] % len(paths) == 0:
        block = total // len(paths)
    if block * len(paths) != total:
        raise InputError(f"{path}: {len(paths)} data files of {block} samples each (blocks of {subdim} axes) "
                         f"do not make {stated} {total} samples")
    return block


def text_values(words, dtype, path, type_name: str):
    """Text samples ``words`` (bytes) as ``dtype``: each read as a double, as C's ``strtod``
    reads it, and integer types taking only integers in their range (``type_name`` names the
    type in the message); float32 samples rounded once from the text, as ``strtof`` rounds
    them (`float32_from_text`). Parsing straight into the type, NumPy refused ``1.e5`` and
    read -1 as 255 in an unsigned type."""
    no_digit_separators(words, path, "the text samples")
    try:
        exact = np.array(words, dtype=np.float64)
    except ValueError:
        bad = next(w for w in words if not _is_float(w))
        raise InputError(f"{path}: the text sample {bad[:40].decode('ascii', 'replace')!r} is not a number") from None
    dtype = np.dtype(dtype)
    if dtype.kind in "iu":
        info = np.iinfo(dtype)
        inside = (exact >= info.min) & (exact <= info.max)
        wrong = np.flatnonzero(~(inside & (exact == np.round(exact))))
        if wrong.size:
            n = wrong[0]
            if inside[n]:       # in range: "outside" a type that holds 4 and 5 misled about 4.5
                raise InputError(f"{path}: the text sample {exact[n]:.17g} is not a whole number, as {type_name} "
                                 f"holds (integers {info.min} to {info.max})")
            raise InputError(f"{path}: the text sample {exact[n]:.17g} is outside {type_name} "
                             f"(integers {info.min} to {info.max})")
    if dtype == np.float32:
        return float32_from_text(words, exact)
    return exact.astype(dtype)


#: The float32 overflow threshold, halfway between its largest value and 2^128:
#: text at or above it rounds to infinity.
_FLOAT32_TOP = float(np.finfo(np.float32).max) + 2.0 ** 103


def float32_from_text(words, doubles):
    """float32 samples of text ``words`` (bytes), each rounded once from its decimal value,
    as C's ``strtof`` rounds it (NRRD's, MetaImage's and VTK's own readers read floats so).

    ``doubles`` holds the same words read as float64. Rounding that double to float32 again
    differs from rounding once only where the double lies exactly halfway between two float32
    neighbours (a double holds every such midpoint: 25 bits) and the text does not: through
    the double, ``1.00000005960464477539062500001`` reads as 1.0 (the halfway double, rounded
    to even), where it lies above halfway and rounds to 1.0000001. Those few words are
    settled by their exact decimal value.
    """
    doubles = np.asarray(doubles, dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        single = doubles.astype(np.float32)
        below = np.nextafter(single, np.float32(-np.inf))
        above = np.nextafter(single, np.float32(np.inf))
        here = single.astype(np.float64)
        halfway = np.isfinite(doubles) & ((doubles == (here + below.astype(np.float64)) * 0.5)
                                          | (doubles == (here + above.astype(np.float64)) * 0.5)
                                          | (np.abs(doubles) == _FLOAT32_TOP))
    for n in np.flatnonzero(halfway):
        try:
            text = Fraction(decimal.Decimal(bytes(words[n]).decode("ascii").strip()))
        except (ValueError, ArithmeticError, UnicodeError):
            continue
        middle = Fraction(float(doubles[n]))
        if text == middle:
            continue                        # truly halfway: the even neighbour, as rounded
        lower, upper = (single[n], above[n]) if float(single[n]) < middle else (below[n], single[n])
        single[n] = upper if text > middle else lower
    return single


def _is_float(word):
    try:
        float(word)
    except ValueError:
        return False
    return True
