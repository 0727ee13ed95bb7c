#!/usr/bin/env python3
"""Textured materials against measured mixtures (issue 48; docs/SVBRDF.md).

A 512x512 textured material painted from three real measurements: the raw RGL files paper_white
(base) and vch_golden_yellow (a soft disc) and the NBRDF network of ilm_l3_37_metallic (soft
stripes on top), each the material of `results/rgl54_fast.safetensors` fitted to it. The ground
truth at a texel of weights w is the exact mixture sum_k w_k g_k of the measurements (a convex
combination of BRDFs is a BRDF). Printed:

1. per-texel SMAPE and cMAE (CONVENTIONS, 10^5 cosine pairs per texel) of the textured material
   against the exact mixture, median and 95th percentile, over 1,200 random texels and over 1,200
   texels of the mixed region (no weight above 0.99), beside the pure materials' own errors and
   the texel's weighted own error sum_k w_k e_k; the runtime path (libhybridbrdf eval_texel on
   the saved folder) checked against the linear combination on 16 texels;
2. the `hbrdf mix` rule (p, z and output layer blended by the weights, no energy table) on 200
   mixed texels;
3. 8-bit maps against float: the weights map as painted (PNG against EXR), and per quantity (kd,
   eta, alpha, z) of every rgl54_fast material quantised to 8/10/12/16 bits by the spec's decode
   (z over the model's range per component): the metrics' change against its measurement;
4. filtering: at a roughness edge (alpha 0.05 | 0.5) and a latent edge (two materials' z), the
   BRDF of the bilinearly interpolated texel against the bilinear combination of the texels' BRDFs.

    python bench/svbrdf_mixture.py [--model results/rgl54_fast.safetensors] [--pairs 100000]
        [--texels 1200] [--out DIR] [--shared ../shared/data]
    python bench/svbrdf_mixture.py --write-masks DIR [--mask-size 1024]   # the masks as PNG, for hbrdf paint
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import tempfile
import time

import numpy as np
import torch

import hybridbrdf as hb
from hybridbrdf import spec
from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape
from hybridbrdf.fit.painting import composite
from hybridbrdf.model.networks import energy_bound_scale
from hybridbrdf.svbrdf.asset import SVBRDF, load_svbrdf
from hybridbrdf.svbrdf.decode import decode, encode, png_channel

ROOT = pathlib.Path(__file__).resolve().parents[1]
LAYERS = [("paper_white_rgb.rgl", "rgl/paper_white_rgb.bsdf"),
          ("vch_golden_yellow_rgb.rgl", "rgl/vch_golden_yellow_rgb.bsdf"),
          ("ilm_l3_37_metallic_rgb", "nbrdf/rgl/ilm_l3_37_metallic_rgb.h5")]
SIZE = 512


def smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0, 1)
    return t * t * (3 - 2 * t)


def masks(size: int = SIZE):
    """A soft disc and soft diagonal stripes, (size, size) each, in [0, 1]."""
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    disc = 1 - smoothstep(0.26, 0.34, np.hypot(x - 0.38, y - 0.5))
    stripes = smoothstep(-0.25, 0.25, np.sin(2 * np.pi * 3 * (x + y)))
    return [disc, stripes]


def texel_metrics(weights, F, G, cos_i):
    """SMAPE and cMAE per texel (rows of weights (T, K)) of sum w F_k against sum w G_k."""
    s, c = np.empty(len(weights)), np.empty(len(weights))
    for t, w in enumerate(weights):
        f = sum(w[k] * F[k] for k in range(len(F)) if w[k] > 0)
        g = sum(w[k] * G[k] for k in range(len(G)) if w[k] > 0)
        s[t], c[t] = smape(g, f), cmae(g, f, cos_i)
    return s, c


def stats(x):
    return f"median {np.median(x):.4f}  p95 {np.percentile(x, 95):.4f}"


def stats_c(x):
    return f"median {np.median(x):.5f}  p95 {np.percentile(x, 95):.5f}"


def quantised(values, channel, bits):
    v = encode(values, channel)
    top = (1 << bits) - 1
    return decode(np.clip(np.rint(np.clip(v, 0, 1) * top), 0, top) / top, channel)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=str(ROOT / "results" / "rgl54_fast.safetensors"))
    ap.add_argument("--pairs", type=int, default=100_000)
    ap.add_argument("--texels", type=int, default=1200)
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"))
    ap.add_argument("--out", help="keep the painted folders here (DIR/float, DIR/png)")
    ap.add_argument("--write-masks", metavar="DIR", help="only write the two masks as 8-bit PNG (DIR/mask1.png, "
                                                         "DIR/mask2.png) at --mask-size, for hbrdf paint, and stop")
    ap.add_argument("--mask-size", type=int, default=SIZE)
    args = ap.parse_args()
    if args.write_masks:
        from PIL import Image

        os.makedirs(args.write_masks, exist_ok=True)
        for k, m in enumerate(masks(args.mask_size), start=1):
            Image.fromarray(np.rint(m * 255).astype(np.uint8), "L").save(os.path.join(args.write_masks, f"mask{k}.png"))
        print(f"wrote {args.write_masks}/mask1.png, mask2.png ({args.mask_size}x{args.mask_size})")
        return 0
    t0 = time.perf_counter()
    model = hb.load_model(args.model)
    names = [n for n, _ in LAYERS]
    sources = [hb.open_source(os.path.join(args.shared, p)) for _, p in LAYERS]
    wi, wo = metric_directions(args.pairs, 7)
    cos_i = wi[:, 2]
    F = [model.eval(wi, wo, n) for n in names]
    G = [np.asarray(s.eval(wi, wo), dtype=np.float64) for s in sources]
    own = [(smape(g, f), cmae(g, f, cos_i)) for f, g in zip(F, G)]
    print(f"model {args.model}; {args.pairs} metric pairs (seed 7); torch threads {torch.get_num_threads()}")
    for n, (s, c) in zip(names, own):
        print(f"  pure {n:28s} SMAPE {s:.4f}  cMAE {c:.5f}")

    weights3 = composite(masks())  # (H, W, 2): layers 1, 2
    full = np.concatenate([1 - weights3.sum(axis=2, keepdims=True), weights3], axis=2)  # (H, W, 3)
    tmp = args.out or tempfile.mkdtemp(prefix="svbrdf_bench_")
    w_map = np.concatenate([weights3, np.zeros((SIZE, SIZE, 1))], axis=2).astype(np.float32)
    SVBRDF(model, names, (SIZE, SIZE), w_map).save(os.path.join(tmp, "float"), format="exr")
    SVBRDF(model, names, (SIZE, SIZE), w_map).save(os.path.join(tmp, "png"), format="png")
    sv_float, sv_png = load_svbrdf(os.path.join(tmp, "float")), load_svbrdf(os.path.join(tmp, "png"))
    rng = np.random.default_rng(0)
    flat = full.reshape(-1, 3)
    mixed_idx = np.nonzero(flat.max(axis=1) < 0.99)[0]
    print(f"masks: {SIZE}x{SIZE}, {len(mixed_idx) / len(flat):.1%} of texels mixed (no weight above 0.99)")
    sets = {"random": rng.choice(len(flat), args.texels, replace=False),
            "mixed": rng.choice(mixed_idx, args.texels, replace=False)}

    # The runtime path on the saved folder against the linear combination, 16 mixed texels.
    worst = 0.0
    for idx in sets["mixed"][:16]:
        r, c = divmod(int(idx), SIZE)
        uv = np.tile([(c + 0.5) / SIZE, (r + 0.5) / SIZE], (args.pairs, 1))
        f_rt = sv_float.eval(uv, wi, wo, filter="nearest")
        w = sv_float.texels(uv[:1], "nearest")["weight"][0].astype(np.float64)
        lin = sum(w[k] * F[k] for k in range(3))
        worst = max(worst, float(np.abs(f_rt - lin).max() / np.abs(lin).max()))
    print(f"runtime check: libhybridbrdf eval_texel on the saved folder vs sum_k w_k f_k: largest relative "
          f"difference {worst:.2e} (16 mixed texels, {args.pairs} pairs each)")

    e_s, e_c = np.array([o[0] for o in own]), np.array([o[1] for o in own])
    print(f"\n1. per-texel error against the exact mixture of the measurements ({args.texels} texels per set)")
    results = {}
    for label, idx in sets.items():
        W = flat[idx]
        s, c = texel_metrics(W, F, G, cos_i)
        bound_s, bound_c = W @ e_s, W @ e_c
        results[label] = (W, s, c)
        print(f"  {label:7s} SMAPE {stats(s)}   (weighted own error {stats(bound_s)}; ratio of medians "
              f"{np.median(s) / np.median(bound_s):.3f}, of p95 {np.percentile(s, 95) / np.percentile(bound_s, 95):.3f})")
        print(f"  {label:7s} cMAE  {stats_c(c)} (weighted own error {stats_c(bound_c)}; ratio of medians "
              f"{np.median(c) / np.median(bound_c):.3f}, of p95 {np.percentile(c, 95) / np.percentile(bound_c, 95):.3f})")
    print(f"  pure materials' own errors: SMAPE {e_s.min():.4f} .. {e_s.max():.4f}, cMAE {e_c.min():.5f} .. {e_c.max():.5f}")

    # 2. The mix rule on 200 mixed texels.
    W = results["mixed"][0][:200]
    mod = model._module(torch.float32)
    rows = [model._material_tensors(model.index(n), torch.float32) for n in names]
    wi_t, wo_t = torch.as_tensor(wi, dtype=torch.float32), torch.as_tensor(wo, dtype=torch.float32)
    ms, mc = [], []
    with torch.no_grad():
        for w in W:
            blend = {k: sum(float(w[j]) * rows[j][k][0] for j in range(3)) for k in ("kd", "eta", "alpha", "z",
                                                                                        "head_weight", "head_bias")}
            n = len(wi)
            f, _ = mod.evaluate_pairs(wi_t, wo_t, blend["kd"].expand(n, 3), blend["eta"].expand(n, 3),
                                      blend["alpha"].expand(n, 2), blend["z"].expand(n, -1),
                                      (blend["head_weight"], blend["head_bias"]))
            g = sum(w[k] * G[k] for k in range(3))
            ms.append(smape(g, f.double().numpy()))
            mc.append(cmae(g, f.double().numpy(), cos_i))
    s_l, c_l = texel_metrics(W, F, G, cos_i)
    print(f"\n2. the mix rule (p, z, output layer blended by the weights) on 200 mixed texels:\n"
          f"  mix rule SMAPE {stats(np.array(ms))}  cMAE {stats_c(np.array(mc))}\n"
          f"  layered  SMAPE {stats(s_l)}  cMAE {stats_c(c_l)}")

    # 3. 8-bit against float.
    Wf = results["mixed"][0]
    uv = np.stack([(sets["mixed"] % SIZE + 0.5) / SIZE, (sets["mixed"] // SIZE + 0.5) / SIZE], axis=1)
    W8 = sv_png.texels(uv, "nearest")["weight"].astype(np.float64)
    s8, c8 = texel_metrics(W8, F, G, cos_i)
    s32, c32 = results["mixed"][1], results["mixed"][2]
    print(f"\n3. 8-bit maps against float\n  weights map (PNG vs EXR), mixed texels: SMAPE median x{np.median(s8) / np.median(s32):.4f}, "
          f"p95 x{np.percentile(s8, 95) / np.percentile(s32, 95):.4f}; cMAE median x{np.median(c8) / np.median(c32):.4f}, "
          f"p95 x{np.percentile(c8, 95) / np.percentile(c32, 95):.4f}")
    bits_study(model, args, wi, wo, cos_i)

    # 4. Filtering at edges.
    filtering(model, names, wi, wo, cos_i)
    print(f"\ntotal {time.perf_counter() - t0:.0f} s; folders in {tmp}")
    return 0


def bits_study(model, args, wi, wo, cos_i, materials: int = 54):
    """Each quantity of every material quantised alone, by the spec's 8-bit decode at several depths."""
    mod = model._module(torch.float32)
    t = model.tensors
    z_lo, z_hi = t["materials.z"].min(axis=0), t["materials.z"].max(axis=0)
    paths = {}
    for p in hb.expand_sources([os.path.join(args.shared, "rgl"), os.path.join(args.shared, "nbrdf", "rgl")]):
        stem = pathlib.Path(p).stem
        paths[f"{stem}.rgl" if p.endswith(".bsdf") else stem] = p
        if p.endswith(".h5") and f"{stem}.rgl" in model.materials:
            paths[f"{stem}.nbrdf"] = p
    names = [n for n in model.materials if n in paths][:materials]
    wi_t, wo_t = torch.as_tensor(wi, dtype=torch.float32), torch.as_tensor(wo, dtype=torch.float32)
    depths = (8, 10, 12, 16)
    ratios = {q: {b: [] for b in depths} for q in ("kd", "eta", "alpha", "z")}
    n = len(wi)
    for name in names:
        i = model.index(name)
        g = np.asarray(hb.open_source(paths[name]).eval(wi, wo), dtype=np.float64)
        row = {k: t[f"materials.{k}"][i].astype(np.float64) for k in ("kd", "eta", "alpha", "z")}
        mt = model._material_tensors(i, torch.float32)
        head = (mt["head_weight"][0], mt["head_bias"][0]) if "head_weight" in mt else None

        def f_of(r):
            with torch.no_grad():
                f, _ = mod.evaluate_pairs(wi_t, wo_t, *(torch.as_tensor(r[k], dtype=torch.float32).expand(n, -1)
                                                        for k in ("kd", "eta", "alpha", "z")), head)
            if "energy_bound" in mt:
                tab = mt["energy_bound"][0]
                f = f * (energy_bound_scale(tab, wi_t[:, 2] / wi_t.norm(dim=1)) *
                         energy_bound_scale(tab, wo_t[:, 2] / wo_t.norm(dim=1)))[:, None]
            return f.double().numpy()

        base = f_of(row)
        s0, c0 = smape(g, base), cmae(g, base, cos_i)
        for q in ratios:
            for b in depths:
                r = dict(row)
                if q == "z":
                    ch = [png_channel("latent", lo, hi) for lo, hi in zip(z_lo, z_hi)]
                    r["z"] = np.array([quantised(v, c, b) for v, c in zip(row["z"], ch)])
                else:
                    r[q] = quantised(row[q], png_channel(q), b)
                fq = f_of(r)
                ratios[q][b].append((smape(g, fq) / s0, cmae(g, fq, cos_i) / c0))
    print(f"  per quantity, {len(names)} materials of the model quantised alone (ratio to float: mean / worst of SMAPE; cMAE):")
    for q, by in ratios.items():
        cells = []
        for b in depths:
            a = np.array(by[b])
            cells.append(f"{b} bits {a[:, 0].mean():.4f}/{a[:, 0].max():.4f}; {a[:, 1].mean():.4f}/{a[:, 1].max():.4f}")
        print(f"    {q:5s} " + " | ".join(cells))


def filtering(model, names, wi, wo, cos_i):
    """BRDF of the interpolated texel vs interpolation of the texels' BRDFs, midway across an edge."""
    mod = model._module(torch.float32)
    n = len(wi)
    wi_t, wo_t = torch.as_tensor(wi, dtype=torch.float32), torch.as_tensor(wo, dtype=torch.float32)
    i = model.index(names[0])
    mt = model._material_tensors(i, torch.float32)
    head = (mt["head_weight"][0], mt["head_bias"][0])

    def f_of(kd, eta, alpha, z, hd=head):
        with torch.no_grad():
            f, _ = mod.evaluate_pairs(wi_t, wo_t, kd.expand(n, 3), eta.expand(n, 3), alpha.expand(n, 2), z.expand(n, -1), hd)
        return f.double().numpy()

    print("\n4. filtering: midway across an edge, BRDF of the interpolated texel vs the mean of the two texels' BRDFs")
    for label, a0, a1 in (("roughness edge alpha 0.05 | 0.5", 0.05, 0.5), ("roughness edge alpha 0.2 | 0.3", 0.2, 0.3)):
        fa = f_of(mt["kd"][0], mt["eta"][0], torch.tensor([a0, a0]), mt["z"][0])
        fb = f_of(mt["kd"][0], mt["eta"][0], torch.tensor([a1, a1]), mt["z"][0])
        fm = f_of(mt["kd"][0], mt["eta"][0], torch.tensor([(a0 + a1) / 2] * 2), mt["z"][0])
        ref = 0.5 * (fa + fb)
        print(f"  {label:34s} SMAPE {smape(ref, fm):.4f}  cMAE {cmae(ref, fm, cos_i):.5f}")
    j = model.index(names[1])
    mj = model._material_tensors(j, torch.float32)
    fa = f_of(mt["kd"][0], mt["eta"][0], mt["alpha"][0], mt["z"][0])
    fb = f_of(mj["kd"][0], mj["eta"][0], mj["alpha"][0], mj["z"][0], (mj["head_weight"][0], mj["head_bias"][0]))
    fm = f_of(*((mt[k][0] + mj[k][0]) / 2 for k in ("kd", "eta", "alpha", "z")),
              hd=((mt["head_weight"][0] + mj["head_weight"][0]) / 2, (mt["head_bias"][0] + mj["head_bias"][0]) / 2))
    ref = 0.5 * (fa + fb)
    print(f"  {'p, z, head edge ' + names[0][:8] + ' | ' + names[1][:8]:34s} SMAPE {smape(ref, fm):.4f}  cMAE {cmae(ref, fm, cos_i):.5f}")
    print("  weights edge (any materials)         0 by construction: f is linear in the weights (tests/python/test_svbrdf.py)")


if __name__ == "__main__":
    sys.exit(main())
