"""Scene files: a valid file gives the Scene it describes; every mistake names the file and the key."""
import math
import re
import textwrap

import numpy as np
import pytest

import parc
from data_tools import InputError, Volume
from data_tools.io import save_volume
from data_tools.synthetic import make_synthetic
from parc.scenefile import load_scene, resolve_view


@pytest.fixture
def folder(tmp_path):
    """A scene folder with two small volumes under data/ and a transfer function file."""
    (tmp_path / "data").mkdir()
    save_volume(make_synthetic("sphere", 16), tmp_path / "data" / "ball.nrrd")     # float32, about [-5.3, 7.7]
    save_volume(make_synthetic("blobs", 16), tmp_path / "data" / "blobs.nrrd")     # uint8
    (tmp_path / "data" / "v_2x2x2.raw").write_bytes(bytes(8))                      # a raw file of any type
    (tmp_path / "data" / "warm.toml").write_text('opacity = [[0, 0.0], [255, 0.5]]\n'
                                                 'color = [[0, 1, 0.5, 0], [255, 1, 1, 1]]\n')
    return tmp_path


def write(folder, text, name="scene.toml"):
    path = folder / name
    path.write_text(textwrap.dedent(text))
    return path


TWO_VOLUMES = """\
    size = [40, 30]
    background = [0.1, 0.2, 0.3]
    shadows = true

    [camera]
    eye = [60, -50, 40]
    look_at = [12, 8, 8]
    up = [0, 0, 1]
    fov = 25

    [[volume]]
    file = "data/ball.nrrd"
    iso = 0.5
    color = [0.9, 0.8, 0.7]
    material = [0.1, 0.7, 0.3, 20]

    [[volume]]
    file = "data/blobs.nrrd"
    tf = "data/warm.toml"
    mode = "composite"
    step = 0.5
    threshold = 0.95
    shade = true
    spacing = [1, 1, 2]
    origin = [20, 0, 0]

    [[light]]
    position = [0, -40, 30]
    color = [1, 0.9, 0.8]
    intensity = 0.7

    [[light]]
    direction = [0, 0, -2]
"""


def test_two_volumes_lights_and_camera(folder, tmp_path_factory, monkeypatch):
    path = write(folder, TWO_VOLUMES)
    monkeypatch.chdir(tmp_path_factory.mktemp("elsewhere"))   # paths are relative to the file, not the cwd
    scene = load_scene(path)

    assert scene.size == (40, 30) and scene.background == (0.1, 0.2, 0.3, 1.0) and scene.shadows
    assert scene.camera == parc.Camera(eye=(60, -50, 40), look_at=(12, 8, 8), up=(0, 0, 1), fov=25)

    iso, tl = scene.volumes
    assert isinstance(iso, parc.Isosurface) and isinstance(tl, parc.Translucent)
    assert iso.value == 0.5 and iso.color == (0.9, 0.8, 0.7) and iso.material == (0.1, 0.7, 0.3, 20.0)
    assert iso.volume.dims == (16, 16, 16) and iso.volume.dtype == np.float32
    assert iso.volume.origin == (0.0, 0.0, 0.0) and iso.volume.spacing == (1.0, 1.0, 1.0)
    assert tl.volume.dtype == np.uint8
    assert tl.volume.spacing == (1.0, 1.0, 2.0) and tl.volume.origin == (20.0, 0.0, 0.0)
    assert (tl.mode, tl.step, tl.threshold, tl.shade) == ("composite", 0.5, 0.95, True)
    assert tl.tf.opacity(np.array([255.0]))[0] == pytest.approx(0.5)

    point, sun = scene.lights
    assert isinstance(point, parc.PointLight) and point.position == (0.0, -40.0, 30.0)
    assert point.color == (1.0, 0.9, 0.8) and point.intensity == 0.7
    assert isinstance(sun, parc.DirectionalLight) and sun.direction == (0.0, 0.0, -1.0) and sun.intensity == 1.0


def test_names_in_a_scene_reached_through_a_link_are_relative_to_the_link(folder, tmp_path_factory):
    # As a shell or a build tool names files: from the scene file as given, whose folder the
    # user sees, not from wherever the link points.
    elsewhere = tmp_path_factory.mktemp("elsewhere")
    target = write(elsewhere, """\
        [[volume]]
        file = "data/ball.nrrd"
        iso = 0
    """)
    link = folder / "linked.toml"
    link.symlink_to(target)
    assert load_scene(link).volumes[0].volume.dims == (16, 16, 16)
    with pytest.raises(InputError, match="data/ball.nrrd"):
        load_scene(target)          # beside the target there is no data/ball.nrrd


def test_public_api_and_defaults(folder):
    path = write(folder, """\
        [[volume]]
        file = "data/ball.nrrd"
        iso = 0
    """)
    scene = parc.load_scene(str(path))
    assert scene.size == (512, 512) and scene.background is None and not scene.shadows
    assert scene.lights == ()                       # the renderer's headlight
    vol = scene.volumes[0].volume
    assert scene.camera == parc.Camera.framing(*vol.bounds)   # the command line's default view


def test_a_background_may_give_its_opacity(folder):
    path = write(folder, "background = [0.1, 0.2, 0.3, 0.5]\n" + textwrap.dedent(VOLUME))
    assert load_scene(path).background == (0.1, 0.2, 0.3, 0.5)


def test_lights_and_shadows_of_a_translucent_scene_are_taken_with_a_warning(folder):
    # The Scene's own warning, said where load_scene was called (the CLI turns it into a note).
    path = write(folder, "shadows = true\n[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\n"
                         "[[light]]\nposition = [0, 0, 0]\n")
    with pytest.warns(parc.ShowsNothingWarning) as caught:
        scene = load_scene(path)
    assert scene.shadows and len(scene.lights) == 1
    assert sorted(str(w.message).split(" on isosurfaces")[0] for w in caught) == ["lights shine", "shadows fall"]
    assert all(w.filename == __file__ for w in caught)


def test_a_point_light_too_far_to_shade_is_told_to_be_directional(folder):
    # PointLight's own refusal named a Python class, which a scene file has no way to write.
    path = write(folder, "[[volume]]\nfile = 'data/ball.nrrd'\niso = 1\n[[light]]\nposition = [0, -1e151, 0]\n")
    with pytest.raises(InputError, match=r"light\[1\]\.position: light position \(0\.0, -1e\+151, 0\.0\) is beyond "
                                         r"1e\+150; a light that far is directional: give its direction "
                                         r"\(DirectionalLight, --sun DX,DY,DZ, or a scene file's direction\) "
                                         "instead of a position$"):
        load_scene(path)
    write(folder, "[[volume]]\nfile = 'data/ball.nrrd'\niso = 1\n[[light]]\nposition = [0, -1e149, 0]\n")
    assert load_scene(path).lights[0].position == (0.0, -1e149, 0.0)


@pytest.mark.parametrize("y, centre", [(30, 22.5), (-30, -7.5)])
def test_default_camera_frames_all_volumes(folder, y, centre):
    path = write(folder, f"""\
        [camera]
        eye = [100, 7.5, 7.5]
        [[volume]]
        file = "data/ball.nrrd"
        iso = 0
        [[volume]]
        file = "data/ball.nrrd"
        iso = 1
        origin = [0, {y}, 0]
    """)
    scene = load_scene(path)
    # look_at defaults to the centre of the union of the boxes: x, z 0..15, y from 0 or y to 15 or y + 15.
    assert scene.camera.look_at == (7.5, centre, 7.5) and scene.camera.eye == (100.0, 7.5, 7.5)
    assert scene.camera.up == (0.0, 0.0, 1.0) and scene.camera.fov == 30.0
    # The same file with the same placement is one Volume; a new placement shares its samples.
    a, b = (v.volume for v in scene.volumes)
    assert a is not b and a.data is b.data and b.origin == (0.0, float(y), 0.0)


def test_same_data_and_placement_share_one_volume(folder):
    path = write(folder, """\
        [[volume]]
        file = "data/ball.nrrd"
        iso = 0
        [[volume]]
        file = "data/ball.nrrd"
        tf = "greyscale"
    """)
    a, b = load_scene(path).volumes
    assert a.volume is b.volume


def test_tables_of_one_source_read_differently_get_volumes_of_their_own(folder):
    # Two seeds of one synthetic volume, and one raw file read as two types and shapes: a
    # cache keyed on the source alone gave the second table the first's samples.
    (folder / "data" / "pair.raw").write_bytes(np.arange(48, dtype=np.uint8).tobytes())
    path = write(folder, """\
        [[volume]]
        synthetic = "blobs"
        size = 8
        seed = 1
        iso = 100.5
        [[volume]]
        synthetic = "blobs"
        size = 8
        seed = 2
        iso = 100.5
        [[volume]]
        file = "data/pair.raw"
        shape = [4, 3, 4]
        dtype = "uint8"
        iso = 20
        [[volume]]
        file = "data/pair.raw"
        shape = [3, 2, 4]
        dtype = "uint16"
        iso = 3000
    """)
    one, two, u8, u16 = (v.volume for v in load_scene(path).volumes)
    assert np.array_equal(one.data, make_synthetic("blobs", 8, seed=1).data)
    assert np.array_equal(two.data, make_synthetic("blobs", 8, seed=2).data)
    assert not np.array_equal(one.data, two.data)
    raw = (folder / "data" / "pair.raw").read_bytes()
    assert np.array_equal(u8.data, np.frombuffer(raw, np.uint8).reshape(4, 3, 4))
    assert np.array_equal(u16.data, np.frombuffer(raw, "<u2").reshape(4, 2, 3))


def test_synthetic_parallel_and_look_at_only(folder):
    path = write(folder, """\
        [camera]
        look_at = [0, 0, 0]
        parallel = 12
        [[volume]]
        synthetic = "blobs"
        size = [12, 10, 8]
        seed = 3
        tf = "viridis"
        mode = "mip"
    """)
    scene = load_scene(path)
    vol = scene.volumes[0].volume
    assert vol.dims == (12, 10, 8)
    np.testing.assert_array_equal(vol.data, make_synthetic("blobs", (12, 10, 8), seed=3).data)
    cam = scene.camera
    assert cam.parallel and cam.parallel_scale == 12.0 and cam.look_at == (0.0, 0.0, 0.0)
    expected = resolve_view(*vol.bounds, look_at=(0, 0, 0), parallel=12.0)
    assert cam.eye == pytest.approx(expected["eye"])


def test_a_files_preset_follows_a_replaced_mode_as_the_same_preset_named_in_python(folder):
    import dataclasses
    path = write(folder, """\
        [[volume]]
        file = "data/ball.nrrd"
        tf = "greyscale"
    """)
    vis = load_scene(path).volumes[0]
    mip = dataclasses.replace(vis, mode="mip")
    # The ramp ends opaque for mip (`parc.transfer.presets.ramp_opacity`), at the data's maximum.
    assert mip.tf.opacity_points[-1].tolist() == [vis.volume.value_range()[1], 1.0]


def test_view_and_size_given_by_the_caller_win(folder):
    path = write(folder, TWO_VOLUMES)
    scene = load_scene(path, view={"eye": (0, -80, 8), "parallel": 20, "up": None}, size=(8, 6))
    assert scene.size == (8, 6)
    # eye replaced; look_at and up kept from the file; parallel replaces the file's fov.
    assert scene.camera == parc.Camera(eye=(0, -80, 8), look_at=(12, 8, 8), up=(0, 0, 1), parallel_scale=20)


@pytest.mark.parametrize("size", [(), 0, [], (np.ma.masked, 10)])     # a masked value: NumPy's MaskError
def test_an_empty_or_zero_size_given_by_the_caller_is_refused(folder, size):
    # None alone keeps the file's size: an empty or zero one is a mistake, not the default.
    with pytest.raises(InputError, match=re.escape(f"size (given to load_scene): image size must be two positive "
                                                   f"integers, got {size!r}")):
        load_scene(write(folder, TWO_VOLUMES), size=size)


def test_raw_file_options(folder):
    data = np.arange(4 * 3 * 2, dtype=np.uint16).reshape(2, 3, 4)
    (folder / "data" / "small.raw").write_bytes(b"\0" * 8 + data.astype(">u2").tobytes())
    path = write(folder, """\
        [[volume]]
        file = "data/small.raw"
        shape = [4, 3, 2]
        dtype = "uint16"
        byte_order = "big"
        offset = 8
        iso = 10
    """)
    np.testing.assert_array_equal(load_scene(path).volumes[0].volume.data, data)


def test_a_raw_files_offset_may_be_zero(folder):
    # Zero bytes before the samples is a headerless file's usual layout, written out or not.
    data = np.arange(24, dtype="<u2").reshape(2, 3, 4)
    (folder / "data" / "plain.raw").write_bytes(data.tobytes())
    path = write(folder, "[[volume]]\nfile = 'data/plain.raw'\nshape = [4, 3, 2]\ndtype = 'uint16'\n"
                         "byte_order = 'little'\noffset = 0\niso = 10\n")
    np.testing.assert_array_equal(load_scene(path).volumes[0].volume.data, data)


@pytest.mark.parametrize("keys, missing, words", [
    ("", "shape", ["shape = [NX, NY, NZ] and dtype"]),
    ("shape = [4, 3, 2]", "dtype", ['give dtype (e.g. "uint8")']),
])
def test_a_raw_file_without_its_keys_names_them(folder, keys, missing, words):
    # In the table's own keys: the command line's --shape and --dtype mean nothing in a scene file.
    (folder / "data" / "plain.raw").write_bytes(bytes(24))
    path = write(folder, f"[[volume]]\nfile = 'data/plain.raw'\n{keys}\niso = 0\n")
    with pytest.raises(InputError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: volume[1].{missing}: ") and "--" not in msg, msg
    assert all(w in msg for w in words), msg


VOLUME = """\
    [[volume]]
    file = "data/ball.nrrd"
    iso = 0
"""

#: (scene file text, the key named, words of the message). {V} is a valid [[volume]] table.
BAD = [
    ("size = [32, 32\n{V}", None, "malformed TOML", "(at line 2, column 1)"),
    ("size = " + "[" * 100000 + "]" * 100000 + "\n{V}", None, "malformed TOML", "nested too deeply"),
    ("size = [1" + "0" * 5000 + ", 32]\n{V}", None, "malformed TOML", "a number too long to read"),
    # Read (tomllib bounds no integer), but beyond float64: float() raises OverflowError.
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = 1" + "0" * 400, "volume[1].iso", "must be a finite number"),
    ("[camera]\neye = [1" + "0" * 400 + ", 0, 0]\n{V}", "camera.eye", "must be an array of 3 finite numbers"),
    ("volumes = 1\n{V}", "volumes", "unknown key; did you mean volume?"),
    ("[camera]\nfvo = 20\n{V}", "camera.fvo", "unknown key; did you mean fov? (known: eye, look_at, up, fov, parallel, zoom)"),
    ("camera = 3\n{V}", "camera", "must be a table"),
    ("size = [32, 32]", "volume", "missing: add at least one [[volume]]"),
    ("volume = []", "volume", "empty"),
    ("[volume]\nfile = 'data/ball.nrrd'\niso = 0", "volume", "array of tables, written [[volume]]"),
    ("{V}[[volume]]\nfile = 'data/ball.nrrd'\nisovalue = 1", "volume[2].isovalue", "unknown key; did you mean iso?"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = 0\ntf = 'greyscale'", "volume[1]", "not both"),
    ("[[volume]]\nfile = 'data/ball.nrrd'", "volume[1]", "give iso (an isosurface) or tf"),
    ("{V}[[volume]]\nfile = 'data/ball.nrrd'\niso = 5000", "volume[2].iso",
     "isovalue 5000 is outside the data range"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = '80'", "volume[1].iso", "must be a finite number, got a string"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = nan", "volume[1].iso", "must be a finite number"),
    ("[[volume]]\nfile = 'data/missing.nrrd'\niso = 0", "volume[1].file", "data/missing.nrrd", "no such file"),
    ("[[volume]]\nfile = 'data/warm.toml'\niso = 0", "volume[1].file", "unknown volume file"),
    ("[[volume]]\niso = 0", "volume[1]", "give file (a volume file) or synthetic"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\nsynthetic = 'sphere'\niso = 0", "volume[1]", "not both"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = 0\ncolor = [1, 2, 0]", "volume[1].color", "[0, 1]"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = 0\ncolor = [1, 0]", "volume[1].color", "an array of 3 finite numbers"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = 0\nmaterial = [0.1, -1, 0, 1]", "volume[1].material", ">= 0"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = 0\nmode = 'mip'", "volume[1].mode",
     "applies to a translucent volume"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\ncolor = [1, 1, 1]", "volume[1].color",
     "applies to an isosurface"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\nmode = 'max'", "volume[1].mode", "unknown mode 'max'"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\nstep = -1", "volume[1].step", "positive"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\nthreshold = 2", "volume[1].threshold", "(0, 1]"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\nshade = 1", "volume[1].shade", "true or false"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\nmode = 'mip'\nshade = true", "volume[1].shade",
     "applies to mode composite"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\nmode = 'average'\nthreshold = 0.5",
     "volume[1].threshold", "applies to mode composite"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\nmaterial = [0.5, 0.1, 0.9, 5]", "volume[1].material",
     "applies to an isosurface, or to a translucent volume with shade = true"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\nmode = 'mip'\nmaterial = [0.5, 0.1, 0.9, 5]",
     "volume[1].material", "with shade = true"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'skin'", "volume[1].tf", "unknown transfer function preset 'skin'"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'data/cold.toml'", "volume[1].tf", "data/cold.toml"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = 0\nspacing = [1, 0, 1]", "volume[1].spacing", "spacing"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = 0\norigin = [0, 0]", "volume[1].origin", "an array of 3 finite numbers"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = 0\nshape = [16, 16, 16]", "volume[1].shape",
     "only to headerless raw files"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = 0\nsize = 8", "volume[1].size", "applies to synthetic volumes"),
    ("[[volume]]\nsynthetic = 'cube'\niso = 0", "volume[1].synthetic", "unknown synthetic volume 'cube'"),
    ("[[volume]]\nsynthetic = 'sphere'\nseed = 2\niso = 0", "volume[1].seed", "takes no seed"),
    ("[[volume]]\nsynthetic = 'sphere'\nsize = 1\niso = 0", "volume[1].size", "at least 2"),
    ("[[volume]]\nsynthetic = 'sphere'\nsize = 100000\niso = 0", "volume[1].size", "GB of memory"),
    ("[[volume]]\nsynthetic = 'sphere'\ndtype = 'uint8'\niso = 0", "volume[1].dtype", "not to synthetic"),
    ("{V}[[light]]\nposition = [0, 0, 9]\ndirection = [0, 0, -1]", "light[1]", "not both"),
    ("{V}[[light]]\ncolor = [1, 1, 1]", "light[1]", "give position (a point light) or direction"),
    ("{V}[[light]]\nposition = [0, 0, 9]\n[[light]]\ndirection = [0, 0, 0]", "light[2].direction", "not be zero"),
    ("{V}[[light]]\nposition = [0, 0, 9]\nintensity = -1", "light[1].intensity", ">= 0"),
    ("{V}[[light]]\nposition = [0, 0, 9]\ncolor = [1, 1, 1.5]", "light[1].color", "[0, 1]"),
    ("{V}[[light]]\nposition = [0, 'a', 9]", "light[1].position", "an array of 3 finite numbers"),
    ("{V}[[light]]\nposition = [0, 0, 9]\nradius = 2", "light[1].radius", "unknown key"),
    ("{V}[light]\nposition = [0, 0, 9]", "light", "array of tables, written [[light]]"),
    ("size = [0, 32]\n{V}", "size", "at least 1"),
    ("size = [32.5, 32]\n{V}", "size", "an array of 2 integers"),
    ("size = 32\n{V}", "size", "an array of 2 integers, got a number 32"),
    ("background = [0, 0, 2]\n{V}", "background", "[0, 1]"),
    ("shadows = 'yes'\n{V}", "shadows", "true or false, got a string"),
    ("[camera]\nfov = 200\n{V}", "camera.fov", "between 0 and 180"),
    ("[camera]\nparallel = 0\n{V}", "camera.parallel", "positive"),
    ("[camera]\nfov = 20\nparallel = 10\n{V}", "camera.parallel", "not both"),
    ("[camera]\neye = [1, 1, 1]\nlook_at = [1, 1, 1]\n{V}", "camera.eye", "same point"),
    ("[camera]\neye = [7.5, 7.5, 7.5]\n{V}", "camera.eye", "centre of the volumes"),   # the default look_at
    ("[camera]\neye = [0, 0, 50]\nlook_at = [0, 0, 0]\nup = [0, 0, 2]\n{V}", "camera.up", "parallel to the view"),
    ("[camera]\neye = [inf, 0, 0]\n{V}", "camera.eye", "finite"),
    ("[camera]\nup = [0, 0, 0]\n{V}", "camera.up", "is zero"),                  # with the default framing
    ("[camera]\nfov = 1e-300\n{V}", "camera.fov", "too narrow to frame"),
    ("[camera]\neye = [1e20, 0, 0]\nparallel = 5\n{V}", "camera.eye", "is over 2^32 times the volumes' size"),
    ("[camera]\nfov = 1e-300\nzoom = 2\n{V}", "camera.fov", "too narrow to frame"),     # not the zoom
    ("[camera]\neye = [40, 0, 0]\nzoom = 2\n{V}", "camera.zoom", "with an eye given, move the eye"),
    ("[[volume]]\nfile = 'data/v_2x2x2.raw'\ndtype = 'float128'\niso = 0", "volume[1].dtype",
     "unsupported sample type 'float128'"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ndtype = 'float128'\niso = 0", "volume[1].dtype",
     "only to headerless raw files"),
    ("[camera]\neye = [0, 0, 50]\nlook_at = [0, 0, 0]\nup = [0, 0, 0]\n{V}", "camera.up", "is zero"),
    # One check each: a row fails where its check is dropped or loosened.
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = true", "volume[1].iso", "must be a finite number, got a boolean true"),
    ("size = [true, 16]\n{V}", "size", "an array of 2 integers"),
    ("[[volume]]\nsynthetic = 'sphere'\nsize = 'big'\niso = 0", "volume[1].size",
     "an integer or an array of 3 integers", "got a string 'big'"),
    ("[[volume]]\nsynthetic = 'sphere'\nsize = [1, 8, 8]\niso = 0", "volume[1].size", "at least 2"),
    ("[[volume]]\nsynthetic = 'blobs'\nseed = -1\niso = 100", "volume[1].seed", "an integer >= 0, got a number -1"),
    ("[[volume]]\nsynthetic = 'blobs'\nseed = true\niso = 100", "volume[1].seed", "got a boolean true"),
    ("[[volume]]\nfile = 'data/v_2x2x2.raw'\ndtype = 'uint8'\noffset = -1\niso = 0", "volume[1].offset",
     "an integer >= 0 (bytes before the samples)"),
    ("[[volume]]\nfile = 'data/v_2x2x2.raw'\ndtype = 'uint8'\noffset = true\niso = 0", "volume[1].offset",
     "got a boolean true"),
    ("[[volume]]\nfile = 'data/v_2x2x2.raw'\ndtype = 'uint8'\nbyte_order = 'middle'\niso = 0",
     "volume[1].byte_order", 'must be "little" or "big"'),
    ("[[volume]]\nfile = 'data/v_2x2x2.raw'\ndtype = 'uint8'\nshape = [1, 2, 4]\niso = 0", "volume[1].shape",
     "at least 2"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\nmode = ''", "volume[1].mode", "a non-empty string"),
    ("background = [-0.1, 0, 0]\n{V}", "background", "[0, 1]"),
    ("background = [0, 1.01, 0]\n{V}", "background", "[0, 1]"),
    ("[camera]\nzoom = 0\n{V}", "camera.zoom", "positive"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\niso = 0\niso_value_of_the_surface = 1",
     "volume[1].iso_value_of_the_surface", "unknown key; did you mean iso?"),    # ~user is a home folder; one of no known user is refused, not a traceback from pathlib.
    ("[[volume]]\nfile = 3\niso = 0", "volume[1].file", "must be a non-empty string, got a number 3"),
    ("[[volume]]\nfile = '~no-such-user-here/ball.nrrd'\niso = 0", "volume[1].file",
     "no home folder is known for ~no-such-user-here"),
    ("[[volume]]\nfile = 'data/ball.nrrd'\ntf = '~no-such-user-here/cold.toml'", "volume[1].tf",
     "no home folder is known for ~no-such-user-here"),
]


@pytest.mark.parametrize("text, key, words", [(b[0], b[1], b[2:]) for b in BAD], ids=[f"{i}-{b[1]}" for i, b in enumerate(BAD)])
def test_errors_name_the_file_and_the_key(text, key, words, folder):
    path = write(folder, text.replace("{V}", textwrap.dedent(VOLUME)))
    with pytest.raises(InputError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg
    prefix = f"{path}: {key}: " if key else f"{path}: "
    assert msg.startswith(prefix) and msg.count(f"{path}: ") == 1, msg
    for w in words:
        assert w in msg, msg


def test_missing_file_shows_the_resolved_path(folder, tmp_path_factory, monkeypatch):
    path = write(folder, "[[volume]]\nfile = 'data/missing.nrrd'\niso = 0\n", name="s.toml")
    monkeypatch.chdir(tmp_path_factory.mktemp("elsewhere"))
    with pytest.raises(InputError, match="volume\\[1\\].file: .*") as info:
        load_scene(path)
    assert str(folder / "data" / "missing.nrrd") in str(info.value)


def test_a_missing_transfer_function_path_without_a_suffix_shows_the_resolved_path(folder, tmp_path_factory,
                                                                                 monkeypatch):
    # A name with a folder in it is a file, relative to the scene, not an unknown preset.
    path = write(folder, "[[volume]]\nfile = 'data/blobs.nrrd'\ntf = 'data/cold'\n", name="s.toml")
    monkeypatch.chdir(tmp_path_factory.mktemp("elsewhere"))
    with pytest.raises(InputError, match=r"volume\[1\]\.tf: transfer function file not found: ") as info:
        load_scene(path)
    assert str(folder / "data" / "cold") in str(info.value)


def test_unreadable_scene_files(tmp_path):
    with pytest.raises(InputError, match="no such scene file"):
        load_scene(tmp_path / "nope.toml")
    with pytest.raises(InputError, match="is a folder"):
        load_scene(tmp_path)
    (tmp_path / "latin1.toml").write_bytes(b"# caf\xe9\n")
    with pytest.raises(InputError, match="not a UTF-8"):
        load_scene(tmp_path / "latin1.toml")


def test_a_byte_order_mark_before_a_scene_file_is_read_past(tmp_path):
    # Editors on Windows write one; the transfer-function reader skips it and so must this one.
    (tmp_path / "bom.toml").write_bytes(b'\xef\xbb\xbf[[volume]]\nsynthetic = "sphere"\nsize = 8\niso = 0\n')
    (vis,) = load_scene(tmp_path / "bom.toml").volumes
    assert vis.value == 0.0 and vis.volume.dims == (8, 8, 8)


def test_a_relative_scene_files_transfer_function_is_made_again_from_the_same_file(folder, monkeypatch):
    # made_from keeps the file's absolute name: replaced after a chdir, the Translucent reads
    # the file the scene named, not one relative to the new working folder.
    import dataclasses
    monkeypatch.chdir(folder)
    text = "[[volume]]\nfile = 'data/blobs.nrrd'\ntf = 'data/warm.toml'\n"
    (vis,) = load_scene(write(folder, text, "rel.toml").relative_to(folder)).volumes
    assert vis.tf.made_from[0] == str(folder / "data" / "warm.toml")
    monkeypatch.chdir(folder / "data")
    assert dataclasses.replace(vis, mode="mip").tf.opacity_points.tolist() == [[0.0, 0.0], [255.0, 0.5]]


def test_the_files_values_are_checked_where_the_command_line_replaces_them(folder):
    vol = textwrap.dedent(VOLUME)
    for text, key, view, size in [(f"size = 'big'\n{vol}", "size", None, (16, 16)),
                                  (f"[camera]\nfov = 0\n{vol}", "camera.fov", {"fov": 30.0}, None),
                                  (f"[camera]\nfov = 0\n{vol}", "camera.fov", {"parallel": 3.0}, None),
                                  (f"[camera]\nzoom = -1\n{vol}", "camera.zoom", {"eye": (40.0, 0, 0)}, None),
                                  (f"[camera]\nup = [0, 0, 0]\n{vol}", "camera.up", {"up": (0, 1.0, 0)}, None)]:
        path = write(folder, text)
        with pytest.raises(InputError) as info:
            load_scene(path, view=view, size=size)
        assert str(info.value).startswith(f"{path}: {key}: "), str(info.value)


@pytest.mark.parametrize("view, words", [({"fov": "x"}, "view: fov must be a number, got 'x'"),
                                         ({"zoom": True}, "view: zoom must be a number"),
                                         ({"eye": (1, 2)}, "view: eye must be three finite numbers"),
                                         ({"look_at": (0, math.inf, 0)}, "view: look_at must be three finite numbers"),
                                         ({"fvo": 20}, "view takes camera settings keyed eye, look_at")])
def test_a_view_of_the_wrong_type_is_named(folder, view, words):
    with pytest.raises(InputError, match=re.escape(words)):
        load_scene(write(folder, TWO_VOLUMES), view=view)


def test_errors_from_a_view_or_size_given_in_place_of_the_files_say_so(folder):
    path = write(folder, TWO_VOLUMES)
    with pytest.raises(InputError, match=r"camera.fov \(given to load_scene\): .*180"):
        load_scene(path, view={"fov": 190.0})
    with pytest.raises(InputError, match=r"size \(given to load_scene\)"):
        load_scene(path, size=(0, 10))
    # An infinite width overflows int(), and a lone number cannot be iterated.
    for size in ((math.inf, 10), 10, (True, True), ("8", "8")):
        with pytest.raises(InputError, match=r"size \(given to load_scene\): image size must be two positive"):
            load_scene(path, size=size)
    eyed = write(folder, "[camera]\neye = [40, 1, 2]\n" + textwrap.dedent(VOLUME), name="eyed.toml")
    with pytest.raises(InputError, match=r"camera.look_at \(given to load_scene\): eye and look_at are the same"):
        load_scene(eyed, view={"look_at": (40.0, 1.0, 2.0)})
    assert load_scene(path, size=iter((12, 10))).size == (12, 10)
    # An endless iterator (itertools.count), or range(10**10), is refused after its third item, not drawn out.
    def endless():
        yield from (8, 9, 10)
        raise AssertionError("drawn past its third item")
    with pytest.raises(InputError, match=r"size \(given to load_scene\): image size must be two positive"):
        load_scene(path, size=endless())
    # parc render names its own flags' origin.
    with pytest.raises(InputError, match=r"camera.fov \(given on the command line\): .*180"):
        load_scene(path, view={"fov": 190.0}, replaced_by="given on the command line")
    with pytest.raises(InputError, match="replaced_by takes text, got int"):
        load_scene(path, replaced_by=5)


def test_resolve_view_matches_framing():
    lo, hi = (0, 0, 0), (10, 20, 30)
    view = resolve_view(lo, hi)
    framed = parc.Camera.framing(lo, hi)
    assert parc.Camera(**view) == framed
    # Looking straight down with the default up: +y instead of the parallel +z.
    down = resolve_view(lo, hi, eye=(5, 10, 100))
    assert down["up"] == (0.0, 1.0, 0.0) and down["look_at"] == (5.0, 10.0, 15.0)
    assert math.isclose(parc.Camera(**down).basis()[0][2], -1.0)


@pytest.mark.parametrize("parallel", [None, 10.0])
def test_naming_the_default_look_at_changes_nothing(parallel):
    # A parallel view's eye moved back to the perspective distance when look_at was given: the
    # same picture, every depth 25 units longer.
    lo, hi = (0, 0, 0), (31, 31, 31)
    plain = resolve_view(lo, hi, parallel=parallel)
    named = resolve_view(lo, hi, look_at=(15.5, 15.5, 15.5), parallel=parallel)
    assert np.allclose(named["eye"], plain["eye"], rtol=0, atol=1e-12) and named["look_at"] == plain["look_at"]


def test_a_bare_tf_name_not_beside_the_scene_is_an_unknown_preset_wherever_it_runs(folder, monkeypatch):
    # A file of that name in the working folder, never loaded from there, gave its own error instead:
    # "transfer function mytf: unknown file type '(none)'".
    (folder / "sub").mkdir()
    path = write(folder / "sub", "[[volume]]\nfile = '../data/ball.nrrd'\ntf = 'mytf'\n")
    (folder / "mytf").write_text("opacity = [[0, 0.0], [1, 0.5]]\n")
    for where in (folder, folder / "sub"):
        monkeypatch.chdir(where)
        with pytest.raises(InputError, match="volume\\[1\\].tf.*unknown transfer function preset 'mytf'"):
            load_scene(path)


def test_volume_placement_keeps_native_samples(folder):
    path = write(folder, "[[volume]]\nfile = 'data/blobs.nrrd'\niso = 100\nspacing = [0.5, 0.5, 1]\n")
    vol = load_scene(path).volumes[0].volume
    assert isinstance(vol, Volume) and vol.dtype == np.uint8 and vol.spacing == (0.5, 0.5, 1.0)


def test_one_source_placed_twice_keeps_each_placement(folder):
    # Tables naming the same data share its samples, not their spacing and origin.
    scene = load_scene(write(folder, """\
        [[volume]]
        synthetic = "sphere"
        size = 8
        iso = 0
        spacing = [1, 1, 1]
        [[volume]]
        synthetic = "sphere"
        size = 8
        iso = 0
        spacing = [2, 2, 2]
        origin = [20, 0, 0]
    """))
    a, b = (v.volume for v in scene.volumes)
    assert (a.spacing, a.origin) == ((1.0, 1.0, 1.0), (0.0, 0.0, 0.0))
    assert (b.spacing, b.origin) == ((2.0, 2.0, 2.0), (20.0, 0.0, 0.0))


def test_a_tables_placement_replaces_a_file_placement_the_volume_refuses(folder):
    # A header whose origin lies 1e12 units out on a unit grid cannot be drawn as it says; the
    # table that moves it opens it, and a table that keeps the file's placement is still refused.
    save_volume(Volume(np.arange(27, dtype=np.uint8).reshape(3, 3, 3)), folder / "far.nhdr")
    header = folder / "far.nhdr"
    header.write_text(header.read_text().replace("space origin: (0,0,0)", "space origin: (1e12,0,0)"))
    table = "[[volume]]\nfile = 'far.nhdr'\niso = 10\n"
    vols = load_scene(write(folder, table + "origin = [0, 0, 5]\n" + table + "origin = [0, 9, 0]\n"
                            + table + "origin = [0, 0, 5]\n")).volumes
    assert [v.volume.origin for v in vols] == [(0.0, 0.0, 5.0), (0.0, 9.0, 0.0), (0.0, 0.0, 5.0)]
    assert np.array_equal(vols[1].volume.data, np.arange(27).reshape(3, 3, 3))
    assert vols[2].volume is vols[0].volume             # the same data and placement: one Volume
    with pytest.raises(InputError, match=r"volume\[2\]\.file: .*far\.nhdr: origin"):
        load_scene(write(folder, table + "origin = [0, 0, 5]\n" + table))
    # A value the table gives that is refused too is the table's, named by its key.
    for placement, key in (("spacing = [0, 1, 1]", "spacing"), ("origin = [1e13, 0, 0]", "origin"),
                           ("spacing = [1, 1, 1]\norigin = [1e13, 0, 0]", "origin"),
                           ("spacing = [0, 1, 1]\norigin = [0, 0, 0]", "spacing")):
        with pytest.raises(InputError, match=rf"volume\[1\]\.{key}: .*far\.nhdr: {key}"):
            load_scene(write(folder, table + placement + "\n"))


def test_a_look_at_alone_moves_the_framing_eye_with_it():
    # resolve_view: given look_at and no eye, the eye keeps the framing view's offset from the point looked at.
    lo, hi = (0.0, 0.0, 0.0), (10.0, 10.0, 10.0)
    framed = parc.Camera.framing(lo, hi)
    view = resolve_view(lo, hi, look_at=(100.0, 0.0, 0.0))
    np.testing.assert_allclose(np.subtract(view["eye"], view["look_at"]), np.subtract(framed.eye, framed.look_at))


@pytest.mark.parametrize("size", [(100, 400), (400, 100), (64, 64)])
def test_the_default_framing_fits_the_volume_in_the_image_as_shaped(folder, size):
    # Geometry, not the framing code: every corner of the box projects inside the image, whose
    # width over height is the file's size, and the box fills most of its tighter side.
    scene = load_scene(write(folder, f"size = [{size[0]}, {size[1]}]\n" + textwrap.dedent(VOLUME)))
    cam = scene.camera
    f, r, u = cam.basis()
    lo, hi = scene.volumes[0].volume.bounds
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    q = corners - np.asarray(cam.eye)
    th = math.tan(math.radians(cam.fov) / 2)
    across, up = np.abs(q @ r) / (q @ f) / (th * size[0] / size[1]), np.abs(q @ u) / (q @ f) / th
    assert max(across.max(), up.max()) <= 1.0 and max(across.max(), up.max()) >= 0.5, (across.max(), up.max())


def test_a_fov_given_makes_a_parallel_file_view_perspective(folder):
    path = write(folder, "[camera]\nparallel = 12\n" + textwrap.dedent(VOLUME))
    cam = load_scene(path, view={"fov": 40.0}).camera
    assert not cam.parallel and cam.fov == 40.0


# A translucent volume's `material` is a documented key (VOLUME_KEYS, the Translucent's shading
# constants with shade = true), but no test writes it: dropping it after parsing passed every test.
# Truth: the numbers written in the file; and a shaded render with the key must differ from one
# without it (the default material), or the key never reached the caster.
TRANSLUCENT_SHADED = """\
    size = [24, 20]

    [[volume]]
    file = "data/blobs.nrrd"
    tf = "data/warm.toml"
    shade = true
"""


def test_a_translucent_volumes_material_reaches_the_scene_and_the_render(folder):
    material = (0.3, 0.2, 0.6, 7.0)
    with_key = load_scene(write(folder, TRANSLUCENT_SHADED + "    material = [0.3, 0.2, 0.6, 7]\n", "m.toml"))
    without = load_scene(write(folder, TRANSLUCENT_SHADED, "d.toml"))
    (tl,) = with_key.volumes
    assert isinstance(tl, parc.Translucent) and tl.shade
    assert tl.material == material
    assert without.volumes[0].material != material
    a = parc.render(with_key, method="brute").image
    b = parc.render(without, method="brute").image
    assert a[..., 3].max() > 0.05                       # the volume shows
    assert np.abs(a - b).max() > 1e-3                   # and its material changes how it looks


def test_names_the_system_refuses_are_input_errors_naming_the_file(folder):
    # Path.exists() raises for a name too long: an OSError, where load_scene's errors are
    # InputErrors, and a scene's tf names its file and key.
    long = "a" * 300
    with pytest.raises(InputError, match="File name too long"):
        load_scene(folder / f"{long}.toml")
    for tf in (f"{long}.toml", long):
        path = write(folder, f"[[volume]]\nfile = 'data/ball.nrrd'\ntf = '{tf}'\n")
        with pytest.raises(InputError, match=re.escape(f"{path}: volume[1].tf: ") + ".*File name too long"):
            load_scene(path)
    loop = folder / "loop.toml"
    loop.symlink_to(loop)
    with pytest.raises(InputError, match="a link that leads nowhere"):
        load_scene(loop)
