"""``hbrdf raster``: a scene drawn by a headless Vulkan graphics pipeline with the generated GLSL in
its fragment stage (docs/RASTER.md)."""

from __future__ import annotations

import argparse
import sys

from hybridbrdf.cli import COMMANDS
from hybridbrdf.fit.settings import Number
from hybridbrdf.raster.sizes import SPHERE_SEGMENTS


def add_parser(sub) -> None:
    p = sub.add_parser(
        "raster", help=COMMANDS["raster"],
        description="Draw a path-tracer scene file (docs/RENDERING.md) the way an engine draws it: its meshes, "
                    "planes and tessellated spheres rasterized by hbrdf_raster (Vulkan), the generated GLSL of its "
                    "materials in the fragment stage, its point and directional lights summed per pixel. No "
                    "shadows, no environment light, one sample at each pixel centre: the tracer's direct-light "
                    "picture (max_depth 1, pixel_jitter 0, shadows 0). Analytic, model and textured materials (one "
                    "textured folder of PNG, EXR or KTX2 maps, its maps through samplers with its mip chain, KTX2 "
                    "blocks as stored); measured materials are refused.")
    p.add_argument("scene", help="scene file (JSON, docs/RENDERING.md)")
    p.add_argument("--out", required=True, help="linear OpenEXR output (float32 RGB)")
    p.add_argument("--png", help="also an 8-bit sRGB PNG (values clipped to [0, 1])")
    p.add_argument("--validation", action="store_true",
                   help="run under the Khronos validation layer; any warning or error it reports fails the command")
    p.add_argument("--repeat", type=Number(int, 0, 100_000), default=0, metavar="R",
                   help="draw R more frames and print the best frame time in ms (host clock; the device's "
                        "timestamps where it has them); default %(default)s")
    p.add_argument("--sphere-segments", type=Number(int, 8, 8192), default=SPHERE_SEGMENTS, metavar="N",
                   help="segments of a sphere's tessellation around its axis (even; half as many pole to pole); "
                        "default %(default)s")
    p.add_argument("--lavapipe", action="store_true",
                   help="pin Mesa's CPU Vulkan driver (lavapipe) instead of the Vulkan loader's first device")
    p.add_argument("--tool", help="the hbrdf_raster executable (default: $HBRDF_RASTER, else hbrdf_raster on PATH; "
                                  "a source build has it in build/)")
    p.add_argument("--language", choices=["glsl", "hlsl"], default="glsl",
                   help="the fragment stage's shading language: the generated GLSL, or the generated HLSL through "
                        "glslang's HLSL front end; default %(default)s")
    p.add_argument("--keep-shaders", metavar="DIR", help="write the generated code, both stages and their SPIR-V into DIR")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.raster.frame import draw_frame

    if args.sphere_segments % 2:
        raise ValueError(f"--sphere-segments: must be even, got {args.sphere_segments}")
    try:
        stats = draw_frame(args.scene, args.out, png=args.png, validation=args.validation, repeat=args.repeat,
                           sphere_segments=args.sphere_segments, lavapipe=args.lavapipe, tool=args.tool,
                           keep_shaders=args.keep_shaders, language=args.language)
    except RuntimeError as exc:  # the tool's, the compilers' or Vulkan's words, one line
        print(f"hbrdf raster: {exc}", file=sys.stderr)
        return 1
    print(f"wrote {args.out}" + (f" and {args.png}" if args.png else "") + f" ({stats.get('device')}, "
          f"{stats.get('size')}, {int(stats.get('triangles', 0))} triangles)")
    if args.repeat:
        gpu = f", {stats['best_gpu_ms']:.3f} ms on the device's clock" if "best_gpu_ms" in stats else ""
        print(f"best frame: {stats['best_ms']:.3f} ms{gpu}")
    return 0
