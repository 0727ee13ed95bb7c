"""Model files from careless or hostile hands: the free-form records of a valid file
never crash `hbrdf info`, damaged bytes give one printable line from both loaders, and weights
that could overflow float32 are refused before any evaluation."""

import json
import pathlib

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf import _core, spec
from hybridbrdf.model.validate import network_overflow_problem
from hybridbrdf.model.random import random_model

from helpers import hard_pairs, run_cli_here


@pytest.mark.parametrize("edit", [
    lambda m: setattr(m, "training", [1, 2]),
    lambda m: setattr(m, "training", "steps 5"),
    lambda m: setattr(m, "training", {"steps": {"x": 1}, "lr": "fast", "train_seconds": None}),
    lambda m: m.material_info[0].update(metrics="good"),
    lambda m: m.material_info[0].update(metrics=[1, 2]),
    lambda m: m.material_info[0].update(metrics={"smape": None, "cmae": True, "\nx": 1.5}),
    lambda m: m.material_info[1].update(sparse_start={"material": None, "smape": None}),
    lambda m: m.material_info[1].update(sparse_start={"material": "a\nb", "smape": "x", "cmae": [1]}),
    lambda m: m.material_info[2].update(origin="line one\nline two\x1b[31m"),
], ids=["training list", "training text", "training odd values", "metrics text", "metrics list",
        "metrics odd values", "sparse_start nulls", "sparse_start odd values", "origin with control characters"])
def test_info_prints_any_valid_file(tmp_path, edit):
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    edit(model)
    path = tmp_path / "m.safetensors"
    model.save(path)
    r = run_cli_here("info", str(path))
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    assert all(ch == "\n" or " " <= ch <= "~" for ch in r.stdout), r.stdout
    assert "3 materials:" in r.stdout


def test_info_reports_the_writer_recorded_in_the_file(tmp_path):
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    path = tmp_path / "m.safetensors"
    model.save(path)
    loaded = hb.load_model(path)
    assert loaded.written_by == hb.__version__


def test_overflow_bound_holds_for_real_evaluations():
    """The loader's interval bound is a true bound: no pre-activation of a real evaluation
    exceeds it (float64, relu network, hard and random directions, every material)."""
    _, model = random_model("hybrid", latent=4, width=16, depth=3)
    model.arch["activation"] = "relu"
    t = model.tensors
    layers = [(t[f"mlp.hidden.{i}.weight"], t[f"mlp.hidden.{i}.bias"]) for i in range(3)]
    layers.append((t["mlp.out.weight"], t["mlp.out.bias"]))
    bounds, b = [], np.concatenate([np.ones(6), np.abs(t["materials.z"]).max(axis=0)])
    for w, bias in layers:
        b = np.abs(w.astype(np.float64)) @ b + np.abs(bias.astype(np.float64))
        bounds.append(b)
    rng = np.random.default_rng(3)
    d = rng.normal(size=(4000, 6))
    d[:, :3] /= np.linalg.norm(d[:, :3], axis=1, keepdims=True)
    d[:, 3:] /= np.linalg.norm(d[:, 3:], axis=1, keepdims=True)
    for m in range(3):
        x = np.concatenate([d, np.repeat(t["materials.z"][m][None].astype(np.float64), len(d), 0)], 1)
        for k, ((w, bias), bound) in enumerate(zip(layers, bounds)):
            pre = x @ w.astype(np.float64).T + bias
            assert (np.abs(pre) <= bound * (1 + 1e-12)).all(), k
            x = np.maximum(pre, 0.0)
    assert network_overflow_problem(model.arch, t) is None
    big = dict(t)
    big["mlp.hidden.1.weight"] = t["mlp.hidden.1.weight"] * np.float32(1e29)
    assert network_overflow_problem(model.arch, big).startswith("tensor mlp.hidden.1.weight: network values may reach")


@pytest.mark.parametrize("arch", list(spec.ARCHS))
def test_largest_accepted_weights_give_finite_outputs(tmp_path, arch):
    """Scale a network up to just below the overflow bound: both loaders accept it, and every
    output of the library (scalar and batched) and of torch float32 stays finite and >= 0."""
    _, model = random_model(arch, latent=12 if arch == "neural" else 4, width=16, depth=2)
    t = model.tensors
    for scale in 10.0 ** np.arange(1, 40):
        trial = {k: (v * np.float32(scale) if k == "mlp.hidden.0.weight" else v) for k, v in t.items()}
        if network_overflow_problem(model.arch, trial) is not None:
            break
        ok_scale = scale
    t["mlp.hidden.0.weight"] = t["mlp.hidden.0.weight"] * np.float32(ok_scale)
    path = tmp_path / "m.safetensors"
    model.save(path)
    loaded = hb.load_model(path)
    cpp = _core.Model(str(path))
    wi, wo = hard_pairs()
    for m in range(3):
        for f in (cpp.eval(wi, wo, m), loaded.eval(wi, wo, m)):
            f = np.asarray(f)
            assert np.isfinite(f).all() and (f >= 0).all()


@pytest.mark.skipif(not getattr(_core, "HAVE_RENDERER", False), reason="built without the renderer")
def test_render_names_scene_key_and_file_for_a_byte_flipped_model(tmp_path):
    """A damaged model header used to surface as UnicodeDecodeError from the C++ loader, naming
    neither file nor problem; now it is one line with the scene, its key and the model file."""
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    path = tmp_path / "m.safetensors"
    model.save(path)
    data = bytearray(path.read_bytes())
    i = data.index(b'"arch', 8)
    data[i + 2:i + 4] = b"\xff\x01"  # not UTF-8, and a control byte, inside the JSON header
    path.write_bytes(bytes(data))
    scene = json.loads((pathlib.Path(__file__).resolve().parents[2] / "scenes" / "sphere_env.json").read_text())
    scene["materials"]["paper"] = {"type": "model", "file": str(path), "material": "mat-0"}
    scene["camera"].update(width=8, height=8)
    scene_path = tmp_path / "scene.json"
    scene_path.write_text(json.dumps(scene))
    r = run_cli_here("render", str(scene_path), "-o", str(tmp_path / "o.exr"), "--quiet")
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    line = r.stderr.strip()
    assert "\n" not in line and f"{scene_path}: materials.paper.file: {path}: " in line, line
    assert "\\xff" in line and "\x01" not in line
