"""Mip chains of a textured material (docs/SVBRDF.md, "Mip chains"): each coarser level holds,
per texel, what its 2x2 block of finer texels (2x1 or 1x2 once a side reaches one texel) means
for the BRDF, each quantity filtered by the rule the BRDF asks of it:

- **weights**: the mean of the normalised weights. f is linear in the weights, so a level's
  texel of a weights-only material *is* the mean of the finer texels' BRDFs (exact).
- **kd**: the mean weighted by the layer's weight, sum w_k kd_k / sum w_k (f is linear in kd
  too, so with p and z otherwise constant the layer's term is the mean of its texels' terms).
- **alpha**: per axis the weighted mean of the perceptual roughness r = sqrt(alpha), squared
  ("perceptual", the default). Measured against the exact mean of GGX lobes (docs/SVBRDF.md,
  "Mip chains"): a mixture of GGX lobes is peakier than the lobe of its mean alpha, so the best
  single alpha lies below the mean; the mean of r is nearer it than the mean of alpha ("value")
  in cMAE, and the mean of alpha^2 ("mean_square", the slopes' second moment of Toksvig 2005
  and LEAN mapping, right for Beckmann lobes and for normal variation) is the farthest. It is
  also what a GPU does to the stored map: an alpha map stores r (the spec's ``square``
  transfer), and a sampler filters r linearly.
- **eta** and the latent code **z**: the weighted mean of the values (no rule makes a mean of
  Fresnel curves or of network outputs one texel's; the error this leaves is measured in
  docs/SVBRDF.md).
- **normal** (one map for the texel, :mod:`hybridbrdf.svbrdf.normals`): the mean of the finer
  unit normals, normalised. The mean's length |n| < 1 is the spread of normals the level can
  no longer show, and it widens every layer's alpha there (Toksvig 2005):
  alpha'^2 = alpha^2 + k (1 - |n|) / |n| per axis, clamped to alpha_max, |n| the length of the
  mean over the level's whole level-0 footprint (a mean of block means over equal blocks) and
  alpha the level's alpha before widening (so widening never compounds from level to level).
  ``toksvig`` k: Toksvig's variance (1 - |n|) / |n| is the per-axis slope variance of a
  Beckmann-like lobe, whose alpha^2 is twice it (alpha^2 = 2 / (s + 2) for Blinn-Phong exponent
  s), so k = 2 is Toksvig's factor in alpha units; k = 1 adds the variance as LEAN mapping adds
  its second moment; k = 0 leaves alpha alone. bench/normal_mips.py measures them against each
  footprint's mean of f_a in its texels' own frames: k = 1 (the default) is nearer than k = 0 in
  median SMAPE and cMAE at every level and roughness measured; k = 2 is nearer still in cMAE at
  alpha 0.1 but farther than k = 0 in SMAPE (GGX's long tails already hold part of the spread).

A layer absent from a block (weight 0 in all its texels) takes the plain mean there: its values
are never evaluated, and the level stays continuous for the trilinear lookup. Chains need
power-of-two sides (a 2x2 box of a power-of-two map tiles it exactly) and are complete, down to
1x1 (spec/model.json, ``svbrdf``).
"""

from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from hybridbrdf import spec

SV = spec.SVBRDF
ALPHA_RULES = ("perceptual", "value", "mean_square")
#: k of alpha'^2 = alpha^2 + k (1 - |n|) / |n| (the module's docstring; bench/normal_mips.py).
TOKSVIG_DEFAULT = 1.0


def is_power_of_two(n: int) -> bool:
    return n > 0 and n & (n - 1) == 0


def chain_length(size) -> int:
    """Levels of a complete chain for a (W, H) map: level 0 down to 1x1."""
    return max(int(size[0]), int(size[1])).bit_length()


def level_size(size, level: int) -> Tuple[int, int]:
    """(W, H) of level ``level``: each side halved per level, never below one texel."""
    return max(1, int(size[0]) >> level), max(1, int(size[1]) >> level)


def chain_problem(size, levels: int) -> Optional[str]:
    """Why a (W, H) material cannot have ``levels`` levels, or None."""
    if levels == 1:
        return None
    w, h = size
    if not (is_power_of_two(w) and is_power_of_two(h)):
        return f"a mip chain needs power-of-two sides, the size is {w}x{h}"
    if levels != chain_length(size):
        return f"a {w}x{h} material's mip chain has 1 or {chain_length(size)} levels (down to 1x1), got {levels}"
    return None


def layer_weights(weights: Optional[np.ndarray], n_layers: int, shape) -> np.ndarray:
    """(H, W, L) float64 weights w_0..w_{L-1} of every texel, normalised as the lookup does (the
    stored w_1..3 divided by their sum above 1, w_0 = 1 - their sum)."""
    if weights is None:
        return np.ones(tuple(shape) + (1,))
    rest = weights[..., :n_layers - 1].astype(np.float64)
    total = rest.sum(axis=2, keepdims=True)
    rest = np.where(total > 1, rest / np.maximum(total, 1e-300), rest)
    return np.concatenate([np.clip(1 - rest.sum(axis=2, keepdims=True), 0, 1), rest], axis=2)


def _blocks(a: np.ndarray) -> np.ndarray:
    """(h, w, c) -> (h', w', n, c): each coarse texel's 2x2 (2x1, 1x2) block of fine texels."""
    h, w, c = a.shape
    fy, fx = (2 if h > 1 else 1), (2 if w > 1 else 1)
    return a.reshape(h // fy, fy, w // fx, fx, c).transpose(0, 2, 1, 3, 4).reshape(h // fy, w // fx, fy * fx, c)


def _weighted_mean(values: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per block, sum w x / sum w (the plain mean where the block's weights are all 0)."""
    vb, wb = _blocks(values), _blocks(w[..., None])
    total = wb.sum(axis=2)
    plain = vb.mean(axis=2)
    return np.where(total > 0, (vb * wb).sum(axis=2) / np.where(total > 0, total, 1.0), plain)


def next_level(weights: Optional[np.ndarray], maps: Sequence[Dict[str, np.ndarray]], n_layers: int,
               alpha_rule: str = "perceptual"):
    """(weights, maps) of the level below a (weights (H, W, 3) or None, per-layer maps) level, in
    float64: the rules of this module's docstring."""
    if alpha_rule not in ALPHA_RULES:
        raise ValueError(f"alpha_rule must be one of {', '.join(ALPHA_RULES)}, got {alpha_rule!r}")
    shape = (weights if weights is not None else next(a for m in maps for a in m.values())).shape[:2]
    w = layer_weights(weights, n_layers, shape)
    coarse_w = None
    if weights is not None:
        stored = np.zeros(shape + (3,))
        stored[..., :n_layers - 1] = w[..., 1:]
        coarse_w = _blocks(stored).mean(axis=2)
    coarse_maps = []
    for k, layer in enumerate(maps):
        out = {}
        for q, values in layer.items():
            x = values.astype(np.float64)
            if q == "alpha" and alpha_rule == "perceptual":
                out[q] = np.square(_weighted_mean(np.sqrt(x), w[..., k]))
            elif q == "alpha" and alpha_rule == "mean_square":
                out[q] = np.sqrt(_weighted_mean(x * x, w[..., k]))
            else:
                out[q] = _weighted_mean(x, w[..., k])
        coarse_maps.append(out)
    return coarse_w, coarse_maps


def build_chain(weights: Optional[np.ndarray], maps: Sequence[Dict[str, np.ndarray]], n_layers: int, size,
                alpha_rule: str = "perceptual", normal: Optional[np.ndarray] = None,
                toksvig: float = TOKSVIG_DEFAULT) -> List[Tuple]:
    """Levels 1 .. down to 1x1 of a level-0 (weights, maps[, normal (H, W, 2)]), each (weights,
    maps, normal) in float32 (normal None without a normal map). Every level is filtered from the
    one above it; a mean of block means over equal blocks is the mean over the whole footprint, so
    level L's weights (and mean normal) are the means over its 2^L x 2^L block. With a normal map,
    every layer needs an alpha map (the widening varies per texel: :meth:`SVBRDF.with_mips` adds
    the material's own alpha where a layer has none); ``toksvig`` is k of the module's docstring."""
    problem = chain_problem(size, chain_length(size))
    if problem:
        raise ValueError(problem)
    if normal is not None and not all("alpha" in m for m in maps):
        raise ValueError("with a normal map every layer needs an alpha map (its widening varies per texel)")
    levels = []
    w64 = None if weights is None else weights.astype(np.float64)
    m64 = [{q: a.astype(np.float64) for q, a in m.items()} for m in maps]
    n64 = None if normal is None else tangent_normals(normal)  # unit normals; their means stay unnormalised
    for _ in range(1, chain_length(size)):
        w64, m64 = next_level(w64, m64, n_layers, alpha_rule)
        out_maps = [{q: a.astype(np.float32) for q, a in m.items()} for m in m64]
        out_normal = None
        if n64 is not None:
            n64 = _blocks(n64).mean(axis=2)
            length = np.linalg.norm(n64, axis=2)
            unit = n64 / np.maximum(length, 1e-12)[..., None]
            out_normal = unit[..., :2].astype(np.float32)
            widen = toksvig * (1 - np.minimum(length, 1.0)) / np.maximum(length, 1e-12)
            for m, m_out in zip(m64, out_maps):
                a = m["alpha"]
                m_out["alpha"] = np.minimum(np.sqrt(a * a + widen[..., None]), spec.ALPHA_MAX).astype(np.float32)
        levels.append((None if w64 is None else w64.astype(np.float32), out_maps, out_normal))
    return levels


def tangent_normals(xy: np.ndarray) -> np.ndarray:
    """(..., 3) float64 unit tangent-space normals of stored (x, y) (..., 2): z = sqrt(max(0,
    1 - x^2 - y^2)) (glTF 2.0), then normalised (x^2 + y^2 > 1 leaves a vector longer than 1)."""
    xy = np.asarray(xy, dtype=np.float64)
    z = np.sqrt(np.maximum(0.0, 1.0 - np.sum(xy * xy, axis=-1, keepdims=True)))
    n = np.concatenate([xy, z], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True).clip(1e-300)


def lod_levels(lod: np.ndarray, levels: int) -> Tuple[np.ndarray, np.ndarray]:
    """(finer level (N,) int, fraction towards the next (N,)) of level-of-detail values: clamped to
    [0, levels - 1], trilinear between the two levels around it (OpenGL 4.6, 8.14.2)."""
    lod = np.clip(np.nan_to_num(np.asarray(lod, dtype=np.float64), nan=0.0), 0.0, levels - 1)
    fine = np.minimum(np.floor(lod).astype(np.int64), levels - 1)
    return fine, lod - fine


def lod_from_footprint(duv_dx: np.ndarray, duv_dy: np.ndarray, size) -> np.ndarray:
    """The isotropic level of detail of a pixel footprint (OpenGL 4.6, 8.14.1): log2 of the longer
    of its two axes measured in level-0 texels; uv derivatives (N, 2) along the pixel's x and y."""
    scale = np.asarray(size, dtype=np.float64)
    rho = np.maximum(np.linalg.norm(np.asarray(duv_dx) * scale, axis=1), np.linalg.norm(np.asarray(duv_dy) * scale, axis=1))
    return np.log2(np.maximum(rho, 1e-300))
