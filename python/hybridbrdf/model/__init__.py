"""Fitted models: the model file, the networks, editing, precision, the shipped prior.

    from hybridbrdf.model import load_model, edit, mix
    m = load_model("model.safetensors")          # no PyTorch needed to load, check, edit or write

Its names load on first access (PEP 562): ``import hybridbrdf.model`` imports no NumPy, so the
command line's parsers can read :mod:`hybridbrdf.model.sizes`; ``random_model`` (a reproducible
random model for tests and benchmarks) imports PyTorch on first use.
"""

from hybridbrdf.exports import lazy_names, public_face

#: Every public name, loaded on first access (PEP 562): their modules import NumPy (random_model's
#: PyTorch), and the command line's parsers read hybridbrdf.model.sizes (plain Python) without it.
_LAZY = {**lazy_names(["albedo_profile", "edit", "mix"], "hybridbrdf.model.editing"),
         "with_bound": "hybridbrdf.model.energy", **lazy_names(["HybridModel", "load_model"], "hybridbrdf.model.file"),
         **lazy_names(["load_prior", "prior_path"], "hybridbrdf.model.prior"), "random_model": "hybridbrdf.model.random"}

__all__ = ["HybridModel", "albedo_profile", "edit", "load_model", "load_prior", "mix", "prior_path", "random_model",
           "with_bound"]

__getattr__, __dir__ = public_face(__name__, globals(), _LAZY)
