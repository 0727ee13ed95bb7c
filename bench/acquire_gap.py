#!/usr/bin/env python3
"""The gap between a light-stage acquisition and a full measurement (issue 61, part 2;
docs/ACQUISITION_GAP.md).

Samples painted from the five raw RGL files that results/prior132_minus_rgl5_32x2_l8_heads_20k
(the held-out prior) never saw, photographed by a light stage (acquire.rigs.light_stage_rig, K
lights x V cameras, Poisson-Gaussian noise at two levels, 1 mm light jitter), fitted on the
held-out prior by acquire.hybrid_fit.fit_hybrid_texels in each configuration (--configs), and
scored per material: the cMAE (CONVENTIONS' metric pairs) of every sampled **pure** texel (one
weight above 0.99) against the truth at its centre, median over the texels. The reference is the
same material fitted from its full measurement: ``hbrdf add`` of the raw file onto the held-out
prior (hybridbrdf.fit.adding.add with its defaults, as bench/prior_heldout.py does), scored on
the same pairs against the file. The ratio hybrid / full measurement is issue 61's target
(at most 1.5 at N >= 32, both noise levels).

    python bench/acquire_gap.py [--stage 8x4] [--photo 96] [--map 24] [--pairs 20000]
        [--configs base,heads] [--seeds 0] [--noise low,high] [--samples paper3,napoli2]
        [--refs /tmp/acquire_gap_refs] [--anisotropic] [--out results/acquire_gap_MACHINE]
    python bench/acquire_gap.py --budget [--configs heads]   # a 512x512 capture of 16x4 photographs
                                                             # onto 128x128: the fit's seconds
    python bench/acquire_gap.py --ceiling                    # the frozen network fitted to each truth

Configurations (CONFIGS): ``base`` the fit with hbrdf acquire fit's defaults, ``heads``
each cluster's output layer refitted on its rows with the pull toward the prior's head
(refit_heads=True), ``heads_free`` the same without the pull (cluster_fit.HEAD_PULL = 0),
``heads_pull10`` with 10 times the pull, ``finetune`` the network, the cluster heads and values
fine-tuned on the clusters' pure texels with the prior's materials replayed, 500 steps
(finetune_network=500; acquire.network_tune), the texels then fitted on the tuned network;
``select`` each cluster's prior material chosen among the training shots' best 3 on held-out
photographs (select=True; acquire.select); ``texels_pull10`` / ``texels_pull100`` the texel
stage's pull toward its cluster's values 10 / 100 times the MAP weight (texel_stage.TEXEL_PULL);
``no_shrink`` the texel stage without the shrink toward the clusters' values (texel_stage.SHRINK);
``finetune200_free`` / ``finetune200_anchor1`` the 200-step fine-tune without its anchor and with
10 times its weight (network_tune.ANCHOR_WEIGHT 0 and 1);
``finetune200`` the fine-tune for 200 steps, ``finetune_lr_half`` for 500 at half the network's
rate (network_tune.NETWORK_LR), ``finetune_pull`` for 500 with the heads pulled toward their start
(network_tune.HEAD_PULL = 1); ``footprint_nearest`` finetune200 with every pixel credited to its
cell's texel (footprint.MODEL, the observation model until 2026-11-30). ``base`` is the fit of today's defaults (the cluster stage on pure
texels with every material screened since issue 61's second round: docs/ACQUISITION_GAP.md).
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import numpy as np
import torch

import hybridbrdf as hb
import hybridbrdf.acquire.cluster_fit as cluster_fit
import hybridbrdf.acquire.footprint as footprint
import hybridbrdf.acquire.network_tune as network_tune
import hybridbrdf.acquire.texel_stage as texel_stage
from hybridbrdf.acquire.hybrid_fit import fit_hybrid_texels
from hybridbrdf.acquire.isotropy import turned_about_normal
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.observations import texel_observations
from hybridbrdf.acquire.rigs import light_stage_rig
from hybridbrdf.acquire.simulation import simulate
from hybridbrdf.evaluate.metrics import cmae

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from acquire_compare import HELD_OUT_PRIOR, NOISE, PURE, Truth, machine_key  # noqa: E402
from svbrdf_mixture import smoothstep  # noqa: E402

#: Samples: the base, then the layers under the disc (and the band) of :func:`sample_masks`.
SAMPLES = {"paper3": ("paper_white_rgb", "vch_golden_yellow_rgb", "cc_ibiza_sunset_rgb"),
           "napoli2": ("colodur_napoli_4f_rgb", "cg_sunflower_rgb")}
#: Per configuration: fit_hybrid_texels keywords and the head refit's pull (cluster_fit.HEAD_PULL; None: its default).
CONFIGS = {"base": ({"refit_heads": False}, None), "heads": ({"refit_heads": True}, None),
           "heads_free": ({"refit_heads": True}, 0.0), "heads_pull10": ({"refit_heads": True}, 10.0),
           "finetune": ({"finetune_network": 500}, None), "select": ({"select": True}, None),
           "texels_pull10": ({}, ("texel_stage.TEXEL_PULL", 10.0)), "texels_pull100": ({}, ("texel_stage.TEXEL_PULL", 100.0)),
           "no_shrink": ({}, ("texel_stage.SHRINK", False)),
           "finetune200_free": ({"finetune_network": 200}, ("network_tune.ANCHOR_WEIGHT", 0.0)),
           "finetune200_anchor1": ({"finetune_network": 200}, ("network_tune.ANCHOR_WEIGHT", 1.0)),
           "finetune200": ({"finetune_network": 200}, None),
           "finetune_lr_half": ({"finetune_network": 500}, ("network_tune.NETWORK_LR", 1e-3)),
           "finetune_pull": ({"finetune_network": 500}, ("network_tune.HEAD_PULL", 1.0)),
           "footprint_nearest": ({"finetune_network": 200}, ("footprint.MODEL", "nearest"))}


def fit_config(obs, prior, config: str, steps: int, seed: int, on_clusters=None, progress=None):
    """fit_hybrid_texels in configuration ``config`` (CONFIGS); cluster_fit.HEAD_PULL restored after.
    ``on_clusters``: fit_hybrid_texels' hook (the clusters once known); ``progress`` its progress."""
    keywords, pull = CONFIGS[config]
    name, value = pull if isinstance(pull, tuple) else ("HEAD_PULL", pull)
    module = {"network_tune": network_tune, "texel_stage": texel_stage, "footprint": footprint}.get(name.split(".")[0], cluster_fit)
    name = name.split(".")[-1]
    default = getattr(module, name)
    setattr(module, name, default if value is None else value)
    try:
        return fit_hybrid_texels(obs, prior, steps=steps, seed=seed, on_clusters=on_clusters, progress=progress,
                                 **keywords)
    finally:
        setattr(module, name, default)
#: The light jitter of issue 61's measurement (1 mm on a 1 m light stage).
JITTER = 0.001
#: A noise level beside acquire_compare.NOISE's: photographs without noise (``--noise none``), what
#: the rig's directions alone allow the fit (the light's 1 mm jitter kept).
NOISELESS = (("none", None, 0.0),)


def sample_masks(size: int):
    """A disc (right of centre, radius 0.25) and a band (x < 0.3), soft over about a texel of a
    24-texel map, (size, size) each: regions wide enough for texels pure over their whole cell
    (bench/svbrdf_mixture.py's stripes leave none at 24x24)."""
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    disc = 1 - smoothstep(0.23, 0.27, np.hypot(x - 0.65, y - 0.5))
    band = 1 - smoothstep(0.28, 0.32, x)
    return [disc, band]


def reference(name: str, shared: pathlib.Path, cache: pathlib.Path):
    """The full-measurement fit of raw RGL ``name``: ``hbrdf add`` onto the held-out prior (its
    defaults), kept in ``cache`` (NAME.safetensors) and reused."""
    path = cache / f"{name}.safetensors"
    if not path.exists():
        from hybridbrdf.fit.adding import add
        from hybridbrdf.fit.settings import ADD_LOSS_EPS, ADD_STEPS, FitSettings

        cache.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        add([hb.open_source(str(shared / "rgl" / f"{name}.bsdf"))], out=str(path), progress=False,
            settings=FitSettings(steps=ADD_STEPS, loss_eps=ADD_LOSS_EPS), prior=str(HELD_OUT_PRIOR))
        print(f"reference {name}: hbrdf add onto the held-out prior in {time.perf_counter() - t0:.0f} s", flush=True)
    return hb.load_model(str(path))


def pure_texels(weights: np.ndarray, layer: int, count: int, seed: int = 0) -> np.ndarray:
    """Up to ``count`` texels (j * W + i) pure over their whole cell, drawn with ``seed``: the weight
    of ``layer`` above PURE at the texel and its 8 neighbours (the weights map is looked up
    bilinearly, so a pixel off the texel's centre mixes in its neighbours' weights, and a texel
    pure at its centre only, beside a stripe, was photographed 6% darker than its centre's truth)."""
    w = weights[..., layer] > PURE
    padded = np.pad(w, 1, mode="edge")  # clamp addressing
    h, wd = w.shape
    inner = np.all([padded[1 + dj:1 + dj + h, 1 + di:1 + di + wd] for dj in (-1, 0, 1) for di in (-1, 0, 1)], axis=0)
    pure = np.nonzero(inner.reshape(-1))[0]
    if len(pure) > count:
        pure = np.sort(np.random.default_rng(seed).choice(pure, count, replace=False))
    return pure


def median_cmae(fit, truth: Truth) -> float:
    """Median over ``truth``'s texels of the cMAE of ``fit.eval`` against the truth at each."""
    n = len(truth.wi)
    return float(np.median([cmae(truth.at(s), fit.eval(np.full(n, t, dtype=np.int64), truth.wi, truth.wo),
                                 truth.wi[:, 2]) for s, t in enumerate(truth.texels)]))


def run_sweep(args) -> int:
    shared, size = pathlib.Path(args.shared), (args.map, args.map)
    prior = hb.load_model(str(HELD_OUT_PRIOR))
    k, v = (int(x) for x in args.stage.split("x"))
    rig = light_stage_rig(k, v, size=(args.photo, args.photo))
    lines = [f"acquire_gap: light stage {k}x{v} = {k * v} photographs of {args.photo}x{args.photo}, light jitter "
             f"{JITTER}, {args.map}x{args.map} map, fit_hybrid_texels steps {args.steps} on {HELD_OUT_PRIOR.name}; "
             f"pure texels (weight > {PURE}, up to {args.texels} a material) x {args.pairs} metric pairs; "
             f"full measurement = hbrdf add of the raw file onto the same prior; rows "
             f"{'as photographed' if args.anisotropic else 'turned about the normal'}; machine {args.machine}, "
             f"torch threads {torch.get_num_threads()}"]
    header = f"{'sample':8s} {'material':24s} {'noise':5s} {'seed':>4s} {'full':>8s} " + " ".join(
        f"{c:>8s} {'ratio':>6s}" for c in args.configs) + "  fit CPU s (" + ", ".join(args.configs) + ")"
    out = open(args.out + ".txt.partial", "w")

    def say(text):
        print(text, flush=True)
        out.write(text + "\n")
        out.flush()

    for line in lines + [header]:
        say(line)
    for sample in args.samples:
        names = SAMPLES[sample]
        sources = [hb.open_source(str(shared / "rgl" / f"{n}.bsdf")) for n in names]
        mixture = Mixture.painted(sources[0], sources[1:], sample_masks(args.map)[:len(names) - 1])
        truths = [Truth(mixture, pure_texels(mixture.weights, i, args.texels), size, args.pairs) for i in range(len(names))]
        wi, wo = truths[0].wi, truths[0].wo
        full = [cmae(np.maximum(src.eval(wi, wo), 0.0), reference(n, shared, pathlib.Path(args.refs)).eval(wi, wo, n),
                     wi[:, 2]) for n, src in zip(names, sources)]
        for label, photons, read in [x for x in NOISE + NOISELESS if x[0] in args.noise]:
            for seed in args.seeds:
                cap = simulate(rig, mixture, NoiseModel(photons=photons, read_noise=read), light_jitter=JITTER,
                               seed=100 * seed + (label == "high"))
                obs = texel_observations(rig, cap.photos, size)
                if not args.anisotropic:  # the fits' isotropy assumption (acquire/isotropy.py), as hbrdf acquire fit
                    obs = turned_about_normal(obs, seed)
                errors, seconds, notes = {}, {}, []
                for config in args.configs:
                    t0 = time.process_time()  # CPU seconds: the machine is shared, wall time is not the fit's
                    merged = []
                    fit = fit_config(obs, prior, config, args.steps, seed,
                                     lambda family, labels, clusters: merged.append(clusters.get("merges", [])))
                    if merged and merged[0]:  # acquire/cluster_merge.py: what k-means split and the fit merged
                        notes.append(f"merges {config} {sample} {label} {seed}: "
                                     + ", ".join(f"{r:.2f}" for _, _, r in merged[0]))
                    seconds[config] = time.process_time() - t0
                    errors[config] = [median_cmae(fit, t) for t in truths]
                    if "select" in args.configs:  # what the held-out choice changed: each config's layers
                        notes.append(f"layers {config} {sample} {label} {seed}: {', '.join(fit.layers)}")
                    tuned = fit.model.training.get("acquisition_finetune")
                    if tuned:  # what the network fine-tune cost the prior's materials (network_tune.replay_drift)
                        d = tuned["drift"]
                        notes.append(f"replay drift {config} {sample} {label} {seed}: SMAPE median {d['median_smape']:.4f}, "
                                     f"worst {d['worst_smape']:.4f} ({d['worst_material']}); cMAE median "
                                     f"{d['median_cmae']:.5f}")
                for i, n in enumerate(names):
                    cells = " ".join(f"{errors[c][i]:8.5f} {errors[c][i] / full[i]:6.2f}" for c in args.configs)
                    say(f"{sample:8s} {n:24s} {label:5s} {seed:4d} {full[i]:8.5f} {cells}  "
                        + ", ".join(f"{seconds[c]:.0f}" for c in args.configs))
                for line in notes:
                    say(line)
    out.close()
    os.replace(args.out + ".txt.partial", args.out + ".txt")
    return 0


def run_budget(args) -> int:
    """Issue 61's budget: a 512x512 capture of 16 x 4 = 64 light-stage photographs (the paper3 sample,
    low noise, jitter) onto a 128x128 map: the seconds of the observations and of each configuration's fit."""
    shared = pathlib.Path(args.shared)
    names = SAMPLES["paper3"]
    sources = [hb.open_source(str(shared / "rgl" / f"{n}.bsdf")) for n in names]
    mixture = Mixture.painted(sources[0], sources[1:], sample_masks(512))
    rig = light_stage_rig(16, 4, size=(512, 512))
    cap = simulate(rig, mixture, NoiseModel(photons=NOISE[0][1], read_noise=NOISE[0][2]), light_jitter=JITTER, seed=1)
    prior = hb.load_model(str(HELD_OUT_PRIOR))
    t0 = time.perf_counter()
    obs = texel_observations(rig, cap.photos, (128, 128))
    if not args.anisotropic:
        obs = turned_about_normal(obs, 0)
    t_obs = time.perf_counter() - t0
    print(f"budget: 64 light-stage photographs of 512x512 onto 128x128, {len(obs.value):,} observations in "
          f"{t_obs:.1f} s; machine {args.machine}, torch threads {torch.get_num_threads()}", flush=True)
    for config in args.configs:
        t0, cpu0 = time.perf_counter(), time.process_time()
        stages = StageClock()
        fit_config(obs, prior, config, args.steps, 0, progress=stages)
        print(f"budget {config}: fit {time.perf_counter() - t0:.0f} s wall, {time.process_time() - cpu0:.0f} s CPU "
              f"(+ {t_obs:.1f} s observations); by stage: {stages.line()}", flush=True)
    return 0


class StageClock:
    """A fit's progress callback that keeps the CPU seconds from each stage's first progress report to
    the next stage's (the first stage's from the clock's start): where the budget goes, roughly (a
    stage's last work before its successor reports, e.g. the first energy table, counts as its own)."""

    def __init__(self):
        self.stages, self.last = {}, time.process_time()
        self.current = None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.current is None:
            self.current = stage
        elif stage != self.current:
            now = time.process_time()
            self.stages[self.current] = self.stages.get(self.current, 0.0) + now - self.last
            self.current, self.last = stage, now

    def line(self) -> str:
        now = time.process_time()
        stages = dict(self.stages)
        if self.current is not None:
            stages[self.current] = stages.get(self.current, 0.0) + now - self.last
        return ", ".join(f"{k} {v:.0f} s" for k, v in stages.items())


def run_footprint(args) -> int:
    """Why the bench scores texels pure over their whole cell: paper3's materials under
    bench/svbrdf_mixture.py's disc and stripes, photographed without noise; per kind of texel, the
    mean over its observations of observed value / the truth at the texel's centre, same directions."""
    from svbrdf_mixture import masks  # noqa: PLC0415

    shared, size = pathlib.Path(args.shared), (args.map, args.map)
    sources = [hb.open_source(str(shared / "rgl" / f"{n}.bsdf")) for n in SAMPLES["paper3"]]
    k, v = (int(x) for x in args.stage.split("x"))
    rig = light_stage_rig(k, v, size=(args.photo, args.photo))
    for layout, layers in (("svbrdf_mixture disc and stripes", masks(args.map)), ("disc and band", sample_masks(args.map))):
        mixture = Mixture.painted(sources[0], sources[1:], layers)
        obs = texel_observations(rig, simulate(rig, mixture).photos, size)
        centre = mixture.weights.reshape(-1, 3)[:, 0] > PURE
        whole = np.zeros_like(centre)
        whole[pure_texels(mixture.weights, 0, 10 ** 9)] = True
        for label, kind in (("pure at the centre only", centre & ~whole), ("pure over the whole cell", whole)):
            ratios = []
            for t in np.nonzero(kind)[0]:
                r = obs.rows(int(t))
                truth = np.maximum(sources[0].eval(obs.wi[r].astype(np.float64), obs.wo[r].astype(np.float64)), 0.0)
                ratios.append(obs.value[r].mean() / truth.mean())
            print(f"footprint, {layout}: {SAMPLES['paper3'][0]} texels {label}: {len(ratios)}, observed / centre "
                  f"truth mean {np.mean(ratios) if ratios else float('nan'):.3f}, min {min(ratios, default=float('nan')):.3f}",
                  flush=True)
    return 0


def run_ceiling(args) -> int:
    """What the frozen network can reach at best: per material of the samples, the prior's 4
    materials that explain it best as they are (2,000 metric pairs), each with its values fitted to
    the truth itself on 20,000 other pairs (the paper's loss, 400 Adam steps of 4,096 pairs), then
    also its output layer; scored as the sweep scores (the median texel's pairs) against the full
    measurement's cMAE. No photographs: the bound no capture on this prior gets past without
    changing the network."""
    from hybridbrdf.acquire.hybrid_fit import HybridFamily  # noqa: PLC0415
    from hybridbrdf.evaluate.metrics import metric_directions  # noqa: PLC0415

    shared = pathlib.Path(args.shared)
    prior = hb.load_model(str(HELD_OUT_PRIOR))
    family = HybridFamily(prior)
    every = family.raw_of_materials()
    wi, wo = (torch.from_numpy(x).float() for x in metric_directions(args.pairs))
    tw, to = (torch.from_numpy(x).float() for x in metric_directions(20_000, seed=777))
    print(f"ceiling: the held-out prior's frozen network fitted to each truth on 20,000 pairs; machine {args.machine}",
          flush=True)
    for name in dict.fromkeys(n for s in args.samples for n in SAMPLES[s]):
        src = hb.open_source(str(shared / "rgl" / f"{name}.bsdf"))
        truth = np.maximum(src.eval(wi.double().numpy(), wo.double().numpy()), 0.0)
        full = cmae(truth, reference(name, shared, pathlib.Path(args.refs)).eval(wi.numpy(), wo.numpy(), name),
                    wi[:, 2].numpy())
        target = torch.log1p(tw[:, 2:3] * torch.from_numpy(np.maximum(src.eval(tw.double().numpy(), to.double().numpy()),
                                                                       0.0)).float())
        with torch.no_grad():
            as_is = [float(((target[:2000] - torch.log1p(tw[:2000, 2:3] * family.evaluate(
                torch.full((2000,), m), {k: v[m][None].expand(2000, -1) for k, v in every.items()},
                tw[:2000], to[:2000]))) ** 2).mean()) for m in range(len(prior.materials))]
        cells = []
        for m in np.argsort(as_is)[:4].tolist():
            for heads in (False, True):
                raw = {k: v[m][None].clone().requires_grad_() for k, v in every.items()}
                head = [family.tensors[k][m:m + 1].clone().requires_grad_(heads) for k in ("materials.head_weight",
                                                                                         "materials.head_bias")]
                opt = torch.optim.Adam(list(raw.values()) + (head if heads else []), lr=0.03)
                gen = torch.Generator().manual_seed(0)
                for step in range(400):
                    opt.param_groups[0]["lr"] = 0.03 * (1 - 0.9 * step / 400)
                    i = torch.randint(0, len(tw), (4096,), generator=gen)
                    f = family.with_heads(torch.tensor([m]), *head).evaluate(
                        torch.zeros(4096, dtype=torch.long), {k: v.expand(4096, -1) for k, v in raw.items()}, tw[i], to[i])
                    opt.zero_grad()
                    ((target[i] - torch.log1p(tw[i, 2:3] * f)) ** 2).mean().backward()
                    opt.step()
                with torch.no_grad():
                    f = family.with_heads(torch.tensor([m]), *head).evaluate(
                        torch.zeros(len(wi), dtype=torch.long), {k: v.expand(len(wi), -1) for k, v in raw.items()}, wi, wo)
                cells.append(f"{prior.materials[m]}{' +head' if heads else ''} "
                             f"{cmae(truth, f.double().numpy(), wi[:, 2].numpy()) / full:.2f}")
        print(f"ceiling {name}: full measurement cMAE {full:.5f}; ratio to it, values (+head) fitted to the truth: "
              + ", ".join(cells), flush=True)
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stage", default="8x4", help="KxV lights x cameras (default 8x4: 32 photographs)")
    ap.add_argument("--photo", type=int, default=96, help="photograph side (default 96)")
    ap.add_argument("--map", type=int, default=24, help="texel map side, = the weights map's (default 24)")
    ap.add_argument("--pairs", type=int, default=20_000, help="metric pairs per texel (default 20000)")
    ap.add_argument("--texels", type=int, default=16, help="pure texels scored per material at most (default 16)")
    ap.add_argument("--steps", type=int, default=300, help="fit_hybrid_texels steps (default 300, hbrdf acquire fit's)")
    ap.add_argument("--configs", default="base,heads", help=f"comma-separated, of {', '.join(CONFIGS)}")
    ap.add_argument("--seeds", default="0", help="capture and fit seeds, comma-separated (default 0)")
    ap.add_argument("--noise", default="low,high", help="noise levels of acquire_compare.NOISE, or none: "
                    "photographs without noise (default low,high)")
    ap.add_argument("--samples", default=",".join(SAMPLES), help=f"comma-separated, of {', '.join(SAMPLES)}")
    ap.add_argument("--refs", default="/tmp/acquire_gap_refs", help="folder caching the hbrdf add references")
    ap.add_argument("--anisotropic", action="store_true",
                    help="fit the rows as photographed (before 2026-11-30: hbrdf acquire fit --anisotropic); default: "
                         "each row turned about the normal (acquire/isotropy.py), as hbrdf acquire fit does")
    ap.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    ap.add_argument("--budget", action="store_true", help="time the 512x512, 64-photograph, 128x128 fit instead")
    ap.add_argument("--footprint", action="store_true",
                    help="print why texels are scored pure over their whole cell (no fits) instead")
    ap.add_argument("--ceiling", action="store_true",
                    help="print what the frozen network reaches fitted to each truth itself (no photographs) instead")
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"), help="the shared data folder")
    ap.add_argument("--machine", default=machine_key(), help="machine key (default: detected)")
    ap.add_argument("--out", help="write PREFIX.txt (default results/acquire_gap_MACHINE)")
    args = ap.parse_args()
    args.configs = args.configs.split(",")
    unknown = [c for c in args.configs if c not in CONFIGS]
    if unknown:
        ap.error(f"--configs: unknown {', '.join(unknown)}; expected {', '.join(CONFIGS)}")
    args.seeds = [int(s) for s in args.seeds.split(",")]
    args.noise, args.samples = args.noise.split(","), args.samples.split(",")
    args.out = args.out or str(ROOT / "results" / f"acquire_gap_{args.machine}")
    torch.set_num_threads(args.threads)
    if args.footprint:
        return run_footprint(args)
    if args.ceiling:
        return run_ceiling(args)
    return run_budget(args) if args.budget else run_sweep(args)


if __name__ == "__main__":
    sys.exit(main())
