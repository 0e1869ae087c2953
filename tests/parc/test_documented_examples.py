"""The examples users copy: the README's Python block and scene file, and examples/*.toml.

Truth: what their comments promise. `parc` gives `brute`'s image; the scene
files load into the volumes, camera and lights they write out. Image sizes
are shrunk to keep the run short; nothing else in the text is changed.
"""
import os
import re
from pathlib import Path

import numpy as np
import pytest

import parc
from data_tools.io import save_volume
from data_tools.synthetic import make_synthetic
from parc.comparison import image_error

ROOT = Path(__file__).parents[2]
README = (ROOT / "README.md").read_text()
CTHEAD = ROOT.parent / "shared" / "data" / "CThead.nrrd"


def _block(language, after):
    """The first ```language block of the README after the heading ``after``."""
    return README.split(after, 1)[1].split(f"```{language}\n", 1)[1].split("```", 1)[0]


def _same_images(scene, **options):
    ref = parc.render(scene, "brute")
    res = parc.render(scene, "parc", **options)
    err = image_error(res, ref, min(min(v.volume.spacing) for v in scene.volumes))
    assert err["hit_mismatches"] == 0 and err["max_depth_cells"] <= 1e-9 and err["max_color"] <= 1e-6, err
    return ref


def test_the_readme_python_block_runs_and_keeps_its_promises(tmp_path, monkeypatch, gl):
    if not CTHEAD.is_file():
        pytest.skip(f"{CTHEAD} not present")
    code = _block("python", "## Python")
    small = re.sub(r"size=\(\d+, \d+\)", "size=(40, 32)", code)
    assert small.count("size=(40, 32)") == 3, "the README's scenes changed: update this test"
    # The README loads ../shared/data/CThead.nrrd, as from a clone beside the shared folder.
    (tmp_path / "shared" / "data").mkdir(parents=True)
    os.symlink(CTHEAD, tmp_path / "shared" / "data" / "CThead.nrrd")
    (tmp_path / "repo").mkdir()
    monkeypatch.chdir(tmp_path / "repo")
    names = {}
    exec(compile(small, "README.md (Python)", "exec"), names)
    scene, lit, tl, rows = names["scene"], names["lit"], names["tl"], names["rows"]
    # "or 'brute': the same image, unaccelerated"; compare's rows say it too.
    assert np.isfinite(names["result"].depth).any()                    # the skin is in view
    _same_images(scene)
    # "as parc render writes it": 8-bit RGBA, opaque where the skin is hit.
    from PIL import Image
    with Image.open(tmp_path / "repo" / "head.png") as png:
        saved = np.asarray(png)
    assert saved.shape == (32, 40, 4) and np.array_equal(saved[..., 3] == 255, np.isfinite(names["result"].depth))
    assert [r["method"] for r in rows] == ["brute", "parc"] and rows[1]["hit_mismatches"] == 0
    # "this head's top is at -z": the lamp "above the head" has the smaller z.
    lamp = lit.lights[0]
    assert lamp.position[2] < scene.volumes[0].volume.bounds[0][2]
    assert lit.shadows and len(lit.volumes) == 2
    # "depth buffers (default), bit planes, or both": each the same image.
    ref = parc.render(tl, "brute")
    assert ref.image[..., 3].max() > 0.1
    for buffers in ("depth", "bits", "depth,bits"):
        assert np.abs(parc.render(tl, "parc", buffers=buffers).image - ref.image).max() <= 1e-6, buffers


def test_the_readme_scene_file_describes_what_it_says(tmp_path, gl):
    text = _block("toml", "## Scene files")
    # "parc make neuron -o neuron.nrrd first"; a smaller one keeps its value range.
    save_volume(make_synthetic("neuron", 48), tmp_path / "neuron.nrrd")
    (tmp_path / "neuron.toml").write_text(text)
    scene = parc.load_scene(tmp_path / "neuron.toml", size=(40, 40))
    neuron, floor = scene.volumes
    assert (neuron.value, floor.value) == (80.5, 127.5)
    assert floor.volume.data.shape == (24, 192, 192)                      # "size samples per axis", a thin slab
    assert np.array_equal(floor.volume.origin, [-32, -32, -12])
    assert np.array_equal(scene.camera.eye, [330, -260, 170]) and scene.camera.fov == 30
    assert scene.shadows and [type(light).__name__ for light in scene.lights] == ["PointLight", "DirectionalLight"]
    assert tuple(scene.background[:3]) == (0.05, 0.05, 0.08)
    ref = _same_images(scene)
    assert np.isfinite(ref.depth).any()


@pytest.mark.parametrize("path", sorted((ROOT / "examples").glob("*.toml")), ids=lambda p: p.name)
def test_each_example_scene_renders_the_same_by_both_methods(path, gl):
    scene = parc.load_scene(path, size=(40, 40))
    ref = _same_images(scene)
    # Every volume of the example shows: each alone hits some pixel of its view.
    for vis in scene.volumes:
        alone = parc.Scene(camera=scene.camera, size=scene.size, volumes=[vis])
        assert np.isfinite(parc.render(alone, "brute").depth).any(), vis.volume.name
    assert np.isfinite(ref.depth).any()
