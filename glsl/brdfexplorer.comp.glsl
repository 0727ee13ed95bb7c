{# Jinja2 template (docs: glsl/README.md): runs the shader block of a BRDF Explorer .brdf file
   as a compute shader, in the local frame (N = z, X = x, Y = y), like eval.comp.glsl
   (tests/python/test_brdfexplorer.py). params: the file's parameters as constants at their
   defaults; shader: the file's shader block (it defines BRDF(L, V, N, X, Y)); n: pair count. #}
#version 450
{% include "compute_io.glsl" %}
{{ params }}
{{ shader }}
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= {{ n }}u) return;
    vec3 L = vec3(data_in[6 * i], data_in[6 * i + 1], data_in[6 * i + 2]);
    vec3 V = vec3(data_in[6 * i + 3], data_in[6 * i + 4], data_in[6 * i + 5]);
    vec3 f = BRDF(L, V, vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0));
    data_out[3 * i] = f.x;
    data_out[3 * i + 1] = f.y;
    data_out[3 * i + 2] = f.z;
}
