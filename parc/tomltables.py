"""Reading a TOML document's tables with errors that name the file and the key.

The scene files (`parc.scenefile`) are read through these: a `Table`
refuses unknown keys with a suggestion and reads typed values by key, and
every complaint is one line, ``FILE: KEY: message``, with the key written
as TOML writes it (``volume[2].iso``, ``camera."a b"``).
"""
from __future__ import annotations

import difflib
import json
import math
import re
from contextlib import contextmanager
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:          # Python 3.10: the same parser, as a package
    import tomli as tomllib

from data_tools import InputError
from data_tools.errors import os_reason
from data_tools.volume import is_number


class Where:
    """The scene file being read: formats errors as ``FILE: KEY: message``."""

    def __init__(self, path, progress=None):
        self.path = Path(path)
        self.folder = self.path.parent
        #: Told, in a line, of work that takes seconds (a large synthetic volume made).
        self.progress = progress or (lambda text: None)

    def error(self, key, message):
        return InputError(f"{self.path}: {key}: {message}" if key else f"{self.path}: {message}")

    @contextmanager
    def key(self, key):
        """Re-raise an InputError from a constructor or reader, or a path the system refuses
        (a name too long), with the file and key in front."""
        try:
            yield
        except InputError as exc:
            raise self.error(key, str(exc)) from None
        except OSError as exc:
            where = f"{exc.filename}: " if exc.filename else ""
            raise self.error(key, f"{where}{os_reason(exc)}") from None

    def read(self):
        try:
            exists = self.path.exists()
        except OSError as exc:              # a name too long for the system, say
            raise InputError(f"{self.path}: {os_reason(exc)}") from None
        if not exists:
            if self.path.is_symlink():
                raise InputError(f"{self.path}: a link that leads nowhere (or in a loop)")
            raise InputError(f"{self.path}: no such scene file")
        if self.path.is_dir():
            raise InputError(f"{self.path}: is a folder, not a scene file")
        if not self.path.is_file():
            raise InputError(f"{self.path}: not a regular file")
        try:
            text = self.path.read_text(encoding="utf-8-sig")   # a byte-order mark is no statement
        except UnicodeDecodeError:
            raise InputError(f"{self.path}: not a UTF-8 text file") from None
        except OSError as exc:
            raise InputError(f"{self.path}: cannot read: {os_reason(exc)}") from None
        from .transfer.files import parse_text
        return parse_text(tomllib.loads, text, self.path, "TOML")

    def resolve(self, name):
        """A path from the file, relative to the file's folder; ``~`` and ``~user`` are home folders."""
        try:
            return self.folder / Path(name).expanduser()
        except RuntimeError:                # ~user of no user known here
            raise InputError(f"{name}: no home folder is known for {name.split('/')[0]}") from None


def kind(value):
    """What a TOML value is, in TOML's words."""
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    return f"a {type(value).__name__}"


def show(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


class Table:
    """One TOML table: refuses unknown keys at once, and reads typed values by key."""

    def __init__(self, where, prefix, raw, known):
        self.where = where
        self.prefix = prefix
        if not isinstance(raw, dict):
            raise where.error(prefix, f"must be a table, got {kind(raw)} {show(raw)}")
        self.raw = raw
        for name in raw:
            if name not in known:
                close = (difflib.get_close_matches(name, known, n=1, cutoff=0.5)
                         or [k for k in known if name and (name.startswith(k) or k.startswith(name))])
                hint = f"; did you mean {close[0]}?" if close else ""
                raise where.error(self.key(name), f"unknown key{hint} (known: {', '.join(known)})")

    def key(self, name):
        # As TOML would write it: a key that is not bare ("", "a b") in quotes.
        name = name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else json.dumps(name, ensure_ascii=False)
        return f"{self.prefix}.{name}" if self.prefix else name

    def __contains__(self, name):
        return name in self.raw

    def error(self, name, message):
        return self.where.error(self.key(name), message)

    def wrong(self, name, what):
        value = self.raw[name]
        return self.error(name, f"must be {what}, got {kind(value)} {show(value)}")

    def number(self, name, default=None):
        """A finite number (TOML integer or float)."""
        if name not in self.raw:
            return default
        value = self.raw[name]
        if not _finite(value):
            raise self.wrong(name, "a finite number")
        return float(value)

    def numbers(self, name, counts, default=None):
        """An array of finite numbers whose length is in ``counts`` (an int or a tuple)."""
        if name not in self.raw:
            return default
        counts = (counts,) if isinstance(counts, int) else tuple(counts)
        value = self.raw[name]
        want = " or ".join(map(str, counts)) + " finite numbers"
        if (not isinstance(value, list) or len(value) not in counts
                or not all(_finite(v) for v in value)):
            raise self.wrong(name, f"an array of {want}")
        return tuple(float(v) for v in value)

    def integers(self, name, count, default=None, minimum=None):
        """An array of ``count`` integers, each at least ``minimum``."""
        if name not in self.raw:
            return default
        value = self.raw[name]
        if (not isinstance(value, list) or len(value) != count
                or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)):
            raise self.wrong(name, f"an array of {count} integers")
        if minimum is not None and min(value) < minimum:
            raise self.error(name, f"must be integers of at least {minimum}, got {value}")
        return tuple(value)

    def string(self, name, default=None):
        if name not in self.raw:
            return default
        value = self.raw[name]
        if not isinstance(value, str) or not value:
            raise self.wrong(name, "a non-empty string")
        return value

    def boolean(self, name, default=None):
        if name not in self.raw:
            return default
        value = self.raw[name]
        if not isinstance(value, bool):
            raise self.wrong(name, "true or false")
        return value

    def material(self, name):
        m = self.numbers(name, 4)
        if m is not None and min(m) < 0.0:
            raise self.error(name, f"ambient, diffuse, specular and shininess must be >= 0, got {list(m)}")
        return m


def _finite(value):
    """Whether ``value`` is a finite number: TOML's integers have no bound in `tomllib`, and one
    beyond float64's range (``iso = 1`` and 400 zeros) makes `math.isfinite` raise OverflowError."""
    try:
        return is_number(value) and math.isfinite(value)
    except OverflowError:
        return False


def array_tables(where, name, raw, *, required):
    """The tables of an array of tables ``[[name]]``, each with its key prefix ``name[i]`` (from 1)."""
    if raw is None:
        if required:
            raise where.error(name, f"missing: add at least one [[{name}]] table")
        return []
    if not isinstance(raw, list):
        raise where.error(name, f"must be an array of tables, written [[{name}]] (not [{name}]), "
                                f"got {kind(raw)}")
    if required and not raw:
        raise where.error(name, f"empty: add at least one [[{name}]] table")
    return [(f"{name}[{i}]", t) for i, t in enumerate(raw, start=1)]


def construct(where, prefix, cls, fixed, keyed):
    """``cls(**fixed, **keyed)``, pinning a constructor's complaint on the key that caused it.

    The keyword arguments of ``keyed`` (``[(key, argument, value), ...]``,
    the required ones first) are added one at a time, so the first
    construction that fails is the one whose newest key is to blame.
    """
    kwargs = dict(fixed)
    obj = None
    for key, arg, value in keyed:
        kwargs[arg] = value
        with where.key(f"{prefix}.{key}"):
            obj = cls(**kwargs)
    if obj is None:
        with where.key(prefix):
            obj = cls(**kwargs)
    return obj
