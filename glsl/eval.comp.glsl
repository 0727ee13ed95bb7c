{# Jinja2 template, rendered by hybridbrdf.codegen.eval_compute_shader (docs: glsl/README.md).
   include: the generated model file; function: hbrdf_eval, hbrdf_eval_analytic or hbrdf_harness_only;
   material: an HBRDF_MATERIAL_<NAME> constant; n: pair count, or none for no guard.
   eval_synthetic.comp.glsl extends it, replacing the blocks "helpers" and "pairs". #}
#version 450
#extension GL_GOOGLE_include_directive : require
{% include "compute_io.glsl" %}
#include "{{ include }}"
{% if function == "hbrdf_harness_only" %}
// The kernel without the BRDF: what making or reading the pairs and writing f costs (bench/fast_model_speed.py).
vec3 hbrdf_harness_only(vec3 wi, vec3 wo, HbrdfMaterial m) { return wi * wo + m.kd; }
{% endif %}
{% block helpers %}{% endblock %}
void main() {
    uint i = gl_GlobalInvocationID.x;
{% if n is not none %}
    if (i >= {{ n }}u) return;
{% endif %}
{% block pairs %}
    vec3 wi = vec3(data_in[6 * i], data_in[6 * i + 1], data_in[6 * i + 2]);
    vec3 wo = vec3(data_in[6 * i + 3], data_in[6 * i + 4], data_in[6 * i + 5]);
{% endblock %}
    vec3 f = {{ function }}(wi, wo, {{ material }});
    data_out[3 * i] = f.x;
    data_out[3 * i + 1] = f.y;
    data_out[3 * i + 2] = f.z;
}
