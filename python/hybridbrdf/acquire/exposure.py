"""Which pixels of a capture a fit may use (docs/ACQUISITION.md, "Bad input"): stated masking, not
refusal, wherever something usable remains.

- **Not finite** (NaN, infinity: a dead pixel, a failed merge): the pixel is left out, counted.
- **Saturated** (a channel at an 8- or 16-bit encoding's largest code: the sensor clipped, the
  radiance is unknown above it): left out as a pixel that is not finite is, counted apart.
- **Under-exposed photograph**: most of the pixels that see the sample (more than half) read below
  :data:`FLOOR_SIGMAS` times the noise floor sigma in every channel, so most of what the
  photograph says about the sample is noise. The floor is the capture's stated read noise in
  radiance units (read_noise / photons, ``capture.json``'s ``noise``) or, when it states none,
  the robust spread (1.4826 x the median absolute deviation) of the photograph's pixels that do
  not see the sample (they read 0 plus noise); with neither, 0: an all-zero photograph is
  under-exposed. Such a photograph is left out whole, not pixel by pixel: dropping only its dark
  pixels would keep the ones that noise pushed up and bias every fit bright.

When no photograph is left, or no pixel, the capture is refused in one line."""

from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from hybridbrdf.acquire.geometry import pixel_geometry
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.rig import Rig

#: A pixel is dark when every channel reads below this many noise floors.
FLOOR_SIGMAS = 3.0
#: Off-sample pixels needed to estimate a photograph's noise floor from them.
MIN_BACKGROUND = 64


def stated_noise_model(index: dict) -> Optional[NoiseModel]:
    """The noise model a capture index states (``simulated.noise``, or ``noise`` for a capture
    that was not simulated), or None."""
    if not isinstance(index, dict):
        return None
    noise = index.get("noise") or (index.get("simulated") or {}).get("noise")
    if isinstance(noise, dict) and noise.get("photons"):
        return NoiseModel(float(noise["photons"]), float(noise.get("read_noise") or 0.0))
    return None


def stated_noise_floor(index: dict) -> Optional[float]:
    """read_noise / photons from a capture index's noise model (:func:`stated_noise_model`), or None."""
    noise = stated_noise_model(index)
    return None if noise is None else noise.read_noise / noise.photons


def background_floor(photo: np.ndarray, sample: np.ndarray) -> float:
    """1.4826 x the median absolute deviation of the finite pixels off the sample, or 0."""
    bg = photo[~sample]
    bg = bg[np.isfinite(bg).all(axis=1)]
    if len(bg) < MIN_BACKGROUND:
        return 0.0
    v = bg.reshape(-1)
    return float(1.4826 * np.median(np.abs(v - np.median(v))))


def usable_pixels(rig: Rig, photos: Sequence[np.ndarray], floor: Optional[float] = None,
                  where: str = "capture", saturated: Optional[Sequence[np.ndarray]] = None
                  ) -> Tuple[List[np.ndarray], Dict[str, object]]:
    """(masks, report): per photograph the (H, W) bool mask of pixels a fit may use, and
    {"not finite": pixels left out, "saturated": pixels left out, "under-exposed": [photograph
    indices left out], "floor": [sigma per photograph]}. ``floor``: the stated noise floor (None:
    from the background); ``saturated``: per photograph the (H, W) mask of saturated pixels
    (:func:`hybridbrdf.acquire.capture.read_photo`), left out as pixels that are not finite are.
    ValueError naming ``where`` when nothing usable remains."""
    masks, report = [], {"not finite": 0, "saturated": 0, "under-exposed": [], "floor": []}
    for k, photo in enumerate(photos):
        photo = np.asarray(photo)
        clipped = np.zeros(photo.shape[:2], bool) if saturated is None else np.asarray(saturated[k], bool)
        report["saturated"] += int(clipped.sum())
        photo = np.where(clipped[..., None], np.nan, photo)
        finite = np.isfinite(photo).all(axis=2)
        report["not finite"] += int((~finite & ~clipped).sum())
        sample = pixel_geometry(rig, k).mask
        sigma = background_floor(photo, sample) if floor is None else floor
        report["floor"].append(sigma)
        seen = sample & finite
        dark = (np.where(finite[..., None], photo, 0.0) <= FLOOR_SIGMAS * sigma).all(axis=2)
        if not seen.any() or (dark & seen).sum() > 0.5 * seen.sum():
            report["under-exposed"].append(k)
            masks.append(np.zeros_like(finite))
        else:
            masks.append(finite)
    n = len(photos)
    if not any(m.any() for m in masks):
        bad = len(report["under-exposed"])
        raise ValueError(f"{where}: nothing usable: {bad} of {n} photographs under-exposed (most sample pixels "
                         f"at or below {FLOOR_SIGMAS:g}x the noise floor, {max(report['floor'] or [0]):.3g})"
                         + (f", {report['not finite']} pixels not finite" if report["not finite"] else ""))
    return masks, report
