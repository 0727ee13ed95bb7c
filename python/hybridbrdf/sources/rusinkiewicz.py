"""Rusinkiewicz half/difference coordinates (Rusinkiewicz 1998), as the MERL
reading code (BRDFRead.cpp, Matusik et al. 2003) and the NBRDF networks
(Sztrajman et al. 2021) define them.

For unit directions ``wi`` (toward the light) and ``wo`` (toward the viewer):

    h = normalize(wi + wo),   theta_h = angle(h, +z),  phi_h = atan2(h.y, h.x)
    d = R_y(-theta_h) R_z(-phi_h) wi                       (the "difference" vector)
    theta_d = angle(d, +z),   phi_d = atan2(d.y, d.x)

``R_a(t)`` is the right-handed rotation by angle t about axis a. The two
rotations carry h onto +z, so d is wi seen from a frame whose normal is h. In
that frame wo is the mirror image of wi about the new z axis,
(-d.x, -d.y, d.z): swapping wi and wo keeps theta_h and theta_d and adds pi
to phi_d. That is why a reciprocal, isotropic BRDF is a function of
(theta_h, theta_d, phi_d mod pi) only.

The rotations are applied with the cosines and sines of phi_h and theta_h
taken straight from h (no trigonometric round trip): cos theta_h = h.z,
sin theta_h = |h_xy|, (cos phi_h, sin phi_h) = h_xy / |h_xy|. Where h = +z
exactly, phi_h is 0, as atan2(0, 0) gives in the reference code.
"""

from __future__ import annotations

from typing import Tuple

import numpy as np


def half_diff_vectors(wi: np.ndarray, wo: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """(h, d) for unit (N,3) float64 directions ``wi``, ``wo`` above the horizon.

    ``h`` is the unit half vector and ``d`` the difference vector: ``wi``
    rotated by -phi_h about the normal (z), then by -theta_h about the
    bitangent (y). Both are (N,3) float64.
    """
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    s = wi + wo
    # Both directions have z > 0, so |wi + wo| >= s.z > 0: no division by zero.
    h = s / np.sqrt((s * s).sum(axis=1, keepdims=True))
    sin_th = np.hypot(h[:, 0], h[:, 1])
    cos_th = h[:, 2]
    on_axis = sin_th <= 0.0
    safe = np.where(on_axis, 1.0, sin_th)
    # phi_h = atan2(h.y, h.x), = 0 when h is the normal (atan2(0, 0) = 0).
    cos_ph = np.where(on_axis, 1.0, h[:, 0] / safe)
    sin_ph = np.where(on_axis, 0.0, h[:, 1] / safe)
    # R_z(-phi_h) wi
    x1 = cos_ph * wi[:, 0] + sin_ph * wi[:, 1]
    y1 = -sin_ph * wi[:, 0] + cos_ph * wi[:, 1]
    z1 = wi[:, 2]
    # R_y(-theta_h): (x cos t - z sin t, y, x sin t + z cos t) with t = theta_h
    d = np.stack([x1 * cos_th - z1 * sin_th, y1, x1 * sin_th + z1 * cos_th], axis=1)
    return h, d


def half_diff_angles(wi: np.ndarray, wo: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(theta_h, phi_h, theta_d, phi_d) in radians for unit (N,3) ``wi``, ``wo``.

    theta_h, theta_d in [0, pi/2] (up to rounding), phi_h, phi_d in (-pi, pi]
    as atan2 returns them; no folding is applied here.
    """
    h, d = half_diff_vectors(wi, wo)
    # atan2 of (sin, cos) rather than acos(cos): accurate near 0 as well.
    theta_h = np.arctan2(np.hypot(h[:, 0], h[:, 1]), h[:, 2])
    phi_h = np.arctan2(h[:, 1], h[:, 0])
    theta_d = np.arctan2(np.hypot(d[:, 0], d[:, 1]), d[:, 2])
    phi_d = np.arctan2(d[:, 1], d[:, 0])
    return theta_h, phi_h, theta_d, phi_d


def dirs_from_half_diff(theta_h, phi_h, theta_d, phi_d) -> Tuple[np.ndarray, np.ndarray]:
    """The inverse map: unit (wi, wo), each (N,3) float64, from half/difference angles.

    wi = R_z(phi_h) R_y(theta_h) d and wo = R_z(phi_h) R_y(theta_h) (-d.x, -d.y, d.z)
    with d = (sin theta_d cos phi_d, sin theta_d sin phi_d, cos theta_d).
    Directions may come out below the horizon (theta_h + theta_d > pi/2 in the
    plane of incidence); callers decide what that means.
    """
    theta_h, phi_h, theta_d, phi_d = np.broadcast_arrays(
        *(np.asarray(a, dtype=np.float64).ravel() for a in (theta_h, phi_h, theta_d, phi_d))
    )
    st, ct = np.sin(theta_d), np.cos(theta_d)
    dx, dy, dz = st * np.cos(phi_d), st * np.sin(phi_d), ct
    sh, ch = np.sin(theta_h), np.cos(theta_h)
    sp, cp = np.sin(phi_h), np.cos(phi_h)

    def to_world(x, y, z):
        # R_y(theta_h): (x cos t + z sin t, y, -x sin t + z cos t), then R_z(phi_h).
        x1 = x * ch + z * sh
        z1 = -x * sh + z * ch
        return np.stack([cp * x1 - sp * y, sp * x1 + cp * y, z1], axis=1)

    return to_world(dx, dy, dz), to_world(-dx, -dy, dz)


__all__ = ["dirs_from_half_diff", "half_diff_angles", "half_diff_vectors"]
