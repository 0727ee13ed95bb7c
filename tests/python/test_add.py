"""hbrdf add / hybridbrdf.add: new materials on a frozen network, merged into one model file."""

import os
import pathlib
import re
import time

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf.fit.adding import merge
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.evaluate.evaluation import evaluate
from hybridbrdf.fit import fit
from hybridbrdf.sources import open_source

from helpers import run_cli_here

# 40 steps: no test here reads how well a tiny fit converged, only what adding does with it (rows
# kept bit for bit, the network frozen or moved, refusals, records); the fine-tune's gain over
# its sparse start sets its own steps. The additions skip the energy bound (its tables are
# test_energy_bound.py's; 0.5-1.3 s a fit); the base has tables, which a merge keeps bit for bit.
TINY = dict(steps=40, batch=256, pool=2048, eval_pairs=2000, energy_bound=False)


@pytest.fixture(scope="module")
def base_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("add") / "base.safetensors"
    settings = FitSettings(width=8, depth=1, latent=2, **dict(TINY, energy_bound=True))
    fit([open_source("synthetic:gold"), open_source("synthetic:plastic")], settings, progress=False,
        log=lambda m: None).save(path)
    return path


def test_added_materials_join_the_base_unchanged(base_file, tmp_path):
    out = tmp_path / "merged.safetensors"
    merged = hb.add(["synthetic:velvet", "synthetic:rough_clay"], to=base_file, out=out,
                    settings=FitSettings(**TINY), progress=False)
    base = hb.load_model(base_file)
    assert merged.materials == ["gold", "plastic", "velvet", "rough_clay"]
    assert hb.load_model(out).materials == merged.materials  # written, and valid for the loader
    for key, value in base.tensors.items():
        got = merged.tensors[key]
        if key.startswith("materials."):
            np.testing.assert_array_equal(got[:2], value)  # the base's materials, bit for bit
        else:
            np.testing.assert_array_equal(got, value)  # the frozen network
    # The new rows are exactly what a sparse fit against the frozen network gives on its own.
    alone = fit([open_source("synthetic:velvet"), open_source("synthetic:rough_clay")],
                FitSettings(frozen_from=str(base_file), width=8, depth=1, latent=2, **TINY), frozen=base,
                progress=False, log=lambda m: None)
    for key in alone.tensors:
        if key.startswith("materials."):
            np.testing.assert_array_equal(merged.tensors[key][2:], alone.tensors[key])
    wi = np.array([[0.3, 0.1, 0.9]], np.float32)
    wo = np.array([[-0.2, 0.2, 0.95]], np.float32)
    # (The tensors are bit-identical; evaluation order in the batched kernel may differ by an ulp.)
    np.testing.assert_allclose(merged.eval(wi, wo, "velvet"), alone.eval(wi, wo, "velvet"), rtol=1e-6)
    assert merged.training["additions"][-1]["materials"] == ["velvet", "rough_clay"]


def test_merge_refuses_materials_of_another_network(base_file):
    base = hb.load_model(base_file)
    other = fit([open_source("synthetic:velvet")], FitSettings(width=8, depth=1, latent=2, seed=3, **TINY),
                progress=False, log=lambda m: None)
    with pytest.raises(ValueError, match="were not fitted to this network"):
        merge(base, other)


@pytest.mark.parametrize("case", ["name taken", "constant taken", "base not a model", "source unreadable",
                                  "out is a folder"])
def test_bad_input_fails_before_training_and_leaves_out_alone(base_file, tmp_path, case):
    out = tmp_path / "out.safetensors"
    out.write_bytes(b"previous file")
    sources, to, target = ["synthetic:velvet"], base_file, out
    if case == "name taken":
        sources, words = ["synthetic:gold"], "gold: material 'gold' is already in"
    elif case == "constant taken":
        clash = tmp_path / "GOLD.bin"  # UTIA's grid: 52 k values (MERL's 1.5 M cost 4 s; any format names it)
        from hybridbrdf.sources.utia import write_utia

        write_utia(clash, open_source("synthetic:gold"))
        sources, words = [str(clash)], "materials 'gold' and 'GOLD' would share the shader constant HBRDF_MATERIAL_GOLD"
    elif case == "base not a model":
        to = tmp_path / "base.safetensors"
        to.write_bytes(b"\x00" * 5)
        words = f"{to}: truncated"
    elif case == "source unreadable":
        bad = tmp_path / "broken.bsdf"
        bad.write_bytes(b"tensor_file\x00\x01")
        sources, words = [str(bad)], f"{bad}: "
    else:
        target = tmp_path
        words = f"{tmp_path}: is a folder"
    t0 = time.perf_counter()
    r = run_cli_here("add", *sources, "--to", str(to), "--out", str(target), "--steps", "100000")
    assert r.returncode == 1, r.stdout + r.stderr
    err = r.stderr.strip()
    assert err.count("\n") == 0 and words in err, err
    assert "Traceback" not in r.stderr
    assert time.perf_counter() - t0 < 60  # 10^5 steps would take far longer: refused before training
    assert out.read_bytes() == b"previous file"


def test_out_may_be_the_base_itself(base_file, tmp_path):
    path = tmp_path / "collection.safetensors"
    path.write_bytes(base_file.read_bytes())
    r = run_cli_here("add", "synthetic:velvet", "--to", str(path), "--out", str(path), "--steps", "5", "--batch", "256",
                "--pool", "2048", "--eval-pairs", "2000", "--quiet")
    assert r.returncode == 0, r.stderr
    assert "added 1 material(s)" in r.stdout and "(3 materials)" in r.stdout
    assert hb.load_model(path).materials == ["gold", "plastic", "velvet"]
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".")]  # no temporaries left


def test_add_takes_only_the_settings_that_apply():
    r = run_cli_here("add", "--help")
    assert r.returncode == 0
    for flag in ("--steps", "--lr", "--loss-eps", "--specular", "--sparse-init", "--to", "--out"):
        assert flag in r.stdout
    for flag in ("--mlp", "--arch", "--latent", "--frozen"):  # the base's network decides these
        assert not re.search(rf"^\s+{flag}\b", r.stdout, re.M), flag


def test_keep_network_on_the_prior_writes_the_new_materials_only_on_its_network(base_file, tmp_path, monkeypatch):
    import hybridbrdf.model.prior as prior_module

    # a small stand-in for the shipped prior hbrdf add takes by default (the reciprocal one since issue 60)
    monkeypatch.setattr(prior_module, "RECIPROCAL_PRIOR_FILE", base_file)
    out = tmp_path / "mine.safetensors"
    added = hb.add(["synthetic:velvet", "synthetic:gold"], out=out, settings=FitSettings(**TINY), progress=False,
                   keep_network=True)
    prior = hb.load_model(base_file)
    # gold is a material of the prior too: on the prior that is no clash, its materials are not written.
    assert added.materials == ["velvet", "gold"] and hb.load_model(out).materials == ["velvet", "gold"]
    for key, value in prior.tensors.items():
        if not key.startswith("materials."):
            np.testing.assert_array_equal(added.tensors[key], value)
        else:
            assert added.tensors[key].shape[0] == 2
    assert added.training["additions"][-1]["frozen_from"] == str(base_file)
    assert added.training["additions"][-1]["mode"] == "sparse"
    # --keep-network is the sparse fit as it was before the fine-tune became the default: bit for bit.
    alone = fit([open_source("synthetic:velvet"), open_source("synthetic:gold")],
                FitSettings(frozen_from=str(base_file), **TINY), frozen=prior, progress=False, log=lambda m: None)
    for key in alone.tensors:
        np.testing.assert_array_equal(added.tensors[key], alone.tensors[key])


def _file_digest(path) -> str:
    import hashlib

    return hashlib.sha256(pathlib.Path(path).read_bytes()).hexdigest()


def test_add_on_the_prior_fine_tunes_its_network_and_leaves_the_prior_file_alone(base_file, tmp_path, monkeypatch):
    """The default onto the prior: the sparse fit, then the network trained with the new material.
    Its cMAE on pairs it was not trained on must end below the sparse fit's (the network's extra
    freedom is used), and the prior's file is never written."""
    import hybridbrdf.model.prior as prior_module

    monkeypatch.setattr(prior_module, "RECIPROCAL_PRIOR_FILE", base_file)  # the default prior's stand-in
    before = _file_digest(base_file)
    settings = FitSettings(**{**TINY, "steps": 300, "eval_pairs": 20_000})
    sparse = hb.add(["synthetic:velvet"], settings=settings, progress=False, keep_network=True)
    tuned = hb.add(["synthetic:velvet"], out=tmp_path / "tuned.safetensors", settings=settings, progress=False,
                   finetune_steps=300)
    assert _file_digest(base_file) == before
    prior = hb.load_model(base_file)
    moved = [k for k in prior.tensors if not k.startswith("materials.")
             and not np.array_equal(prior.tensors[k], tuned.tensors[k])]
    assert moved, "the fine-tune left the network as it was"
    assert tuned.materials == ["velvet"] and hb.load_model(tmp_path / "tuned.safetensors").materials == ["velvet"]
    assert tuned.training["mode"] == "fine-tune" and tuned.training["steps"] == 300
    assert tuned.training["init_from"] == "prior" and tuned.training["sparse_fit"]["frozen_from"] == str(base_file)
    # Metrics of a held sample of pairs (not the training pool): the fine-tune must not lose to its own start.
    src = open_source("synthetic:velvet")
    (s_row,) = evaluate(sparse, [src], n_pairs=50_000, seed=11)
    (t_row,) = evaluate(tuned, [src], n_pairs=50_000, seed=11)
    assert t_row["cmae"] < s_row["cmae"], (t_row, s_row)
    assert tuned.material_info[0]["sparse_fit"]["metrics"]["cmae"] == pytest.approx(
        sparse.material_info[0]["metrics"]["cmae"], rel=1e-6)  # the start it records is the sparse fit's
    r = run_cli_here("info", str(tmp_path / "tuned.safetensors"))
    assert r.returncode == 0 and "added by fine-tuning the network of prior" in r.stdout, r.stdout


def test_fine_tune_flags_belong_to_the_prior(base_file, tmp_path):
    out = tmp_path / "x.safetensors"
    r = run_cli_here("add", "synthetic:velvet", "--to", str(base_file), "--keep-network", "--out", str(out))
    assert r.returncode == 1 and "--keep-network and --finetune-steps are for adding to the shipped prior" in r.stderr
    assert not out.exists()


def test_warm_start_copies_materials_by_name_and_starts_the_rest_from_the_nearest(base_file):
    """fit(init=M): M's network and M's (p, z) for sources of the same name; at a vanishing
    learning rate the fitted model is M's, row for row; a source M lacks gets M's best-fitting material."""
    base = hb.load_model(base_file)
    logs = []
    # With the bound, as the base has: its tables are among the rows compared.
    settings = FitSettings(**{**TINY, "steps": 2, "lr": 1e-12, "energy_bound": True}, init_from=str(base_file))
    warm = fit([open_source("synthetic:plastic"), open_source("synthetic:velvet")], settings, init=base,
               progress=False, log=logs.append)
    assert warm.materials == ["plastic", "velvet"]
    for key, value in base.tensors.items():
        got = warm.tensors[key]
        want = value[1] if key.startswith("materials.") else value  # plastic is the base's second material
        np.testing.assert_allclose(got[0] if key.startswith("materials.") else got, want, rtol=1e-5, atol=1e-6)
    assert any(line.startswith("warm start: velvet <- ") for line in logs), logs
    nearest = logs[-1].split("<- ")[1].split(",")[0]
    k = base.materials.index(nearest)
    np.testing.assert_allclose(warm.tensors["materials.z"][1], base.tensors["materials.z"][k], rtol=1e-5, atol=1e-6)


def test_warm_start_and_frozen_are_exclusive(base_file, tmp_path):
    r = run_cli_here("fit", "synthetic:velvet", "--frozen", str(base_file), "--init", str(base_file),
                "--out", str(tmp_path / "x.safetensors"))
    assert r.returncode == 1 and "give one of them" in r.stderr, r.stderr


def test_warm_started_fit_resumes_its_checkpoint_exactly(base_file, tmp_path):
    """An --init fit checkpoints and resumes like any fit: stopped and resumed, it equals the uninterrupted run."""
    base = hb.load_model(base_file)
    srcs = [open_source("synthetic:velvet"), open_source("synthetic:gold")]
    settings = FitSettings(**{**TINY, "steps": 40}, init_from=str(base_file))
    whole = fit(srcs, settings, init=base, progress=False, log=lambda m: None)
    ck = tmp_path / "ck.pt"
    assert fit(srcs, settings, init=base, checkpoint=str(ck), checkpoint_every=10, stop_after=20,
               progress=False, log=lambda m: None) is None
    resumed = fit(srcs, settings, init=base, checkpoint=str(ck), resume=True, progress=False, log=lambda m: None)
    for key in whole.tensors:
        np.testing.assert_array_equal(resumed.tensors[key], whole.tensors[key])


def test_add_without_a_prior_installed_says_so_in_one_line(tmp_path, monkeypatch):
    import hybridbrdf.model.prior as prior_module

    monkeypatch.setattr(prior_module, "RECIPROCAL_PRIOR_FILE", tmp_path / "absent" / "prior_reciprocal.safetensors")
    out = tmp_path / "mine.safetensors"
    with pytest.raises(hb.InputFileError, match="shipped prior is missing") as err:
        hb.add(["synthetic:velvet"], out=out, settings=FitSettings(**TINY), progress=False)
    assert "\n" not in str(err.value) and not out.exists()


def test_the_shipped_prior_is_installed_with_the_package_and_valid():
    """The checkout's prior (python/hybridbrdf/data) must reach the installed package, bit for bit."""
    from hybridbrdf.model.prior import PRIOR_FILE

    from helpers import ROOT

    source = ROOT / "python" / "hybridbrdf" / "data" / "prior.safetensors"
    if not source.is_file():
        pytest.skip("no prior in this checkout (bench/train_prior.py writes it)")
    assert PRIOR_FILE.is_file(), f"{PRIOR_FILE} missing: the wheel did not carry the prior"
    assert PRIOR_FILE.read_bytes() == source.read_bytes()
    prior = hb.load_prior()
    assert prior.kind == "hybrid" and len(prior.materials) >= 100
    assert PRIOR_FILE.stat().st_size < 1 << 20  # small enough to ship in the wheel


class _ModelMaterial(hb.BRDFSource):
    """A material of a fitted model as a source: the loss of its own (p, z) is ~0."""

    def __init__(self, model, material):
        self.model, self.material, self.name, self.isotropic, self.origin = model, material, "twin", True, "model"

    def _eval(self, wi, wo):
        return self.model.eval(wi.astype(np.float32), wo.astype(np.float32), self.material).astype(np.float64)


def test_several_starts_keep_the_start_of_lowest_loss(base_file):
    """sparse_starts: each new material is fitted from its k best-scoring base materials at once
    and the fit of lowest training loss is kept. A twin of a base material (its own values) is
    fitted exactly from that material's (p, z), so with 0 steps the kept start must be it: the
    selection picks by loss, whatever row the start sits in."""
    base = hb.load_model(base_file)
    logs = []
    twin = _ModelMaterial(base, "plastic")
    for starts in (1, 2):
        settings = FitSettings(frozen_from=str(base_file), sparse_starts=starts,
                               **dict(TINY, steps=1, lr=1e-9, energy_bound=True))  # the base's tables compared too
        model = fit([twin], settings, frozen=base, progress=False, log=logs.append)
        assert model.materials == ["twin"] and model.material_info[0]["sparse_start"]["material"] == "plastic"
        for key, value in base.tensors.items():
            if key.startswith("materials."):
                got = model.tensors[key][0]
                np.testing.assert_allclose(got, value[base.materials.index("plastic")], rtol=1e-5, atol=1e-6)
    assert any(re.search(r"twin <- plastic \| gold", m) for m in logs), logs  # both starts were fitted
    assert any("kept the fits started from twin <- plastic" in m for m in logs), logs


def test_several_starts_pick_the_better_fit_when_the_nearest_is_not_it(base_file, monkeypatch):
    """Put the worse start first (row m k + 0): the selection must still keep the other."""
    import hybridbrdf.fit.joint as fitting

    base = hb.load_model(base_file)
    real = fitting.start_from_nearest

    def reversed_order(module, frozen, pool, eps, eps_a, settings, starts=1, **kw):
        best = real(module, frozen, pool, eps, eps_a, settings, starts=starts, **kw)
        swapped = [best[i ^ 1] for i in range(len(best))]  # row 0 <-> row 1 of each material
        for m, k in enumerate(swapped):
            module.set_analytic(m, *(np.asarray(base.tensors[f"materials.{p}"][k]) for p in ("kd", "eta", "alpha")))
            module.z.data[m] = torch.from_numpy(base.tensors["materials.z"][k])
        return swapped

    monkeypatch.setattr(fitting, "start_from_nearest", reversed_order)
    # analytic_guard off: its restart is a sparse fit too, which the patch above would reorder
    model = fit([_ModelMaterial(base, "gold")], FitSettings(frozen_from=str(base_file), sparse_starts=2,
                                                            analytic_guard=False, **dict(TINY, steps=1, lr=1e-9)),
                frozen=base, progress=False, log=lambda m: None)
    assert model.material_info[0]["sparse_start"]["material"] == "gold"


def test_refine_trains_the_base_network_and_records_each_base_materials_drift(base_file, tmp_path):
    """--refine: BASE's network moves, BASE's materials are replayed against BASE's output, and the
    drift each records is the SMAPE / cMAE of the refined model against BASE, recomputed here."""
    from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape

    out = tmp_path / "refined.safetensors"
    settings = FitSettings(**{**TINY, "eval_pairs": 20_000})
    refined = hb.add(["synthetic:velvet"], to=base_file, out=out, settings=settings, progress=False, refine=True,
                     finetune_steps=40, max_drift=10.0)
    base = hb.load_model(base_file)
    assert refined.materials == ["gold", "plastic", "velvet"] and refined.training["mode"] == "refine"
    assert any(not np.array_equal(base.tensors[k], refined.tensors[k]) for k in base.tensors
               if not k.startswith("materials."))
    wi, wo = metric_directions(20_000, 7)
    for name in ("gold", "plastic"):
        info = refined.material_info[refined.index(name)]
        was = base.eval(wi, wo, name, dtype=torch.float64)
        now = refined.eval(wi, wo, name, dtype=torch.float32)
        assert info["refine_drift"]["smape"] == pytest.approx(smape(was, now), rel=1e-3, abs=1e-6)
        assert info["refine_drift"]["cmae"] == pytest.approx(cmae(was, now, wi[:, 2]), rel=1e-3, abs=1e-8)
        assert info["origin"] == base.material_info[base.index(name)]["origin"]
    assert "refine_drift" not in refined.material_info[2]


def test_refine_at_a_vanishing_rate_leaves_the_base_where_it_was(base_file):
    refined = hb.add(["synthetic:velvet"], to=base_file, settings=FitSettings(**{**TINY, "lr": 1e-12}),
                     progress=False, refine=True, finetune_steps=5)
    for info in refined.material_info[:2]:
        assert info["refine_drift"]["smape"] < 1e-5, info


def test_refine_above_max_drift_writes_nothing_and_names_the_material(base_file, tmp_path):
    out = tmp_path / "out.safetensors"
    out.write_bytes(b"previous file")
    r = run_cli_here("add", "synthetic:velvet", "--to", str(base_file), "--refine", "--max-drift", "1e-9",
                "--steps", "5", "--finetune-steps", "5", "--batch", "256", "--pool", "2048", "--eval-pairs", "2000",
                "--out", str(out), "--quiet")
    assert r.returncode == 1, r.stdout + r.stderr
    assert re.search(r"--refine moved (gold|plastic) by SMAPE [0-9.]+ against .* \(above --max-drift 1e-09\); "
                     r"nothing written", r.stderr), r.stderr
    assert out.read_bytes() == b"previous file"
    for argv, words in ((["--refine"], "--refine refines the network of --to BASE"),
                        (["--max-drift", "0.1"], "--max-drift applies to --refine only")):
        r = run_cli_here("add", "synthetic:velvet", *argv, "--out", str(out))
        assert r.returncode == 1 and words in r.stderr, r.stderr


def test_a_fine_tuned_model_goes_through_every_consumer_like_a_fitted_one(base_file, tmp_path, monkeypatch):
    """A fine-tuned file (its record nests the sparse fit's) loads in libhybridbrdf, which agrees
    with PyTorch in float64; the generated C++ header computes what the library computes; the
    path tracer renders it; and, where Mitsuba 3 is installed, the plugin loads and evaluates it."""
    import hybridbrdf.model.prior as prior_module
    from hybridbrdf import _core
    from hybridbrdf.codegen.main import generate
    from hybridbrdf.codegen.scene import load_scene
    from hybridbrdf.evaluate.directions import cosine_directions
    from hybridbrdf.render.tracer import render
    from test_codegen import _build_driver, _run_driver, tracer_scene

    monkeypatch.setattr(prior_module, "PRIOR_FILE", base_file)
    path = tmp_path / "tuned.safetensors"
    hb.add(["synthetic:velvet", "synthetic:rough_clay"], out=path, settings=FitSettings(**dict(TINY, energy_bound=True)),
           progress=False, finetune_steps=20)  # bounded, as a fit is by default
    model = hb.load_model(path)
    rng = np.random.default_rng(5)
    wi = cosine_directions(rng, 2000).astype(np.float32)
    wo = cosine_directions(rng, 2000).astype(np.float32)
    cpp = _core.Model(str(path))
    for m in range(2):
        want = model.eval(wi, wo, m, dtype=torch.float64)
        np.testing.assert_allclose(cpp.eval(wi, wo, m), want, rtol=2e-4, atol=1e-7)
    u = rng.random((2000, 2)).astype(np.float32)
    got = _run_driver(_build_driver(tmp_path, generate(model, "cpp"), model.materials), wi, wo, u, 2)
    for m in range(2):
        np.testing.assert_allclose(got[m][:, :3], cpp.eval_scalar(wi, wo, m), rtol=1e-5, atol=1e-9)
    for target in ("glsl", "hlsl", "brdfexplorer"):
        assert generate(model, target)
    scene = tracer_scene(path, {"a": "velvet", "b": "rough_clay"}, spp=2)
    image, _ = render(scene, width=16, height=16)
    assert np.isfinite(image).all() and image.max() > 0
    assert load_scene(scene, model) is not None
    try:
        import mitsuba as mi

        mi.set_variant("scalar_rgb")
        from hybridbrdf.render import mitsuba as hbmi
    except ImportError:
        return
    hbmi.register()
    bsdf = mi.load_dict({"type": "hbrdf", "filename": str(path), "material": "velvet"})
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*map(float, wo[0]))
    value = bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*map(float, wi[0])))
    np.testing.assert_allclose(np.array(value), cpp.eval(wi[:1], wo[:1], 0)[0] * wi[0, 2], rtol=1e-4)
