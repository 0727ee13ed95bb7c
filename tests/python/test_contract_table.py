"""spec/activation_combine.json, the model contract's activations and combine rules on hard inputs
(signed zeros, denormals, the hardGeLU knee and its float32 neighbours, the pre-exp bound and
beyond, f_a up to 3.2e15), reproduced by PyTorch and by every generated dialect: GLSL, HLSL and Slang
under lavapipe (validation layer on), WGSL under lavapipe through wgpu (naga), and the C++ header
compiled with g++. libhybridbrdf's scalar
and batched paths check the same table in test_contract_table_cpp.py.

The expected values are a float64 evaluation of spec/model.json's formulas written in
scripts/gen_contract_table.py, not any reader's code."""

import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest
import torch

from hybridbrdf import spec
from hybridbrdf.codegen.main import generate
from hybridbrdf.model.networks import activation_fn, combine
from hybridbrdf.model.random import random_model

from helpers import skip_without_vulkan
from shader_kernels import render_shader
from slang_wgsl_tools import run_kernel, skip_without_slang, skip_without_wgpu

ROOT = pathlib.Path(__file__).resolve().parents[2]
TABLE = json.loads((ROOT / "spec" / "activation_combine.json").read_text())
REL, ABS = TABLE["rel_tol"], TABLE["abs_tol"]
#: An architecture for each combine rule, read from the spec.
ARCH_OF_RULE = {rule: next(a for a, d in spec.ARCHS.items() if d["combine"] == rule) for rule in spec.COMBINES}


def check_rows(got, want, rel, what):
    got, want = np.asarray(got, dtype=np.float64), np.asarray(want, dtype=np.float64)
    assert np.isfinite(got).all(), f"{what}: non-finite outputs {got[~np.isfinite(got)][:5]}"
    bad = np.abs(got - want) > rel * np.abs(want) + ABS
    assert not bad.any(), f"{what}: {bad.sum()} rows off, first: got {got[bad][:4]} want {want[bad][:4]}"


def combine_rows(rule, bound=None):
    rows = np.array(TABLE["combines"][rule], dtype=np.float32)
    return rows if bound is None else rows[rows[:, 3] == np.float32(bound)]


def test_table_is_current_and_covers_the_spec():
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "gen_contract_table.py"), "--check"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert set(TABLE["activations"]) == set(spec.ACTIVATIONS)
    assert set(TABLE["combines"]) == set(spec.COMBINES)
    bounds = {float(np.float32(b)) for b in (spec.PRE_EXP_MAX, spec.PRE_EXP_MAX_LIMIT)}
    for rule in spec.COMBINES:
        assert {float(b) for b in combine_rows(rule)[:, 3]} == bounds


def test_the_table_can_fail():
    """The check rejects a reader eight float32 steps off on ramp values and one that flushes a
    normal result to zero (so passing it says something)."""
    x, want = np.array(TABLE["activations"]["hardgelu"], dtype=np.float32).T
    ramp = (np.abs(x) < spec.HARDGELU_KNEE) & (np.abs(want) > 0.1)
    with pytest.raises(AssertionError):
        check_rows(want + 8 * np.spacing(np.where(ramp, np.abs(want), 0)), want, REL["activation"], "perturbed")
    rows = combine_rows("gated")
    with pytest.raises(AssertionError):
        check_rows(np.where(rows[:, 4] > 1e-30, 0.0, rows[:, 4]), rows[:, 4], REL["combine"], "flushed")


@pytest.mark.parametrize("name", list(spec.ACTIVATIONS))
def test_pytorch_activation(name):
    x, want = np.array(TABLE["activations"][name], dtype=np.float32).T
    got = activation_fn(name)(torch.from_numpy(x)).numpy()
    check_rows(got, want, REL["activation"], f"torch {name}")


@pytest.mark.parametrize("rule", list(spec.COMBINES))
def test_pytorch_combine(rule):
    for bound in (spec.PRE_EXP_MAX, spec.PRE_EXP_MAX_LIMIT):
        rows = combine_rows(rule, bound)
        o, g, fa = (torch.from_numpy(np.ascontiguousarray(rows[:, k])) for k in range(3))
        n_out = 6 if rule == "gated" else 3
        out = torch.stack([o] * 3 + ([g] * 3 if n_out == 6 else []), dim=-1)
        f_a = torch.stack([fa] * 3, dim=-1) if spec.ARCHS[ARCH_OF_RULE[rule]]["analytic"] else None
        got = combine(rule, out, f_a, float(np.float32(bound)))
        assert got.dtype == torch.float32
        for c in range(3):
            check_rows(got[:, c].numpy(), rows[:, 4], REL["combine"], f"torch {rule} bound {bound} channel {c}")


# ---- the generated dialects ----------------------------------------------------------------------
# Each case is a model (an architecture, its activation and pre_exp_max) whose generated code a
# kernel (glsl/contract_table.comp.j2) calls directly: out[0] = hbrdf_activation(in[0]),
# out[1] = hbrdf_combine(in[1..3]).
CASES = [(rule, activation, bound) for rule in spec.COMBINES
         for activation, bound in zip(spec.ACTIVATIONS, (spec.PRE_EXP_MAX, spec.PRE_EXP_MAX_LIMIT))]


def case_model(rule, activation, bound):
    arch = ARCH_OF_RULE[rule]
    _, model = random_model(arch, n=1, latent=12 if not spec.ARCHS[arch]["analytic"] else 2, width=4, depth=1)
    model.arch["activation"] = activation
    model.arch["pre_exp_max"] = float(bound)
    return model


def case_inputs(rule, activation, bound):
    """(n, 4) float32 rows: the activation's x (cycled) beside the combine row (o, g, fa)."""
    rows = combine_rows(rule, bound)
    x = np.array(TABLE["activations"][activation], dtype=np.float32)
    n = max(len(rows), len(x))
    xs = x[np.arange(n) % len(x)]
    cr = rows[np.arange(n) % len(rows)]
    return np.column_stack([xs[:, 0], cr[:, 0], cr[:, 1], cr[:, 2]]).astype(np.float32), xs[:, 1], cr[:, 4]


def combine_call(rule, o, g, fa):
    if rule == "gated":
        return f"hbrdf_combine({o}, {g}, {fa})"
    if spec.ARCHS[ARCH_OF_RULE[rule]]["analytic"]:
        return f"hbrdf_combine({o}, {fa})"
    return f"hbrdf_combine({o})"


CPP_DRIVER = """#include <cstdio>
#include <cstdlib>
#include "model.h"
int main() {
    unsigned n = 0;
    if (std::fread(&n, 4, 1, stdin) != 1) return 1;
    const std::size_t count = std::size_t(4) * n;
    float* const in = static_cast<float*>(std::calloc(count + 1, 4));  // not <vector>: 0.13 s less g++ a compile
    if (in == nullptr || std::fread(in, 4, count, stdin) != count) return 1;
    for (unsigned i = 0; i < n; ++i) {
        const float* data_in = &in[4 * i];
        float out[2] = {hbrdf::hbrdf_activation(data_in[0]), hbrdf::COMBINE};
        std::fwrite(out, 4, 2, stdout);
    }
    return 0;
}
"""


def run_dialect(tmp_path, target, model, rule, inputs):
    n = len(inputs)
    if target == "cpp":
        (tmp_path / "model.h").write_text(generate(model, "cpp"))
        call = combine_call(rule, "data_in[1]", "data_in[2]", "data_in[3]")
        (tmp_path / "driver.cpp").write_text(CPP_DRIVER.replace("COMBINE", call))
        exe = tmp_path / "driver"
        # -ffp-contract=off as the other generated-C++ tests; no -ffast-math (denormals kept).
        r = subprocess.run(["g++", "-std=c++17", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror",
                            "-I", str(tmp_path), str(tmp_path / "driver.cpp"), "-o", str(exe)],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr[:3000]
        r = subprocess.run([str(exe)], input=np.uint32(n).tobytes() + inputs.tobytes(), capture_output=True)
        assert r.returncode == 0
        return np.frombuffer(r.stdout, dtype=np.float32).reshape(n, 2)
    code = generate(model, target)
    (tmp_path / f"model.{target}").write_text(code)
    call = combine_call(rule, "data_in[4 * i + 1]", "data_in[4 * i + 2]", "data_in[4 * i + 3]")
    extra = {"model_code": code} if target == "wgsl" else {}
    kernel = render_shader(f"contract_table.comp.{target}", include=f"model.{target}", n=n, combine=call, **extra)
    return run_kernel(tmp_path, target, kernel, inputs, out_floats=2)


@pytest.mark.parametrize("target", ["glsl", "hlsl", "slang", "wgsl", "cpp"])
def test_generated_code_reproduces_the_table(tmp_path, target):
    if target != "cpp":
        skip_without_vulkan()
    if target == "slang":
        skip_without_slang()
    if target == "wgsl":
        skip_without_wgpu()
    for k, (rule, activation, bound) in enumerate(CASES):
        work = tmp_path / str(k)
        work.mkdir()
        inputs, want_act, want_comb = case_inputs(rule, activation, bound)
        got = run_dialect(work, target, case_model(rule, activation, bound), rule, inputs)
        check_rows(got[:, 0], want_act, REL["activation"], f"{target} {activation}")
        check_rows(got[:, 1], want_comb, REL["combine"], f"{target} {rule} bound {bound}")
