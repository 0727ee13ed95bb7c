"""``hbrdf render``: a JSON scene through the Embree path tracer."""

from __future__ import annotations

import argparse
import signal
import sys
import threading

from hybridbrdf import _core
from hybridbrdf.cli import COMMANDS, FINITE
from hybridbrdf.fit.settings import Number

#: --exposure's range in stops: 2^64 scales any radiance float32 holds past its range or below it.
EXPOSURE_STOPS = 64


def add_parser(sub) -> None:
    p = sub.add_parser("render", help=COMMANDS["render"],
                       description="Render a JSON scene (docs/RENDERING.md) with the reference path tracer: "
                                   "linear float32 OpenEXR, optionally a tone-mapped sRGB PNG.")
    p.add_argument("scene", help="scene file (JSON)")
    p.add_argument("-o", "--out", required=True, help="OpenEXR file to write (linear RGB, float32)")
    p.add_argument("--png", help="also write an 8-bit sRGB PNG")
    add_render_setting_flags(p)
    p.add_argument("--exposure", type=Number(float, -EXPOSURE_STOPS, EXPOSURE_STOPS), default=0.0,
                   help=f"PNG exposure in stops, within +-{EXPOSURE_STOPS} (default: %(default)s)")
    p.add_argument("--tonemap", choices=("clamp", "aces"), default="clamp", help="PNG tone map (default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def render_settings():
    """The library's scene settings as :func:`hybridbrdf.render.tracer.settings` gives them, read from
    the extension here: the tracer's module imports NumPy, and ``hbrdf render`` with a mistyped flag
    should not wait for it."""
    return list(_core.render_settings()) if getattr(_core, "HAVE_RENDERER", False) else []


def add_render_setting_flags(parser: argparse.ArgumentParser) -> None:
    """--spp, --max-depth, ...: one flag per scene setting of the library's table (hybridbrdf.render.tracer.settings()),
    typed and documented by it; the library checks the ranges when rendering (one-line errors)."""
    for s in render_settings():
        flag = "--" + s["name"].replace("_", "-")
        default = str(s["default"]).lower() if s["type"] == "bool" else s["default"]
        help_text = f"{s['doc']} (default: the scene's, else {default})".replace("%", "%%")
        if s["type"] == "bool":
            parser.add_argument(flag, dest=s["name"], action=argparse.BooleanOptionalAction, default=None,
                                help=help_text)
        else:
            parser.add_argument(flag, dest=s["name"], type={"int": int, "float": FINITE, "str": str}[s["type"]],
                                choices=s["choices"], default=None,
                                metavar=None if s["choices"] else ("N" if s["type"] == "int" else "X"),
                                help=help_text)


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.render.tracer import RenderMaterialError, render  # NumPy: not for --help

    # One flag per scene setting (the library's table); None = keep the scene's value.
    overrides = {s["name"]: getattr(args, s["name"]) for s in render_settings()}
    # SIGTERM stops the render as Ctrl-C does: the library runs Python's signal handlers while it
    # works, and an exception from one cancels the render before any file is written.
    terminated = []

    def on_sigterm(signum, frame):
        terminated.append(signum)
        raise KeyboardInterrupt

    in_main_thread = threading.current_thread() is threading.main_thread()  # signal.signal needs it
    previous = signal.signal(signal.SIGTERM, on_sigterm) if in_main_thread else None
    try:
        _, stats = render(args.scene, out=args.out, png=args.png, quiet=args.quiet, exposure=args.exposure,
                          tonemap=args.tonemap, **overrides)
    except KeyboardInterrupt:
        print(f"hbrdf render: {'terminated' if terminated else 'interrupted'}, nothing written", file=sys.stderr)
        return 128 + (signal.SIGTERM if terminated else signal.SIGINT)
    except RenderMaterialError as exc:  # one line naming the scene and the material, as main() prints scene errors
        print(f"hbrdf render: error: {exc}", file=sys.stderr)
        return 1
    except MemoryError as exc:  # the sizes a scene sets are checked up front; this is the machine's limit
        print(f"hbrdf render: error: out of memory ({exc or 'MemoryError'})", file=sys.stderr)
        return 1
    finally:
        if in_main_thread:
            signal.signal(signal.SIGTERM, previous if previous is not None else signal.SIG_DFL)
    print(f"rendered {args.scene}: {stats['spp']} spp in {stats['seconds']:.2f} s "
          f"({stats['samples_per_second']:,.0f} samples/s, {stats['rays']:,} rays + {stats['shadow_rays']:,} shadow rays, "
          f"{stats['network_evals']:,} of {stats['brdf_evals']:,} BRDF evaluations ran the network, "
          f"{stats['threads']} threads); wrote {args.out}" + (f" and {args.png}" if args.png else ""))
    return 0
