"""Fitted models: the model file, the networks, editing, precision, the shipped prior.

    from hybridbrdf.model import load_model, edit, mix
    m = load_model("model.safetensors")          # no PyTorch needed to load, check, edit or write

``random_model`` (a reproducible random model for tests and benchmarks) imports PyTorch on first use.
"""

from hybridbrdf.exports import public_face
from hybridbrdf.model.editing import albedo_profile, edit, mix
from hybridbrdf.model.energy import with_bound
from hybridbrdf.model.file import HybridModel, load_model
from hybridbrdf.model.prior import load_prior, prior_path

#: Public names whose module imports PyTorch, loaded on first access (PEP 562).
_LAZY = {"random_model": "hybridbrdf.model.random"}

__all__ = ["HybridModel", "albedo_profile", "edit", "load_model", "load_prior", "mix", "prior_path", "random_model",
           "with_bound"]

__getattr__, __dir__ = public_face(__name__, globals(), _LAZY)
