{# Included by the GLSL kernels here (docs: glsl/README.md): the interface hbrdf_vk_runner
   dispatches against, 64 invocations per workgroup, the input floats at binding 0 and the
   output floats at binding 1. #}
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer In { float data_in[]; };
layout(std430, binding = 1) writeonly buffer Out { float data_out[]; };
