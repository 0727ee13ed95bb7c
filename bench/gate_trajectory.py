#!/usr/bin/env python3
"""How a gated hybrid's gate and correction evolve for one material over a fit (issue 60).

bench/gate_probe.py reads a finished model from outside; this script watches the fit itself: every
``--every`` steps it evaluates the network for ``--material`` on fixed uniform pairs and prints its
output layer's biases, the medians of the correction's and gate's pre-activations (o_c, o_g; the
gated combine is f = exp(o_c) + sigmoid(o_g) f_a), the gate's range, the largest hidden feature and
the fraction of hidden features that are zero on every pair for that material ("dead": hardGeLU
passes no gradient through them). One JSON line per row goes to ``--out`` as well.

    python bench/gate_trajectory.py --arch hybrid-reciprocal --out rec.jsonl
    python bench/gate_trajectory.py --arch hybrid --out plain.jsonl

The main job's settings (8 synthetic materials, 3,000 steps, material output layers); one torch thread.
"""

from __future__ import annotations

import argparse
import json

import torch

import hybridbrdf as hb
from hybridbrdf.brdf.torch_brdf import reciprocal_inputs
from hybridbrdf.fit import fit
from hybridbrdf.fit.settings import FitSettings


class StopWatching(Exception):
    """Raised by the observer once the last row is written: the guard's refits are not watched."""


def uniform_pairs(n: int, seed: int):
    """(wi, wo), each (n, 3): directions uniform on the upper hemisphere (normalised Gaussians, z
    folded up)."""
    g = torch.Generator().manual_seed(seed)
    pairs = []
    for _ in range(2):
        w = torch.nn.functional.normalize(torch.randn(n, 3, generator=g), dim=-1)
        pairs.append(torch.cat([w[:, :2], w[:, 2:].abs()], dim=-1))
    return pairs[0], pairs[1]


def row(step: int, module, material: int, arch: str, wi, wo) -> dict:
    """The network's state for ``material`` on the pairs (wi, wo) after ``step`` steps."""
    idx = torch.tensor([material])
    with torch.no_grad():
        directions = reciprocal_inputs(wi, wo) if arch == "hybrid-reciprocal" else torch.cat([wi, wo], -1)
        features = module.mlp.features_from(module._first_layer(directions, module.z[idx], None))
        head = module.heads(idx)
        o = (torch.baddbmm(head[1][:, None, :], features, head[0].transpose(1, 2)) if head is not None
             else module.mlp.out(features))[0]
        gate = torch.sigmoid(o[:, 3:6])
        bias = head[1][0] if head is not None else module.mlp.out.bias
    return dict(step=step, bias_c=[round(float(b), 3) for b in bias[0:3]], bias_g=[round(float(b), 3) for b in bias[3:6]],
                o_c_median=float(o[:, 0:3].median()), o_g_median=float(o[:, 3:6].median()),
                gate_min=float(gate.min()), gate_max=float(gate.max()), feature_max=float(features.abs().max()),
                dead_features=float((features.abs().amax(dim=1) < 1e-6).float().mean()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--arch", default="hybrid-reciprocal", help="hybrid or hybrid-reciprocal (default: %(default)s)")
    ap.add_argument("--material", default="brushed_aluminium", help="synthetic material watched (default: %(default)s)")
    ap.add_argument("--seed", type=int, default=0, help="the fit's seed (default: %(default)s)")
    ap.add_argument("--steps", type=int, default=3000, help="fit steps (default: %(default)s, the main job's)")
    ap.add_argument("--every", type=int, default=100, help="steps between rows (default: %(default)s)")
    ap.add_argument("--pairs", type=int, default=2000, help="uniform pairs evaluated per row (default: %(default)s)")
    ap.add_argument("--out", required=True, help="JSON lines file written row by row")
    args = ap.parse_args()
    torch.set_num_threads(1)
    sources = [hb.open_source(s) for s in hb.expand_sources(["synthetic:all"])]
    material = [s.name for s in sources].index(args.material)
    wi, wo = uniform_pairs(args.pairs, 5)
    settings = FitSettings(steps=args.steps, arch=args.arch, seed=args.seed)

    with open(args.out, "w") as out:
        def observe(step, module):
            if step % args.every and step != 1:
                return
            r = row(step, module, material, args.arch, wi, wo)
            out.write(json.dumps(r) + "\n")
            out.flush()
            print(f"{step:5d}  o_c median {r['o_c_median']:7.2f}  o_g median {r['o_g_median']:6.2f}  gate "
                  f"{r['gate_min']:.3f}..{r['gate_max']:.3f}  biases c {r['bias_c']} g {r['bias_g']}  "
                  f"dead {r['dead_features']:.2f}", flush=True)
            if step >= args.steps:
                raise StopWatching()
        try:
            fit(sources, settings, progress=False, log=lambda msg: None, observe=observe)
        except StopWatching:
            pass


if __name__ == "__main__":
    main()
