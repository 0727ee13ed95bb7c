"""Quality metrics of docs/CONVENTIONS.md ("Measuring quality").

All take reference values ``f_ref`` and model values ``f_hat`` of shape
(N, 3) for the same direction pairs. Measured references may hold small
negative values (noise); they are clamped to 0 first, and so is the model.
"""

from __future__ import annotations

from typing import Tuple

import numpy as np

from hybridbrdf.evaluate.directions import cosine_hemisphere  # fitting.py imports it from here too

#: Seed of the metric directions: fixed so that numbers compare between runs and versions.
METRIC_SEED = 7
#: Number of direction pairs of a CONVENTIONS metric.
METRIC_PAIRS = 1_000_000


def metric_directions(n: int = METRIC_PAIRS, seed: int = METRIC_SEED) -> Tuple[np.ndarray, np.ndarray]:
    """The metric's direction pairs: wi and wo drawn cosine-weighted and independently."""
    rng = np.random.default_rng(seed)
    wi = cosine_hemisphere(rng, n)
    wo = cosine_hemisphere(rng, n)
    return wi, wo


def _clamped(f_ref, f_hat):
    a = np.maximum(np.asarray(f_ref, dtype=np.float64), 0.0)
    b = np.maximum(np.asarray(f_hat, dtype=np.float64), 0.0)
    if a.shape != b.shape:
        raise ValueError(f"reference has shape {a.shape} but model values have {b.shape}")
    return a, b


def smape_terms(f_ref, f_hat) -> np.ndarray:
    """The per-value terms of SMAPE, 2 |f - f^| / (|f| + |f^|) (0 where both are 0), same shape as
    the inputs; their mean is :func:`smape`."""
    a, b = _clamped(f_ref, f_hat)
    den = a + b
    return 2.0 * np.divide(np.abs(a - b), den, out=np.zeros_like(den), where=den > 0)


def smape(f_ref, f_hat) -> float:
    """Symmetric mean absolute percentage error (paper Sec. 4.1):
    2/N sum |f - f^| / (|f| + |f^|), averaged over RGB; a term where both are 0 counts 0.
    Ranges over [0, 2]."""
    return float(smape_terms(f_ref, f_hat).mean())


def cmae(f_ref, f_hat, cos_theta_i) -> float:
    """Cosine-weighted mean absolute error: mean of |f - f^| cos(theta_i) over pairs and RGB.
    Weighs errors as a renderer sees them (SMAPE is dominated by dark regions)."""
    a, b = _clamped(f_ref, f_hat)
    c = np.asarray(cos_theta_i, dtype=np.float64).reshape(-1, 1)
    return float((np.abs(a - b) * c).mean())


def mae(f_ref, f_hat) -> float:
    """Mean absolute error over pairs and RGB."""
    a, b = _clamped(f_ref, f_hat)
    return float(np.abs(a - b).mean())


def reciprocity_error(eval_fn, n: int = 100_000, seed: int = METRIC_SEED) -> float:
    """SMAPE between f(wi, wo) and f(wo, wi) on n metric pairs; 0 for a reciprocal BRDF."""
    wi, wo = metric_directions(n, seed)
    return smape(eval_fn(wi, wo), eval_fn(wo, wi))


def directional_albedo(eval_fn, theta_o: float, n: int = 200_000, seed: int = METRIC_SEED) -> np.ndarray:
    """a(wo) = integral of f cos(theta_i) dwi for wo at elevation theta_o (radians, phi = 0),
    estimated with n cosine-weighted samples: mean of pi * f. Returns RGB."""
    rng = np.random.default_rng(seed)
    wi = cosine_hemisphere(rng, n)
    wo = np.tile([np.sin(theta_o), 0.0, np.cos(theta_o)], (n, 1))
    return np.pi * np.maximum(np.asarray(eval_fn(wi, wo), dtype=np.float64), 0.0).mean(axis=0)
