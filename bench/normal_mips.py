"""Normal-map mip levels against their footprints' mean BRDF (docs/SVBRDF.md, "Normal maps"; issue 58).

A level of a mip chain holds, per texel, one normal (the normalised mean of its footprint's) and
one alpha per layer; the footprint's texels each shade in their own perturbed frame. The length
|n| < 1 of the mean normal measures the spread the level no longer shows, and
hybridbrdf.svbrdf.mips widens alpha by it: alpha'^2 = alpha^2 + k (1 - |n|) / |n| (Toksvig 2005).
This bench measures k = 0 (no widening), 1 (the variance added as LEAN adds its second moment)
and 2 (Toksvig's factor in alpha units) by the analytic lobe f_a alone in float64
(so that the network's error does not blur the alpha rule's; k = 1 is the default): per level L, the level's texel
f_a(R^T wi, R^T wo; alpha') against the mean over its 2^L x 2^L level-0 texels of f_a in each
texel's frame (f = 0 below either horizon, the library's rule), as median and p95 SMAPE / cMAE
over footprints, on a bump field of sines (the chain built by SVBRDF.with_mips itself).

Usage: python bench/normal_mips.py [--size 64] [--pairs 1000] [--alpha 0.1]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from hybridbrdf.brdf.torch_brdf import eval_analytic
from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape
from hybridbrdf.svbrdf.mips import build_chain, tangent_normals
from hybridbrdf.svbrdf.normals import shading_frame


def bump_normals(size: int, rng, amplitude: float = 0.35) -> np.ndarray:
    """(size, size, 2) tangent-space x, y of a height field of sines (periods of 4 to 32 texels)."""
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    dx = np.zeros((size, size))
    dy = np.zeros((size, size))
    for period in (4, 8, 16, 32):
        k = 2 * np.pi * size / period
        a, b = rng.uniform(0, 2 * np.pi, 2)
        dx += amplitude / 4 * np.cos(k * x + a) * np.cos(k * y + b)
        dy -= amplitude / 4 * np.sin(k * x + a) * np.sin(k * y + b)
    n = np.stack([-dx, -dy, np.ones_like(dx)], axis=2)
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    return n[..., :2].astype(np.float32)


def f_frame(normals: np.ndarray, alpha: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """(T, P, 3) f_a of T texels (unit normals (T, 3), alpha (T, 2)) at P geometric-frame pairs."""
    t_s, b_s, n_s = shading_frame(normals)
    frames = np.stack([t_s, b_s, n_s], axis=1)  # (T, 3, 3): rows the shading axes
    li, lo = np.einsum("tij,pj->tpi", frames, wi), np.einsum("tij,pj->tpi", frames, wo)
    visible = (li[..., 2] > 0) & (lo[..., 2] > 0) & (wi[None, :, 2] > 0) & (wo[None, :, 2] > 0)
    kd = torch.full((3,), 0.05, dtype=torch.float64)
    eta = torch.full((3,), 1.5, dtype=torch.float64)
    a = torch.as_tensor(alpha, dtype=torch.float64)[:, None, :].expand(li.shape[0], li.shape[1], 2)
    f = eval_analytic(torch.as_tensor(li), torch.as_tensor(lo), kd, eta, a).numpy()
    return np.where(visible[..., None], f, 0.0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--pairs", type=int, default=1000)
    ap.add_argument("--alpha", type=float, default=0.1)
    ap.add_argument("--footprints", type=int, default=12)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    start = time.time()
    normal = bump_normals(args.size, rng)
    alpha = np.full((args.size, args.size, 2), args.alpha, np.float32)
    n0 = tangent_normals(normal)
    wi, wo = (np.asarray(a, np.float64) for a in metric_directions(args.pairs, 1))
    print(f"# normal-map mips: {args.size}^2 bump field, alpha {args.alpha}, {args.pairs} pairs, f_a in float64")
    print("| level (texels per footprint) | mean &#124;n&#124; | k = 0: SMAPE median / p95 | cMAE median / p95 "
          "| k = 1 (default) | | k = 2 | |")
    print("|---|---|---|---|---|---|---|---|")
    chains = {k: build_chain(None, [{"alpha": alpha}], 1, (args.size, args.size), normal=normal, toksvig=k) for k in (0.0, 1.0, 2.0)}
    for L in (2, 3, 4):
        side = args.size >> L
        picks = [(int(c), int(r)) for c, r in rng.integers(0, side, (args.footprints, 2))]
        rows = {k: [] for k in chains}
        lengths = []
        for col, row in picks:
            block = (slice(row << L, (row + 1) << L), slice(col << L, (col + 1) << L))
            ref = f_frame(n0[block].reshape(-1, 3), alpha[block].reshape(-1, 2), wi, wo).mean(axis=0)
            lengths.append(np.linalg.norm(n0[block].reshape(-1, 3).mean(axis=0)))
            for k, chain in chains.items():
                _, maps, lvl_normal = chain[L - 1]
                g = f_frame(tangent_normals(lvl_normal[row, col][None]), maps[0]["alpha"][row, col][None], wi, wo)[0]
                rows[k].append((smape(ref, g), cmae(ref, g, wi[:, 2])))
        cells = []
        for k in chains:
            s, c = np.array(rows[k]).T
            cells += [f"{np.median(s):.3f} / {np.percentile(s, 95):.3f}", f"{np.median(c):.4f} / {np.percentile(c, 95):.4f}"]
        print(f"| {L} ({4 ** L}) | {np.mean(lengths):.4f} | " + " | ".join(cells) + " |")
    print(f"# {time.time() - start:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
