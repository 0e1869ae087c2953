"""Named transfer functions (`--tf PRESET`): CT skin and bone, and two ramps over the data range."""
from __future__ import annotations

import math

from data_tools import InputError
from data_tools.volume import three_numbers

from .function import TransferFunction, short_repr


#: Opacity at the top of the data range for the ramp presets (``greyscale``,
#: ``viridis``) and for ParaView maps without opacity points.
RAMP_OPACITY = 0.1

#: The ramp presets are transparent over this bottom fraction of the data
#: range, so the background and its noise stay empty cells.
RAMP_START = 0.1

#: Viridis (matplotlib; van der Walt, Smith, Firing; CC0): 32 of its 256
#: colours, ``(position in [0, 1], r, g, b)``, sample ``i`` at ``i / 255``.
#: Linear interpolation between them stays within 0.0065 of the full table.
VIRIDIS = (
    (0, 0.267004, 0.004874, 0.329415), (8, 0.277018, 0.050344, 0.375715),
    (16, 0.282327, 0.094955, 0.417331), (25, 0.282623, 0.140926, 0.457517),
    (33, 0.278012, 0.180367, 0.486697), (41, 0.269308, 0.218818, 0.509577),
    (49, 0.257322, 0.256130, 0.526563), (58, 0.241237, 0.296485, 0.539709),
    (66, 0.225863, 0.330805, 0.547314), (74, 0.210503, 0.363727, 0.552206),
    (82, 0.195860, 0.395433, 0.555276), (90, 0.182256, 0.426184, 0.557120),
    (99, 0.168126, 0.459988, 0.558082), (107, 0.156270, 0.489624, 0.557936),
    (115, 0.144759, 0.519093, 0.556572), (123, 0.133743, 0.548535, 0.553541),
    (132, 0.123463, 0.581687, 0.547445), (140, 0.119423, 0.611141, 0.538982),
    (148, 0.124780, 0.640461, 0.527068), (156, 0.143303, 0.669459, 0.511215),
    (165, 0.180653, 0.701402, 0.488189), (173, 0.226397, 0.728888, 0.462789),
    (181, 0.281477, 0.755203, 0.432552), (189, 0.344074, 0.780029, 0.397381),
    (197, 0.412913, 0.803041, 0.357269), (206, 0.496615, 0.826376, 0.306377),
    (214, 0.575563, 0.844566, 0.256415), (222, 0.657642, 0.860219, 0.203082),
    (230, 0.741388, 0.873449, 0.149561), (239, 0.835270, 0.886029, 0.102646),
    (247, 0.916242, 0.896091, 0.100717), (255, 0.993248, 0.906157, 0.143936),
)

# CT presets are in the units of 16-bit CT like the Stanford CThead (not
# Hounsfield: air 0-300, skin and soft tissue ~1000-1100, bone 1200-3000;
# the air/skin boundary passes 500-900, the tissue/bone one 1100-1300).
# Opacities are per reference step (a quarter voxel): 0.08 makes a few
# voxels of skin a visible shell, 0.024 (skin in ct_skin_bone) a veil, and
# 0.5 is opaque within a voxel.
_SKIN_OPACITY = ((400.0, 0.0), (600.0, 0.08), (850.0, 0.08), (1000.0, 0.0))

_SKIN_COLOR = ((400.0, 0.70, 0.40, 0.30), (700.0, 0.93, 0.68, 0.55), (1000.0, 1.0, 0.82, 0.70))

_BONE_OPACITY = ((1200.0, 0.0), (1500.0, 0.4), (2000.0, 0.7))

_BONE_COLOR = ((1200.0, 0.90, 0.80, 0.65), (1600.0, 1.0, 0.96, 0.88), (2500.0, 1.0, 1.0, 1.0))

def _ct_skin(data_range=None, mode="composite"):
    return TransferFunction(_SKIN_OPACITY, _SKIN_COLOR, name="ct_skin",
                            description=PRESET_DESCRIPTIONS["ct_skin"], source="preset ct_skin")

def _ct_bone(data_range=None, mode="composite"):
    return TransferFunction(_BONE_OPACITY, _BONE_COLOR, name="ct_bone",
                            description=PRESET_DESCRIPTIONS["ct_bone"], source="preset ct_bone")

def _ct_skin_bone(data_range=None, mode="composite"):
    skin = tuple((v, 0.3 * a) for v, a in _SKIN_OPACITY)   # a veil: bone shows through
    return TransferFunction(skin + _BONE_OPACITY, _SKIN_COLOR + _BONE_COLOR, name="ct_skin_bone",
                            description=PRESET_DESCRIPTIONS["ct_skin_bone"],
                            source="preset ct_skin_bone")

def ramp_opacity(mode="composite"):
    """The ramp presets' opacity over a normalized [0, 1] range, for rendering ``mode``.

    Composite opacities are per reference step, and `RAMP_OPACITY` at the top
    lets a ray see into the volume. A maximum-intensity pixel shows one value
    at that value's opacity: there the ramp ends opaque, else its brightest
    pixel was 10% grey on black. (The average mode asks only where the
    opacity is non-zero, which is the same in either ramp.)
    """
    return ((0.0, 0.0), (RAMP_START, 0.0), (1.0, RAMP_OPACITY if mode == "composite" else 1.0))

def _greyscale(data_range=None, mode="composite"):
    lo, hi = data_range_of(data_range, "greyscale")
    tf = TransferFunction(ramp_opacity(mode), ((0.0, 0.0, 0.0, 0.0), (1.0, 1.0, 1.0, 1.0)),
                          name="greyscale", description=PRESET_DESCRIPTIONS["greyscale"],
                          source="preset greyscale")
    return tf.mapped(lo, hi)

def _viridis(data_range=None, mode="composite"):
    lo, hi = data_range_of(data_range, "viridis")
    col = [(i / 255.0, r, g, b) for i, r, g, b in VIRIDIS]
    tf = TransferFunction(ramp_opacity(mode), col, name="viridis",
                          description=PRESET_DESCRIPTIONS["viridis"], source="preset viridis")
    return tf.mapped(lo, hi)

def data_range_of(data_range, who):
    """``(lo, hi)`` floats with ``hi > lo`` (a one-value range is widened to ``(lo, lo + max(1, 1e-9 |lo|))``,
    a span float64 holds at any ``lo``)."""
    if data_range is None:
        raise InputError(f"{who} spans the data range: give the data range (lo, hi)")
    pair = three_numbers(data_range)
    if pair is None or len(pair) != 2:
        raise InputError(f"{who}: data range must be two numbers, got {short_repr(data_range)}")
    lo, hi = pair
    if not (math.isfinite(lo) and math.isfinite(hi) and math.isfinite(hi - lo)):
        raise InputError(f"{who}: data range must be finite, got ({lo:g}, {hi:g})")
    if hi < lo:
        raise InputError(f"{who}: data range ({lo:g}, {hi:g}) is reversed")
    if hi == lo:
        hi = lo + max(1.0, abs(lo) * 1e-9)
    return lo, hi

#: One line per preset: each preset's ``description``.
PRESET_DESCRIPTIONS = {
    "ct_skin": "CThead-like CT: translucent skin-toned shell at the air/skin boundary (500-900)",
    "ct_bone": "CThead-like CT: whitish, nearly opaque bone (1200 and up)",
    "ct_skin_bone": "CThead-like CT: faint skin over opaque bone, the classic CT look",
    "greyscale": "black to white over the data range, opacity ramping up from 10% of it (to 1 for mip, average)",
    "viridis": "viridis colours over the data range, opacity ramping up from 10% of it (to 1 for mip, average)",
}

#: Preset name -> factory ``f(data_range=None, mode="composite") -> TransferFunction``. The
#: CT presets use absolute values and ignore the range; the others need it, and ramp
#: their opacity by the mode (`ramp_opacity`).
PRESETS = {
    "ct_skin": _ct_skin,
    "ct_bone": _ct_bone,
    "ct_skin_bone": _ct_skin_bone,
    "greyscale": _greyscale,
    "viridis": _viridis,
}

#: The rendering modes of a translucent volume, which its transfer function is made for: the ramps end by it.
MODES = ("composite", "mip", "average")


def check_mode(mode):
    """Refuse a ``mode`` other than one of `MODES` (an array too, which NumPy cannot compare)."""
    if not isinstance(mode, str) or mode not in MODES:
        raise InputError(f"unknown mode {mode!r}; choose one of {', '.join(MODES)}")


def preset(name, data_range=None, mode="composite"):
    """The preset ``name`` for data in ``data_range = (lo, hi)`` rendered in ``mode`` (the ramps
    end opaque for maximum and average intensity, `ramp_opacity`); see `PRESETS`."""
    if not isinstance(name, str) or name not in PRESETS:     # a list is no key
        raise InputError(f"unknown transfer function preset {name!r}; known: {', '.join(PRESETS)}")
    check_mode(mode)
    if data_range is not None:
        # Checked for the CT presets too, which do not use it: a wrong range is a wrong call.
        data_range_of(data_range, name)
    return PRESETS[name](data_range, mode)
