#!/usr/bin/env python3
"""Mip chains of a textured material against the exact mean BRDF of each footprint (issue 58;
docs/SVBRDF.md, "Mip chains").

A 512x512 material of three real measurements' materials of `results/rgl54_fast.safetensors`
(paper_white base, vch_golden_yellow in a soft disc, ilm_l3_37_metallic in diagonal stripes 32
texels apart), with maps that vary at every scale (multi-octave value noise): kd of the base,
alpha of the disc's layer, eta and the latent code z of the stripes' layer. One variant per
quantity (the weights map plus that quantity's map) and one with every map. For each, the chain
is built (`SVBRDF.with_mips`, float32 EXR so that storage adds nothing) and, at 4x, 16x and 64x
minification (levels 2, 4, 6), every level texel of a random sample (at most --footprints) is
compared with the mean over its footprint of the level-0 texels' BRDFs (libhybridbrdf, batched,
nearest texel: 4^L texels each, the same --pairs cosine-weighted direction pairs). Printed:
median and p95 over footprints of SMAPE and cMAE (CONVENTIONS), per quantity, and the alpha map's
three rules (perceptual: the chain's; value: plain averaging of alpha; mean_square: Toksvig/LEAN's
second moment) and a fitted rule (each level texel's alpha, Fresnel amplitude and kd fitted to
its footprint's mean f_a: `fit_lobe`). First, f_a alone: one GGX lobe of each rule's alpha
against the mean of lobes of several alphas; then what the best single lobe of 1, 2 or 3 fitted
quantities reaches (fitted on the metric's own pairs: what no rule of those quantities can beat)
and the fitted rule (fitted on other pairs, as a chain would be).

    python bench/svbrdf_mips.py [--model results/rgl54_fast.safetensors] [--pairs 500]
        [--footprints 256] [--size 512] [--out DIR] [--lobes-only] [--alpha-only]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import tempfile
import time

import numpy as np
from scipy.optimize import minimize

import hybridbrdf as hb
from hybridbrdf.brdf.microfacet import fresnel_dielectric, ggx_microfacet
from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape
from hybridbrdf.fit.painting import composite
from hybridbrdf.svbrdf import SVBRDF, load_svbrdf

ROOT = pathlib.Path(__file__).resolve().parents[1]
LAYERS = ["paper_white_rgb.rgl", "vch_golden_yellow_rgb.rgl", "ilm_l3_37_metallic_rgb"]
LEVELS = (2, 4, 6)


def smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0, 1)
    return t * t * (3 - 2 * t)


def value_noise(rng, size, octaves=6):
    """Sum of bilinearly upsampled random grids from 4x4 to size/2 cells, in [0, 1]: variation at
    every scale the chain filters."""
    out = np.zeros((size, size))
    total = 0.0
    for o in range(octaves):
        cells = 4 << o
        grid = rng.uniform(size=(cells + 1, cells + 1))
        x = np.linspace(0, cells, size, endpoint=False) + 0.5 * cells / size
        i, f = np.floor(x).astype(int), x - np.floor(x)
        rows = grid[i] * (1 - f)[:, None] + grid[i + 1] * f[:, None]
        out += 0.5 ** o * (rows[:, i] * (1 - f)[None, :] + rows[:, i + 1] * f[None, :])
        total += 0.5 ** o
    out /= total
    return (out - out.min()) / (out.max() - out.min())


def material(model, size, rng):
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    disc = 1 - smoothstep(0.26, 0.30, np.hypot(x - 0.4, y - 0.5))
    stripes = smoothstep(-0.3, 0.3, np.sin(2 * np.pi * (x + y) * size / 32))
    weights = np.concatenate([composite([disc, stripes]), np.zeros((size, size, 1))], axis=2).astype(np.float32)
    t = model.tensors
    i = [model.index(n) for n in LAYERS]
    maps = {"kd": (0, (t["materials.kd"][i[0]] * (0.25 + 0.75 * value_noise(rng, size))[..., None]).clip(0, 1)),
            "alpha": (1, (t["materials.alpha"][i[1]] * np.exp2(3 * value_noise(rng, size) - 1.5)[..., None]).clip(1e-4, 1)),
            "eta": (2, (t["materials.eta"][i[2]] * (0.8 + 0.4 * value_noise(rng, size))[..., None]).clip(1, 10)),
            "latent": (2, t["materials.z"][i[2]] + 0.5 * (np.stack([value_noise(rng, size) for _ in range(t["materials.z"].shape[1])],
                                                                  axis=2) - 0.5))}
    return weights, {q: (k, v.astype(np.float32)) for q, (k, v) in maps.items()}


def footprint_errors(core, size, wi, wo, cos_i, levels, picks):
    """Per level, [(smape, cmae)] of the level's texels in `picks[level]` against their footprints'
    mean level-0 BRDF (level-0 texels evaluated once, a band of rows at a time)."""
    P = len(wi)
    w32, o32 = wi.astype(np.float32), wo.astype(np.float32)
    top = max(levels)
    band = 1 << top  # rows of level 0 under one row of the coarsest level
    sums = {L: {} for L in levels}
    for r0 in range(0, size, band):
        ys, xs = np.mgrid[r0:r0 + band, 0:size]
        need = np.zeros(ys.shape, bool)
        for L in levels:
            for (col, row) in picks[L]:
                if (row << L) // band * band == r0:
                    need[(row << L) - r0:((row + 1) << L) - r0, col << L:(col + 1) << L] = True
        if not need.any():
            continue
        ty, tx = ys[need], xs[need]
        uv = np.repeat(np.stack([(tx + 0.5) / size, (ty + 0.5) / size], axis=1), P, axis=0).astype(np.float32)
        f = core.eval(uv, np.tile(w32, (len(tx), 1)), np.tile(o32, (len(tx), 1)), "nearest", batched=True)
        f = f.reshape(len(tx), P, 3).astype(np.float64)
        for L in levels:
            for (col, row) in picks[L]:
                inside = ((ty >> L) == row) & ((tx >> L) == col)
                if inside.any():
                    sums[L][(col, row)] = sums[L].get((col, row), 0.0) + f[inside].sum(axis=0)
    out = {}
    for L in levels:
        if not picks[L]:
            out[L] = []
            continue
        n = 4 ** L
        side = size >> L
        cols = np.array([c for c, _ in picks[L]]), np.array([r for _, r in picks[L]])
        uv = np.repeat(np.stack([(cols[0] + 0.5) / side, (cols[1] + 0.5) / side], axis=1), P, axis=0).astype(np.float32)
        lod = np.full(len(uv), float(L), np.float32)
        g = core.eval(uv, np.tile(w32, (len(cols[0]), 1)), np.tile(o32, (len(cols[0]), 1)), "bilinear", batched=True, lod=lod)
        g = g.reshape(len(cols[0]), P, 3).astype(np.float64)
        out[L] = [(smape(sums[L][fp] / n, g[j]), cmae(sums[L][fp] / n, g[j], cos_i)) for j, fp in enumerate(picks[L])]
    return out


def one_lobe(wi, wo, kd, eta, alpha):
    """f_a (N, C) of one texel (kd, eta (C,), isotropic alpha), float64."""
    lobe, c = ggx_microfacet(wi, wo, alpha, alpha)
    return np.asarray(kd, np.float64) / np.pi + fresnel_dielectric(c, np.asarray(eta, np.float64)) * lobe[:, None]


def f0(eta):
    """Fresnel reflectance at normal incidence of a dielectric of index eta."""
    return ((eta - 1) / (eta + 1)) ** 2


def fit_lobe(target, wi, wo, kd, eta, alpha0, free=("alpha", "eta", "kd"), objective="cmae"):
    """(alpha, eta (C,), kd (C,)) of the one f_a lobe nearest ``target`` (N, C) on (wi, wo) in
    ``objective`` ('cmae' or 'smape'), starting from (kd, eta, alpha0): Nelder-Mead over the
    ``free`` quantities, each one number for all channels: log alpha; log of a factor on F0 (each
    channel's eta from its F0 times it, so that the lobe's amplitude scales and its Fresnel curve
    stays a dielectric's); a kd offset."""
    kd, eta = np.asarray(kd, np.float64), np.asarray(eta, np.float64)
    cos_i = wi[:, 2:3]

    def unpack(x):
        it = iter(x)
        a = float(np.clip(np.exp(next(it)), 1e-4, 1)) if "alpha" in free else alpha0
        e = eta
        if "eta" in free:
            r = np.sqrt(np.clip(f0(eta) * np.exp(next(it)), 0, f0(10.0)))
            e = (1 + r) / (1 - r)
        k = np.clip(kd + next(it), 0, 1) if "kd" in free else kd
        return a, e, k

    def cost(x):
        a, e, k = unpack(x)
        g = one_lobe(wi, wo, k, e, a)
        return smape(target, g) if objective == "smape" else float(np.mean(np.abs(g - target) * cos_i))
    best = None
    for s in (1.0, 0.5, 0.25):
        x0 = ([np.log(alpha0 * s)] if "alpha" in free else []) + [0.0] * (("eta" in free) + ("kd" in free))
        r = minimize(cost, x0, method="Nelder-Mead", options=dict(xatol=1e-4, fatol=1e-10, maxiter=1500))
        if best is None or r.fun < best.fun:
            best = r
        if "alpha" not in free:
            break
    return unpack(best.x)


def fitted_lobes(cases, f, wi, wo, cos_i):
    """The lobe table's second part: per case, against averaging alpha by value, the best lobe of
    each set of fitted quantities on the metric's own pairs, and the fitted rule (fit on 20,000
    other pairs, seed 7)."""
    fwi, fwo = metric_directions(20_000, 7)
    sets = {"alpha": ("alpha",), "alpha, eta": ("alpha", "eta"), "alpha, kd": ("alpha", "kd"),
            "alpha, eta, kd": ("alpha", "eta", "kd"), "same, SMAPE fit": ("alpha", "eta", "kd")}
    print("Fitted lobes: cMAE / SMAPE of the best lobe of the fitted quantities (in cMAE; the last in SMAPE), as a "
          "ratio to averaging alpha by value (fitted on the metric's pairs: a bound for every rule); the fitted rule: "
          "fitted in cMAE on other pairs")
    print(f"{'alphas':28s} {'value':>18s} " + " ".join(f"{k:>15s}" for k in sets) + f" {'fitted rule':>15s}"
          + "  (its alpha, eta, kd)")
    for name, alphas in cases:
        alphas = np.asarray(alphas, np.float64)
        ref = np.mean([f(wi, wo, a) for a in alphas], axis=0)
        v = f(wi, wo, alphas.mean())
        base = cmae(ref, v, cos_i), smape(ref, v)
        cells = []
        for key, free in sets.items():
            a, e, k = fit_lobe(ref, wi, wo, [0.1], [1.5], alphas.mean(), free, "smape" if "SMAPE" in key else "cmae")
            g = one_lobe(wi, wo, k, e, a)
            cells.append(f"{cmae(ref, g, cos_i) / base[0]:.2f} / {smape(ref, g) / base[1]:.2f}")
        a, e, k = fit_lobe(np.mean([f(fwi, fwo, x) for x in alphas], axis=0), fwi, fwo, [0.1], [1.5], alphas.mean())
        g = one_lobe(wi, wo, k, e, a)
        cells.append(f"{cmae(ref, g, cos_i) / base[0]:.2f} / {smape(ref, g) / base[1]:.2f}")
        print(f"{name:28s} {f'{base[0]:.5f} ({base[1]:.4f})':>18s} " + " ".join(f"{c:>15s}" for c in cells)
              + f"  ({a:.3f}, {e[0]:.3f}, {k[0]:.4f})", flush=True)


def lobe_mixtures(pairs: int = 100_000):
    """f_a alone (kd 0.1, eta 1.5): the mean of GGX lobes of several alphas against one lobe of each
    rule's alpha, and against the best single alpha on a grid (what no rule can beat)."""
    import torch

    from hybridbrdf.brdf.torch_brdf import eval_analytic

    wi, wo = metric_directions(pairs, 3)
    cos_i = wi[:, 2]
    w64 = [torch.as_tensor(np.asarray(a), dtype=torch.float64) for a in (wi, wo)]
    n = len(wi)

    def f(a):
        full = lambda v, c: torch.full((n, c), v, dtype=torch.float64)  # noqa: E731
        return eval_analytic(*w64, full(0.1, 3), full(1.5, 3), full(float(a), 2)).numpy()

    rules = {"perceptual": lambda a: np.mean(np.sqrt(a)) ** 2, "value": np.mean,
             "mean_square": lambda a: np.sqrt(np.mean(a * a))}
    rng = np.random.default_rng(0)
    cases = [("0.05 | 0.5", [0.05, 0.5]), ("0.2 | 0.3", [0.2, 0.3]), ("0.02 | 0.1", [0.02, 0.1]),
             ("0.3 | 0.6", [0.3, 0.6]), ("16 of U(0.05, 0.4)", rng.uniform(0.05, 0.4, 16)),
             ("64 log-normal around 0.15", np.exp(rng.normal(np.log(0.15), 0.5, 64)).clip(1e-3, 1))]
    print("GGX lobes alone (f_a, kd 0.1, eta 1.5): cMAE (SMAPE) of one lobe against the mean of the lobes")
    print(f"{'alphas':28s} " + " ".join(f"{r:>18s}" for r in rules) + f" {'best single alpha':>26s}")
    for name, alphas in cases:
        alphas = np.asarray(alphas, np.float64)
        ref = np.mean([f(a) for a in alphas], axis=0)
        cells = [f"{cmae(ref, f(r(alphas)), cos_i):.5f} ({smape(ref, f(r(alphas))):.4f})" for r in rules.values()]
        grid = np.linspace(alphas.min(), alphas.max(), 41)
        errs = [cmae(ref, f(g), cos_i) for g in grid]
        best = int(np.argmin(errs))
        print(f"{name:28s} " + " ".join(f"{c:>18s}" for c in cells) + f" {errs[best]:.5f} at {grid[best]:.3f}".rjust(27))
    fitted_lobes(cases, lambda wi_, wo_, a: one_lobe(wi_, wo_, [0.1], [1.5], a), wi, wo, cos_i)


def footprint_mean(wi, wo, kd, eta, alpha, w):
    """(N, C) mean of the f_a of texels (kd, eta, alpha[t]) weighted by w[t], on (wi, wo)."""
    n, total = len(wi), 0.0
    for j in range(0, len(alpha), 64):  # 64 texels' lobes at a time
        a = np.repeat(alpha[j:j + 64], n)
        lobe, c = ggx_microfacet(np.tile(wi, (len(a) // n, 1)), np.tile(wo, (len(a) // n, 1)), a, a)
        total = total + (w[j:j + 64, None] * lobe.reshape(-1, n)).sum(axis=0)
    return kd / np.pi + fresnel_dielectric(c[:n], eta) * (total / w.sum())[:, None]


def footprint_bounds(model, weights, alpha, layer, picks, level, pairs=20_000):
    """The material's own footprints at ``level`` (``picks``), f_a of ``layer`` alone: the best
    lobe of (alpha, eta, kd) fitted in cMAE and in SMAPE on the metric's pairs (seed 5) themselves,
    each as a ratio (cMAE / SMAPE) to averaging alpha by value: what no rule for a texel can beat."""
    t, i = model.tensors, model.index(LAYERS[layer])
    kd, eta = (np.asarray(t[f"materials.{q}"][i], np.float64) for q in ("kd", "eta"))
    w = np.concatenate([1 - weights[..., :2].sum(axis=2, keepdims=True), weights[..., :2]], axis=2)[..., layer]
    wi, wo = metric_directions(pairs, 5)
    print(f"Level {level}'s footprints, f_a of {LAYERS[layer]} alone ({pairs} pairs): best lobe against value, "
          "cMAE / SMAPE ratios")
    for col, row in picks:
        block = np.s_[row << level:(row + 1) << level, col << level:(col + 1) << level]
        a, wt = alpha[block][..., 0].ravel().astype(np.float64), w[block].ravel().astype(np.float64)
        ref = footprint_mean(wi, wo, kd, eta, a, wt)
        value = one_lobe(wi, wo, kd, eta, float((a * wt).sum() / wt.sum()))
        cells = []
        for objective in ("cmae", "smape"):
            fa, fe, fk = fit_lobe(ref, wi, wo, kd, eta, float((a * wt).sum() / wt.sum()), objective=objective)
            g = one_lobe(wi, wo, fk, fe, fa)
            cells.append(f"{objective} fit {cmae(ref, g, wi[:, 2]) / cmae(ref, value, wi[:, 2]):.2f} / "
                         f"{smape(ref, g) / smape(ref, value):.2f}")
        print(f"  texel ({col}, {row}), alpha {a.min():.3f}-{a.max():.3f}: " + ", ".join(cells), flush=True)


def fitted_alpha_material(model, weights, alpha, layer, picks, size, fit_pairs=2000):
    """The alpha variant's material whose level texels in ``picks`` hold the fitted rule: alpha, eta
    and kd of ``layer`` fitted (:func:`fit_lobe`) to the mean over the texel's level-0 footprint
    of the layer's f_a, weighted by the layer's weight (its term of the mixture), on ``fit_pairs``
    pairs other than the metric's (seed 7). The layer gains kd and eta maps, its material's values
    at level 0; the texels the measurement does not read keep averaging by value."""
    t, i = model.tensors, model.index(LAYERS[layer])
    kd, eta = (np.asarray(t[f"materials.{q}"][i], np.float64) for q in ("kd", "eta"))
    maps = [{} for _ in LAYERS]
    maps[layer] = {"alpha": alpha, "kd": np.broadcast_to(kd, (size, size, 3)).astype(np.float32),
                   "eta": np.broadcast_to(eta, (size, size, 3)).astype(np.float32)}
    sv = SVBRDF(model, LAYERS, (size, size), weights, maps).with_mips("value")
    w = np.concatenate([1 - weights[..., :2].sum(axis=2, keepdims=True), weights[..., :2]], axis=2)[..., layer]
    fwi, fwo = metric_directions(fit_pairs, 7)
    for L in LEVELS:
        level_maps = sv.mips[L - 1][1][layer]
        for col, row in picks[L]:
            block = np.s_[row << L:(row + 1) << L, col << L:(col + 1) << L]
            a, wt = alpha[block][..., 0].ravel().astype(np.float64), w[block].ravel().astype(np.float64)
            keep = wt > 0
            if not keep.any():
                continue
            a, wt = a[keep], wt[keep]
            target = footprint_mean(fwi, fwo, kd, eta, a, wt)
            fa, fe, fk = fit_lobe(target, fwi, fwo, kd, eta, float(level_maps["alpha"][row, col, 0]))
            level_maps["alpha"][row, col] = fa
            level_maps["eta"][row, col] = fe
            level_maps["kd"][row, col] = fk
    return sv


def level_stats(errors):
    """Per level, (median SMAPE, p95 SMAPE, median cMAE, p95 cMAE) over its footprints (None: none)."""
    out = []
    for L in LEVELS:
        s, c = np.array(errors[L]).T if errors[L] else (None, None)
        out.append(None if s is None else (np.median(s), np.percentile(s, 95), np.median(c), np.percentile(c, 95)))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=str(ROOT / "results" / "rgl54_fast.safetensors"))
    ap.add_argument("--pairs", type=int, default=500)
    ap.add_argument("--footprints", type=int, default=256)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--out", help="keep the chained folders here")
    ap.add_argument("--lobes-only", action="store_true", help="only the GGX-lobe tables (f_a alone: minutes)")
    ap.add_argument("--alpha-only", action="store_true",
                    help="only the material's alpha-map variants, its four rules (value, perceptual, mean_square, "
                         "fitted), without the lobe tables")
    args = ap.parse_args()
    t0 = time.perf_counter()
    if not args.alpha_only:
        lobe_mixtures()
    if args.lobes_only:
        return 0
    model = hb.load_model(args.model)
    rng = np.random.default_rng(11)
    weights, maps = material(model, args.size, rng)
    wi, wo = metric_directions(args.pairs, 5)
    cos_i = wi[:, 2]
    full = np.concatenate([1 - weights[..., :2].sum(axis=2, keepdims=True), weights[..., :2]], axis=2)

    def picks_for(layer):
        """Per level, up to --footprints random level texels where `layer` (None: any) has a mean
        weight of at least one half: the footprints a quantity of that layer shapes."""
        picks = {}
        for L in LEVELS:
            side = args.size >> L
            mean = full.reshape(side, 1 << L, side, 1 << L, 3).mean(axis=(1, 3))
            ok = np.ones(side * side, bool) if layer is None else (mean[..., layer] >= 0.5).ravel()
            idx = rng.choice(np.nonzero(ok)[0], min(args.footprints, int(ok.sum())), replace=False)
            picks[L] = [(int(i % side), int(i // side)) for i in idx]
        return picks
    tmp = args.out or tempfile.mkdtemp(prefix="svbrdf_mips_")
    variants = [("weights only", (), "perceptual", None), ("+ kd (base)", ("kd",), "perceptual", 0),
                ("+ alpha (disc), perceptual", ("alpha",), "perceptual", 1), ("+ alpha (disc), value", ("alpha",), "value", 1),
                ("+ alpha (disc), mean_square", ("alpha",), "mean_square", 1),
                ("+ alpha (disc), fitted", ("alpha",), "fitted", 1), ("+ eta (stripes)", ("eta",), "perceptual", 2),
                ("+ z (stripes)", ("latent",), "perceptual", 2),
                ("all maps", ("kd", "alpha", "eta", "latent"), "perceptual", None),
                ("all maps, alpha by value", ("kd", "alpha", "eta", "latent"), "value", None)]
    if args.alpha_only:
        variants = [v for v in variants if v[0].startswith("+ alpha")]
    picks_of = {layer: picks_for(layer) for layer in (None, 0, 1, 2)}
    print(f"model {args.model}; {args.size}x{args.size}, {args.pairs} pairs (seed 5), footprints per level "
          f"{ {k: [len(p[L]) for L in LEVELS] for k, p in picks_of.items()} } (by layer of at least half the weight; "
          f"None: any); hybridbrdf {hb.__version__}, simd {hb.simd_path()}")
    print(f"{'variant':32s} " + " ".join(f"{f'{2 ** L}x (level {L}) SMAPE med/p95  cMAE med/p95':>48s}"
                                        for L in LEVELS))
    stats = {}
    for name, quantities, rule, layer in variants:
        picks = picks_of[layer]
        layer_maps = [{} for _ in LAYERS]
        for q in quantities:
            k, values = maps[q]
            layer_maps[k][q] = values
        folder = os.path.join(tmp, name.replace(" ", "_").replace("(", "").replace(")", "").replace(",", "").replace("+", "p"))
        if rule == "fitted":
            sv = fitted_alpha_material(model, weights, maps["alpha"][1], layer, picks, args.size)
        else:
            sv = SVBRDF(model, LAYERS, (args.size, args.size), weights, layer_maps).with_mips(rule)
        sv.save(folder, format="exr")
        core = hb._core.Svbrdf(load_svbrdf(folder).path)
        stats[name] = level_stats(footprint_errors(core, args.size, wi, wo, cos_i, LEVELS, picks))
        cells = ["no footprint" if st is None else "{:.3g}/{:.3g}  {:.3g}/{:.3g}".format(*st) for st in stats[name]]
        print(f"{name:32s} " + " ".join(f"{cell:>48s}" for cell in cells), flush=True)
    value = stats.get("+ alpha (disc), value")
    for name in [n for n in stats if n.startswith("+ alpha") and not n.endswith(", value") and value is not None]:
        cells = ["-" if st is None else "x{:.2f}/x{:.2f}  x{:.2f}/x{:.2f}".format(*np.divide(st, v))
                 for st, v in zip(stats[name], value)]
        print(f"{name + ' / value':32s} " + " ".join(f"{cell:>48s}" for cell in cells), flush=True)
    if args.alpha_only:
        footprint_bounds(model, weights, maps["alpha"][1], 1, picks_of[1][LEVELS[-1]], LEVELS[-1])
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
