"""VolVis ``.slc`` volumes: ASCII header, RGB icon, then raw or run-length 8-bit slices."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ..memory import check_memory
from ..volume import Volume
from ._common import file_volume, reading

EXTENSIONS = (".slc",)
MAGIC = b"11111"
_WS = b" \t\r\n"


class _Cursor:
    """Walks the file bytes: ASCII tokens in the header, raw runs after each ``X``."""

    def __init__(self, buf: bytes, path):
        self.buf, self.pos, self.path = buf, 0, path

    def token(self, what: str, stop: bytes = b"") -> bytes:
        """The next word, ended by white space or a byte of ``stop`` (the ``X`` after a count:
        VolVis and VTK read ``%d X``, which takes ``4X`` as well as ``4 X``)."""
        buf, n = self.buf, len(self.buf)
        while self.pos < n and buf[self.pos] in _WS:
            self.pos += 1
        start = self.pos
        ends = _WS + stop
        while self.pos < n and buf[self.pos] not in ends and self.pos - start < 64:
            self.pos += 1
        if start == self.pos:
            if self.pos < n:        # at an X, where the count should be
                raise InputError(f"{self.path}: bad SLC header: {what} should be a number, got "
                                 f"{buf[start:start + 20]!r}")
            raise InputError(f"{self.path}: SLC file ends before {what}")
        if self.pos - start == 64 and self.pos < n and buf[self.pos] not in ends:
            raise InputError(f"{self.path}: bad SLC header: {what} is not a number (over 64 characters)")
        return buf[start:self.pos]

    def number(self, cast, what: str, stop: bytes = b""):
        tok = self.token(what, stop)
        try:
            if b"_" in tok:
                raise ValueError    # Python reads 1_000; VolVis's and VTK's readers do not
            return cast(tok.decode("ascii"))
        except (UnicodeDecodeError, ValueError):
            raise InputError(f"{self.path}: bad SLC header: {what} should be a number, got {tok[:20]!r}") from None

    def marker(self, what: str):
        """Skip whitespace and the ``X`` that precedes binary bytes."""
        buf, n = self.buf, len(self.buf)
        while self.pos < n and buf[self.pos] in _WS:
            self.pos += 1
        if self.pos >= n or buf[self.pos] != ord("X"):
            raise InputError(f"{self.path}: bad SLC file: expected 'X' before {what}")
        self.pos += 1

    def take(self, count: int, what: str) -> bytes:
        if count < 0 or self.pos + count > len(self.buf):
            raise InputError(f"{self.path}: SLC data truncated in {what}: {count} bytes needed, "
                             f"{len(self.buf) - self.pos} left")
        out = self.buf[self.pos:self.pos + count]
        self.pos += count
        return out


def read_slc(path, *, spacing=None, origin=None) -> Volume:
    """Read a VolVis SLC volume (8-bit samples, raw or run-length slices).

    Layout: ``11111``; ``nx ny nz bits``; ``sx sy sz``; ``unit_type
    data_origin data_modification compression``; ``icon_w icon_h X`` then
    ``3*icon_w*icon_h`` icon bytes (R, G, B planes); then ``nz`` slices of
    ``nx*ny`` bytes, x fastest. With compression 1 each slice is
    ``size X`` followed by ``size`` run-length bytes.

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
    with reading(path, "SLC"):
        buf = path.read_bytes()
    cur = _Cursor(buf, path)
    if cur.token("the magic number") != MAGIC:
        raise InputError(f"{path}: not an SLC file (it must start with the magic number 11111)")
    nx, ny, nz, bits = (cur.number(int, w) for w in ("xsize", "ysize", "zsize", "bits"))
    spacing = tuple(cur.number(float, w) for w in ("x spacing", "y spacing", "z spacing"))
    unit, data_origin, modification, compression = (
        cur.number(int, w) for w in ("unit type", "data origin", "data modification", "compression"))
    if bits != 8:
        raise InputError(f"{path}: SLC with {bits}-bit samples is not supported (only 8)")
    if min(nx, ny, nz) < 1:
        raise InputError(f"{path}: bad SLC size {nx}x{ny}x{nz}")
    if compression not in (0, 1):
        raise InputError(f"{path}: unknown SLC compression {compression} (0 raw, 1 run-length)")
    icon_w, icon_h = cur.number(int, "icon width"), cur.number(int, "icon height", b"X")
    if min(icon_w, icon_h) < 0:
        raise InputError(f"{path}: bad SLC icon size {icon_w}x{icon_h} (0 or more each)")
    cur.marker("the icon")
    cur.take(3 * icon_w * icon_h, "the icon")
    plane = nx * ny
    # Run-length data can claim more samples than its file holds bytes: ask before allocating.
    check_memory(plane * nz, f"{path}: its {nx}x{ny}x{nz} samples")
    data = np.empty((nz, ny, nx), dtype=np.uint8)
    flat = data.reshape(nz, plane)
    for k in range(nz):
        what = f"slice {k}"
        if compression:
            size = cur.number(int, f"the size of {what}", b"X")
            if size < 0:
                raise InputError(f"{path}: bad SLC header: {what} has {size} bytes")
            cur.marker(what)
            flat[k] = np.frombuffer(_rle_decode(cur.take(size, what), plane, path, k), dtype=np.uint8)
        else:
            flat[k] = np.frombuffer(cur.take(plane, what), dtype=np.uint8)
    if cur.pos < len(buf):
        # Nothing follows the last slice: bytes left over mean the header or the icon was
        # misread (a size edited, a line repeated), and every sample shifted with them.
        raise InputError(f"{path}: {len(buf) - cur.pos} bytes after the last of its {nz} slices; "
                         "the header's sizes or icon do not match the data (corrupt?)")
    meta = {"format": "slc", "compression": "rle" if compression else "raw",
            "unit_type": unit, "data_origin": data_origin, "data_modification": modification}
    return file_volume(data, spacing, (0.0, 0.0, 0.0), path, meta, given)


def _rle_decode(src: bytes, size: int, path, k: int) -> bytes:
    """VolVis 8-bit run-length: count byte with high bit = literal run, else repeat next byte; 0 ends."""
    out = bytearray()
    pos, n = 0, len(src)
    while pos < n:
        code = src[pos]
        pos += 1
        count = code & 0x7F
        if count == 0:
            break
        if code & 0x80:
            out += src[pos:pos + count]
            pos += count
        else:
            if pos >= n:
                break
            out += bytes((src[pos],)) * count
            pos += 1
        if len(out) > size:
            raise InputError(f"{path}: SLC slice {k} decodes to more than its {size} samples")
    if len(out) != size:
        raise InputError(f"{path}: SLC slice {k} decodes to {len(out)} samples, expected {size} (corrupt or truncated)")
    return bytes(out)
