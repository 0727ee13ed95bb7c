"""``hbrdf-codegen DIR`` on a textured material's folder (docs/CODEGEN.md, "A textured material in an
engine"): the code holds exactly the layers' materials and the maps' sampler lookup and decode; the
section's fragment shaders compile as printed (glslang for GLSL and HLSL, slangc, naga); the lookup
compiles in every dialect for folders with every kind of map; the C++ decode gives the library's
texel; and the WGSL lookup RUNS through real wgpu samplers on lavapipe against libhybridbrdf
(textured_engine.py: the reference and the tolerance, one 8-bit step per map channel, measured here
as lavapipe's texture precision); the WGSL fragment shader of the section, drawn."""

from __future__ import annotations

import contextlib
import io
import json
import pathlib
import re
import shlex
import shutil
import subprocess

import numpy as np
import pytest

from hybridbrdf.codegen.main import generate_textured
from hybridbrdf.codegen.main import main as codegen
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.svbrdf import load_svbrdf
from hybridbrdf.svbrdf.maps import read_map

import textured_engine as te
from helpers import skip_without_vulkan
from slang_wgsl_tools import find_slangc, patch_opsource, skip_without_slang, skip_without_wgpu, wgsl_errors

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("textured")
    return {kind: te.make_folder(tmp / kind, kind) for kind in ("doc", "linear", "all", "normal")}


def _run_codegen(argv):
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        rc = codegen(argv)
    return rc, out.getvalue(), err.getvalue()


def test_folder_gives_exactly_its_layers_and_its_maps(folders, tmp_path):
    """The layers' materials, each once (the linear folder names one material twice), and no other;
    per map its decode constants as the index says; the one-line refusals of what does not apply."""
    folder = folders["linear"]
    index = json.loads((folder / "svbrdf.json").read_text())
    layers = [layer["material"] for layer in index["layers"]]
    model = load_svbrdf(folder).model
    for target in ("glsl", "hlsl", "slang", "wgsl", "cpp"):
        code = generate_textured(folder, target)
        emitted = re.findall(r"HBRDF_MATERIAL_(\w+)(?:: HbrdfMaterial)? =", code)
        assert sorted(emitted) == sorted({n.upper().replace("-", "_") for n in layers}), (target, emitted)
        assert len(set(layers)) < len(layers)  # the control: one material twice, emitted once
        for entry in index["maps"]:
            assert entry["file"] in code
        if target != "cpp":
            assert "hbrdf_texel_grad" in code and "hbrdf_texel_lod" in code
    doc = generate_textured(folders["doc"], "glsl")  # two layers of a three-material model: the third is not emitted
    assert len(model.materials) == 3 and re.findall(r"const HbrdfMaterial HBRDF_MATERIAL_(\w+) =", doc) == ["MAT_0", "MAT_1"]
    # The latent map's per-channel scale and offset are the index's, printed to round-trip float32.
    latent = next(e for e in index["maps"] if e["quantity"] == "latent" and e["first"] == 0)
    glsl = generate_textured(folder, "glsl")
    scale = re.search(r"const vec3 HBRDF_MAP_LAYER3_LATENT0_SCALE = vec3\((.*?)\);", glsl).group(1).split(", ")
    assert [np.float32(float(s.rstrip("f"))) for s in scale] == [np.float32(d["scale"]) for d in latent["decode"]]
    out = tmp_path / "m.glsl"
    rc, stdout, _ = _run_codegen([str(folder), "--target", "glsl", "-o", str(out)])
    assert rc == 0 and out.read_text() == glsl and "textured material" in stdout
    for extra, words in ((["--materials", layers[0]], "--materials does not apply"),
                         (["--scene", str(ROOT / "scenes" / "sphere_env.json")], "--scene does not apply")):
        rc, _, err = _run_codegen([str(folder), "--target", "glsl", *extra, "-o", str(tmp_path / "x.glsl")])
        assert rc == 1 and words in err and len(err.strip().splitlines()) == 1, err
    rc, _, err = _run_codegen([str(folder), "--target", "brdfexplorer", "-o", str(tmp_path / "x.brdf")])
    assert rc == 1 and "one uniform material" in err
    # -o naming one of the folder's files, by another path too, or inside it: refused, nothing touched.
    before = {f.name: f.read_bytes() for f in folder.iterdir()}
    (tmp_path / "link.png").symlink_to(folder / "weights.png")
    for out in (folder / "svbrdf.json", folder / "weights.png", tmp_path / "link.png", folder / "new.glsl"):
        rc, _, err = _run_codegen([str(folder), "--target", "glsl", "-o", str(out)])
        assert rc == 1 and "-o/--out" in err and len(err.strip().splitlines()) == 1, (out, err)
    assert {f.name: f.read_bytes() for f in folder.iterdir()} == before
    (tmp_path / "bad").mkdir()
    rc, _, err = _run_codegen([str(tmp_path / "bad"), "--target", "glsl", "-o", str(tmp_path / "x.glsl")])
    assert rc == 1 and "svbrdf.json" in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x.glsl").exists()


# ---- the documented shaders, as printed ----------------------------------------------------------


def _section():
    text = (ROOT / "docs" / "CODEGEN.md").read_text()
    return text.split("## A textured material in an engine", 1)[1].split("\n## ", 1)[0]


def _tool(name):
    if shutil.which(name) is None:
        skip_without_vulkan()  # fails under HBRDF_REQUIRE_VULKAN=1 only if Vulkan is missing
        pytest.skip(f"{name} is not installed (scripts/setup.sh installs it)")


def test_documented_fragment_shaders_compile_as_printed(folders, tmp_path, monkeypatch):
    """The section's commands and shaders, for a folder shaped as scenes/textured.json's painted one
    (two layers, a weights map): GLSL and HLSL by glslang, Slang by slangc, WGSL by naga."""
    _tool("glslangValidator")
    skip_without_slang()
    skip_without_wgpu()
    text = _section()
    shaders = re.findall(r"```(?:glsl|hlsl|wgsl)\n// (\S+)\n(.*?)```", text, re.S)
    commands = re.findall(r"^    ((?:hbrdf-codegen|glslangValidator|slangc|cat) .*)$", text, re.M)
    assert [name for name, _ in shaders] == ["textured.frag", "textured.hlsl", "textured.wgsl"]
    assert len(commands) == 8, commands
    for name, body in shaders:
        (tmp_path / name).write_text(body)
    hlsl = dict(shaders)["textured.hlsl"]
    (tmp_path / "textured.slang").write_text(hlsl.replace('#include "material.hlsl"', '#include "material.slang"'))
    (tmp_path / "out").mkdir()
    shutil.copytree(folders["doc"], tmp_path / "out" / "textured")
    monkeypatch.chdir(tmp_path)
    for command in commands:
        argv = shlex.split(command.split(">")[0])
        if argv[0] == "hbrdf-codegen":
            assert _run_codegen(argv[1:])[0] == 0, command
        elif argv[0] == "cat":
            target = command.split(">")[1].strip()
            pathlib.Path(target).write_text("".join(pathlib.Path(a).read_text() for a in argv[1:]))
        else:
            exe = str(find_slangc()) if argv[0] == "slangc" else argv[0]
            r = subprocess.run([exe, *argv[1:]], capture_output=True, text=True)
            assert r.returncode == 0, (command, r.stdout[-3000:], r.stderr[-3000:])
            spv = pathlib.Path(argv[argv.index("-o") + 1])
            if argv[0] == "slangc":
                patch_opsource(spv)
            if shutil.which("spirv-val"):
                v = subprocess.run(["spirv-val", str(spv)], capture_output=True, text=True)
                assert v.returncode == 0, (spv, v.stderr)
    errors = wgsl_errors(pathlib.Path("shader.wgsl").read_text())
    assert errors is None, errors[-3000:]


# ---- every kind of map, every dialect ----------------------------------------------------------------


def _engine_shader(code: str, target: str) -> str:
    """A fragment shader that declares every map the generated lookup takes and shades one pixel."""
    signature = re.search(r"hbrdf_texel_grad\((.*?)\)", code).group(1)
    params = [p for p in re.findall(r"\b(map_\w+)", signature) if p != "map_sampler"]
    if target == "glsl":
        decl = "".join(f"layout(binding = {j}) uniform sampler2D {p};\n" for j, p in enumerate(params))
        return ("#version 450\n#extension GL_GOOGLE_include_directive : require\n#include \"m.glsl\"\n" + decl +
                "layout(location = 0) in vec2 uv;\nlayout(location = 0) out vec4 o;\nvoid main() {\n"
                f"    HbrdfTexel t = hbrdf_texel_grad({', '.join(params)}, uv, dFdx(uv), dFdy(uv));\n"
                f"    HbrdfTexel u = hbrdf_texel_lod({', '.join(params)}, uv, 0.0);\n"
                "    o = vec4(hbrdf_eval_texel(vec3(0.1, 0.2, 0.9), vec3(0.0, -0.3, 0.8), t) + "
                "hbrdf_pdf_texel(vec3(0.1, 0.2, 0.9), vec3(0.0, -0.3, 0.8), u), 1.0);\n}\n")
    if target in ("hlsl", "slang"):
        decl = "".join(f"Texture2D<float4> {p} : register(t{j});\n" for j, p in enumerate(params))
        args = ", ".join(params + ["s"])
        return (f"#include \"m.{target}\"\n" + decl + "SamplerState s : register(s0);\n"
                "float4 main(float4 pos : SV_Position, float2 uv : TEXCOORD0) : SV_Target {\n"
                f"    HbrdfTexel t = hbrdf_texel_grad({args}, uv, ddx(uv), ddy(uv));\n"
                f"    HbrdfTexel u = hbrdf_texel_lod({args}, uv, 0.0);\n"
                "    float3 wi = float3(0.1, 0.2, 0.9), wo = float3(0.0, -0.3, 0.8);\n"
                "    return float4(hbrdf_eval_texel(wi, wo, t) + hbrdf_pdf_texel(wi, wo, u), 1.0);\n}\n")
    decl = "".join(f"@group(0) @binding({j + 1}) var {p}: texture_2d<f32>;\n" for j, p in enumerate(params))
    args = ", ".join(params + ["s"])
    return (code + "@group(0) @binding(0) var s: sampler;\n" + decl +
            "@fragment\nfn main(@location(0) uv: vec2f) -> @location(0) vec4f {\n"
            f"    let t = hbrdf_texel_grad({args}, uv, dpdx(uv), dpdy(uv));\n"
            f"    let u = hbrdf_texel_lod({args}, uv, 0.0);\n"
            "    let wi = vec3f(0.1, 0.2, 0.9);\n    let wo = vec3f(0.0, -0.3, 0.8);\n"
            "    return vec4f(hbrdf_eval_texel(wi, wo, t) + hbrdf_pdf_texel(wi, wo, u), 1.0);\n}\n")


@pytest.mark.parametrize("target", ["glsl", "hlsl", "slang", "wgsl"])
@pytest.mark.parametrize("kind", ["linear", "all", "normal"])
def test_lookup_compiles_in_every_dialect(folders, tmp_path, target, kind):
    code = generate_textured(folders[kind], target)
    shader = _engine_shader(code, target)
    if target == "wgsl":
        skip_without_wgpu()
        errors = wgsl_errors(shader)
        assert errors is None, errors[-3000:]
        return
    (tmp_path / f"m.{target}").write_text(code)
    src, spv = tmp_path / f"e.{'frag' if target == 'glsl' else target}", tmp_path / "e.spv"
    src.write_text(shader)
    if target == "slang":
        skip_without_slang()
        argv = [str(find_slangc()), str(src), "-target", "spirv", "-stage", "fragment", "-entry", "main", "-O0", "-o", str(spv)]
    else:
        _tool("glslangValidator")
        argv = ["glslangValidator", "-V", "-S", "frag", str(src), "-o", str(spv)] if target == "glsl" else \
            ["glslangValidator", "-D", "-V", "-S", "frag", "-e", "main", str(src), "-o", str(spv)]
    r = subprocess.run(argv, capture_output=True, text=True)
    assert r.returncode == 0, (r.stdout[-3000:], r.stderr[-3000:])


CPP_DRIVER = r"""
#include <cstdio>
#include <cstdlib>
#include "m.h"
int main() {
    unsigned n = 0, k = 0;
    if (std::fread(&n, 4, 1, stdin) != 1 || std::fread(&k, 4, 1, stdin) != 1) return 1;
    const std::size_t count = std::size_t(n) * (6 + 3 * k);
    float* const in = static_cast<float*>(std::calloc(count + 1, 4));  // not <vector>: 0.13 s less g++ a compile
    if (in == nullptr || std::fread(in, 4, count, stdin) != count) return 1;
    for (unsigned i = 0; i < n; ++i) {
        const float* p = &in[std::size_t(i) * (6 + 3 * k)];
        const hbrdf::float3 wi(p[0], p[1], p[2]), wo(p[3], p[4], p[5]);
        const float* s = p + 6;
        const hbrdf::HbrdfTexel t = hbrdf::hbrdf_decode_texel(ARGS);
        const hbrdf::float3 f = hbrdf::hbrdf_eval_texel(wi, wo, t);
        const float out[3] = {f.x, f.y, f.z};
        std::fwrite(out, 4, 3, stdout);
    }
    return 0;
}
"""


@pytest.mark.parametrize("kind", ["linear", "all"])
def test_cpp_decode_of_stored_texels_is_the_library(folders, tmp_path, kind):
    """The C++ header's hbrdf_decode_texel + hbrdf_eval_texel, given a texel's stored map values (what
    a CPU sampler returns at a texel centre), against SVBRDF.eval at that centre."""
    folder = folders[kind]
    code = generate_textured(folder, "cpp")
    params = re.search(r"hbrdf_decode_texel\((.*?)\)", code).group(1)
    files = re.findall(r"//   map_\w+: (\S+) ", code)
    (tmp_path / "m.h").write_text(code)
    args = ", ".join(f"hbrdf::float3(s[{3 * j}], s[{3 * j + 1}], s[{3 * j + 2}])" for j in range(len(files)))
    assert params.count("float3") == len(files)
    (tmp_path / "d.cpp").write_text(CPP_DRIVER.replace("ARGS", args))
    r = subprocess.run(["g++", "-std=c++17", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror", "-I", str(tmp_path),
                        str(tmp_path / "d.cpp"), "-o", str(tmp_path / "d")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[:3000]
    rng = np.random.default_rng(5)
    n = 3000
    cols, rows = rng.integers(0, te.W, n), rng.integers(0, te.H, n)
    uv = np.stack([(cols + 0.5) / te.W, (rows + 0.5) / te.H], axis=1)
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    stored = np.concatenate([read_map(folder / f)[0][rows, cols] for f in files], axis=1)
    payload = np.asarray([n, len(files)], np.uint32).tobytes() + np.concatenate([wi, wo, stored], 1).astype(np.float32).tobytes()
    out = subprocess.run([str(tmp_path / "d")], input=payload, capture_output=True)
    assert out.returncode == 0
    got = np.frombuffer(out.stdout, np.float32).reshape(n, 3)
    lib = load_svbrdf(folder).eval(uv, wi, wo)
    big = np.abs(lib) > 1e-6
    assert big.mean() > 0.9
    assert (np.abs(got - lib)[big] / np.abs(lib)[big]).max() < 1e-5


# ---- it runs: WGSL through wgpu's samplers on lavapipe -------------------------------------------


def test_lavapipe_filters_to_8_bits():
    """The measurement behind the tolerance: lavapipe's bilinear filter of an rgba8unorm texture (0 and
    1 in neighbouring texels) returns 8-bit values (256 distinct outputs over 4,097 fractions, off by
    at most one step, 1/255, from the exact lerp), and rgba8unorm-srgb decodes to the nearest 8-bit
    linear value (within 0.5/255 of the EOTF)."""
    skip_without_wgpu()
    fractions = np.arange(4097) / 4096
    got = te.sample_probe("rgba8unorm", np.array([0, 255] * 8, np.uint8), (0.5 + fractions) / 16)
    assert np.abs(got - fractions).max() <= te.STEP + 1e-6
    codes = np.arange(256, dtype=np.uint8)
    got = te.sample_probe("rgba8unorm-srgb", codes, (np.arange(256) + 0.5) / 256)
    v = codes / 255.0
    eotf = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)
    assert np.abs(got - eotf).max() <= 0.5 * te.STEP
    got = te.sample_probe("rgba8unorm", codes, (np.arange(256) + 0.5) / 256)
    assert np.abs(got - v).max() < 1e-6  # a texel centre is the stored value


def _pairs(n, seed):
    rng = np.random.default_rng(seed)
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    uv = rng.uniform(-1, 2, (n, 2))
    q = n // 4  # texel centres, beyond [0, 1] too; then fractions k / 256 (exact in 8 bits); then anywhere
    uv[:q] = (rng.integers(-te.W, 2 * te.W, (q, 2)) + 0.5) / [te.W, te.H]
    cells = rng.integers(-te.W, 2 * te.W, (q, 2)) + 0.5 + rng.integers(0, 256, (q, 2)) / 256
    uv[q:2 * q] = cells / [te.W, te.H]
    uv = uv.astype(np.float32).astype(np.float64)  # the kernel reads float32
    return uv, wi, wo, np.arange(n) < q


@pytest.mark.parametrize("srgb_textures", [False, True], ids=["linear-textures", "srgb-textures"])
@pytest.mark.parametrize("kind", ["linear", "all"])
def test_wgsl_lookup_runs_like_the_library(folders, kind, srgb_textures):
    skip_without_wgpu()
    folder = folders[kind]
    uv, wi, wo, centres = _pairs(4000, 7)
    got = te.run_wgsl_textured(generate_textured(folder, "wgsl"), folder, np.concatenate([uv, wi, wo], 1), srgb_textures)
    assert np.array_equal(got[:, :3], got[:, 3:])  # textureSampleLevel 0 and textureSampleGrad with zero derivatives
    f = got[:, :3].astype(np.float64)
    lib = load_svbrdf(folder).eval(uv, wi, wo)
    ref = te.eval_reference(folder, uv, wi, wo, srgb_textures)
    tol = te.step_tolerance(folder, uv, wi, wo, srgb_textures, ref) + 1e-4 * np.abs(ref) + 1e-6
    assert np.isfinite(f).all() and (lib > 0).mean() > 0.9
    assert (np.abs(f - ref) <= tol).all(), np.max((np.abs(f - ref) - tol) / np.maximum(np.abs(ref), 1e-6))
    assert np.median(tol / np.maximum(np.abs(ref), 1e-6)) < 0.02  # not vacuous: one 8-bit step
    big = np.abs(lib) > 1e-6
    if not srgb_textures:  # the stored values themselves at texel centres: the library within float rounding
        sel = centres[:, None] & big
        assert (np.abs(f - lib)[sel] / np.abs(lib)[sel]).max() < 1e-4
    if kind == "linear" and srgb_textures:  # each channel linear or decoded before the filter: the reference is the library
        assert (np.abs(ref - lib)[big] / np.abs(lib)[big]).max() < 1e-5


def test_documented_wgsl_fragment_shader_draws_the_library(folders):
    """The section's WGSL fragment shader, as printed after the generated code, drawn by wgpu on
    lavapipe (a triangle over a viewport of one pixel per texel, uv at the texel centres, the frame
    from the interpolated normal and glTF tangent, one light): each pixel is the library's
    SVBRDF.eval(uv, wi, wo) wi.z at its uv, within float rounding."""
    skip_without_wgpu()
    shader = dict(re.findall(r"```(?:glsl|hlsl|wgsl)\n// (\S+)\n(.*?)```", _section(), re.S))["textured.wgsl"]
    folder = folders["doc"]
    light, eye = np.array([0.3, -0.2, 0.9]), np.array([-0.4, 0.1, 0.8])
    light, eye = light / np.linalg.norm(light), eye / np.linalg.norm(eye)
    image = te.draw_wgsl_fragment(generate_textured(folder, "wgsl") + shader, folder / "weights.png", light, eye)
    rows, cols = np.mgrid[0:te.H, 0:te.W]
    uv = np.stack([(cols.ravel() + 0.5) / te.W, (rows.ravel() + 0.5) / te.H], axis=1)
    n = len(uv)
    lib = load_svbrdf(folder).eval(uv, np.repeat(light[None], n, 0), np.repeat(eye[None], n, 0)) * light[2]
    assert len(np.unique(lib[:, 0].round(6))) > 10 and lib.min() > 0  # the control: the texels differ
    assert (np.abs(image.reshape(-1, 3) - lib) / lib).max() < 1e-4


def test_wgsl_lookup_reads_the_level_the_sampler_picks(folders, tmp_path):
    """Mip-agnostic: a folder saved with its mip chain (format 2, SVBRDF.with_mips) generates the same
    code but for the header's level count; with its chain's files uploaded as the textures' levels,
    the lookup at lod 1 and 2, and through textureSampleGrad with derivatives of 2 and 4 texels, reads
    that level: at the level's texel centres, libhybridbrdf's SVBRDF.eval at that lod (float rounding),
    not what a sampler reads at level 0 there."""
    skip_without_wgpu()
    mipped = load_svbrdf(folders["linear"]).with_mips()
    mipped.save(tmp_path / "sv")
    folder = tmp_path / "sv"
    plain, code = generate_textured(folders["linear"], "wgsl"), generate_textured(folder, "wgsl")
    saved = load_svbrdf(folder)
    assert saved.levels == 5 and code == plain.replace("repeat addressing) ----", "repeat addressing, 5 mip levels) ----")
    rng = np.random.default_rng(11)
    n = 1000
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    uvs = []
    for lod in (1, 2):
        size = np.array([te.W >> lod, te.H >> lod])
        uvs.append((rng.integers(0, size, (n, 2)) + 0.5) / size)
    # Both levels in one dispatch (one pipeline: lavapipe compiling it is most of the test's time).
    pairs = np.concatenate([np.concatenate([uv, wi, wo], 1) for uv in uvs])
    out = te.run_wgsl_textured(code, folder, pairs, False, lod=np.repeat([1, 2], n))
    for k, (lod, uv) in enumerate(zip((1, 2), uvs)):
        got = out[k * n:(k + 1) * n]
        lib = saved.eval(uv, wi, wo, lod=float(lod))  # the saved (8-bit) chain, as the textures hold it
        big = np.abs(lib) > 1e-6
        for f in (got[:, :3], got[:, 3:]):
            assert (np.abs(f - lib)[big] / np.abs(lib)[big]).max() < 1e-4, lod
        level0 = te.eval_reference(folder, uv, wi, wo, False)
        assert (np.abs(level0 - lib)[big] / np.abs(lib)[big]).max() > 0.01  # the control: level 0 differs there
