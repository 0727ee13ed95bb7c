#!/usr/bin/env python3
"""The paper's editing and interpolation figures (Sec. 5.1), rendered by this project's tracer
from the shipped prior: an editing grid of a fitted material (rows: diffuse colour kd, index of
refraction eta, roughness alpha; the fitted values in the middle column) and an interpolation
strip between two fitted MERL materials (``model.mix`` at evenly spaced t). Every image is the
sphere-under-sky scene of bench/render_error.py with the MIS sampler; each tile is labelled with
the edit and its maximum directional albedo (``model.albedo``).

    python bench/edit_figures.py [--material satin_gold_rgb] [--mix gold-metallic-paint specular-blue-phenolic]
        [--size 128] [--spp 64] [--out-dir docs/figures]

Writes editing_grid.png and interpolation_strip.png to --out-dir, and prints a table of the
edits (parameters and maximum albedo) and the render time.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

import hybridbrdf as hb
from hybridbrdf.render.tracer import render

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from render_error import scene, srgb  # noqa: E402

SCALES = (0.25, 0.5, 1.0, 2.0, 4.0)
COLOURS = ([0.8, 0.2, 0.1], [0.1, 0.45, 0.8], None, [0.2, 0.7, 0.25], [0.9, 0.9, 0.9])  # None: the fitted kd


def edits(model, material):
    """(row label, column label, edit keywords) of the grid; the middle column is the fitted material."""
    p = model.analytic_params(material)
    out = []
    for kd in COLOURS:
        out.append(("kd", "fitted" if kd is None else ",".join(f"{v:g}" for v in kd), {} if kd is None else {"kd": kd}))
    for s in SCALES:  # scale eta - 1: the Fresnel tint of a coloured eta is kept
        eta = np.minimum(1.0 + s * (p.eta - 1.0), hb.ETA_MAX)
        out.append(("eta", "fitted" if s == 1 else f"1+{s:g}(eta-1)", {} if s == 1 else {"eta": eta.tolist()}))
    for s in SCALES:
        alpha = np.clip(s * p.alpha, hb.ALPHA_MIN, hb.ALPHA_MAX)
        out.append(("alpha", "fitted" if s == 1 else f"{s:g} alpha", {} if s == 1 else {"alpha": alpha.tolist()}))
    return out


def shown(img, exposure=0.0):
    return srgb(np.clip(img * 2.0 ** exposure, 0.0, 1.0))


def contact_sheet(plt, tiles, rows, cols, size, title, path):
    """The labelled images of ``tiles`` ((image, label) pairs) on a rows x cols grid, as a PNG."""
    fig, axes = plt.subplots(rows, cols, figsize=size, squeeze=False)
    for ax, (img, label) in zip(axes.ravel(), tiles):
        ax.imshow(shown(img))
        ax.set_title(label, fontsize=7)
        ax.axis("off")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", help="model file (default: the shipped prior)")
    ap.add_argument("--material", default="satin_gold_rgb", help="material of the editing grid (the paper's)")
    ap.add_argument("--mix", nargs=2, default=["gold-metallic-paint", "specular-blue-phenolic"], metavar=("A", "B"))
    ap.add_argument("--steps", type=int, default=7, help="images in the interpolation strip")
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--out-dir", default="docs/figures")
    args = ap.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    base = hb.load_model(args.model or hb.prior_path())
    grid = edits(base, args.material)
    model = base
    names = []
    for k, (_, _, kw) in enumerate(grid):
        name = args.material if not kw else f"edit{k}"
        if kw:
            model = model.edit(args.material, name, **kw)
        names.append(name)
    ts = np.linspace(0.0, 1.0, args.steps)
    mixes = []
    for k, t in enumerate(ts):
        model = model.mix(args.mix[0], args.mix[1], float(t), f"mix{k}")
        mixes.append(f"mix{k}")
    os.makedirs(args.out_dir, exist_ok=True)
    t0 = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "edited.safetensors")
        model = model.save_checked(path)

        def image(name):
            s = scene({"type": "model", "file": path, "material": name}, args.size, args.spp, 1)
            s["sampler"] = "mis"
            return render(s)[0]

        print(f"{'row':6s} {'edit':22s} {'kd':>22s} {'eta':>22s} {'alpha':>18s} {'max albedo':>10s}")
        tiles = []
        for (row, label, _), name in zip(grid, names):
            p = model.analytic_params(name)
            a = model.albedo(name)["max"]
            print(f"{row:6s} {label:22s} {str(p.kd.round(3).tolist()):>22s} {str(p.eta.round(3).tolist()):>22s} "
                  f"{str(p.alpha.round(4).tolist()):>18s} {a:10.3f}", flush=True)
            tiles.append((image(name), f"{row} {label}\nmax albedo {a:.2f}"))
        strip = []
        for t, name in zip(ts, mixes):
            a = model.albedo(name)["max"]
            print(f"{'mix':6s} {f't = {t:.3f}':22s} {'':>22s} {'':>22s} {'':>18s} {a:10.3f}", flush=True)
            strip.append((image(name), f"t = {t:.2f}\nmax albedo {a:.2f}"))
    seconds = time.time() - t0

    cols = len(SCALES)
    contact_sheet(plt, tiles, 3, cols, (2.0 * cols, 2.0 * 3 + 0.4),
                  f"Editing {args.material} (shipped prior): kd, eta, alpha rows; fitted in the middle",
                  os.path.join(args.out_dir, "editing_grid.png"))
    contact_sheet(plt, strip, 1, len(strip), (1.9 * len(strip), 2.3),
                  f"Interpolating (p, z): {args.mix[0]} (t = 0) to {args.mix[1]} (t = 1)",
                  os.path.join(args.out_dir, "interpolation_strip.png"))
    print(f"{len(tiles) + len(strip)} renders, {args.size}x{args.size}, {args.spp} spp, MIS sampler, in {seconds:.0f} s; "
          f"wrote {args.out_dir}/editing_grid.png and {args.out_dir}/interpolation_strip.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
