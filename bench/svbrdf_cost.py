#!/usr/bin/env python3
"""What texturing costs in libhybridbrdf (issue 48; docs/SVBRDF.md): a textured material's batched
evaluation (Svbrdf::eval_batch: texel lookup, layers sorted by material, HybridModel::eval_batch_layers)
against the uniform material's (HybridModel::eval_batch), one thread, in one run.

The textured material is bench/svbrdf_mixture.py's (512x512, three layers of
`results/rgl54_fast.safetensors`), with and without maps of kd and z on its base layer. Pairs:
cosine-weighted directions; uv on pure texels (the base alone), anywhere (the whole texture:
21% of its texels mixed) and on mixed texels only, in texture order (as a renderer's tile reads
them), and anywhere in random order (every lookup a cache miss on a 512x512 map). Best of --runs
runs each, the
uniform material timed alternately with each textured set (its ratio is to that best).

    python bench/svbrdf_cost.py [--model results/rgl54_fast.safetensors] [--pairs 262144] [--runs 15]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import platform
import sys
import tempfile
import time

import numpy as np

import hybridbrdf as hb
from hybridbrdf import _core
from hybridbrdf.evaluate.metrics import metric_directions
from hybridbrdf.fit.painting import composite
from hybridbrdf.svbrdf.asset import SVBRDF, load_svbrdf

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from svbrdf_mixture import LAYERS, SIZE, masks  # noqa: E402


def best(fn, runs):
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def best_pair(fa, fb, runs):
    """Best times of fa and fb run alternately: a virtual machine's slow spells hit both."""
    ta, tb = [], []
    for _ in range(runs):
        ta.append(best(fa, 1))
        tb.append(best(fb, 1))
    return min(ta), min(tb)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=str(ROOT / "results" / "rgl54_fast.safetensors"))
    ap.add_argument("--pairs", type=int, default=1 << 18)
    ap.add_argument("--runs", type=int, default=15)
    args = ap.parse_args()
    model = hb.load_model(args.model)
    names = [n for n, _ in LAYERS]
    w = composite(masks())
    weights = np.concatenate([w, np.zeros((SIZE, SIZE, 1))], axis=2).astype(np.float32)
    full = np.concatenate([1 - w.sum(axis=2, keepdims=True), w], axis=2).reshape(-1, 3)
    base = model.index(names[0])
    rng = np.random.default_rng(0)
    maps0 = {"kd": np.clip(model.tensors["materials.kd"][base] * rng.uniform(0.8, 1.0, (SIZE, SIZE, 1)), 0, 1).astype(np.float32),
             "latent": (model.tensors["materials.z"][base] + rng.normal(0, 0.05, (SIZE, SIZE, model.arch["latent"]))).astype(np.float32)}
    tmp = tempfile.mkdtemp(prefix="svbrdf_cost_")
    SVBRDF(model, names, (SIZE, SIZE), weights).save(os.path.join(tmp, "plain"), format="exr")
    SVBRDF(model, names, (SIZE, SIZE), weights, [maps0, {}, {}]).save(os.path.join(tmp, "maps"), format="exr")
    n = args.pairs
    wi, wo = (a.astype(np.float32) for a in metric_directions(n, 3))

    def uv_of(texels):
        t = np.sort(rng.choice(texels, n))  # in texture order, as a renderer's tile reads them
        return np.stack([(t % SIZE + rng.uniform(0.2, 0.8, n)) / SIZE, (t // SIZE + rng.uniform(0.2, 0.8, n)) / SIZE],
                        axis=1).astype(np.float32)

    # Texels whose bilinear neighbourhood is pure base: all four neighbours' base weight 1.
    pure_map = (full[:, 0] == 1).reshape(SIZE, SIZE)
    inner = pure_map & np.roll(pure_map, 1, 0) & np.roll(pure_map, -1, 0) & np.roll(pure_map, 1, 1) & np.roll(pure_map, -1, 1)
    sets = {"pure texels": uv_of(np.nonzero(inner.ravel())[0]),
            "whole texture": uv_of(np.arange(SIZE * SIZE)),
            "whole, random": rng.uniform(0, 1, (n, 2)).astype(np.float32),
            "mixed texels": uv_of(np.nonzero(full.max(axis=1) < 0.99)[0])}
    lib = _core.Model(args.model)
    t_uniform = best(lambda: lib.eval(wi, wo, base), args.runs)
    print(f"{platform.processor() or platform.machine()}; model SIMD path {_core.model_simd_path()}; {n} pairs, best of "
          f"{args.runs}; one thread")
    print(f"uniform material ({names[0]}), HybridModel::eval_batch: {n / t_uniform / 1e6:.2f} M evaluations/s")
    for label in ("plain", "maps"):
        sv = _core.Svbrdf(os.path.join(tmp, label))
        twin = load_svbrdf(os.path.join(tmp, label))  # the Python loader: how many layers each pair evaluates
        for name, uv in sets.items():
            t_u, t_b = best_pair(lambda: lib.eval(wi, wo, base), lambda: sv.eval(uv, wi, wo, "bilinear", False, True),
                                 args.runs)
            layers = float(np.mean((twin.texels(uv.astype(np.float64), "bilinear")["weight"] > 0).sum(axis=1)))
            print(f"  textured ({label:5s}) {name:14s} batched {n / t_b / 1e6:6.2f} M/s = {t_b / t_u:.2f}x the uniform "
                  f"material ({layers:.2f} layers per pair)")
        t_s = best(lambda: sv.eval(sets["pure texels"], wi, wo, "bilinear", False, False), 1)
        print(f"  textured ({label:5s}) pure texels    scalar  {n / t_s / 1e6:6.2f} M/s = {t_s / t_uniform:.2f}x (the tracer "
              f"before eval_batch)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
