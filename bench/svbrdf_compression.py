#!/usr/bin/env python3
"""What GPU block compression (KTX2: BC1/BC4/BC5/BC7) costs a textured material (issue 58;
docs/SVBRDF.md, "KTX2 maps").

1. Against its measurements: bench/svbrdf_mixture.py's material (three real measurements'
   materials of `results/rgl54_fast.safetensors` under a soft disc and soft stripes, 512x512),
   its weights map stored as float32 EXR, 8-bit PNG and KTX2 (BC5: two layers' weights), each
   texel's BRDF against the exact mixture of the measurements (the RGL files and the NBRDF
   network, read from ../shared/data): SMAPE and cMAE median / p95 over mixed texels (no weight
   above 0.99) and random ones, and each format's ratio to the float maps'.
2. Per quantity: a map of kd (the base), alpha (the disc's layer), eta and z (the stripes'
   layer) with variation at every scale (bench/svbrdf_mips.py's noise), stored as PNG and KTX2,
   each texel's BRDF against the same material with float maps: the error each format adds,
   beside the layer material's own error against its measurement (what "5% more" is of).
3. Bytes per texel of each map and format, the mip chain's third on top.
4. The whole material of the issue's target (weights, kd on the base, alpha on the disc's layer,
   a normal map: bench/normal_mips.py's bump field) against the exact mixture of the
   measurements, its maps as float32 EXR, 8-bit PNG and KTX2 with kd in BC1 (the writer's
   default) and in BC7: median / p95 and the ratio to the float maps'. Its kd, alpha and normal
   maps move every texel away from the measurements (what a painter asks for); the ratio says
   what storing those maps adds.

    python bench/svbrdf_compression.py [--pairs 20000] [--texels 600] [--shared ../shared/data]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import tempfile
import time

import numpy as np

import hybridbrdf as hb
from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape
from hybridbrdf.fit.painting import composite
from hybridbrdf.svbrdf import SVBRDF, load_svbrdf
from hybridbrdf.svbrdf.ktx2 import read_ktx2

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from normal_mips import bump_normals  # noqa: E402
from svbrdf_mips import material as noise_maps  # noqa: E402
from svbrdf_mixture import LAYERS, SIZE, masks, texel_metrics  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]


def stats(s, c):
    return f"SMAPE {np.median(s):.4f} / {np.percentile(s, 95):.4f}   cMAE {np.median(c):.5f} / {np.percentile(c, 95):.5f}"


def texel_errors(sv, ref_sv, uv, wi, wo, cos_i):
    """Per texel (uv rows), SMAPE and cMAE of sv's BRDF against ref_sv's (nearest texel)."""
    s, c = np.empty(len(uv)), np.empty(len(uv))
    for t, p in enumerate(uv):
        at = np.repeat(p[None], len(wi), axis=0)
        f, g = sv.eval(at, wi, wo, filter="nearest"), ref_sv.eval(at, wi, wo, filter="nearest")
        s[t], c[t] = smape(g, f), cmae(g, f, cos_i)
    return s, c


def ratios(s, c, base) -> str:
    return (f"  x{np.median(s) / np.median(base[0]):.4f}, x{np.percentile(s, 95) / np.percentile(base[0], 95):.4f}; "
            f"x{np.median(c) / np.median(base[1]):.4f}, x{np.percentile(c, 95) / np.percentile(base[1], 95):.4f}")


def whole_material(model, names, w_map, full, G, sets, wi, wo, cos_i, tmp) -> None:
    """Part 4: weights, kd, alpha and normal maps, each format against the measurements' mixture."""
    _, maps = noise_maps(model, SIZE, np.random.default_rng(11))
    layer_maps = [{} for _ in names]
    for q in ("kd", "alpha"):
        k, values = maps[q]
        layer_maps[k][q] = values
    normal = bump_normals(SIZE, np.random.default_rng(5), amplitude=0.2)
    sv = SVBRDF(model, names, (SIZE, SIZE), w_map, layer_maps, normal=normal)
    variants = {"exr": ("exr", "bc1"), "png": ("png", "bc1"), "ktx2 kd bc1": ("ktx2", "bc1"), "ktx2 kd bc7": ("ktx2", "bc7")}
    for label, (fmt, kd_format) in variants.items():
        sv.save(os.path.join(tmp, "whole_" + label.replace(" ", "_")), format=fmt, kd_format=kd_format)
    print("\n4. the whole material (weights, kd, alpha, normal map) against the exact mixture of the measurements, "
          "median / p95 (ratio to float maps: median, p95)")
    for label, idx in sets.items():
        idx = idx[:len(idx) // 2]
        uv = np.stack([(idx % SIZE + 0.5) / SIZE, (idx // SIZE + 0.5) / SIZE], axis=1)
        base = None
        for name in variants:
            loaded = load_svbrdf(os.path.join(tmp, "whole_" + name.replace(" ", "_")))
            s, c = np.empty(len(idx)), np.empty(len(idx))
            for t, (p, i) in enumerate(zip(uv, idx)):
                g = sum(full[i, k] * G[k] for k in range(len(G)) if full[i, k] > 0)
                f = loaded.eval(np.repeat(p[None], len(wi), axis=0), wi, wo, filter="nearest")
                s[t], c[t] = smape(g, f), cmae(g, f, cos_i)
            base = base or (s, c)
            print(f"  {label:6s} {name:12s} {stats(s, c)}{ratios(s, c, base)}", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=str(ROOT / "results" / "rgl54_fast.safetensors"))
    ap.add_argument("--pairs", type=int, default=20_000)
    ap.add_argument("--texels", type=int, default=600)
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"))
    args = ap.parse_args()
    t0 = time.perf_counter()
    model = hb.load_model(args.model)
    names = [n for n, _ in LAYERS]
    wi, wo = metric_directions(args.pairs, 7)
    cos_i = wi[:, 2]
    print(f"model {args.model}; {SIZE}x{SIZE}; {args.pairs} pairs (seed 7), {args.texels} texels per set; "
          f"hybridbrdf {hb.__version__}, simd {hb.simd_path()}")
    tmp = tempfile.mkdtemp(prefix="svbrdf_bc_")
    weights3 = composite(masks())
    w_map = np.concatenate([weights3, np.zeros((SIZE, SIZE, 1))], axis=2).astype(np.float32)
    for fmt in ("exr", "png", "ktx2"):
        SVBRDF(model, names, (SIZE, SIZE), w_map).save(os.path.join(tmp, fmt), format=fmt)
    svs = {fmt: load_svbrdf(os.path.join(tmp, fmt)) for fmt in ("exr", "png", "ktx2")}
    print(f"weights map as KTX2: {read_ktx2(os.path.join(tmp, 'ktx2', 'weights.ktx2')).name}")

    # 1. Against the measurements: only the weights vary, so each texel is sum_k w_k F_k.
    sources = [hb.open_source(os.path.join(args.shared, p)) for _, p in LAYERS]
    F = [model.eval(wi, wo, n) for n in names]
    G = [np.asarray(s.eval(wi, wo), dtype=np.float64) for s in sources]
    full = np.concatenate([1 - weights3.sum(axis=2, keepdims=True), weights3], axis=2).reshape(-1, 3)
    rng = np.random.default_rng(0)
    sets = {"mixed": rng.choice(np.nonzero(full.max(axis=1) < 0.99)[0], args.texels, replace=False),
            "random": rng.choice(len(full), args.texels, replace=False)}
    print("\n1. against the exact mixture of the measurements, median / p95 (ratio to float maps: median, p95)")
    for label, idx in sets.items():
        uv = np.stack([(idx % SIZE + 0.5) / SIZE, (idx // SIZE + 0.5) / SIZE], axis=1)
        base = None
        for fmt, sv in svs.items():
            W = sv.texels(uv, "nearest")["weight"].astype(np.float64)
            s, c = texel_metrics(W, F, G, cos_i)
            base = base or (s, c)
            print(f"  {label:6s} {fmt:5s} {stats(s, c)}{ratios(s, c, base)}")

    # 2. Per quantity, against the same material with float maps.
    own = {n: (smape(g, f), cmae(g, f, cos_i)) for n, f, g in zip(names, F, G)}
    _, maps = noise_maps(model, SIZE, np.random.default_rng(11))
    print("\n2. per quantity: each format's material against the float maps' (texels where the layer has weight >= 0.5),"
          " median / p95; the layer material's own error against its measurement beside it")
    for q, (k, values) in maps.items():
        layer_maps = [{} for _ in names]
        layer_maps[k][q] = values
        for fmt in ("exr", "png", "ktx2"):
            SVBRDF(model, names, (SIZE, SIZE), w_map, layer_maps).save(os.path.join(tmp, f"{q}_{fmt}"), format=fmt)
        ref = load_svbrdf(os.path.join(tmp, f"{q}_exr"))
        idx = np.nonzero(full[:, k] >= 0.5)[0]
        idx = rng.choice(idx, min(args.texels // 4, len(idx)), replace=False)
        uv = np.stack([(idx % SIZE + 0.5) / SIZE, (idx // SIZE + 0.5) / SIZE], axis=1)
        for fmt in ("png", "ktx2"):
            s, c = texel_errors(load_svbrdf(os.path.join(tmp, f"{q}_{fmt}")), ref, uv, wi, wo, cos_i)
            files = [p for p in os.listdir(os.path.join(tmp, f"{q}_{fmt}")) if p.startswith(f"layer{k}_{q}")]
            kind = ",".join(sorted(read_ktx2(os.path.join(tmp, f"{q}_{fmt}", p)).name for p in files)) if fmt == "ktx2" else "8-bit"
            print(f"  {q:6s} layer {k} {fmt:5s} ({kind}) {stats(s, c)}   own error of {names[k]}: "
                  f"SMAPE {own[names[k]][0]:.4f}, cMAE {own[names[k]][1]:.5f}", flush=True)

    print("\n3. bytes per texel (level 0; a mip chain adds a third): PNG 3 per map (8-bit RGB); KTX2 BC7, BC5 1, BC4, BC1 0.5 "
          "(weights of 2 layers BC4, of 3 BC5, of 4 BC7; kd BC1 sRGB (default) or BC7 sRGB; alpha BC5; eta BC7; "
          "z BC7 per 3 components; normal map BC5)")
    whole_material(model, names, w_map, full, G, sets, wi, wo, cos_i, tmp)
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
