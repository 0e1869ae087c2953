"""ShowsNothingWarning names the user's line, however deep in PARC the Translucent is made."""
import dataclasses
import warnings

import numpy as np

import parc
from data_tools import Volume
from data_tools.io import save_volume
from parc.comparison import step_sweep


def _caught(make):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        make()
    return [(w.filename, w.category) for w in caught]


def test_the_warning_names_the_callers_line_through_replace_load_scene_and_a_sweep(tmp_path):
    vol = Volume(np.linspace(0, 10, 27, dtype=np.float32).reshape(3, 3, 3))
    above = parc.TransferFunction(opacity=[[10.5, 0], [20, 1]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fog = parc.Translucent(vol, above)
    assert _caught(lambda: dataclasses.replace(fog, step=0.5)) == [(__file__, parc.ShowsNothingWarning)]
    save_volume(vol, tmp_path / "v.npy")
    (tmp_path / "far.toml").write_text("opacity = [[10.5, 0], [20, 1]]\n")
    (tmp_path / "s.toml").write_text('size = [8, 8]\n[[volume]]\nfile = "v.npy"\ntf = "far.toml"\n')
    assert _caught(lambda: parc.load_scene(tmp_path / "s.toml")) == [(__file__, parc.ShowsNothingWarning)]
    scene = parc.Scene(camera=parc.Camera.framing(*vol.bounds), size=(8, 8), volumes=[fog])
    got = _caught(lambda: step_sweep(scene, [1.0], repeats=1, warmup=0))
    assert got and all(w == (__file__, parc.ShowsNothingWarning) for w in got)
