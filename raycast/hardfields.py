"""Exact-trilinear scenes for the hard-ray suite (`raycast.hardcases`).

An exact-trilinear field (index coordinates i, j, k)

    F(i, j, k) = c0 + c1 i + c2 j + c3 k + c4 ij + c5 jk + c6 ki + c7 ijk

is reproduced exactly by trilinear interpolation of its samples, so the
caster's isosurface is exactly ``{F = iso}``. With integer or dyadic
coefficients the samples are exact in float64 (and in uint16/int16 when
they fit). Here: the field, its gradient and range in exact fractions, a
`Scene` (the field sampled on a placed grid) and random scenes and
isovalues, seeded.
"""
import math
from fractions import Fraction

import numpy as np

# ----------------------------------------------------------------- fields

def field_value(c, i, j, k):
    """F(i, j, k) exactly for int/Fraction/float (dyadic) inputs."""
    return (c[0] + c[1] * i + c[2] * j + c[3] * k + c[4] * i * j + c[5] * j * k
            + c[6] * k * i + c[7] * i * j * k)


def field_grad(c, i, j, k):
    """Index-space gradient of F (same exact arithmetic as the inputs)."""
    return (c[1] + c[4] * j + c[6] * k + c[7] * j * k,
            c[2] + c[4] * i + c[5] * k + c[7] * i * k,
            c[3] + c[5] * j + c[6] * i + c[7] * i * j)


def field_range(c, shape):
    """(min, max) of F over the sample box; F is multilinear, so at its corners."""
    nz, ny, nx = shape
    vals = [Fraction(field_value([Fraction(x) for x in c], i, j, k))
            for i in (0, nx - 1) for j in (0, ny - 1) for k in (0, nz - 1)]
    return min(vals), max(vals)


def sample_field(c, shape, dtype):
    """Samples ``data[k, j, i] = F(i, j, k)``, checked to be exact in ``dtype``.

    Coefficients must be dyadic (k / 2^e): the samples times the common
    denominator are then integers, computed exactly in int64 and required to
    stay below 2^53 so that they are exact in float64.
    """
    cf = [Fraction(x) for x in c]
    den = 1
    for x in cf:
        den = max(den, x.denominator)
    if den & (den - 1) or any(den % x.denominator for x in cf):
        raise ValueError("coefficients must be dyadic")
    ci = [int(x * den) for x in cf]
    nz, ny, nx = shape
    mono = [1, nx, ny, nz, nx * ny, ny * nz, nz * nx, nx * ny * nz]
    if sum(abs(a) * m for a, m in zip(ci, mono)) >= 2 ** 53:
        raise ValueError("field too large to be exact in float64")
    k, j, i = np.meshgrid(np.arange(nz, dtype=np.int64), np.arange(ny, dtype=np.int64),
                          np.arange(nx, dtype=np.int64), indexing="ij")
    exact = field_value(ci, i, j, k)               # int64, exact (< 2^53)
    data = exact.astype(np.float64) / den          # exact: power-of-two divisor
    if np.dtype(dtype) != np.float64:
        info = np.iinfo(dtype)
        if data.min() < info.min or data.max() > info.max or np.any(data != np.round(data)):
            raise ValueError(f"field samples do not fit {np.dtype(dtype)}")
    return data.astype(dtype)


class Scene:
    """An exact-trilinear field sampled on a grid with origin/spacing (x, y, z).

    ``coeffs`` are ``(c0, ..., c7)`` of ``F`` (exact in float64), ``shape``
    is ``(nz, ny, nx)``; ``data`` holds the samples in ``dtype``.
    """

    def __init__(self, coeffs, shape, dtype=np.float64, origin=(0.0, 0.0, 0.0),
                 spacing=(1.0, 1.0, 1.0), name=""):
        self.coeffs = tuple(float(x) for x in coeffs)
        if any(Fraction(x) != Fraction(y) for x, y in zip(self.coeffs, coeffs)):
            raise ValueError("coefficients must be exact in float64")
        self.shape = tuple(int(s) for s in shape)
        self.origin = np.array(origin, dtype=np.float64)
        self.spacing = np.array(spacing, dtype=np.float64)
        self.data = sample_field(self.coeffs, self.shape, dtype)
        self.name = name

    def index_to_world(self, p):
        return self.origin + np.asarray(p, dtype=np.float64) * self.spacing

    @property
    def lo_world(self):
        return self.origin.copy()

    @property
    def hi_world(self):
        nz, ny, nx = self.shape
        return self.origin + np.array([nx - 1, ny - 1, nz - 1]) * self.spacing

    def value_at_index(self, p):
        """F at an index point, exactly (Fraction)."""
        cf = [Fraction(x) for x in self.coeffs]
        return field_value(cf, *[Fraction(float(x)) for x in p])


# Grids: anisotropic with an origin far from 0, dyadic (grid planes exact in
# world coordinates), and the unit grid.
ANISO = dict(origin=(-5.5, 3.25, 100.0), spacing=(0.7, 1.3, 2.1))
DYADIC = dict(origin=(-4.0, 2.5, 8.0), spacing=(0.5, 1.0, 2.0))
UNIT = dict(origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0))

TERMS = {
    "full": (1, 1, 1, 1, 1, 1, 1, 1),
    "no_xyz": (1, 1, 1, 1, 1, 1, 1, 0),
    "linear": (1, 1, 1, 1, 0, 0, 0, 0),
    "saddle_xy": (1, 1, 1, 0, 1, 0, 0, 0),
    "xyz_only": (1, 0, 0, 0, 0, 0, 0, 1),
    "bilinear": (1, 0, 0, 0, 1, 1, 1, 0),
}


# ------------------------------------------------------------------ scenes

def random_scene(rng, shape, dtype=np.float64, terms="full", span=None, grid=ANISO,
                 denominator=1, name=""):
    """A random exact-trilinear field on ``shape`` whose samples span about ``span``.

    Integer coefficients (multiples of ``1/denominator`` for float64); for
    integer dtypes the field is shifted and shrunk until it fits.
    """
    nz, ny, nx = shape
    mono_max = [1, nx - 1, ny - 1, nz - 1, (nx - 1) * (ny - 1), (ny - 1) * (nz - 1),
                (nz - 1) * (nx - 1), (nx - 1) * (ny - 1) * (nz - 1)]
    if np.dtype(dtype).kind in "ui":
        info = np.iinfo(dtype)
        limit = int(info.max) - int(info.min)
        span = span or 0.9 * limit
    else:
        info, limit = None, None
        span = span or 1000.0
    mask = TERMS[terms]
    while True:
        w = rng.uniform(-1, 1, 8) * np.array(mask)
        w[0] = 0
        active = max(1, sum(mask[1:]))
        coeffs = [Fraction(round(w[m] * span / active / max(mono_max[m], 1) * denominator),
                           denominator) if mask[m] else Fraction(0) for m in range(8)]
        if all(c == 0 for c in coeffs[1:]):
            continue
        lo, hi = field_range(coeffs, shape)
        if hi > lo:      # stretch to the requested span (still integer / dyadic)
            f = Fraction(span) / (hi - lo)
            coeffs = [Fraction(math.floor(c * f * denominator), denominator) for c in coeffs]
            lo, hi = field_range(coeffs, shape)
        if info is not None:
            if hi - lo > limit:
                span *= 0.8
                continue
            shift = int(info.min) - lo + Fraction(int(rng.integers(0, int(limit - (hi - lo)) + 1)))
            coeffs[0] = Fraction(math.floor(shift))
        else:
            coeffs[0] = Fraction(round(rng.uniform(-1, 1) * span * denominator), denominator) - lo
        return Scene([float(c) for c in coeffs], shape, dtype, name=name or terms, **grid)


def data_range(scene):
    return float(scene.data.min()), float(scene.data.max())


def random_isos(rng, scene, n):
    """Mixed isovalues: random doubles in range, sample values, half-way values."""
    lo, hi = data_range(scene)
    flat = scene.data.ravel()
    out = []
    for m in range(n):
        kind = m % 3
        if kind == 0:
            out.append(float(rng.uniform(lo, hi)))
        elif kind == 1:
            out.append(float(flat[rng.integers(flat.size)]))
        else:
            out.append(float(flat[rng.integers(flat.size)]) + 0.5)
    return out
