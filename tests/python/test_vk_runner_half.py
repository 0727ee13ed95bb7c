"""hbrdf_vk_runner enables shaderFloat16 where the device has it (bench/shader_forms.py's packed-half
forms, measured on a GPU by bench/gpu_measure.py): a kernel with half arithmetic runs under lavapipe
with the validation layer on (which rejects the Float16 capability on a device created without the
feature) and computes in half, against numpy's binary16 arithmetic."""

from __future__ import annotations

import numpy as np

from helpers import compile_spirv, run_on_lavapipe, skip_without_vulkan

KERNEL = """#version 450
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer In { float data_in[]; };
layout(std430, binding = 1) writeonly buffer Out { float data_out[]; };
void main() {
    uint i = gl_GlobalInvocationID.x;
    f16vec2 a = f16vec2(float16_t(data_in[3u * i]), float16_t(data_in[3u * i + 1u]));
    f16vec2 s = a + f16vec2(float16_t(data_in[3u * i + 2u]));
    data_out[3u * i] = float(s.x);
    data_out[3u * i + 1u] = float(s.y);
    data_out[3u * i + 2u] = float(a.x * a.y);
}
"""


def test_runner_runs_half_arithmetic(tmp_path):
    skip_without_vulkan()
    (tmp_path / "h.comp").write_text(KERNEL)
    compile_spirv(tmp_path / "h.comp", tmp_path / "h.spv")
    rng = np.random.default_rng(3)
    x = rng.uniform(-4, 4, (256, 3)).astype(np.float32)
    x[0] = (1.0, 3.0, 2.0 ** -11)  # 1 + 2^-11 is a tie in half: rounds to 1 (float32 keeps it)
    got = run_on_lavapipe(tmp_path / "h.spv", x)
    h = x.astype(np.float16)
    want = np.stack([h[:, 0] + h[:, 2], h[:, 1] + h[:, 2], h[:, 0] * h[:, 1]], axis=1).astype(np.float32)
    assert got[0, 0] == 1.0
    np.testing.assert_array_equal(got, want)
