"""``hbrdf view``'s WebGPU backend (docs/VIEWER.md, "WebGPU"): the page in headless chromium with
WebGPU on SwiftShader, against the C++ path tracer and against the page's own WebGL2 backend.

WebGPU is asynchronous: the tests drive chromium through its DevTools protocol on a pipe
(view_harness.py: one browser per test process and set of flags, a new tab per page) and read the
document once the page's title says how loading went, as test_view.py does.

Flags: test_view's CHROMIUM_FLAGS without ``--virtual-time-budget``, and
``--enable-unsafe-webgpu --use-webgpu-adapter=swiftshader`` (WebGPU on SwiftShader) with
``--enable-features=Vulkan --use-vulkan=swiftshader``: without the last two the canvas's swap
chain cannot be shared with the compositor (ANGLE's GL: "Could not find SharedImageBackingFactory
... WebgpuSwapChainTexture") and the device is lost at the first present.

Skips: chromium missing -> skip unless HBRDF_REQUIRE_BROWSER=1 (test_view.chromium); chromium
without a WebGPU adapter under these flags -> the browser WebGPU tests skip with that reason,
unless HBRDF_REQUIRE_WEBGPU=1. The WGSL test needs no browser (naga through the ``wgpu`` package on
lavapipe; skips as the other WGSL tests, unless HBRDF_REQUIRE_VULKAN=1).

Bounds: as test_view's docstring argues, with the page's 256 samples per pixel against the
tracer's 64 (environment map) or the page's exact sun: MAD(page, tracer seed 0) <= MAD(tracer
seed 0, tracer seed 1) + 1. WebGPU against WebGL2 (the same page and state): each is an estimate
of the same image E with 256 samples per pixel, E + n_gpu and E + n_gl with |n| about half the
tracer's noise; even independent, MAD(gpu, gl) ~ E|n_gpu - n_gl| ~ 0.7 E|n_t|, below MAD(t0, t1) ~
1.4 E|n_t|, so MAD(gpu, gl) <= MAD(t0, t1) + 1 holds (the 1 for the two 8-bit roundings). The
backends draw the same random numbers, so in practice they agree far closer (measured: 0, the
same bytes, on SwiftShader). The sun alone is one exact evaluation per pixel in both: at most 1
(8-bit rounding) at every interior pixel.

Sizes as test_view's docstring says: the map's comparisons at ENV_SIZE (48 x 48), the sun's at SIZE."""

import os
import pathlib
import re
import urllib.parse

import numpy as np
import pytest

from hybridbrdf.viewer import page as viewer
from hybridbrdf.viewer.scene import tracer_scene
from hybridbrdf.codegen.main import generate
from hybridbrdf.model.file import load_model
import view_harness
from test_view import (BROWSER_FLAGS, CHROMIUM_FLAGS, ENV_SIZE, ENV_STATE, HEADS_MODEL, MODEL, NEURAL_MODEL, SIZE,
                       assert_matches_tracer, check_fragment_changes, chromium, env_state, interior_mask, mad,
                       model_page, needs_renderer, page, page_state,
                       read_state, shared_page_state, shared_tracer_pixels,
                       unescape)  # noqa: F401 (page: the module-scoped page fixture)

#: Headless chromium with WebGPU on SwiftShader (module docstring). No virtual time: the page's
#: title says when it is done.
WEBGPU_FLAGS = [f for f in CHROMIUM_FLAGS if not f.startswith("--virtual-time-budget")] + [
    "--enable-unsafe-webgpu", "--use-webgpu-adapter=swiftshader", "--enable-features=Vulkan",
    "--use-vulkan=swiftshader"]
#: Seconds a page may take to say "hbrdf view: ok" or an error.
PAGE_TIMEOUT = 180


def open_page_devtools(page, hash_="", flags=None, timeout=PAGE_TIMEOUT, fresh=False, keep=False):
    """As test_view.open_page: (title, status line, dom, console lines), the page opened from its
    path, read when its title is "hbrdf view: ..." (ok or an error) or after ``timeout`` seconds.
    In this test process's chromium for ``flags`` (view_harness: a new tab per page; ``keep``: in
    the page's kept tab, as test_view.open_page), or with ``fresh`` in a chromium started for this
    page alone (bench/viewer_load.py: a cold load)."""
    exe = chromium()
    flags = WEBGPU_FLAGS if flags is None else flags
    if fresh:
        b = view_harness.Browser(exe, flags)
        try:
            url = "file://" + urllib.parse.quote(os.path.abspath(page)) + ("#" + hash_ if hash_ else "")
            title, dom, console = b.open(url, timeout)
        finally:
            b.close()
    else:
        title, dom, console = view_harness.open_url(exe, flags, page, hash_, timeout=timeout, keep=keep)
    status = re.search(r'<div id="status">(.*?)</div>', dom, re.S)
    return title, status.group(1) if status else "", dom, console


_PROBE = """<!DOCTYPE html><html><head><meta charset="utf-8"><title>probe</title></head><body><script>
(async function () {
  try {
    const a = navigator.gpu && await navigator.gpu.requestAdapter();
    if (!a) { document.title = "hbrdf view: no adapter"; return; }
    await a.requestDevice();
    document.title = "hbrdf view: webgpu";
  } catch (e) { document.title = "hbrdf view: " + e.message; }
})();
</script></body></html>"""


@pytest.fixture(scope="module")
def webgpu(tmp_path_factory):
    """Skips (or fails, HBRDF_REQUIRE_WEBGPU=1) when chromium gives no WebGPU device under WEBGPU_FLAGS."""
    probe = tmp_path_factory.mktemp("probe") / "probe.html"
    probe.write_text(_PROBE)
    title = open_page_devtools(probe, timeout=60)[0]
    if title != "hbrdf view: webgpu":
        why = f"chromium gives no WebGPU device with {' '.join(WEBGPU_FLAGS[-4:])} ({title!r})"
        if os.environ.get("HBRDF_REQUIRE_WEBGPU") == "1":
            pytest.fail(why + " and HBRDF_REQUIRE_WEBGPU=1")
        pytest.skip(why)


def samples_line(dom):
    return re.search(r'<div id="samples">(.*?)</div>', dom, re.S).group(1)


def webgpu_state(page, hash_, size=SIZE, keep=False):
    """As test_view.page_state for the WebGPU backend: (canvas (size, size, 3) uint8 top row first,
    the scene the page shows for the tracer, its hbrdf edit line); asserts a clean load (or change of
    the fragment, ``keep``) by WebGPU."""
    title, status, dom, console = open_page_devtools(page, f"backend=webgpu&readback=1&size={size}&" + hash_, keep=keep)
    assert title == "hbrdf view: ok", (title, status)
    assert console == [], console
    assert samples_line(dom).endswith("samples per pixel (WebGPU)"), samples_line(dom)
    return read_state(dom)


def shared_webgpu_state(tmp_path_factory, page, hash_, size=SIZE):
    """webgpu_state, made once per test run for every test that opens these page bytes with this
    fragment at this size (view_harness.shared: the load is asserted clean where it is made), in the
    page's kept tab."""
    return view_harness.shared(tmp_path_factory, "webgpu", [view_harness.file_sha256(page), hash_, size, WEBGPU_FLAGS,
                                                            chromium()], lambda: webgpu_state(page, hash_, size, keep=True))


# ---- (1), (2): against the path tracer ----

@needs_renderer
@pytest.mark.parametrize("material,analytic,rotation", [("cc_ibiza_sunset_rgb.rgl", False, -40),
                                                       ("paper_white_rgb.rgl", True, 70)],
                         ids=["glossy_full", "diffuse_analytic"])
def test_webgpu_matches_tracer_under_the_environment(webgpu, page, material, analytic, rotation, tmp_path_factory):
    """(1) WebGPU's Monte Carlo under the map (256 samples per pixel) against the tracer's 64 (bound
    in the module docstring); the map turns the same way (the opposite turn is far off). glossy_full
    is test_view.ENV_STATE: its picture and renders are shared with the backend comparison and
    test_view's test of that state."""
    img, scene, _ = shared_webgpu_state(tmp_path_factory, page, env_state(material, analytic, rotation), ENV_SIZE)
    assert scene == tracer_scene(MODEL, material, width=ENV_SIZE, height=ENV_SIZE, analytic=analytic, spp=256,
                                 rotation=rotation)
    diff, noise = assert_matches_tracer(img, scene, max_noise=6.0, shared=tmp_path_factory)
    mirrored = tracer_scene(MODEL, material, width=ENV_SIZE, height=ENV_SIZE, analytic=analytic, rotation=-rotation)
    assert mad(img, shared_tracer_pixels(tmp_path_factory, mirrored), interior_mask(ENV_SIZE)) > noise + 4.0


@needs_renderer
@pytest.mark.parametrize("material,analytic", [("paper_white_rgb.rgl", False), ("cc_ibiza_sunset_rgb.rgl", True)],
                         ids=["diffuse_full", "glossy_analytic"])
def test_webgpu_matches_tracer_in_the_sun(webgpu, page, material, analytic, tmp_path_factory):
    """(2) The sun alone (one exact sample per pixel) against the tracer's 64 samples (diffuse_full's
    renders shared with test_view.test_page_matches_tracer[full], the same scene)."""
    img, scene, _ = webgpu_state(page, f"material={material}&analytic={int(analytic)}&light=sun&sun_el=40&sun_az=130",
                                 keep=True)
    assert scene == tracer_scene(MODEL, material, width=SIZE, height=SIZE, analytic=analytic, spp=64,
                                        light="sun", elevation=40, azimuth=130)
    assert_matches_tracer(img, scene, shared=tmp_path_factory)


# ---- (3): WebGPU against WebGL2 ----

@needs_renderer
def test_webgpu_and_webgl2_agree(webgpu, page, tmp_path_factory):
    """(3) The same page and state drawn by both backends (WebGL2 as test_view opens it): under the
    map within the tracer's two-seed noise + 1 (module docstring); the sun alone within 1 at every
    interior pixel (the same float32 expression, rounded to 8 bits). The state under the map is
    test_view.ENV_STATE, whose pictures (one per backend) and renders the run's tests against the
    tracer of that state make too: shared (view_harness.shared), not drawn again."""
    mask = interior_mask(ENV_SIZE)
    gpu, scene, _ = shared_webgpu_state(tmp_path_factory, page, ENV_STATE, ENV_SIZE)
    gl, gl_scene, _ = shared_page_state(tmp_path_factory, page, ENV_STATE, ENV_SIZE)
    assert gl_scene == scene
    t0, t1 = shared_tracer_pixels(tmp_path_factory, scene, seed=0), shared_tracer_pixels(tmp_path_factory, scene, seed=1)
    noise = mad(t0, t1, mask)
    diff = mad(gpu, gl, mask)
    assert diff <= noise + 1.0, (diff, noise)
    # The same random numbers and float32 operations: the same bytes on SwiftShader (measured 0); 0.1
    # leaves room for a compiler that contracts multiply-adds differently. A port that took a pixel's
    # numbers from another pixel (rows counted from the top) is 0.26 off at rotation 25, 0.28 at ENV_STATE's -40
    # (2026-11-29), the tracer's noise 1.9.
    assert diff <= 0.1, diff
    sun = "material=cc_ibiza_sunset_rgb.rgl&light=sun&sun_el=30&sun_az=-60&alpha=0.05,0.4"
    mask = interior_mask(SIZE)
    gpu = webgpu_state(page, sun, keep=True)[0].astype(np.int32)
    gl = page_state(page, sun, keep=True)[0].astype(np.int32)
    assert np.abs(gpu - gl)[mask].max() <= 1, np.abs(gpu - gl)[mask].max()
    assert gpu[mask].max() > 50  # a lit sphere


def test_webgpu_fragment_change_draws_what_a_fresh_load_draws(webgpu, page):
    """test_view's check of a change of the fragment against fresh loads, with WebGPU drawing: the
    sums' buffer and bind groups made again for the new size, the same pixels."""
    check_fragment_changes(page, WEBGPU_FLAGS, "webgpu")


# ---- (4): a clean load; other architectures ----

def test_webgpu_is_chosen_and_logs_nothing(webgpu, page):
    """(4) The page as a user opens it (no backend parameter, no readback) in a browser with WebGPU:
    WebGPU draws, nothing on the console, the load time set at the first picture, two scripts."""
    html = page.read_text(encoding="utf-8")
    assert html.count("<script") == 2 and html.lower().count("</script") == 2
    title, status, dom, console = open_page_devtools(page, "")
    assert (title, status.strip(), console) == ("hbrdf view: ok", "", [])
    assert re.search(r"samples per pixel \(WebGPU\)$", samples_line(dom)), samples_line(dom)
    assert re.search(r'data-load-ms="\d+"', dom)


@pytest.mark.parametrize("model", [HEADS_MODEL, NEURAL_MODEL], ids=["heads", "neural"])
def test_webgpu_other_architectures_load(webgpu, tmp_path_factory, model):
    """(4) A model with material output layers (the head from the uniform buffer) and the neural baseline:
    a fresh load of the model's page (test_view.model_page: written once per process for both backends)."""
    out = model_page(tmp_path_factory, model)
    img = webgpu_state(out, "spp=16")[0]
    assert img[SIZE // 2 - 10:SIZE // 2 + 10, SIZE // 2 - 10:SIZE // 2 + 10].max() > 10  # the sphere is lit


def test_webgpu_compile_error_one_line(webgpu, page, tmp_path):
    """(4) WGSL that the browser's compiler refuses (here an i32 + u32 put into the page's shader) is
    one line on the page and in its title, with the line and column getCompilationInfo gives."""
    html = page.read_text(encoding="utf-8")
    good = "let c1: f32 = hbrdf_view_env_cdf[start + lo + 1];"
    assert html.count(good) == 1
    broken = tmp_path / "broken.html"
    broken.write_text(html.replace(good, good.replace("1]", "1u]")), encoding="utf-8")
    title, status, _, _ = open_page_devtools(broken, "backend=webgpu")
    line = unescape(status)
    assert re.fullmatch(r"compute WGSL compile failed: line \d+:\d+: .*\(i32, u32\).*", line), line
    assert title == "hbrdf view: error: " + line


# ---- (5): a browser without WebGPU ----

#: Chromium without WebGPU, read over DevTools once the page has said ok or an error: --dump-dom's
#: virtual time budget can end while the adapter request is still pending on a loaded machine.
NO_WEBGPU_FLAGS = BROWSER_FLAGS  # test_view's browser (one chromium for both modules)


def test_without_webgpu(page):
    """(5) Chromium without WebGPU flags (no adapter): backend=webgpu is one line on the page; the
    page left to choose draws with WebGL2, the browser's "No available adapters." its only console
    line; a backend that does not exist is one line."""
    title, status, dom, console = open_page_devtools(page, "backend=webgpu", flags=NO_WEBGPU_FLAGS)
    line = "backend=webgpu: this browser gives no WebGPU device (navigator.gpu.requestAdapter() gave no adapter)."
    assert (unescape(status), title) == (line, "hbrdf view: error: " + line), (title, status)
    title, status, dom, console = open_page_devtools(page, "size=16", flags=NO_WEBGPU_FLAGS)  # its frame at 16 x 16
    assert (title, status.strip()) == ("hbrdf view: ok", "")
    assert samples_line(dom).endswith("samples per pixel (WebGL2)"), samples_line(dom)
    assert all('"No available adapters."' in c for c in console), console
    title, status, _, _ = open_page_devtools(page, "backend=vulkan", flags=NO_WEBGPU_FLAGS)
    line = 'URL parameter backend="vulkan": expected webgpu or webgl2'
    assert (unescape(status), title) == (line, "hbrdf view: error: " + line), (title, status)


# ---- (6): the WGSL without a browser ----

@pytest.mark.parametrize("model_file", [MODEL, HEADS_MODEL, NEURAL_MODEL], ids=["hybrid", "heads", "neural"])
def test_wgsl_is_the_generated_code_and_validates(model_file):
    """(6) The page's WGSL: hbrdf-codegen's WGSL unchanged, then the page's; naga (wgpu on lavapipe)
    accepts it and the display pass, and makes their pipelines with the bind group layouts that
    viewer_webgpu.js makes."""
    from slang_wgsl_tools import skip_without_wgpu, wgpu_device, wgsl_errors

    model = load_model(model_file)
    data = viewer.page_data(model, model_file)
    wgsl = generate(model, "wgsl", materials=[model.materials[0]], model_path=model_file)
    assert data["wgsl"].startswith(wgsl) and "fn hbrdf_view_main(" in data["wgsl"][len(wgsl):]
    skip_without_wgpu()
    import wgpu

    for code in (data["wgsl"], data["wgsl_display"]):
        errors = wgsl_errors(code)
        assert errors is None, errors[-3000:]
        # Chrome's compiler (Tint) refuses a float literal beyond f32's range, where naga rounds it
        # (codegen's FLT_MAX was 3.40282347e+38f): none in the page's WGSL.
        literals = [float(x) for x in re.findall(r"(?<![\w.])(\d+\.\d*(?:e[-+]?\d+)?|\d+e[-+]?\d+)f", code)]
        assert literals and max(literals) <= float(np.finfo(np.float32).max)
    device = wgpu_device()
    C, F = wgpu.ShaderStage.COMPUTE, wgpu.ShaderStage.FRAGMENT
    compute_layout = device.create_bind_group_layout(entries=[
        {"binding": 0, "visibility": C, "buffer": {"type": "uniform"}},
        {"binding": 1, "visibility": C, "buffer": {"type": "uniform", "has_dynamic_offset": True}},
        {"binding": 2, "visibility": C, "buffer": {"type": "storage"}},
        {"binding": 3, "visibility": C, "buffer": {"type": "read-only-storage"}},
        {"binding": 4, "visibility": C, "buffer": {"type": "read-only-storage"}}])
    display_layout = device.create_bind_group_layout(entries=[
        {"binding": 0, "visibility": F, "buffer": {"type": "read-only-storage"}},
        {"binding": 1, "visibility": F, "buffer": {"type": "uniform"}}])
    device.create_compute_pipeline(
        layout=device.create_pipeline_layout(bind_group_layouts=[compute_layout]),
        compute={"module": device.create_shader_module(code=data["wgsl"]), "entry_point": "hbrdf_view_main"})
    display = device.create_shader_module(code=data["wgsl_display"])
    device.create_render_pipeline(
        layout=device.create_pipeline_layout(bind_group_layouts=[display_layout]),
        vertex={"module": display, "entry_point": "hbrdf_view_vertex"},
        fragment={"module": display, "entry_point": "hbrdf_view_fragment", "targets": [{"format": "rgba8unorm"}]},
        primitive={"topology": "triangle-list"})
    # the uniform block as viewer_webgpu.js fills it: the head's floats, then the packed material
    from hybridbrdf.viewer import wgsl as viewer_wgsl

    assert f"pack: array<vec4f, {(data['n_pack'] + 3) // 4}>" in data["wgsl"]
    js = (pathlib.Path(viewer.__file__).parent / "viewer_webgpu.js").read_text()
    assert f"const PARAMS_HEAD_FLOATS = {viewer_wgsl.PARAMS_HEAD_BYTES // 4};" in js
    assert f"const WORKGROUP = {viewer_wgsl.WORKGROUP};" in js
