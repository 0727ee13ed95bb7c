"""Material output layers (spec/model.json, output_layers "material"): each material
evaluates with its own output layer, in every implementation, and keeps it through edits,
blends and sparse fits.

Oracle: the hybrid model in NumPy float64 from the textbook forms (reference.textbook_fa, the
hardGeLU layers, the gated combine), with material m's head applied by hand; the library's
batched kernels (each instruction set), its scalar path and PyTorch are held against it."""

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf import _core
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.model.editing import edit, mix
from hybridbrdf.model.random import random_model


def numpy_hybrid_with_heads(t, arch, wi, wo, m):
    from textbook_reference import textbook_fa

    t = {k: np.asarray(v, dtype=np.float64) for k, v in t.items()}
    z = np.broadcast_to(t["materials.z"][m], (len(wi), arch["latent"]))
    x = np.concatenate([wi, wo, z], axis=1)
    for i in range(arch["depth"]):
        x = x @ t[f"mlp.hidden.{i}.weight"].T + t[f"mlp.hidden.{i}.bias"]
        x = x * np.clip((x + 1.5) / 3.0, 0.0, 1.0)
    o = x @ t["materials.head_weight"][m].T + t["materials.head_bias"][m]
    fa = textbook_fa(wi, wo, t["materials.kd"][m], t["materials.eta"][m], t["materials.alpha"][m])
    return np.exp(np.minimum(o[:, :3], arch["pre_exp_max"])) + fa / (1.0 + np.exp(-o[:, 3:]))


@pytest.fixture()
def head_model(tmp_path):
    _, model = random_model("hybrid", latent=4, width=32, depth=2, isotropic=[True, False, True],
                            output_layer="material")
    path = tmp_path / "heads.safetensors"
    model.save(path)
    return path, hb.load_model(path)


def test_every_path_applies_the_materials_own_output_layer(head_model):
    path, py = head_model
    assert py.arch["output_layer"] == "material"
    heads = py.tensors["materials.head_weight"]
    assert heads.shape == (3, 6, 32) and not np.allclose(heads[0], heads[1])  # really per material
    cpp = _core.Model(str(path))
    rng = np.random.default_rng(3)
    n = 3001  # not a multiple of the batched kernels' 64-pair chunk
    wi = cosine_directions(rng, n).astype(np.float32).astype(np.float64)
    wo = cosine_directions(rng, n).astype(np.float32).astype(np.float64)
    best = _core.model_simd_path()
    kernels = ["avx512", "avx2+fma", "baseline"]
    try:
        for m in range(3):
            ref = numpy_hybrid_with_heads(py.tensors, py.arch, wi, wo, m)
            results = {"scalar": cpp.eval_scalar(wi, wo, m), "torch": py.eval(wi, wo, m, dtype=torch.float64)}
            for k in kernels[kernels.index(best):]:
                _core.limit_model_simd(k)
                results[k] = cpp.eval(wi, wo, m)
            for name, got in results.items():
                rel = np.abs(np.asarray(got, np.float64) - ref) / np.maximum(np.abs(ref), 1e-12)
                assert rel.max() < 2e-4, (name, m, rel.max())
        # Material 1 evaluated with material 0's head differs: the head is what makes it material 1.
        swapped = dict(py.tensors)
        swapped["materials.head_weight"] = heads[[1, 0, 2]]
        assert not np.allclose(numpy_hybrid_with_heads(swapped, py.arch, wi, wo, 0),
                               numpy_hybrid_with_heads(py.tensors, py.arch, wi, wo, 0), rtol=1e-3)
    finally:
        _core.limit_model_simd("avx512")


def test_edit_keeps_the_head_and_mix_blends_it(head_model):
    _, py = head_model
    edited = edit(py, "mat-1", "mat-1-red", kd=(0.8, 0.1, 0.1))
    for key in ("head_weight", "head_bias", "z"):
        assert np.array_equal(edited.tensors[f"materials.{key}"][3], py.tensors[f"materials.{key}"][1])
    for t, expect_from in ((0.0, 0), (1.0, 2)):
        blend = mix(py, "mat-0", "mat-2", t, "blend")
        assert np.array_equal(blend.tensors["materials.head_weight"][3], py.tensors["materials.head_weight"][expect_from])
    half = mix(py, "mat-0", "mat-2", 0.5, "blend").tensors["materials.head_bias"][3]
    np.testing.assert_allclose(half, 0.5 * (py.tensors["materials.head_bias"][0] + py.tensors["materials.head_bias"][2]),
                               rtol=1e-6)


def test_a_sparse_fit_gives_new_materials_heads_and_keeps_the_hidden_layers(tmp_path):
    from hybridbrdf.fit.settings import FitSettings
    from hybridbrdf.fit import fit
    from hybridbrdf.sources import open_source

    base = fit([open_source("synthetic:plastic"), open_source("synthetic:gold")],
               FitSettings(width=16, depth=2, steps=150, pool=4096, eval_pairs=4000, output_layer="material"),
               progress=False, log=lambda m: None)
    assert base.arch["output_layer"] == "material"
    path = tmp_path / "base.safetensors"
    base.save(path)
    frozen = hb.load_model(path)
    new = fit([open_source("synthetic:velvet")], FitSettings(steps=100, pool=4096, eval_pairs=4000),
              frozen=frozen, progress=False, log=lambda m: None)
    assert new.arch["output_layer"] == "material"
    for k, v in frozen.tensors.items():
        if k.startswith("mlp."):
            assert np.array_equal(new.tensors[k], v), k  # the shared layers stay the frozen ones
    assert new.tensors["materials.head_weight"].shape == (1, 6, 16)
    # The new head moved from where it started (the nearest material's).
    start = frozen.tensors["materials.head_weight"]
    assert min(np.abs(new.tensors["materials.head_weight"][0] - s).max() for s in start) > 0


def test_the_neural_baseline_keeps_one_output_layer():
    from hybridbrdf.fit.settings import FitSettings
    from hybridbrdf.model.networks import build_model

    with pytest.raises(ValueError, match="analytic part"):
        build_model("neural", 2, 8, 1, 12, "relu", output_layer="material")
    assert FitSettings().output_layer == "material"  # the default of the hybrid architectures
    assert FitSettings(arch="neural").network_output_layer() == "shared"
    assert FitSettings(arch="hybrid-half").network_output_layer() == "material"
    assert FitSettings.from_recipe("paper").output_layer == "shared"
    assert FitSettings.from_recipe("fast").output_layer == "material"


def test_generated_code_takes_a_scenes_one_head_as_literals(tmp_path):
    """Specialised for a scene of one material, the head becomes literals (no head_w in
    HbrdfMaterial) and the header still computes what the library computes; BRDF Explorer files
    hold the default material's head as literals too."""
    from test_codegen import _build_driver, _run_driver, tracer_scene

    from hybridbrdf.codegen.main import generate
    from hybridbrdf.codegen.scene import load_scene
    from helpers import saved_random_model

    path, model = saved_random_model(tmp_path, "hybrid", output_layer="material")
    general = generate(model, "cpp")
    assert "float head_w[96];" in general  # 6 x 16
    scene = load_scene(tracer_scene(path, {"one": "mat-1"}), model)
    text = generate(model, "cpp", scene=scene)
    assert "head_w" not in text and "folded into the first layer" in text
    rng = np.random.default_rng(9)
    wi = cosine_directions(rng, 3000).astype(np.float32)
    wo = cosine_directions(rng, 3000).astype(np.float32)
    u = rng.random((3000, 2)).astype(np.float32)
    got = _run_driver(_build_driver(tmp_path, text, ["mat-1"]), wi, wo, u, 1)[0]
    ref = _core.Model(str(path)).eval_scalar(wi, wo, 1)
    assert np.allclose(got[:, :3], ref, rtol=1e-5, atol=1e-9)
    explorer = generate(model, "brdfexplorer")
    assert "head_w" not in explorer and "hbrdf_mlp(x, o)" in explorer
