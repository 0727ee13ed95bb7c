#!/usr/bin/env python3
"""Issue 60: does the hybrid-reciprocal fit fail because its inputs are small? (main job, one seed)

The reciprocal direction inputs of spec/model.json format 1 were m = (wi + wo) / 2 and the six
products of e = (wi - wo) / 2. Over uniform hemisphere pairs their standard deviations are 0.41,
0.41, 0.20 and 0.20, 0.20, 0.05, 0.15, 0.08, 0.08: a total variance of 0.49, against 1.50 for the
plain hybrid's (wi, wo). This script fits the main job (8 synthetic materials, 3,000 steps,
material output layers, one torch thread) with ``--inputs``:

    sums    s = wi + wo and the products of d = wi - wo (4x the products, 2x the sum: the same
            information, still exchanged bit for bit, at the plain inputs' scale): the format's
            definition since format 2 (issue 60), so hybrid-reciprocal as every runtime reads it
    halves  format 1's inputs, patched into the PyTorch model for this process only (no file
            format, runtime or shader reads them any more)
    plain   the non-reciprocal hybrid (wi, wo), for comparison

and prints each material's SMAPE / cMAE of the fitted module on 20,000 cosine-weighted pairs
(the same pairs for every run), f_a's SMAPE, and the means. Before format 2 "sums" was the patched
mode and "halves" the format; the fits are the same either way (the same functions, the same
seed). ``--model FILE`` fits nothing: it prints the same figures for a model file (a real
``hbrdf fit synthetic:all --steps 3000 --arch hybrid-reciprocal`` output, through libhybridbrdf),
to show that the format reproduces the probe.

    python bench/reciprocal_scale_probe.py --inputs sums --seed 0
    python bench/reciprocal_scale_probe.py --model r.safetensors
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


def halves_inputs(wi: torch.Tensor, wo: torch.Tensor) -> torch.Tensor:
    """Format 1's reciprocal inputs: m = (wi + wo) / 2, then the products of e = (wi - wo) / 2."""
    m, e = 0.5 * (wi + wo), 0.5 * (wi - wo)
    ex, ey, ez = e.unbind(-1)
    return torch.cat([m, torch.stack([ex * ex, ey * ey, ez * ez, ex * ey, ex * ez, ey * ez], dim=-1)], dim=-1)


def cosine_pairs(n: int, seed: int):
    """(wi, wo), each (n, 3), cosine-weighted on the upper hemisphere."""
    g = torch.Generator().manual_seed(seed)

    def one():
        u = torch.rand(n, 2, generator=g)
        r, phi = u[:, 0].sqrt(), 2.0 * math.pi * u[:, 1]
        return torch.stack([r * phi.cos(), r * phi.sin(), (1.0 - u[:, 0]).clamp(min=0.0).sqrt()], dim=-1)
    return one(), one()


def report(sources, wi, wo, evaluate) -> None:
    """Each material's SMAPE / cMAE of ``evaluate(k) -> (f_t, f_a)`` (float64 arrays) and the means."""
    wi64, wo64, cos_i = wi.double().numpy(), wo.double().numpy(), wi[:, 2].double().numpy()
    rows = []
    for k, source in enumerate(sources):
        ref = source.eval(wi64, wo64)
        ft, fa = evaluate(k)
        rows.append((smape(ref, ft), cmae(ref, ft, cos_i)))
        print(f"{source.name:18s} hybrid {rows[-1][0]:.4f} / {rows[-1][1]:.5f}   f_a {smape(ref, fa):.4f}", flush=True)
    print(f"{'mean':18s} hybrid {sum(r[0] for r in rows) / len(rows):.4f} / {sum(r[1] for r in rows) / len(rows):.5f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--inputs", choices=("halves", "sums", "plain"), default="sums",
                    help="the direction inputs fitted (default: %(default)s)")
    ap.add_argument("--seed", type=int, default=0, help="the fit's seed (default: %(default)s)")
    ap.add_argument("--model", help="fit nothing: evaluate this model file (its materials in the main job's order)")
    args = ap.parse_args()
    if args.inputs == "halves":
        networks.reciprocal_inputs = halves_inputs
    torch.set_num_threads(1)
    sources = [hb.open_source(s) for s in hb.expand_sources(["synthetic:all"])]
    wi, wo = cosine_pairs(20000, 9)
    if args.model:
        model = hb.load_model(args.model)
        assert model.materials == [s.name for s in sources], model.materials
        w32 = wi.numpy(), wo.numpy()
        report(sources, wi, wo, lambda k: (model.eval(*w32, k).astype("float64"),
                                           model.eval_analytic(*w32, k).astype("float64")))
        return
    settings = FitSettings(steps=3000, arch="hybrid" if args.inputs == "plain" else "hybrid-reciprocal", seed=args.seed)

    def observe(step, module):
        if step < settings.steps:
            return
        with torch.no_grad():
            f_t, f_a = module(wi, wo)
        report(sources, wi, wo, lambda k: (f_t[k].double().numpy(), f_a[k].double().numpy()))
        raise Done()
    try:
        fit(sources, settings, progress=False, log=lambda msg: None, observe=observe)
    except Done:
        pass


if __name__ == "__main__":
    main()
