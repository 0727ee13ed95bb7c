#!/usr/bin/env python3
"""Block-compression encoders against each other, and what each format costs each quantity of
a textured material (issue 58; docs/TEXTURES.md).

Part 1 (encoders): every encoder of ``hybridbrdf.svbrdf.bcenc.ENCODERS`` on every format, over the
maps of a painted material (``--svbrdf DIR``, a folder ``hbrdf paint`` wrote: its weights, kd and
alpha PNGs) and synthetic content (smooth gradients with an edge; a tangent-space normal map's xy
from a height field; value noise): PSNR (8-bit peak), max and mean absolute error in stored
steps (1/255), and encode time per megatexel (one thread, best of --repeat).

Part 2 (quantities): with the chosen encoder of each format, each quantity of the material
(weights RGB, kd sRGB, alpha RG, and eta and latent maps added to layer 1 as
``with_eta_and_latent`` says: hbrdf paint writes none; a synthetic normal map's xy) stored as BC7, BC1, BC4 (one channel each) or
BC5 (two channels), max / mean decode error in stored units against the 8-bit PNG the folder holds
(PNG is lossless: its error is 0), and bytes per texel of each.

    python bench/bc_encoders.py [--svbrdf DIR] [--size 512] [--repeat 3]

DIR is optional: without it, the material's maps are painted here from the model's own materials
(``hybridbrdf.fit.painting.paint``, no fit: --model, default results/merl80_hybrid_32x3_10k).
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import tempfile
import time

import numpy as np
from PIL import Image

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))

from hybridbrdf.svbrdf import bcenc  # noqa: E402


def value_noise(size: int, octaves: int, seed: int) -> np.ndarray:
    """Smooth fractal noise in [0, 1] (bilinearly upsampled random grids, halving amplitude)."""
    rng = np.random.default_rng(seed)
    out = np.zeros((size, size))
    for o in range(octaves):
        cells = 4 << o
        grid = rng.random((cells + 1, cells + 1))
        t = np.linspace(0, cells, size, endpoint=False)
        i = t.astype(int)
        f = t - i
        rows = grid[i] * (1 - f)[:, None] + grid[i + 1] * f[:, None]
        out += 0.5 ** o * (rows[:, i] * (1 - f) + rows[:, i + 1] * f)
    out -= out.min()
    return out / out.max()


def to8(x: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(x * 255), 0, 255).astype(np.uint8)


def synthetic(size: int) -> dict:
    """Named uint8 maps: smooth RGB with an edge, normal xy, value noise."""
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    smooth = np.stack([0.5 + 0.4 * np.sin(5 * x + k) * np.cos(3 * y - k) for k in range(3)], -1)
    smooth += np.where((x - 0.5) ** 2 + (y - 0.5) ** 2 < 0.08, 0.15, 0.0)[..., None]
    height = value_noise(size, 5, 1) * 8
    gy, gx = np.gradient(height, 1.0 / size * 40)
    n = np.stack([-gx, -gy, np.ones_like(gx)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return {"smooth RGB + edge": to8(np.clip(smooth, 0, 1)),
            "normal map xy": to8(0.5 + 0.5 * n[..., :2]),
            "value noise": to8(np.stack([value_noise(size, 6, s) for s in (2, 3, 4)], -1))}


def paint_material(size: int, model: str, out: str) -> str:
    """A 3-layer material of the model's own materials (no fit), with kd and roughness textures."""
    import svbrdf_mixture

    folder = pathlib.Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    for k, m in enumerate(svbrdf_mixture.masks(size), 1):
        Image.fromarray(to8(m)).save(folder / f"mask{k}.png")
    albedo = np.stack([0.25 + 0.6 * value_noise(size, 6, 10 + c) for c in range(3)], -1)
    Image.fromarray(to8(albedo)).save(folder / "albedo.png")
    Image.fromarray(to8(0.2 + 0.6 * value_noise(size, 5, 20))).save(folder / "rough.png")
    from hybridbrdf.cli import main
    code = main(["paint", model, "--base", "beige-fabric", "--layer", f"alum-bronze={folder / 'mask1.png'}",
                 "--layer", f"aventurnine={folder / 'mask2.png'}", "--kd", f"0={folder / 'albedo.png'}",
                 "--roughness", f"1={folder / 'rough.png'}", "--out", str(folder / "material"), "--quiet"])
    if code:
        raise SystemExit(f"hbrdf paint failed ({code})")
    return str(folder / "material")


def with_eta_and_latent(folder: str, out: str) -> str:
    """The painted material with an eta and a latent map on layer 1, which hbrdf paint does not
    write: eta its material's times a smooth 0.8..1.2 field, the latent code moving from its
    material's to layer 2's across the stripes mask (what a code map between two fits holds).
    Saved as PNG by the asset's own encoder (per-channel scale and offset for z)."""
    import svbrdf_mixture

    from hybridbrdf.svbrdf.asset import SVBRDF, load_svbrdf

    sv = load_svbrdf(folder)
    w, h = sv.size
    t = sv.model.tensors
    i1, i2 = sv.indices[1], sv.indices[2]
    field = 0.8 + 0.4 * value_noise(w, 3, 40)[:h, :w, None]
    mask = svbrdf_mixture.masks(w)[1][:h, :w, None]
    maps = [dict(m) for m in sv.maps]
    maps[1]["eta"] = np.clip(t["materials.eta"][i1] * field, 1.0, 10.0).astype(np.float32)
    maps[1]["latent"] = (t["materials.z"][i1] + (t["materials.z"][i2] - t["materials.z"][i1]) * mask).astype(np.float32)
    SVBRDF(sv.model, sv.layers, sv.size, sv.weights, maps, sv.addressing).save(out, format="png")
    return out


def painted_maps(folder: str) -> dict:
    """The folder's 8-bit maps by quantity: weights, kd, alpha (RG), eta, latent."""
    maps = {}
    for name in sorted(os.listdir(folder)):
        if name.endswith(".png"):
            rgb = np.asarray(Image.open(os.path.join(folder, name)).convert("RGB"))
            key = name[:-4]
            maps[key] = rgb[..., :2] if key.endswith("_alpha") else rgb
    return maps


def measure(img: np.ndarray, fmt: str, encoder: str, repeat: int) -> tuple:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        data = bcenc.encode_blocks(img, fmt, encoder)
        best = min(best, time.perf_counter() - t0)
    back = bcenc.decode_blocks(data, fmt, img.shape[1], img.shape[0])[..., :img.shape[2]]
    err = np.abs(back.astype(np.int64) - img)
    mse = float((err.astype(np.float64) ** 2).mean())
    psnr = 10 * np.log10(255.0 ** 2 / mse) if mse else float("inf")
    return psnr, int(err.max()), float(err.mean()), best * 1e3 / (img.shape[0] * img.shape[1] / 1e6)


def channels_for(fmt: str, img: np.ndarray) -> list:
    """The slices of ``img`` a format stores: BC4 each channel alone, BC5 pairs, BC1/BC7 RGB."""
    c = img.shape[2]
    if fmt == "bc4":
        return [img[..., k:k + 1] for k in range(c)]
    if fmt == "bc5":
        return [img[..., k:k + 2] for k in range(0, c - 1, 2)] + ([img[..., c - 1:c]] if c % 2 else [])
    return [img if c == 3 else np.concatenate([img, np.zeros_like(img[..., :3 - c])], -1)] if c <= 3 else [img[..., :3]]


def part1(contents: dict, repeat: int) -> None:
    print("\n## 1. Encoders: PSNR dB / max / mean error (8-bit steps) / encode ms per megatexel")
    print("| content | format | " + " | ".join(f"{e}" for e in ("etcpak", "quicktex", "bc7enc", "hybridbrdf")) + " |")
    print("|---|---|---|---|---|---|")
    for fmt in bcenc.BLOCK_FORMATS:
        for cname, img in contents.items():
            if (fmt in ("bc1", "bc7")) != (img.shape[2] >= 3) and fmt != "bc7":
                continue
            cells = []
            for enc in ("etcpak", "quicktex", "bc7enc", "hybridbrdf"):
                if enc not in bcenc.ENCODERS[fmt]:
                    cells.append("-")
                    continue
                parts = [measure(s, fmt, enc, repeat) for s in channels_for(fmt, img)]
                psnr = np.mean([p[0] for p in parts])
                cells.append(f"{psnr:.2f} / {max(p[1] for p in parts)} / {np.mean([p[2] for p in parts]):.3f} / "
                             f"{sum(p[3] for p in parts):.0f}")
            print(f"| {cname} | {fmt} | " + " | ".join(cells) + " |")


BYTES_PER_TEXEL = {"png8": None, "bc7": 1.0, "bc1": 0.5, "bc4": 0.5, "bc5": 1.0}


def part2(maps: dict) -> None:
    print("\n## 2. Per quantity, chosen encoders: max / mean error in stored steps (1/255), bytes per texel")
    print("| map | channels | 8-bit PNG | BC7 | BC1 | BC4 per channel | BC5 pairs (+ BC4) |")
    print("|---|---|---|---|---|---|---|")
    for name, img in maps.items():
        c = img.shape[2]
        cells = [f"0 / 0, {c} B"]
        for fmt in ("bc7", "bc1", "bc4", "bc5"):
            slices = channels_for(fmt, img)
            errs = [np.abs(bcenc.encode_decode(s, fmt)[..., :s.shape[2]].astype(int) - s) for s in slices]
            per = {"bc7": 1.0, "bc1": 0.5}.get(fmt)
            size = per if per else sum(0.5 if s.shape[2] == 1 else 1.0 for s in slices)
            cells.append(f"{max(e.max() for e in errs)} / {np.mean([e.mean() for e in errs]):.3f}, {size:g} B")
        print(f"| {name} | {c} | " + " | ".join(cells) + " |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--svbrdf", help="a painted folder; default: paint one here")
    ap.add_argument("--model", default=str(ROOT / "results" / "merl80_hybrid_32x3_10k.safetensors"))
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from hybridbrdf import simd_path
    print(f"# bench/bc_encoders.py (size {args.size}, {os.cpu_count()} CPUs, libhybridbrdf {simd_path()})")
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.svbrdf or paint_material(args.size, args.model, tmp)
        maps = painted_maps(with_eta_and_latent(folder, os.path.join(tmp, "with_eta_latent")))
        maps["normal map xy (synthetic)"] = synthetic(args.size)["normal map xy"]
        print("maps:", ", ".join(f"{k} {v.shape[1]}x{v.shape[0]}x{v.shape[2]}" for k, v in maps.items()))
        contents = {f"painted {k}": v for k, v in maps.items() if "synthetic" not in k}
        contents.update(synthetic(args.size))
        part1(contents, args.repeat)
        part2(maps)
    return 0


if __name__ == "__main__":
    sys.exit(main())
