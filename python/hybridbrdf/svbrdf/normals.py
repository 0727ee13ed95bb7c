"""Normal maps of textured materials (docs/SVBRDF.md, "Normal maps"): the shading frame a texel's
tangent-space normal builds from the geometric frame, and the rule for directions its horizon
cuts off. libhybridbrdf's twin is cpp/include/hybridbrdf/normal_map.hpp.

Convention (glTF 2.0 ``normalTexture``): the map stores x and y in [-1, 1] (8-bit: offset -1,
scale 2, linear), z = sqrt(max(0, 1 - x^2 - y^2)). +x is the tangent t (increasing u), +y the
bitangent b = n x t of the right-handed geometric frame (t, b, n); with this library's uv (v = 0
the image's top row, glTF's) b points towards *decreasing* v, the image's top, for a uv map that
is not mirrored: green up, OpenGL-style, as glTF's bitangent = cross(normal, tangent.xyz) *
tangent.w with w = +1. A mirrored uv map (glTF w = -1) needs the engine's own b.

The frame: n_s = normalize(x t + y b + z n); t_s = t - (t . n_s) n_s normalised (Gram-Schmidt:
the anisotropic alpha_x axis stays as near the tangent as the new normal allows); b_s = n_s x t_s.

Directions below a horizon: f = 0 unless wi and wo are both above the shading horizon (n_s) and
the geometric one (n). The same test for wi and wo, so the texel stays reciprocal where its layers
are; it only removes lobe, so the perturbed frame's albedo stays within the layers' bound. The
alternatives and why not: flipping a direction to its mirror about the shading plane invents
light where the shading frame sees none and breaks the energy bound at grazing angles; clamping
cos to the horizon does the same; Schussler et al. 2017 (microfacet-based normal mapping) keeps
energy and continuity but adds a second facet, a multiple-scattering estimate and its own
sampler per evaluation, beyond a texel lookup. Zeroing darkens the grazing fringe of steep
normals, which is the visible cost, measured in tests/python/test_svbrdf_normals.py.
"""

from __future__ import annotations

from typing import Tuple

import numpy as np

from hybridbrdf.errors import InputFileError
from hybridbrdf.svbrdf.maps import map_bits, read_map
from hybridbrdf.svbrdf.mips import tangent_normals

__all__ = ["tangent_normals", "shading_frame", "to_shading", "read_normal_map"]


def read_normal_map(path) -> np.ndarray:
    """(H, W, 2) float32 tangent-space x, y of a glTF-style normal map: an 8-bit RGB PNG whose R and
    G hold (x + 1) / 2 and (y + 1) / 2 (B, z, is reconstructed, not read), green up as glTF's.
    One-line InputFileError naming the file for anything else (an EXR, RGBA, 16 bits)."""
    if map_bits(path) != 8:
        raise InputFileError(path, "a normal map is an 8-bit RGB PNG (glTF 2.0 style: R, G = (x + 1) / 2, (y + 1) / 2)")
    stored, _ = read_map(path)
    return (stored[..., :2] * 2.0 - 1.0).astype(np.float32)


def shading_frame(normal: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t_s, b_s, n_s), each (N, 3) float64, of unit tangent-space normals (N, 3): the shading frame
    in the geometric frame's coordinates (t = +x, b = +y, n = +z). A normal along +-t (z = 0, so
    Gram-Schmidt leaves nothing of t) takes t_s = b x n_s normalised, as normal_map.hpp does."""
    n_s = np.asarray(normal, dtype=np.float64)
    n_s = n_s / np.linalg.norm(n_s, axis=1, keepdims=True).clip(1e-300)
    t = np.zeros_like(n_s)
    t[:, 0] = 1.0
    t_s = t - np.sum(t * n_s, axis=1, keepdims=True) * n_s
    length = np.linalg.norm(t_s, axis=1, keepdims=True)
    fallback = np.cross(np.array([0.0, 1.0, 0.0]), n_s)  # b x n_s: orthogonal to n_s, nonzero when n_s is +-t
    t_s = np.where(length > 1e-6, t_s / length.clip(1e-300), fallback / np.linalg.norm(fallback, axis=1, keepdims=True).clip(1e-300))
    return t_s, np.cross(n_s, t_s), n_s


def to_shading(normal: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(wi_s, wo_s, visible): geometric-frame directions (N, 3) expressed in each texel's shading
    frame (float64), and whether f may be nonzero (both above both horizons; the module's rule)."""
    t_s, b_s, n_s = shading_frame(normal)
    wi, wo = (np.asarray(w, dtype=np.float64) for w in (wi, wo))

    def local(w):
        return np.stack([np.sum(w * t_s, axis=1), np.sum(w * b_s, axis=1), np.sum(w * n_s, axis=1)], axis=1)

    wi_s, wo_s = local(wi), local(wo)
    visible = (wi_s[:, 2] > 0) & (wo_s[:, 2] > 0) & (wi[:, 2] > 0) & (wo[:, 2] > 0)
    return wi_s, wo_s, visible
