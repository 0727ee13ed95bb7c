"""The per-pixel form of the generated code (``generate(..., pixel_split=True)``, codegen/pixel.j2):
``hbrdf_pixel(wo, m)`` once per pixel holds the first layer's bias plus its latent and wo terms (and
the energy scale at wo.z), ``hbrdf_eval_pixel(wi, px, m)`` per light adds the wi terms and runs the
rest; the raster frame draws its model materials with it (docs/RASTER.md "Cost").

- Its first-layer statements, read back and summed in float64, are W0 x + b of the model's own
  tensors (an independent reference: the tensors, not the code generator), for every architecture
  with local direction inputs, the latent code an input or folded into the bias. Seen failing with
  wo's terms given wi's weights, and with the latent terms dropped.
- Executed under lavapipe (validation layer on), GLSL and HLSL, against libhybridbrdf's eval on
  cosine pairs and the hard cases, with shared and material output layers and energy tables. Seen
  failing with the two breakages above, and (the energy cases) with hbrdf_pixel's energy scale
  taken at wo.x instead of wo.z.
- Refused in one line where it does not exist (wi and wo mixed in the inputs, the loops form,
  other dialects).
- From the command line (``hbrdf-codegen --per-pixel``): the file it writes, GLSL and HLSL, runs under
  lavapipe as above against libhybridbrdf (seen failing with the flag not passed on to the generator:
  the file has no hbrdf_pixel, glslang refuses the wrapper); the refusals are one line naming the
  model file and the flag, with no file written; docs/CODEGEN.md's fragment shader around it compiles
  as printed (glslang, spirv-val).
"""

import contextlib
import io
import pathlib
import re
import shlex
import shutil
import subprocess

import numpy as np
import pytest

from hybridbrdf import _core, spec
from hybridbrdf.codegen.literals import material_constant
from hybridbrdf.codegen.main import generate, main as codegen
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.model.random import random_model

from helpers import compile_spirv, hard_pairs, run_cli_here, run_on_lavapipe, saved_random_model, skip_without_vulkan
from shader_kernels import eval_compute_shader

LOCAL = [a for a, v in spec.ARCHS.items() if v["directions"] in ("local", "local_half")]
PIXEL = re.compile(r"px\.pre0\[(\d+)\] = (.*);$")
LIGHT = re.compile(r"float h0_(\d+) = hbrdf_activation\((.*)\);$")


def _value(expr: str, names: dict) -> float:
    """A generated sum of products of literals and named inputs, in float64."""
    expr = re.sub(r"(\d)f\b", r"\1", expr)
    for name, value in names.items():
        expr = expr.replace(name, repr(float(value)))
    assert re.fullmatch(r"[-+*(). 0-9e]+", expr), expr  # nothing left unread
    return eval(expr)  # noqa: S307 (literals and operators only, checked above)


@pytest.mark.parametrize("arch", LOCAL)
@pytest.mark.parametrize("fold", [False, True])
def test_first_layer_split_sums_the_models_first_layer(arch, fold):
    _, model = random_model(arch, latent=4, width=8, depth=2, isotropic=[True, False, True])
    name = model.materials[1]
    scene = {"name": "s", "materials": [{"name": name, "evaluate": "full"}]} if fold else None
    code = generate(model, "glsl", None if fold else [name], scene=scene, pixel_split=True)
    pixel = {int(m[1]): m[2] for m in map(PIXEL.search, code.splitlines()) if m}
    light = {int(m[1]): m[2] for m in map(LIGHT.search, code.splitlines()) if m}
    w0 = np.asarray(model.tensors["mlp.hidden.0.weight"], np.float64)
    b0 = np.asarray(model.tensors["mlp.hidden.0.bias"], np.float64)
    z = np.asarray(model.tensors["materials.z"][1], np.float64)
    assert sorted(pixel) == sorted(light) == list(range(len(b0)))
    assert ("m.z[" in "".join(pixel.values())) != fold  # folded: the latent terms are in the bias
    rng = np.random.default_rng(3)
    n_dir = spec.ARCHS[arch]["direction_count"]
    for _ in range(5):
        x = rng.uniform(-1, 1, w0.shape[1])  # every input, the per-light ones past wi too (x[6], x[7], log1p f_a)
        x[n_dir:n_dir + 4] = z
        names = {f"m.z[{k}]": z[k] for k in range(4)} | {"wo.x": x[3], "wo.y": x[4], "wo.z": x[5]}
        for j in range(len(b0)):
            pre = _value(pixel[j], names)
            # the code's x[k]: the model's inputs, less the latent ones where they are folded
            code_x = np.delete(x, np.s_[n_dir:n_dir + 4]) if fold else x
            got = _value(light[j], {"px.pre0[" + str(j) + "]": pre} | {f"x[{k}]": v for k, v in enumerate(code_x)})
            ref = b0[j] + w0[j] @ x
            scale = abs(b0[j]) + np.abs(w0[j]) @ np.abs(x)
            # 9-digit literals of float32 values (~1e-9 each), summed in float64; folded: the bias rounded to float32.
            assert abs(got - ref) <= (1e-7 if fold else 1e-8) * scale, (j, got, ref)


CASES = [("hybrid", "shared", False, "glsl"), ("hybrid", "material", True, "glsl"), ("hybrid", "material", True, "hlsl"),
         ("additive", "shared", False, "glsl"), ("logmul", "shared", False, "hlsl"),
         ("analytic-input", "shared", False, "glsl"), ("hybrid-half", "material", True, "glsl")]
WRAPPER = {"glsl": "vec3 hbrdf_eval_split(const vec3 wi, const vec3 wo, const HbrdfMaterial m) {\n",
           "hlsl": "float3 hbrdf_eval_split(float3 wi, float3 wo, HbrdfMaterial m) {\n"}


@pytest.mark.parametrize("arch,output_layer,energy,target", CASES)
def test_per_pixel_form_matches_the_library_under_lavapipe(tmp_path, arch, output_layer, energy, target):
    skip_without_vulkan()
    path, model = saved_random_model(tmp_path, arch, "hardgelu", 16, 2, output_layer, energy_bound=energy)
    code = generate(model, target, [model.materials[1]], pixel_split=True)  # the anisotropic one
    _check_split_against_library(tmp_path, code, path, model, arch, target)


def _check_split_against_library(tmp_path, code, path, model, arch, target, material=1):
    """``code`` (the per-pixel form of ``model``'s material ``material``) under lavapipe: a kernel
    that evaluates hbrdf_eval_pixel(wi, hbrdf_pixel(wo, m), m), against libhybridbrdf on cosine
    pairs and the hard cases."""
    code += WRAPPER[target] + "    return hbrdf_eval_pixel(wi, hbrdf_pixel(wo, m), m);\n}\n"
    (tmp_path / f"model.{target}").write_text(code)
    rng = np.random.default_rng(5)
    hwi, hwo = hard_pairs()
    wi = np.concatenate([cosine_directions(rng, 20_000), hwi]).astype(np.float32)
    wo = np.concatenate([cosine_directions(rng, 20_000), hwo]).astype(np.float32)
    src = tmp_path / ("wrap.comp" if target == "glsl" else "wrap.hlsl")
    src.write_text(eval_compute_shader("hbrdf_eval_split", material_constant(model.materials[material]),
                                       f"model.{target}", target, n=len(wi)))
    compile_spirv(src, tmp_path / "shader.spv", target, include_dir=tmp_path)
    got = run_on_lavapipe(tmp_path / "shader.spv", np.concatenate([wi, wo], axis=1))
    ref = _core.Model(str(path)).eval(wi, wo, material)
    assert np.isfinite(got).all() and np.array_equal(got == 0, ref == 0)
    big = np.abs(ref) > 1e-6
    if spec.ARCHS[arch]["combine"] == "additive":  # max(f_a + o, 0) cancels: bound by the size of its terms
        assert np.abs(got - ref).max() < 1e-4 * np.abs(ref).max()
    else:  # test_shader_conformance's bound: lavapipe's exp and fused multiply-adds
        assert (np.abs(got[big] - ref[big]) / np.abs(ref[big])).max() < 1e-4


@pytest.mark.parametrize("arch,options,words", [
    ("hybrid-reciprocal", {}, "'reciprocal' direction inputs mix wi and wo"),
    ("neural", {}, "'frames' direction inputs mix wi and wo"),
    ("hybrid", {"mlp_form": "loops"}, "the unrolled form only"),
    ("hybrid", {"target": "wgsl"}, "GLSL and HLSL only"),
])
def test_refused_in_one_line_where_there_is_no_split(arch, options, words):
    _, model = random_model(arch, latent=12 if arch == "neural" else 4, width=8, depth=1)
    options = {"target": "glsl"} | options
    with pytest.raises(ValueError, match=re.escape(words)) as info:
        generate(model, options.pop("target"), pixel_split=True, **options)
    assert str(info.value).startswith("pixel_split: ") and "\n" not in str(info.value)


# ---- hbrdf-codegen --per-pixel ---------------------------------------------------------------------------


def _codegen(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = codegen([str(a) for a in argv])
    return rc, out.getvalue(), err.getvalue()


@pytest.mark.parametrize("target", ["glsl", "hlsl"])
def test_command_line_per_pixel_form_matches_the_library_under_lavapipe(tmp_path, target):
    skip_without_vulkan()
    path, model = saved_random_model(tmp_path, "hybrid", "hardgelu", 16, 2, "material", energy_bound=True)
    out = tmp_path / f"cli.{target}"
    rc, said, _ = _codegen([path, "--target", target, "--materials", model.materials[1], "--per-pixel", "-o", out])
    assert rc == 0 and said.startswith(f"wrote {out}")
    code = out.read_text()
    assert f"--target {target} --materials {model.materials[1]} --per-pixel" in code  # the header's regenerate line
    _check_split_against_library(tmp_path, code, path, model, "hybrid", target)


@pytest.mark.parametrize("arch,flags,words", [
    ("hybrid-reciprocal", ["--target", "glsl"], "the 'reciprocal' direction inputs mix wi and wo"),
    ("hybrid", ["--target", "hlsl", "--mlp-form", "loops"], "the unrolled form only"),
    ("hybrid", ["--target", "wgsl"], "GLSL and HLSL only"),
    ("hybrid", ["--target", "slang"], "GLSL and HLSL only"),
    ("hybrid", ["--target", "brdfexplorer"], "GLSL and HLSL only"),
])
def test_command_line_refuses_per_pixel_in_one_line(tmp_path, arch, flags, words):
    path, _ = saved_random_model(tmp_path, arch)
    out = tmp_path / "out.txt"
    rc, said, err = _codegen([path, *flags, "--per-pixel", "-o", out])
    assert rc == 1 and said == "" and not out.exists()
    assert err.startswith(f"hbrdf-codegen: error: {path}: --per-pixel: {words}") and err.count("\n") == 1, err


def test_command_line_per_pixel_form_of_a_textured_folder(tmp_path):
    """``hbrdf-codegen DIR --per-pixel``: the layers' constants gain the form (the texel's functions
    stay per light); the file compiles in an engine's shader that calls both."""
    if shutil.which("glslangValidator") is None:
        skip_without_vulkan()
        pytest.skip("glslangValidator is not installed (scripts/setup.sh installs it)")
    path, model = saved_random_model(tmp_path, "hybrid")
    folder = tmp_path / "folder"
    r = run_cli_here("paint", str(path), "--base", model.materials[0], "--size", "4x4", "--out", str(folder))
    assert r.returncode == 0, r.stderr
    rc, _, err = _codegen([folder, "--target", "glsl", "--per-pixel", "-o", tmp_path / "t.glsl"])
    assert rc == 0, err
    (tmp_path / "t.frag").write_text(
        "#version 450\n#extension GL_GOOGLE_include_directive : require\n#include \"t.glsl\"\n"
        "layout(location = 0) in vec3 v_wo;\nlayout(location = 0) out vec4 o;\nvoid main() {\n"
        "    HbrdfTexel t = hbrdf_decode_texel();\n    HbrdfPixel px = hbrdf_pixel(v_wo, t.m0);\n"
        "    o = vec4(hbrdf_eval_pixel(vec3(0.0, 0.0, 1.0), px, t.m0) + hbrdf_eval_texel(vec3(0.0, 0.0, 1.0), v_wo, t), 1.0);\n}\n")
    r = subprocess.run(["glslangValidator", "-V", str(tmp_path / "t.frag"), "-o", str(tmp_path / "t.spv")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-2000:]


def test_documented_per_pixel_shader_compiles_as_printed(tmp_path, monkeypatch):
    """docs/CODEGEN.md, "The per-pixel form": its hbrdf-codegen and glslangValidator lines and its
    fragment shader, as printed, from a folder laid out like the repository."""
    if shutil.which("glslangValidator") is None:
        skip_without_vulkan()
        pytest.skip("glslangValidator is not installed (scripts/setup.sh installs it)")
    root = pathlib.Path(__file__).resolve().parents[2]
    text = (root / "docs" / "CODEGEN.md").read_text().split("## The per-pixel form", 1)[1].split("\n## ", 1)[0]
    shaders = re.findall(r"```glsl\n// (\S+)\n(.*?)```", text, re.S)
    commands = re.findall(r"^    ((?:hbrdf-codegen|glslangValidator) .*)$", text, re.M)
    assert [name for name, _ in shaders] == ["pixel.frag"] and len(commands) == 2, (shaders, commands)
    (tmp_path / "pixel.frag").write_text(shaders[0][1])
    (tmp_path / "results").symlink_to(root / "results")
    monkeypatch.chdir(tmp_path)
    for command in commands:
        argv = shlex.split(command)
        if argv[0] == "hbrdf-codegen":
            rc, _, err = _codegen(argv[1:])
            assert rc == 0, (command, err)
            continue
        r = subprocess.run(argv, capture_output=True, text=True)
        assert r.returncode == 0, (command, r.stdout[-2000:], r.stderr[-2000:])
        if shutil.which("spirv-val"):
            v = subprocess.run(["spirv-val", "pixel.spv"], capture_output=True, text=True)
            assert v.returncode == 0, v.stderr
