"""The compute kernels that run generated shaders under Vulkan (glsl/, docs: glsl/README.md),
shared by the shader tests and the benchmarks: not part of the installed library. Benchmarks
import it with ``sys.path.insert(0, str(ROOT / "tests" / "python"))``.

Each kernel is one Jinja2 source, ``glsl/<kernel>.comp.j2``, written once for every dialect:
:func:`render_shader` renders ``<kernel>.comp.glsl``, ``.hlsl``, ``.slang`` (the HLSL form, which
slangc reads) or ``.wgsl`` from it. WGSL has no ``#include``: its kernels take the generated
code itself (``model_code``) and put it first."""

from __future__ import annotations

import pathlib
import subprocess
from typing import Optional

import jinja2

from hybridbrdf.codegen.literals import DIALECTS, material_constant

SHADER_DIR = pathlib.Path(__file__).resolve().parents[2] / "glsl"

#: What differs between the kernels' dialects: the vector types, and the generated code's own
#: declarations (let, var) and out-argument (ref: &pdf in WGSL) from hybridbrdf.codegen.literals.DIALECTS.
KERNEL_DIALECTS = {t: {"v3": DIALECTS[t]["v3"], "v2": DIALECTS[t]["v2"],
                       **{k: DIALECTS[t][k] for k in ("let", "var", "ref")}}
                   for t in ("glsl", "hlsl", "slang", "wgsl")}
#: The file name of the kernel source each dialect's compiler reads.
KERNEL_FILE = {"glsl": "wrap.comp", "hlsl": "wrap.hlsl", "slang": "wrap.slang", "wgsl": "wrap.wgsl"}


def render_shader(name: str, **values) -> str:
    """The kernel ``<kernel>.comp.<glsl|hlsl|slang|wgsl>`` rendered from ``glsl/<kernel>.comp.j2`` with
    its template variables set from ``values``; a variable left unset is an error, not an empty
    string."""
    stem, _, target = name.rpartition(".")
    if target not in KERNEL_DIALECTS or not stem.endswith(".comp"):
        raise ValueError(f"render_shader: expected <kernel>.comp.<{'|'.join(KERNEL_DIALECTS)}>, got {name!r}")
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(SHADER_DIR)), undefined=jinja2.StrictUndefined,
                             trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                             autoescape=False)
    return env.get_template(f"{stem}.j2").render(target=target, **KERNEL_DIALECTS[target], **values)


def eval_compute_shader(function: str, material_constant_name: str, include: str, target: str = "glsl",
                        n: Optional[int] = None, directions: str = "buffer", model_code: Optional[str] = None) -> str:
    """A compute shader (64 invocations per workgroup, GLSL or HLSL for glslang's HLSL front end)
    that includes the generated file ``include`` and writes ``function(wi, wo, MATERIAL)``
    (hbrdf_eval or hbrdf_eval_analytic) for pairs read from binding 0 (6 floats each) to
    binding 1 (3 floats each); with ``n`` set, invocations past the n-th pair return early.
    The kernel of spirv_size, bench/bench_inference.py and the shader conformance tests;
    its source is glsl/eval.comp.j2.

    ``directions="synthetic"`` (GLSL only, for speed measurements) makes each invocation's pair
    in the shader from a hash of its index instead of reading it (glsl/eval_synthetic.comp.j2):
    under lavapipe the per-lane buffer loads are a sizeable share of a small network's evaluation
    time (docs/CODEGEN.md), which is the harness's cost, not the BRDF's. There ``function`` may
    also be "hbrdf_harness_only" (the kernel without the BRDF).

    Slang kernels are the HLSL form; WGSL ones start with ``model_code`` (WGSL has no #include)."""
    if target not in KERNEL_DIALECTS:
        raise ValueError(f"eval_compute_shader: target must be one of {', '.join(KERNEL_DIALECTS)}, got {target!r}")
    if directions not in ("buffer", "synthetic"):
        raise ValueError(f"eval_compute_shader: directions must be buffer or synthetic, got {directions!r}")
    if directions == "synthetic":
        if target != "glsl" or n is not None:
            raise ValueError("eval_compute_shader: synthetic directions are GLSL only and take no pair count")
        return render_shader("eval_synthetic.comp.glsl", include=include, function=function,
                             material=material_constant_name, n=None)
    extra = {"model_code": model_code} if target == "wgsl" else {}
    return render_shader(f"eval.comp.{target}", include=include, function=function,
                         material=material_constant_name, n=n, **extra)


def every_function_shader(tmp_path, target, model_code, material):
    """glsl/every_function.comp.j2 around the generated ``model_code`` (written to
    tmp_path/model.<target>), as tmp_path/wrap.comp, .hlsl, .slang or .wgsl (KERNEL_FILE):
    compiling it compiles every generated function."""
    (tmp_path / f"model.{target}").write_text(model_code)
    src = tmp_path / KERNEL_FILE[target]
    extra = {"model_code": model_code} if target == "wgsl" else {}
    src.write_text(render_shader(f"every_function.comp.{target}", include=f"model.{target}",
                                 material=material_constant(material), **extra))
    return src


def spirv_size(glsl_code: str, material_constant_name: str, workdir) -> int:
    """Bytes of the SPIR-V (glslangValidator -V, optimised with -Os) of a compute shader
    that evaluates ``hbrdf_eval`` for one material of the given generated GLSL."""
    workdir = pathlib.Path(workdir)
    (workdir / "probe_model.glsl").write_text(glsl_code)
    src = workdir / "probe.comp"
    src.write_text(eval_compute_shader("hbrdf_eval", material_constant_name, "probe_model.glsl"))
    spv = workdir / "probe.spv"
    r = subprocess.run(["glslangValidator", "-V", "-Os", "--target-env", "vulkan1.1", "-I" + str(workdir), str(src),
                        "-o", str(spv)], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"glslangValidator failed: {r.stdout[-2000:]}")
    return spv.stat().st_size
