"""``hbrdf bound``: fit energy-bound tables, so that no material reflects more light than it receives."""

from __future__ import annotations

import argparse

from hybridbrdf.cli import COMMANDS, add_quiet_flag, progress_bar
from hybridbrdf.fit.settings import positive_int
from hybridbrdf.model import sizes


def add_parser(sub) -> None:
    p = sub.add_parser("bound", help=COMMANDS["bound"],
                       description="Fit each material's energy-bound table (docs/ENERGY.md): f = k(wi.z) k(wo.z) f_t "
                                   "with k <= 1 per material, so that every directional albedo is at most 0.99; "
                                   "1 (no change) where it already is. Reciprocity is kept exactly. hbrdf fit, add, "
                                   "edit and mix do this already; this command bounds a model written before "
                                   "(or refits its tables). --out is written only when everything is valid.")
    p.add_argument("model", help="model file")
    p.add_argument("--out", required=True, help="model file to write (may be MODEL itself)")
    p.add_argument("--materials", metavar="A,B,...", help="only these materials (default: all); the others keep "
                                                          "their tables (or none: a table of ones)")
    p.add_argument("--samples", type=positive_int, default=sizes.SAMPLES, metavar="N",
                   help="MIS samples per direction of the albedo estimate (default: %(default)s; at most what fits "
                        f"this machine's memory, {sizes.energy_bytes_per_sample() / 1024:.0f} KiB a sample; "
                        "docs/CONVENTIONS.md, \"Counts and memory\")")
    p.add_argument("--verbose", action="store_true", help="list every material, not only the dimmed ones")
    add_quiet_flag(p, "the tables are fitted")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.files import check_writable, file_lock
    from hybridbrdf.limits import check_count
    from hybridbrdf.model import energy
    from hybridbrdf.model.file import load_model

    check_count("--samples", args.samples, sizes.energy_bytes_per_sample())
    check_writable(args.out, "model")
    with file_lock(args.out):  # --out MODEL: MODEL is read under the lock (docs/CONVENTIONS.md, "Writing files")
        model = load_model(args.model)
        names = [n.strip() for n in args.materials.split(",")] if args.materials else None
        for n in names or []:
            model.index(n)  # KeyError naming the material and the model's
        n = len(names) if names is not None else len(model.materials)
        with progress_bar(None, n, "energy bound", " materials", quiet=args.quiet) as bar:
            bounded = energy.with_bound(model, names, samples=args.samples, progress=bar.update)
        bounded = bounded.save_checked(args.out)
    changed = 0
    for m in bounded.material_info:
        rec = m.get("energy_bound")
        if isinstance(rec, dict) and (names is None or m["name"] in names):
            dimmed = rec["min_factor"] < 1.0
            changed += dimmed
            if dimmed or args.verbose:
                print(f"  {m['name']:28s} max albedo {rec['max_albedo_unbounded']:.3f} -> {rec['max_albedo']:.3f} "
                      f"(smallest factor {rec['min_factor']:.3f})")
    print(f"wrote {args.out}: {len(names or bounded.materials)} energy-bound table(s) fitted, {changed} material(s) "
          f"dimmed where they reflected more than {energy.TARGET} of the light")
    return 0
