"""The ``hbrdf`` command line: ``fit``, ``add``, ``edit``, ``mix``, ``eval``, ``view``, ``info``, ``demo``, ``render``.

``hbrdf <command> --help`` documents every flag. The fit flags, their help and defaults are
generated from :class:`hybridbrdf.fit.settings.FitSettings` (:func:`add_fit_flags`), and so is the
README's synopsis of ``hbrdf fit`` (:func:`fit_synopsis`; a test keeps the README current).

A SOURCE is a file (.binary MERL, .bsdf RGL, .bin UTIA, .h5 NBRDF), a folder, a
glob, or synthetic:NAME (synthetic:all for every built-in material).
Errors are printed as one line on stderr with a non-zero exit status.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import signal
import sys
import threading

from tqdm import tqdm

from hybridbrdf import spec
from hybridbrdf.acquire.command import add_acquire_parser
from hybridbrdf.demo import run_demo
from hybridbrdf.errors import InputFileError, one_line_text
from hybridbrdf.evaluate.evaluation import bytes_per_pair, evaluate, format_extended_table, format_table
from hybridbrdf.fit import checkpoint as ckpt, distributed as dd
from hybridbrdf.fit.adding import add
from hybridbrdf.fit.distributed import RankLostError
from hybridbrdf.fit.paint import paint
from hybridbrdf.fit.fit import default_device, fit, frozen_arch_settings
from hybridbrdf.fit.record import environment_line
from hybridbrdf.fit.settings import ADD_LOSS_EPS, ADD_STEPS, PAIRS, FitSettings, Number, parse_mlp, positive_int
from hybridbrdf.demo import BYTES_PER_SAMPLE as DEMO_BYTES_PER_SAMPLE
from hybridbrdf.limits import check_count
from hybridbrdf.model import energy
from hybridbrdf.model.editing import albedo_bytes_per_sample, parse_assignments
from hybridbrdf.model.file import HybridModel, load_model
from hybridbrdf.model.prior import prior_path
from hybridbrdf.render.preview import ROWS, render_preview
from hybridbrdf.render.tracer import RenderMaterialError, render
from hybridbrdf.render.tracer import settings as render_settings
from hybridbrdf.sources import expand_sources, open_source
from hybridbrdf.util import check_writable, file_lock
from hybridbrdf.version import __version__
from hybridbrdf.viewer import measured as viewer_sources
from hybridbrdf.viewer.page import write_page

EPILOG = ("SOURCE: a file (.binary MERL, .bsdf RGL, .bin UTIA, .h5 NBRDF network), a folder, a glob, "
          "or synthetic:NAME (synthetic:all = every built-in material).")


#: A loop that can run for minutes shows a progress bar on stderr: on a terminal from the start,
#: elsewhere (a log) once it has run this many seconds, and then a line every PROGRESS_LOG_S.
PROGRESS_DELAY_S = 3.0
PROGRESS_LOG_S = 10.0


def progress_bar(iterable, total: int, desc: str, unit: str, quiet: bool = False):
    """``iterable`` with a progress bar on stderr (tqdm) unless ``quiet``: drawn at once when stderr
    is a terminal, else only after :data:`PROGRESS_DELAY_S` seconds, so quick runs and pipes
    stay clean. Print lines meanwhile with :func:`print_beside`, which does not tear it."""
    tty = sys.stderr.isatty()
    return tqdm(iterable, total=total, desc=desc, unit=unit, file=sys.stderr, disable=quiet, leave=False,
                delay=0.0 if tty else PROGRESS_DELAY_S, mininterval=0.1 if tty else PROGRESS_LOG_S)


def print_beside(bar, line: str) -> None:
    """``line`` on stdout while ``bar`` runs: through ``bar.write`` (which clears and redraws it)
    when both go to one terminal, else a plain print (a redraw would write the bar into a log)."""
    if sys.stdout.isatty() and sys.stderr.isatty():
        bar.write(line, file=sys.stdout)
    else:
        print(line, flush=True)


def _open_all(specs):
    return [open_source(s) for s in expand_sources(specs)]


def _fit_fields():
    return [f for f in dataclasses.fields(FitSettings) if f.metadata.get("flag")]


def add_fit_flags(parser: argparse.ArgumentParser, sections=None, skip=()) -> None:
    """``hbrdf fit``'s setting flags, one per FitSettings field that has one (only those of
    ``sections`` when given, and none of the fields named in ``skip``)."""
    for f in _fit_fields():
        m = f.metadata
        if (sections is not None and m["section"] not in sections) or f.name in skip:
            continue
        kwargs = dict(m["cli"])
        if kwargs.get("action") not in ("store_true", "store_false"):
            kwargs["default"] = None  # unset: FitSettings' default (shown in the help text)
        parser.add_argument(m["flag"], dest=f.name, help=m["help"].replace("%(default)s", str(f.default)), **kwargs)


def settings_from_args(args: argparse.Namespace, sparse: bool = False):
    """FitSettings from parsed flags: a flag left unset keeps its value in the recipe
    (``--recipe``, default hybridbrdf: the fields' defaults). ``sparse``: the settings of a
    sparse fit (``hbrdf add``), whose steps default to :data:`~hybridbrdf.fit.settings.ADD_STEPS` and
    (without --recipe) its loss epsilon to :data:`~hybridbrdf.fit.settings.ADD_LOSS_EPS`."""
    values = {}
    for f in _fit_fields():
        v = getattr(args, f.name, None)  # a command may offer a subset of the flags (hbrdf add)
        if v is not None:
            values[f.name] = v
    if "width" in values:  # --mlp WIDTHxDEPTH sets two fields
        values["width"], values["depth"] = parse_mlp(values["width"])
    if "latent" not in values and spec.ARCHS.get(values.get("arch"), {}).get("analytic") is False:
        values["latent"] = 12  # no analytic part: the hybrid's l = 4 plus its 8 analytic parameters
    if sparse:
        values.setdefault("steps", ADD_STEPS)
        if "recipe" not in values:  # hbrdf add's own loss epsilon, unless a recipe sets one
            values.setdefault("loss_eps", ADD_LOSS_EPS)
    values.setdefault("device", default_device())
    return FitSettings.from_recipe(values.pop("recipe", "hybridbrdf"), sources=list(args.sources), **values)


def fit_synopsis() -> str:
    """The README's synopsis of the fit flags, generated from FitSettings."""
    parts = []
    for f in _fit_fields():
        m = f.metadata
        action = m["cli"].get("action")
        if action in ("store_true", "store_false"):
            parts.append(f"[{m['flag']}]")
            continue
        if "choices" in m["cli"]:
            value = "|".join(m["cli"]["choices"])
        elif f.name == "width":
            value = f"{f.default}x3"
        else:
            value = m["cli"].get("metavar") or (str(f.default) if f.default is not None else "X")
        parts.append(f"[{m['flag']} {value}]")
    lines, line = [], "hbrdf fit SOURCE... --out MODEL"
    for part in parts:
        if len(line) + 1 + len(part) > 96:
            lines.append(line)
            line = "         " + part
        else:
            line += " " + part
    lines.append(line)
    return "\n".join(lines)


def _check_fit_outputs(args: argparse.Namespace) -> None:
    """--out and --checkpoint: writable, and not the same file (the model would replace the
    checkpoint a later --resume needs); an existing checkpoint only with --resume or --force.
    Raises InputFileError naming the path."""

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


def _cmd_fit(args: argparse.Namespace) -> int:

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
    frozen = load_model(settings.frozen_from) if settings.frozen_from else None
    if frozen is not None and settings.init_from:
        raise ValueError("--frozen keeps MODEL's network and --init trains it further: give one of them")
    init = None
    if settings.init_from:
        init = load_model(prior_path() if settings.init_from == "prior" else settings.init_from)
    for start_model in (frozen, init):
        if start_model is not None:
            frozen_arch_settings(settings, start_model)
    if args.resume and os.path.exists(args.checkpoint):
        ckpt.load(args.checkpoint, settings)  # fit() restores it; this only fails early
    sources = _open_all(args.sources)
    _check_out_is_no_source(args.out, sources)
    log = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
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
    model.save(args.out)
    rows = [dict(material=m["name"], origin=m["origin"], **m["metrics"]) for m in model.material_info]
    print(format_table(rows, settings.eval_pairs))
    rate = model.training.get("pairs_x_materials_per_second")
    print(f"trained {settings.steps} steps in {model.training['train_seconds']:.1f} s"
          + (f" ({rate:,.0f} pairs x materials / s)" if rate else "") + f"; wrote {args.out}")
    if args.preview_path:
        _write_preview(args.out, args.sources, args.preview_path)
    if ranks.distributed:
        dd.end_process(0)
    return 0


def _write_preview(model_path: str, sources, png: str) -> None:
    """The picture that ends `hbrdf fit`. The model is written by then: a preview that cannot be
    rendered (a build without the renderer, a source the tracer's reader refuses) is reported in
    one line and does not fail the command."""
    try:
        info = render_preview(model_path, sources, png)
    except (RuntimeError, ValueError, OSError) as exc:
        print(f"preview not written: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}", file=sys.stderr)
        return
    shown = len(info["materials"])
    print(f"wrote {png}: {shown} material{'s' if shown != 1 else ''} as spheres, rows "
          f"{' | '.join(label for label, _ in ROWS)} (rendered in {info['seconds']:.1f} s)")


def _cmd_add(args: argparse.Namespace) -> int:
    settings = settings_from_args(args, sparse=True)
    if args.to is not None and (args.keep_network or (args.finetune_steps is not None and not args.refine)):
        raise ValueError("--keep-network and --finetune-steps are for adding to the shipped prior or with --refine; "
                         "with --to BASE alone the fit is sparse (BASE's network kept)")
    if args.refine and args.to is None:
        raise ValueError("--refine refines the network of --to BASE; onto the shipped prior the network is "
                         "fine-tuned by default")
    if args.max_drift is not None and not args.refine:
        raise ValueError("--max-drift applies to --refine only")
    log = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    try:
        model = add(args.sources, to=args.to, out=args.out, settings=settings, progress=not args.quiet, log=log,
                    keep_network=args.keep_network, finetune_steps=args.finetune_steps, refine=args.refine,
                    **({} if args.max_drift is None else {"max_drift": args.max_drift}))
    except MemoryError:
        raise ValueError("out of memory; lower --pool, --batch or --eval-pairs") from None
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
        how = (f"fine-tuned the shipped prior's network with them ({settings.steps} sparse + "
               f"{model.training['steps']} fine-tune steps)")
    else:
        added = set(model.training["additions"][-1]["materials"])
        new = [m for m in model.material_info if m["name"] in added]
        seconds = model.training["additions"][-1].get("train_seconds", 0.0)
        how = f"sparse fit on {args.to or 'the shipped prior'}'s network, kept bit-exact"
    print(format_table([dict(material=m["name"], origin=m.get("origin", ""), **m["metrics"]) for m in new],
                       settings.eval_pairs))
    print(f"added {len(new)} material(s) in {seconds:.1f} s of training: {how}; wrote {args.out} "
          f"({len(model.materials)} materials)")
    return 0


def _describe_new_material(model, name: str, out: str) -> int:
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


def _cmd_bound(args: argparse.Namespace) -> int:
    check_count("--samples", args.samples, energy.bytes_per_sample())
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


def _layer_option(values, flag: str) -> dict:
    """``K=PATH`` pairs of --kd / --roughness: layer index -> path."""
    out = {}
    for v in values or []:
        k, sep, path = v.partition("=")
        if not sep or not k.strip().isdigit() or not path:
            raise ValueError(f"{flag} takes LAYER=FILE with LAYER a number (0 the base), got {v!r}")
        out[int(k)] = path
    return out


def _cmd_paint(args: argparse.Namespace) -> int:
    layers = []
    for v in args.layer or []:
        name, sep, mask = v.rpartition("=")
        if not sep or not name or not mask:
            raise ValueError(f"--layer takes MATERIAL_OR_FILE=MASK, got {v!r}")
        layers.append((name, mask))
    size = None
    if args.size:
        w, sep, h = args.size.lower().partition("x")
        if not sep or not w.isdigit() or not h.isdigit():
            raise ValueError(f"--size takes WxH, got {args.size!r}")
        size = (int(w), int(h))
    sv = paint(args.model, args.base, layers, args.out, size=size, format=args.format, addressing=args.addressing,
               kd=_layer_option(args.kd, "--kd"), roughness=_layer_option(args.roughness, "--roughness"),
               progress=not args.quiet, log=print)
    w, h = sv.size
    print(f"wrote {args.out}: {w}x{h} texels, {len(sv.layers)} layer(s) ({', '.join(sv.layers)}), {args.format} maps")
    return 0


def _cmd_edit(args: argparse.Namespace) -> int:
    values = parse_assignments(args.set)
    check_writable(args.out, "model")
    # --out MODEL updates MODEL in place: it is read under the lock, so a concurrent update
    # either finished before (and is kept) or waits for this one (docs/CONVENTIONS.md, "Writing files").
    with file_lock(args.out):
        model = load_model(args.model)
        edited = model.edit(args.material, args.as_name, conserve_energy=args.conserve_energy, **values)
        written = edited.save_checked(args.out)
    return _describe_new_material(written, args.as_name, args.out)


def _cmd_view(args: argparse.Namespace) -> int:
    if args.svbrdf is None and args.model is None:
        raise ValueError("give MODEL, or --svbrdf DIR")
    info = write_page(args.model, args.out, args.sources, env=args.env,
                      source_options={"size": args.source_size, "spp": args.source_spp}, svbrdf=args.svbrdf)
    what = f"{info['materials']} materials" if args.svbrdf is None else "a textured material"
    print(f"wrote {args.out} ({info['bytes'] / 2**20:.2f} MiB, {what}): open it in a browser "
          f"with {'WebGPU or ' if args.svbrdf is None else ''}WebGL2; it needs no network")
    return 0


def _cmd_mix(args: argparse.Namespace) -> int:
    check_writable(args.out, "model")
    with file_lock(args.out):  # as _cmd_edit: an update in place reads MODEL under the lock
        model = load_model(args.model)
        blend = model.mix(args.a, args.b, args.t, args.as_name, conserve_energy=args.conserve_energy)
        written = blend.save_checked(args.out)
    return _describe_new_material(written, args.as_name, args.out)


def _cmd_eval(args: argparse.Namespace) -> int:
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


def _shown(value) -> str:
    """A value from a model file's free-form records (training, metrics, origin) as ``hbrdf
    info`` prints it: floats with 6 significant digits, anything else as one printable line.
    Those records are informative, not part of the contract, so no value of them may stop info."""
    if isinstance(value, (bool, int)):
        return str(value)
    if isinstance(value, float):
        text = f"{value:.6g}"
        return text if any(c in text for c in ".enia") else text + ".0"  # a float still reads as one
    return one_line_text(value if isinstance(value, str) else json.dumps(value, default=str)[:200])


def _cmd_info(args: argparse.Namespace) -> int:
    if args.albedo_samples < 0:
        raise ValueError(f"--albedo-samples {args.albedo_samples}: must be >= 0 (0: no albedo)")
    check_count("--albedo-samples", args.albedo_samples, albedo_bytes_per_sample(HybridModel.LIBRARY_BYTES_PER_PAIR))
    model = load_model(args.model)
    a = model.arch
    written_by = getattr(model, "written_by", None)
    print(f"{args.model}: hybridbrdf model, format {spec.FORMAT_VERSION}, conventions {spec.CONVENTIONS_VERSION}"
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


#: What a fit records besides its settings (hybridbrdf.fit.fit.fit), printed by ``hbrdf info``.
RECORDED_TIMINGS = ("train_seconds", "train_seconds_from_step", "resumed_at_step", "compile_seconds")


def _settings_line(title: str, recorded: dict, sections, extra=()) -> str:
    """``title: key value, ...`` for the FitSettings fields of ``sections`` a model file records."""
    keys = [f.name for f in dataclasses.fields(FitSettings) if f.metadata["section"] in sections
            and f.name != "sources"] + list(extra)
    return f"{title}: " + ", ".join(f"{k} {_shown(recorded[k])}" for k in keys if recorded.get(k) is not None)


def _cmd_demo(args: argparse.Namespace) -> int:
    run_demo(args.out, samples=args.samples)
    return 0


def _cmd_render(args: argparse.Namespace) -> int:

    # One flag per scene setting (the library's table); None = keep the scene's value.
    overrides = {s["name"]: getattr(args, s["name"]) for s in render_settings()}
    # SIGTERM stops the render as Ctrl-C does: the library runs Python's signal handlers while it
    # works, and an exception from one cancels the render before any file is written.
    terminated = []

    def on_sigterm(signum, frame):
        terminated.append(signum)
        raise KeyboardInterrupt

    in_main_thread = threading.current_thread() is threading.main_thread()  # signal.signal needs it
    previous = signal.signal(signal.SIGTERM, on_sigterm) if in_main_thread else None
    try:
        _, stats = render(args.scene, out=args.out, png=args.png, quiet=args.quiet, exposure=args.exposure,
                          tonemap=args.tonemap, **overrides)
    except KeyboardInterrupt:
        print(f"hbrdf render: {'terminated' if terminated else 'interrupted'}, nothing written", file=sys.stderr)
        return 128 + (signal.SIGTERM if terminated else signal.SIGINT)
    except RenderMaterialError as exc:  # one line naming the scene and the material, as main() prints scene errors
        print(f"hbrdf render: error: {exc}", file=sys.stderr)
        return 1
    except MemoryError as exc:  # the sizes a scene sets are checked up front; this is the machine's limit
        print(f"hbrdf render: error: out of memory ({exc or 'MemoryError'})", file=sys.stderr)
        return 1
    finally:
        if in_main_thread:
            signal.signal(signal.SIGTERM, previous if previous is not None else signal.SIG_DFL)
    print(f"rendered {args.scene}: {stats['spp']} spp in {stats['seconds']:.2f} s "
          f"({stats['samples_per_second']:,.0f} samples/s, {stats['rays']:,} rays + {stats['shadow_rays']:,} shadow rays, "
          f"{stats['network_evals']:,} of {stats['brdf_evals']:,} BRDF evaluations ran the network, "
          f"{stats['threads']} threads); wrote {args.out}" + (f" and {args.png}" if args.png else ""))
    return 0


#: A render setting's number: finite (nan and inf say nothing about a scene); the library checks
#: each setting's own range when rendering.
FINITE = Number(float, -math.inf, math.inf)
#: --exposure's range in stops: 2^64 scales any radiance float32 holds past its range or below it.
EXPOSURE_STOPS = 64


def _add_render_setting_flags(parser: argparse.ArgumentParser) -> None:
    """--spp, --max-depth, ...: one flag per scene setting of the library's table (hybridbrdf.render.tracer.settings()),
    typed and documented by it; the library checks the ranges when rendering (one-line errors)."""
    for s in render_settings():
        flag = "--" + s["name"].replace("_", "-")
        default = str(s["default"]).lower() if s["type"] == "bool" else s["default"]
        help_text = f"{s['doc']} (default: the scene's, else {default})".replace("%", "%%")
        if s["type"] == "bool":
            parser.add_argument(flag, dest=s["name"], action=argparse.BooleanOptionalAction, default=None,
                                help=help_text)
        else:
            parser.add_argument(flag, dest=s["name"], type={"int": int, "float": FINITE, "str": str}[s["type"]],
                                choices=s["choices"], default=None,
                                metavar=None if s["choices"] else ("N" if s["type"] == "int" else "X"),
                                help=help_text)


def _add_fit_parser(sub) -> None:
    """``hbrdf fit``."""
    p = sub.add_parser("fit", help="fit one shared network + per-material parameters to BRDF sources",
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
    p.set_defaults(func=_cmd_fit)


def _add_add_parser(sub) -> None:
    """``hbrdf add``."""
    p = sub.add_parser("add", help="add BRDF sources to the shipped prior (fine-tuned) or to a model (network kept)",
                       description="Onto the shipped prior (no --to): each source's analytic parameters and latent "
                                   "code are fitted on the prior's frozen network (paper Sec. 4.2), then the network "
                                   "is trained further together with them (--finetune-steps); the model holds the "
                                   "new materials and their own network. --keep-network stops after the first part. "
                                   "With --to BASE: the sparse fit only, BASE's network kept bit-exact, and the model "
                                   "holds BASE's materials followed by the new ones. Inputs are checked before any "
                                   "training; --out is written only when the fit succeeds. Without --recipe or --loss-eps "
                                   "the loss epsilon is 0.03 (ADD_LOSS_EPS, docs/FITTING.md), not a joint fit's 0.1.",
                       epilog=EPILOG)
    p.add_argument("sources", nargs="+", metavar="SOURCE", help="BRDF files, folders, globs or synthetic:NAME")
    p.add_argument("--to", metavar="BASE", help="model file whose network the new materials share (default: the "
                                                "shipped prior, hybridbrdf.model.prior; the model then holds the new "
                                                "materials only)")
    p.add_argument("--out", required=True, help="model file to write (may be BASE itself)")
    add_fit_flags(p, sections=("training", "loss", "sparse", "run"), skip=("frozen_from", "init_from"))
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
    p.set_defaults(func=_cmd_add)


def _add_eval_parser(sub) -> None:
    """``hbrdf eval``."""
    p = sub.add_parser("eval", help="per-material SMAPE/cMAE of a model against BRDF sources",
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
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar (shown on stderr while the sources are evaluated: at once on a terminal, "
                        "elsewhere after a few seconds)")
    p.set_defaults(func=_cmd_eval)


def _add_new_material_flags(p, kd: str, whose: str) -> None:
    """--as, --out and --conserve-energy: the flags hbrdf edit and hbrdf mix share for the material they add."""
    p.add_argument("--as", dest="as_name", required=True, metavar="NAME", help="name of the new material")
    p.add_argument("--out", required=True, help="model file to write (may be MODEL itself)")
    p.add_argument("--conserve-energy", action="store_true",
                   help=f"also scale {kd} down (hue kept) until {whose} maximum directional albedo is at most 0.99, "
                        "where kd can do it (the energy-bound table bounds it in any case; docs/ENERGY.md)")


def _add_edit_parser(sub) -> None:
    """``hbrdf edit``."""
    p = sub.add_parser("edit", help="add an edited copy of a material (new analytic parameters, same latent code)",
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
    _add_new_material_flags(p, "the new kd", "the")
    p.set_defaults(func=_cmd_edit)


def _add_paint_parser(sub) -> None:
    """``hbrdf paint``."""
    p = sub.add_parser("paint", help="paint a textured material: layers of materials under grey masks (docs/SVBRDF.md)",
                       description="Write a textured material's folder (docs/SVBRDF.md): a base material and up to "
                                   "three layers painted over it by grey masks (the last on top), optional albedo "
                                   "and roughness textures per layer. A layer that names a measured file is added "
                                   "to the model first by a sparse fit on its frozen network. Per texel the "
                                   "material is the mixture of its layers' BRDFs. OUT is replaced only once complete.")
    p.add_argument("model", help="model file holding the layers' materials (a hybrid model)")
    p.add_argument("--base", required=True, metavar="MATERIAL_OR_FILE", help="layer 0: a material of MODEL or a measured file")
    p.add_argument("--layer", action="append", metavar="MATERIAL_OR_FILE=MASK",
                   help="a layer over the others (repeatable, at most 3): a material or measured file and its mask "
                        "(PNG or EXR; grey values, the first channel, are the layer's coverage)")
    p.add_argument("--kd", action="append", metavar="LAYER=ALBEDO",
                   help="layer LAYER's kd from an albedo texture (sRGB 8-bit PNG or linear EXR; repeatable); a texture "
                        "brighter than the layer's material gives the layer an energy-bounded edit, MATERIAL.kdmapLAYER")
    p.add_argument("--roughness", action="append", metavar="LAYER=ROUGHNESS",
                   help="layer LAYER's GGX alpha = r^2 from a grey roughness texture r (repeatable)")
    p.add_argument("--size", metavar="WxH", help="texels (default: the masks' size; masks and textures must have it)")
    p.add_argument("--format", choices=("png", "exr"), default="png",
                   help="maps as 8-bit PNG or float32 OpenEXR (default: %(default)s)")
    p.add_argument("--addressing", choices=tuple(spec.SVBRDF["addressing"]), default="repeat",
                   help="how uv outside [0, 1] reads the maps (default: %(default)s)")
    p.add_argument("--out", required=True, help="folder to write (replaced if it is a textured material's folder)")
    p.add_argument("--quiet", action="store_true", help="no progress bar while measured files are fitted")
    p.set_defaults(func=_cmd_paint)


def _add_bound_parser(sub) -> None:
    """``hbrdf bound``."""
    p = sub.add_parser("bound", help="fit energy-bound tables so that no material reflects more light than it receives",
                       description="Fit each material's energy-bound table (docs/ENERGY.md): f = k(wi.z) k(wo.z) f_t "
                                   "with k <= 1 per material, so that every directional albedo is at most 0.99; "
                                   "1 (no change) where it already is. Reciprocity is kept exactly. hbrdf fit, add, "
                                   "edit and mix do this already; this command bounds a model written before "
                                   "(or refits its tables). --out is written only when everything is valid.")
    p.add_argument("model", help="model file")
    p.add_argument("--out", required=True, help="model file to write (may be MODEL itself)")
    p.add_argument("--materials", metavar="A,B,...", help="only these materials (default: all); the others keep "
                                                          "their tables (or none: a table of ones)")
    p.add_argument("--samples", type=positive_int, default=energy.SAMPLES, metavar="N",
                   help="MIS samples per direction of the albedo estimate (default: %(default)s; at most what fits "
                        f"this machine's memory, {energy.bytes_per_sample() / 1024:.0f} KiB a sample; "
                        "docs/CONVENTIONS.md, \"Counts and memory\")")
    p.add_argument("--verbose", action="store_true", help="list every material, not only the dimmed ones")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar (shown on stderr while the tables are fitted: at once on a terminal, "
                        "elsewhere after a few seconds)")
    p.set_defaults(func=_cmd_bound)


def _add_mix_parser(sub) -> None:
    """``hbrdf mix``."""
    p = sub.add_parser("mix", help="add a blend of two materials (analytic parameters and latent codes)",
                       description="Paper Sec. 5.1: the linear blend (1 - t) A + t B of two materials' analytic "
                                   "parameters and latent codes, added to MODEL's materials and written to --out; "
                                   "t = 0 and 1 reproduce A and B exactly. Prints the blend's maximum directional "
                                   "albedo.")
    p.add_argument("model", help="model file holding both materials")
    p.add_argument("a", metavar="A", help="material at t = 0")
    p.add_argument("b", metavar="B", help="material at t = 1")
    p.add_argument("--t", type=FINITE, required=True, help="blend weight of B, in [0, 1] (the library checks the range)")
    _add_new_material_flags(p, "the blend's kd", "its")
    p.set_defaults(func=_cmd_mix)


def _add_view_parser(sub) -> None:
    """``hbrdf view``."""
    p = sub.add_parser("view", help="write one self-contained HTML page that shows the materials live "
                                    "(WebGPU or WebGL2)",
                       description="Write one HTML file, with everything inlined (it opens from disk, without "
                                   "network), that renders each material of MODEL on a sphere with WebGPU where the "
                                   "browser has it, else WebGL2, from the WGSL and GLSL that hbrdf-codegen writes: a "
                                   "material picker, the analytic part alone, "
                                   "kd / eta / alpha sliders that preview hbrdf edit (with its command line), "
                                   "exposure, and light from an environment map (default the path tracer's sky) or "
                                   "the sun alone (docs/VIEWER.md). With --svbrdf DIR it shows a textured material "
                                   "instead (WebGL2).")
    p.add_argument("model", nargs="?", metavar="MODEL",
                   help="model file (optional with --svbrdf, which shows the folder's own model; given, it must be "
                        "that model)")
    p.add_argument("sources", nargs="*", metavar="SOURCE",
                   help="BRDF sources the materials were fitted to: each is shown beside the material the fit "
                        "named after it, as the path tracer's render of the measurement and BRDF slices of the "
                        "model, its f_a and the measurement (docs/VIEWER.md)")
    p.add_argument("--out", "-o", required=True, help="HTML file to write")
    p.add_argument("--env", metavar="sky|MAP", default="sky",
                   help="environment map the page lights with: 'sky' (default: the path tracer's sky, a sun of "
                        "irradiance pi) or an equirectangular .exr / .hdr map (the tracer's mapping; maps wider "
                        "than 1024 texels are area-averaged down)")

    p.add_argument("--svbrdf", metavar="DIR",
                   help="show the textured material of DIR (written by hbrdf paint; docs/SVBRDF.md) on the sphere, "
                        "its layers mixed per texel by its maps at the path tracer's sphere uv (bilinear), with the "
                        "maps as small images beside it; WebGL2 only (docs/VIEWER.md, 'A textured material')")
    p.add_argument("--source-size", type=positive_int, default=viewer_sources.DEFAULT_SOURCE_SIZE, metavar="N",
                   help="pixels (square) of each SOURCE's measured render, 8 to 1024 (default: %(default)s)")
    p.add_argument("--source-spp", type=positive_int, default=viewer_sources.DEFAULT_SOURCE_SPP, metavar="N",
                   help="samples per pixel of each SOURCE's measured render (default: %(default)s; about 4 s "
                        "per RGL source on 2 cores)")
    p.set_defaults(func=_cmd_view)


def _add_info_parser(sub) -> None:
    """``hbrdf info``."""
    p = sub.add_parser("info", help="describe a model file", description="Print a model file's architecture, "
                                                                         "training settings and materials.")
    p.add_argument("model", help="model file")
    p.add_argument("--albedo-samples", type=int, default=1 << 11, metavar="N",
                   help="incident samples per outgoing direction for each material's maximum directional albedo "
                        "(44 outgoing directions; default: %(default)s, about 1%% noise; hbrdf edit and mix use "
                        "8192; 0: do not estimate it); at most what fits this machine's memory, about "
                        f"{albedo_bytes_per_sample(HybridModel.LIBRARY_BYTES_PER_PAIR) / 1024:.1f} KiB a sample "
                        "(docs/CONVENTIONS.md, \"Counts and memory\")")
    p.add_argument("--quiet", action="store_true",
                   help="no progress bar (shown on stderr while the albedo estimates run: at once on a terminal, "
                        "elsewhere after a few seconds)")
    p.set_defaults(func=_cmd_info)


def _add_demo_parser(sub) -> None:
    """``hbrdf demo``."""
    p = sub.add_parser(
        "demo",
        help="plot BRDF slices of built-in analytic materials and print their albedo",
        description="Plot in-plane slices and polar lobes of f_a for a few built-in analytic materials "
        "(C++ library, checked against the float64 PyTorch implementation) and print each material's "
        "directional albedo estimated with every sampling strategy.",
    )
    p.add_argument("--out", default="out/analytic_slices.png", help="PNG file to write (default: %(default)s)")
    p.add_argument("--samples", type=int, default=200_000, metavar="N",
                   help=f"samples per albedo estimate (default: %(default)s; at most what fits this machine's memory, "
                        f"{DEMO_BYTES_PER_SAMPLE} bytes a sample; docs/CONVENTIONS.md, \"Counts and memory\")")
    p.set_defaults(func=_cmd_demo)


def _add_render_parser(sub) -> None:
    """``hbrdf render``."""
    p = sub.add_parser("render", help="render a scene with the Embree path tracer",
                       description="Render a JSON scene (docs/RENDERING.md) with the reference path tracer: "
                                   "linear float32 OpenEXR, optionally a tone-mapped sRGB PNG.")
    p.add_argument("scene", help="scene file (JSON)")
    p.add_argument("-o", "--out", required=True, help="OpenEXR file to write (linear RGB, float32)")
    p.add_argument("--png", help="also write an 8-bit sRGB PNG")
    _add_render_setting_flags(p)
    p.add_argument("--exposure", type=Number(float, -EXPOSURE_STOPS, EXPOSURE_STOPS), default=0.0,
                   help=f"PNG exposure in stops, within +-{EXPOSURE_STOPS} (default: %(default)s)")
    p.add_argument("--tonemap", choices=("clamp", "aces"), default="clamp", help="PNG tone map (default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_render)


def build_parser() -> argparse.ArgumentParser:
    """The ``hbrdf`` parser: one subcommand per ``_add_<command>_parser``."""
    parser = argparse.ArgumentParser(prog="hbrdf", description="Hybrid neural-microfacet BRDFs.", epilog=EPILOG)
    parser.add_argument("--version", action="version", version=f"hybridbrdf {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_fit_parser(sub)
    _add_add_parser(sub)
    _add_eval_parser(sub)
    _add_edit_parser(sub)
    _add_mix_parser(sub)
    _add_bound_parser(sub)
    _add_paint_parser(sub)
    _add_view_parser(sub)
    _add_info_parser(sub)
    _add_demo_parser(sub)
    _add_render_parser(sub)
    add_acquire_parser(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt as exc:
        # A fit stopped between steps says how far it got and where its checkpoint is.
        print(f"hbrdf {args.command}: {exc if str(exc) else 'interrupted'}", file=sys.stderr)
        return 130
    except (ValueError, KeyError, OSError, FloatingPointError, RankLostError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        print(f"hbrdf {args.command}: error: {one_line_text(str(msg))}", file=sys.stderr)  # one line, always
        return 1


if __name__ == "__main__":
    sys.exit(main())
