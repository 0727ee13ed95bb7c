{# Jinja2 template, rendered by hybridbrdf.codegen.eval_compute_shader(..., directions="synthetic")
   (docs: glsl/README.md): eval.comp.glsl with each invocation's pair made in the shader, for speed
   measurements only; nothing is read from binding 0, n is none (dispatch a multiple of 64 pairs). #}
{% extends "eval.comp.glsl" %}
{% block helpers %}
// 32 well-mixed bits of an index (the PCG hash of Jarzynski & Olano 2020, "Hash Functions for
// GPU Rendering"): a handful of integer operations, where lavapipe's six per-lane buffer loads
// take about a quarter of a 32x2's evaluation time with AVX2 only (docs/CODEGEN.md).
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
{% endblock %}
{% block pairs %}
    vec3 wi = bench_direction(bench_hash(2u * i));
    vec3 wo = bench_direction(bench_hash(2u * i + 1u));
{% endblock %}
