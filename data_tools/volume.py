"""The Volume: samples on a regular axis-aligned grid.

Axis rule (the one used everywhere in the project): ``data`` is indexed
``[z, y, x]`` (shape ``(nz, ny, nx)``, x varies fastest); positions,
directions, ``spacing`` and ``origin`` are ``(x, y, z)``. Sample
``data[k, j, i]`` sits at world ``origin + (i*sx, j*sy, k*sz)``. Samples are
points; cell ``(i, j, k)`` is the box between samples ``i..i+1``,
``j..j+1``, ``k..k+1`` and holds the trilinear interpolant of its corners.
"""
from __future__ import annotations

import functools
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field, is_dataclass

import numpy as np

from .errors import InputError
from .memory import check_memory

#: Sample types the kernels read natively.
SUPPORTED_DTYPES = tuple(np.dtype(t) for t in (
    "uint8", "int8", "uint16", "int16", "uint32", "int32", "float32", "float64"))


def settled(cls):
    """Class decorator: the fields of an instance are fixed once ``__init__`` has checked them.

    Renderers cache what they derive from a volume or scene (cell ranges,
    proxies, skip tables) on the object; a field changed afterwards would
    skip the checks and leave those caches describing another object, so
    PARC and the unaccelerated caster would disagree. A changed object is a
    new one: ``dataclasses.replace(obj, field=...)`` for a dataclass.
    """
    init = cls.__init__

    @functools.wraps(init)
    def __init__(self, *args, **kwargs):
        object.__setattr__(self, "_settled", False)
        init(self, *args, **kwargs)
        object.__setattr__(self, "_settled", True)

    def refuse_change(self, name):
        if self.__dict__.get("_settled"):
            kind = type(self).__name__
            how = f": dataclasses.replace(obj, {name}=...)" if is_dataclass(self) else ""
            raise AttributeError(f"{kind}.{name} cannot change once built; make a new {kind}{how}")

    def __setattr__(self, name, value):
        refuse_change(self, name)
        object.__setattr__(self, name, value)

    # Deleting a dataclass field would show its class default, under caches made from the value.
    def __delattr__(self, name):
        refuse_change(self, name)
        object.__delattr__(self, name)

    cls.__init__ = __init__
    cls.__setattr__ = __setattr__
    cls.__delattr__ = __delattr__
    return cls


@settled
@dataclass(eq=False)
class Volume:
    """Scalar samples on a regular grid, in their native dtype.

    Parameters
    ----------
    data : ndarray, shape (nz, ny, nx)
        Samples, C-contiguous, native byte order (converted if not), of one
        of `SUPPORTED_DTYPES`; booleans become uint8, float16 float32, and
        64-bit integers 32-bit ones when every value fits.
    spacing : (sx, sy, sz)
        Distance between neighbouring samples along x, y, z; positive.
    origin : (ox, oy, oz)
        World position of ``data[0, 0, 0]``.
    name : str
        Where the volume came from, for messages and reports.
    meta : dict
        Anything a reader wants to pass on (e.g. a note that oblique
        NRRD ``space directions`` were reduced to their column norms).
        Copied, without the caches kept under keys starting with ``_``.

    Notes
    -----
    A volume is fixed once built (`settled`): its samples are read-only,
    and its fields cannot be reassigned. Rendering caches cell ranges,
    proxies and skip tables on it, so it keeps its own copy of an array
    that could still be written (``data``, or an array it views), and
    changing that array later changes nothing here. An array read-only all
    the way down is used in place, without a copy (then keep no writeable
    view of it: NumPy cannot tell), and so is a memory map
    (`numpy.memmap`): neither it nor its file may change while the volume
    is in use.

    Raises
    ------
    InputError
        Not 3-D, a dimension below 2, an unsupported dtype, non-finite
        float samples or samples beyond ±1e200 (`MAX_SAMPLE`: a cell's cubic
        would overflow), float samples none of which reaches 1e-200 in
        magnitude (`MIN_SAMPLE`: its normals would underflow), or a spacing
        outside 1e-30 to 1e30 (`MIN_SPACING`, `MAX_SPACING`).
    """

    data: np.ndarray
    spacing: tuple = (1.0, 1.0, 1.0)
    origin: tuple = (0.0, 0.0, 0.0)
    name: str = "volume"
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.name, str):
            # Every message and stats table names the volume by it.
            raise InputError(f"a volume's name must be text, got {self.name!r}")
        if self.data is None:
            raise InputError(f"{self.name}: no samples given (None); give a 3-D array")
        if isinstance(self.data, np.ma.MaskedArray):
            # Its masked entries hold fill values, which would be drawn as data.
            if np.ma.getmaskarray(self.data).any():
                raise InputError(f"{self.name}: a masked array with {int(np.ma.getmaskarray(self.data).sum())} "
                                 "masked samples; fill them with values to draw (np.ma.filled) first")
            self.data = np.ma.getdata(self.data)
        # Whether the samples are already an array of this volume's own, made here: from a list,
        # or by a conversion below. Any other array may be the caller's (np.asarray hands back
        # an object's own buffer), and is copied if it could still be written.
        converted = isinstance(self.data, (list, tuple))
        try:
            data = np.asarray(self.data) if not isinstance(self.data, np.memmap) else self.data
        except ValueError:
            raise InputError(f"{self.name}: samples must form a 3-D array (a nested list of equal lengths)") from None
        if data.ndim != 3:
            raise InputError(f"{self.name}: a volume needs 3 dimensions, got shape {data.shape}")
        if min(data.shape) < 2:
            nz, ny, nx = data.shape
            raise InputError(f"{self.name}: every dimension must be at least 2 samples, got {nx}x{ny}x{nz} (x×y×z)")
        dt = data.dtype
        if dt.isnative and dt.byteorder not in ("=", "|"):
            # '<i2' on a little-endian machine (a reader's file order): the same bytes, named
            # natively without a copy, which had doubled every little-endian raw and MetaImage load.
            data = data.view(dt.newbyteorder("="))
        elif not dt.isnative and dt.newbyteorder("=") in SUPPORTED_DTYPES:
            data, converted = data.astype(dt.newbyteorder("=")), True
        if data.dtype not in SUPPORTED_DTYPES:
            data, converted = _narrowed(data, self.name), True
        if not data.flags.c_contiguous:
            data, converted = np.ascontiguousarray(data), True
        if data.dtype.kind == "f":
            # Policy: non-finite samples have no isosurface or colour; refuse them.
            bad, top = _count_non_finite(data)
            if bad:
                raise InputError(f"{self.name}: {bad} non-finite samples (NaN or inf); replace them before rendering")
            if abs(top) > MAX_SAMPLE:
                raise InputError(f"{self.name}: samples reach {top:.3g}, beyond the ±{MAX_SAMPLE:g} a cell's cubic "
                                 "holds without overflow (a fill value?); replace them before rendering")
            if 0.0 < abs(top) < MIN_SAMPLE:
                raise InputError(f"{self.name}: samples reach only {abs(top):.3g} in magnitude, below the "
                                 f"{MIN_SAMPLE:g} under which a cell's normals and cubic underflow; scale them up "
                                 "before rendering")
        if isinstance(data, np.memmap):
            if data.flags.writeable:
                data = data.view()
                data.flags.writeable = False
        elif converted:
            data.flags.writeable = False
        elif _writeable_below(data):
            # The caller's samples could change under the caches: keep a copy of them.
            check_memory(data.nbytes, f"{self.name}: a copy of the samples",
                         " (an array that owns its samples, made read-only with a.flags.writeable = False "
                         "and with no writeable view kept, is used without one)")
            data = data.copy()
            data.flags.writeable = False
        if data.flags.owndata:
            # A read-only array owning its memory may be made writeable again; a view of it may not.
            data = data.view()
            data.flags.writeable = False
        self.data = data
        if self.meta is not None and not isinstance(self.meta, Mapping):
            raise InputError(f"{self.name}: meta must be a dict, got {type(self.meta).__name__}")
        self.meta = {k: v for k, v in dict(self.meta or {}).items() if not str(k).startswith("_")}
        self.spacing = _triple(self.spacing, "spacing", self.name, positive=True)
        self.origin = _triple(self.origin, "origin", self.name, positive=False)
        # Positions must resolve a cell finely in float64 (2^-20 of a cell):
        # a volume placed 1e20 spacings from the origin is smaller than one
        # rounding step there, and no ray through it is well defined.
        far = np.maximum(np.abs(self.origin), np.abs(np.add(self.origin, self.extent)))
        if not np.isfinite(far).all():
            raise InputError(f"{self.name}: spacing {self.spacing} and origin {self.origin} put the grid "
                             f"beyond float64's range")
        if not (far <= 2.0 ** 32 * np.array(self.spacing)).all():
            raise InputError(f"{self.name}: origin {self.origin} with spacing {self.spacing} puts the grid more "
                             f"than 2^32 cells from 0, beyond float64's resolution of a cell; move the origin")

    def __reduce__(self):
        # Copies and pickles are built anew, through the checks: read-only
        # samples, and none of the caches (they would outlive a change to the copy).
        meta = {k: v for k, v in self.meta.items() if not str(k).startswith("_")}
        return (_rebuilt, (type(self), self.data, self.spacing, self.origin, self.name, meta))

    def __repr__(self):
        # Short whatever the size: the default printed the samples, and the caches kept in meta.
        nx, ny, nz = self.dims
        return (f"Volume({self.name!r}, {nx}x{ny}x{nz} {self.dtype}, {self.data.nbytes / 2**20:.1f} MiB, "
                f"spacing={self.spacing}, origin={self.origin})")

    @property
    def shape(self):
        """``(nz, ny, nx)``, as the array."""
        return self.data.shape

    @property
    def dims(self):
        """``(nx, ny, nz)``: sample counts in x, y, z order."""
        nz, ny, nx = self.data.shape
        return (nx, ny, nz)

    @property
    def dtype(self):
        return self.data.dtype

    @property
    def extent(self):
        """World size of the sampled box, ``(nx-1)*sx, ...``."""
        return tuple((n - 1) * s for n, s in zip(self.dims, self.spacing))

    @property
    def bounds(self):
        """``(lo, hi)`` world corners of the box, each ``(x, y, z)``."""
        lo = np.array(self.origin, dtype=np.float64)
        return lo, lo + np.array(self.extent)

    @property
    def center(self):
        lo, hi = self.bounds
        return 0.5 * (lo + hi)

    def value_range(self):
        """``(min, max)`` of the samples, computed once and kept."""
        if "_range" not in self.meta:
            self.meta["_range"] = (float(self.data.min()), float(self.data.max()))
        return self.meta["_range"]


#: Largest sample magnitude, and the range of spacings, for which a cell's cubic (solved in
#: world units, its coefficients up to 8 samples over spacing^3) stays within float64:
#: 8e200 x 1e90 is far from overflow, and real data (float32 at most 3.4e38) far inside.
MAX_SAMPLE = 1e200
#: ... and the largest sample magnitude may not be below this: divided by a spacing of 1e30, the
#: gradient of samples of 1e-300 underflowed to zero, and every normal faced the eye.
MIN_SAMPLE = 1e-200
MIN_SPACING, MAX_SPACING = 1e-30, 1e30


def _writeable_below(a):
    """Whether ``a``, an array it is a view of, or the buffer beneath them can be written.
    NumPy records only the array that owns the memory: a view of it kept writeable elsewhere is
    not seen. A read-only memoryview may show a ``bytearray``, and numpy's ``as_strided`` keeps
    its array in an object of its own: both are followed down. What cannot be shown read-only
    counts as writeable: a copy costs memory, samples changed under the caches a wrong image."""
    for _ in range(1000):          # a chain of bases ends; a loop of them would not
        if a is None:
            return False
        if isinstance(a, np.ndarray):
            if a.flags.writeable:
                return True
            a = a.base
        elif isinstance(a, memoryview):
            if not a.readonly:
                return True
            a = a.obj
        else:
            try:
                return not memoryview(a).readonly      # bytes, an mmap opened to read: read-only
            except TypeError:
                if not hasattr(a, "base"):
                    return True
                a = a.base
    return True


def _rebuilt(cls, data, *fields):
    """A copied or unpickled volume: its samples are the copy's own, so they are not copied again."""
    return cls(hand_over(data), *fields)


def hand_over(data):
    """``data``, made read-only with every array it views: for code that builds samples only to
    give them to a `Volume` and keeps no other reference, so that the volume need not copy them."""
    a = data
    while isinstance(a, np.ndarray) and not isinstance(a, np.memmap):
        a.flags.writeable = False
        a = a.base
    return data


def _count_non_finite(data, slab_bytes=64 << 20):
    """NaN and inf samples in float ``data``, and the finite sample of largest magnitude, with
    its sign (float64 only: float32 cannot pass `MAX_SAMPLE` or `MIN_SAMPLE`), a slab of z-slices at a time: a
    memory-mapped file is read through once, and no mask as large as the volume is made."""
    per = max(1, slab_bytes // max(data[0].nbytes, 1))
    bad, top = 0, 0.0
    for z in range(0, data.shape[0], per):
        slab = data[z:z + per]
        finite = np.isfinite(slab)
        bad += int(slab.size - np.count_nonzero(finite))
        if data.dtype.itemsize == 8 and not bad:
            top = max(top, float(slab.min()), float(slab.max()), key=abs)
    return bad, top


def _narrowed(data, name):
    """``data`` in a sample type the kernels read, where that loses nothing: a mask as uint8,
    half floats as float32, 64-bit integers (NumPy's default for whole numbers) as 32-bit ones
    when every value fits. Anything else is refused."""
    kind = data.dtype.kind
    target = None
    if kind == "b":
        target = np.uint8
    elif kind == "f" and data.dtype.itemsize < 4:
        target = np.float32
    elif kind in "iu" and data.size:
        lo, hi = int(data.min()), int(data.max())
        for t in (np.int32, np.uint32):
            if np.iinfo(t).min <= lo and hi <= np.iinfo(t).max:
                target = t
                break
    if target is None:
        names = ", ".join(t.name for t in SUPPORTED_DTYPES)
        raise InputError(f"{name}: unsupported sample type {data.dtype}"
                         + (" with values beyond 32 bits" if kind in "iu" else "") + f"; use one of {names}")
    return data.astype(target)


def is_number(value):
    """Whether ``value`` is a real number: a Python or NumPy int or float, not a boolean."""
    return isinstance(value, numbers.Real) and not text_or_flag(value)


def text_or_flag(value):
    """Whether ``value`` is something `float` takes that a number argument must not: text
    (``"5"``), a boolean, a complex number (its imaginary part dropped with a warning), or a
    NumPy date or duration (its count of units)."""
    return isinstance(value, (str, bytes, bool, np.bool_, complex, np.complexfloating, np.datetime64,
                              np.timedelta64))


def three_numbers(value):
    """``value`` (three numbers, or another count the caller allows) as a tuple of floats, or
    None when it is not a sequence of numbers: text and
    booleans are not numbers (``"123"`` would otherwise read as (1, 2, 3), ``True`` as 1).
    The caller checks the count and the range."""
    try:
        # A dict or set iterates its keys, in an order not the caller's.
        if isinstance(value, (str, bytes, dict, set, frozenset)) or any(text_or_flag(v) for v in value):
            return None
        return tuple(float(v) for v in value)
    except (TypeError, ValueError, OverflowError):
        return None


def _triple(value, what, name, *, positive):
    t = three_numbers(value)
    if t is None:
        raise InputError(f"{name}: {what} must be three numbers, got {value!r}")
    if len(t) != 3 or not all(np.isfinite(t)):
        raise InputError(f"{name}: {what} must be three finite numbers, got {value!r}")
    if positive and min(t) <= 0:
        raise InputError(f"{name}: {what} must be positive, got {t}")
    if positive and not all(MIN_SPACING <= v <= MAX_SPACING for v in t):
        # A cell's cubic is solved in world units: its coefficients scale as 1/spacing^3.
        raise InputError(f"{name}: {what} must lie between {MIN_SPACING:g} and {MAX_SPACING:g}, got {t}")
    return t
