"""``hbrdf edit``: an edited copy of a material (new analytic parameters, same latent code), and
what ``hbrdf mix`` shares with it: the flags and the report of the material they add."""

from __future__ import annotations

import argparse
import sys

from hybridbrdf.cli import COMMANDS
from hybridbrdf.files import check_writable, file_lock


def add_parser(sub) -> None:
    p = sub.add_parser("edit", help=COMMANDS["edit"],
                       description="Paper Sec. 5.1: change the analytic parameters of a fitted material (diffuse "
                                   "colour kd, index of refraction eta, GGX roughness alpha; two alpha values make "
                                   "it anisotropic) and keep its latent code, so the network's correction follows. "
                                   "Writes MODEL's materials plus the edited one to --out and prints its maximum "
                                   "directional albedo (a warning when it exceeds 1). --out is written only when "
                                   "everything is valid.")
    p.add_argument("model", help="model file holding the material")
    p.add_argument("material", help="name of the material to start from")
    p.add_argument("--set", action="append", required=True, metavar="KEY=VALUES",
                   help="a new parameter: kd=R,G,B or kd=V (in [0, 1]), eta=V or eta=R,G,B (in [1, 10]), "
                        "alpha=V (isotropic) or alpha=AX,AY (anisotropic; in [1e-4, 1]); repeatable")
    add_new_material_flags(p, "the new kd", "the")
    p.set_defaults(func=run)


def add_new_material_flags(p, kd: str, whose: str) -> None:
    """--as, --out and --conserve-energy: the flags hbrdf edit and hbrdf mix share for the material they add."""
    p.add_argument("--as", dest="as_name", required=True, metavar="NAME", help="name of the new material")
    p.add_argument("--out", required=True, help="model file to write (may be MODEL itself)")
    p.add_argument("--conserve-energy", action="store_true",
                   help=f"also scale {kd} down (hue kept) until {whose} maximum directional albedo is at most 0.99, "
                        "where kd can do it (the energy-bound table bounds it in any case; docs/ENERGY.md)")


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.model.editing import parse_assignments  # NumPy: imported by the command, not by --help
    from hybridbrdf.model.file import load_model

    values = parse_assignments(args.set)
    check_writable(args.out, "model")
    # --out MODEL updates MODEL in place: it is read under the lock, so a concurrent update
    # either finished before (and is kept) or waits for this one (docs/CONVENTIONS.md, "Writing files").
    with file_lock(args.out):
        model = load_model(args.model)
        edited = model.edit(args.material, args.as_name, conserve_energy=args.conserve_energy, **values)
        written = edited.save_checked(args.out)
    return describe_new_material(written, args.as_name, args.out)


def describe_new_material(model, name: str, out: str) -> int:
    """Describe the new material of an edited or blended model just written to ``out``:
    parameters and maximum directional albedo, with a warning when it exceeds 1."""
    line = f"wrote {out} ({len(model.materials)} materials): {name}"
    if model.has_analytic:
        p = model.analytic_params(name)
        line += f" kd {p.kd.round(4).tolist()} eta {p.eta.round(4).tolist()} alpha {p.alpha.round(5).tolist()}"
    print(line)
    bound = model.material_info[model.index(name)].get("energy_bound")
    if isinstance(bound, dict):
        print(f"energy bound: max directional albedo {bound['max_albedo_unbounded']:.3f} before it, "
              f"{bound['max_albedo']:.3f} after (smallest factor {bound['min_factor']:.3f}; docs/ENERGY.md)")
    a = model.albedo(name)
    print(f"max directional albedo {a['max']:.3f} (theta_o {a['argmax_deg'][0]:g}, phi_o {a['argmax_deg'][1]:g} degrees)")
    if a["max"] > 1.0:  # only the estimates' noise can leave one above 1 after the bound
        print(f"warning: the estimate of {name}'s maximum directional albedo exceeds 1", file=sys.stderr)
    return 0
