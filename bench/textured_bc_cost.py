#!/usr/bin/env python3
"""What reading a textured material's maps as GPU block formats with mip chains costs the generated
shader (issue 58's cost target; docs/SVBRDF.md, "KTX2 maps").

The generated WGSL of a textured folder (`hbrdf-codegen DIR --target wgsl`: `hbrdf_texel_lod` and
`hbrdf_texel_grad` through real samplers, then `hbrdf_eval_texel`) in one compute kernel under
lavapipe (wgpu, the CPU adapter with `texture-compression-bc`), the same kernel and pairs over three
uploads of the same maps: today's single uncompressed level (rgba8unorm; kd rgba8unorm-srgb), the
uncompressed mip chain, and the chain in the KTX2 block formats `SVBRDF.save(format="ktx2")` writes
(BC5 weights and alpha, sRGB BC1 kd; the blocks encoded as the writer does), and that chain with
kd in sRGB BC7 (`kd_format="bc7"`). The material:
`results/rgl54_fast.safetensors`' three bench/svbrdf_mixture.py layers, 512x512, with kd and alpha
maps (bench/svbrdf_mips.py's noise). Printed: Mpairs/s per upload (median of interleaved runs) and
the ratio to today's; lavapipe decodes blocks in software, so compare ratios of one run, and on a
GPU (where a block format reads a quarter of the bytes) run it there.

The same for the generated GLSL (`--target glsl`; issue 58's cost target names it): the kernel of
tests/python/textured_vk.py (`hbrdf_texel_lod` and `hbrdf_texel_grad` per pair, `HBRDF_SRGB_TEXTURES`
1) run by hbrdf_vk_runner, the maps bound as combined image samplers: today's single level and the
rgba8 chain as hbrdf raster's HBTX files (R8G8B8A8_UNORM, kd R8G8B8A8_SRGB), the chain in the KTX2
folder's own files (BC blocks as stored: kd in BC1 sRGB, the writer's default), and those with kd in BC7 sRGB. Each variant a runner process of `--repeat 3` dispatches
(the best), the variants interleaved `--runs` times; printed the median of the best host-clock times
and of the best CPU times of the runner process (lavapipe's threads: the work, whatever else the
machine runs).

    python bench/textured_bc_cost.py [--pairs 262144] [--lod 2] [--runs 5] [--target wgsl|glsl|both]
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))
sys.path.insert(0, str(ROOT / "bench"))

import hybridbrdf as hb  # noqa: E402
from hybridbrdf.codegen import generate_textured  # noqa: E402
from hybridbrdf.evaluate.directions import cosine_directions  # noqa: E402
from hybridbrdf.fit.painting import composite  # noqa: E402
from hybridbrdf.svbrdf import SVBRDF, bcenc  # noqa: E402
from hybridbrdf.svbrdf.maps import read_map  # noqa: E402

from svbrdf_mips import material as noise_maps  # noqa: E402
from svbrdf_mixture import LAYERS, SIZE, masks  # noqa: E402
from textured_engine import WGSL_KERNEL, map_params  # noqa: E402
import textured_vk  # noqa: E402

#: WebGPU's names of the block formats entries.KTX2_FORMATS writes.
BLOCK = {"BC4_UNORM_BLOCK": ("bc4-r-unorm", "bc4"), "BC5_UNORM_BLOCK": ("bc5-rg-unorm", "bc5"),
         "BC7_UNORM_BLOCK": ("bc7-rgba-unorm", "bc7"), "BC7_SRGB_BLOCK": ("bc7-rgba-unorm-srgb", "bc7"),
         "BC1_RGB_SRGB_BLOCK": ("bc1-rgba-unorm-srgb", "bc1")}
CHANNELS = {"bc1": 3, "bc4": 1, "bc5": 2, "bc7": 4}
#: The KTX2 variants: the folder as SVBRDF.save(format="ktx2") writes it (kd in BC1 sRGB, the
#: default) and with kd in BC7 sRGB (kd_format="bc7").
KTX2_VARIANTS = {"KTX2 folder (kd BC1 sRGB)": "ktx2", "KTX2, kd in BC7 sRGB": "ktx2_bc7"}


def device():
    import wgpu

    from helpers import LVP_ICD

    os.environ["VK_DRIVER_FILES"] = LVP_ICD
    os.environ.setdefault("XDG_RUNTIME_DIR", tempfile.mkdtemp(prefix="hbrdf-xdg-"))
    from wgpu.backends.wgpu_native.extras import set_instance_extras

    set_instance_extras(backends=["Vulkan"])
    adapter = next(a for a in wgpu.gpu.enumerate_adapters_sync() if a.info["adapter_type"] == "CPU")
    return adapter, adapter.request_device_sync(required_features=["texture-compression-bc"])


def upload(dev, chain, fmt):
    """A texture of ``fmt`` holding ``chain`` (levels of 8-bit (H, W, 3)), block-encoded for BC formats."""
    import wgpu

    h, w = chain[0].shape[:2]
    tex = dev.create_texture(size=(w, h, 1), format=fmt, mip_level_count=len(chain),
                             usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST)
    for level, values in enumerate(chain):
        lh, lw = values.shape[:2]
        if fmt.startswith("bc"):
            kind = fmt.split("-")[0]
            texels = np.ascontiguousarray(values[..., :min(3, CHANNELS[kind])])
            data = bcenc.encode_blocks(texels, kind)
            bw, bh = -(-lw // 4), -(-lh // 4)
            dev.queue.write_texture({"texture": tex, "mip_level": level}, data,
                                    {"bytes_per_row": bw * len(data) // (bw * bh), "rows_per_image": bh},
                                    (bw * 4, bh * 4, 1))
        else:
            rgba = np.concatenate([values, np.full((lh, lw, 1), 255, np.uint8)], axis=2)
            dev.queue.write_texture({"texture": tex, "mip_level": level}, np.ascontiguousarray(rgba),
                                    {"bytes_per_row": 4 * lw, "rows_per_image": lh}, (lw, lh, 1))
    return tex.create_view()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=1 << 18)
    ap.add_argument("--lod", type=float, default=2.0, help="the lookups' level of detail (2: 4x minified)")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--target", choices=("wgsl", "glsl", "both"), default="both",
                    help="the generated dialect timed: WGSL through wgpu, GLSL through hbrdf_vk_runner, or both")
    args = ap.parse_args()
    model = hb.load_model(ROOT / "results" / "rgl54_fast.safetensors")
    names = [n for n, _ in LAYERS]
    weights = np.concatenate([composite(masks()), np.zeros((SIZE, SIZE, 1))], axis=2).astype(np.float32)
    _, maps = noise_maps(model, SIZE, np.random.default_rng(11))
    layer_maps = [{"kd": maps["kd"][1]}, {"alpha": maps["alpha"][1]}, {}]
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="textured_bc_"))
    SVBRDF(model, names, (SIZE, SIZE), weights, layer_maps).save(tmp / "png1", format="png")
    SVBRDF(model, names, (SIZE, SIZE), weights, layer_maps).with_mips().save(tmp / "png", format="png")
    SVBRDF(model, names, (SIZE, SIZE), weights, layer_maps).with_mips().save(tmp / "ktx2", format="ktx2")
    SVBRDF(model, names, (SIZE, SIZE), weights, layer_maps).with_mips().save(tmp / "ktx2_bc7", format="ktx2", kd_format="bc7")
    rng = np.random.default_rng(3)
    n = args.pairs
    pairs = np.concatenate([rng.uniform(0, 1, (n, 2)), cosine_directions(rng, n), cosine_directions(rng, n)], axis=1)
    print(f"{n} pairs, lod {args.lod}; generated code of a {SIZE}x{SIZE} three-layer folder (weights, sRGB kd, alpha "
          f"maps; rgl54_fast 16x2); hybridbrdf {hb.__version__}; median of {args.runs} interleaved runs")
    if args.target in ("wgsl", "both"):
        wgsl_times(args, tmp, pairs)
    if args.target in ("glsl", "both"):
        glsl_times(args, tmp, pairs)
    return 0


def glsl_times(args, tmp: pathlib.Path, pairs: np.ndarray) -> None:
    """The generated GLSL under hbrdf_vk_runner over the three uploads (module docstring)."""
    n = len(pairs)
    code = generate_textured(tmp / "png", "glsl")
    spv = textured_vk.compile_kernel(tmp / "glsl", code, "glsl", (SIZE, SIZE), True)
    rows = np.concatenate([pairs, np.full((n, 1), args.lod)], axis=1)
    variants = {"rgba8, one level (today)": textured_vk.folder_textures(tmp / "png1", tmp / "hbtx1"),
                "rgba8, mip chain": textured_vk.folder_textures(tmp / "png", tmp / "hbtx"),
                **{v: textured_vk.folder_textures(tmp / d, tmp / "unused") for v, d in KTX2_VARIANTS.items()}}
    times = {v: {"best_ms": [], "best_cpu_ms": []} for v in variants}
    outs = {}
    for _ in range(args.runs):
        for v, textures in variants.items():
            out, process = textured_vk.run(spv, textures, rows, False, repeat=3, validation=False)
            outs[v] = out
            for key, t in textured_vk.timings(process).items():
                if key in times[v]:
                    times[v][key].append(t)
    device = process.stdout.splitlines()[0].split(" ", 1)[1]
    print(f"GLSL, hbrdf_vk_runner on {device}, combined image samplers; best of 3 dispatches per run")
    base = {k: np.median(times["rgba8, one level (today)"][k]) for k in ("best_ms", "best_cpu_ms")}
    ref = outs["rgba8, mip chain"]
    for v in variants:
        wall, cpu = np.median(times[v]["best_ms"]), np.median(times[v]["best_cpu_ms"])
        diff = np.abs(outs[v] - ref).max() / np.abs(ref).max()
        # Each run's own ratio (the variants of one run are interleaved): their spread over runs.
        per_run = [np.array(times[v][k]) / np.array(times["rgba8, one level (today)"][k]) for k in ("best_ms", "best_cpu_ms")]
        print(f"  {v:28s} {n / wall / 1e3:7.2f} Mpairs/s   {wall / base['best_ms']:5.2f}x today's time, "
              f"{cpu / base['best_cpu_ms']:5.2f}x its CPU time (per run {per_run[0].min():.2f}-{per_run[0].max():.2f}x, "
              f"CPU {per_run[1].min():.2f}-{per_run[1].max():.2f}x)   (f against the rgba8 chain: max {diff:.3g} of max f)")


def wgsl_times(args, tmp: pathlib.Path, pairs: np.ndarray) -> None:
    """The generated WGSL through wgpu over the three uploads (module docstring)."""
    import wgpu

    n = len(pairs)
    code = generate_textured(tmp / "png", "wgsl")
    params = map_params(code)
    index = {e["file"].split(".")[0]: e for e in json.loads((tmp / "png" / "svbrdf.json").read_text())["maps"]}
    ktx2 = {d: {e["file"].split(".")[0]: e for e in json.loads((tmp / d / "svbrdf.json").read_text())["maps"]}
            for d in KTX2_VARIANTS.values()}
    from hybridbrdf.svbrdf.ktx2 import read_ktx2

    adapter, dev = device()
    textures = "\n".join(f"@group(0) @binding({3 + j}) var {p}: texture_2d<f32>;" for j, p in enumerate(params))
    kernel = code + WGSL_KERNEL.format(TEXTURES=textures, ARGS=", ".join(params + ["map_sampler"]), LOD=f"{args.lod:.1f}",
                                       DX=f"vec2f({2 ** args.lod / SIZE!r}, 0.0)", DY=f"vec2f(0.0, {2 ** args.lod / SIZE!r})")
    pipeline = dev.create_compute_pipeline(layout="auto", compute={
        "module": dev.create_shader_module(code=kernel), "entry_point": "main", "constants": {"HBRDF_SRGB_TEXTURES": 1.0}})
    buf_in = dev.create_buffer_with_data(data=pairs.astype(np.float32).ravel(), usage=wgpu.BufferUsage.STORAGE)
    buf_out = dev.create_buffer(size=24 * n, usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
    sampler = dev.create_sampler(address_mode_u="repeat", address_mode_v="repeat", mag_filter="linear",
                                 min_filter="linear", mipmap_filter="linear")
    groups = {}
    for variant in ("rgba8, one level (today)", "rgba8, mip chain", *KTX2_VARIANTS):
        views = []
        for p in params:
            stem = p[len("map_"):]
            entry = index[stem]
            files = [entry["file"]] + (list(entry.get("mips", [])) if "one level" not in variant else [])
            chain = [np.rint(read_map(tmp / "png" / f)[0] * 255).astype(np.uint8) for f in files]
            srgb = all(d is None or d["transfer"] == "srgb" for d in entry["decode"])
            if variant.startswith("KTX2"):
                d = KTX2_VARIANTS[variant]
                fmt = BLOCK[read_ktx2(tmp / d / ktx2[d][stem]["file"]).name][0]
            else:
                fmt = "rgba8unorm-srgb" if srgb else "rgba8unorm"
            views.append(upload(dev, chain, fmt))
        entries = [{"binding": 0, "resource": {"buffer": buf_in}}, {"binding": 1, "resource": {"buffer": buf_out}},
                   {"binding": 2, "resource": sampler}] + [{"binding": 3 + j, "resource": v} for j, v in enumerate(views)]
        groups[variant] = dev.create_bind_group(layout=pipeline.get_bind_group_layout(0), entries=entries)

    def run(group):
        encoder = dev.create_command_encoder()
        compute = encoder.begin_compute_pass()
        compute.set_pipeline(pipeline)
        compute.set_bind_group(0, group)
        compute.dispatch_workgroups((n + 63) // 64, 1, 1)
        compute.end()
        t0 = time.perf_counter()
        dev.queue.submit([encoder.finish()])
        out = np.frombuffer(dev.queue.read_buffer(buf_out), np.float32)
        return time.perf_counter() - t0, out

    times = {v: [] for v in groups}
    outs = {}
    for v, g in groups.items():
        outs[v] = run(g)[1].reshape(n, 6).copy()  # warm: the first dispatch of a bind group
    for _ in range(args.runs):
        for v, g in groups.items():
            times[v].append(run(g)[0])
    print(f"WGSL, wgpu on {adapter.info['device']}")
    base = np.median(times["rgba8, one level (today)"])
    ref = outs["rgba8, mip chain"]
    for v in groups:
        t = np.median(times[v])
        diff = np.abs(outs[v] - ref).max() / np.abs(ref).max()
        print(f"  {v:28s} {n / t / 1e6:7.2f} Mpairs/s   {t / base:5.2f}x today's time   (f against the rgba8 chain: "
              f"max {diff:.3g} of max f)")


if __name__ == "__main__":
    raise SystemExit(main())
