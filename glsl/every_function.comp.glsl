{# Jinja2 template (docs: glsl/README.md): calls every function of a generated model file
   once and combines the results, so that compiling it checks them all (tests/python/test_codegen.py).
   include: the generated model file; material: an HBRDF_MATERIAL_<NAME> constant. #}
#version 450
#extension GL_GOOGLE_include_directive : require
{% include "compute_io.glsl" %}
#include "{{ include }}"
void main() {
    uint i = gl_GlobalInvocationID.x;
    vec3 wi = vec3(data_in[8 * i], data_in[8 * i + 1], data_in[8 * i + 2]);
    vec3 wo = vec3(data_in[8 * i + 3], data_in[8 * i + 4], data_in[8 * i + 5]);
    float pdf;
    vec3 s = hbrdf_sample(wo, vec2(data_in[8 * i + 6], data_in[8 * i + 7]), {{ material }}, pdf);
    vec3 f = hbrdf_eval(wi, wo, {{ material }}) + hbrdf_eval_analytic(wi, wo, {{ material }}) + s
        + hbrdf_eval_depth(wi, wo, {{ material }}, int(i & 3u));
    data_out[3 * i] = f.x + pdf + hbrdf_pdf(wi, wo, {{ material }});
    data_out[3 * i + 1] = f.y;
    data_out[3 * i + 2] = f.z;
}
