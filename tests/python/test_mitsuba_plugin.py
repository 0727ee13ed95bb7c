"""The Mitsuba 3 plugin (hybridbrdf.render.mitsuba): its queries against libhybridbrdf under the two
projects' conventions in scalar_rgb, Mitsuba's own chi-square test of its sampler and renders that
agree with hbrdf render within Monte Carlo noise, in llvm_ad_rgb, all of them from one subprocess
per module (tests/python/mitsuba_llvm_checks.py: a process holds one Mitsuba variant at a time; a
scalar_rgb render makes one Python call per sample, about 12 s of CPU per 48 x 48, 32 spp image,
where llvm_ad_rgb makes one per wavefront, a fraction of a second)."""

import contextlib
import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf.render.tracer import render, write_exr

import mitsuba as mi  # noqa: E402  (a test extra)
mi.set_variant("scalar_rgb")
import hybridbrdf.render.mitsuba as hbmi  # noqa: E402

from mitsuba_scenes import agreement, environment_map, hbrdf_scene, mitsuba_scene  # noqa: E402
from helpers import run_shared_path  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
GLOSSY = "satin_gold_rgb"


@pytest.fixture(scope="module")
def edited_model(tmp_path_factory):
    """A prior plus an anisotropic edit (the plugin must use Mitsuba's tangent frame): the
    shared-output prior these renders were written against (tests/data; test_editing.py says
    why a fixed file); material output layers through the plugin: test_add.py."""
    path = tmp_path_factory.mktemp("mi") / "edited.safetensors"
    prior = hb.load_model(os.path.join(HERE, "..", "data", "prior_shared_20261123.safetensors"))
    return prior.edit(GLOSSY, "aniso", alpha=[0.05, 0.4]).save_checked(path)


@pytest.fixture(scope="module")
def env_file(tmp_path_factory):
    path = str(tmp_path_factory.mktemp("mi") / "env.exr")
    write_exr(environment_map(), path)
    return path


def llvm_env():
    """The environment of a subprocess that uses llvm_ad_rgb: DRJIT_LIBLLVM_PATH at the newest
    libLLVM of the system (>= 16, which scripts/setup.sh installs) unless the caller set one, so
    that Dr.Jit does not pick Mesa's older LLVM (docs/MITSUBA.md)."""
    import glob
    import re

    env = dict(os.environ)
    if "DRJIT_LIBLLVM_PATH" not in env:
        found = []
        for path in glob.glob("/usr/lib/*/libLLVM*.so*") + glob.glob("/usr/lib/llvm-*/lib/libLLVM*.so*"):
            m = re.search(r"libLLVM(?:-|\.so\.)(\d+)", os.path.basename(path))
            if m and int(m.group(1)) >= 16:
                found.append((int(m.group(1)), path))
        if found:
            env["DRJIT_LIBLLVM_PATH"] = max(found)[1]
    return env


#: The render comparisons of this module: name -> (material, evaluate) of the edited model, or
#: "textured" (the folder of the textured_folder fixture). Each is rendered by Mitsuba in the
#: llvm_ad_rgb process of the llvm_checks fixture, by hbrdf render in the test.
RENDER_SIZE, RENDER_SPP = 48, 32
RENDERS = {f"{GLOSSY}-full": (GLOSSY, "full"), "aniso-full": ("aniso", "full"),
           "aniso-analytic": ("aniso", "analytic"), "textured": None}


def _content_key(text: str, *paths) -> str:
    """A SHA-256 prefix of ``text`` and the bytes of ``paths`` (files, or folders: every file in
    them by name)."""
    import hashlib

    h = hashlib.sha256(text.encode())
    for path in map(pathlib.Path, paths):
        for f in sorted(path.rglob("*")) if path.is_dir() else [path]:
            if f.is_file():
                h.update(f.name.encode() + b"\0" + f.read_bytes())
    return h.hexdigest()[:16]


@pytest.fixture(scope="module")
def llvm_checks(edited_model, env_file, textured_folder, tmp_path_factory):
    """One llvm_ad_rgb process for the module: its chi-square tests and render comparison
    (llvm.json) and Mitsuba's two-seed renders of RENDERS (NAME.npy). Returns (result, folder).
    Under pytest-xdist these tests land on both workers: the first runs the process into the
    folder the run's workers share (fresh for every run, so no earlier run's images are read),
    under a name keyed by the bytes of every input (model, environment map, textured folder, the
    jobs, the scripts), and the other reads it."""

    jobs = []
    for name, case in RENDERS.items():
        bsdf = ({"type": "hbrdf", "svbrdf": textured_folder} if case is None else
                {"type": "hbrdf", "filename": str(edited_model.path), "material": case[0], "evaluate": case[1]})
        jobs.append({"name": name, "bsdf": bsdf, "size": RENDER_SIZE, "spp": RENDER_SPP})
    script = os.path.join(HERE, "mitsuba_llvm_checks.py")
    if "PYTEST_XDIST_WORKER" not in os.environ:
        shared = contextlib.nullcontext(tmp_path_factory.mktemp("llvm"))
    else:
        cases = json.dumps([(j["name"], j["size"], j["spp"], j["bsdf"].get("material"), j["bsdf"].get("evaluate"))
                            for j in jobs])
        key = _content_key(cases, edited_model.path, env_file, textured_folder, script,
                           os.path.join(HERE, "mitsuba_scenes.py"), hbmi.__file__)
        shared = run_shared_path(tmp_path_factory, f"test_mitsuba_plugin-llvm-{key}")
    with shared as out:
        if not (out / "llvm.json").exists():
            out.mkdir(exist_ok=True)
            (out / "renders.json").write_text(json.dumps(jobs))
            r = subprocess.run([sys.executable, script, str(edited_model.path), env_file, str(out), str(out / "renders.json")],
                               capture_output=True, text=True, cwd=out, env=llvm_env())  # chi2 may write its data there
            assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return json.loads((out / "llvm.json").read_text()), out


def test_the_shared_llvm_results_are_keyed_by_every_input(tmp_path):
    """llvm_checks' key changes with the cases and with any byte of any input file, one in a folder
    included (a changed model, map or script is rendered again, never read from another worker's run)."""
    (tmp_path / "folder").mkdir()
    files = [tmp_path / "model", tmp_path / "script.py", tmp_path / "folder" / "weights.exr"]
    for f in files:
        f.write_bytes(b"abc")
    inputs = (files[0], files[1], tmp_path / "folder")
    key = _content_key("cases", *inputs)
    assert key == _content_key("cases", *inputs)
    assert key != _content_key("other cases", *inputs)
    for f in files:
        f.write_bytes(b"abd")
        assert _content_key("cases", *inputs) != key, f
        f.write_bytes(b"abc")
    (tmp_path / "folder" / "more.exr").write_bytes(b"")
    assert _content_key("cases", *inputs) != key


def plugin(model, material, **extra):
    hbmi.register()
    return mi.load_dict(dict({"type": "hbrdf", "filename": str(model.path), "material": material}, **extra))


def test_queries_follow_the_libraries_conventions(edited_model):
    """Mitsuba's si.wi is hybridbrdf's wo (toward the viewer), its wo our wi (toward the light);
    eval (and eval_pdf) carries cos(theta_light); sample's weight is f cos / pdf of the material's
    MIS sampler; an inactive lane gets nothing. In scalar_rgb, one lane per query: the plugin's
    conversions that the llvm_ad_rgb renders (wavefronts) do not run."""
    b = plugin(edited_model, "aniso")
    params = edited_model.analytic_params("aniso")
    rng = np.random.default_rng(4)
    ctx = mi.BSDFContext()
    for _ in range(50):
        view = rng.normal(size=3)
        light = rng.normal(size=3)
        view[2], light[2] = abs(view[2]), abs(light[2])
        view, light = view / np.linalg.norm(view), light / np.linalg.norm(light)
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*view)
        want = edited_model.eval(light[None], view[None], "aniso")[0] * light[2]
        np.testing.assert_allclose(np.array(b.eval(ctx, si, mi.Vector3f(*light))), want, rtol=1e-5)
        want_pdf = hb.pdf(light[None], view[None], params)[0]
        assert float(b.pdf(ctx, si, mi.Vector3f(*light))) == pytest.approx(want_pdf, rel=1e-5)
        # eval_pdf: what Mitsuba's integrators call for emitter samples
        value, density = b.eval_pdf(ctx, si, mi.Vector3f(*light))
        np.testing.assert_allclose(np.array(value), want, rtol=1e-5)
        assert float(density) == pytest.approx(want_pdf, rel=1e-5)
        u = rng.random(2)
        bs, weight = b.sample(ctx, si, 0.5, mi.Point2f(*u))
        wi, pdf, _ = hb.sample(view[None], u[None], params)
        np.testing.assert_allclose(np.array(bs.wo), wi[0], atol=1e-6)
        assert float(bs.pdf) == pytest.approx(pdf[0], rel=1e-5)
        f = edited_model.eval(wi, view[None], "aniso")[0]
        np.testing.assert_allclose(np.array(weight), f * max(wi[0, 2], 0) / pdf[0], rtol=1e-4, atol=1e-7)
    # an inactive lane: nothing, in every query
    si.wi = mi.Vector3f(0.0, 0.6, 0.8)
    assert float(np.max(np.array(b.eval(ctx, si, mi.Vector3f(0, 0, 1), False)))) == 0.0
    assert float(b.pdf(ctx, si, mi.Vector3f(0, 0, 1), False)) == 0.0
    value, density = b.eval_pdf(ctx, si, mi.Vector3f(0, 0, 1), False)
    assert float(np.max(np.array(value))) == 0.0 and float(density) == 0.0
    _, weight = b.sample(ctx, si, 0.5, mi.Point2f(0.3, 0.3), False)
    assert float(np.max(np.array(weight))) == 0.0
    # below the horizon: nothing, in every query
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(0.0, 0.6, -0.8)
    assert float(np.max(np.array(b.eval(ctx, si, mi.Vector3f(0, 0, 1))))) == 0.0
    assert float(b.pdf(ctx, si, mi.Vector3f(0, 0, 1))) == 0.0
    _, weight = b.sample(ctx, si, 0.5, mi.Point2f(0.3, 0.3))
    assert float(np.max(np.array(weight))) == 0.0


def test_bad_properties_give_clear_errors(edited_model):
    hbmi.register()
    for extra, message in (({"material": "nope"}, "no material 'nope'"), ({"sampler": "tabulated"}, "sampler"),
                           ({"evaluate": "neural"}, "evaluate")):
        with pytest.raises(Exception, match=message):
            mi.load_dict(dict({"type": "hbrdf", "filename": str(edited_model.path), "material": "aniso"}, **extra))
    with pytest.raises(Exception, match="needs 'filename'"):
        mi.load_dict({"type": "hbrdf", "material": "aniso"})


def assert_renders_agree(mitsuba_images, scene):
    """Mitsuba's two seeds against hbrdf render's two seeds of the same scene (mitsuba_scenes.py):
    |z| < 4.5 on every tile and channel, and the sun's highlight in both."""
    mits = list(mitsuba_images)
    ours = [render(dict(scene, seed=s))[0] for s in (1, 2)]
    mask = render(dict(scene, spp=1), max_depth=0)[0].sum(-1) == 0  # the sphere's pixels
    z, m_tiles, o_tiles = agreement(mits[0], mits[1], ours[0], ours[1], mask)
    assert len(z) >= 20
    assert np.abs(z).max() < 4.5, (np.abs(z).max(), m_tiles[np.abs(z).max(axis=1).argmax()])
    # and the images are not trivially alike: the sun's highlight is in both
    assert m_tiles.max() > 2 * np.median(m_tiles)


@pytest.mark.parametrize("material, evaluate", [(GLOSSY, "full"), ("aniso", "full"), ("aniso", "analytic")])
def test_a_mitsuba_render_agrees_with_hbrdf_render(edited_model, env_file, llvm_checks, material, evaluate):
    """The sphere under the environment map (direct lighting: a convex object sees only the sky),
    48x48 pixels, 32 spp per render, two seeds per renderer, Mitsuba in llvm_ad_rgb. Statistic: per
    8x8 tile and channel, z = (mean_Mitsuba - mean_hbrdf) / sigma, sigma from each pixel's two seeds;
    with ~30 tiles x 3 channels, |z| < 4.5 everywhere fails by chance with probability < 1e-3, while
    a convention error (a swapped wi/wo, a mirrored frame, a lost cosine) moves tiles by tens of sigma."""
    _, out = llvm_checks
    scene = hbrdf_scene(env_file, str(edited_model.path), material, RENDER_SIZE, RENDER_SPP, 0)
    scene["materials"]["m"]["evaluate"] = evaluate
    assert_renders_agree(np.load(out / f"{material}-{evaluate}.npy"), scene)


def test_llvm_variant_chi_square_and_render(llvm_checks):
    """Mitsuba's chi-square test (mitsuba.chi2, 1e6 samples, 101 x 202 bins, the pdf integrated on
    8 x 8 points per bin, significance 0.01 for the whole set of cases, Sidak-corrected) for the
    plugin's samplers in llvm_ad_rgb,
    and the render comparison there at 64x64, 64 spp."""
    res, _ = llvm_checks
    assert res["variant"] == "llvm_ad_rgb"
    assert len(res["chi2"]) >= 6
    for case in res["chi2"]:
        assert case["passed"], case
    assert res["render"]["max_abs_z"] < 4.5, res["render"]
    assert res["render"]["tiles"] >= 40


def test_the_readme_example_runs(tmp_path):
    """The README's Mitsuba example as written (at 1 spp instead of 64, for time)."""
    readme = open(os.path.join(HERE, "..", "..", "README.md")).read()
    section = readme[readme.index("## Mitsuba 3"):]
    code = section[section.index("```python") + len("```python"):section.index("```", section.index("```python") + 9)]
    assert "spp=64" in code
    r = subprocess.run([sys.executable, "-c", code.replace("spp=64", "spp=1")], capture_output=True, text=True,
                       cwd=tmp_path, env=llvm_env())
    assert r.returncode == 0, r.stderr[-3000:]
    img = np.array(mi.Bitmap(str(tmp_path / "ball.exr")))
    assert img.shape[2] >= 3 and np.isfinite(img).all() and img.max() > 0


@pytest.fixture(scope="module")
def textured_folder(edited_model, tmp_path_factory):
    """A textured material of two layers of the edited model (the glossy material and its anisotropic
    edit) with the same weights everywhere (w_1 = 0.4): a mixture that does not depend on uv, so that
    Mitsuba's and the tracer's uv conventions cannot differ in the render."""
    from hybridbrdf.svbrdf.asset import SVBRDF

    folder = tmp_path_factory.mktemp("mi") / "sv"
    weights = np.zeros((4, 4, 3), np.float32)
    weights[..., 0] = 0.4
    SVBRDF(edited_model, [GLOSSY, "aniso"], (4, 4), weights).save(folder, format="exr")
    return str(folder)


def test_textured_queries_are_the_librarys_texels(edited_model, tmp_path):
    """The plugin with 'svbrdf' evaluates libhybridbrdf's Svbrdf at Mitsuba's si.uv (wi and wo
    swapped, times cos(theta_light)); its pdf is the texel's mixture pdf."""
    from hybridbrdf.svbrdf.asset import SVBRDF

    rng = np.random.default_rng(6)
    weights = rng.uniform(0, 0.5, (3, 5, 3)).astype(np.float32)
    weights[..., 1:] = 0
    SVBRDF(edited_model, [GLOSSY, "aniso"], (5, 3), weights).save(tmp_path / "sv", format="exr")
    hbmi.register()
    b = mi.load_dict({"type": "hbrdf", "svbrdf": str(tmp_path / "sv"), "filter": "nearest"})
    lib = hb._core.Svbrdf(str(tmp_path / "sv"))
    ctx = mi.BSDFContext()
    for _ in range(40):
        view, light = rng.normal(size=3), rng.normal(size=3)
        view[2], light[2] = abs(view[2]), abs(light[2])
        view, light = view / np.linalg.norm(view), light / np.linalg.norm(light)
        uv = rng.uniform(0, 1, 2)
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*view)
        si.uv = mi.Point2f(*uv)
        got = np.array(b.eval(ctx, si, mi.Vector3f(*light)))
        rows = [np.array([r], np.float32) for r in (uv, light, view)]
        ref = lib.eval(*rows, "nearest")[0] * light[2]
        np.testing.assert_allclose(got, ref, rtol=1e-5, atol=1e-7)
        p = float(b.pdf(ctx, si, mi.Vector3f(*light)))
        assert p == pytest.approx(float(lib.pdf(*rows, "mis", "nearest")[0]), rel=1e-5)
    with pytest.raises(Exception, match="not both"):
        mi.load_dict({"type": "hbrdf", "svbrdf": str(tmp_path / "sv"), "filename": str(edited_model.path), "material": GLOSSY})


@pytest.mark.parametrize("filt", ["nearest", "bilinear"])
def test_weights_as_a_mitsuba_texture(edited_model, tmp_path, filt):
    """'weights' as Mitsuba textures: the folder's own weights map read back by Mitsuba's bitmap
    texture (its lookup, filter and wrapping) gives the texels of the folder's map read by
    libhybridbrdf (the uv conventions agree), and a constant 'rgb' texture the texels of a constant
    map; eval, pdf and sample against libhybridbrdf's Svbrdf."""
    from hybridbrdf.svbrdf.asset import SVBRDF

    rng = np.random.default_rng(9)
    weights = rng.uniform(0, 0.5, (4, 6, 3)).astype(np.float32)
    weights[..., 1:] = 0
    SVBRDF(edited_model, [GLOSSY, "aniso"], (6, 4), weights).save(tmp_path / "sv", format="exr")
    SVBRDF(edited_model, [GLOSSY, "aniso"], (6, 4), np.full((4, 6, 3), [0.3, 0, 0], np.float32)).save(
        tmp_path / "flat", format="exr")
    hbmi.register()
    bitmap = {"type": "bitmap", "filename": str(tmp_path / "sv" / "weights.exr"), "raw": True,
              "filter_type": filt, "wrap_mode": "repeat"}
    cases = [(mi.load_dict({"type": "hbrdf", "svbrdf": str(tmp_path / "sv"), "filter": filt, "weights": bitmap}),
              hb._core.Svbrdf(str(tmp_path / "sv"))),
             (mi.load_dict({"type": "hbrdf", "svbrdf": str(tmp_path / "sv"), "filter": filt,
                            "weights": {"type": "rgb", "value": [0.3, 0, 0]}}), hb._core.Svbrdf(str(tmp_path / "flat")))]
    ctx = mi.BSDFContext()
    for b, lib in cases:
        for _ in range(40):
            view, light = rng.normal(size=3), rng.normal(size=3)
            view[2], light[2] = abs(view[2]), abs(light[2])
            view, light = view / np.linalg.norm(view), light / np.linalg.norm(light)
            uv = rng.uniform(-0.5, 1.5, 2)
            si = mi.SurfaceInteraction3f()
            si.wi = mi.Vector3f(*view)
            si.uv = mi.Point2f(*uv)
            rows = [np.array([r], np.float32) for r in (uv, light, view)]
            ref = lib.eval(*rows, filt)[0] * light[2]
            np.testing.assert_allclose(np.array(b.eval(ctx, si, mi.Vector3f(*light))), ref, rtol=2e-5, atol=1e-7)
            assert float(b.pdf(ctx, si, mi.Vector3f(*light))) == pytest.approx(float(lib.pdf(*rows, "mis", filt)[0]),
                                                                             rel=2e-5)
            u = rng.uniform(0, 1, 2)
            bs, _ = b.sample(ctx, si, 0.5, mi.Point2f(*u))
            wi_ref, pdf_ref, _ = lib.sample(rows[0], rows[2], np.array([u], np.float32), "mis", filt)
            np.testing.assert_allclose(np.array(bs.wo), wi_ref[0], atol=2e-5)
    assert "weights=" in str(cases[0][0])
    with pytest.raises(Exception, match="only a textured material"):
        mi.load_dict({"type": "hbrdf", "filename": str(edited_model.path), "material": GLOSSY,
                      "weights": {"type": "rgb", "value": [0.3, 0, 0]}})


def test_a_textured_mitsuba_render_agrees_with_hbrdf_render(edited_model, env_file, llvm_checks, textured_folder):
    """As test_a_mitsuba_render_agrees_with_hbrdf_render, for the textured material (the mixture
    sampled by the plugin through libhybridbrdf's texel sampler, evaluated per texel)."""
    _, out = llvm_checks
    scene = hbrdf_scene(env_file, str(edited_model.path), GLOSSY, RENDER_SIZE, RENDER_SPP, 0)
    scene["materials"]["m"] = {"type": "textured", "svbrdf": textured_folder}
    assert_renders_agree(np.load(out / "textured.npy"), scene)
