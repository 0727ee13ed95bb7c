"""A fitted model's material as a BRDF source: the model's own output is the reference.

``hbrdf add --to BASE --refine`` trains BASE's network further with new materials; BASE's own
materials are then replayed against BASE's outputs (distillation from the model itself), so no
original measurement is needed to keep them where they were.
"""

from __future__ import annotations

import numpy as np
import torch

from hybridbrdf.sources.base import BRDFSource


class ModelMaterialSource(BRDFSource):
    """Material ``material`` of a :class:`~hybridbrdf.model.file.HybridModel`, evaluated by
    PyTorch in float64 (the reference the C++ library is tested against): the full model f_t,
    no cosine. ``origin`` names the model."""

    def __init__(self, model, material: str):
        self.model, self.name = model, material
        info = model.material_info[model.index(material)]
        self.isotropic = bool(info.get("isotropic", True))
        self.origin = f"its own output in {model.path or 'the base model'}"
        self.path = None

    def _eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        return self.model.eval(wi, wo, self.name, dtype=torch.float64)
