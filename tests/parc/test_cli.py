"""The command line: good runs write what they say; bad input gets one line, status 2, no file."""
import importlib
import json
import os
import re
import signal
import subprocess
import stat
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from data_tools import Volume
from data_tools.io import load_volume, save_volume
from parc.cli import build_parser, main
from parc.scene import ShowsNothingWarning

#: What `parc.outputs.Progress` writes for a render (a terminal gets it as one line rewritten).
PROGRESS_LINE = re.compile(r"\r?parc: (rendering \d+x\d+: +(\d+%(, about [\d hmins]+ left)?|done in [\d.]+ s) *"
                           r"|(reading .*|making the built-in volume)( \.\.\.|: done in [\d.]+ s))\r?\n?$")


@pytest.fixture
def vol_file(tmp_path):
    k, j, i = np.mgrid[0:12, 0:12, 0:12]
    data = (((i - 5.5) ** 2 + (j - 5.5) ** 2 + (k - 5.5) ** 2) ** 0.5).astype(np.float32)
    return save_volume(Volume(data), tmp_path / "ball.nrrd")


def _run(argv, capsys):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    # A render slower than Progress's delay (the first, compiling, on a loaded machine) reports
    # progress too; the tests judge the rest.
    err = "".join(line for line in err.splitlines(keepends=True) if not PROGRESS_LINE.match(line))
    return rc, out, err


def test_render_writes_png_depth_and_stats(vol_file, tmp_path, capsys):
    out, dep, st = tmp_path / "a.png", tmp_path / "d.npy", tmp_path / "s.json"
    rc, _, err = _run(["render", vol_file, "--iso", 4.0, "--size", 40, 30, "-o", out,
                       "--depth", dep, "--stats", st], capsys)
    assert rc == 0, err
    from PIL import Image
    img = Image.open(out)
    assert img.size == (40, 30) and img.mode == "RGBA"
    depth = np.load(dep)
    assert depth.shape == (30, 40) and depth.dtype == np.float64
    assert np.isfinite(depth).any() and np.isinf(depth).any()
    stats = json.loads(st.read_text())
    assert stats["method"] == "brute" and stats["hits"] == int(np.isfinite(depth).sum())
    # The file holds the render's whole stats: every count as the library gives it, times aside.
    import parc
    vol = parc.load_volume(vol_file)
    lib = parc.render(parc.Scene(camera=parc.Camera.framing(*vol.bounds), size=(40, 30),
                                 volumes=[parc.Isosurface(vol, 4.0)])).stats
    assert set(stats) == set(lib)
    for key, value in lib.items():
        if key != "seconds":
            assert stats[key] == json.loads(json.dumps(value, default=str)), key


def test_progress_shows_only_for_work_that_takes_a_while(monkeypatch, capsys):
    import parc.outputs
    now = [100.0]
    monkeypatch.setattr(parc.outputs.time, "perf_counter", lambda: now[0])
    quick, slow = parc.outputs.Progress("quick"), parc.outputs.Progress("slow")
    for n in range(1, 17):
        now[0] += 0.05                      # quick: 0.8 s in all; slow: 16 s
        quick(n / 16)
    quick.done()
    assert capsys.readouterr().err == ""
    slow.start = now[0]
    for n in range(1, 17):
        now[0] += 1.0
        slow(n / 16)
    slow.done()
    # The time left is at the pace since the first report: the start may have been compiling.
    assert capsys.readouterr().err.splitlines() == [
        "parc: slow: 6%", "parc: slow: 25%, about 10 s left", "parc: slow: 50%, about 8 s left",
        "parc: slow: 75%, about 4 s left", "parc: slow: done in 16.0 s"]         # not left at 75%


def _progress_on_a_clock_of_our_own(monkeypatch):
    """A Progress ("work") whose clock is ``now[0]``, its pending 0% report cancelled."""
    from parc import outputs
    now = [100.0]
    monkeypatch.setattr(outputs.time, "perf_counter", lambda: now[0])
    work = outputs.Progress("work")
    work.pending.cancel()
    return work, now


def test_the_time_left_ignores_a_slow_start(monkeypatch, capsys):
    # A first band that compiled the casters for 30 s, then 15 bands of a second each.
    work, now = _progress_on_a_clock_of_our_own(monkeypatch)
    for n in range(1, 17):
        now[0] += 30.0 if n == 1 else 1.0
        work(n / 16)
    assert capsys.readouterr().err.splitlines()[1:4] == [
        "parc: work: 25%, about 10 s left", "parc: work: 50%, about 8 s left", "parc: work: 75%, about 4 s left"]


def test_the_time_left_leaves_out_compiling_after_the_first_report(monkeypatch, capsys):
    # A lit scene reported 2% before its first caster call compiled for 22 s: "27%, about 2 min
    # left" with 4 s to go. Here: 1 s of work a sixteenth, the second sixteenth 20 s compiling.
    from numba.core import event
    work, now = _progress_on_a_clock_of_our_own(monkeypatch)
    for n in range(1, 17):
        if n == 2:
            event.start_event("numba:compile")
            event.start_event("numba:compile")          # a callee, inside its caller's compile
            now[0] += 20.0
            event.end_event("numba:compile")
            event.end_event("numba:compile")
        now[0] += 1.0
        work(n / 16)
    work.done()
    assert capsys.readouterr().err.splitlines()[1:4] == [
        "parc: work: 25%, about 10 s left", "parc: work: 50%, about 8 s left", "parc: work: 75%, about 4 s left"]
    event.start_event("numba:compile")                  # done: no longer listening
    event.end_event("numba:compile")
    assert work.compiling.seconds(now[0]) == 20.0


@pytest.mark.parametrize("seconds, said", [(0.3, "about 1 s left"), (7.4, "about 7 s left"),
                                           (42.0, "about 40 s left"), (59.0, "about 1 min left"),
                                           (185.0, "about 3 min left"),
                                           (3599.0, "about 1 h 0 min left"), (7500.0, "about 2 h 5 min left")])
def test_the_time_left_is_rounded_as_an_estimate(seconds, said):
    from parc.outputs import time_left
    assert time_left(seconds) == said


def test_a_terminal_line_is_written_over_whole(monkeypatch, capsys):
    from parc import outputs
    now = [100.0]
    monkeypatch.setattr(outputs.time, "perf_counter", lambda: now[0])
    monkeypatch.setattr(outputs.sys.stderr, "isatty", lambda: True)
    work = outputs.Progress("work")
    work.pending.cancel()
    for fraction in (0.1, 0.2):
        now[0] += 100.0
        work(fraction)
    work.done()
    err = capsys.readouterr().err
    long = "parc: work:  20%, about 13 min left"
    assert err == "\rparc: work:  10%" + "\r" + long + "\r" + "parc: work: done in 200.0 s".ljust(len(long)) + "\n"


def test_a_png_keeps_the_colour_of_faint_pixels(tmp_path):
    # Straight colour c with alpha a, premultiplied as the renderer gives it:
    # the PNG holds round(255 c) and round(255 a), whatever a is.
    from PIL import Image
    from parc.outputs import write_png
    # (No value lands on a half step of 1/255, where float32 could round either way.)
    alpha = np.array([0.0, 0.02, 0.05, 0.31, 1.0])
    colour = np.array([[0.3, 0.6, 0.9], [0.11, 0.52, 0.97], [0.31, 0.62, 0.93], [0.07, 0.52, 0.95],
                       [0.25, 0.55, 0.75]])
    image = np.concatenate([colour * alpha[:, None], alpha[:, None]], axis=1)[None].astype(np.float32)
    write_png(image, tmp_path / "faint.png")
    with Image.open(tmp_path / "faint.png") as im:
        png = np.asarray(im)[0]
    assert np.array_equal(png[:, 3], np.rint(alpha * 255))
    assert np.array_equal(png[1:, :3], np.rint(colour[1:] * 255)) and not png[0, :3].any()


def test_json_is_strict_and_takes_numpy_numbers():
    # RFC 8259 has no NaN or Infinity: each becomes null, however deep and whatever its type,
    # and numpy's numbers are numbers, not an error in the middle of writing the stats.
    from parc.outputs import to_json
    text = to_json({"psnr": np.float64(np.inf), 2: (np.float32(0.5), np.nan, -np.inf), "n": np.int64(7),
                    "hit": np.bool_(True), "file": Path("a/b.png"), "rows": [{"d": float("nan"), "e": 1e308}]})

    def refuse(token):
        raise AssertionError(f"{token} is not JSON")
    assert json.loads(text, parse_constant=refuse) == {
        "psnr": None, "2": [0.5, None, None], "n": 7, "hit": True, "file": "a/b.png", "rows": [{"d": None, "e": 1e308}]}


@pytest.mark.parametrize("method", ["brute", "parc"])
@pytest.mark.parametrize("look, count", [(["--iso", 4.0], "cells_visited"), (["--tf", "greyscale"], "samples")])
def test_render_writes_the_work_per_pixel(vol_file, tmp_path, capsys, method, look, count, gl):
    st, arr, pic = tmp_path / "s.json", tmp_path / "w.npy", tmp_path / "w.png"
    argv = ["render", vol_file, *look, "--size", 40, 30, "--method", method, "--stats", st]
    rc, _, err = _run(argv + ["-o", tmp_path / "a.png", "--work", arr], capsys)
    assert rc == 0, err
    work = np.load(arr)
    assert work.shape == (30, 40) and work.dtype == np.int64
    assert work.sum() == json.loads(st.read_text())[count] > 0
    rc, _, err = _run(argv + ["-o", tmp_path / "b.png", "--work", pic], capsys)
    assert rc == 0, err
    from PIL import Image
    with Image.open(pic) as im:
        assert im.format == "PNG"


@pytest.mark.parametrize("method", ["brute", "parc"])
def test_work_of_a_lit_shadowed_surface_is_its_camera_rays(vol_file, tmp_path, capsys, method, gl):
    # Lights send the render through the several-volume driver; the camera rays' cells are
    # the unlit render's, which the one-volume driver counts on its own.
    look = ["render", vol_file, "--iso", 4.0, "--size", 24, 20, "--method", method]
    maps = []
    for extra in ([], ["--light", "30,30,30", "--sun", "0,1,0", "--shadows"]):
        out, work = tmp_path / f"a{len(maps)}.png", tmp_path / f"w{len(maps)}.npy"
        rc, _, err = _run(look + extra + ["-o", out, "--work", work], capsys)
        assert rc == 0, err
        maps.append(np.load(work))
    assert maps[0].sum() > 0 and np.array_equal(maps[0], maps[1])


def test_work_of_a_scene_of_surfaces_and_translucent_volumes_is_refused(vol_file, tmp_path, capsys):
    scene = tmp_path / "scene.toml"
    scene.write_text(f"size = [8, 8]\n[[volume]]\nfile = '{vol_file.name}'\niso = 4.0\n"
                     f"[[volume]]\nfile = '{vol_file.name}'\ntf = 'greyscale'\n")
    out, work = tmp_path / "a.png", tmp_path / "w.npy"
    rc, _, err = _run(["render", scene, "-o", out, "--work", work], capsys)
    assert rc == 2 and err.count("\n") == 1, err
    assert ("--work: per-pixel work counts cells visited for isosurfaces and samples taken for translucent "
            "volumes, and this scene has both") in err
    assert not out.exists() and not work.exists()


def test_render_npy_matches_the_library(vol_file, tmp_path, capsys):
    import parc
    out = tmp_path / "a.npy"
    eye = "20,-15,9"
    rc, _, err = _run(["render", vol_file, "--iso", 3.5, "--size", 16, 12, "--eye", eye, "-o", out], capsys)
    assert rc == 0, err
    vol = parc.load_volume(vol_file)
    cam = parc.Camera(eye=(20, -15, 9), look_at=tuple(vol.center), up=(0, 0, 1))
    ref = parc.render(parc.Scene(camera=cam, size=(16, 12), volumes=[parc.Isosurface(vol, 3.5)]))
    image = np.load(out)
    assert image.dtype == np.float32 and image.shape == (12, 16, 4)
    np.testing.assert_array_equal(image, ref.image)


def test_a_png_holds_the_image_the_right_way_up(tmp_path, capsys):
    # A ramp seen from the side, through a greyscale transfer function: no row or column
    # mirrors another, so a flipped or transposed PNG differs from the array.
    k, j, i = np.mgrid[0:12, 0:12, 0:12]
    vol = save_volume(Volume((i + 2.0 * j + 4.0 * k).astype(np.float32)), tmp_path / "ramp.nrrd")
    look = ["render", vol, "--tf", "greyscale", "--size", 16, 12, "--eye", "20,-15,9"]
    for out in (tmp_path / "a.png", tmp_path / "a.npy"):
        rc, _, err = _run(look + ["-o", out], capsys)
        assert rc == 0, err
    image = np.load(tmp_path / "a.npy").astype(np.float64)
    assert not np.allclose(image, image[::-1], atol=0.05) and not np.allclose(image, image[:, ::-1], atol=0.05)
    with Image.open(tmp_path / "a.png") as im:
        png = np.asarray(im).astype(np.float64)
    # Straight colour, as PNG stores it; a unit either way where float32 lands on a half step.
    a = image[..., 3:]
    straight = np.concatenate([np.divide(image[..., :3], a, out=np.zeros_like(a.repeat(3, -1)), where=a > 0), a], -1)
    assert png.shape == (12, 16, 4) and np.abs(png - np.rint(255 * straight)).max() <= 1


def test_an_array_written_over_a_npy_volume_takes_its_sidecar_away(vol_file, tmp_path, capsys):
    # Left behind, the sidecar gave the image, read back as a volume, the old volume's spacing and origin.
    vol = tmp_path / "v.npy"
    rc, _, err = _run(["convert", vol_file, "-o", vol, "--spacing", "2,2,2", "--origin", "5,5,5"], capsys)
    assert rc == 0 and (tmp_path / "v.npy.json").is_file(), err
    for flag in ("-o", "--depth"):
        other = ["-o", tmp_path / "a.png"] if flag == "--depth" else []
        rc, _, err = _run(["render", vol_file, "--iso", 3.5, "--size", 16, 12, flag, vol] + other, capsys)
        assert rc == 0 and "removed " in err and not (tmp_path / "v.npy.json").exists(), err
        if flag == "-o":
            back = load_volume(vol)             # the RGBA image, as a 4 x 16 x 12 volume
            assert back.spacing == (1.0, 1.0, 1.0) and back.origin == (0.0, 0.0, 0.0)
            assert back.data.shape == (12, 16, 4)
        else:
            assert np.load(vol).shape == (12, 16)
        rc, _, err = _run(["convert", vol_file, "-o", vol, "--spacing", "2,2,2"], capsys)
        assert rc == 0 and load_volume(vol).spacing == (2.0, 2.0, 2.0), err


def test_only_a_real_sidecar_is_taken_away_and_through_a_link_both(vol_file, tmp_path, capsys):
    # A run's stats named img.npy.json are no sidecar: kept. Through a link, the sidecar beside
    # the file it leads to went stale too.
    img, stats = tmp_path / "img.npy", tmp_path / "img.npy.json"
    rc, _, err = _run(["render", vol_file, "--iso", 3.5, "--size", 8, 8, "-o", img, "--stats", stats], capsys)
    assert rc == 0 and stats.is_file(), err
    rc, _, err = _run(["render", vol_file, "--iso", 3.5, "--size", 8, 8, "-o", img], capsys)
    assert rc == 0 and stats.is_file() and "removed" not in err, err
    real = tmp_path / "real.npy"
    rc, _, err = _run(["convert", vol_file, "-o", real, "--spacing", "2,2,2"], capsys)
    assert rc == 0 and (tmp_path / "real.npy.json").is_file(), err
    (tmp_path / "link.npy").symlink_to(real)
    rc, _, err = _run(["render", vol_file, "--iso", 3.5, "--size", 8, 8, "-o", tmp_path / "link.npy"], capsys)
    assert rc == 0 and not (tmp_path / "real.npy.json").exists(), err
    assert load_volume(real).spacing == (1.0, 1.0, 1.0)


def test_stats_are_not_written_over_a_npy_volumes_sidecar(vol_file, tmp_path, capsys):
    # Written over, the volume lost its placement and could no longer be read (unknown keys).
    vol, side = tmp_path / "v.npy", tmp_path / "v.npy.json"
    rc, _, err = _run(["convert", vol_file, "-o", vol, "--spacing", "2,2,2"], capsys)
    assert rc == 0 and side.is_file(), err
    (tmp_path / "link.npy.json").symlink_to(side)
    before = side.read_bytes()
    for stats in (side, tmp_path / "link.npy.json"):
        rc, _, err = _run(["render", vol_file, "--iso", 3.5, "--size", 8, 8, "-o", tmp_path / "a.png",
                           "--stats", stats], capsys)
        assert rc == 2 and err.count("\n") == 1 and "spacing and origin of the volume v.npy" in err, err
        assert side.read_bytes() == before and not (tmp_path / "a.png").exists()
    assert load_volume(vol).spacing == (2.0, 2.0, 2.0)
    # Nor beside a volume without one: read back as its sidecar, the stats stopped it loading.
    bare = tmp_path / "bare.npy"
    np.save(bare, np.zeros((2, 2, 2), np.uint8))
    rc, _, err = _run(["render", vol_file, "--iso", 3.5, "--size", 8, 8, "-o", tmp_path / "a.png",
                       "--stats", tmp_path / "bare.npy.json"], capsys)
    assert rc == 2 and "would be read as the spacing and origin of the volume bare.npy" in err, err
    assert not (tmp_path / "bare.npy.json").exists() and load_volume(bare).spacing == (1.0, 1.0, 1.0)
    # Unless the run writes over the volume itself: its sidecar is stale then, the stats welcome.
    rc, _, err = _run(["render", vol_file, "--iso", 3.5, "--size", 8, 8, "-o", vol, "--stats", side], capsys)
    assert rc == 0 and '"method"' in side.read_text() and np.load(vol).shape == (8, 8, 4), err


def test_stats_are_not_written_over_the_sidecar_of_a_volume_named_in_capitals(vol_file, tmp_path, capsys):
    # V.NPY reads its spacing and origin from V.NPY.json as v.npy does from v.npy.json.
    vol, side = tmp_path / "V.NPY", tmp_path / "V.NPY.json"
    rc, _, err = _run(["convert", vol_file, "-o", vol, "--spacing", "2,2,2"], capsys)
    assert rc == 0 and side.is_file() and load_volume(vol).spacing == (2.0, 2.0, 2.0), err
    before = side.read_bytes()
    rc, _, err = _run(["render", vol_file, "--iso", 3.5, "--size", 8, 8, "-o", tmp_path / "a.png",
                       "--stats", side], capsys)
    assert rc == 2 and err.count("\n") == 1 and "spacing and origin of the volume V.NPY" in err, err
    assert side.read_bytes() == before and not (tmp_path / "a.png").exists()
    assert load_volume(vol).spacing == (2.0, 2.0, 2.0)


def test_render_without_iso_suggests_one(vol_file, tmp_path, capsys):
    rc, _, err = _run(["render", vol_file, "--size", 8, 8, "-o", tmp_path / "a.png"], capsys)
    assert rc == 0 and "suggested from the histogram" in err


def test_render_builtin_volume(tmp_path, capsys):
    rc, _, err = _run(["render", "--size", 24, 24, "-o", tmp_path / "b.png"], capsys)
    assert rc == 0, err
    # The built-in view frames the torus: a good part of the picture is surface, its edges are not.
    alpha = np.asarray(Image.open(tmp_path / "b.png"))[..., 3]
    assert 0.05 < (alpha == 255).mean() < 0.9 and (alpha[[0, -1]] == 0).all() and (alpha[:, [0, -1]] == 0).all()


def test_info_and_make(tmp_path, capsys):
    rc, out, _ = _run(["make", "blobs", "--size", 20, "-o", tmp_path / "b.nrrd"], capsys)
    assert rc == 0
    rc, out, _ = _run(["info", tmp_path / "b.nrrd"], capsys)
    assert rc == 0 and "20" in out and "uint8" in out


def test_convert_gives_a_raw_file_its_header(tmp_path, capsys):
    from data_tools.io import load_volume
    data = np.arange(5 * 4 * 3, dtype=np.int16).reshape(5, 4, 3) * 37 - 900     # [z, y, x]
    raw = tmp_path / "scan.raw"
    raw.write_bytes(data.astype(">i2").tobytes())
    out = tmp_path / "scan.nrrd"
    rc, stdout, err = _run(["convert", raw, "--shape", "3,4,5", "--dtype", "int16", "--byte-order", "big",
                            "--spacing", "0.5,0.5,2", "--origin", "-1,2,-3", "-o", out], capsys)
    assert rc == 0, err
    assert "3x4x5 int16" in stdout and "spacing 0.5, 0.5, 2" in stdout
    vol = load_volume(out)
    assert vol.data.dtype == np.int16 and np.array_equal(vol.data, data)
    assert vol.spacing == (0.5, 0.5, 2.0) and vol.origin == (-1.0, 2.0, -3.0)


def test_a_raw_file_behind_a_vendor_header_is_read_with_offset(tmp_path, capsys):
    data = np.arange(5 * 4 * 3, dtype=np.uint16).reshape(5, 4, 3) * 1000     # [z, y, x]
    raw = tmp_path / "scan.dat"
    raw.write_bytes(b"VENDOR HEADER".ljust(100, b"\0") + data.tobytes())
    flags = ["--shape", "3,4,5", "--dtype", "uint16", "--offset", "100"]
    rc, stdout, err = _run(["convert", raw, *flags, "-o", tmp_path / "scan.nrrd"], capsys)
    assert rc == 0, err
    assert np.array_equal(load_volume(tmp_path / "scan.nrrd").data, data)
    rc, stdout, err = _run(["info", raw, *flags], capsys)
    assert rc == 0 and "range:       0 .. 59000, mean 29500" in stdout, (stdout, err)
    for offset, words in (("-1", "--offset: must be a byte count (a whole number >= 0), got '-1'"),
                          ("200", "needs 120 bytes after a 200-byte header, the file has 20 after it (220 in all)")):
        rc, _, err = _run(["info", raw, *flags[:4], "--offset", offset], capsys)
        assert rc == 2 and words in err and err.count("\n") == 1, err
    rc, _, err = _run(["render", "--offset", "4", "-o", tmp_path / "b.png"], capsys)
    assert rc == 2 and "--offset applies to a volume file; the built-in volume takes none" in err, err


@pytest.mark.parametrize("second, words", [(1.0, "every sample is 1; there is no isosurface to show"),
                                           (np.nextafter(1.0, 2.0), "no level lies strictly between its samples' "
                                                                    "values, 1 and 1.0000000000000002;")])
def test_render_without_iso_says_why_no_level_is_suggested(tmp_path, capsys, second, words):
    data = np.ones((6, 6, 6))
    data[2:4, 2:4, 2:4] = second
    np.save(tmp_path / "v.npy", data)
    rc, _, err = _run(["render", tmp_path / "v.npy", "--size", 8, 8, "-o", tmp_path / "v.png"], capsys)
    assert rc == 2 and err.count("\n") == 1 and words in err, err
    assert not (tmp_path / "v.png").exists()


def test_convert_a_tiff_stack_says_when_its_spacing_is_unknown(tmp_path, capsys):
    import tifffile
    from data_tools.io import load_volume
    data = np.random.default_rng(3).integers(0, 255, (6, 5, 4)).astype(np.uint8)
    tif = tmp_path / "stack.tif"
    tifffile.imwrite(tif, data, photometric="minisblack")
    rc, _, err = _run(["convert", tif, "-o", tmp_path / "a.npy"], capsys)
    assert rc == 0 and "no voxel size (no ImageJ or OME metadata)" in err
    rc, _, err = _run(["convert", tif, "--spacing", "0.2,0.2,1", "-o", tmp_path / "b.mha"], capsys)
    assert rc == 0 and err == ""
    vol = load_volume(tmp_path / "b.mha")
    assert np.array_equal(vol.data, data) and vol.spacing == (0.2, 0.2, 1.0)


@pytest.mark.parametrize("out_name, words", [("v.png", "output must end in"), ("ball.nrrd", "is the input file"),
                                              ("none/v.nrrd", "does not exist")])
def test_convert_refusals_write_nothing(vol_file, out_name, words, capsys):
    before = sorted(vol_file.parent.iterdir())
    stamp = vol_file.stat().st_mtime_ns
    rc, _, err = _run(["convert", vol_file, "-o", vol_file.parent / out_name], capsys)
    assert rc == 2 and err.count("\n") == 1 and words in err, err
    assert sorted(vol_file.parent.iterdir()) == before and vol_file.stat().st_mtime_ns == stamp


@pytest.mark.parametrize("source, out_name", [("scan.raw", "scan.mhd"), ("scan.raw", "scan.nhdr"),
                                               ("head.mhd", "head.nhdr"), ("head.nhdr", "head.mhd"),
                                               ("head.mhd", "head.raw"), ("head.nhdr", "head.raw")])
def test_convert_refuses_to_write_samples_over_the_input(tmp_path, source, out_name, capsys):
    # .mhd and .nhdr write their samples to STEM.raw: here the raw file read,
    # or the data file the input header names; a .raw output can be that data file itself.
    data = np.arange(4 * 3 * 2, dtype=np.int16).reshape(4, 3, 2) * 37 - 300
    raw = tmp_path / "scan.raw"
    raw.write_bytes(data.astype(">i2").tobytes())
    argv = ["convert", raw, "--shape", "2,3,4", "--dtype", "int16", "--byte-order", "big"]
    if source != "scan.raw":
        save_volume(Volume(data), tmp_path / source)
        argv = ["convert", tmp_path / source]
    before = {f.name: f.read_bytes() for f in tmp_path.iterdir()}
    rc, _, err = _run(argv + ["-o", tmp_path / out_name], capsys)
    words = "is read by this run" if out_name.endswith(".raw") else "which the volume is read from"
    assert rc == 2 and err.count("\n") == 1 and words in err, err
    assert {f.name: f.read_bytes() for f in tmp_path.iterdir()} == before


@pytest.mark.parametrize("name", ["my data.raw", "LISTING.raw"])
def test_convert_refuses_to_write_over_a_data_file_named_like_a_list(tmp_path, capsys, name):
    # Only the word LIST, alone or with one more, names a list of data files: a name with a
    # space, or LISTING.raw, is the header's one data file.
    data = np.arange(8, dtype=">i2") * 100
    (tmp_path / name).write_bytes(data.tobytes())
    (tmp_path / "x.nhdr").write_text("NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nendian: big\n"
                                     f"encoding: raw\ndata file: {name}\n")
    before = {f.name: f.read_bytes() for f in tmp_path.iterdir()}
    rc, _, err = _run(["convert", tmp_path / "x.nhdr", "-o", tmp_path / name], capsys)
    assert rc == 2 and "is read by this run" in err, err
    assert {f.name: f.read_bytes() for f in tmp_path.iterdir()} == before


@pytest.mark.parametrize("command", ["make", "convert"])
def test_a_header_never_writes_over_a_data_file_not_its_own(vol_file, tmp_path, command, capsys):
    # scan.mhd's samples go to scan.raw: an unrelated scan.raw stays; an earlier scan.mhd's is rewritten.
    argv = ["make", "sphere", "--size", 5] if command == "make" else ["convert", vol_file]
    (tmp_path / "scan.raw").write_bytes(b"someone else's samples")
    rc, _, err = _run(argv + ["-o", tmp_path / "scan.mhd"], capsys)
    assert rc == 2 and err.count("\n") == 1 and "scan.raw, which exists" in err, err
    assert (tmp_path / "scan.raw").read_bytes() == b"someone else's samples"
    assert not (tmp_path / "scan.mhd").exists()
    (tmp_path / "scan.raw").unlink()
    for _ in range(2):
        rc, out, err = _run(argv + ["-o", tmp_path / "scan.mhd"], capsys)
        assert rc == 0 and f"wrote {tmp_path / 'scan.mhd'} and {tmp_path / 'scan.raw'} (" in out, err




@pytest.mark.parametrize("command", ["make", "convert"])
@pytest.mark.parametrize("header", ["ElementDataFile = LOCAL\n", "ElementDataFile = elsewhere.bin\n"])
def test_a_header_of_that_name_reading_other_samples_does_not_make_the_raw_file_ours(
        vol_file, tmp_path, command, header, capsys):
    # A scan.mhd that keeps its samples within itself, or in another file, never wrote scan.raw.
    argv = ["make", "sphere", "--size", 5] if command == "make" else ["convert", vol_file]
    (tmp_path / "elsewhere.bin").write_bytes(bytes(range(8)))
    (tmp_path / "scan.mhd").write_bytes(b"ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\n"
                                        b"ElementType = MET_UCHAR\n" + header.encode()
                                        + (bytes(range(8)) if "LOCAL" in header else b""))
    (tmp_path / "scan.raw").write_bytes(b"someone else's samples")
    before = {f.name: f.read_bytes() for f in tmp_path.iterdir()}
    rc, _, err = _run(argv + ["-o", tmp_path / "scan.mhd"], capsys)
    assert rc == 2 and err.count("\n") == 1 and "scan.raw, which exists" in err, err
    assert {f.name: f.read_bytes() for f in tmp_path.iterdir()} == before


def test_a_raw_output_keeps_the_samples_of_any_header_beside_it_that_reads_them(tmp_path, capsys):
    # A detached NRRD header may end in .nrrd, in any case; one that reads other samples does not count.
    save_volume(Volume(np.arange(27, dtype=np.uint8).reshape(3, 3, 3)), tmp_path / "scan.nhdr")
    (tmp_path / "scan.nhdr").rename(tmp_path / "scan.NRRD")
    before = {f.name: f.read_bytes() for f in tmp_path.iterdir()}
    for out in ("scan.raw", "scan.mhd"):
        rc, _, err = _run(["make", "torus", "--size", 8, "-o", tmp_path / out], capsys)
        assert rc == 2 and err.count("\n") == 1 and "scan.raw holds scan.NRRD's samples" in err, err
        assert {f.name: f.read_bytes() for f in tmp_path.iterdir()} == before
    save_volume(Volume(np.zeros((2, 2, 2), np.uint8)), tmp_path / "other.nrrd")
    (tmp_path / "other.nrrd").rename(tmp_path / "loose.nrrd")
    (tmp_path / "loose.raw").write_bytes(b"mine")
    rc, _, err = _run(["make", "torus", "--size", 8, "-o", tmp_path / "loose.raw"], capsys)
    assert rc == 0 and (tmp_path / "loose.raw").stat().st_size == 8 ** 3 * 4, err
def test_make_s_help_gives_each_volume_s_size_as_made(capsys):
    # "--size N: default depends on the volume" left it to be found by making one.
    import re as regex
    from data_tools.synthetic import SYNTHETIC, make_synthetic
    with pytest.raises(SystemExit):
        main(["make", "--help"])
    listed = dict(regex.findall(r"^  (\w+) +\[(\d+)\] ", capsys.readouterr().out, regex.MULTILINE))
    assert set(listed) == set(SYNTHETIC)
    for name, size in listed.items():
        assert make_synthetic(name).dims[0] == int(size), name


@pytest.mark.parametrize("name, out", [("sphere", "s.nrrd"), ("ct_phantom", "my ct.mha"), ("marschner_lobb", "ml.raw"),
                                       ("trilinear_field", "t.npy")])
def test_make_says_how_to_render_what_it_wrote(tmp_path, capsys, monkeypatch, name, out):
    # The histogram's suggestion need not be the level a synthetic volume is made for (sphere:
    # 7.34 where its surface is at 0), so make gives the command with that level.
    import shlex
    from data_tools.synthetic import DESCRIPTIONS, ISOVALUES, make_synthetic
    assert all(f"iso {v:g}" in DESCRIPTIONS[name] for v in ISOVALUES[name])      # as make --help says
    if ISOVALUES[name]:                                                          # and as the volume says
        assert make_synthetic(name, 12).meta["iso"] == ISOVALUES[name][0]
    monkeypatch.chdir(tmp_path)
    rc, said, err = _run(["make", name, "--size", 12, "-o", tmp_path / out], capsys)
    assert rc == 0, err
    lines = said.splitlines()
    argv = shlex.split(lines[1].partition(": ")[2])
    if not ISOVALUES[name]:
        # Made for no level (a random trilinear field): one from the histogram, inside the samples,
        # the one a render without --iso takes (its note names it).
        from data_tools.info import suggest_isovalues
        levels = suggest_isovalues(make_synthetic(name, 12))
        level = levels[len(levels) // 2]
        assert lines[1].startswith(f"isovalue {level:g}, from the histogram: ") and f"--iso {level:g}" in lines[1]
        without = argv[1:argv.index("--iso")] + argv[argv.index("--iso") + 2:]
        rc, _, err = _run(without + ["--size", 16, 16], capsys)
        assert rc == 0 and f"no --iso given; using {level:g}," in err, err
    else:
        lo, hi = make_synthetic(name, 12).value_range()
        levels = [v for v in ISOVALUES[name] if lo <= v <= hi]         # ct_phantom's bone needs more samples
        assert lines[1].startswith(f"isovalue{'s' if len(levels) > 1 else ''} "
                                   f"{' and '.join(f'{v:g}' for v in levels)}:")
        assert f"--iso {ISOVALUES[name][0]:g}" in lines[1]
    assert argv[:2] == ["parc", "render"]
    rc, _, err = _run(argv[1:] + ["--size", 16, 16], capsys)
    assert rc == 0, err
    assert (tmp_path / argv[-1]).stat().st_size > 0


@pytest.mark.parametrize("size", [2, 3])
def test_the_command_make_suggests_runs_at_any_size(tmp_path, capsys, monkeypatch, size):
    # At 3 samples a side the neuron's samples lie in [91, 216], above the 80.5 it is made for.
    import shlex
    from data_tools.io import load_volume
    from data_tools.synthetic import ISOVALUES
    monkeypatch.chdir(tmp_path)
    for name in sorted(ISOVALUES):
        rc, said, err = _run(["make", name, "--size", size, "-o", tmp_path / "v.nrrd"], capsys)
        assert rc == 0, err
        lines = said.splitlines()
        lo, hi = load_volume(tmp_path / "v.nrrd").value_range()
        if lo == hi:                                      # no surface to suggest, and the reason
            assert len(lines) == 2 and lines[1].startswith(f"at this size every sample of the {name} is ")
            assert lines[1].endswith(": it has no isosurface to render; give a larger --size"), (name, said)
            continue
        argv = shlex.split(lines[1].partition(": ")[2])
        rc, _, err = _run(argv[1:] + ["--size", 8, 8], capsys)
        assert rc == 0, (name, lines[1], err)


def test_a_raw_output_says_it_keeps_no_spacing(tmp_path, capsys):
    from data_tools.io import load_volume
    rc, out, err = _run(["make", "marschner_lobb", "--size", 5, "-o", tmp_path / "ml.raw"], capsys)
    flags = "--shape 5,5,5 --dtype float32 --spacing 0.5,0.5,0.5 --origin -1,-1,-1"
    assert rc == 0 and f"samples only: read it back with {flags}; a .raw file has no header" in out, err
    vol = load_volume(tmp_path / "ml.raw", shape=(5, 5, 5), dtype="float32", spacing=(0.5,) * 3, origin=(-1,) * 3)
    rc, out, err = _run(["convert", tmp_path / "ml.raw", *flags.split(), "-o", tmp_path / "ml.nrrd"], capsys)
    assert rc == 0 and "spacing 0.5, 0.5, 0.5, origin -1, -1, -1" in out, err
    assert np.array_equal(load_volume(tmp_path / "ml.nrrd").data, vol.data)


@pytest.mark.parametrize("name, says", [("ct_6x5x4_int16_be.raw", "read it back with --spacing 0.3333333333333333,0.1,2 "
                                                                   "--origin -1e-07,123456.789,0;"),
                                         ("ct_int16_msb.raw", "read it back with --shape 6,5,4 --spacing"),
                                         ("ct.raw", "read it back with --shape 6,5,4 --dtype int16 --spacing")])
def test_a_raw_output_names_the_flags_that_read_it_back(tmp_path, capsys, name, says):
    # The message's flags, with what the name states, read the samples back as they were,
    # in the byte order the name gives (written big-endian for _be and _msb), and spacing and
    # origin to the last digit.
    from data_tools import Volume
    from data_tools.io import load_volume, save_volume
    arr = np.arange(120, dtype=np.int16).reshape(4, 5, 6) * 131       # two different bytes: the order shows
    spacing, origin = (1 / 3, 0.1, 2.0), (-1e-7, 123456.789, 0.0)
    save_volume(Volume(arr, spacing=spacing, origin=origin), tmp_path / "v.nrrd")
    rc, out, err = _run(["convert", tmp_path / "v.nrrd", "-o", tmp_path / name], capsys)
    assert rc == 0 and says in out, (out, err)
    flags = out.split("read it back with ")[1].split(";")[0].split() if "read it back" in out else []
    rc, out, err = _run(["convert", tmp_path / name, *flags, "-o", tmp_path / "back.npy"], capsys)
    assert rc == 0, err
    back = load_volume(tmp_path / "back.npy")
    assert np.array_equal(back.data, arr) and back.spacing == spacing and back.origin == origin


def test_a_raw_output_whose_name_says_it_all_needs_no_flags(tmp_path, capsys):
    from data_tools import Volume
    from data_tools.io import load_volume, save_volume
    arr = np.arange(120, dtype=np.int16).reshape(4, 5, 6) * 131
    save_volume(Volume(arr), tmp_path / "v.nrrd")
    rc, out, err = _run(["convert", tmp_path / "v.nrrd", "-o", tmp_path / "ct_6x5x4_int16_be.raw"], capsys)
    assert rc == 0 and "samples only; its name gives their shape and type" in out, (out, err)
    assert np.array_equal(load_volume(tmp_path / "ct_6x5x4_int16_be.raw").data, arr)


@pytest.mark.parametrize("name, says", [("ct_64x64x64_int16.raw", "the name says 64x64x64,"),
                                         ("ct_6x5x4_uint8.raw", "the name says uint8,"),
                                         ("ct_float_double.raw", "the name says float32 or float64,")])
def test_a_raw_output_whose_name_states_other_samples_is_refused(tmp_path, capsys, name, says):
    from data_tools import Volume
    from data_tools.io import save_volume
    save_volume(Volume(np.zeros((4, 5, 6), np.int16)), tmp_path / "v.nrrd")
    rc, out, err = _run(["convert", tmp_path / "v.nrrd", "-o", tmp_path / name], capsys)
    assert rc == 2 and err.count("\n") == 1 and says in err and "6x5x4 int16" in err, err
    assert not (tmp_path / name).exists()


@pytest.mark.parametrize("command", ["render", "make", "convert"])
def test_an_upper_case_npy_extension_is_the_file_written(vol_file, tmp_path, command, capsys):
    from data_tools.io import load_volume
    out = tmp_path / "out.NPY"
    argv = {"render": ["render", vol_file, "--iso", 4.0, "--size", 12, 10, "--depth", tmp_path / "d.NPY"],
            "make": ["make", "sphere", "--size", 8], "convert": ["convert", vol_file]}[command]
    rc, _, err = _run(argv + ["-o", out], capsys)
    assert rc == 0, err
    names = sorted(f.name for f in tmp_path.iterdir() if f != vol_file)
    assert names == (["d.NPY", "out.NPY"] if command == "render" else ["out.NPY"])
    shape = np.load(out).shape
    assert shape == ((10, 12, 4) if command == "render" else load_volume(out).data.shape)


def test_a_failed_write_names_the_output_not_its_temporary_file(tmp_path):
    from data_tools import InputError
    from parc.outputs import atomic_write_all

    def full_disk(tmp):
        raise OSError(28, "No space left on device", str(tmp))
    out = tmp_path / "a.png"
    with pytest.raises(InputError, match=r"^\S*a\.png: cannot write: No space left on device$"):
        atomic_write_all([(tmp_path / "s.json", lambda tmp: tmp.write_text("{}")), (out, full_disk)])
    assert list(tmp_path.iterdir()) == []


def test_a_name_near_the_length_limit_can_be_written(vol_file, tmp_path, capsys):
    # 251 characters and ".png": a temporary name built from it had passed the 255-byte limit.
    for out in (tmp_path / ("a" * 251 + ".png"), tmp_path / ("b" * 251 + ".mhd")):
        argv = ["render", vol_file, "--iso", 4.0, "--size", 8, 8] if out.suffix == ".png" else ["convert", vol_file]
        rc, _, err = _run(argv + ["-o", out], capsys)
        assert rc == 0 and out.exists(), err


def test_headers_that_name_their_data_file(vol_file, tmp_path, capsys):
    # An ASCII header cannot name "ö.raw"; and STEM.raw is already STEM.mhd's when STEM.nhdr comes.
    rc, _, err = _run(["convert", vol_file, "-o", tmp_path / "ö.mhd"], capsys)
    assert rc == 2 and err.count("\n") == 1 and "names its data file in ASCII" in err, err
    rc, _, err = _run(["convert", vol_file, "-o", tmp_path / "v.mhd"], capsys)
    assert rc == 0, err
    before = (tmp_path / "v.raw").read_bytes()
    rc, _, err = _run(["make", "sphere", "--size", 8, "-o", tmp_path / "v.nhdr"], capsys)
    assert rc == 2 and "v.raw holds v.mhd's samples" in err, err
    assert (tmp_path / "v.raw").read_bytes() == before and not (tmp_path / "v.nhdr").exists()
    # Nor may a bare .raw output replace them (v.mhd would read the new samples).
    for argv in (["make", "torus", "--size", 8], ["convert", vol_file]):
        rc, _, err = _run(argv + ["-o", tmp_path / "v.raw"], capsys)
        assert rc == 2 and err.count("\n") == 1 and "v.raw: v.raw holds v.mhd's samples" in err, err
        assert (tmp_path / "v.raw").read_bytes() == before
    rc, _, err = _run(["make", "torus", "--size", 8, "-o", tmp_path / "w.raw"], capsys)
    assert rc == 0 and (tmp_path / "w.raw").exists(), err


def test_no_command_is_one_line(capsys):
    rc, out, err = _run([], capsys)
    assert rc == 2 and out == "" and err.count("\n") == 1 and err.startswith("parc: error: give a command"), err


def test_a_vtk_title_is_one_ascii_line(tmp_path, capsys):
    from data_tools.io import load_volume
    k, j, i = np.mgrid[0:4, 0:5, 0:6]
    source = save_volume(Volume((i + 10 * j + 100 * k).astype(np.int16)), tmp_path / "a\nb ü.nrrd")
    rc, _, err = _run(["convert", source, "-o", tmp_path / "t.vtk"], capsys)
    assert rc == 0, err
    assert (tmp_path / "t.vtk").read_bytes().split(b"\n")[1] == b"a?b ?.nrrd"
    assert np.array_equal(load_volume(tmp_path / "t.vtk").data, load_volume(source).data)


@pytest.mark.parametrize("how", ["stderr closed", "ascii output"])
def test_odd_output_streams(vol_file, tmp_path, how):
    # Closed stderr: the image is still made. An ASCII-only stdout: the tables escape Δ, no traceback.
    import os
    env = dict(os.environ, PYTHONIOENCODING="ascii")
    if how == "stderr closed":
        out = tmp_path / "o.png"
        p = subprocess.run([sys.executable, "-m", "parc.cli", "render", str(vol_file), "--iso", "4", "--size", "8", "8",
                            "-o", str(out)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, close_fds=True,
                           preexec_fn=lambda: os.close(2), timeout=300)
        assert p.returncode == 0 and out.exists() and p.stdout == b""
    else:
        p = subprocess.run([sys.executable, "-m", "parc.cli", "compare", str(vol_file), "--tf", "greyscale",
                            "--size", "8", "8", "--repeats", "1", "--sweep-step", "1", "--quiet"],
                           capture_output=True, env=env, timeout=300)
        assert p.returncode == 0 and b"\\u0394" in p.stdout and b"Traceback" not in p.stderr, p.stderr


def test_standard_descriptors_closed_at_the_start_are_not_given_to_files(tmp_path):
    # With 2>&- the first file opened took descriptor 2: what Mesa printed to stderr went into it.
    import os
    script = ("import os; from parc.console import _open_closed_standard_descriptors as fill; fill(); "
              f"fd = os.open({str(tmp_path / 'f')!r}, os.O_WRONLY | os.O_CREAT); "
              f"open({str(tmp_path / 'fd')!r}, 'w').write(str(fd))")
    p = subprocess.run([sys.executable, "-c", script], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, close_fds=True, preexec_fn=lambda: [os.close(fd) for fd in (0, 1, 2)],
                       timeout=300)
    assert p.returncode == 0 and int((tmp_path / "fd").read_text()) > 2


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
@pytest.mark.parametrize("buffered", [True, False])
@pytest.mark.parametrize("command", [["info", "{vol}"], ["convert", "{vol}", "-o", "{tmp}/c.nrrd"],
                                     ["make", "sphere", "--size", "4", "-o", "{tmp}/m.nrrd"],
                                     ["compare", "{vol}", "--iso", "4", "--size", "8", "8", "--repeats", "1",
                                      "--quiet", "--json"],
                                     ["compare", "{vol}", "--iso", "4", "--size", "8", "8", "--repeats", "1",
                                      "--quiet", "--work", "{tmp}/w.png"], ["--version"], ["render", "--help"]])
def test_a_full_standard_output_is_named(vol_file, tmp_path, command, buffered):
    # `> /dev/full` ended in "No space left on device" alone, with convert's file written;
    # buffered, the text left behind failed again at exit: a second complaint, status 120.
    # Help and version were lost with status 0 (argparse drops a failed write).
    argv = [a.format(tmp=tmp_path, vol=vol_file) for a in command]
    env = {k: v for k, v in os.environ.items() if not (buffered and k == "PYTHONUNBUFFERED")}
    with open("/dev/full", "w") as full:
        p = subprocess.run([sys.executable, "-m", "parc"] + argv, stdout=full, stderr=subprocess.PIPE, env=env,
                           timeout=300)
    assert p.returncode == 2
    # (A loaded machine's slow read adds a "reading ... done" line, which is not the point here.)
    err = "".join(line for line in p.stderr.decode().splitlines(keepends=True) if not PROGRESS_LINE.match(line))
    # What convert and make wrote, and compare's work map, is whole and stays: their line says so.
    flag = next((f for f in ("-o", "--work") if f in argv), None)
    written = argv[argv.index(flag) + 1] if flag else None
    done = f"wrote {written}, but " if written else ""
    assert err == f"parc: error: {done}cannot write to standard output: No space left on device\n"
    assert written is None or Path(written).is_file()


def test_python_m_parc_is_the_command(vol_file):
    from importlib.metadata import version
    p = subprocess.run([sys.executable, "-m", "parc", "--version"], capture_output=True, timeout=120)
    assert p.returncode == 0 and p.stdout.decode() == f"parc {version('parc')}\n" and p.stderr == b""


def test_an_output_that_is_a_link_is_written_where_it_leads(vol_file, tmp_path, capsys):
    # Renamed onto the link itself, the new file replaced the link.
    (tmp_path / "out").mkdir()
    for name, target in (("i.png", "out/real.png"), ("v.nrrd", "out/real.nrrd")):
        (tmp_path / name).symlink_to(target)
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", tmp_path / "i.png"], capsys)
    assert rc == 0, err
    rc, _, err = _run(["convert", vol_file, "-o", tmp_path / "v.nrrd"], capsys)
    assert rc == 0, err
    assert (tmp_path / "i.png").is_symlink() and (tmp_path / "v.nrrd").is_symlink()
    assert Image.open(tmp_path / "out" / "real.png").size == (8, 8)
    assert np.array_equal(load_volume(tmp_path / "out" / "real.nrrd").data, load_volume(vol_file).data)


@pytest.mark.parametrize("command", [["render", "{vol}", "--iso", 4, "--size", 8, 8, "-o", "{out}.png"],
                                     ["render", "{vol}", "--iso", 4, "--size", 8, 8, "-o", "ok.png",
                                      "--stats", "{out}.json"],
                                     ["convert", "{vol}", "-o", "{out}.nrrd"]])
@pytest.mark.parametrize("kind", ["pipe", "link to a pipe"])
def test_an_output_on_a_pipe_is_refused_and_left_a_pipe(vol_file, tmp_path, capsys, command, kind):
    # Renamed onto, a named pipe (or a device: a link to /dev/null, for root) became a plain file.
    os.mkfifo(tmp_path / "fifo")
    out = tmp_path / "o"
    if kind == "pipe":
        os.rename(tmp_path / "fifo", tmp_path / ("o" + Path(command[-1]).suffix))
        pipe = tmp_path / ("o" + Path(command[-1]).suffix)
    else:
        (tmp_path / ("o" + Path(command[-1]).suffix)).symlink_to(tmp_path / "fifo")
        pipe = tmp_path / "fifo"
    argv = [str(a).format(vol=vol_file, out=out) for a in command]
    argv = [str(tmp_path / a) if a == "ok.png" else a for a in argv]
    rc, out_text, err = _run(argv, capsys)
    assert rc == 2 and out_text == ""
    assert err.startswith("parc: error: ") and "not a regular file (a device, pipe or socket)" in err
    assert err.count("\n") == 1
    assert stat.S_ISFIFO(os.stat(pipe).st_mode)
    assert not (tmp_path / "ok.png").exists()


@pytest.mark.parametrize("case, words", [
    ("a file for a folder", "x.png/o.png: {tmp}/x.png is a file, not a folder"),
    ("a link in a loop", "loop.nrrd: a link that leads nowhere (or in a loop)"),
    ("a sidecar folder", "v.npy.json: the sidecar of v.npy (its spacing and origin) is not a file"),
    ("a link into a missing folder", "dangling.png: a link to {tmp}/gone/o.png, whose folder does not exist"),
])
def test_paths_that_are_not_what_they_seem_are_named(vol_file, tmp_path, capsys, case, words):
    # Each was named wrongly: "folder x.png does not exist", "no such file", "v.npy: cannot write: Is a directory".
    (tmp_path / "x.png").write_bytes(b"")
    (tmp_path / "loop.nrrd").symlink_to(tmp_path / "loop2.nrrd")
    (tmp_path / "loop2.nrrd").symlink_to(tmp_path / "loop.nrrd")
    (tmp_path / "v.npy.json").mkdir()
    (tmp_path / "dangling.png").symlink_to(tmp_path / "gone" / "o.png")    # refused before the render
    argv = {"a file for a folder": ["render", vol_file, "-o", tmp_path / "x.png" / "o.png"],
            "a link into a missing folder": ["render", vol_file, "--iso", 4, "-o", tmp_path / "dangling.png"],
            "a link in a loop": ["info", tmp_path / "loop.nrrd"],
            "a sidecar folder": ["convert", vol_file, "-o", tmp_path / "v.npy"]}[case]
    rc, out, err = _run(argv, capsys)
    assert rc == 2 and err.count("\n") == 1 and words.format(tmp=tmp_path) in err, err
    if case == "a sidecar folder":
        rc, out, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", tmp_path / "v.npy"], capsys)
        assert rc == 2 and err.count("\n") == 1 and words in err and not (tmp_path / "v.npy").exists(), err
    np.save(tmp_path / "v.npy", np.zeros((3, 3, 3), np.float32))
    rc, out, err = _run(["info", tmp_path / "v.npy"], capsys)
    assert rc == 2 and "v.npy.json: the sidecar of v.npy (its spacing and origin) is not a file" in err, err


def test_a_misspelt_flag_is_named_before_a_missing_output(vol_file, capsys):
    # argparse checks required arguments first: "--isovalue 3" without -o was "-o is required".
    rc, _, err = _run(["render", vol_file, "--isovalue", "3"], capsys)
    assert rc == 2 and err.strip() == "parc: error: unrecognized arguments: --isovalue 3", err
    rc, _, err = _run(["render", vol_file, "--sup", "4"], capsys)                  # a prefix argparse takes
    assert rc == 2 and "required: -o/--output" in err, err
    rc, _, err = _run(["make", "sphere", "--colour=red"], capsys)
    assert rc == 2 and "unrecognized arguments: --colour=red" in err, err
    rc, _, err = _run(["render", vol_file, "-O", "x.png"], capsys)                # a short flag too
    assert rc == 2 and "unrecognized arguments: -O x.png" in err, err


@pytest.mark.parametrize("argv, hint", [
    (["render", "V", "--look_at", "1,2,3"], "unrecognized arguments: --look_at 1,2,3; did you mean --look-at?"),
    (["render", "V", "--lookat=1,2,3"], "unrecognized arguments: --lookat=1,2,3; did you mean --look-at?"),
    (["compare", "V", "--metods", "brute"], "unrecognized arguments: --metods brute; did you mean --methods?"),
    (["render", "V", "V"], "; one volume a command: show several with a scene file's [[volume]] tables"),
    (["info", "V", "V"], "; info takes one volume"),
    (["render", "V", "--size", "64,64"], "argument --size: expected 2 arguments (width and height, apart: "
                                         "--size 640 480)"),
    (["render", "V", "--shape", "60", "50", "40"], "--shape: must be 3 integers apart by commas, like 64,64,32"),
])
def test_a_mistaken_argument_gets_a_hint(vol_file, tmp_path, capsys, argv, hint):
    argv = [vol_file if a == "V" else a for a in argv]
    rc, _, err = _run([*argv, "-o", tmp_path / "x.png"] if argv[0] == "render" else argv, capsys)
    assert rc == 2 and err.count("\n") == 1 and hint in err, err
    assert not (tmp_path / "x.png").exists()


def test_a_folder_given_for_a_file_is_called_a_folder(vol_file, tmp_path, capsys):
    # Three messages said "directory", and a transfer function's folder "unknown file type '(none)'".
    for name in ("v.nrrd", "tf", "tf.toml"):
        (tmp_path / name).mkdir()
    cases = [(["info", tmp_path / "v.nrrd"], "v.nrrd: is a folder"),
             (["render", vol_file, "--tf", tmp_path / "tf", "-o", tmp_path / "o.png"], "tf: is a folder, not a file"),
             (["render", vol_file, "--tf", tmp_path / "tf.toml", "-o", tmp_path / "o.png"],
              "tf.toml: is a folder, not a file"),
             (["bench", "--tiny", "--data", vol_file, "--out", tmp_path / "b"], f"--data {vol_file}: not a folder")]
    for argv, words in cases:
        rc, _, err = _run(argv, capsys)
        assert rc == 2 and err.count("\n") == 1 and words in err and "directory" not in err, err


def test_a_closed_pipe_ends_the_command_quietly(vol_file):
    # As `parc info VOLUME | head -0`: the reader is gone before the first line.
    p = subprocess.Popen([sys.executable, "-m", "parc.cli", "info", str(vol_file)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) == 141 and err == ""


def _bad_files(tmp_path):
    """(name, argv maker) for each kind of bad input file."""
    files = {}
    (tmp_path / "garbage.nrrd").write_bytes(bytes(range(256)) * 4)
    files["garbage header"] = tmp_path / "garbage.nrrd"
    (tmp_path / "short.raw").write_bytes(b"\0" * 100)
    files["size mismatch"] = tmp_path / "short_8x8x8_uint8.raw"
    (tmp_path / "short_8x8x8_uint8.raw").write_bytes(b"\0" * 100)
    mhd = tmp_path / "trunc.mhd"
    mhd.write_text("NDims = 3\nDimSize = 8 8 8\nElementType = MET_SHORT\nElementDataFile = trunc.dat\n")
    (tmp_path / "trunc.dat").write_bytes(b"\0" * 600)
    files["truncated data"] = mhd
    np.save(tmp_path / "flat.npy", np.zeros((1, 5, 5), np.float32))
    files["dimension below 2"] = tmp_path / "flat.npy"
    nan = np.zeros((4, 4, 4), np.float32)
    nan[1, 2, 3] = np.nan
    np.save(tmp_path / "nan.npy", nan)
    files["non-finite samples"] = tmp_path / "nan.npy"
    (tmp_path / "vol.xyz").write_bytes(b"\0" * 64)
    files["unknown extension"] = tmp_path / "vol.xyz"
    files["missing file"] = tmp_path / "nope.nrrd"
    return files


BAD_FILE_KINDS = ["garbage header", "size mismatch", "truncated data", "dimension below 2",
                  "non-finite samples", "unknown extension", "missing file"]


@pytest.mark.parametrize("kind", BAD_FILE_KINDS)
def test_bad_volume_files(kind, tmp_path, capsys):
    path = _bad_files(tmp_path)[kind]
    out = tmp_path / "out.png"
    rc, _, err = _run(["render", path, "--iso", 0.5, "-o", out], capsys)
    assert rc == 2
    # The message names the file at fault (a detached header's data file counts).
    assert err.count("\n") == 1 and err.startswith("parc: error: ") and path.stem in err
    assert not out.exists()


@pytest.mark.parametrize("extra, words", [
    (["--iso", 1000], "outside the data range"),
    (["--iso", 4, "--eye", "1,2,3", "--look-at", "1,2,3"], "eye equals look-at"),
    (["--iso", 4, "--eye", "5.5,5.5,40", "--look-at", "5.5,5.5,0", "--up", "0,0,1"], "parallel"),
    (["--iso", 4, "--size", 0, 10], "size"),
    (["--iso", 4, "--size", 10, -3], "size"),
    (["--iso", 4, "--fov", 200], "--fov must be a number of degrees between 0 and 180"),
    (["--iso", 4, "--eye", "1,2"], "--eye"),
    (["--iso", "abc"], "--iso"),
    (["--iso", 4, "--method", "magic"], "method"),
    (["--tf", "greyscale", "--method", "parc", "--buffers", "depth,colour"], "buffers must be depth, bits"),
])
def test_bad_arguments(extra, words, vol_file, tmp_path, capsys):
    out = tmp_path / "out.png"
    rc, _, err = _run(["render", vol_file, "-o", out] + extra, capsys)
    assert rc == 2 and err.count("\n") == 1 and words in err, err
    assert not out.exists()


def test_iso_outside_range_names_the_range(vol_file, tmp_path, capsys):
    rc, _, err = _run(["render", vol_file, "--iso", -1, "-o", tmp_path / "o.png"], capsys)
    d = [float(np.float32(np.sqrt(3 * r ** 2))) for r in (0.5, 5.5)]  # the ball's nearest and farthest samples
    assert rc == 2 and f"[{d[0]!r}, {d[1]!r}]" in err


@pytest.mark.parametrize("target", ["missing_dir/out.png", "out.jpg", "."])
def test_unwritable_outputs(target, vol_file, tmp_path, capsys):
    out = tmp_path / target
    rc, _, err = _run(["render", vol_file, "--iso", 4, "-o", out], capsys)
    assert rc == 2 and err.count("\n") == 1
    assert not (tmp_path / "missing_dir").exists() and not (tmp_path / "out.jpg").exists()


def test_an_image_too_large_for_memory_gets_one_line(vol_file, tmp_path, capsys):
    out = tmp_path / "o.png"
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 10**6, 10**6, "-o", out], capsys)
    assert rc == 2 and err.count("\n") == 1 and "needs about" in err and "--size" in err
    assert not out.exists()


def test_a_bits_buffer_past_what_opengl_maps_is_refused_in_one_line(vol_file, tmp_path, capsys, monkeypatch):
    # 8,630 planes along x at 2048x2048 (4.5 GB of bits) ended in moderngl's "cannot map the
    # buffer" and a traceback. The limit is lowered here to what this small render needs.
    import parc.bitplanes
    out = tmp_path / "o.png"
    argv = ["render", vol_file, "--tf", "viridis", "--buffers", "bits", "--supercell", "0.25,8,8",
            "--eye", "40,5.5,5.5", "--look-at", "5.5,5.5,5.5", "--size", 48, 32, "--method", "parc", "-o", out]
    monkeypatch.setattr(parc.bitplanes, "MAX_BITS_BYTES", 48 * 32 * 8)        # 44 planes: two words
    rc, _, err = _run(argv, capsys)
    assert rc == 0 and out.exists(), err
    out.unlink()
    monkeypatch.setattr(parc.bitplanes, "MAX_BITS_BYTES", 48 * 32 * 8 - 1)
    rc, _, err = _run(argv, capsys)
    assert rc == 2 and err.count("\n") == 1 and not out.exists(), err
    assert re.match(r"parc: error: a bits buffer of 44 planes along x at 48x32 needs 0\.0 GB in one OpenGL buffer, "
                    r"over the 4 GB it can map; use larger supercells along x, a smaller image, or --buffers depth",
                    err), err


def test_running_out_of_memory_gets_one_line(vol_file, tmp_path, capsys, monkeypatch):
    # Whatever allocation fails (a volume, a table), the user sees one line.
    import data_tools.synthetic

    def too_big(*args, **kwargs):
        raise MemoryError("Unable to allocate 931. GiB for an array")
    monkeypatch.setattr(data_tools.synthetic, "make_synthetic", too_big)
    rc, _, err = _run(["make", "sphere", "--size", 16, "-o", tmp_path / "s.nrrd"], capsys)
    assert rc == 1 and err.count("\n") == 1 and "out of memory: Unable to allocate 931. GiB" in err
    assert err.endswith("try a smaller --size\n") and not (tmp_path / "s.nrrd").exists()
    # A supercell far below a cell is the likelier cause where one is given.
    import parc

    monkeypatch.setattr(parc, "render", too_big)
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "--method", "parc", "--supercell", "0.5",
                       "-o", tmp_path / "o.png"], capsys)
    assert rc == 1 and err.endswith("try a smaller --size (or a larger --supercell), or --method brute, which keeps "
                                    "no tables of the volume\n"), err
    # parc's tables grow with the volume: a 1300^3 volume ran out at a 128x128 image, told to shrink it.
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "--method", "parc", "-o", tmp_path / "o.png"],
                      capsys)
    assert rc == 1 and err.endswith("try a smaller --size, or --method brute, which keeps no tables of the volume\n")
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", tmp_path / "o.png"], capsys)
    assert rc == 1 and err.endswith("try a smaller --size\n")              # brute keeps none


def test_a_speedup_below_a_hundredth_keeps_two_digits():
    from parc.comparison import ratio_text
    assert (ratio_text(0.0042), ratio_text(0.01), ratio_text(3.14159), ratio_text(0.0)) == ("0.0042", "0.01", "3.14", "0.00")


def test_a_vector_starting_with_a_minus_sign_is_a_value(vol_file, tmp_path, capsys):
    # As the --help epilog writes it: "--sun -1,1,-1", not only "--sun=-1,1,-1".
    outs = [tmp_path / "a.npy", tmp_path / "b.npy"]
    for out, sun in zip(outs, (["--sun", "-1,1,-1"], ["--sun=-1,1,-1"])):
        rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 12, 10, "--eye", "-20,-30,25",
                           *sun, "-o", out], capsys)
        assert rc == 0, err
    np.testing.assert_array_equal(np.load(outs[0]), np.load(outs[1]))


@pytest.mark.parametrize("extra, words", [
    (["--fov", "0"], "--fov must be a number of degrees"),                   # the default framing divided by sin(0)
    (["--fov", "5e-324"], "field of view"),
    (["--up", "0,0,0"], "is zero"),
    (["--origin", "1e20,0,0"], "2^32 cells"),             # the grid is below float64's resolution there
    (["--method", "brute", "--buffers", "bits"], "--buffers applies to --method parc"),
    (["--method", "parc", "--buffers", "bits"], "--buffers applies to translucent volumes"),
    (["--output-twice"], "out.npy: given to both -o and --depth; each output needs a file of its own"),
    (["--fov", "20", "--parallel", "40"], "not both"),
    (["--threshold", "0"], "--threshold applies to translucent volumes"),     # 0 is given, not absent
    (["--stats", ""], "the output path is empty"),                             # was ".: output must end in"
    # Refused: it would not add a second surface, as it may look, but replace the first (also abbreviated).
    (["--is=5"], "--iso given twice (4 and 5); several surfaces or volumes are shown by a scene file's [[volume]]"),
    (["--tf", "greyscale", "--tf", "viridis"], "--tf given twice (greyscale and viridis)"),
])
def test_more_bad_arguments(extra, words, vol_file, tmp_path, capsys):
    out = tmp_path / "out.npy"
    if extra == ["--output-twice"]:
        extra = ["--depth", str(out)]
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", out] + extra, capsys)
    assert rc == 2 and err.count("\n") == 1 and words in err, err
    assert not out.exists()


@pytest.mark.parametrize("extra, words", [
    (["--mode", "mip", "--shade"], "--shade applies to --mode composite"),
    (["--mode", "average", "--threshold", "0.5"], "--threshold applies to --mode composite"),
    (["--mode", "mip", "--threshold", "0"], "--threshold applies to --mode composite"),
    (["--step", "inf"], "--step must be a positive, finite distance, got inf"),
    (["--step", "0"], "--step must be a positive, finite distance, got 0"),
    (["--threshold", "1.5"], "--threshold must be an opacity in (0, 1], got 1.5"),
    (["--fov", "0"], "--fov must be a number of degrees between 0 and 180, got 0"),
    (["--parallel", "-2"], "--parallel must be positive and finite, got -2"),
    (["--size", "0", "8"], "--size must be two positive integers, got 0 8"),
    (["--step", "1e-300"], "--step 1e-300 is below 1e-4 of the smallest spacing"),
    (["--spacing", "1e-7,1,1"], "the default step 2.5e-08 puts 6.2e+08 samples on a ray across the volume's "
                                "diagonal (15.5563), more than 1e+08: give a step of at least 1.56e-07"),
    (["--spacing", "1e-7,1,1", "--step", "1e-8"], "--step 1e-08 puts"),
    (["--eye", "1e20,0,0", "--parallel", "5"], "--eye: the eye (1e+20, 0.0, 0.0) is over 2^32 times"),
    (["--background", "2,0,0"], "argument --background: components must be in [0, 1], got '2,0,0'"),
])
def test_translucent_flags_that_cannot_apply_are_refused(extra, words, vol_file, tmp_path, capsys):
    out = tmp_path / "o.png"
    rc, _, err = _run(["render", vol_file, "--tf", "greyscale", "--size", 8, 8, "-o", out, *extra], capsys)
    assert rc == 2 and err.count("\n") == 1 and words in err, err
    assert not out.exists()


@pytest.mark.parametrize("command", ["render", "compare"])
@pytest.mark.parametrize("shade", [[], ["--shade"]])
@pytest.mark.parametrize("light", [["--light", "1,2,3"], ["--sun", "0,0,-1", "--shadows"], ["--shadows"]])
def test_lights_on_a_translucent_volume_light_shaded_samples_and_nothing_else(command, shade, light, vol_file,
                                                                            tmp_path, capsys):
    # Lights and shadows light and shadow shaded samples (--shade) and are said to change nothing
    # without them (and --shadows alone then gets no advice to add --light or --sun, which would
    # not make them show; with --shade it does).
    argv = [command, vol_file, "--tf", "greyscale", *shade, "--size", 8, 8]
    out = [["-o", tmp_path / "lit.npy"], ["-o", tmp_path / "unlit.npy"]] if command == "render" else [[], []]
    rc, _, err = _run(argv + light + out[0], capsys)
    lit = ("--light" in light or "--sun" in light)
    said = [w for w, flag in (("lights shine", lit and not shade), ("shadows fall", "--shadows" in light and not shade))
            if flag]
    assert rc == 0 and all(f"parc: {w} on isosurfaces" in err for w in said), err
    assert ("add --light" in err) == (light == ["--shadows"] and bool(shade))
    assert err.count("on isosurfaces") == len(said)
    if command == "render":
        rc, _, err = _run(argv + out[1], capsys)
        assert rc == 0 and "on isosurfaces" not in err
        same = (np.load(tmp_path / "lit.npy") == np.load(tmp_path / "unlit.npy")).all()
        assert same == (not (lit and shade))


def test_an_output_on_the_input_is_refused(tmp_path, capsys):
    vol = tmp_path / "v.npy"
    np.save(vol, np.arange(27, dtype=np.float32).reshape(3, 3, 3))
    rc, _, err = _run(["render", vol, "--iso", 4, "--size", 8, 8, "-o", vol], capsys)
    assert rc == 2 and "is the input file" in err
    assert np.load(vol).shape == (3, 3, 3)


def test_reading_flags_without_a_volume_file_are_refused(tmp_path, capsys):
    rc, _, err = _run(["render", "--size", 8, 8, "--spacing", "2,2,2", "-o", tmp_path / "o.png"], capsys)
    assert rc == 2 and err.count("\n") == 1 and "--spacing applies to a volume file" in err


def test_a_path_the_system_refuses_gets_one_line(vol_file, tmp_path, capsys):
    out = tmp_path / ("a" * 300 + ".png")
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", out], capsys)
    assert rc == 2 and err.count("\n") == 1 and "File name too long" in err


def test_a_failed_write_leaves_no_output_of_the_set(vol_file, tmp_path, capsys, monkeypatch):
    # The depth file cannot be written (disk full): the image written just
    # before it must not be left on its own.
    real_save = np.save

    def save(path, arr, *a, **k):
        if arr.dtype == np.float64:
            raise OSError(28, "No space left on device", str(path))
        return real_save(path, arr, *a, **k)
    monkeypatch.setattr(np, "save", save)
    out, depth = tmp_path / "o.png", tmp_path / "d.npy"
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", out, "--depth", depth], capsys)
    assert rc == 2 and err.count("\n") == 1 and "No space left" in err
    assert list(tmp_path.iterdir()) == [tmp_path / "ball.nrrd"]


@pytest.mark.parametrize("argv, words", [
    (["make", "blobs", "--size", 8, "--seed", -1], "--seed must be 0 or more"),
    (["make", "sphere", "--size", 10**7], "needs about"),
    (["make", "sphere", "--size", 10**400], "needs about over 1e+300 GB of memory"),
    (["make", "floor", "--size", 10**400], "needs about over 1e+300 GB of memory"),
])
def test_make_refuses_what_it_cannot_make(argv, words, tmp_path, capsys):
    out = tmp_path / "m.nrrd"
    rc, _, err = _run(argv + ["-o", out], capsys)
    assert rc == 2 and err.count("\n") == 1 and words in err, err
    assert not out.exists()


@pytest.mark.parametrize("cmd", [["render", "--method", "parc", "-o", "o.png"], ["compare", "--repeats", 1]])
def test_an_image_past_the_opengl_limit_is_refused_alone(cmd, vol_file, tmp_path, capsys, gl_context):
    # No --iso: refused in the render, the limit would come after the level's note, and for
    # compare after brute's warm-up.
    argv = [cmd[0], vol_file, "--size", 100000, 1] + [tmp_path / a if a == "o.png" else a for a in cmd[1:]]
    rc, _, err = _run(argv, capsys)
    assert rc == 2 and err.count("\n") == 1 and "exceeds this OpenGL's limit" in err, err
    assert list(tmp_path.iterdir()) == [tmp_path / "ball.nrrd"]


@pytest.mark.parametrize("size", [[10**400, 8], [8, 10**400]])
@pytest.mark.parametrize("scene", [False, True])
def test_a_size_past_float_range_is_refused_in_one_line(size, scene, vol_file, tmp_path, capsys):
    src = vol_file
    if scene:
        src = tmp_path / "s.toml"
        src.write_text(f'[[volume]]\nfile = "{Path(vol_file).as_posix()}"\niso = 4\n')
    out = tmp_path / "o.png"
    for argv in (["render", src, "--iso", 4, "-o", out], ["compare", src, "--iso", 4, "--repeats", 1]):
        argv = [a for a in argv if not (scene and a in ("--iso", 4))]
        rc, _, err = _run(argv + ["--size", *size], capsys)
        assert rc == 2 and err.count("\n") == 1 and "needs about" in err, err
        assert not out.exists()


def test_pipes_are_refused_not_read(vol_file, tmp_path, capsys):
    import os
    if not hasattr(os, "mkfifo"):
        pytest.skip("no named pipes here")
    for name in ("scene.toml", "tf.toml", "data.raw"):
        os.mkfifo(tmp_path / name)
    (tmp_path / "h.nhdr").write_text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n"
                                     "data file: data.raw\n")
    out = tmp_path / "o.png"
    for argv in (["render", tmp_path / "scene.toml"], ["render", vol_file, "--tf", tmp_path / "tf.toml"],
                 ["render", tmp_path / "h.nhdr", "--iso", 1]):
        rc, _, err = _run(argv + ["--size", 8, 8, "-o", out], capsys)
        assert rc == 2 and "not a regular file" in err, err


def test_a_byte_order_mark_is_read_past(vol_file, tmp_path, capsys):
    tf = tmp_path / "tf.toml"
    tf.write_bytes(b"\xef\xbb\xbfopacity = [[0, 0], [6, 1]]\n")
    rc, _, err = _run(["render", vol_file, "--tf", tf, "--size", 8, 8, "-o", tmp_path / "o.png"], capsys)
    assert rc == 0, err


def test_console_script_prints_no_traceback(tmp_path):
    out = tmp_path / "o.png"
    p = subprocess.run([sys.executable, "-m", "parc.cli", "render", str(tmp_path / "nothing.nrrd"), "-o", str(out)],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "Traceback" not in p.stderr and p.stderr.startswith("parc: error:")
    assert not out.exists()


def test_render_translucent(vol_file, tmp_path, capsys):
    out = tmp_path / "t.png"
    rc, _, err = _run(["render", vol_file, "--tf", "viridis", "--mode", "mip", "--size", 20, 16, "-o", out,
                       "--method", "parc"], capsys)
    assert rc == 0, err
    assert "samples" in err and np.asarray(Image.open(out))[..., 3].max() > 0


def test_render_translucent_depth_is_inf_and_background_fills_the_rest(vol_file, tmp_path, capsys):
    # A translucent volume has no opaque hit (the README's --depth); the background shows
    # where the volume is transparent, composited under it.
    out, depth = tmp_path / "t.npy", tmp_path / "d.npy"
    rc, _, err = _run(["render", vol_file, "--tf", "greyscale", "--size", 20, 16, "-o", out, "--depth", depth,
                       "--background", "0.2,0.4,0.6"], capsys)
    assert rc == 0, err
    assert np.isposinf(np.load(depth)).all()
    image = np.load(out)
    assert np.allclose(image[..., 3], 1.0)                 # an opaque background behind every pixel
    corner = image[0, 0]
    np.testing.assert_allclose(corner, [0.2, 0.4, 0.6, 1.0], atol=1e-6)     # no volume there
    rc, _, err = _run(["render", vol_file, "--iso", 4.0, "--size", 20, 16, "-o", out, "--background", "0.2,0.4,0.6"],
                      capsys)
    image = np.load(out)
    assert rc == 0 and (image[..., 3] == 1.0).all()
    missed = np.all(np.abs(image - [0.2, 0.4, 0.6, 1.0]) <= 1e-6, axis=-1)
    assert 0 < missed.sum() < missed.size, "the background shows around the surface, not over it"


@pytest.mark.parametrize("content, words", [
    ("opacity = [[1, 0.5], [0, 0.2]]\n", "ascend"),
    ("opacity = [[0, 1.5]]\n", "opacity"),
    ("colour = [[0, 1, 1, 1]]\nopacity = [[0, 0.1]]\n", "colour"),
    ("opacity = [[0, 0.1]\n", "bad.toml"),
])
def test_bad_transfer_function_files(content, words, vol_file, tmp_path, capsys):
    tf = tmp_path / "bad.toml"
    tf.write_text(content)
    out = tmp_path / "t.png"
    rc, _, err = _run(["render", vol_file, "--tf", tf, "-o", out], capsys)
    assert rc == 2 and err.count("\n") == 1 and words in err and "bad.toml" in err, err
    assert not out.exists()


def test_tf_and_iso_together_are_refused(vol_file, tmp_path, capsys):
    rc, _, err = _run(["render", vol_file, "--tf", "greyscale", "--iso", 3, "-o", tmp_path / "t.png"], capsys)
    assert rc == 2 and "not both" in err


def test_compare_prints_a_table(vol_file, capsys):
    rc, out, err = _run(["compare", vol_file, "--iso", 4, "--size", 16, 16, "--repeats", 1], capsys)
    assert rc == 0, err
    assert "brute" in out and "parc" in out and "speedup" in out and "OpenGL" in out
    # One round: the round's ratio is the speedup itself.
    rc, out, err = _run(["compare", vol_file, "--iso", 4, "--size", 16, 16, "--repeats", 1, "--json"], capsys)
    def strict(constant):
        raise ValueError(f"not strict JSON: {constant}")
    parc_row = json.loads(out, parse_constant=strict)[1]
    assert parc_row["speedup_low"] == parc_row["speedup_high"] == pytest.approx(parc_row["speedup"])
    assert parc_row["hit_mismatches"] == 0 and parc_row["psnr"] is None   # identical: infinite PSNR


def test_compare_json_rows_say_what_was_compared(vol_file, tmp_path, capsys):
    # Saved from several runs, rows without the volume, level, size and view could not be told apart.
    rc, out, err = _run(["compare", vol_file, "--iso", 4, "--size", 16, 12, "--repeats", 2, "--json",
                         "--eye", "30,20,10"], capsys)
    assert rc == 0, err
    rc2, _, err = _run(["render", vol_file, "--iso", 4, "--size", 16, 12, "--eye", "30,20,10",
                        "-o", tmp_path / "r.png", "--stats", tmp_path / "r.json"], capsys)
    assert rc2 == 0, err
    rendered = json.loads((tmp_path / "r.json").read_text())["parameters"]
    for row in json.loads(out):
        assert row["repeats"] == 2 and row["parameters"] == rendered
        assert row["parameters"]["isovalue"] == 4.0 and row["parameters"]["size"] == [16, 12]
        assert row["parameters"]["camera"]["eye"] == [30.0, 20.0, 10.0]
        assert row["parameters"]["volume"] == str(vol_file)


@pytest.mark.parametrize("look, count", [(["--iso", 4.0], "cells_visited"),
                                         (["--tf", "greyscale", "--no-blocks"], "samples")])
def test_compare_draws_the_work_of_each_method_it_timed(look, count, vol_file, tmp_path, capsys, monkeypatch, gl):
    # Each map is a render's with the options compare timed it with: each map's sum is its own
    # row's count. A surface's two sweep sizes visit different numbers of cells; a translucent
    # volume's take the same samples, but more than a render with the skip tables would
    # (--no-blocks), so options left out of the maps' renders change their sums either way.
    heatmaps = importlib.import_module("parc.bench.heatmaps")
    draw = heatmaps.work_heat_maps
    drawn = {}

    def recording(path, maps, what, where):
        drawn.update(maps)
        return draw(path, maps, what, where)
    monkeypatch.setattr(heatmaps, "work_heat_maps", recording)
    pic = tmp_path / "w.png"
    rc, out, err = _run(["compare", vol_file, *look, "--size", 20, 16, "--repeats", 1, "--json",
                         "--sweep-supercell", "1,3", "--work", pic], capsys)
    assert rc == 0, err
    rows = {row["method"]: row for row in json.loads(out)}
    assert list(drawn) == ["brute", "parc:1", "parc:3"]
    for name, work in drawn.items():
        assert work.shape == (16, 20) and work.sum() == rows[name][count] > 0, name
    if count == "cells_visited":
        assert rows["parc:1"][count] != rows["parc:3"][count]
    assert f"wrote {pic}: the work per pixel of brute, parc:1, parc:3" in err
    with Image.open(pic) as im:
        assert im.format == "PNG"


@pytest.mark.parametrize("extra, words", [
    (["--tf", "greyscale", "--sweep-step", "1,0.5"], "--work draws the work of compare's methods side by side; "
                                                     "it is not for --sweep-step"),
    (["--iso", 4.0, "--work", "w.npy"], "output must end in .png"),
    (["--iso", 4.0, "--work", "link.png"], "is the input file"),
    (["--scene"], "--work: per-pixel work counts cells visited for isosurfaces and samples taken for "
                  "translucent volumes, and this scene has both"),
])
def test_compare_refuses_work_it_cannot_draw_before_any_render(extra, words, vol_file, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "link.png").symlink_to(vol_file)      # the volume read, under another name
    source = vol_file
    if extra == ["--scene"]:
        source = tmp_path / "scene.toml"
        source.write_text(f"size = [8, 8]\n[[volume]]\nfile = '{vol_file.name}'\niso = 4.0\n"
                          f"[[volume]]\nfile = '{vol_file.name}'\ntf = 'greyscale'\n")
        extra = []
    monkeypatch.setattr(importlib.import_module("parc.comparison"), "render", lambda *a, **k: pytest.fail("rendered"))
    argv = ["compare", source, "--size", 8, 8, "--repeats", 1, *extra]
    if "--work" not in argv:
        argv += ["--work", "w.png"]
    rc, out, err = _run(argv, capsys)
    assert rc == 2 and err.count("\n") == 1 and words in err, err
    assert not out and sorted(p.name for p in tmp_path.iterdir() if p.suffix in (".png", ".npy")) == ["link.png"]
    assert (tmp_path / "link.png").resolve() == vol_file.resolve() and load_volume(vol_file).data.shape == (12, 12, 12)


@pytest.mark.parametrize("extra", [[], ["--sweep-supercell", "2,4"], ["--work", "w.png"]])
def test_compare_names_its_buffers_flag_when_a_scene_refuses_it(extra, vol_file, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scene.toml").write_text(f"size = [8, 8]\n[[volume]]\nfile = '{vol_file}'\niso = 4.0\n"
                                         f"[[volume]]\nfile = '{vol_file}'\ntf = 'greyscale'\n")
    rc, _, err = _run(["compare", "scene.toml", "--repeats", 1, "--buffers", "bits", *extra], capsys)
    assert rc == 2 and err.count("\n") == 1, err
    assert err.startswith("parc: error: --buffers bits leave out the depth buffers") and "give --buffers" in err, err


def test_compare_quiet_keeps_stderr_empty(vol_file, capsys):
    base = ["compare", vol_file, "--iso", 4, "--size", 12, 12, "--repeats", 1]
    rc, out, err = _run(base, capsys)
    assert rc == 0 and "warming up" in err
    for extra in ([], ["--sweep-supercell", "1,2"]):
        rc, out, err = _run(base + extra + ["--quiet"], capsys)
        assert rc == 0 and err == "" and "speedup" in out


def test_a_supercell_sweep_says_what_its_labels_mean(vol_file, capsys):
    rc, out, err = _run(["compare", vol_file, "--iso", 4, "--size", 8, 8, "--repeats", 1, "--quiet",
                         "--sweep-supercell", "1;2,2,4"], capsys)
    lines = out.splitlines()
    assert rc == 0, err
    assert [line.split()[0] for line in lines[3:6]] == ["brute", "parc:1", "parc:2x2x4"]
    notes = [line for line in lines if line.startswith("parc:S: ")]
    assert len(notes) == 1 and "supercells of S cells a side (SxTxU: S by T by U cells)" in notes[0]
    # Below the rows and their legend, above the seconds per phase.
    assert lines.index(notes[0]) < lines.index("")
    rc, out, _ = _run(["compare", vol_file, "--iso", 4, "--size", 8, 8, "--repeats", 1, "--quiet"], capsys)
    assert rc == 0 and "parc:S: " not in out


def test_every_phase_a_render_reports_is_explained_under_the_table():
    from data_tools.synthetic import blobs
    from parc import Camera, Isosurface, PointLight, Scene, Translucent, compare
    from parc.comparison import PHASE_NOTES, format_table
    vol = blobs(16, seed=2)
    mid = float(vol.data.mean())
    cam = Camera.framing(*vol.bounds)
    scenes = [Scene(camera=cam, size=(12, 12), volumes=[Isosurface(vol, mid)]),
              Scene(camera=cam, size=(12, 12), volumes=[Translucent(vol, "greyscale")]),
              Scene(camera=cam, size=(12, 12), volumes=[Isosurface(vol, mid), Translucent(vol, "greyscale")],
                    lights=[PointLight(position=(40.0, -30.0, 50.0))], shadows=True)]
    for scene in scenes:
        # Bit planes: their phase is explained too (drawn for the lone translucent volume; among
        # several volumes they would compile a merged walk of their own for this alone).
        bits = len(scene.volumes) == 1 and isinstance(scene.volumes[0], Translucent)
        rows = compare(scene, repeats=1, warmup=0, options={"parc": {"buffers": "depth,bits"} if bits else {}})
        table = format_table(rows)
        for phase in rows[1]["phases"]:
            assert phase in PHASE_NOTES and f"  {phase}: {PHASE_NOTES[phase]}" in table


@pytest.mark.parametrize("extra", [["--supercell", "0.001"], ["--sweep-supercell", "1,0.001"]])
def test_compare_refuses_a_supercell_before_warming_up(extra, vol_file, capsys):
    rc, _, err = _run(["compare", vol_file, "--iso", 4, "--size", 8, 8, "--repeats", 1] + extra, capsys)
    assert rc == 2 and err.count("\n") == 1 and "supercell size 0.001" in err, err


def test_a_ctrl_c_while_the_outputs_move_in_says_they_were_written(vol_file, tmp_path, monkeypatch, capsys):
    # The Ctrl-C is held until every output is in place, then acted on: "interrupted" alone, with
    # status 130, read as if the earlier image and stats had been kept.
    import signal
    out, stats = tmp_path / "a.png", tmp_path / "a.json"
    render = ["render", vol_file, "--iso", 4, "-o", out, "--stats", stats, "--quiet", "--size"]
    assert _run(render + [8, 8], capsys)[0] == 0
    earlier = out.read_bytes()
    replace = os.replace

    def ctrl_c_at_the_first(a, b):
        monkeypatch.setattr(os, "replace", replace)
        os.kill(os.getpid(), signal.SIGINT)
        replace(a, b)
    monkeypatch.setattr(os, "replace", ctrl_c_at_the_first)
    # Python's own handler, as at a terminal: a suite started in the background ignores SIGINT,
    # and so, rightly, would parc.
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        rc, _, err = _run(render + [12, 12], capsys)
    finally:
        signal.signal(signal.SIGINT, before)
    assert rc == 130 and err == f"parc: interrupted; {out}, {stats} had been written whole\n"
    assert out.read_bytes() != earlier and json.loads(stats.read_text())["parameters"]["size"] == [12, 12]
    from data_tools.signals import done_before_stop
    assert done_before_stop() == ""             # said once: a later interruption is its own


def test_notes_are_held_back_when_the_render_refuses(vol_file, tmp_path, capsys):
    # The note on the chosen level waits for the render: a supercell refused there is the only line.
    rc, _, err = _run(["render", vol_file, "--size", 8, 8, "--method", "parc", "--supercell", "0.001",
                       "-o", tmp_path / "o.png"], capsys)
    assert rc == 2 and err.count("\n") == 1 and "supercell size 0.001" in err, err


@pytest.mark.parametrize("flag, value, words", [("--supercell", "-2,2,2", "supercell size must be"),
                                                ("--background", "-1,0,0", "background"),
                                                ("--sweep-supercell", "-1,2", "--sweep-supercell")])
def test_negative_values_reach_their_checks(flag, value, words, vol_file, tmp_path, capsys):
    cmd = "compare" if flag.startswith("--sweep") else "render"
    out = [] if cmd == "compare" else ["-o", tmp_path / "o.png"]
    rc, _, err = _run([cmd, vol_file, "--iso", 4, "--size", 8, 8, flag, value] + out, capsys)
    assert rc == 2 and err.count("\n") == 1 and words in err and "expected one argument" not in err, err


def test_notes_are_held_back_when_the_scene_is_refused(vol_file, tmp_path, capsys):
    # Without --iso a note names the level chosen; with a bad camera the error is the only line.
    rc, _, err = _run(["render", vol_file, "--size", 8, 8, "--up", "0,0,0", "-o", tmp_path / "o.png"], capsys)
    assert rc == 2 and err.count("\n") == 1 and "is zero" in err, err
    rc, _, err = _run(["render", vol_file, "--size", 8, 8, "-o", tmp_path / "o.png"], capsys)
    assert rc == 0 and "no --iso given" in err


@pytest.mark.parametrize("cmd", ["render", "compare"])
def test_notes_come_before_the_rendering_starts(cmd, vol_file, tmp_path, monkeypatch, capsys):
    # A note can tell the user the render is not the one wanted; it is no use after the wait.
    import parc
    import parc.comparison
    said = []
    module = parc if cmd == "render" else parc.comparison
    real = module.render

    def render(*args, **kwargs):
        said.append(capsys.readouterr().err)
        return real(*args, **kwargs)

    monkeypatch.setattr(module, "render", render)
    out = ["-o", tmp_path / "o.png"] if cmd == "render" else ["--repeats", 1]
    rc, _, err = _run([cmd, vol_file, "--size", 8, 8] + out, capsys)
    assert rc == 0 and said and "no --iso given" in said[0], (said, err)
    assert "no --iso given" not in err


@pytest.mark.parametrize("cmd", ["info", "convert", "render", "compare"])
def test_reading_a_slow_volume_is_said_before_and_after(cmd, vol_file, tmp_path, monkeypatch, capsys):
    # A large file read in silence for half a minute looked like a hang.
    import parc.outputs
    monkeypatch.setattr(parc.outputs, "SLOW_NOTE_DELAY", 0.0)
    extra = {"info": [], "convert": ["-o", tmp_path / "c.nrrd"], "render": ["--iso", 4, "-o", tmp_path / "r.png"],
             "compare": ["--iso", 4, "--repeats", 1]}[cmd]
    rc = main([cmd, str(vol_file)] + [str(a) for a in extra] + (["--size", "8", "8"] if cmd in ("render", "compare") else []))
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert rc == 0 and f"parc: reading {vol_file} ..." in lines, err
    done = [line for line in lines if re.fullmatch(rf"parc: reading {re.escape(str(vol_file))}: done in [\d.]+ s", line)]
    assert len(done) == 1 and lines.index(done[0]) > lines.index(f"parc: reading {vol_file} ..."), err


@pytest.mark.parametrize("cmd", ["convert", "make"])
def test_writing_a_slow_volume_is_said_before_and_after(cmd, vol_file, tmp_path, monkeypatch, capsys):
    # Compressing a 640^3 volume took 13 s after the last word.
    import parc.outputs
    monkeypatch.setattr(parc.outputs, "SLOW_NOTE_DELAY", 0.0)
    out = tmp_path / "w.nrrd"
    argv = ["convert", str(vol_file), "-o", str(out)] if cmd == "convert" else ["make", "sphere", "--size", "6",
                                                                                 "-o", str(out)]
    rc = main(argv)
    lines = capsys.readouterr().err.splitlines()
    assert rc == 0 and f"parc: writing {out} ..." in lines, lines
    assert any(re.fullmatch(rf"parc: writing {re.escape(str(out))}: done in [\d.]+ s", line) for line in lines), lines


def test_slow_work_that_fails_leaves_its_error_line_to_say_the_rest(tmp_path, monkeypatch, capsys):
    import parc.outputs
    monkeypatch.setattr(parc.outputs, "SLOW_NOTE_DELAY", 0.0)
    (tmp_path / "bad.nrrd").write_bytes(b"NRRD0004\nsizes: 2 2\n\n")
    rc = main(["info", str(tmp_path / "bad.nrrd")])
    err = capsys.readouterr().err
    assert rc == 2 and "done in" not in err and err.splitlines()[-1].startswith("parc: error:"), err


def test_the_level_chosen_pasted_back_gives_the_same_image(tmp_path, capsys):
    # Levels near 1e9 (int32 samples), where six digits are not the level.
    k, j, i = np.mgrid[0:10, 0:10, 0:10]
    ball = (((i - 4.5) ** 2 + (j - 4.5) ** 2 + (k - 4.5) ** 2) ** 0.5 * 2.1e8 + 12345).astype(np.int32)
    vol = save_volume(Volume(ball), tmp_path / "deep.nrrd")
    rc, _, err = _run(["render", vol, "--size", 16, 16, "-o", tmp_path / "a.npy"], capsys)
    level = re.search(r"no --iso given; using (\S+),", err).group(1)
    rc2, _, err2 = _run(["render", vol, "--size", 16, 16, "--iso", level, "-o", tmp_path / "b.npy"], capsys)
    assert rc == rc2 == 0, err + err2
    a, b = np.load(tmp_path / "a.npy"), np.load(tmp_path / "b.npy")
    assert a[..., 3].any() and np.array_equal(a, b)


def test_supercell_sweep_takes_sizes_per_axis(vol_file, capsys):
    rc, out, err = _run(["compare", vol_file, "--iso", 4, "--size", 12, 12, "--repeats", 1, "--json",
                         "--sweep-supercell", "1,2,3;2"], capsys)
    assert rc == 0, err
    rows = json.loads(out)
    assert [r["method"] for r in rows] == ["brute", "parc:1x2x3", "parc:2"]
    assert all(r["hit_mismatches"] == 0 for r in rows)
    # One such size alone, by a trailing ';' (without it, "2,2,4" is three sizes, 2 twice).
    rc, out, err = _run(["compare", vol_file, "--iso", 4, "--size", 12, 12, "--repeats", 1, "--json",
                         "--sweep-supercell", "2,2,4;"], capsys)
    assert rc == 0 and [r["method"] for r in json.loads(out)] == ["brute", "parc:2x2x4"], err


@pytest.mark.parametrize("extra, words", [
    (["--sweep-supercell", ""], "--sweep-supercell"),
    (["--sweep-step", ""], "--sweep-step must be"),
    (["--sweep-step", "nan"], "--sweep-step must be"),
    (["--sweep-step", "1", "--sweep-supercell", "2"], "not both"),
    (["--sweep-supercell", "1,2", "--supercell", "3"], "--supercell does not combine"),
    (["--sweep-supercell", "1,2", "--methods", "parc:a"], "--methods does not combine"),
    (["--sweep-step", "1", "--methods", "brute"], "--methods does not combine"),
    (["--methods", "brute,parc:"], "--methods: 'parc:' has an empty label"),
    (["--methods", "parc:,parc:"], "--methods: 'parc:' has an empty label"),      # not "named twice"
    (["--methods", "brute,magic"], "--methods: unknown method 'magic'"),
    (["--sweep-step", "1e-4"], "reference step"),
    (["--sweep-supercell", "4,4.0"], "--sweep-supercell gives 4 twice; sizes of M,N,P cells are apart by ';'"),
    (["--sweep-supercell", "2;2.0;"], "--sweep-supercell gives 2 twice\n"),
    (["--sweep-supercell", "2;;4"], "--sweep-supercell"),
    (["--sweep-supercell", "2,2,2;2"], "--sweep-supercell gives 2 twice\n"),
    (["--sweep-step", "1,0.5,0.50"], "--sweep-step gives 0.5 twice"),
    (["--methods", "brute,brute"], "--methods names 'brute' twice"),
    (["--methods", "parc:a,parc:a"], "--methods names 'parc:a' twice"),
    (["--methods", ""], "--methods names no method"),
    (["--methods", ","], "--methods names no method"),
    (["--methods", "brute,,parc"], "--methods 'brute,,parc' has an empty name between commas"),
    (["--methods", "parc,"], "--methods 'parc,' has an empty name between commas"),
    (["--methods", "brute, ,parc"], "--methods 'brute, ,parc' has an empty name between commas"),
    (["--methods", " "], "--methods names no method, got ' '; name some"),
])
def test_bad_sweeps_are_refused_before_any_work(extra, words, vol_file, capsys):
    rc, out, err = _run(["compare", vol_file, "--tf", "greyscale", "--size", 8, 8, "--repeats", 1] + extra, capsys)
    # (A run that finds the kernels uncached says so first: some refusals need the scene.)
    err = "".join(line for line in err.splitlines(keepends=True) if "compiling the ray casters" not in line)
    assert rc == 2 and err.count("\n") == 1 and words in err, err


def test_a_step_sweep_says_it_replaces_a_scene_files_step(tmp_path, capsys):
    # --step with --sweep-step is refused; the file's step went unsaid.
    scene = tmp_path / "s.toml"
    scene.write_text('[[volume]]\nsynthetic = "blobs"\nsize = 8\ntf = "greyscale"\nstep = 0.5\n')
    rc, _, err = _run(["compare", scene, "--sweep-step", "1,0.5", "--size", 8, 8, "--repeats", 1], capsys)
    assert rc == 0 and f"the step sweep replaces volume[1]'s step 0.5 from {scene}" in err, err
    scene.write_text('[[volume]]\nsynthetic = "blobs"\nsize = 8\ntf = "greyscale"\n')
    rc, _, err = _run(["compare", scene, "--sweep-step", "1,0.5", "--size", 8, 8, "--repeats", 1], capsys)
    assert rc == 0 and "replaces" not in err, err


@pytest.mark.parametrize("methods", ["parc,brute", "brute,parc", "parc"])
def test_a_sweep_takes_methods_that_name_what_it_runs(methods, vol_file, capsys):
    # brute always runs, and the order is not the user's to get right.
    rc, out, err = _run(["compare", vol_file, "--iso", 4, "--size", 8, 8, "--repeats", 1, "--json",
                         "--methods", methods, "--sweep-supercell", "2"], capsys)
    assert rc == 0, err
    assert [r["method"] for r in json.loads(out)] == ["brute", "parc:2"]


def test_compare_json_and_step_sweep(vol_file, capsys):
    rc, out, err = _run(["compare", vol_file, "--tf", "greyscale", "--size", 12, 12, "--repeats", 1,
                         "--sweep-step", "1,0.5", "--json"], capsys)
    assert rc == 0, err
    rows = json.loads(out)
    assert [r["step"] for r in rows] == [1.0, 0.5] and all(r["parc_vs_brute"] == 0 for r in rows)
    assert rows[1]["brute_samples"] > rows[0]["brute_samples"] > 0
    assert [(r["parameters"]["step"], r["parameters"]["transfer_function"], r["repeats"]) for r in rows] == \
        [(1.0, "greyscale", 1), (0.5, "greyscale", 1)]
    # The table says what it measured, as compare's own table does, and against which reference.
    rc, out, err = _run(["compare", vol_file, "--tf", "greyscale", "--size", 12, 12, "--repeats", 1,
                         "--sweep-step", "1,0.5"], capsys)
    lines = out.splitlines()
    assert rc == 0 and lines[0].startswith(f"{vol_file}: ") and "composite of greyscale, 12x12 pixels" in lines[0]
    assert [line.split()[0] for line in lines[2:4]] == ["1", "0.5"] and "at step 0.125" in lines[4], out


@pytest.mark.parametrize("extra, parc_options", [
    (["--sweep-step", "1"], {"buffers": ("depth", "bits"), "blocks": False}),
    (["--sweep-step", "1", "--supercell", "3"],
     {"buffers": ("depth", "bits"), "blocks": False, "supercell": (3.0, 3.0, 3.0)}),
    (["--methods", "brute,parc:a,parc:b", "--supercell", "3"],
     {"buffers": ("depth", "bits"), "blocks": False, "supercell": (3.0, 3.0, 3.0)}),
])
def test_compare_gives_parc_flags_to_every_parc_run(extra, parc_options, vol_file, capsys, monkeypatch, gl):
    # Every render compare times, with the options it was given; brute gets none.
    compare_module = sys.modules["parc.comparison"]
    render = compare_module.render
    calls = []

    def recording(scene, method="brute", **kw):
        calls.append((method, kw))
        return render(scene, method=method, **kw)
    monkeypatch.setattr(compare_module, "render", recording)
    rc, _, err = _run(["compare", vol_file, "--tf", "greyscale", "--size", 8, 8, "--repeats", 1,
                       "--buffers", "depth,bits", "--no-blocks", "--json", *extra], capsys)
    assert rc == 0, err
    assert {m for m, _ in calls} == {"brute", "parc"}
    for method, kw in calls:
        kw = {k: (tuple(v) if isinstance(v, (list, tuple)) else v) for k, v in kw.items()}
        if "supercell" in kw and not isinstance(kw["supercell"], tuple):
            kw["supercell"] = (float(kw["supercell"]),) * 3
        assert kw == (parc_options if method == "parc" else {}), (method, kw)


def test_step_sweep_times_its_methods_in_turns(vol_file, capsys, monkeypatch, gl):
    # As compare does: all of brute's runs before parc's would let the machine's drift into the ratio.
    compare_module = importlib.import_module("parc.comparison")
    render = compare_module.render
    calls = []

    def recording(scene, method="brute", **kw):
        calls.append((scene.volumes[0].step, method))
        return render(scene, method=method, **kw)
    monkeypatch.setattr(compare_module, "render", recording)
    rc, _, err = _run(["compare", vol_file, "--tf", "greyscale", "--size", 8, 8, "--repeats", 3,
                       "--sweep-step", "1", "--json"], capsys)
    assert rc == 0, err
    assert calls[0] == (0.25, "brute")          # the reference, at a quarter of the finest step
    assert [m for _, m in calls[1:]] == ["brute", "parc"] * (1 + 3) and {st for st, _ in calls[1:]} == {1.0}


def test_supercell_sizes_that_print_alike_keep_rows_of_their_own(vol_file, capsys, gl):
    rc, out, err = _run(["compare", vol_file, "--iso", 4, "--size", 8, 8, "--repeats", 1,
                         "--sweep-supercell", "4,4.0000001", "--json"], capsys)
    assert rc == 0, err
    assert [r["method"] for r in json.loads(out)] == ["brute", "parc:4", "parc:4.0000001"]


@pytest.mark.parametrize("look", [["--iso", 4], ["--tf", "greyscale", "--buffers", "depth,bits"]])
def test_supercell_sweep_times_no_proxy_builds(vol_file, capsys, gl, look):
    # The sweep's methods take turns repeat by repeat: each size's proxy
    # must outlive the other sizes' frames, or every timed frame rebuilds it.
    sizes = [1, 1.5, 2, 3, 4, 6]
    rc, out, err = _run(["compare", vol_file, *look, "--size", 16, 16, "--repeats", 2,
                         "--sweep-supercell", ",".join(map(str, sizes)), "--json"], capsys)
    assert rc == 0, err
    rows = json.loads(out)
    assert [r["method"] for r in rows] == ["brute"] + [f"parc:{s:g}" for s in sizes]
    assert all(r["hit_mismatches"] == 0 and r["max_color"] <= 1e-6 for r in rows)
    assert [r["phases"]["proxy"] for r in rows[1:]] == [0.0] * len(sizes)
    assert rows[0]["speedup_low"] == rows[0]["speedup_high"] == 1.0
    assert all(0.0 < r["speedup_low"] <= r["speedup_high"] for r in rows)
    # The OpenGL share is the OpenGL passes' part of the same run's phases.
    assert rows[0]["opengl_share"] == 0.0
    for r in rows[1:]:
        ph = r["phases"]
        gl = ph["raster"] + ph.get("raster_bits", 0.0)
        assert 0.0 < r["opengl_share"] < 1.0 and r["opengl_share"] == pytest.approx(gl / ph["total"])


def test_outputs_are_ordinary_files(vol_file, tmp_path, capsys):
    import os
    import stat
    out = tmp_path / "p.png"
    old = os.umask(0o022)
    try:
        rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", out], capsys)
    finally:
        os.umask(old)
    assert rc == 0, err
    assert stat.S_IMODE(out.stat().st_mode) == 0o644


def test_a_cache_folder_that_cannot_be_written_is_named(vol_file, tmp_path, capsys, monkeypatch):
    import raycast.kernel_cache
    monkeypatch.setattr(raycast.kernel_cache, "_REFUSED", str(tmp_path / "a file" / "cache"))
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", tmp_path / "a.png"], capsys)
    assert rc == 0 and "cannot be written, so every run compiles them again" in err, err


def test_a_first_run_says_the_casters_compile(vol_file, tmp_path, capsys, monkeypatch):
    """With no compiled kernel cached for these sources, render says why its progress is late; once one is, not."""
    import numba.core.config

    import raycast.kernel_cache  # noqa: F401 - first, or its import sets the folder patched here
    from raycast.iso import cast_iso_image
    own = Path(cast_iso_image._cache._cache_file._index_path)        # as Numba reads it, in the folder given
    empty = tmp_path / "cache"
    (empty / own.parent.name).mkdir(parents=True)     # Numba makes its folders before it compiles anything
    monkeypatch.setattr(numba.core.config, "CACHE_DIR", str(empty))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(empty))  # Numba reloads its config from the environment
    render = ["render", vol_file, "--iso", 4, "--size", 8, 8, "-o"]
    rc, _, err = _run(render + [tmp_path / "a.png"], capsys)
    assert rc == 0 and "compiling the ray casters for this kind of render and sample type, once" in err
    index = empty / own.parent.name / own.name
    index.write_bytes(b"")
    rc, _, err = _run(render + [tmp_path / "b.png"], capsys)
    assert rc == 0 and err and "compiling" not in err
    # Another kind of render compiles casters of its own, and says so too.
    rc, _, err = _run(["render", vol_file, "--tf", "greyscale", "--size", 8, 8, "-o", tmp_path / "t.png"], capsys)
    assert rc == 0 and "compiling the ray casters for this kind of render and sample type, once" in err
    index.unlink()
    rc, _, err = _run(render + [tmp_path / "c.png", "--quiet"], capsys)
    assert rc == 0 and err == ""


def test_a_render_that_compiles_says_how_much_of_its_time_compiling_took(vol_file, tmp_path, capsys, monkeypatch):
    """A first run's line gave 16 s for a render that takes 0.4 s once its casters are compiled."""
    import numba

    import parc.cli
    real = parc.render
    fresh = []

    def render_compiling(*args, **kwargs):
        if not fresh:           # Numba compiles a function made here on its first call, as a first run does
            fresh.append(numba.njit(lambda x: x + 1))
            fresh[0](1)
        return real(*args, **kwargs)

    monkeypatch.setattr(parc, "render", render_compiling)
    monkeypatch.setattr(parc.cli, "COMPILE_SAID", 1e-9)      # the lambda compiles in well under the bar
    render = ["render", vol_file, "--iso", 4, "--size", 8, 8, "-o"]
    for n, compiles in enumerate((True, False)):
        rc, _, err = _run(render + [tmp_path / f"{n}.png"], capsys)
        assert rc == 0 and bool(re.search(r" s, [0-9,]+ cells| s \([0-9.]+ s of it compiling the casters, once\), "
                                          r"[0-9,]+ cells", err)), err
        assert ("of it compiling" in err) == compiles, err
    # Where the cache cannot be written, every run compiles again: not "once".
    import raycast.kernel_cache
    monkeypatch.setattr(raycast.kernel_cache, "_REFUSED", str(tmp_path / "a file" / "cache"))
    fresh.clear()
    rc, _, err = _run(render + [tmp_path / "2.png"], capsys)
    assert rc == 0 and re.search(r" s \([0-9.]+ s of it compiling the casters\), [0-9,]+ cells", err), err

    # A full disk kept the kernel out of the cache: not "once" either, and the reason given.
    import errno

    from numba.core.caching import IndexDataCacheFile

    def full(self, *args):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(raycast.kernel_cache, "_REFUSED", None)
    monkeypatch.setattr(raycast.kernel_cache, "_UNSAVED", [])
    monkeypatch.setattr(IndexDataCacheFile, "_save_index", full)
    monkeypatch.setattr(IndexDataCacheFile, "_save_data", full)

    def render_compiling_a_cached_kernel(*args, **kwargs):
        numba.njit(cache=True)(_add_one)(1.5)
        return real(*args, **kwargs)
    monkeypatch.setattr(parc, "render", render_compiling_a_cached_kernel)
    rc, _, err = _run(render + [tmp_path / "3.png"], capsys)
    assert rc == 0 and re.search(r" s \([0-9.]+ s of it compiling the casters, not kept: No space left on device\), "
                                 r"[0-9,]+ cells", err), err


def _add_one(x):
    """A kernel cached as the casters are, compiled afresh for a type no test gives it elsewhere."""
    return x + 1


def test_samples_of_a_type_not_yet_compiled_are_said_to_compile(tmp_path, monkeypatch):
    """Numba compiles a kernel for each type of samples it is given: the CT head's int16 after
    uint8 took 5 s unsaid, and so did four volumes merged after three."""
    import pickle

    import numba
    import raycast.kernel_cache
    from numba.core import types
    from parc.outputs import compile_notice
    from raycast.iso import cast_iso_image
    monkeypatch.setattr(raycast.kernel_cache, "cache_folder", lambda: tmp_path)
    own = Path(cast_iso_image._cache._cache_file._index_path)    # as Numba reads it, in the folder given
    index = tmp_path / own.relative_to(numba.core.config.CACHE_DIR)
    index.parent.mkdir()

    def samples(dtype, n=None):
        one = np.empty((2, 2, 2), dtype)
        one.flags.writeable = False
        return numba.typeof(one) if n is None else types.UniTuple(numba.typeof(one), n)

    def says(wanted, *cached):
        index.write_bytes(pickle.dumps("0.68") + pickle.dumps(
            (0.0, {((first, types.float64), "cpu"): "x.nbc" for first in cached})))
        said = []
        compile_notice(said.append, [(cast_iso_image, wanted)])
        return bool(said) and "compiling the ray casters" in said[0]

    u8, i16 = samples("uint8"), samples("int16")
    assert not says((u8,), u8)
    assert says((i16,), u8)
    assert says((u8, i16), u8) and not says((u8, i16), i16, u8)
    assert not says((), u8)                                          # a kernel that takes no samples
    assert says((samples("uint8", 4),), samples("uint8", 3)) and not says((samples("uint8", 3),), samples("uint8", 3))
    # An index elsewhere in the folder (Numba alone files one under a hash of its checkout's
    # path) is not the one this Numba reads: the first found answered, and a run compiled unsaid.
    other = tmp_path / "raycast_0123" / own.name
    other.parent.mkdir()
    other.write_bytes(pickle.dumps("0.68") + pickle.dumps(
        (0.0, {((first, types.float64), "cpu"): "x.nbc" for first in (u8, i16)})))
    assert says((i16,), u8) and not says((u8,), u8)
    index.unlink()
    said = []
    compile_notice(said.append, [(cast_iso_image, (u8,))])
    assert said


def test_a_compile_not_foretold_is_said_as_it_starts(monkeypatch, tmp_path):
    # The cell ranges' passes and the shadow rays compiled for int16 after uint8 without a word.
    import threading

    import numba
    from parc import outputs
    monkeypatch.setattr(outputs, "_NOTICE_SAID", [False])
    said = []

    def fresh():
        @numba.njit
        def twice(x):
            return 2 * x
        return twice
    with outputs.late_compile_notice(said.append):
        assert not said                         # nothing compiled yet, nothing said
        fresh()(1)
        fresh()(2.0)                            # said once a run
    assert len(said) == 1 and said[0].startswith("compiling the ray casters for this kind of render")
    fresh()(3)                                  # after the block: not listened to
    assert len(said) == 1
    # Said before the work by compile_notice: not again. A thread's compile is not the run's.
    monkeypatch.setattr(outputs, "_NOTICE_SAID", [False])
    said.clear()
    with outputs.late_compile_notice(said.append):
        worker = threading.Thread(target=lambda: fresh()(4))
        worker.start()
        worker.join()
        assert said == []
        outputs._NOTICE_SAID[0] = True
        fresh()(5)
    assert said == []


def test_each_kernel_is_checked_for_the_samples_it_is_given(gl):
    """A scene of an int16 isosurface and a uint8 translucent volume compiled nothing new on its
    second run, yet said it compiled: every kernel was asked for both types."""
    import parc
    from parc.renderer import kernel_samples
    rng = np.random.default_rng(0)
    a = Volume(rng.integers(0, 1000, (6, 6, 6)).astype(np.int16))
    b = Volume(rng.integers(0, 200, (6, 6, 6)).astype(np.uint8))
    c = Volume(rng.integers(0, 200, (6, 6, 6)).astype(np.float32))
    cam = parc.Camera.framing(*a.bounds)
    scene = parc.Scene(camera=cam, size=(8, 8), volumes=[parc.Isosurface(a, 500.5), parc.Translucent(b, "greyscale"),
                                                          parc.Translucent(c, "greyscale")])
    parc.render(scene)
    asked = dict(kernel_samples(scene))
    assert sum(len(samples) for samples in asked.values()) == 2       # the surface's, and the two merged
    for kernel, samples in asked.items():
        assert set(map(str, samples)) <= {str(s[0]) for s in kernel.signatures}, kernel


def test_a_surface_out_of_sight_is_not_said_to_compile_on_every_run(gl):
    """An int32 surface inside a uint16 one wins no pixel: its frames and shadow rays are never
    made, so never compiled for int32, and the notice, asking for them, came on every run. What
    the notice asks each kernel for must be what one render compiles (or loads) it for."""
    import parc
    from parc.renderer import kernel_samples
    from raycast.iso import cast_iso_image
    k, j, i = np.mgrid[:12, :12, :12] - 5.5
    r = np.sqrt(i * i + j * j + k * k)
    outer = parc.Isosurface(Volume((2000.0 - 150.0 * r).astype(np.uint16)), 1325.5)      # radius 4.5, closed
    inner = parc.Isosurface(Volume(np.rint(10.0 * r).astype(np.int32)), 20.5)           # radius 2, inside
    scene = parc.Scene(camera=parc.Camera.framing(*outer.volume.bounds), size=(8, 8), volumes=[outer, inner],
                       lights=[parc.PointLight((30.0, -30.0, 30.0))], shadows=True)
    parc.render(scene)
    for kernel, samples in kernel_samples(scene):
        assert set(map(str, samples)) <= {str(s[0]) for s in kernel.signatures}, kernel
        # Directly, as well: Numba's signatures are the process's, and an earlier test may have
        # compiled a frame kernel for int32. Only the caster, which runs for both, is asked for them.
        if kernel is not cast_iso_image:
            assert "int32" not in " ".join(map(str, samples)), kernel


def test_the_casters_a_render_is_said_to_compile_are_those_it_runs(gl):
    """`parc.renderer.kernel_samples` (which the first-compile notice checks) names kernels each kind
    of render runs, with the sample types it runs them on: after the render, each has a compiled or
    loaded signature for each of those types. PARC's list holds its own kernels besides the casters
    (`brute`'s cached, its first render compiled for seconds unsaid)."""
    import parc
    from data_tools.synthetic import blobs
    from parc.renderer import kernel_samples
    from parc.skip import expect_frames
    vol = blobs(10, seed=1)
    lo, hi = vol.value_range()
    cam = parc.Camera.framing(*vol.bounds)
    iso = parc.Isosurface(vol, (lo + hi) / 2)
    far = tuple(2.0 * np.array(vol.bounds[1]))
    kinds = [
        ([iso], [], "brute", "depth"),
        ([iso], [], "parc", "depth"),
        ([iso], [parc.PointLight(far)], "parc", "depth"),
        ([parc.Translucent(vol, "greyscale")], [], "parc", "bits"),
        ([parc.Translucent(vol, "greyscale", shade=True)], [], "brute", "depth"),
        ([parc.Translucent(vol, "greyscale")], [], "parc", "depth,bits"),
        ([iso, parc.Translucent(vol, "greyscale", mode="mip"), parc.Translucent(vol, "viridis", shade=True)],
         [parc.PointLight(far)], "parc", "depth"),
        ([parc.Translucent(vol, "greyscale", shade=True)], [parc.PointLight(far)], "brute", "depth"),
        ([parc.Translucent(vol, "greyscale", shade=True)], [parc.PointLight(far)], "parc", "depth"),
        # The merged walk with bit planes, as `test_shadows` compiles it (two uint8 volumes).
        ([parc.Translucent(vol, "greyscale", shade=True), parc.Translucent(vol, "viridis")],
         [parc.PointLight(far)], "parc", "depth,bits"),
    ]
    for volumes, lights, method, buffers in kinds:
        scene = parc.Scene(camera=cam, size=(8, 8), volumes=volumes, lights=lights, shadows=bool(lights))
        if method == "parc":
            # The frames after a first, whose tables by ray octant are listed too; alone in its
            # process, this test's first PARC isosurface frame built none.
            expect_frames(scene)
        parc.render(scene, method, **({"buffers": buffers} if method == "parc" else {}))
        pairs = kernel_samples(scene, (method,), buffers)
        named = [k for k, _ in pairs]
        assert named and all(k.signatures for k in named), [k.py_func.__qualname__ for k in named]
        for k, samples in pairs:
            compiled = {sig[0] for sig in k.signatures}
            assert set(samples) <= compiled, (k.py_func.__qualname__, samples, compiled)
        if method == "parc":
            assert set(named) - {k for k, _ in kernel_samples(scene, ("brute",), buffers)}


def test_parcs_own_kernels_said_to_compile_are_those_a_render_calls(gl, monkeypatch):
    """PARC's kernels beside the casters (the segments' unpacking, the skip tables) named for a
    render are those it calls. The skip tables by ray octant wait for an isovalue's second frame,
    yet every isosurface was said to need them: `parc render --method parc` of a surface said it
    compiled on every run, until a `parc compare` had built them."""
    import parc
    import parc.raster
    import parc.skip
    from data_tools.synthetic import blobs
    from parc.renderer import kernel_samples
    called, spied = set(), {}

    def spy(module, name):
        kernel = getattr(module, name)

        def recorded(*args):
            called.add(kernel)
            return kernel(*args)
        spied[recorded] = kernel          # as `kernel_samples` reads it from the module
        monkeypatch.setattr(module, name, recorded)
        return kernel

    own = {spy(parc.raster, "unpack_segments")} | {
        spy(parc.skip, k.py_func.__name__) for k in parc.skip.OCTANT_KERNELS + parc.skip.CENTRED_KERNELS}
    lo, hi = blobs(10, seed=1).value_range()
    far = tuple(2.0 * np.array(blobs(10, seed=1).bounds[1]))
    kinds = [  # volumes (a function of one fresh volume), lights, buffers
        (lambda v: [parc.Isosurface(v, (lo + hi) / 2)], [], "depth"),
        (lambda v: [parc.Isosurface(v, (lo + hi) / 2)], [parc.PointLight(far)], "depth"),
        (lambda v: [parc.Isosurface(v, (lo + hi) / 2), parc.Isosurface(v, (lo + hi) / 2)], [], "depth"),
        (lambda v: [parc.Isosurface(v, (lo + hi) / 2), parc.Isosurface(v, lo + (hi - lo) / 4)], [], "depth"),
        (lambda v: [parc.Translucent(v, "greyscale")], [], "bits"),
        (lambda v: [parc.Translucent(v, "greyscale")], [], "depth,bits"),
        (lambda v: [parc.Isosurface(v, (lo + hi) / 2), parc.Translucent(v, "greyscale", shade=True)],
         [parc.PointLight(far)], "depth"),
    ]
    for volumes, lights, buffers in kinds:
        for repeated in (False, True):
            vol = blobs(10, seed=1)          # a fresh volume: no table built, no isovalue asked before
            scene = parc.Scene(camera=parc.Camera.framing(*vol.bounds), size=(8, 8), volumes=volumes(vol),
                               lights=lights, shadows=bool(lights))
            if repeated:
                parc.skip.expect_frames(scene)
            called.clear()
            parc.render(scene, "parc", buffers=buffers)
            named = {spied.get(k, k) for k, _ in kernel_samples(scene, ("parc",), buffers, repeated=repeated)} & own
            assert named == called, (buffers, repeated, sorted(k.py_func.__name__ for k in named ^ called))


def test_one_lit_translucent_volume_is_said_to_compile_the_caster_it_runs(gl):
    """One translucent volume with lights is cast by its own driver, as without them: the notice
    asked for the merged walk of several volumes instead, which such a render never runs, and
    said it compiled on every run (and nothing on the first, which compiled)."""
    import parc
    from data_tools.synthetic import blobs
    from parc.renderer import kernel_samples
    vol = blobs(10, seed=1)
    cam = parc.Camera.framing(*vol.bounds)
    vis = parc.Translucent(vol, "greyscale", shade=True)
    lit = parc.Scene(camera=cam, size=(8, 8), volumes=[vis], lights=[parc.PointLight((30.0, -20.0, 25.0))])
    for method, buffers in (("brute", "depth"), ("parc", "depth,bits")):
        parc.render(lit, method, **({"buffers": buffers} if method == "parc" else {}))
        pairs = kernel_samples(lit, (method,), buffers)
        for k, samples in pairs:
            assert set(samples) <= {sig[0] for sig in k.signatures}, k.py_func.__qualname__
        assert pairs == kernel_samples(parc.Scene(camera=cam, size=(8, 8), volumes=[vis]), (method,), buffers)


def test_shadows_with_no_surface_to_fall_on_are_not_said_to_compile_shadow_rays(gl):
    """Shadow rays leave isosurface hits and shaded samples alone: in a scene of unshaded
    translucent volumes they are never cast, and the notice, asking for their kernels, said it
    compiled on every run until some other scene had compiled them."""
    import parc
    from data_tools.synthetic import blobs
    from parc.renderer import kernel_samples
    vol = blobs(10, seed=1)
    volumes = [parc.Translucent(vol, "greyscale"), parc.Translucent(vol, "viridis")]
    lights = [parc.PointLight((30.0, -20.0, 25.0))]
    cam = parc.Camera.framing(*vol.bounds)
    with pytest.warns(parc.ShowsNothingWarning):
        shadowed = parc.Scene(camera=cam, size=(8, 8), volumes=volumes, lights=lights, shadows=True)
    with pytest.warns(parc.ShowsNothingWarning):
        plain = parc.Scene(camera=cam, size=(8, 8), volumes=volumes, lights=lights)
    for method in ("brute", "parc"):
        assert (parc.render(shadowed, method).image == parc.render(plain, method).image).all()
        assert kernel_samples(shadowed, (method,)) == kernel_samples(plain, (method,))


def _readme_command_lines():
    """The lines of the README's "Command line" block."""
    text = (Path(__file__).parents[2] / "README.md").read_text()
    return text.split("## Command line", 1)[1].split("```", 2)[1].splitlines()


def _readme_synopsis():
    """``{command: set of flags}`` from the README's "Command line" block, comments dropped."""
    flags = {}
    command = None
    for line in _readme_command_lines():
        words = line.split("#", 1)[0].split()
        if words[:1] == ["parc"]:
            command = words[1]
        if command is not None:
            flags.setdefault(command, set()).update(
                re.findall(r"(?<![\w-])-(?:-[a-z][a-z-]*|[a-z])\b", " ".join(words)))
    return flags


def _parser_options():
    """``{command: [set of one option's spellings, ...]}`` from the parsers, help left out."""
    return {name: [set(a.option_strings) for a in p._actions if a.option_strings and a.dest != "help"]
            for name, p in _subparsers().items()}


def _subparsers():
    """``{command: its parser}``."""
    return next(a for a in build_parser()._actions if isinstance(a.choices, dict)).choices


def test_the_readme_synopsis_is_the_command_line():
    """Every flag the README's synopsis gives exists, and every option the parsers take is given
    (in either spelling; compare names render's flags of what, how and where to look instead of
    repeating them)."""
    documented = _readme_synopsis()
    options = _parser_options()
    assert set(documented) == set(options)
    taken = {command: set().union(*spellings) for command, spellings in options.items()}
    for command, flags in documented.items():
        assert flags <= taken[command], f"parc {command}: the README gives {sorted(flags - taken[command])}"
    documented["compare"] |= documented["render"] & taken["compare"]
    for command, spellings in options.items():
        missing = [sorted(s) for s in spellings if not s & documented[command]]
        assert not missing, f"parc {command}: the README leaves out {missing}"


def test_the_readme_names_every_synthetic_volume():
    """The synopsis's ``parc make`` comment lists exactly the names the parser takes."""
    lines = _readme_command_lines()
    at = next(n for n, line in enumerate(lines) if line.startswith("parc make "))
    comment = lines[at].split("#", 1)[1]
    for line in lines[at + 1:]:
        if not line.lstrip().startswith("#"):
            break
        comment += line.split("#", 1)[1]
    named = {w.strip() for w in comment.split(",")}
    make = next(a for a in _subparsers()["make"]._actions if a.dest == "name")
    assert named == set(make.choices)


def test_compare_takes_a_background(vol_file, capsys, gl):
    rc, out, err = _run(["compare", vol_file, "--iso", 4.0, "--size", 24, 20, "--repeats", 1,
                         "--background", "0.2,0.3,0.4", "--json", "--quiet"], capsys)
    assert rc == 0, err
    rows = json.loads(out)
    assert [r["method"] for r in rows] == ["brute", "parc"]
    assert rows[1]["hit_mismatches"] == 0 and rows[1]["max_color"] == 0.0


@pytest.mark.parametrize("signum", ["SIGTERM", "SIGHUP"])
def test_a_stop_signal_while_writing_leaves_no_temporary_file(signum, vol_file, tmp_path, capsys, monkeypatch):
    """SIGTERM or SIGHUP unwinds as Ctrl-C does: the temporary output is removed, one line, 128 + signal."""
    import os
    import signal
    import parc.cli as cli
    real = cli.write_png

    def write_then_stop(image, path):
        real(image, path)
        os.kill(os.getpid(), getattr(signal, signum))
    monkeypatch.setattr(cli, "write_png", write_then_stop)
    # The signal's default action, as a shell gives it: under nohup SIGHUP comes ignored, and
    # a run keeps it ignored (the test after this one).
    outer = signal.signal(getattr(signal, signum), signal.SIG_DFL)
    try:
        out = tmp_path / "o.png"
        rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", out], capsys)
        assert rc == 128 + getattr(signal, signum) and err == f"parc: stopped by {signum}\n"
        assert sorted(p.name for p in tmp_path.iterdir()) == ["ball.nrrd"]
        assert signal.getsignal(getattr(signal, signum)) == signal.SIG_DFL
    finally:
        signal.signal(getattr(signal, signum), outer)


def test_an_ignored_stop_signal_stays_ignored(vol_file, tmp_path, capsys, monkeypatch):
    # Under nohup SIGHUP is ignored, and a run replacing its handler was stopped by the hangup.
    import signal
    import parc.cli as cli
    real = cli.write_png

    def write_then_hang_up(image, path):
        real(image, path)
        os.kill(os.getpid(), signal.SIGHUP)
    monkeypatch.setattr(cli, "write_png", write_then_hang_up)
    before = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", tmp_path / "o.png"], capsys)
        assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGHUP, before)
    assert rc == 0, err
    assert Image.open(tmp_path / "o.png").size == (8, 8)


class _SignalInCompile:
    """Sends ``signum`` to this process ``times`` times as Numba starts compiling a function."""

    def __init__(self, signum, times):
        import numba.core.event as ev

        class Send(ev.Listener):
            def on_start(self, event):
                for _ in range(times):
                    signal.raise_signal(signum)      # each handled before the next is sent

            def on_end(self, event):
                pass
        self.kind, self.listener = "numba:compile", Send()

    def __enter__(self):
        import numba.core.event as ev
        ev.register(self.kind, self.listener)

    def __exit__(self, *exc):
        import numba.core.event as ev
        ev.unregister(self.kind, self.listener)


@pytest.fixture
def stop_signals_at_their_defaults():
    """Ctrl-C and SIGTERM as a run started at a terminal has them: a run started in the
    background (a CI job under &) inherits Ctrl-C ignored, which `parc.stops.stop_on_signals` keeps."""
    was = {signal.SIGINT: signal.signal(signal.SIGINT, signal.default_int_handler),
           signal.SIGTERM: signal.signal(signal.SIGTERM, signal.SIG_DFL)}
    yield
    for signum, handler in was.items():
        signal.signal(signum, handler)


@pytest.mark.parametrize("signum, again", [("SIGINT", "Ctrl-C"), ("SIGTERM", "SIGTERM")])
def test_a_signal_while_a_kernel_compiles_is_raised_once_it_has_compiled(capsys, signum, again,
                                                                        stop_signals_at_their_defaults):
    # Raised inside Numba's compile, a KeyboardInterrupt was swallowed (the run went on and
    # wrote its file), crashed the process, or broke the kernel ("no compiled object yet").
    import numba
    from parc.stops import Stopped, stop_on_signals
    from raycast.compiler import compiling        # imported, it watches Numba's compiler lock

    @numba.njit
    def twice(x):
        return 2 * x
    assert not compiling()
    replaced = stop_on_signals()
    try:
        with _SignalInCompile(getattr(signal, signum), 1), \
                pytest.raises(KeyboardInterrupt if signum == "SIGINT" else Stopped):
            twice(3)
    finally:
        for number, handler in replaced.items():
            signal.signal(number, handler)
    assert len(twice.overloads) == 1        # compiled whole before the signal was acted on
    assert twice(3) == 6 and not compiling()
    assert capsys.readouterr().err == f"parc: stopping once the kernel under way is ready ({again} again to stop at once)\n"


def test_ctrl_c_while_the_kernel_module_is_still_importing_is_a_plain_interrupt(monkeypatch,
                                                                              stop_signals_at_their_defaults):
    # A module half imported has no `compiling` yet: the handler raised AttributeError, a traceback.
    import types
    from parc.stops import stop_on_signals
    monkeypatch.setitem(sys.modules, "raycast.compiler", types.ModuleType("raycast.compiler"))
    replaced = stop_on_signals()
    try:
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)
    finally:
        for number, handler in replaced.items():
            signal.signal(number, handler)


_TWO_CTRL_C_IN_A_COMPILE = """
import shutil, signal, sys
from pathlib import Path
import numba
import raycast.config
from data_tools.signals import building
from parc.stops import stop_on_signals

class CtrlCTwice(numba.core.event.Listener):
    def on_start(self, event):
        signal.raise_signal(signal.SIGINT)
        signal.raise_signal(signal.SIGINT)

    def on_end(self, event):
        pass

@numba.njit
def twice(x):
    return 2 * x
signal.signal(signal.SIGINT, signal.default_int_handler)     # ignored where the tests run in the background
stop_on_signals()
numba.core.event.register("numba:compile", CtrlCTwice())
stage = Path(sys.argv[1]) / ".stage"
stage.mkdir()
(stage / "half.png").write_bytes(b"x")
kernels = Path(sys.argv[1]) / "parc-kernels-temporary"       # as for a cache folder not writable
kernels.mkdir()
raycast.config.at_exit(shutil.rmtree, kernels)
with building(stage):
    twice(3)
print("not reached")
"""


def test_ctrl_c_twice_while_a_kernel_compiles_stops_at_once_leaving_nothing(tmp_path):
    # Ended at once, the run skips `atexit`: what it fills and what it would remove at exit
    # (a temporary kernel folder, the root study's worker pool) are removed first.
    p = subprocess.run([sys.executable, "-c", _TWO_CTRL_C_IN_A_COMPILE, tmp_path], capture_output=True, text=True,
                       timeout=300, cwd=Path(__file__).parents[2])
    assert (p.returncode, p.stdout) == (130, "")
    assert p.stderr == ("parc: stopping once the kernel under way is ready (Ctrl-C again to stop at once)\n"
                        "parc: interrupted\n")
    assert list(tmp_path.iterdir()) == []


#: The `parc` script's own lines, with a Ctrl-C arriving as Python imports ``{module}``.
_INTERRUPTED_WHILE_LOADING = """
import sys
class CtrlC:
    @staticmethod
    def find_spec(name, path=None, target=None):
        if name == {module!r}:
            raise KeyboardInterrupt
sys.meta_path.insert(0, CtrlC)
from parc.console import main
sys.exit(main())
"""


@pytest.mark.parametrize("module", ["numpy", "numba"])
def test_ctrl_c_while_the_libraries_load_is_one_line(module, vol_file, tmp_path):
    # They take about 0.3 s to load: the console script loads them inside its error handling.
    out = tmp_path / "o.png"
    p = subprocess.run([sys.executable, "-c", _INTERRUPTED_WHILE_LOADING.format(module=module),
                        "render", vol_file, "--iso", "4", "--size", "8", "8", "-o", out],
                       capture_output=True, text=True, timeout=300)
    assert (p.returncode, p.stderr) == (130, "parc: interrupted\n")
    assert not out.exists()


def test_importing_parc_loads_no_library_until_a_name_is_used():
    p = subprocess.run([sys.executable, "-c", "import sys, parc, parc.console; "
                        "print(sorted({'numpy', 'numba', 'moderngl'} & set(sys.modules))); "
                        "print(parc.compare.__module__, parc.render.__module__, parc.Volume.__module__)"],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.splitlines() == ["[]", "parc.comparison parc.renderer data_tools.volume"]


def test_every_public_name_resolves_and_is_listed():
    import parc
    for name in parc.__all__:
        assert getattr(parc, name).__name__ == name and name in dir(parc)
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        parc.nothing


def test_an_error_after_live_progress_starts_a_line_of_its_own(vol_file, tmp_path, capsys, monkeypatch):
    from parc import outputs
    monkeypatch.setattr(outputs.sys.stderr, "isatty", lambda: True)
    live = outputs.Progress("rendering 8x8", delay=60.0)
    live.start -= 60.0
    live(0.43)
    outputs.error_line("interrupted")
    assert capsys.readouterr().err == "\rparc: rendering 8x8:  43%\nparc: interrupted\n"


def test_progress_says_the_work_has_begun_before_its_first_report(capsys):
    # A large volume's cell ranges or the OpenGL pass come before the first band is cast.
    import time
    from parc import outputs
    slow = outputs.Progress("rendering 8x8", delay=0.05)
    for _ in range(200):
        if slow.last >= 0:
            break
        time.sleep(0.01)
    slow(0.5)
    slow.done()
    lines = capsys.readouterr().err.splitlines()
    assert lines[:2] == ["parc: rendering 8x8: 0%", "parc: rendering 8x8: 50%"]
    assert len(lines) == 3 and lines[2].startswith("parc: rendering 8x8: done in ")


def test_progress_that_cannot_be_written_leaves_the_work_alone(monkeypatch):
    from parc import outputs

    class Closed:
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            pass

        def isatty(self):
            return True
    monkeypatch.setattr(outputs.sys, "stderr", Closed())
    live = outputs.Progress("rendering 8x8", delay=0.0)
    live(0.5)
    live(0.9)
    live.done()
    assert live.mute and outputs.Progress.open_line is None


@pytest.mark.parametrize("slow", [True, False])
def test_compare_says_what_it_times_on_stderr_json_or_not(slow, vol_file, capsys, monkeypatch):
    import importlib
    monkeypatch.setattr(importlib.import_module("parc.comparison"), "SLOW_ROUND", 0.0 if slow else 1e9)
    rc, out, err = _run(["compare", vol_file, "--iso", 4, "--size", 12, 12, "--repeats", 2, "--json"], capsys)
    assert rc == 0 and [r["method"] for r in json.loads(out)] == ["brute", "parc"]
    rounds = ["parc: timing round 1 of 2 ...", "parc: timing round 2 of 2 ..."] if slow else []
    lines = [s for s in err.splitlines() if "compiling" not in s]
    assert lines == ["parc: warming up brute ...", "parc: warming up parc ...", *rounds]


@pytest.mark.parametrize("command", ["info", "compare"])
def test_a_closed_stdout_is_refused_where_the_result_goes_there(command, vol_file, capsys, monkeypatch):
    monkeypatch.setattr(sys, "stdout", None)            # started with >&-
    rc = main([command, str(vol_file)] + (["--iso", "4", "--size", "8", "8"] if command == "compare" else []))
    monkeypatch.undo()
    err = capsys.readouterr().err
    assert rc == 2 and err == f"parc: error: standard output is closed; parc {command} prints its result there\n"


def test_a_large_image_says_it_is_being_written(vol_file, tmp_path, capsys, monkeypatch):
    import parc.cli as cli
    monkeypatch.setattr(cli, "LARGE_WRITE_PIXELS", 64)
    out = tmp_path / "o.png"
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", out], capsys)
    assert rc == 0 and f"parc: writing {out} ...\n" in err and out.exists()
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 7, 9, "-o", out], capsys)
    assert rc == 0 and "writing" not in err


def test_a_transfer_function_transparent_over_the_data_gets_a_note(vol_file, tmp_path, capsys):
    tf = tmp_path / "far.toml"
    tf.write_text("opacity = [[1000, 0], [2000, 1]]\n")
    rc, _, err = _run(["render", vol_file, "--tf", tf, "--size", 8, 8, "-o", tmp_path / "o.png"], capsys)
    assert rc == 0 and f"{tf} is transparent over the data range [0.8660253882408142, 9.52627944946289]" in err
    # Named by its file in every line, the step sweep's heading too (not "the transfer function");
    # said once, though the sweep makes more of that volume (each would warn from Python).
    with warnings.catch_warnings():
        warnings.simplefilter("error", ShowsNothingWarning)
        rc, out, err = _run(["compare", vol_file, "--tf", tf, "--size", 8, 8, "--repeats", 1, "--sweep-step", 1],
                            capsys)
    assert rc == 0 and f"composite of {tf}" in out and err.count("transparent over") == 1, (out, err)
    rc, _, err = _run(["render", vol_file, "--tf", "greyscale", "--size", 8, 8, "-o", tmp_path / "g.png"], capsys)
    assert rc == 0 and "transparent" not in err


@pytest.mark.parametrize("size", [(32, 96), (96, 32)])
def test_the_default_view_frames_a_long_volume_whole_in_a_tall_image(size, tmp_path, capsys):
    data = np.zeros((16, 16, 256), np.float32)
    data[1:-1, 1:-1, 1:-1] = 1.0                        # a long bar, 255 x 15 x 75 in the world
    bar = save_volume(Volume(data, spacing=(1, 1, 5)), tmp_path / "bar.nrrd")
    depth = tmp_path / "d.npy"
    rc, _, err = _run(["render", bar, "--iso", 0.5, "--size", *size, "-o", tmp_path / "o.png", "--depth", depth],
                      capsys)
    hit = np.isfinite(np.load(depth))
    assert rc == 0 and hit.sum() > 20, err
    assert not (hit[0].any() or hit[-1].any() or hit[:, 0].any() or hit[:, -1].any())


def test_an_eye_at_the_centre_looked_at_by_default_is_named(vol_file, tmp_path, capsys):
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--eye", "5.5,5.5,5.5", "-o", tmp_path / "o.png"], capsys)
    assert rc == 2 and "--eye 5.5,5.5,5.5 is the centre of the volume" in err and "--look-at" in err


def test_every_command_and_argument_is_explained_in_its_help():
    # `parc info --help` had no description and a bare "volume" positional.
    for name, parser in _subparsers().items():
        assert parser.description and len(parser.description) > 40, name
        for action in parser._actions:
            if action.dest != "help":
                assert action.help, (name, action.dest)


def test_help_text_is_filled_to_the_terminal_width(monkeypatch):
    # Prose fits 80 columns; only the indented examples and lists keep lines of their own length.
    monkeypatch.setenv("COLUMNS", "80")
    parsers = {"parc": build_parser(), **_subparsers()}
    for name, parser in parsers.items():
        text = parser.format_help()
        long = [line for line in text.splitlines() if len(line) > 80 and not line.startswith("  ")]
        assert not long, (name, long)
        assert parser.description.split(".")[0] in " ".join(text.split()), name


def test_a_file_name_with_a_newline_or_an_escape_stays_on_the_error_line(vol_file, tmp_path, capsys):
    out = tmp_path / "o.png"
    for name, shown in [("no\nsuch.nrrd", r"no\nsuch.nrrd"), ("x\x1b[31m.toml", r"x\x1b[31m.toml")]:
        argv = (["render", tmp_path / name, "--iso", 1] if name.endswith(".nrrd") else
                ["render", vol_file, "--tf", tmp_path / name])
        rc, _, err = _run(argv + ["-o", out], capsys)
        assert rc == 2 and err.count("\n") == 1 and "\x1b" not in err and shown in err, err
        assert not out.exists()


def test_info_says_the_note_a_volume_was_read_with(tmp_path, capsys):
    import nrrd
    nrrd.write(str(tmp_path / "m.nrrd"), np.zeros((3, 4, 5), np.uint8), {"spacings": np.array([-1.0, 2.0, 3.0])},
               index_order="C")
    rc, out, err = _run(["info", tmp_path / "m.nrrd"], capsys)
    assert rc == 0 and "spacing" in out
    # Once, among the report's lines: not again on stderr, where one capturing both would see it twice.
    assert (out + err).count("negative spacings (mirrored axes) were reduced to positive spacings") == 1
    assert "note:        negative spacings" in out and err == ""


@pytest.mark.parametrize("command", [["info"], ["convert", "-o", "out.nrrd"]])
def test_info_and_convert_of_a_scene_file_say_it_is_one(vol_file, tmp_path, capsys, command):
    scene = tmp_path / "s.toml"
    scene.write_text(f"[[volume]]\nfile = '{vol_file}'\niso = 3.5\n")
    rc, _, err = _run([command[0], scene] + [tmp_path / a if a.endswith(".nrrd") else a for a in command[1:]], capsys)
    assert rc == 2 and err.count("\n") == 1, err
    assert f"s.toml: a scene file; parc {command[0]} reads one volume file" in err
    assert not (tmp_path / "out.nrrd").exists()


@pytest.mark.parametrize("header, lost", [
    ({"space": "left-posterior-superior", "space directions": np.diag([-1.0, 2.0, 3.0])}, True),
    ({"space": "left-posterior-superior", "space directions": np.array([[0.0, 1, 0], [1, 0, 0], [0, 0, 1]])}, True),
    ({"spacings": np.array([1.0, -2.0, 3.0])}, True),
    ({"space": "left-posterior-superior", "space directions": np.diag([1.0, 2.0, 3.0])}, False),
    ({"spacings": np.array([1.0, np.nan, 3.0])}, False),
])
def test_convert_says_when_the_written_file_loses_the_inputs_orientation(tmp_path, capsys, header, lost):
    import nrrd
    src = tmp_path / "m.nrrd"
    nrrd.write(str(src), np.zeros((3, 4, 5), np.uint8), header, index_order="C")
    rc, _, err = _run(["convert", src, "-o", tmp_path / "out.mha"], capsys)
    assert rc == 0 and lost == ("out.mha is written on an axis-aligned grid, without the orientation of" in err), err


def test_a_stderr_that_cannot_take_the_notes_does_not_fail_the_run(vol_file, tmp_path, monkeypatch):
    # stderr on a full disk (2>/dev/full): every file was written, and the run ended with status 2.
    import errno
    import io

    class Full(io.TextIOBase):
        def write(self, text):
            raise OSError(errno.ENOSPC, "No space left on device")

        def flush(self):
            pass
    monkeypatch.setattr(sys, "stderr", Full())
    out, stats = tmp_path / "o.png", tmp_path / "s.json"
    assert main(["render", str(vol_file), "--iso", "4", "--size", "8", "8", "-o", str(out), "--stats", str(stats)]) == 0
    assert out.is_file() and stats.is_file()
    assert main(["info", str(vol_file)]) == 0


@pytest.mark.parametrize("threads, ok", [("0", False), ("-1", False), ("abc", False), ("100000", False), ("²", False),
                                         ("", True), ("2", True)])
def test_numba_thread_count_from_the_environment_is_checked_first(vol_file, threads, ok):
    # Numba failed on 0 with a traceback, printed a traceback-like warning for "abc",
    # and crashed at 100,000; empty is taken as unset.
    import os
    env = dict(os.environ, NUMBA_NUM_THREADS=threads)
    p = subprocess.run([sys.executable, "-c", "import sys; from parc.console import main; sys.exit(main())",
                        "info", str(vol_file)], capture_output=True, text=True, timeout=300, env=env)
    if ok:
        assert p.returncode == 0 and p.stderr == "" and "dimensions" in p.stdout, p.stderr
    else:
        assert (p.returncode, p.stderr) == (2, "parc: error: NUMBA_NUM_THREADS must be a whole number "
                                               f"from 1 to 1024, got {threads!r}\n")


@pytest.mark.parametrize("layer, words", [("bogus", "The threading layer requested 'bogus' is unknown to Numba."),
                                          ("", None), ("workqueue", None)])
def test_numba_threading_layer_from_the_environment_is_checked_first(vol_file, tmp_path, layer, words):
    # Numba reads it at the first parallel kernel, after the compile, and failed with a traceback.
    import os
    env = dict(os.environ, NUMBA_THREADING_LAYER=layer)
    p = subprocess.run([sys.executable, "-c", "import sys; from parc.console import main; sys.exit(main())",
                        "render", str(vol_file), "--iso", "4", "--size", "8", "8", "--quiet", "-o",
                        str(tmp_path / "v.png")], capture_output=True, text=True, timeout=300, env=env)
    if words is None:
        assert p.returncode == 0 and p.stderr == "" and (tmp_path / "v.png").is_file(), p.stderr
    else:
        assert (p.returncode, p.stderr) == (2, f"parc: error: NUMBA_THREADING_LAYER={layer!r}: {words} "
                                               "(unset it, or give omp or workqueue)\n")
        assert not (tmp_path / "v.png").exists()


def test_a_working_folder_deleted_under_the_run_is_named(tmp_path):
    gone = tmp_path / "gone"
    gone.mkdir()
    script = (f"cd {gone} && rmdir {gone} && exec {sys.executable} -c "
              "'import sys; from parc.console import main; sys.exit(main())' render -o rel.png --size 8 8")
    p = subprocess.run(["bash", "-c", script], capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr
    assert "the working folder no longer exists" in p.stderr


def test_ctrl_c_while_the_interpreter_exits_after_a_run_prints_nothing(tmp_path):
    # The image written, Python's exit still runs finalizers for about 0.3 s; a Ctrl-C there
    # printed "Exception ignored in atexit callback" and a traceback after the run's last line.
    # The Ctrl-C comes from an exit callback registered first, so that it runs last.
    script = ("import atexit, os, signal, sys\n"
              "signal.signal(signal.SIGINT, signal.default_int_handler)   # ignored where tests run in the background\n"
              "def ctrl_c():\n"
              "    os.kill(os.getpid(), signal.SIGINT)\n"
              "    sum(range(1000))     # Python code, where a handler would raise\n"
              "atexit.register(ctrl_c)\n"
              "from parc.console import main\n"
              "sys.exit(main())\n")
    out = tmp_path / "o.png"
    p = subprocess.run([sys.executable, "-c", script, "render", "-o", str(out), "--size", "8", "8"],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and "Traceback" not in p.stderr and "KeyboardInterrupt" not in p.stderr, p.stderr
    assert p.stderr.splitlines()[-1].startswith(f"parc: wrote {out}:") and out.exists(), p.stderr


def test_no_blocks_reaches_the_render(tmp_path, capsys, gl):
    # The image is the same either way (test_translucent), so only the stats can tell the flag was heard.
    for flags, blocks in (([], True), (["--no-blocks"], False)):
        rc, _, err = _run(["render", "--size", 8, 8, "--method", "parc", *flags, "--quiet",
                           "-o", tmp_path / "a.png", "--stats", tmp_path / "s.json"], capsys)
        assert rc == 0, err
        assert json.loads((tmp_path / "s.json").read_text())["blocks"] is blocks


def test_a_large_make_says_it_takes_time(tmp_path, capsys, monkeypatch):
    import data_tools.synthetic
    monkeypatch.setattr(data_tools.synthetic, "LARGE_SYNTHETIC_SAMPLES", 10 ** 3)
    rc, _, err = _run(["make", "sphere", "--size", 9, "-o", tmp_path / "a.nrrd"], capsys)
    assert rc == 0 and "making" not in err, err
    rc, _, err = _run(["make", "sphere", "--size", 10, "-o", tmp_path / "b.nrrd"], capsys)
    assert rc == 0 and err.startswith("parc: making sphere 10x10x10 (1,000 samples) ..."), err
    # So does a scene file's, before the render (not with --quiet).
    scene = tmp_path / "s.toml"
    scene.write_text('size = [8, 8]\n[[volume]]\nsynthetic = "sphere"\nsize = 11\niso = 0.5\n'
                     '[[volume]]\nsynthetic = "floor"\nsize = 10\niso = 127.5\n')
    rc, _, err = _run(["render", scene, "-o", tmp_path / "s.png"], capsys)
    assert rc == 0 and err.startswith("parc: making sphere 11x11x11 (1,331 samples) ...\n"), err
    assert "making floor" not in err                # 10 x 10 x 8 samples: a floor is thin
    rc, _, err = _run(["render", scene, "-o", tmp_path / "t.png", "--quiet"], capsys)
    assert rc == 0 and err == "", err


def test_a_slow_make_below_the_large_size_is_said_before_and_after(tmp_path, monkeypatch, capsys):
    # A neuron is made slowly for its samples: at 256 a side, below the size said at once, it
    # takes 3.5 s, too long for silence.
    import parc.outputs
    monkeypatch.setattr(parc.outputs, "SLOW_NOTE_DELAY", 0.0)
    rc = main(["make", "neuron", "--size", "12", "-o", str(tmp_path / "n.nrrd")])
    lines = capsys.readouterr().err.splitlines()
    assert rc == 0 and lines[0] == "parc: making neuron ...", lines
    assert re.fullmatch(r"parc: making neuron: done in [\d.]+ s", lines[1]), lines
    # Said once where the size is said at once; a refused --seed ends on its error line, with no time.
    import data_tools.synthetic
    monkeypatch.setattr(data_tools.synthetic, "LARGE_SYNTHETIC_SAMPLES", 10 ** 3)
    rc = main(["make", "sphere", "--size", "10", "-o", str(tmp_path / "s.nrrd")])
    lines = capsys.readouterr().err.splitlines()
    assert rc == 0 and [line for line in lines if "making" in line] == [
        "parc: making sphere 10x10x10 (1,000 samples) ..."], lines
    rc = main(["make", "sphere", "--size", "4", "--seed", "1", "-o", str(tmp_path / "t.nrrd")])
    lines = capsys.readouterr().err.splitlines()
    assert rc == 2 and lines[-1] == "parc: error: sphere takes no --seed" and "done in" not in "".join(lines), lines


def test_a_raw_output_whose_name_gives_two_types_names_the_one_written(tmp_path, capsys):
    # "int16_uint16": both fit the file's size, and a reader by name takes int16 first; the message
    # must give --dtype uint16, or values past 32767 read back negative. Truth: the array written.
    from data_tools import Volume
    from data_tools.io import load_volume, save_volume
    arr = (np.arange(120, dtype=np.uint16).reshape(4, 5, 6) * 500)          # up to 59500
    save_volume(Volume(arr), tmp_path / "v.nrrd")
    name = "ct_6x5x4_int16_uint16.raw"
    rc, out, err = _run(["convert", tmp_path / "v.nrrd", "-o", tmp_path / name], capsys)
    assert rc == 0 and "read it back with --dtype uint16;" in out, (out, err)
    flags = out.split("read it back with ")[1].split(";")[0].split()
    rc, out, err = _run(["convert", tmp_path / name, *flags, "-o", tmp_path / "back.npy"], capsys)
    assert rc == 0, err
    assert np.array_equal(load_volume(tmp_path / "back.npy").data, arr)


@pytest.mark.parametrize("value, words", [("2;;4", "--sweep-supercell: supercell size must be"),
                                          ("2,2,2;2", "--sweep-supercell gives 2 twice"),
                                          (" 2 ; 4 ; ", "none.nrrd: no such file")])     # read: the sizes pass
def test_a_supercell_sweep_is_read_before_the_volume(value, words, tmp_path, capsys):
    rc, _, err = _run(["compare", tmp_path / "none.nrrd", "--iso", 4, "--size", 8, 8, "--repeats", 1,
                       "--sweep-supercell", value], capsys)
    assert rc == 2 and err.count("\n") == 1 and words in err, err


@pytest.mark.parametrize("flag", ["-o", "--stats", "--depth"])
def test_an_output_named_with_a_trailing_slash_is_refused(flag, vol_file, tmp_path, capsys):
    # pathlib drops the slash: "o.png/" was written as the file o.png, where the name says a folder.
    name = {"-o": "o.png", "--stats": "s.json", "--depth": "d.npy"}[flag]
    outputs = {"-o": tmp_path / "o.png", flag: f"{tmp_path / name}/"}
    argv = ["render", vol_file, "--iso", 4, "--size", 8, 8, *[x for kv in outputs.items() for x in kv]]
    rc, _, err = _run(argv, capsys)
    assert rc == 2 and err.count("\n") == 1 and f"{name}/: ends in a slash" in err, err
    assert not (tmp_path / "o.png").exists() and not (tmp_path / name).exists()


@pytest.mark.parametrize("kind", ["folder", "pipe", "stats on a pipe"])
def test_an_output_that_cannot_be_a_file_is_refused_before_the_render(kind, vol_file, tmp_path, capsys, monkeypatch):
    # Refused only after the render, the same line would come once the wait was over.
    import parc

    def render(*args, **kwargs):
        raise AssertionError("rendered")
    monkeypatch.setattr(parc, "render", render)
    out, stats = tmp_path / "o.png", tmp_path / "s.json"
    argv = ["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", out]
    if kind == "folder":
        out.mkdir()
    elif kind == "pipe":
        os.mkfifo(out)
    else:
        os.mkfifo(stats)
        argv += ["--stats", stats]
    rc, _, err = _run(argv, capsys)
    words = "o.png: is a folder" if kind == "folder" else "not a regular file (a device, pipe or socket)"
    assert rc == 2 and err.count("\n") == 1 and words in err, err


def test_quiet_shows_no_progress_however_long_the_render(vol_file, tmp_path, capsys, monkeypatch):
    import parc.cli as cli
    from parc.outputs import Progress

    class Eager(Progress):
        def __init__(self, what):
            super().__init__(what, delay=0.0)
    monkeypatch.setattr(cli, "Progress", Eager)
    argv = ["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", tmp_path / "o.png"]
    rc = main([str(a) for a in argv])
    assert rc == 0 and "parc: rendering 8x8: " in capsys.readouterr().err
    rc = main([str(a) for a in argv + ["--quiet"]])
    assert rc == 0 and capsys.readouterr().err == ""


def test_progress_ended_within_its_delay_says_nothing_later(capsys):
    # Its timer, left running, would say "0%" a second on: after the result, or after an error line.
    import time
    from parc import outputs
    quick = outputs.Progress("rendering 8x8", delay=0.05)
    quick.done()
    failed = outputs.Progress("rendering 8x8", delay=0.05)
    outputs.end_progress_line()          # as an error line does
    time.sleep(0.3)
    assert capsys.readouterr().err == "" and quick.last < 0 and failed.last < 0


@pytest.mark.parametrize("target", ["file", "folder"])
def test_a_read_only_output_or_folder_is_refused_before_the_render(vol_file, tmp_path, capsys, monkeypatch, target):
    # As an ordinary user's permissions have it (root may write anywhere): the rename would
    # replace a read-only file all the same, so the output is refused by its mode.
    real_access = os.access

    def access(path, mode, **kwargs):
        try:
            read_only = not os.stat(path).st_mode & stat.S_IWUSR
        except OSError:
            read_only = False
        return not (mode & os.W_OK and read_only) and real_access(path, mode, **kwargs)
    monkeypatch.setattr(os, "access", access)
    folder = tmp_path / "out"
    folder.mkdir()
    out = folder / "p.png"
    out.write_bytes(b"old")
    (out if target == "file" else folder).chmod(0o555)
    try:
        rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", out], capsys)
    finally:
        folder.chmod(0o755)
    assert rc == 2 and err.count("\n") == 1 and f"{out}: not writable" in err, err
    assert out.read_bytes() == b"old" and sorted(os.listdir(folder)) == ["p.png"]


def test_progress_never_shows_more_than_the_work_done(monkeypatch, capsys):
    # 24.9% done is not yet 25%: a line off a terminal says so only once the quarter is reached.
    from parc import outputs
    now = [100.0]
    monkeypatch.setattr(outputs.time, "perf_counter", lambda: now[0])
    work = outputs.Progress("work")
    work.pending.cancel()
    now[0] += 5.0
    for fraction in (0.249, 0.2499, 0.25, 0.7499):
        work(fraction)
    assert capsys.readouterr().err.splitlines() == ["parc: work: 24%", "parc: work: 25%", "parc: work: 74%"]


@pytest.mark.parametrize("umask, mode", [(0o002, 0o664), (0o077, 0o600)])
def test_outputs_take_the_umask(vol_file, tmp_path, capsys, umask, mode):
    out, stats = tmp_path / "p.png", tmp_path / "s.json"
    old = os.umask(umask)
    try:
        rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", out, "--stats", stats], capsys)
    finally:
        os.umask(old)
    assert rc == 0, err
    assert stat.S_IMODE(out.stat().st_mode) == stat.S_IMODE(stats.stat().st_mode) == mode


def test_an_output_written_over_keeps_its_mode(vol_file, tmp_path, capsys):
    # As an editor's save does: a private file stays private whatever the umask, while a new one
    # beside it takes the umask.
    out, new = tmp_path / "p.png", tmp_path / "n.png"
    out.write_bytes(b"old")
    out.chmod(0o600)
    old = os.umask(0o022)
    try:
        for path in (out, new):
            rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, "-o", path], capsys)
            assert rc == 0, err
    finally:
        os.umask(old)
    assert out.read_bytes()[:4] == b"\x89PNG"
    assert (stat.S_IMODE(out.stat().st_mode), stat.S_IMODE(new.stat().st_mode)) == (0o600, 0o644)


def test_a_raw_shape_may_be_given_as_nxnyxnz(tmp_path, capsys):
    raw = tmp_path / "scan.raw"
    np.arange(60, dtype=np.uint16).tofile(raw)
    rc, stdout, err = _run(["info", raw, "--shape", "3x4x5", "--dtype", "uint16"], capsys)
    assert rc == 0 and "dimensions:  3 x 4 x 5" in stdout and "uint16" in stdout, (stdout, err)


@pytest.mark.parametrize("flag", ["--eye", "--look-at", "--light", "--sun"])
def test_a_vector_of_infinities_is_refused_by_its_flag(flag, vol_file, tmp_path, capsys):
    # Let through, "--eye inf,0,0" would be called "the centre of the volume".
    rc, _, err = _run(["render", vol_file, "--iso", 4, "--size", 8, 8, flag, "inf,0,1", "-o", tmp_path / "o.png"],
                      capsys)
    assert rc == 2 and err.count("\n") == 1, err
    assert f"argument {flag}: must be 3 comma-separated finite numbers, got 'inf,0,1'" in err, err


@pytest.fixture
def ctrl_c_handler_kept():
    """`parc.console.main` leaves Ctrl-C ignored for its process's exit; this process goes on."""
    was = signal.getsignal(signal.SIGINT)
    yield
    signal.signal(signal.SIGINT, was)


@pytest.mark.parametrize("threads, ok", [("1", True), ("1024", True), ("1025", False), (" 4 ", True)])
def test_numba_thread_counts_at_the_bounds(threads, ok, monkeypatch, capsys, ctrl_c_handler_kept):
    import parc.cli
    from parc.console import main as console_main
    monkeypatch.setenv("NUMBA_NUM_THREADS", threads)
    monkeypatch.setattr(parc.cli, "main", lambda: 0)      # the check alone, before Numba would start them
    assert console_main() == (0 if ok else 2)
    assert ("must be a whole number from 1 to 1024" in capsys.readouterr().err) != ok


@pytest.mark.parametrize("threads", ["", "  "])
def test_an_empty_numba_thread_count_is_unset_before_numba_reads_it(threads, monkeypatch, capsys,
                                                                   ctrl_c_handler_kept):
    # Numba reads "" with a warning that prints a traceback; unset, it takes its default quietly.
    import parc.cli
    from parc.console import main as console_main
    monkeypatch.setenv("NUMBA_NUM_THREADS", threads)
    seen = []
    monkeypatch.setattr(parc.cli, "main", lambda: seen.append(os.environ.get("NUMBA_NUM_THREADS")) or 0)
    assert console_main() == 0 and seen == [None]
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("argv, loop", [(["render", "{loop}.nrrd", "--size", 8, 8, "-o", "{tmp}/o.png"], "input"),
                                        (["convert", "{loop}.nrrd", "-o", "{tmp}/o.nrrd"], "input"),
                                        (["render", "{vol}", "--iso", 4, "--size", 8, 8, "-o", "{loop}.png"], "output"),
                                        (["render", "{vol}", "--iso", 4, "--size", 8, 8, "-o", "{tmp}/o.png",
                                          "--stats", "{loop}.json"], "output"),
                                        (["make", "sphere", "--size", 4, "-o", "{loop}.nrrd"], "output"),
                                        (["convert", "{vol}", "-o", "{loop}.nrrd"], "output")])
def test_a_link_in_a_loop_is_named_as_input_or_output(argv, loop, vol_file, tmp_path, capsys):
    # Python 3.11's Path.resolve raises RuntimeError ("Symlink loop"), which would end in a
    # traceback; and a file renamed onto the link would leave a file where the loop was.
    suffix = Path(next(a for a in argv if "{loop}" in str(a))).suffix
    first, second = tmp_path / f"loop{suffix}", tmp_path / f"loop2{suffix}"
    first.symlink_to(second)
    second.symlink_to(first)
    argv = [str(a).format(loop=tmp_path / "loop", tmp=tmp_path, vol=vol_file) for a in argv]
    rc, _, err = _run(argv, capsys)
    assert rc == 2 and err.count("\n") == 1 and f"loop{suffix}: a link " in err and "in a loop" in err, err
    assert first.is_symlink() and second.is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["ball.nrrd", first.name, second.name])


def test_convert_through_a_link_keeps_another_headers_samples(tmp_path, capsys):
    # The samples are written beside the file the link leads to, where real.raw is real.nhdr's:
    # the check looks there, not beside the link's name.
    (tmp_path / "b").mkdir()
    theirs = np.arange(27, dtype=np.uint8).reshape(3, 3, 3)
    save_volume(Volume(theirs), tmp_path / "b" / "real.nhdr")
    before = (tmp_path / "b" / "real.raw").read_bytes()
    mine = tmp_path / "mine.npy"
    np.save(mine, np.full((4, 4, 4), 7, np.int16))
    (tmp_path / "b" / "same.mhd").symlink_to("real.mhd")
    rc, _, err = _run(["convert", mine, "-o", tmp_path / "b" / "same.mhd"], capsys)
    assert rc == 2 and err.count("\n") == 1 and "holds real.nhdr's samples" in err, err
    assert (tmp_path / "b" / "real.raw").read_bytes() == before
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == ["real.nhdr", "real.raw", "same.mhd"]


def test_average_mode_on_a_transparent_background_says_how_to_see_it(vol_file, tmp_path, capsys):
    """The average mode's grey is white at that opacity: without --background a note says so; with one, none."""
    render = ["render", vol_file, "--tf", "greyscale", "--mode", "average", "--size", 8, 8, "-o"]
    rc, _, err = _run(render + [tmp_path / "a.png"], capsys)
    assert rc == 0 and "--background 0,0,0" in err
    rc, _, err = _run(render + [tmp_path / "b.png", "--background", "0,0,0"], capsys)
    assert rc == 0 and "--background" not in err
    rc, _, err = _run(render + [tmp_path / "c.png", "--quiet"], capsys)
    assert rc == 0 and err == ""
    # A scene file's average volume, among others, the same: only a scene file giving a
    # background, or the flag, goes without the note; parc compare writes no image.
    volumes = (f"[[volume]]\nfile = '{vol_file}'\niso = 3\n"
               f"[[volume]]\nfile = '{vol_file}'\ntf = 'greyscale'\nmode = 'average'\n")
    for n, (head, extra, noted) in enumerate([("", [], True), ("background = [0, 0, 0]\n", [], False),
                                              ("", ["--background", "0,0,0"], False)]):
        scene = tmp_path / f"s{n}.toml"
        scene.write_text("size = [8, 8]\n" + head + volumes)
        rc, _, err = _run(["render", scene, "-o", tmp_path / f"s{n}.png", *extra], capsys)
        assert rc == 0 and ("--background 0,0,0" in err) == noted, err
    rc, _, err = _run(["compare", tmp_path / "s0.toml", "--repeats", 1], capsys)
    assert rc == 0 and "--background" not in err


def test_a_mip_through_a_faint_table_says_the_image_is_faint(vol_file, tmp_path, capsys):
    """A MIP pixel is one value at its own opacity: a table peaking at 0.2 gives at most 0.2 alpha,
    which the note says; a composite of it, or the ramp presets made opaque for MIP, get no note."""
    tf = tmp_path / "faint.toml"
    tf.write_text("opacity = [[0, 0], [5, 0.2], [10, 0]]\ncolor = [[0, 1, 1, 1], [10, 1, 1, 1]]\n")
    render = ["render", vol_file, "--size", 12, 12, "--tf"]
    rc, _, err = _run(render + [tf, "--mode", "mip", "-o", tmp_path / "a.png"], capsys)
    assert rc == 0 and "faint.toml is at most 0.2 opaque over the data's values: a MIP shows" in err, err
    with Image.open(tmp_path / "a.png") as im:
        alpha = np.asarray(im)[..., 3]
    assert 0 < alpha.max() <= round(0.2 * 255)
    for flags in ([tf, "-o", tmp_path / "b.png"], ["greyscale", "--mode", "mip", "-o", tmp_path / "c.png"]):
        rc, _, err = _run(render + flags, capsys)
        assert rc == 0 and "opaque" not in err, err


def test_a_mip_through_a_table_faint_over_the_data_says_so_whatever_it_reaches_past_them(vol_file, tmp_path,
                                                                                          capsys):
    """The table ends opaque at 1000, far past the ball's largest value (about 9.5): over the data
    it stays below 0.11, and so does the image."""
    tf = tmp_path / "far.toml"
    tf.write_text("opacity = [[0, 0.1], [1000, 1]]\ncolor = [[0, 1, 1, 1], [1000, 1, 1, 1]]\n")
    rc, _, err = _run(["render", vol_file, "--size", 12, 12, "--tf", tf, "--mode", "mip", "-o", tmp_path / "a.png"],
                      capsys)
    assert rc == 0 and "far.toml is at most 0.10" in err and "a MIP shows" in err, err
    with Image.open(tmp_path / "a.png") as im:
        alpha = np.asarray(im)[..., 3]
    assert 0 < alpha.max() <= round(0.11 * 255)


@pytest.mark.parametrize("level, said", [(0.0, "smallest value"), (4.0, "largest value"), (2.0, None)])
def test_an_isovalue_at_an_end_of_the_data_says_its_flat_cells_show_solid(tmp_path, capsys, level, said):
    """Samples clipped to [0, 4] around a ball: at either end, cells flat at the level are surface
    throughout, and the note says so; a level between the ends gets none."""
    k, j, i = np.mgrid[0:12, 0:12, 0:12]
    r = ((i - 5.5) ** 2 + (j - 5.5) ** 2 + (k - 5.5) ** 2) ** 0.5
    vol = save_volume(Volume(np.clip(r - 2.0, 0.0, 4.0).astype(np.float32)), tmp_path / "clipped.nrrd")
    rc, _, err = _run(["render", vol, "--iso", level, "--size", 16, 16, "-o", tmp_path / "a.png"], capsys)
    assert rc == 0, err
    if said is None:
        assert "surface throughout" not in err, err
    else:
        assert (f"isovalue {level:g} is the data's {said}: cells whose samples all equal it are surface "
                "throughout") in err, err


def test_average_mode_in_compare_gets_no_note_about_an_image(capsys):
    """parc compare writes no image: the render's note on the average mode's background is no help there."""
    rc, out, err = _run(["compare", "--tf", "greyscale", "--mode", "average", "--size", 8, 8, "--repeats", 1,
                         "--json"], capsys)
    assert rc == 0 and out and "--background" not in err, err


def test_compare_s_heading_names_the_volume_s_size_once(vol_file, tmp_path, capsys):
    # The built-in volume's name holds its size: "builtin 64x64x64: 64x64x64 uint8" said it twice.
    # A name holding another size only ending in it is no such name.
    raw = tmp_path / "x_112x12x12_float32.raw"
    np.zeros(12 ** 3, np.float32).tofile(raw)
    for argv, heading in ((["compare"], "builtin 64x64x64: uint8, isovalue 127.5, 8x8 pixels"),
                          (["compare", vol_file, "--iso", 4], f"{vol_file}: 12x12x12 float32, isovalue 4, 8x8 pixels"),
                          (["compare", raw, "--shape", "12,12,12", "--iso", 0], f"{raw}: 12x12x12 float32, ")):
        rc, out, err = _run([*argv, "--size", 8, 8, "--repeats", 1, "--methods", "brute", "--quiet"], capsys)
        assert rc == 0 and out.splitlines()[0].startswith(heading), out
