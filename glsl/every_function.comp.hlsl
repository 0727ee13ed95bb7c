{# Jinja2 template (docs: glsl/README.md): the HLSL twin of every_function.comp.glsl,
   with the same variables. #}
#include "{{ include }}"
{% include "compute_io.hlsl" %}
[numthreads(64, 1, 1)]
void main(uint3 id : SV_DispatchThreadID) {
    uint i = id.x;
    float3 wi = float3(data_in[8 * i], data_in[8 * i + 1], data_in[8 * i + 2]);
    float3 wo = float3(data_in[8 * i + 3], data_in[8 * i + 4], data_in[8 * i + 5]);
    float pdf;
    float3 s = hbrdf_sample(wo, float2(data_in[8 * i + 6], data_in[8 * i + 7]), {{ material }}, pdf);
    float3 f = hbrdf_eval(wi, wo, {{ material }}) + hbrdf_eval_analytic(wi, wo, {{ material }}) + s
        + hbrdf_eval_depth(wi, wo, {{ material }}, int(i & 3u));
    data_out[3 * i] = f.x + pdf + hbrdf_pdf(wi, wo, {{ material }});
    data_out[3 * i + 1] = f.y;
    data_out[3 * i + 2] = f.z;
}
