"""The ``hbrdf`` command line.

    hbrdf demo [--out PATH] [--samples N]   plot f_a slices of a few materials to PNG
    hbrdf --version

Errors are printed as one line on stderr with a non-zero exit status.
"""

from __future__ import annotations

import argparse
import sys


def _cmd_demo(args: argparse.Namespace) -> int:
    from hybridbrdf.demo import run_demo

    run_demo(args.out, samples=args.samples)
    return 0


def build_parser() -> argparse.ArgumentParser:
    from hybridbrdf import __version__

    parser = argparse.ArgumentParser(prog="hbrdf", description="Hybrid neural-microfacet BRDFs.")
    parser.add_argument("--version", action="version", version=f"hybridbrdf {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser(
        "demo",
        help="plot BRDF slices of built-in analytic materials and print their albedo",
        description="Plot in-plane slices and polar lobes of f_a for a few built-in analytic materials "
        "(C++ library, checked against the float64 PyTorch implementation) and print each material's "
        "directional albedo estimated with every sampling strategy.",
    )
    demo.add_argument("--out", default="out/analytic_slices.png", help="PNG file to write (default: %(default)s)")
    demo.add_argument(
        "--samples", type=int, default=200_000, help="samples per albedo estimate (default: %(default)s)"
    )
    demo.set_defaults(func=_cmd_demo)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, OSError) as exc:
        print(f"hbrdf {args.command}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
