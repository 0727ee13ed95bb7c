"""What a capture says about each texel (docs/ACQUISITION.md, issue 46 step 2's input): every
photographed pixel turned back into a BRDF value at its texel,

    g_obs = L d^2 / (I cos(theta_i)),

the inverse of the simulator's radiometry, with the pixel's own wi and wo in the sample's frame.
A pixel belongs to the texel whose cell holds its uv (``nearest``: texel (i, j) covers
[i / W, (i + 1) / W) x [j / H, (j + 1) / H)). A fit per texel reads its rows; a fit that shares
work between texels (clusters, a pyramid) reads them all at once.

Stated masking: pixels that do not see the sample, pixels lit or seen at grazing angles
(cos(theta_i) or cos(theta_o) below ``min_cos``: the division by cos(theta_i) amplifies their
noise without bound, and a pixel's footprint there spans many texels), pixels of a light with a
channel of zero intensity and pixels outside the caller's ``usable`` masks (NaN pixels, under-exposed
photographs: :mod:`hybridbrdf.acquire.exposure`) are left out; the counts are kept
(``Observations.dropped``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

from hybridbrdf.acquire.geometry import pixel_geometry
from hybridbrdf.acquire.rig import Rig

#: Default smallest cos(theta_i) and cos(theta_o) of a kept pixel (about 87 degrees).
MIN_COS = 0.05


@dataclass
class Observations:
    """Per texel of a (W, H) map, its observations: rows ``offsets[t]:offsets[t + 1]`` of ``wi``,
    ``wo`` (M, 3) unit, ``value`` (M, 3) the BRDF estimate (no cosine; noise can make it negative),
    ``uv`` (M, 2) and ``shot`` (M,) the photograph; texel t = j * W + i. ``dropped`` counts the
    pixels of the sample left out, by reason."""
    size: Tuple[int, int]
    offsets: np.ndarray
    wi: np.ndarray
    wo: np.ndarray
    value: np.ndarray
    uv: np.ndarray
    shot: np.ndarray
    dropped: Dict[str, int] = field(default_factory=dict)

    def rows(self, texel: int) -> slice:
        """The rows of texel ``texel`` (j * W + i)."""
        return slice(int(self.offsets[texel]), int(self.offsets[texel + 1]))

    def counts(self) -> np.ndarray:
        """(H, W) observations per texel."""
        w, h = self.size
        return np.diff(self.offsets).reshape(h, w)


def texel_observations(rig: Rig, photos: Sequence[np.ndarray], size: Tuple[int, int],
                       min_cos: float = MIN_COS, usable: Optional[Sequence[np.ndarray]] = None) -> Observations:
    """The observations of a texel map of ``size`` (W, H) from ``photos`` (one (H, W, 3) linear
    radiance image per shot of ``rig``, finite), with the rig's stated light positions.
    ``usable``: per photograph an (H, W) bool mask; pixels outside it are left out (counted as
    ``masked``) and may hold anything, NaN included (:mod:`hybridbrdf.acquire.exposure`)."""
    w, h = int(size[0]), int(size[1])
    if w < 1 or h < 1:
        raise ValueError(f"the texel map needs a positive size, got {w}x{h}")
    if len(photos) != len(rig.shots):
        raise ValueError(f"{len(photos)} photographs for the rig's {len(rig.shots)} shots")
    pw, ph = rig.image_size
    parts = {"wi": [], "wo": [], "value": [], "uv": [], "shot": [], "texel": []}
    dropped = {"grazing": 0, "dark light channel": 0, "masked": 0}
    if usable is not None and len(usable) != len(photos):
        raise ValueError(f"{len(usable)} usable-pixel masks for {len(photos)} photographs")
    for k, (shot, photo) in enumerate(zip(rig.shots, photos)):
        photo = np.asarray(photo)
        if photo.shape != (ph, pw, 3):
            raise ValueError(f"photograph {k} ({shot.image}) has shape {photo.shape}; the rig says {(ph, pw, 3)}")
        ok = np.ones((ph, pw), dtype=bool) if usable is None else np.asarray(usable[k], dtype=bool)
        if ok.shape != (ph, pw):
            raise ValueError(f"usable-pixel mask {k} has shape {ok.shape}; the rig says {(ph, pw)}")
        if not np.isfinite(photo[ok]).all():
            raise ValueError(f"photograph {k} ({shot.image}) has values that are not finite")
        geo = pixel_geometry(rig, k)
        intensity = rig.lights[shot.light].intensity
        masked = ~ok[geo.mask]
        dropped["masked"] += int(masked.sum())
        keep = (geo.wi[:, 2] >= min_cos) & (geo.wo[:, 2] >= min_cos) & ~masked
        dropped["grazing"] += int((~keep & ~masked).sum())
        if (intensity <= 0).any():
            dropped["dark light channel"] += int(keep.sum())
            continue
        radiance = photo[geo.mask][keep].astype(np.float64)
        scale = geo.distance2[keep] / geo.wi[keep, 2]
        uv = geo.uv[keep]
        col = np.clip(np.floor(uv[:, 0] * w), 0, w - 1).astype(np.int64)
        row = np.clip(np.floor(uv[:, 1] * h), 0, h - 1).astype(np.int64)
        parts["wi"].append(geo.wi[keep])
        parts["wo"].append(geo.wo[keep])
        parts["value"].append(radiance * scale[:, None] / intensity)
        parts["uv"].append(uv)
        parts["shot"].append(np.full(len(uv), k, dtype=np.int32))
        parts["texel"].append(row * w + col)
    cat = {name: (np.concatenate(v) if v else np.zeros((0,) + ((3,) if name in ("wi", "wo", "value") else
                                                                (2,) if name == "uv" else ())))
           for name, v in parts.items()}
    texel = cat["texel"].astype(np.int64)
    order = np.argsort(texel, kind="stable")
    offsets = np.zeros(w * h + 1, dtype=np.int64)
    np.cumsum(np.bincount(texel, minlength=w * h), out=offsets[1:])
    return Observations((w, h), offsets, cat["wi"][order].astype(np.float32), cat["wo"][order].astype(np.float32),
                        cat["value"][order].astype(np.float32), cat["uv"][order].astype(np.float32),
                        cat["shot"][order].astype(np.int32), dropped)
