"""``hbrdf paint``: a textured material, layers of materials under grey masks (docs/SVBRDF.md)."""

from __future__ import annotations

import argparse

from hybridbrdf import spec
from hybridbrdf.cli import COMMANDS, layer_masks


def add_parser(sub) -> None:
    p = sub.add_parser("paint", help=COMMANDS["paint"],
                       description="Write a textured material's folder (docs/SVBRDF.md): a base material and up to "
                                   "three layers painted over it by grey masks (the last on top), optional albedo "
                                   "and roughness textures per layer. A layer that names a measured file is added "
                                   "to the model first by a sparse fit on its frozen network. Per texel the "
                                   "material is the mixture of its layers' BRDFs. OUT is replaced only once complete.")
    p.add_argument("model", help="model file holding the layers' materials (a hybrid model)")
    p.add_argument("--base", required=True, metavar="MATERIAL_OR_FILE", help="layer 0: a material of MODEL or a measured file")
    p.add_argument("--layer", action="append", metavar="MATERIAL_OR_FILE=MASK",
                   help="a layer over the others (repeatable, at most 3): a material or measured file and its mask "
                        "(PNG or EXR; grey values, the first channel, are the layer's coverage)")
    p.add_argument("--kd", action="append", metavar="LAYER=ALBEDO",
                   help="layer LAYER's kd from an albedo texture (sRGB 8-bit PNG or linear EXR; repeatable); a texture "
                        "brighter than the layer's material gives the layer an energy-bounded edit, MATERIAL.kdmapLAYER")
    p.add_argument("--roughness", action="append", metavar="LAYER=ROUGHNESS",
                   help="layer LAYER's GGX alpha = r^2 from a grey roughness texture r (repeatable)")
    p.add_argument("--normal", metavar="NORMALMAP",
                   help="a tangent-space normal map for the texel, all layers (glTF 2.0 style: 8-bit RGB PNG, R and G "
                        "the normal's x and y as (v + 1) / 2, green up; z reconstructed; docs/SVBRDF.md, Normal maps)")
    p.add_argument("--size", metavar="WxH", help="texels (default: the masks' size; masks and textures must have it)")
    p.add_argument("--format", choices=("png", "exr", "ktx2"), default="png",
                   help="maps as 8-bit PNG, float32 OpenEXR or KTX2 in GPU block formats (BC1/BC4/BC5/BC7; each file "
                        "holds its mip chain) (default: %(default)s)")
    p.add_argument("--mips", action="store_true",
                   help="write the complete mip chain, each quantity filtered as the BRDF asks (docs/SVBRDF.md, "
                        "Mip chains); the size's sides must be powers of two")
    p.add_argument("--addressing", choices=tuple(spec.SVBRDF["addressing"]), default="repeat",
                   help="how uv outside [0, 1] reads the maps (default: %(default)s)")
    p.add_argument("--out", required=True, help="folder to write (replaced if it is a textured material's folder)")
    p.add_argument("--quiet", action="store_true", help="no progress bar while measured files are fitted")
    p.add_argument("--kd-format", choices=("bc1", "bc7"), default="bc1",
                   help="with --format ktx2, the block format of kd maps: bc1 (sRGB, half a byte a texel) or bc7 "
                        "(sRGB, a byte, a third of BC1's error; decoded in software at every tap by CPU Vulkan "
                        "drivers) (default: %(default)s; docs/SVBRDF.md, KTX2 maps)")
    p.set_defaults(func=run)


def _layer_option(values, flag: str) -> dict:
    """``K=PATH`` pairs of --kd / --roughness: layer index -> path."""
    out = {}
    for v in values or []:
        k, sep, path = v.partition("=")
        if not sep or not k.strip().isdigit() or not path:
            raise ValueError(f"{flag} takes LAYER=FILE with LAYER a number (0 the base), got {v!r}")
        out[int(k)] = path
    return out


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.fit import paint

    layers = layer_masks(args.layer, "MATERIAL_OR_FILE")
    size = None
    if args.size:
        w, sep, h = args.size.lower().partition("x")
        if not sep or not w.isdigit() or not h.isdigit():
            raise ValueError(f"--size takes WxH, got {args.size!r}")
        size = (int(w), int(h))
    sv = paint(args.model, args.base, layers, args.out, size=size, format=args.format, addressing=args.addressing,
               kd=_layer_option(args.kd, "--kd"), roughness=_layer_option(args.roughness, "--roughness"),
               progress=not args.quiet, log=print, mips=args.mips, normal=args.normal,
               kd_format=args.kd_format)
    w, h = sv.size
    chain = (f", {sv.levels} mip levels" if sv.levels > 1 else "") + (", a normal map" if sv.normal is not None else "")
    print(f"wrote {args.out}: {w}x{h} texels, {len(sv.layers)} layer(s) ({', '.join(sv.layers)}), {args.format} maps{chain}")
    return 0
