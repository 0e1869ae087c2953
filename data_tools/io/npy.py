"""NumPy ``.npy`` volumes, with an optional JSON sidecar for spacing and origin."""
from __future__ import annotations

import json
import math
import os
import tokenize
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..volume import Volume
from ..jsontext import RepeatedKey, strict_json
from ._common import file_volume, one_line, reading

EXTENSIONS = (".npy",)


def sidecar_path(path) -> Path:
    """Where the spacing/origin sidecar of ``path`` lives: ``vol.npy`` → ``vol.npy.json``."""
    path = Path(path)
    return path.with_name(path.name + ".json")


def read_npy(path, *, spacing=None, origin=None) -> Volume:
    """Read a 3-D ``.npy`` array indexed ``[z, y, x]``.

    Spacing and origin come from ``<path>.json`` (keys ``spacing``,
    ``origin``, each ``[x, y, z]``) when it exists, else ``(1, 1, 1)`` and
    ``(0, 0, 0)``; with both given, the sidecar is not read.

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
    with reading(path, "NumPy"):
        with open(path, "rb") as f:
            if f.read(6) != b"\x93NUMPY":
                raise InputError(f"{path}: not a NumPy .npy file (bad magic bytes)")
        try:
            _check_length(path)
            data = np.load(path, allow_pickle=False)
        except InputError:
            raise
        except (SyntaxError, tokenize.TokenError):
            # NumPy parses the header as a Python literal: a broken one fails as the parser
            # does, with the parser's words about a line of its own.
            raise InputError(f"{path}: not a valid .npy array file (its header is not a Python "
                             "dictionary literal)") from None
        except ValueError as exc:
            if "malformed node" in str(exc):      # a literal holding a call or a name: the same
                raise InputError(f"{path}: not a valid .npy array file (its header is not a Python "
                                 "dictionary literal)") from None
            if "pickle" in str(exc):
                raise InputError(f"{path}: holds Python objects, not a numeric array") from None
            raise InputError(f"{path}: not a valid .npy array file ({one_line(exc)})") from None
    if not isinstance(data, np.ndarray):
        raise InputError(f"{path}: holds several arrays (.npz?), expected one 3-D array")
    spacing, origin, meta = (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), {"format": "npy"}
    side = sidecar_path(path)
    if given["spacing"] is not None and given["origin"] is not None:
        side = None             # both replaced: the sidecar, whatever it holds, is not read
    elif side.exists() and not side.is_file():
        raise InputError(f"{side}: the sidecar of {path.name} (its spacing and origin) is not a file")
    if side is not None and side.is_file():
        try:
            info = strict_json(side.read_text(encoding="utf-8-sig"))
        except RepeatedKey as exc:
            raise InputError(f"{side}: key {exc.args[0]!r} is given twice in the sidecar") from None
        except RecursionError:
            raise InputError(f"{side}: bad sidecar (arrays or objects nested too deep); "
                             "expected JSON with spacing and origin") from None
        except (OSError, ValueError) as exc:
            raise InputError(f"{side}: bad sidecar ({one_line(exc)}); expected JSON with spacing and origin") from None
        if not isinstance(info, dict):
            raise InputError(f"{side}: the sidecar holds {json.dumps(info)[:40]}; expected a JSON object "
                             '{"spacing": [x, y, z], "origin": [x, y, z]}')
        spacing = info.get("spacing", spacing)
        origin = info.get("origin", origin)
        unknown = sorted(set(info) - {"spacing", "origin"})
        if unknown:
            raise InputError(f"{side}: unknown keys {', '.join(map(repr, unknown))} in the sidecar; "
                             "it holds spacing and origin")
        for key, value in (("spacing", spacing), ("origin", origin)):
            # A string is a sequence too: "123" must not become (1, 2, 3).
            if not (isinstance(value, (list, tuple)) and len(value) == 3
                    and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
                raise InputError(f"{side}: {key} must be an array of three numbers, got {json.dumps(value)}")
        meta["sidecar"] = str(side)
    return file_volume(data, spacing, origin, path, meta, given)


def is_sidecar(path) -> bool:
    """Whether ``path`` is a file holding a sidecar's JSON object: keys among spacing and origin
    (a file of another kind by that name, a run's stats say, is not one)."""
    try:
        if not Path(path).is_file() or Path(path).stat().st_size > 1 << 16:
            return False
        info = json.loads(Path(path).read_text(encoding="utf-8-sig"))
    except (OSError, ValueError, RecursionError):
        return False
    return isinstance(info, dict) and set(info) <= {"spacing", "origin"}


def _check_length(path):
    """Refuse a file shorter than its header's array before NumPy allocates it: a truncated file
    whose header claims a huge array failed as out of memory, not as truncated."""
    fmt = np.lib.format
    with open(path, "rb") as f:
        version = fmt.read_magic(f)
        if version not in ((1, 0), (2, 0)):
            return              # NumPy's own read tells
        read = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
        shape, _, dtype = read(f)
        if any(n < 0 for n in shape):
            raise InputError(f"{path}: its header gives the shape {shape}, with a negative size")
        if dtype.hasobject:
            return
        start = f.tell()
        f.seek(start - 1)
        if f.read(1) != b"\n":
            # The format's header ends in a newline (NumPy writes one; its reader does not look):
            # a header edited to another length, its stated length unchanged, shifts every sample.
            raise InputError(f"{path}: its header does not end where its stated length says "
                             "(edited or corrupt); the samples' start is unknown")
        need = start + math.prod(shape) * dtype.itemsize
        size = os.fstat(f.fileno()).st_size
    if size < need:
        raise InputError(f"{path}: truncated: its header's {'x'.join(map(str, shape))} {dtype} array needs "
                         f"{need} bytes, the file has {size}")
    if size > need:
        # numpy.save writes nothing after the array; NumPy's reader ignores what follows it.
        raise InputError(f"{path}: {size - need} bytes after its header's {'x'.join(map(str, shape))} {dtype} "
                         f"array ({need} bytes): several arrays in one file, or a corrupt header")


def save_array(path, array):
    """Write ``array`` as a ``.npy`` file at exactly ``path``.

    Given a name, `numpy.save` appends ``.npy`` unless the name ends in it
    in lower case, so ``x.NPY`` would be written to ``x.NPY.npy``; an open
    file keeps the name.
    """
    with open(path, "wb") as f:
        np.save(f, array, allow_pickle=False)


def write_npy(volume: Volume, path, *, sidecar=None) -> Path:
    """Write the array, and a ``.json`` sidecar with spacing and origin.

    ``sidecar=None`` writes it only when they are not the defaults;
    ``True`` always (so an existing sidecar cannot go stale); ``False``
    none for a volume at the default spacing and origin, and one all the
    same for any other (which `save_volume` refuses with ``False``).
    """
    path = Path(path)
    save_array(path, volume.data)
    plain = volume.spacing == (1.0, 1.0, 1.0) and volume.origin == (0.0, 0.0, 0.0)
    if sidecar or not plain:
        sidecar_path(path).write_text(
            json.dumps({"spacing": list(volume.spacing), "origin": list(volume.origin)}) + "\n", encoding="utf-8")
    return path
