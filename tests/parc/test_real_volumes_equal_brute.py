"""PARC against the unaccelerated caster on the real volumes of ``../shared/data``, from random views.

Truth: ``method="brute"`` on the same scene, as in `test_parc_equals_brute`
and `test_translucent`, whose volumes are small and synthetic. These are
the measured ones the benchmarks use (CT, MRI, protein potentials, the
buckyball), with their own spacings, sizes and value ranges: isosurfaces
at their useful levels and at random ones, and the transfer-function
presets, seen from afar, close up, along an axis and from inside, some
lit and shadowed. Skipped where the data folder is absent.
"""
import functools
from pathlib import Path

import numpy as np
import pytest

from parc import (Camera, DirectionalLight, Isosurface, PointLight, Scene, TransferFunction, Translucent,
                  load_transfer_function, load_volume, render)
from parc.classify import VolumeIndex

DATA = Path(__file__).parents[2].parent / "shared" / "data"
#: Each file with levels where it shows structure (its README's "useful levels").
FILES = {"CThead.nrrd": (600.0, 1500.0), "neghip.slc": (30.0, 80.0, 160.0), "poship.slc": (30.0, 80.0, 160.0),
         "ironProt.vtk": (80.0,), "HeadMRVolume.mhd": (20.0, 60.0), "bucky_32x32x32_uint8.raw": (128.0,),
         "FLAIR.nrrd": ()}
SUPERCELLS = (None, 0.5, 1, 2, 3, 4.5, 8, (2, 3, 1.5))
SIZE = (36, 30)


@functools.lru_cache(maxsize=None)
def _volume(name):
    if not (DATA / name).is_file():
        pytest.skip(f"real data file {DATA / name} not present")
    return load_volume(DATA / name)


def _camera(rng, vol, supercell, iso):
    lo, hi = (np.asarray(b) for b in vol.bounds)
    extent = float(np.linalg.norm(hi - lo))
    view = rng.integers(5)
    if view <= 1:
        # Zoomed up to 12 times: a few cells across the image at most.
        return Camera.framing(lo, hi, azimuth=rng.uniform(0, 360), elevation=rng.uniform(-85, 85),
                              zoom=float(np.exp(rng.uniform(0, np.log(12)))), parallel=view == 1,
                              fov=rng.uniform(10, 80))
    if view == 2:
        axis = rng.integers(3)
        e = np.zeros(3)
        e[axis] = rng.choice([-1.0, 1.0]) * 2.5 * extent
        up = np.zeros(3)
        up[(axis + 1) % 3] = 1.0
        c = (lo + hi) / 2 + rng.uniform(-0.2, 0.2, 3) * (hi - lo) * (np.arange(3) != axis)
        if rng.random() < 0.5:
            return Camera(eye=tuple(c + e), look_at=tuple(c), up=tuple(up),
                          parallel_scale=float(rng.uniform(0.05, 0.5) * extent))
        return Camera(eye=tuple(c + e), look_at=tuple(c), up=tuple(up), fov=float(rng.uniform(3, 40)))
    eye = lo + rng.uniform(0.05, 0.95, 3) * (hi - lo)
    if view == 3 and iso is not None:
        # Inside a possibly contributing supercell, where the paper starts rays at the view plane.
        index = VolumeIndex.of(vol)
        size = 4 if supercell is None else supercell
        pc = np.argwhere(index.classify(iso, size))
        if len(pc):
            edges = index.grid(size).world_edges(vol)
            k, j, i = pc[rng.integers(len(pc))]
            eye = np.array([rng.uniform(edges[0][i], edges[0][i + 1]), rng.uniform(edges[1][j], edges[1][j + 1]),
                            rng.uniform(edges[2][k], edges[2][k + 1])])
    look, up = tuple(eye + rng.normal(size=3)), tuple(rng.normal(size=3))
    if rng.random() < 0.5:
        return Camera(eye=tuple(eye), look_at=look, up=up, fov=float(rng.uniform(20, 100)))
    return Camera(eye=tuple(eye), look_at=look, up=up, parallel_scale=float(rng.uniform(0.05, 0.5) * extent))


def _lights(rng, vol):
    lo, hi = (np.asarray(b) for b in vol.bounds)
    return [DirectionalLight(tuple(rng.normal(size=3))) if rng.random() < 0.5
            else PointLight(tuple(lo + rng.uniform(-0.5, 1.5, 3) * (hi - lo)))
            for _ in range(int(rng.integers(1, 3)))]


def _scene(seed):
    """``(scene, parc's keyword arguments, what it shows)`` for one seed."""
    rng = np.random.default_rng(31_000 + seed)
    name = list(FILES)[seed % len(FILES)]
    vol = _volume(name)
    lo, hi = vol.value_range()
    supercell = SUPERCELLS[int(rng.integers(len(SUPERCELLS)))]
    kw = {"supercell": supercell}
    if seed % 2 == 0:
        levels = FILES[name]
        pick = rng.random()
        if levels and pick < 0.5:
            iso = float(rng.choice(levels))
        elif pick < 0.7:
            iso = float(vol.data.flat[rng.integers(vol.data.size)])       # equal to a sample
        else:
            iso = float(rng.uniform(lo, hi))
        lit = rng.random() < 0.3
        scene = Scene(camera=_camera(rng, vol, supercell, iso), size=SIZE, volumes=[Isosurface(vol, iso)],
                      lights=_lights(rng, vol) if lit else [], shadows=lit and rng.random() < 0.7)
        return scene, kw, f"{name} iso {iso:g} supercell {supercell}"
    mode = ("composite", "composite", "mip", "average")[int(rng.integers(4))]
    if rng.random() < 0.3:
        # A narrow spike of opacity at a random level.
        a, b = sorted(rng.uniform(lo, hi, 2))
        tf = TransferFunction([[a, 0.0], [(a + b) / 2, float(rng.uniform(0.05, 1.0))], [b, 0.0]],
                              [[lo, 1.0, 0.5, 0.2], [hi, 0.2, 0.5, 1.0]])
    elif name == "CThead.nrrd":
        tf = load_transfer_function(str(rng.choice(["ct_skin_bone", "ct_skin", "ct_bone"])))
    else:
        tf = load_transfer_function(str(rng.choice(["greyscale", "viridis"])), (lo, hi))
    shade = mode == "composite" and rng.random() < 0.4
    step = None if rng.random() < 0.7 else float(rng.uniform(0.2, 1.5) * min(vol.spacing))
    lit = shade and rng.random() < 0.5
    shadows = lit and rng.random() < 0.4
    if not shadows:
        kw["buffers"] = ("depth", "bits", "depth,bits")[int(rng.integers(3))]
    scene = Scene(camera=_camera(rng, vol, supercell, None), size=SIZE,
                  volumes=[Translucent(vol, tf, mode=mode, shade=shade, step=step)],
                  lights=_lights(rng, vol) if lit else [], shadows=shadows)
    return scene, kw, f"{name} {mode} shade={shade} lights={len(scene.lights)} shadows={shadows} {kw}"


@pytest.mark.filterwarnings("ignore::parc.ShowsNothingWarning")
@pytest.mark.random_scenes(42)
def test_parc_equals_brute_on_real_volumes(seed, gl):
    scene, kw, where = _scene(seed)
    ref = render(scene, method="brute")
    res = render(scene, method="parc", **kw)
    hit_ref, hit = np.isfinite(ref.depth), np.isfinite(res.depth)
    assert (hit == hit_ref).all(), f"hit masks differ at {np.argwhere(hit != hit_ref)[:5].tolist()}: {where}"
    cell = min(scene.volumes[0].volume.spacing)
    assert np.abs(res.depth[hit] - ref.depth[hit]).max(initial=0) <= 1e-9 * cell, where
    assert np.abs(res.image - ref.image).max() <= 1e-6, where


def test_the_real_scenes_show_something(gl):
    # Scenes that showed nothing could not catch a missed cell: most of them must.
    if not DATA.is_dir():
        pytest.skip(f"real data folder {DATA} not present")
    shown = 0
    for seed in range(42):
        scene, _, _ = _scene(seed)
        shown += bool((render(scene, method="brute").image[..., 3] > 0.01).sum() >= 20)
    assert shown >= 30, shown
