"""``hbrdf eval``: per-material SMAPE and cMAE of a model against BRDF sources."""

from __future__ import annotations

import argparse

from hybridbrdf.cli import COMMANDS, EPILOG, _open_all, add_quiet_flag, progress_bar
from hybridbrdf.fit.settings import PAIRS, positive_int


def add_parser(sub) -> None:
    p = sub.add_parser("eval", help=COMMANDS["eval"],
                       description="Evaluate a model against the sources its materials were fitted to (matched by "
                                   "name): SMAPE and cMAE of the analytic part and of the full model.", epilog=EPILOG)
    p.add_argument("model", help="model file")
    p.add_argument("sources", nargs="+", metavar="SOURCE", help="BRDF files, folders, globs or synthetic:NAME")
    p.add_argument("--pairs", type=positive_int, default=1_000_000,
                   help="metric direction pairs (default: %(default)s; at most 10^8 and what fits this machine's "
                        "memory: docs/CONVENTIONS.md, \"Counts and memory\")")
    p.add_argument("--all-metrics", action="store_true",
                   help="also print MAE, reciprocity error (SMAPE of f(wi,wo) vs f(wo,wi)) and directional albedo "
                        "at 45 degrees for the reference, the analytic part and the model, and the model's largest "
                        "directional albedo with the outgoing direction where it occurs (above 1: it reflects more "
                        "light than it receives)")
    add_quiet_flag(p, "the sources are evaluated")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.evaluate.evaluation import bytes_per_pair, evaluate, format_extended_table, format_table
    from hybridbrdf.limits import check_count
    from hybridbrdf.model.file import load_model

    problem = PAIRS.problem(args.pairs)  # the range of fit's --eval-pairs (argparse takes counts up to 1e9)
    if problem:
        raise ValueError(f"--pairs {problem}")
    # eval writes no file: its inputs are checked by load_model and the readers.
    model = load_model(args.model)
    check_count("--pairs", args.pairs, bytes_per_pair(model))  # before any pair is drawn
    # The sources are read outside the --pairs advice below: a reader's failure is the reader's
    # (each refuses files larger than its format, so memory is the machine's limit, not --pairs').
    try:
        sources = _open_all(args.sources)
    except MemoryError:
        raise ValueError("out of memory while reading the sources") from None
    try:
        with progress_bar(None, len(sources), "eval", " sources", quiet=args.quiet) as bar:
            rows = evaluate(model, sources, n_pairs=args.pairs, extended=args.all_metrics, progress=bar.update)
    except MemoryError:
        raise ValueError(f"out of memory for {args.pairs} pairs; lower --pairs") from None
    print(format_table(rows, args.pairs))
    if args.all_metrics:
        print()
        print(format_extended_table(rows))
    return 0
