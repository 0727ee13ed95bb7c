"""``hbrdf add``: new materials on the shipped prior's network (fine-tuned) or on a model's (kept)."""

from __future__ import annotations

import argparse
import math

from hybridbrdf.cli import COMMANDS, EPILOG, add_fit_flags, log_function, settings_from_args
from hybridbrdf.fit.settings import Number, positive_int


def add_parser(sub) -> None:
    p = sub.add_parser("add", help=COMMANDS["add"],
                       description="Onto the shipped prior (no --to): each source's analytic parameters and latent "
                                   "code are fitted on the prior's frozen network (paper Sec. 4.2), then the network "
                                   "is trained further together with them (--finetune-steps); the model holds the "
                                   "new materials and their own network. --keep-network stops after the first part. "
                                   "With --to BASE: the sparse fit only, BASE's network kept bit-exact, and the model "
                                   "holds BASE's materials followed by the new ones. Inputs are checked before any "
                                   "training; --out is written only when the fit succeeds. Without --recipe or --loss-eps "
                                   "the loss epsilon is 0.03 (ADD_LOSS_EPS, docs/ADDING.md), not a joint fit's 0.1.",
                       epilog=EPILOG)
    p.add_argument("sources", nargs="+", metavar="SOURCE", help="BRDF files, folders, globs or synthetic:NAME")
    p.add_argument("--to", metavar="BASE", help="model file whose network the new materials share (default: the "
                                                "shipped prior, hybridbrdf.model.prior; the model then holds the new "
                                                "materials only)")
    p.add_argument("--out", required=True, help="model file to write (may be BASE itself)")
    add_fit_flags(p, sections=("training", "loss", "sparse", "run"), skip=("frozen_from", "init_from"))
    p.add_argument("--reciprocal", action=argparse.BooleanOptionalAction, default=None,
                   help="onto the shipped reciprocal prior (its network reads wi + wo and the products of wi - wo), "
                        "the default: the model is reciprocal bit for bit, f(wi, wo) = f(wo, wi) "
                        "(docs/RECIPROCITY.md); --no-reciprocal: onto the plain prior (architecture hybrid); "
                        "neither with --to")
    p.add_argument("--keep-network", action="store_true",
                   help="onto the shipped prior: fit only the sources' parameters and latent codes, the network "
                        "bit-identical to the prior's (for engines that already ship it)")
    p.add_argument("--finetune-steps", type=positive_int, default=None,
                   help="onto the shipped prior: steps of the fine-tune after the --steps sparse steps "
                        "(default: 5000; --lr, --network-lr and the loss flags apply to both); with --refine, "
                        "the refinement's steps")
    p.add_argument("--refine", action="store_true",
                   help="with --to BASE: after the sparse fit, train BASE's network further with the new materials "
                        "and BASE's own, replayed against BASE's outputs with their (p, z) free; each BASE "
                        "material's drift (SMAPE and cMAE against BASE) is printed and recorded")
    p.add_argument("--max-drift", type=Number(float, 0, math.inf, lo_open=True), default=None, metavar="X",
                   help="with --refine: the largest drift (SMAPE against BASE's own output) a BASE material may "
                        "take; above it nothing is written (default: 0.75)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or log messages")
    p.set_defaults(func=run)



def run(args: argparse.Namespace) -> int:
    from hybridbrdf.fit.adding import add

    settings = settings_from_args(args, sparse=True)
    if args.to is not None and (args.keep_network or (args.finetune_steps is not None and not args.refine)):
        raise ValueError("--keep-network and --finetune-steps are for adding to the shipped prior or with --refine; "
                         "with --to BASE alone the fit is sparse (BASE's network kept)")
    if args.refine and args.to is None:
        raise ValueError("--refine refines the network of --to BASE; onto the shipped prior the network is "
                         "fine-tuned by default")
    if args.max_drift is not None and not args.refine:
        raise ValueError("--max-drift applies to --refine only")
    log = log_function(args.quiet)
    try:
        model = add(args.sources, to=args.to, out=args.out, settings=settings, progress=not args.quiet, log=log,
                    keep_network=args.keep_network, finetune_steps=args.finetune_steps, refine=args.refine,
                    reciprocal=args.reciprocal,
                    **({} if args.max_drift is None else {"max_drift": args.max_drift}))
    except MemoryError:
        raise ValueError("out of memory; lower --pool, --batch or --eval-pairs") from None
    _report(args, settings, model)
    return 0


def _report(args, settings, model) -> None:
    """The new materials' metrics and what the addition did to the network."""
    from hybridbrdf.evaluate.evaluation import format_table

    if model.training.get("mode") == "refine":
        n_base = sum("refine_drift" in m for m in model.material_info)
        new = model.material_info[n_base:]
        seconds = model.training["sparse_fit"].get("train_seconds", 0.0) + model.training.get("train_seconds", 0.0)
        drift = [(m["refine_drift"]["smape"], m["refine_drift"]["cmae"], m["name"]) for m in model.material_info[:n_base]]
        worst = max(drift)
        how = (f"refined {args.to}'s network with them and its {n_base} materials ({settings.steps} sparse + "
               f"{model.training['steps']} refine steps); its materials moved by SMAPE {sum(d[0] for d in drift) / n_base:.4f} "
               f"on average against {args.to}, at most {worst[0]:.4f} ({worst[2]}; --max-drift {model.training['max_drift']:g})")
    elif model.training.get("mode") == "fine-tune":
        new = model.material_info
        seconds = model.training["sparse_fit"].get("train_seconds", 0.0) + model.training.get("train_seconds", 0.0)
        how = (f"fine-tuned the shipped {'plain ' if args.reciprocal is False else 'reciprocal '}prior's network with them "
               f"({settings.steps} sparse + "
               f"{model.training['steps']} fine-tune steps)")
    else:
        added = set(model.training["additions"][-1]["materials"])
        new = [m for m in model.material_info if m["name"] in added]
        seconds = model.training["additions"][-1].get("train_seconds", 0.0)
        prior = "the shipped plain prior" if args.reciprocal is False else "the shipped reciprocal prior"
        how = f"sparse fit on {args.to or prior}'s network, kept bit-exact"
    print(format_table([dict(material=m["name"], origin=m.get("origin", ""), **m["metrics"]) for m in new],
                       settings.eval_pairs))
    print(f"added {len(new)} material(s) in {seconds:.1f} s of training: {how}; wrote {args.out} "
          f"({len(model.materials)} materials)")
