"""``hbrdf fit``: a joint fit of BRDF sources, the model file and its preview picture."""

from __future__ import annotations

import argparse
import os
import sys

from hybridbrdf.cli import COMMANDS, EPILOG, _open_all, add_fit_flags, log_function, settings_from_args
from hybridbrdf.errors import InputFileError
from hybridbrdf.fit.settings import positive_int
from hybridbrdf.files import check_writable


def add_parser(sub) -> None:
    p = sub.add_parser("fit", help=COMMANDS["fit"],
                       description="Jointly fit a collection of BRDFs (paper Sec. 3.3) and write a model file. "
                                   "Prints the per-material metrics table.", epilog=EPILOG)
    p.add_argument("sources", nargs="+", metavar="SOURCE", help="BRDF files, folders, globs or synthetic:NAME")
    p.add_argument("--out", required=True, help="model file to write (safetensors)")
    add_fit_flags(p)
    p.add_argument("--compile", action="store_true",
                   help="compile each training step with torch.compile: 1.1-1.6x the steps per second on a CPU "
                        "(most at 32x2/32x3) after a one-time compilation of a minute or two (needs a C++ compiler; "
                        "docs/FITTING.md)")
    p.add_argument("--checkpoint", help="checkpoint file written during training (for --resume)")
    p.add_argument("--checkpoint-every", type=positive_int, default=1000, help="steps between checkpoints (default: %(default)s)")
    p.add_argument("--resume", action="store_true", help="continue from --checkpoint if it exists")
    p.add_argument("--force", action="store_true",
                   help="start afresh over an existing --checkpoint (without it, or --resume, an existing "
                        "checkpoint is refused: it may be another fit's)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or log messages")
    p.add_argument("--preview", metavar="PNG",
                   help="picture of the fitted materials to write: spheres under the example scene's sky, the exact "
                        "material beside the hybrid beside its f_a alone, rendered by the path tracer (the first "
                        "8 materials; default: --out with .png)")
    p.add_argument("--no-preview", action="store_true", help="write no preview picture")
    p.set_defaults(func=run)


def _check_fit_outputs(args: argparse.Namespace) -> None:
    """--out and --checkpoint: writable, and not the same file (the model would replace the
    checkpoint a later --resume needs); an existing checkpoint only with --resume or --force.
    Raises InputFileError naming the path."""
    from hybridbrdf.fit import checkpoint as ckpt

    check_writable(args.out, "model")
    if getattr(args, "preview_path", None):
        check_writable(args.preview_path, "preview")
    if args.checkpoint:
        if os.path.realpath(args.checkpoint) == os.path.realpath(args.out):
            raise InputFileError(args.out, "--out and --checkpoint name the same file")
        check_writable(args.checkpoint, "checkpoint")
        ckpt.check_not_another_fits(args.checkpoint, args.resume, args.force)  # fit() checks again, under the lock
    elif args.resume:
        raise ValueError("--resume needs --checkpoint FILE")
    elif args.force:
        raise ValueError("--force replaces an existing --checkpoint FILE; give one")


def _check_out_is_no_source(out: str, sources) -> None:
    """Refuse to write the model over one of the files it is fitted to."""

    target = os.path.realpath(out)
    for src in sources:
        if src.path and os.path.realpath(src.path) == target:
            raise InputFileError(out, "--out names one of the sources; the model would overwrite it")


def _start_models(settings):
    """The models a fit starts from: --frozen's and --init's (None where not given)."""
    from hybridbrdf.model.file import load_model  # NumPy: imported by the command, not by --help
    from hybridbrdf.model.prior import prior_path
    from hybridbrdf.fit.joint import frozen_arch_settings

    frozen = load_model(settings.frozen_from) if settings.frozen_from else None
    if frozen is not None and settings.init_from:
        raise ValueError("--frozen keeps MODEL's network and --init trains it further: give one of them")
    init = None
    if settings.init_from:
        # "prior": the shipped prior of the fit's architecture (the reciprocal one by default, the plain
        # one with --arch hybrid); the fit then takes that prior's network settings.
        prior = prior_path(reciprocal=settings.arch == "hybrid-reciprocal")
        init = load_model(prior if settings.init_from == "prior" else settings.init_from)
    for start_model in (frozen, init):
        if start_model is not None:
            frozen_arch_settings(settings, start_model)
    return frozen, init


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.fit import checkpoint as ckpt, distributed as dd

    settings = settings_from_args(args)
    settings.check()
    args.preview_path = None if args.no_preview else (args.preview or os.path.splitext(args.out)[0] + ".png")
    if args.preview_path and os.path.abspath(args.preview_path) == os.path.abspath(args.out):
        raise InputFileError(args.out, "--out and --preview name the same file")
    # Under torchrun (WORLD_SIZE > 1): a data-parallel fit, rank 0 writes the files.
    ranks = dd.Ranks(world=dd.launched_world_size())
    dd.check_batch_split(settings.batch, ranks)
    # Whatever can fail without the sources fails before they are opened and evaluated (which,
    # with the training itself, is the expensive part): outputs, the frozen model, the checkpoint.
    _check_fit_outputs(args)
    frozen, init = _start_models(settings)
    if args.resume and os.path.exists(args.checkpoint):
        ckpt.load(args.checkpoint, settings)  # fit() restores it; this only fails early
    sources = _open_all(args.sources)
    _check_out_is_no_source(args.out, sources)
    model, ranks = _train(args, settings, sources, frozen, init)
    _report(args, settings, model)
    if ranks.distributed:
        dd.end_process(0)
    return 0


def _train(args, settings, sources, frozen, init):
    """fit() on this process's rank: the model and the ranks, on rank 0 (the other ranks end here)."""
    from hybridbrdf.fit import distributed as dd
    from hybridbrdf.fit import fit

    log = log_function(args.quiet)
    dd.error_prefix = "hbrdf fit: error: "  # a rank that ends itself (a stuck step) says so as main() would
    ranks = dd.join(settings.device)
    try:
        settings.device = dd.rank_device(settings.device, ranks)
        if ranks.distributed and ranks.main:
            log(f"data-parallel fit on {ranks.world} ranks: {settings.batch // ranks.world} pairs of each "
                f"{settings.batch}-pair batch per rank")
        model = fit(sources, settings, frozen=frozen, init=init, checkpoint=args.checkpoint,
                    checkpoint_every=args.checkpoint_every, resume=args.resume, progress=not args.quiet, log=log,
                    compile_step=args.compile, ranks=ranks, force=args.force)
    except KeyboardInterrupt:
        if not ranks.main:
            dd.leave(ranks)
            dd.end_process(130)  # rank 0 says where the checkpoint is
        raise
    except MemoryError:
        raise ValueError("out of memory; lower --pool, --batch or --eval-pairs") from None
    finally:
        dd.leave(ranks)
    if not ranks.main:
        dd.end_process(0)
    return model, ranks


def _report(args, settings, model) -> None:
    """Write the model, print its metrics table and training time, and write the preview."""
    from hybridbrdf.evaluate.evaluation import format_table

    model.save(args.out)
    rows = [dict(material=m["name"], origin=m["origin"], **m["metrics"]) for m in model.material_info]
    print(format_table(rows, settings.eval_pairs))
    rate = model.training.get("pairs_x_materials_per_second")
    print(f"trained {settings.steps} steps in {model.training['train_seconds']:.1f} s"
          + (f" ({rate:,.0f} pairs x materials / s)" if rate else "") + f"; wrote {args.out}")
    if args.preview_path:
        _write_preview(args.out, args.sources, args.preview_path)


def _write_preview(model_path: str, sources, png: str) -> None:
    """The picture that ends `hbrdf fit`. The model is written by then: a preview that cannot be
    rendered (a build without the renderer, a source the tracer's reader refuses) is reported in
    one line and does not fail the command."""
    from hybridbrdf.render.preview import ROWS, render_preview

    try:
        info = render_preview(model_path, sources, png)
    except (RuntimeError, ValueError, OSError) as exc:
        print(f"preview not written: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}", file=sys.stderr)
        return
    shown = len(info["materials"])
    print(f"wrote {png}: {shown} material{'s' if shown != 1 else ''} as spheres, rows "
          f"{' | '.join(label for label, _ in ROWS)} (rendered in {info['seconds']:.1f} s)")
