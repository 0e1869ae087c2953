"""Multi-page TIFF stacks (``.tif``, ``.tiff``), read with tifffile: microscopy's usual volume file.

tifffile is an optional extra (``pip install 'parc[tiff]'``, with
imagecodecs for LZW and the other compressions): TIFF's many compressions
and tilings, and the ImageJ and OME metadata conventions, are what it is
made for.
"""
from __future__ import annotations

import contextlib
import json
import lzma
import math
import re
import struct
import zlib
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..memory import check_memory
from ..volume import Volume
from ._common import file_volume, one_line, optional_library, silenced, to_native

EXTENSIONS = (".tif", ".tiff")

#: Files in a folder that say it holds a DICOM series rather than slices.
_DICOM = (".dcm", ".dicom", ".ima")

#: TIFF ResolutionUnit "none": ImageJ stores pixels per unit of its own ``unit``.
_RESUNIT_NONE = 1


def read_tiff(path, *, spacing=None, origin=None) -> Volume:
    """Read a stack of grey-level TIFF pages as a volume, one page per z slice.

    The stack is the file's first series (ImageJ hyperstacks and OME-TIFF
    name their axes); axes of length 1 are dropped, and what is left must
    be z, y, x. Plain pages that no metadata ties together are stacked in
    file order when they all have the same shape and type.

    Spacing, in the file's own unit: OME-TIFF ``PhysicalSizeX/Y/Z``, each
    axis's size converted to x's unit; ImageJ's ``XResolution``/
    ``YResolution`` (pixels per unit, or per cm or inch) and ``spacing``
    (z); otherwise 1, 1, 1 and ``meta['note']`` says so.
    Origin is 0, 0, 0.

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
    tifffile = optional_library("tifffile", path, "TIFF", "tiff")
    with _reading_tiff(path), tifffile.TiffFile(str(path)) as tif:
        data, axes, spacing, note, meta = _stack(tifffile, tif, path)
    meta.update(format="tiff", axes=axes)
    if note:
        meta["spacing_note"] = note         # `file_volume` drops it when the caller gives the spacing
    return file_volume(np.ascontiguousarray(to_native(data)), spacing, (0.0, 0.0, 0.0), path, meta, given)


#: Exceptions that tifffile does not raise on purpose (it raises TiffFileError, ValueError...).
_SLIPS = (ArithmeticError, AssertionError, IndexError, KeyError, AttributeError, TypeError, struct.error)


@contextlib.contextmanager
def _reading_tiff(path):
    """tifffile's failures on ``path`` as one InputError line; its own log lines silenced,
    so that a bad file gets that line alone."""
    try:
        with silenced("tifffile"):
            yield
    except InputError:
        raise
    except MemoryError:
        raise InputError(f"{path}: not enough memory to load this TIFF volume") from None
    except Exception as exc:  # noqa: BLE001 - tifffile raises many kinds on bad files
        detail = one_line(exc) or type(exc).__name__
        if isinstance(exc, _SLIPS):
            # Not tifffile's own complaint but a slip of its code on values no TIFF holds
            # ("integer division or modulo by zero", a bare AssertionError).
            slip = type(exc).__name__ + (f": {one_line(exc)}" if one_line(exc) else "")
            detail = f"corrupt file: its header or tags do not hold together ({slip})"
        if "imagecodecs" in detail:
            # LZW and most other compressions: tifffile decodes them with imagecodecs.
            detail += " (pip install imagecodecs, or the extra: pip install 'parc[tiff]')"
        raise InputError(f"{path}: cannot read TIFF file: {detail}") from None


def _grey_pages(tif, path, *, series=True):
    """The first page of an open TIFF file, after checking it holds grey-level images (and,
    with ``series``, that tifffile makes a series of them)."""
    if len(tif.pages) == 0 or (series and not tif.series):
        raise InputError(f"{path}: no readable image in this TIFF file")
    page = tif.pages[0]
    if page.samplesperpixel > 1:
        raise InputError(f"{path}: TIFF pages hold {page.samplesperpixel} samples per pixel (colour or "
                         "channels); a volume needs one grey value per pixel")
    return page


def _check_shaped(tif, series, path):
    """Refuse a file whose tifffile description (``{"shape": [...]}``) and pages disagree.

    With more slices stated than pages, tifffile reads the stated samples on from the first
    page's data, through the tags after them (garbage slices); with its chain of pages broken,
    it falls back to the pages it can join, and a slice goes missing."""
    if not tif.is_shaped:
        return
    stated = (tif.shaped_metadata or ({},))[0]
    if series.kind in ("generic", "uniform") and len(tif.series) > 1 and _first_shape(tif) != tuple(series.shape):
        # tifffile found the stated shape wrong and split the pages: the first part is not the
        # stack. (A first series of the shape the first page states is: a page after the stack
        # without the description, a thumbnail another writer added, drops it to "generic" too.)
        raise InputError(f"{path}: its {len(tif.pages)} pages do not make the shape its description "
                         "states, and split into several series (corrupt or edited)")
    if (series.kind == "shaped" and not stated.get("truncated")
            and len(series.pages) * series.keyframe.size < math.prod(series.shape)):
        raise InputError(f"{path}: its description states the shape {series.shape}, more samples than its "
                         f"{len(tif.pages)} pages hold (corrupt or edited)")


def _is_slice(page):
    """Whether ``page`` may be a slice: not a reduced-size image (thumbnail, NewSubfileType 1)
    nor a transparency mask (4)."""
    return not getattr(page, "subfiletype", 0) & 0b101


def _check_gapless(tif, series, path):
    """Refuse a stack whose pages lie among full-size pages of another size or type.

    Without metadata naming its pages, tifffile makes its first series of the pages like the
    first, wherever they lie, and leaves the others out: pages of two sizes taking turns read
    as half the slices. Pages after the stack (a page another writer added), reduced-size
    pages (thumbnails) and transparency masks are left out. OME, ImageJ and LSM metadata
    name the pages of each image, which may take turns with another image's."""
    if series.kind != "generic":
        return
    indices = [p.index for p in series.pages if p is not None]
    if not indices or len(indices) == indices[-1] - indices[0] + 1:
        return
    between = sorted(set(range(indices[0], indices[-1] + 1)) - set(indices))
    other = next((i for i in between if _is_slice(tif.pages[i])), None)
    if other is not None:
        raise InputError(f"{path}: its TIFF pages differ in size or sample type (page {other + 1} of "
                         f"{len(tif.pages)} is not like page {indices[0] + 1}); a stack needs equal pages")


def _check_uniform(tif, series, path):
    """Refuse a stack whose pages are not all like the first.

    tifffile makes one series of a file's pages when its second, eighth and last pages are like
    the first, and reads every page with the first's size, type and compression: a page twice as
    tall would lose its lower half, a 16-bit page come back as twice as many 8-bit samples."""
    if series.kind != "uniform":
        return
    first = _decoding_entries(tif, series.keyframe)
    for page in series.pages:
        # Equal entries are equal pages; others may still be (a value stored elsewhere, other
        # padding, a default written out): tifffile's own reading of the page decides.
        if page is None or _decoding_entries(tif, page) == first or page.aspage().hash == series.keyframe.hash:
            continue
        raise InputError(f"{path}: its TIFF pages differ in size, sample type or compression (page "
                         f"{page.index + 1} of {len(tif.pages)} is not like page 1); a stack needs equal pages")


#: The tags that decide how tifffile decodes a page (`TiffPage.hash`): its size and samples,
#: strips or tiles, compression and predictor.
_DECODING_TAGS = frozenset({256, 257, 258, 259, 262, 266, 277, 278, 284, 317, 322, 323, 338, 339, 530,
                            32997, 32998})


def _decoding_entries(tif, page):
    """``{code: raw entry}`` of `_DECODING_TAGS` in ``page``'s IFD: type, count, and the value (or
    where it is stored), as the file holds them."""
    tiff, fh = tif.tiff, tif.filehandle
    fh.seek(page.offset)
    count = struct.unpack(tiff.tagnoformat, fh.read(tiff.tagnosize))[0]
    raw = fh.read(count * tiff.tagsize)
    code = tiff.byteorder + "H"
    return {struct.unpack_from(code, raw, at)[0]: raw[at + 2:at + tiff.tagsize]
            for at in range(0, len(raw) - tiff.tagsize + 1, tiff.tagsize)
            if struct.unpack_from(code, raw, at)[0] in _DECODING_TAGS}


def _first_shape(tif):
    """The shape the first page's tifffile description states, or None."""
    try:
        return tuple(int(n) for n in json.loads(tif.pages[0].description)["shape"])
    except Exception:  # noqa: BLE001 - any description that is not such JSON
        return None


def _described_one_by_one(tif):
    """The file's slices when each one's tifffile description states that page alone, as tifffile
    writes pages one at a time (``TiffWriter.write`` of each slice); otherwise None.

    tifffile makes each such page a series of its own, and sorts them in time quadratic in their
    number (minutes for tens of thousands of pages); its first series is the first page, and the
    stack all the slices, which are read here without the series. Reduced-size pages (thumbnails)
    and transparency masks are no slices, described or not (as in `_check_gapless`). A slice with
    another description, or none, gives other series (`_check_shaped`)."""
    if len(tif.pages) < 2 or not _states_itself(tif.pages[0]):
        return None
    pages = [p for p in tif.pages if _is_slice(p)]
    return pages if len(pages) > 1 and all(_states_itself(p) for p in pages) else None


def _states_itself(page):
    """Whether ``page``'s tifffile description (``{"shape": [y, x]}``) states that page alone."""
    if page.subifds or page.shaped_description is None:
        return False
    try:
        stated = json.loads(page.shaped_description)
        shape = tuple(int(n) for n in stated["shape"])
    except Exception:  # noqa: BLE001 - any description that is not such JSON
        return False
    return shape == page.shape and stated.get("axes", page.axes) == page.axes


def _stack(tifffile, tif, path):
    """``(data [z, y, x], axes, spacing, note, meta)`` of an open TIFF file."""
    pages = _described_one_by_one(tif)
    if pages:
        page = _grey_pages(tif, path, series=False)
        data, axes = _every_page(tifffile, tif, page, pages, path), "Z" + page.axes
    else:
        page = _grey_pages(tif, path)
        series = tif.series[0]
        _check_shaped(tif, series, path)
        _check_gapless(tif, series, path)
        _check_uniform(tif, series, path)
        axes = series.axes
        _check_decoding(tifffile, tif, series.pages, series.shape, series.dtype, path)
        data = series.asarray()
        if data.ndim == 2 and len(tif.pages) > 1:
            data, axes = _every_page(tifffile, tif, page, list(tif.pages), path), "Z" + axes
    keep = [i for i, n in enumerate(data.shape) if n != 1]
    shape = " x ".join(f"{n} {a}" for n, a in zip(data.shape, axes))
    if len(keep) < 3:
        raise InputError(f"{path}: a single 2-D image ({shape}), not a stack of slices")
    if len(keep) > 3:
        raise InputError(f"{path}: TIFF axes {shape}: a volume needs 3 (z, y, x); "
                         "save one channel and time point as its own stack")
    data = data.reshape([data.shape[i] for i in keep])
    axes = "".join(axes[i] for i in keep)
    if axes[0] == "C":
        raise InputError(f"{path}: the stack's slices are channels ({shape}), not z slices")
    spacing, note, meta = _spacing(tif, path)
    return data, axes, spacing, note, meta


def _every_page(tifffile, tif, page, pages, path):
    """The file's ``pages`` stacked in file order [z, y, x], all of ``page``'s shape and type."""
    if any(p.shape != page.shape or p.dtype != page.dtype for p in pages):
        raise InputError(f"{path}: its {len(pages)} TIFF pages differ in size or sample type; "
                         "a stack needs equal pages")
    _check_decoding(tifffile, tif, pages, (len(pages), *page.shape), page.dtype, path)
    return np.stack([p.asarray() for p in pages])


#: Compressions that tifffile decodes, without imagecodecs, with Python's own decompressors or
#: its own PackBits loop: each strip or tile inflated whole, however far past its size, and
#: then cut to it.
_STREAMS = {8: "deflate", 32946: "deflate", 50013: "deflate", 34925: "LZMA", 32773: "PackBits",
            50000: "Zstandard", 34926: "Zstandard"}


def _check_decoding(tifffile, tif, pages, shape, dtype, path):
    """Refuse, before tifffile decodes ``pages`` (the samples of a stack of ``shape`` and ``dtype``),
    samples more than the memory available, and a compressed strip or tile that decodes to more
    than its size.

    A compressed (or empty) strip holds far fewer bytes than it decodes to: a file of a few
    hundred bytes stated 3 GB of samples. And decoded whole, a 1 MB strip of deflated zeros
    took 1 GB and 13 s for a 16x16 page, once for every page that names it."""
    pages = [p for p in pages if p is not None]
    largest = 0
    seen = set()
    for number, page in enumerate(pages, 1):
        key = getattr(page, "keyframe", None) or page
        kind = _STREAMS.get(int(key.compression))
        if kind not in _DECOMPRESSORS or not _decoded_whole(tifffile, key.compression):
            continue            # Zstandard before Python 3.14: tifffile cannot decode it either
        most = _segment_bytes(key)
        largest = max(largest, most)
        # An OME-TIFF's pages may lie in the other files of its set (closed until tifffile reads
        # them): their offsets are there.
        fh = getattr(getattr(page, "parent", None), "filehandle", None) or tif.filehandle
        reopened = fh.closed
        if reopened:
            fh.open()
        try:
            for offset, size in zip(page.dataoffsets, page.databytecounts):
                if not offset or not size or (id(fh), offset, size, most) in seen:
                    continue
                seen.add((id(fh), offset, size, most))
                fh.seek(offset)
                data = fh.read(max(min(size, fh.size - offset), 0))
                if _decoded_length(kind, data, most) > most:
                    raise InputError(f"{path}: page {number}: one of its {kind} strips or tiles decodes to more "
                                     f"than the {most} bytes the page states for it (corrupt, or made to exhaust "
                                     "memory)")
        finally:
            if reopened:
                fh.close()
    need = math.prod(int(n) for n in shape) * np.dtype(dtype).itemsize + largest
    check_memory(need, f"{path}: a {'x'.join(str(int(n)) for n in shape[::-1])} {np.dtype(dtype).name} stack")


def _decoded_whole(tifffile, compression):
    """Whether tifffile decodes ``compression`` with a stand-in of its own, which decodes a
    strip or tile whole; imagecodecs (when installed) decodes into the size tifffile gives it."""
    try:
        codec = tifffile.TIFF.DECOMPRESSORS[compression]
    except KeyError:
        return False            # not decoded at all: tifffile says why
    except Exception:  # noqa: BLE001 - a tifffile without that table
        return True
    return not str(getattr(codec, "__module__", "")).startswith("imagecodecs")


def _segment_bytes(page):
    """The bytes a whole strip or tile of ``page`` decodes to (the last strip's rows all)."""
    bits = page.bitspersample
    bits = max(bits) if isinstance(bits, tuple) else int(bits)
    samples = page.samplesperpixel if page.planarconfig == 1 else 1
    if page.is_tiled:
        pixels = page.tiledepth * page.tilelength * page.tilewidth
    else:
        pixels = min(max(page.rowsperstrip, 1), page.imagelength) * page.imagewidth
    return pixels * samples * -(-bits // 8)


def _decoded_length(kind, data, most):
    """The bytes ``data`` decode to, counted to ``most + 1`` at most; data that do not decode
    count as far as they do (tifffile then says what is wrong with them)."""
    if kind == "PackBits":
        return _packbits_length(data, most)
    total = 0
    while data and total <= most:
        stream = _DECOMPRESSORS[kind]()
        try:
            total += len(stream.decompress(data, max_length=most + 1 - total))
        except _CODEC_ERRORS:
            break
        # Python's zlib.decompress reads one stream; lzma's and zstd's read on into the next.
        if not stream.eof or kind == "deflate":
            break
        data = stream.unused_data
    return total


def _packbits_length(data, most):
    """The bytes PackBits ``data`` decode to, counted as tifffile's own decoder decodes them
    (a run cut short by the end gives what is left of it), to ``most + 1`` at most."""
    total, at, end = 0, 0, len(data)
    while at < end and total <= most:
        head = data[at]
        at += 1
        if head < 128:
            total += min(head + 1, end - at)
            at += head + 1
        elif head > 128:
            total += 257 - head if at < end else 0
            at += 1
    return total


#: The decompressors of `_STREAMS` here (PackBits is counted by `_packbits_length`).
_DECOMPRESSORS = {"deflate": zlib.decompressobj, "LZMA": lzma.LZMADecompressor, "PackBits": None}
_CODEC_ERRORS = (zlib.error, lzma.LZMAError, EOFError, ValueError)
try:
    from compression import zstd as _zstd          # Python 3.14 on: tifffile's stand-in for Zstandard
except ImportError:
    _zstd = None
if _zstd is not None:
    _DECOMPRESSORS["Zstandard"] = _zstd.ZstdDecompressor
    _CODEC_ERRORS += (_zstd.ZstdError,)


#: OME's length units as powers of ten of a metre (its default is µm; the micro sign comes in
#: two code points). Whole powers, so that 2 µm is 2000 nm exactly.
_OME_POWERS = {"m": 0, "dm": -1, "cm": -2, "mm": -3, "µm": -6, "μm": -6, "um": -6, "nm": -9, "Å": -10,
               "pm": -12}


def _spacing(tif, path):
    """``(spacing (x, y, z), note, meta)`` from OME or ImageJ metadata."""
    if tif.is_ome and tif.ome_metadata:
        found, units = {}, {}
        for a in "XYZ":
            m = re.search(rf'PhysicalSize{a}="([^"]+)"', tif.ome_metadata)
            if m:
                found[a] = _positive(m.group(1))
                u = re.search(rf'PhysicalSize{a}Unit="([^"]+)"', tif.ome_metadata)
                units[a] = u.group(1) if u else "µm"
        unit = units.get("X", next(iter(units.values()), "µm"))
        meta = {"unit": unit}
        for a, u in units.items():
            # Each axis may have its own unit (nm across, µm between slices): all go to x's.
            if u != unit and found[a]:
                if u not in _OME_POWERS or unit not in _OME_POWERS:
                    # Said, not refused: a spacing given replaces it, and its note.
                    return (1.0, 1.0, 1.0), (f"the TIFF gives voxel sizes in {unit} and {u}, which cannot be "
                                             "converted: spacing 1, 1, 1 (give --spacing SX,SY,SZ)"), meta
                k = _OME_POWERS[u] - _OME_POWERS[unit]
                found[a] = found[a] * 10 ** k if k >= 0 else found[a] / 10 ** -k
        if all(found.get(a) for a in "XYZ"):
            return (found["X"], found["Y"], found["Z"]), None, meta
        return _partial(found, meta)
    if tif.is_imagej:
        ij = tif.imagej_metadata or {}
        page = tif.pages[0]
        found = {"Z": _positive(ij.get("spacing"))}
        unit = ij.get("unit", "pixel")
        resunit = int(getattr(page.tags.get("ResolutionUnit"), "value", _RESUNIT_NONE))
        # Pixels per unit: ImageJ's own unit, or (when it is cm or inch) the tag's.
        scale = 1.0 if resunit == _RESUNIT_NONE else _IMAGEJ_RESOLUTION.get((resunit, unit))
        if scale is not None:
            for a, tag in (("X", "XResolution"), ("Y", "YResolution")):
                res = page.tags.get(tag)
                if res is not None:
                    num, den = res.value
                    found[a] = _positive(scale * den / num) if num else None
        meta = {"unit": unit}
        if all(found.get(a) for a in "XYZ"):
            return (found["X"], found["Y"], found["Z"]), None, meta
        return _partial(found, meta)
    # A plain TIFF's resolution tags are a print size (72 dots an inch), with no slice distance.
    return (1.0, 1.0, 1.0), ("the TIFF gives no voxel size (no ImageJ or OME metadata): spacing 1, 1, 1 "
                             "(give --spacing SX,SY,SZ)"), {}


#: TIFF ResolutionUnit inch (2) or cm (3), with ImageJ's unit: that unit's lengths per
#: ResolutionUnit (ImageJ writes cm and inch this way).
_IMAGEJ_RESOLUTION = {(2, "inch"): 1.0, (3, "cm"): 1.0, (3, "mm"): 10.0, (2, "cm"): 2.54}


def _partial(found, meta):
    spacing = tuple(found.get(a) or 1.0 for a in "XYZ")
    missing = ", ".join(a.lower() for a in "XYZ" if not found.get(a))
    return spacing, f"the TIFF gives no voxel size along {missing}: 1 was used (give --spacing SX,SY,SZ)", meta


def _positive(value):
    """``value`` as a positive finite float, or None."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return None
    return v if np.isfinite(v) and v > 0 else None


def read_tiff_folder(path, *, spacing=None, origin=None) -> Volume:
    """Read a folder of single-slice TIFF files (an image sequence) as a volume.

    The slices are the folder's ``.tif``/``.tiff`` files in natural order
    (``z2`` before ``z10``), one z slice each, all of one shape and type.
    Spacing along x and y comes from the first slice's ImageJ or OME
    metadata where it has some; along z the files say nothing, so it is 1
    and ``meta['note']`` says so (give ``spacing``).

    Parameters
    ----------
    path : str or Path
        The folder.
    spacing, origin : (x, y, z), optional
        Replace the file's, before the Volume checks them (`data_tools.io._common.file_volume`).

    Returns
    -------
    Volume
    """
    given = {"spacing": spacing, "origin": origin}     # the names are the file's own below
    path = Path(path)
    # Hidden files are no slices: macOS leaves "._slice001.tif" beside each slice copied to a
    # disk of another kind (its own attributes, not a TIFF).
    files = sorted((f for f in path.iterdir()
                    if f.suffix.lower() in EXTENSIONS and not f.name.startswith(".") and f.is_file()),
                   key=lambda f: _natural_key(f.name))
    if not files:
        if any(f.suffix.lower() in _DICOM for f in path.iterdir()):
            raise InputError(f"{path}: a DICOM series is not read here; convert it to NRRD or NIfTI first "
                             "(e.g. with dcm2niix)")
        raise InputError(f"{path}: is a folder with no .tif slices, not a volume file")
    if len(files) < 2:
        raise InputError(f"{path}: holds one .tif slice ({files[0].name}); a volume needs at least 2")
    tifffile = optional_library("tifffile", path, "TIFF", "tiff")
    slices = []
    spacing = (1.0, 1.0, 1.0)
    for n, f in enumerate(files):
        with _reading_tiff(f), tifffile.TiffFile(str(f)) as tif:
            _grey_pages(tif, f)
            series = tif.series[0]
            # The first slice's size stands for all of them (others are refused below).
            shape = (len(files), *series.shape) if n == 0 else series.shape
            _check_decoding(tifffile, tif, series.pages, shape, series.dtype, f)
            image = series.asarray()
            if n == 0:
                spacing, _, _ = _spacing(tif, f)
        image = image.reshape([d for d in image.shape if d != 1] or [1])
        if image.ndim != 2:
            raise InputError(f"{f}: holds a {image.ndim}-D image; a folder of slices needs one 2-D image a file")
        if slices and (image.shape != slices[0].shape or image.dtype != slices[0].dtype):
            raise InputError(f"{f}: {image.shape[1]}x{image.shape[0]} {image.dtype}, but {files[0].name} is "
                             f"{slices[0].shape[1]}x{slices[0].shape[0]} {slices[0].dtype}; slices must match")
        slices.append(to_native(image))
    note = (f"{len(files)} slices; the files give no spacing between them: 1 was used along z "
            "(give --spacing SX,SY,SZ)")
    meta = {"format": "tiff slices", "files": len(files), "spacing_note": note}
    return file_volume(np.stack(slices), (spacing[0], spacing[1], 1.0), (0.0, 0.0, 0.0), path, meta, given)


def _natural_key(name):
    """Sort key that orders the numbers in a name by value: ``z2`` before ``z10``."""
    return [(0, int(part), "") if part.isdigit() else (1, 0, part.lower()) for part in re.split(r"(\d+)", name)]

