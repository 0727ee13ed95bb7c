"""``hbrdf demo``: BRDF slices of built-in analytic materials and their albedo."""

from __future__ import annotations

import argparse

from hybridbrdf.demo.sizes import BYTES_PER_SAMPLE, SAMPLES
from hybridbrdf.cli import COMMANDS


def add_parser(sub) -> None:
    p = sub.add_parser(
        "demo",
        help=COMMANDS["demo"],
        description="Plot in-plane slices and polar lobes of f_a for a few built-in analytic materials "
        "(C++ library, checked against the float64 PyTorch implementation) and print each material's "
        "directional albedo estimated with every sampling strategy.",
    )
    p.add_argument("--out", default="out/analytic_slices.png", help="PNG file to write (default: %(default)s)")
    p.add_argument("--samples", type=int, default=SAMPLES, metavar="N",
                   help=f"samples per albedo estimate (default: %(default)s; at most what fits this machine's memory, "
                        f"{BYTES_PER_SAMPLE} bytes a sample; docs/CONVENTIONS.md, \"Counts and memory\")")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.demo.slices import run_demo

    run_demo(args.out, samples=args.samples)
    return 0
