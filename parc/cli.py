"""The `parc` command line: render, compare, bench, info, make (the scene its flags describe: `parc.flagscene`).

Every user mistake ends in one line on stderr (``parc: error: ...``) and
exit status 2: no traceback, and no output file, complete or partial.
Outputs are written to a temporary file beside the target and renamed into
place only once whole.
"""
from __future__ import annotations

import argparse
import os
import re
import signal
import sys
from pathlib import Path

import numpy as np

from data_tools import InputError
from data_tools.errors import os_reason
from data_tools.info import exact_text
from data_tools.io.npy import save_array

from .flagscene import load_volume_flags, scene_and_notes
from .outputs import (Progress, atomic_write_all, check_distinct, check_output, compile_notice, end_progress_line,
                      to_json, write_png)

EXIT_USAGE = 2

EPILOG = """\
examples:
  parc render -o out.png                      render the built-in volume
  parc render head.nrrd --iso 600 -o skin.png --size 800 600
  parc render bucky_32x32x32_uint8.raw --iso 128 --eye 60,-40,50 -o bucky.png
  parc render CThead.nrrd --iso 1500 --method parc -o bone.png   same image, faster
  parc render CThead.nrrd --tf ct_skin_bone --up 0,0,-1 -o ct.png   translucent
  parc compare neghip.slc --iso 80 --sweep-supercell 1,2,4,8      speed against error
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


class _Parser(argparse.ArgumentParser):
    """argparse that reports errors as one line with status 2, like the rest of parc."""

    def error(self, message):
        raise InputError(message)


def _floats(n, what):
    def parse(text):
        try:
            vals = tuple(float(v) for v in text.replace(" ", "").split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} must be {n} comma-separated numbers, got {text!r}")
        if len(vals) != n or not all(np.isfinite(vals)):
            raise argparse.ArgumentTypeError(f"{what} must be {n} comma-separated finite numbers, got {text!r}")
        return vals
    return parse


def _supercell(text):
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) not in (1, 3) or not all(np.isfinite(vals)) or min(vals) <= 0:
        raise argparse.ArgumentTypeError(f"supercell size must be M or M,N,P positive numbers, got {text!r}")
    return vals[0] if len(vals) == 1 else vals


def _ints(n, what):
    def parse(text):
        try:
            vals = tuple(int(v) for v in text.replace("x", ",").split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} must be {n} integers like 64,64,32, got {text!r}")
        if len(vals) != n:
            raise argparse.ArgumentTypeError(f"{what} must be {n} integers, got {text!r}")
        return vals
    return parse


def _add_volume_options(p, scenes=True):
    g = p.add_argument_group("reading the volume (headerless raw files need shape and dtype "
                             "unless the name says, e.g. bucky_32x32x32_uint8.raw"
                             + ("; a scene file sets these per volume instead)" if scenes else ")"))
    g.add_argument("--shape", type=_ints(3, "--shape"), metavar="NX,NY,NZ", help="raw: samples along x, y, z")
    g.add_argument("--dtype", metavar="TYPE", help="raw: sample type, e.g. uint8, int16, uint16, float32")
    g.add_argument("--byte-order", choices=("little", "big"), help="raw: byte order (default little)")
    g.add_argument("--spacing", type=_floats(3, "--spacing"), metavar="SX,SY,SZ",
                   help="sample spacing; replaces what the file says")
    g.add_argument("--origin", type=_floats(3, "--origin"), metavar="OX,OY,OZ",
                   help="world position of the first sample; replaces what the file says")


def _add_look_options(p):
    g = p.add_argument_group("what to show (an isosurface, or with --tf a translucent volume; "
                             "a scene file sets these per volume instead)")
    g.add_argument("--iso", type=float, metavar="V", help="isovalue (default: suggested from the histogram)")
    g.add_argument("--tf", metavar="FILE|PRESET",
                   help="transfer function: a .toml/.json file, a ParaView colour-map .json, or a preset "
                        "(ct_skin, ct_bone, ct_skin_bone, greyscale, viridis); renders a translucent volume")
    g.add_argument("--mode", choices=("composite", "mip", "average"),
                   help="with --tf: front-to-back compositing (default), maximum or average intensity")
    g.add_argument("--step", type=float, metavar="S",
                   help="with --tf: world distance between samples (default a quarter of the smallest spacing)")
    g.add_argument("--threshold", type=float, metavar="A",
                   help="with --tf, composite: stop a ray once its opacity reaches A (default 0.99)")
    g.add_argument("--shade", action="store_true", help="with --tf, composite: shade samples with the gradient")
    g.add_argument("--buffers", metavar="LIST",
                   help="with --tf, for parc: PARC's buffers: depth (near/far, default), bits "
                        "(planes of supercells), or depth,bits")


def _add_view_options(p):
    g = p.add_argument_group("view (default: a three-quarter view framing the whole volume; with a scene "
                             "file, these replace the file's camera settings and size)")
    g.add_argument("--eye", type=_floats(3, "--eye"), metavar="X,Y,Z", help="camera position")
    g.add_argument("--look-at", type=_floats(3, "--look-at"), metavar="X,Y,Z",
                   help="point looked at (default: the centre of the volume, or of all a scene file's)")
    g.add_argument("--up", type=_floats(3, "--up"), metavar="X,Y,Z", help="up direction (default 0,0,1, or 0,1,0 when the view is along z)")
    g.add_argument("--fov", type=float, metavar="DEG",
                   help="vertical field of view in degrees (default 30)")
    g.add_argument("--parallel", type=float, metavar="SCALE",
                   help="parallel projection, instead of --fov; SCALE is half the view height in world units")
    g.add_argument("--size", type=int, nargs=2, metavar=("W", "H"),
                   help="image size in pixels (default 512 512)")
    g.add_argument("--background", type=_floats(3, "--background"), metavar="R,G,B",
                   help="opaque background colour in [0,1] (default transparent)")


def _add_light_options(p):
    g = p.add_argument_group(
        "lights and shadows (default: one white headlight at the eye; lights given here are added "
        "to a scene file's [[light]] tables; colours and intensities: use a scene file)")
    g.add_argument("--light", type=_floats(3, "--light"), action="append", metavar="X,Y,Z",
                   help="a white point light at X,Y,Z (world coordinates, may be inside the volume); "
                        "repeat for several lights")
    g.add_argument("--sun", type=_floats(3, "--sun"), action="append", metavar="DX,DY,DZ",
                   help="a white directional light, infinitely far away, whose rays travel along "
                        "DX,DY,DZ (0,0,-1: straight down); repeat for several")
    g.add_argument("--shadows", action="store_true",
                   help="cast shadow rays from every isosurface hit to every light: isosurfaces "
                        "block them, translucent volumes dim them (the headlight casts no visible shadows)")


def build_parser():
    p = _Parser(prog="parc", description="Ray cast 3D scalar volumes, exactly, with OpenGL-assisted acceleration.",
                epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    r = sub.add_parser("render", help="render a volume to an image",
                       description="Render the isosurface of a volume (--iso), or the volume translucent "
                                   "through a transfer function (--tf). Without a volume, renders a built-in "
                                   "synthetic one. Without --iso or --tf, uses a level suggested from the histogram. "
                                   "Given a scene file (SCENE.toml), renders the volumes, camera, lights and image "
                                   "size it describes.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("volume", nargs="?", metavar="VOLUME|SCENE.toml",
                   help="volume file (.nrrd .nhdr .mhd .mha .vtk .slc .npy .raw; .nii .nii.gz with nibabel, "
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
                        "(.npy); scenes of one volume without lights")
    r.add_argument("--method", default="brute", choices=("brute", "parc"),
                   help="brute: unaccelerated casting (default); parc: walk only the ray segments "
                        "OpenGL finds from a polygon proxy of the possibly contributing supercells "
                        "(the same image, faster frame for frame; but the first frame of a volume also pays "
                        "for its cell ranges, skip tables and the OpenGL context, so for a single picture "
                        "brute is often quicker: parc pays over many frames, as in parc compare or the "
                        "Python API)")
    r.add_argument("--supercell", type=_supercell, metavar="M[,N,P]",
                   help="parc: supercell size in cells, fractional allowed (default: chosen by a cost model)")
    r.add_argument("--no-blocks", action="store_true",
                   help="parc: walk the whole of each OpenGL segment, without skipping the empty "
                        "cells and cubes of such cells inside it (same image, slower)")
    r.add_argument("--quiet", action="store_true", help="no progress or notes on stderr")
    _add_look_options(r)
    _add_view_options(r)
    _add_light_options(r)
    _add_volume_options(r)

    c = sub.add_parser("compare", help="time PARC against unaccelerated casting, with image errors",
                       description="Render one scene with each method (after a warm-up), report the median "
                                   "time, speedup against brute, and the image error against brute's image: "
                                   "hit-mask mismatches, max |depth difference| in cells, max |colour "
                                   "difference|, RMSE, PSNR; with cells visited, cubic solves, polygons and "
                                   "seconds per phase.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    c.add_argument("volume", nargs="?", metavar="VOLUME|SCENE.toml",
                   help="volume file or scene file (.toml) (default: the built-in volume)")
    c.add_argument("--methods", default="brute,parc", metavar="LIST",
                   help="comma-separated methods (default brute,parc; brute always runs as the reference)")
    c.add_argument("--supercell", type=_supercell, metavar="M[,N,P]",
                   help="parc's supercell size (default: chosen by the cost model)")
    c.add_argument("--no-blocks", action="store_true",
                   help="parc walks the whole of each OpenGL segment, without skipping the empty "
                        "cells and cubes of such cells inside it (same image, slower)")
    c.add_argument("--sweep-supercell", metavar="LIST",
                   help="run parc once per supercell size, e.g. 0.5,1,2,4,8: speed against error")
    c.add_argument("--sweep-step", metavar="LIST",
                   help="with --tf: run brute and parc once per sample step, e.g. 1,0.5,0.25, against a "
                        "reference at the finest step / 4: speed against error")
    c.add_argument("--repeats", type=int, default=3, help="timed renders per method; the median is reported")
    c.add_argument("--json", action="store_true",
                   help="print the rows as JSON instead of a table (strict JSON: psnr null means identical images)")
    c.add_argument("--quiet", action="store_true", help="no progress or notes on stderr")
    _add_look_options(c)
    _add_view_options(c)
    _add_light_options(c)
    _add_volume_options(c)

    b = sub.add_parser("bench", help="run the benchmark suite: the papers' tables, sweeps, Visible Woman scale",
                       description="Run the fixed benchmark suite and write OUT/report.md, OUT/results.json, "
                                   "PNG charts and pictures: Sobierajski & Avila's Tables 1-3 (brute against "
                                   "parc), Parker et al.'s time shares and thread scaling, sweeps of speed "
                                   "against error (supercell, sample step, root finder, storage precision), a "
                                   "512x512x1734 int16 memory-mapped phantom, and the ideal bound. Real volumes "
                                   "from ../shared/data are used when present, synthetic ones otherwise. The "
                                   "full suite takes several minutes on 2 cores (the phantom, 910 MB, is written "
                                   "to the cache folder on the first run); exits 1 if a consistency check fails.")
    b.add_argument("--out", default="bench-report", metavar="DIR", help="output folder (default bench-report)")
    size = b.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true",
                      help="a reduced suite in a few minutes: half-size images, a 256x256x867 phantom")
    size.add_argument("--tiny", action="store_true",
                      help="tiny synthetic volumes and images, seconds: checks the report, not the speed")
    b.add_argument("--data", metavar="DIR", help="folder of real volumes (default ../shared/data beside the checkout)")

    i = sub.add_parser("info", help="describe a volume and suggest isovalues")
    i.add_argument("volume")
    _add_volume_options(i, scenes=False)

    v = sub.add_parser("convert", help="write a volume in another format",
                       description="Read a volume (any format render reads, with the same reading flags) and write "
                                   "it in the format OUT's extension names. Samples keep their type; spacing and "
                                   "origin go into the header (.npy: a .npy.json sidecar; .raw: samples only). "
                                   "Use it to give a raw file or a TIFF stack its shape and spacing once.")
    v.add_argument("volume", metavar="VOLUME", help="volume file to read (the formats render reads)")
    v.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output file: .nrrd (gzip) .nhdr .npy .mhd .mha .vtk .raw")
    _add_volume_options(v, scenes=False)

    from data_tools.synthetic import DESCRIPTIONS
    m = sub.add_parser("make", help="write a synthetic volume",
                       description="Write a synthetic volume.\n\n" + "\n".join(
                           f"  {k:16s} {v}" for k, v in DESCRIPTIONS.items()),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    m.add_argument("name", choices=sorted(DESCRIPTIONS), metavar="NAME", help="which volume (see above)")
    m.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output file: .nrrd (gzip) .nhdr .npy .mhd .mha .vtk .raw")
    m.add_argument("--size", type=int, metavar="N", help="samples per axis (default depends on the volume)")
    m.add_argument("--seed", type=int, help="random seed, for the random volumes")
    return p


#: Options taking one value that may start with a minus sign (argparse reads
#: ``--sun -1,1,-1`` as two options, and only plain negative numbers as values).
_SIGNED_OPTIONS = {"--eye", "--look-at", "--up", "--light", "--sun", "--spacing", "--origin", "--iso",
                   "--step", "--threshold", "--fov", "--parallel", "--supercell", "--background", "--shape",
                   "--sweep-supercell", "--sweep-step"}
_NUMBERS = re.compile(r"-[\d.][\d.eE+\-,; ]*|-(inf|nan)", re.IGNORECASE)


def _join_signed_values(argv):
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


def main(argv=None):
    """Entry point of the `parc` console script; returns the exit status."""
    if sys.stderr is None:
        # Started with stderr closed (2>&-): notes and progress go nowhere, not to stdout.
        sys.stderr = open(os.devnull, "w")
    for stream in (sys.stdout, sys.stderr):
        # A terminal or pipe that is not UTF-8 still gets the tables' Δ and × (escaped), not a traceback.
        if stream is not None and hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    argv = _join_signed_values(list(sys.argv[1:] if argv is None else argv))
    stops = _stop_on_signals()
    try:
        # Extreme but valid numbers (an eye at 1e200) may overflow on the way to
        # a clean error or a picture; NumPy's warnings would only add lines.
        with np.errstate(all="ignore"):
            return _main(argv)
    except InputError as exc:
        _error(f"error: {exc}")
        return EXIT_USAGE
    except BrokenPipeError:
        # The reader went away (`parc compare ... | head`): stop quietly, as
        # a command killed by SIGPIPE would, and let nothing flush into the
        # closed pipe at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + signal.SIGPIPE
    except OSError as exc:
        # A path the system refuses (too long, not a folder, no permission)
        # found only when it is used.
        where = f"{exc.filename}: " if exc.filename else ""
        _error(f"error: {where}{os_reason(exc)}")
        return EXIT_USAGE
    except MemoryError as exc:
        # NumPy says how much it could not allocate; the usual cause is a
        # --size too large for this machine.
        detail = f": {exc}" if str(exc) else ""
        _error(f"error: out of memory{detail}; try a smaller --size")
        return 1
    except KeyboardInterrupt:
        _error("interrupted")
        return 130
    except _Stopped as exc:
        _error(f"stopped by {signal.Signals(exc.signum).name}")
        return 128 + exc.signum
    finally:
        for signum, handler in stops.items():
            if handler is not None:                 # None: set outside Python, not ours to restore
                signal.signal(signum, handler)


class _Stopped(BaseException):
    """SIGTERM or SIGHUP, raised where the program is, so that the writes under way clean up
    their temporary files (`atomic_write_all`, `save_volume`) as on Ctrl-C."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


def _stop_on_signals():
    """Turn SIGTERM and SIGHUP into `_Stopped` for the run; the handlers they replace, to restore."""
    def stop(signum, frame):
        raise _Stopped(signum)
    replaced = {}
    for signum in (signal.SIGTERM, signal.SIGHUP):
        try:
            replaced[signum] = signal.signal(signum, stop)
        except (ValueError, OSError):     # not the main thread, or no such signal here
            pass
    return replaced


def _error(text):
    """``parc: text`` on stderr, on a line of its own after any unfinished progress."""
    end_progress_line()
    try:
        print(f"parc: {text}", file=sys.stderr)
    except (OSError, ValueError):
        pass


def _main(argv):
    args = build_parser().parse_args(argv)
    if args.command is None:
        build_parser().print_help()
        return EXIT_USAGE
    args.argv = argv
    if sys.stdout is None and args.command in ("info", "compare"):
        # Started with stdout closed (>&-): what it prints would be lost without a word.
        raise InputError(f"standard output is closed; parc {args.command} prints its result there")
    commands = {"render": cmd_render, "compare": cmd_compare, "info": cmd_info, "make": cmd_make,
                "convert": cmd_convert, "bench": cmd_bench}
    return commands[args.command](args)


# --- commands -----------------------------------------------------------

def cmd_info(args):
    from data_tools.info import format_info, volume_info
    vol = load_volume_flags(args)
    print(format_info(volume_info(vol)))
    return 0


def cmd_make(args):
    from data_tools.io import save_volume
    from data_tools.synthetic import check_synthetic_size, make_synthetic
    out = check_output(args.output, (".nrrd", ".nhdr", ".npy", ".mhd", ".mha", ".vtk", ".raw"))
    kwargs = {} if args.seed is None else {"seed": args.seed}
    if args.size is not None and args.size < 2:
        raise InputError(f"--size must be at least 2, got {args.size}")
    if args.seed is not None and args.seed < 0:
        raise InputError(f"--seed must be 0 or more, got {args.seed}")
    if args.size is not None:
        check_synthetic_size(args.size, f"--size {args.size}", args.name)
    try:
        vol = make_synthetic(args.name, args.size, **kwargs)
    except TypeError:
        raise InputError(f"{args.name} takes no --seed") from None
    _refuse_overwriting_input(out, [])
    save_volume(vol, out)  # all-or-nothing itself, and keeps sidecar names right
    print(f"wrote {out} ({'x'.join(map(str, vol.dims))} {vol.dtype})")
    return 0


def _exists(path):
    try:
        return path.exists()
    except OSError:         # a name too long to be a file (the other header's suffix is longer)
        return False


def _refuse_overwriting_input(out, inputs):
    """Refuse an output whose detached data file (``.mhd``, ``.nhdr``: ``STEM.raw``) is a file
    the volume was read from (the header and its samples, or a raw file itself), or the data
    file of the other kind of header beside it (``STEM.nhdr`` for ``STEM.mhd``)."""
    from data_tools.io import data_file_written
    data = data_file_written(out)
    if data is None:
        return
    for source in inputs:
        if source is not None and Path(source).resolve() == data.resolve():
            raise InputError(f"{out}: would write its samples to {data}, which the volume is read from; "
                             "write the output elsewhere or under another name")
    for other in (out.with_suffix(".mhd"), out.with_suffix(".nhdr")):
        if other.suffix != out.suffix.lower() and _exists(other) and data.exists():
            raise InputError(f"{out}: would write its samples to {data}, which holds {other.name}'s; "
                             "write the output under another name")


def cmd_convert(args):
    from data_tools.io import WRITE_EXTENSIONS, save_volume
    out = check_output(args.output, WRITE_EXTENSIONS)
    check_distinct(args.volume, [out])
    vol = load_volume_flags(args)
    _refuse_overwriting_input(out, [args.volume, vol.meta.get("data_file")])
    save_volume(vol, out)  # all-or-nothing itself, and keeps sidecar names right
    if "note" in vol.meta:
        print(f"parc: {vol.meta['note']}", file=sys.stderr)
    spacing = ", ".join(f"{s:g}" for s in vol.spacing)
    origin = ", ".join(f"{o:g}" for o in vol.origin)
    print(f"wrote {out} ({'x'.join(map(str, vol.dims))} {vol.dtype}, spacing {spacing}, origin {origin})")
    return 0


#: Images from this many pixels up take seconds to write (a 4000 x 4000 PNG about 4 s): say so.
LARGE_WRITE_PIXELS = 1 << 22


def cmd_render(args):
    import parc

    from .renderer import DEFAULT_BUFFERS, casters_for

    out = check_output(args.output, (".png", ".npy"))
    depth_out = check_output(args.depth, (".npy",)) if args.depth else None
    stats_out = check_output(args.stats, (".json",)) if args.stats else None
    work_out = check_output(args.work, (".png", ".npy")) if args.work else None
    check_distinct(args.volume, [out, depth_out, stats_out, work_out])
    say = (lambda *a: None) if args.quiet else (lambda msg: print(f"parc: {msg}", file=sys.stderr))
    scene, notes = scene_and_notes(args)
    w, h = scene.size
    kwargs = ({"supercell": args.supercell, "buffers": _buffers(args, scene), "blocks": not args.no_blocks}
              if args.method == "parc" else {})
    if args.method != "parc":
        _refuse_parc_flags(args, "applies to --method parc")
    compile_notice(say, casters_for(scene, (args.method,), kwargs.get("buffers", DEFAULT_BUFFERS)))
    progress = None if args.quiet else Progress(f"rendering {w}x{h}")
    result = parc.render(scene, method=args.method, progress=progress, work=work_out is not None, **kwargs)
    if progress is not None:
        progress.done()
    for note in notes:
        say(note)

    writes = [(out, (lambda tmp: write_png(result.image, tmp)) if out.suffix.lower() == ".png"
               else (lambda tmp: save_array(tmp, result.image)))]
    if depth_out:
        writes.append((depth_out, lambda tmp: save_array(tmp, result.depth)))
    if stats_out:
        writes.append((stats_out, lambda tmp: tmp.write_text(to_json(result.stats) + "\n")))
    if work_out:
        writes.append((work_out, lambda tmp: _write_work(result, scene, args.method, tmp)))
    if w * h >= LARGE_WRITE_PIXELS:
        say(f"writing {', '.join(str(path) for path, _ in writes)} ...")   # seconds, after the progress ends
    atomic_write_all(writes)
    s = result.stats
    vis = scene.volumes[0]
    if len(scene.volumes) > 1:
        say(f"wrote {out}: {len(scene.volumes)} volumes ({'; '.join(_describe(v) for v in scene.volumes)}); "
            f"{s['seconds']['total']:.3f} s")
    elif isinstance(vis, parc.Isosurface):
        say(f"wrote {out}: {s['hits']} of {s['pixels']} pixels hit the isosurface {exact_text(vis.value)}; "
            f"{s['seconds']['total']:.3f} s, {s['cells_visited']:,} cells visited, {s['cubic_solves']:,} cubics")
    else:
        say(f"wrote {out}: {vis.mode} of {vis.tf.name or 'the transfer function'}, step {vis.step:g}; "
            f"{s['seconds']['total']:.3f} s, {s['samples']:,} samples")
    return 0


def _write_work(result, scene, method, path):
    """The work per pixel of a one-volume render: an int64 array (.npy) or a heat map (.png)."""
    if path.suffix.lower() == ".npy":
        save_array(path, result.work)
        return
    from .bench.heatmaps import work_heat_maps
    from .scene import Isosurface
    w, h = scene.size
    what = "cells visited" if isinstance(scene.volumes[0], Isosurface) else "samples taken"
    work_heat_maps(path, {method: result.work}, what, f"{w}x{h}")


def _shown(vis):
    """What a volume shows, in a few words: its isovalue, or its transfer function's mode and step."""
    return (f"isovalue {exact_text(vis.value)}" if hasattr(vis, "value")
            else f"{vis.mode} of {vis.tf.name or 'transfer function'}, step {vis.step:g}")


def _describe(vis):
    """One volume of a scene in a few words, for notes and table headers."""
    return f"{vis.volume.name}, {_shown(vis)}"


def cmd_compare(args):
    from .compare import method_names, compare, format_table
    from .renderer import casters_for

    say = (lambda *a: None) if args.quiet else (lambda msg: print(f"parc: {msg}", file=sys.stderr))
    warming = None if args.quiet else (lambda line: say(f"{line} ..."))
    methods = method_names(args.methods)
    if args.repeats < 1:
        raise InputError(f"--repeats must be at least 1, got {args.repeats}")
    _check_sweep_flags(args)
    steps = None
    if args.sweep_step is not None:
        try:
            steps = [float(v) for v in args.sweep_step.split(",")]
        except ValueError:
            steps = []
        if not steps or not all(np.isfinite(steps)) or min(steps) <= 0:
            raise InputError(f"--sweep-step must be comma-separated positive numbers, got {args.sweep_step!r}")
    scene, notes = scene_and_notes(args)
    common = {"buffers": _buffers(args, scene), "blocks": not args.no_blocks}
    if warming is not None:
        compile_notice(say, casters_for(scene, ["brute"] + [m.split(":")[0] for m in methods], common["buffers"]))
    if steps is not None:
        from .compare import format_step_table, step_sweep
        rows = step_sweep(scene, steps, repeats=args.repeats, progress=warming, options=common)
        for note in notes:
            say(note)
        print(to_json(rows) if args.json else format_step_table(rows))
        return 0
    # Every parc method gets the flags, labelled ones ("parc:x") too.
    options = {m: dict(common) for m in methods if m.split(":")[0] == "parc"}
    if args.sweep_supercell is not None:
        sizes = [_supercell_or_error(v) for v in args.sweep_supercell.split(";" if ";" in args.sweep_supercell else ",")]
        labels = [f"parc:{_size_label(s)}" for s in sizes]
        methods = ["brute"] + labels
        options = {label: {"supercell": s, **common} for label, s in zip(labels, sizes)}
    elif args.supercell is not None:
        options = {m: {"supercell": args.supercell, **opts} for m, opts in options.items()}
    if not options:
        _refuse_parc_flags(args, "applies to parc, which --methods leaves out")
    rows = compare(scene, methods=methods, repeats=args.repeats, options=options, progress=warming)
    for note in notes:
        say(note)
    if args.json:
        print(to_json(rows))
    else:
        w, h = scene.size
        vis = scene.volumes[0]
        if len(scene.volumes) > 1:
            print(f"{args.volume}: {len(scene.volumes)} volumes "
                  f"({'; '.join(_describe(v) for v in scene.volumes)}), "
                  f"{w}x{h} pixels, median of {args.repeats} after a warm-up")
        else:
            print(f"{vis.volume.name}: {'x'.join(map(str, vis.volume.dims))} {vis.volume.dtype}, {_shown(vis)}, "
                  f"{w}x{h} pixels, median of {args.repeats} after a warm-up")
        print(format_table(rows))
    return 0


def cmd_bench(args):
    from .bench import main
    return main(args)


def _buffers(args, scene=None):
    """PARC's buffers from --buffers (parsed, refused where no volume of ``scene`` is translucent)."""
    from .renderer import DEFAULT_BUFFERS, bits_refused, parse_buffers
    from .scene import Translucent
    if args.buffers is None:
        return DEFAULT_BUFFERS
    buffers = parse_buffers(args.buffers)
    if scene is not None and not any(isinstance(v, Translucent) for v in scene.volumes):
        raise InputError("--buffers applies to translucent volumes (--tf); isosurfaces use the depth buffers")
    refused = bits_refused(scene) if scene is not None and "bits" in buffers else None
    if refused:
        raise InputError(f"--buffers {args.buffers}: {refused}")
    return buffers


def _refuse_parc_flags(args, why):
    """Refuse PARC's own flags where no parc render runs: ``--FLAG {why}``."""
    for flag, given in (("--supercell", args.supercell is not None), ("--no-blocks", args.no_blocks),
                        ("--buffers", args.buffers is not None)):
        if given:
            raise InputError(f"{flag} {why}")


def _check_sweep_flags(args):
    """Refuse compare flags a sweep would ignore: one sweep at a time, and no fixed setting of what it varies."""
    if args.sweep_step is not None and args.sweep_supercell is not None:
        raise InputError("give --sweep-step or --sweep-supercell, not both")
    if args.sweep_step is not None:
        sweep = "--sweep-step"
    elif args.sweep_supercell is not None:
        sweep = "--sweep-supercell"
    else:
        return
    if args.supercell is not None:
        raise InputError(f"--supercell does not combine with {sweep} (it sets parc's supercell itself)")
    if args.methods != "brute,parc":
        raise InputError(f"--methods does not combine with {sweep} (it runs brute and parc itself)")
    if sweep == "--sweep-step" and args.step is not None:
        raise InputError("--step does not combine with --sweep-step (it varies the step)")


def _size_label(size):
    """A supercell size as a method label: ``4`` or ``1x2x3``."""
    return "x".join(f"{v:g}" for v in size) if isinstance(size, tuple) else f"{size:g}"


def _supercell_or_error(text):
    try:
        return _supercell(text)
    except argparse.ArgumentTypeError as exc:
        raise InputError(f"--sweep-supercell: {exc}") from None


if __name__ == "__main__":
    sys.exit(main())
