#!/usr/bin/env python3
"""Data-parallel scaling of ``hbrdf fit`` on this machine: the same fit (same global batch,
seed and steps) as 1 rank x T threads and as R ranks x 1 thread under torchrun (gloo over
loopback), timed by the fits' own training clocks (``train_seconds``, pool evaluation and
compilation excluded), with the two models' accuracy side by side.

    python bench/bench_distributed.py [SOURCE...] [--steps 2000] [--batch 1024] [--mlp 32x2]
        [--ranks 2] [--threads 2] [--compile]

Default SOURCE: the 54 RGL materials of ../shared/data (5 raw files + 49 NBRDF networks).
"""

from __future__ import annotations

import argparse
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

import hybridbrdf as hb

ROOT = pathlib.Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sources", nargs="*", default=[str(DATA / "rgl"), str(DATA / "nbrdf" / "rgl")])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--mlp", default="32x2")
    ap.add_argument("--ranks", type=int, default=2, help="ranks of the data-parallel run (1 thread each)")
    ap.add_argument("--threads", type=int, default=2, help="torch threads of the 1-rank run")
    ap.add_argument("--compile", action="store_true", help="hbrdf fit --compile in both runs")
    args = ap.parse_args()
    fit = ["fit", *args.sources, "--mlp", args.mlp, "--steps", str(args.steps), "--batch", str(args.batch),
           "--eval-pairs", "200000", "--quiet"] + (["--compile"] if args.compile else [])
    runs = {f"1 rank x {args.threads} threads": ([sys.executable, "-m", "hybridbrdf.cli"], str(args.threads)),
            f"{args.ranks} ranks x 1 thread": ([sys.executable, "-m", "torch.distributed.run", "--standalone",
                                                f"--nproc_per_node={args.ranks}", "-m", "hybridbrdf.cli"], "1")}
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for i, (label, (launcher, threads)) in enumerate(runs.items()):
            out = os.path.join(d, f"m{i}.safetensors")
            r = subprocess.run([*launcher, *fit, "--out", out], env=dict(os.environ, OMP_NUM_THREADS=threads),
                               capture_output=True, text=True)
            if r.returncode != 0:
                print(r.stderr[-3000:], file=sys.stderr)
                return 1
            m = hb.load_model(out)
            t = m.training
            steps = args.steps - (1 if "compile_seconds" in t else 0)
            seconds = t["train_seconds"] - t.get("compile_seconds", 0.0)
            rows.append((label, seconds, steps / seconds, np.mean([x["metrics"]["smape"] for x in m.material_info]),
                         np.mean([x["metrics"]["cmae"] for x in m.material_info])))
    print(f"hbrdf fit {' '.join(fit[1:])}  ({len(hb.expand_sources(args.sources))} materials)")
    print(f"{'run':24s} {'train s':>8s} {'steps/s':>8s} {'speed-up':>8s} {'mean SMAPE':>10s} {'mean cMAE':>10s}")
    for label, seconds, rate, sm, cm in rows:
        print(f"{label:24s} {seconds:8.1f} {rate:8.2f} {rate / rows[0][2]:7.2f}x {sm:10.4f} {cm:10.5f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
