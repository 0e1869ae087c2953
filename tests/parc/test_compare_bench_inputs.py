"""`parc compare`'s step sweep and `parc bench`'s scene sources: what they print is what was run.

Truth: the volumes and steps the tests make themselves (their dims, dtype and
spacing; two steps that differ), and the order of events a progress callback records.
"""
import numpy as np
import pytest

import parc
from data_tools import InputError, Volume, save_volume
from data_tools.synthetic import blobs
from parc.bench import scenes
from parc.comparison import format_step_table, step_sweep


def test_the_bench_names_the_ct_volume_it_read_not_the_stanford_heads_shape(tmp_path):
    # A CThead.nrrd under --data that is not the Stanford head: 4x5x6 int16, spacing 0.5, 1, 1.5.
    data = np.arange(6 * 5 * 4, dtype=np.int16).reshape(6, 5, 4)        # [z, y, x]
    save_volume(Volume(data, spacing=(0.5, 1.0, 1.5)), tmp_path / "CThead.nrrd")
    vol, source = scenes.ct_volume(tmp_path, False)
    assert vol.dims == (4, 5, 6)
    assert "4×5×6 int16" in source and "spacing 0.5, 1, 1.5" in source
    assert "256" not in source and "113" not in source


def test_the_bench_names_the_protein_volumes_it_read(tmp_path, monkeypatch):
    # Files of the real names whose contents are 10³ blobs: the report must say 10³, not 66³.
    for name in ("poship.slc", "neghip.slc"):
        (tmp_path / name).write_bytes(b"")
    small = blobs(10, seed=1)
    small = Volume(np.clip(small.data, 0, 255).astype(np.uint8), name="small")
    monkeypatch.setattr(scenes, "load_volume", lambda path: small)
    _, source = scenes.iron_protein(8, tmp_path)
    assert "10×10×10 uint8" in source
    assert "66" not in source


def _row(step):
    return {"step": step, "brute_seconds": 0.001, "parc_seconds": 0.001, "speedup": 1.0, "brute_samples": 1,
            "parc_samples": 1, "max_color": 0.0, "psnr": float("inf"), "parc_vs_brute": 0.0}


def test_two_steps_of_a_sweep_never_share_a_label():
    steps = [0.5000001, 0.5]
    lines = format_step_table([_row(s) for s in steps]).splitlines()
    labels = [line.split()[0] for line in lines[1:3]]
    assert len(set(labels)) == 2
    assert [float(x) for x in labels] == steps


def test_a_step_sweeps_supercell_is_refused_before_the_reference_is_rendered():
    vol = blobs(12, seed=3)
    scene = parc.Scene(camera=parc.Camera.framing(*vol.bounds), size=(8, 8),
                       volumes=[parc.Translucent(vol, "greyscale")])
    said = []
    with pytest.raises(InputError, match="supercell"):
        step_sweep(scene, [1.0, 0.5], repeats=1, options={"supercell": 0.0001}, progress=said.append)
    assert said == []           # nothing rendered, not even the reference


def test_compare_rows_keep_the_shadow_rays_samples_through_a_translucent_volume():
    # An isosurface lit by a lamp, a translucent volume in the way: shadow rays take samples there.
    surf = blobs(12, seed=3)
    fog = Volume(blobs(12, seed=4).data, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 6.0), name="fog")
    scene = parc.Scene(camera=parc.Camera.framing((0, 0, 0), (11, 11, 17)), size=(12, 12),
                       volumes=[parc.Isosurface(surf, float(surf.data.mean())), parc.Translucent(fog, "greyscale")],
                       lights=[parc.PointLight((5.5, 5.5, 60.0))], shadows=True)
    expected = {m: parc.render(scene, method=m).stats for m in ("brute", "parc")}
    assert expected["brute"]["shadow_samples"] > 0
    for row in parc.compare(scene, repeats=1):
        assert row["shadow_samples"] == expected[row["method"]]["shadow_samples"]
        assert row["shadow_rays"] == expected[row["method"]]["shadow_rays"]


def test_the_tiny_suite_refuses_real_volumes_before_any_work(tmp_path, monkeypatch):
    # --tiny promises tiny synthetic volumes; with --data it would read the 256x256x113 CT head.
    import parc.bench as bench
    from types import SimpleNamespace
    monkeypatch.setattr(bench, "run_bench", lambda *a, **k: pytest.fail("the suite ran"))
    args = SimpleNamespace(tiny=True, quick=False, out=str(tmp_path / "out"), data=str(tmp_path), argv=[])
    with pytest.raises(InputError, match="--tiny"):
        bench.main(args)


def test_a_long_step_label_widens_its_column():
    from parc.comparison import format_step_table
    row = dict(step=0.1 * 3, brute_seconds=1.0, parc_seconds=0.5, speedup=2.0, brute_samples=10,
               parc_samples=5, max_color=0.1, psnr=30.0, parc_vs_brute=0.0)
    lines = format_step_table([row, dict(row, step=0.25)]).splitlines()
    assert lines[1].startswith("0.30000000000000004  ")
    # Every column ends where the heading's does.
    assert len({line.index("1.0000") + 6 for line in lines[1:3]} | {lines[0].index("brute s") + 7}) == 1


@pytest.mark.parametrize("kind", ["missing", "file"])
def test_a_data_folder_named_by_the_environment_must_be_one(kind, tmp_path, monkeypatch):
    # As --data's is: a slip in PARC_DATA_DIR ran the suite on synthetic stand-ins, exit 0.
    import parc.bench as bench
    from types import SimpleNamespace
    monkeypatch.setattr(bench, "run_bench", lambda *a, **k: pytest.fail("the suite ran"))
    place = tmp_path / "data"
    if kind == "file":
        place.write_text("x")
    monkeypatch.setenv("PARC_DATA_DIR", str(place))
    args = SimpleNamespace(tiny=False, quick=True, out=str(tmp_path / "out"), data=None, argv=[])
    words = "not a folder" if kind == "file" else "no such folder"
    with pytest.raises(InputError, match=f"^PARC_DATA_DIR={place}: {words}$"):
        bench.main(args)
    assert not (tmp_path / "out").exists()


def test_a_step_sweep_renders_the_scenes_shadows():
    # Truth: brute's own renders of the shadowed scene, at the step and at a quarter of it.
    vol = blobs(12, seed=3)
    lit = parc.Translucent(vol, "viridis", shade=True)
    light = [parc.DirectionalLight(direction=(0.3, 0.2, -1.0))]
    kw = dict(camera=parc.Camera.framing(*vol.bounds), size=(16, 16), volumes=[lit], lights=light)
    scene = parc.Scene(**kw, shadows=True)

    def brute(step, shadows):
        at = parc.Scene(**{**kw, "volumes": [parc.Translucent(vol, "viridis", shade=True, step=step)]},
                        shadows=shadows)
        return parc.render(at, method="brute").image

    (row,) = step_sweep(scene, [1.0], repeats=1, warmup=0)
    shadowed, reference = brute(1.0, True), brute(0.25, True)
    assert np.abs(shadowed - brute(1.0, False)).max() > 0.01       # the shadows show here
    assert row["parameters"]["shadows"] is True
    assert row["max_color"] == pytest.approx(float(np.abs(shadowed - reference).max()), abs=1e-6)
    assert row["parc_vs_brute"] == 0
