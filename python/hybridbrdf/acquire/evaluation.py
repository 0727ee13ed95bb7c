"""Evaluating a per-texel fit at arbitrary (texel, wi, wo) rows: the one interface every fit of
docs/ACQUISITION.md shares (``result.eval(texel, wi, wo)``), so a comparison (issue 46 step 3)
scores the hybrid, analytic-only and neural-only fits the same way."""

from __future__ import annotations

from typing import Callable

import numpy as np
import torch

#: Rows evaluated at once: 10^6 rows of a 32-wide network stay within a few hundred MB.
CHUNK = 65536


def eval_chunked(texel: np.ndarray, wi: np.ndarray, wo: np.ndarray, n_texels: int,
                 fn: Callable[[np.ndarray, torch.Tensor, torch.Tensor], torch.Tensor]) -> np.ndarray:
    """(M, 3) float64 of ``fn(texel_chunk, wi_chunk, wo_chunk)`` over chunks of :data:`CHUNK` rows,
    without gradients; ``texel`` (M,) int in [0, n_texels), ``wi``, ``wo`` (M, 3)."""
    texel = np.asarray(texel, dtype=np.int64).reshape(-1)
    wi = np.asarray(wi, dtype=np.float64).reshape(-1, 3)
    wo = np.asarray(wo, dtype=np.float64).reshape(-1, 3)
    if not (len(texel) == len(wi) == len(wo)):
        raise ValueError(f"eval: texel, wi and wo need one row each, got {len(texel)}, {len(wi)}, {len(wo)}")
    if len(texel) and (texel.min() < 0 or texel.max() >= n_texels):
        raise ValueError(f"eval: texel index out of range [0, {n_texels})")
    out = np.zeros((len(texel), 3))
    with torch.no_grad():
        for s in range(0, len(texel), CHUNK):
            e = s + CHUNK
            out[s:e] = fn(texel[s:e], torch.from_numpy(wi[s:e]), torch.from_numpy(wo[s:e])).double().numpy()
    return out
