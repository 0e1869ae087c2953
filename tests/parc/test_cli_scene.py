"""The command line with scene files, lights and shadows: what it builds, and one line for each mistake."""
import json
import textwrap

import numpy as np
import pytest

import parc
from data_tools.io import save_volume
from data_tools.synthetic import make_synthetic
from parc.cli import build_parser, main
from parc.flagscene import scene_from_flags


@pytest.fixture
def scene_file(tmp_path):
    """A single-volume scene file (sphere isosurface) with its volume beside it, under data/."""
    (tmp_path / "data").mkdir()
    save_volume(make_synthetic("sphere", 16), tmp_path / "data" / "ball.nrrd")
    path = tmp_path / "scene.toml"
    path.write_text(textwrap.dedent("""\
        size = [24, 20]
        background = [0, 0, 0]
        [camera]
        eye = [40, -30, 25]
        [[volume]]
        file = "data/ball.nrrd"
        iso = 0.5
        [[light]]
        position = [30, -30, 30]
    """))
    return path


def _run(argv, capsys):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def _scene_of(argv):
    notes = []
    return scene_from_flags(build_parser().parse_args([str(a) for a in argv]), notes.append), notes


def _assert_refused(rc, err, out_file, *words):
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("parc: error: "), err
    for w in words:
        assert w in lines[0], lines[0]
    assert not out_file.exists()
    assert not list(out_file.parent.glob(".parc-*"))     # no temporary left behind


def test_render_scene_file_from_another_folder(scene_file, tmp_path_factory, monkeypatch, capsys):
    out = tmp_path_factory.mktemp("out") / "scene.npy"
    monkeypatch.chdir(tmp_path_factory.mktemp("elsewhere"))     # the volume is found beside the scene file
    rc, _, err = _run(["render", scene_file, "-o", out, "--quiet"], capsys)
    assert rc == 0, err
    ref = parc.render(parc.load_scene(scene_file))
    np.testing.assert_array_equal(np.load(out), ref.image)
    assert ref.image.shape == (20, 24, 4)


def test_view_flags_override_the_file(scene_file, tmp_path, capsys):
    out = tmp_path / "o.npy"
    rc, _, err = _run(["render", scene_file, "--size", 16, 12, "--eye", "0,-40,8", "--fov", 40,
                       "-o", out, "--quiet"], capsys)
    assert rc == 0, err
    scene = parc.load_scene(scene_file, view={"eye": (0, -40, 8), "fov": 40.0}, size=(16, 12))
    assert scene.camera.eye == (0.0, -40.0, 8.0) and scene.camera.fov == 40.0
    np.testing.assert_array_equal(np.load(out), parc.render(scene).image)


def test_flags_add_lights_and_shadows(scene_file):
    scene, notes = _scene_of(["render", scene_file, "-o", "x.png", "--light", "1,2,3", "--sun", "0,0,-5",
                              "--light", "4,5,6", "--shadows", "--background", "1,1,1"])
    kinds = [type(light).__name__ for light in scene.lights]
    # The file's lights first, then --light in order, then --sun.
    assert kinds == ["PointLight", "PointLight", "PointLight", "DirectionalLight"]
    assert [light.position for light in scene.lights[1:3]] == [(1.0, 2.0, 3.0), (4.0, 5.0, 6.0)]
    assert scene.lights[3].direction == (0.0, 0.0, -1.0)
    assert scene.shadows and scene.background == (1.0, 1.0, 1.0, 1.0) and not notes


def test_lights_on_a_volume_file(scene_file):
    vol = scene_file.parent / "data" / "ball.nrrd"
    scene, _ = _scene_of(["render", vol, "--iso", 0.5, "-o", "x.png", "--sun", "1,1,-1"])
    assert len(scene.lights) == 1 and isinstance(scene.lights[0], parc.DirectionalLight)
    assert not scene.shadows
    scene, _ = _scene_of(["compare", vol, "--iso", 0.5])
    assert scene.lights == () and not scene.shadows           # the headlight


def test_shadows_with_only_the_headlight_get_a_note(scene_file):
    vol = scene_file.parent / "data" / "ball.nrrd"
    scene, notes = _scene_of(["render", vol, "--iso", 0.5, "-o", "x.png", "--shadows"])
    assert scene.shadows and scene.lights == ()
    assert any("headlight" in n for n in notes)


@pytest.mark.parametrize("flags", [["--background", "0,0,0"], ["--light", "0,0,50"], ["--shadows"]])
def test_lights_of_a_translucent_scene_file_are_noted_once(scene_file, flags):
    """The scene file's light shines on no isosurface and no shaded volume: one note says so,
    however many flags rebuild the scene after it is read."""
    path = scene_file.parent / "glow.toml"
    path.write_text("[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\n[[light]]\nposition = [0, 0, 0]\n")
    _, notes = _scene_of(["render", path, "-o", "x.png", *flags])
    assert sum(n.startswith("lights shine on isosurfaces") for n in notes) == 1, notes


def test_a_scene_file_s_light_lights_its_shaded_translucent_volume(scene_file, capsys):
    """With ``shade = true`` the file's [[light]] lights the samples: no note, and another image
    than the same file's without the light."""
    images = []
    for light in ("[[light]]\nposition = [40, 0, 0]\n", ""):
        path = scene_file.parent / "glow.toml"
        path.write_text(f"size = [24, 20]\n[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\nshade = true\n"
                        f"{light}")
        out = scene_file.parent / "glow.npy"
        assert main(["render", str(path), "-o", str(out)]) == 0
        assert "shine" not in capsys.readouterr().err
        images.append(np.load(out))
    assert images[0][..., 3].max() > 0.1
    assert np.abs(images[0] - images[1]).max() > 0.05


def test_multi_volume_scene_file_loads(tmp_path):
    save_volume(make_synthetic("sphere", 16), tmp_path / "a.nrrd")
    path = tmp_path / "two.toml"
    path.write_text("[[volume]]\nfile = 'a.nrrd'\niso = 0\n"
                    "[[volume]]\nfile = 'a.nrrd'\ntf = 'greyscale'\norigin = [20, 0, 0]\n"
                    "[[light]]\ndirection = [0, 1, -1]\n")
    scene, _ = _scene_of(["compare", path, "--parallel", 30, "--light", "0,0,50"])
    assert len(scene.volumes) == 2 and len(scene.lights) == 2
    assert scene.camera.parallel_scale == 30.0 and scene.size == (512, 512)


def _many_volumes(tmp_path, count, kind):
    save_volume(make_synthetic("sphere", 8), tmp_path / "a.nrrd")
    path = tmp_path / "many.toml"
    path.write_text("size = [6, 4]\n" + "".join(f"[[volume]]\nfile = 'a.nrrd'\n{kind}\norigin = [{10 * k}, 0, 0]\n"
                                               for k in range(count)))
    return path


def test_a_scene_of_many_volumes_is_named_in_a_line_of_its_first_few(tmp_path, capsys):
    from parc.cli import DESCRIBED_VOLUMES
    out = tmp_path / "o.png"
    rc, _, err = _run(["render", _many_volumes(tmp_path, 40, "iso = 0"), "-o", out], capsys)
    assert rc == 0, err
    line, = [x for x in err.splitlines() if x.startswith(f"parc: wrote {out}")]
    assert "40 volumes (" in line and f"; and {40 - DESCRIBED_VOLUMES + 1} more)" in line
    assert line.count("isovalue 0") == DESCRIBED_VOLUMES - 1 and line.count(str(tmp_path)) == DESCRIBED_VOLUMES


def test_a_scene_file_merging_too_many_composite_volumes_is_one_line(tmp_path, capsys):
    from raycast.merged import MAX_MERGED
    out = tmp_path / "o.png"
    rc, _, err = _run(["render", _many_volumes(tmp_path, MAX_MERGED + 1, "tf = 'greyscale'"), "-o", out], capsys)
    _assert_refused(rc, err, out, f"at most {MAX_MERGED} translucent volumes together",
                    f"this one has {MAX_MERGED + 1} in composite mode")


@pytest.mark.parametrize("extra, words", [
    (["--iso", "3"], ["--iso does not apply to a scene file", "[[volume]]"]),
    (["--iso", "0"], ["--iso does not apply to a scene file"]),        # 0 is a value, not "not given"
    (["--step", "0"], ["--step does not apply to a scene file"]),
    (["--threshold", "0"], ["--threshold does not apply to a scene file"]),
    (["--tf", "greyscale"], ["--tf does not apply to a scene file"]),
    (["--mode", "mip"], ["--mode does not apply"]),
    (["--spacing", "1,1,2"], ["--spacing does not apply"]),
    (["--byte-order", "big"], ["--byte-order does not apply"]),
    (["--offset", "8"], ["--offset does not apply to a scene file"]),
    (["--sun", "0,0,0"], ["--sun: light direction must not be zero"]),
    (["--light", "1,2"], ["argument --light: must be 3 comma-separated finite numbers"]),
    (["--fov", "200"], ["camera.fov (given on the command line)", "180"]),
    (["--size", "0", "10"], ["size (given on the command line)"]),
])
def test_bad_flags_with_a_scene_file(extra, words, scene_file, tmp_path, capsys):
    out = tmp_path / "o.png"
    rc, _, err = _run(["render", scene_file, "-o", out] + extra, capsys)
    _assert_refused(rc, err, out, *words)


def test_bad_scene_file_is_one_line(scene_file, tmp_path, capsys):
    scene_file.write_text(scene_file.read_text().replace("iso = 0.5", "iso = 5000"))
    out = tmp_path / "o.png"
    rc, _, err = _run(["render", scene_file, "-o", out], capsys)
    _assert_refused(rc, err, out, f"{scene_file}: volume[1].iso: isovalue 5000 is outside the data range")
    rc, _, err = _run(["render", tmp_path / "missing.toml", "-o", out], capsys)
    _assert_refused(rc, err, out, "missing.toml: no such scene file")


@pytest.mark.parametrize("text, words", [
    ('file = "no\\nsuch.nrrd"', r"volume[1].file: {dir}/no\nsuch.nrrd: no such file"),
    ('file = "x\\u001b[2Jred.nrrd"', r"volume[1].file: {dir}/x\x1b[2Jred.nrrd: no such file"),
    ('file = "' + "y" * 300 + '.nrrd"', "volume[1].file: {dir}/" + "y" * 300 + ".nrrd: "),
    ('"a\\rparc: all good" = 1', r'volume[1]."a\rparc: all good": unknown key'),
    ('"" = 1', 'volume[1]."": unknown key (known'),
])
def test_a_name_or_key_from_the_file_stays_on_the_error_line(scene_file, tmp_path, capsys, text, words):
    # Newlines, carriage returns and terminal escapes shown escaped; a path the system
    # refuses (a name too long) and an empty key named with the file and the key.
    scene_file.write_text(scene_file.read_text().replace('file = "data/ball.nrrd"',
                                                         text if text.startswith("file") else
                                                         'file = "data/ball.nrrd"\n' + text))
    out = tmp_path / "o.png"
    rc, _, err = _run(["render", scene_file, "-o", out], capsys)
    _assert_refused(rc, err, out, f"{scene_file}: {words.replace('{dir}', str(tmp_path))}")
    assert "did you mean" not in err


def test_compare_scene_file(scene_file, capsys):
    rc, out, err = _run(["compare", scene_file, "--size", 12, 12, "--repeats", 1, "--json"], capsys)
    assert rc == 0, err
    rows = json.loads(out)
    assert [r["method"] for r in rows] == ["brute", "parc"] and rows[0]["pixels"] == 144
    assert rows[1]["hit_mismatches"] == 0


def test_a_supercell_sweep_over_a_scene_reports_each_size(scene_file, capsys):
    # Rows of a scene with several volumes gave "supercell": null, the size only in the label.
    scene_file.write_text(scene_file.read_text() + "[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\n"
                          "origin = [20, 0, 0]\n")
    rc, out, err = _run(["compare", scene_file, "--size", 12, 12, "--repeats", 1, "--json",
                         "--sweep-supercell", "2,3"], capsys)
    assert rc == 0, err
    rows = json.loads(out)
    assert [r["method"] for r in rows] == ["brute", "parc:2", "parc:3"]
    assert [r["supercell"] for r in rows] == [None, [2.0] * 3, [3.0] * 3]
    assert [r["supercells"] for r in rows] == [[], [[2.0] * 3] * 2, [[3.0] * 3] * 2]
    assert all(r["hit_mismatches"] == 0 and r["max_color"] <= 1e-6 for r in rows)


def test_help_explains_scene_files_and_lights(capsys):
    for command in ("render", "compare"):
        with pytest.raises(SystemExit) as info:
            main([command, "--help"])
        assert info.value.code == 0
        text = capsys.readouterr().out
        for words in ("SCENE.toml", "lights and shadows", "--light X,Y,Z", "--sun DX,DY,DZ", "--shadows",
                      "headlight", "parc render scene.toml"):
            assert words in text, (command, words)


def test_no_output_is_written_over_a_file_the_render_reads(tmp_path, capsys):
    # A scene's volumes, a .npy's sidecar, a transfer-function file: each is read, none may be written.
    save_volume(make_synthetic("sphere", 8), tmp_path / "ball.npy", sidecar=True)
    (tmp_path / "tf.json").write_text('{"opacity": [[-1, 0], [1, 0.5]]}')
    (tmp_path / "scene.toml").write_text("size = [8, 8]\n[[volume]]\nfile = 'ball.npy'\ntf = 'tf.json'\n")
    before = {f.name: f.read_bytes() for f in tmp_path.iterdir()}
    for argv in (["render", tmp_path / "scene.toml", "-o", tmp_path / "ball.npy"],
                 ["render", tmp_path / "scene.toml", "-o", tmp_path / "a.png", "--stats", tmp_path / "tf.json"],
                 ["render", tmp_path / "ball.npy", "--iso", 0, "--size", 8, 8, "-o", tmp_path / "a.png",
                  "--stats", tmp_path / "ball.npy.json"],
                 ["render", tmp_path / "ball.npy", "--tf", tmp_path / "tf.json", "--size", 8, 8,
                  "-o", tmp_path / "a.png", "--stats", tmp_path / "tf.json"]):
        rc, _, err = _run(argv, capsys)
        _assert_refused(rc, err, tmp_path / "a.png", "is read by this run")
        assert {f.name: f.read_bytes() for f in tmp_path.iterdir()} == before


def test_the_threshold_flag_defaults_to_the_documented_0_99():
    scene, _ = _scene_of(["render", "--tf", "greyscale", "--size", 8, 8, "-o", "x.png"])
    assert scene.volumes[0].threshold == 0.99


def test_a_light_flag_keeps_the_scene_files_shadows(scene_file):
    text = scene_file.read_text()
    scene_file.write_text("shadows = true\n" + text)
    scene, _ = _scene_of(["render", scene_file, "--light", "5,3,9", "-o", "x.png"])
    assert scene.shadows and len(scene.lights) == 2


@pytest.mark.parametrize("zoom", [0.5, 2.0])
def test_zoom_brings_the_default_eye_closer(tmp_path, zoom):
    # The default framing fits the volume's bounding sphere, loosely: --zoom (and a scene file's
    # zoom) moves the eye that many times closer along the same line, looking at the same point.
    vol = tmp_path / "ball.nrrd"
    save_volume(make_synthetic("sphere", 16), vol)
    base, _ = _scene_of(["render", vol, "--iso", 0.5, "-o", tmp_path / "a.png"])
    near, _ = _scene_of(["render", vol, "--iso", 0.5, "-o", tmp_path / "a.png", "--zoom", zoom])
    c = np.array(base.camera.look_at)
    assert near.camera.look_at == base.camera.look_at
    np.testing.assert_allclose(np.subtract(near.camera.eye, c), np.subtract(base.camera.eye, c) / zoom, rtol=1e-12)
    scene = tmp_path / "s.toml"
    scene.write_text(f'[camera]\nzoom = {zoom}\n[[volume]]\nfile = "ball.nrrd"\niso = 0.5\n')
    np.testing.assert_allclose(parc.load_scene(scene, size=(512, 512)).camera.eye, near.camera.eye, rtol=1e-12)


@pytest.mark.parametrize("extra, words", [
    (["--zoom", 2, "--eye", "1,2,3"], ["zoom moves the default eye closer; with an eye given, move the eye"]),
    (["--zoom", 2, "--parallel", 10], ["zoom applies to a perspective view"]),
    (["--zoom", 0], ["--zoom must be positive and finite, got 0"]),
    (["--zoom", "inf"], ["--zoom must be positive and finite"]),
])
def test_bad_zoom_is_one_line(tmp_path, capsys, extra, words):
    vol = tmp_path / "ball.nrrd"
    save_volume(make_synthetic("sphere", 8), vol)
    rc, _, err = _run(["render", vol, "--iso", 0.5, "-o", tmp_path / "a.png", *extra], capsys)
    _assert_refused(rc, err, tmp_path / "a.png", *words)


def test_stats_give_the_camera_a_default_view_was_made_with(tmp_path, capsys):
    # The default eye was never said: now the stats hold the view, to give again or move from.
    vol = tmp_path / "ball.nrrd"
    save_volume(make_synthetic("sphere", 8), vol)
    rc, _, err = _run(["render", vol, "--iso", 0.5, "--size", 12, 10, "-o", tmp_path / "a.npy",
                       "--stats", tmp_path / "s.json", "--quiet"], capsys)
    assert rc == 0, err
    camera = json.loads((tmp_path / "s.json").read_text())["parameters"]["camera"]
    again = parc.Scene(camera=parc.Camera(**camera), size=(12, 10),
                       volumes=[parc.Isosurface(parc.load_volume(vol), 0.5)])
    np.testing.assert_array_equal(parc.render(again).image, np.load(tmp_path / "a.npy"))


def test_an_eye_or_a_parallel_view_on_the_command_line_drops_the_file_s_zoom(tmp_path, capsys):
    # As --parallel drops the file's fov: the file's zoom, which applies to neither, was refused.
    save_volume(make_synthetic("sphere", 8), tmp_path / "ball.nrrd")
    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\nzoom = 2\n[[volume]]\nfile = "ball.nrrd"\niso = 0.5\n')
    for extra in (["--eye", "40,-30,20"], ["--parallel", 5]):
        rc, _, err = _run(["render", scene, "--size", 8, 8, "-o", tmp_path / "a.png", "--quiet", *extra], capsys)
        assert rc == 0, err
    rc, _, err = _run(["render", scene, "--zoom", "1e300", "-o", tmp_path / "b.png"], capsys)
    _assert_refused(rc, err, tmp_path / "b.png", "a zoom of 1e+300 brings the eye onto the point it looks at")


def test_shadows_without_a_light_say_how_to_add_one_where_it_can_go(scene_file):
    # A scene file takes a [[light]] table too; a volume on the command line takes flags only.
    text = scene_file.read_text()
    scene_file.write_text("shadows = true\n" + text[:text.index("[[light]]")])
    _, notes = _scene_of(["render", scene_file, "-o", "x.png"])
    # Said once, in the command line's words (the Scene's own, "give the scene lights", was said too).
    headlight = [n for n in notes if "only the headlight" in n]
    assert len(headlight) == 1 and headlight[0].endswith("add --light or --sun, or a [[light]] table to the scene file")
    ball = scene_file.parent / "data" / "ball.nrrd"
    _, notes = _scene_of(["render", ball, "--iso", 0.5, "--shadows", "-o", "x.png"])
    headlight = [n for n in notes if "only the headlight" in n]
    assert len(headlight) == 1 and headlight[0].endswith("add --light or --sun"), notes


def test_a_scene_files_volumes_get_the_notes_of_the_flags_naming_their_tables(scene_file):
    """An isosurface at its data's largest value and a MIP through a table at most 0.2 opaque
    over the sphere's values: each note names the volume's table. The level between and the
    greyscale MIP, which ends opaque, get none."""
    from data_tools import load_volume
    hi = load_volume(scene_file.parent / "data" / "ball.nrrd").value_range()[1]
    (scene_file.parent / "faint.toml").write_text("opacity = [[-5, 0], [0, 0.2], [8, 0]]\n")
    path = scene_file.parent / "four.toml"
    path.write_text("[[volume]]\nfile = 'data/ball.nrrd'\niso = 0.5\n"
                    f"[[volume]]\nfile = 'data/ball.nrrd'\niso = {hi!r}\n"
                    "[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'greyscale'\nmode = 'mip'\n"
                    "[[volume]]\nfile = 'data/ball.nrrd'\ntf = 'faint.toml'\nmode = 'mip'\n")
    _, notes = _scene_of(["render", path, "-o", "x.png"])
    said = [n for n in notes if "shows the shapes" in n or "a MIP shows" in n]
    assert len(said) == 2, notes
    assert said[0].startswith(f"isovalue {hi!r} is volume[2]'s largest value: cells whose samples all equal it")
    assert "faint.toml is at most 0.2 opaque over volume[4]'s values: a MIP shows" in said[1]
