"""The training pool of a fit: direction pairs and every source's reference values on them,
computed once (readers can be slow; the network is fast). Measured negatives (noise) are
clamped to 0. Pairs are cosine-weighted as in the paper (wi and wo independent), and a
fraction of them can be drawn around the mirror configuration (:func:`specular_pairs`).
"""

from __future__ import annotations

from typing import Callable, Optional, Sequence, Tuple

import numpy as np
import torch

from hybridbrdf.errors import InputFileError
from hybridbrdf.evaluate.directions import cosine_hemisphere
from hybridbrdf.sources.base import BRDFSource


def specular_pairs(rng: np.random.Generator, n: int, alpha: float) -> Tuple[np.ndarray, np.ndarray]:
    """n direction pairs (wi, wo) near the mirror configuration: wo cosine-weighted, a half vector
    h drawn from the GGX distribution D(h) cos(theta_h) of roughness ``alpha`` (Walter et al. 2007,
    Eq. 35-36: tan^2 theta_h = alpha^2 u / (1 - u)), wi = reflect(wo, h). Pairs whose wi falls
    below the horizon are redrawn; wi and wo swap roles at random so that the set is symmetric
    under reciprocity. float64 (n,3) each."""
    wi_out = np.empty((0, 3))
    wo_out = np.empty((0, 3))
    while len(wi_out) < n:
        m = 2 * (n - len(wi_out)) + 64  # ~half survive at grazing wo; draw extra
        wo = cosine_hemisphere(rng, m)
        u1, u2 = rng.random(m), rng.random(m)
        tan2 = alpha * alpha * u1 / np.maximum(1.0 - u1, 1e-12)
        cos_h = 1.0 / np.sqrt(1.0 + tan2)
        sin_h = np.sqrt(np.maximum(0.0, 1.0 - cos_h * cos_h))
        phi = 2.0 * np.pi * u2
        h = np.stack([sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h], axis=1)
        wi = 2.0 * np.sum(wo * h, axis=1, keepdims=True) * h - wo
        keep = wi[:, 2] > 1e-4
        wi_out = np.concatenate([wi_out, wi[keep]])
        wo_out = np.concatenate([wo_out, wo[keep]])
    wi_out, wo_out = wi_out[:n], wo_out[:n]
    wi_out /= np.linalg.norm(wi_out, axis=1, keepdims=True)
    swap = rng.random(n) < 0.5
    wi_out[swap], wo_out[swap] = wo_out[swap].copy(), wi_out[swap].copy()
    return wi_out, wo_out


#: Peak bytes per pool pair besides the values: the float64 pairs (48), their float32 copies (24),
#: one source's evaluation (sources.base.BYTES_PER_PAIR) and its float64 values (24), with a margin.
POOL_BYTES_PER_PAIR = 640


def pool_bytes_per_pair(rows: int) -> int:
    """Peak memory of a :class:`TrainingPool` per pair for ``rows`` material rows (float32 RGB
    each): what ``--pool`` is bounded by (hybridbrdf.limits)."""
    return POOL_BYTES_PER_PAIR + 12 * rows


class TrainingPool:
    """Direction pairs and every source's reference values on them (float32).

    A fraction ``specular`` of the pairs comes from :func:`specular_pairs` (half vectors
    concentrated around the normal, where glossy materials put their energy), the rest is
    cosine-weighted as in the paper."""

    def __init__(self, sources: Sequence[BRDFSource], n_pairs: int, seed: int,
                 progress: Optional[Callable[[str], None]] = None,
                 specular: float = 0.0, specular_alpha: float = 0.1):
        rng = np.random.default_rng(seed + 1_000_003)
        wi = cosine_hemisphere(rng, n_pairs)
        wo = cosine_hemisphere(rng, n_pairs)
        n_spec = int(round(specular * n_pairs))
        if n_spec > 0:
            # The cosine pairs come first and are unchanged, so specular = 0 reproduces earlier pools.
            wi[n_pairs - n_spec:], wo[n_pairs - n_spec:] = specular_pairs(rng, n_spec, specular_alpha)
        ref = np.empty((len(sources), n_pairs, 3), dtype=np.float32)
        for m, src in enumerate(sources):
            if progress:
                progress(f"evaluating {src.name} ({m + 1}/{len(sources)}) on {n_pairs} pairs")
            values = np.asarray(src.eval(wi, wo), dtype=np.float64)
            if not np.isfinite(values).all():
                raise InputFileError(src.path or src.name, "source returned NaN or Inf values")
            ref[m] = np.maximum(values, 0.0)
        n_cos = n_pairs - n_spec if n_spec < n_pairs else n_pairs  # all-specular pool: best available
        #: mean cos(theta_i) f_ref over the cosine-weighted pairs and RGB, per material (M,): an
        #: unbiased estimate of the material's mean albedo-like brightness.
        self.brightness = torch.from_numpy(
            (ref[:, :n_cos] * wi[None, :n_cos, 2:3].astype(np.float32)).mean(axis=(1, 2)).astype(np.float32))
        #: mean f_ref over the same pairs (M,): the scale of a loss that does not weigh by cos(theta_i).
        self.mean_f = torch.from_numpy(ref[:, :n_cos].mean(axis=(1, 2), dtype=np.float64).astype(np.float32))
        self.wi = torch.from_numpy(wi.astype(np.float32))
        self.wo = torch.from_numpy(wo.astype(np.float32))
        self.ref = torch.from_numpy(ref)

    def repeat_materials(self, k: int) -> "TrainingPool":
        """Each material's values k times in a row (material m becomes rows m k .. m k + k - 1):
        the pool of a sparse fit from k starts per material (FitSettings.sparse_starts)."""
        self.ref = self.ref.repeat_interleave(k, dim=0)
        self.brightness = self.brightness.repeat_interleave(k)
        self.mean_f = self.mean_f.repeat_interleave(k)
        return self

    def to(self, device: str) -> "TrainingPool":
        self.wi, self.wo, self.ref = self.wi.to(device), self.wo.to(device), self.ref.to(device)
        self.brightness, self.mean_f = self.brightness.to(device), self.mean_f.to(device)
        return self

