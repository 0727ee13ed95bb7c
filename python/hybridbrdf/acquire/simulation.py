"""The capture simulator (docs/ACQUISITION.md, issue 46 step 1): photographs of a flat sample whose
SVBRDF is an exact mixture of measured BRDFs (:class:`~hybridbrdf.acquire.mixture.Mixture`), taken
by a rig (:mod:`hybridbrdf.acquire.rig`), with the noise of a real sensor and, optionally, the
lights not quite where the rig says (calibration error).

Per pixel (one ray through its centre): radiance = g(uv, wi, wo) cos(theta_i) I / d^2 for a point
light of intensity I at distance d; pixels that do not see the sample read 0 (before noise)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, List, Optional

import numpy as np

from hybridbrdf.acquire.geometry import pixel_geometry
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.rig import Rig, check_rig


@dataclass
class Capture:
    """A simulated capture: the ``rig`` as stated (nominal light positions), its ``photos``
    ((H, W, 3) float32 linear radiance, one per shot), and the truth behind them: the lights'
    ``true_light_positions`` (lights, 3), the ``mixture``, the ``noise`` model, ``light_jitter``
    and ``seed``."""
    rig: Rig
    photos: List[np.ndarray]
    true_light_positions: np.ndarray
    mixture: Mixture
    noise: NoiseModel = field(default_factory=NoiseModel)
    light_jitter: float = 0.0
    seed: int = 0


def radiance(rig: Rig, shot: int, mixture: Mixture, light_position: Optional[np.ndarray] = None) -> np.ndarray:
    """The noiseless photograph of shot ``shot``: (H, W, 3) float64 radiance, 0 off the sample."""
    geo = pixel_geometry(rig, shot, light_position)
    w, h = rig.image_size
    image = np.zeros((h, w, 3))
    if geo.mask.any():
        intensity = rig.lights[rig.shots[shot].light].intensity
        cos_i = np.maximum(geo.wi[:, 2], 0.0)
        image[geo.mask] = mixture.eval(geo.uv, geo.wi, geo.wo) * (cos_i / geo.distance2)[:, None] * intensity
    return image


def simulate(rig: Rig, mixture: Mixture, noise: Optional[NoiseModel] = None, light_jitter: float = 0.0,
             seed: int = 0, on_photo: Optional[Callable[[int], None]] = None) -> Capture:
    """Photograph ``mixture`` with every shot of ``rig``. ``noise``: the sensor
    (:class:`NoiseModel`; None: noiseless); ``light_jitter``: the standard deviation (the rig's
    length unit) of a Gaussian offset per axis added to each light's position before rendering,
    while the capture keeps stating the rig's positions. One ``seed`` draws jitter and noise.
    ``on_photo(k)`` is called once photograph ``k`` is taken (a progress bar)."""
    rig = check_rig(rig)
    noise = noise or NoiseModel()
    if not (np.isfinite(light_jitter) and light_jitter >= 0):
        raise ValueError(f"light_jitter must be a number >= 0, got {light_jitter!r}")
    rng = np.random.default_rng(seed)
    nominal = np.array([l.position for l in rig.lights])
    true = nominal + (rng.normal(0.0, light_jitter, nominal.shape) if light_jitter > 0 else 0.0)
    if (true[:, 2] <= 0).any():
        raise ValueError(f"light_jitter {light_jitter:g} moved a light below the sample plane; use less")
    photos = []
    for k, shot in enumerate(rig.shots):
        clean = radiance(rig, k, mixture, true[shot.light])
        photos.append(noise.apply(clean, rng).astype(np.float32))
        if on_photo is not None:
            on_photo(k)
    return Capture(rig, photos, true, mixture, noise, float(light_jitter), int(seed))
