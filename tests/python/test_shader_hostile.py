"""Hostile input through the generated GLSL and HLSL under lavapipe: every generated
function that takes directions (hbrdf_eval, hbrdf_eval_analytic, hbrdf_eval_depth, hbrdf_pdf,
hbrdf_sample) on the adversarial directions -- the shared table tests/data/hard_directions.json
crossed with itself, more of the same kinds (1e30, 1e-30, grazing z <= 1e-4, z = -0 and slightly
negative, below the horizon, wi = +-wo, unnormalised lengths, subnormal components) and random
directions of random length anywhere on the sphere, with hostile sample numbers u -- for every
architecture of the contract (spec.ARCHS), both shader dialects, and scene-specialised code.

Wanted: no NaN, no Inf, nothing negative, anywhere; and the library's values on the same inputs
(1e-4 relative where |ref| > 1e-6 and zeros in the same places, the budget of
test_shader_conformance.py). The policy for invalid input (docs/CODEGEN.md): a direction with a NaN
or Inf component, or whose squared length is 0, below FLT_MIN or above FLT_MAX, is invalid; then,
as below the horizon, f = 0 (every eval function), pdf = 0 (wo invalid or below the horizon, or wi
invalid: the pdf is over the whole sphere), and hbrdf_sample returns wi = +z with pdf = 0. Sample
numbers are clamped to [0, 1 - 2^-24] with NaN read as 0, so they never invalidate a sample.

Subnormals: lavapipe keeps them (measured: a z of 1e-40 is above the horizon, as in the library),
so the comparison holds on every pair. A GPU that flushes them reads such a component as 0, which
is another input of this set (finite, non-negative outputs too)."""

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf import _core, spec
from hybridbrdf.codegen.main import generate
from hybridbrdf.codegen.literals import material_constant
from hybridbrdf.model.random import random_model

from helpers import hard_directions, saved_random_model, skip_without_vulkan
from shader_kernels import render_shader
from slang_wgsl_tools import run_kernel

skip_without_vulkan(allow_module_level=True)

F32 = np.finfo(np.float32)
OUT = {"eval": slice(0, 3), "analytic": slice(3, 6), "depth0": slice(6, 9), "depth_max": slice(9, 12),
       "pdf": slice(12, 13), "sample_wi": slice(13, 16), "sample_pdf": slice(16, 17)}

# More directions of the kinds the issue names, beside the shared table (crossed with it and
# themselves; the mirrored ones make wi = -wo pairs).
EXTRA_DIRECTIONS = [
    (1e30, 0.0, 1e30), (0.0, 0.0, 1e30), (1e30, 1e30, 1e30),      # the squared length overflows
    (1e-30, 1e-30, 1e-30), (0.0, 0.0, 1e-30),                     # the squared length underflows
    (1e19, 1e19, 1e19),                                           # squared length 3e38, just below FLT_MAX
    (1e-19, 1e-19, 1e-19),                                        # subnormal squares, normal sum (valid)
    (1.0, 0.0, 1e-40), (1.0, 0.0, -1e-40),                        # subnormal z, either side of the horizon
    (0.3e-15, 0.4e-15, 0.866e-15), (3e15, 4e15, 8.66e15), (2.1, 2.8, 6.062),  # unnormalised, valid
    (np.sqrt(1 - 1e-8), 0.0, 1e-4), (0.0, -np.sqrt(1 - 1e-8), 1e-4),          # grazing, z = 1e-4
    (0.6, 0.8, 1e-6), (1.0, 0.0, 1e-30),                          # grazing, z = 1e-6 and 1e-30
    (1.0, 0.0, -0.0), (0.0, 1.0, -0.0),                           # z = -0
    (1.0, 0.0, -1e-7), (0.6, -0.8, -1e-4), (1.0, 0.0, -1e-30),    # slightly below the horizon
    (-0.3, -0.4, -0.86602540378443860),                           # -(the table's ordinary direction)
    (0.70710678, 0.0, -0.70710678), (-0.6, 0.0, 0.8), (0.6, 0.0, 0.8),
    ("nan", "nan", "nan"), ("inf", "inf", "inf"), (0.0, 0.0, "-inf"), (0.0, "-inf", 1.0),
    (np.finfo(np.float32).max, 0.0, 1.0), (0.0, 0.0, np.finfo(np.float32).max),
]

# Sample numbers: in range, at and beyond its ends, NaN, Inf.
HOSTILE_U = [0.0, 0.5, 0.99999994, 1.0, -0.0, -1.0, 2.0, 1e30, -1e30, float("nan"), float("inf"), float("-inf"),
             1e-40, 0.25]


def adversarial_directions() -> np.ndarray:
    extra = np.array([[float(v) for v in w] for w in EXTRA_DIRECTIONS])
    return np.concatenate([hard_directions(), extra]).astype(np.float32)


def adversarial_inputs(n_random=2000, seed=20):
    """(wi, wo, u) float32: the adversarial directions crossed with themselves, then random
    directions on the whole sphere with lengths 10^[-25, 25] (some components zeroed), with
    hostile and random u."""
    d = adversarial_directions()
    wi = np.repeat(d, len(d), axis=0)
    wo = np.tile(d, (len(d), 1))
    rng = np.random.default_rng(seed)

    def random_dirs(n):
        v = rng.normal(size=(n, 3))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        v *= 10.0 ** rng.uniform(-25, 25, size=(n, 1))
        v[rng.random((n, 3)) < 0.1] = 0.0
        return v

    wi = np.concatenate([wi, random_dirs(n_random)]).astype(np.float32)
    wo = np.concatenate([wo, random_dirs(n_random)]).astype(np.float32)
    hu = np.array(HOSTILE_U)
    u = rng.random((len(wi), 2))
    k = np.arange(len(wi))
    pick = rng.random(len(wi)) < 0.5
    u[pick, 0] = hu[k[pick] % len(hu)]
    u[pick, 1] = hu[(k[pick] // len(hu)) % len(hu)]
    return wi, wo, u.astype(np.float32)


def run_all_outputs(tmp_path, target, model, material, wi, wo, u, **generate_options):
    """glsl/all_outputs.comp.j2 around the generated model in ``target`` (glsl, hlsl: glslang;
    slang: slangc; wgsl: wgpu), under lavapipe: (n, 17) outputs (see OUT)."""
    code = generate(model, target, **generate_options)
    (tmp_path / f"model.{target}").write_text(code)
    extra = {"model_code": code} if target == "wgsl" else {}  # WGSL has no #include
    kernel = render_shader(f"all_outputs.comp.{target}", include=f"model.{target}",
                           material=material_constant(material), n=len(wi), **extra)
    return run_kernel(tmp_path, target, kernel, np.concatenate([wi, wo, u], axis=1), out_floats=17)


def bad_counts(out):
    """{output: (non-finite count, negative count)} over the pairs, for the failure message."""
    counts = {}
    for name, sl in OUT.items():
        v = out[:, sl]
        if name == "sample_wi":  # a direction: components may be negative
            counts[name] = (int((~np.isfinite(v)).any(1).sum()), 0)
        else:
            counts[name] = (int((~np.isfinite(v)).any(1).sum()), int((v < 0).any(1).sum()))
    return {k: c for k, c in counts.items() if c != (0, 0)}


def usable(w):
    """Directions the implementations can normalise (float32 squared length finite, >= FLT_MIN)."""
    w = w.astype(np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        len2 = (w * w).sum(axis=1, dtype=np.float32)
    return np.isfinite(len2) & (len2 >= F32.tiny)


def library_outputs(path, model, material, wi, wo, u, analytic_at=()):
    """What libhybridbrdf gives for each output of OUT (sampling: its wi and pdf). ``analytic_at``
    names the eval outputs that are f_a in the generated code (a scene's analytic-only material, or
    hbrdf_eval_depth at HBRDF_NEURAL_MAX_DEPTH)."""
    cpp = _core.Model(str(path))
    f = cpp.eval(wi, wo, material)
    if model.kind == "neural":  # its material constants: kd = 0, eta = 1, alpha = 1, so f_a = 0
        p, fa = hb.AnalyticParams(kd=0.0, eta=1.0, alpha=1.0), np.zeros_like(f)
    else:
        p = model.analytic_params(material)
        fa = hb.analytic_eval(wi, wo, p)
    s_wi, s_pdf, _ = hb.sample(wo, u, p, "mis")
    ref = {"eval": f, "analytic": fa, "depth0": f, "depth_max": fa if model.kind != "neural" else f,
           "pdf": hb.pdf(wi, wo, p, "mis")[:, None], "sample_wi": s_wi, "sample_pdf": s_pdf[:, None]}
    for name in analytic_at:
        ref[name] = fa
    return ref, p


def assert_agrees(name, got, ref, additive=False):
    """The budget of test_shader_conformance.py, on the pairs where the library is finite."""
    ok = np.isfinite(ref).all(axis=1)
    got, ref = got[ok], ref[ok]
    assert np.array_equal(got == 0, ref == 0), f"{name}: zeros in other places on {int(((got == 0) != (ref == 0)).any(1).sum())} pairs"
    if additive:  # max(f_a + o, 0) cancels: bound the error by the size of its terms
        assert np.abs(got - ref).max() <= 1e-4 * np.abs(ref).max(), name
        return
    big = np.abs(ref) > 1e-6
    rel = np.abs(got[big] - ref[big]) / np.abs(ref[big])
    assert rel.size == 0 or rel.max() < 1e-4, f"{name}: max relative error {rel.max():.3g}"


def check_outputs(out, ref, p, wi, wo, u, kind):
    """Finite and non-negative everywhere, the invalid-input policy, and the library's values."""
    bad = bad_counts(out)
    assert not bad, f"(non-finite, negative) pairs per output: {bad}"
    above = usable(wi) & usable(wo) & (wi[:, 2] > 0) & (wo[:, 2] > 0)
    for name in ("eval", "analytic", "depth0", "depth_max"):
        assert (out[~above, OUT[name]] == 0).all(), f"{name} is not 0 for an invalid or below-horizon pair"
        assert_agrees(name, out[:, OUT[name]], ref[name], additive=kind == "additive" and name in ("eval", "depth0"))
    pdf = out[:, 12]
    assert (pdf[~(usable(wi) & usable(wo) & (wo[:, 2] > 0))] == 0).all(), "pdf is not 0 for invalid input"
    assert_agrees("pdf", out[:, OUT["pdf"]], ref["pdf"])
    # hbrdf_sample. No sample (pdf = 0, wi = +z) exactly where wo is invalid or below the horizon.
    s_wi, s_pdf = out[:, OUT["sample_wi"]], out[:, 16]
    no_wo = ~(usable(wo) & (wo[:, 2] > 0))
    assert (s_pdf[no_wo] == 0).all() and (s_wi[no_wo] == [0, 0, 1]).all()
    assert (s_wi[s_pdf == 0] == [0, 0, 1]).all()
    # Away from the horizon (wi.z > 0.05, as docs/CONVENTIONS.md "Tolerances" compares sampled
    # values: near it the reflection and sqrt(1 - r^2) cancel, and below it the sign of
    # (wi + wo).z decides whether the GGX density is 0), the pdf it returns is the library's pdf
    # of the wi it returns, and that wi is the library's sample. Near the visible cap's pole
    # sqrt(1 - z^2) turns one rounding of z (6e-8) into 3.5e-4 (lavapipe contracts multiply-adds);
    # at its rim (u.y -> 1, where u = 1, 2, 1e30 and +Inf are clamped to) the half vector's
    # z + wo.z cancels completely, so the sampled wi is compared for u.y < 0.999 only.
    some = (s_pdf > 0) & (s_wi[:, 2] > 0.05)
    assert_agrees("sample pdf", s_pdf[some, None], hb.pdf(s_wi[some], wo[some], p, "mis")[:, None])
    ref_wi = ref["sample_wi"]
    u_y = np.nan_to_num(u[:, 1].astype(np.float64), nan=0.0)
    both = some & (ref["sample_pdf"][:, 0] > 0) & (ref_wi[:, 2] > 0.05) & (u_y < 0.999)
    assert both.sum() > len(wi) // 10  # (most pairs have a wo that gives no sample)
    err = np.abs(s_wi[both] - ref_wi[both]).max(axis=1)
    assert err.max() < 1e-3, (wo[both][err.argmax()], u[both][err.argmax()], err.max())


CASES = [(arch, "hardgelu" if i % 2 == 0 else "relu") for i, arch in enumerate(spec.ARCHS)]


@pytest.mark.parametrize("target", ["glsl", "hlsl"])
@pytest.mark.parametrize("arch,activation", CASES)
def test_hostile_directions_give_finite_non_negative_library_values(tmp_path, arch, activation, target):
    path, model = saved_random_model(tmp_path, arch, activation, 16, 2)
    wi, wo, u = adversarial_inputs()
    material = 1  # the anisotropic one
    out = run_all_outputs(tmp_path, target, model, model.materials[material], wi, wo, u)
    ref, p = library_outputs(path, model, material, wi, wo, u)
    check_outputs(out, ref, p, wi, wo, u, arch)


# Scene-specialised code takes other paths: isotropic-only GGX, a mixed scene's analytic_only flag,
# HBRDF_NEURAL_MAX_DEPTH = 1, and one material's latent code folded into the first layer.
SCENES = {"mixed": ([("mat-0", "full"), ("mat-2", "analytic")], 1), "single": ([("mat-0", "full")], None)}


@pytest.mark.parametrize("target", ["glsl", "hlsl"])
@pytest.mark.parametrize("scene", sorted(SCENES))
def test_hostile_directions_through_scene_specialised_shaders(tmp_path, scene, target):
    check_scene_specialised(tmp_path, scene, target, *adversarial_inputs(n_random=1000))


def check_scene_specialised(tmp_path, scene, target, wi, wo, u):
    """Every output of SCENES[scene]'s specialised code in ``target`` against the library (f_a
    where the scene asks for the analytic part) on the pairs (wi, wo, u)."""
    path, model = saved_random_model(tmp_path, "hybrid", "hardgelu", 16, 2)
    materials, depth = SCENES[scene]
    plan = {"name": scene, "materials": [{"name": n, "evaluate": e} for n, e in materials], "neural_max_depth": depth}
    for name, evaluate in materials:
        work = tmp_path / name
        work.mkdir()
        out = run_all_outputs(work, target, model, name, wi, wo, u, scene=plan)
        analytic_at = ("eval", "depth0", "depth_max") if evaluate == "analytic" else (
            ("depth_max",) if depth is not None else ())
        ref, p = library_outputs(path, model, model.index(name), wi, wo, u, analytic_at)
        check_outputs(out, ref, p, wi, wo, u, "hybrid")


@pytest.mark.parametrize("target", ["glsl", "hlsl"])
@pytest.mark.parametrize("arch", ["hybrid", "logmul", "neural"])
def test_the_largest_pre_exp_max_cannot_overflow(tmp_path, arch, target):
    """pre_exp_max = 80 (the contract's limit) with every network output clamped there: exp(80) =
    5.5e34. logmul multiplies it by f_a, which reaches 3.2e15 at ALPHA_MIN (docs/CONVENTIONS.md):
    above f_a = FLT_MAX / 5.5e34 = 6.2e3 the product is Inf in float32 (13 of these pairs before
    the template clamped it), and the shaders clamp it to FLT_MAX. The gate and exp combines add
    or return exp(80), finite."""
    _, model = random_model(arch, latent=4, width=16, depth=2, isotropic=[True, False, True])
    model.arch["pre_exp_max"] = spec.PRE_EXP_MAX_LIMIT
    model.tensors["mlp.out.bias"][:] = 100.0
    if arch != "neural":
        model.tensors["materials.alpha"][1] = [spec.ALPHA_MIN, 1e-3]
    path = tmp_path / "m.safetensors"
    model.save(path)
    model = hb.load_model(path)
    wi, wo, u = adversarial_inputs(n_random=1000)
    out = run_all_outputs(tmp_path, target, model, model.materials[1], wi, wo, u)
    assert not bad_counts(out)
    ref = _core.Model(str(path)).eval(wi, wo, 1)
    if arch == "logmul":
        assert (out[:, :3] == F32.max).any()  # the clamp was reached
        # The library (cpp/src/model_math.hpp) does not clamp yet: where it overflows, FLT_MAX.
        assert (out[:, :3][~np.isfinite(ref)] == F32.max).all()
    assert_agrees("eval", out[:, :3], ref)
