"""The `parc` command line's grammar: its commands, flags and help, and how argv's negative
numbers reach them (`parc.cli` runs the commands)."""
from __future__ import annotations

import argparse
import difflib
import os
import re
import sys
import textwrap

import numpy as np

from data_tools import InputError

EPILOG = """\
examples:
  parc render -o out.png                      render the built-in volume
  parc render head.nrrd --iso 600 -o skin.png --size 800 600
  parc render bucky_32x32x32_uint8.raw --iso 128 --eye 60,-40,50 -o bucky.png
  parc render CThead.nrrd --iso 1500 --up 0,0,-1 -o bone.png   this head's top is at -z
  parc render CThead.nrrd --iso 1500 --up 0,0,-1 --method parc -o bone.png   same image by PARC
  parc render CThead.nrrd --tf ct_skin_bone --up 0,0,-1 -o ct.png   translucent
  parc compare neghip.slc --iso 80 --sweep-supercell 1,2,4,8      speed against error
  parc compare neghip.slc --iso 80 --work work.png   and each method's cells per pixel, drawn
  parc render head.nrrd --iso 600 --sun -1,1,-1 --shadows -o lit.png   sunlight and shadows
  parc render head.nrrd --iso 600 --light 0,-300,200 --light 300,0,0 -o two.png   two point lights
  parc render scene.toml -o scene.png         a scene file: several volumes, camera, lights
  parc compare scene.toml --size 256 256      flags override the scene file's view and size
  parc info CThead.nrrd                       dims, spacing, histogram, isovalues
  parc make ct_phantom --size 128 -o ct.nrrd  a synthetic volume
  parc convert stack.tif --spacing 0.2,0.2,1 -o stack.nrrd   another format, with the spacing it lacked
  parc bench --quick --out report/            the benchmark suite: report.md and charts

Axis order: positions, spacing and origin are x,y,z; arrays are [z,y,x].
Scene files (.toml) are described in the README ("Scene files") and in
`python -m pydoc parc.scenefile`.
"""


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Help text as written (the examples' columns), but a paragraph written as one line is
    filled to the terminal's width, as argparse's default formatter would."""

    def _fill_text(self, text, width, indent):
        paragraphs = text.split("\n\n")
        return "\n\n".join(p if "\n" in p.strip("\n") else textwrap.fill(p, width, initial_indent=indent,
                                                                          subsequent_indent=indent)
                           for p in paragraphs)


class _Parser(argparse.ArgumentParser):
    """argparse that reports errors as one line with status 2, like the rest of parc."""

    def parse_known_args(self, args=None, namespace=None):
        self._given = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def _print_message(self, message, file=None):
        if message and file is not None and file is sys.stdout:
            # Help and version: argparse drops a failed write (`> /dev/full`) and exits with 0.
            from .outputs import print_out
            print_out(message, end="")
        else:
            super()._print_message(message, file)

    def error(self, message):
        # argparse checks required arguments before it looks for unknown ones: a misspelt
        # flag, the likelier mistake, was reported as a missing -o.
        if message.startswith("the following arguments are required") and hasattr(self, "_given"):
            # So the arguments are parsed again with none required, and argparse names what
            # it does not know, as it would have (prefixes, "--" and values its own way).
            required = [action for action in self._actions if action.required]
            given = self.__dict__.pop("_given")
            try:
                for action in required:
                    action.required = False
                _, unknown = super().parse_known_args(given)
            except InputError:
                unknown = []
            finally:
                for action in required:
                    action.required = True
            if unknown:
                message = f"unrecognized arguments: {' '.join(unknown)}"
        if message.startswith("unrecognized arguments: "):
            # "--light x,y,z ..." reads as one flag taking several lights.
            given = getattr(self, "_given", [])
            unknown = message.partition(": ")[2].split()
            flag = next((f for f in ("--light", "--sun") if f in given), None)
            if flag and any(TRIPLE.fullmatch(w) for w in unknown):
                message += one_flag_a_light(flag)
            else:
                message += self._hint(unknown)
        elif re.fullmatch(r"argument --size: expected 2 arguments", message):
            message += " (width and height, apart: --size 640 480)"
        raise InputError(message)

    def _hint(self, unknown):
        """What a user likely meant by the first of the ``unknown`` arguments: a flag spelt
        otherwise (``--look_at``, ``--lookat``), or a second volume, which takes a scene file."""
        if not unknown:             # an empty argument ("") is unknown as no word
            return ""
        first = unknown[0]
        # The command's parser: argparse reports what it does not know from the top one.
        given = getattr(self, "_given", [])
        commands = next((a.choices for a in self._actions if isinstance(a, argparse._SubParsersAction)), {})
        command = next((w for w in given if w in commands), None)
        parser = commands.get(command, self)
        if first.startswith("--"):
            name = first.partition("=")[0].replace("_", "-")
            flags = [f for action in parser._actions for f in action.option_strings if f.startswith("--")]
            close = difflib.get_close_matches(name, flags, n=1, cutoff=0.75)
            return f"; did you mean {close[0]}?" if close else ""
        if (any(a.dest == "volume" for a in parser._actions) and not first.startswith("-")
                and (os.path.exists(first) or _looks_like_a_file(first))):
            if command in ("render", "compare"):
                return ("; one volume a command: show several with a scene file's [[volume]] tables "
                        "(README, Scene files)")
            return f"; {command} takes one volume"
        return ""


def _looks_like_a_file(word):
    """Whether ``word`` is named as a volume or scene file is (``b.nrrd``), not a number or a vector."""
    from data_tools.io import READ_EXTENSIONS
    return word.lower().endswith(tuple(READ_EXTENSIONS) + (".toml",))


def one_flag_a_light(flag):
    return f"; give {flag} once for each light: {flag} x,y,z {flag} x,y,z"


#: Three comma-separated values: a light's position or direction.
TRIPLE = re.compile(r"[^,\s]+,[^,\s]+,[^,\s]+")


class _OneSurface(argparse.Action):
    """--iso or --tf given at most once: a second would not add a surface or volume, as a user
    might expect, but replace the first, so it is refused with the way to show several."""

    def __call__(self, parser, namespace, values, option_string=None):
        earlier = getattr(namespace, self.dest, None)
        if earlier is not None:
            def text(v):
                return repr(v).removesuffix(".0") if isinstance(v, float) else v
            raise InputError(f"{self.option_strings[-1]} given twice ({text(earlier)} and {text(values)}); "
                             "several surfaces or volumes are shown by a scene file's [[volume]] tables "
                             "(README, Scene files; examples/*.toml)")
        setattr(namespace, self.dest, values)


def _floats(n, most=None):
    # argparse names the flag: "argument --eye: must be ..."
    counts = f"{n}" if most is None else f"{n} or {most}"
    def parse(text):
        try:
            vals = tuple(float(v) for v in text.replace(" ", "").split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {counts} comma-separated numbers, got {text!r}")
        if len(vals) not in (n, most or n) or not all(np.isfinite(vals)):
            raise argparse.ArgumentTypeError(f"must be {counts} comma-separated finite numbers, got {text!r}")
        return vals
    return parse


def _colour(text):
    # Scene checks the range too, but a flag's error should name the flag.
    vals = _floats(3, 4)(text)
    if not all(0.0 <= v <= 1.0 for v in vals):
        raise argparse.ArgumentTypeError(f"components must be in [0, 1], got {text!r}")
    return vals


def supercell_flag(text):
    """``--supercell``'s ``M`` or ``M,N,P``: a number, or three (`parc.ranges.supercell_size`
    checks either as a size)."""
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) not in (1, 3) or not all(np.isfinite(vals)) or min(vals) <= 0:
        raise argparse.ArgumentTypeError(f"supercell size must be M or M,N,P positive numbers, got {text!r}")
    return vals[0] if len(vals) == 1 else vals


def _ints(n):
    def parse(text):
        try:
            vals = tuple(int(v) for v in text.replace("x", ",").split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {n} integers like 64,64,32, got {text!r}")
        if len(vals) != n:
            raise argparse.ArgumentTypeError(f"must be {n} integers apart by commas, like 64,64,32, got {text!r}")
        return vals
    return parse


def _byte_count(text):
    try:
        n = int(text)
    except ValueError:
        n = -1
    if n < 0:
        raise argparse.ArgumentTypeError(f"must be a byte count (a whole number >= 0), got {text!r}")
    return n


def _add_volume_options(p, scenes=True):
    g = p.add_argument_group("reading the volume",
                             "Headerless raw files need shape and dtype unless the name says, e.g. "
                             "bucky_32x32x32_uint8.raw" + ("; a scene file sets these per volume instead." if scenes
                                                           else "."))
    g.add_argument("--shape", type=_ints(3), metavar="NX,NY,NZ", help="raw: samples along x, y, z")
    g.add_argument("--dtype", metavar="TYPE", help="raw: sample type, e.g. uint8, int16, uint16, float32")
    g.add_argument("--byte-order", choices=("little", "big"), help="raw: byte order (default little, or what the file name says: be, msb, bigendian...)")
    g.add_argument("--offset", type=_byte_count, metavar="BYTES",
                   help="raw: bytes before the samples, such as a vendor's header (default 0)")
    g.add_argument("--spacing", type=_floats(3), metavar="SX,SY,SZ",
                   help="sample spacing; replaces what the file says")
    g.add_argument("--origin", type=_floats(3), metavar="OX,OY,OZ",
                   help="world position of the first sample; replaces what the file says")


def _add_look_options(p):
    g = p.add_argument_group("what to show", "An isosurface, or with --tf a translucent volume; "
                             "a scene file sets these per volume instead.")
    g.add_argument("--iso", type=float, action=_OneSurface, metavar="V", help="isovalue (default: suggested from the histogram)")
    g.add_argument("--tf", action=_OneSurface, metavar="FILE|PRESET",
                   help="transfer function: a .toml/.json file, a ParaView colour-map .json, or a preset "
                        "(ct_skin, ct_bone, ct_skin_bone, greyscale, viridis); renders a translucent volume")
    g.add_argument("--mode", choices=("composite", "mip", "average"),
                   help="with --tf: front-to-back compositing (default), maximum or average intensity")
    g.add_argument("--step", type=float, metavar="S",
                   help="with --tf: world distance between samples (default a quarter of the smallest spacing; "
                        "at least 1e-4 of it, and at most 1e8 samples across the volume's diagonal)")
    g.add_argument("--threshold", type=float, metavar="A",
                   help="with --tf, composite: stop a ray once its opacity reaches A (default 0.99)")
    g.add_argument("--shade", action="store_true",
                   help="with --tf, composite: shade samples with the gradient, lit by the headlight or by "
                        "--light and --sun (shadowed with --shadows)")
    g.add_argument("--buffers", metavar="LIST",
                   help="with --tf or a scene's translucent volumes, for parc: their buffers: depth (near/far, "
                        "default), bits (planes of supercells), or depth,bits; isosurfaces use depth")


def _add_view_options(p):
    g = p.add_argument_group("view", "Default: a three-quarter view framing the whole volume; with a scene "
                             "file, these replace the file's camera settings and size.")
    g.add_argument("--eye", type=_floats(3), metavar="X,Y,Z", help="camera position")
    g.add_argument("--look-at", type=_floats(3), metavar="X,Y,Z",
                   help="point looked at (default: the centre of the volume, or of all a scene file's); "
                        "without --eye, the default eye moves with it, as a pan")
    g.add_argument("--up", type=_floats(3), metavar="X,Y,Z", help="up direction (default 0,0,1, or 0,1,0 when the view is along z)")
    g.add_argument("--fov", type=float, metavar="DEG",
                   help="vertical field of view in degrees (default 30)")
    g.add_argument("--parallel", type=float, metavar="SCALE",
                   help="parallel projection, instead of --fov; SCALE is half the view height in world units")
    g.add_argument("--zoom", type=float, metavar="Z",
                   help="without --eye: the default eye Z times closer (default 1; the view stays framed "
                        "on the whole volume at 1)")
    g.add_argument("--size", type=int, nargs=2, metavar=("W", "H"),
                   help="image size in pixels (default 512 512)")
    g.add_argument("--background", type=_colour, metavar="R,G,B[,A]",
                   help="background colour in [0,1], opaque unless an alpha A is given (default transparent)")


def _add_light_options(p):
    g = p.add_argument_group(
        "lights and shadows", "Default: one white headlight at the eye. Lights shine on isosurfaces and on "
        "translucent samples shaded with --shade; those given here are added to a scene file's [[light]] "
        "tables; colours and intensities: use a scene file.")
    g.add_argument("--light", type=_floats(3), action="append", metavar="X,Y,Z",
                   help="a white point light at X,Y,Z (world coordinates, may be inside the volume); "
                        "repeat for several lights")
    g.add_argument("--sun", type=_floats(3), action="append", metavar="DX,DY,DZ",
                   help="a white directional light, infinitely far away, whose rays travel along "
                        "DX,DY,DZ (0,0,-1: straight down); repeat for several")
    g.add_argument("--shadows", action="store_true",
                   help="cast shadow rays from every isosurface hit, and every translucent sample shaded "
                        "with --shade, to every light: isosurfaces block them, translucent volumes dim them "
                        "(the headlight casts no visible shadows). A shaded translucent volume casts one for each "
                        "of its samples that adds colour, towards each light: many times as many as the pixels")


def _add_common_options(p):
    """What render and compare both take: parc's settings, --quiet, and what, how and where to look."""
    p.add_argument("--supercell", type=supercell_flag, metavar="M[,N,P]",
                   help="parc: supercell size in cells, fractional allowed (default: chosen by a cost model)")
    p.add_argument("--no-blocks", action="store_true",
                   help="parc: walk the whole of each OpenGL segment, without skipping the empty "
                        "cells and cubes of such cells inside it (same image, slower)")
    p.add_argument("--quiet", action="store_true", help="no progress or notes on stderr")
    _add_look_options(p)
    _add_view_options(p)
    _add_light_options(p)
    _add_volume_options(p)


def package_version():
    """The installed package's version (`parc --version`)."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("parc")
    except PackageNotFoundError:        # run from a checkout that was never installed
        return "(not installed)"


def build_parser():
    p = _Parser(prog="parc", description="Ray cast 3D scalar volumes, exactly, with OpenGL-assisted acceleration.",
                epilog=EPILOG, formatter_class=_Formatter)
    p.add_argument("--version", action="version", version=f"parc {package_version()}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    r = sub.add_parser("render", help="render a volume to an image",
                       description="Render the isosurface of a volume (--iso), or the volume translucent "
                                   "through a transfer function (--tf). Without a volume, renders a built-in "
                                   "synthetic one. Without --iso or --tf, uses a level suggested from the histogram (the built-in "
                                   "volume: the level it is made for, 127.5). "
                                   "Given a scene file (SCENE.toml), renders the volumes, camera, lights and image "
                                   "size it describes.",
                       epilog=EPILOG, formatter_class=_Formatter)
    r.add_argument("volume", nargs="?", metavar="VOLUME|SCENE.toml",
                   help="volume file (.nrrd .nhdr .mhd .mha .vtk .slc .npy, raw .raw .bin .dat; .nii .nii.gz with nibabel, "
                        ".tif .tiff stacks with tifffile) or a folder of .tif slices, or a scene file (.toml) "
                        "with several volumes, camera and lights")
    r.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="image: .png (8-bit RGBA) or .npy (float32 RGBA array)")
    r.add_argument("--depth", metavar="D.npy", help="also write the float64 depth image: world distance to the first isosurface hit, "
                        "inf where none (translucent volumes have no surface)")
    r.add_argument("--stats", metavar="S.json",
                   help="also write timings and counts as JSON (strict: a non-finite number is null)")
    r.add_argument("--work", metavar="W.png|W.npy",
                   help="also write the work per pixel: cells visited (isosurface) or samples taken "
                        "(translucent), as a heat map (.png, log scale, white where none) or an int64 array "
                        "(.npy); camera rays only, several volumes' work added; not for a scene with both "
                        "isosurfaces and translucent volumes")
    r.add_argument("--method", default="brute", choices=("brute", "parc"),
                   help="brute: unaccelerated casting (default); parc: walk only the ray segments "
                        "OpenGL finds from a polygon proxy of the possibly contributing supercells "
                        "(the same image, faster frame for frame; but the first frame of a volume also pays "
                        "for its cell ranges and the OpenGL context, and an isovalue's second frame for its "
                        "skip tables, so for a single picture "
                        "brute is often quicker: parc pays over many frames, as in parc compare or the "
                        "Python API)")
    _add_common_options(r)

    c = sub.add_parser("compare", help="time PARC against unaccelerated casting, with image errors",
                       description="Render one scene with each method (after a warm-up), report the median "
                                   "time, speedup against brute, and the image error against brute's image: "
                                   "hit-mask mismatches, max |depth difference| in cells, max |colour "
                                   "difference|, RMSE and PSNR; with cells visited, cubic solves, "
                                   "polygons and seconds per phase.",
                       epilog=EPILOG, formatter_class=_Formatter)
    c.add_argument("volume", nargs="?", metavar="VOLUME|SCENE.toml",
                   help="volume file or scene file (.toml) (default: the built-in volume)")
    c.add_argument("--methods", default="brute,parc", metavar="LIST",
                   help="comma-separated methods (default brute,parc; brute always runs as the reference); "
                        "a label after a colon times a method twice, as in brute,parc:a,parc:b")
    c.add_argument("--sweep-supercell", metavar="LIST",
                   help="run parc once per supercell size, e.g. 0.5,1,2,4,8: speed against error "
                        "(sizes of M,N,P cells apart by ';': '2,2,4;4,4,8', one alone '2,2,4;')")
    c.add_argument("--sweep-step", metavar="LIST",
                   help="with --tf: run brute and parc once per sample step, e.g. 1,0.5,0.25, against a "
                        "reference at the finest step / 4: speed against error")
    c.add_argument("--repeats", type=int, default=3, metavar="N",
                   help="timed renders per method (1 to 10000), after one to warm up; the median is reported (default 3)")
    c.add_argument("--json", action="store_true",
                   help="print the rows as JSON instead of a table (strict JSON: psnr null means identical images)")
    c.add_argument("--work", metavar="W.png",
                   help="also draw each method's work per pixel side by side, on one log scale: cells visited "
                        "(isosurfaces) or samples taken (translucent volumes), from one more render of each "
                        "after the timing; not with --sweep-step, nor for a scene with both isosurfaces and "
                        "translucent volumes")
    _add_common_options(c)

    b = sub.add_parser("bench", help="run the benchmark suite: the papers' tables, sweeps, Visible Woman scale",
                       description="Run the fixed benchmark suite and write OUT/report.md, OUT/results.json, "
                                   "PNG charts and pictures: Sobierajski & Avila's Tables 1-3 (brute against "
                                   "parc), Parker et al.'s time shares and thread scaling, sweeps of speed "
                                   "against error (supercell, sample step, root finder, storage precision), a "
                                   "512x512x1734 int16 memory-mapped phantom, and the ideal bound. Real volumes "
                                   "from ../shared/data are used when present, synthetic ones otherwise. The "
                                   "full suite takes about 2 minutes on 2 cores (the phantom, 910 MB, is written "
                                   "to the cache folder on the first run, a minute more); exits 1 if a consistency "
                                   "check fails.")
    b.add_argument("--out", default="bench-report", metavar="DIR",
                   help="output folder: new, empty, or an earlier report's (default bench-report)")
    size = b.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true",
                      help="a reduced suite, under a minute on 2 cores: half-size images, 2 repeats, a 256x256x867 phantom")
    size.add_argument("--tiny", action="store_true",
                      help="tiny synthetic volumes and images, seconds once the casters are compiled: checks "
                           "the report, not the speed")
    b.add_argument("--data", metavar="DIR", help="folder of real volumes (default $PARC_DATA_DIR, else ../shared/data beside "
                        "the checkout); not with --tiny")

    i = sub.add_parser("info", help="describe a volume and suggest isovalues",
                       description="Describe a volume: its dimensions, sample type, spacing and origin, the "
                                   "range, mean, percentiles and a histogram of its values, and isovalues worth "
                                   "trying with render --iso (multi-level Otsu thresholds between the "
                                   "histogram's classes, the minimum left out). Reads "
                                   "what render reads, with the same reading flags.")
    i.add_argument("volume", metavar="VOLUME",
                   help="volume file (the formats render reads) or a folder of .tif slices")
    _add_volume_options(i, scenes=False)

    v = sub.add_parser("convert", help="write a volume in another format",
                       description="Read a volume (any format render reads, with the same reading flags) and write "
                                   "it in the format OUT's extension names. Samples keep their type; spacing and "
                                   "origin go into the header (.npy: a .npy.json sidecar, unless they are 1 and 0; "
                                   ".raw: samples only). "
                                   "Use it to give a raw file or a TIFF stack its shape and spacing once.")
    v.add_argument("volume", metavar="VOLUME", help="volume file to read (the formats render reads)")
    v.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output file: .nrrd (gzip) .nhdr .npy .mhd .mha .vtk .raw")
    _add_volume_options(v, scenes=False)

    from data_tools.synthetic import DESCRIPTIONS, default_size
    m = sub.add_parser("make", help="write a synthetic volume",
                       description="Write a synthetic volume ([N]: its --size unless given).\n\n" + "\n".join(
                           f"  {k:16s} [{default_size(k)}] {v}" for k, v in DESCRIPTIONS.items()),
                       formatter_class=_Formatter)
    m.add_argument("name", choices=sorted(DESCRIPTIONS), metavar="NAME", help="which volume (see above)")
    m.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output file: .nrrd (gzip) .nhdr .npy .mhd .mha .vtk .raw")
    m.add_argument("--size", type=int, metavar="N", help="samples per axis (default: the volume's own, listed above)")
    m.add_argument("--seed", type=int, metavar="S", help="random seed, for the random volumes")
    return p


#: Options taking one value that may start with a minus sign (argparse reads
#: ``--sun -1,1,-1`` as two options, and only plain negative numbers as values).
_SIGNED_OPTIONS = {"--eye", "--look-at", "--up", "--light", "--sun", "--spacing", "--origin", "--iso",
                   "--step", "--threshold", "--fov", "--parallel", "--zoom", "--supercell", "--background",
                   "--shape", "--sweep-supercell", "--sweep-step"}
#: A number or list starting with a minus sign, "inf" and "nan" anywhere in it too ("-1,inf,0"),
#: so that its flag's own check names what is wrong with it.
_NUMBERS = re.compile(r"-([\d.]|inf|nan)[\w.+\-,; ]*", re.IGNORECASE)


def join_signed_values(argv):
    """``["--sun", "-1,1,-1"]`` as ``["--sun=-1,1,-1"]``, so that argparse takes it as the option's value."""
    out = []
    i = 0
    while i < len(argv):
        if argv[i] in _SIGNED_OPTIONS and i + 1 < len(argv) and _NUMBERS.fullmatch(argv[i + 1]):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out
