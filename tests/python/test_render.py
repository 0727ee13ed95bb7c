"""The path tracer through Python: the binding, measured callables, the CLI, files and errors.

The statistical tests of the integrator itself (furnace, samplers, env-map pdf) are in
tests/cpp/test_render.cpp; the ones here check what only Python can: measured materials
evaluated by Python callables, overrides, output files, and that all paths agree bit for bit
where they must.
"""

import copy
import json
import os
import pathlib

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf import _core
from hybridbrdf.render import tracer as hr

from helpers import run_cli, sphere_on_floor_scene

ROOT = pathlib.Path(__file__).resolve().parents[2]
MODEL = ROOT / "results" / "rgl54_hybrid_32x2.safetensors"

pytestmark = pytest.mark.skipif(not getattr(_core, "HAVE_RENDERER", False), reason="built without the renderer")

PARAMS = dict(kd=[0.3, 0.2, 0.1], eta=[1.5, 1.6, 1.7], alpha=[0.2, 0.35])


def scene(material, env=None, **settings):
    """A unit sphere of ``material`` on an analytic floor under ``env`` (the sky by default),
    20x16 pixels, 4 samples per pixel."""
    if env:
        settings["environment"] = env
    return sphere_on_floor_scene(material, {"type": "analytic", "kd": 0.5, "eta": 1.5, "alpha": 0.4},
                                 **{"spp": 4, **settings})


def analytic_material():
    return {"type": "analytic", **PARAMS}


def test_white_furnace_from_python():
    s = scene({"type": "analytic", "kd": 1, "eta": 1, "alpha": 0.5}, env={"type": "constant", "radiance": 1},
              sampler="cosine", nee=False, max_depth=1)
    s["objects"] = s["objects"][:1]  # the sphere alone: convex, one bounce is exact
    img, stats = hr.render(s, spp=8)
    assert img.shape == (16, 20, 3) and img.dtype == np.float32
    np.testing.assert_allclose(img, 1.0, atol=1e-5)
    assert stats["spp"] == 8 and stats["rays"] > 0


def test_measured_callable_matches_the_analytic_material_exactly():
    # A "measured" material whose callable is f_a itself, sampled with the same analytic proxy:
    # the image must be identical to the analytic material's, bit for bit.
    params = hb.AnalyticParams(**PARAMS)
    calls = []

    def factory(source):
        assert source == "synthetic:mine"

        def f(wi, wo):
            calls.append(len(wi))
            return hb.analytic_eval(wi, wo, params).astype(np.float32)
        return f

    measured = {"type": "measured", "source": "synthetic:mine", "sampling_params": PARAMS}
    img_m, st_m = hr.render(scene(measured), measured_factory=factory)
    img_a, st_a = hr.render(scene(analytic_material()))
    assert np.array_equal(img_m, img_a)
    # Batched: far fewer callbacks than evaluated pairs.
    assert sum(calls) > 0 and len(calls) < sum(calls) / 20


def test_measured_sources_render_through_the_readers():
    img, stats = hr.render(scene({"type": "measured", "source": "synthetic:gold"}), spp=2)
    assert np.isfinite(img).all() and (img >= 0).all() and img.mean() > 0
    assert stats["network_evals"] == 0


def test_errors_in_a_measured_callable_stop_the_render():
    def factory(source):
        def f(wi, wo):
            raise RuntimeError("reader exploded")
        return f

    with pytest.raises(RuntimeError, match="reader exploded"):
        hr.render(scene({"type": "measured", "source": "x.bsdf"}), measured_factory=factory)


def test_images_do_not_depend_on_the_thread_count():
    s = scene(analytic_material(), max_depth=4)
    a, _ = hr.render(s, threads=1)
    b, st = hr.render(s, threads=2)
    assert st["threads"] == 2
    assert np.array_equal(a, b)
    c, _ = hr.render(s, threads=2, seed=1)
    assert not np.array_equal(a, c)


@pytest.mark.skipif(not MODEL.exists(), reason="fitted model not in the checkout")
def test_neural_max_depth_zero_equals_the_analytic_render():
    full = {"type": "model", "file": str(MODEL), "material": "paper_white_rgb.rgl"}
    analytic = dict(full, evaluate="analytic")
    img_full, st_full = hr.render(scene(full))
    img_off, st_off = hr.render(scene(full), neural_max_depth=0)
    img_an, _ = hr.render(scene(analytic))
    assert np.array_equal(img_off, img_an)
    assert not np.array_equal(img_full, img_off)
    assert st_off["network_evals"] == 0 < st_full["network_evals"]
    _, st_1 = hr.render(scene(full), neural_max_depth=1)
    assert 0 < st_1["network_evals"] < st_full["network_evals"]


def test_exr_and_png_written_and_read_back(tmp_path):
    out, png = tmp_path / "a" / "img.exr", tmp_path / "img.png"
    img, _ = hr.render(scene(analytic_material()), out=str(out), png=str(png))
    back = hr.read_image(str(out))
    assert np.array_equal(back, img)  # float32 EXR: exact
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [p for p in tmp_path.rglob("*.tmp*")]  # atomic writes leave no temporaries
    rnd = np.random.default_rng(0).uniform(-1, 1e3, size=(3, 5, 3)).astype(np.float32)
    hr.write_exr(rnd, str(tmp_path / "r.exr"))
    assert np.array_equal(hr.read_image(str(tmp_path / "r.exr")), rnd)


@pytest.mark.parametrize("mutate, message", [
    (lambda s: s.pop("camera"), "<scene dict>: missing key 'camera'"),
    (lambda s: s["objects"][0].update(radius=-1), "<scene dict>: objects[0].radius: must be > 0"),
    (lambda s: s["objects"][0].update(type="torus"), "objects[0].type: unknown object type 'torus'"),
    (lambda s: s.update(sampler="best"), "sampler: unknown sampler 'best'"),
    (lambda s: s["materials"].update(m={"type": "model", "file": "missing.safetensors", "material": "x"}),
     "materials.m.file: "),
    (lambda s: s.update(environment={"type": "file", "file": "missing.exr"}), "environment.file: "),
    (lambda s: s.update(spp=0), "<scene dict>: spp: must be >= 1, got 0"),
    # Integers are bounded before any conversion: 3000000000 is not wrapped to a negative int.
    (lambda s: s.update(spp=3000000000), "<scene dict>: spp: must be <= 2147483647, got 3000000000"),
    (lambda s: s.update(max_depth=2.5), "<scene dict>: max_depth: expected an integer, got a number (2.5)"),
    (lambda s: s.update(seed=-1), "<scene dict>: seed: must be >= 0, got -1"),
    (lambda s: s.update(nee=1), "<scene dict>: nee: expected true or false, got an integer"),
    (lambda s: s.update(tabulated_resolution_deg=91), "<scene dict>: tabulated_resolution_deg: must be <= 90, got 91"),
    (lambda s: s["camera"].update(width=2**32 + 16), "<scene dict>: camera.width: must be <= 2147483647, got 4294967312"),
])
def test_bad_scenes_give_the_documented_errors(mutate, message):
    s = scene(analytic_material())
    mutate(s)
    with pytest.raises(ValueError) as info:
        hr.render(s)
    assert message in str(info.value)


def test_overrides_are_checked_by_the_settings_table():
    s = scene(analytic_material())
    with pytest.raises(ValueError, match=r"^spp: must be >= 1, got 0$"):
        hr.render(s, spp=0)
    with pytest.raises(ValueError, match=r"^sampler: unknown sampler 'best'; expected cosine, ggx, mis or tabulated$"):
        hr.render(s, sampler="best")
    with pytest.raises(TypeError, match="unexpected setting 'sp'"):
        hr.render(s, sp=4)


def test_seeds_beyond_32_bits_are_not_wrapped():
    # A seed read through a 32-bit int would make 2**32 the same as 0.
    s = scene(analytic_material(), spp=1)
    a, _ = hr.render(s, seed=0)
    b, _ = hr.render(s, seed=2**32)
    c, _ = hr.render(s, seed=2**64 - 1)
    assert not np.array_equal(a, b) and not np.array_equal(a, c)


def test_settings_table_matches_the_documentation():
    """The settings of docs/RENDERING.md's top-level table (written by hand) are the library's
    table: same names in the same order, same defaults."""
    text = (ROOT / "docs" / "RENDERING.md").read_text()
    lines = text[text.index("| `spp` |"):].splitlines()
    table = lines[:next(i for i, line in enumerate(lines) if not line.startswith("|"))]
    rows = [line.split("|")[1:3] for line in table]
    documented = {name.strip().strip("`"): default.strip().strip("`") for name, default in rows}
    lib = hr.settings()
    assert list(documented) == [s["name"] for s in lib]
    for s in lib:
        doc = documented[s["name"]]
        if s["name"] == "neural_max_depth":
            assert doc == "= max_depth" and s["default"] == -1
        elif s["type"] == "bool":
            assert doc == str(s["default"]).lower()
        elif s["type"] == "str":
            assert doc == s["default"] and set(s["choices"]) == {"cosine", "ggx", "mis", "tabulated"}
        else:
            assert float(doc) == s["default"], s["name"]
    assert hr.SETTINGS == tuple(s["name"] for s in lib)


def test_bad_json_file_names_the_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{ \"camera\": ")
    with pytest.raises(ValueError, match=r"bad\.json: invalid JSON"):
        hr.render(str(bad))


def test_example_scene_renders(tmp_path):
    img, stats = hr.render(str(ROOT / "scenes" / "sphere_env.json"), width=32, height=24, spp=2)
    assert img.shape == (24, 32, 3) and np.isfinite(img).all() and img.mean() > 0
    assert stats["network_evals"] > 0


def test_cli_render(tmp_path):
    path = tmp_path / "s.json"
    path.write_text(json.dumps(scene(analytic_material())))
    r = run_cli("render", str(path), "-o", str(tmp_path / "o.exr"), "--png", str(tmp_path / "o.png"), "--spp", "2",
                "--threads", "1", "--quiet")
    assert r.returncode == 0, r.stderr
    assert "rendered" in r.stdout and (tmp_path / "o.exr").exists() and (tmp_path / "o.png").exists()
    assert r.stderr == ""
    bad = copy.deepcopy(scene(analytic_material()))
    bad["objects"][0]["material"] = "nope"
    path.write_text(json.dumps(bad))
    r = run_cli("render", str(path), "-o", str(tmp_path / "x.exr"))
    assert r.returncode == 1
    assert r.stderr.strip().count("\n") == 0
    assert f"{path}: objects[0].material: no material named 'nope'" in r.stderr
    assert not (tmp_path / "x.exr").exists()


def test_cli_render_has_a_flag_per_setting(tmp_path):
    r = run_cli("render", "--help")
    assert r.returncode == 0
    for s in hr.settings():
        flag = "--" + s["name"].replace("_", "-")
        assert (f"{flag}, --no-{flag[2:]}" if s["type"] == "bool" else flag) in r.stdout, flag
    path = tmp_path / "s.json"
    path.write_text(json.dumps(scene(analytic_material())))
    r = run_cli("render", str(path), "-o", str(tmp_path / "o.exr"), "--spp", "1", "--max-depth", "0",
                "--sampler", "cosine", "--no-nee", "--threads", "1", "--quiet")
    assert r.returncode == 0, r.stderr
    img = hr.read_image(str(tmp_path / "o.exr"))
    # max_depth 0: only the environment seen directly, so the sphere and the floor are black.
    assert img[8, 10].max() == 0 and img[0, 0].max() > 0
    r = run_cli("render", str(path), "-o", str(tmp_path / "x.exr"), "--spp", "0")
    assert r.returncode == 1 and r.stderr.strip() == "hbrdf render: error: spp: must be >= 1, got 0"


OCTAHEDRON_OBJ = """v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1
f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6
"""


def test_obj_mesh_white_furnace(tmp_path):
    # A closed convex mesh (flat-shaded octahedron, scaled and moved) with Lambert kd = 1 under a
    # constant environment vanishes exactly: mesh reading, the transform and the frames are right.
    (tmp_path / "octa.obj").write_text(OCTAHEDRON_OBJ)
    s = scene({"type": "analytic", "kd": 1, "eta": 1}, env={"type": "constant", "radiance": 1},
              sampler="cosine", nee=False, max_depth=1)
    s["objects"] = [{"type": "mesh", "file": "octa.obj", "material": "m", "smooth_normals": False,
                     "transform": {"scale": 1.2, "rotate_deg": [10, 20, 0], "translate": [0, 0.1, 0]}}]
    path = tmp_path / "s.json"
    path.write_text(json.dumps(s))
    img, stats = hr.render(str(path))
    np.testing.assert_allclose(img, 1.0, atol=1e-5)
    assert stats["brdf_evals"] > 0  # the mesh was hit
    s["objects"][0]["file"] = "missing.obj"
    path.write_text(json.dumps(s))
    with pytest.raises(ValueError, match=r"objects\[0\]\.file: .*missing\.obj: no such file"):
        hr.render(str(path))
