"""What each pixel of a photograph sees (docs/ACQUISITION.md): the pinhole ray through the pixel's
centre, where it meets the sample plane z = 0, that point's uv, and the directions to the light
and to the camera in the sample's frame (the world frame: normal +z, tangent +x)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from hybridbrdf.acquire.rig import Rig


@dataclass
class PixelGeometry:
    """The pixels of one shot that see the sample: ``mask`` (H, W) bool, and for the M pixels where
    it holds (row-major order): ``point`` (M, 3), ``uv`` (M, 2), ``wi`` (M, 3) unit, to the light,
    ``wo`` (M, 3) unit, to the camera, ``distance2`` (M,) squared distance to the light."""
    mask: np.ndarray
    point: np.ndarray
    uv: np.ndarray
    wi: np.ndarray
    wo: np.ndarray
    distance2: np.ndarray


def pixel_geometry(rig: Rig, shot: int, light_position: Optional[np.ndarray] = None) -> PixelGeometry:
    """The geometry of shot ``shot`` of ``rig``: one ray through each pixel's centre (pixel (i, j)
    at column i from the left, row j from the top). ``light_position`` replaces the rig's (a
    jittered light: the rig states where the light was thought to be, this where it was)."""
    s = rig.shots[shot]
    cam = rig.cameras[s.camera]
    light = rig.lights[s.light].position if light_position is None else np.asarray(light_position, dtype=np.float64)
    w, h = rig.image_size
    right, up, forward = cam.basis()
    t = math.tan(math.radians(cam.fov_deg) / 2)
    x = (2 * (np.arange(w) + 0.5) / w - 1) * t * (w / h)
    y = (1 - 2 * (np.arange(h) + 0.5) / h) * t
    rays = forward[None, None, :] + x[None, :, None] * right + y[:, None, None] * up  # (H, W, 3)
    dz = rays[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        dist = np.where(dz < 0, -cam.position[2] / dz, np.inf)
    points = cam.position + dist[..., None] * rays
    ew, eh = rig.sample_extent
    mask = (dz < 0) & (np.abs(points[..., 0]) <= ew / 2) & (np.abs(points[..., 1]) <= eh / 2)
    p = points[mask]
    p[:, 2] = 0.0
    uv = np.stack([p[:, 0] / ew + 0.5, 0.5 - p[:, 1] / eh], axis=1)
    to_light = light - p
    d2 = (to_light * to_light).sum(axis=1)
    to_cam = cam.position - p
    wo = to_cam / np.linalg.norm(to_cam, axis=1, keepdims=True)
    return PixelGeometry(mask, p, uv, to_light / np.sqrt(d2)[:, None], wo, d2)
