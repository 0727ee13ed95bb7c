"""Evaluation: the metrics of the paper, their directions, the per-material tables.

    from hybridbrdf.evaluate import evaluate, format_table   # PyTorch, imported on first use
    from hybridbrdf.evaluate import metric_directions, smape, cmae
"""

from hybridbrdf.evaluate.directions import cosine_directions, cosine_hemisphere
from hybridbrdf.evaluate.metrics import cmae, directional_albedo, mae, metric_directions, reciprocity_error, smape
from hybridbrdf.exports import lazy_names, public_face

#: Public names whose module imports PyTorch, loaded on first access (PEP 562).
_LAZY = lazy_names(["evaluate", "format_table", "format_extended_table"], "hybridbrdf.evaluate.evaluation")

__all__ = ["cmae", "cosine_directions", "cosine_hemisphere", "directional_albedo", "evaluate",
           "format_extended_table", "format_table", "mae", "metric_directions", "reciprocity_error", "smape"]

__getattr__, __dir__ = public_face(__name__, globals(), _LAZY)
