"""Cosine-weighted direction generators, shared by the metrics, the fitting pools,
the benchmarks and the tests.

Both generators apply the same map (:func:`cosine_from_uniform`); they differ only in
the order in which they draw the uniform numbers, and each order is kept because
numbers already published depend on it: :func:`cosine_hemisphere` (all u1, then all
u2) fixes the CONVENTIONS metric directions, :func:`cosine_directions` (one (u1, u2)
row per direction) the random cases of the tests and benchmarks."""

from __future__ import annotations

import numpy as np


def cosine_from_uniform(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Directions on the upper hemisphere, cosine-distributed for uniform u1, u2 in [0, 1):
    radius sqrt(u1) on the unit disk at angle 2 pi u2, lifted onto the hemisphere."""
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1.0 - u1))], axis=1)


def cosine_hemisphere(rng: np.random.Generator, n: int) -> np.ndarray:
    """n directions drawn cosine-weighted on the upper hemisphere (float64, (n,3)); the
    draw order of the CONVENTIONS metrics (n values of u1, then n values of u2)."""
    u1 = rng.random(n)
    u2 = rng.random(n)
    return cosine_from_uniform(u1, u2)


def cosine_directions(rng: np.random.Generator, n: int) -> np.ndarray:
    """n directions drawn cosine-weighted on the upper hemisphere (float64, (n,3)); the
    draw order of the tests and benchmarks (one row (u1, u2) per direction)."""
    u = rng.random((n, 2))
    return cosine_from_uniform(u[:, 0], u[:, 1])
