"""Transfer functions: data value -> colour and opacity, for translucent volumes.

- `parc.transfer.function`: `TransferFunction`, piecewise-linear opacity
  and colour with the range test classification asks (which cells may
  contribute), and the opacity's reference step;
- `parc.transfer.presets`: the named ones (``--tf ct_skin_bone``);
- `parc.transfer.files`: our TOML/JSON files and ParaView colour maps.

The casters' kernels are `raycast.transfer`'s; `correct_opacity`,
`tf_lookup` and `tf_opacity` are re-exported here with the rest.
"""
from raycast.transfer import correct_opacity, tf_lookup, tf_opacity

from .files import load_for_volume, load_transfer_function, save_transfer_function
from .function import REFERENCE_STEP_FRACTION, TransferFunction, reference_step
from .presets import PRESET_DESCRIPTIONS, PRESETS, RAMP_OPACITY, VIRIDIS, preset

__all__ = [
    "PRESETS", "PRESET_DESCRIPTIONS", "RAMP_OPACITY", "REFERENCE_STEP_FRACTION", "VIRIDIS",
    "TransferFunction", "correct_opacity", "load_for_volume", "load_transfer_function", "preset",
    "reference_step", "save_transfer_function", "tf_lookup", "tf_opacity",
]
