#!/usr/bin/env python3
"""SVBRDF acquisition from sparse, noisy photographs: hybrid against analytic-only and neural-only
(issue 46 step 3; docs/ACQUISITION.md, docs/BENCHMARKS.md).

The sample is an exact mixture (acquire.mixture.Mixture) of three raw RGL measurements, the
soft disc and stripes of bench/svbrdf_mixture.py as masks (paper_white the base,
vch_golden_yellow the disc, cc_ibiza_sunset the stripes); the weights map is the texel map's
size, so edge texels are mixed. It is photographed by the phone-flash rig (acquire.rigs.flash_rig)
with N = 1, 2, 4, 8, 16, 32, 64 photographs at two noise levels, no light jitter, and every model
is fitted per texel to the same observations with the same number of Adam steps:

- analytic: f_a's p = (kd, eta, alpha) per texel (acquire.texel_fit.fit_analytic_texels);
- hybrid: p and z per texel on a frozen prior (fit_hybrid_texels), once on the prior that never
  saw the three measurements (results/prior132_minus_rgl5_32x2_l8_heads_20k) and once on the
  shipped prior, which did ("not held out");
- neural: a latent per texel on a neural baseline's network (fit_neural_texels), once on
  results/rgl44_heldout_neural_32x3_10k (44 NBRDF-RGL networks, never saw the three) and once on
  the issue's results/rgl54_neural_32x3_10k, which saw them ("not held out").

Errors against the truth over all directions, not only the photographed ones: for S sampled
texels (half pure, half mixed, fixed seed), --pairs cosine pairs each (CONVENTIONS' metric
directions), truth = the mixture at the texel centre's weights, fitted = the fit's eval at that
texel; per-texel SMAPE and cMAE (hybridbrdf.evaluate.metrics), median and 95th percentile over
the texels. And a re-render under a novel light and camera (light at 60 deg elevation, camera at
40 deg elevation on the opposite azimuth: a separated light and view no flash photograph has): the
truth rendered without noise (acquire.simulation.radiance) against each fit rendered with the same
pixel geometry, each pixel as the fit's textured material shows it (bilinear between texel
centres, as the simulator reads its weights map: :func:`render_fit`; nearest texel until
2026-11-30); error = mean |L_fit - L_true| / mean L_true over the pixels that see the sample and
the three channels (a relative MAE). The same error of the truth's own map at the fit's resolution
(:class:`CentreTruth`) is the floor (0 read bilinearly, 0.149 by nearest texel on the verdict's
sample).

    python bench/acquire_compare.py [--steps 400] [--rows-per-texel 8] [--pairs 100000] [--photo 128]
        [--map 32] [--texels 32] [--ns 1,2,4,8,16,32,64] [--out results/acquire_compare_MACHINE]
    python bench/acquire_compare.py --plot results/acquire_compare_X1.jsonl [--png docs/figures/acquire_compare.png]

A model whose fit function does not exist in hybridbrdf.acquire yet is skipped (printed).
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import json
import math
import os
import pathlib
import pkgutil
import sys
import time

import numpy as np
import torch

import hybridbrdf as hb
import hybridbrdf.acquire as acquire_pkg
from hybridbrdf.acquire.geometry import pixel_geometry
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.observations import texel_observations
from hybridbrdf.acquire.rig import Camera, Light, Rig, Shot, check_rig
from hybridbrdf.acquire.rigs import flash_rig
from hybridbrdf.acquire.simulation import radiance, simulate
from hybridbrdf.acquire.texel_rows import ROWS_PER_TEXEL
from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape
from hybridbrdf.model.prior import prior_path

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from svbrdf_mixture import masks  # noqa: E402

LAYERS = ("paper_white_rgb.bsdf", "vch_golden_yellow_rgb.bsdf", "cc_ibiza_sunset_rgb.bsdf")
HELD_OUT_PRIOR = ROOT / "results" / "prior132_minus_rgl5_32x2_l8_heads_20k.safetensors"
NEURAL = ROOT / "results" / "rgl54_neural_32x3_10k.safetensors"
HELD_OUT_NEURAL = ROOT / "results" / "rgl44_heldout_neural_32x3_10k.safetensors"
#: (hybrid, neural) pairs the verdict compares: both held out (the honest pair), both not held
#: out, and the issue's literal pair (the honest hybrid against the network that saw them).
PAIRS = (("hybrid_heldout", "neural_heldout"), ("hybrid_shipped", "neural"), ("hybrid_heldout", "neural"))
#: The two noise levels: (label, photons at radiance 1, read noise in electrons).
NOISE = (("low", 1e4, 2.0), ("high", 200.0, 4.0))
#: A texel is pure when one weight is above this.
PURE = 0.99
#: The claim's N ranges (issue 46): hybrid >= analytic at N <= SPARSE, >= neural at N >= DENSE.
SPARSE, DENSE = 4, 32
#: The verdict's metrics: jsonl key and label.
VERDICT_METRICS = (("smape_median", "SMAPE median"), ("cmae_median", "cMAE median"), ("render", "re-render rel. MAE"))


# --- The sample and the rigs -------------------------------------------------------------------

def sample_mixture(shared: pathlib.Path, size: int) -> Mixture:
    """The three RGL measurements under bench/svbrdf_mixture.py's disc and stripes, a size x size weights map."""
    sources = [hb.open_source(str(shared / "rgl" / name)) for name in LAYERS]
    return Mixture.painted(sources[0], sources[1:], masks(size))


def novel_rig(photo: int, extent=(0.1, 0.1), distance: float = 0.3,
              light_elevation_deg: float = 60.0, light_azimuth_deg: float = 30.0,
              camera_elevation_deg: float = 40.0, camera_azimuth_deg: float = 210.0) -> Rig:
    """One shot under a light and from a camera that no flash photograph has: the light at 60 deg
    elevation, the camera at 40 deg on the opposite azimuth (20 deg off the light's mirror
    direction, so the highlight's flank is in view), both at ``distance``; the flash rigs' field
    of view and intensity pi d^2."""

    def at(elevation, azimuth):
        e, a = math.radians(elevation), math.radians(azimuth)
        return distance * np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])

    fov = math.degrees(2 * math.atan(1.1 * 0.5 * math.hypot(*extent) / distance))
    cam = Camera(at(camera_elevation_deg, camera_azimuth_deg), np.zeros(3), np.array([0.0, 1.0, 0.0]), fov)
    light = Light(at(light_elevation_deg, light_azimuth_deg), np.full(3, math.pi * distance ** 2))
    return check_rig(Rig((photo, photo), tuple(extent), [cam], [light], [Shot(0, 0, "novel.exr")]))


def sampled_texels(weights: np.ndarray, count: int, seed: int = 0) -> np.ndarray:
    """``count`` texel indices (j * W + i) of the (H, W, K) weights map, half pure (one weight
    above PURE), half mixed, drawn without replacement with ``seed`` (the rest from the other
    kind where one kind has too few)."""
    flat = weights.reshape(-1, weights.shape[2])
    pure = np.nonzero(flat.max(axis=1) > PURE)[0]
    mixed = np.nonzero(flat.max(axis=1) <= PURE)[0]
    rng = np.random.default_rng(seed)
    n_mixed = min(len(mixed), count // 2)
    n_pure = min(len(pure), count - n_mixed)
    n_mixed = min(len(mixed), count - n_pure)
    return np.sort(np.concatenate([rng.choice(pure, n_pure, replace=False),
                                   rng.choice(mixed, n_mixed, replace=False)]))


def texel_centres(texels: np.ndarray, size) -> np.ndarray:
    """(S, 2) uv of the centres of texels j * W + i of a (W, H) map."""
    w, h = size
    j, i = np.divmod(np.asarray(texels), w)
    return np.stack([(i + 0.5) / w, (j + 0.5) / h], axis=1)


# --- Errors ------------------------------------------------------------------------------------

class Truth:
    """The mixture's values over the metric pairs at sampled texels' centres: each source is
    evaluated once over the pairs (negative measured values as 0, as Mixture.eval counts them)
    and combined by each texel's weights; the same for every N, noise level and model."""

    def __init__(self, mixture: Mixture, texels: np.ndarray, size, pairs: int):
        self.texels = np.asarray(texels, dtype=np.int64)
        self.wi, self.wo = metric_directions(pairs)
        self.weights = mixture.weights_at(texel_centres(self.texels, size))  # (S, K)
        self.values = [np.maximum(np.asarray(s.eval(self.wi, self.wo), dtype=np.float64), 0.0)
                       for s in mixture.sources]

    def at(self, s: int) -> np.ndarray:
        """(pairs, 3) the truth at sampled texel ``s`` (an index into ``texels``)."""
        w = self.weights[s]
        return sum(w[k] * self.values[k] for k in range(len(self.values)) if w[k] > 0)


def texel_errors(fit, truth: Truth):
    """(SMAPE, cMAE) arrays over the sampled texels of ``fit`` (``fit.eval(texel, wi, wo)``) against ``truth``."""
    n = len(truth.wi)
    s_err, c_err = np.empty(len(truth.texels)), np.empty(len(truth.texels))
    for s, t in enumerate(truth.texels):
        f = np.asarray(fit.eval(np.full(n, t, dtype=np.int64), truth.wi, truth.wo), dtype=np.float64)
        g = truth.at(s)
        s_err[s], c_err[s] = smape(g, f), cmae(g, f, truth.wi[:, 2])
    return s_err, c_err


def nearest_texels(uv: np.ndarray, size) -> np.ndarray:
    """Texel j * W + i whose cell holds each uv (M, 2), clamped to the map (texel_observations' rule)."""
    w, h = size
    i = np.clip(np.floor(uv[:, 0] * w).astype(np.int64), 0, w - 1)
    j = np.clip(np.floor(uv[:, 1] * h).astype(np.int64), 0, h - 1)
    return j * w + i


def render_fit(fit, rig: Rig, size, filter: str = "bilinear") -> np.ndarray:
    """The noiseless photograph of ``rig``'s shot 0 with ``fit`` as the sample: (H, W, 3),
    L = f cos(theta_i) I / d^2 as the simulator has it, each pixel's BRDF as the fit's textured
    material shows it at the pixel's uv (``bilinear``, ``fit.eval_uv``: how the simulator reads its
    weights map and an engine its textures) or from its nearest texel (``nearest``, the rule until
    2026-11-30: the truth at texel centres then renders 0.149 off, a floor every fit shared)."""
    geo = pixel_geometry(rig, 0)
    w, h = rig.image_size
    image = np.zeros((h, w, 3))
    if filter == "bilinear":
        f = fit.eval_uv(geo.uv, geo.wi, geo.wo)
    else:
        f = fit.eval(nearest_texels(geo.uv, size), geo.wi, geo.wo)
    cos_i = np.maximum(geo.wi[:, 2], 0.0)
    image[geo.mask] = np.asarray(f, dtype=np.float64) * (cos_i / geo.distance2)[:, None] * rig.lights[rig.shots[0].light].intensity
    return image


def relative_mae(image: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> float:
    """mean |image - reference| / mean reference over the pixels of ``mask`` and the channels."""
    return float(np.abs(image[mask] - reference[mask]).mean() / reference[mask].mean())


class CentreTruth:
    """The truth as a per-texel map: texel t's BRDF is the mixture at t's centre weights (the
    best any per-texel fit can be; its re-render error is the floor of :func:`render_fit`'s filter)."""

    def __init__(self, mixture: Mixture, size):
        self.mixture, self.size = mixture, size

    def eval(self, texel, wi, wo):
        uv = texel_centres(texel, self.size)
        return self.mixture.eval(uv, wi, wo)

    def eval_uv(self, uv, wi, wo):
        """The mixture itself: its weights map is read bilinearly between the same texel centres."""
        return self.mixture.eval(uv, wi, wo)


# --- The fits ----------------------------------------------------------------------------------

def find_fit(name: str):
    """The function ``name`` in any module of hybridbrdf.acquire, or None (not built yet)."""
    for info in pkgutil.iter_modules(acquire_pkg.__path__):
        if info.name == "command":
            continue
        try:  # a fit module mid-edit elsewhere must not stop the models that exist
            module = importlib.import_module(f"hybridbrdf.acquire.{info.name}")
        except Exception as e:  # noqa: BLE001
            print(f"hybridbrdf.acquire.{info.name} does not import ({type(e).__name__}: {e}); skipped", flush=True)
            continue
        if callable(getattr(module, name, None)):
            return getattr(module, name)
    return None


def budget(fn, steps: int, rows_per_texel):
    """``fn``'s keyword arguments for the shared budget: ``steps`` Adam steps, each reading
    ``rows_per_texel`` rows per texel (passed where the fit takes it)."""
    kw = {"steps": steps}
    if "rows_per_texel" in inspect.signature(fn).parameters:
        kw["rows_per_texel"] = rows_per_texel
    return kw


def models(steps: int, rows_per_texel):
    """[(key, label, held_out, fit(obs) or None)]: the comparison's models with the same budget."""
    analytic, hybrid, neural = (find_fit(n) for n in ("fit_analytic_texels", "fit_hybrid_texels", "fit_neural_texels"))
    out = [("analytic", "analytic only (f_a p per texel)", True,
            (lambda obs: analytic(obs, **budget(analytic, steps, rows_per_texel))) if analytic else None)]
    for key, label, path, held in (("hybrid_heldout", "hybrid, prior that never saw them", HELD_OUT_PRIOR, True),
                                   ("hybrid_shipped", "hybrid, shipped prior (not held out)", pathlib.Path(prior_path()), False)):
        fn = None
        if hybrid:
            model = hb.load_model(str(path))
            fn = (lambda m: lambda obs: hybrid(obs, m, seed=0, **budget(hybrid, steps, rows_per_texel)))(model)
        out.append((key, label, held, fn))
    for key, label, path, held in (("neural_heldout", "neural only, rgl44_heldout_neural_32x3 (never saw them)",
                                    HELD_OUT_NEURAL, True),
                                   ("neural", "neural only, rgl54_neural_32x3 (not held out)", NEURAL, False)):
        fn = None
        if neural:
            net = hb.load_model(str(path))
            fn = (lambda m: lambda obs: neural(obs, m, seed=0, **budget(neural, steps, rows_per_texel)))(net)
        out.append((key, label, held, fn))
    return out


# --- The sweep ---------------------------------------------------------------------------------

def machine_key() -> str:
    """X1 on the Intel Xeon family 6 model 167 with AVX-512 (docs/BENCHMARKS.md "Machines"), else 'local'."""
    try:
        text = pathlib.Path("/proc/cpuinfo").read_text()
    except OSError:
        return "local"
    family = "cpu family\t: 6" in text
    model = any(line.split(":")[1].strip() == "167" for line in text.splitlines() if line.startswith("model\t"))
    return "X1" if family and model and "avx512f" in text else "local"


class Output:
    """The table (PREFIX.txt) and rows (PREFIX.jsonl) written to temporaries beside the targets,
    flushed row by row (a run cut short leaves its rows in the .partial files) and renamed into
    place at the end."""

    def __init__(self, prefix: str):
        self.targets = [prefix + ".txt", prefix + ".jsonl"]
        os.makedirs(os.path.dirname(os.path.abspath(prefix)), exist_ok=True)
        self.files = [open(t + ".partial", "w") for t in self.targets]

    def line(self, text: str = ""):
        print(text, flush=True)
        self.files[0].write(text + "\n")
        self.files[0].flush()

    def row(self, row: dict):
        self.files[1].write(json.dumps(row) + "\n")
        self.files[1].flush()

    def close(self):
        for f, t in zip(self.files, self.targets):
            f.flush()
            os.fsync(f.fileno())
            f.close()
            os.replace(t + ".partial", t)


def verdicts(rows, hybrid_key: str = "hybrid_heldout", neural_key: str = "neural_heldout"):
    """Lines of the claim's three conditions per noise level and metric, from ``rows`` (the
    jsonl's dicts): (a) hybrid <= analytic at every N <= SPARSE, (b) hybrid <= neural at every
    N >= DENSE, (c) hybrid strictly below both at some N between; the claim holds when all three do."""
    by = {(r["noise"], r["model"], r["n"]): r for r in rows}
    ns = sorted({r["n"] for r in rows})
    lines = []
    for noise in [n for n, *_ in NOISE if any(r["noise"] == n for r in rows)]:
        for key, label in VERDICT_METRICS:
            def compare(n, others):
                """(hybrid below or equal to every other, hybrid strictly below every other, text), or None."""
                h, o = by.get((noise, hybrid_key, n)), [by.get((noise, m, n)) for m in others]
                if h is None or None in o:
                    return None
                h, o = h[key], [r[key] for r in o]
                return all(h <= x for x in o), all(h < x for x in o), f"N={n} {h:.4g} vs {'/'.join(f'{x:.4g}' for x in o)}"

            def over(range_ns, others, quantifier, strict):
                """quantifier (all or any) of the comparisons at range_ns: hybrid <= others (strict: <)."""
                got = [compare(n, others) for n in range_ns]
                if not got or None in got:
                    return None, "not measured"
                ok = quantifier(g[1] if strict else g[0] for g in got)
                return ok, ("yes" if ok else "no") + " (" + "; ".join(g[2] for g in got) + ")"

            a = over([n for n in ns if n <= SPARSE], ["analytic"], all, False)
            b = over([n for n in ns if n >= DENSE], [neural_key], all, False)
            c = over([n for n in ns if SPARSE < n < DENSE], ["analytic", neural_key], any, True)
            holds = "not measured" if None in (a[0], b[0], c[0]) else ("HOLDS" if a[0] and b[0] and c[0] else "FAILS")
            lines.append(f"verdict {noise} noise, {hybrid_key} vs {neural_key}, {label}: claim {holds}; "
                         f"(a) hybrid <= analytic at N <= {SPARSE}: {a[1]}; (b) hybrid <= neural at N >= {DENSE}: "
                         f"{b[1]}; (c) hybrid below analytic/neural at some {SPARSE} < N < {DENSE}: {c[1]}")
    return lines


def sweep(args) -> int:
    torch.set_num_threads(args.threads)
    t_start = time.perf_counter()
    size = (args.map, args.map)
    mixture = sample_mixture(pathlib.Path(args.shared), args.map)
    texels = sampled_texels(mixture.weights, args.texels)
    n_pure = int((mixture.weights.reshape(-1, 3)[texels].max(axis=1) > PURE).sum())
    truth = Truth(mixture, texels, size, args.pairs)
    novel = novel_rig(args.photo)
    true_render = radiance(novel, 0, mixture)
    mask = pixel_geometry(novel, 0).mask
    floor = relative_mae(render_fit(CentreTruth(mixture, size), novel, size), true_render, mask)
    todo = models(args.steps, args.rows_per_texel)
    out = Output(args.out)
    out.line(f"acquire_compare: {', '.join(LAYERS)} under the disc/stripes masks, {args.map}x{args.map} texel map "
             f"(= the weights map; {int((mixture.weights.max(axis=2) <= PURE).sum())} of {args.map ** 2} texels mixed); "
             f"flash rig, {args.photo}x{args.photo} photographs, no light jitter; {args.steps} Adam steps per model, "
             f"{args.rows_per_texel or 'every'} rows per texel per step; "
             f"{len(texels)} sampled texels ({n_pure} pure, {len(texels) - n_pure} mixed, seed 0), {args.pairs} metric pairs each; "
             f"torch threads {torch.get_num_threads()}; machine {args.machine}")
    out.line(f"noise: " + "; ".join(f"{l}: photons {p:g}, read noise {r:g}" for l, p, r in NOISE))
    out.line(f"re-render: light at 60 deg elevation (azimuth 30), camera at 40 deg (azimuth 210), {args.photo}x{args.photo}; "
             f"rel. MAE = mean |L_fit - L_true| / mean L_true; floor (truth at texel centres, nearest) {floor:.4f}")
    for key, label, held, fn in todo:
        out.line(f"model {key}: {label}" + ("" if fn else "  -- SKIPPED: its fit function is not in hybridbrdf.acquire yet"))
    out.line(f"{'noise':5s} {'N':>3s} {'obs':>7s} {'model':15s} {'fit s':>7s} {'SMAPE med':>9s} {'p95':>7s} "
             f"{'cMAE med':>9s} {'p95':>8s} {'render':>7s}")
    rows = []
    for noise_label, photons, read in NOISE:
        for n in args.ns:
            rig = flash_rig(n, size=(args.photo, args.photo))
            cap = simulate(rig, mixture, NoiseModel(photons=photons, read_noise=read), light_jitter=0.0,
                           seed=1000 * (noise_label == "high") + n)
            obs = texel_observations(rig, cap.photos, size)
            for key, label, held, fn in todo:
                if fn is None:
                    continue
                t0 = time.perf_counter()
                fit = fn(obs)
                fit_s = time.perf_counter() - t0
                s_err, c_err = texel_errors(fit, truth)
                render = relative_mae(render_fit(fit, novel, size), true_render, mask)
                row = {"machine": args.machine, "noise": noise_label, "photons": photons, "read_noise": read, "n": n,
                       "observations": int(len(obs.value)), "model": key, "label": label, "held_out": held,
                       "steps": args.steps, "rows_per_texel": args.rows_per_texel, "fit_s": round(fit_s, 2), "texels": len(texels), "pairs": args.pairs,
                       "smape_median": float(np.median(s_err)), "smape_p95": float(np.percentile(s_err, 95)),
                       "cmae_median": float(np.median(c_err)), "cmae_p95": float(np.percentile(c_err, 95)),
                       "render": render, "render_floor": floor, "photo": args.photo, "map": args.map}
                rows.append(row)
                out.row(row)
                out.line(f"{noise_label:5s} {n:3d} {row['observations']:7d} {key:15s} {fit_s:7.1f} "
                         f"{row['smape_median']:9.4f} {row['smape_p95']:7.4f} {row['cmae_median']:9.5f} "
                         f"{row['cmae_p95']:8.5f} {render:7.4f}")
    for hybrid_key, neural_key in PAIRS:
        for line in verdicts(rows, hybrid_key, neural_key):
            out.line(line)
    out.line(f"total {time.perf_counter() - t_start:.0f} s")
    out.close()
    return 0


# --- The figure --------------------------------------------------------------------------------

STYLE = {"analytic": ("tab:blue", "o", "-"), "hybrid_heldout": ("tab:red", "s", "-"),
         "hybrid_shipped": ("tab:red", "s", "--"), "neural_heldout": ("tab:green", "^", "-"),
         "neural": ("tab:green", "^", "--")}


def plot(jsonl: str, png: str) -> int:
    """Error against N (log2 axis): rows SMAPE / cMAE (median solid, p95 faint) and the re-render,
    one column per noise level; the four fits."""
    import matplotlib  # noqa: PLC0415 (bench script: only --plot needs it)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    rows = [json.loads(line) for line in open(jsonl) if line.strip()]
    noises = [n for n, *_ in NOISE if any(r["noise"] == n for r in rows)]
    metrics = (("smape", "per-texel SMAPE"), ("cmae", "per-texel cMAE"), ("render", "re-render rel. MAE"))
    fig, axes = plt.subplots(len(metrics), len(noises), figsize=(5.2 * len(noises), 3.4 * len(metrics)), squeeze=False)
    for col, noise in enumerate(noises):
        level = next(r for r in rows if r["noise"] == noise)
        for row_i, (metric, title) in enumerate(metrics):
            ax = axes[row_i][col]
            for key, (colour, marker, ls) in STYLE.items():
                rs = sorted((r for r in rows if r["noise"] == noise and r["model"] == key), key=lambda r: r["n"])
                if not rs:
                    continue
                ns = [r["n"] for r in rs]
                label = rs[0]["label"]
                if metric == "render":
                    ax.plot(ns, [r["render"] for r in rs], ls=ls, marker=marker, color=colour, label=label)
                else:
                    ax.plot(ns, [r[f"{metric}_median"] for r in rs], ls=ls, marker=marker, color=colour,
                            label=f"{label}, median")
                    ax.plot(ns, [r[f"{metric}_p95"] for r in rs], ls=ls, marker=marker, color=colour, alpha=0.3,
                            markersize=3, label=f"p95" if key == "analytic" else None)
            if metric == "render":
                ax.axhline(level["render_floor"], color="grey", lw=0.8, ls=":", label="per-texel floor")
            ax.set_xscale("log", base=2)
            ax.set_xticks(sorted({r["n"] for r in rows}), [str(n) for n in sorted({r["n"] for r in rows})])
            ax.set_yscale("log")
            ax.set_xlabel("photographs N")
            ax.set_title(f"{title}, {noise} noise (photons {level['photons']:g}, read {level['read_noise']:g})",
                         fontsize=9)
            ax.grid(alpha=0.3, which="both")
    handles, labels = axes[0][0].get_legend_handles_labels()
    h2, l2 = axes[-1][0].get_legend_handles_labels()
    fig.legend(handles + h2[-1:], labels + l2[-1:], loc="lower center", ncol=3, fontsize=7)
    r0 = rows[0]
    fig.suptitle(f"Acquisition from N flash photographs ({r0['photo']}x{r0['photo']} onto {r0['map']}x{r0['map']} texels, "
                 f"{r0['steps']} steps each; {r0['texels']} texels x {r0['pairs']} pairs; machine {r0['machine']})",
                 fontsize=9)
    fig.tight_layout(rect=(0, 0.06, 1, 0.98))
    tmp = png + ".partial.png"
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, png)
    print(f"wrote {png}")
    for hybrid_key, neural_key in PAIRS:
        for line in verdicts(rows, hybrid_key, neural_key):
            print(line)
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=400, help="Adam steps per fit, the same for every model (default 400)")
    ap.add_argument("--rows-per-texel", type=int, default=ROWS_PER_TEXEL,
                    help=f"rows of each texel every step of every fit reads (default {ROWS_PER_TEXEL}; 0: every "
                         "observation, the analytic fit only: the fits on a prior refuse it)")
    ap.add_argument("--pairs", type=int, default=100_000, help="metric direction pairs per sampled texel (default 10^5)")
    ap.add_argument("--texels", type=int, default=32, help="sampled texels, half pure, half mixed (default 32)")
    ap.add_argument("--photo", type=int, default=128, help="photograph side in pixels (default 128)")
    ap.add_argument("--map", type=int, default=32, help="texel map side (= the weights map's; default 32)")
    ap.add_argument("--ns", default="1,2,4,8,16,32,64", help="photograph counts N, comma-separated")
    ap.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"), help="the shared data folder")
    ap.add_argument("--machine", default=machine_key(), help="machine key of docs/BENCHMARKS.md (default: detected)")
    ap.add_argument("--out", help="write PREFIX.txt and PREFIX.jsonl (default results/acquire_compare_MACHINE)")
    ap.add_argument("--plot", metavar="JSONL", help="only draw the figure from a sweep's jsonl and print its verdicts")
    ap.add_argument("--png", default=str(ROOT / "docs" / "figures" / "acquire_compare.png"), help="the figure (--plot)")
    args = ap.parse_args()
    if args.plot:
        return plot(args.plot, args.png)
    args.ns = [int(v) for v in args.ns.split(",")]
    args.rows_per_texel = args.rows_per_texel or None
    args.out = args.out or str(ROOT / "results" / f"acquire_compare_{args.machine}")
    return sweep(args)


if __name__ == "__main__":
    sys.exit(main())
