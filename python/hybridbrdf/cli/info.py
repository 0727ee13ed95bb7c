"""``hbrdf info``: a model file's architecture, training settings and materials."""

from __future__ import annotations

import argparse

from hybridbrdf import spec
from hybridbrdf.cli import COMMANDS, _settings_line, _shown, add_quiet_flag, print_beside, progress_bar
from hybridbrdf.model.sizes import LIBRARY_BYTES_PER_PAIR, albedo_bytes_per_sample

#: What a fit records besides its settings (hybridbrdf.fit.fit, in fit/joint.py), printed by ``hbrdf info``.
RECORDED_TIMINGS = ("train_seconds", "train_seconds_from_step", "resumed_at_step", "compile_seconds")


def add_parser(sub) -> None:
    p = sub.add_parser("info", help=COMMANDS["info"], description="Print a model file's architecture, "
                                                                         "training settings and materials.")
    p.add_argument("model", help="model file")
    p.add_argument("--albedo-samples", type=int, default=1 << 11, metavar="N",
                   help="incident samples per outgoing direction for each material's maximum directional albedo "
                        "(44 outgoing directions; default: %(default)s, about 1%% noise; hbrdf edit and mix use "
                        "8192; 0: do not estimate it); at most what fits this machine's memory, about "
                        f"{albedo_bytes_per_sample(LIBRARY_BYTES_PER_PAIR) / 1024:.1f} KiB a sample "
                        "(docs/CONVENTIONS.md, \"Counts and memory\")")
    add_quiet_flag(p, "the albedo estimates run")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from hybridbrdf.fit.record import environment_line
    from hybridbrdf.limits import check_count
    from hybridbrdf.model.container import format_version
    from hybridbrdf.model.file import load_model

    if args.albedo_samples < 0:
        raise ValueError(f"--albedo-samples {args.albedo_samples}: must be >= 0 (0: no albedo)")
    check_count("--albedo-samples", args.albedo_samples, albedo_bytes_per_sample(LIBRARY_BYTES_PER_PAIR))
    model = load_model(args.model)
    a = model.arch
    written_by = getattr(model, "written_by", None)
    print(f"{args.model}: hybridbrdf model, format {format_version(a['kind'])}, conventions {spec.CONVENTIONS_VERSION}"
          + (f", written by hybridbrdf {_shown(written_by)}" if written_by is not None else ""))
    heads = model.output_layer == "material"
    print(f"architecture: {a['kind']}, MLP {a['width']}x{a['depth']} {a['activation']}, latent {a['latent']}, "
          f"{a['n_in']} inputs -> {a['n_out']} outputs"
          + (", output layer per material" if heads else "")
          + (", energy bound per material" if a.get("energy_bound") == "albedo_table" else ", no energy bound"))
    n_net = sum(v.size for k, v in model.tensors.items() if not k.startswith("materials."))
    n_mat = sum(v[0].size for k, v in model.tensors.items() if k.startswith("materials."))
    print(f"shared network: {n_net} weights ({4 * n_net / 1024:.1f} KiB float32); per material: {n_mat} floats "
          f"({4 * n_mat} bytes" + (f", {a['n_out'] * (a['width'] + 1)} of them its output layer)" if heads else ")"))
    t = model.training if isinstance(model.training, dict) else {}
    if t:
        sections = ("training", "run") + (("sparse",) if t.get("frozen_from") else ())  # sparse_init: sparse fits only
        print(_settings_line("training", t, sections, RECORDED_TIMINGS))
        print(_settings_line("loss", t, ("loss",)))
        print(environment_line(t, _shown))  # ranks, device, threads, versions (or what an older file lacks)
        if t.get("mode") == "fine-tune" and isinstance(t.get("sparse_fit"), dict):
            print(f"added by fine-tuning the network of {_shown(t.get('init_from'))} (the training line above) "
                  f"after a sparse fit on it:")
            print(_settings_line("sparse fit", t["sparse_fit"], ("training", "sparse"), RECORDED_TIMINGS))
        elif t.get("init_from"):
            print(f"warm start: the network of {_shown(t['init_from'])}, trained further")
    print(f"{len(model.materials)} materials:", flush=True)
    # The albedo estimates are the slow part (about 12 ms a material; 4 minutes for 20,000).
    bar = progress_bar(model.material_info, len(model.materials), "albedo", " materials",
                       quiet=args.quiet or not args.albedo_samples)
    for m in bar:
        line = f"  {m['name']:28s} {'iso ' if m.get('isotropic', True) else 'aniso'} {_shown(m.get('origin', ''))}"
        if model.has_analytic:
            p = model.analytic_params(m["name"])
            line += (f"\n      kd {p.kd.round(4).tolist()} eta {p.eta.round(4).tolist()} "
                     f"alpha {p.alpha.round(5).tolist()}")
        met = m.get("metrics")
        if isinstance(met, dict) and met:
            line += "\n      " + ", ".join(f"{_shown(k)} {_shown(v)}" for k, v in met.items()
                                           if isinstance(v, (int, float)) and not isinstance(v, bool))
        bound = m.get("energy_bound")
        if isinstance(bound, dict):
            line += (f"\n      energy bound: max albedo {_shown(bound.get('max_albedo_unbounded'))} without it, "
                     f"{_shown(bound.get('max_albedo'))} with it, smallest factor {_shown(bound.get('min_factor'))}")
        if args.albedo_samples:
            a = model.albedo(m["name"], samples=args.albedo_samples)
            line += (f"\n      max directional albedo {a['max']:.3f} (theta_o {a['argmax_deg'][0]:g}, "
                     f"phi_o {a['argmax_deg'][1]:g} degrees)" + ("  EXCEEDS 1" if a["max"] > 1.0 else ""))
        for key, what in (("edit", "edit"), ("mix", "blend")):
            rec = m.get(key)
            if isinstance(rec, dict):
                line += f"\n      {what}: " + ", ".join(f"{_shown(k)} {_shown(v)}" for k, v in rec.items())
        st = m.get("sparse_start")
        if isinstance(st, dict):
            line += (f"\n      sparse fit started from {_shown(st.get('material'))} "
                     f"(smape {_shown(st.get('smape'))}, cmae {_shown(st.get('cmae'))})")
        print_beside(bar, line)
    return 0
