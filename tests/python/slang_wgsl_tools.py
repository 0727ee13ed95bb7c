"""The Slang and WGSL toolchains of the shader tests (docs/CODEGEN.md, "Slang and WGSL"):

- Slang: ``slangc`` as PyPI's ``slangtorch`` wheel ships it (``pip install --no-deps
  slangtorch==1.3.22``: only its compiler is used, not its PyTorch builder) compiles a kernel to
  SPIR-V 1.3, which spirv-val checks and hbrdf_vk_runner runs under lavapipe with the validation
  layer, like the GLSL and HLSL kernels (helpers.run_on_lavapipe);
- WGSL: PyPI's ``wgpu`` (wgpu-native, whose WGSL front end and validator is naga) on lavapipe's
  Vulkan device, in this process.

Either is missing: the tests skip, unless HBRDF_REQUIRE_VULKAN=1 (scripts/test.sh), where a
missing tool is an error, as for the other shader tests (helpers.skip_without_vulkan)."""

from __future__ import annotations

import importlib.util
import os
import pathlib
import shutil
import struct
import subprocess
import tempfile
from typing import Optional

import numpy as np
import pytest

from helpers import LAVAPIPE_ENV, skip_without_vulkan

SLANGTORCH_PIN = "slangtorch==1.3.22"
WGPU_PIN = "wgpu==0.32.0"


def _missing(what: str, install: str):
    if os.environ.get("HBRDF_REQUIRE_VULKAN") == "1":
        raise RuntimeError(f"shader tests need {what} ({install}; scripts/setup.sh installs it)")
    pytest.skip(f"{what} not available ({install})")


# ---- Slang --------------------------------------------------------------------------------------


def find_slangc() -> Optional[pathlib.Path]:
    """$SLANGC, else slangtorch's bin/slangc, else slangc on PATH; None when there is none."""
    if os.environ.get("SLANGC"):
        return pathlib.Path(os.environ["SLANGC"])
    found = importlib.util.find_spec("slangtorch")
    if found and found.submodule_search_locations:
        candidate = pathlib.Path(list(found.submodule_search_locations)[0]) / "bin" / "slangc"
        if candidate.exists():
            return candidate
    which = shutil.which("slangc")
    return pathlib.Path(which) if which else None


def skip_without_slang():
    skip_without_vulkan()
    if find_slangc() is None:
        _missing("slangc", f"pip install --no-deps {SLANGTORCH_PIN}")


def patch_opsource(spv: pathlib.Path) -> None:
    """slangc writes ``OpSource Slang`` (source language 11), which the SPIRV-Tools and Vulkan
    validation layer of Debian 12 do not know yet ("Invalid source language operand: 11"): the
    operand becomes 0 (Unknown) in place. It is a debug annotation; the code is unchanged."""
    data = spv.read_bytes()
    words = list(struct.unpack(f"<{len(data) // 4}I", data))
    assert words[0] == 0x07230203, f"{spv}: not SPIR-V"
    i = 5
    while i < len(words):
        opcode, count = words[i] & 0xFFFF, words[i] >> 16
        if opcode == 3 and words[i + 1] == 11:  # OpSource Slang
            words[i + 1] = 0
        i += max(count, 1)
    spv.write_bytes(struct.pack(f"<{len(words)}I", *words))


def compile_slang(src: pathlib.Path, spv: pathlib.Path, include_dir=None) -> None:
    """A Slang compute kernel (entry ``main``) to SPIR-V for hbrdf_vk_runner; asserts that slangc
    and spirv-val accept it. ``-lang slang``: Slang's C-like scoping (not legacy HLSL's);
    ``-profile spirv_1_3``: the runner's Vulkan 1.1; ``-O0``: the wheel has no spirv-opt (lavapipe's
    LLVM optimises anyway); ``-fvk-u-shift 0 0``: register(uN) is binding N of set 0."""
    include = [f"-I{include_dir}"] if include_dir is not None else []
    r = subprocess.run([str(find_slangc()), "-lang", "slang", str(src), "-target", "spirv", "-profile", "spirv_1_3",
                        "-stage", "compute", "-entry", "main", "-O0", "-fvk-u-shift", "0", "0", *include,
                        "-o", str(spv)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-3000:]
    patch_opsource(spv)
    r = subprocess.run(["spirv-val", "--target-env", "vulkan1.1", str(spv)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


# ---- WGSL ----------------------------------------------------------------------------------------

_DEVICE = None


def skip_without_wgpu():
    skip_without_vulkan()
    if importlib.util.find_spec("wgpu") is None:
        _missing("wgpu (wgpu-native, naga)", f"pip install {WGPU_PIN}")


def wgpu_device():
    """A wgpu device on lavapipe (the Vulkan backend only, the CPU adapter), made once."""
    global _DEVICE
    if _DEVICE is None:
        os.environ.update(LAVAPIPE_ENV)  # before wgpu makes its instance (lavapipe reads GALLIVM_PERF once)
        if not os.environ.get("XDG_RUNTIME_DIR"):  # silences libwayland's probe on stderr
            os.environ["XDG_RUNTIME_DIR"] = tempfile.mkdtemp(prefix="hbrdf-xdg-")
        import wgpu
        from wgpu.backends.wgpu_native.extras import set_instance_extras

        set_instance_extras(backends=["Vulkan"])  # before the first adapter call: no GL/EGL probing
        adapters = [a for a in wgpu.gpu.enumerate_adapters_sync() if a.info["adapter_type"] == "CPU"]
        assert adapters, "no CPU (lavapipe) adapter in wgpu"
        assert "llvmpipe" in adapters[0].info["device"], adapters[0].info
        _DEVICE = adapters[0].request_device_sync()
    return _DEVICE


def wgsl_errors(code: str) -> Optional[str]:
    """None when naga accepts ``code``, else its report (with line:column for parse errors)."""
    import wgpu

    try:
        wgpu_device().create_shader_module(code=code)
        return None
    except wgpu.GPUValidationError as e:
        return str(e)


def run_wgsl(code: str, inputs: np.ndarray, out_floats: int = 3) -> np.ndarray:
    """A WGSL kernel (``main``, 64 invocations per workgroup, binding 0 the input floats,
    binding 1 the output floats) run on ``inputs`` (one row per invocation) under lavapipe;
    returns its (n, out_floats) float32 output. A shader naga refuses fails the test with naga's
    report."""
    import wgpu

    device = wgpu_device()
    try:  # one module: naga parses and validates the code once (wgsl_errors' way, kept)
        module = device.create_shader_module(code=code)
    except wgpu.GPUValidationError as e:
        raise AssertionError(str(e)[-3000:]) from None
    n = len(inputs)
    pipeline = device.create_compute_pipeline(layout="auto", compute={"module": module, "entry_point": "main"})
    data = np.ascontiguousarray(inputs, dtype=np.float32).ravel()
    buf_in = device.create_buffer_with_data(data=data, usage=wgpu.BufferUsage.STORAGE)
    buf_out = device.create_buffer(size=4 * n * out_floats, usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
    bind = device.create_bind_group(layout=pipeline.get_bind_group_layout(0),
                                    entries=[{"binding": 0, "resource": {"buffer": buf_in}},
                                             {"binding": 1, "resource": {"buffer": buf_out}}])
    encoder = device.create_command_encoder()
    compute = encoder.begin_compute_pass()
    compute.set_pipeline(pipeline)
    compute.set_bind_group(0, bind)
    groups = (n + 63) // 64
    # one dimension of at most 65535 workgroups (4.19 M invocations): enough for these tests
    assert groups <= 65535, "run_wgsl: more than 65535 * 64 invocations"
    compute.dispatch_workgroups(max(groups, 1), 1, 1)
    compute.end()
    device.queue.submit([encoder.finish()])
    return np.frombuffer(device.queue.read_buffer(buf_out), dtype=np.float32).copy().reshape(n, out_floats)


def run_kernel(work: pathlib.Path, target: str, kernel: str, inputs: np.ndarray, out_floats: int) -> np.ndarray:
    """A rendered compute kernel of glsl/*.comp.j2 in ``target`` run on ``inputs`` under lavapipe:
    WGSL through wgpu; GLSL and HLSL through glslang, Slang through slangc, then hbrdf_vk_runner.
    The generated model code it includes must already be in ``work``. Returns (n, out_floats)."""
    from helpers import compile_spirv, run_on_lavapipe
    from shader_kernels import KERNEL_FILE

    if target == "wgsl":
        return run_wgsl(kernel, inputs, out_floats=out_floats)
    src = work / KERNEL_FILE[target]
    src.write_text(kernel)
    spv = work / "kernel.spv"
    if target == "slang":
        compile_slang(src, spv, include_dir=work)
    else:
        compile_spirv(src, spv, target, include_dir=work)
    return run_on_lavapipe(spv, inputs, out_floats=out_floats)
