"""The volume a micro-benchmark script measures, from its flags (shared by the scripts here)."""
from pathlib import Path

CTHEAD = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "CThead.nrrd"

#: The CT volumes' default level: skin.
CT_SKIN = 600.5


def add_volume_flags(ap):
    """The flags `pick_volume` reads, on an argparse parser."""
    ap.add_argument("--volume")
    ap.add_argument("--iso", type=float)
    ap.add_argument("--synthetic", help="a data_tools synthetic volume name (sphere, torus, ...)")
    ap.add_argument("--n", type=int, default=256, help="synthetic volume size")


def pick_volume(args, need_iso=True):
    """``(volume, isovalue)``: ``--synthetic NAME --n N`` (its own level), ``--volume PATH``, or
    else CThead from ../shared/data when present and a CT-like phantom when not (skin); ``--iso``
    replaces the default level, and a file's has none (None where not ``need_iso``)."""
    from data_tools.io import load_volume
    from data_tools.synthetic import ct_phantom, make_synthetic
    if args.synthetic:
        vol = make_synthetic(args.synthetic, args.n)
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
    return vol, iso
