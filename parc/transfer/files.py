"""Transfer-function files: our TOML/JSON format and ParaView colour maps, loaded and saved.

File formats
------------
Our own format, TOML or JSON with the same keys::

    name = "skin and bone"            # optional
    description = "..."               # optional
    space = "data"                    # optional: "data" (default) or "normalized"
    opacity = [[500, 0.0], [650, 0.05], [1000, 0.0]]      # [value, alpha], required
    color = [[500, 0.8, 0.5, 0.4], [1000, 1.0, 0.9, 0.8]]  # [value, r, g, b], optional (white)

With ``space = "normalized"`` the values lie in [0, 1] and map linearly
onto the data range ``(lo, hi)`` given to `load_transfer_function`.

ParaView colour-map JSON (File > Export in the colour map editor): a list
of objects (the first is used) or one object, with ``"RGBPoints": [x, r, g,
b, ...]`` and optionally ``"Points": [x, alpha, midpoint, sharpness, ...]``
(only ``x, alpha`` are used: opacity is linear between points). Without
``"Points"`` the opacity is the ramp the range presets use. Other keys
(``"Name"``, ``"ColorSpace"``, ``"NanColor"``...) are read or ignored. When
the colour points span [0, 1] or [-1, 1] (a preset meant to be stretched)
and a data range is given, both point lists are mapped onto it.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:          # Python 3.10: the same parser, as a package
    import tomli as tomllib

import numpy as np

from data_tools import InputError
from data_tools.errors import os_reason
from data_tools.jsontext import RepeatedKey, strict_json
from data_tools.volume import is_number

from .function import TransferFunction, control_points, short_repr
from .presets import PRESETS, check_mode, data_range_of, preset, ramp_opacity


_OUR_KEYS = ("color", "description", "name", "opacity", "space")

def parse_text(loads, text, where, kind):
    """``loads(text)`` (`tomllib.loads`, `json.loads`), any failure an InputError naming ``where``."""
    try:
        return loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        # tomllib's and json's messages end with where: "(at line L, column C)", "line L column C".
        raise InputError(f"{where}: malformed {kind}: {exc}") from None
    except RepeatedKey as exc:
        raise InputError(f"{where}: key {exc.args[0]!r} is given twice in one object") from None
    except ValueError:
        # The only other: an integer of thousands of digits, which Python will not convert.
        raise InputError(f"{where}: malformed {kind}: a number too long to read") from None
    except RecursionError:
        raise InputError(f"{where}: malformed {kind}: arrays or tables nested too deeply") from None


def unknown_preset(name):
    """The error for a bare name that is neither a preset nor a file."""
    return InputError(f"unknown transfer function preset {name!r}; known: {', '.join(PRESETS)}; "
                      "or give a .toml or .json file")


def load_transfer_function(spec, data_range=None, mode="composite"):
    """A transfer function from a preset name or a file.

    Parameters
    ----------
    spec : str, path or TransferFunction
        A name in `PRESETS`, or a ``.toml`` / ``.json`` file in our format or
        ParaView's (see the module notes). A TransferFunction is returned as is.
    data_range : (lo, hi), optional
        The volume's value range: needed by the ramp presets and
        ``space = "normalized"`` files, and used to stretch normalized
        ParaView maps.
    mode : {"composite", "mip", "average"}
        The mode it renders in: the ramp presets and ParaView maps without
        opacity points end opaque for maximum and average intensity
        (`parc.transfer.presets.ramp_opacity`).

    Returns
    -------
    TransferFunction

    Raises
    ------
    InputError
        One line naming the file (or preset) and the offending key.
    """
    check_mode(mode)
    if isinstance(spec, TransferFunction):
        return spec
    if not isinstance(spec, (str, os.PathLike)):
        raise InputError(f"a transfer function is a TransferFunction, a preset name or a file's path, "
                         f"got {type(spec).__name__}")
    text = os.fspath(spec)
    if not isinstance(text, str):
        raise InputError(f"a transfer function's path must be text, got {type(text).__name__}")
    if text in PRESETS:
        return preset(text, data_range, mode)
    if not text.strip():
        raise InputError(f"a transfer function is a preset ({', '.join(PRESETS)}) or a .toml or .json file; "
                         "got an empty name")
    path = Path(text)
    ext = path.suffix.lower()
    try:
        exists = path.exists()
    except OSError as exc:                  # a name too long for the system, say
        raise InputError(f"transfer function {text}: {os_reason(exc)}") from None
    if not exists:
        if path.is_symlink():
            raise InputError(f"transfer function {text}: a link that leads nowhere (or in a loop)")
        if ext in (".toml", ".json") or os.sep in text or "/" in text:
            raise InputError(f"transfer function file not found: {text}")
        raise unknown_preset(text)
    where = f"transfer function {text}"
    if path.is_dir():
        raise InputError(f"{where}: is a folder, not a file")
    if ext not in (".toml", ".json"):
        raise InputError(f"{where}: unknown file type {ext or '(none)'!r}; use .toml or .json")
    if not path.is_file():
        raise InputError(f"{where}: not a regular file")
    try:
        raw = path.read_text(encoding="utf-8-sig")   # a byte-order mark is no content
    except UnicodeDecodeError:
        raise InputError(f"{where}: not a UTF-8 text file") from None
    except OSError as exc:
        raise InputError(f"{where}: cannot read: {os_reason(exc)}") from None
    if ext == ".toml":
        doc = parse_text(tomllib.loads, raw, where, "TOML")
    else:
        doc = parse_text(strict_json, raw, where, "JSON")
        if isinstance(doc, dict) and "RGBPoints" in doc and {"opacity", "color"} & set(doc):
            raise InputError(f"{where}: holds ParaView's RGBPoints and our opacity/color keys; "
                             "keep one kind (a file is read as one or the other)")
        if isinstance(doc, list) or (isinstance(doc, dict) and "RGBPoints" in doc):
            return _from_paraview(doc, where, text, data_range, mode)
        paraview_keys = {"ColorSpace", "Name", "Points"}
        if isinstance(doc, dict) and not {"opacity", "color"} & set(doc) and paraview_keys & set(doc):
            raise InputError(f"{where}: a ParaView colour map needs RGBPoints (value, r, g, b, ...); none given")
    if not isinstance(doc, dict):
        kind = {str: "a string", int: "a number", float: "a number", bool: "true or false"}.get(type(doc), "null")
        raise InputError(f"{where}: expected an object with 'opacity' and 'color' keys, got {kind}")
    return _from_ours(doc, where, text, data_range)


def holds_a_transfer_function(doc):
    """Whether a parsed TOML or JSON document is a transfer function (ours: ``opacity`` or
    ``color``; ParaView's: ``RGBPoints``) and not a scene file (``[[volume]]`` tables): to name a
    file given in the wrong role for the role it has."""
    tables = doc if isinstance(doc, list) else [doc]
    return all(isinstance(t, dict) for t in tables) and any(
        "volume" not in t and {"opacity", "color", "RGBPoints"} & set(t) for t in tables)


def load_for_volume(spec, volume, mode="composite"):
    """`load_transfer_function` for ``volume``'s own value range, as `parc.Translucent` and scene
    files resolve a name: one made from a name is marked ``made_from = (name, data_range, mode)``
    (a file's name made absolute), so that a Translucent replaced with another volume or mode
    (``dataclasses.replace``) makes it again for them. A TransferFunction is returned as is."""
    data_range = volume.value_range()
    tf = load_transfer_function(spec, data_range=data_range, mode=mode)
    if tf is not spec:
        text = os.fspath(spec)
        # Marked as it is made, before anything else holds it; a TransferFunction is fixed after.
        object.__setattr__(tf, "made_from", (text if text in PRESETS else os.path.abspath(text), data_range, mode))
    return tf


def _from_ours(doc, where, source, data_range):
    unknown = sorted(set(doc) - set(_OUR_KEYS))
    if "volume" in unknown:
        raise InputError(f"{where}: a scene file (it has [[volume]] tables), not a transfer function: give it "
                         "as the volume, as in parc render SCENE.toml")
    if unknown:
        raise InputError(f"{where}: unknown key{'s' if len(unknown) > 1 else ''} "
                         f"{', '.join(repr(k) for k in unknown)}; known: {', '.join(_OUR_KEYS)}")
    for key in ("name", "description", "space"):
        if key in doc and not isinstance(doc[key], str):
            raise InputError(f"{where}: {key}: must be a string, got {short_repr(doc[key])}")
    if "opacity" not in doc:
        raise InputError(f"{where}: opacity: missing; give opacity = [[value, alpha], ...]")
    if "color" in doc and doc["color"] is None:      # JSON's null: leave the key out for white
        raise InputError(f"{where}: color: expected a list of [value, r, g, b] points, got null; "
                         "leave color out for white")
    space = doc.get("space", "data")
    if space not in ("data", "normalized"):
        raise InputError(f"{where}: space: must be \"data\" or \"normalized\", got {space!r}")
    tf = TransferFunction(doc["opacity"], doc.get("color"), name=doc.get("name", ""),
                          description=doc.get("description", ""), source=source)
    if space == "normalized":
        for key, xs in (("opacity", tf.arrays()[0]), ("color", tf.arrays()[2])):
            bad = np.flatnonzero((xs < 0.0) | (xs > 1.0))
            if len(bad):
                raise InputError(f"{where}: {key} point {bad[0] + 1}: value {xs[bad[0]]:g} is outside [0, 1] "
                                 "(space = \"normalized\")")
        if data_range is None:
            raise InputError(f"{where}: space: \"normalized\" needs the data range (lo, hi)")
        lo, hi = data_range_of(data_range, where)
        tf = tf.mapped(lo, hi)
    return tf

def _from_paraview(doc, where, source, data_range, mode):
    if isinstance(doc, list):
        if not doc:
            raise InputError(f"{where}: the ParaView colour-map list is empty")
        doc = doc[0]
        if not isinstance(doc, dict):
            raise InputError(f"{where}: the list's first entry: expected a ParaView colour-map object, got "
                             f"{short_repr(doc)}")
    name = doc.get("Name", "")
    if not isinstance(name, str):
        raise InputError(f"{where}: Name: must be a string, got {short_repr(name)}")
    if "RGBPoints" not in doc:
        extra = " (indexed/categorical maps are not supported)" if "IndexedColors" in doc else ""
        raise InputError(f"{where}: RGBPoints: missing{extra}")
    col = control_points(_flat_groups(doc["RGBPoints"], "RGBPoints", 4, 4, where), "RGBPoints",
                  ("r", "g", "b"), where, label=lambda i, j: f"RGBPoints number {4 * i + j + 1} (point {i + 1})")
    if "Points" in doc:
        op = control_points(_flat_groups(doc["Points"], "Points", 4, 2, where), "Points", ("alpha",),
                     where, label=lambda i, j: f"Points number {4 * i + j + 1} (point {i + 1})")
    else:
        x0, x1 = col[0, 0], col[-1, 0]
        # One colour point: the ramp a preset makes over a one-value range, whose span float64
        # holds at any x0 (one unit added to 1e17 is lost, and three ramp points fall on one value).
        top = x1 if x1 > x0 else data_range_of((x0, x0), where)[1]
        op = np.array(ramp_opacity(mode))
        op[:, 0] = x0 + op[:, 0] * (top - x0)
        op[-1, 0] = top      # x0 + (top - x0) may round past top
    tf = TransferFunction(op, col, name=name, source=source)
    x0, x1 = col[0, 0], col[-1, 0]
    normalized = x1 > x0 and abs(x1 - 1.0) <= 1e-6 and (abs(x0) <= 1e-6 or abs(x0 + 1.0) <= 1e-6)
    if normalized and data_range is not None:
        lo, hi = data_range_of(data_range, where)
        tf = tf.mapped(lo, hi, src=(x0, x1))
    return tf

def _flat_groups(raw, key, group, keep, where):
    """``[[x, ...], ...]`` from a flat ParaView list in groups of ``group``, first ``keep`` of each."""
    shape = "[x, r, g, b, ...]" if key == "RGBPoints" else "[x, alpha, midpoint, sharpness, ...]"
    if not isinstance(raw, list):
        raise InputError(f"{where}: {key}: expected a flat list {shape}, got {short_repr(raw)}")
    if not raw:
        raise InputError(f"{where}: {key}: the list is empty")
    if len(raw) % group:
        raise InputError(f"{where}: {key}: {len(raw)} numbers is not a multiple of {group} {shape}")
    for i, x in enumerate(raw):
        if not is_number(x):
            raise InputError(f"{where}: {key} number {i + 1} (point {i // group + 1}): must be a number, "
                             f"got {short_repr(x)}")
    return [raw[i:i + keep] for i in range(0, len(raw), group)]

def save_transfer_function(tf, path):
    """Write ``tf`` to ``path`` (``.toml`` or ``.json``) in our format; `load_transfer_function` reads it back equal."""
    if not isinstance(tf, TransferFunction):
        raise InputError(f"save_transfer_function takes a TransferFunction, got {type(tf).__name__}")
    if not isinstance(path, (str, os.PathLike)) or isinstance(os.fspath(path), bytes):
        raise InputError(f"save_transfer_function takes a file's path, got {type(path).__name__}")
    path = Path(path)
    ext = path.suffix.lower()
    d = tf.to_dict()
    if ext == ".json":
        text = json.dumps(d, indent=2) + "\n"
    elif ext == ".toml":
        lines = []
        for key in ("name", "description", "space"):
            if key in d:
                # A JSON string is a TOML basic string, once DEL is escaped too;
                # a lone surrogate (JSON's "\ud800") is neither TOML nor UTF-8.
                if any("\ud800" <= c <= "\udfff" for c in d[key]):
                    raise InputError(f"transfer function {path}: the {key} holds a lone surrogate, which TOML "
                                     "cannot hold; save it as .json")
                value = json.dumps(d[key], ensure_ascii=False).replace("\x7f", "\\u007f")
                lines.append(f"{key} = {value}")
        for key in ("opacity", "color"):
            lines.append(f"{key} = [")
            lines += ["    [" + ", ".join(repr(float(x)) for x in p) + "]," for p in d[key]]
            lines.append("]")
        text = "\n".join(lines) + "\n"
    else:
        raise InputError(f"transfer function {path}: unknown file type {ext or '(none)'!r}; "
                         "use .toml or .json")
    data = text.encode("utf-8")
    from ..outputs import atomic_write_all
    try:
        # Through a file beside it, renamed once whole: a failure leaves no half-written file
        # (and an InputError naming the path).
        atomic_write_all([(path, lambda tmp: tmp.write_bytes(data))])
    except InputError:                      # a ValueError too, already naming the path
        raise
    except ValueError as exc:               # a NUL in the name
        raise InputError(f"transfer function {path}: cannot write: {exc}") from None
