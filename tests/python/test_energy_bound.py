"""The energy bound (docs/ENERGY.md, spec/model.json energy_bounds): f = k(wi.z) k(wo.z) f_t with a
table k <= 1 per material, fitted so that no directional albedo exceeds spec.ENERGY_TARGET.

Checked here against references the bound's own code does not use: an independent Monte Carlo
estimate of the directional albedo (fresh random numbers, cosine-weighted and MIS sampling, both
sides of a non-reciprocal network), a float64 evaluation of the table by its definition (hat
functions at the nodes), the white furnace of the tracer, exact reciprocity, and both loaders'
refusal of tables that could add light. Each bound has its control: the same material without the
table reflects more than it receives, so every check can fail."""

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf import _core, spec
from hybridbrdf.brdf.analytic import sample
from hybridbrdf.codegen.literals import material_constant
from hybridbrdf.codegen.main import generate
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.model import energy
from hybridbrdf.model.random import random_model
from hybridbrdf.render import tracer

from helpers import hard_pairs, run_cli_here, skip_without_vulkan
from shader_kernels import render_shader
from slang_wgsl_tools import run_kernel

SATIN = "satin_purple_rgb"  # the shipped prior's material the issue found at 1.16-1.18 (80 degrees)


def independent_albedo(model, material, w_fixed, samples, seed, side="wo", strategy="mis"):
    """Directional albedo (max over RGB) at each of ``w_fixed`` by fresh random numbers (not the
    stratified ones the table was fitted with); ``side`` "wo" integrates over wi, "wi" over wo.
    Returns (albedo, standard error), float64."""
    rng = np.random.default_rng(seed)
    params = model.analytic_params(material)
    w = np.repeat(w_fixed, samples, axis=0)
    ws, pdf, _ = sample(w, rng.random((len(w), 2)), params, strategy)
    f = model.eval(ws, w, material) if side == "wo" else model.eval(w, ws, material)
    ok = pdf > 0
    c = np.where(ok[:, None], f * np.maximum(ws[:, 2:3], 0) / np.where(ok, pdf, 1)[:, None], 0).reshape(-1, samples, 3)
    k = c.mean(axis=1).argmax(axis=1)
    per = c[np.arange(len(w_fixed)), :, k]
    return per.mean(axis=1), per.std(axis=1) / np.sqrt(samples)


def elevations(theta_deg, phi_deg=(0.0, 90.0, 200.0)):
    t, p = np.meshgrid(np.radians(theta_deg), np.radians(phi_deg), indexing="ij")
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)


@pytest.fixture(scope="module")
def prior():
    return hb.load_prior()


@pytest.fixture(scope="module")
def bright_edit(prior, tmp_path_factory):
    """satin_purple_rgb edited to kd = 1, eta = 10 (the range corner where every material exceeds 1),
    saved, and the same edit's unbounded f_t saved beside it."""
    folder = tmp_path_factory.mktemp("energy")
    edited = prior.edit(SATIN, "bright", kd=1.0, eta=10.0).save_checked(folder / "bounded.safetensors")
    free = energy.unbounded(edited).save_checked(folder / "unbounded.safetensors")
    return edited, free


def test_the_table_is_its_definition_in_float64():
    """k(x) = sum_j k_j max(0, 1 - |x (K - 1) - j|): libhybridbrdf's and PyTorch's evaluation of the
    table against the definition in float64, at the nodes (exactly k_j), between them, at 0 and 1."""
    rng = np.random.default_rng(3)
    table = rng.uniform(0.0, 1.0, spec.ENERGY_NODES).astype(np.float32)
    x = np.concatenate([np.arange(spec.ENERGY_NODES) / (spec.ENERGY_NODES - 1), rng.random(200), [0.0, 1.0]])
    t = x * (spec.ENERGY_NODES - 1)
    ref = (table.astype(np.float64)[None, :] * np.maximum(0, 1 - np.abs(t[:, None] - np.arange(spec.ENERGY_NODES)))).sum(1)
    from hybridbrdf.model.networks import energy_bound_scale
    got_torch = energy_bound_scale(torch.from_numpy(table).double(), torch.from_numpy(x)).numpy()
    np.testing.assert_allclose(got_torch, ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(energy.scale(table, x), ref, rtol=1e-12, atol=1e-15)
    at_nodes = energy.scale(table, np.arange(spec.ENERGY_NODES) / (spec.ENERGY_NODES - 1))
    np.testing.assert_allclose(at_nodes, table, rtol=1e-7)


def test_the_table_fit_from_moments_is_the_direct_estimate():
    """energy.moments turns the bound's estimate mean_s(k(z_s) c_s) into sum_j k_j M[d, j] (k is
    linear in its nodes): for any table the same number as the direct mean, and the fitted table
    the one the direct damped steps reach, to rounding. z as the sampler returns it (float32,
    some below the horizon, exactly 0 and 1, at nodes)."""
    rng = np.random.default_rng(8)
    n, samples, nodes = 96, 300, spec.ENERGY_NODES
    z = rng.uniform(-0.2, 1.0, (n, samples)).astype(np.float32)
    z[:, :nodes] = (np.arange(nodes) / (nodes - 1)).astype(np.float32)
    z[:, nodes], z[:, nodes + 1] = 0.0, 1.0
    c = rng.gamma(0.5, 2.0, (n, samples, 3)) * (z > 0)[..., None]
    x = rng.choice(np.concatenate([[0.0005, 0.002], np.linspace(0.004, 1.0, 61)]), n)
    m = energy.moments(c, z)

    def direct(k):  # the estimate by its definition: k at every sample, then the mean
        return energy.scale(k, x) * (energy.scale(k, z)[..., None] * c).mean(axis=1).max(axis=1)

    for k in (np.ones(nodes), rng.uniform(0.3, 1.0, nodes)):
        np.testing.assert_allclose(energy._albedo(m, x, k), direct(k), rtol=1e-12, atol=1e-15)
    top = direct(np.ones(nodes)).max()
    for target in (0.95 * top, 0.5 * top):  # binding at a few nodes, and everywhere
        k = np.ones(nodes)

        def room(k):
            rho = direct(k)
            return energy._node_minimum(np.where(rho > 0, target / rho, np.inf), x)

        if direct(k).max() > target:
            k = np.minimum(1.0, room(k))
            for _ in range(energy.ITERATIONS):
                k = np.minimum(1.0, k * np.sqrt(room(k)))
            k = k * np.minimum(1.0, room(k))
        got = energy.fit_table(c, z, x, target)
        assert got.min() < 1.0  # the control: the table binds
        np.testing.assert_allclose(got, k, rtol=1e-12, atol=1e-15)
        assert direct(got).max() <= target * (1 + 1e-12)


def test_a_model_with_tables_agrees_between_implementations(tmp_path):
    """libhybridbrdf's scalar path and every batched kernel against the float64 PyTorch model, for
    the hybrid, the reciprocal form with material output layers and the neural baseline."""
    rng = np.random.default_rng(5)
    hwi, hwo = hard_pairs()
    wi = np.concatenate([cosine_directions(rng, 4099), hwi]).astype(np.float32)
    wo = np.concatenate([cosine_directions(rng, 4099), hwo]).astype(np.float32)
    for arch, layer in (("hybrid", "shared"), ("hybrid-reciprocal", "material"), ("neural", "shared")):
        _, model = random_model(arch, latent=12 if arch == "neural" else 4, isotropic=[True, False, True],
                                output_layer=layer, energy_bound=True)
        path = tmp_path / f"{arch}.safetensors"
        model = model.save_checked(path)
        cpp = _core.Model(str(path))
        plain = energy.unbounded(model).save_checked(tmp_path / f"{arch}_plain.safetensors")
        for m in range(3):
            ref = model.eval(wi, wo, m, dtype=torch.float64)
            zeros = model.eval(wi, wo, m, dtype=torch.float32) == 0  # float32's invalid directions are float64's valid ones
            for got in (cpp.eval(wi, wo, m), cpp.eval_scalar(wi, wo, m)):
                assert np.isfinite(got).all() and np.array_equal(got == 0, zeros)
                big = (np.abs(ref) > 1e-6) & ~zeros
                assert (np.abs(got[big] - ref[big]) / np.abs(ref[big])).max() < 2e-5, (arch, m)
            # The control: the table changes the values (it is not ones), so the agreement means something.
            assert not np.allclose(plain.eval(wi, wo, m), cpp.eval(wi, wo, m), rtol=1e-3)


def test_reciprocity_is_kept_bit_for_bit(tmp_path):
    _, model = random_model("hybrid-reciprocal", isotropic=[True, False, True], energy_bound=True)
    path = tmp_path / "m.safetensors"
    model = model.save_checked(path)
    rng = np.random.default_rng(9)
    hwi, hwo = hard_pairs()
    wi = np.concatenate([cosine_directions(rng, 3000), hwi]).astype(np.float32)
    wo = np.concatenate([cosine_directions(rng, 3000), hwo]).astype(np.float32)
    cpp = _core.Model(str(path))
    for m in range(3):
        assert np.array_equal(cpp.eval(wi, wo, m), cpp.eval(wo, wi, m))
        assert np.array_equal(cpp.eval_scalar(wi, wo, m), cpp.eval_scalar(wo, wi, m))
        assert np.array_equal(model.eval(wi, wo, m, dtype=torch.float32), model.eval(wo, wi, m, dtype=torch.float32))


def test_the_generated_glsl_with_tables_is_exactly_reciprocal_under_lavapipe(tmp_path):
    skip_without_vulkan()
    _, model = random_model("hybrid-reciprocal", isotropic=[True, False, True], energy_bound=True)
    rng = np.random.default_rng(2)
    wi = cosine_directions(rng, 2000).astype(np.float32)
    wo = cosine_directions(rng, 2000).astype(np.float32)
    u = np.full((len(wi), 2), 0.5, dtype=np.float32)
    (tmp_path / "model.glsl").write_text(generate(model, "glsl"))
    kernel = render_shader("all_outputs.comp.glsl", include="model.glsl", material=material_constant(model.materials[1]),
                           n=2 * len(wi))
    rows = np.concatenate([np.concatenate([wi, wo, u], axis=1), np.concatenate([wo, wi, u], axis=1)])
    out = run_kernel(tmp_path, "glsl", kernel, rows, out_floats=17)
    f, g = out[:len(wi), 0:3], out[len(wi):, 0:3]
    assert (f > 0).any() and np.array_equal(f, g)


def test_a_bright_edit_is_bounded_by_an_independent_estimate(bright_edit):
    """kd = 1, eta = 10: without the table the material reflects far more than it receives near
    grazing; with it, an independent estimate (fresh random numbers, 2^15 MIS samples per direction,
    both sides) stays within 1 + 4 standard errors + 2e-3 everywhere on a grid of elevations that
    the table's own estimate did not use."""
    edited, free = bright_edit
    w = elevations([0.0, 17.0, 41.0, 63.0, 71.0, 77.0, 79.5, 82.0, 84.5, 86.0, 87.5, 89.0])
    worst_free = 0.0
    for side in ("wo", "wi"):
        a, se = independent_albedo(edited, "bright", w, 1 << 15, seed=11, side=side)
        assert (a <= 1.0 + 4 * se + 2e-3).all(), (side, a.max(), se[a.argmax()])
        b, _ = independent_albedo(free, "bright", w, 1 << 13, seed=12, side=side)
        worst_free = max(worst_free, b.max())
        assert (a <= b + 1e-9 + 4 * se).all()  # the bound only removes light
    assert worst_free > 1.2  # the control: without the table the edit is far above 1


def test_the_table_leaves_normal_incidence_and_dim_materials_alone(prior, bright_edit):
    edited, free = bright_edit
    # kd = 1 with eta = 10 reflects more than 1 even at normal incidence: dimmed everywhere.
    assert edited.tensors["materials.energy_bound"][edited.index("bright")].max() < 1.0
    # satin_purple_rgb exceeds 1 near grazing only: dimmed there, untouched toward the normal.
    table = prior.tensors["materials.energy_bound"][prior.index(SATIN)]
    assert table.min() < 0.95 and (table[6:] == 1.0).all()
    dim = [m for m in prior.materials if prior.material_info[prior.index(m)].get("energy_bound", {}).get("min_factor") == 1.0]
    assert len(dim) > 100
    t = prior.tensors["materials.energy_bound"]
    assert all((t[prior.index(m)] == 1.0).all() for m in dim)


def test_the_shipped_prior_is_bounded(prior, tmp_path):
    """Every material of the shipped prior has a table, and its recorded estimate is within the
    target; the material the issue measured at 1.16-1.18 is within 1 by the independent estimate."""
    assert prior.arch["energy_bound"] == "albedo_table"
    for info in prior.material_info:
        assert info["energy_bound"]["max_albedo"] <= spec.ENERGY_TARGET + 1e-9, info["name"]
    w = elevations(np.arange(70.0, 89.0, 2.0))
    a, se = independent_albedo(prior, SATIN, w, 1 << 14, seed=3)
    assert (a <= 1.0 + 4 * se + 2e-3).all(), a.max()
    b, _ = independent_albedo(energy.unbounded(prior).save_checked(tmp_path / "free.safetensors"), SATIN, w, 1 << 14, seed=4)
    assert b.max() > 1.05  # the control


def test_white_furnace_a_bounded_sphere_is_never_brighter_than_its_environment(bright_edit, tmp_path):
    """A sphere of the bright edit alone under a constant environment of radiance 1, one bounce
    (convex: exact), MIS sampling: each pixel estimates the albedo toward the camera. With the
    table no pixel exceeds 1 beyond 4 standard errors (from 4 independent seeds); without it the
    rim does, far beyond them."""
    edited, free = bright_edit

    def render(path, seed):
        s = {"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "fov_deg": 32, "width": 48, "height": 48},
             "environment": {"type": "constant", "radiance": [1, 1, 1]},
             "materials": {"m": {"type": "model", "file": str(path), "material": "bright"}},
             "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
             "spp": 128, "max_depth": 1, "threads": 2, "seed": seed, "nee": False}
        img, _ = tracer.render(s)
        return img.max(axis=2).astype(np.float64)

    for path, bounded in ((edited.path, True), (free.path, False)):
        imgs = np.stack([render(path, seed) for seed in range(4)])
        mean, se = imgs.mean(0), imgs.std(0, ddof=1) / 2
        on = mean > 0.05  # the sphere's pixels
        excess = (mean - 1.0)[on] / np.maximum(se[on], 1e-4)
        if bounded:
            assert excess.max() < 4.0, (mean[on].max(), excess.max())
        else:
            assert mean[on].max() > 1.1 and excess.max() > 8.0


def test_edits_and_blends_keep_the_bound_instead_of_refusing(prior, monkeypatch, tmp_path):
    """--conserve-energy scales kd where that suffices, and where even kd = 0 reflects too much (the
    previous release refused) the table alone bounds the material."""
    edit = prior.edit(SATIN, "e", eta=10.0, conserve_energy=True)
    rec = edit.material_info[edit.index("e")]
    assert 0.0 < rec["edit"]["kd_scaled_for_energy"] < 1.0
    assert rec["energy_bound"]["max_albedo"] <= spec.ENERGY_TARGET + 1e-9
    from hybridbrdf.model import editing
    monkeypatch.setattr(editing, "ALBEDO_TARGET", 0.1)  # below what the blend reflects with kd = 0
    blend = prior.mix(SATIN, "acrylic_felt_orange_rgb", 0.5, "half", conserve_energy=True)
    rec = blend.material_info[blend.index("half")]
    assert rec["mix"]["kd_scaled_for_energy"] is None
    assert rec["energy_bound"]["max_albedo"] <= spec.ENERGY_TARGET + 1e-9
    w = elevations([0.0, 60.0, 75.0, 80.0, 84.0, 87.0])
    for model, name in ((edit, "e"), (blend, "half")):
        model = model.save_checked(tmp_path / f"{name}.safetensors")  # evaluated by libhybridbrdf, as bright_edit
        a, se = independent_albedo(model, name, w, 1 << 13, seed=5)
        assert (a <= 1.0 + 4 * se + 2e-3).all(), (name, a.max())


def test_a_fit_writes_tables_and_no_energy_bound_does_not(tmp_path):
    out = tmp_path / "m.safetensors"
    plain = tmp_path / "plain.safetensors"
    # 10 steps and no preview: the tables follow whatever the fit ends at; the preview is not read here.
    # hbrdf in this process (a fresh interpreter imports torch and torch._dynamo: 4-5 s of CPU).
    for path, extra in ((out, []), (plain, ["--no-energy-bound"])):
        r = run_cli_here("fit", "synthetic:gold", "synthetic:plastic", "--steps", "10", "--batch", "512", "--pool",
                         "4096", "--eval-pairs", "2000", "--mlp", "8x1", "--no-preview", "--out", str(path), *extra)
        assert r.returncode == 0, r.stderr
    model, free = hb.load_model(out), hb.load_model(plain)
    assert model.arch["energy_bound"] == "albedo_table" and model.tensors["materials.energy_bound"].shape == (2, spec.ENERGY_NODES)
    assert all("energy_bound" in m for m in model.material_info)
    assert free.arch["energy_bound"] == "none" and "materials.energy_bound" not in free.tensors
    r = run_cli_here("info", str(out), "--albedo-samples", "0")
    assert r.returncode == 0, r.stderr
    assert "energy bound per material" in r.stdout and "energy bound: max albedo" in r.stdout


def test_hbrdf_bound_bounds_an_old_file_and_leaves_out_alone_on_error(tmp_path, bright_edit):
    edited, free = bright_edit
    out = tmp_path / "b.safetensors"
    r = run_cli_here("bound", free.path, "--out", str(out), "--materials", "bright")
    assert r.returncode == 0, r.stderr
    assert "bright" in r.stdout and "1 material(s) dimmed" in r.stdout
    bounded = hb.load_model(out)
    assert bounded.tensors["materials.energy_bound"][bounded.index("bright")].min() < 0.9
    others = [i for i, m in enumerate(bounded.materials) if m != "bright"]
    assert (bounded.tensors["materials.energy_bound"][others] == 1.0).all()
    r = run_cli_here("bound", free.path, "--out", str(tmp_path / "x"), "--materials", "no-such")
    assert r.returncode == 1 and "no-such" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()
