"""The `parc` command line: render, compare, bench, info, make, convert (its flags and help: `parc.arguments`;
the scene its flags describe: `parc.flagscene`).

Every user mistake ends in one line on stderr (``parc: error: ...``) and
exit status 2: no traceback, and no output file, complete or partial.
Outputs are written to a temporary file beside the target and renamed into
place only once whole.
"""
from __future__ import annotations

import argparse
import contextlib
import os
import re
import shlex
import signal
import sys
import warnings
from pathlib import Path

import numpy as np

from data_tools import InputError
from data_tools.errors import os_reason
from data_tools.info import exact_text
from data_tools.io.npy import save_array
from data_tools.signals import done_before_stop

from .arguments import build_parser, join_signed_values, supercell_flag
from .flagscene import load_volume_flags, scene_and_notes
from .outputs import (Progress, atomic_write_all, check_distinct, check_not_sidecar, check_output, compile_notice,
                      compile_took, compiling_seconds, error_line, late_compile_notice, note, print_out, slow_note,
                      stale_sidecars, to_json, write_png)
from .scene import ShowsNothingWarning
from .stops import Stopped, restore_handlers, stop_on_signals

EXIT_USAGE = 2


def main(argv=None):
    """Entry point of the `parc` console script; returns the exit status."""
    if sys.stderr is None:
        # Started with stderr closed (2>&-): notes and progress go nowhere, not to stdout.
        sys.stderr = open(os.devnull, "w")
    for stream in (sys.stdout, sys.stderr):
        # A terminal or pipe that is not UTF-8 still gets the tables' Δ and × (escaped), not a traceback.
        if stream is not None and hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    argv = join_signed_values(list(sys.argv[1:] if argv is None else argv))
    stops = stop_on_signals()
    try:
        # Extreme but valid numbers (an eye at 1e200) may overflow on the way to
        # a clean error or a picture; NumPy's warnings would only add lines.
        # A volume that shows nothing is said once, in a note (`scene_and_notes`), not again as a
        # warning from every copy of the scene a comparison makes.
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", ShowsNothingWarning)
            return _main(argv)
    except InputError as exc:
        error_line(f"error: {exc}")
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
        if not where and _working_folder_gone():
            where = "the working folder no longer exists (give absolute paths, or cd to a folder): "
        error_line(f"error: {where}{os_reason(exc)}")
        return EXIT_USAGE
    except MemoryError as exc:
        # NumPy says how much it could not allocate; the usual cause is a
        # --size too large for this machine, or for parc a --supercell far below a cell.
        detail = f": {exc}" if str(exc) else ""
        supercell = (" (or a larger --supercell)"
                     if any(str(a).startswith(("--supercell", "--sweep-supercell")) for a in argv) else "")
        # parc's tables (cell ranges, skip tables) grow with the volume, not the image.
        parc_ran = argv[:1] == ["compare"] or any(str(a) in ("parc", "--method=parc") for a in argv)
        tables = ", or --method brute, which keeps no tables of the volume" if parc_ran else ""
        error_line(f"error: out of memory{detail}; try a smaller --size{supercell}{tables}")
        return 1
    except KeyboardInterrupt:
        error_line(f"interrupted{done_before_stop()}")
        return 130
    except Stopped as exc:
        error_line(f"stopped by {signal.Signals(exc.signum).name}{done_before_stop()}")
        return 128 + exc.signum
    finally:
        restore_handlers(stops)


def _working_folder_gone():
    try:
        os.getcwd()
    except OSError:
        return True
    return False


def _main(argv):
    args = build_parser().parse_args(argv)
    if args.command is None:
        raise InputError("give a command: render, compare, bench, info, convert or make (parc --help lists them)")
    args.argv = argv
    if sys.stdout is None and args.command in ("info", "compare"):
        # Started with stdout closed (>&-): what it prints would be lost without a word.
        raise InputError(f"standard output is closed; parc {args.command} prints its result there")
    commands = {"render": cmd_render, "compare": cmd_compare, "info": cmd_info, "make": cmd_make,
                "convert": cmd_convert, "bench": cmd_bench}
    return commands[args.command](args)


# --- commands -----------------------------------------------------------

def _reading(args, say=note):
    """`slow_note` for reading the volume or scene file the arguments name (and what is
    computed from it before any progress can show)."""
    if args.volume is None:
        return slow_note("making the built-in volume", say)
    return slow_note(f"reading {args.volume}", say)


def cmd_info(args):
    from data_tools.info import format_info, volume_info
    with _reading(args):
        info = volume_info(load_volume_flags(args))
    print_out(format_info(info))        # the reader's note among its lines
    return 0


def cmd_make(args):
    from data_tools.io import WRITE_EXTENSIONS, save_volume
    from data_tools.synthetic import ISOVALUES, check_synthetic_size, make_synthetic, making_note
    out = check_output(args.output, WRITE_EXTENSIONS)
    kwargs = {} if args.seed is None else {"seed": args.seed}
    if args.size is not None and args.size < 2:
        raise InputError(f"--size must be at least 2, got {args.size}")
    if args.seed is not None and args.seed < 0:
        raise InputError(f"--seed must be 0 or more, got {args.seed}")
    if args.size is not None:
        check_synthetic_size(args.size, f"--size {args.size}", args.name)
    making = making_note(args.name, args.size)
    if making:
        note(making)
    # Below the size said at once, a neuron still takes seconds (3.5 s at 256 a side).
    try:
        with contextlib.nullcontext() if making else slow_note(f"making {args.name}", note):
            vol = make_synthetic(args.name, args.size, **kwargs)
    except TypeError:
        raise InputError(f"{args.name} takes no --seed") from None
    _refuse_overwriting_input(out, [])
    with slow_note(f"writing {out}", note):    # a compressed 640^3 volume takes seconds
        save_volume(vol, out)  # all-or-nothing itself, and keeps sidecar names right
    print_out(f"wrote {_written(out)} ({'x'.join(map(str, vol.dims))} {vol.dtype}{_placement(vol, out)})",
              done=f"wrote {_written(out)}")
    made_for = ISOVALUES[args.name]
    # A small volume can miss the levels it is made for (a neuron of 3 samples a side), and a
    # random trilinear field is made for none: the command suggested must run all the same.
    lo, hi = vol.value_range()
    levels = [v for v in made_for if lo <= v <= hi]
    what = f"isovalue{'s' if len(levels) > 1 else ''} {' and '.join(exact_text(v) for v in levels)}"
    if not levels:
        from data_tools.info import default_isovalue, suggest_isovalues
        level = default_isovalue(suggest_isovalues(vol))        # the one render takes without --iso
        levels = [] if level is None else [level]
        missed = f"level{'s' if len(made_for) > 1 else ''} {' and '.join(exact_text(v) for v in made_for)}"
        why = (f" (at this size the samples, {lo:.6g} to {hi:.6g}, miss the {missed} {args.name} is made for)"
               if made_for else "")
        what = f"isovalue {exact_text(levels[0])}, from the histogram{why}" if levels else None
    if what is not None:
        print_out(f"{what}: " + " ".join(["parc render", shlex.quote(str(out)), *_raw_flags(vol, out),
                                          f"--iso {exact_text(levels[0])}", "-o", shlex.quote(out.stem + ".png")]))
    else:
        print_out(f"at this size every sample of the {args.name} is {exact_text(lo)}: it has no isosurface "
                  "to render; give a larger --size")
    return 0


def _written(out):
    """``out`` and the files written beside it (a header's data file, a ``.npy``'s sidecar)."""
    from data_tools.io import data_file_written, written_path
    from data_tools.io.npy import sidecar_path
    target = written_path(out)
    beside = data_file_written(target) or (sidecar_path(target) if out.suffix.lower() == ".npy" else None)
    return f"{out} and {beside}" if beside is not None and beside.exists() else str(out)


def _placement(vol, out):
    """The spacing and origin written, for the "wrote" line; a ``.raw`` file keeps neither."""
    spacing = ", ".join(f"{s:g}" for s in vol.spacing)
    origin = ", ".join(f"{o:g}" for o in vol.origin)
    if out.suffix.lower() != ".raw":
        return f", spacing {spacing}, origin {origin}"
    flags = _raw_flags(vol, out)
    if not flags:
        return ", samples only; its name gives their shape and type"
    return f", samples only: read it back with {' '.join(flags)}; a .raw file has no header"


def _raw_flags(vol, out):
    """The flags that read ``vol`` back from ``out``: none but for a ``.raw`` file, which holds
    the samples alone (its name may give their shape and type)."""
    if out.suffix.lower() != ".raw":
        return []
    from data_tools.io.raw import guess_from_name
    named = guess_from_name(out)
    flags = []
    if "shape" not in named:
        flags.append(f"--shape {','.join(map(str, vol.dims))}")
    if "dtype" not in named or "dtypes" in named:
        flags.append(f"--dtype {vol.dtype}")
    # Shortest exact forms: ":g" rounds to 6 digits, and a spacing of 1/3 would read back changed.
    if vol.spacing != (1.0, 1.0, 1.0):
        flags.append(f"--spacing {','.join(map(exact_text, vol.spacing))}")
    if vol.origin != (0.0, 0.0, 0.0):
        flags.append(f"--origin {','.join(map(exact_text, vol.origin))}")
    return flags


def _exists(path):
    try:
        return path.exists()
    except OSError:         # a name too long to be a file (the other header's suffix is longer)
        return False


def _refuse_overwriting_input(out, inputs):
    """Refuse an output whose samples file (a ``.raw`` output itself; ``STEM.raw`` for a
    ``.mhd`` or ``.nhdr``) is a file the volume was read from (the header and its samples, or a
    raw file itself), or the data file of another header beside it: writing it would change
    what that header reads."""
    from data_tools.io import data_file_written, headers_reading, written_path
    out = written_path(out)        # through a link, the files written are beside the file it leads to
    samples = out if out.suffix.lower() == ".raw" else data_file_written(out)
    if samples is None:
        return
    for source in inputs:
        if source is not None and os.path.realpath(source) == os.path.realpath(samples):
            raise InputError(f"{out}: would write its samples to {samples}, which the volume is read from; "
                             "write the output elsewhere or under another name")
    if not _exists(samples):
        return
    readers = headers_reading(samples)
    others = [h for h in readers if os.path.realpath(h) != os.path.realpath(out)]
    if others:
        raise InputError(f"{out}: {samples.name} holds {others[0].name}'s samples, which writing it would "
                         "replace; write the output under another name")
    if samples != out and not readers:
        # Rewriting an earlier output replaces its data file too; any other file of that name is not ours.
        raise InputError(f"{out}: would write its samples to {samples}, which exists and is no earlier "
                         f"{out.name}'s; remove it or write the output under another name")


def cmd_convert(args):
    from data_tools.io import WRITE_EXTENSIONS, save_volume
    out = check_output(args.output, WRITE_EXTENSIONS)
    check_distinct(args.volume, [out])
    with _reading(args):
        vol = load_volume_flags(args)
    files = vol.meta.get("files", ())
    check_distinct(args.volume, [out], read=files)     # a header's own data file, say
    _refuse_overwriting_input(out, [args.volume, *files])
    with slow_note(f"writing {out}", note):    # a compressed 640^3 volume takes seconds
        save_volume(vol, out)  # all-or-nothing itself, and keeps sidecar names right
    if "note" in vol.meta:
        note(vol.meta["note"])
    if vol.meta.get("reoriented"):
        note(f"{out} is written on an axis-aligned grid, without the orientation of {args.volume}: "
             "it does not overlay the input in world space")
    print_out(f"wrote {_written(out)} ({'x'.join(map(str, vol.dims))} {vol.dtype}{_placement(vol, out)})",
              done=f"wrote {_written(out)}")
    return 0


#: Images from this many pixels up take seconds to write (a 4000 x 4000 PNG about 4 s): say so.
LARGE_WRITE_PIXELS = 1 << 22
#: Compiling seconds a render's line reports: its time is then a first run's, not the renderer's.
COMPILE_SAID = 0.5


def cmd_render(args):
    import parc

    from .comparison import check_opengl, check_options
    from .renderer import DEFAULT_BUFFERS, check_request, kernel_samples
    from .workspace import check_scene_memory

    out = check_output(args.output, (".png", ".npy"))
    # An empty path is a mistake to name, not a flag to ignore.
    depth_out = check_output(args.depth, (".npy",)) if args.depth is not None else None
    stats_out = check_output(args.stats, (".json",)) if args.stats is not None else None
    work_out = check_output(args.work, (".png", ".npy")) if args.work is not None else None
    flags = ("-o", "--depth", "--stats", "--work")
    check_distinct(args.volume, [out, depth_out, stats_out, work_out], flags=flags)
    # realpath, not Path.resolve: a sidecar may be a link in a loop, which resolve raises for.
    written = {os.path.realpath(p) for p in (out, depth_out, stats_out, work_out) if p is not None}
    stale = [side for side in stale_sidecars([out, depth_out, work_out]) if os.path.realpath(side) not in written]
    say = (lambda *a: None) if args.quiet else note
    with _reading(args, say):
        scene, notes = scene_and_notes(args)
    check_distinct(args.volume, [out, depth_out, stats_out, work_out] + stale, read=_files_read(scene), flags=flags)
    if stats_out is not None:
        check_not_sidecar(stats_out, [out, depth_out, work_out])   # a volume read is named above
    w, h = scene.size
    kwargs = ({"supercell": args.supercell, "buffers": _buffers(args, scene), "blocks": not args.no_blocks}
              if args.method == "parc" else {})
    if args.method != "parc":
        _refuse_parc_flags(args, "applies to --method parc")
    check_request(scene, kwargs.get("buffers", DEFAULT_BUFFERS), work_out is not None, ("--buffers", "--work"))
    check_scene_memory(scene)
    if args.method == "parc":
        # Its options (a supercell no volume takes), then OpenGL and its image limit: refused before any note.
        check_options(scene, {args.method: kwargs})
        check_opengl(scene, [args.method])
    # What the render will refuse is refused by now, so a note (the level chosen, a transfer
    # function that shows nothing) is said before the wait, not after it.
    for line in notes:
        say(line)
    compile_notice(say, kernel_samples(scene, (args.method,), kwargs.get("buffers", DEFAULT_BUFFERS)))
    progress = None if args.quiet else Progress(f"rendering {w}x{h}")
    with compiling_seconds() as compiling, late_compile_notice(say):
        result = parc.render(scene, method=args.method, progress=progress, work=work_out is not None, **kwargs)
    if progress is not None:
        progress.done()

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
    atomic_write_all(writes, remove=stale)
    s = result.stats
    vis = scene.volumes[0]
    out = ", ".join(str(path) for path, _ in writes)        # every file written, the image first
    took = f"{s['seconds']['total']:.3f} s"
    if compiling[0] >= COMPILE_SAID:
        took += compile_took(compiling[0])
    if len(scene.volumes) > 1:
        say(f"wrote {out}: {len(scene.volumes)} volumes ({_describe_all(scene.volumes)}); {took}")
    elif isinstance(vis, parc.Isosurface):
        say(f"wrote {out}: {s['hits']} of {s['pixels']} pixels hit the isosurface {exact_text(vis.value)}; "
            f"{took}, {s['cells_visited']:,} cells visited, {s['cubic_solves']:,} cubics")
    else:
        say(f"wrote {out}: {vis.mode} of {vis.tf.title}, step {vis.step:g}; {took}, {s['samples']:,} samples")
    for side in stale:
        say(f"removed {side}: the spacing and origin of the .npy volume written over")
    return 0


def _files_read(scene):
    """The files a scene's volumes and transfer functions were read from."""
    files = []
    for vis in scene.volumes:
        files += vis.volume.meta.get("files", ())
        tf = getattr(vis, "tf", None)
        if tf is not None and tf.source and Path(tf.source).is_file():
            files.append(tf.source)
    return files


def _write_work(result, scene, method, path):
    """The work per pixel of a render: an int64 array (.npy) or a heat map (.png)."""
    if path.suffix.lower() == ".npy":
        save_array(path, result.work)
    else:
        _work_png(path, {method: result.work}, scene)


def _work_png(path, maps, scene):
    """Heat maps of the work per pixel of each of ``maps`` (method -> (H, W) counts), side by side."""
    from .bench.heatmaps import work_heat_maps
    from .scene import Isosurface
    w, h = scene.size
    what = "cells visited" if isinstance(scene.volumes[0], Isosurface) else "samples taken"
    work_heat_maps(path, maps, what, f"{w}x{h}")


def _shown(vis):
    """What a volume shows, in a few words: its isovalue, or its transfer function's mode and step."""
    return (f"isovalue {exact_text(vis.value)}" if hasattr(vis, "value")
            else f"{vis.mode} of {vis.tf.title}, step {vis.step:g}")


def _describe(vis):
    """One volume of a scene in a few words, for notes and table headers."""
    return f"{vis.volume.name}, {_shown(vis)}"


#: A scene's volumes named in a line: all up to this many, else one fewer and how many more (a
#: scene of 300 made a line of 11,000 characters).
DESCRIBED_VOLUMES = 6


def _describe_all(volumes):
    """A scene's volumes in one line: each in a few words, the first few where there are many."""
    shown = volumes if len(volumes) <= DESCRIBED_VOLUMES else volumes[:DESCRIBED_VOLUMES - 1]
    rest = len(volumes) - len(shown)
    return "; ".join([_describe(v) for v in shown] + ([f"and {rest} more"] if rest else []))


def cmd_compare(args):
    from .comparison import MAX_REPEATS, SUPERCELL_SWEEP_NOTE, compare, format_table, method_names, work_per_pixel
    from .renderer import check_request, kernel_samples

    say = (lambda *a: None) if args.quiet else note
    notes = []

    def announce(line):
        # Called first once compare's checks have passed: the notes come before the wait.
        while notes:
            say(notes.pop(0))
        say(f"{line} ...")

    warming = None if args.quiet else announce
    methods = method_names(args.methods, "--methods")
    if not any(m.split(":")[0] == "parc" for m in methods):
        # Before the scene and the note on compiling the casters: a run refused has its error line alone.
        _refuse_parc_flags(args, "applies to parc, which --methods leaves out")
    if not 1 <= args.repeats <= MAX_REPEATS:
        raise InputError(f"--repeats must be from 1 to {MAX_REPEATS}, got {args.repeats}")
    _check_sweep_flags(args)
    work_out = check_output(args.work, (".png",)) if args.work is not None else None
    if work_out is not None and args.sweep_step is not None:
        raise InputError("--work draws the work of compare's methods side by side; it is not for --sweep-step")
    # Parsed before the volume is read: refused before any work.
    steps = _swept_steps(args.sweep_step) if args.sweep_step is not None else None
    if args.sweep_supercell is not None:
        sizes = _swept_supercells(args.sweep_supercell)
        labels = [f"parc:{_size_label(s)}" for s in sizes]
    with _reading(args, say):
        scene, said = scene_and_notes(args)
    notes.extend(said)
    if steps is not None:
        from .transfer import reference_step
        # --step with the sweep is refused; a scene file's own step is replaced, and said so.
        for n, vis in enumerate(scene.volumes, 1):
            if hasattr(vis, "tf") and vis.step != reference_step(vis.volume.spacing):
                notes.append(f"the step sweep replaces volume[{n}]'s step {vis.step:g} from {args.volume}")
    common = {"buffers": _buffers(args, scene), "blocks": not args.no_blocks}
    check_request(scene, common["buffers"], work_out is not None, ("--buffers", "--work"))
    if work_out is not None:
        check_distinct(args.volume, [work_out], read=_files_read(scene), flags=("--work",))
    if steps is not None and args.supercell is not None:
        common["supercell"] = args.supercell
    if warming is not None:
        compile_notice(say, kernel_samples(scene, ["brute"] + [m.split(":")[0] for m in methods], common["buffers"],
                                            repeated=True))
    if steps is not None:
        from .comparison import format_step_table, step_sweep
        with late_compile_notice(say):
            rows = step_sweep(scene, steps, repeats=args.repeats, progress=warming, options=common)
        if args.json:
            print_out(to_json(rows))
        else:
            print_out(_heading(args, scene, sweeping_step=True))
            print_out(format_step_table(rows))
        return 0
    # Every parc method gets the flags, labelled ones ("parc:x") too.
    options = {m: dict(common) for m in methods if m.split(":")[0] == "parc"}
    if args.sweep_supercell is not None:
        methods = ["brute"] + labels
        options = {label: {"supercell": s, **common} for label, s in zip(labels, sizes)}
    elif args.supercell is not None:
        options = {m: {"supercell": args.supercell, **opts} for m, opts in options.items()}
    with late_compile_notice(say):
        rows = compare(scene, methods=methods, repeats=args.repeats, options=options, progress=warming)
    done = None
    if work_out is not None:
        # Written before the table: a closed or full standard output must not cost the picture.
        with slow_note(f"rendering {', '.join(methods)} once more for --work", say):
            maps = work_per_pixel(scene, methods, options=options)
        atomic_write_all([(work_out, lambda tmp: _work_png(tmp, maps, scene))])
        done = f"wrote {work_out}"
    if args.json:
        print_out(to_json(rows), done=done)
    else:
        print_out(_heading(args, scene), done=done)
        print_out(format_table(rows, notes=[SUPERCELL_SWEEP_NOTE] if args.sweep_supercell is not None else []),
                  done=done)
    if work_out is not None:
        say(f"wrote {work_out}: the work per pixel of {', '.join(maps)}")
    return 0


def _heading(args, scene, sweeping_step=False):
    """The line above compare's table: what was rendered, how large, how often."""
    w, h = scene.size
    vis = scene.volumes[0]
    runs = f"{w}x{h} pixels, median of {args.repeats} after a warm-up"
    if len(scene.volumes) > 1:
        return f"{args.volume}: {len(scene.volumes)} volumes ({_describe_all(scene.volumes)}), {runs}"
    shown = f"{vis.mode} of {vis.tf.title}" if sweeping_step else _shown(vis)
    dims = "x".join(map(str, vis.volume.dims))
    named = re.search(rf"(?<!\d){dims}(?!\d)", vis.volume.name)         # "builtin 64x64x64"
    sized = f"{vis.volume.dtype}" if named else f"{dims} {vis.volume.dtype}"
    return f"{vis.volume.name}: {sized}, {shown}, {runs}"


def cmd_bench(args):
    from .bench import main
    return main(args)


def _buffers(args, scene):
    """PARC's buffers from --buffers (parsed, refused where no volume of ``scene`` is translucent;
    the rest of what a scene refuses, `parc.renderer.check_request` says)."""
    from .renderer import DEFAULT_BUFFERS, parse_buffers
    from .scene import Translucent
    if args.buffers is None:
        return DEFAULT_BUFFERS
    buffers = parse_buffers(args.buffers)
    if not any(isinstance(v, Translucent) for v in scene.volumes):
        raise InputError("--buffers applies to translucent volumes (--tf); isosurfaces use the depth buffers")
    return buffers


def _refuse_parc_flags(args, why):
    """Refuse PARC's own flags where no parc render runs: ``--FLAG {why}``."""
    for flag, given in (("--supercell", args.supercell is not None), ("--no-blocks", args.no_blocks),
                        ("--buffers", args.buffers is not None)):
        if given:
            raise InputError(f"{flag} {why}")


def _check_sweep_flags(args):
    """Refuse compare flags a sweep would ignore: one sweep at a time, and no fixed setting of what it varies."""
    from .comparison import method_names
    if args.sweep_step is not None and args.sweep_supercell is not None:
        raise InputError("give --sweep-step or --sweep-supercell, not both")
    if args.sweep_step is not None:
        sweep = "--sweep-step"
    elif args.sweep_supercell is not None:
        sweep = "--sweep-supercell"
    else:
        return
    if sweep == "--sweep-supercell" and args.supercell is not None:
        raise InputError("--supercell does not combine with --sweep-supercell (it varies the supercell)")
    if set(method_names(args.methods)) != {"brute", "parc"}:
        raise InputError(f"--methods does not combine with {sweep} (it runs brute and parc itself)")
    if sweep == "--sweep-step" and args.step is not None:
        raise InputError("--step does not combine with --sweep-step (it varies the step)")


def _size_label(size):
    """A supercell size as a method label: ``4``, ``4.0000001`` or ``1x2x3``: every digit it
    needs, so that two sizes never share a label (and a row)."""
    if isinstance(size, tuple) and len(set(size)) == 1:
        size = size[0]              # 2,2,2 is the size 2: one label, so that a sweep takes it once
    return "x".join(map(exact_text, size)) if isinstance(size, tuple) else exact_text(size)


def _swept_steps(given):
    """``--sweep-step``'s steps, or one error line."""
    try:
        steps = [float(v) for v in given.split(",")]
    except ValueError:
        steps = []
    if not steps or not all(np.isfinite(steps)) or min(steps) <= 0:
        raise InputError(f"--sweep-step must be comma-separated positive numbers, got {given!r}")
    twice = sorted({v for v in steps if steps.count(v) > 1})
    if twice:
        raise InputError(f"--sweep-step gives {twice[0]:g} twice")
    return steps


def _swept_supercells(given):
    """``--sweep-supercell``'s sizes, or one error line: numbers apart by ',', or sizes of M,N,P
    cells apart by ';' (one alone as ``2,2,4;``)."""
    given = given.strip()
    entries = given.removesuffix(";").split(";") if ";" in given else given.split(",")
    sizes = [_swept_supercell(v) for v in entries]
    labels = [_size_label(s) for s in sizes]
    twice = sorted({label for label in labels if labels.count(label) > 1})
    if twice:
        raise InputError(f"--sweep-supercell gives {twice[0]} twice"
                         + ("" if ";" in given else "; sizes of M,N,P cells are apart by ';', "
                            "as in '2,2,4;4,4,8' (one alone: '2,2,4;')"))
    return sizes


def _swept_supercell(text):
    """One size of ``--sweep-supercell``, as ``--supercell`` reads it, or one error line."""
    try:
        return supercell_flag(text)
    except argparse.ArgumentTypeError as exc:
        raise InputError(f"--sweep-supercell: {exc}") from None


if __name__ == "__main__":
    sys.exit(main())
