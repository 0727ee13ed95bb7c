"""Helpers shared by the Python tests: the hard-case table, parameter sets, rotation
matrices, a source with exact values, model files, the command line, a scene for the
renderer, the Mitsuba oracle and the Vulkan (lavapipe) runner.

Direction generators live in the package (hybridbrdf.evaluate.directions) and the float64
textbook oracle beside this file (textbook_reference.py): the benchmarks use them too."""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf.model.precision import half_rounded
from hybridbrdf.model.random import random_model
from hybridbrdf.sources.base import BRDFSource
from hybridbrdf.brdf.torch_brdf import eval_analytic

ROOT = pathlib.Path(__file__).resolve().parents[2]
HARD_DIRECTIONS_FILE = ROOT / "tests" / "data" / "hard_directions.json"


# ---- hard cases ----------------------------------------------------------------


def _hard_component(value, dtype) -> float:
    """A component of the table: a number, or one of the strings the table uses for
    what JSON cannot hold."""
    if not isinstance(value, str):
        return float(value)
    if value == "denorm_min":
        return float(np.finfo(dtype).smallest_subnormal)
    if value in ("nan", "inf", "-inf"):
        return float(value)
    raise ValueError(f"{HARD_DIRECTIONS_FILE}: unknown component {value!r}")


def hard_directions(dtype=np.float32) -> np.ndarray:
    """The hard directions of tests/data/hard_directions.json (shared with the C++ tests) as a
    float64 (n, 3) array; "denorm_min" is the smallest subnormal of ``dtype``, by default
    float32, the type of the C++ library, the bindings and the shaders most tests check."""
    table = json.loads(HARD_DIRECTIONS_FILE.read_text())["directions"]
    return np.array([[_hard_component(v, dtype) for v in entry["w"]] for entry in table])


def hard_pairs(dtype=np.float32):
    """Every (wi, wo) of the hard directions crossed with themselves: adds wi = wo and mirrored pairs."""
    d = hard_directions(dtype)
    n = len(d)
    wi = np.repeat(d, n, axis=0)
    wo = np.tile(d, (n, 1))
    return wi, wo


def valid_upper(w: np.ndarray, dtype=np.float32) -> np.ndarray:
    """Which directions an implementation working in `dtype` treats as usable and
    above the horizon (squared length finite and >= the smallest normal)."""
    w = w.astype(dtype)
    with np.errstate(over="ignore", invalid="ignore"):
        len2 = (w * w).sum(axis=1, dtype=dtype)
        return np.isfinite(len2) & (len2 >= np.finfo(dtype).tiny) & (w[:, 2] > 0)


# ---- parameters and directions -------------------------------------------------


PARAM_CORNERS = [
    hb.AnalyticParams(kd=[0.0, 0.5, 1.0], eta=[eta, 1.33, eta], alpha=(ax, ay))
    for ax in (hb.ALPHA_MIN, 0.01, 0.3, 1.0)
    for ay in (hb.ALPHA_MIN, 0.3, 1.0)
    for eta in (1.0, 1.5, 10.0)
]


def random_params(rng: np.random.Generator, alpha_min: float = 1e-3) -> hb.AnalyticParams:
    lo = np.log10(alpha_min)
    return hb.AnalyticParams(
        kd=rng.random(3),
        eta=1.0 + 9.0 * rng.random(3) * rng.random(3),
        alpha=10.0 ** (lo * rng.random(2)),
    )


def seeded_cosine_directions(n: int, seed: int) -> np.ndarray:
    """n cosine-distributed unit directions of the upper hemisphere, reproducible from ``seed``
    (the library's sampler on a fresh generator)."""
    from hybridbrdf.evaluate.directions import cosine_directions

    return cosine_directions(np.random.default_rng(seed), n)


def spherical(theta: float, phi: float) -> np.ndarray:
    return np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])


def rot_y(t):
    """Rotation by t about the y axis, as a matrix (independent of the modules' formulas)."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(t):
    """Rotation by t about the z axis, as a matrix."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# ---- a source with exact values ---------------------------------------------------


class AnalyticTestSource(BRDFSource):
    """A BRDFSource with exactly known values for fitting tests: f_a of the project's own
    analytic model (float64 PyTorch), optionally plus a retro-reflective bump that no
    single GGX lobe can express."""

    def __init__(self, name, params, retro=0.0):
        self.name, self.params, self.retro = name, params, retro
        self.isotropic = params.isotropic
        self.origin = "test: analytic" + (" + retro bump" if retro else "")

    def _eval(self, wi, wo):
        p = self.params
        f = eval_analytic(torch.tensor(wi), torch.tensor(wo), torch.tensor(p.kd), torch.tensor(p.eta),
                          torch.tensor(p.alpha)).numpy()
        return f + self.retro * np.exp(-20.0 * (1.0 - (wi * wo).sum(1)))[:, None]


# ---- model files ------------------------------------------------------------------


def saved_random_model(tmp_path, arch, activation="hardgelu", width=16, depth=2, output_layer="shared",
                       energy_bound=False, latent=None):
    """A random model of ``arch`` (latent ``latent``, by default 12 for the neural baseline and 4
    otherwise; materials isotropic, anisotropic, isotropic; ``output_layer`` shared or material;
    with ``energy_bound`` random energy-bound tables) with ``activation``, saved as
    tmp_path/m.safetensors and loaded back: (path, the loaded model), so that both sides of a
    comparison read one file."""
    latent = latent if latent is not None else (12 if arch == "neural" else 4)
    _, model = random_model(arch, latent=latent, width=width, depth=depth,
                            isotropic=[True, False, True], output_layer=output_layer, energy_bound=energy_bound)
    model.arch["activation"] = activation
    path = tmp_path / "m.safetensors"
    model.save(path)
    return path, hb.load_model(path)


def half_rounded_copy(model, path):
    """The same model with its layer weights rounded to binary16 (what --precision fp16 stores),
    saved to ``path`` and loaded back."""
    half_rounded(model).save(path)
    return hb.load_model(path)


# ---- the command line ----------------------------------------------------------


def run_cli(*args):
    """`hbrdf ARGS` in a fresh interpreter (the package on this interpreter's path, with its _core).
    For tests about the fresh interpreter; the others use :func:`run_cli_here`."""
    return subprocess.run([sys.executable, "-m", "hybridbrdf.cli", *args], capture_output=True, text=True)


def run_cli_here(*args):
    """`hbrdf ARGS` run by :func:`hybridbrdf.cli.main` in this process, as :func:`run_cli` reports it
    (a CompletedProcess: exit status, stdout, stderr) without a fresh interpreter's 2-4 s of
    importing torch. Output is captured at the file descriptors too, so a line the C++ library
    writes counts as it would from a child; an exception main lets escape (a child's traceback)
    propagates and fails the test."""
    import io
    import tempfile

    from hybridbrdf.cli import main

    argv = [str(a) for a in args]
    streams = io.StringIO(), io.StringIO()
    with tempfile.TemporaryFile() as fd_out, tempfile.TemporaryFile() as fd_err:
        sys.stdout.flush()
        sys.stderr.flush()
        saved = os.dup(1), os.dup(2)
        os.dup2(fd_out.fileno(), 1)
        os.dup2(fd_err.fileno(), 2)
        try:
            with contextlib.redirect_stdout(streams[0]), contextlib.redirect_stderr(streams[1]):
                try:
                    status = main(argv)
                except SystemExit as exc:  # argparse's errors, --help, sys.exit(message) as the child says it
                    status = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
                    if isinstance(exc.code, str):
                        print(exc.code, file=sys.stderr)
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
        fd_text = []
        for f in (fd_out, fd_err):
            f.seek(0)
            fd_text.append(f.read().decode(errors="replace"))
    return subprocess.CompletedProcess(["hbrdf", *argv], status, streams[0].getvalue() + fd_text[0],
                                       streams[1].getvalue() + fd_text[1])


# ---- a scene for the renderer -----------------------------------------------------


def sphere_on_floor_scene(material, floor=None, **settings):
    """A scene dict: a unit sphere of ``material`` (named "m") on an 8 x 8 floor of ``floor``
    (named "floor"; the sphere's "m" when None) under the sky, 20x16 pixels, one sample per
    pixel, three bounces on two threads. ``settings`` replace top-level keys."""
    materials = {"m": material} if floor is None else {"m": material, "floor": floor}
    s = {
        "camera": {"position": [0, 0.5, 4], "look_at": [0, 0, 0], "fov_deg": 40, "width": 20, "height": 16},
        "environment": {"type": "sky", "resolution": [64, 32]},
        "materials": materials,
        "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"},
                    {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": 8,
                     "material": "m" if floor is None else "floor"}],
        "spp": 1, "max_depth": 3, "threads": 2,
    }
    s.update(settings)
    return s


# ---- Mitsuba 3, the oracle -------------------------------------------------------


def mitsuba():
    """Mitsuba 3 with its scalar_rgb variant (the only one that runs here), or a skip."""
    mi = pytest.importorskip("mitsuba", reason="Mitsuba 3 is an oracle of these tests (test extras)")
    mi.set_variant("scalar_rgb")
    return mi


def mitsuba_f(bsdf, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """f(wi, wo), (N,3) RGB, of a loaded Mitsuba BSDF. Mitsuba's si.wi points to the viewer
    (our wo); its eval() takes the light direction (our wi) and returns f * wi.z."""
    mi = mitsuba()
    ctx = mi.BSDFContext()
    si = mi.SurfaceInteraction3f()
    out = np.empty((len(wi), 3))
    for k in range(len(wi)):
        si.wi = mi.Vector3f(*wo[k])
        v = bsdf.eval(ctx, si, mi.Vector3f(*wi[k]))
        out[k] = (v[0], v[1], v[2])
    return out / wi[:, 2:3]


def mitsuba_measured(path):
    """Mitsuba 3's ``measured`` plugin on an RGL ``.bsdf`` file: the project's RGL oracle."""
    return mitsuba().load_dict({"type": "measured", "filename": str(path)})


# ---- shaders under Vulkan (lavapipe) ----------------------------------------------


RUNNER = pathlib.Path(os.environ.get("HBRDF_VK_RUNNER", ROOT / "build" / "hbrdf_vk_runner"))
LVP_ICD = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"
# lavapipe without LLVM's optimisation passes (Mesa's GALLIVM_PERF=nopt; the code generator still runs):
# a shader test's time is mostly lavapipe compiling its one kernel for one dispatch, and the passes
# cost more than they save there (issue 56, 2026-11-29, cold Mesa cache: test_shader_conformance.py
# and test_shader_hostile.py 61.4 -> 52.8 s of CPU; the neural 8x2 WGSL loops case 28.0 -> 19.1). The
# kernels' IEEE float semantics are the SPIR-V's either way; the passes are the driver's, not the
# generated code under test. A GALLIVM_PERF the caller set is kept.
LAVAPIPE_ENV = {"VK_DRIVER_FILES": LVP_ICD, "GALLIVM_PERF": os.environ.get("GALLIVM_PERF", "nopt")}


def skip_without_vulkan(allow_module_level=False):
    """Skips unless hbrdf_vk_runner and lavapipe are there; HBRDF_REQUIRE_VULKAN=1 (scripts/test.sh)
    turns the skip into an error, so that a full test run cannot pass without the shader tests."""
    if RUNNER.exists() and os.path.exists(LVP_ICD):
        return
    if os.environ.get("HBRDF_REQUIRE_VULKAN") == "1":
        raise RuntimeError(f"shader tests need {RUNNER} (cmake --build build) and lavapipe ({LVP_ICD})")
    pytest.skip("hbrdf_vk_runner or lavapipe not available", allow_module_level=allow_module_level)


RASTER_TOOL = ROOT / "build" / "hbrdf_raster"


def skip_without_raster_tool() -> None:
    """A raster test module's guard, at its top: skips the module unless hbrdf_raster and lavapipe are
    there; under HBRDF_REQUIRE_VULKAN=1 (scripts/test.sh) an error instead, as skip_without_vulkan."""
    if RASTER_TOOL.exists() and os.path.exists(LVP_ICD):
        return
    if os.environ.get("HBRDF_REQUIRE_VULKAN") == "1":
        raise RuntimeError(f"the raster tests need {RASTER_TOOL} (cmake --build build --target hbrdf_raster) and lavapipe")
    pytest.skip("hbrdf_raster or lavapipe not available", allow_module_level=True)


@pytest.fixture(scope="module", autouse=True)
def lavapipe_without_llvm_passes():
    """hbrdf_raster's lavapipe without LLVM's optimisation passes, as every shader test's
    (LAVAPIPE_ENV, issue 56): the frames' draws are small beside compiling their shaders. A raster
    test module imports it, which makes it autouse there."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("GALLIVM_PERF", LAVAPIPE_ENV["GALLIVM_PERF"])
        yield


def compile_spirv(src: pathlib.Path, spv: pathlib.Path, target: str = "glsl", include_dir=None) -> None:
    """A compute shader (GLSL, or HLSL through glslang's HLSL front end) to SPIR-V for Vulkan 1.1;
    asserts that glslangValidator and spirv-val both accept it."""
    args = ["-V"] if target == "glsl" else ["-D", "-V", "-e", "main", "-S", "comp"]
    include = ["-I" + str(include_dir)] if include_dir is not None else []
    r = subprocess.run(["glslangValidator", *args, "--target-env", "vulkan1.1", *include, str(src), "-o", str(spv)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-3000:]
    r = subprocess.run(["spirv-val", str(spv)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def run_on_lavapipe(spv: pathlib.Path, inputs: np.ndarray, out_floats: int = 3) -> np.ndarray:
    """Runs a compute shader of glsl/ on inputs (one row of floats per invocation) under
    lavapipe with the validation layer on; returns its (n, out_floats) float32 output."""
    n = len(inputs)
    work = spv.parent
    np.ascontiguousarray(inputs, dtype=np.float32).tofile(work / "in.bin")
    r = subprocess.run([str(RUNNER), str(spv), str(work / "in.bin"), str(work / "out.bin"), str(n), str(out_floats),
                        "--validation"], capture_output=True, text=True, env=dict(os.environ, **LAVAPIPE_ENV))
    assert r.returncode == 0, r.stderr[-3000:]
    assert "llvmpipe" in r.stdout
    return np.fromfile(work / "out.bin", dtype=np.float32).reshape(n, out_floats)


@contextlib.contextmanager
def run_shared_path(tmp_path_factory, name: str):
    """A path that every pytest-xdist worker of this run shares (in the folder above each worker's
    own temporary folder: fresh for every run, so nothing of an earlier run is read), held under an
    exclusive lock for the body: the first worker makes what the path names, the others find it
    made. ``name`` must be keyed by everything the made thing depends on."""
    path = tmp_path_factory.getbasetemp().parent / name
    with open(f"{path}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        yield path


def split_effort_final_choice(monkeypatch):
    """The acquisition fit's final clusters chosen with the split clusters' screen, rows and
    candidates (cluster_fit.FINAL_* as SCREEN_ROWS, SCREEN_STEPS, CLUSTER_ROWS, CANDIDATES): for a
    test of one cluster, where nothing merges and the final choice repeats the split clusters'
    (test_acquire_fit.py's halves keep the defaults)."""
    from hybridbrdf.acquire import cluster_fit

    for final, split in (("FINAL_SCREEN_ROWS", "SCREEN_ROWS"), ("FINAL_SCREEN_STEPS", "SCREEN_STEPS"),
                         ("FINAL_ROWS", "CLUSTER_ROWS"), ("FINAL_CANDIDATES", "CANDIDATES")):
        monkeypatch.setattr(cluster_fit, final, getattr(cluster_fit, split))


def shorten_acquire_fit(monkeypatch):
    """The acquisition fit cut to what a test of a command-line flag needs: 10 cluster steps, 2
    clusters at most and none merged, no energy tables for bright kd maps. Such a test checks that the flag reaches
    the fit and its output, not what the stages buy (their own tests measure that)."""
    from hybridbrdf.acquire import cluster_fit, cluster_merge, hybrid_fit

    monkeypatch.setattr(cluster_fit, "CLUSTER_STEPS", 10)
    monkeypatch.setattr(cluster_fit, "MAX_CLUSTERS", 2)
    monkeypatch.setattr(cluster_merge, "SPLIT_CLUSTERS", 2)  # k-means makes as many
    monkeypatch.setattr(cluster_merge, "MERGE_RATIO", 0.0)  # and keeps them: a flag's test counts its clusters
    split_effort_final_choice(monkeypatch)
    monkeypatch.setattr(hybrid_fit, "bound_bright_kd", lambda model, names, kd_maps, log: (model, names))
