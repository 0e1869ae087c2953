"""Headerless raw volumes: shape and type from options or the file name."""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..volume import Volume, hand_over
from ._common import read_samples, reading

EXTENSIONS = (".raw", ".bin", ".dat")

#: Type words seen in raw file names (Open SciVis: ``name_NxNxN_uint8.raw``).
DTYPE_WORDS = {
    "uint8": "uint8", "int8": "int8", "uint16": "uint16", "int16": "int16",
    "uint32": "uint32", "int32": "int32", "float32": "float32", "float64": "float64",
    "uchar": "uint8", "ubyte": "uint8", "byte": "uint8", "char": "int8",
    "ushort": "uint16", "short": "int16", "uint": "uint32", "int": "int32",
    "float": "float32", "double": "float64",
}

#: Three sizes, not three of four or more (4x5x6x2 is no 4x5x6 volume).
_SHAPE_RE = re.compile(r"(?<![0-9])(?<![0-9]x)(\d+)x(\d+)x(\d+)(?!x?[0-9])", re.IGNORECASE)
_SIZES_RE = re.compile(r"(?<![0-9])\d+(?:x\d+){3,}(?![0-9])", re.IGNORECASE)
_ENDIAN_WORDS = {"be": "big", "bigendian": "big", "msb": "big",
                 "le": "little", "littleendian": "little", "lsb": "little"}


def guess_from_name(path) -> dict:
    """Shape, dtype and byte order that a file name like ``bucky_32x32x32_uint8.raw`` states.

    A name can hold more than one type word (``double_helix_64x64x64_uint8``):
    a word with its width (``uint8``) comes before a C type word
    (``double``), and otherwise the first one named comes first.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    dict
        Any of ``shape`` ``(nx, ny, nz)``, ``dtype`` (numpy name: the first
        named with its width, else the first named) and ``byte_order`` found
        in the name; with more than one type named, ``dtypes``, all of them
        in that order (`read_raw` takes the one the file's size fits). A
        name giving two shapes or both byte orders also has ``shapes`` or
        ``byte_orders``, in its order (`read_raw` then asks which), and one
        giving four sizes or more, ``sizes``, their text (``4x5x6x2``).
        Empty when the name says nothing.
    """
    stem = Path(path).stem
    found = {}
    if (many := _SIZES_RE.search(stem)) is not None:
        found["sizes"] = many.group()
    shapes = list(dict.fromkeys(tuple(int(g) for g in m.groups()) for m in _SHAPE_RE.finditer(stem)))
    orders = list(dict.fromkeys(_ENDIAN_WORDS[word] for word in re.split(r"[^A-Za-z0-9]+", stem.lower())
                                if word in _ENDIAN_WORDS))
    for key, named in (("shape", shapes), ("byte_order", orders)):
        if named:
            found[key] = named[0]
        if len(named) > 1:
            found[key + "s"] = named
    sized, words = _type_words(stem)
    dtypes = list(dict.fromkeys(sized + words))
    if dtypes:
        found["dtype"] = dtypes[0]
    if len(dtypes) > 1:
        found["dtypes"] = dtypes
    return found


def _shape_text(shape):
    return "x".join(map(str, shape))


def _type_words(stem):
    """The types a name gives: ``(sized, other)``, those named with their width (``uint8``) and
    the C words (``double``), each in the name's order."""
    sized, words = [], []
    for word in re.split(r"[^A-Za-z0-9]+", stem.lower()):
        if word in DTYPE_WORDS:
            (sized if any(c.isdigit() for c in word) else words).append(DTYPE_WORDS[word])
    return list(dict.fromkeys(sized)), list(dict.fromkeys(words))


def _fitting_type(path, guess, shape, offset):
    """The type, among those the name gives, that the file's size fits: one named with its
    width before a C word; `guess_from_name`'s (the first named with its width, else the first
    named) when none fits (the read then says why)."""
    try:
        count = int(np.prod(_parse_shape(shape, path), dtype=np.int64))
        size = path.stat().st_size - _whole(offset)
    except (InputError, OSError, TypeError, ValueError):
        return guess["dtype"]       # the read reports these
    for kind in _type_words(path.stem):
        fits = [d for d in kind if count * np.dtype(d).itemsize == size]
        if len(fits) > 1:
            raise InputError(f"{path}: the name gives the sample types {' and '.join(fits)}, and the file's size "
                             f"fits either; give --dtype")
        if fits:
            return fits[0]
    return guess["dtype"]


def _whole(value):
    """``value`` as an int: an integer, an integral float or a string of digits; else ValueError
    (``int()`` would make 4.5 samples 4, silently)."""
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)) and float(value).is_integer():
        return int(value)
    if isinstance(value, str) and re.fullmatch(r"\s*[+-]?\d+\s*", value):
        return int(value)
    raise ValueError(value)


def _parse_shape(shape, path):
    if isinstance(shape, str):
        shape = [s for s in re.split(r"[x,\s]+", shape.strip().lower()) if s]
    try:
        dims = tuple(_whole(s) for s in shape)
    except (TypeError, ValueError):
        raise InputError(f"{path}: shape must be three integers nx,ny,nz, got {shape!r}") from None
    if len(dims) != 3 or min(dims) < 1:
        raise InputError(f"{path}: shape must be three positive integers nx,ny,nz, got {shape!r}")
    return dims


def parse_dtype(dtype, path):
    """The sample type word ``dtype`` names (``uint8`` ...), or an error naming ``path``."""
    key = str(np.dtype(dtype).name if isinstance(dtype, (type, np.dtype)) else dtype).lower()
    name = DTYPE_WORDS.get(key)
    if name is None:
        raise InputError(f"{path}: unsupported sample type {dtype!r} "
                         f"(use one of uint8, int8, uint16, int16, uint32, int32, float32, float64)")
    return name


#: Headers that may keep their samples in a file beside them, of another name.
_DETACHED_HEADERS = (".mhd", ".mha", ".nhdr", ".nrrd")


def headers_reading(path):
    """The MetaImage and NRRD headers of ``path``'s stem beside it whose data file is ``path``,
    as their own readers read it, sorted: the samples of such a pair are often opened instead of
    its header, and writing them changes what the header reads."""
    from . import metaimage, nrrd_format
    path = Path(path)
    try:
        siblings = [p for p in path.parent.iterdir()
                    if p.stem == path.stem and p.suffix.lower() in _DETACHED_HEADERS and p.is_file()]
    except OSError:
        return []
    found = []
    for header in sorted(siblings):
        try:
            if header.suffix.lower() in (".mhd", ".mha"):
                named = metaimage._parse_header(header)[0].get("ElementDataFile")
                data = header.parent / named if named else None
            else:
                data = nrrd_format._check_data_file(header)
        except (InputError, OSError):
            continue
        if data is not None and os.path.realpath(data) == os.path.realpath(path):     # never raises, for loops too
            found.append(header)
    return found


def read_raw(path, *, shape=None, dtype=None, byte_order=None, offset=0,
             spacing=None, origin=None, mmap=False) -> Volume:
    """Read a headerless raw volume, x varying fastest.

    Parameters
    ----------
    path : str or Path
    shape : (nx, ny, nz) or str like ``"256,256,113"``, optional
        Sample counts; taken from the file name when not given.
    dtype : str, optional
        numpy type name (``uint8``, ``int16``, ``float32``...); from the name
        when not given.
    byte_order : {'little', 'big'}, optional
        Of multi-byte samples; default little (or what the name says).
    offset : int
        Header bytes to skip before the samples.
    spacing, origin : (x, y, z), optional
        Default ``(1, 1, 1)`` and ``(0, 0, 0)``.
    mmap : bool
        Memory-map the samples read-only instead of reading them: a volume
        larger than memory renders, paged in as rays reach it.

    Returns
    -------
    Volume

    Raises
    ------
    InputError
        Shape or type unknown, or the file size is not ``offset`` plus
        ``nx*ny*nz*itemsize``.
    """
    if not isinstance(mmap, (bool, np.bool_)):
        # bool() would take "no" for True.
        raise InputError(f"mmap must be True or False, got {mmap!r}")
    path = Path(path)
    guess = guess_from_name(path)
    shape_given, dtype_given = shape is not None, dtype is not None
    if shape is None and "sizes" in guess and "shape" not in guess:
        raise InputError(f"{path}: the name gives {guess['sizes'].lower().count('x') + 1} sizes ({guess['sizes']}), "
                         "where a volume has three; give --shape NX,NY,NZ (shape in Python and scene files)")
    if shape is None and "shapes" in guess:
        raise InputError(f"{path}: the name gives the shapes {' and '.join(map(_shape_text, guess['shapes']))}; "
                         "give --shape NX,NY,NZ (shape in Python and scene files)")
    shape = shape if shape is not None else guess.get("shape")
    if dtype is None and "dtypes" in guess and shape is not None:
        dtype = _fitting_type(path, guess, shape, offset)
    dtype = dtype if dtype is not None else guess.get("dtype")
    order_named = byte_order is None and "byte_orders" in guess
    byte_order = byte_order if byte_order is not None else guess.get("byte_order", "little")
    missing = [name for name, v in (("shape", shape), ("dtype", dtype)) if v is None]
    if missing:
        # One message for the command line, Python and scene files, which name the options alike.
        flags = {"shape": "--shape NX,NY,NZ", "dtype": "--dtype TYPE"}
        headers = headers_reading(path)
        if headers:
            header = headers[0]
            raise InputError(f"{path}: a raw file has no header; {header.name} beside it names this file "
                             f"as its data: open {header.name} instead")
        raise InputError(
            f"{path}: a raw file has no header; give {' and '.join(flags[m] for m in missing)} "
            f"(and --byte-order, --offset, --spacing if needed; in Python and scene files "
            f"{', '.join(missing)}, byte_order, offset, spacing), or name it like vol_64x64x64_uint8.raw")
    dims = _parse_shape(shape, path)
    dtype = parse_dtype(dtype, path)
    if order_named and np.dtype(dtype).itemsize > 1:
        # Single bytes read the same either way.
        raise InputError(f"{path}: the name gives both byte orders; give --byte-order little or big "
                         "(byte_order in Python and scene files)")
    if str(byte_order).lower() not in ("little", "big"):
        raise InputError(f"{path}: byte order must be 'little' or 'big', got {byte_order!r}")
    try:
        offset = _whole(offset)
    except (TypeError, ValueError):
        raise InputError(f"{path}: offset must be a byte count, got {offset!r}") from None
    if offset < 0:
        raise InputError(f"{path}: offset must not be negative, got {offset}")
    # What the file's name gave, for the errors of a file read otherwise than it was written.
    named = [flag for flag, given, words in (("--shape", shape_given, ("shape",)),
                                             ("--dtype", dtype_given, ("dtype", "dtypes")))
             if not given and any(w in guess for w in words)]
    try:
        with reading(path, "raw"):
            data = read_samples(path, offset, dims, dtype, str(byte_order).lower() == "big", mmap=bool(mmap))
        return Volume(hand_over(data), spacing=spacing if spacing is not None else (1.0, 1.0, 1.0),
                      origin=origin if origin is not None else (0.0, 0.0, 0.0),
                      name=str(path), meta={"format": "raw", "byte_order": str(byte_order).lower()})
    except InputError as exc:
        text = str(exc)
        if named and (" data truncated: " in text or " data too long: " in text):
            what = " and ".join({"--shape": "shape", "--dtype": "type"}[f] for f in named)
            give = f"{named[0]} gives another" if len(named) == 1 else f"{' and '.join(named)} give others"
            keys = ", ".join(f[2:] for f in named)
            raise InputError(f"{text} ({what} from the file's name; {give}, {keys} in Python and scene "
                             "files)") from None
        if "non-finite samples" in text:
            # Floats read in the wrong byte order, or another type read as floats, come out so.
            raise InputError(f"{text}, unless they are misread: check --byte-order, --dtype and --offset "
                             "(byte_order, dtype, offset in Python and scene files)") from None
        raise


def write_raw(volume: Volume, path, *, byte_order: str | None = None) -> Path:
    """Write the samples alone, x fastest; shape, type and spacing are not stored.

    The byte order is ``byte_order``, else the one the name states (``_be``), else little.
    """
    path = Path(path)
    if byte_order is None:
        byte_order = guess_from_name(path).get("byte_order", "little")
    dt = volume.data.dtype.newbyteorder("<" if byte_order == "little" else ">")
    volume.data.astype(dt, copy=False).tofile(path)
    return path


def check_name(volume: Volume, path, byte_order: str | None = None) -> None:
    """Refuse to write ``volume`` to a raw file whose name states another shape, sample type
    or byte order (``ct_64x64x64_uint8.raw``): read back by its name, it would be misread."""
    path = Path(path)
    guess = guess_from_name(path)
    said = []
    # A name giving two shapes, or both byte orders for samples of several bytes, is read back
    # only with the flag that settles it, so it is refused as one that states another.
    if "shapes" in guess:
        said.append(" and ".join(map(_shape_text, guess["shapes"])))
    elif "sizes" in guess and "shape" not in guess:
        said.append(guess["sizes"])
    elif "shape" in guess and tuple(guess["shape"]) != tuple(volume.dims):
        said.append(_shape_text(guess["shape"]))
    named = guess.get("dtypes") or ([guess["dtype"]] if "dtype" in guess else [])
    if named and not any(np.dtype(d) == volume.dtype for d in named):
        said.append(" or ".join(named))
    elif len(named) > 1:
        # Several types named: the reader takes the first of those the file's size fits, a
        # type with its width before a C word (`_fitting_type`). One of the volume's width
        # other than its own would read the samples back as that type, silently.
        for kind in _type_words(path.stem):
            fits = [d for d in kind if np.dtype(d).itemsize == volume.dtype.itemsize]
            if len(fits) == 1 and np.dtype(fits[0]) != volume.dtype:
                said.append(f"{fits[0]} (the type of its width it names first)")
            if fits:
                break
    if "byte_orders" in guess:
        if volume.dtype.itemsize > 1:
            said.append("both little- and big-endian")
    elif byte_order is not None and guess.get("byte_order", byte_order) != byte_order:
        said.append(f"{guess['byte_order']}-endian")
    if said:
        raise InputError(f"{path}: the name says {', '.join(said)}, and the samples written would be "
                         f"{'x'.join(map(str, volume.dims))} {volume.dtype}"
                         f"{f', {byte_order}-endian' if byte_order is not None else ''}; "
                         "name the file for what it holds")
