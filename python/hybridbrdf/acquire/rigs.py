"""Rigs of real capture set-ups (docs/ACQUISITION.md): a phone with its flash beside the lens,
moved to N positions, and a light stage of K lights photographed by V cameras (K x V shots).

Positions spread evenly over a spherical cap above the sample (area-uniform in cos(theta), the
golden angle in phi), the first straight above it. Intensities are set so that a white Lambertian
sample (albedo 1) lit head-on from the rig's light distance reads 1: intensity = pi d^2. Every
camera looks at the sample's centre with a field of view that holds the whole sample."""

from __future__ import annotations

import math
from typing import Tuple

import numpy as np

from hybridbrdf.acquire.rig import Camera, Light, Rig, Shot, check_rig, photo_name

GOLDEN_ANGLE = math.pi * (3 - math.sqrt(5))


def cap_directions(n: int, max_theta_deg: float) -> np.ndarray:
    """(n, 3) unit directions over the cap theta <= max_theta, the first +z: cos(theta) linear in
    the index (equal areas), phi advancing by the golden angle."""
    if n < 1:
        raise ValueError(f"need at least one position, got {n}")
    if not 0 <= max_theta_deg < 90:
        raise ValueError(f"the cap's polar angle must lie in [0, 90) degrees, got {max_theta_deg}")
    i = np.arange(n)
    z = 1 - (1 - math.cos(math.radians(max_theta_deg))) * i / max(n - 1, 1)
    s = np.sqrt(np.maximum(0.0, 1 - z * z))
    phi = GOLDEN_ANGLE * i
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)


def _fov_deg(extent: Tuple[float, float], distance: float, margin: float = 1.1) -> float:
    """A vertical field of view that holds the sample's half diagonal from ``distance`` (times ``margin``)."""
    return math.degrees(2 * math.atan(margin * 0.5 * math.hypot(*extent) / distance))


def _camera(position: np.ndarray, extent, distance: float) -> Camera:
    return Camera(np.asarray(position, dtype=np.float64), np.zeros(3), np.array([0.0, 1.0, 0.0]),
                  _fov_deg(extent, distance))


def flash_rig(n: int, distance: float = 0.3, extent: Tuple[float, float] = (0.1, 0.1),
              size: Tuple[int, int] = (256, 256), max_theta_deg: float = 50.0,
              flash_offset: float = 0.01) -> Rig:
    """A phone-style capture: ``n`` photographs from positions at ``distance`` from the sample's
    centre over a cap of ``max_theta_deg``, each lit by its own flash ``flash_offset`` to the right
    of the lens (0: exactly collocated); one light per shot."""
    if not distance > 0 or not flash_offset >= 0:
        raise ValueError(f"distance must be positive and flash_offset not negative, got {distance}, {flash_offset}")
    cameras, lights, shots = [], [], []
    for k, d in enumerate(cap_directions(n, max_theta_deg)):
        cam = _camera(d * distance, extent, distance)
        right = cam.basis()[0]
        cameras.append(cam)
        lights.append(Light(cam.position + flash_offset * right, np.full(3, math.pi * distance ** 2)))
        shots.append(Shot(k, k, photo_name(k)))
    return check_rig(Rig(tuple(size), tuple(extent), cameras, lights, shots))


def light_stage_rig(k: int, v: int, light_distance: float = 1.0, camera_distance: float = 1.0,
                    extent: Tuple[float, float] = (0.1, 0.1), size: Tuple[int, int] = (256, 256),
                    light_theta_deg: float = 75.0, camera_theta_deg: float = 60.0) -> Rig:
    """A light stage: ``k`` lights over a cap of ``light_theta_deg`` at ``light_distance`` and
    ``v`` cameras over a cap of ``camera_theta_deg`` at ``camera_distance``; every camera
    photographs the sample under every light, one light at a time (k * v shots, camera-major)."""
    if not light_distance > 0 or not camera_distance > 0:
        raise ValueError(f"distances must be positive, got {light_distance}, {camera_distance}")
    # The cameras' cap is turned by half a golden angle so that no camera off the zenith sits on a
    # light. Both caps start at +z, which the turn leaves where it is: at equal distances the first
    # camera and the first light coincide, one collocated (retro-reflection) shot of the k * v, as a
    # light stage's top camera beside its top light sees (tests/python/test_acquire_verdict.py).
    cam_dirs = cap_directions(v, camera_theta_deg)
    turn = GOLDEN_ANGLE / 2
    rot = np.array([[math.cos(turn), -math.sin(turn), 0], [math.sin(turn), math.cos(turn), 0], [0, 0, 1]])
    cameras = [_camera(rot @ d * camera_distance, extent, camera_distance) for d in cam_dirs]
    lights = [Light(d * light_distance, np.full(3, math.pi * light_distance ** 2))
              for d in cap_directions(k, light_theta_deg)]
    shots = [Shot(c, l, photo_name(c * k + l)) for c in range(v) for l in range(k)]
    return check_rig(Rig(tuple(size), tuple(extent), cameras, lights, shots))
