"""The ``hbrdf`` command line.

    hbrdf fit SOURCE... --out MODEL [--arch hybrid|neural|additive|logmul|analytic-input]
              [--mlp 32x3] [--latent 4] [--activation hardgelu|relu] [--steps N] [--batch 1024]
              [--lr 5e-3] [--weight-decay 0.01] [--seed 0] [--pool N] [--eval-pairs N]
              [--loss-eps 1] [--loss-eps-relative] [--loss-no-cos] [--analytic-loss-eps E] [--analytic-expectile 0.5]
              [--specular 0] [--specular-alpha 0.1] [--fc-init -4]
              [--device cpu|cuda] [--compile]
              [--checkpoint PATH [--checkpoint-every N] [--resume]] [--frozen MODEL [--sparse-init nearest|neutral]] [--quiet]
    hbrdf eval MODEL SOURCE... [--pairs N] [--all-metrics]
    hbrdf info MODEL
    hbrdf demo [--out PATH] [--samples N]
    hbrdf render SCENE.json -o OUT.exr [--png OUT.png] [--spp N] [--threads N] [--seed N] [--exposure EV]
                 [--tonemap clamp|aces] [--quiet]

A SOURCE is a file (.binary MERL, .bsdf RGL, .bin UTIA, .h5 NBRDF), a folder, a
glob, or synthetic:NAME (synthetic:all for every built-in material).
Errors are printed as one line on stderr with a non-zero exit status.
"""

from __future__ import annotations

import argparse
import sys

EPILOG = ("SOURCE: a file (.binary MERL, .bsdf RGL, .bin UTIA, .h5 NBRDF network), a folder, a glob, "
          "or synthetic:NAME (synthetic:all = every built-in material).")


def _open_all(specs):
    from hybridbrdf.sources import expand_sources, open_source

    return [open_source(s) for s in expand_sources(specs)]


def _cmd_fit(args: argparse.Namespace) -> int:
    from hybridbrdf.fitting import FitSettings, default_device, fit, format_table
    from hybridbrdf.model_file import load_model
    from hybridbrdf.models import parse_mlp

    width, depth = parse_mlp(args.mlp)
    latent = args.latent if args.latent is not None else (12 if args.arch == "neural" else 4)
    settings = FitSettings(arch=args.arch, width=width, depth=depth, latent=latent, activation=args.activation,
                           steps=args.steps, batch=args.batch, lr=args.lr, weight_decay=args.weight_decay,
                           seed=args.seed, pool=args.pool,
                           eval_pairs=args.eval_pairs, loss_eps=args.loss_eps, loss_eps_relative=args.loss_eps_relative,
                           analytic_loss_eps=args.analytic_loss_eps, loss_cos=not args.loss_no_cos,
                           analytic_expectile=args.analytic_expectile, fc_init=args.fc_init,
                           specular=args.specular, specular_alpha=args.specular_alpha,
                           device=args.device or default_device(),
                           sparse_init=args.sparse_init, sources=list(args.sources), frozen_from=args.frozen)
    settings.check()
    frozen = load_model(args.frozen) if args.frozen else None
    sources = _open_all(args.sources)
    log = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    model = fit(sources, settings, frozen=frozen, checkpoint=args.checkpoint, checkpoint_every=args.checkpoint_every,
                resume=args.resume, progress=not args.quiet, log=log, compile_step=args.compile)
    model.save(args.out)
    rows = [dict(material=m["name"], origin=m["origin"], **m["metrics"]) for m in model.material_info]
    print(format_table(rows, settings.eval_pairs))
    rate = model.training.get("pairs_x_materials_per_second")
    print(f"trained {settings.steps} steps in {model.training['train_seconds']:.1f} s"
          + (f" ({rate:,.0f} pairs x materials / s)" if rate else "") + f"; wrote {args.out}")
    return 0


def _cmd_eval(args: argparse.Namespace) -> int:
    from hybridbrdf.fitting import evaluate, format_extended_table, format_table
    from hybridbrdf.model_file import load_model

    model = load_model(args.model)
    rows = evaluate(model, _open_all(args.sources), n_pairs=args.pairs, extended=args.all_metrics)
    print(format_table(rows, args.pairs))
    if args.all_metrics:
        print()
        print(format_extended_table(rows))
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from hybridbrdf.model_file import load_model

    model = load_model(args.model)
    a = model.arch
    h = model.header()
    print(f"{args.model}: hybridbrdf model, format {h['format_version']}, conventions {h['conventions_version']}, "
          f"written by hybridbrdf {h['library_version']}")
    print(f"architecture: {a['kind']}, MLP {a['width']}x{a['depth']} {a['activation']}, latent {a['latent']}, "
          f"{a['n_in']} inputs -> {a['n_out']} outputs")
    n_net = sum(v.size for k, v in model.tensors.items() if not k.startswith("materials."))
    print(f"shared network: {n_net} weights ({4 * n_net / 1024:.1f} KiB float32)")
    t = model.training
    if t:
        keys = ("steps", "batch", "lr", "weight_decay", "seed", "pool", "device", "train_seconds",
                "train_seconds_from_step", "resumed_at_step", "compile_seconds", "frozen_from")
        print("training: " + ", ".join(f"{k} {t[k]}" for k in keys if t.get(k) is not None)
              + (f", sparse_init {t.get('sparse_init', 'neutral')}" if t.get("frozen_from") else ""))
        keys = ("loss_eps", "loss_eps_relative", "loss_cos", "analytic_loss_eps", "analytic_expectile", "specular")
        print("loss: " + ", ".join(f"{k} {t[k]}" for k in keys if t.get(k) is not None))
    print(f"{len(model.materials)} materials:")
    for m in model.material_info:
        line = f"  {m['name']:28s} {'iso ' if m.get('isotropic', True) else 'aniso'} {m.get('origin', '')}"
        if model.kind != "neural":
            p = model.analytic_params(m["name"])
            line += (f"\n      kd {p.kd.round(4).tolist()} eta {p.eta.round(4).tolist()} "
                     f"alpha {p.alpha.round(5).tolist()}")
        met = m.get("metrics") or {}
        if met:
            line += "\n      " + ", ".join(f"{k} {v:.4g}" for k, v in met.items() if isinstance(v, (int, float)))
        st = m.get("sparse_start")
        if isinstance(st, dict):
            line += (f"\n      sparse fit started from {st.get('material')} "
                     f"(smape {st.get('smape', float('nan')):.4g}, cmae {st.get('cmae', float('nan')):.4g})")
        print(line)
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from hybridbrdf.demo import run_demo

    run_demo(args.out, samples=args.samples)
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    from hybridbrdf.render import render

    _, stats = render(args.scene, out=args.out, png=args.png, quiet=args.quiet, exposure=args.exposure,
                      tonemap=args.tonemap, spp=args.spp, threads=args.threads, seed=args.seed)
    print(f"rendered {args.scene}: {stats['spp']} spp in {stats['seconds']:.2f} s "
          f"({stats['samples_per_second']:,.0f} samples/s, {stats['rays']:,} rays + {stats['shadow_rays']:,} shadow rays, "
          f"{stats['network_evals']:,} of {stats['brdf_evals']:,} BRDF evaluations ran the network, "
          f"{stats['threads']} threads); wrote {args.out}" + (f" and {args.png}" if args.png else ""))
    return 0


def _positive_int(text: str) -> int:
    try:
        v = int(float(text))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def build_parser() -> argparse.ArgumentParser:
    from hybridbrdf import __version__
    from hybridbrdf.models import ACTIVATIONS, ARCHS

    parser = argparse.ArgumentParser(prog="hbrdf", description="Hybrid neural-microfacet BRDFs.", epilog=EPILOG)
    parser.add_argument("--version", action="version", version=f"hybridbrdf {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    fit = sub.add_parser("fit", help="fit one shared network + per-material parameters to BRDF sources",
                         description="Jointly fit a collection of BRDFs (paper Sec. 3.3) and write a model file. "
                                     "Prints the per-material metrics table.", epilog=EPILOG)
    fit.add_argument("sources", nargs="+", metavar="SOURCE", help="BRDF files, folders, globs or synthetic:NAME")
    fit.add_argument("--out", required=True, help="model file to write (safetensors)")
    fit.add_argument("--arch", choices=ARCHS, default="hybrid", help="model architecture (default: %(default)s)")
    fit.add_argument("--mlp", default="32x3", help="hidden layers as WIDTHxDEPTH (default: %(default)s)")
    fit.add_argument("--latent", type=int, default=None,
                     help="latent dimensions per material (default: 4, or 12 for --arch neural)")
    fit.add_argument("--activation", choices=ACTIVATIONS, default="hardgelu", help="hidden activation (default: %(default)s)")
    fit.add_argument("--steps", type=_positive_int, default=2000, help="optimiser steps (default: %(default)s)")
    fit.add_argument("--batch", type=_positive_int, default=1024, help="direction pairs per step (default: %(default)s)")
    fit.add_argument("--lr", type=float, default=5e-3, help="AdamW learning rate, cosine-decayed (default: %(default)s)")
    fit.add_argument("--weight-decay", type=float, default=0.01,
                     help="AdamW weight decay of the shared network (not of p or z) (default: %(default)s, "
                          "torch's default, which the paper's AdamW implies)")
    fit.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    fit.add_argument("--pool", type=_positive_int, default=1 << 18,
                     help="direction pairs in the training pool, evaluated once per source (default: %(default)s)")
    fit.add_argument("--eval-pairs", type=_positive_int, default=100_000,
                     help="pairs for the metrics stored with the model (default: %(default)s; CONVENTIONS uses 1e6)")
    fit.add_argument("--loss-eps", type=float, default=1.0,
                     help="epsilon of the loss log(eps + cos f); 1 = the paper's log(1 + cos f), smaller values weigh "
                          "relative errors in dark regions (default: %(default)s)")
    fit.add_argument("--loss-eps-relative", action="store_true",
                     help="scale --loss-eps per material by its mean cos f (brightness-invariant loss; "
                          "for collections with very dark materials)")
    fit.add_argument("--loss-no-cos", action="store_true",
                     help="fit log(eps + f) instead of the paper's log(eps + cos f), so grazing angles keep their "
                          "relative weight (docs/FITTING.md, \"Grazing angles\")")
    fit.add_argument("--analytic-loss-eps", type=float, default=None,
                     help="epsilon of the analytic term L(f_ref, f_a) of the loss (default: --loss-eps); an ablation "
                          "knob: a larger value lets f_a drift and costs the hybrid too (docs/FITTING.md)")
    fit.add_argument("--analytic-expectile", type=float, default=0.5,
                     help="expectile tau in [0.5, 1) of the analytic loss term: tau > 0.5 weighs f_a below the data "
                          "more, fitting an upper envelope the gate can dim (default: %(default)s, the paper's loss)")
    fit.add_argument("--specular", type=float, default=0.0,
                     help="fraction of the training pool drawn around the mirror direction instead of cosine-weighted; "
                          "weighs the specular peaks that dominate cMAE (default: %(default)s, the paper's sampling)")
    fit.add_argument("--specular-alpha", type=float, default=0.1,
                     help="GGX roughness of the half-vector distribution of --specular pairs (default: %(default)s)")
    fit.add_argument("--fc-init", type=float, default=-4.0,
                     help="initial pre-exp bias of the hybrid correction f_c = exp(o) (default: %(default)s)")
    fit.add_argument("--device", default=None, help="torch device (default: cuda when available, else cpu)")
    fit.add_argument("--compile", action="store_true",
                     help="compile each training step with torch.compile: 1.1-1.6x the steps per second on a CPU "
                          "(most at 32x2/32x3) after a one-time compilation of a minute or two (needs a C++ compiler; "
                          "docs/FITTING.md)")
    fit.add_argument("--checkpoint", help="checkpoint file written during training (for --resume)")
    fit.add_argument("--checkpoint-every", type=_positive_int, default=1000, help="steps between checkpoints (default: %(default)s)")
    fit.add_argument("--resume", action="store_true", help="continue from --checkpoint if it exists")
    fit.add_argument("--frozen", metavar="MODEL", help="sparse fitting: keep MODEL's network, fit only (p, z) of the sources")
    fit.add_argument("--sparse-init", choices=("nearest", "neutral"), default="nearest",
                     help="with --frozen: start each source's (p, z) from MODEL's best-fitting material (nearest) or "
                          "from the neutral grey rough lobe with z ~ 0 (neutral) (default: %(default)s)")
    fit.add_argument("--quiet", action="store_true", help="no progress bar or log messages")
    fit.set_defaults(func=_cmd_fit)

    ev = sub.add_parser("eval", help="per-material SMAPE/cMAE of a model against BRDF sources",
                        description="Evaluate a model against the sources its materials were fitted to (matched by "
                                    "name): SMAPE and cMAE of the analytic part and of the full model.", epilog=EPILOG)
    ev.add_argument("model", help="model file")
    ev.add_argument("sources", nargs="+", metavar="SOURCE", help="BRDF files, folders, globs or synthetic:NAME")
    ev.add_argument("--pairs", type=_positive_int, default=1_000_000, help="metric direction pairs (default: %(default)s)")
    ev.add_argument("--all-metrics", action="store_true",
                    help="also print MAE, reciprocity error (SMAPE of f(wi,wo) vs f(wo,wi)) and directional albedo "
                         "at 45 degrees for the reference, the analytic part and the model")
    ev.set_defaults(func=_cmd_eval)

    info = sub.add_parser("info", help="describe a model file", description="Print a model file's architecture, "
                                                                            "training settings and materials.")
    info.add_argument("model", help="model file")
    info.set_defaults(func=_cmd_info)

    demo = sub.add_parser(
        "demo",
        help="plot BRDF slices of built-in analytic materials and print their albedo",
        description="Plot in-plane slices and polar lobes of f_a for a few built-in analytic materials "
        "(C++ library, checked against the float64 PyTorch implementation) and print each material's "
        "directional albedo estimated with every sampling strategy.",
    )
    demo.add_argument("--out", default="out/analytic_slices.png", help="PNG file to write (default: %(default)s)")
    demo.add_argument("--samples", type=int, default=200_000, help="samples per albedo estimate (default: %(default)s)")
    demo.set_defaults(func=_cmd_demo)

    rn = sub.add_parser("render", help="render a scene with the Embree path tracer",
                        description="Render a JSON scene (docs/RENDERING.md) with the reference path tracer: "
                                    "linear float32 OpenEXR, optionally a tone-mapped sRGB PNG.")
    rn.add_argument("scene", help="scene file (JSON)")
    rn.add_argument("-o", "--out", required=True, help="OpenEXR file to write (linear RGB, float32)")
    rn.add_argument("--png", help="also write an 8-bit sRGB PNG")
    rn.add_argument("--spp", type=_positive_int, help="samples per pixel (default: the scene's)")
    rn.add_argument("--threads", type=int, help="worker threads, 0 = all cores (default: the scene's)")
    rn.add_argument("--seed", type=int, help="random seed (default: the scene's)")
    rn.add_argument("--exposure", type=float, default=0.0, help="PNG exposure in stops (default: %(default)s)")
    rn.add_argument("--tonemap", choices=("clamp", "aces"), default="clamp", help="PNG tone map (default: %(default)s)")
    rn.add_argument("--quiet", action="store_true", help="no progress bar")
    rn.set_defaults(func=_cmd_render)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print(f"hbrdf {args.command}: interrupted", file=sys.stderr)
        return 130
    except (ValueError, KeyError, OSError, FloatingPointError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        print(f"hbrdf {args.command}: error: {msg}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
