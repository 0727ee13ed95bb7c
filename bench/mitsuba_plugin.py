#!/usr/bin/env python3
"""The Mitsuba 3 plugin (hybridbrdf.render.mitsuba) at work: for materials fitted to raw RGL files, the
render error of the plugin against Mitsuba's own ``measured`` plugin on the same file (the
reference), and the frame time of each, in scalar_rgb or llvm_ad_rgb.

The scene is the plugin tests' (tests/python/mitsuba_scenes.py): a sphere under a smooth
environment map with a blurred sun, direct lighting, box filter. The reference is the measured
plugin at --ref-spp; MAE is over the sphere's pixels and RGB of the linear images, for renders
at --spp; the noise column is the MAE of the measured plugin itself at --spp (another seed)
against the reference: what noise alone contributes. Times are per frame at --spp, after a
first frame that compiles the kernels.

    python bench/mitsuba_plugin.py [--variant llvm_ad_rgb] [--model results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors]
        [--size 128] [--spp 256] [--ref-spp 2048] [NAME ...]

NAME: raw RGL files of ../shared/data/rgl (default: the five), matched to the model's
``NAME.rgl`` materials.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))
FIVE = ["cc_ibiza_sunset_rgb", "cg_sunflower_rgb", "colodur_napoli_4f_rgb", "paper_white_rgb", "vch_golden_yellow_rgb"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", default=FIVE)
    ap.add_argument("--variant", default="llvm_ad_rgb", choices=("scalar_rgb", "llvm_ad_rgb"))
    ap.add_argument("--model", default=str(ROOT / "results" / "rgl54_hybrid_32x2_e09_120k_refit01.safetensors"))
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--ref-spp", type=int, default=2048)
    ap.add_argument("--shared", default=str(ROOT.parent / "shared" / "data"))
    args = ap.parse_args()

    import mitsuba as mi

    mi.set_variant(args.variant)
    import hybridbrdf as hb
    import hybridbrdf.render.mitsuba as hbmi
    from hybridbrdf.render.tracer import write_exr
    from mitsuba_scenes import environment_map, mitsuba_scene

    hbmi.register()
    model = hb.load_model(args.model)

    def frame(bsdf, seed, spp=args.spp):
        scene = mi.load_dict(mitsuba_scene(mi, env, bsdf, args.size, spp))
        mi.render(scene, seed=seed, spp=1)  # first frame: kernels compiled (llvm), files loaded
        t0 = time.perf_counter()
        img = np.array(mi.render(scene, seed=seed, spp=spp))  # spp again: the warm-up's spp=1 sticks
        return img, time.perf_counter() - t0

    with tempfile.TemporaryDirectory() as tmp:
        env = os.path.join(tmp, "env.exr")
        write_exr(environment_map(), env)
        print(f"Mitsuba {mi.__version__} {args.variant}; sphere under an environment map, {args.size}x{args.size}, "
              f"direct lighting; renders {args.spp} spp against the measured plugin at {args.ref_spp} spp; "
              f"model {args.model}")
        print(f"{'material':24s} {'noise MAE':>9s} {'MAE full':>9s} {'MAE f_a':>9s} | {'measured s':>10s} "
              f"{'hbrdf s':>8s} {'f_a s':>7s}")
        rows = []
        for name in args.names:
            path = os.path.join(args.shared, "rgl", f"{name}.bsdf")
            material = f"{name}.rgl" if f"{name}.rgl" in model.materials else name
            ref, _ = frame({"type": "measured", "filename": path}, 1, args.ref_spp)
            ref2, t_ref = frame({"type": "measured", "filename": path}, 2)
            full, t_full = frame({"type": "hbrdf", "filename": args.model, "material": material}, 3)
            fa, t_fa = frame({"type": "hbrdf", "filename": args.model, "material": material, "evaluate": "analytic"}, 3)
            hit = sphere_mask(mi, env, args.size)
            mae = lambda img: float(np.abs(img[hit] - ref[hit]).mean())  # noqa: E731
            rows.append((mae(ref2), mae(full), mae(fa)))
            print(f"{name:24s} {mae(ref2):9.5f} {mae(full):9.5f} {mae(fa):9.5f} | {t_ref:10.2f} {t_full:8.2f} {t_fa:7.2f}",
                  flush=True)
        r = np.array(rows)
        print(f"{'mean':24s} {r[:, 0].mean():9.5f} {r[:, 1].mean():9.5f} {r[:, 2].mean():9.5f}")
    return 0


def sphere_mask(mi, env, size):
    """The sphere's pixels: those whose camera ray hits it (a depth-1 render with a black sphere)."""
    from mitsuba_scenes import mitsuba_scene

    d = mitsuba_scene(mi, env, {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}}, size, 1)
    d["integrator"] = {"type": "path", "max_depth": 1}
    img = np.array(mi.render(mi.load_dict(d), spp=4))
    return img.sum(-1) == 0


if __name__ == "__main__":
    sys.exit(main())
