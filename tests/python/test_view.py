"""``hbrdf view`` (hybridbrdf.viewer.page, docs/VIEWER.md): the page in a real browser.

Chromium headless with software WebGL2 (ANGLE on SwiftShader) opens the page from its file path
(one browser per test process and set of flags, a new tab per page, read over the DevTools
protocol: view_harness.py); the page draws at load and, with ``#readback=1``, writes its canvas's
pixels into the DOM and its outcome into the title ("hbrdf view: ok" or "hbrdf view: error: ...").
Without chromium the browser tests skip, unless HBRDF_REQUIRE_BROWSER=1 (then they fail).

The oracle for the pixels is the C++ path tracer rendering the same camera, light and material
(hybridbrdf.viewer.page.tracer_scene: direct light only). Bound on the mean absolute difference (8-bit sRGB
units) over the pixels the sphere covers entirely:
    MAD(page, tracer seed 0) <= MAD(tracer seed 0, tracer seed 1) + 1.
Why: the tracer's images are E + n_i with independent noise n_i of its sample count (64 per pixel),
so MAD(t0, t1) ~ E|n0 - n1| ~ 1.4 E|n| (for Gaussian noise). The sun alone: the page shows the
converged image E (one exact sample), so MAD(page, t0) ~ E|n|. The environment map: the page's own
Monte Carlo estimate has 4x the tracer's samples per pixel (256) with the same kind of estimator
(map and BRDF samples, power heuristic), so its noise n_p ~ n / 2 and MAD(page, t0) ~ E|n_p - n0| ~
1.1 E|n|, still below MAD(t0, t1). The 1 covers the two 8-bit roundings, the box filter of the
tracer's pixels against the page's pixel centres (sun) and the sun's disc against its direction. A page that renders
another material, frame or light direction is off by far more (checked: the unedited page
against the edited material's render).

Sizes: the sun's comparisons at SIZE (96 x 96: the page's one sample per pixel is cheap, and the
tracer's noise there, which sets the bound, comes from its pixels' footprints, smaller at a finer
grid); the environment map's at ENV_SIZE (48 x 48), where each pixel's noise is set by its samples
alone, so the bound and every margin are the same at either size and the page draws 4x fewer
samples. Measured at 96 / 48 (tests' scenes, tracer seeds 0 and 1): page-tracer MAD 3.20 / 3.22
against a bound of 5.42 / 5.61 (paper_white, rotation 70), 1.33 / 1.34 against 2.86 / 2.86
(cc_ibiza_sunset, -40), 1.13 / 1.18 against 2.56 / 2.58 (its f_a); the map turned the other way
87.5 / 87.7 and 24.6 / 25.3 off, another material 70-150 off at both (1,388 interior pixels at 48)."""

import base64
import hashlib
import json
import os
import re
import shlex
import shutil
import subprocess

import numpy as np
import pytest

from hybridbrdf import _core
from hybridbrdf.viewer import page as viewer
from hybridbrdf.viewer.scene import CAMERA, srgb8, tracer_scene
from hybridbrdf.viewer.glsl import DISPLAY_SHADER
from hybridbrdf.model.file import load_model
from helpers import run_cli
import view_harness

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MODEL = os.path.join(REPO, "results", "rgl54_hybrid_32x2.safetensors")
HEADS_MODEL = os.path.join(REPO, "results", "rgl54_32x2_heads_fast15k.safetensors")
NEURAL_MODEL = os.path.join(REPO, "results", "merl80_neural_32x3_10k.safetensors")
SIZE = 96
ENV_SIZE = 48  # the environment map's comparisons (module docstring, "Sizes")
SPP = 64

#: The flags that give headless chromium WebGL2 without a GPU (ANGLE on SwiftShader). --no-sandbox:
#: the tests run as root in CI, where chromium's sandbox refuses to start; the page is local.
#: --disable-dev-shm-usage: containers' small /dev/shm. Each run gets a profile folder of its own.
#: --host-resolver-rules: no name resolves, for every page the tests open (a page that reached for the
#: network would fail to load something and log it: test_page_is_self_contained_and_logs_nothing), in
#: the one browser they share rather than one started for that test alone.
NO_NAMES = "--host-resolver-rules=MAP * ~NOTFOUND"
CHROMIUM_FLAGS = ["--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                  "--enable-webgl", "--ignore-gpu-blocklist", "--enable-logging=stderr", "--v=0",
                  "--virtual-time-budget=20000", "--disable-dev-shm-usage", "--no-first-run", NO_NAMES]
#: The same without virtual time, for the browser the tests drive over DevTools (view_harness): the
#: page is read once its title says it is done. --disable-gpu-compositing: the browser composites the
#: tab's frames in software; WebGL2 still draws on SwiftShader and the tests read its pixels with
#: readPixels, so no picture changes (a textured page's readback: the same bytes with and without),
#: but the GPU process no longer compiles the compositor's shaders at start (2.4-2.6 -> 1.0-1.1 s of
#: its CPU) nor composites each frame of the page, which a loaded machine made the load wait for:
#: test_view_svbrdf.py 73.8 -> 71.4 s of CPU, 208 -> 137 s wall (back to back, 2 cores at load 17-20,
#: 2026-11-29). The WebGPU tests keep GPU compositing (test_view_webgpu.WEBGPU_FLAGS: the canvas's
#: swap chain is shared with the compositor).
BROWSER_FLAGS = [f for f in CHROMIUM_FLAGS if not f.startswith("--virtual-time-budget")] + ["--disable-gpu-compositing"]


def chromium():
    exe = os.environ.get("HBRDF_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        if os.environ.get("HBRDF_REQUIRE_BROWSER") == "1":
            pytest.fail("chromium not found and HBRDF_REQUIRE_BROWSER=1 (scripts/setup.sh installs it)")
        pytest.skip("chromium not installed (scripts/setup.sh installs it)")
    return exe


needs_renderer = pytest.mark.skipif(not getattr(_core, "HAVE_RENDERER", False), reason="build without the renderer")


def open_page(page, hash_="", extra_flags=(), backend="webgl2", keep=False):
    """(title, status line, dom, the page's console lines) of the page opened from its path, in this
    test process's chromium for these flags (view_harness: one browser, a new tab per page; the
    document once loaded and titled "hbrdf view: ...", every console message of the tab). ``keep``:
    in the tab kept open for these page bytes (view_harness.open_url), where a page opened before
    draws the new fragment without loading again (its shader compiled once; the console lines since
    the change): for the pages several tests read; a test whose point is the load opens it fresh.
    ``backend``: put ``backend=...`` in front of the URL's fragment (``None``: the fragment as
    given). These tests are the WebGL2 backend's: the page would first ask for a WebGPU adapter,
    and chromium without WebGPU flags answers none and logs "No available adapters." on the console
    (the automatic choice is tested in test_view_webgpu.py)."""
    exe = chromium()
    if backend is not None:
        hash_ = f"backend={backend}" + ("&" + hash_ if hash_ else "")
    title, dom, console = view_harness.open_url(exe, [*BROWSER_FLAGS, *extra_flags], page, hash_, timeout=180, keep=keep)
    # ANGLE's performance note "GPU stall due to ReadPixels" is no message of the page's: with
    # --disable-gpu-compositing (BROWSER_FLAGS) the browser's software compositor copies the WebGL
    # canvas out with a readPixels of its own, and on a loaded machine that copy waits (CI, a page
    # without readback=1 at size=16, 2026-11-29); the tests' own readback (page_dom) can draw it too.
    # Only that exact note is dropped: any other console line still fails the test that reads it.
    console = without_stall_note(console)
    assert re.search(r"<title>(.*?)</title>", dom, re.S).group(1) == title
    status = re.search(r'<div id="status">(.*?)</div>', dom, re.S).group(1)
    return title, status, dom, console


def without_stall_note(console):
    """The console lines but ANGLE's "GPU stall due to ReadPixels" note (open_page says why)."""
    return [line for line in console if "GPU stall due to ReadPixels" not in line]


def unescape(text):
    return text.replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", '"').replace("&amp;", "&")


def page_dom(page, hash_, size=SIZE, keep=False):
    """The DOM of the page opened with readback=1 at size x size (``keep``: open_page's); asserts a
    clean load (or change of the fragment)."""
    title, status, dom, console = open_page(page, f"readback=1&size={size}&" + hash_, keep=keep)
    if any("CONTEXT_LOST_WEBGL" in line for line in console):
        # SwiftShader's WebGL context lost under the shared browser's load (seen once in two clean-
        # clone runs of the suite, the page code unchanged): the page is opened once more, in a new
        # tab, and that one must load clean; a second loss fails below.
        view_harness.close_kept(page)
        title, status, dom, console = open_page(page, f"readback=1&size={size}&" + hash_)
    assert title == "hbrdf view: ok", (title, status)
    assert console == [], console  # ANGLE's "GPU stall due to ReadPixels" note already dropped (open_page)
    return dom


def page_state(page, hash_, size=SIZE, keep=False):
    """(canvas as (size, size, 3) uint8 top row first, the scene the page shows for the tracer,
    its hbrdf edit line); asserts a clean load (``keep``: open_page's)."""
    return read_state(page_dom(page, hash_, size, keep))


def read_state(dom):
    """(canvas as (SIZE, SIZE, 3) uint8 top row first, the scene the page shows, its hbrdf edit line)
    of a page's DOM opened with readback=1."""
    size, b64 = re.search(r'<pre id="readback">(\d+) ([A-Za-z0-9+/=]+)</pre>', dom).groups()
    px = np.frombuffer(base64.b64decode(b64), dtype=np.uint8).reshape(int(size), int(size), 4)
    scene = json.loads(unescape(re.search(r'<pre id="scene">(.*?)</pre>', dom, re.S).group(1)))
    cmd = unescape(re.search(r'<div id="cmd">(.*?)</div>', dom, re.S).group(1))
    return px[::-1, :, :3], scene, cmd  # the readback gives the bottom row first


def shared_page_state(tmp_path_factory, page, hash_, size=SIZE):
    """page_state, made once per test run for every test that opens these page bytes with this
    fragment at this size (view_harness.shared: the load is asserted clean where it is made), in the
    page's kept tab (open_page's ``keep``)."""
    return view_harness.shared(tmp_path_factory, "webgl2", [view_harness.file_sha256(page), hash_, size, BROWSER_FLAGS,
                                                            chromium()], lambda: page_state(page, hash_, size, keep=True))


def page_pixels(page, hash_):
    return page_state(page, hash_)[0]


def tracer_pixels(scene, seed=0):
    from hybridbrdf.render.tracer import render

    img, _ = render(scene, seed=seed, spp=SPP, threads=2)
    return srgb8(img)


_CORE_SHA256 = []


def shared_tracer_pixels(tmp_path_factory, scene, seed=0):
    """tracer_pixels, rendered once per test run for every test that renders this scene (the files it
    reads by content, view_harness.content_key) with this seed by this build of the library."""
    if not _CORE_SHA256:
        _CORE_SHA256.append(view_harness.file_sha256(_core.__file__))
    key = [view_harness.content_key(scene), seed, SPP, _CORE_SHA256[0]]
    return view_harness.shared(tmp_path_factory, "tracer", key, lambda: tracer_pixels(scene, seed))


def interior_mask(size=SIZE):
    """Pixels of a size x size picture that the unit sphere covers entirely (the page's camera;
    corners and centre hit it)."""
    cam = CAMERA
    pos, look, up = (np.array(cam[k], dtype=np.float64) for k in ("position", "look_at", "up"))
    f = (look - pos) / np.linalg.norm(look - pos)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    t = np.tan(np.radians(cam["fov_deg"]) / 2)
    mask = np.ones((size, size), bool)
    for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1), (0.5, 0.5)):
        x, y = np.meshgrid(np.arange(size) + dx, np.arange(size) + dy)
        d = f[None, None] + r[None, None] * ((2 * x / size - 1) * t)[..., None] + u[None, None] * ((1 - 2 * y / size) * t)[..., None]
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        b = d @ pos
        mask &= b * b - (pos @ pos - 1) > 0
    return mask


def mad(a, b, mask):
    return float(np.abs(a.astype(np.int32) - b.astype(np.int32))[mask].mean())


def _sha256(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


_PAGES = {}  # (model path, its bytes' sha256), or ("model_page", ...) -> (its page, the page's sha256)


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    """MODEL's page, written by `hbrdf view` as a command (a fresh interpreter: the command's own
    start), once per test process: this module and test_view_webgpu.py share it (their tests only
    read it); written again if the model's bytes or the page's have changed since."""
    key = (MODEL, _sha256(MODEL))
    got = _PAGES.get(key)
    if got is None or not os.path.exists(got[0]) or _sha256(got[0]) != got[1]:
        out = tmp_path_factory.mktemp("view") / "page.html"
        r = run_cli("view", MODEL, "--out", str(out))
        assert r.returncode == 0, r.stderr
        got = _PAGES[key] = (out, _sha256(out))
    return got[0]


def assert_matches_tracer(page_img, scene, max_noise=3.0, shared=None):
    """The page's picture against the tracer's render of ``scene`` (the picture's size) within the
    bound of the module docstring; (the difference, the tracer's two-seed noise). ``shared``: the
    tmp_path_factory through which the renders are shared with the run's other tests
    (shared_tracer_pixels); None renders them here."""
    assert scene["camera"]["width"] == scene["camera"]["height"] == len(page_img)
    mask = interior_mask(len(page_img))
    if shared is None:
        t0, t1 = tracer_pixels(scene, seed=0), tracer_pixels(scene, seed=1)
    else:
        t0, t1 = shared_tracer_pixels(shared, scene, seed=0), shared_tracer_pixels(shared, scene, seed=1)
    noise = mad(t0, t1, mask)
    lit = (t0[mask].max(axis=-1) > 10).mean()
    assert lit > 0.3 and noise < max_noise, (lit, noise)  # a lit sphere, a converged-enough tracer
    diff = mad(page_img, t0, mask)
    assert diff <= noise + 1.0, (diff, noise)
    return diff, noise


@needs_renderer
@pytest.mark.parametrize("analytic", [False, True], ids=["full", "analytic"])
def test_page_matches_tracer(page, analytic, tmp_path_factory):
    """(1) The page's sphere against the tracer's image of the scene the page shows for it (the
    renders shared with test_view_webgpu's test of the same scene)."""
    material = "paper_white_rgb.rgl"
    img, scene, _ = page_state(page, f"material={material}&analytic={int(analytic)}&light=sun&sun_el=40&sun_az=130",
                               keep=True)
    assert scene == tracer_scene(MODEL, material, width=SIZE, height=SIZE, analytic=analytic, spp=64,
                                        light="sun", elevation=40, azimuth=130)
    assert_matches_tracer(img, scene, shared=tmp_path_factory)


def env_state(material, analytic, rotation):
    """The URL fragment of the page under the environment map with 256 samples per pixel."""
    return f"material={material}&analytic={int(analytic)}&rotation={rotation}&spp=256"


#: The state under the map that test_page_matches_tracer_under_the_environment[glossy_full],
#: test_view_webgpu's glossy_full and its backend comparison all draw (one load per backend per run).
ENV_STATE = env_state("cc_ibiza_sunset_rgb.rgl", False, -40)


@needs_renderer
@pytest.mark.parametrize("material,analytic,rotation", [("paper_white_rgb.rgl", False, 70),
                                                       ("cc_ibiza_sunset_rgb.rgl", False, -40),
                                                       ("cc_ibiza_sunset_rgb.rgl", True, 0)],
                         ids=["diffuse_full", "glossy_full", "glossy_analytic"])
def test_page_matches_tracer_under_the_environment(page, material, analytic, rotation, tmp_path_factory):
    """(1) The page's default light, the environment map (the tracer's sky), by Monte Carlo in the
    page: 256 samples per pixel against the tracer's 64 (bound in the module docstring); the map's
    rotation turns the same way in both (the opposite turn is far off). The picture and the renders
    are shared with the run's other tests of the same state (test_view_webgpu's glossy_full and
    backend comparison: ENV_STATE)."""
    img, scene, _ = shared_page_state(tmp_path_factory, page, env_state(material, analytic, rotation), ENV_SIZE)
    assert scene == tracer_scene(MODEL, material, width=ENV_SIZE, height=ENV_SIZE, analytic=analytic, spp=256,
                                 rotation=rotation)
    diff, noise = assert_matches_tracer(img, scene, max_noise=6.0, shared=tmp_path_factory)
    if rotation:
        mirrored = tracer_scene(MODEL, material, width=ENV_SIZE, height=ENV_SIZE, analytic=analytic, rotation=-rotation)
        assert mad(img, shared_tracer_pixels(tmp_path_factory, mirrored), interior_mask(ENV_SIZE)) > noise + 4.0


@pytest.fixture(scope="module")
def copy_page(tmp_path_factory):
    """(a copy of MODEL, its page): written once per module for both of the slider test's parameters,
    whose pictures are changes of the fragment in the page's kept tab (one load, one shader compiled:
    2-3 s of CPU). The page names the copy in its edit line; each test puts the copy's bytes back to
    MODEL's before running that line (the previous test's edit wrote a material into it)."""
    d = tmp_path_factory.mktemp("slider")
    model, out = d / "m.safetensors", d / "p.html"
    shutil.copyfile(MODEL, model)
    assert view_harness.cli("view", str(model), "--out", str(out)).returncode == 0
    return model, out


@needs_renderer
@pytest.mark.parametrize("key,value", [("kd", "0.8,0.2,0.1"), ("alpha", "0.05,0.4")], ids=["kd", "alpha_anisotropic"])
def test_slider_previews_hbrdf_edit(copy_page, key, value, page, tmp_path_factory):
    """(2) kd (or an anisotropic alpha: the tangent frame) set through the URL, as the sliders set it,
    renders as what the page's `hbrdf edit` line writes for it, in the tracer scene the page shows.
    The page is the copy's (copy_page: one load for both parameters, in its kept tab). The control,
    the material unedited, is MODEL's page (``page``: the same bytes as the copy's model), one load
    for both parameters (shared_page_state)."""
    model, edited_page = copy_page
    shutil.copyfile(MODEL, model)  # the copy as the page was written for it: no edit of an earlier test in it
    material = "cc_ibiza_sunset_rgb.rgl"
    img, scene, cmd = page_state(edited_page, f"material={material}&light=sun&{key}={value}", keep=True)
    argv = shlex.split(cmd)
    assert argv == ["hbrdf", "edit", str(model), material, "--set", f"{key}={value}", "--as", f"{material}_edit",
                    "--out", str(model)], cmd
    r = view_harness.cli(*argv[1:])  # the page's command line, run
    assert r.returncode == 0, r.stderr
    assert scene["materials"]["m"] == {"type": "model", "file": str(model), "material": f"{material}_edit",
                                       "evaluate": "full"}
    assert_matches_tracer(img, scene)
    unedited = shared_page_state(tmp_path_factory, page, f"material={material}&light=sun")[0]
    assert mad(img, unedited, interior_mask()) > 2.0  # the slider changes the image


def test_page_is_self_contained_and_logs_nothing(page):
    """(3) Opened from its path: no reference to anything outside the file, no console message."""
    html = page.read_text(encoding="utf-8")
    assert not re.search(r"\b(src|href)\s*=", html, re.I)
    assert "default-src 'none'" in html  # and the page's policy forbids any fetch
    own = re.sub(r'(<script type="application/json" id="hbrdf-data">).*?(</script>)', r"\1\2", html, flags=re.S)
    assert not re.search(r"https?:|wss?:|ftp:|//[a-z0-9.-]+\.[a-z]{2,}/", own, re.I)  # the page's own HTML and script
    assert not re.search(r"\b(fetch|XMLHttpRequest|WebSocket|importScripts|import\()", own)
    # no name resolves (the tests' browser's NO_NAMES): a page that reached for the network would fail
    # to load something and log it
    assert NO_NAMES in BROWSER_FLAGS
    title, status, dom, console = open_page(page, "")
    assert (title, status.strip(), console) == ("hbrdf view: ok", "", [])


def model_page(tmp_path_factory, model_file):
    """``hbrdf view MODEL_FILE``'s page (in this process: view_harness.cli), written once per test
    process for the tests that open it (the other architectures' in this module and in
    test_view_webgpu.py, each a fresh load in its own backend); written again if the model's bytes or
    the page's have changed since."""
    key = ("model_page", model_file, _sha256(model_file))
    got = _PAGES.get(key)
    if got is None or not os.path.exists(got[0]) or _sha256(got[0]) != got[1]:
        out = tmp_path_factory.mktemp("model_page") / "p.html"
        r = view_harness.cli("view", model_file, "--out", str(out))
        assert r.returncode == 0, r.stderr
        got = _PAGES[key] = (out, _sha256(out))
    return got[0]


@pytest.mark.parametrize("model", [HEADS_MODEL, NEURAL_MODEL], ids=["heads", "neural"])
def test_other_architectures_load(tmp_path_factory, model):
    out = model_page(tmp_path_factory, model)  # a fresh load of it (the load is the point), not a kept tab
    img = page_pixels(out, "spp=4")  # the map's one frame: the network evaluated and sampled
    assert img[SIZE // 2 - 10:SIZE // 2 + 10, SIZE // 2 - 10:SIZE // 2 + 10].max() > 10  # the sphere is lit


def test_a_reciprocal_model_loads(tmp_path):
    """hybrid-reciprocal's network inputs (m and the products of e) through the page's GLSL ES."""
    from hybridbrdf.model.random import random_model

    _, model = random_model("hybrid-reciprocal", width=16, depth=2, isotropic=[True, False, True])
    path = tmp_path / "r.safetensors"
    model.save(path)
    out = tmp_path / "p.html"
    r = view_harness.cli("view", str(path), "--out", str(out))
    assert r.returncode == 0, r.stderr
    img = page_pixels(out, "spp=4")  # the map's one frame: the network evaluated and sampled
    assert img[SIZE // 2 - 10:SIZE // 2 + 10, SIZE // 2 - 10:SIZE // 2 + 10].max() > 10  # the sphere is lit


HOSTILE = ["</script><script>document.title='pwned'</script>", "<!--<script>", "a\"b'c`${x}\\",
           "line\nbreak\r\u2028\u2029end", "<img src=x onerror=\"document.title='pwned'\">", "&amp;&lt;"]


def test_hostile_text_cannot_inject(tmp_path):
    """(4) Origin labels and training records of the model are shown as text, never run."""
    model = load_model(MODEL)
    for i, text in enumerate(HOSTILE):
        model.material_info[i]["origin"] = text
    model.training = dict(model.training, sources=HOSTILE)
    hostile_path = tmp_path / "m'<b>&.safetensors"
    model.save(str(hostile_path))
    out = tmp_path / "p.html"
    r = view_harness.cli("view", str(hostile_path), "--out", str(out))
    assert r.returncode == 0, r.stderr
    html = out.read_text(encoding="utf-8")
    assert html.count("<script") == 2 and html.lower().count("</script") == 2
    assert "\u2028" not in html and "\u2029" not in html
    # size=16: the page's frame after its title drawn at 16 x 16 (the test reads its text, not its picture).
    # An origin, shown for its material, reads back as the text it is (all: the training line): the
    # first material's on the page as opened (the default material; kd set as its slider sets it, for
    # the edit line below), the fourth's chosen in the URL. One tab: the first by a load, the fourth
    # material's by a change of the fragment (keep: the page's shader compiled once, 2-3 s of CPU).
    doms = []
    for i, chosen in ((0, "&kd=0.5"), (3, f"&material={model.materials[3]}")):
        title, status, dom, console = open_page(out, "size=16" + chosen, keep=True)
        assert title == "hbrdf view: ok" and console == [], (title, status, console)
        assert "pwned" not in title
        assert dom.count("<script") == 2 and "<img" not in dom and "<b>" not in dom
        info = re.search(r'<p id="info">(.*?)</p>', dom, re.S).group(1)
        shown = info.replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", '"').replace("&amp;", "&")
        assert shown.startswith("origin: " + HOSTILE[i]), (HOSTILE[i], shown)  # exactly: the DOM over DevTools keeps CR
        doms.append(dom)
    # the hbrdf edit line of the default material's tab quotes the hostile path for a POSIX shell
    cmd = re.search(r'<div id="cmd">(.*?)</div>', doms[0], re.S).group(1)
    cmd = cmd.replace("&lt;", "<").replace("&gt;", ">").replace("&amp;", "&")
    assert shlex.split(cmd) == ["hbrdf", "edit", str(hostile_path), model.materials[0], "--set", "kd=0.5,0.5,0.5", "--as",
                                model.materials[0] + "_edit", "--out", str(hostile_path)], cmd


def _error_line(capsys, *argv):
    """The one line ``hbrdf ARGV`` prints to stderr (in-process: the same code as the command), after its prefix."""
    from hybridbrdf import cli

    assert cli.main(list(argv)) == 1
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    prefix = f"hbrdf {argv[0]}: error: "
    assert out == "" and len(lines) == 1 and lines[0].startswith(prefix), (out, err)
    return lines[0][len(prefix):]


def test_refused_models_same_error_as_info(tmp_path, capsys):
    """(5) Model files the loaders refuse: the one line `hbrdf info` prints; nothing written."""
    good = open(MODEL, "rb").read()
    cases = {"empty.safetensors": b"", "garbage.safetensors": b"not a model" * 10,
             "truncated.safetensors": good[: len(good) // 2], "header.safetensors": good[:8] + b"{" + good[9:200],
             "missing.safetensors": None}
    for name, content in cases.items():
        path = tmp_path / name
        if content is not None:
            path.write_bytes(content)
        out = tmp_path / (name + ".html")
        view = _error_line(capsys, "view", str(path), "--out", str(out))
        assert view == _error_line(capsys, "info", str(path)) and str(path) in view, view
        assert not out.exists()
    # the page over its own model is refused before anything is read
    assert "names the input" in _error_line(capsys, "view", MODEL, "--out", MODEL)


def test_too_large_model_refused(tmp_path, monkeypatch, capsys):
    """A model over the size limit is refused with its size and the limit."""
    from hybridbrdf import cli

    n = viewer.weight_bytes(load_model(MODEL))
    monkeypatch.setattr(viewer, "MAX_VIEW_WEIGHT_BYTES", n - 4)
    out = tmp_path / "p.html"
    assert cli.main(["view", MODEL, "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("hbrdf view: error: ") and "\n" not in err
    assert f"({n // 4} float32 values)" in err and f"limit: {(n - 4) / 2**20:g} MiB" in err, err
    assert not out.exists()


def test_without_webgl2_one_line(page):
    """A browser without WebGL2 sees one line saying so."""
    title, status, dom, console = open_page(page, "", ["--disable-3d-apis"])
    assert status.strip() == "This viewer needs WebGL2, which this browser does not provide (or has turned off)."
    assert title.startswith("hbrdf view: error: This viewer needs WebGL2")


@pytest.mark.parametrize("hash_,line,keep", [
    ("material=nope", 'no material "nope" in the model', False),
    ("kd=2", 'URL parameter kd="2": expected 1 or 3 numbers in [0, 1]', True),
    ("alpha=0.1,", 'URL parameter alpha="0.1,": expected 1 or 2 numbers in [0.0001, 1]', True),
])
def test_bad_url_parameters_one_line(page, hash_, line, keep):
    """A bad parameter is one line on the page and in its title: at load (the first case, a fresh
    tab) and on a change of the fragment (the others, in MODEL's kept tab, which the next fragment
    puts right: test_fragment_change_draws_what_a_fresh_load_draws)."""
    title, status, _, _ = open_page(page, hash_, keep=keep)
    assert unescape(status) == line and title == "hbrdf view: error: " + line, (title, status)


#: Two states of a model's page that differ in every parameter the page reads from its fragment (A
#: the sun, B the map): the change A -> B leaves A's kd, eta, alpha, exposure, light, sun_el, sun_az
#: and analytic out (each must fall back to its default) and brings rotation and spp in; B -> A the
#: reverse; the material and the size change both ways. Small: each is drawn twice per backend.
FRAGMENT_A = ("readback=1&size=40&material=cc_ibiza_sunset_rgb.rgl&kd=0.8,0.2,0.1&eta=2.5&alpha=0.05,0.4"
              "&exposure=0.7&light=sun&sun_el=30&sun_az=-60&analytic=1")
FRAGMENT_B = "readback=1&size=48&material=paper_white_rgb.rgl&rotation=25&spp=8"
FRAGMENT_BAD = "readback=1&size=40&kd=2"


def shown_state(dom):
    """What a page's DOM shows of its state: the status line, the canvas's size and its read-back
    pixels, the samples line, the hbrdf edit line, the tracer scene and its command, the info lines."""
    got = {"canvas": re.search(r'<canvas id="view"[^>]*>', dom).group(0)}
    for tag, id_ in (("div", "status"), ("pre", "readback"), ("div", "samples"), ("div", "cmd"), ("pre", "scene"),
                     ("code", "render_cmd"), ("p", "info")):
        got[id_] = re.search(f'<{tag} id="{id_}">(.*?)</{tag}>', dom, re.S).group(1)
    return got


def check_fragment_changes(page, flags, backend):
    """Fragments A, a bad one, B and A again in one tab (view_harness.Tab: the page draws each change
    without loading again) against fresh loads of A and B in tabs of their own: title, status line,
    pixels and every text the page shows equal, no console line; the bad fragment is the page's one
    line and the next one puts the page right."""
    exe = chromium()
    a, b, bad = (f"backend={backend}&{h}" for h in (FRAGMENT_A, FRAGMENT_B, FRAGMENT_BAD))
    fresh_b = view_harness.open_url(exe, flags, page, b)
    tab = view_harness.Tab(view_harness.browser(exe, flags), view_harness.page_url(page, a), 180)
    try:
        fresh_a = tab.first
        for fresh in (fresh_a, fresh_b):
            assert (fresh[0], without_stall_note(fresh[2])) == ("hbrdf view: ok", []), fresh[::2]
        title, dom, console = tab.goto(bad, 180)
        line = 'URL parameter kd="2": expected 1 or 3 numbers in [0, 1]'
        assert (title, unescape(shown_state(dom)["status"])) == ("hbrdf view: error: " + line, line)
        assert shown_state(dom)["readback"] == "" and console == [], console
        for fragment, fresh in ((b, fresh_b), (a, fresh_a)):
            title, dom, console = tab.goto(fragment, 180)
            assert (title, without_stall_note(console)) == ("hbrdf view: ok", []), (fragment, title, console)
            got, want = shown_state(dom), shown_state(fresh[1])
            assert got == want, (fragment, {k: (got[k][:200], want[k][:200]) for k in got if got[k] != want[k]})
    finally:
        tab.close()


def test_fragment_change_draws_what_a_fresh_load_draws(page):
    """A change of the URL's fragment (docs/VIEWER.md, "URL parameters") shows what a fresh load of the
    new URL shows, pixel for pixel (check_fragment_changes): the redraw the tests drive their kept
    tabs with (open_page's ``keep``) forgets no parameter, and a bad one is put right."""
    check_fragment_changes(page, BROWSER_FLAGS, "webgl2")


@pytest.mark.parametrize("model_file", [MODEL, HEADS_MODEL, NEURAL_MODEL], ids=["hybrid", "heads", "neural"])
def test_fragment_shader_is_the_generated_glsl_as_es300(tmp_path, model_file):
    """The page's shader: ES 3.00 lines, then hbrdf-codegen's GLSL unchanged, then the page's main;
    glslang compiles it as a GLSL ES 3.00 fragment shader (without a browser)."""
    from hybridbrdf.codegen.main import generate

    model = load_model(model_file)
    frag = viewer.page_data(model, model_file)["fragment"]
    glsl = generate(model, "glsl", materials=[model.materials[0]], model_path=model_file)
    assert frag.startswith("#version 300 es\nprecision highp float;\nprecision highp int;\n" + glsl)
    exe = shutil.which("glslangValidator")
    if exe is None:
        pytest.skip("glslangValidator not installed (scripts/setup.sh installs glslang-tools)")
    for name, source in (("page.frag", frag), ("display.frag", DISPLAY_SHADER)):
        (tmp_path / name).write_text(source)
        r = subprocess.run([exe, "-S", "frag", str(tmp_path / name)], capture_output=True, text=True)
        assert r.returncode == 0, (name, r.stdout[-3000:])


# ---- the environment map (hybridbrdf.viewer.lighting) ----

def _irradiance_up(image):
    """Irradiance on an upward-facing surface from an equirect map (the tracer's mapping: texel rows
    from the zenith down, each of solid angle 2 pi^2 sin(theta) / (W H)), in float64."""
    h, w, _ = image.shape
    theta = np.pi * (np.arange(h) + 0.5) / h
    weight = np.clip(np.cos(theta), 0, None) * np.sin(theta) * 2 * np.pi ** 2 / (w * h)
    return np.einsum("hwc,h->c", image.astype(np.float64), weight)


@needs_renderer
def test_reduced_map_keeps_the_light():
    """A map wider than the page carries is area-averaged, rows by their solid angle: the sky's
    irradiance on an upward surface (its 1 degree sun included) is kept, and a map that fits is
    passed through untouched."""
    from hybridbrdf import _core
    from hybridbrdf.viewer import lighting as viewer_lighting

    big = dict(viewer_lighting.DEFAULT_ENVIRONMENT, resolution=[2048, 1024], sun_size_deg=0.5)
    image = np.asarray(_core.render_environment(json.dumps(big), ".", "test"))
    reduced = viewer_lighting.reduce_map(image, viewer_lighting.MAX_ENV_WIDTH)
    assert reduced.shape == (512, 1024, 3)
    np.testing.assert_allclose(_irradiance_up(reduced), _irradiance_up(image), rtol=2e-3)
    def power(im):  # radiance integrated over the sphere, every direction
        h, w, _ = im.shape
        return (im.astype(np.float64).sum(axis=(1, 2)) * np.sin(np.pi * (np.arange(h) + 0.5) / h)).sum() / (h * w)
    assert abs(power(reduced) / power(image) - 1) < 1e-3
    small = image[::4, ::4]
    assert viewer_lighting.reduce_map(small, 1024) is not small and np.array_equal(viewer_lighting.reduce_map(small, 1024), small)


@needs_renderer
def test_env_file_lights_page_and_tracer_alike(tmp_path):
    """`hbrdf view --env MAP.exr`: the page carries the map's texels and prints the map's path in its
    scene; page and tracer agree under it (an off-centre bright patch and a coloured sky)."""
    from hybridbrdf import _core

    h, w = 32, 64
    theta = np.pi * (np.arange(h) + 0.5) / h
    image = np.zeros((h, w, 3), np.float32)
    image[:] = np.where(theta[:, None, None] < np.pi / 2, [0.2, 0.3, 0.6], [0.1, 0.08, 0.05])
    image[6:9, 40:44] = [40.0, 30.0, 20.0]  # a patch light up and to one side
    env = tmp_path / "studio map.exr"
    _core.render_write_exr(image, str(env))
    out = tmp_path / "p.html"
    r = view_harness.cli("view", MODEL, "--env", str(env), "--out", str(out))
    assert r.returncode == 0, r.stderr
    material = "cc_ibiza_sunset_rgb.rgl"
    img, scene, _ = page_state(out, f"material={material}&rotation=25&spp=256", ENV_SIZE)
    assert scene["environment"] == {"type": "file", "file": str(env), "rotation_deg": 25}
    assert_matches_tracer(img, scene, max_noise=6.0)


@needs_renderer
def test_reduced_map_is_said_on_the_page(tmp_path):
    """A map wider than the page carries: the page says it lights with an averaged copy."""
    from hybridbrdf import _core

    env = tmp_path / "wide.exr"
    _core.render_write_exr(np.full((1024, 2048, 3), 0.5, np.float32), str(env))
    out = tmp_path / "p.html"
    assert view_harness.cli("view", MODEL, "--env", str(env), "--out", str(out)).returncode == 0
    title, status, dom, console = open_page(out, "light=sun&size=16")  # size=16: the test reads the page's text
    assert title == "hbrdf view: ok" and console == [], (title, status, console)
    info = unescape(re.search(r'<p id="info">(.*?)</p>', dom, re.S).group(1))
    assert "the map is area-averaged from 2048 x 1024 to 1024 x 512 texels here" in info, info


def test_env_refused_with_its_name(tmp_path):
    """A map the tracer's reader refuses: one line naming it, nothing written."""
    out = tmp_path / "p.html"
    bad = tmp_path / "broken.hdr"
    bad.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 8\n\x02")
    for env in (str(tmp_path / "missing.exr"), str(bad)):
        r = view_harness.cli("view", MODEL, "--env", env, "--out", str(out))
        assert r.returncode != 0 and not out.exists()
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and os.path.basename(env) in lines[0], r.stderr


def test_shared_pictures_are_keyed_by_what_they_read(tmp_path, tmp_path_factory):
    """view_harness.shared (the pictures and renders several tests read, made once per run): the key
    follows the bytes of every file a scene names (not only its path), a new key makes the value
    again, and a make that fails leaves nothing behind."""
    model = tmp_path / "m.safetensors"
    model.write_bytes(b"one")
    scene = {"materials": {"m": {"type": "model", "file": str(model)}}, "spp": 64}
    before = view_harness.content_key(scene)
    model.write_bytes(b"two")  # the same path, other bytes
    assert view_harness.content_key(scene) != before
    folder = tmp_path / "sv"
    folder.mkdir()
    (folder / "kd.png").write_bytes(b"a")
    textured = view_harness.content_key({"svbrdf": str(folder)})
    (folder / "kd.png").write_bytes(b"b")  # a file inside a folder the scene names
    assert view_harness.content_key({"svbrdf": str(folder)}) != textured
    made = []
    tag = f"test-{os.getpid()}-{tmp_path.name}"

    def make(value):
        made.append(value)
        return value
    assert view_harness.shared(tmp_path_factory, tag, [before], lambda: make(1)) == 1
    assert view_harness.shared(tmp_path_factory, tag, [before], lambda: make(2)) == 1 and made == [1]
    assert view_harness.shared(tmp_path_factory, tag, [view_harness.content_key(scene)], lambda: make(3)) == 3

    def fail():
        raise AssertionError("a load that was not clean")
    with pytest.raises(AssertionError):
        view_harness.shared(tmp_path_factory, tag, ["failed"], fail)
    assert view_harness.shared(tmp_path_factory, tag, ["failed"], lambda: make(4)) == 4 and made == [1, 3, 4]
