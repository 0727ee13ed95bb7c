"""The analytic BRDF f_a: the C++-backed API, its PyTorch twin and the float64 reference."""
