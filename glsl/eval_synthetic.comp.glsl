{# Jinja2 template, rendered by hybridbrdf.codegen.eval_compute_shader(..., directions="synthetic")
   (docs: glsl/README.md). include: the generated model file; function: hbrdf_eval,
   hbrdf_eval_analytic or hbrdf_harness_only; material: an HBRDF_MATERIAL_<NAME> constant.
   Speed only: the pairs are made in the shader, so nothing is read from binding 0. #}
#version 450
#extension GL_GOOGLE_include_directive : require
{% include "compute_io.glsl" %}
#include "{{ include }}"
{% if function == "hbrdf_harness_only" %}
// The kernel without the BRDF: what the harness itself costs per pair.
vec3 hbrdf_harness_only(vec3 wi, vec3 wo, HbrdfMaterial m) { return wi * wo + m.kd; }
{% endif %}
// 32 well-mixed bits of an index (the PCG hash of Jarzynski & Olano 2020, "Hash Functions for
// GPU Rendering"): a handful of integer operations, where lavapipe spends about as much on six
// per-lane buffer loads as on 700 multiply-adds (docs/CODEGEN.md).
uint bench_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}
// An unnormalised direction above the horizon from 32 bits (x, y in [-1, 1], z in [0.02, 1.02]):
// hbrdf_eval normalises its inputs, and every pair is valid, so every invocation runs the model.
vec3 bench_direction(uint bits) {
    vec3 u = vec3(float(bits & 1023u) * (1.0 / 1023.0), float((bits >> 10u) & 1023u) * (1.0 / 1023.0),
                  float(bits >> 20u) * (1.0 / 4095.0));
    return vec3(2.0 * u.x - 1.0, 2.0 * u.y - 1.0, u.z + 0.02);
}
void main() {
    uint i = gl_GlobalInvocationID.x;
    vec3 wi = bench_direction(bench_hash(2u * i));
    vec3 wo = bench_direction(bench_hash(2u * i + 1u));
    vec3 f = {{ function }}(wi, wo, {{ material }});
    data_out[3 * i] = f.x;
    data_out[3 * i + 1] = f.y;
    data_out[3 * i + 2] = f.z;
}
