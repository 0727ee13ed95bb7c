"""The analytic BRDF f_a: the C++-backed API, its PyTorch twin and the float64 reference.

    from hybridbrdf.brdf import AnalyticParams, analytic_eval, sample, pdf   # libhybridbrdf
    from hybridbrdf.brdf import eval_analytic     # PyTorch, differentiable (imports torch on first use)

The PyTorch twins of ``sample`` and ``pdf`` stay in :mod:`hybridbrdf.brdf.torch_brdf`; the NumPy
float64 formulas in :mod:`hybridbrdf.brdf.microfacet`.
"""

from hybridbrdf.brdf.analytic import AnalyticParams, analytic_eval, pdf, sample, simd_path
from hybridbrdf.exports import public_face

#: Public names whose module imports PyTorch, loaded on first access (PEP 562).
_LAZY = {"eval_analytic": "hybridbrdf.brdf.torch_brdf"}

__all__ = ["AnalyticParams", "analytic_eval", "eval_analytic", "pdf", "sample", "simd_path"]

__getattr__, __dir__ = public_face(__name__, globals(), _LAZY)
