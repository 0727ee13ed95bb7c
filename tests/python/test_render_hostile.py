"""Hostile input and interruption for the renderer (docs/RENDERING.md, "Cancellation" and "Limits
and validation"): Ctrl-C and SIGTERM stop ``hbrdf render`` and ``hybridbrdf.render.tracer.render()`` within
about one tile and leave the previous output files untouched; sizes beyond the limits, negative or
non-finite values, unwritable outputs and bad measured sources are one-line errors, raised before any
rendering (the C++ side of the same rules: tests/cpp/test_render_hostile.cpp)."""

import contextlib
import copy
import json
import os
import re
import select
import signal
import struct
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from hybridbrdf import _core
from hybridbrdf.render import tracer as hr

from helpers import run_cli, sphere_on_floor_scene

pytestmark = pytest.mark.skipif(not getattr(_core, "HAVE_RENDERER", False), reason="built without the renderer")


def scene(**settings):
    """A sphere on a floor, both of one analytic material, under the sky, 20x16 pixels."""
    return sphere_on_floor_scene({"type": "analytic", "kd": 0.5, "eta": 1.5, "alpha": 0.3}, **settings)


def slow_scene():
    """Minutes of work (64x64 pixels, 2^20 samples each) in 16 tiles: nothing finishes by accident."""
    s = scene(spp=1 << 20, max_depth=4)
    s["camera"].update(width=64, height=64)
    return s


def old_outputs(tmp_path):
    """Existing output files with known bytes, as a previous render would have left them."""
    exr, png = tmp_path / "o.exr", tmp_path / "o.png"
    exr.write_bytes(b"previous exr")
    png.write_bytes(b"previous png")
    return exr, png


def only_outputs_left(tmp_path, exr, png):
    """The old files' bytes, and no temporary left behind."""
    assert exr.read_bytes() == b"previous exr" and png.read_bytes() == b"previous png"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["o.exr", "o.png", "s.json"])


# ---- cancellation ----------------------------------------------------------------


def wait_for(stream, text: str, timeout: float) -> str:
    """Read `stream` (unbuffered) until `text` appears; what was read."""
    seen, deadline = b"", time.monotonic() + timeout
    while text.encode() not in seen:
        left = deadline - time.monotonic()
        assert left > 0, f"no {text!r} within {timeout} s: {seen[-500:]!r}"
        if select.select([stream], [], [], left)[0]:
            chunk = os.read(stream.fileno(), 4096)
            assert chunk, f"the process ended before {text!r}: {seen[-2000:]!r}"
            seen += chunk
    return seen.decode(errors="replace")


@pytest.mark.parametrize("sig, status, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_a_signal_stops_hbrdf_render_within_a_tile_and_keeps_the_old_files(tmp_path, sig, status, word):
    exr, png = old_outputs(tmp_path)
    path = tmp_path / "s.json"
    path.write_text(json.dumps(slow_scene()))
    # SIGINT as an interactive shell leaves it (a background job may have inherited SIG_IGN).
    proc = subprocess.Popen([sys.executable, "-m", "hybridbrdf.cli", "render", str(path), "-o", str(exr), "--png", str(png)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        seen = wait_for(proc.stderr, "render [", timeout=120)  # the render has started: the bar is drawn
        time.sleep(1.0)  # inside the first tiles, which take minutes
        sent = time.monotonic()
        proc.send_signal(sig)
        _, rest = proc.communicate(timeout=30)
        elapsed = time.monotonic() - sent
    finally:
        proc.kill()
    stderr = seen + rest.decode(errors="replace")
    assert proc.returncode == status, stderr[-2000:]
    assert elapsed < 5.0  # measured ~0.5 s, interpreter exit included; the render itself takes minutes
    assert stderr.splitlines()[-1] == f"hbrdf render: {word}, nothing written"
    assert "Traceback" not in stderr
    only_outputs_left(tmp_path, exr, png)


@pytest.fixture
def sigint_raises():
    """Python's own SIGINT handler for the test (a test run started in the background inherits SIG_IGN)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def interrupt_in(seconds: float) -> dict:
    """SIGINT to this process after `seconds`, from a timer thread; returns {'at': monotonic time}."""
    sent = {}

    def fire():
        time.sleep(seconds)
        sent["at"] = time.monotonic()
        os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=fire, daemon=True).start()
    return sent


@pytest.mark.parametrize("material", ["analytic", "measured"])
def test_ctrl_c_raises_keyboard_interrupt_from_render_and_writes_nothing(tmp_path, material, sigint_raises):
    # A measured material runs Python callbacks on the worker threads: they share the GIL with the
    # thread that watches for signals.
    (tmp_path / "s.json").write_text("{}")
    exr, png = old_outputs(tmp_path)
    s = slow_scene()
    if material == "measured":
        s["materials"]["m"] = {"type": "measured", "source": "synthetic:gold"}
    sent = interrupt_in(1.0)
    with pytest.raises(KeyboardInterrupt):
        hr.render(s, out=str(exr), png=str(png))
    assert time.monotonic() - sent["at"] < 1.0  # measured: 6-12 ms
    only_outputs_left(tmp_path, exr, png)


def test_ctrl_c_stops_a_tabulated_sampler_build(sigint_raises):
    # Building a tabulated sampler from a Python reader takes ~10 s; it checks the flag per batch.
    s = scene(sampler="tabulated")
    s["materials"]["m"] = {"type": "measured", "source": "synthetic:gold"}
    sent = interrupt_in(0.5)
    with pytest.raises(KeyboardInterrupt):
        hr.render(s)
    assert time.monotonic() - sent["at"] < 1.0  # measured: ~40 ms


def test_keyboard_interrupt_in_a_measured_callable_cancels_the_render():
    def factory(source):
        def f(wi, wo):
            raise KeyboardInterrupt
        return f

    s = scene()
    s["materials"]["m"] = {"type": "measured", "source": "synthetic:x"}
    with pytest.raises(KeyboardInterrupt):
        hr.render(s, measured_factory=factory)


# ---- sizes -------------------------------------------------------------------------


def fails_fast(s, match, **kwargs):
    """render() raises ValueError matching `match`, in well under a second (nothing was allocated)."""
    t0 = time.monotonic()
    with pytest.raises(ValueError, match=match):
        hr.render(s, **kwargs)
    assert time.monotonic() - t0 < 0.5


def _tabulated_scene(n, resolution_deg):
    """n anisotropic materials (alpha x != y: 210 MB of tables each at 1 degree), tabulated sampling."""
    s = scene(sampler="tabulated", tabulated_resolution_deg=resolution_deg)
    s["camera"].update(width=4, height=4)
    s["materials"] = {f"m{i}": {"type": "analytic", "alpha": [0.1, 0.3]} for i in range(n)}
    for obj in s["objects"]:
        obj["material"] = "m0"
    return s


@contextlib.contextmanager
def _peak_resident_growth(growth):
    """Fills ``growth[0]`` with how far this process's peak resident memory rose above its resident
    memory at the start of the block (the peak is reset first: /proc/self/clear_refs, Linux)."""
    def status(key):
        with open("/proc/self/status") as fh:
            return next(int(line.split()[1]) * 1024 for line in fh if line.startswith(key + ":"))

    with open("/proc/self/clear_refs", "w") as fh:
        fh.write("5")
    start = status("VmRSS")
    try:
        yield
    finally:
        growth[0] = status("VmHWM") - start


def test_tabulated_tables_over_the_budget_are_refused_before_any_is_built(tmp_path):
    # 100 materials at 1 degree would be ~21 GB and half an hour of building: refused at
    # load, from the table sizes, before the first table: within half a second, and the peak
    # resident memory rises by less than 100 MB (one table alone is 210 MB).
    path = tmp_path / "many.json"
    path.write_text(json.dumps(_tabulated_scene(100, 1)))
    growth = [None]
    with _peak_resident_growth(growth):
        fails_fast(str(path), "^" + re.escape(
            f"{path}: sampler: the tabulated sampler's tables for 100 materials (100 anisotropic) at 1 degree need "
            "~21 GB, above the budget of 1.1 GB (1 GiB) for all of a scene's tables; use fewer materials, a coarser "
            "tabulated_resolution_deg (3 fits) or another sampler") + "$")
    assert growth[0] < 100 << 20, growth
    r = run_cli("render", str(path), "-o", str(tmp_path / "o.exr"), "--quiet")
    assert r.returncode == 1 and "Traceback" not in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith(f"hbrdf render: error: {path}: sampler: the tabulated sampler's tables"), r.stderr
    # 6 at 1 degree is just over (1.26 GB), 5 just inside (1.05 GB): the advice is then 2 degrees.
    fails_fast(_tabulated_scene(6, 1), r"^<scene dict>: sampler: .* for 6 materials \(6 anisotropic\) at 1 degree "
                                       r"need ~1.3 GB, .*a coarser tabulated_resolution_deg \(2 fits\)")


def test_tabulated_tables_inside_the_budget_still_load():
    # 100 anisotropic materials at 18 degrees: ~1.6 kB of tables each, rendered.
    _, stats = hr.render(_tabulated_scene(100, 18))
    assert stats["sampler"] == "tabulated"
    assert len(stats["sampler_memory_bytes"]) == 100
    assert all(0 < b < 10000 for b in stats["sampler_memory_bytes"].values())


def test_huge_films_and_skies_are_errors_with_an_estimate_not_memory_errors():
    s = scene()
    s["camera"].update(width=100000, height=100000)
    fails_fast(s, r"^<scene dict>: camera: width x height = 100000 x 100000 = 10000000000 pixels need ~120 GB of film "
                  r"\(limit 134217728 pixels, e.g. 16384 x 8192\)$")
    fails_fast(scene(), r"camera: width x height = 200000 x 100000 .* need ~240 GB of film", width=200000, height=100000)
    s = scene(environment={"type": "sky", "resolution": [100000, 50000]})
    fails_fast(s, r"^<scene dict>: environment.resolution: 100000 x 50000 = 5000000000 pixels need ~140 GB")
    s = scene(environment={"type": "sky", "resolution": [64.5, 32]})
    fails_fast(s, r"environment.resolution\[0\]: expected an integer, got 64.5")


@pytest.mark.parametrize("key, value, message", [
    ("spp", 4294967297, "spp: must be <= 2147483647, got 4294967297"),
    ("max_depth", -1, "max_depth: must be >= 0, got -1"),
    ("threads", 4096, "threads: must be <= 1024, got 4096"),
])
def test_integer_settings_are_bounded_not_narrowed(key, value, message):
    fails_fast(scene(**{key: value}), f"^<scene dict>: {message}$")  # in the scene
    with pytest.raises(ValueError, match=f"^{message}$"):  # as an override
        hr.render(scene(), **{key: value})


def test_integer_flags_are_bounded_not_narrowed(tmp_path):
    path = tmp_path / "s.json"
    path.write_text(json.dumps(scene()))
    r = run_cli("render", str(path), "-o", str(tmp_path / "o.exr"), "--spp", "4294967297")
    assert r.returncode == 1 and r.stderr == "hbrdf render: error: spp: must be <= 2147483647, got 4294967297\n"
    assert not (tmp_path / "o.exr").exists()


# ---- values ------------------------------------------------------------------------


@pytest.mark.parametrize("environment, message", [
    ({"type": "sky", "scale": -1}, "environment.scale: must be >= 0, got -1"),
    ({"type": "constant", "radiance": [1, -1, 1]}, r"environment.radiance\[1\]: must be >= 0, got -1"),
    ({"type": "constant", "radiance": 1, "scale": 1e300}, r"environment.scale: must be within \+-3.40282e\+38, got 1e\+300"),
    ({"type": "constant", "radiance": 1e30, "scale": 1e30}, "environment: scale: 1e\\+30 x the brightest texel"),
    ({"type": "sky", "ground_albedo": -0.2}, "environment.ground_albedo: must be >= 0, got -0.2"),
    ({"type": "sky", "sun_irradiance": [5, 5, -5]}, r"environment.sun_irradiance\[2\]: must be >= 0, got -5"),
    ({"type": "sky", "sky_intensity": -1}, "environment.sky_intensity: must be >= 0, got -1"),
    ({"type": "sky", "turbidity": 0}, r"environment.turbidity: must be in \[1, 10\], got 0"),
    ({"type": "sky", "sun_size_deg": 1e-30}, "environment.sun_size_deg: is too small for sun_irradiance"),
])
def test_negative_and_overflowing_radiances_are_errors_naming_the_key(environment, message):
    fails_fast(scene(environment=environment), f"^<scene dict>: {message}")


def test_python_nan_and_inf_are_rejected():
    # json.dumps writes NaN/Infinity, which is not JSON: the scene is refused, not rendered black.
    for bad in (float("nan"), float("inf")):
        s = scene()
        s["environment"]["scale"] = bad
        with pytest.raises(ValueError, match=r"^<scene dict>: invalid JSON"):
            hr.render(s)
    with pytest.raises(ValueError, match=r"^neural_min_throughput: expected a finite number, got nan$"):
        hr.render(scene(), neural_min_throughput=float("nan"))


def test_malformed_meshes_are_errors_not_crashes(tmp_path):
    # An out-of-range face index crashed the process in assimp's post-processing (SIGSEGV).
    (tmp_path / "bad.ply").write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                      "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                      "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    s = scene()
    s["objects"].append({"type": "mesh", "file": "bad.ply", "material": "m"})
    (tmp_path / "s.json").write_text(json.dumps(s))
    with pytest.raises(ValueError, match=r"s\.json: objects\[2\]\.file: .*bad\.ply: cannot read the mesh: .*out of range"):
        hr.render(str(tmp_path / "s.json"))


# ---- outputs -----------------------------------------------------------------------


def unwritable_folder(tmp_path):
    """A folder in which files cannot be created, even by root (who ignores permission bits), or a skip."""
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    for candidate in (str(ro), "/sys", "/proc"):
        try:
            with open(os.path.join(candidate, "probe.tmp"), "wb"):
                pass
            os.remove(os.path.join(candidate, "probe.tmp"))
        except OSError:
            return candidate
    pytest.skip("no unwritable folder on this machine")


def test_unusable_outputs_fail_before_the_render(tmp_path):
    s = slow_scene()  # minutes of work: the errors must come before it
    (tmp_path / "file").write_text("a file")
    fails_fast(s, f"^{tmp_path}: is a folder, expected a file name$", out=str(tmp_path))
    fails_fast(s, f"^{tmp_path}/file/o.exr: {tmp_path}/file is a file, not a folder$", out=str(tmp_path / "file" / "o.exr"))
    fails_fast(s, f"^{tmp_path}/file/a/o.png: cannot create the folder {tmp_path}/file/a \\(Not a directory\\)$",
               png=str(tmp_path / "file" / "a" / "o.png"))
    folder = unwritable_folder(tmp_path)
    fails_fast(s, f"^{folder}/o.exr: cannot create files in {folder} \\(", out=f"{folder}/o.exr")
    fails_fast(s, "the EXR and the PNG output are the same file", out=str(tmp_path / "x"), png=str(tmp_path / "x"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "ro"]


def test_cli_output_errors_are_one_line_and_come_before_the_render(tmp_path):
    path = tmp_path / "s.json"
    path.write_text(json.dumps(slow_scene()))
    t0 = time.monotonic()
    r = run_cli("render", str(path), "-o", str(tmp_path), "--quiet")
    # The interpreter start (importing torch) is most of this; the render would take minutes.
    assert time.monotonic() - t0 < 30
    assert r.returncode == 1 and r.stderr == f"hbrdf render: error: {tmp_path}: is a folder, expected a file name\n"


# ---- measured sources --------------------------------------------------------------


@pytest.mark.parametrize("write, problem", [
    (None, "missing.binary: no such file"),
    (lambda p: p.write_bytes(struct.pack("<3i", 90, 90, 180) + bytes(100)), "missing.binary: truncated MERL file"),
])
def test_bad_measured_sources_are_one_line_naming_scene_key_and_problem(tmp_path, write, problem):
    if write:
        write(tmp_path / "missing.binary")
    s = scene()
    s["materials"]["m"] = {"type": "measured", "source": "missing.binary"}
    path = tmp_path / "s.json"
    path.write_text(json.dumps(s))
    r = run_cli("render", str(path), "-o", str(tmp_path / "o.exr"), "--quiet")
    assert r.returncode == 1
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr and "At:" not in r.stderr
    assert r.stderr.startswith(f"hbrdf render: error: {path}: materials.m.source: {tmp_path}/{problem}")


def test_a_failing_measured_callable_names_the_scene_and_the_material():
    def factory(source):
        def f(wi, wo):
            raise ZeroDivisionError("reader exploded\nsecond line")
        return f

    s = scene()
    s["materials"]["m"] = {"type": "measured", "source": "synthetic:x"}
    with pytest.raises(hr.RenderMaterialError) as info:
        hr.render(s, measured_factory=factory)
    assert isinstance(info.value, RuntimeError)
    assert str(info.value) == ("<scene dict>: materials.m: measured material 'synthetic:x': eval(wi, wo) raised "
                               "ZeroDivisionError: reader exploded second line")


def test_a_measured_factory_error_is_one_line():
    def factory(source):
        raise OSError(2, "No such file or directory", source)

    s = scene()
    s["materials"]["m"] = {"type": "measured", "source": "x.bsdf"}
    with pytest.raises(ValueError) as info:
        hr.render(s, measured_factory=factory)
    assert "\n" not in str(info.value)
    assert str(info.value).startswith("<scene dict>: materials.m.source: [Errno 2] No such file or directory: ")


# ---- outputs that are inputs, special and deeply nested scene files --------------


def _scene_with_files(tmp_path):
    """A scene file naming a model file, a measured source and a mesh (files that exist)."""
    from hybridbrdf.model.random import random_model

    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    model.save(tmp_path / "m.safetensors")
    (tmp_path / "gold.bsdf").write_bytes(b"measured")
    (tmp_path / "bunny.obj").write_text("v 0 0 0\n")
    s = slow_scene()  # minutes of work; the mesh is malformed, so without the check the load fails instead
    s["materials"]["n"] = {"type": "model", "file": "m.safetensors", "material": "mat-0"}
    s["materials"]["g"] = {"type": "measured", "source": "gold.bsdf"}
    s["objects"].append({"type": "mesh", "file": "bunny.obj", "material": "n"})
    path = tmp_path / "sc.json"
    path.write_text(json.dumps(s))
    return path


def _contents(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.mark.parametrize("flag", ["out", "png"])
@pytest.mark.parametrize("target", ["sc.json", "m.safetensors", "gold.bsdf", "bunny.obj", "link", "sub/../m.safetensors"])
def test_render_refuses_to_write_over_its_inputs(tmp_path, flag, target):
    scene_path = _scene_with_files(tmp_path)
    (tmp_path / "sub").mkdir()
    if target == "link":  # a symlink to the model: followed, as the write would follow it
        (tmp_path / "link").symlink_to(tmp_path / "m.safetensors")
    before = _contents(tmp_path)
    out = str(tmp_path / target)
    named = {"sc.json": str(scene_path), "link": str(tmp_path / "m.safetensors"),
             "sub/../m.safetensors": str(tmp_path / "m.safetensors")}.get(target, str(tmp_path / target))
    what = "EXR" if flag == "out" else "PNG"
    fails_fast(str(scene_path), f"^{re.escape(out)}: the {what} output names the input {re.escape(named)}; "
                                f"writing it would destroy that input$", **{flag: out})
    assert _contents(tmp_path) == before


def test_exr_and_png_through_a_symlink_are_the_same_file(tmp_path):
    (tmp_path / "b.png").symlink_to(tmp_path / "a.exr")
    s = scene()
    s["materials"]["m"] = {"type": "velvet"}  # without the check the library's own error comes instead
    fails_fast(s, "the EXR and the PNG output are the same file",
               out=str(tmp_path / "a.exr"), png=str(tmp_path / "b.png"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.png"]


def test_hbrdf_render_over_its_scene_is_one_line_and_leaves_it(tmp_path):
    scene_path = _scene_with_files(tmp_path)
    before = _contents(tmp_path)
    r = run_cli("render", str(scene_path), "-o", str(scene_path), "--quiet")
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert r.stderr == (f"hbrdf render: error: {scene_path}: the EXR output names the input {scene_path}; "
                        f"writing it would destroy that input\n"), r.stderr
    assert _contents(tmp_path) == before


def test_a_scene_nested_5000_levels_is_one_line(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text('{"description": ' + "[" * 5000 + "]" * 5000 + "}")  # 10 KB: RecursionError before
    fails_fast(str(path), f"^{re.escape(str(path))}: scene file: JSON nested deeper than 64 levels$")
    r = run_cli("render", str(path), "-o", str(tmp_path / "o.exr"), "--quiet")
    assert r.returncode == 1 and r.stderr == (f"hbrdf render: error: {path}: scene file: JSON nested deeper than "
                                              f"64 levels\n"), r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["deep.json"]


# ---- environment maps and meshes that lie, or are not files --------------------

HDR_HEADER = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n"


def hdr_flat(width, height, rgbe=(128, 128, 128, 129)):
    """A Radiance file of flat pixels (stb_image reads widths below 8 so); default texel 1.0."""
    return HDR_HEADER + b"-Y %d +X %d\n" % (height, width) + bytes(rgbe) * (width * height)


def hdr_rle(width, height, rgbe=(128, 128, 128, 129)):
    """A run-length encoded Radiance file (8 <= width < 32768): each channel one run per scanline."""
    assert 8 <= width <= 127
    line = bytes([2, 2, width >> 8, width & 255]) + b"".join(bytes([128 + width, c]) for c in rgbe)
    return HDR_HEADER + b"-Y %d +X %d\n" % (height, width) + line * height


def render_with_environment(tmp_path, env_bytes=None, env_name="e.hdr", mesh=None):
    """`hbrdf render` of scene() under the map `env_bytes` (written to env_name unless None: then
    env_name must exist already), with an extra mesh object `mesh` if given; over old outputs."""
    if env_bytes is not None:
        (tmp_path / env_name).write_bytes(env_bytes)
    s = scene(spp=16)
    s["environment"] = {"type": "file", "file": env_name}
    if mesh:
        s["objects"].append({"type": "mesh", "file": mesh, "material": "m"})
    (tmp_path / "s.json").write_text(json.dumps(s))
    exr, png = tmp_path / "o.exr", tmp_path / "o.png"
    exr.write_bytes(b"previous exr")
    png.write_bytes(b"previous png")
    t0 = time.monotonic()
    # A timeout, so that a render blocked on a FIFO fails the test rather than hangs it.
    r = subprocess.run([sys.executable, "-m", "hybridbrdf.cli", "render", str(tmp_path / "s.json"), "-o", str(exr),
                        "--png", str(png), "--quiet"], capture_output=True, text=True, timeout=120)
    assert exr.read_bytes() == b"previous exr" and png.read_bytes() == b"previous png"
    return r, time.monotonic() - t0


def one_line_error(r, pattern):
    assert r.returncode == 1, (r.returncode, r.stderr[-2000:])
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert re.search(pattern, r.stderr), r.stderr


@pytest.mark.parametrize("label, data, problem", [
    # 52 bytes declaring 4096 x 32768 texels (the limit itself) and no pixels: stb_image allocated
    # 3.9 GB and rendered a black sky with exit 0.
    ("header only", HDR_HEADER + b"-Y 4096 +X 32768\n", "truncated: scanline 1 of 4096"),
    ("flat, cut in scanline 3", hdr_flat(4, 4)[:-(4 * 4 + 3)], "truncated: scanline 3 of 4"),
    ("flat, one byte short", hdr_flat(4, 4)[:-1], "truncated: scanline 4 of 4"),
    ("run-length, cut in scanline 2", hdr_rle(16, 2)[:-5], "truncated: scanline 2 of 2"),
    ("run-length, no data", hdr_rle(16, 2)[:-24], "truncated: scanline 1 of 2"),
])
def test_a_truncated_hdr_environment_is_an_error_not_black_texels(tmp_path, label, data, problem):
    r, seconds = render_with_environment(tmp_path, data)
    one_line_error(r, re.escape(f"s.json: environment.file: {tmp_path}/e.hdr: {problem}") + "$")
    assert seconds < 60, (label, seconds)


def test_complete_hdr_files_still_read_exactly(tmp_path):
    for name, data in (("flat.hdr", hdr_flat(4, 4, (128, 64, 32, 130))), ("rle.hdr", hdr_rle(16, 2, (128, 64, 32, 130)))):
        (tmp_path / name).write_bytes(data)
        img = _core.render_read_image(str(tmp_path / name))
        assert np.array_equal(img, np.broadcast_to(np.float32([2.0, 1.0, 0.5]), img.shape)), name


def test_an_environment_too_bright_for_float32_sums_is_refused(tmp_path):
    """Texels of 1.69e38 (RGBE 255 255 255 255, the format's largest) passed the old check of
    scale x brightest texel; at 16 spp every pixel was +Inf, written with exit 0."""
    r, _ = render_with_environment(tmp_path, hdr_flat(4, 4, (255, 255, 255, 255)))
    one_line_error(r, re.escape(f"s.json: environment: {tmp_path}/e.hdr: the brightest texel x scale is 1.69") +
                   r".*, above the limit 1e\+20 \(a pixel's samples would overflow float32\)$")


@pytest.mark.parametrize("kind", ["environment", "mesh"])
def test_fifo_and_device_inputs_are_refused_before_opening(tmp_path, kind):
    """A FIFO blocks open() until a writer comes (hbrdf render hung); /dev/zero never ends."""
    fifo = tmp_path / "pipe.hdr"
    os.mkfifo(fifo)
    (tmp_path / "e.hdr").write_bytes(hdr_flat(4, 4))
    for target, words in ((str(fifo), "is a FIFO, not a regular file"), ("/dev/zero", "is a character device, not a regular file")):
        if kind == "environment":
            r, seconds = render_with_environment(tmp_path, None, env_name=target)
        else:
            r, seconds = render_with_environment(tmp_path, None, mesh=target)
        one_line_error(r, re.escape(f"{target}: {words}") + "$")
        assert seconds < 60, (kind, target, seconds)
