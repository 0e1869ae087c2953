"""NIfTI and TIFF stacks: read through nibabel and tifffile, the files written by those libraries themselves.

Truth: the array and geometry each file was written with. Bad files, and a
missing library, get one InputError line naming the file.
"""
from __future__ import annotations

import gzip
import json
import lzma
import struct
import sys
import tracemalloc
import zlib

import nibabel as nib
import numpy as np
import pytest
import tifffile

from data_tools import InputError, Volume, load_volume, memory
from data_tools.io import save_volume
from data_tools.io._common import REORIENTED_NOTE

from load_errors import fails

RNG = np.random.default_rng(7)
ZYX = (7, 5, 6)


def _data(dtype):
    """A [z, y, x] array using much of ``dtype``'s range."""
    if np.dtype(dtype).kind == "f":
        return (RNG.normal(size=ZYX) * 1e3).astype(dtype)
    info = np.iinfo(dtype)
    return RNG.integers(info.min, info.max, ZYX, endpoint=True).astype(dtype)


def _nifti(path, zyx, affine, cls=nib.Nifti1Image, slope_inter=None):
    img = cls(zyx.T, affine)           # nibabel arrays are [x, y, z]
    if slope_inter is not None:
        img.header.set_slope_inter(*slope_inter)
    nib.save(img, str(path))
    return path


@pytest.mark.parametrize("ext", [".nii", ".nii.gz", ".NII.GZ"])
@pytest.mark.parametrize("dtype", ["uint8", "int16", "uint16", "int32", "float32", "float64"])
def test_nifti_round_trip(tmp_path, ext, dtype):
    a = _data(dtype)
    affine = np.diag([0.5, 0.75, 2.0, 1.0])
    affine[:3, 3] = (10.0, -20.0, 30.5)
    vol = load_volume(_nifti(tmp_path / f"v{ext}", a, affine))
    assert vol.data.dtype == a.dtype and vol.data.flags.c_contiguous
    assert np.array_equal(vol.data, a)
    assert vol.spacing == (0.5, 0.75, 2.0) and vol.origin == (10.0, -20.0, 30.5)
    assert vol.meta["format"] == "nifti" and "note" not in vol.meta


def test_nifti2(tmp_path):
    a = _data("int16")
    vol = load_volume(_nifti(tmp_path / "v.nii", a, np.diag([1.0, 2.0, 3.0, 1.0]), cls=nib.Nifti2Image))
    assert np.array_equal(vol.data, a) and vol.spacing == (1.0, 2.0, 3.0) and vol.meta["version"] == 2


def test_nifti_scaled_samples_are_the_scaled_values(tmp_path):
    a = _data("int16")
    vol = load_volume(_nifti(tmp_path / "s.nii.gz", a, np.eye(4), slope_inter=(0.5, -1024.0)))
    assert vol.data.dtype == np.float32
    assert np.array_equal(vol.data, (a.astype(np.float64) * 0.5 - 1024.0).astype(np.float32))
    assert vol.meta["scaling"] == {"slope": 0.5, "inter": -1024.0}


@pytest.mark.parametrize("kind", ["flipped", "rotated"])
def test_nifti_orientation_reduced_to_spacings_with_a_note(tmp_path, kind):
    if kind == "flipped":
        affine = np.diag([-0.8, 0.8, 1.6, 1.0])     # LAS, as many scanners write
        words = "flipped"
    else:
        c, s = np.cos(0.3), np.sin(0.3)
        affine = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]) @ np.diag([0.8, 0.8, 1.6, 1])
        words = "rotated"
    affine[:3, 3] = (4.0, 5.0, 6.0)
    a = _data("uint8")
    vol = load_volume(_nifti(tmp_path / "o.nii", a, affine))
    assert np.array_equal(vol.data, a)
    assert np.allclose(vol.spacing, (0.8, 0.8, 1.6)) and vol.origin == (4.0, 5.0, 6.0)
    assert words in vol.meta["note"] and vol.meta["reoriented"]
    given = load_volume(_nifti(tmp_path / "o.nii", a, affine), spacing=(1, 2, 3))
    assert given.spacing == (1.0, 2.0, 3.0) and given.meta["note"] == REORIENTED_NOTE


def test_nifti_trailing_axis_of_one_is_a_volume(tmp_path):
    a = _data("uint8")
    nib.save(nib.Nifti1Image(a.T[..., None], np.eye(4)), str(tmp_path / "t.nii"))
    assert np.array_equal(load_volume(tmp_path / "t.nii").data, a)


def test_nifti_time_series_is_refused(tmp_path):
    nib.save(nib.Nifti1Image(np.zeros((6, 5, 7, 3), np.float32), np.eye(4)), str(tmp_path / "ts.nii"))
    fails(tmp_path / "ts.nii", "3 volumes: save one as a file of its own")
    # The way the message gives makes a volume that reads, placed as the series was.
    nib.save(nib.load(tmp_path / "ts.nii").slicer[..., 1], str(tmp_path / "one.nii"))
    assert load_volume(tmp_path / "one.nii").dims == (6, 5, 7)


def test_nifti_bad_files(tmp_path):
    (tmp_path / "junk.nii").write_bytes(b"not a nifti header" * 30)
    fails(tmp_path / "junk.nii", "not a NIfTI file")
    good = _nifti(tmp_path / "good.nii.gz", _data("float32"), np.eye(4)).read_bytes()
    # Cut inside the header: nibabel said it "cannot work out file type".
    (tmp_path / "cut.nii.gz").write_bytes(good[: len(good) // 2])
    fails(tmp_path / "cut.nii.gz", "not a NIfTI file, or its header is cut short")
    ramp = np.arange(8000, dtype=np.int16).reshape(20, 20, 20)          # compresses past its header
    whole = _nifti(tmp_path / "ramp.nii.gz", ramp, np.eye(4)).read_bytes()
    (tmp_path / "short.nii.gz").write_bytes(whole[: 3 * len(whole) // 4])
    fails(tmp_path / "short.nii.gz", "truncated: the compressed samples end early")


def test_nifti_header_claiming_more_than_the_file_holds_is_truncated_not_out_of_memory(tmp_path):
    # dim 32767^3 in a 1 kB file: nibabel allocated first, and the message was "not enough memory".
    import struct
    p = _nifti(tmp_path / "v.nii", np.zeros((10, 9, 8), np.uint8), np.eye(4))
    raw = bytearray(p.read_bytes())
    struct.pack_into("<4h", raw, 40, 3, 32767, 32767, 32767)
    p.write_bytes(bytes(raw))
    fails(p, f"truncated: its header's 32767x32767x32767 uint8 samples need {352 + 32767 ** 3} bytes, "
             f"the file has {len(raw)}")


@pytest.mark.parametrize("slope", [None, 2.0])
def test_nifti_gz_header_claiming_more_than_memory_states_it(tmp_path, slope):
    # Compressed, its length is known once inflated (and the stream checked), before nibabel
    # allocates what the header claims: the message gives both.
    import gzip
    import struct
    p = _nifti(tmp_path / "v.nii", np.zeros((10, 9, 8), np.uint8), np.eye(4),
               slope_inter=None if slope is None else (slope, 0.0))
    raw = bytearray(p.read_bytes())
    struct.pack_into("<4h", raw, 40, 3, 32767, 32767, 32767)
    (tmp_path / "v.nii.gz").write_bytes(gzip.compress(bytes(raw)))
    fails(tmp_path / "v.nii.gz", f"truncated: its header's 32767x32767x32767 uint8 samples need "
                                 f"{352 + 32767 ** 3} bytes, the compressed data hold {len(raw)}")


@pytest.mark.parametrize("cls, offset", [(nib.Nifti1Image, 352), (nib.Nifti2Image, 544)])
def test_nifti_whose_samples_would_start_in_its_header_is_refused(tmp_path, cls, offset):
    # vox_offset 0 in a .nii: nibabel read from byte 0, the header's bytes as samples.
    import struct
    p = _nifti(tmp_path / "v.nii", _data("int16"), np.eye(4), cls=cls)
    raw = bytearray(p.read_bytes())
    at, fmt = (108, "<f") if cls is nib.Nifti1Image else (168, "<q")    # vox_offset's place and type
    assert struct.unpack_from(fmt, raw, at)[0] == offset
    struct.pack_into(fmt, raw, at, 0)
    p.write_bytes(bytes(raw))
    fails(p, f"vox_offset 0 lies inside the header; a .nii file's samples start at byte {offset} or later")


def test_tiff_imagej_stack_with_its_voxel_size(tmp_path):
    a = _data("uint16")
    p = tmp_path / "ij.tif"
    tifffile.imwrite(p, a, imagej=True, resolution=(1 / 0.25, 1 / 0.5),
                     metadata={"spacing": 2.0, "unit": "um", "axes": "ZYX"})
    vol = load_volume(p)
    assert vol.data.dtype == np.uint16 and np.array_equal(vol.data, a)
    assert vol.spacing == (0.25, 0.5, 2.0) and vol.meta["unit"] == "um" and "note" not in vol.meta


def test_ome_tiff_physical_sizes(tmp_path):
    a = _data("float32")
    p = tmp_path / "v.ome.tiff"
    tifffile.imwrite(p, a, ome=True,
                     metadata={"axes": "ZYX", "PhysicalSizeX": 0.3, "PhysicalSizeY": 0.4, "PhysicalSizeZ": 1.5})
    vol = load_volume(p)
    assert np.array_equal(vol.data, a) and vol.spacing == (0.3, 0.4, 1.5)


@pytest.mark.parametrize("byteorder", ["<", ">"])
def test_plain_tiff_stack_gets_unit_spacing_and_a_note(tmp_path, byteorder):
    a = _data("int16")
    p = tmp_path / "plain.tiff"
    tifffile.imwrite(p, a, photometric="minisblack", byteorder=byteorder)
    vol = load_volume(p)
    assert vol.data.dtype.isnative and np.array_equal(vol.data, a)
    assert vol.spacing == (1.0, 1.0, 1.0) and "--spacing" in vol.meta["note"]
    given = load_volume(p, spacing=(1, 2, 3))
    assert given.spacing == (1, 2, 3) and "note" not in given.meta


def test_tiff_pages_written_one_by_one_are_stacked(tmp_path):
    a = _data("uint8")
    p = tmp_path / "pages.tif"
    with tifffile.TiffWriter(p) as w:
        for page in a:
            w.write(page, contiguous=False)
    assert np.array_equal(load_volume(p).data, a)


@pytest.mark.parametrize("metadata", [{}, {"axes": "YX"}, {"name": "slice"}])
def test_tiff_pages_each_with_its_own_description_are_stacked_without_tifffile_series(tmp_path, monkeypatch,
                                                                                      metadata):
    # Each page's description states that page alone: tifffile makes a series of each page and
    # sorts every series against every other, in time quadratic in the pages (minutes for 20,000).
    a = _data("uint16")
    p = tmp_path / "pages.tif"
    with tifffile.TiffWriter(p) as w:
        for page in a:
            w.write(page, photometric="minisblack", metadata=metadata)
    with tifffile.TiffFile(p) as tif:
        assert json.loads(tif.pages[-1].description)["shape"] == [5, 6]

    def unsorted(tif):
        raise RuntimeError("the pages were sorted into series")

    monkeypatch.setattr(tifffile.TiffFile, "series", property(unsorted))
    vol = load_volume(p)
    assert vol.data.dtype == np.uint16 and np.array_equal(vol.data, a)
    assert vol.meta["axes"] == "ZYX" and vol.spacing == (1.0, 1.0, 1.0) and "--spacing" in vol.meta["note"]


@pytest.mark.parametrize("odd", [np.zeros((5, 7), np.uint8), np.zeros((5, 6), np.uint16)], ids=["size", "type"])
def test_tiff_pages_each_with_its_own_description_that_differ_are_refused(tmp_path, odd):
    a = _data("uint8")
    p = tmp_path / "pages.tif"
    with tifffile.TiffWriter(p) as w:
        for k, page in enumerate(a):
            w.write(odd if k == 4 else page, photometric="minisblack")
    fails(p, f"its {len(a)} TIFF pages differ in size or sample type")


@pytest.mark.parametrize("byte, flip", [(28, 0xFF), (43, 0xFF), (38, 0x01)])
def test_tiff_whose_tags_do_not_hold_together_is_called_corrupt(tmp_path, byte, flip):
    # tifffile's own code slipped on them: "integer division or modulo by zero", a bare
    # AssertionError, "tuple index out of range".
    p = tmp_path / "c.tif"
    tifffile.imwrite(p, np.zeros((10, 9, 8), np.uint8))
    raw = bytearray(p.read_bytes())
    raw[byte] ^= flip
    p.write_bytes(bytes(raw))
    fails(p, "cannot read TIFF file: corrupt file: its header or tags do not hold together (")


def test_tiff_refusals(tmp_path):
    tifffile.imwrite(tmp_path / "rgb.tif", np.zeros((6, 5, 4, 3), np.uint8), photometric="rgb")
    fails(tmp_path / "rgb.tif", "samples per pixel")
    tifffile.imwrite(tmp_path / "one.tif", np.zeros((5, 4), np.uint8))
    fails(tmp_path / "one.tif", "single 2-D image")
    tifffile.imwrite(tmp_path / "hyper.tif", np.zeros((2, 3, 4, 5, 6), np.uint16), imagej=True,
                     metadata={"axes": "TZCYX"})
    fails(tmp_path / "hyper.tif", "needs 3")
    tifffile.imwrite(tmp_path / "chan.tif", np.zeros((3, 5, 6), np.uint16), imagej=True, metadata={"axes": "CYX"})
    fails(tmp_path / "chan.tif", "channels")
    with tifffile.TiffWriter(tmp_path / "mixed.tif") as w:
        w.write(np.zeros((5, 6), np.uint8), contiguous=False)
        w.write(np.zeros((5, 7), np.uint8), contiguous=False)
    fails(tmp_path / "mixed.tif", "differ")
    (tmp_path / "junk.tif").write_bytes(b"II*\x00" + b"\xff" * 40)
    fails(tmp_path / "junk.tif", "TIFF")


@pytest.mark.parametrize("name, module, extra", [("v.nii.gz", "nibabel", "nifti"), ("v.tif", "tifffile", "tiff")])
def test_missing_library_says_how_to_install_it(tmp_path, monkeypatch, name, module, extra):
    p = tmp_path / name
    p.write_bytes(b"\x00" * 400)
    monkeypatch.setitem(sys.modules, module, None)    # import now raises ImportError
    msg = fails(p, module)
    assert f"parc[{extra}]" in msg


def test_a_nifti_volume_renders_as_the_same_array_does(tmp_path):
    from parc import Camera, Isosurface, Scene, render
    k, j, i = np.mgrid[0:10, 0:12, 0:14]
    a = (((i - 6.5) ** 2 + (j - 5.5) ** 2 + 2 * (k - 4.5) ** 2) ** 0.5).astype(np.float32)
    affine = np.diag([1.0, 1.0, 0.5, 1.0])
    affine[:3, 3] = (-3.0, 2.0, 1.0)
    from_file = load_volume(_nifti(tmp_path / "ball.nii.gz", a, affine))
    direct = Volume(a, spacing=(1.0, 1.0, 0.5), origin=(-3.0, 2.0, 1.0))
    lo, hi = direct.bounds
    images = [render(Scene(camera=Camera.framing(lo, hi), size=(24, 20), volumes=[Isosurface(v, 4.0)]),
                     method="brute") for v in (from_file, direct)]
    assert np.isfinite(images[1].depth).any()
    assert np.array_equal(images[0].depth, images[1].depth) and np.array_equal(images[0].image, images[1].image)


def test_writing_nifti_or_tiff_is_refused_clearly(tmp_path):
    for name in ("v.nii", "v.tif"):
        with pytest.raises(InputError, match="supported"):
            save_volume(Volume(_data("uint8")), tmp_path / name)


def _slices(folder, zyx, names=None, **kw):
    folder.mkdir()
    names = names or [f"slice{z + 1}.tif" for z in range(len(zyx))]
    for name, image in zip(names, zyx):
        tifffile.imwrite(folder / name, image, **kw)
    return folder


def test_folder_of_slices_in_natural_order(tmp_path):
    a = RNG.integers(0, 4000, (12, 5, 6)).astype(np.uint16)      # 12 slices: slice10 sorts after slice9
    folder = _slices(tmp_path / "seq", a, imagej=True, resolution=(1 / 0.25, 1 / 0.5), metadata={"unit": "um"})
    (folder / "notes.txt").write_text("not a slice")
    (folder / "._slice0.tif").write_bytes(b"\x00\x05\x16\x07" + bytes(4092))     # macOS's attributes
    vol = load_volume(folder)
    assert np.array_equal(vol.data, a) and vol.spacing == (0.25, 0.5, 1.0)
    assert "12 slices" in vol.meta["note"] and "--spacing" in vol.meta["note"]
    given = load_volume(folder, spacing=(0.25, 0.5, 2.0))
    assert given.spacing == (0.25, 0.5, 2.0) and "note" not in given.meta


def test_folder_refusals(tmp_path):
    a = _data("uint8")
    folder = _slices(tmp_path / "mixed", a[:3])
    tifffile.imwrite(folder / "slice4.tif", np.zeros((5, 7), np.uint8))
    fails(folder, "slices must match")
    fails(_slices(tmp_path / "one", a[:1]), "at least 2")
    (tmp_path / "dicom").mkdir()
    (tmp_path / "dicom" / "IM0001.dcm").write_bytes(b"\0" * 132 + b"DICM")
    fails(tmp_path / "dicom", "DICOM")
    (tmp_path / "empty").mkdir()
    fails(tmp_path / "empty", "no .tif slices")
    stacks = _slices(tmp_path / "stacks", [a, a], photometric="minisblack")
    fails(stacks, "2-D image")


def test_lzw_tiff_reads_or_says_to_install_imagecodecs(tmp_path):
    from PIL import Image
    a = _data("uint8")
    p = tmp_path / "lzw.tif"
    pages = [Image.fromarray(page) for page in a]
    pages[0].save(p, compression="tiff_lzw", save_all=True, append_images=pages[1:])
    try:
        import imagecodecs  # noqa: F401
    except ImportError:
        fails(p, "pip install imagecodecs")
    else:
        assert np.array_equal(load_volume(p).data, a)


def test_nifti_without_qform_or_sform_is_placed_at_zero(tmp_path):
    # NIfTI's method 1: the pixel dimensions alone, voxel (0, 0, 0) at the origin, nothing flipped.
    data = np.arange(60, dtype=np.int16).reshape(5, 4, 3)         # [x, y, z] as nibabel holds it
    img = nib.Nifti1Image(data, None)
    img.header.set_zooms((0.5, 0.75, 2.25))
    img.set_qform(None, 0)
    img.set_sform(None, 0)
    nib.save(img, tmp_path / "plain.nii")
    vol = load_volume(tmp_path / "plain.nii")
    assert np.array_equal(vol.data, data.T)
    assert vol.spacing == (0.5, 0.75, 2.25) and vol.origin == (0.0, 0.0, 0.0) and "note" not in vol.meta


def test_ome_tiff_units_of_each_axis(tmp_path):
    # 500 nm across, 2 µm between slices: the z spacing in x's unit is 2000.
    data = np.arange(60, dtype=np.uint16).reshape(3, 4, 5)
    tifffile.imwrite(tmp_path / "u.ome.tif", data, ome=True, metadata={
        "axes": "ZYX", "PhysicalSizeX": 500, "PhysicalSizeXUnit": "nm", "PhysicalSizeY": 500,
        "PhysicalSizeYUnit": "nm", "PhysicalSizeZ": 2, "PhysicalSizeZUnit": "µm"})
    vol = load_volume(tmp_path / "u.ome.tif")
    assert np.array_equal(vol.data, data)
    assert vol.spacing == (500.0, 500.0, 2000.0) and vol.meta["unit"] == "nm"


@pytest.mark.parametrize("unit, xy", [("cm", 0.05), ("mm", 0.5)])
def test_imagej_tiff_in_centimetres(tmp_path, unit, xy):
    # ImageJ writes a cm calibration as pixels per cm (ResolutionUnit 3); the slices' spacing is in its unit.
    data = np.arange(60, dtype=np.uint16).reshape(3, 4, 5)
    tifffile.imwrite(tmp_path / "cm.tif", data, imagej=True, resolution=(20.0, 20.0), resolutionunit="CENTIMETER",
                     metadata={"spacing": 0.2, "unit": unit, "axes": "ZYX"})
    vol = load_volume(tmp_path / "cm.tif")
    assert np.array_equal(vol.data, data) and "note" not in vol.meta
    assert vol.spacing == pytest.approx((xy, xy, 0.2)) and vol.meta["unit"] == unit


@pytest.mark.parametrize("unit, per_inch, xy", [("inch", 200.0, 1 / 200), ("cm", 100.0, 2.54 / 100)])
def test_imagej_tiff_calibrated_per_inch(tmp_path, unit, per_inch, xy):
    # ResolutionUnit 2: pixels per inch, whatever ImageJ's unit; an inch is 2.54 cm.
    data = np.arange(60, dtype=np.uint16).reshape(3, 4, 5)
    tifffile.imwrite(tmp_path / "in.tif", data, imagej=True, resolution=(per_inch, per_inch),
                     resolutionunit="INCH", metadata={"spacing": 0.2, "unit": unit, "axes": "ZYX"})
    vol = load_volume(tmp_path / "in.tif")
    assert np.array_equal(vol.data, data) and "note" not in vol.meta
    assert vol.spacing == pytest.approx((xy, xy, 0.2)) and vol.meta["unit"] == unit


def test_nibabel_writes_nothing_of_its_own_on_stderr(tmp_path, caplog):
    # Its header checks log "pixdim[1,2,3] should be positive": a line before or beside ours.
    img = nib.Nifti1Image(np.zeros((5, 4, 3), np.uint8), None)
    img.set_qform(None, 0)
    img.set_sform(None, 0)
    nib.save(img, tmp_path / "neg.nii")
    raw = bytearray((tmp_path / "neg.nii").read_bytes())
    raw[80:92] = np.array([-2.0, 3.0, 4.0], "<f4").tobytes()          # pixdim[1:4]
    (tmp_path / "neg.nii").write_bytes(bytes(raw))
    (tmp_path / "cut.nii").write_bytes(bytes(raw[:-10]))
    neg = load_volume(tmp_path / "neg.nii")
    assert neg.spacing == (2.0, 3.0, 4.0)
    assert neg.meta["note"] == "the header gives voxel size -2 along x (pixdim); 2 was used"
    fails(tmp_path / "cut.nii", "truncated: its header's 5x4x3 uint8 samples need 412 bytes, the file has 402")
    assert [r.getMessage() for r in caplog.records] == []


@pytest.mark.parametrize("qform", [0, 1])
def test_a_nifti_voxel_size_of_0_is_said_to_be_taken_as_1(tmp_path, qform):
    # nibabel sets a pixdim of 0 to 1 as it loads the header, and says so only in its log; the
    # qform's affine takes the sizes from pixdim too.
    img = nib.Nifti1Image(np.zeros((5, 4, 3), np.uint8), None)
    img.set_qform(np.eye(4) if qform else None, qform)
    img.set_sform(None, 0)
    nib.save(img, tmp_path / "zero.nii")
    raw = bytearray((tmp_path / "zero.nii").read_bytes())
    raw[80:92] = np.array([2.0, 0.0, 0.0], "<f4").tobytes()          # pixdim[1:4]
    (tmp_path / "zero.nii").write_bytes(bytes(raw))
    vol = load_volume(tmp_path / "zero.nii")
    assert vol.spacing == (2.0, 1.0, 1.0)
    assert vol.meta["note"] == ("the header gives voxel size 0 along y (pixdim); 1 was used; "
                                "voxel size 0 along z (pixdim); 1 was used")


def test_rotated_anisotropic_nifti_spacing_is_nibabels_zooms(tmp_path):
    # A 90-degree turn about z times diag(1, 2, 3): the spacing is the affine's column norms.
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    aff = np.eye(4)
    aff[:3, :3] = rot @ np.diag([1.0, 2.0, 3.0])
    nib.save(nib.Nifti1Image(np.zeros((4, 3, 2), np.float32), aff), tmp_path / "r.nii")
    vol = load_volume(tmp_path / "r.nii")
    np.testing.assert_allclose(vol.spacing, nib.load(tmp_path / "r.nii").header.get_zooms()[:3])
    np.testing.assert_allclose(vol.spacing, (1.0, 2.0, 3.0))


def test_nifti_intercept_without_slope_is_applied(tmp_path):
    # CT stored with scl_inter = -1024 and scl_slope = 1: nibabel's values, as float32, and the scaling noted.
    import struct
    stored = np.arange(24, dtype=np.int16).reshape(4, 3, 2) * 50          # nibabel's [x, y, z]
    nib.save(nib.Nifti1Image(stored, np.eye(4)), tmp_path / "ct.nii")
    raw = bytearray((tmp_path / "ct.nii").read_bytes())
    raw[112:120] = struct.pack("<ff", 1.0, -1024.0)                          # scl_slope, scl_inter
    (tmp_path / "ct.nii").write_bytes(bytes(raw))
    truth = nib.load(tmp_path / "ct.nii").get_fdata()
    np.testing.assert_allclose(truth, stored - 1024.0)
    vol = load_volume(tmp_path / "ct.nii")
    np.testing.assert_allclose(vol.data, truth.transpose(2, 1, 0))
    assert vol.data.dtype == np.float32
    assert vol.meta["scaling"] == {"slope": 1.0, "inter": -1024.0}


@pytest.mark.parametrize("name", ["s.nii", "s.nii.gz"])
@pytest.mark.parametrize("slope", [np.inf, -np.inf])
def test_nifti_infinite_scl_slope_is_refused(tmp_path, name, slope):
    # nibabel reads it as no scaling, as it reads 0 and NaN: the samples came out unscaled, where a
    # slope of 3e38 scales them past float32 and is refused. The standard turns scaling off at 0 only.
    stored = np.arange(24, dtype=np.int16).reshape(4, 3, 2)
    nib.save(nib.Nifti1Image(stored, np.eye(4)), tmp_path / "s.nii")
    raw = bytearray((tmp_path / "s.nii").read_bytes())
    raw[112:120] = struct.pack("<ff", slope, 0.0)                           # scl_slope, scl_inter
    p = tmp_path / name
    p.write_bytes(gzip.compress(bytes(raw)) if name.endswith(".gz") else bytes(raw))
    fails(p, f"scl_slope is {slope:g}, not a finite number; the samples cannot be scaled by it")
    # NaN is how nibabel writes "no scaling" (its default header): read unscaled, as nibabel reads it.
    raw[112:120] = struct.pack("<ff", np.nan, np.nan)
    p.write_bytes(gzip.compress(bytes(raw)) if name.endswith(".gz") else bytes(raw))
    vol = load_volume(p)
    assert vol.data.dtype == np.int16 and "scaling" not in vol.meta
    np.testing.assert_array_equal(vol.data, stored.T)


def _placed_files(tmp_path, arr, write_slc):
    """``arr`` (uint8, z, y, x) in every format a reader takes, each placed at spacing 3 and
    origin 7 where the format holds a placement: ``{name: (path, load options)}``."""
    vol = Volume(arr, spacing=(3, 3, 3), origin=(7, 7, 7))
    files = {ext: (save_volume(vol, tmp_path / f"v{ext}"), {}) for ext in (".nrrd", ".nhdr", ".npy", ".mhd",
                                                                           ".mha", ".vtk")}
    nz, ny, nx = arr.shape
    files[".raw"] = (save_volume(vol, tmp_path / f"r_{nx}x{ny}x{nz}_uint8.raw"), {})
    files[".slc"] = (write_slc(tmp_path / "v.slc", arr, spacing=(3.0, 3.0, 3.0)), {})
    files[".nii"] = (_nifti(tmp_path / "v.nii", arr, np.diag([3.0, 3.0, 3.0, 1.0])), {})
    tifffile.imwrite(tmp_path / "v.tif", arr, imagej=True, resolution=(1 / 3, 1 / 3),
                     metadata={"spacing": 3.0, "axes": "ZYX"})
    files[".tif"] = (tmp_path / "v.tif", {})
    (tmp_path / "slices").mkdir()
    for k in range(nz):
        tifffile.imwrite(tmp_path / "slices" / f"z{k}.tif", arr[k])
    files["tif folder"] = (tmp_path / "slices", {})
    for k in range(nz):
        (tmp_path / f"s{k}.raw").write_bytes(arr[k].tobytes())
    (tmp_path / "list.mhd").write_text(f"NDims = 3\nDimSize = {nx} {ny} {nz}\nElementType = MET_UCHAR\n"
                                       "ElementSpacing = 3 3 3\nOffset = 7 7 7\nElementDataFile = LIST 2D\n"
                                       + "".join(f"s{k}.raw\n" for k in range(nz)))
    files[".mhd LIST"] = (tmp_path / "list.mhd", {})
    return files


def test_every_reader_places_the_samples_by_the_spacing_and_origin_given(tmp_path, writers):
    # Each reader builds its Volume with the spacing and origin given, in place of its file's
    # (load_volume no longer replaces them afterwards): one that dropped them went unseen.
    arr = (np.arange(60) * 4).astype(np.uint8).reshape(3, 4, 5)
    files = _placed_files(tmp_path, arr, writers.slc)
    assert len(files) == 12
    for name, (path, _) in files.items():
        vol = load_volume(path, spacing=(0.5, 2.0, 1.25), origin=(-1.0, 4.0, 9.0))
        assert np.array_equal(vol.data, arr) and vol.spacing == (0.5, 2.0, 1.25), name
        assert vol.origin == (-1.0, 4.0, 9.0), name
        assert load_volume(path, origin=(-1.0, 4.0, 9.0)).origin == (-1.0, 4.0, 9.0), name
        given = load_volume(path, spacing=(0.5, 2.0, 1.25))
        assert given.spacing == (0.5, 2.0, 1.25) and given.origin == load_volume(path).origin, name


def test_ome_tiff_sizes_in_units_that_do_not_convert_take_the_spacing_given(tmp_path):
    # Refused, the file could not be opened even with the --spacing its message asked for.
    a = _data("uint8")
    p = tmp_path / "mixed.ome.tif"
    tifffile.imwrite(p, a, ome=True, metadata={"axes": "ZYX", "PhysicalSizeX": 0.3, "PhysicalSizeXUnit": "µm",
                                               "PhysicalSizeY": 0.3, "PhysicalSizeYUnit": "µm",
                                               "PhysicalSizeZ": 2.0, "PhysicalSizeZUnit": "pixel"})
    vol = load_volume(p)
    assert vol.spacing == (1.0, 1.0, 1.0) and "cannot be converted" in vol.meta["note"]
    given = load_volume(p, spacing=(0.3, 0.3, 1.2))
    assert given.spacing == (0.3, 0.3, 1.2) and "note" not in given.meta and np.array_equal(given.data, a)


def _put(raw, tag, value, index=0):
    """``value`` in place of item ``index`` of a TIFF tag's value, at its place in the file bytes ``raw``."""
    size = tag.valuebytecount // tag.count
    struct.pack_into("<" + {2: "H", 4: "I"}[size], raw, tag.valueoffset + index * size, value)


def _tiff_with_one_strip_for_every_page(path, strip, compression):
    """A stack of three 16x16 uint8 pages whose strip is ``strip``, one block of bytes that
    every page names, in ``compression`` (a TIFF code)."""
    tifffile.imwrite(path, np.zeros((3, 16, 16), np.uint8), photometric="minisblack")
    raw = bytearray(path.read_bytes())
    with tifffile.TiffFile(path) as tif:
        tags = [p.tags for p in tif.pages]
    for t in tags:
        _put(raw, t["Compression"], compression)
        _put(raw, t["StripOffsets"], len(raw))
        _put(raw, t["StripByteCounts"], len(strip))
    path.write_bytes(bytes(raw) + strip)
    return path


@pytest.mark.parametrize("compression, pack", [
    (8, lambda b: zlib.compress(b, 9)),                     # deflate: 16 kB
    (34925, lambda b: lzma.compress(b, preset=0)),          # LZMA: 3 kB
    (32773, lambda b: b"\x81\x00" * (len(b) // 128)),       # PackBits: 256 kB
], ids=["deflate", "LZMA", "PackBits"])
def test_tiff_strip_that_decodes_past_its_size_is_refused_before_it_is_decoded(tmp_path, compression, pack):
    # tifffile decodes a strip whole and keeps the 256 bytes of the page: 1 GB and 13 s a page
    # for 1 MB of deflated zeros; PackBits in a list of Python integers, 8 bytes a byte.
    p = _tiff_with_one_strip_for_every_page(tmp_path / "bomb.tif", pack(bytes(16 << 20)), compression)
    tracemalloc.start()
    try:
        fails(p, "strips or tiles decodes to more than the 256 bytes")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 4 << 20, peak


@pytest.mark.parametrize("compression, strip", [
    (8, zlib.compress(bytes(256))),
    (34925, lzma.compress(bytes(256))),
    (32773, b"\x81\x00\x81\x00"),
], ids=["deflate", "LZMA", "PackBits"])
def test_tiff_strip_of_its_size_named_by_every_page_is_read(tmp_path, compression, strip):
    p = _tiff_with_one_strip_for_every_page(tmp_path / "shared.tif", strip, compression)
    assert np.array_equal(load_volume(p).data, np.zeros((3, 16, 16), np.uint8))


@pytest.mark.parametrize("compression, predictor", [("zlib", False), ("zlib", True), ("lzma", True)])
def test_compressed_tiff_in_several_strips_reads_as_written(tmp_path, compression, predictor):
    a = _data("uint16")
    p = tmp_path / "c.tif"
    # 5 rows in strips of 2: the last strip holds 1 row.
    tifffile.imwrite(p, a, photometric="minisblack", compression=compression, predictor=predictor, rowsperstrip=2)
    with tifffile.TiffFile(p) as tif:
        assert len(tif.pages[0].dataoffsets) == 3
    assert np.array_equal(load_volume(p).data, a)


def test_packbits_tiff_reads_as_written(tmp_path):
    from PIL import Image
    a = _data("uint8")
    p = tmp_path / "packbits.tif"
    pages = [Image.fromarray(page) for page in a]
    pages[0].save(p, compression="packbits", save_all=True, append_images=pages[1:])
    with tifffile.TiffFile(p) as tif:
        assert tif.pages[0].compression == 32773
    assert np.array_equal(load_volume(p).data, a)


def test_tiff_last_strip_holding_every_row_of_a_strip_is_read(tmp_path):
    # Some writers fill the last strip to its full rows; tifffile keeps the rows the image has.
    a = _data("uint8")[:, :4]
    p = tmp_path / "full.tif"
    tifffile.imwrite(p, a, photometric="minisblack", compression="zlib", rowsperstrip=3)
    raw = bytearray(p.read_bytes())
    with tifffile.TiffFile(p) as tif:
        tags = [pg.tags for pg in tif.pages]
    for k, t in enumerate(tags):
        rows = np.concatenate([a[k, 3:], np.full((2, a.shape[2]), 99, np.uint8)])
        strip = zlib.compress(rows.tobytes())
        _put(raw, t["StripOffsets"], len(raw), 1)
        _put(raw, t["StripByteCounts"], len(strip), 1)
        raw += strip
    p.write_bytes(bytes(raw))
    assert np.array_equal(load_volume(p).data, a)


def test_tiff_stating_more_samples_than_memory_holds_is_refused_before_reading(tmp_path, monkeypatch):
    # Empty compressed strips, which tifffile fills with zeros: a file of a few hundred bytes stated
    # 3 GB of samples (and a folder of such slices, as many times over).
    p = _tiff_with_one_strip_for_every_page(tmp_path / "sparse.tif", b"", 8)
    monkeypatch.setattr(memory, "available_memory", lambda: 700)
    fails(p, "a 16x16x3 uint8 stack needs about")
    (tmp_path / "slices").mkdir()
    for k in range(3):
        tifffile.imwrite(tmp_path / "slices" / f"z{k}.tif", np.zeros((16, 16), np.uint8), compression="zlib")
    fails(tmp_path / "slices", "a 16x16x3 uint8 stack needs about")
    monkeypatch.setattr(memory, "available_memory", lambda: 2000)
    assert load_volume(tmp_path / "slices").dims == (16, 16, 3)
    assert load_volume(p).dims == (16, 16, 3)


def _ome_tiff_set(folder, strip=None):
    """An OME-TIFF of three 16x16 uint8 slices: the first in ``a.ome.tif``, which names the set,
    the other two in ``b.ome.tif``, whose pages both name ``strip`` (deflated) when given."""
    folder.mkdir()
    planes = "".join(f'<TiffData FirstZ="{z}" IFD="{ifd}" PlaneCount="1"><UUID FileName="{name}">'
                     f'urn:uuid:00000000-0000-0000-0000-00000000000{name[0]}</UUID></TiffData>'
                     for z, ifd, name in ((0, 0, "a.ome.tif"), (1, 0, "b.ome.tif"), (2, 1, "b.ome.tif")))
    xml = ('<?xml version="1.0" encoding="UTF-8"?><OME xmlns="http://www.openmicroscopy.org/Schemas/OME/2016-06" '
           'UUID="urn:uuid:00000000-0000-0000-0000-00000000000a"><Image ID="Image:0"><Pixels ID="Pixels:0" '
           'DimensionOrder="XYZCT" Type="uint8" SizeX="16" SizeY="16" SizeZ="3" SizeC="1" SizeT="1">'
           f'<Channel ID="Channel:0:0" SamplesPerPixel="1"/>{planes}</Pixels></Image></OME>')
    tifffile.imwrite(folder / "a.ome.tif", np.zeros((16, 16), np.uint8), description=xml, metadata=None,
                     photometric="minisblack", compression="zlib")
    other = folder / "b.ome.tif"
    tifffile.imwrite(other, np.ones((2, 16, 16), np.uint8), metadata=None, photometric="minisblack", compression="zlib")
    if strip is not None:
        raw = bytearray(other.read_bytes())
        with tifffile.TiffFile(other) as tif:
            tags = [p.tags for p in tif.pages]
        for t in tags:
            _put(raw, t["StripOffsets"], len(raw))
            _put(raw, t["StripByteCounts"], len(strip))
        other.write_bytes(bytes(raw) + strip)
    return folder / "a.ome.tif"


def test_ome_tiff_strip_in_another_file_of_the_set_is_checked_there(tmp_path):
    # The offsets of the second file's pages are the second file's: read in the first, they
    # would name its own bytes, and the strip that decodes to 16 MB would be let through.
    assert np.array_equal(load_volume(_ome_tiff_set(tmp_path / "set")).data[:, 0, 0], [0, 1, 1])
    fails(_ome_tiff_set(tmp_path / "bomb", zlib.compress(bytes(16 << 20), 9)),
          "page 2: one of its deflate strips or tiles decodes to more than the 256 bytes")
