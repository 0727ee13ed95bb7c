#!/usr/bin/env python3
"""Texture aliasing in the tracer, with mip chains read at the camera rays' footprints and without
(issue 58; docs/RENDERING.md, "Texture footprints" and "Anisotropic footprints").

A plane receding to the horizon carries a fine checkerboard of two measured materials' fits (the
weights map SIZE x SIZE, squares of SQUARE texels, its complete mip chain) under a constant white
environment, one bounce. Rendered at 1 sample per pixel in three variants (SEEDS seeds each):
without mips (`"mip_lod": false`), with mips read at the ray cone's isotropic lod (`"anisotropic":
1`) and with the anisotropic lookup over the pixel's footprint (`"anisotropic": ANISOTROPIC`), each
against a converged render (REF_SPP samples per pixel without mips: jittered pixel samples, so the
box-filtered truth), over the pixels wholly on the plane (those a render of the environment alone
leaves black). Prints the relative MAE and RMSE (colour-averaged, over the mean of the truth) and
their ratio to no mips (issue 58's target: at most 1/4), the seconds of CPU per 1-spp frame, and
writes the figure: truth | no mips | isotropic | anisotropic, 1 spp.

    python bench/texture_aliasing.py [--model results/rgl54_fast.safetensors]
        [--layers spectralon_rgb leaf_maple_rgb] [--size 1024] [--square 8] [--width 160] [--height 90]
        [--ref-spp 1024] [--seeds 8] [--anisotropic 16] [--shading lambert|full] [--threads 1]
        [--out out/texture_aliasing] [--png PNG]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import platform
import time

import numpy as np
from PIL import Image

import hybridbrdf as hb
from hybridbrdf.render.tracer import render
from hybridbrdf.svbrdf import SVBRDF

ROOT = pathlib.Path(__file__).resolve().parents[1]


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", default=str(ROOT / "results" / "rgl54_fast.safetensors"), help="hybrid model file")
    p.add_argument("--layers", nargs=2, default=["spectralon_rgb", "leaf_maple_rgb"], help="the two materials")
    p.add_argument("--size", type=int, default=1024, help="weights map side (a power of two)")
    p.add_argument("--square", type=int, default=8, help="checker square side in texels")
    p.add_argument("--width", type=int, default=160)
    p.add_argument("--height", type=int, default=90)
    p.add_argument("--ref-spp", type=int, default=1024, help="samples per pixel of the converged render")
    p.add_argument("--seeds", type=int, default=8, help="1-spp renders per variant (errors averaged)")
    p.add_argument("--anisotropic", type=int, default=16, help="most probes of the anisotropic variant")
    p.add_argument("--shading", choices=["lambert", "full"], default="lambert",
                   help="lambert: each layer's kd alone (an eta map of 1 turns Fresnel off; f_a evaluated, cosine "
                        "sampling: a sample returns the texel's albedo exactly, so the error is the texture's alone); "
                        "full: the fitted hybrid materials, MIS sampling (adds the BRDF's own sampling noise)")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--out", default="out/texture_aliasing", help="folder for the material and images")
    p.add_argument("--png", default=None, help="the figure (default OUT/texture_aliasing.png)")
    return p.parse_args(argv)


def checker_material(model_path: str, layers, size: int, square: int, folder: str, lambert: bool) -> None:
    """A size x size weights map: layer 1 on the odd squares, with its complete mip chain; with
    `lambert` an eta map of 1 on both layers (Fresnel 0: f_a = kd / pi)."""
    ys, xs = np.mgrid[0:size, 0:size]
    weights = np.zeros((size, size, 3), np.float32)
    weights[..., 0] = ((xs // square + ys // square) % 2).astype(np.float32)
    maps = [{"eta": np.ones((size, size, 3), np.float32)} for _ in layers] if lambert else None
    SVBRDF(hb.load_model(model_path), list(layers), (size, size), weights=weights, maps=maps).with_mips().save(
        folder, format="png")


def scene(folder: str, width: int, height: int, lambert: bool, **settings) -> dict:
    """The plane y = 0, 200 units square (its texture once across), the camera 1 above it near its
    front edge, looking toward the horizon; one bounce, BSDF sampling alone."""
    material = {"type": "textured", "svbrdf": folder, "evaluate": "analytic" if lambert else "full"}
    return {"camera": {"position": [0, 1, 95], "look_at": [0, 0.55, 85], "fov_deg": 30, "width": width, "height": height},
            "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "materials": {"checker": material},
            "objects": [{"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "tangent": [1, 0, 0], "size": 200,
                         "material": "checker"}],
            "max_depth": 1, "nee": False, "sampler": "cosine" if lambert else "mis", **settings}


def errors(image: np.ndarray, truth: np.ndarray, mask: np.ndarray):
    """Relative MAE and RMSE over the masked pixels, colour-averaged, over the truth's mean there."""
    d, mean = (image - truth)[mask], truth[mask].mean()
    return float(np.abs(d).mean() / mean), float(np.sqrt((d ** 2).mean()) / mean)


def figure(images, path: str) -> None:
    """The images side by side, clamped and sRGB-encoded, 2 pixels of white between them."""
    def srgb(x):
        x = np.clip(x, 0, 1)
        return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    h = images[0].shape[0]
    gap = np.ones((h, 2, 3))
    row = np.concatenate([part for im in images for part in (srgb(im), gap)][:-1], axis=1)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    Image.fromarray(np.rint(row * 255).astype(np.uint8)).save(path)


def main(argv=None) -> None:
    a = parse_args(argv)
    folder = os.path.abspath(os.path.join(a.out, "checker"))
    os.makedirs(a.out, exist_ok=True)
    lambert = a.shading == "lambert"
    checker_material(a.model, a.layers, a.size, a.square, folder, lambert)
    base = dict(threads=a.threads, quiet=True)
    sky, _ = render(scene(folder, a.width, a.height, lambert, spp=16, max_depth=0), **base)
    mask = (sky == 0).all(axis=2)  # wholly on the plane: no sample saw the environment directly
    t0 = time.perf_counter()
    truth, _ = render(scene(folder, a.width, a.height, lambert, spp=a.ref_spp, seed=1000, mip_lod=False), **base)
    t_ref = time.perf_counter() - t0
    variants = {"no mips": dict(mip_lod=False), "mips, isotropic": dict(mip_lod=True, anisotropic=1),
                f"mips, anisotropic {a.anisotropic}": dict(mip_lod=True, anisotropic=a.anisotropic)}
    runs, cpu = {}, {}
    for name, settings in variants.items():
        c0 = time.process_time()
        runs[name] = [render(scene(folder, a.width, a.height, lambert, spp=1, seed=s, **settings), **base)[0]
                      for s in range(a.seeds)]
        cpu[name] = (time.process_time() - c0) / a.seeds
    # Minified pixels: where the isotropic chain changed a sample (one seed traces the same jitter
    # with and without; a sample whose lod is <= 0 reads level 0 either way, bit for bit).
    names = list(variants)
    minified = mask & np.any([(m != n).any(axis=2) for m, n in zip(runs[names[1]], runs[names[0]])], axis=0)
    rows = {name: np.array([errors(im, truth, mask) + errors(im, truth, minified) for im in runs[name]]).mean(axis=0)
            for name in names}
    print(f"texture aliasing: {a.layers[0]} | {a.layers[1]} checkerboard, {a.size}x{a.size} weights, "
          f"{a.square}-texel squares, {a.shading} shading, {a.width}x{a.height}, plane pixels {int(mask.sum())} of "
          f"{mask.size}, of which minified {int(minified.sum())}")
    print(f"truth: {a.ref_spp} spp without mips, {t_ref:.1f} s on {a.threads} thread(s); "
          f"1-spp errors: mean of {a.seeds} seeds; machine {platform.processor() or platform.machine()}, "
          f"libhybridbrdf {hb.simd_path()}")
    print(f"{'1 spp':<22} {'rel. MAE':>9} {'rel. RMSE':>9} {'/ no mips':>15} | minified: {'MAE':>7} {'RMSE':>7} "
          f"{'/ no mips':>13} | {'CPU s/frame':>11}")
    for name in names:
        e, r = rows[name], rows[name] / rows[names[0]]
        print(f"{name:<22} {e[0]:>9.4f} {e[1]:>9.4f} {r[0]:>7.3f} {r[1]:>7.3f} | {'':10}{e[2]:>7.4f} {e[3]:>7.4f} "
              f"{r[2]:>6.3f} {r[3]:>6.3f} | {cpu[name]:>11.3f}")
    best = min((rows[n][:2] / rows[names[0]][:2]).max() for n in names[1:])
    print(f"target: the mips' error at most 1/4 of no mips' over the plane: {'met' if best <= 0.25 else 'missed'} "
          f"(best variant {best:.3f})")
    png = a.png or os.path.join(a.out, "texture_aliasing.png")
    figure([truth] + [runs[name][0] for name in names], png)
    print(f"wrote {png}")


if __name__ == "__main__":
    main()
