"""``hbrdf mix``: a blend of two materials' analytic parameters and latent codes."""

from __future__ import annotations

import argparse

from hybridbrdf.cli import COMMANDS, FINITE
from hybridbrdf.cli.edit import add_new_material_flags, describe_new_material
from hybridbrdf.files import check_writable, file_lock


def add_parser(sub) -> None:
    p = sub.add_parser("mix", help=COMMANDS["mix"],
                       description="Paper Sec. 5.1: the linear blend (1 - t) A + t B of two materials' analytic "
                                   "parameters and latent codes, added to MODEL's materials and written to --out; "
                                   "t = 0 and 1 reproduce A and B exactly. Prints the blend's maximum directional "
                                   "albedo.")
    p.add_argument("model", help="model file holding both materials")
    p.add_argument("a", metavar="A", help="material at t = 0")
    p.add_argument("b", metavar="B", help="material at t = 1")
    p.add_argument("--t", type=FINITE, required=True, help="blend weight of B, in [0, 1] (the library checks the range)")
    add_new_material_flags(p, "the blend's kd", "its")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.model.file import load_model  # NumPy: imported by the command, not by --help

    check_writable(args.out, "model")
    with file_lock(args.out):  # as hbrdf edit: an update in place reads MODEL under the lock
        model = load_model(args.model)
        blend = model.mix(args.a, args.b, args.t, args.as_name, conserve_energy=args.conserve_energy)
        written = blend.save_checked(args.out)
    return describe_new_material(written, args.as_name, args.out)
