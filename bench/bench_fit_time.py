#!/usr/bin/env python3
"""Time to accuracy of joint fitting: metric against wall seconds for the old and new schedules.

Fits the 54 RGL materials of ``../shared/data`` (5 raw files + 49 NBRDF reconstructions) with
each schedule in turn, in one run, on ``--threads`` torch threads, and snapshots the model every
``--snapshot-every`` seconds of the schedule's wall time. A schedule is a list of phases, each an
``hbrdf fit`` (the refit is ``hbrdf fit --frozen``): its clock runs from the first phase's start,
pool evaluation and compilation (from a cold cache) included, and stops at ``--budget`` seconds (a phase still
running then is cut off: what a user with that budget would hold). Snapshot copies are excluded
from the clock; the snapshots are evaluated after the schedule ends, with the CONVENTIONS metrics
(``--eval-pairs`` pairs, seed 7) against references evaluated once for the whole run.

The target is the accuracy of ``results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors``
(evaluated here on the same pairs): its mean SMAPE and mean cMAE over the 54 materials, and a
win over the authors' released model on both metrics for each of the five raw RGL rows.

    python bench/bench_fit_time.py [--schedules new,old] [--budget 1800] [--threads 2] [--init-prior MODEL]
        [--snapshot-every 150] [--eval-pairs 1000000] [--device cpu|cuda] [--out docs/figures/fit_time]
        [--save-model results/rgl54_hybrid_32x2_fast58k_exp_refit005.safetensors]

Writes OUT.txt (what it prints), OUT.json (every curve point) and OUT.png (the curves).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pathlib
import sys
import tempfile
import time
from dataclasses import dataclass
from typing import Dict, List, Optional

import numpy as np
import torch

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

import hybridbrdf as hb  # noqa: E402
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.fit import fit
from hybridbrdf.sources.names import material_names
from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape  # noqa: E402
from hybridbrdf.model.file import HybridModel  # noqa: E402
from hybridbrdf.model.networks import build_model  # noqa: E402
from bench_analytic import cpu_name  # noqa: E402
from rgl_paper_comparison import PAPER, beats_paper  # noqa: E402

DATA = ROOT.parent / "shared" / "data"
TARGET_MODEL = ROOT / "results" / "rgl54_hybrid_32x2_e09_120k_refit01.safetensors"

#: The network and loss both schedules share (results/README.md, rgl54_hybrid_32x2_e09_120k).
COMMON = dict(arch="hybrid", width=32, depth=2, latent=4, activation="hardgelu", loss_eps=0.01,
              specular=0.1, analytic_expectile=0.9, output_layer="shared")


@dataclass
class Phase:
    """One ``hbrdf fit`` of a schedule: ``settings`` (FitSettings fields over COMMON); ``refit``:
    a frozen fit of (p, z) on the previous phase's network (``hbrdf fit --frozen``)."""
    label: str
    settings: Dict[str, object]
    refit: bool = False
    #: a warm start (``hbrdf fit --init PRIOR``) from the ``--init-prior`` model; the network
    #: settings are then the prior's.
    init: bool = False

    def command(self) -> str:
        merged = {**COMMON, **self.settings}
        fixed = ("width", "depth", "latent", "output_layer")  # spelled out below from the merged values
        flags = " ".join(f"--{k.replace('_', '-')} {v}" for k, v in self.settings.items()
                         if k not in fixed or self.refit or self.init)
        if self.refit:
            return f"hbrdf fit --frozen PREV ../shared/data/rgl ../shared/data/nbrdf/rgl {flags} --compile"
        if self.init:
            return f"hbrdf fit --init PRIOR ../shared/data/rgl ../shared/data/nbrdf/rgl {flags} --compile"
        return (f"hbrdf fit ../shared/data/rgl ../shared/data/nbrdf/rgl --mlp {merged['width']}x{merged['depth']} "
                f"--latent {merged['latent']} --output-layer {merged['output_layer']} {flags} --compile")


#: The schedules compared. "old": the commands of results/rgl54_hybrid_32x2_e09_120k_refit01
#: (120,000 steps at lr 5e-3, cosine decay, then a 3,000-step refit of (p, z) under loss eps 0.1).
#: "new" (--recipe fast): the same network and loss at 8x the learning rate, decayed exponentially
#: to 1/100 of it over 58,000 steps, then the refit under eps 0.05 (docs/LOSS.md, "Fitting in
#: 30 minutes: the learning rate"). "cosine": the fast schedule's first form (cosine decay, refit
#: eps 0.1; its figures: docs/BENCHMARKS_HISTORY.md), kept for comparison; not run by default.
#: "heads": today's --recipe fast, the "new" schedule on a 16x2 network with material output layers
#: and no refit; not run by default (`--schedules new,heads`).
SCHEDULES = {
    "old": [Phase("joint", dict(steps=120_000, lr=5e-3)),
            Phase("refit", dict(steps=3000, loss_eps=0.1), refit=True)],
    "new": [Phase("joint", dict(steps=58_000, lr=4e-2, lr_schedule="exponential", lr_final=0.01)),
            Phase("refit", dict(steps=3000, loss_eps=0.05), refit=True)],
    "cosine": [Phase("joint", dict(steps=58_000, lr=4e-2)),
               Phase("refit", dict(steps=3000, loss_eps=0.1), refit=True)],
    "heads": [Phase("joint", dict(width=16, output_layer="material", steps=58_000, lr=4e-2,
                                  lr_schedule="exponential", lr_final=0.01))],
    # A warm start from a prior that never saw an RGL material (--init-prior;
    # bench/train_prior.py --folders nbrdf/merl,nbrdf/nielsen: 32x2, latent 8, material output
    # layers) against the cold start of the same network ("heads32"), both on the fast loss.
    "warm": [Phase("joint", dict(steps=8000, lr=1e-2, lr_schedule="exponential", lr_final=0.01,
                                 output_layer="material"), init=True)],
    "heads32": [Phase("joint", dict(latent=8, output_layer="material", steps=15_000, lr=4e-2,
                                    lr_schedule="exponential", lr_final=0.01))],
}


class OutOfTime(Exception):
    """Raised by the snapshot observer when a schedule's budget is spent."""


@dataclass
class Snapshot:
    """A curve point: the module's state mid-phase, or the phase's finished model."""
    seconds: float
    phase: str
    step: int
    state: Optional[Dict[str, torch.Tensor]] = None
    model: Optional[HybridModel] = None
    settings: Optional[FitSettings] = None  # the network the state belongs to


def run_schedule(name: str, phases: List[Phase], sources, budget: float, every: float,
                 log, device: str = "cpu", init: Optional[HybridModel] = None
                 ) -> (List[Snapshot], Optional[HybridModel], float):
    """Run ``phases`` until done or ``budget`` seconds; returns the snapshots, the final model
    (None when cut off) and the clock at the end."""
    snaps: List[Snapshot] = []
    paused = 0.0
    t0 = time.perf_counter()
    clock = lambda: time.perf_counter() - t0 - paused  # noqa: E731
    next_at = [every]
    current = {"phase": ""}

    def observe(step, module):
        nonlocal paused
        now = clock()
        if now >= next_at[0] or now >= budget:
            t = time.perf_counter()
            snaps.append(Snapshot(now, current["phase"], step,
                                  {k: v.detach().cpu().clone() for k, v in module.state_dict().items()},
                                  settings=dataclasses.replace(current["settings"])))
            while next_at[0] <= now:
                next_at[0] += every
            paused += time.perf_counter() - t
        if now >= budget:
            raise OutOfTime

    model = None
    for phase in phases:
        current["phase"] = phase.label
        settings = FitSettings(**{**COMMON, **phase.settings, "eval_pairs": 1000, "device": device})
        current["settings"] = settings  # fit() sets a warm start's network fields to the prior's
        if phase.init and init is None:
            raise SystemExit(f"schedule {name} starts from a prior: give --init-prior")
        log(f"  {name}/{phase.label}: {phase.command()}")
        try:
            model = fit(sources, settings, frozen=model if phase.refit else None,
                        init=init if phase.init else None, progress=False,
                        log=lambda msg: None, compile_step=True, observe=observe)
        except OutOfTime:
            log(f"  {name}: budget of {budget:.0f} s spent in phase {phase.label} at step {snaps[-1].step}")
            return snaps, None, clock()
        # The phase's last state is a curve point too (fit() evaluated it on 1000 pairs only).
        t = time.perf_counter()
        snaps.append(Snapshot(clock(), phase.label, settings.steps, model=model))
        paused += time.perf_counter() - t
        log(f"  {name}/{phase.label}: done at {snaps[-1].seconds:.0f} s "
            f"(compile {model.training.get('compile_seconds', 0):.0f} s)")
    return snaps, model, clock()


class Evaluator:
    """CONVENTIONS metrics of many models of one collection, the references evaluated once."""

    def __init__(self, sources, names, n_pairs: int):
        self.names = names
        self.wi, self.wo = metric_directions(n_pairs)
        self.cos = self.wi[:, 2]
        self.refs = [np.asarray(s.eval(self.wi, self.wo), dtype=np.float32) for s in sources]
        self.iso = [bool(s.isotropic) for s in sources]
        self.origins = [s.origin for s in sources]

    def model_of(self, snap: Snapshot) -> HybridModel:
        if snap.model is not None:
            return snap.model
        st = snap.settings
        module = build_model(st.arch, len(self.names), st.width, st.depth, st.latent, st.activation, self.iso,
                             output_layer=st.network_output_layer())
        module.load_state_dict(snap.state)
        return HybridModel.from_module(module.eval(), self.names, self.origins, {})

    def metrics(self, model: HybridModel) -> Dict[str, object]:
        rows = []
        for name, ref in zip(self.names, self.refs):
            f, fa = model._eval(self.wi, self.wo, name, torch.float32)
            rows.append({"material": name, "smape": smape(ref, f), "cmae": cmae(ref, f, self.cos),
                         "smape_analytic": smape(ref, fa), "cmae_analytic": cmae(ref, fa, self.cos)})
        five = {}
        for raw in PAPER:
            row = next(r for r in rows if r["material"] in (raw, f"{raw}.rgl"))
            five[raw] = {"smape": row["smape"], "cmae": row["cmae"], "beats": beats_paper(row, PAPER[raw])}
        mean = lambda k: float(np.mean([r[k] for r in rows]))  # noqa: E731
        return {"smape": mean("smape"), "cmae": mean("cmae"), "smape_analytic": mean("smape_analytic"),
                "cmae_analytic": mean("cmae_analytic"), "wins": sum(v["beats"] for v in five.values()),
                "five": five}


def reached(m: Dict[str, object], target: Dict[str, object]) -> bool:
    return m["smape"] <= target["smape"] and m["cmae"] <= target["cmae"] and m["wins"] == len(PAPER)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--schedules", default="new,old", help="comma-separated names of SCHEDULES (default: new,old)")
    ap.add_argument("--budget", type=float, default=1800.0, help="wall seconds per schedule (default: 1800)")
    ap.add_argument("--threads", type=int, default=2, help="torch threads (default: 2)")
    ap.add_argument("--snapshot-every", type=float, default=150.0, help="seconds between curve points (default: 150)")
    ap.add_argument("--eval-pairs", type=int, default=1_000_000, help="metric pairs (default: 1000000, CONVENTIONS)")
    ap.add_argument("--out", default=str(ROOT / "docs" / "figures" / "fit_time"),
                    help="writes OUT.txt, OUT.json, OUT.png (default: docs/figures/fit_time)")
    ap.add_argument("--save-model", metavar="PATH", help="write the first schedule's final model there")
    ap.add_argument("--device", default="cpu",
                    help="torch device of the fits, e.g. cuda (default: cpu; the metrics are computed on the CPU)")
    ap.add_argument("--init-prior", metavar="MODEL", help="the prior of the warm-start schedule 'warm'")
    ap.add_argument("--steps-scale", type=float, default=1.0,
                    help="multiply every phase's steps (a quick check of the script; default: 1)")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    lines: List[str] = []

    def log(msg: str = "") -> None:
        print(msg, flush=True)
        lines.append(msg)

    sources = [hb.open_source(p) for p in hb.expand_sources([str(DATA / "rgl"), str(DATA / "nbrdf" / "rgl")])]
    names = material_names(sources)
    device = torch.cuda.get_device_name(0) if args.device.startswith("cuda") else cpu_name()
    log(f"machine: {device} ({args.device}), {args.threads} torch threads, torch {torch.__version__}; "
        f"{len(sources)} RGL materials (raw + NBRDF reconstructions); budget {args.budget:.0f} s per schedule")
    t = time.perf_counter()
    ev = Evaluator(sources, names, args.eval_pairs)
    log(f"references on {args.eval_pairs} metric pairs (seed 7) evaluated once: {time.perf_counter() - t:.0f} s")
    target = ev.metrics(hb.load_model(str(TARGET_MODEL)))
    log(f"target ({TARGET_MODEL.relative_to(ROOT)}): mean SMAPE {target['smape']:.4f}, mean cMAE "
        f"{target['cmae']:.5f}, {target['wins']} of 5 rows beat the released model")

    results = {}
    for name in args.schedules.split(","):
        # Each schedule compiles from a cold cache, as a first fit on a fresh machine does: the
        # schedules share their graphs, so the second would otherwise reuse the first's kernels.
        os.environ["TORCHINDUCTOR_CACHE_DIR"] = tempfile.mkdtemp(prefix=f"hbrdf_inductor_{name}_")
        torch._dynamo.reset()
        phases = [dataclasses.replace(p, settings={**p.settings, "steps": max(1, round(p.settings["steps"] * args.steps_scale))})
                  for p in SCHEDULES[name]]
        log(f"\nschedule {name}:")
        snaps, model, end = run_schedule(name, phases, sources, args.budget, args.snapshot_every, log,
                                         args.device, hb.load_model(args.init_prior) if args.init_prior else None)
        if model is not None and args.save_model and not results:
            model.save_checked(args.save_model)
            log(f"  wrote {args.save_model}")
        points = []
        log(f"  {'wall s':>7s} {'phase':6s} {'step':>7s} {'SMAPE':>7s} {'cMAE':>8s} {'SMAPE a':>7s} {'cMAE a':>8s} "
            f"{'rows':>4s}  reached")
        first = None
        for s in snaps:
            m = ev.metrics(ev.model_of(s))
            ok = reached(m, target)
            if ok and first is None:
                first = s.seconds
            points.append({"seconds": s.seconds, "phase": s.phase, "step": s.step, **m, "reached": ok})
            log(f"  {s.seconds:7.0f} {s.phase:6s} {s.step:7d} {m['smape']:7.4f} {m['cmae']:8.5f} "
                f"{m['smape_analytic']:7.4f} {m['cmae_analytic']:8.5f} {m['wins']:2d}/5  {'yes' if ok else 'no'}")
        verdict = (f"reached the target at {first:.0f} s" if first is not None
                   else f"not reached within {min(end, args.budget):.0f} s")
        log(f"  {name}: {verdict}")
        results[name] = {"phases": [dataclasses.asdict(p) for p in phases], "points": points,
                         "reached_seconds": first, "end_seconds": end}
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".txt").write_text("\n".join(lines) + "\n")
    out.with_suffix(".json").write_text(json.dumps({"machine": cpu_name(), "threads": args.threads,
                                                    "budget": args.budget, "target": target,
                                                    "schedules": results}, indent=1))
    plot(results, target, out.with_suffix(".png"), args.budget)
    return 0


def plot(results, target, path, budget) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    keys = [("cmae", "mean cMAE (54 materials)"), ("smape", "mean SMAPE (54 materials)"),
            ("gy", "vch_golden_yellow cMAE / released model's")]
    for ax, (key, title) in zip(axes, keys):
        for name, r in results.items():
            xs = [p["seconds"] for p in r["points"]]
            if key == "gy":
                ys = [p["five"]["vch_golden_yellow_rgb"]["cmae"] / PAPER["vch_golden_yellow_rgb"][2] for p in r["points"]]
            else:
                ys = [p[key] for p in r["points"]]
            ax.plot(xs, ys, marker="o", ms=3, label=name)
        ax.axhline(1.0 if key == "gy" else target[key], color="k", ls="--", lw=0.8, label="target")
        ax.axvline(budget, color="grey", ls=":", lw=0.8)
        ax.set_xlabel("wall seconds")
        ax.set_title(title, fontsize=10)
        ax.set_yscale("log")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    sys.exit(main())
