#!/usr/bin/env python3
"""One prepared measurement run on a lent GPU machine (an H100 or H200; docs: /work/.library/device):
the generated shaders' speed on a real GPU through Vulkan, a raster frame's cost (f_a only against
the hybrid), the CUDA fitting tests, and a short CUDA fit's time. Two steps, because the GPU
machine has neither glslang nor this package's extension for its Python (3.12), and no network:

    python bench/gpu_measure.py prepare          # here: writes .gpu/ (ignored, carried)
    python3 bench/gpu_measure.py device [--pairs 16777216] [--rounds 2] [--repeat 20] [--raster-repeat 50]
                                        [--skip vk,raster,ext,tests,fit | --only vk,raster]
                                        [--groups forms,half,fa,fast,textured]   # there: numpy + the runner

``prepare`` (needs the installed package, glslangValidator, build/hbrdf_vk_runner and
build/hbrdf_raster) writes .gpu/: the SPIR-V of every kernel below, 16384 cosine-weighted direction
pairs (pairs.bin) and the float64 PyTorch model's f on them (ref_*.bin), a manifest
(manifest.json), copies of the two tools, and copies of the header-only GLM and nlohmann-json
(deps/, with their CMake files) for building the extension there; for the textured kernel its
pairs with uv (tex_*.bin) and maps (tex_maps.bin); for the raster frame raster/ (bench/gpu_raster.py).
About 35 MB (its lib/ included), so that .gpu travels in the run's carry list (with .gl: the Vulkan
loader's and glvnd's .debs, ``apt-get download libvulkan1 libglvnd0 libegl1 libgl1 libglx0 libgles2
libopengl0``, for a machine without them). The tools' own libraries beyond the C/C++ runtimes
(the KTX2 reader's assimp, draco, tinyexr, minizip; hbrdf_raster's embree and TBB) travel in
.gpu/lib, those over 4 MiB xz-compressed (embree is 44 MB): ``device`` unpacks them into /tmp.

``device`` (plain python3 + numpy; nothing of hybridbrdf imported) does, each part guarded so
that one failing leaves the others to run:

1. ``vk``: the Vulkan loader from .gl/*.deb where none is installed, the NVIDIA ICD where the
   loader finds no GPU by itself; then every kernel by hbrdf_vk_runner over --pairs pairs (the
   16384 pairs tiled: a GPU gains nothing from repeated pairs, and no input has to travel),
   ``--rounds`` interleaved rounds of ``--repeat`` timed dispatches, best device time
   (Vulkan timestamps around the dispatch; the runner keeps both buffers in device memory).
   One table per question (``--groups`` picks them): ``forms``, the code forms of
   bench/shader_forms.py at 32x2 and 32x3 (ratio to today's unrolled default; the open target
   is >= 1.3x); ``half``, its packed half-precision forms (half2, half2acc8: hidden layers in
   f16vec2, two multiply-adds per HFMA2; the runner enables shaderFloat16); ``fa``, f_a alone
   and the kernel without a BRDF; ``fast``, the fast 16x2 model (material output layers)
   against the 32x2 as in bench/fast_model_speed.py (buffer and synthetic pairs); ``textured``,
   glsl/textured.comp.j2 (uv per pair, the maps read from the buffer) on pure and on mixed
   texels against the uniform material, as in bench/svbrdf_glsl_cost.py. The first round's
   outputs (the first and last 16384 pairs) are checked against the group's default form and
   the float64 reference (textured: libhybridbrdf's Svbrdf::eval on the same maps).
2. ``raster``: bench/raster_frame.py's 1280x720 frame (docs/RASTER.md "Cost": sphere on plane,
   paper_white_rgb.rgl, 256 sphere segments) drawn by hbrdf_raster, the driver chosen as for
   ``vk``: f_a only, the hybrid 32x2 and 16x2 (rgl54_fast) in the per-pixel form, and the textured
   folder of docs/RASTER.md, each at 1, 2 and 4 lights; ``--rounds`` interleaved rounds of
   ``--raster-repeat`` frames, best and median device ms (timestamps around the render pass) and
   their ratio to the f_a frame of the same light count; $OUT/gpu_raster.json, and one frame
   (the 32x2 at 2 lights) as $OUT/gpu_raster_frame.png to look at.
3. ``ext``: the extension hybridbrdf._core built for the machine's Python (no renderer, no C++
   tests: only the module), the package assembled in /tmp/hbrdf-py from python/hybridbrdf.
4. ``tests``: tests/python/test_fit_cuda.py with that package (the two-GPU test skips on one).
5. ``fit``: ``hbrdf fit synthetic:all --steps 3000 --device cuda`` (the README's main job; under
   a minute on this project's 2-core CPU machine), seconds per 1000 steps.

Check the device step here under lavapipe first (small, quick; about 10 s):
    VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json python bench/gpu_measure.py device \
        --pairs 65536 --rounds 1 --repeat 2 --skip raster,ext,tests,fit
and the raster frame (12 rows; about 20 s on one core, the ratios those of bench/raster_frame.py):
    VK_DRIVER_FILES=/usr/share/vulkan/icd.d/lvp_icd.x86_64.json LP_NUM_THREADS=1 python bench/gpu_measure.py \
        device --only raster --rounds 1 --raster-repeat 2

The shaders alone, the half forms and the textured kernel (9 kernels x 2 rounds: about a minute
of the device's time besides its start), carrying .gpu and .gl:
    python3 bench/gpu_measure.py device --only vk --groups half,textured
The raster frame alone (12 rows x 2 rounds of 50 frames, a run of the tool each: about a minute):
    python3 bench/gpu_measure.py device --only raster
"""

from __future__ import annotations

import argparse
import atexit
import functools
import glob
import json
import lzma
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

from gpu_raster import TOOL as RASTER_TOOL, prepare_raster, raster_speed

ROOT = pathlib.Path(__file__).resolve().parents[1]
GPU = ROOT / ".gpu"
BASE = 16384  # distinct pairs; --pairs must be a multiple
MODELS = {"32x2": "results/rgl54_hybrid_32x2_e09_120k_refit01.safetensors",  # bench/shader_forms.py's default
          "32x3": "results/rgl54_hybrid_32x3_10k.safetensors",
          "fast16x2": "results/rgl54_fast.safetensors"}  # bench/fast_model_speed.py's candidate
GOLDEN = "vch_golden_yellow_rgb.rgl"  # bench/fast_model_speed.py's material
FORMS = ("unrolled", "fma", "tree", "acc4", "rows4", "mat4", "pairs4")
NVIDIA_ICDS = ("/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json", "/usr/share/vulkan/icd.d/nvidia_icd.json",
               "/etc/vulkan/icd.d/nvidia_icd.json")


# ---- prepare (here) ----------------------------------------------------------------------


def prepare(args) -> int:
    sys.path.insert(0, str(ROOT / "bench"))
    sys.path.insert(0, str(ROOT / "tests" / "python"))
    import torch

    import hybridbrdf as hb
    from hybridbrdf.codegen.main import generate
    from hybridbrdf.codegen.literals import material_constant
    from hybridbrdf.evaluate.directions import cosine_hemisphere
    from shader_forms import FORMS as CODE_FORMS, HALF_FORMS, form_glsl, pairs4_shader
    from shader_kernels import eval_compute_shader
    from svbrdf_mixture import LAYERS, SIZE

    subprocess.run(["cmake", "--build", str(ROOT / "build"), "--target", "hbrdf_vk_runner", RASTER_TOOL], check=True)
    shutil.rmtree(GPU / "spv", ignore_errors=True)
    (GPU / "spv").mkdir(parents=True)
    shutil.copy2(ROOT / "build" / "hbrdf_vk_runner", GPU / "hbrdf_vk_runner")
    copy_runner_libs([ROOT / "build" / "hbrdf_vk_runner", ROOT / "build" / RASTER_TOOL], GPU / "lib")
    # GLM and nlohmann-json as installed here (headers + CMake package files, relocatable):
    # the extension's only build dependencies the GPU machine lacks.
    for src, dst in (("/usr/include/glm", "include/glm"), ("/usr/include/nlohmann", "include/nlohmann"),
                     ("/usr/share/cmake/glm", "share/cmake/glm"),
                     ("/usr/share/cmake/nlohmann_json", "share/cmake/nlohmann_json")):
        shutil.rmtree(GPU / "deps" / dst, ignore_errors=True)
        shutil.copytree(src, GPU / "deps" / dst)

    rng = np.random.default_rng(7)
    wi, wo = cosine_hemisphere(rng, BASE), cosine_hemisphere(rng, BASE)
    np.concatenate([wi, wo], axis=1).astype(np.float32).tofile(GPU / "pairs.bin")
    models = {tag: hb.load_model(ROOT / path) for tag, path in MODELS.items()}
    kernels, refs = {}, {}

    def reference(tag, material, analytic=False):
        key = f"ref_{tag}_{'fa_' if analytic else ''}{hb_safe(material)}.bin"
        if key not in refs:
            m = models[tag]
            f = (m.eval_analytic if analytic else m.eval)(wi, wo, material, dtype=torch.float64)
            np.asarray(f, dtype=np.float32).tofile(GPU / key)
            refs[key] = True
        return key

    def add(name, model_glsl, kernel, pairs_per_item=1, ref=None, same_as=None, floats=3, inputs=None):
        with tempfile.TemporaryDirectory() as d:
            (pathlib.Path(d) / "model.glsl").write_text(model_glsl)
            (pathlib.Path(d) / "w.comp").write_text(kernel)
            subprocess.run(["glslangValidator", "-V", "--target-env", "vulkan1.1", f"-I{d}", f"{d}/w.comp", "-o",
                            str(GPU / "spv" / f"{name}.spv")], check=True, capture_output=True)
        kernels[name] = {"spv": f"spv/{name}.spv", "pairs_per_item": pairs_per_item, "floats": floats * pairs_per_item,
                         "ref": ref, "same_as": same_as, "input": inputs}

    # The code forms of bench/shader_forms.py (its first material, as there).
    for tag in ("32x2", "32x3"):
        m = models[tag]
        mat = m.materials[0]
        mc, ref = material_constant(mat), reference(tag, mat)
        glsl = generate(m, "glsl", [mat])
        add(f"{tag}.unrolled", glsl, eval_compute_shader("hbrdf_eval", mc, "model.glsl"), ref=ref)
        for form in CODE_FORMS:
            add(f"{tag}.{form}", form_glsl(m, mat, form), eval_compute_shader("hbrdf_eval", mc, "model.glsl"),
                ref=ref, same_as=f"{tag}.unrolled")
        add(f"{tag}.pairs4", *pairs4_shader(glsl, mc), pairs_per_item=4, ref=ref, same_as=f"{tag}.unrolled")
        for form in HALF_FORMS:  # packed half precision (f16vec2 hidden layers; shaderFloat16)
            add(f"{tag}.{form}", form_glsl(m, mat, form), eval_compute_shader("hbrdf_eval", mc, "model.glsl"),
                ref=ref, same_as=f"{tag}.unrolled")
        if tag == "32x2":  # f_a alone, and the kernel without a BRDF (reading pairs, writing f)
            add("fa", glsl, eval_compute_shader("hbrdf_eval_analytic", mc, "model.glsl"),
                ref=reference(tag, mat, analytic=True))
            add("harness", glsl, eval_compute_shader("hbrdf_harness_only", mc, "model.glsl"))
    # bench/fast_model_speed.py: the same material in both models, buffer and synthetic pairs.
    for tag in ("32x2", "fast16x2"):
        glsl, mc = generate(models[tag], "glsl", [GOLDEN]), material_constant(GOLDEN)
        add(f"{tag}.golden", glsl, eval_compute_shader("hbrdf_eval", mc, "model.glsl"), ref=reference(tag, GOLDEN))
        add(f"{tag}.golden.syn", glsl, eval_compute_shader("hbrdf_eval", mc, "model.glsl", directions="synthetic"))
    textured_kernels(models["fast16x2"], wi, wo, add)
    glsl = generate(models["32x2"], "glsl", [GOLDEN])
    add("harness.syn", glsl, eval_compute_shader("hbrdf_harness_only", material_constant(GOLDEN), "model.glsl",
                                                 directions="synthetic"))

    forms = lambda tag: [f"{tag}.{f}" for f in FORMS]  # noqa: E731  (the default, the forms, pairs4)
    groups = [
        {"key": "forms", "title": f"code forms, 32x2 ({MODELS['32x2']}, {models['32x2'].materials[0]}), buffer pairs",
         "baseline": "32x2.unrolled", "kernels": forms("32x2")},
        {"key": "forms", "title": f"code forms, 32x3 ({MODELS['32x3']}, {models['32x3'].materials[0]}), buffer pairs",
         "baseline": "32x3.unrolled", "kernels": forms("32x3")},
        {"key": "half", "title": "packed half precision (bench/shader_forms.py half2: hidden layers in f16vec2, "
         "sums in half; half2acc8: sums of 8 half products added in float32), 32x2", "baseline": "32x2.unrolled",
         "kernels": ["32x2.unrolled", *(f"32x2.{f}" for f in HALF_FORMS)]},
        {"key": "half", "title": "packed half precision, 32x3", "baseline": "32x3.unrolled",
         "kernels": ["32x3.unrolled", *(f"32x3.{f}" for f in HALF_FORMS)]},
        {"key": "fa", "title": "f_a alone (hbrdf_eval_analytic) and the kernel without a BRDF, against the 32x2",
         "baseline": "32x2.unrolled", "kernels": ["32x2.unrolled", "fa", "harness"]},
        {"key": "fast", "title": f"fast 16x2 ({MODELS['fast16x2']}) against the 32x2, {GOLDEN}, buffer pairs",
         "baseline": "32x2.golden", "kernels": ["32x2.golden", "fast16x2.golden"]},
        {"key": "fast", "title": f"fast 16x2 against the 32x2, {GOLDEN}, synthetic pairs (made in the shader)",
         "baseline": "32x2.golden.syn", "kernels": ["32x2.golden.syn", "fast16x2.golden.syn", "harness.syn"]},
        {"key": "textured", "title": f"textured (glsl/textured.comp.j2: uv per pair, bilinear lookups of a "
         f"{SIZE}x{SIZE} weights map and layer 0's sRGB kd map, hbrdf_eval_layers + hbrdf_pdf_layers) against the "
         f"uniform material ({LAYERS[0][0]}, hbrdf_eval of its constant), {MODELS['fast16x2']}",
         "baseline": "tex.uniform", "kernels": ["tex.uniform", "tex.pure", "tex.mixed"]},
    ]
    manifest = {"base_pairs": BASE, "pairs": "pairs.bin", "kernels": kernels, "groups": groups,
                "models": MODELS, "runner": "hbrdf_vk_runner", "raster": prepare_raster(GPU)}
    (GPU / "manifest.json").write_text(json.dumps(manifest, indent=1))
    size = sum(p.stat().st_size for p in GPU.rglob("*") if p.is_file())
    print(f"wrote {GPU}: {len(kernels)} kernels, {len(manifest['raster']['rows'])} raster rows, {size / 2**20:.1f} MiB")
    return 0


# The C and C++ runtimes and the Vulkan loader are the GPU machine's own (or .gl's); every other
# library the tools link (assimp, draco, tinyexr, minizip: the runner's --texture reader's; embree and
# TBB: hbrdf_raster's scene loader's) travels in .gpu/lib.
SYSTEM_LIBS = ("linux-vdso", "ld-linux", "libc.so", "libm.so", "libstdc++", "libgcc_s", "libvulkan", "libz.so")
PACK_OVER = 4 << 20  # libraries larger than this travel xz-compressed: embree alone is 44 MB of a 64 MiB carry


def copy_runner_libs(binaries, dst: pathlib.Path):
    """The libraries ``binaries`` link beyond SYSTEM_LIBS, into ``dst``; the large ones as NAME.xz
    (runner_env unpacks them on the device, outside .gpu, so that .gpu stays small to carry)."""
    shutil.rmtree(dst, ignore_errors=True)
    dst.mkdir(parents=True)
    libs = {}
    for binary in binaries:
        ldd = subprocess.run(["ldd", str(binary)], check=True, capture_output=True, text=True).stdout
        for line in ldd.splitlines():
            m = re.match(r"\s*(\S+) => (\S+)", line)
            if m and not m.group(1).startswith(SYSTEM_LIBS):
                libs[m.group(1)] = pathlib.Path(m.group(2))
    for name, path in libs.items():
        if path.stat().st_size > PACK_OVER:
            (dst / f"{name}.xz").write_bytes(lzma.compress(path.read_bytes(), preset=6))
        else:
            shutil.copy2(path, dst / name)


def textured_kernels(model, wi, wo, add):
    """glsl/textured.comp.j2 on bench/svbrdf_mixture.py's three-layer material (bench/svbrdf_glsl_cost.py's
    kernel with weights and an sRGB kd map of layer 0: the kd the material's x 0.8-1.0), pairs at the
    centres of pure texels (layer 0 alone) and of mixed ones, and the uniform material's hbrdf_eval of
    the same generated file. The template bakes the pair count in (N); here N is the dispatch's
    invocation count instead, so that one SPIR-V serves any --pairs. References: libhybridbrdf's
    Svbrdf::eval on the saved maps (f; the pdf, the kernel's fourth float, is not compared)."""
    import torch

    from hybridbrdf import _core
    from hybridbrdf.codegen.literals import material_constant
    from hybridbrdf.codegen.main import generate
    from hybridbrdf.fit.painting import composite
    from hybridbrdf.svbrdf.asset import SVBRDF
    from hybridbrdf.svbrdf.maps import read_map
    from shader_kernels import eval_compute_shader, render_shader
    from svbrdf_mixture import LAYERS, SIZE, masks

    names = [n for n, _ in LAYERS]
    chosen = [model.materials[i] for i in sorted(model.materials.index(n) for n in names)]
    glsl = generate(model, "glsl", chosen)
    rng = np.random.default_rng(0)
    w = composite(masks())
    weights = np.concatenate([w, np.zeros((SIZE, SIZE, 1))], axis=2).astype(np.float32)
    kd = np.clip(model.tensors["materials.kd"][model.index(names[0])] * rng.uniform(0.8, 1.0, (SIZE, SIZE, 1)), 0, 1)
    with tempfile.TemporaryDirectory() as d:
        sv = SVBRDF(model, names, (SIZE, SIZE), weights, [{"kd": kd.astype(np.float32)}, {}, {}])
        sv.save(f"{d}/sv", format="png")
        stored_w, _ = read_map(f"{d}/sv/weights.png")
        stored_kd, _ = read_map(f"{d}/sv/layer0_kd.png")
        lib = _core.Svbrdf(f"{d}/sv")
        full = np.concatenate([1 - w.sum(axis=2, keepdims=True), w], axis=2).reshape(-1, 3)
        maps = np.concatenate([stored_w.ravel(), stored_kd.ravel()]).astype(np.float32)
        maps = np.concatenate([maps, np.zeros(-len(maps) % 8, np.float32)])
        maps.tofile(GPU / "tex_maps.bin")
        sets = (("pure", np.nonzero(full[:, 0] == 1)[0]), ("mixed", np.nonzero(full.max(axis=1) < 0.99)[0]))
        for label, texels in sets:
            t = np.sort(rng.choice(texels, BASE))  # texture order: neighbouring invocations, neighbouring texels
            uv = np.stack([(t % SIZE + 0.5) / SIZE, (t // SIZE + 0.5) / SIZE], axis=1).astype(np.float32)
            np.concatenate([uv, wi, wo], axis=1).astype(np.float32).tofile(GPU / f"tex_{label}.bin")
            f = lib.eval(uv, wi.astype(np.float32), wo.astype(np.float32), "bilinear")
            np.asarray(f, dtype=np.float32).tofile(GPU / f"ref_tex_{label}.bin")
    consts = [material_constant(n) for n in names] + [material_constant(names[0])]
    kernel = render_shader("textured.comp.glsl", include="model.glsl", materials=consts, n=BASE, width=SIZE,
                           height=SIZE, kd0=True)
    kernel, count = re.subn(r"const uint N = \d+u;", "#define N (gl_NumWorkGroups.x * gl_WorkGroupSize.x)", kernel)
    kernel, count2 = re.subn(r"const uint (WEIGHTS|KD0) = (.*);", r"#define \1 (\2)", kernel)
    if (count, count2) != (1, 2):
        raise SystemExit("glsl/textured.comp.j2 no longer declares N, WEIGHTS and KD0 as this script patches them")
    ref = "ref_tex_uniform.bin"
    np.asarray(model.eval(wi, wo, names[0], dtype=torch.float64), dtype=np.float32).tofile(GPU / ref)
    add("tex.uniform", glsl, eval_compute_shader("hbrdf_eval", material_constant(names[0]), "model.glsl"), ref=ref)
    for label in ("pure", "mixed"):
        add(f"tex.{label}", glsl, kernel, floats=4, ref=f"ref_tex_{label}.bin",
            inputs={"rows": f"tex_{label}.bin", "row_floats": 8, "tail": "tex_maps.bin"})


def hb_safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]", "_", name)


# ---- device (on the GPU machine; numpy only) -----------------------------------------------


def sh(cmd, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, **kw)


def section(title):
    print(f"\n===== {title}", flush=True)


def vulkan_loader():
    """The loader from .gl/*.deb (the device notes' recipe), only where none is installed. NVIDIA's
    ICD library (libGLX_nvidia) needs glvnd's libGLdispatch too: without it the loader reports
    VK_ERROR_INCOMPATIBLE_DRIVER (H200, 2026-11-30), so .gl carries glvnd's packages as well."""
    installed = sh(["ldconfig", "-p"]).stdout
    if "libvulkan.so.1" in installed and "libGLdispatch.so.0" in installed:
        print("Vulkan loader: installed")
        return
    debs = sorted(glob.glob(str(ROOT / ".gl" / "*.deb")))
    if not debs:
        raise RuntimeError("no libvulkan.so.1 and no .gl/*.deb to unpack (carry .gl)")
    for deb in debs:
        subprocess.run(["dpkg", "-x", deb, "/"], check=True)
    subprocess.run(["ldconfig"], check=True)
    print(f"Vulkan loader: unpacked {len(debs)} packages from .gl")


@functools.cache
def unpacked_libs() -> str:
    """A folder under /tmp holding .gpu/lib/*.xz unpacked (copy_runner_libs), once per process."""
    folder = tempfile.mkdtemp(prefix="hbrdf-gpu-lib-")
    atexit.register(shutil.rmtree, folder, True)
    for packed in (GPU / "lib").glob("*.xz"):
        (pathlib.Path(folder) / packed.stem).write_bytes(lzma.decompress(packed.read_bytes()))
    return folder


def runner_env():
    """The environment for the tools: .gpu/lib and its unpacked .xz libraries first on the library
    path (read at each call: choose_driver may add the driver's folder)."""
    libs = ":".join([str(GPU / "lib"), unpacked_libs(), os.environ.get("LD_LIBRARY_PATH", "")]).rstrip(":")
    return dict(os.environ, LD_LIBRARY_PATH=libs)


def run_kernel(man, name, inp, out, n_pairs, repeat, timeout=60):
    k = man["kernels"][name]
    r = sh([str(GPU / man["runner"]), str(GPU / k["spv"]), str(inp), str(out), str(n_pairs // k["pairs_per_item"]),
            str(k["floats"]), "--repeat", str(repeat)], timeout=timeout, env=runner_env())
    if r.returncode != 0:
        raise RuntimeError(f"{name}: runner exit {r.returncode}: {r.stderr.strip()[-400:]}")
    vals = dict(ln.split(" ", 1) for ln in r.stdout.splitlines() if " " in ln)
    return vals


def choose_driver(draw):
    """Keeps a VK_DRIVER_FILES set by the caller; else the loader's own choice, or the NVIDIA ICD
    where that finds no GPU (the device notes: the driver's files sit under /usr/local/nvidia).
    ``draw()``: a small run of a tool, returning the device's name."""
    def probe():
        try:
            return draw(), ""
        except Exception as e:  # noqa: BLE001
            return None, str(e)
    name, err = probe()
    if "VK_DRIVER_FILES" not in os.environ and (name is None or "llvmpipe" in name or "lavapipe" in name):
        for icd in NVIDIA_ICDS:
            if os.path.exists(icd):
                os.environ["VK_DRIVER_FILES"] = icd
                os.environ.setdefault("__EGL_VENDOR_LIBRARY_FILENAMES",
                                      "/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json")
                # The ICD names its library without a path: let the loader find the driver's folder.
                libs = [d for d in ("/usr/local/nvidia/lib64", "/usr/local/nvidia/lib") if os.path.isdir(d)]
                os.environ["LD_LIBRARY_PATH"] = ":".join(libs + [os.environ.get("LD_LIBRARY_PATH", "")]).rstrip(":")
                name, err = probe()
                break
    if name is None:
        raise RuntimeError(f"no Vulkan device: {err}")
    print(f"Vulkan device: {name}   (VK_DRIVER_FILES={os.environ.get('VK_DRIVER_FILES', 'unset')})")
    if "llvmpipe" in name:
        print("NOTE: this is lavapipe (CPU), not a GPU")
    return name


def max_rel(a, b):
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-6)))


def shader_speed(args):
    man = json.loads((GPU / "manifest.json").read_text())
    base = man["base_pairs"]
    n = args.pairs
    if n % base or n % 256:
        raise SystemExit(f"--pairs must be a multiple of {base} and of 256")
    groups = man["groups"]
    if args.groups:
        keys = set(args.groups.split(","))
        unknown = keys - {g["key"] for g in groups}
        if unknown:
            raise SystemExit(f"--groups: unknown group(s) {', '.join(sorted(unknown))} "
                             f"(this .gpu has {', '.join(sorted({g['key'] for g in groups}))})")
        groups = [g for g in groups if g["key"] in keys]
    names = list(dict.fromkeys(k for g in groups for k in g["kernels"]))
    vulkan_loader()
    work = pathlib.Path(tempfile.mkdtemp(prefix="hbrdf-vk-"))
    pairs = np.fromfile(GPU / man["pairs"], dtype=np.float32).reshape(base, 6)
    inp = work / "in.bin"
    np.tile(pairs, (n // base, 1)).tofile(inp)
    inputs = {}  # kernel -> its input file: the tiled pairs, or (textured kernels) rows of their own + maps
    for name in names:
        spec = man["kernels"][name].get("input")
        if not spec:
            inputs[name] = inp
            continue
        path = work / f"in_{spec['rows']}"
        if not path.exists():
            rows = np.fromfile(GPU / spec["rows"], dtype=np.float32).reshape(base, spec["row_floats"])
            with open(path, "wb") as f:
                np.tile(rows, (n // base, 1)).tofile(f)
                np.fromfile(GPU / spec["tail"], dtype=np.float32).tofile(f)
        inputs[name] = path
    device_name = choose_driver(lambda: run_kernel(man, "harness", inp, os.devnull, 256, 0).get("device", "?"))
    smi = sh(["nvidia-smi", "--query-gpu=name,driver_version,clocks.sm,clocks.max.sm,temperature.gpu,power.draw",
              "--format=csv,noheader"]) if shutil.which("nvidia-smi") else None
    if smi is not None:
        print(f"nvidia-smi before: {smi.stdout.strip()}")
    # Warm-up, uncounted: a few hundred dispatches so that the clocks are up before the first timing.
    t0 = time.time()
    run_kernel(man, "32x2.unrolled", inp, os.devnull, n, max(2, args.repeat * 5))
    print(f"{len(names)} kernels, {n} pairs each ({n * 24 / 2**20:.0f} MiB in, {n * 12 / 2**20:.0f} MiB out), "
          f"{args.rounds} interleaved rounds x {args.repeat} timed dispatches (warm-up {time.time() - t0:.1f} s)",
          flush=True)
    best, host, checks, failed, gpu_clock = {}, {}, {}, {}, False
    for rnd in range(args.rounds):
        for name in (names if rnd % 2 == 0 else names[::-1]):  # alternate the order: no form always first
            if name in failed or len(failed) >= 3:  # a broken driver: stop spending device time on it
                continue
            out = work / "out.bin" if rnd == 0 else os.devnull  # outputs are read once
            try:
                v = run_kernel(man, name, inputs[name], out, n, args.repeat)
            except Exception as e:  # noqa: BLE001
                failed[name] = str(e)
                print(f"FAILED {e}", flush=True)
                continue
            ms = float(v.get("best_gpu_ms", v["best_ms"]))
            gpu_clock = gpu_clock or "best_gpu_ms" in v
            best[name] = min(ms, best.get(name, ms))
            host[name] = min(float(v["best_ms"]), host.get(name, float(v["best_ms"])))
            if rnd == 0:  # the first and the last tile of pairs
                per = man["kernels"][name]["floats"] // man["kernels"][name]["pairs_per_item"]  # floats per pair
                f = [np.fromfile(out, dtype=np.float32, count=per * base, offset=o) for o in (0, 4 * per * (n - base))]
                checks[name] = np.concatenate(f).reshape(2 * base, per)
    timed_by = "Vulkan timestamps around the dispatch" if gpu_clock else "host clock around submit + wait"
    if smi is not None:
        print(f"nvidia-smi after:  {sh(smi.args).stdout.strip()}")
    for g in groups:
        section(g["title"])
        print(f"{'kernel':20s} {'best ms':>9s} {'M eval/s':>10s} {'vs ' + g['baseline']:>18s} {'host ms':>9s} "
              f"{'rel vs default':>15s} {'rel vs float64':>15s}")
        b = best.get(g["baseline"])
        for name in g["kernels"]:
            if name not in best:
                print(f"{name:20s} FAILED: {failed.get(name, 'not run')[:200]}")
                continue
            k, out = man["kernels"][name], checks.get(name)
            vs_default = vs_ref = "-"
            if out is not None and k["same_as"] in checks:
                vs_default = f"{max_rel(out, checks[k['same_as']]):.2e}"
            if out is not None and k["ref"]:  # f (3 floats); a textured kernel's 4th, the pdf, is not compared
                ref = np.fromfile(GPU / k["ref"], dtype=np.float32).reshape(base, 3)
                vs_ref = f"{max_rel(out[:, :3], np.concatenate([ref, ref])):.2e}"
            if out is not None and not np.all(np.isfinite(out)):
                vs_ref += " NON-FINITE"
            ratio = f"{b / best[name]:.3f}x" if b else "-"
            print(f"{name:20s} {best[name]:9.4f} {n / best[name] / 1e3:10.1f} {ratio:>18s} {host[name]:9.3f} "
                  f"{vs_default:>15s} {vs_ref:>15s}")
    print(f"\nbest ms: {timed_by}, best over rounds and dispatches; M eval/s = pairs / best ms; host ms: submit + "
          "fence wait; rel: max |a - b| / max(|b|, 1e-6) over the first and last 16384 pairs (float64 = the "
          "PyTorch model in float64, computed by prepare)")
    if os.environ.get("OUT"):  # the figures, for the record (the device tool brings $OUT back)
        (pathlib.Path(os.environ["OUT"]) / "gpu_vk.json").write_text(json.dumps(
            {"device": device_name, "pairs": n, "rounds": args.rounds, "repeat": args.repeat, "timed_by": timed_by,
             "best_ms": best, "host_ms": host, "failed": failed}, indent=1))
    shutil.rmtree(work, ignore_errors=True)


def build_extension():
    """hybridbrdf._core for this machine's Python: the module alone (no renderer, no C++ tests),
    GLM and nlohmann-json from .gpu/deps, pybind11 from this Python's package."""
    build, pkg = pathlib.Path("/tmp/hbrdf-ext"), pathlib.Path("/tmp/hbrdf-py")
    pybind = sh([sys.executable, "-m", "pybind11", "--cmakedir"]).stdout.strip()
    gen = ["-G", "Ninja"] if shutil.which("ninja") else []
    t0 = time.time()
    cfg = sh(["cmake", "-S", str(ROOT), "-B", str(build), *gen, "-DHBRDF_BUILD_PYTHON=ON", "-DHBRDF_BUILD_TESTS=OFF",
              "-DHBRDF_BUILD_RENDERER=OFF", f"-DCMAKE_PREFIX_PATH={GPU / 'deps'}", f"-Dpybind11_DIR={pybind}",
              f"-DPython_EXECUTABLE={sys.executable}"])
    if cfg.returncode:
        raise RuntimeError(f"cmake configure failed:\n{(cfg.stdout + cfg.stderr)[-2500:]}")
    t1 = time.time()
    bld = sh(["cmake", "--build", str(build), "--target", "_core", "-j", str(os.cpu_count() or 4)])
    if bld.returncode:
        raise RuntimeError(f"build failed:\n{(bld.stdout + bld.stderr)[-2500:]}")
    t2 = time.time()
    shutil.rmtree(pkg, ignore_errors=True)
    shutil.copytree(ROOT / "python" / "hybridbrdf", pkg / "hybridbrdf",
                    ignore=shutil.ignore_patterns("__pycache__", "*.so"))
    # The templates, where the install puts them (CMakeLists.txt: codegen/*.j2 beside the codegen package).
    shutil.copytree(ROOT / "codegen", pkg / "hybridbrdf" / "codegen", dirs_exist_ok=True,
                    ignore=shutil.ignore_patterns("*.md"))
    for so in build.glob("_core*.so"):
        shutil.copy2(so, pkg / "hybridbrdf")
    print(f"extension: configure {t1 - t0:.1f} s, build {t2 - t1:.1f} s on {os.cpu_count()} cores ({' '.join(gen) or 'make'})")
    r = sh([sys.executable, "-c", "import hybridbrdf, torch; print('hybridbrdf', hybridbrdf.__file__); "
            "print('torch', torch.__version__, 'cuda', torch.cuda.is_available(), "
            "torch.cuda.get_device_name(0) if torch.cuda.is_available() else '')"],
           env=dict(os.environ, PYTHONPATH=str(pkg)))
    print((r.stdout + r.stderr).strip()[-1500:])
    if r.returncode:
        raise RuntimeError("import hybridbrdf failed")
    return pkg


def cuda_tests(pkg):
    t0 = time.time()
    r = sh([sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", "tests/python/test_fit_cuda.py"],
           cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(pkg)), timeout=240)
    print((r.stdout + r.stderr).strip()[-3000:])
    print(f"test_fit_cuda.py: exit {r.returncode} in {time.time() - t0:.1f} s")


def cuda_fit(pkg, steps, fit_device, log_dir):
    out = pathlib.Path(tempfile.mkdtemp(prefix="hbrdf-fit-")) / "synthetic_cuda.safetensors"
    t0 = time.time()
    r = sh([sys.executable, "-m", "hybridbrdf.cli", "fit", "synthetic:all", "--steps", str(steps), "--device", fit_device,
            "--no-preview", "--out", str(out)], env=dict(os.environ, PYTHONPATH=str(pkg), TQDM_DISABLE="1"),
           timeout=180)
    wall = time.time() - t0
    text = r.stdout + r.stderr
    if log_dir:
        (pathlib.Path(log_dir) / "fit_cuda.log").write_text(text)
    # The table and the summary line only: a progress bar's carriage returns would fill the output.
    print("\n".join(ln for ln in text.splitlines() if "\r" not in ln and "evaluating" not in ln)[-2500:])
    m = re.search(r"trained (\d+) steps in ([\d.]+) s", text)
    if r.returncode or not m:
        raise RuntimeError(f"fit exit {r.returncode}")
    secs = float(m.group(2))
    print(f"{fit_device} fit, synthetic:all (8 materials, 32x3, batch 1024): {steps} steps in {secs:.1f} s = "
          f"{1000 * secs / steps:.2f} s per 1000 steps ({steps / secs:.0f} steps/s); whole command {wall:.1f} s")


PARTS = ("vk", "raster", "ext", "tests", "fit")


def device(args) -> int:
    skip = set(filter(None, args.skip.split(",")))
    only = set(filter(None, args.only.split(",")))
    for flag, keys in (("--skip", skip), ("--only", only)):
        if keys - set(PARTS):
            raise SystemExit(f"{flag}: unknown part(s) {', '.join(sorted(keys - set(PARTS)))} "
                             f"(parts: {', '.join(PARTS)})")
    if only:
        skip |= set(PARTS) - only
    log_dir = os.environ.get("OUT")  # the device tool's folder of files that come back
    pkg = None
    for key, title in (("vk", "shader speed through Vulkan"), ("raster", "a raster frame (bench/raster_frame.py's)"),
                       ("ext", "the extension for this Python"),
                       ("tests", "CUDA tests (tests/python/test_fit_cuda.py)"), ("fit", "a CUDA fit")):
        if key in skip:
            continue
        section(title)
        t0 = time.time()
        try:  # each part on its own: a failure is reported and the next part runs
            if key == "vk":
                shader_speed(args)
            elif key == "raster":
                vulkan_loader()
                raster_speed(args, GPU, choose_driver, runner_env)
            elif key == "ext":
                pkg = build_extension()
            elif pkg is None:
                print("skipped: needs the extension (part ext failed or was skipped)")
            elif key == "tests":
                cuda_tests(pkg)
            else:
                cuda_fit(pkg, args.fit_steps, args.fit_device, log_dir)
        except Exception as e:  # noqa: BLE001
            print(f"FAILED: {type(e).__name__}: {e}")
        print(f"[{key}: {time.time() - t0:.1f} s]", flush=True)
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="step", required=True)
    sub.add_parser("prepare", help="here: write .gpu/ (SPIR-V, pairs, references, raster frames, manifest, tools, "
                   "headers)")
    d = sub.add_parser("device", help="on the GPU machine: run what .gpu/ holds")
    d.add_argument("--pairs", type=int, default=1 << 24, help="pairs per dispatch (default 2^24)")
    d.add_argument("--rounds", type=int, default=2, help="interleaved rounds over the kernels (default 2)")
    d.add_argument("--repeat", type=int, default=20, help="timed dispatches per kernel and round (default 20)")
    d.add_argument("--fit-steps", type=int, default=3000)
    d.add_argument("--fit-device", default="cuda", help="the fit's --device (cpu: check the part here)")
    d.add_argument("--raster-repeat", type=int, default=50, help="raster: timed frames per row and round (default 50)")
    d.add_argument("--skip", default="", help="comma-separated parts to skip: vk, raster, ext, tests, fit")
    d.add_argument("--only", default="", help="comma-separated parts to run, the others skipped (e.g. vk,raster)")
    d.add_argument("--groups", default="", help="vk: comma-separated kernel groups to time (forms, half, fa, fast, "
                   "textured; default all), e.g. half,textured: the packed-half forms and the textured kernel")
    args = ap.parse_args()
    return prepare(args) if args.step == "prepare" else device(args)


if __name__ == "__main__":
    sys.exit(main())
