"""``hbrdf view --svbrdf DIR`` (docs/VIEWER.md, "A textured material"): the page's textured sphere in
headless chromium (WebGL2 on SwiftShader, as test_view.py; skipped without chromium unless
HBRDF_REQUIRE_BROWSER=1).

References, none of them the page's code:
- under the sun alone the page shows f(uv, wi, wo) cos(theta_i) E exactly at each pixel's centre, so
  its pixels are compared with libhybridbrdf's ``eval_texels`` (``SVBRDF.eval``: the runtimes' texel
  lookup and mixture in double and float) at directions and uv computed here in float64 from the
  camera, the unit sphere and the tracer's sphere uv (docs/RENDERING.md), tone-mapped by
  ``viewer.scene.srgb8``. Bound: float32 against float64 geometry and rounding to 8 bits, mean
  absolute difference 0.05 of an 8-bit step, no pixel more than 2 off; the same comparison with v
  flipped (a wrong uv convention) is off by more than 1 (asserted, so the test can fail);
- a textured material of one layer whose maps are constant is its material with those values: the page
  of the model's material with the same kd, eta and alpha set through the URL (what the sliders set)
  under the environment map, which exercises the mixture's sampling and density too: the same
  random numbers and float32 operations, so the same bytes (bound: mean 0.05, max 1);
- a material of two regions (the weights map's left and right halves) shows each region as the page
  of that region's material does, pixel for pixel where the pixel's whole footprint reads pure texels.

The four-layer material's page in the sun is built and opened once per module and model kind (the
``four_layer`` fixture) and read by the tests that compare or inspect that state: against
libhybridbrdf (at the tracer's 96 x 96), against the tracer (full), its maps beside the sphere.
"""

import json
import shutil
import subprocess

import numpy as np
import pytest

from hybridbrdf.svbrdf.asset import SVBRDF, load_svbrdf
from hybridbrdf.svbrdf.entries import SVBRDFError
from hybridbrdf.viewer.scene import CAMERA, SUN_IRRADIANCE, srgb8, tracer_scene
from helpers import saved_random_model
import view_harness
from test_view import (BROWSER_FLAGS, SIZE as TRACER_SIZE, assert_matches_tracer, chromium, needs_renderer, open_page,
                       page_dom, page_state, read_state)

SIZE = 48
#: The random models' kinds: (output layer, energy bound) of helpers.saved_random_model's "hybrid".
KINDS = {"shared": ("shared", False), "heads-bounded": ("material", True)}
#: The sun of the four-layer material's page (the `four_layer` fixture).
SUN = "light=sun&sun_el=40&sun_az=130"


@pytest.fixture(scope="module")
def kind_models(tmp_path_factory):
    """kind -> (the random model of that kind (KINDS), saved once per module and loaded back; its
    page, `hbrdf view MODEL`): the constant-maps and two-region tests read both, so the uniform page
    of a material they both compare with is one page load per run (_shared_pixels)."""
    built = {}

    def get(kind):
        if kind not in built:
            d = tmp_path_factory.mktemp(f"model-{kind}")
            output_layer, bound = KINDS[kind]
            path, m = saved_random_model(d, "hybrid", output_layer=output_layer, energy_bound=bound)
            uniform = d / "uniform.html"
            assert view_harness.cli("view", str(path), "--out", str(uniform)).returncode == 0
            built[kind] = (m, uniform)
        return built[kind]
    return get


@pytest.fixture(params=list(KINDS))
def model(request, kind_models):
    """The module's model of each kind (kind_models) and its uniform page."""
    return kind_models(request.param)


@pytest.fixture(scope="module")
def four_layer(tmp_path_factory, kind_models):
    """The page of _four_layer_material on a random model of each kind (KINDS), built and opened once
    per module in the sun at TRACER_SIZE with readback (a clean load): the tests that read it share
    the load (SwiftShader compiles a textured page's shader in seconds). kind -> (model, textured
    material, its folder, the page, its DOM)."""
    built = {}

    def get(kind):
        if kind not in built:
            d = tmp_path_factory.mktemp("four_layer")
            m, _ = kind_models(kind)
            sv = _four_layer_material(m, d / "sv")
            page = _view(d, d / "sv")
            built[kind] = (m, sv, d / "sv", page, page_dom(page, f"analytic=0&{SUN}", TRACER_SIZE, keep=True))
        return built[kind]
    return get


def _view(tmp_path, folder, *extra):
    out = tmp_path / "page.html"
    r = view_harness.cli("view", "--svbrdf", str(folder), "--out", str(out), *extra)
    assert r.returncode == 0, r.stderr
    return out


def _pixels(page, hash_, keep=False):
    """The page's converged picture (SIZE x SIZE, top row first) after a clean load (``keep``: in the
    page's kept tab, test_view.open_page: for the uniform pages, which several tests read)."""
    title, status, dom, console = open_page(page, f"readback=1&size={SIZE}&" + hash_, keep=keep)
    assert title == "hbrdf view: ok", (title, status)
    assert console == [], console  # ANGLE's "GPU stall due to ReadPixels" note already dropped (test_view.open_page)
    return read_state(dom)[0].astype(np.int32)


def _shared_pixels(tmp_path_factory, page, hash_):
    """_pixels, made once per test run for every test that opens these page bytes with this fragment
    (view_harness.shared, keyed as test_view.shared_page_state)."""
    return view_harness.shared(tmp_path_factory, "webgl2-pixels", [view_harness.file_sha256(page), hash_, SIZE,
                                                                   BROWSER_FLAGS, chromium()], lambda: _pixels(page, hash_, True))


#: The environment map's state of the constant-maps and two-region tests: the uniform page of the
#: material they both compare with (materials[1]) is one load per run.
COMMON = "spp=8&rotation=-40"


def sphere_pixels(size, sun_el=90.0, sun_az=0.0, dx=0.0, dy=0.0):
    """Per pixel centre (top row first; moved by (dx, dy) pixels), in float64: uv (the tracer's sphere
    uv), wi toward the sun and wo toward the camera in the tracer's sphere frame, and whether the
    pixel's ray hits the sphere."""
    pos, look, up = (np.array(CAMERA[k], dtype=np.float64) for k in ("position", "look_at", "up"))
    fwd = (look - pos) / np.linalg.norm(look - pos)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    up2 = np.cross(right, fwd)
    tan = np.tan(np.radians(CAMERA["fov_deg"]) / 2)
    y, x = np.mgrid[0:size, 0:size] + 0.5
    x, y = x + dx, y + dy
    sx, sy = (2 * x / size - 1) * tan, (1 - 2 * y / size) * tan
    d = fwd + right * sx[..., None] + up2 * sy[..., None]
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    b = d @ pos
    disc = b * b - (pos @ pos - 1)
    hit = disc > 0
    t = -b - np.sqrt(np.maximum(disc, 0))
    n = pos + t[..., None] * d
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    tg = np.stack([-n[..., 2], np.zeros_like(n[..., 0]), n[..., 0]], axis=-1)
    tg /= np.maximum(np.linalg.norm(tg, axis=-1, keepdims=True), 1e-12)
    bt = np.cross(n, tg)
    el, az = np.radians(sun_el), np.radians(sun_az)
    sun = np.array([np.cos(el) * np.sin(az), np.sin(el), -np.cos(el) * np.cos(az)])
    frame = np.stack([tg, bt, n], axis=-2)  # rows: the local axes
    wo = np.einsum("...ij,...j->...i", frame, -d)
    wi = np.einsum("...ij,j->...i", frame, sun)
    uv = np.stack([np.arctan2(n[..., 2], n[..., 0]) / (2 * np.pi) + 0.5, np.arccos(np.clip(n[..., 1], -1, 1)) / np.pi],
                  axis=-1)
    return uv, wi, wo, hit


def sun_reference(sv, size, sun_el, sun_az, flip_v=False):
    """(the page's picture under the sun as libhybridbrdf evaluates the textured material, the pixels
    compared: inside the sphere, away from its rim and from the sun's terminator)."""
    uv, wi, wo, hit = sphere_pixels(size, sun_el, sun_az)
    if flip_v:
        uv = uv * [1, -1] + [0, 1]
    f = sv.eval(uv.reshape(-1, 2), wi.reshape(-1, 3), wo.reshape(-1, 3)).reshape(size, size, 3)
    radiance = np.where(((wi[..., 2] > 0) & hit)[..., None], f * np.maximum(wi[..., 2:], 0) * SUN_IRRADIANCE, 0)
    shown = hit & (wo[..., 2] > 0.2) & (np.abs(wi[..., 2]) > 0.02)
    return srgb8(radiance).astype(np.int32), shown


def _four_layer_material(model, folder):
    """Four layers (the model's three materials and the first again), smooth random weights and a map
    of each quantity on some layer, as 8-bit PNG (the page uploads the loader's decoded values)."""
    rng = np.random.default_rng(7)
    h, w = 6, 9
    weights = rng.uniform(0, 0.6, (h, w, 3)).astype(np.float32)
    weights[:2, :3] = 0  # pure base texels
    maps = [{"kd": rng.uniform(0.05, 0.9, (h, w, 3)).astype(np.float32)},
            {"alpha": rng.uniform(0.05, 0.6, (h, w, 2)).astype(np.float32)},
            {"eta": rng.uniform(1.2, 3.0, (h, w, 3)).astype(np.float32)},
            {"latent": rng.uniform(-1.5, 1.5, (h, w, 4)).astype(np.float32)}]
    layers = [model.materials[0], model.materials[1], model.materials[2], model.materials[0]]
    SVBRDF(model, layers, (w, h), weights, maps).save(folder, format="png")
    return load_svbrdf(folder)


@pytest.mark.parametrize("kind", list(KINDS))
def test_page_is_libhybridbrdf_under_the_sun(four_layer, kind):
    _, sv, _, _, dom = four_layer(kind)
    el, az = 40.0, 130.0  # SUN
    got = read_state(dom)[0].astype(np.int32)
    size = len(got)
    want, shown = sun_reference(sv, size, el, az)
    assert shown.sum() > 0.4 * size * size * np.pi / 4 * 0.25  # a good part of the sphere is compared
    diff = np.abs(got - want)[shown]
    assert want[shown].mean() > 20, "the reference is not dark"
    print(f"page against libhybridbrdf: mean {diff.mean():.4f}, max {diff.max()} over {shown.sum()} pixels")
    assert diff.mean() <= 0.05 and diff.max() <= 2, (diff.mean(), diff.max())
    flipped, _ = sun_reference(sv, size, el, az, flip_v=True)
    assert np.abs(got - flipped)[shown].mean() > 1, "the comparison cannot tell v down from v up"


@needs_renderer
@pytest.mark.parametrize("analytic", [False, True], ids=["full", "analytic"])
def test_page_matches_tracer_of_the_scene_it_prints(four_layer, analytic):
    """The scene the page prints (a textured material, bilinear) is tracer_scene's, and the path tracer's
    render of it is the page's picture within test_view.py's bound (two tracer seeds' difference + 1),
    the full model and the layers' f_a alone (``analytic=1``, the tracer's "evaluate": "analytic")."""
    m, _, folder, page, dom = four_layer("shared")
    img, scene, _ = page_state(page, f"analytic=1&{SUN}", keep=True) if analytic else read_state(dom)
    assert scene == tracer_scene(str(folder / "model.safetensors"), m.materials[0], width=TRACER_SIZE,
                                 height=TRACER_SIZE, analytic=analytic, spp=64, light="sun", elevation=40, azimuth=130,
                                 svbrdf=str(folder))
    assert_matches_tracer(img, scene)


def test_constant_maps_are_the_uniform_material(model, tmp_path, tmp_path_factory):
    model, uniform = model
    h, w = 3, 4
    kd, eta, alpha = [0.62, 0.31, 0.12], [1.7, 2.2, 1.4], [0.09, 0.35]
    z = np.asarray(model.tensors["materials.z"][1], dtype=np.float32)
    maps = {"kd": np.broadcast_to(np.float32(kd), (h, w, 3)).copy(),
            "eta": np.broadcast_to(np.float32(eta), (h, w, 3)).copy(),
            "alpha": np.broadcast_to(np.float32(alpha), (h, w, 2)).copy(),
            "latent": np.broadcast_to(z, (h, w, len(z))).copy()}
    SVBRDF(model, [model.materials[1]], (w, h), None, [maps]).save(tmp_path / "sv", format="exr")
    textured = _view(tmp_path, tmp_path / "sv")
    got = _pixels(textured, COMMON)
    f32 = lambda v: ",".join(repr(float(np.float32(x))) for x in v)  # noqa: E731
    want = _pixels(uniform, f"{COMMON}&material={model.materials[1]}&kd={f32(kd)}&eta={f32(eta)}&alpha={f32(alpha)}",
                   keep=True)
    other = _shared_pixels(tmp_path_factory, uniform, f"{COMMON}&material={model.materials[1]}")  # two_regions' too
    diff = np.abs(got - want)
    print(f"constant maps against the uniform page: mean {diff.mean():.4f}, max {diff.max()}; "
          f"against the material without them {np.abs(got - other).mean():.2f}")
    assert diff.mean() <= 0.05 and diff.max() <= 1, (diff.mean(), diff.max())
    assert np.abs(got - other).mean() > 2, "the maps' values change the picture"


def test_two_regions_show_each_material(model, tmp_path, tmp_path_factory):
    model, uniform = model
    h, w = 4, 8
    weights = np.zeros((h, w, 3), np.float32)
    weights[:, 6:, 0] = 1  # u >= 3/4 (the camera sees u from 1/2 to 1, centre 3/4): layer 1
    layers = [model.materials[1], model.materials[2]]  # anisotropic beside isotropic
    SVBRDF(model, layers, (w, h), weights, addressing="clamp").save(tmp_path / "sv")
    sv = load_svbrdf(tmp_path / "sv")
    textured = _view(tmp_path, tmp_path / "sv")
    got = _pixels(textured, COMMON)
    # A pixel reads pure texels of one layer when the corners of its footprint do (the page jitters
    # its samples over the pixel); the layer from libhybridbrdf's texel lookup, not the page's.
    corners = []
    for dy in (-0.5, 0.5):
        for dx in (-0.5, 0.5):
            uv, _, wo, hit = sphere_pixels(SIZE, dx=dx, dy=dy)
            weight = sv.texels(uv.reshape(-1, 2))["weight"].reshape(SIZE, SIZE, 2)
            corners.append((weight, hit & (wo[..., 2] > 0.1)))
    for layer, material in enumerate(layers):
        pure = np.logical_and.reduce([ok & (wt[..., layer] == 1) for wt, ok in corners])
        assert pure.sum() > 100, pure.sum()
        want = _shared_pixels(tmp_path_factory, uniform, f"{COMMON}&material={material}")  # [1]: constant_maps' too
        diff = np.abs(got - want)[pure]
        print(f"region of layer {layer}: mean {diff.mean():.4f}, max {diff.max()} over {pure.sum()} pixels")
        assert diff.mean() <= 0.05 and diff.max() <= 1, (layer, diff.mean(), diff.max())
        assert np.abs(got - want)[~pure & corners[0][1]].mean() > 1, "the other region differs"


def test_textured_fragment_shader_compiles_as_es300(model, tmp_path):
    """The textured page's shader (four layers, every quantity mapped), for a shared output layer and
    for material output layers with energy tables: hbrdf-codegen's GLSL unchanged, then the page's
    code, which glslang compiles as a GLSL ES 3.00 fragment shader (without a browser), and no
    HbrdfMaterial is a parameter or field of the page's code (a layer's material is built where it is
    used: four of them passed by value were most of what SwiftShader compiled, docs/VIEWER.md)."""
    from hybridbrdf.codegen.main import generate
    from hybridbrdf.viewer.page import page_data

    model, _ = model
    sv = _four_layer_material(model, tmp_path / "sv")
    frag = page_data(sv.model, sv.model.path, svbrdf=sv)["fragment"]
    glsl = generate(sv.model, "glsl", materials=[sv.model.materials[0]], model_path=sv.model.path)
    assert frag.startswith("#version 300 es\nprecision highp float;\nprecision highp int;\n" + glsl)
    page_code = frag[len("#version 300 es\nprecision highp float;\nprecision highp int;\n" + glsl):]
    assert "HbrdfMaterial m0" not in page_code and "HbrdfMaterial s" not in page_code
    exe = shutil.which("glslangValidator")
    if exe is None:
        pytest.skip("glslangValidator not installed (scripts/setup.sh installs glslang-tools)")
    (tmp_path / "page.frag").write_text(frag)
    r = subprocess.run([exe, "-S", "frag", str(tmp_path / "page.frag")], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-3000:]


def test_normal_map_is_libhybridbrdf_under_the_sun(tmp_path):
    """A two-layer material with an alpha map and a tangent-space normal map (smooth bumps, up to 50
    degrees; docs/SVBRDF.md "Normal maps"): under the sun the page shows SVBRDF.eval's f (which
    shades each texel in its frame, 0 unless wi and wo are above both horizons) times the sphere
    normal's cosine, as the four-layer test bounds it. Controls: the same material without its map,
    and with the map's green flipped (y read along -b), are each more than one 8-bit step away."""
    path, m = saved_random_model(tmp_path, "hybrid", output_layer="material", energy_bound=True)
    h, w = 8, 16
    u, v = (np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h
    normal = np.stack(np.broadcast_arrays(0.6 * np.sin(2 * np.pi * u)[None, :], 0.55 * np.cos(2 * np.pi * v)[:, None]), 2)
    weights = np.zeros((h, w, 3), np.float32)
    weights[:, w // 2:, 0] = 1.0
    layers, maps = [m.materials[0], m.materials[1]], [{}, {"alpha": np.full((h, w, 2), 0.25, np.float32)}]
    for name, n in (("sv", normal), ("flat", None), ("flipped", normal * [1, -1])):
        SVBRDF(m, layers, (w, h), weights, maps, normal=None if n is None else n.astype(np.float32)).save(
            tmp_path / name, format="png")
    el, az = 40.0, 130.0  # SUN
    got = read_state(page_dom(_view(tmp_path, tmp_path / "sv"), f"analytic=0&{SUN}", TRACER_SIZE))[0].astype(np.int32)
    size = len(got)
    want, shown = sun_reference(load_svbrdf(tmp_path / "sv"), size, el, az)
    assert shown.sum() > 0.4 * size * size * np.pi / 4 * 0.25 and want[shown].mean() > 20
    diff = np.abs(got - want)[shown]
    print(f"normal-mapped page against libhybridbrdf: mean {diff.mean():.4f}, max {diff.max()} over {shown.sum()} pixels")
    assert diff.mean() <= 0.05 and diff.max() <= 2, (diff.mean(), diff.max())
    for other in ("flat", "flipped"):
        control, _ = sun_reference(load_svbrdf(tmp_path / other), size, el, az)
        assert np.abs(got - control)[shown].mean() > 1, other


def test_mip_chain_is_libhybridbrdf_at_each_pixels_lod(tmp_path):
    """A 256 x 128 material with its mip chain (kd noise, a normal map, so every layer has widened
    alpha maps) on a 48-pixel page: the page reads the level of detail libhybridbrdf's Svbrdf::lod
    gives the uv differences to the next pixel right and below, trilinearly; under the sun its pixels
    are SVBRDF.eval(uv, wi, wo, lod=) there (float64 geometry here), as the four-layer test bounds it.
    Control: level 0 alone (what the page read before) is more than one 8-bit step away."""
    path, m = saved_random_model(tmp_path, "hybrid", output_layer="material", energy_bound=True)
    rng = np.random.default_rng(3)
    h, w = 128, 256
    u, v = (np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h
    normal = np.stack(np.broadcast_arrays(0.5 * np.sin(16 * np.pi * u)[None, :], 0.5 * np.cos(8 * np.pi * v)[:, None]), 2)
    normal = normal + rng.uniform(-0.3, 0.3, (h, w, 2))
    weights = np.zeros((h, w, 3), np.float32)
    weights[..., 0] = rng.uniform(0, 1, (h, w))
    maps = [{"kd": rng.uniform(0.05, 0.9, (h, w, 3)).astype(np.float32)}, {}]
    SVBRDF(m, [m.materials[0], m.materials[1]], (w, h), weights, maps, normal=normal.astype(np.float32)).with_mips().save(
        tmp_path / "sv", format="exr")
    sv = load_svbrdf(tmp_path / "sv")
    assert sv.levels == 9
    el, az = 40.0, 130.0  # SUN
    got = read_state(page_dom(_view(tmp_path, tmp_path / "sv"), f"analytic=0&{SUN}", SIZE))[0].astype(np.int32)
    uv, wi, wo, hit = sphere_pixels(SIZE, el, az)
    steps = []
    for dx, dy in ((1, 0), (0, 1)):
        uv_n, _, _, hit_n = sphere_pixels(SIZE, el, az, dx, dy)
        step = uv_n - uv
        step[..., 0] -= np.floor(step[..., 0] + 0.5)  # across the seam u = 0 | 1
        steps.append((step * [w, h], hit_n))
    lod = 0.5 * np.log2(np.maximum(np.maximum(*[(a ** 2).sum(-1) for a, _ in steps]), 1e-30))
    shown = hit & steps[0][1] & steps[1][1] & (wo[..., 2] > 0.2) & (np.abs(wi[..., 2]) > 0.02)
    assert np.median(lod[shown]) > 1  # the control: the page is minified

    def picture(lods):
        f = sv.eval(uv.reshape(-1, 2), wi.reshape(-1, 3), wo.reshape(-1, 3), lod=lods).reshape(SIZE, SIZE, 3)
        return srgb8(np.where(((wi[..., 2] > 0) & hit)[..., None], f * np.maximum(wi[..., 2:], 0) * SUN_IRRADIANCE, 0))

    want = picture(lod.ravel()).astype(np.int32)
    diff = np.abs(got - want)[shown]
    print(f"mipped page against libhybridbrdf: mean {diff.mean():.4f}, max {diff.max()} over {shown.sum()} pixels")
    assert want[shown].mean() > 20 and diff.mean() <= 0.05 and diff.max() <= 2, (diff.mean(), diff.max())
    level0 = picture(np.zeros(SIZE * SIZE)).astype(np.int32)
    assert np.abs(got - level0)[shown].mean() > 1, "level 0 alone"


def test_maps_shown_beside_the_sphere_and_webgpu_refused(four_layer):
    _, _, _, page, dom = four_layer("shared")  # loaded clean in the sun (page_dom)
    # the weights and one image per map file (kd, alpha, eta, two latent maps): data URIs with captions
    assert dom.count('<img src="data:image/png;base64,') == 6
    assert "layer 3 (" in dom and "latent z_0..z_2" in dom and "weights" in dom
    title, status, _, _ = open_page(page, "", backend="webgpu")
    assert status == ("backend=webgpu: the WebGPU backend does not draw textured materials (hbrdf view --svbrdf) "
                      "yet; use backend=webgl2"), status
    assert title == "hbrdf view: error: " + status


def _corrupt_index(folder):
    (folder / "svbrdf.json").write_text('{"format_version": 1,')


def _other_size(folder):
    index = json.loads((folder / "svbrdf.json").read_text())
    index["size"] = [5, 5]
    (folder / "svbrdf.json").write_text(json.dumps(index))


def _no_folder(folder):
    shutil.rmtree(folder)


def _no_index(folder):
    (folder / "svbrdf.json").unlink()


@pytest.mark.parametrize("damage", [_no_folder, _no_index, _corrupt_index, _other_size])
def test_bad_folders_refused_with_the_loaders_line(tmp_path, damage):
    """The loader's one line (hybridbrdf.load_svbrdf's SVBRDFError, naming the file), nothing written."""
    path, m = saved_random_model(tmp_path, "hybrid")
    folder = tmp_path / "sv"
    SVBRDF(m, m.materials[:2], (4, 3), np.zeros((3, 4, 3), np.float32)).save(folder)
    damage(folder)
    with pytest.raises(SVBRDFError) as exc:
        load_svbrdf(folder)
    out = tmp_path / "page.html"
    r = view_harness.cli("view", "--svbrdf", str(folder), "--out", str(out))
    assert r.returncode == 1 and r.stderr == f"hbrdf view: error: {exc.value}\n", r.stderr
    assert str(folder) in r.stderr and not out.exists()


def test_model_must_be_the_folders(tmp_path):
    """MODEL with --svbrdf names the folder's own model (same bytes) or is refused in one line; SOURCE
    arguments are refused; a page is written for the folder's model."""
    path, m = saved_random_model(tmp_path, "hybrid")
    folder = tmp_path / "sv"
    SVBRDF(m, m.materials[:1], (2, 2)).save(folder)
    out = tmp_path / "page.html"
    (tmp_path / "other").mkdir()
    other, _ = saved_random_model(tmp_path / "other", "hybrid", width=8)
    r = view_harness.cli("view", str(other), "--svbrdf", str(folder), "--out", str(out))
    assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith(f"hbrdf view: error: {other}: is not the model of the textured material"), r.stderr
    r = view_harness.cli("view", str(path), "synthetic:plastic", "--svbrdf", str(folder), "--out", str(out))
    assert r.returncode == 1 and "SOURCE arguments are not shown beside a textured material" in r.stderr, r.stderr
    assert not out.exists()
    r = view_harness.cli("view", str(path), "--svbrdf", str(folder), "--out", str(out))  # the same bytes: accepted
    assert r.returncode == 0 and out.exists(), r.stderr
