"""``hbrdf view``: one self-contained HTML page that shows the materials live (WebGPU or WebGL2)."""

from __future__ import annotations

import argparse

from hybridbrdf.fit.settings import positive_int
from hybridbrdf.viewer.sizes import DEFAULT_SOURCE_SIZE, DEFAULT_SOURCE_SPP
from hybridbrdf.cli import COMMANDS


def add_parser(sub) -> None:
    p = sub.add_parser("view", help=COMMANDS["view"],
                       description="Write one HTML file, with everything inlined (it opens from disk, without "
                                   "network), that renders each material of MODEL on a sphere with WebGPU where the "
                                   "browser has it, else WebGL2, from the WGSL and GLSL that hbrdf-codegen writes: a "
                                   "material picker, the analytic part alone, "
                                   "kd / eta / alpha sliders that preview hbrdf edit (with its command line), "
                                   "exposure, and light from an environment map (default the path tracer's sky) or "
                                   "the sun alone (docs/VIEWER.md). With --svbrdf DIR it shows a textured material "
                                   "instead (WebGL2).")
    p.add_argument("model", nargs="?", metavar="MODEL",
                   help="model file (optional with --svbrdf, which shows the folder's own model; given, it must be "
                        "that model)")
    p.add_argument("sources", nargs="*", metavar="SOURCE",
                   help="BRDF sources the materials were fitted to: each is shown beside the material the fit "
                        "named after it, as the path tracer's render of the measurement and BRDF slices of the "
                        "model, its f_a and the measurement (docs/VIEWER.md)")
    p.add_argument("--out", "-o", required=True, help="HTML file to write")
    p.add_argument("--env", metavar="sky|MAP", default="sky",
                   help="environment map the page lights with: 'sky' (default: the path tracer's sky, a sun of "
                        "irradiance pi) or an equirectangular .exr / .hdr map (the tracer's mapping; maps wider "
                        "than 1024 texels are area-averaged down)")

    p.add_argument("--svbrdf", metavar="DIR",
                   help="show the textured material of DIR (written by hbrdf paint; docs/SVBRDF.md) on the sphere, "
                        "its layers mixed per texel by its maps at the path tracer's sphere uv (bilinear), with the "
                        "maps as small images beside it; WebGL2 only (docs/VIEWER.md, 'A textured material')")
    p.add_argument("--source-size", type=positive_int, default=DEFAULT_SOURCE_SIZE, metavar="N",
                   help="pixels (square) of each SOURCE's measured render, 8 to 1024 (default: %(default)s)")
    p.add_argument("--source-spp", type=positive_int, default=DEFAULT_SOURCE_SPP, metavar="N",
                   help="samples per pixel of each SOURCE's measured render (default: %(default)s; about 4 s "
                        "per RGL source on 2 cores)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.viewer.page import write_page

    if args.svbrdf is None and args.model is None:
        raise ValueError("give MODEL, or --svbrdf DIR")
    info = write_page(args.model, args.out, args.sources, env=args.env,
                      source_options={"size": args.source_size, "spp": args.source_spp}, svbrdf=args.svbrdf)
    what = f"{info['materials']} materials" if args.svbrdf is None else "a textured material"
    print(f"wrote {args.out} ({info['bytes'] / 2**20:.2f} MiB, {what}): open it in a browser "
          f"with {'WebGPU or ' if args.svbrdf is None else ''}WebGL2; it needs no network")
    return 0
