"""Normal maps in the generated code of a textured folder (docs/CODEGEN.md, "A textured material in an
engine"; docs/SVBRDF.md, "Normal maps"): ``hbrdf-codegen DIR`` on a folder with a normal map reads it
as one more map (``map_normal``, last), rebuilds z, and shades each texel in its frame by the library's
rule. Checked in every dialect against libhybridbrdf (``_core.Svbrdf``, the tracer's) on the same folder:

- GLSL, HLSL and Slang under lavapipe (glsl/texel_decode.comp.j2 through hbrdf_vk_runner), WGSL through
  wgpu and the C++ header compiled and run: hbrdf_decode_texel of the stored map values at texel
  centres, then hbrdf_eval_texel, hbrdf_pdf_texel and hbrdf_sample_texel, against Svbrdf::eval, pdf
  and sample there;
- WGSL through real wgpu samplers (textured_engine.py): anywhere, against the sampler's filter in
  float64 with the frame rotated by a float64 reference written from docs/SVBRDF.md, within one 8-bit
  step per map channel; with the folder's mip chain uploaded, at lod 1 and 2 against the library's
  trilinear lookup (the chain's widened alpha and normalised normals);
- hbrdf_normal_frame on an engine's own TBN (both handednesses) against that reference's frame;
- docs/CODEGEN.md's WGSL fragment shader with the two lines the section gives for a normal map, drawn.
"""

from __future__ import annotations

import re
import subprocess

import numpy as np
import pytest

from hybridbrdf import _core
from hybridbrdf.codegen.main import generate_textured
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.svbrdf import load_svbrdf
from hybridbrdf.svbrdf.maps import read_map

import textured_engine as te
from helpers import skip_without_vulkan
from shader_kernels import render_shader
from slang_wgsl_tools import run_kernel, skip_without_slang, skip_without_wgpu
from test_codegen_textured import _section

#: Pairs whose f is 0 on one side and not on the other: a direction within float rounding of the
#: shading horizon (the library builds the normal in double, the shaders in float).
BOUNDARY = 2e-3


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return te.make_folder(tmp_path_factory.mktemp("normal"), "normal")


def _centre_rows(folder, code, n=3000, seed=3):
    """Pairs at random texel centres: uv, wi, wo, u, and the rows the kernels read (wi, wo, u, then
    each map's stored values in the lookup's parameter order)."""
    files = re.findall(r"//   map_\w+: (\S+) ", code)
    assert files[-1] == "normal.png"  # the normal map, last
    rng = np.random.default_rng(seed)
    cols, rows = rng.integers(0, te.W, n), rng.integers(0, te.H, n)
    uv = np.stack([(cols + 0.5) / te.W, (rows + 0.5) / te.H], axis=1).astype(np.float32)
    wi, wo = (cosine_directions(rng, n).astype(np.float32) for _ in range(2))
    u = rng.uniform(0, 1, (n, 2)).astype(np.float32)
    stored = np.concatenate([read_map(folder / f)[0][rows, cols] for f in files], axis=1)
    return uv, wi, wo, u, np.concatenate([wi, wo, u, stored], 1).astype(np.float32), len(files)


def _library(folder, uv, wi, wo, u):
    lib = _core.Svbrdf(str(folder))
    f = lib.eval(uv, wi, wo, "bilinear").astype(np.float64)
    pdf = lib.pdf(uv, wi, wo, "mis", "bilinear").astype(np.float64)
    dirs, sample_pdf, _ = lib.sample(uv, wo, u)
    return f, pdf, dirs.astype(np.float64), sample_pdf.astype(np.float64)


def _check(got, ref):
    f_ref, pdf_ref, dirs_ref, spdf_ref = ref
    assert np.isfinite(got).all()
    f, pdf, dirs, spdf = got[:, :3], got[:, 3], got[:, 4:7], got[:, 7]
    cut = (f_ref == 0).all(axis=1)
    assert 0.05 < cut.mean() < 0.6  # the control: the rule cuts pairs off, most stay
    assert ((f == 0).all(axis=1) != cut).mean() <= BOUNDARY
    big = np.abs(f_ref) > 1e-6
    both = big & (np.abs(f) > 0)
    assert (np.abs(f - f_ref)[both] / np.abs(f_ref)[both]).max() < 1e-4
    p = (pdf_ref > 1e-6) & (pdf > 0)
    assert (np.abs(pdf[p] - pdf_ref[p]) / pdf_ref[p]).max() < 1e-3
    drawn = (spdf_ref > 1e-6) & (spdf > 1e-6)
    assert drawn.mean() > 0.5 and ((spdf > 0) != (spdf_ref > 0)).mean() <= BOUNDARY
    assert np.abs(dirs[drawn] - dirs_ref[drawn]).max() < 2e-3  # the same direction, in the geometric frame
    assert (np.abs(spdf[drawn] - spdf_ref[drawn]) / spdf_ref[drawn]).max() < 1e-3
    assert (dirs[drawn, 2] > 0).all()


@pytest.mark.parametrize("target", ["glsl", "hlsl", "slang", "wgsl"])
def test_texel_functions_run_like_the_library(folder, tmp_path, target):
    """hbrdf_decode_texel of a texel's stored values (a sampler's answer at its centre), then eval, pdf
    and sample, under lavapipe, against libhybridbrdf's Svbrdf at that centre."""
    if target == "wgsl":
        skip_without_wgpu()
    elif target == "slang":
        skip_without_slang()
    else:
        skip_without_vulkan()
    code = generate_textured(folder, target)
    uv, wi, wo, u, rows, maps = _centre_rows(folder, code)
    extra = {"model_code": code} if target == "wgsl" else {}
    (tmp_path / f"m.{target}").write_text(code)
    kernel = render_shader(f"texel_decode.comp.{target}", include=f"m.{target}", n=len(rows), maps=maps, **extra)
    _check(run_kernel(tmp_path, target, kernel, rows, out_floats=8), _library(folder, uv, wi, wo, u))


CPP_DRIVER = r"""
#include <cstdio>
#include <cstdlib>
#include "m.h"
int main() {
    unsigned n = 0, k = 0;
    if (std::fread(&n, 4, 1, stdin) != 1 || std::fread(&k, 4, 1, stdin) != 1) return 1;
    const std::size_t count = std::size_t(n) * (8 + 3 * k);
    float* const in = static_cast<float*>(std::calloc(count + 1, 4));  // not <vector>: 0.13 s less g++ a compile
    if (in == nullptr || std::fread(in, 4, count, stdin) != count) return 1;
    for (unsigned i = 0; i < n; ++i) {
        const float* p = &in[std::size_t(i) * (8 + 3 * k)];
        const hbrdf::float3 wi(p[0], p[1], p[2]), wo(p[3], p[4], p[5]);
        const float* s = p + 8;
        const hbrdf::HbrdfTexel t = hbrdf::hbrdf_decode_texel(ARGS);
        const hbrdf::float3 f = hbrdf::hbrdf_eval_texel(wi, wo, t);
        float sample_pdf = 0.f;
        const hbrdf::float3 d = hbrdf::hbrdf_sample_texel(wo, hbrdf::float2(p[6], p[7]), t, sample_pdf);
        const float out[8] = {f.x, f.y, f.z, hbrdf::hbrdf_pdf_texel(wi, wo, t), d.x, d.y, d.z, sample_pdf};
        std::fwrite(out, 4, 8, stdout);
    }
    return 0;
}
"""


def _compile_cpp(tmp_path, code, driver):
    (tmp_path / "m.h").write_text(code)
    (tmp_path / "d.cpp").write_text(driver)
    r = subprocess.run(["g++", "-std=c++17", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror", "-I", str(tmp_path),
                        str(tmp_path / "d.cpp"), "-o", str(tmp_path / "d")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[:3000]
    return tmp_path / "d"


def test_cpp_texel_functions_run_like_the_library(folder, tmp_path):
    code = generate_textured(folder, "cpp")
    uv, wi, wo, u, rows, maps = _centre_rows(folder, code)
    args = ", ".join(f"hbrdf::float3(s[{3 * j}], s[{3 * j + 1}], s[{3 * j + 2}])" for j in range(maps))
    exe = _compile_cpp(tmp_path, code, CPP_DRIVER.replace("ARGS", args))
    payload = np.asarray([len(rows), maps], np.uint32).tobytes() + rows.tobytes()
    out = subprocess.run([str(exe)], input=payload, capture_output=True)
    assert out.returncode == 0
    _check(np.frombuffer(out.stdout, np.float32).reshape(-1, 8).astype(np.float64), _library(folder, uv, wi, wo, u))


FRAME_DRIVER = r"""
#include <cstdio>
#include "m.h"
int main() {
    float p[12];
    while (std::fread(p, 4, 12, stdin) == 12) {
        const hbrdf::HbrdfFrame s = hbrdf::hbrdf_normal_frame(hbrdf::float3(p[0], p[1], p[2]), hbrdf::float3(p[3], p[4], p[5]),
                                                             hbrdf::float3(p[6], p[7], p[8]), hbrdf::float3(p[9], p[10], p[11]));
        const float out[9] = {s.t.x, s.t.y, s.t.z, s.b.x, s.b.y, s.b.z, s.n.x, s.n.y, s.n.z};
        std::fwrite(out, 4, 9, stdout);
    }
    return 0;
}
"""


def test_normal_frame_on_an_engines_tbn(folder, tmp_path):
    """hbrdf_normal_frame(t, b, n, tn) on a random world-space frame, right- and left-handed (glTF
    TANGENT.w = -1: b = -(n x t)), is that frame's image of the float64 reference frame built in
    tangent space: (t b n) [t_s b_s n_s]."""
    exe = _compile_cpp(tmp_path, generate_textured(folder, "cpp"), FRAME_DRIVER)
    rng = np.random.default_rng(9)
    n = 2000
    q, _ = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    t, nrm = q[:, :, 0], q[:, :, 2]
    hand = np.where(rng.uniform(size=n) < 0.5, -1.0, 1.0)
    b = hand[:, None] * np.cross(nrm, t)
    tbn = np.stack([t, b, nrm], 2)  # columns t, b, n
    xy = rng.uniform(-0.7, 0.7, (n, 2))
    tn = np.concatenate([xy, np.sqrt(np.maximum(0, 1 - (xy ** 2).sum(1, keepdims=True)))], 1)
    payload = np.concatenate([t, b, nrm, tn], 1).astype(np.float32).tobytes()
    out = subprocess.run([str(exe)], input=payload, capture_output=True)
    assert out.returncode == 0
    got = np.frombuffer(out.stdout, np.float32).reshape(n, 3, 3).astype(np.float64)  # rows t_s, b_s, n_s
    eye = np.eye(3)
    # frames[:, i] = the reference's t_s, b_s, n_s in tangent space: component k is e_k's coordinate i.
    frames = np.stack([te.shading_directions(xy, np.repeat(eye[None, k], n, 0), np.repeat(eye[None, k], n, 0))[0]
                       for k in range(3)], 2)
    want = np.einsum("nij,nkj->nki", tbn, frames)
    assert 0.3 < (hand < 0).mean() < 0.7  # the control: both handednesses
    assert np.abs(got - want).max() < 1e-5


def test_wgsl_samplers_read_the_normal_map_like_the_reference(folder):
    """The WGSL lookup through wgpu's samplers anywhere on the map (between texels, beyond [0, 1]):
    the sampler's filter of the stored values in float64, the frame rotated in float64, within one
    8-bit step per map channel (test_codegen_textured.py's tolerance)."""
    skip_without_wgpu()
    rng = np.random.default_rng(17)
    n = 3000
    uv = rng.uniform(-1, 2, (n, 2)).astype(np.float32).astype(np.float64)
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    got = te.run_wgsl_textured(generate_textured(folder, "wgsl"), folder, np.concatenate([uv, wi, wo], 1), False)
    assert np.array_equal(got[:, :3], got[:, 3:])
    f = got[:, :3].astype(np.float64)
    ref = te.eval_reference(folder, uv, wi, wo, False)
    tol = te.step_tolerance(folder, uv, wi, wo, False, ref) + 1e-4 * np.abs(ref) + 1e-6
    off = (np.abs(f - ref) > tol).any(axis=1)
    assert off.mean() <= BOUNDARY, np.max((np.abs(f - ref) - tol) / np.maximum(np.abs(ref), 1e-6))
    assert 0.05 < (ref == 0).all(axis=1).mean() < 0.6
    flat = te.eval_reference(folder, uv, wi, wo, False, ignore_normal=True)
    assert (np.abs(flat - ref) > tol).any(axis=1).mean() > 0.5  # the control: the map matters


def test_wgsl_reads_the_chains_levels_like_the_library(folder, tmp_path):
    """The folder with its mip chain (SVBRDF.with_mips: normalised mean normals, alpha widened by
    their spread): its own levels uploaded, the lookup at lod 1 and 2 (and through textureSampleGrad)
    at the level's texel centres is libhybridbrdf's trilinear lookup at that lod."""
    skip_without_wgpu()
    load_svbrdf(folder).with_mips().save(tmp_path / "mip")
    mipped = tmp_path / "mip"
    saved = load_svbrdf(mipped)
    code = generate_textured(mipped, "wgsl")
    rng = np.random.default_rng(23)
    n = 1500
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    uvs = []
    for lod in (1, 2):
        size = np.array([te.W >> lod, te.H >> lod])
        uvs.append((rng.integers(0, size, (n, 2)) + 0.5) / size)
    # Both levels in one dispatch (one pipeline: lavapipe compiling it is most of the test's time).
    pairs = np.concatenate([np.concatenate([uv, wi, wo], 1) for uv in uvs])
    out = te.run_wgsl_textured(code, mipped, pairs, False, lod=np.repeat([1, 2], n))
    for k, (lod, uv) in enumerate(zip((1, 2), uvs)):
        got = out[k * n:(k + 1) * n]
        lib = saved.eval(uv, wi, wo, lod=float(lod))
        for f in (got[:, :3], got[:, 3:]):
            assert ((f == 0).all(axis=1) != (lib == 0).all(axis=1)).mean() <= BOUNDARY
            both = (np.abs(lib) > 1e-6) & (np.abs(f) > 0)
            assert (np.abs(f - lib)[both] / np.abs(lib)[both]).max() < 1e-4, lod
        level0 = saved.eval(uv, wi, wo)
        assert (np.abs(level0 - lib) > 0.01 * np.abs(lib)).any(axis=1).mean() > 0.3  # the control: level 0 differs


def test_documented_normal_map_lines_draw_the_library(tmp_path):
    """docs/CODEGEN.md's textured.wgsl with the section's two lines for a normal map (the texture's
    declaration after the sampler's, the lookup's call in place of textured.wgsl's), drawn by wgpu on
    lavapipe, one pixel per texel centre: the library's SVBRDF.eval(uv, wi, wo) wi.z."""
    skip_without_wgpu()
    text = _section()
    base = dict(re.findall(r"```(?:glsl|hlsl|wgsl)\n// (\S+)\n(.*?)```", text, re.S))["textured.wgsl"]
    delta = re.search(r"```wgsl\n// textured_normal\.wgsl[^\n]*\n(.*?)```", text, re.S).group(1).splitlines()
    declaration, call = delta[0], delta[1]
    sampler_line = next(line for line in base.splitlines() if "var u_sampler" in line)
    call_line = next(line for line in base.splitlines() if "hbrdf_texel_grad" in line)
    shader = base.replace(sampler_line, sampler_line + "\n" + declaration).replace(call_line, call)
    folder = te.make_folder(tmp_path, "doc_normal")  # the section's folder, with a normal map
    light, eye = np.array([0.3, -0.2, 0.9]), np.array([-0.4, 0.1, 0.8])
    light, eye = light / np.linalg.norm(light), eye / np.linalg.norm(eye)
    image = te.draw_wgsl_fragment(generate_textured(folder, "wgsl") + shader, folder / "weights.png", light, eye,
                                  normal_png=folder / "normal.png")
    rows, cols = np.mgrid[0:te.H, 0:te.W]
    uv = np.stack([(cols.ravel() + 0.5) / te.W, (rows.ravel() + 0.5) / te.H], axis=1)
    n = len(uv)
    lib = load_svbrdf(folder).eval(uv, np.repeat(light[None], n, 0), np.repeat(eye[None], n, 0)) * light[2]
    flat = te.eval_reference(folder, uv, np.repeat(light[None], n, 0), np.repeat(eye[None], n, 0), False, ignore_normal=True)
    assert (np.abs(flat * light[2] - lib) > 0.01 * lib).mean() > 0.5  # the control: the map matters here
    big = lib > 1e-6
    assert big.mean() > 0.5 and np.array_equal(image.reshape(-1, 3) == 0, lib == 0)
    assert (np.abs(image.reshape(-1, 3) - lib)[big] / lib[big]).max() < 1e-4
