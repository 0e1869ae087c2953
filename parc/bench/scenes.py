"""The benchmark's scenes: the papers' figures, on real volumes when present, synthetic analogues otherwise.

Each builder returns ``(scene, source)``: the `Scene` at the asked image
size and one line saying what was rendered (file or synthetic stand-in),
which the report prints beside its table.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from data_tools import Volume, load_volume
from data_tools.volume import hand_over
from data_tools.synthetic import blobs, ct_phantom, floor, neuron

from ..camera import Camera
from ..scene import Isosurface, PointLight, Scene, Translucent
from ..transfer import TransferFunction


def default_data_dir():
    """``$PARC_DATA_DIR``, else ``../shared/data`` beside the checkout."""
    env = os.environ.get("PARC_DATA_DIR")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2].parent / "shared" / "data"


def _missing(data_dir, names):
    """Why a scene stands in a synthetic volume for the real one(s)."""
    return "the tiny suite's stand-in" if data_dir is None else f"{names} not found"


def _describe(vol):
    """A loaded volume as the report names it: ``256×256×113 int16, spacing 1, 1, 2``."""
    from data_tools.info import exact_text
    return (f"{'×'.join(map(str, vol.dims))} {vol.dtype}, spacing {', '.join(map(exact_text, vol.spacing))}")


def _real(data_dir, name):
    if data_dir is None:
        return None
    path = Path(data_dir) / name
    return path if path.is_file() else None


def ct_volume(data_dir, tiny):
    """The CT head (Stanford CThead, 256x256x113 int16, spacing 1,1,2) or a CT-like phantom of its shape."""
    path = _real(data_dir, "CThead.nrrd")
    if path is not None:
        # What was read, not what the Stanford CT head is: a file of that name under --data may be another.
        vol = load_volume(path)
        return vol, f"`{path.name}` ({_describe(vol)})"
    dims = (32, 32, 16) if tiny else (256, 256, 113)
    vol = ct_phantom(dims, spacing=(1.0, 1.0, 2.0))
    return vol, (f"synthetic CT phantom {dims[0]}×{dims[1]}×{dims[2]} int16, spacing 1, 1, 2 "
                 f"({_missing(data_dir, '`CThead.nrrd`')})")


def _ct_camera(vol):
    # CThead's slices run from the top of the head down: look with -z up. The phantom standing in
    # for it is built head up, its face to -y as CThead's: seen so, it would stand on its head.
    # Its view is CThead's mirrored in z.
    if vol.meta.get("synthetic") == "ct_phantom":
        return Camera.framing(*vol.bounds, up=(0.0, 0.0, 1.0), azimuth=160.0, elevation=-20.0, zoom=1.15)
    return Camera.framing(*vol.bounds, up=(0.0, 0.0, -1.0), azimuth=200.0, elevation=-20.0, zoom=1.15)


def ct_translucent(size, data_dir=None, tiny=False):
    """Table 1 (Sobierajski & Avila's Fig. 11): the CT translucent, skin veil over bone, composite."""
    vol, source = ct_volume(data_dir, tiny)
    scene = Scene(camera=_ct_camera(vol), size=(size, size), background=(0.0, 0.0, 0.0),
                  volumes=[Translucent(vol, "ct_skin_bone", mode="composite")])
    return scene, source


def ct_iso(size, iso, data_dir=None, tiny=False):
    """A CT isosurface (skin 600 or bone 1500): Parker et al.'s Table 1 and the supercell sweep."""
    vol, source = ct_volume(data_dir, tiny)
    scene = Scene(camera=_ct_camera(vol), size=(size, size), background=(0.0, 0.0, 0.0),
                  volumes=[Isosurface(vol, float(iso), color=(0.95, 0.85, 0.75) if iso < 1000 else (1.0, 1.0, 0.95))])
    return scene, source


#: The negative potential shown translucent around the positive isosurface (Fig. 12).
PROTEIN_TF = TransferFunction(((20.0, 0.0), (60.0, 0.05), (160.0, 0.25), (255.0, 0.4)),
                              ((20.0, 0.2, 0.3, 0.9), (160.0, 0.4, 0.7, 1.0), (255.0, 0.9, 0.95, 1.0)),
                              name="protein_negative", description="blue haze of the negative potential")


def iron_protein(size, data_dir=None, tiny=False):
    """Table 2 (Fig. 12): the positive potential's isosurface (80) inside the negative one, translucent."""
    pos, neg = _real(data_dir, "poship.slc"), _real(data_dir, "neghip.slc")
    if pos is not None and neg is not None:
        vp, vn = load_volume(pos), load_volume(neg)
        source = (f"`poship.slc` isosurface 80 ({_describe(vp)}) inside `neghip.slc` translucent "
                  f"({_describe(vn)})")
    else:
        n = 24 if tiny else 66
        vp, vn = blobs(n, seed=3), blobs(n, seed=4)
        vp = _to_uint8(vp)
        vn = _to_uint8(vn)
        source = (f"synthetic blobs {n}³ uint8: an isosurface 80 inside a translucent field "
                  f"({_missing(data_dir, ' and '.join(f'`{name}`' for name, path in (('poship.slc', pos), ('neghip.slc', neg)) if path is None))})")
    cam = Camera.framing(*vp.bounds, azimuth=30.0, elevation=20.0, zoom=1.1)
    scene = Scene(camera=cam, size=(size, size), background=(0.0, 0.0, 0.0),
                  volumes=[Isosurface(vp, 80.0, color=(1.0, 0.6, 0.3)), Translucent(vn, PROTEIN_TF)])
    return scene, source


def _to_uint8(vol):
    d = vol.data.astype(np.float64)
    d = np.clip(np.rint(255.0 * (d - d.min()) / max(float(d.max() - d.min()), 1e-12)), 0, 255).astype(np.uint8)
    return Volume(hand_over(d), spacing=vol.spacing, origin=vol.origin, name=vol.name)


def neuron_floor(size, data_dir=None, tiny=False):
    """Table 3 (Fig. 13): a neuron-like volume casting two shadows on a volumetric floor, two point lights."""
    n = 32 if tiny else 128
    cell = neuron(n)
    ground = floor(n)
    scale = n / 128.0
    ground = Volume(ground.data, spacing=(2.0 * scale, 2.0 * scale, scale),
                    origin=(-64 * scale, -64 * scale, -12 * scale), name=ground.name)
    cell = Volume(cell.data, spacing=(scale, scale, scale), name=cell.name)
    s = lambda *v: tuple(scale * x for x in v)  # noqa: E731
    cam = Camera(eye=s(64, -250, 190), look_at=s(64, 64, 30), up=(0.0, 0.0, 1.0), fov=38.0)
    scene = Scene(camera=cam, size=(size, size), background=(0.05, 0.05, 0.08), shadows=True,
                  volumes=[Isosurface(cell, 80.0, color=(0.95, 0.78, 0.55)),
                           Isosurface(ground, 127.5, color=(0.6, 0.65, 0.75))],
                  lights=[PointLight(position=s(230, -60, 260), color=(1.0, 0.95, 0.85), intensity=0.7),
                          PointLight(position=s(-110, -20, 240), color=(0.75, 0.85, 1.0), intensity=0.5)])
    source = (f"synthetic neuron {n}³ uint8 (isosurface 80) on a synthetic volumetric floor, two point lights "
              f"(the paper's confocal neuron is not distributed)")
    return scene, source


