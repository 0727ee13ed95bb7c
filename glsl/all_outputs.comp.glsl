{# Jinja2 template (docs: glsl/README.md): every generated function that takes directions, each
   output written separately (17 floats per pair), for the hostile-input tests
   (tests/python/test_shader_hostile.py). Input per pair: wi, wo, u (8 floats). Output: hbrdf_eval (3),
   hbrdf_eval_analytic (3), hbrdf_eval_depth at depth 0 (3) and at HBRDF_NEURAL_MAX_DEPTH (3),
   hbrdf_pdf (1), hbrdf_sample's wi (3) and pdf (1).
   include: the generated model file; material: an HBRDF_MATERIAL_<NAME> constant; n: pair count. #}
#version 450
#extension GL_GOOGLE_include_directive : require
{% include "compute_io.glsl" %}
#include "{{ include }}"
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= {{ n }}u) return;
    vec3 wi = vec3(data_in[8 * i], data_in[8 * i + 1], data_in[8 * i + 2]);
    vec3 wo = vec3(data_in[8 * i + 3], data_in[8 * i + 4], data_in[8 * i + 5]);
    vec2 u = vec2(data_in[8 * i + 6], data_in[8 * i + 7]);
    float pdf;
    vec3 s = hbrdf_sample(wo, u, {{ material }}, pdf);
    vec3 f[4] = vec3[4](hbrdf_eval(wi, wo, {{ material }}), hbrdf_eval_analytic(wi, wo, {{ material }}),
                        hbrdf_eval_depth(wi, wo, {{ material }}, 0),
                        hbrdf_eval_depth(wi, wo, {{ material }}, HBRDF_NEURAL_MAX_DEPTH));
    for (int k = 0; k < 4; ++k) {
        data_out[17 * i + 3 * k] = f[k].x;
        data_out[17 * i + 3 * k + 1] = f[k].y;
        data_out[17 * i + 3 * k + 2] = f[k].z;
    }
    data_out[17 * i + 12] = hbrdf_pdf(wi, wo, {{ material }});
    data_out[17 * i + 13] = s.x;
    data_out[17 * i + 14] = s.y;
    data_out[17 * i + 15] = s.z;
    data_out[17 * i + 16] = pdf;
}
