#!/usr/bin/env python3
"""The acquisition comparison in the paper's own setting, with seeds (issue 61 step 1;
docs/ACQUISITION_GAP.md, "Hybrid against analytic-only and neural-only on three rigs").

bench/acquire_compare.py's sample (three raw RGL measurements under the disc and stripes), its
errors (per-texel SMAPE and cMAE against the exact mixture over all directions, medians over every
texel of the map; the novel-view re-render's relative MAE) and its models, photographed by three
rigs instead of the phone flash alone:

- ``flash``: acquire.rigs.flash_rig(N), every photograph on the collocated slice (wi ~ wo);
- ``flash-multiview``: V phones at flash_rig(V)'s positions; each fires its flash in turn and all
  V photograph the sample under it (V x V shots: V collocated, V (V - 1) with wi != wo);
- ``light-stage``: acquire.rigs.light_stage_rig(K, V), K lights x V cameras (no shot collocated).

Each point (rig, N, noise level) is measured with several seeds (--seeds): seed s draws the
sensor noise and the light jitter (--jitter, rig length units) and the fits' own seed; every seed
scores the same texels (--texels N > 0: N drawn per seed instead, the rule until 2026-11-30, whose
spread held the draw's too). A row reports each metric's mean over the seeds and its spread
(min-max). The verdict of hybrid against another model on a metric (:func:`verdict`): the gap
between the two models' seed means counts only when it exceeds both models' seed ranges
(max - min); inside them: tie. ``--ceiling`` also prints what the hybrid reaches with every
direction measured: each layer its full-measurement fit, mixed by the true weights.

    python bench/acquire_verdict.py [--rig flash,flash-multiview,light-stage] [--flash-ns 8,32]
        [--views 3,6] [--stages 4x2,8x4,16x8] [--seeds 3] [--models analytic,hybrid_heldout,neural_heldout] [--hybrid KEY]
        [--steps 150] [--photo 48] [--map 16] [--texels 0] [--pairs 2000] [--render-filter bilinear]
        [--observation-model bilinear] [--seen-degrees 5] [--ceiling] [--refs /tmp/acquire_gap_refs] [--out results/acquire_verdict_MACHINE]
    python bench/acquire_verdict.py --table results/acquire_verdict_M2.jsonl   # the verdict table again

Each point also reports SMAPE and cMAE split by what the photographs saw (--seen-degrees): each
texel's metric pairs within that angle of a direction pair photographed at it, and the rest,
whose values no photograph constrained (the model's and its prior's extrapolation).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
import zlib

import numpy as np
import torch
from scipy.spatial import cKDTree

import hybridbrdf as hb
from hybridbrdf.acquire import footprint
from hybridbrdf.acquire.geometry import pixel_geometry
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.isotropy import turned_about_normal
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.observations import texel_observations
from hybridbrdf.acquire.rig import Rig, Shot, check_rig, photo_name
from hybridbrdf.acquire.rigs import flash_rig, light_stage_rig
from hybridbrdf.acquire.simulation import radiance, simulate
from hybridbrdf.acquire.sizes import default_finetune
from hybridbrdf.acquire.texel_rows import ROWS_PER_TEXEL
from hybridbrdf.evaluate.metrics import smape_terms
from hybridbrdf.model.prior import prior_path
from hybridbrdf.sources.model import ModelMaterialSource
from hybridbrdf.sources.rusinkiewicz import half_diff_vectors

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
import acquire_compare as ac  # noqa: E402

RIGS = ("flash", "flash-multiview", "light-stage")
#: Model key -> (label, held out, fit function name, weights file or None).
MODELS = {"analytic": ("analytic only (f_a p per texel)", True, "fit_analytic_texels", None),
          "hybrid_heldout": ("hybrid, prior that never saw them, hbrdf acquire fit's default (its network fine-tuned "
                             "from 32 photographs on: acquire.sizes.default_finetune)", True, "fit_hybrid_texels",
                             ac.HELD_OUT_PRIOR),
          "hybrid_frozen": ("hybrid, prior that never saw them, its network frozen at every N", True,
                            "fit_hybrid_texels", ac.HELD_OUT_PRIOR),
          "neural_heldout": ("neural only, rgl44_heldout_neural_32x3 (never saw them)", True, "fit_neural_texels",
                             ac.HELD_OUT_NEURAL),
          "hybrid_shipped": ("hybrid, shipped prior (NOT held out)", False, "fit_hybrid_texels", None),
          "neural": ("neural only, rgl54_neural_32x3 (NOT held out)", False, "fit_neural_texels", ac.NEURAL),
          "hybrid_tuned": ("hybrid, prior that never saw them, its network fine-tuned 200 steps on the capture",
                           True, "fit_hybrid_texels", ac.HELD_OUT_PRIOR)}
#: Model key -> the fit's keyword arguments beyond the shared budget, each a value or a function of
#: the capture's photograph count (the product's default fine-tune: ``hbrdf acquire fit`` and
#: ``acquire()`` pass default_finetune(photographs) when none is asked for).
EXTRA = {"hybrid_tuned": {"finetune_network": 200}, "hybrid_frozen": {"finetune_network": 0},
         "hybrid_heldout": {"finetune_network": default_finetune},
         "hybrid_shipped": {"finetune_network": default_finetune}}
#: The hybrid of the verdict and the models it is compared with.
HYBRID, OTHERS = "hybrid_heldout", ("analytic", "neural_heldout")
METRICS = ac.VERDICT_METRICS
#: The SMAPE and cMAE split by what the photographs saw (:func:`seen_pairs`): each texel's metric
#: pairs near a direction pair photographed at it, and the rest; medians over the texels.
SPLIT_METRICS = (("smape_seen", "SMAPE-seen"), ("smape_unseen", "SMAPE-unseen"),
                 ("cmae_seen", "cMAE-seen"), ("cmae_unseen", "cMAE-unseen"))


# --- The rigs ----------------------------------------------------------------------------------

def multiview_flash_rig(v: int, size=(256, 256)) -> Rig:
    """V phones at flash_rig(V)'s positions, each flash fired in turn and photographed by every
    phone: V x V shots (camera-major), the V with camera == light on the collocated slice."""
    base = flash_rig(v, size=size)
    shots = [Shot(c, l, photo_name(c * v + l)) for c in range(v) for l in range(v)]
    return check_rig(Rig(base.image_size, base.sample_extent, base.cameras, base.lights, shots))


def build_rig(kind: str, point: str, photo: int) -> Rig:
    """The rig ``kind`` at size ``point``: N (flash), V (flash-multiview: V x V shots) or KxV (light-stage)."""
    size = (photo, photo)
    if kind == "flash":
        return flash_rig(int(point), size=size)
    if kind == "flash-multiview":
        return multiview_flash_rig(int(point), size=size)
    if kind == "light-stage":
        k, v = (int(x) for x in point.split("x"))
        return light_stage_rig(k, v, size=size)
    raise ValueError(f"unknown rig {kind!r}; expected one of {', '.join(RIGS)}")


def shot_angles(rig: Rig) -> np.ndarray:
    """(shots,) median angle in degrees between wi and wo over each shot's pixels that see the sample."""
    out = []
    for k in range(len(rig.shots)):
        g = pixel_geometry(rig, k)
        out.append(np.degrees(np.median(np.arccos(np.clip((g.wi * g.wo).sum(axis=1), -1.0, 1.0)))))
    return np.array(out)


# --- The verdict -------------------------------------------------------------------------------

def spread(values) -> float:
    """The seed range max - min of ``values``."""
    return float(np.max(values) - np.min(values))


def verdict(hybrid, other) -> str:
    """"better" / "worse" / "tie" for the hybrid's seed values against another model's, lower is
    better: the gap of the means counts only when it exceeds both seed ranges (max - min);
    fewer than two seeds on either side: "n/a" (no spread to compare with)."""
    hybrid, other = np.asarray(hybrid, dtype=float), np.asarray(other, dtype=float)
    if len(hybrid) < 2 or len(other) < 2:
        return "n/a"
    gap = float(other.mean() - hybrid.mean())
    if abs(gap) <= max(spread(hybrid), spread(other)):
        return "tie"
    return "better" if gap > 0 else "worse"


def verdict_lines(rows, hybrid: str = HYBRID, metrics=METRICS) -> list:
    """The verdict table from the per-seed rows: one line per (rig, noise, N), a word per other
    model and metric of ``metrics`` (``hybrid`` against each of OTHERS), then the counts."""
    groups = {}
    for r in rows:
        groups.setdefault((r["rig"], r["noise"], r["n"], r["point"]), {}).setdefault(r["model"], []).append(r)
    head = " | ".join(f"vs {o}: " + "/".join(label.split()[0] for _, label in metrics) for o in OTHERS)
    lines = [f"verdict table (hybrid = {hybrid}; lower is better; rule: a gap of seed means beyond both "
             f"models' seed ranges (max-min) counts, inside them a tie)",
             f"{'rig':16s} {'noise':5s} {'N':>4s} {'point':>6s} | {head}"]
    counts = {o: {"better": 0, "worse": 0, "tie": 0, "n/a": 0} for o in OTHERS}
    for (rig, noise, n, point), by in sorted(groups.items(), key=lambda kv: (RIGS.index(kv[0][0]), kv[0][1], kv[0][2])):
        cells = []
        for o in OTHERS:
            if hybrid not in by or o not in by:
                cells.append("not measured")
                continue
            if any(key not in r for key, _ in metrics for r in by[hybrid] + by[o]):
                cells.append("not measured")
                continue
            words = [verdict([r[key] for r in by[hybrid]], [r[key] for r in by[o]]) for key, _ in metrics]
            for w in words:
                counts[o][w] += 1
            cells.append("/".join(words))
        lines.append(f"{rig:16s} {noise:5s} {n:4d} {point:>6s} | " + " | ".join(f"{c:30s}" for c in cells))
    for o in OTHERS:
        lines.append(f"verdict counts, {hybrid} vs {o}: " + ", ".join(f"{w} {c}" for w, c in counts[o].items() if c))
    return lines


# --- The sweep ---------------------------------------------------------------------------------

def fitters(keys, steps: int, rows_per_texel):
    """{key: fit(obs, seed, shots)} of the models ``keys`` with the same budget, ``shots`` the
    capture's photographs (a fit function not in hybridbrdf.acquire: skipped, printed)."""
    out = {}
    for key in keys:
        label, held, fn_name, path = MODELS[key]
        fn = ac.find_fit(fn_name)
        if fn is None:
            print(f"model {key}: {fn_name} not in hybridbrdf.acquire; skipped", flush=True)
            continue
        kw = {**ac.budget(fn, steps, rows_per_texel), **EXTRA.get(key, {})}
        if path is None and key != "analytic":
            path = pathlib.Path(prior_path())
        model = () if path is None else (hb.load_model(str(path)),)
        out[key] = (lambda f, m, k: lambda obs, seed, shots: f(
            obs, *m, seed=seed, **{n: v(shots) if callable(v) else v for n, v in k.items()}))(fn, model, kw)
    return out


def scored_texels(weights: np.ndarray, count: int, seed: int) -> np.ndarray:
    """The texels a seed scores: ``count`` drawn with the seed (acquire_compare.sampled_texels: half
    pure, half mixed), or with ``count`` 0 every texel of the map, the same for every seed (so the
    seeds' spread is the capture's and the fit's, not the draw's)."""
    if count == 0:
        return np.arange(weights.shape[0] * weights.shape[1])
    return ac.sampled_texels(weights, count, seed=seed)


def isotropic_points(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """(N, 4) coordinates of direction pairs in which an isotropic, reciprocal BRDF's domain is
    Euclidean to first order: theta_h and the difference vector d with its azimuth folded to the
    first quadrant (phi_d -> -phi_d is isotropy's mirror, phi_d -> phi_d + pi reciprocity's swap).
    Near pairs differ by about the angle (radians) their half and difference vectors differ by."""
    h, d = half_diff_vectors(wi, wo)
    theta_h = np.arctan2(np.hypot(h[:, 0], h[:, 1]), h[:, 2])
    return np.stack([theta_h, np.abs(d[:, 0]), np.abs(d[:, 1]), d[:, 2]], axis=1)


def seen_pairs(obs, truth, degrees: float) -> np.ndarray:
    """(scored texels, pairs) bool: the metric pairs of each scored texel within ``degrees`` of a
    direction pair some photograph saw at that texel (:func:`isotropic_points`). What no
    photograph saw is the fit's extrapolation: its model's shape there, its prior's guess."""
    metric = isotropic_points(truth.wi, truth.wo)
    seen = np.zeros((len(truth.texels), len(metric)), dtype=bool)
    for s, t in enumerate(truth.texels):
        lo, hi = obs.offsets[t], obs.offsets[t + 1]
        if hi > lo:
            dist, _ = cKDTree(isotropic_points(obs.wi[lo:hi], obs.wo[lo:hi])).query(metric, k=1)
            seen[s] = dist <= np.radians(degrees)
    return seen


def split_errors(fit, truth, seen: np.ndarray) -> tuple:
    """(SMAPE (texels,), cMAE (texels,), split): each scored texel's errors over all its pairs, as
    acquire_compare.texel_errors gives them, and the medians over the texels of SMAPE and cMAE on
    their seen and unseen pairs (:data:`SPLIT_METRICS`; a texel without pairs of a kind is left out
    of that median), from one evaluation of the fit per texel."""
    out = {key: [] for key, _ in SPLIT_METRICS}
    s_err, c_err = np.empty(len(truth.texels)), np.empty(len(truth.texels))
    n = len(truth.wi)
    cos_i = truth.wi[:, 2:3]
    for s, t in enumerate(truth.texels):
        f = np.asarray(fit.eval(np.full(n, t, dtype=np.int64), truth.wi, truth.wo), dtype=np.float64)
        g = truth.at(s)
        terms = smape_terms(g, f)
        absolute = np.abs(np.maximum(g, 0.0) - np.maximum(f, 0.0)) * cos_i
        s_err[s], c_err[s] = terms.mean(), absolute.mean()
        for kind, mask in (("seen", seen[s]), ("unseen", ~seen[s])):
            out[f"smape_{kind}"].append(terms[mask].mean() if mask.any() else np.nan)
            out[f"cmae_{kind}"].append(absolute[mask].mean() if mask.any() else np.nan)
    split = {key: float(np.nanmedian(v)) if np.isfinite(v).any() else float("nan") for key, v in out.items()}
    return s_err, c_err, split


def points(args):
    """[(rig kind, size point)] of the run, in the order measured."""
    sizes = {"flash": args.flash_ns, "flash-multiview": args.views, "light-stage": args.stages}
    return [(kind, p) for kind in args.rig for p in sizes[kind]]


def measure(args, kind, point, noise, seed, truth, mixture, novel, fits):
    """Simulate one capture and fit and score every model: the rows of one (point, noise, seed)."""
    label, photons, read = noise
    rig = build_rig(kind, point, args.photo)
    capture_seed = zlib.crc32(f"{kind} {point} {label} {seed}".encode())
    cap = simulate(rig, mixture, NoiseModel(photons=photons, read_noise=read), light_jitter=args.jitter,
                   seed=capture_seed)
    size = (args.map, args.map)
    obs = texel_observations(rig, cap.photos, size)
    if not args.anisotropic:  # every model fits the same rows: turned about the normal (acquire/isotropy.py)
        obs = turned_about_normal(obs, seed)
    true_render, mask = novel
    seen = seen_pairs(obs, truth, args.seen_degrees)
    rows = []
    for key, fit_fn in fits.items():
        t0 = time.process_time()
        fit = fit_fn(obs, seed, len(rig.shots))
        cpu = time.process_time() - t0
        s_err, c_err, split = split_errors(fit, truth, seen)
        render = ac.relative_mae(ac.render_fit(fit, args.novel_rig, size, args.render_filter), true_render, mask)
        rows.append({"machine": args.machine, "rig": kind, "point": point, "n": len(rig.shots), "noise": label,
                     "photons": photons, "read_noise": read, "seed": seed, "capture_seed": capture_seed,
                     "model": key, "held_out": MODELS[key][1], "observations": int(len(obs.value)),
                     "fit_cpu_s": round(cpu, 2), "smape_median": float(np.median(s_err)),
                     "cmae_median": float(np.median(c_err)), "render": render, "steps": args.steps,
                     "photo": args.photo, "map": args.map, "texels": len(truth.texels), "pairs": args.pairs,
                     "render_filter": args.render_filter, "observation_model": footprint.MODEL,
                     "jitter": args.jitter, "isotropic": not args.anisotropic,
                     "seen_degrees": args.seen_degrees, "seen_share": float(seen.mean()),
                     **split})
    return rows


def ceiling_of(mixture: Mixture, references) -> Mixture:
    """The hybrid's ceiling on the sample: each layer's source replaced by ``references`` (one
    :class:`~hybridbrdf.model.file.HybridModel` per layer, its last material the layer's fit), the
    true weights kept. With the full-measurement fits (acquire_gap.reference: ``hbrdf add`` onto the
    held-out prior) it is what the model reaches where every direction is measured."""
    return Mixture([ModelMaterialSource(m, m.materials[-1]) for m in references], mixture.weights)


def ceiling_line(args, mixture: Mixture, truth, novel) -> str:
    """The ``--ceiling`` line: the scored texels' median SMAPE and cMAE and the re-render of
    :func:`ceiling_of` with the full-measurement fits (made once, then read from ``--refs``)."""
    import acquire_gap

    refs = [acquire_gap.reference(name.removesuffix(".bsdf"), pathlib.Path(args.shared), pathlib.Path(args.refs))
            for name in ac.LAYERS]
    fit = ac.CentreTruth(ceiling_of(mixture, refs), (args.map, args.map))
    s_err, c_err = ac.texel_errors(fit, truth)
    render = ac.relative_mae(ac.render_fit(fit, args.novel_rig, (args.map, args.map), args.render_filter), *novel)
    return (f"ceiling (each layer its full-measurement fit, hbrdf add onto the held-out prior, mixed by the true "
            f"weights): SMAPE median {np.median(s_err):.4f} cMAE median {np.median(c_err):.4f} re-render {render:.4f}")


def summary_line(kind, point, noise, model, rs, metrics=METRICS) -> str:
    """One point's model over its seeds: each metric of ``metrics``' mean and min-max."""
    cells = []
    for key, _ in metrics:
        v = np.array([r[key] for r in rs])
        cells.append(f"{v.mean():8.4f} [{v.min():.4f}-{v.max():.4f}]")
    cpu = np.mean([r["fit_cpu_s"] for r in rs])
    return f"{kind:16s} {point:>6s} {rs[0]['n']:4d} {noise:5s} {model:15s} {len(rs):2d} {cpu:6.1f} " + " ".join(cells)


def header(args, out, floor, fits):
    scored = (f"{args.texels} sampled texels per seed (half pure, half mixed, drawn with the seed)" if args.texels
              else "every texel scored (the same for every seed)")
    drawn = "noise, jitter, fit, texels" if args.texels else "noise, jitter, fit"
    out.line(f"acquire_verdict: {', '.join(ac.LAYERS)} under the disc/stripes masks, {args.map}x{args.map} texel map; "
             f"{args.photo}x{args.photo} photographs, light jitter {args.jitter} (rig units); {args.steps} Adam steps "
             f"per model, {args.rows_per_texel or 'every'} rows per texel per step; {scored} x {args.pairs} metric "
             f"pairs; seeds {args.seeds} ({drawn}); torch threads {torch.get_num_threads()}; machine {args.machine}")
    out.line("rigs: flash = flash_rig(N) (collocated slice); flash-multiview V = V phones, each flash photographed by "
             "all V (V x V shots); light-stage KxV = light_stage_rig(K, V)")
    out.line("noise: " + "; ".join(f"{l}: photons {p:g}, read noise {r:g}" for l, p, r in ac.NOISE))
    out.line(f"re-render: acquire_compare.novel_rig ({args.photo}x{args.photo}), maps read {args.render_filter}; rel. MAE "
             f"floor (truth at texel centres) {floor:.4f}; every fit's observation model {footprint.MODEL}; rows "
             f"{'as photographed' if args.anisotropic else 'turned about the normal'}")
    for key in fits:
        out.line(f"model {key}: {MODELS[key][0]}")
    out.line(f"each point's 'split' lines: " + ", ".join(label for _, label in SPLIT_METRICS) + f" (metric pairs within "
             f"{args.seen_degrees:g} deg of a pair photographed at the texel: seen; the share in parentheses)")
    out.line(f"{'rig':16s} {'point':>6s} {'N':>4s} {'noise':5s} {'model':15s} {'S':>2s} {'cpu s':>6s} "
             + " ".join(f"{label + ' mean [min-max]':>24s}" for _, label in METRICS))


def sweep(args) -> int:
    torch.set_num_threads(args.threads)
    t_start = time.perf_counter()
    size = (args.map, args.map)
    mixture = ac.sample_mixture(pathlib.Path(args.shared), args.map)
    truths = {s: ac.Truth(mixture, scored_texels(mixture.weights, args.texels, s), size, args.pairs) for s in args.seeds}
    args.novel_rig = ac.novel_rig(args.photo)
    novel = (radiance(args.novel_rig, 0, mixture), pixel_geometry(args.novel_rig, 0).mask)
    floor = ac.relative_mae(ac.render_fit(ac.CentreTruth(mixture, size), args.novel_rig, size, args.render_filter), *novel)
    fits = fitters(args.models, args.steps, args.rows_per_texel)
    out = ac.Output(args.out)
    header(args, out, floor, fits)
    if args.ceiling:
        out.line(ceiling_line(args, mixture, truths[args.seeds[0]], novel))
    rows = []
    for kind, point in points(args):
        for noise in ac.NOISE:
            got = []
            for seed in args.seeds:
                for r in measure(args, kind, point, noise, seed, truths[seed], mixture, novel, fits):
                    out.row(r)
                    got.append(r)
            for key in fits:
                out.line(summary_line(kind, point, noise[0], key, [r for r in got if r["model"] == key]))
            share = np.mean([r["seen_share"] for r in got])
            for key in fits:
                out.line(f"  split (seen {share:.0%}): "
                         + summary_line(kind, point, noise[0], key, [r for r in got if r["model"] == key], SPLIT_METRICS))
            rows += got
    for line in verdict_lines(rows, args.hybrid):
        out.line(line)
    out.line(f"by what the photographs saw (metric pairs within {args.seen_degrees:g} deg of a photographed pair at "
             f"the texel, in (theta_h, d) with phi_d folded; the rest unseen):")
    for line in verdict_lines(rows, args.hybrid, SPLIT_METRICS):
        out.line(line)
    out.line(f"total {time.perf_counter() - t_start:.0f} s wall")
    out.close()
    return 0


def parse(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rig", default=",".join(RIGS), help=f"comma-separated rigs, of {', '.join(RIGS)} (default all)")
    ap.add_argument("--flash-ns", default="8,32", help="flash rig photograph counts N (default 8,32)")
    ap.add_argument("--views", default="3,6", help="flash-multiview phone counts V, V x V shots each (default 3,6)")
    ap.add_argument("--stages", default="4x2,8x4,16x8", help="light-stage sizes KxV (default 4x2,8x4,16x8)")
    ap.add_argument("--seeds", type=int, default=3, help="seeds per point, 0..S-1 (default 3)")
    ap.add_argument("--models", default="analytic,hybrid_heldout,neural_heldout",
                    help=f"comma-separated, of {', '.join(MODELS)} (default the held-out three)")
    ap.add_argument("--hybrid", default=HYBRID,
                    help=f"the model the verdict judges against the others, of {', '.join(MODELS)} (default {HYBRID})")
    ap.add_argument("--steps", type=int, default=150, help="Adam steps per fit, the same for every model (default 150)")
    ap.add_argument("--rows-per-texel", type=int, default=ROWS_PER_TEXEL,
                    help=f"rows of each texel every step reads (default {ROWS_PER_TEXEL}; 0: every observation, the analytic "
                         "fit only: the fits on a prior refuse it)")
    ap.add_argument("--photo", type=int, default=48, help="photograph side in pixels (default 48)")
    ap.add_argument("--map", type=int, default=16, help="texel map side (= the weights map's; default 16)")
    ap.add_argument("--texels", type=int, default=0,
                    help="texels scored: 0 (the default) every texel of the map, the same for every seed; N > 0: N drawn "
                         "per seed, half pure, half mixed (the rule until 2026-11-30)")
    ap.add_argument("--pairs", type=int, default=2000, help="metric direction pairs per scored texel (default 2000)")
    ap.add_argument("--render-filter", choices=("bilinear", "nearest"), default="bilinear",
                    help="the re-render reads each fit's maps bilinearly (the default: as its textured material shows "
                         "them) or by nearest texel (the rule until 2026-11-30)")
    ap.add_argument("--observation-model", choices=("bilinear", "nearest"), default=footprint.MODEL,
                    help=f"every fit's observation model (acquire/footprint.py; default {footprint.MODEL}): a pixel as "
                         "its bilinear footprint shows the map, or credited to its cell's texel (until 2026-11-30)")
    ap.add_argument("--anisotropic", action="store_true",
                    help="every model fits the rows as photographed (the rule until 2026-11-30); default: each row "
                         "turned about the normal (acquire/isotropy.py), as hbrdf acquire fit does")
    ap.add_argument("--seen-degrees", type=float, default=5.0,
                    help="a metric pair counts as seen within this angle (degrees) of a pair photographed at its "
                         "texel, for the seen / unseen split of SMAPE and cMAE (default 5)")
    ap.add_argument("--jitter", type=float, default=0.001, help="light position jitter, rig units (default 0.001)")
    ap.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"), help="the shared data folder")
    ap.add_argument("--machine", default=ac.machine_key(), help="machine key of docs/BENCHMARKS.md (default: detected)")
    ap.add_argument("--out", help="write PREFIX.txt and PREFIX.jsonl (default results/acquire_verdict_MACHINE)")
    ap.add_argument("--ceiling", action="store_true",
                    help="also print the hybrid's ceiling: each layer its full-measurement fit (hbrdf add onto the "
                         "held-out prior), mixed by the true weights")
    ap.add_argument("--refs", default="/tmp/acquire_gap_refs",
                    help="folder caching the full-measurement fits of --ceiling (acquire_gap.py's)")
    ap.add_argument("--table", metavar="JSONL", help="only print the verdict table of a run's jsonl")
    args = ap.parse_args(argv)
    args.rig = args.rig.split(",")
    args.models = args.models.split(",")
    for name, given, known in (("--rig", args.rig, RIGS), ("--models", args.models, MODELS),
                               ("--hybrid", [args.hybrid], MODELS)):
        bad = [g for g in given if g not in known]
        if bad:
            ap.error(f"{name}: unknown {', '.join(bad)}; expected {', '.join(known)}")
    try:
        args.flash_ns = [str(int(v)) for v in args.flash_ns.split(",")]
        args.views = [str(int(v)) for v in args.views.split(",")]
        args.stages = [f"{int(k)}x{int(v)}" for k, v in (s.split("x") for s in args.stages.split(","))]
    except ValueError as e:
        ap.error(f"--flash-ns / --views / --stages: {e}")
    if args.seeds < 1:
        ap.error(f"--seeds must be at least 1, got {args.seeds}")
    args.seeds = list(range(args.seeds))
    args.rows_per_texel = args.rows_per_texel or None
    args.out = args.out or str(ROOT / "results" / f"acquire_verdict_{args.machine}")
    footprint.MODEL = args.observation_model
    return args


def table(jsonl: str, hybrid: str = HYBRID) -> int:
    """Print the verdict table of a run's rows, ``hybrid`` judged against the others."""
    rows = [json.loads(line) for line in open(jsonl) if line.strip()]
    for line in verdict_lines(rows, hybrid):
        print(line)
    if all(key in r for key, _ in SPLIT_METRICS for r in rows):
        for line in verdict_lines(rows, hybrid, SPLIT_METRICS):
            print(line)
    return 0


if __name__ == "__main__":
    ARGS = parse()
    sys.exit(table(ARGS.table, ARGS.hybrid) if ARGS.table else sweep(ARGS))
