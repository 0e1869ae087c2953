"""The flags' values as the command line reads them, and the scene they describe, against the
same scene built with the Python API."""
import numpy as np
import pytest

import parc
from data_tools import Volume
from data_tools.io import save_volume
from parc.arguments import build_parser, join_signed_values
from parc.cli import main
from parc.flagscene import scene_from_flags


@pytest.fixture
def vol_file(tmp_path):
    k, j, i = np.mgrid[0:12, 0:10, 0:8]
    data = (((i - 3.5) ** 2 + (j - 4.5) ** 2 + (k - 5.5) ** 2) ** 0.5).astype(np.float32)
    return save_volume(Volume(data, spacing=(1.0, 1.5, 0.5), origin=(2.0, -3.0, 1.0)), tmp_path / "ball.nrrd")


def _args(*argv):
    return build_parser().parse_args(join_signed_values([str(a) for a in argv]))


def _scene(*argv):
    notes = []
    return scene_from_flags(_args(*argv), notes.append), notes


def _run(argv, capsys):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def _refused(argv, words, capsys):
    rc, _, err = _run(argv, capsys)
    assert rc == 2 and err.count("\n") == 1 and err.startswith("parc: error: ") and words in err, err
    assert "Traceback" not in err


@pytest.mark.parametrize("flag", ["--eye", "--look-at", "--up", "--light", "--sun", "--spacing", "--origin"])
def test_a_vector_of_four_numbers_is_refused(flag, vol_file, tmp_path, capsys):
    _refused(["render", vol_file, "--iso", 3, "--size", 8, 8, flag, "0.5,0.5,0.5,0.5", "-o", tmp_path / "o.png"],
             f"argument {flag}: must be 3 comma-separated finite numbers, got '0.5,0.5,0.5,0.5'", capsys)
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("value", ["0", "1,2", "1,0,2", "1,2,3,4"])
def test_a_supercell_size_is_one_or_three_positive_numbers(value, vol_file, tmp_path, capsys):
    _refused(["render", vol_file, "--iso", 3, "--size", 8, 8, "--method", "parc", "--supercell", value,
              "-o", tmp_path / "o.png"], f"supercell size must be M or M,N,P positive numbers, got '{value}'", capsys)


def test_a_supercell_size_reads_as_one_number_or_three():
    assert _args("render", "-o", "o.png", "--supercell", "2.5").supercell == 2.5
    assert _args("render", "-o", "o.png", "--supercell", "1,2,4").supercell == (1.0, 2.0, 4.0)


def test_a_raw_shape_of_four_numbers_is_refused(tmp_path, capsys):
    raw = tmp_path / "scan.raw"
    raw.write_bytes(bytes(2 * 3 * 4))
    _refused(["info", raw, "--shape", "2,3,4,1", "--dtype", "uint8"],
             "argument --shape: must be 3 integers apart by commas, like 64,64,32, got '2,3,4,1'", capsys)


def test_an_offset_of_zero_reads_from_the_first_byte_and_a_word_is_refused(tmp_path, capsys):
    data = np.arange(4 * 3 * 2, dtype=np.uint8).reshape(4, 3, 2)     # [z, y, x]
    raw = tmp_path / "scan.raw"
    raw.write_bytes(data.tobytes())
    flags = ["--shape", "2,3,4", "--dtype", "uint8"]
    rc, _, err = _run(["convert", raw, *flags, "--offset", 0, "-o", tmp_path / "scan.npy"], capsys)
    assert rc == 0, err
    assert np.array_equal(np.load(tmp_path / "scan.npy"), data)
    _refused(["info", raw, *flags, "--offset", "ten"],
             "argument --offset: must be a byte count (a whole number >= 0), got 'ten'", capsys)


@pytest.mark.parametrize("flag, value, parsed", [
    ("--look-at", "-1e0,2,3", (-1.0, 2.0, 3.0)), ("--eye", "-2E1,-1,5", (-20.0, -1.0, 5.0)),
    ("--up", "-1,0,0", (-1.0, 0.0, 0.0)), ("--light", "-1e1,2,3", [(-10.0, 2.0, 3.0)]),
    ("--sun", "-.5,1,-1", [(-0.5, 1.0, -1.0)]), ("--origin", "-1e0,0,0", (-1.0, 0.0, 0.0)),
    ("--iso", "-2.5e-1", -0.25), ("--iso", "-inf", -np.inf), ("--step", "-1e-1", -0.1),
    ("--threshold", "-1e-1", -0.1), ("--fov", "-1e1", -10.0), ("--parallel", "-1e1", -10.0),
    ("--zoom", "-1e-3", -0.001), ("--eye", "-1,inf,0", None),
])
def test_a_value_starting_with_a_minus_sign_reaches_its_flag(flag, value, parsed, vol_file, tmp_path, capsys):
    # argparse takes "-1e0,2,3" for an option of its own: "expected one argument", though one was given.
    if parsed is None:
        _refused(["render", vol_file, "-o", tmp_path / "o.png", flag, value],
                 f"argument {flag}: must be 3 comma-separated finite numbers, got '{value}'", capsys)
        return
    assert getattr(_args("render", "-o", "o.png", flag, value), flag[2:].replace("-", "_")) == parsed
    swept = _args("compare", "--sweep-step", "-1e0,2", "--sweep-supercell", "-2,1")
    assert (swept.sweep_step, swept.sweep_supercell) == ("-1e0,2", "-2,1")


@pytest.mark.parametrize("flag", ["--eye", "--iso", "--zoom"])
def test_a_flag_left_without_its_value_at_the_end_is_named(flag, vol_file, tmp_path, capsys):
    _refused(["render", vol_file, "-o", tmp_path / "o.png", flag], f"argument {flag}: expected one argument", capsys)


def _same_camera(got, want):
    assert np.array_equal(got.eye, want.eye) and np.array_equal(got.look_at, want.look_at), (got, want)
    assert np.array_equal(got.up, want.up) and got.fov == want.fov and got.parallel_scale == want.parallel_scale


def _frame(vol, **kw):
    # The 24 x 16 image of the view tests.
    return parc.Camera.framing(*parc.load_volume(vol).bounds, **{"aspect": 1.5, **kw})


def test_the_default_view_frames_the_volume_across_the_image(vol_file):
    # Documented: a three-quarter view framing the whole volume, fov 30, up 0,0,1, size 512 512.
    scene, _ = _scene("render", vol_file, "--iso", 3, "-o", "o.png")
    assert scene.size == (512, 512) and scene.background is None and not scene.lights and not scene.shadows
    _same_camera(scene.camera, _frame(vol_file, aspect=1.0))
    assert scene.camera.fov == 30.0 and scene.camera.up == (0.0, 0.0, 1.0)
    wide, _ = _scene("render", vol_file, "--iso", 3, "--size", 40, 10, "-o", "o.png")
    tall, _ = _scene("render", vol_file, "--iso", 3, "--size", 10, 40, "-o", "o.png")
    _same_camera(wide.camera, _frame(vol_file, aspect=4.0))
    _same_camera(tall.camera, _frame(vol_file, aspect=0.25))
    # A tall image fits the volume across its width: the eye stands farther off than for a wide one.
    centre = np.asarray(scene.camera.look_at)
    assert np.linalg.norm(np.subtract(tall.camera.eye, centre)) > np.linalg.norm(np.subtract(wide.camera.eye, centre))


@pytest.mark.parametrize("extra, camera", [
    (["--zoom", 2.5], lambda v: _frame(v, zoom=2.5)),
    (["--fov", 50], lambda v: _frame(v, fov=50.0)),
    (["--parallel", 7], lambda v: parc.Camera(eye=_frame(v, parallel=True).eye, look_at=_frame(v).look_at,
                                              up=(0.0, 0.0, 1.0), parallel_scale=7.0)),
    (["--up", "0,1,0"], lambda v: _frame(v, up=(0.0, 1.0, 0.0))),
    (["--eye", "30,-20,10", "--up", "1,0,1"], lambda v: parc.Camera(eye=(30.0, -20.0, 10.0), look_at=_frame(v).look_at,
                                                                   up=(1.0, 0.0, 1.0))),
    (["--look-at", "4,2,3"], lambda v: parc.Camera(
        eye=tuple(np.add((4.0, 2.0, 3.0), np.subtract(_frame(v).eye, _frame(v).look_at))), look_at=(4.0, 2.0, 3.0),
        up=(0.0, 0.0, 1.0))),
])
def test_the_view_flags_give_the_camera_built_by_hand(extra, camera, vol_file):
    scene, _ = _scene("render", vol_file, "--iso", 3, "--size", 24, 16, "-o", "o.png", *extra)
    _same_camera(scene.camera, camera(vol_file))


def test_zoom_brings_the_default_eye_that_many_times_closer(vol_file):
    near, _ = _scene("render", vol_file, "--iso", 3, "--zoom", 4, "-o", "o.png")
    far, _ = _scene("render", vol_file, "--iso", 3, "-o", "o.png")
    centre = parc.load_volume(vol_file).center
    offset = np.subtract(far.camera.eye, centre)
    np.testing.assert_allclose(np.subtract(near.camera.eye, centre), offset / 4, rtol=1e-12)


def test_tf_flags_give_the_translucent_volume_built_by_hand(vol_file):
    vol = parc.load_volume(vol_file)
    scene, _ = _scene("render", vol_file, "--tf", "greyscale", "--size", 24, 16, "-o", "o.png")
    (got,) = scene.volumes
    # Documented defaults: composite, a quarter of the smallest spacing, opacity 0.99, unshaded.
    want = parc.Translucent(vol, "greyscale")
    assert (got.mode, got.step, got.threshold, got.shade) == ("composite", 0.125, 0.99, False)
    assert (got.mode, got.step, got.threshold, got.shade) == (want.mode, want.step, want.threshold, want.shade)
    assert got.tf == want.tf
    scene, _ = _scene("render", vol_file, "--tf", "greyscale", "--step", 0.3, "--threshold", 0.5, "--shade",
                      "--background", "0.25,0.5,1", "-o", "o.png")
    (got,) = scene.volumes
    assert (got.mode, got.step, got.threshold, got.shade) == ("composite", 0.3, 0.5, True)
    assert scene.background == (0.25, 0.5, 1.0, 1.0)
    for mode in ("mip", "average"):
        scene, _ = _scene("render", vol_file, "--tf", "greyscale", "--mode", mode, "-o", "o.png")
        assert scene.volumes[0].mode == mode


def test_without_iso_the_middle_level_suggested_is_shown_and_the_others_named(vol_file):
    from data_tools.info import exact_text, suggest_isovalues
    levels = suggest_isovalues(parc.load_volume(vol_file))
    assert len(levels) >= 3
    scene, notes = _scene("render", vol_file, "-o", "o.png")
    middle = levels[len(levels) // 2]
    assert scene.volumes[0].value == middle
    others = ", ".join(exact_text(v) for v in levels if v != middle)
    assert notes == [f"no --iso given; using {exact_text(middle)}, suggested from the histogram (others: {others})"]


def test_the_builtin_volume_is_shown_at_its_own_level_or_through_a_tf():
    scene, notes = _scene("render", "-o", "o.png", "--size", 8, 8)
    assert scene.volumes[0].value == 127.5 and not any("--iso" in n for n in notes)
    scene, _ = _scene("render", "-o", "o.png", "--size", 8, 8, "--tf", "greyscale")
    assert isinstance(scene.volumes[0], parc.Translucent)


def test_the_defaults_are_those_the_help_names():
    parser = build_parser()
    compare = parser._subparsers._group_actions[0].choices["compare"]
    help_of = {a.dest: a.help for a in compare._actions}
    args = _args("compare")
    assert "(default 3)" in help_of["repeats"] and args.repeats == 3
    assert "default brute,parc" in help_of["methods"] and args.methods == "brute,parc"
    assert _args("render", "-o", "o.png").method == "brute"


def test_the_default_up_turns_to_y_for_a_view_along_z(vol_file):
    centre = parc.load_volume(vol_file).center
    above = ",".join(map(str, np.add(centre, (0.0, 0.0, 40.0))))
    scene, _ = _scene("render", vol_file, "--iso", 3, "--eye", above, "-o", "o.png")
    assert scene.camera.up == (0.0, 1.0, 0.0) and np.array_equal(scene.camera.look_at, centre)
    scene, _ = _scene("render", vol_file, "--iso", 3, "--eye", "30,-20,10", "-o", "o.png")
    assert scene.camera.up == (0.0, 0.0, 1.0)


@pytest.mark.parametrize("extra, flag", [(["--shade"], "--shade"), (["--mode", "mip"], "--mode"),
                                         (["--step", "0.5"], "--step"), (["--threshold", "0.5"], "--threshold")])
def test_translucent_flags_on_an_isosurface_are_refused(extra, flag, vol_file, tmp_path, capsys):
    _refused(["render", vol_file, "--iso", 3, "--size", 8, 8, *extra, "-o", tmp_path / "o.png"],
             f"{flag} applies to translucent volumes (--tf)", capsys)
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("extra, words", [
    (["--repeats", "0"], "--repeats must be from 1 to 10000, got 0"),
    (["--repeats", "10001"], "--repeats must be from 1 to 10000, got 10001"),
    (["--repeats", "99999999999999999999"], "--repeats must be from 1 to 10000, got 99999999999999999999"),
    (["--sweep-step", "0,1"], "--sweep-step must be comma-separated positive numbers, got '0,1'"),
    (["--sweep-step", "-1,1"], "--sweep-step must be comma-separated positive numbers, got '-1,1'"),
    (["--sweep-step", "1,0.5", "--step", "0.25"], "--step does not combine with --sweep-step (it varies the step)"),
])
def test_compare_refuses_counts_and_steps_it_would_not_use(extra, words, vol_file, capsys):
    _refused(["compare", vol_file, "--tf", "greyscale", "--size", 8, 8, *extra], words, capsys)


@pytest.mark.parametrize("command, extra, words", [
    ("render", ["--no-blocks"], "--no-blocks applies to --method parc"),
    ("compare", ["--methods", "brute", "--no-blocks"], "--no-blocks applies to parc, which --methods leaves out"),
])
def test_parcs_own_flags_are_refused_where_parc_does_not_run(command, extra, words, vol_file, tmp_path, capsys):
    out = ["-o", tmp_path / "o.png"] if command == "render" else []
    _refused([command, vol_file, "--iso", 3, "--size", 8, 8, *extra, *out], words, capsys)
    assert not (tmp_path / "o.png").exists()


def test_parcs_flags_without_parc_are_refused_before_any_note_of_compiling(vol_file, capsys, monkeypatch):
    # As a machine whose kernels are not yet compiled: the note would come before the refusal.
    import parc.cli
    monkeypatch.setattr(parc.cli, "compile_notice", lambda say, kernels: say("compiling the ray casters"))
    rc, _, err = _run(["compare", vol_file, "--iso", 3, "--size", 8, 8, "--methods", "brute", "--no-blocks"], capsys)
    assert rc == 2 and err == "parc: error: --no-blocks applies to parc, which --methods leaves out\n", err


def test_a_light_too_far_to_shade_is_told_to_be_a_sun(vol_file, tmp_path, capsys):
    # PointLight's own refusal named a Python class, which the command line has no flag for.
    out = tmp_path / "o.png"
    _refused(["render", vol_file, "--iso", 3, "--light", "1e151,0,-2", "-o", out],
             "--light: light position (1e+151, 0.0, -2.0) is beyond 1e+150; a light that far is directional: "
             "give its direction (DirectionalLight, --sun DX,DY,DZ, or a scene file's direction) instead of a "
             "position", capsys)
    assert not out.exists()
    scene, _ = _scene("render", vol_file, "--iso", 3, "--light", "-1e149,0,-2", "-o", out)
    assert scene.lights[0].position == (-1e149, 0.0, -2.0)


@pytest.mark.parametrize("flag", ["--light", "--sun"])
@pytest.mark.parametrize("with_volume", [True, False])
def test_two_lights_after_one_flag_are_refused_with_the_flag_once_a_light(flag, with_volume, vol_file, tmp_path,
                                                                          capsys):
    # argparse reads the second light as an unknown argument, or as the volume where none came first.
    volume = [vol_file] if with_volume else []
    out = tmp_path / "o.png"
    for second in ("1,0,-1", "-1,0,-1"):
        taken = f"{second}: no such file" if not volume and second[0] != "-" else f"unrecognized arguments: {second}"
        _refused(["render", *volume, flag, "0,0,-1", second, "-o", out],
                 f"{taken}; give {flag} once for each light: {flag} x,y,z {flag} x,y,z", capsys)
        assert not out.exists()


def test_an_unknown_argument_without_lights_gets_no_advice_on_them(vol_file, tmp_path, capsys):
    _refused(["render", vol_file, "1,2,3", "-o", tmp_path / "o.png"], "unrecognized arguments: 1,2,3", capsys)
    rc, _, err = _run(["render", "--light", "1,2,3", "nosuch.nrrd", "-o", tmp_path / "o.png"], capsys)
    assert rc == 2 and "no such file" in err and "once for each light" not in err


def test_a_file_given_in_the_wrong_role_is_named_for_the_role_it_has(vol_file, tmp_path, capsys):
    # A transfer function as the volume, or a scene file as the transfer function, was refused
    # for its keys ("opacity: unknown key") or its extension, which said nothing of the mix-up.
    tf_toml, tf_json, scene = tmp_path / "tf.toml", tmp_path / "tf.json", tmp_path / "scene.toml"
    tf_toml.write_text("opacity = [[0, 0], [10, 1]]\n")
    tf_json.write_text('{"opacity": [[0, 0], [10, 1]]}')
    scene.write_text(f'[[volume]]\nfile = "{vol_file}"\niso = 3\n')
    out = tmp_path / "o.png"
    _refused(["render", tf_toml, "-o", out], f"{tf_toml}: a transfer function, not a scene (it has no [[volume]] "
             "tables): give it with --tf", capsys)
    for tf in (tf_json, tf_toml):
        for command in (["render", tf, "-o", out], ["info", tf], ["convert", tf, "-o", tmp_path / "v.nrrd"]):
            if command[0] == "render" and tf == tf_toml:
                continue                        # a scene file's place: said above
            _refused(command, f"{tf}: a transfer function, not a volume: parc render and parc compare take it "
                     "with --tf", capsys)
    # A volume's sidecar, or JSON of neither kind, is not called a transfer function.
    np.save(tmp_path / "v.npy", np.zeros((2, 2, 2), np.float32))
    (tmp_path / "v.npy.json").write_text('{"spacing": [1, 1, 1], "origin": [0, 0, 0]}')
    _refused(["info", tmp_path / "v.npy.json"], f"{tmp_path / 'v.npy.json'}: the spacing and origin of "
             f"{tmp_path / 'v.npy'} (its sidecar): give {tmp_path / 'v.npy'}", capsys)
    (tmp_path / "other.json").write_text('{"a": 1}')
    _refused(["info", tmp_path / "other.json"], "unknown volume file type '.json'", capsys)
    _refused(["render", vol_file, "--tf", scene, "-o", out], f"{scene}: a scene file (it has [[volume]] tables), "
             "not a transfer function: give it as the volume", capsys)
    assert not out.exists()
    # Given as they should be, they are taken.
    rc, _, err = _run(["render", vol_file, "--tf", tf_toml, "--size", 8, 8, "-o", out, "--quiet"], capsys)
    assert rc == 0 and out.exists(), err


def test_a_background_takes_an_alpha_as_a_scene_file_s_does(vol_file, tmp_path, capsys):
    scene, _ = _scene("render", vol_file, "--iso", 3, "--background", "0.25,0.5,1,0.5", "-o", "o.png")
    assert scene.background == (0.25, 0.5, 1.0, 0.5)
    _refused(["render", vol_file, "--iso", 3, "--background", "0,0,0,0.5,1", "-o", tmp_path / "o.png"],
             "argument --background: must be 3 or 4 comma-separated finite numbers, got '0,0,0,0.5,1'", capsys)
    _refused(["render", vol_file, "--iso", 3, "--background", "0,0,0,2", "-o", tmp_path / "o.png"],
             "argument --background: components must be in [0, 1], got '0,0,0,2'", capsys)
