"""The **neural-only** per-texel fit (docs/ACQUISITION.md, issue 46's comparison): a latent code
per texel on a frozen neural-baseline network (``kind`` neural: NeuralBRDF, the paper's adaptation
of Zeltner et al. 2024), by the same stages as the hybrid fit
(:mod:`~hybridbrdf.acquire.cluster_fit`): clusters from an analytic fit, each cluster started at
the network's material that explains it best and fitted, then per-texel codes pulled toward the
cluster's. Not a textured material (the format's layers need an analytic part): ``eval`` only."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Dict, Optional

import numpy as np
import torch

from hybridbrdf.acquire import cluster_merge, footprint
from hybridbrdf.acquire.cluster_fit import fit_on_prior
from hybridbrdf.acquire.evaluation import eval_chunked
from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.texel_rows import ROWS_PER_TEXEL, Progress
from hybridbrdf.model.file import HybridModel


class NeuralFamily:
    """A neural model's frozen network and its materials' latent codes, per row:
    ``evaluate(material, {"z": (N, l)}, wi, wo)`` = f (N, 3) (the material is not used: the
    network is shared, the code is the material)."""

    def __init__(self, model: HybridModel):
        if model.kind != "neural":
            raise ValueError(f"the neural-only fit needs a model of kind neural; {model.path or 'this one'} "
                             f"is '{model.kind}'")
        self.model = model
        self.module = model._module(torch.float32)
        for p in self.module.parameters():
            p.requires_grad_(False)

    def raw_of_materials(self) -> Dict[str, torch.Tensor]:
        return {"z": torch.from_numpy(self.model.tensors["materials.z"]).clone()}

    def evaluate(self, material: torch.Tensor, raw: Dict[str, torch.Tensor], wi, wo) -> torch.Tensor:
        """NeuralBRDF.evaluate_pairs: each pair's directions in its own code's shading frames,
        then the shared MLP, f = exp(o)."""
        return self.module.evaluate_pairs(wi.to(torch.float32), wo.to(torch.float32), raw["z"]).to(wi.dtype)

    @staticmethod
    def values(raw: Dict[str, torch.Tensor]) -> Dict[str, torch.Tensor]:
        """The decoded values: the code itself (no reparameterisation)."""
        return {"z": raw["z"]}

    def evaluate_decoded(self, material: torch.Tensor, values: Dict[str, torch.Tensor], wi, wo) -> torch.Tensor:
        return self.evaluate(material, values, wi, wo)


@dataclass
class NeuralMaps:
    """A neural-only fit: ``model`` (the neural network), ``z`` (H, W, l) float32 per texel,
    ``material`` (H, W) the network's material each texel's cluster started from, ``counts`` (H, W)."""
    model: HybridModel
    z: np.ndarray
    material: np.ndarray
    counts: np.ndarray

    def eval(self, texel: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """The fitted BRDF (no cosine) at texels ``texel`` ((M,) int, j * W + i) for ``wi``, ``wo``
        (M, 3): (M, 3) float64, in chunks without gradients."""
        family = NeuralFamily(self.model)
        z = torch.from_numpy(np.ascontiguousarray(self.z.reshape(-1, self.z.shape[-1])))
        return eval_chunked(texel, wi, wo, len(z),
                            lambda t, a, b: family.evaluate(None, {"z": z[torch.from_numpy(t)]}, a, b))

    def eval_uv(self, uv: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """The fit at uv (M, 2), its code map read bilinearly between texel centres
        (:func:`~hybridbrdf.acquire.footprint.filtered`): (M, 3) float64."""
        family = NeuralFamily(self.model)
        z = torch.from_numpy(footprint.filtered({"z": self.z}, uv)["z"]).float()
        return eval_chunked(np.arange(len(uv)), wi, wo, len(uv),
                            lambda t, a, b: family.evaluate(None, {"z": z[torch.from_numpy(t)]}, a, b))


def fit_neural_texels(obs: Observations, model: HybridModel, steps: int = 300, seed: int = 0,
                      progress: Optional[Progress] = None, rows_per_texel: int = ROWS_PER_TEXEL,
                      state: Optional[dict] = None, save_state: Optional[Callable[[dict], None]] = None
                      ) -> NeuralMaps:
    """Fit a latent code per texel on ``model``'s frozen network (kind neural), with the budget of
    :func:`hybridbrdf.acquire.hybrid_fit.fit_hybrid_texels` (the same stages and steps)."""
    family = NeuralFamily(model)
    labels, clusters, raw = fit_on_prior(family, obs, steps, seed, rows_per_texel, progress, state, save_state,
                                         merge=cluster_merge)
    w, h = obs.size
    material = clusters["material"].numpy()[labels].reshape(h, w)
    return NeuralMaps(model, raw["z"].numpy().astype(np.float32).reshape(h, w, -1), material, obs.counts())
