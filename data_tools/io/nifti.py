"""NIfTI-1 and NIfTI-2 volumes (``.nii``, ``.nii.gz``), read with nibabel.

nibabel is an optional extra (``pip install 'parc[nifti]'``): NIfTI has
two header versions, qform and sform orientations and scaled storage, all
of which nibabel already reads correctly.
"""
from __future__ import annotations

import math
import os
import zlib
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..volume import Volume
from ._common import check_inflatable, file_volume, one_line, optional_library, silenced, to_native

EXTENSIONS = (".nii", ".nii.gz")


def read_nifti(path, *, spacing=None, origin=None) -> Volume:
    """Read a 3-D NIfTI volume (NIfTI-1 or -2, gzipped or not).

    Samples keep their stored type unless the header scales them
    (``scl_slope``/``scl_inter``), in which case they are the scaled values
    as float32. Spacing is the length of each voxel axis in the affine
    (sform, else qform, else the pixel dimensions); origin is the affine's
    translation, the position of voxel (0, 0, 0), or (0, 0, 0) with neither
    form. Rotated or flipped axes
    cannot be kept on an axis-aligned grid: they are reduced to their
    lengths and ``meta['note']`` says so. A 4-D file with one volume (a
    trailing axis of length 1) is read as 3-D.

    Parameters
    ----------
    path : str or Path
    spacing, origin : (x, y, z), optional
        Replace the file's, before the Volume checks them (`data_tools.io._common.file_volume`).

    Returns
    -------
    Volume
    """
    path = Path(path)
    nib = optional_library("nibabel", path, "NIfTI", "nifti")
    with silenced("nibabel.global"):        # its header checks ("pixdim[1,2,3] should be positive")
        return _read(nib, path, {"spacing": spacing, "origin": origin})


def _read(nib, path, given):
    try:
        img = nib.load(str(path), mmap=False)
    except MemoryError:
        raise InputError(f"{path}: not enough memory to load this NIfTI volume") from None
    except Exception as exc:  # noqa: BLE001 - nibabel raises many kinds on bad files
        if str(exc).startswith("Cannot work out file type"):
            # nibabel's words for a header it cannot read as any of its formats.
            raise InputError(f"{path}: not a NIfTI file, or its header is cut short") from None
        raise InputError(f"{path}: cannot read NIfTI file: {one_line(exc) or type(exc).__name__}") from None
    if not isinstance(img, (nib.Nifti1Image, nib.Nifti2Image)):
        raise InputError(f"{path}: not a NIfTI image ({type(img).__name__})")
    header = img.header
    stored = _stored_header(img, path)
    slope = float(stored["scl_slope"])
    if math.isinf(slope):
        # nibabel reads an infinite slope as no scaling, as it reads 0 and NaN; the standard has
        # scaling off only at 0 (NaN is how nibabel writes "none"), and scaled by it, every sample
        # is infinite or NaN. A finite slope with a non-finite scl_inter nibabel refuses itself.
        raise InputError(f"{path}: scl_slope is {slope:g}, not a finite number; the samples cannot be scaled by it "
                         "(0 or NaN: unscaled)")
    start = getattr(img.dataobj, "offset", None)        # where the samples are read from
    if (bytes(header["magic"]).rstrip(b"\0") in (b"n+1", b"n+2") and start is not None
            and start < header.single_vox_offset):
        # nibabel reads a .nii whose vox_offset is 0 from byte 0: its own header as samples.
        raise InputError(f"{path}: vox_offset {start} lies inside the header; a .nii file's samples start at "
                         f"byte {header.single_vox_offset} or later")
    shape = tuple(int(n) for n in img.shape)
    while len(shape) > 3 and shape[-1] == 1:
        shape = shape[:-1]
    if len(shape) != 3:
        # Nothing here picks one: say how to make a file of one (nibabel keeps its placement).
        more = (f"; it holds {int(np.prod(shape[3:]))} volumes: save one as a file of its own "
                f"(in Python: nibabel.save(nibabel.load(path).slicer[..., k], 'one.nii')) "
                "and render that") if len(shape) > 3 else ""
        raise InputError(f"{path}: NIfTI image has shape {img.shape}, expected a 3-D volume{more}")
    _check_length(img, path, start)
    try:
        proxy = img.dataobj
        scaled = _scaled(proxy)
        data = np.asarray(img.get_fdata(dtype=np.float32) if scaled else np.asanyarray(proxy))
    except MemoryError:
        stated = math.prod(int(n) for n in img.shape) * (4 if scaled else img.header.get_data_dtype().itemsize)
        raise InputError(f"{path}: not enough memory to load this NIfTI volume: its header states "
                         f"{'x'.join(str(int(n)) for n in img.shape)} samples, {stated / 1e9:.3g} GB "
                         "(truncated or corrupt, if that is not its size)") from None
    except EOFError:
        # gzip's "Compressed file ended before the end-of-stream marker was reached".
        raise InputError(f"{path}: truncated: the compressed samples end early") from None
    except Exception as exc:  # noqa: BLE001 - truncated or corrupt data
        raise InputError(f"{path}: cannot read NIfTI data: {one_line(exc) or type(exc).__name__}") from None
    # The file stores x fastest, which nibabel gives as an [x, y, z] array in
    # Fortran order: its transpose is [z, y, x] in C order, without a copy.
    data = np.ascontiguousarray(to_native(data.reshape(shape, order="F")).T)
    zooms = img.header.get_zooms()[:3]
    # With neither form (NIfTI's method 1) nibabel's affine is Analyze's: x
    # flipped and the origin at the centre. The standard's is the pixel
    # dimensions alone, from (0, 0, 0).
    has_form = int(img.header["qform_code"]) > 0 or int(img.header["sform_code"]) > 0
    spacing, origin, note, reoriented = _geometry(img.affine if has_form else None, zooms)
    if int(img.header["sform_code"]) <= 0:
        # Without an sform the voxel sizes are pixdim's, which nibabel repairs unsaid on loading
        # (0 to 1, -2 to 2; NaN it keeps, and `_geometry` says so).
        repaired = _pixdim_note(stored["pixdim"][1:4])
        note = "; ".join(n for n in (repaired, note) if n) or None
    meta = {"format": "nifti", "version": 2 if isinstance(img, nib.Nifti2Image) else 1}
    if scaled:
        meta["scaling"] = {"slope": float(proxy.slope), "inter": float(proxy.inter)}
    if note:
        meta["spacing_note"] = note         # `file_volume` says it, or what holds with a spacing given
    if reoriented:
        meta["reoriented"] = True           # a file written from it is no longer in the same place
    return file_volume(data, spacing, origin, path, meta, given)


def _stored_header(img, path):
    """The header as the file stores it. The image's own has its scl_slope set to NaN once
    nibabel has taken the scaling into its array proxy (which holds 1 for a slope it reads as
    none), and its pixdim repaired."""
    try:
        with img.file_map["image"].get_prepare_fileobj(mode="rb") as f:
            return img.header_class.from_fileobj(f, check=False)
    except Exception as exc:  # noqa: BLE001 - as in _read: nibabel raises many kinds
        raise InputError(f"{path}: cannot read NIfTI file: {one_line(exc) or type(exc).__name__}") from None


def _pixdim_note(pixdims):
    """What was made of voxel sizes ``pixdim[1:4]`` that are 0 or negative, or None."""
    said = [f"voxel size {size:g} along {axis} (pixdim); {abs(size) if size else 1:g} was used"
            for axis, size in zip("xyz", (float(d) for d in pixdims)) if size <= 0]
    return f"the header gives {'; '.join(said)}" if said else None


def _check_length(img, path, start):
    """Refuse an uncompressed file shorter than its header's samples before nibabel allocates
    them: a truncated file whose header claims a huge volume failed as out of memory."""
    name = img.file_map["image"].filename
    if start is None or name is None:
        return
    shape = tuple(int(n) for n in img.shape)
    dtype = img.header.get_data_dtype()
    need = int(start) + math.prod(shape) * dtype.itemsize
    if str(name).lower().endswith(".gz"):
        _check_gzip(name, path, need, f"{'x'.join(map(str, shape))} {dtype.name}")
        # Inflated above a piece at a time, and let go: nibabel's array of them is asked for next.
        check_inflatable(path, shape, dtype)
        return
    size = os.stat(name).st_size
    if size < need:
        raise InputError(f"{path}: truncated: its header's {'x'.join(map(str, shape))} {dtype.name} samples need "
                         f"{need} bytes, the file has {size}")


def _scaled(proxy):
    """Whether the stored samples are scaled (slope other than 1, or an intercept)."""
    slope = getattr(proxy, "slope", 1.0)
    inter = getattr(proxy, "inter", 0.0)
    return (np.isfinite(slope) and slope not in (0.0, 1.0)) or (np.isfinite(inter) and inter != 0.0)


def _geometry(affine, zooms):
    """``(spacing, origin, note, reoriented)`` from the voxel-to-world affine (4x4); ``reoriented``:
    rotated or flipped axes were laid on the axis-aligned grid."""
    a = np.asarray(affine if affine is not None else np.full((4, 4), np.nan), dtype=np.float64)
    if a.shape != (4, 4) or not np.isfinite(a).all():
        a = np.diag([*(float(z) for z in zooms), 1.0])
    m = a[:3, :3]
    lengths = np.linalg.norm(m, axis=0)          # column c: the step of voxel axis c
    note = None
    if not (lengths > 0).all():
        lengths = np.where(lengths > 0, lengths, 1.0)
        note = "the header gives a voxel axis no length; spacing 1 was used for it"
    off = m - np.diag(np.diag(m))
    rotated, flipped = np.abs(off).max() > 1e-6 * lengths.max(), (np.diag(m) < 0).any()
    if rotated:
        note = ("rotated voxel axes were reduced to axis-aligned spacings "
                f"(their lengths {tuple(round(float(n), 6) for n in lengths)}); orientation is ignored")
    elif flipped:
        note = "flipped voxel axes (negative affine diagonal) were reduced to positive spacings"
    return tuple(float(n) for n in lengths), tuple(float(v) for v in a[:3, 3]), note, bool(rotated or flipped)


def _check_gzip(name, path, need, samples):
    """Refuse a gzip stream that is corrupt before or after the samples. nibabel inflates only
    up to the samples' end and stops, so a damaged stream would give wrong samples silently:
    gzip's check (CRC-32 and length) comes at the end of the stream, after them. Inflated a
    piece at a time and discarded, to the end of the stream or a little past the samples."""
    inflate = zlib.decompressobj(zlib.MAX_WBITS | 16)
    total = 0
    with open(name, "rb") as f:
        while total <= need + (1 << 16):
            if inflate.eof:
                if total >= need:
                    break
                # Another member follows (``cat a.gz b.gz``, bgzip): Python's gzip reader, which
                # nibabel uses, reads on into it, as does teem's for NRRD (`nrrd_format._decode`).
                chunk = inflate.unused_data
                if len(chunk) < 2:
                    chunk += f.read(1 << 20)
                if not chunk.startswith(b"\x1f\x8b"):
                    break
                inflate = zlib.decompressobj(zlib.MAX_WBITS | 16)
            else:
                chunk = inflate.unconsumed_tail or f.read(1 << 20)
            if not chunk:
                raise InputError(f"{path}: truncated: the compressed samples end early")
            try:
                total += len(inflate.decompress(chunk, 1 << 24))
            except zlib.error as exc:
                raise InputError(f"{path}: corrupt compressed data ({one_line(exc)})") from None
    if total < need:
        raise InputError(f"{path}: truncated: its header's {samples} samples need {need} bytes, the compressed "
                         f"data hold {total}")
