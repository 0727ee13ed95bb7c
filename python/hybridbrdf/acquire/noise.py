"""The sensor's noise (docs/ACQUISITION.md): Poisson-Gaussian, the standard model of a raw linear
sensor (Foi et al. 2008). A pixel of radiance L (the rig's units) collects n ~ Poisson(P L)
photoelectrons, P the ``photons`` collected at L = 1 (a white Lambertian sample lit head-on by the
rig generators' lights reads 1), and reads out with Gaussian noise of ``read_noise`` electrons:

    value = (n + N(0, read_noise^2)) / P,    E[value] = L,    Var[value] = L / P + (read_noise / P)^2.

Values are linear HDR, unclipped (no saturation) and may be negative where L is near 0 (read
noise), as a raw frame less its black level is."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class NoiseModel:
    """``photons``: photoelectrons per channel at radiance 1 (None: no noise at all);
    ``read_noise``: the Gaussian read noise's standard deviation in electrons."""
    photons: float = None
    read_noise: float = 0.0

    def __post_init__(self):
        if self.photons is not None and not (math.isfinite(self.photons) and self.photons > 0):
            raise ValueError(f"photons must be a positive number, got {self.photons!r}")
        if not (math.isfinite(self.read_noise) and self.read_noise >= 0):
            raise ValueError(f"read_noise must be a number >= 0, got {self.read_noise!r}")

    def variance(self, radiance: np.ndarray) -> np.ndarray:
        """The variance of a pixel of mean ``radiance`` (the model's, for checks and weighting)."""
        if self.photons is None:
            return np.zeros_like(np.asarray(radiance, dtype=np.float64))
        return np.maximum(radiance, 0) / self.photons + (self.read_noise / self.photons) ** 2

    def apply(self, radiance: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A noisy reading of ``radiance`` (any shape, float64 out); the mean of the Poisson draw
        is the radiance clamped at 0."""
        radiance = np.asarray(radiance, dtype=np.float64)
        if self.photons is None:
            return radiance.copy()
        electrons = rng.poisson(np.maximum(radiance, 0) * self.photons).astype(np.float64)
        if self.read_noise > 0:
            electrons += rng.normal(0.0, self.read_noise, radiance.shape)
        return electrons / self.photons

    def to_dict(self) -> dict:
        """The model as capture.json records it."""
        return {"model": "poisson-gaussian", "photons": self.photons, "read_noise": self.read_noise}
