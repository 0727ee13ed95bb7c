{# Included by the HLSL kernels here (docs: glsl/README.md): the buffers of compute_io.glsl
   (input floats at u0, output floats at u1); the 64-wide workgroup is main's [numthreads]. #}
RWStructuredBuffer<float> data_in : register(u0);
RWStructuredBuffer<float> data_out : register(u1);
