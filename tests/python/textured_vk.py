"""Helpers of tests/python/test_codegen_textured_vk.py and bench/textured_bc_cost.py: the generated
GLSL, HLSL and Slang lookups of a textured folder (docs/CODEGEN.md, "A textured material in an
engine") run through real samplers under lavapipe by hbrdf_vk_runner --texture (cpp/tools/vk_runner.cpp:
combined image samplers for GLSL, one sampler and sampled images for HLSL and Slang), each map
uploaded with its mip chain: a KTX2 file in its own format (BC blocks as stored) or hbrdf raster's
HBTX file (8-bit RGBA levels of a PNG folder's maps, hybridbrdf.raster.textures)."""

from __future__ import annotations

import os
import pathlib
import re
import subprocess
from typing import List, Sequence

import numpy as np

from helpers import LAVAPIPE_ENV, RUNNER, compile_spirv

#: Per pair 9 floats in: uv, wi, wo and the level of detail; 6 out: f through hbrdf_texel_lod(lod),
#: then through hbrdf_texel_grad with derivatives of 2^lod texels along u and v (the same level).
GLSL_KERNEL = """#version 450
#extension GL_GOOGLE_include_directive : require
#define HBRDF_SRGB_TEXTURES {SRGB}
#include "m.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer In {{ float pairs[]; }};
layout(std430, binding = 1) writeonly buffer Out {{ float outv[]; }};
{TEXTURES}
void main() {{
    uint i = gl_GlobalInvocationID.x;
    if (i >= uint(pairs.length()) / 9u) return;
    vec2 uv = vec2(pairs[9u * i], pairs[9u * i + 1u]);
    vec3 wi = vec3(pairs[9u * i + 2u], pairs[9u * i + 3u], pairs[9u * i + 4u]);
    vec3 wo = vec3(pairs[9u * i + 5u], pairs[9u * i + 6u], pairs[9u * i + 7u]);
    float lod = pairs[9u * i + 8u];
    vec2 step = exp2(lod) / vec2({W}.0, {H}.0);
    vec3 f_lod = hbrdf_eval_texel(wi, wo, hbrdf_texel_lod({ARGS}, uv, lod));
    vec3 f_grad = hbrdf_eval_texel(wi, wo, hbrdf_texel_grad({ARGS}, uv, vec2(step.x, 0.0), vec2(0.0, step.y)));
    outv[6u * i] = f_lod.x; outv[6u * i + 1u] = f_lod.y; outv[6u * i + 2u] = f_lod.z;
    outv[6u * i + 3u] = f_grad.x; outv[6u * i + 4u] = f_grad.y; outv[6u * i + 5u] = f_grad.z;
}}
"""

HLSL_KERNEL = """#define HBRDF_SRGB_TEXTURES {SRGB}
#include "m.{EXT}"
[[vk::binding(0)]] RWStructuredBuffer<float> pairs : register(u0);
[[vk::binding(1)]] RWStructuredBuffer<float> outv : register(u1);
[[vk::binding(2)]] SamplerState map_sampler : register(s0);
{TEXTURES}
[numthreads(64, 1, 1)]
void main(uint3 gid : SV_DispatchThreadID) {{
    uint i = gid.x;
    uint count, stride;
    pairs.GetDimensions(count, stride);
    if (i >= count / 9u) return;
    float2 uv = float2(pairs[9u * i], pairs[9u * i + 1u]);
    float3 wi = float3(pairs[9u * i + 2u], pairs[9u * i + 3u], pairs[9u * i + 4u]);
    float3 wo = float3(pairs[9u * i + 5u], pairs[9u * i + 6u], pairs[9u * i + 7u]);
    float lod = pairs[9u * i + 8u];
    float2 step = exp2(lod) / float2({W}.0, {H}.0);
    float3 f_lod = hbrdf_eval_texel(wi, wo, hbrdf_texel_lod({ARGS}, uv, lod));
    float3 f_grad = hbrdf_eval_texel(wi, wo, hbrdf_texel_grad({ARGS}, uv, float2(step.x, 0.0), float2(0.0, step.y)));
    outv[6u * i] = f_lod.x; outv[6u * i + 1u] = f_lod.y; outv[6u * i + 2u] = f_lod.z;
    outv[6u * i + 3u] = f_grad.x; outv[6u * i + 4u] = f_grad.y; outv[6u * i + 5u] = f_grad.z;
}}
"""


def map_params(code: str, target: str) -> List[str]:
    """The lookup's map parameters, in binding order, from the generated hbrdf_texel_lod's signature."""
    sig = re.search(r"hbrdf_texel_lod\((.*?)\)", code).group(1)
    kind = "sampler2D" if target == "glsl" else r"Texture2D<float4>"
    return re.findall(kind + r" (map_\w+)", sig)


def kernel(code: str, target: str, size, srgb_textures: bool) -> str:
    """The compute kernel over the generated ``code`` (saved beside it as m.glsl / m.hlsl / m.slang)."""
    params = map_params(code, target)
    w, h = size
    if target == "glsl":
        textures = "\n".join(f"layout(binding = {2 + j}) uniform sampler2D {p};" for j, p in enumerate(params))
        return GLSL_KERNEL.format(SRGB=int(srgb_textures), TEXTURES=textures, ARGS=", ".join(params), W=w, H=h)
    textures = "\n".join(f"[[vk::binding({3 + j})]] Texture2D<float4> {p} : register(t{j});" for j, p in enumerate(params))
    return HLSL_KERNEL.format(SRGB=int(srgb_textures), EXT=target, TEXTURES=textures, ARGS=", ".join(params + ["map_sampler"]),
                              W=w, H=h)


def compile_kernel(work: pathlib.Path, code: str, target: str, size, srgb_textures: bool) -> pathlib.Path:
    """The kernel compiled to SPIR-V (glslang for GLSL and HLSL, slangc for Slang), validated by spirv-val."""
    work.mkdir(parents=True, exist_ok=True)
    (work / f"m.{target}").write_text(code)
    src = work / {"glsl": "k.comp", "hlsl": "k.hlsl", "slang": "k.slang"}[target]
    src.write_text(kernel(code, target, size, srgb_textures))
    spv = work / f"k_{target}_{int(srgb_textures)}.spv"
    if target == "slang":
        from slang_wgsl_tools import compile_slang

        compile_slang(src, spv, include_dir=work)
    else:
        compile_spirv(src, spv, target, include_dir=work)
    return spv


def folder_textures(folder: pathlib.Path, work: pathlib.Path) -> List[pathlib.Path]:
    """The files hbrdf_vk_runner --texture uploads for ``folder``'s maps, in the lookup's parameter
    order: a KTX2 folder's own files; HBTX files of a PNG folder's 8-bit levels."""
    from hybridbrdf.codegen.textured import textured_plan
    from hybridbrdf.raster.textures import write_textures

    plan = textured_plan(folder)
    if all(m["file"].endswith(".ktx2") for m in plan["maps"]):
        return [folder / m["file"] for m in plan["maps"]]
    work.mkdir(parents=True, exist_ok=True)
    return write_textures(folder, plan, work)


def run(spv: pathlib.Path, textures: Sequence[pathlib.Path], pairs: np.ndarray, separate_sampler: bool, *,
        clamp: bool = False, nearest_mip: bool = False, repeat: int = 0, validation: bool = True, check: bool = True,
        extra: Sequence[str] = ()):
    """hbrdf_vk_runner on ``pairs`` (n, 9) with ``textures`` bound (``extra``: more of its flags), with
    the validation layer unless told not; returns ((n, 6) float32, or None where it failed, the finished
    process). ``check``: assert that it succeeded."""
    work = spv.parent
    n = len(pairs)
    np.ascontiguousarray(pairs, np.float32).tofile(work / "in.bin")
    out = work / "out.bin"
    if out.exists():
        out.unlink()
    argv = [str(RUNNER), str(spv), str(work / "in.bin"), str(out), str(n), "6"]
    for t in textures:
        argv += ["--texture", str(t)]
    argv += (["--separate-sampler"] if separate_sampler else []) + (["--clamp"] if clamp else []) + \
        (["--nearest-mip"] if nearest_mip else []) + (["--repeat", str(repeat)] if repeat else []) + \
        (["--validation"] if validation else []) + list(extra)
    r = subprocess.run(argv, capture_output=True, text=True, env=dict(os.environ, **LAVAPIPE_ENV))
    if check:
        assert r.returncode == 0, r.stderr[-3000:]
    got = np.fromfile(out, np.float32).reshape(n, 6) if r.returncode == 0 else None
    return got, r


def timings(process) -> dict:
    """The runner's timings of a --repeat run: best_ms (host clock), best_cpu_ms (the process's CPU
    time: lavapipe's threads) and, where the queue has timestamps, best_gpu_ms and median_gpu_ms."""
    return {k: float(v) for k, v in re.findall(r"^(\w+_ms) (\S+)$", process.stdout, re.M)}
