#!/usr/bin/env python3
"""Issue 60: does the hybrid-reciprocal fit fail because its inputs are small? (main job, one seed)

The reciprocal direction inputs of spec/model.json are m = (wi + wo) / 2 and the six products of
e = (wi - wo) / 2. Over uniform hemisphere pairs their standard deviations are 0.41, 0.41, 0.20 and
0.20, 0.20, 0.05, 0.15, 0.08, 0.08: a total variance of 0.49, against 1.50 for the plain hybrid's
(wi, wo). This script fits the main job (8 synthetic materials, 3,000 steps, material output layers,
one torch thread) with ``--inputs``:

    halves  the inputs as the file format defines them today (hybrid-reciprocal)
    sums    s = wi + wo and the products of d = wi - wo (4x the products, 2x the sum: the same
            information, still exchanged bit for bit, at the plain inputs' scale) — patched into
            the PyTorch model for this process only: no file format, runtime or shader reads it
    plain   the non-reciprocal hybrid (wi, wo), for comparison

and prints each material's SMAPE / cMAE of the fitted module on 20,000 cosine-weighted pairs
(the same pairs for every run), and f_a's SMAPE.

    python bench/reciprocal_scale_probe.py --inputs sums --seed 0
"""

from __future__ import annotations

import argparse
import math

import torch

import hybridbrdf as hb
from hybridbrdf.evaluate.metrics import cmae, smape
from hybridbrdf.fit import fit
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.model import networks


class Done(Exception):
    """Raised by the observer after the last step's evaluation: the guard's refits are not needed."""


def sum_difference_inputs(wi: torch.Tensor, wo: torch.Tensor) -> torch.Tensor:
    """s = wi + wo, then the products of d = wi - wo (the reciprocal inputs without the halves)."""
    s, d = wi + wo, wi - wo
    dx, dy, dz = d.unbind(-1)
    return torch.cat([s, torch.stack([dx * dx, dy * dy, dz * dz, dx * dy, dx * dz, dy * dz], dim=-1)], dim=-1)


def cosine_pairs(n: int, seed: int):
    """(wi, wo), each (n, 3), cosine-weighted on the upper hemisphere."""
    g = torch.Generator().manual_seed(seed)

    def one():
        u = torch.rand(n, 2, generator=g)
        r, phi = u[:, 0].sqrt(), 2.0 * math.pi * u[:, 1]
        return torch.stack([r * phi.cos(), r * phi.sin(), (1.0 - u[:, 0]).clamp(min=0.0).sqrt()], dim=-1)
    return one(), one()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--inputs", choices=("halves", "sums", "plain"), default="sums",
                    help="the direction inputs fitted (default: %(default)s)")
    ap.add_argument("--seed", type=int, default=0, help="the fit's seed (default: %(default)s)")
    args = ap.parse_args()
    if args.inputs == "sums":
        networks.reciprocal_inputs = sum_difference_inputs
    torch.set_num_threads(1)
    sources = [hb.open_source(s) for s in hb.expand_sources(["synthetic:all"])]
    wi, wo = cosine_pairs(20000, 9)
    settings = FitSettings(steps=3000, arch="hybrid" if args.inputs == "plain" else "hybrid-reciprocal", seed=args.seed)

    def observe(step, module):
        if step < settings.steps:
            return
        with torch.no_grad():
            f_t, f_a = module(wi, wo)
        wi64, wo64, cos_i = wi.double().numpy(), wo.double().numpy(), wi[:, 2].double().numpy()
        for k, source in enumerate(sources):
            ref, ft, fa = source.eval(wi64, wo64), f_t[k].double().numpy(), f_a[k].double().numpy()
            print(f"{source.name:18s} hybrid {smape(ref, ft):.4f} / {cmae(ref, ft, cos_i):.5f}   f_a {smape(ref, fa):.4f}",
                  flush=True)
        raise Done()
    try:
        fit(sources, settings, progress=False, log=lambda msg: None, observe=observe)
    except Done:
        pass


if __name__ == "__main__":
    main()
