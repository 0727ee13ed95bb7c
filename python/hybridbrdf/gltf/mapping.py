"""The closed-form mapping between a glTF metallic-roughness material and f_a's parameters
(docs/GLTF.md, "The mapping"): one function each way, used by the export (the fit's start) and
by readers of glTF assets (:func:`material_to_fa`; libhybridbrdf's tracer states the same rule).

    kd_c    = baseColor_c (1 - metallic)
    F0_c    = mix(min(((ior - 1) / (ior + 1))^2 specularColor_c, 1) specular, baseColor_c, metallic)
    eta_c   = (1 + sqrt F0_c) / (1 - sqrt F0_c), clamped to [1, 10]
    alpha   = roughness^2, clamped to [alpha_min, 1]
    alpha_x = mix(alpha, 1, s^2), alpha_y = alpha     (s: anisotropyStrength)

An anisotropyRotation that is an odd multiple of pi/2 exchanges alpha_x and alpha_y (f_a's frame
has no other rotation; other angles are taken at the nearest multiple of pi/2).
"""

from __future__ import annotations

import math

import numpy as np

from hybridbrdf import _core
from hybridbrdf.gltf.brdf import GltfMaterial, alphas

ETA_MIN, ETA_MAX = float(_core.ETA_MIN), float(_core.ETA_MAX)
ALPHA_MIN, ALPHA_MAX = float(_core.ALPHA_MIN), float(_core.ALPHA_MAX)
#: The glTF default ior's F0: ((1.5 - 1) / (1.5 + 1))^2.
F0_DEFAULT = 0.04


def eta_from_f0(f0) -> np.ndarray:
    """The real index whose normal-incidence Fresnel reflectance is ``f0``, clamped to [1, 10]."""
    r = np.sqrt(np.clip(np.asarray(f0, dtype=np.float64), 0.0, 1.0))
    with np.errstate(divide="ignore"):
        eta = np.where(r < 1.0, (1.0 + r) / np.maximum(1.0 - r, 1e-300), ETA_MAX)
    return np.clip(eta, ETA_MIN, ETA_MAX)


def f0_from_eta(eta) -> np.ndarray:
    """((eta - 1) / (eta + 1))^2, the normal-incidence reflectance of a real index."""
    eta = np.asarray(eta, dtype=np.float64)
    r = (eta - 1.0) / (eta + 1.0)
    return r * r


def quarter_turns(rotation: float) -> int:
    """anisotropyRotation as a whole number of quarter turns (0..3), the nearest one."""
    return int(round(float(rotation) / (0.5 * math.pi))) % 4


def material_to_fa(material: GltfMaterial) -> dict:
    """f_a's parameters ``{"kd": (3,), "eta": (3,), "alpha": (alpha_x, alpha_y)}`` (float64) of a
    glTF material by the closed-form mapping of the module docstring."""
    base = np.asarray(material.base_color, dtype=np.float64)
    m = float(material.metallic)
    spec_color = np.asarray(material.specular_color, dtype=np.float64)
    # min(., 1): KHR_materials_specular's clamp (specularColor may exceed 1)
    dielectric_f0 = np.minimum(material.dielectric_f0_scale() * spec_color, 1.0) * material.specular
    f0 = (1.0 - m) * dielectric_f0 + m * base
    alpha_t, alpha_b = alphas(material.roughness, material.anisotropy)
    alpha_t, alpha_b = (min(max(a, ALPHA_MIN), ALPHA_MAX) for a in (alpha_t, alpha_b))
    if quarter_turns(material.anisotropy_rotation) % 2:
        alpha_t, alpha_b = alpha_b, alpha_t
    return {"kd": np.clip(base * (1.0 - m), 0.0, 1.0), "eta": eta_from_f0(f0), "alpha": np.array([alpha_t, alpha_b])}


def _metallic_for(kd: np.ndarray, f0: np.ndarray) -> float:
    """The smallest metallic m (on a 1/1000 grid) for which baseColor = kd / (1 - m) <= 1 and the
    dielectric F0 left, (F0 - m baseColor) / (1 - m), lies in [0, 1]; else the m of least
    violation. A plastic keeps m = 0; a bare metal (kd 0, F0 high) gets m near 1."""
    m = np.linspace(0.0, 0.999, 1000)[:, None]
    base = kd[None, :] / (1.0 - m)
    dielectric = (f0[None, :] - m * base) / (1.0 - m)
    violation = (np.maximum(base - 1.0, 0.0) + np.maximum(dielectric - 1.0, 0.0)
                 + np.maximum(-dielectric, 0.0)).sum(axis=1)
    ok = np.flatnonzero(violation <= 1e-12)
    return float(m[ok[0], 0] if len(ok) else m[np.argmin(violation), 0])


def fa_to_material(kd, eta, alpha) -> GltfMaterial:
    """A glTF material whose :func:`material_to_fa` is f_a's (kd, eta, alpha), exactly where the
    glTF parameters can hold it: metallic from :func:`_metallic_for`, ior carrying the largest
    dielectric F0 and specularColor its tint (each <= 1), specular 1, roughness sqrt of the
    smaller alpha, anisotropy strength sqrt((alpha_big - alpha_small) / (1 - alpha_small)),
    rotated a quarter turn when alpha_y is the larger. The fit's start (docs/GLTF.md)."""
    kd = np.asarray(kd, dtype=np.float64) * np.ones(3)
    f0 = f0_from_eta(np.asarray(eta, dtype=np.float64) * np.ones(3))
    ax, ay = (float(a) for a in np.asarray(alpha, dtype=np.float64) * np.ones(2))
    m = _metallic_for(kd, f0)
    base = np.clip(kd / (1.0 - m), 0.0, 1.0)
    dielectric = np.clip((f0 - m * base) / (1.0 - m), 0.0, 0.999999)
    level = float(dielectric.max())
    ior = float((1.0 + math.sqrt(level)) / (1.0 - math.sqrt(level))) if level > 0 else 1.0
    color = dielectric / level if level > 0 else np.ones(3)
    small, big = min(ax, ay), max(ax, ay)
    strength = math.sqrt(max(big - small, 0.0) / (1.0 - small)) if small < 1.0 else 0.0
    return GltfMaterial(base_color=tuple(base), metallic=m, roughness=math.sqrt(small), ior=ior, specular=1.0,
                        specular_color=tuple(np.clip(color, 0.0, 1.0)), anisotropy=strength,
                        anisotropy_rotation=0.0 if ax >= ay else 0.5 * math.pi)
