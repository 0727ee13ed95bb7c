"""``hbrdf convert``: a textured material's folder with its maps in another format, with or
without its mip chain (docs/SVBRDF.md, "Mip chains" and "KTX2 maps")."""

from __future__ import annotations

import argparse

from hybridbrdf.cli import COMMANDS


def add_parser(sub) -> None:
    p = sub.add_parser("convert", help=COMMANDS["convert"],
                       description="Read a textured material's folder and write it again with its maps as 8-bit PNG, "
                                   "float32 OpenEXR or KTX2 (GPU block formats: BC1/BC4/BC5/BC7, each file holding its "
                                   "mip chain), with the complete mip chain built from level 0 (--mips) or level 0 "
                                   "alone (--no-mips); without either, the chain SRC has. The model and layers are copied unchanged. OUT is replaced "
                                   "only once complete; OUT may be SRC.")
    p.add_argument("src", metavar="SRC", help="a textured material's folder")
    p.add_argument("--out", required=True, help="folder to write (replaced if it is a textured material's folder)")
    p.add_argument("--format", choices=("png", "exr", "ktx2"), required=True, help="the maps' format")
    chain = p.add_mutually_exclusive_group()
    chain.add_argument("--mips", action="store_true", default=None,
                       help="build the complete mip chain from level 0 (power-of-two sides)")
    chain.add_argument("--no-mips", dest="mips", action="store_false", help="write level 0 alone")
    p.add_argument("--kd-format", choices=("bc1", "bc7"), default="bc1",
                   help="with --format ktx2, the block format of kd maps: bc1 (sRGB, half a byte a texel) or bc7 "
                        "(sRGB, a byte, a third of BC1's error; decoded in software at every tap by CPU Vulkan "
                        "drivers) (default: %(default)s; docs/SVBRDF.md, KTX2 maps)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.svbrdf import load_svbrdf

    sv = load_svbrdf(args.src)
    level0 = type(sv)(sv.model, sv.layers, sv.size, sv.weights, sv.maps, sv.addressing, sv.path, normal=sv.normal)
    # Neither flag: the chain as it is (levels someone authored stay theirs).
    out = sv if args.mips is None else level0.with_mips() if args.mips else level0
    out.save(args.out, format=args.format, kd_format=args.kd_format)
    w, h = out.size
    chain = f", {out.levels} mip levels" if out.levels > 1 else ""
    print(f"wrote {args.out}: {w}x{h} texels, {len(out.layers)} layer(s), {args.format} maps{chain}")
    return 0
