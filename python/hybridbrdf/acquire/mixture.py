"""The ground truth of a simulated capture (docs/ACQUISITION.md): a flat sample whose SVBRDF is an
exact mixture of measured BRDFs under weights maps,

    g(uv, wi, wo) = sum_k w_k(uv) g_k(wi, wo),

a convex combination of BRDFs (a BRDF). The weights map is looked up as docs/SVBRDF.md's textured
materials look theirs up: texel (i, j) centred at ((i + 0.5) / W, (j + 0.5) / H), bilinear,
``clamp`` addressing (a sample does not repeat beyond its edge)."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from hybridbrdf.fit.painting import composite
from hybridbrdf.sources.base import BRDFSource
from hybridbrdf.svbrdf.asset import texel_taps


class Mixture:
    """Sources ``sources`` (K :class:`BRDFSource`) mixed by ``weights`` (H, W, K), each texel's
    weights non-negative and summing to 1."""

    def __init__(self, sources: Sequence[BRDFSource], weights: np.ndarray):
        weights = np.asarray(weights, dtype=np.float64)
        if weights.ndim != 3 or weights.shape[2] != len(sources) or not len(sources):
            raise ValueError(f"weights must have shape (H, W, {len(sources)}) for {len(sources)} sources, "
                             f"got {weights.shape}")
        if not np.isfinite(weights).all() or weights.min() < 0 or np.abs(weights.sum(axis=2) - 1).max() > 1e-6:
            raise ValueError("weights must be finite, non-negative and sum to 1 at every texel")
        self.sources, self.weights = list(sources), weights

    @classmethod
    def painted(cls, base: BRDFSource, layers: Sequence[BRDFSource], masks: Sequence[np.ndarray]) -> "Mixture":
        """``layers`` painted over ``base`` by grey ``masks`` (each (H, W) in [0, 1]) front to back,
        the last on top, as ``hbrdf paint`` composites them."""
        if len(layers) != len(masks):
            raise ValueError("one mask per layer")
        if not layers:
            return cls([base], np.ones((1, 1, 1)))
        rest = composite([np.asarray(m, dtype=np.float64) for m in masks])
        return cls([base, *layers], np.concatenate([1 - rest.sum(axis=2, keepdims=True), rest], axis=2))

    def weights_at(self, uv: np.ndarray) -> np.ndarray:
        """(N, K) weights at uv (N, 2): bilinear between texel centres, clamped at the edges."""
        h, w, _ = self.weights.shape
        return sum(t[:, None] * self.weights[rows, cols] for rows, cols, t in texel_taps(uv, (w, h), "clamp", "bilinear"))

    def eval(self, uv, wi, wo) -> np.ndarray:
        """g(uv, wi, wo) (N, 3) float64, no cosine; each source evaluated only where it weighs.
        Measured values below 0 (noise in a measurement) count as 0, as the metrics count them."""
        uv = np.asarray(uv, dtype=np.float64)
        wi, wo = np.asarray(wi, dtype=np.float64), np.asarray(wo, dtype=np.float64)
        weights = self.weights_at(uv)
        out = np.zeros((len(uv), 3))
        for k, source in enumerate(self.sources):
            rows = np.nonzero(weights[:, k] > 0)[0]
            if len(rows):
                out[rows] += weights[rows, k, None] * np.maximum(source.eval(wi[rows], wo[rows]), 0.0)
        return out
