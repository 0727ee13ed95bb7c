{# Jinja2 template, rendered by hybridbrdf.codegen.eval_compute_shader (docs: glsl/README.md);
   the HLSL twin of eval.comp.glsl, for glslang's HLSL front end, with the same variables. #}
#include "{{ include }}"
{% include "compute_io.hlsl" %}
[numthreads(64, 1, 1)]
void main(uint3 id : SV_DispatchThreadID) {
    uint i = id.x;
{% if n is not none %}
    if (i >= {{ n }}u) return;
{% endif %}
    float3 wi = float3(data_in[6 * i], data_in[6 * i + 1], data_in[6 * i + 2]);
    float3 wo = float3(data_in[6 * i + 3], data_in[6 * i + 4], data_in[6 * i + 5]);
    float3 f = {{ function }}(wi, wo, {{ material }});
    data_out[3 * i] = f.x;
    data_out[3 * i + 1] = f.y;
    data_out[3 * i + 2] = f.z;
}
