"""hbrdf-codegen: GLSL, HLSL, Slang, WGSL, C++ and BRDF Explorer sources from a model file."""
