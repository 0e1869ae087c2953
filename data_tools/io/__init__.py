"""Volume files in and out: ``load_volume`` and ``save_volume`` dispatch on the extension."""
from __future__ import annotations

import errno
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ..errors import InputError, os_reason
from ..signals import signals_held
from ..volume import Volume
from . import metaimage, nifti, npy, nrrd_format, raw, slc, tiff, vtk_legacy
from ._common import check_file, reading
from .raw import headers_reading

_READERS = {}
for _mod, _fn in ((nrrd_format, nrrd_format.read_nrrd), (metaimage, metaimage.read_metaimage),
                  (vtk_legacy, vtk_legacy.read_vtk), (slc, slc.read_slc),
                  (npy, npy.read_npy), (nifti, nifti.read_nifti), (tiff, tiff.read_tiff),
                  (raw, raw.read_raw)):
    for _ext in _mod.EXTENSIONS:
        _READERS[_ext] = _fn

#: Extensions ``load_volume`` reads (lower case; matching ignores case).
READ_EXTENSIONS = tuple(_READERS)
#: Extensions ``save_volume`` writes.
WRITE_EXTENSIONS = (".nrrd", ".nhdr", ".npy", ".mhd", ".mha", ".vtk", ".raw")
#: Options only a headerless raw file takes.
RAW_ONLY_OPTIONS = ("shape", "dtype", "byte_order", "offset", "mmap")


def volume_extension(path) -> str:
    """The extension that names a volume file's format, lower case: ``.nii.gz`` counts as one."""
    name = Path(path).name.lower()
    for ext in READ_EXTENSIONS:
        if "." in ext[1:] and name.endswith(ext):
            return ext
    return Path(path).suffix.lower()


def load_volume(path, **options) -> Volume:
    """Read a volume file, choosing the reader by extension (case-insensitive).

    Parameters
    ----------
    path : str, Path or ndarray
        ``.nrrd``/``.nhdr``, ``.mhd``/``.mha``, ``.vtk``, ``.slc``, ``.npy``,
        ``.nii``/``.nii.gz`` (needs nibabel), ``.tif``/``.tiff`` stacks (needs
        tifffile), a folder of single-slice ``.tif`` files (an image
        sequence, in natural order), or headerless ``.raw``/``.bin``/``.dat``.
        Or samples already in memory, an array ``(nz, ny, nx)``: a `Volume` of
        it with the ``spacing`` and ``origin`` given (else 1 and 0). The
        Volume keeps a copy of an array that could still be written, so a
        change to it afterwards reaches neither the samples nor what was
        worked out from them (the value range, PARC's cell ranges); one
        read-only all the way down, of a supported type in C order and the
        machine's byte order, is used in place, and so is a memory map,
        which must then not change (see `Volume`).
    **options
        For raw files: ``shape=(nx, ny, nz)``, ``dtype``, ``byte_order``,
        ``offset``, ``mmap`` (see `data_tools.io.raw.read_raw`). ``spacing`` and
        ``origin`` apply to every format and replace what the file says.
        Options that are ``None`` are ignored.

    Returns
    -------
    Volume
        ``data`` indexed ``[z, y, x]`` in the file's sample type; read from a file,
        ``meta['files']`` the files read (with a header's data file and a ``.npy``'s sidecar).

    Raises
    ------
    InputError
        One line naming the file: missing, unknown extension, bad header,
        size mismatch, truncated or corrupt data, unsupported type.
    TypeError
        An option name that no reader takes (a programming error, not bad input).
    """
    unknown = set(options) - set(RAW_ONLY_OPTIONS) - {"spacing", "origin"}
    if unknown:
        raise TypeError(f"load_volume() got unexpected options {sorted(unknown)}")
    if isinstance(path, np.ndarray):
        return _from_array(path, options)
    if isinstance(path, (str, bytes)) and not path:
        # Path("") is the current folder, read as a folder of TIFF slices.
        raise InputError("the volume path is empty; give a volume file")
    try:
        path = Path(path)
    except TypeError:
        raise InputError(f"load_volume takes a file's path or a NumPy array, got {type(path).__name__}") from None
    options = {k: v for k, v in options.items() if v is not None and not (k == "mmap" and not v)}
    _check_nameable(path)
    if path.is_dir():
        reader, kind = tiff.read_tiff_folder, "TIFF"
    else:
        reader, kind = _file_reader(path)
    if reader is raw.read_raw:
        with reading(path, kind):
            return _read_from(raw.read_raw(path, **options), path)
    extra = sorted(set(options) - {"spacing", "origin"})
    if extra:
        # mmap is load_volume's alone: the others are also parc's flags, and are named as such.
        flags = ", ".join(k if k == "mmap" else "--" + k.replace("_", "-") for k in extra)
        verb = "applies" if len(extra) == 1 else "apply"
        raise InputError(f"{path}: {flags} {verb} only to headerless raw files; this file has a header")
    with reading(path, kind):
        # The readers place the samples by the spacing and origin given, before the Volume's
        # checks: a header value those would refuse is what a user overrides.
        return _read_from(reader(path, **options), path)


def _from_array(data, options):
    """A volume of samples already in memory, ``(nz, ny, nx)``: the file reader's way in for
    code that holds an array, with the same ``spacing`` and ``origin`` options."""
    given = {k: v for k, v in options.items() if v is not None and not (k == "mmap" and not v)}
    extra = sorted(set(given) - {"spacing", "origin"})
    if extra:
        raise InputError(f"load_volume: {', '.join(extra)} {'describes' if len(extra) == 1 else 'describe'} "
                         "a raw file's bytes; an array in memory takes only spacing and origin")
    return Volume(data, name="array", **given)


def _read_from(vol, path):
    """``vol`` with ``meta['files']``: every file it was read from (the file named, a header's
    detached data file or files, a sidecar), which the command line never writes over."""
    named = (path, vol.meta.get("data_file"), *vol.meta.get("data_files", ()), vol.meta.get("sidecar"))
    vol.meta["files"] = tuple(str(p) for p in named if p)
    return vol


def _file_reader(path):
    """``(reader, kind)`` for a volume file, after the checks every file gets."""
    ext = volume_extension(path)
    if ext not in _READERS:
        if not path.exists():
            check_file(path)
        kind = f"type '{path.suffix}'" if path.suffix else "type (no extension)"
        raise InputError(f"{path}: unknown volume file {kind}; "
                         f"supported: {', '.join(READ_EXTENSIONS)}")
    check_file(path)
    if path.stat().st_size == 0:
        raise InputError(f"{path}: file is empty")
    reader = _READERS[ext]
    return reader, "raw" if reader is raw.read_raw else ext.split(".")[1].upper()


def data_file_written(path):
    """The detached data file `save_volume` writes beside ``path`` (``.mhd``, ``.nhdr``: the
    same name with ``.raw``), or None."""
    path = Path(path)
    return path.with_suffix(".raw") if path.suffix.lower() in (".mhd", ".nhdr") else None


#: The options each writer takes, and what each may be: a request it cannot honour is refused,
#: not dropped (``compress="no"`` wrote gzip, ``byte_order="BIG"`` little-endian).
_WRITE_OPTIONS = {".nrrd": {"compress": bool}, ".nhdr": {"compress": bool}, ".npy": {"sidecar": (bool, None)},
                  ".mhd": {"byte_order": ("little", "big")}, ".mha": {"byte_order": ("little", "big")},
                  ".vtk": {"ascii": bool}, ".raw": {"byte_order": ("little", "big", None)}}


def _check_write_options(ext, options):
    allowed = _WRITE_OPTIONS[ext]
    for name, value in options.items():
        spec = allowed.get(name)
        if spec is None:
            raise InputError(f"{ext} files take the option{'s' if len(allowed) > 1 else ''} "
                             f"{', '.join(allowed)}; got {name}")
        if spec is bool:
            ok, want = isinstance(value, (bool, np.bool_)), "True or False"
        elif spec == (bool, None):
            ok, want = value is None or isinstance(value, (bool, np.bool_)), "True, False or None"
        else:
            ok = (value is None and None in spec) or (isinstance(value, str) and value in spec)
            want = " or ".join(repr(v) for v in spec)
        if not ok:
            raise InputError(f"{name} must be {want}, got {value!r}")


def _check_nameable(path):
    """Refuse a path the system cannot name a file by: a NUL in it (Python raises ValueError) or
    a name too long (OSError), where the readers and writers expect neither."""
    if "\0" in str(path):
        raise InputError(f"{path}: a file's path cannot hold a NUL character")
    try:
        path.exists()
    except OSError as exc:
        raise InputError(f"{path}: {os_reason(exc)}") from None


def save_volume(volume: Volume, path, **options) -> Path:
    """Write ``volume`` to ``path`` in the format its extension names, all or nothing.

    Files are written in a temporary folder beside ``path`` and moved into
    place at the end (companion files first, ``path`` last), so a failure
    leaves no half-written output and companions keep their final names.

    Parameters
    ----------
    volume : Volume
    path : str or Path
        ``.nrrd`` (gzip; ``compress=False`` for raw encoding), ``.nhdr``
        (+ ``.raw``), ``.npy`` (+ ``.npy.json`` sidecar for spacing and
        origin when they are not the defaults or a sidecar exists), ``.mhd``
        (+ ``.raw``), ``.mha``, ``.vtk``, ``.raw`` (samples only).
    **options
        Passed to the writer: ``compress`` (NRRD), ``byte_order`` (MetaImage,
        raw), ``ascii`` (VTK), ``sidecar`` (NumPy: True always writes the
        ``.npy.json``, False never, refused when the spacing or origin is not
        the default; None, the default, as above).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    InputError
        Unknown extension, or the file cannot be written.
    """
    if not isinstance(volume, Volume):
        raise InputError(f"save_volume takes a Volume, got {type(volume).__name__}; "
                         "wrap samples as Volume(array, spacing=..., origin=...)")
    if not isinstance(path, (str, os.PathLike)) or isinstance(os.fspath(path), bytes):
        raise InputError(f"save_volume takes a file's path, got {type(path).__name__}")
    path = Path(path)
    _check_nameable(path)
    ext = path.suffix.lower()
    writers = {".nrrd": nrrd_format.write_nrrd, ".nhdr": nrrd_format.write_nrrd, ".npy": npy.write_npy,
               ".mhd": metaimage.write_metaimage, ".mha": metaimage.write_metaimage,
               ".vtk": vtk_legacy.write_vtk, ".raw": raw.write_raw}
    if ext not in writers:
        kind = f"'{path.suffix}' files" if path.suffix else "files without an extension"
        raise InputError(f"{path}: cannot write {kind}; "
                         f"supported: {', '.join(WRITE_EXTENSIONS)}")
    _check_write_options(ext, options)
    if ext == ".raw":
        raw.check_name(volume, path, options.get("byte_order"))
    given, path = path, written_path(path)
    if ext in (".mhd", ".nhdr"):
        _check_data_file_name(given, path)
    if ext == ".npy":
        plain = volume.spacing == (1.0, 1.0, 1.0) and volume.origin == (0.0, 0.0, 0.0)
        if options.get("sidecar") is False and not plain:
            raise InputError(f"{given}: sidecar=False would lose the spacing {volume.spacing} and origin "
                             f"{volume.origin}; a .npy file keeps them only in its sidecar")
        sides = dict.fromkeys([npy.sidecar_path(given), npy.sidecar_path(path)])
        for side in sides:
            if side.exists() and not side.is_file():
                raise InputError(f"{side}: the sidecar of {given.name} (its spacing and origin) is not a file")
            if side.exists() and not npy.is_sidecar(side):
                # A run's stats, say: written over, or read back as the volume's sidecar.
                raise InputError(f"{side}: where {given.name}'s sidecar (its spacing and origin) goes, a file "
                                 "of another kind; move it or write elsewhere")
        if len(sides) > 1 and (not plain or npy.sidecar_path(given).exists()):
            # Written beside the file the link leads to, a sidecar is not read through the link.
            raise InputError(f"{given}: a link to {path}; its sidecar {npy.sidecar_path(path).name} would be "
                             f"written beside that, and read through the link it would not be found: "
                             f"write to {path} itself")
        if npy.sidecar_path(path).exists():
            options["sidecar"] = True   # rewrite it, or it would go stale
    tmpdir = None
    failed = given
    try:
        tmpdir = Path(tempfile.mkdtemp(prefix=".parc-", dir=path.parent))
        writers[ext](volume, tmpdir / path.name, **options)
        for f in tmpdir.iterdir():
            if (path.parent / f.name).is_dir():
                # Before any is moved: a header refused after its data file was would leave that behind.
                raise InputError(f"{path.parent / f.name}: is a folder; {given} cannot be written")
        with signals_held(done=str(given)):        # a header and its data file are replaced together
            for f in sorted(tmpdir.iterdir()):
                if f.name != path.name:
                    failed = path.parent / f.name       # a companion: name it, not the header
                    os.replace(f, failed)
            failed = given
            os.replace(tmpdir / path.name, path)
    except OSError as exc:
        written = Path(exc.filename) if exc.filename is not None else None
        if failed is given and written is not None and tmpdir is not None and written.parent == tmpdir:
            failed = path.parent / written.name         # the writer's own file: a header's data file, say
        raise InputError(f"{failed}: cannot write: {os_reason(exc)}") from None
    except UnicodeEncodeError:
        # MetaImage, NRRD and VTK headers are ASCII, and .mhd and .nhdr name their data file.
        raise InputError(f"{path}: a {ext} header names its data file in ASCII; "
                         "choose a name without other characters") from None
    finally:
        if tmpdir is not None:
            shutil.rmtree(tmpdir, ignore_errors=True)
    return given


def _check_data_file_name(given, target):
    """Refuse a ``.mhd`` or ``.nhdr`` header whose data file name its readers would not read
    back (the header names it on a line of its own, relative to its folder): a link to a header
    in another folder (read through the link, the name is looked for beside the link), a name
    with control characters or blanks at either end, or one the readers take for a list of
    data files (``LIST`` as its first word)."""
    name = data_file_written(target).name
    if os.path.realpath(given.parent) != os.path.realpath(target.parent):
        raise InputError(f"{given}: a link to {target}; its data file {name} would be written beside that, "
                         f"and read through the link the header would not find it: write to {target} itself")
    words = name.split()
    if (not name.replace("\t", " ").isprintable() or name != name.strip()
            or (words and words[0].upper() == "LIST" and len(words) <= 2)):
        raise InputError(f"{given}: its header would name the data file {name!r}, which it cannot be read "
                         "back by (control characters, blanks at either end, or LIST, which names a list "
                         "of files); choose another name")


def written_path(path) -> Path:
    """The file a write to ``path`` replaces: a symbolic link's target (made if missing), else
    ``path``. Writes go through a temporary file renamed onto it, and renamed onto the link
    itself they replaced the link with a file. Refused when that is neither a file nor absent
    (nor a folder, which the writers refuse in their own words)."""
    path = Path(path)
    if path.is_symlink():
        try:
            os.stat(path)
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                # realpath stops somewhere in the loop: the rename would replace a link with a file.
                raise InputError(f"{path}: a link in a loop; write elsewhere") from None
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    if target.exists() and not (target.is_file() or target.is_dir()):
        # Renamed onto, a device (/dev/null) or a pipe would be replaced by a file: for root, silently.
        where = f"a link to {target}, " if target != path else ""
        raise InputError(f"{path}: {where}not a regular file (a device, pipe or socket); write to a file")
    return target


__all__ = ["load_volume", "save_volume", "written_path", "data_file_written", "headers_reading", "volume_extension",
           "READ_EXTENSIONS", "WRITE_EXTENSIONS"]
