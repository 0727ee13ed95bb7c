"""The glTF 2.0 metallic-roughness BRDF in NumPy float64: the reference a glTF viewer approximates,
what the exported fallback material is fitted with (docs/GLTF.md, "The fallback").

Formulas (written from the texts, not from any implementation):

- glTF 2.0, Appendix B: ``specular_brdf(alpha) = V D`` with the GGX distribution and the
  height-correlated Smith visibility, ``diffuse_brdf(color) = color / pi``, Schlick's Fresnel
  ``F = f0 + (f90 - f0) (1 - |V.H|)^5``, ``material = mix(dielectric_brdf, metal_brdf, metallic)``,
  ``metal_brdf = specular_brdf * (baseColor + (1 - baseColor) fw)``.
- KHR_materials_ior and KHR_materials_specular (ratified): ``dielectric_f0 = min(((ior - 1) /
  (ior + 1))^2 specularColor, 1) specular``, ``dielectric_f90 = specular``,
  ``dielectric_brdf = F specular_brdf + (1 - max_rgb(F)) diffuse_brdf(baseColor)``.
- KHR_materials_anisotropy: ``alpha_t = mix(alpha, 1, strength^2)`` along the tangent (rotated by
  ``anisotropyRotation``), ``alpha_b = alpha``; anisotropic GGX D and the height-correlated
  ``V = 1 / (2 (N.L |(at T.V, ab B.V, N.V)| + N.V |(at T.L, ab B.L, N.L)|))`` (the extension's
  sample clamps V to [0, 1]; the reference here does not).

Directions are in the local frame of docs/CONVENTIONS.md (normal +z, tangent +x); ``wi`` is L
(toward the light), ``wo`` is V. Zero below either horizon.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from hybridbrdf.brdf.microfacet import dot, half_vector


@dataclass(frozen=True)
class GltfMaterial:
    """The parameters of a glTF metallic-roughness material with KHR_materials_ior, _specular and
    _anisotropy (their factors; textures are not part of the reference). Defaults are the
    specification's."""

    base_color: tuple = (1.0, 1.0, 1.0)
    metallic: float = 1.0
    roughness: float = 1.0
    ior: float = 1.5
    specular: float = 1.0
    specular_color: tuple = (1.0, 1.0, 1.0)
    anisotropy: float = 0.0
    #: anisotropyRotation in radians, counter-clockwise from the tangent.
    anisotropy_rotation: float = 0.0
    extras: dict = field(default_factory=dict, compare=False)

    def dielectric_f0_scale(self) -> float:
        """((ior - 1) / (ior + 1))^2; ior 0 (the specification's "no limit") gives 1."""
        if self.ior == 0.0:
            return 1.0
        r = (self.ior - 1.0) / (self.ior + 1.0)
        return r * r


def alphas(roughness: float, anisotropy: float, alpha_min: float = 0.0):
    """(alpha_t, alpha_b): alpha = roughness^2 (at least ``alpha_min``), the tangent's raised by
    KHR_materials_anisotropy to mix(alpha, 1, strength^2)."""
    alpha = max(roughness * roughness, alpha_min)
    s2 = anisotropy * anisotropy
    return alpha * (1.0 - s2) + s2, alpha


def _rotated(w: np.ndarray, angle: float) -> np.ndarray:
    """``w`` in the anisotropy frame: the tangent rotated by ``angle`` about the normal."""
    if angle == 0.0:
        return w
    c, s = math.cos(angle), math.sin(angle)
    return np.stack([c * w[:, 0] + s * w[:, 1], -s * w[:, 0] + c * w[:, 1], w[:, 2]], axis=1)


def specular_lobe(wi: np.ndarray, wo: np.ndarray, alpha_t: float, alpha_b: float) -> np.ndarray:
    """V D of Appendix B with KHR_materials_anisotropy's anisotropic D and height-correlated V,
    (N,), for directions in the anisotropy frame, both above the horizon."""
    h = half_vector(wi, wo)
    a2 = alpha_t * alpha_b
    fx, fy, fz = alpha_b * h[:, 0], alpha_t * h[:, 1], a2 * h[:, 2]
    w2 = a2 / (fx * fx + fy * fy + fz * fz)
    d = a2 * w2 * w2 / np.pi
    len_v = np.sqrt((alpha_t * wo[:, 0]) ** 2 + (alpha_b * wo[:, 1]) ** 2 + wo[:, 2] ** 2)
    len_l = np.sqrt((alpha_t * wi[:, 0]) ** 2 + (alpha_b * wi[:, 1]) ** 2 + wi[:, 2] ** 2)
    v = 0.5 / (wi[:, 2] * len_v + wo[:, 2] * len_l)
    return v * d


def gltf_eval(wi, wo, material: GltfMaterial, alpha_min: float = 0.0) -> np.ndarray:
    """The glTF BRDF f(wi, wo) of ``material``, (N, 3) float64, no cosine; 0 where either
    direction is at or below the horizon. ``alpha_min`` floors roughness^2 (a renderer's
    clamp; the specification has none, and alpha 0 is a mirror whose f is 0 almost everywhere)."""
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    above = (wi[:, 2] > 0.0) & (wo[:, 2] > 0.0)
    out = np.zeros((len(wi), 3))
    if not above.any():
        return out
    li = _rotated(wi[above], material.anisotropy_rotation)
    lo = _rotated(wo[above], material.anisotropy_rotation)
    alpha_t, alpha_b = alphas(material.roughness, material.anisotropy, alpha_min)
    lobe = specular_lobe(li, lo, alpha_t, alpha_b)[:, None]
    v_dot_h = np.abs(dot(lo, half_vector(li, lo)))[:, None]
    fw = (1.0 - np.minimum(v_dot_h, 1.0)) ** 5
    base = np.asarray(material.base_color, dtype=np.float64)[None, :]
    spec_color = np.asarray(material.specular_color, dtype=np.float64)[None, :]
    f0 = np.minimum(material.dielectric_f0_scale() * spec_color, 1.0) * material.specular
    fresnel = f0 + (material.specular - f0) * fw
    dielectric = fresnel * lobe + (1.0 - fresnel.max(axis=1, keepdims=True)) * base / np.pi
    metal = (base + (1.0 - base) * fw) * lobe
    m = material.metallic
    out[above] = (1.0 - m) * dielectric + m * metal
    return out
