#!/usr/bin/env python3
"""Train the shipped prior (hybridbrdf.model.prior): one network for every measured material of
../shared/data (5 raw RGL files, the NBRDF reconstructions of 49 RGL, 80 MERL and 8 Nielsen
materials: 142), written into the package (python/hybridbrdf/data/prior.safetensors).

    python bench/train_prior.py [--steps 20000] [--batch 512] [--mlp 32x2] [--latent 8]
        [--output-layer shared|material] [--folders F,...] [--leave-out NAME]... [--out FILE] [--checkpoint FILE] [--compile]
        [--arch hybrid|hybrid-reciprocal]

--leave-out NAME drops a material in every form (raw file and reconstruction): the prior of
the new-measurement hold-out (protocol (a) with the prior's recipe), e.g. all five raw RGL files, then
``python bench/prior_heldout.py --prior FILE`` adds them with ``hybridbrdf.add``'s defaults.
The recipe is the fit defaults (FitSettings) except for the flags above; --batch is per
material, so 512 x 142 materials is 2.5x the pairs of a 54-material fit at 1024.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import hybridbrdf as hb
from hybridbrdf.fit.settings import FitSettings, parse_mlp
from hybridbrdf.fit import fit

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from model_metrics import collection_means  # noqa: E402

FOLDERS = ("rgl", "nbrdf/rgl", "nbrdf/merl", "nbrdf/nielsen")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=20_000)
    ap.add_argument("--batch", type=int, default=512, help="direction pairs per material and step")
    ap.add_argument("--mlp", default="32x2")
    ap.add_argument("--latent", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--output-layer", choices=("shared", "material"), default="material",
                    help="the network's output layer: one shared, or each material's own (the shipped prior "
                         "has material output layers; the one before it is 'shared')")
    ap.add_argument("--folders", default=",".join(FOLDERS),
                    help="folders of --shared to train on, comma-separated (default: %(default)s; "
                         "nbrdf/merl,nbrdf/nielsen: a prior that never saw an RGL material, for warm-start tests)")
    ap.add_argument("--leave-out", action="append", default=[], metavar="NAME",
                    help="leave this material out in every form (repeatable)")
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"))
    ap.add_argument("--out", help="the model file (default: the package's prior.safetensors, or with --arch "
                                  "hybrid-reciprocal its prior_reciprocal.safetensors)")
    ap.add_argument("--checkpoint", help="checkpoint file (resumed if it exists)")
    ap.add_argument("--compile", action="store_true", help="torch.compile the training steps")
    ap.add_argument("--arch", default="hybrid", help="model architecture (hybrid, or hybrid-reciprocal: issue 60)")
    args = ap.parse_args()
    if args.out is None:
        name = "prior_reciprocal.safetensors" if args.arch == "hybrid-reciprocal" else "prior.safetensors"
        args.out = str(ROOT / "python" / "hybridbrdf" / "data" / name)
    folders = tuple(f for f in args.folders.split(",") if f)
    specs = [p for p in hb.expand_sources([os.path.join(args.shared, f) for f in folders])
             if pathlib.Path(p).stem not in set(args.leave_out)]
    missing = set(args.leave_out) - {pathlib.Path(p).stem for p in hb.expand_sources(
        [os.path.join(args.shared, f) for f in folders])}
    if missing:
        ap.error(f"--leave-out names no material of the data: {', '.join(sorted(missing))}")
    sources = [hb.open_source(p) for p in specs]
    width, depth = parse_mlp(args.mlp)
    # Sources recorded relative to the data folder: the file ships, the machine's paths do not.
    settings = FitSettings(arch=args.arch, width=width, depth=depth, latent=args.latent, steps=args.steps,
                           batch=args.batch,
                           seed=args.seed, eval_pairs=100_000, output_layer=args.output_layer,
                           sources=[os.path.relpath(p, args.shared) for p in specs])
    t0 = time.time()
    model = fit(sources, settings, checkpoint=args.checkpoint, resume=args.checkpoint is not None,
                progress=False, log=print, compile_step=args.compile)
    model.training["prior"] = {"collection": list(folders), "left_out": sorted(args.leave_out)}
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    model.save(args.out)
    print(f"prior: {len(sources)} materials ({', '.join(folders)}; left out: {', '.join(args.leave_out) or 'none'}), "
          f"{args.mlp} ({args.output_layer} output layer), latent {args.latent}, {args.steps} steps x {args.batch} pairs per material, "
          f"{time.time() - t0:.0f} s (training {model.training['train_seconds']:.0f} s)")
    print(f"its own fit (10^5 pairs): {collection_means(model)}")
    print(f"wrote {args.out}: {os.path.getsize(args.out):,} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
