"""BRDF Explorer (.brdf) output: a parser that enforces the explorer's rules,
then the shader block compiled by glslang and run under lavapipe against
libhybridbrdf (parameters at their defaults = the chosen material)."""

import re

import numpy as np
import pytest

from hybridbrdf import _core
from hybridbrdf.codegen.main import generate
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.model.random import random_model

from helpers import compile_spirv, run_on_lavapipe, saved_random_model, skip_without_vulkan
from shader_kernels import render_shader

PARAM = re.compile(r"^float ([A-Za-z_][A-Za-z0-9_]*) (\S+) (\S+) (\S+)$")
FLOAT = re.compile(r"^-?(\d+\.\d*|\d*\.\d+)(e[-+]?\d+)?$|^-?\d+(\.\d*)?e[-+]?\d+$")


def parse_brdf_file(text):
    """Parses a .brdf file as Disney's BRDF Explorer does, failing on what it rejects:
    returns ({name: (min, max, default)}, shader source)."""
    lines = text.splitlines()
    assert lines[0] == "analytic", "first line must be 'analytic'"
    assert not [ln for ln in lines if ln.startswith("#")], "the explorer's parser drops lines starting with '#'"
    i_pb, i_pe = lines.index("::begin parameters"), lines.index("::end parameters")
    i_sb, i_se = lines.index("::begin shader"), lines.index("::end shader")
    assert i_pb < i_pe < i_sb < i_se
    params = {}
    for ln in lines[i_pb + 1:i_pe]:
        m = PARAM.match(ln)
        assert m, f"bad parameter line {ln!r}"
        values = m.groups()[1:]
        assert all(FLOAT.match(v) for v in values), f"parameter values must be float literals: {ln!r}"
        lo, hi, default = (float(v) for v in values)
        assert lo <= default <= hi, ln
        params[m.group(1)] = (lo, hi, default)
    shader = "\n".join(lines[i_sb + 1:i_se])
    assert re.search(r"^const float PI\b", shader, re.M), "the shader must define const float PI"
    assert "vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)" in shader
    assert not re.search(r"(?<=[0-9.])f\b", shader), "no 'f' suffixes in the explorer's GLSL"
    return params, shader


@pytest.mark.parametrize("arch", ["hybrid", "neural"])
def test_brdfexplorer_file_parses_compiles_and_matches_the_library(tmp_path, arch):
    path, model = saved_random_model(tmp_path, arch)
    text = generate(model, "brdfexplorer", ["mat-1"])
    params, shader = parse_brdf_file(text)
    expected = {"kd_r", "kd_g", "kd_b", "eta_r", "eta_g", "eta_b", "alpha_x", "alpha_y"}
    expected |= {f"z{k}" for k in range(model.arch["latent"])}
    assert set(params) == expected
    if arch == "hybrid":
        assert params["alpha_y"][2] == pytest.approx(float(model.tensors["materials.alpha"][1, 1]), rel=1e-7)
    skip_without_vulkan()
    n = 20000
    rng = np.random.default_rng(2)
    wi, wo = cosine_directions(rng, n).astype(np.float32), cosine_directions(rng, n).astype(np.float32)
    decl = "\n".join(f"const float {k} = {v[2]!r};" for k, v in params.items())
    src = tmp_path / "wrap.comp"
    src.write_text(render_shader("brdfexplorer.comp.glsl", params=decl, shader=shader, n=n))
    spv = tmp_path / "s.spv"
    compile_spirv(src, spv)
    got = run_on_lavapipe(spv, np.concatenate([wi, wo], axis=1))
    ref = _core.Model(str(path)).eval(wi, wo, 1)
    big = np.abs(ref) > 1e-6
    assert np.isfinite(got).all() and np.array_equal(got == 0, ref == 0)
    assert (np.abs(got[big] - ref[big]) / np.abs(ref[big])).max() < 1e-4


def test_parser_rejects_what_the_explorer_rejects():
    _, model = random_model()
    good = generate(model, "brdfexplorer")
    parse_brdf_file(good)
    for bad in (good.replace("analytic", "analytical", 1), good.replace("::begin shader", "#define X 1\n::begin shader"),
                good.replace("const float PI", "const float PIE"), good.replace(" 0.0 1.0 ", " 0 1 ", 1)):
        with pytest.raises(AssertionError):
            parse_brdf_file(bad)
