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
"""

import re

import numpy as np
import pytest

from hybridbrdf import _core, spec
from hybridbrdf.codegen.literals import material_constant
from hybridbrdf.codegen.main import generate
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.model.random import random_model

from helpers import compile_spirv, hard_pairs, run_on_lavapipe, saved_random_model, skip_without_vulkan
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
    material = 1  # the anisotropic one
    code = generate(model, target, [model.materials[material]], pixel_split=True)
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
