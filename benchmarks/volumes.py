"""What the micro-benchmark scripts here share: the volume one measures, from its flags, and
how a script reads counts and ends on bad input."""
import argparse
import sys
from pathlib import Path

CTHEAD = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "CThead.nrrd"

#: The CT volumes' default level: skin.
CT_SKIN = 600.5

#: A synthetic volume's side where ``--n`` does not give one.
SYNTHETIC_SIZE = 256


def add_volume_flags(ap):
    """The flags `pick_volume` reads, on an argparse parser."""
    ap.add_argument("--volume")
    ap.add_argument("--iso", type=float)
    ap.add_argument("--synthetic", help="a data_tools synthetic volume name (sphere, torus, ...)")
    ap.add_argument("--n", type=count, help=f"synthetic volume size (default {SYNTHETIC_SIZE})")


def pick_volume(args, need_iso=True):
    """``(volume, isovalue)``: ``--synthetic NAME --n N`` (its own level), ``--volume PATH``, or
    else CThead from ../shared/data when present and a CT-like phantom when not (skin); ``--iso``
    replaces the default level, and a file's has none (None where not ``need_iso``)."""
    from data_tools.io import load_volume
    from data_tools.synthetic import ct_phantom, make_synthetic
    # A flag that would change nothing is refused: a measurement taken believing it applied
    # would be of another scene than the one named.
    if args.synthetic and args.volume:
        raise ValueError("give --synthetic or --volume, not both")
    if args.n is not None and not args.synthetic:
        raise ValueError("--n sizes a --synthetic volume; it does not apply here")
    if args.iso is not None and not need_iso:
        raise ValueError("--iso applies to an isosurface; this run casts a translucent volume (--tf)")
    if args.synthetic:
        vol = make_synthetic(args.synthetic, args.n or SYNTHETIC_SIZE)
        default = vol.meta.get("iso", 0.0)
    elif args.volume:
        vol, default = load_volume(args.volume), None
    elif CTHEAD.exists():
        vol, default = load_volume(str(CTHEAD)), CT_SKIN
    else:
        vol, default = ct_phantom(192), CT_SKIN
    iso = args.iso if args.iso is not None else default
    if iso is None and need_iso:
        raise ValueError("--volume needs --iso")
    if iso is not None and need_iso:
        # Refused as `parc` refuses it (outside the data, not finite): scripts that call the kernels
        # directly would otherwise time an empty scene and call it the same as brute's.
        from parc import Isosurface
        Isosurface(vol, iso)
    return vol, iso


def count(text):
    """An argparse type: a whole number of at least 1 (a size, repeats, threads)."""
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number of at least 1, got {text!r}")
    return n


def run(main):
    """Exit with ``main()``'s status; bad input (a missing file, a level outside the data) ends
    in one line naming the script and status 2, as `parc`'s own commands do, not in a traceback."""
    try:
        status = main()
    except (ValueError, OSError) as exc:         # InputError is a ValueError
        print(f"{Path(sys.argv[0]).name}: error: {exc}", file=sys.stderr)
        sys.exit(2)
    except MemoryError as exc:
        print(f"{Path(sys.argv[0]).name}: error: out of memory{f': {exc}' if str(exc) else ''}; "
              "try smaller sizes", file=sys.stderr)
        sys.exit(1)
    sys.exit(status)
