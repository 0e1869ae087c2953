"""Bad arguments to the library: an InputError whose message names the problem, raised before any work.

Truth: the documented argument types; each case below once ended in a
TypeError, ValueError, ZeroDivisionError, MemoryError or Numba typing error
deep inside, or was silently accepted.
"""
import dataclasses
import math
import re

import numpy as np
import pytest

import parc
from data_tools import InputError, Volume
from data_tools.io import save_volume
from data_tools.io.raw import read_raw
from data_tools.synthetic import blobs
from parc.comparison import step_sweep
from parc.transfer import preset, save_transfer_function

VOL = blobs(12, seed=3)
ISO = float(VOL.data.mean())
CAM = parc.Camera.framing(*VOL.bounds)


def _fog():
    return _scene(volumes=[parc.Translucent(VOL, "greyscale")])


def _thin_scene(spacing_x, camera):
    ramp = np.broadcast_to(np.arange(8.0), (8, 8, 8))
    thin = parc.Isosurface(Volume(np.ascontiguousarray(ramp), spacing=(spacing_x, 1.0, 1.0)), 3.0)
    return parc.Scene(camera=camera, size=(8, 8), volumes=[thin])


def _scene(**kw):
    args = dict(camera=CAM, size=(8, 8), volumes=[parc.Isosurface(VOL, ISO)])
    args.update(kw)
    return parc.Scene(**args)


CASES = {
    "volume spacing as a string": (lambda: Volume(VOL.data, spacing="123"), "spacing"),
    "volume spacing of booleans": (lambda: Volume(VOL.data, spacing=[True] * 3), "spacing"),
    "surface colour as a word": (lambda: parc.Isosurface(VOL, ISO, color="red"), "colour"),
    "material of two numbers": (lambda: parc.Isosurface(VOL, ISO, material=(0.1, 0.7)), "material"),
    "material none": (lambda: parc.Isosurface(VOL, ISO, material=None), "material"),
    "negative material": (lambda: parc.Translucent(VOL, "greyscale", material=(-1, 1, 1, 10)), "material"),
    "transfer function as a dict": (lambda: parc.Translucent(VOL, {"opacity": 1}), "transfer function"),
    "threshold as text": (lambda: parc.Translucent(VOL, "greyscale", threshold="abc"), "threshold"),
    "shade as text": (lambda: parc.Translucent(VOL, "greyscale", shade="yes"), "shade"),
    "camera eye as text": (lambda: parc.Camera(eye="abc", look_at=(0, 0, 0)), "eye"),
    # Triples of text or booleans, which NumPy reads as numbers ("1" as 1.0, True as 1.0).
    "camera eye of digits": (lambda: parc.Camera(eye=["1", "2", "3"], look_at=(0, 0, 0)), "camera eye"),
    "camera up of booleans": (lambda: parc.Camera(eye=(0, 0, 5), look_at=(0, 0, 0), up=[False, True, False]),
                              "camera up"),
    "light position of digits": (lambda: parc.PointLight(["1", "2", "3"]), "light position"),
    "sun direction of booleans": (lambda: parc.DirectionalLight([True, False, False]), "light direction"),
    "surface colour of digits": (lambda: parc.Isosurface(VOL, ISO, color=["1", "0", "0"]), "surface colour"),
    "background of digits": (lambda: _scene(background=["0", "0", "0"]), "background"),
    "background of booleans": (lambda: _scene(background=[True, True, True, True]), "background"),
    "parallel scale as a list": (lambda: parc.Camera(eye=(0, 0, 5), look_at=(0, 0, 0), parallel_scale=[5]),
                                 "parallel scale"),
    "framing zoom 0": (lambda: parc.Camera.framing(*VOL.bounds, zoom=0), "zoom"),
    "framing azimuth inf": (lambda: parc.Camera.framing(*VOL.bounds, azimuth=math.inf), "finite angles"),
    "framing parallel as text": (lambda: parc.Camera.framing(*VOL.bounds, parallel="False"), "True or False"),
    "framing zoom as text": (lambda: parc.Camera.framing(*VOL.bounds, zoom="3"), "numeric zoom"),
    "supercell of the smallest float": (lambda: parc.render(_scene(), "parc", supercell=5e-324),
                                        "gives over 1e300 supercells"),  # no integer holds the count
    # Checked but not used by brute, which took what parc refused: one set of arguments serves both.
    "supercell too small for the volume, for brute": (lambda: parc.render(_scene(), "brute", supercell=1e-9),
                                                      "supercells (at most 268435456)"),
    "transfer function None": (lambda: parc.load_transfer_function(None), "got NoneType"),
    "transfer function path as bytes": (lambda: parc.load_transfer_function(b"x.toml"), "got bytes"),
    "save_volume to None": (lambda: save_volume(VOL, None), "takes a file's path, got NoneType"),
    "methods as bytes": (lambda: parc.compare(_scene(), methods=[b"brute"]), "methods must be names"),
    "transfer function of an unknown mode": (lambda: parc.load_transfer_function("greyscale", (0, 1), mode="bogus"),
                                             "unknown mode 'bogus'"),
    # An array for a name: NumPy's "truth value ... ambiguous", or an unhashable key, from deep inside.
    "translucent mode as an array": (lambda: parc.Translucent(VOL, "greyscale", mode=np.array(["mip", "average"])),
                                     "unknown mode array"),
    "translucent mode as an array of one": (lambda: parc.Translucent(VOL, "greyscale", mode=np.array(["mip"])),
                                            "unknown mode array"),
    "transfer function mode as an array": (lambda: parc.load_transfer_function("ct_skin", mode=np.array(["mip"])),
                                           "unknown mode array"),
    "preset as a list": (lambda: preset(["greyscale"]), "unknown transfer function preset"),
    "preset mode as an array": (lambda: preset("greyscale", mode=np.array(["mip"])), "unknown mode array"),
    "save_transfer_function of None": (lambda: save_transfer_function(None, "x.toml"),
                                       "takes a TransferFunction, got NoneType"),
    "parallel eye past float64's resolution of the volume": (
        lambda: _scene(camera=parc.Camera(eye=(1e20, 0, 0), look_at=(0, 0, 0), parallel_scale=5)),
        "is over 2^32 times the volumes' size"),
    "perspective eye past it": (lambda: _scene(camera=parc.Camera(eye=(-1e16, 0, 0), look_at=(0, 0, 0))),
                                "bring the eye closer"),
    # Float64 placed rays across a volume 7e-16 thick, seen from 12 away, at a few points only:
    # two thirds of its hits were lost, without a word.
    "volume thinner than float64 resolves from the eye": (
        lambda: _thin_scene(1e-16, parc.Camera.framing((0, 0, 0), (7e-16, 7, 7))), "check its spacing along x"),
    "eye too far for a thin volume": (
        lambda: _thin_scene(1e-9, parc.Camera(eye=(7.6e8, -4.56e8, 3.04e8), look_at=(0, 3.5, 3.5), parallel_scale=6)),
        "bring the eye closer"),
    "framing corner of two": (lambda: parc.Camera.framing((0, 0, 0), (1, 1)), "corners"),
    "size infinite": (lambda: _scene(size=(float("inf"), 16)), "image size"),
    "volumes not a list": (lambda: _scene(volumes=parc.Isosurface(VOL, ISO)), "volumes must be a list"),
    "lights none": (lambda: _scene(lights=None), "lights must be a list"),
    "background as a word": (lambda: _scene(background="black"), "background"),
    "shadows as text": (lambda: _scene(shadows="false"), "shadows"),
    "zero sun from overflow": (lambda: parc.DirectionalLight((1e308, 1e308, 0)).direction, None),
    "render without a scene": (lambda: parc.render(parc.Isosurface(VOL, ISO)), "Scene"),
    "blocks as an array": (lambda: parc.render(_scene(), blocks=np.array([1, 1])), "blocks"),
    "progress not callable": (lambda: parc.render(_scene(), progress=5), "progress"),
    "work as text": (lambda: parc.render(_scene(), work="yes"), "work"),
    "work for surfaces and translucent volumes": (
        lambda: parc.render(_scene(volumes=[parc.Isosurface(VOL, ISO), parc.Translucent(VOL, "greyscale")]),
                            work=True),
        "work: per-pixel work counts cells visited for isosurfaces and samples taken for translucent volumes"),
    "supercell 1e-9": (lambda: parc.render(_scene(), method="parc", supercell=1e-9), "choose a larger size"),
    # Short, not a 300-digit count (nor a float too large for the count's format).
    "supercell 1e-300": (lambda: parc.render(_scene(), method="parc", supercell=1e-300), "gives about 1e9"),
    "light buffer of 2.5": (lambda: parc.render(_scene(), light_buffer=2.5), "light buffers"),
    "light buffer of 1e9": (lambda: parc.render(_scene(lights=[parc.PointLight((1, 2, 3))]), light_buffer=10**9),
                            "light buffers"),
    "buffers on a lit scene": (lambda: parc.render(_scene(lights=[parc.PointLight((1, 2, 3))]), buffers="foo"),
                               "buffers"),
    "framing fov 1e-13": (lambda: parc.Camera.framing(*VOL.bounds, fov=1e-13), "too narrow"),
    "framing straight down": (lambda: parc.Camera.framing(*VOL.bounds, elevation=90), "elevation of 90"),
    "load_scene of None": (lambda: parc.load_scene(None), "path of a scene file"),
    "load_scene view with a typo": (lambda: parc.load_scene("scene.toml", view={"fvo": 50}), "view takes camera"),
    "bit planes for an isosurface": (lambda: parc.render(_scene(), method="parc", buffers="bits"), "bit planes"),
    # As the render docstring says (a scene of isosurfaces alone refuses bits) and `parc render
    # --buffers` refuses, rather than left out without a word; brute checks them too.
    "depth and bit planes for an isosurface": (lambda: parc.render(_scene(), method="parc", buffers="depth,bits"),
                                               "this scene has an isosurface; use depth"),
    "depth and bit planes for an isosurface, brute": (lambda: parc.render(_scene(), buffers=("depth", "bits")),
                                                      "this scene has an isosurface; use depth"),
    "depth and bit planes for isosurfaces": (
        lambda: parc.render(_scene(volumes=[parc.Isosurface(VOL, ISO)] * 2), method="parc", buffers="depth,bits"),
        "this scene has isosurfaces alone"),
    "bit planes alone beside an isosurface": (
        lambda: parc.render(_scene(volumes=[parc.Isosurface(VOL, ISO), parc.Translucent(VOL, "greyscale")]),
                            method="parc", buffers="bits"),
        "leave out the depth buffers isosurfaces use; bit planes apply to translucent volumes: give buffers "
        "depth,bits for both"),
    "supercell as text for brute": (lambda: parc.render(_scene(), supercell="a"), "supercell"),
    "shade with mip": (lambda: parc.Translucent(VOL, "greyscale", mode="mip", shade=True), "mode composite"),
    # Refused as the command line and scene files refuse it, not taken and ignored.
    "threshold with average": (lambda: parc.Translucent(VOL, "greyscale", mode="average", threshold=0.5),
                               "threshold applies to mode composite; average does not stop rays early"),
    "step sweep repeats 0": (lambda: step_sweep(_fog(), [0.5], repeats=0), "repeats"),
    "step sweep of one number": (lambda: step_sweep(_fog(), 0.5), "sweep steps"),
    "step sweep of a word": (lambda: step_sweep(_fog(), ["fine"]), "sweep steps"),
    "step sweep of a boolean": (lambda: step_sweep(_fog(), [True]), "sweep steps"),
    # Named as given, not as the reference a quarter of it would be.
    "step sweep of a step too fine": (lambda: step_sweep(_fog(), [0.5, 1e-5]), "step 1e-05 is below 1e-4"),
    "step sweep of a Translucent": (lambda: step_sweep(parc.Translucent(VOL, "greyscale"), [0.5]), "Scene"),
    "step sweep progress 5": (lambda: step_sweep(_fog(), [0.5], progress=5), "progress"),
    "step as text": (lambda: parc.Translucent(VOL, "greyscale", step="0.5"), "step must be a number"),
    # 1e-4 of the smallest spacing per step, but 4e8 steps across the box's diagonal (9.9).
    "step too fine for the box": (lambda: parc.Translucent(Volume(np.zeros((8, 8, 8)), spacing=(1e-7, 1, 1)),
                                                           "greyscale"),
                                  "the default step 2.5e-08 puts 4e+08 samples on a ray across the volume's diagonal "
                                  "(9.89949), more than 1e+08: give a step of at least 9.9e-08"),
    "step True": (lambda: parc.Translucent(VOL, "greyscale", step=True), "step must be a number"),
    "threshold True": (lambda: parc.Translucent(VOL, "greyscale", threshold=True), "threshold"),
    "rays of no rows": (lambda: parc.Camera(eye=(0, 0, 5), look_at=(0, 0, 0)).rays(8, 0),
                        "image size must be two positive integers, got 8 x 0"),
    "rays of a float width": (lambda: parc.Camera(eye=(0, 0, 5), look_at=(0, 0, 0)).rays(8.0, 8),
                              "image size must be two positive integers, got 8.0 x 8"),
    "projection past int32 pixels": (
        lambda: parc.Camera(eye=(0, 0, 5), look_at=(0, 0, 0)).projection_matrix(2 ** 31, 1, 0.1, 10),
        "image size must be two positive integers, got 2147483648 x 1"),
    # Its repr cut short: 401 digits would make the one line a screenful.
    "rays of a size past float": (lambda: parc.Camera(eye=(0, 0, 5), look_at=(0, 0, 0)).rays(10 ** 400, 1),
                                  "image size must be two positive integers, got "
                                  "1000000000000000000000000000000000000000 x 1"),
    "projection of no depth": (lambda: parc.Camera(eye=(0, 0, 5), look_at=(0, 0, 0)).projection_matrix(8, 8, 1, 1),
                               "depth range must be finite numbers near < far, near > 0, got near 1.0, far 1.0"),
    "perspective from the eye": (lambda: parc.Camera(eye=(0, 0, 5), look_at=(0, 0, 0)).projection_matrix(8, 8, 0, 1),
                                 "near > 0"),
    "CT preset over a reversed range": (lambda: parc.load_transfer_function("ct_skin", (1, 0)),
                                        "ct_skin: data range (1, 0) is reversed"),
    "CT preset over a range of text": (lambda: parc.load_transfer_function("ct_bone", "0,100"),
                                       "ct_bone: data range must be two numbers"),
    "fov as text": (lambda: parc.Camera(eye=(0, 0, 5), look_at=(0, 0, 0), fov="30"), "field of view"),
    "fov True": (lambda: parc.Camera(eye=(0, 0, 5), look_at=(0, 0, 0), fov=True), "field of view"),
    "light intensity True": (lambda: parc.PointLight((1, 2, 3), intensity=True), "intensity"),
    "isovalue as text": (lambda: parc.Isosurface(VOL, str(ISO)), "isovalue must be a number"),
    "isovalue True": (lambda: parc.Isosurface(VOL, True), "isovalue must be a number"),
    "isovalue NaN": (lambda: parc.Isosurface(VOL, math.nan), "isovalue must be finite, got nan"),
    "isovalue inf": (lambda: parc.Isosurface(VOL, -math.inf), "isovalue must be finite, got -inf"),
    "size of booleans": (lambda: _scene(size=(True, True)), "image size"),
    "size as text": (lambda: _scene(size=("8", "8")), "image size"),
    "supercell True": (lambda: parc.render(_scene(), method="parc", supercell=True), "supercell"),
    "supercell as text": (lambda: parc.render(_scene(), method="parc", supercell="4"), "supercell"),
    "supercell with a boolean": (lambda: parc.render(_scene(), method="parc", supercell=(2, True, 2)), "supercell"),
    "supercell of two numbers": (lambda: parc.render(_scene(), method="parc", supercell=(1, 2)),
                                 "supercell size must be a number or three numbers, got 2: (1, 2)"),
    "parallel scale True": (lambda: parc.Camera(eye=(0, 0, 5), look_at=(0, 0, 0), parallel_scale=True),
                            "parallel scale"),
    "volume named by a number": (lambda: Volume(VOL.data, name=5), "a volume's name must be text, got 5"),
    "eye as a dict": (lambda: parc.Camera(eye={0: 1, 1: 2, 2: 3}), "camera eye must be three finite numbers"),
    "volume meta as a list": (lambda: Volume(VOL.data, meta=[1, 2]), "meta must be a dict"),
    "ragged nested list": (lambda: Volume([[[1, 2], [3]], [[1, 2], [3, 4]]]), "3-D array"),
    "compare option unknown": (lambda: parc.compare(_scene(), options={"parc": {"bogus": 1}}), "bogus"),
    "compare option method": (lambda: parc.compare(_scene(), options={"parc": {"method": "brute"}}), "method"),
    "compare progress 5": (lambda: parc.compare(_scene(), progress=5), "progress"),
    "repeats 1.5": (lambda: parc.compare(_scene(), repeats=1.5), "repeats"),
    "warmup none": (lambda: parc.compare(_scene(), warmup=None), "warmup"),
    "methods as a set": (lambda: parc.compare(_scene(), methods={"brute", "parc"}), "not a set"),
    "methods none": (lambda: parc.compare(_scene(), methods=None), "methods"),
    "options not dicts": (lambda: parc.compare(_scene(), options={"parc": None}), "options"),
    # Empty, but not a dict: a mistake in the call, not "no options".
    "options an empty list": (lambda: parc.compare(_scene(), options=[]), "options must map method names"),
    "step sweep options an empty list": (lambda: step_sweep(_fog(), [0.5], options=[]),
                                         "options must be a dict of render() arguments"),
    "method misspelt": (lambda: parc.render(_scene(), "Parc"), "unknown method 'Parc'; choose one of brute, parc"),
    # An array of one name would pass `in METHODS` (NumPy compares element-wise) and come back as stats["method"].
    "method as an array": (lambda: parc.render(_scene(), np.array(["brute"])), "unknown method array(['brute']"),
    "buffers none named": (lambda: parc.render(_fog(), "parc", buffers=[]), "PARC buffers must be"),
    "light buffer of 1": (lambda: parc.render(_scene(lights=[parc.PointLight((1, 2, 3))]), light_buffer=1),
                          "light buffers take a whole number of pixels from 2"),
    "repeats True": (lambda: parc.compare(_scene(), repeats=True), "repeats must be a whole number"),
    "repeats 10001": (lambda: parc.compare(_scene(), repeats=10_001), "repeats must be at most 10000, got 10001"),
    "warmup 10**20": (lambda: step_sweep(_fog(), [0.5], warmup=10**20), "warmup must be at most 10000"),
    "options for a method not run": (lambda: parc.compare(_scene(), methods=("brute",), options={"parc": {}}),
                                     "not among the methods"),
    # Taken before: load_scene kept a progress it could not call.
    "scene progress of a number": (lambda: parc.load_scene("scene.toml", progress=1),
                                   "progress must be a function of a line of text, got 1"),
}


def test_camera_rays_beyond_memory_are_refused_before_they_are_made(monkeypatch):
    # Allocated before: a MemoryError, or the process killed. (The memory is fixed here, so that
    # the test asks the same of every machine.)
    from data_tools import memory
    monkeypatch.setattr(memory, "available_memory", lambda: 2**30)
    with pytest.raises(InputError, match=r"camera rays for 100000x100000 pixels needs about .* 1\.0 GB is available"):
        CAM.rays(10**5, 10**5)
    origins, directions = CAM.rays(4, 3)
    assert origins.shape == directions.shape == (3, 4, 3)


def test_a_raw_files_mmap_is_a_flag(tmp_path):
    # bool("no") is True: the file was mapped.
    path = tmp_path / "v_2x2x2_uint8.raw"
    path.write_bytes(bytes(8))
    for value in ("no", 2, None):
        with pytest.raises(InputError, match=re.escape(f"mmap must be True or False, got {value!r}")):
            parc.load_volume(path, mmap=value) if value is not None else read_raw(path, mmap=value)
    assert parc.load_volume(path, mmap=True).dims == (2, 2, 2)


@pytest.mark.parametrize("name", list(CASES))
def test_bad_arguments_raise_input_error(name):
    make, words = CASES[name]
    if words is None:
        # A vector whose squared length overflows still has a direction.
        assert make() == pytest.approx((2 ** -0.5, 2 ** -0.5, 0.0))
        return
    with pytest.raises(InputError) as exc:
        make()
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_methods_may_be_named_in_one_string_each_once():
    rows = parc.compare(_scene(), methods="parc:a , brute", repeats=1, warmup=0)
    assert [r["method"] for r in rows] == ["brute", "parc:a"]
    # A name given twice would be timed once: refused, as a supercell size swept twice is.
    with pytest.raises(InputError, match="methods names 'parc' twice; to time a method twice, label"):
        parc.compare(_scene(), methods="brute,parc,parc", repeats=1, warmup=0)
    # A generator is read once: its names, not "names no method" from a second, empty read.
    rows = parc.compare(_scene(), methods=(m for m in ["brute", "parc"]), repeats=1, warmup=0)
    assert [r["method"] for r in rows] == ["brute", "parc"]


@pytest.mark.parametrize("options, words", [
    # An isosurface alone: the planes apply to nothing, and depth,bits would be refused in turn.
    ({"parc": {"buffers": "bits"}}, "buffers bits leave out the depth buffers isosurfaces use; bit planes apply to "
                                    "translucent volumes: give buffers depth"),
    ({"parc": {"buffers": "bogus"}}, "PARC buffers must be depth, bits or both"),
    ({"parc": {"blocks": "yes"}}, "blocks must be True or False, got 'yes'"),
    ({"parc:a": {"light_buffer": 1}}, "light buffers take a whole number of pixels from 2"),
    ({"brute": {"buffers": "depth,bits"}}, "this scene has an isosurface"),
])
def test_a_comparisons_options_are_refused_before_brute_renders(options, words):
    # Refused by the method's own first render, they would come after brute's warm-up
    # (minutes on a large scene).
    said = []
    with pytest.raises(InputError, match=re.escape(words)):
        parc.compare(_scene(), methods=["parc:a" if "parc:a" in options else "parc"], options=options, repeats=1,
                     progress=said.append)
    assert said == []


def test_a_step_sweeps_options_are_refused_before_its_reference_renders():
    said = []
    with pytest.raises(InputError, match="blocks must be True or False"):
        step_sweep(_fog(), [0.5], repeats=1, options={"blocks": "no"}, progress=said.append)
    assert said == []


#: A Python int float() cannot hold: it raises OverflowError, not the ValueError the checks catch.
BEYOND_FLOAT = 10 ** 400


@pytest.mark.parametrize("make, words", [
    (lambda: Volume(VOL.data, spacing=(BEYOND_FLOAT, 1, 1)), "spacing must be three numbers"),
    (lambda: parc.Isosurface(VOL, BEYOND_FLOAT), "isovalue must be a number"),
    (lambda: parc.Isosurface(VOL, ISO, material=(0.1, 0.7, 0.2, BEYOND_FLOAT)), "material must be"),
    (lambda: parc.Translucent(VOL, "greyscale", step=BEYOND_FLOAT), "step must be a number"),
    (lambda: parc.Translucent(VOL, "greyscale", threshold=BEYOND_FLOAT), "opacity threshold must be"),
    (lambda: parc.Camera(eye=(BEYOND_FLOAT, 0, 0)), "camera eye must be three finite numbers"),
    (lambda: parc.Camera(fov=BEYOND_FLOAT), "field of view must be"),
    (lambda: parc.Camera(parallel_scale=BEYOND_FLOAT), "parallel scale must be"),
    (lambda: parc.Camera.framing(*VOL.bounds, zoom=BEYOND_FLOAT), "numeric zoom"),
    (lambda: parc.PointLight((1, 2, 3), intensity=BEYOND_FLOAT), "light intensity must be"),
    (lambda: _scene(background=(BEYOND_FLOAT, 0, 0)), "background must be"),
    (lambda: parc.render(_scene(), supercell=BEYOND_FLOAT), "supercell size must be"),
    (lambda: parc.load_transfer_function("greyscale", (0, BEYOND_FLOAT)), "data range must be two numbers"),
    (lambda: step_sweep(_fog(), [BEYOND_FLOAT]), "sweep steps must be"),
], ids=lambda v: "" if callable(v) else v.split(" must")[0].replace(" ", "_"))
def test_an_integer_beyond_float64_is_refused_not_overflowed(make, words):
    with pytest.raises(InputError, match=re.escape(words)):
        make()


#: A value whose repr takes several lines.
GRID = np.ones((2, 2))


@pytest.mark.parametrize("make", [
    lambda: parc.Camera(fov=GRID),
    lambda: parc.Camera(eye=GRID),
    lambda: Volume(VOL.data, spacing=GRID),
    lambda: parc.Isosurface(VOL, GRID),
    lambda: parc.PointLight(GRID),
    lambda: _scene(size=GRID),
    lambda: parc.render(_scene(), supercell=GRID),
    lambda: parc.compare(_scene(), repeats=GRID),
    lambda: parc.Isosurface(Volume(VOL.data, name="two\nlines"), 1e9),
], ids=["fov", "eye", "spacing", "isovalue", "light", "size", "supercell", "repeats", "name"])
def test_a_message_echoing_a_value_of_several_lines_is_one_line(make):
    # NumPy writes a 2-D array's repr over lines, and a name may hold a newline; the command
    # line prints every message as one line after "parc: error:".
    with pytest.raises(InputError) as info:
        make()
    assert str(info.value).isprintable() and "  " not in str(info.value)
    assert "[1., 1.], [1., 1.]" in str(info.value) or "two\\nlines" in str(info.value)


def test_complex_numbers_dates_and_text_are_not_taken_for_numbers():
    # float() takes each, dropping an imaginary part (with a warning) or counting days since 1970.
    for value in (np.complex128(2.5 + 9j), np.datetime64("2020-01-01"), np.timedelta64(3, "D")):
        with pytest.raises(InputError, match="isovalue must be a number"):
            parc.Isosurface(VOL, value)
    with pytest.raises(InputError, match="camera eye must be three finite numbers"):
        parc.Camera(eye=np.array([20 + 5j, -15, 12]))
    with pytest.raises(InputError, match="material must be"):
        parc.Isosurface(VOL, ISO, material=("0.5", True, np.datetime64("2020-01-01"), 40))
    with pytest.raises(InputError, match="framing needs two corners of three numbers"):
        parc.Camera.framing(("1", b"2", True), VOL.bounds[1])
    for pair in (("0", "6"), {6.0, 0.0}, (False, True), b"\x00\x06"):
        with pytest.raises(InputError, match="data range must be two numbers"):
            parc.load_transfer_function("viridis", data_range=pair)
    for size in (b"\x08\x08", (np.ma.masked, 8)):
        with pytest.raises(InputError, match="image size must be two positive integers"):
            _scene(size=size)
    with pytest.raises(InputError, match="camera up must be three finite numbers"):
        parc.Camera.framing(*VOL.bounds, up=(BEYOND_FLOAT, 0, 1))


@pytest.mark.parametrize("make, words", [
    (lambda: parc.Isosurface(VOL, ISO, material=(0.1, 1e200, 0.2, 40)), "material must be"),
    (lambda: parc.Translucent(VOL, "greyscale", shade=True, material=(1e308, 1e308, 0.25, 40)), "material must be"),
    (lambda: parc.Isosurface(VOL, ISO, material=(0.1, 0.7, 0.2, 2e6)), "each at most 1e+06"),
    (lambda: parc.PointLight((1, 2, 3), intensity=1e200), "light intensity must be at most 1e+06, got 1e+200"),
    (lambda: parc.DirectionalLight((1, 2, 3), intensity=1.5e6), "light intensity must be at most 1e+06"),
])
def test_shading_factors_past_the_bound_are_refused(make, words):
    # Taken, 1e200 times 1e200 was infinite, and times a colour channel of 0 a NaN pixel.
    with pytest.raises(InputError, match=re.escape(words)):
        make()


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_the_largest_shading_factors_light_without_overflow(method):
    # Every factor at its bound, two lights, and a transfer function with a colour channel of 0.
    big = parc.scene.MAX_SHADING_FACTOR
    tf = parc.TransferFunction([(VOL.value_range()[0], 0.0), (ISO, 0.8), (VOL.value_range()[1], 0.1)],
                               [(VOL.value_range()[0], 1, 0, 0), (VOL.value_range()[1], 0, 0, 1)])
    lights = [parc.PointLight(tuple(np.asarray(VOL.bounds[1]) * 2), intensity=big),
              parc.DirectionalLight((-1, 0.5, -2), intensity=big)]
    for vis in (parc.Isosurface(VOL, ISO, color=(1, 0, 0.5), material=(big,) * 4),
                parc.Translucent(VOL, tf, shade=True, material=(big,) * 4)):
        image = parc.render(_scene(volumes=[vis], lights=lights, size=(16, 16)), method=method).image
        assert np.isfinite(image).all() and image.min() >= 0.0 and image.max() <= 1.0
        # Lit, and clipped: a surface's brightest channel at 1, a translucent one's at its opacity.
        rgb, alpha = image[..., :3].max(axis=-1), image[..., 3]
        assert np.isclose(rgb, alpha, atol=1e-6)[alpha > 0.5].any()


def test_a_step_may_put_up_to_the_bound_of_samples_across_the_box():
    from parc.scene import MAX_RAY_SAMPLES
    vol = Volume(np.arange(512.0).reshape(8, 8, 8), spacing=(1e-7, 1, 1))
    diagonal = float(np.linalg.norm(np.subtract(*vol.bounds)))
    step = diagonal / MAX_RAY_SAMPLES * (1 + 1e-12)
    assert parc.Translucent(vol, "greyscale", step=step).step == step
    with pytest.raises(InputError, match="samples on a ray across"):
        parc.Translucent(vol, "greyscale", step=step * (1 - 1e-9))


def test_a_string_is_not_taken_for_a_sequence_of_digits():
    # Iterated, "123" would be spacing (1, 2, 3).
    assert dataclasses.replace(VOL, spacing=(1, 2, 3)).spacing == (1.0, 2.0, 3.0)
    with pytest.raises(InputError, match="spacing must be three numbers"):
        dataclasses.replace(VOL, spacing="123")


def test_changing_the_array_a_volume_was_built_from_leaves_its_renders_as_they_were(gl):
    # PARC's cell ranges, proxy and skip tables are kept on the volume from its first frame: had
    # the volume kept the caller's array, the blob moved here would be drawn from stale caches.
    a = np.zeros((12, 12, 12), np.float32)
    a[4:8, 4:8, 4:8] = 1.0
    vol = parc.Volume(a)
    scene = parc.Scene(camera=parc.Camera.framing(*vol.bounds), size=(48, 48), volumes=[parc.Isosurface(vol, 0.5)])
    first = parc.render(scene, method="parc")
    parc.render(scene, method="parc")
    a[:] = 0.0
    a[1:4, 1:4, 1:4] = 1.0
    for method in ("brute", "parc"):
        again = parc.render(scene, method=method)
        np.testing.assert_array_equal(again.depth, first.depth)
        np.testing.assert_array_equal(again.image, first.image)
    assert np.isfinite(first.depth).sum() > 50 and vol.value_range() == (0.0, 1.0)


def test_copies_and_pickles_are_new_volumes_without_caches():
    import copy
    import pickle
    vol = blobs(12, seed=5)
    scene = parc.Scene(camera=parc.Camera.framing(*vol.bounds), size=(12, 12),
                       volumes=[parc.Isosurface(vol, float(vol.data.mean()))])
    ref = parc.render(scene, method="brute")
    try:
        parc.render(scene, method="parc")     # leaves caches on the volume
    except parc.OpenGLUnavailable:
        pass
    for other in (copy.copy(vol), copy.deepcopy(vol), pickle.loads(pickle.dumps(vol))):
        assert not other.data.flags.writeable
        assert not [k for k in other.meta if str(k).startswith("_")]
        np.testing.assert_array_equal(other.data, vol.data)
    again = pickle.loads(pickle.dumps(scene))
    assert isinstance(again.volumes, tuple) and isinstance(again.lights, tuple)
    np.testing.assert_array_equal(parc.render(again, method="brute").image, ref.image)


def test_a_scene_holds_its_volumes_and_lights_as_tuples():
    scene = _scene(lights=[parc.PointLight((1.0, 2.0, 3.0))])
    assert isinstance(scene.volumes, tuple) and isinstance(scene.lights, tuple)
    with pytest.raises(AttributeError):
        scene.volumes.append("junk")


def test_a_comparison_counts_the_images_it_keeps(monkeypatch):
    import parc.workspace as workspace
    from data_tools import memory
    scene = _scene()
    one = 8 * 8 * workspace.FRAME_BYTES_PER_PIXEL
    monkeypatch.setattr(memory, "available_memory", lambda: one + 8 * 8 * workspace.KEPT_IMAGE_BYTES_PER_PIXEL)
    parc.render(scene)                                     # one frame fits
    with pytest.raises(InputError, match="needs about"):
        parc.compare(scene, methods=("brute", "parc"))     # a frame and two kept images do not


def test_a_step_sweep_counts_the_images_it_holds_at_once(monkeypatch):
    # The reference and each method's image of the step being timed: a step's images go once its row is made.
    import parc.workspace as workspace
    from data_tools import memory
    one = 8 * 8 * workspace.FRAME_BYTES_PER_PIXEL
    kept = 8 * 8 * workspace.KEPT_IMAGE_BYTES_PER_PIXEL
    monkeypatch.setattr(memory, "available_memory", lambda: one + 3 * kept)
    assert len(step_sweep(_fog(), [1.0, 0.75, 0.5, 0.25], repeats=1, warmup=0)) == 4
    monkeypatch.setattr(memory, "available_memory", lambda: one + 2 * kept)
    with pytest.raises(InputError, match="needs about"):
        step_sweep(_fog(), [1.0], repeats=1, warmup=0)


def test_load_volume_of_something_not_a_path_says_what_to_do():
    with pytest.raises(InputError, match=re.escape("takes a file's path or a NumPy array, got float")):
        parc.load_volume(3.5, spacing=(1, 2, 3))


def test_load_volume_of_an_array_keeps_its_samples_spacing_and_origin():
    data = np.arange(4 * 5 * 6, dtype=np.int16).reshape(4, 5, 6)
    vol = parc.load_volume(data, spacing=(1, 2, 3), origin=(-1, 0, 5))
    assert vol.data.dtype == np.int16 and np.array_equal(vol.data, data)
    assert vol.spacing == (1.0, 2.0, 3.0) and vol.origin == (-1.0, 0.0, 5.0)
    plain = parc.load_volume(data, shape=None, mmap=False)       # options left unset are ignored
    assert plain.spacing == (1.0, 1.0, 1.0) and plain.origin == (0.0, 0.0, 0.0)
    with pytest.raises(InputError, match="an array in memory takes only spacing and origin"):
        parc.load_volume(data, dtype="uint8")
    with pytest.raises(InputError, match="3 dimensions"):
        parc.load_volume(data[0])


def test_reprs_are_short_whatever_the_volume():
    # The defaults printed the samples and the caches kept with a volume: 1.4 KB for a volume,
    # 5.5 KB for a render's result.
    big = Volume(np.zeros((64, 64, 64), np.int16), spacing=(0.5, 0.5, 1.0), name="ct")
    big.value_range()
    assert repr(big) == "Volume('ct', 64x64x64 int16, 0.5 MiB, spacing=(0.5, 0.5, 1.0), origin=(0.0, 0.0, 0.0))"
    res = parc.render(_scene())
    assert re.fullmatch(r"RenderResult\(8x8, method='brute', hits=\d+, seconds=[\d.e-]+\)", repr(res)), repr(res)
    assert len(repr(_scene())) < 600


def test_a_masked_array_is_refused_where_masked_and_none_is_no_volume():
    # The masked entries' fill values were drawn as data.
    data = np.ma.array(np.ones((3, 3, 3)), mask=np.zeros((3, 3, 3), bool))
    assert np.array_equal(Volume(data).data, np.ones((3, 3, 3)))
    data.mask[1, 1, 1] = True
    with pytest.raises(InputError, match="a masked array with 1 masked samples; fill them"):
        Volume(data)
    with pytest.raises(InputError, match=re.escape("no samples given (None)")):
        Volume(None)


def test_the_package_has_its_version():
    from importlib.metadata import version
    assert parc.__version__ == version("parc")


@pytest.mark.parametrize("given, shown", [(iter(["brute", 1]), "['brute', 1]"), ((m for m in ["parc", None]), "['parc', None]"),
                                          (iter(["", " "]), "['', ' ']"), ({"brute": 1, 3: 2}, "{'brute': 1, 3: 2}")])
def test_refused_methods_show_what_was_given_an_iterators_items(given, shown):
    from parc.comparison import method_names
    with pytest.raises(InputError) as exc:
        method_names(given)
    assert f"got {shown}" in str(exc.value) and "object at" not in str(exc.value), str(exc.value)


def test_the_public_names_are_listed_before_their_first_use():
    # `import parc` loads them on first use (PEP 562); dir() and tab completion list them all the same.
    import subprocess
    import sys
    # And, before any use loads its submodules, nothing else public: not the modules it imports.
    code = ("import parc; print(sorted(set(parc.__all__) - set(dir(parc))), "
            "sorted({n for n in dir(parc) if not n.startswith('_')} - set(parc.__all__)))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and p.stdout.strip() == "[] []", (p.stdout, p.stderr[-2000:])


@pytest.mark.parametrize("call, words", [
    (lambda: parc.render(_fog(), "parc", buffers="junk"), "PARC buffers must be"),
    (lambda: parc.render(_scene(lights=[parc.PointLight((1, 2, 3))]), "parc", light_buffer=1), "light buffers"),
    (lambda: parc.compare(_scene(), options={"parc": {"buffers": "junk"}}), "PARC buffers must be"),
    (lambda: step_sweep(_fog(), "word"), "sweep steps"),
])
def test_an_arguments_own_refusal_comes_before_opengl_is_asked_for(call, words, monkeypatch):
    # Without OpenGL (simulated), a bad argument is still named, not hidden behind OpenGL's absence.
    import parc.gl

    def no_context():
        raise parc.OpenGLUnavailable("OpenGL is not available (simulated)")
    monkeypatch.setattr(parc.gl, "get_context", no_context)
    with pytest.raises(InputError, match=words):
        call()
