{# Jinja2 template (docs: glsl/README.md): the HLSL twin of all_outputs.comp.glsl, with the same
   variables and the same 17 outputs per pair. #}
#include "{{ include }}"
{% include "compute_io.hlsl" %}
[numthreads(64, 1, 1)]
void main(uint3 id : SV_DispatchThreadID) {
    uint i = id.x;
    if (i >= {{ n }}u) return;
    float3 wi = float3(data_in[8 * i], data_in[8 * i + 1], data_in[8 * i + 2]);
    float3 wo = float3(data_in[8 * i + 3], data_in[8 * i + 4], data_in[8 * i + 5]);
    float2 u = float2(data_in[8 * i + 6], data_in[8 * i + 7]);
    float pdf;
    float3 s = hbrdf_sample(wo, u, {{ material }}, pdf);
    float3 f[4] = {hbrdf_eval(wi, wo, {{ material }}), hbrdf_eval_analytic(wi, wo, {{ material }}),
                   hbrdf_eval_depth(wi, wo, {{ material }}, 0),
                   hbrdf_eval_depth(wi, wo, {{ material }}, HBRDF_NEURAL_MAX_DEPTH)};
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
