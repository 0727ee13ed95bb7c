"""Shared fixtures and generators for the Python test suite."""

import numpy as np
import pytest

import hybridbrdf as hb


def cosine_directions(rng: np.random.Generator, n: int) -> np.ndarray:
    """n directions drawn cosine-weighted on the upper hemisphere (float64)."""
    u = rng.random((n, 2))
    r = np.sqrt(u[:, 0])
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - u[:, 0])], axis=1)


def spherical(theta: float, phi: float) -> np.ndarray:
    return np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])


def hard_directions() -> np.ndarray:
    """The foundation issue's hard cases: grazing (z = 0 and 1e-8), the normal,
    wi = wo and mirrored pairs (formed by crossing the list with itself), below
    the horizon, zero length, NaN and Inf, tiny and huge lengths."""
    g = 1e-8
    s = np.sqrt(1 - g * g)
    inf, nan = np.inf, np.nan
    return np.array(
        [
            [0, 0, 1], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [s, 0, g], [0, s, g], [-s, 0, g],
            [0.6 * s, 0.8 * s, g], [0, 0, -1], [0.6, 0, -0.8], [0, 0, 0], [nan, 0, 1], [0, nan, 1],
            [0, 0, nan], [inf, 0, 1], [0, 0, inf], [-inf, 0, 1], [0.3, 0.4, np.sqrt(0.75)],
            [1e-30, 0, 1e-30], [1e20, 1e20, 1e20], [0.70710678, 0, 0.70710678], [-0.70710678, 0, 0.70710678],
        ]
    )


def hard_pairs():
    d = hard_directions()
    n = len(d)
    wi = np.repeat(d, n, axis=0)
    wo = np.tile(d, (n, 1))
    return wi, wo


def valid_upper(w: np.ndarray, dtype=np.float32) -> np.ndarray:
    """Which directions an implementation working in `dtype` treats as usable and
    above the horizon (squared length finite and >= the smallest normal)."""
    w = w.astype(dtype)
    with np.errstate(over="ignore", invalid="ignore"):
        len2 = (w * w).sum(axis=1, dtype=dtype)
        return np.isfinite(len2) & (len2 >= np.finfo(dtype).tiny) & (w[:, 2] > 0)


PARAM_CORNERS = [
    hb.AnalyticParams(kd=[0.0, 0.5, 1.0], eta=[eta, 1.33, eta], alpha=(ax, ay))
    for ax in (hb.ALPHA_MIN, 0.01, 0.3, 1.0)
    for ay in (hb.ALPHA_MIN, 0.3, 1.0)
    for eta in (1.0, 1.5, 10.0)
]


def random_params(rng: np.random.Generator, alpha_min: float = 1e-3) -> hb.AnalyticParams:
    lo = np.log10(alpha_min)
    return hb.AnalyticParams(
        kd=rng.random(3),
        eta=1.0 + 9.0 * rng.random(3) * rng.random(3),
        alpha=10.0 ** (lo * rng.random(2)),
    )


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
