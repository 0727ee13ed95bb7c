"""A pixel's footprint on the texel map: the fits' observation model (the texel stage,
:mod:`~hybridbrdf.acquire.texel_stage`, and the analytic-only fit; docs/ACQUISITION_FOOTPRINT.md).

A fit's texels are not seen one by one. The simulator renders a pixel at uv with the weights map
looked up bilinearly between texel centres, and the textured material a fit exports
(:meth:`~hybridbrdf.acquire.hybrid_fit.HybridMaps.svbrdf`, docs/SVBRDF.md) is rendered the same
way: its layer weights filtered (which filters the BRDFs), each layer's values p, z filtered as
values. A pixel in texel t's cell therefore shows t's neighbours too: up to three quarters of
what it sees (at the cell's corner; 7/16 on average over the cell) comes from the three texels
nearest its uv. Where they are t's own material that
changes little; where a layer boundary crosses the footprint, a fit that credits the whole pixel
to t fits t to a mixture: the rim texels of a layer come out between the two materials and the
pixels beside them are explained twice.

So the fit predicts each pixel as the exported material shows it. With the four bilinear taps
(texel u, weight b_u) at the pixel's uv and l(u) each texel's layer (its cluster):

    f(uv, wi, wo) = sum_k w_k f_t(wi, wo; p_k, layer k),   w_k = sum_{u: l(u) = k} b_u,
    p_k = sum_u b_u (p_u if l(u) = k else the fill value of layer k),

the fill value being what the exported maps hold outside a layer (the fit uses the cluster's
values; the export its texels' mean). One evaluation per layer a footprint touches: one inside a
layer, two to four on its boundary. The values are blended decoded (kd, eta, alpha, z), as a
texture unit filters the stored maps."""

from __future__ import annotations

from typing import Dict

import numpy as np
import torch

from hybridbrdf.svbrdf.asset import texel_taps

#: The fits' observation model (the texel stage; the analytic-only fit unless told): "bilinear"
#: (this module) or "nearest" (every pixel credited to the texel whose cell holds it, the model until
#: 2026-11-30; bench knobs: bench/acquire_gap.py's ``footprint_nearest``, acquire_verdict.py's
#: ``--observation-model``).
MODEL = "bilinear"
MODELS = ("bilinear", "nearest")


class Footprint:
    """The bilinear footprints of ``uv`` (M, 2) rows on a (W, H) = ``size`` map whose texels belong
    to layers ``labels`` (n_texels,) with ``fill`` {name: (layers, c)} decoded values outside each."""

    def __init__(self, uv: np.ndarray, size, labels: np.ndarray, fill: Dict[str, torch.Tensor]):
        self.uv, self.size = uv, (int(size[0]), int(size[1]))
        self.labels = torch.as_tensor(np.asarray(labels, dtype=np.int64))
        self.fill = fill

    def taps(self, rows: torch.Tensor):
        """(texel (N, 4) long, weight (N, 4) float32) of the rows' bilinear taps (clamped at the edges)."""
        taps = texel_taps(self.uv[rows.numpy()], self.size, "clamp", "bilinear")
        texel = np.stack([r * self.size[0] + c for r, c, _ in taps], axis=1)
        weight = np.stack([t for _, _, t in taps], axis=1)
        return torch.from_numpy(texel), torch.from_numpy(weight.astype(np.float32))

    def predict(self, evaluate, table: Dict[str, torch.Tensor], offset: torch.Tensor, rows: torch.Tensor,
                wi: torch.Tensor, wo: torch.Tensor) -> torch.Tensor:
        """f (N, 3) of ``rows`` as the module docstring says. ``table`` {name: (T, c)} holds decoded
        values per texel, the row's texel u read at ``offset[row] + u`` (one map per twin);
        ``evaluate(layer (n,), values {name: (n, c)}, wi, wo)`` is f_t of each layer."""
        texel, weight = self.taps(rows)
        layer = self.labels[texel]
        out = torch.zeros((len(rows), 3), dtype=torch.float32)
        index = offset[:, None] + texel
        # Every value in one (T, C) table, so that each layer's blend is one gather of (n, 4, C) and
        # its backward one scatter, not one per value (the texel stage's largest cost after the network).
        names = list(table)
        widths = [table[n].shape[1] for n in names]
        packed = torch.cat([table[n] for n in names], dim=1)
        for k in torch.nonzero(torch.bincount(layer.reshape(-1)))[:, 0].tolist():  # torch.unique, without its sort
            member = (layer == k).to(weight.dtype)
            w_k = (weight * member).sum(1)
            hit = torch.nonzero(w_k > 0)[:, 0]
            everyone = len(hit) == len(rows)  # a layer every footprint touches (a map of one layer): no gathers
            b, m = (weight, member) if everyone else (weight[hit], member[hit])
            blended = ((b * m)[..., None] * packed[index if everyone else index[hit]]).sum(1)
            outside = (b * (1 - m)).sum(1, keepdim=True)  # 0 on a map of one layer (no fill needed)
            values = {}
            for n, v in zip(names, torch.split(blended, widths, dim=1)):
                values[n] = v + outside * self.fill[n][k] if n in self.fill else v
            a, c = (wi, wo) if everyone else (wi[hit], wo[hit])
            f = evaluate(torch.full((len(hit),), k, dtype=torch.long), values, a, c)
            out = out + w_k[:, None] * f.to(out.dtype) if everyone else out.index_add(0, hit, w_k[hit, None] * f.to(out.dtype))
        return out


def rim_texels(layer: np.ndarray) -> np.ndarray:
    """(H, W) bool: the texels of a (H, W) ``layer`` map with a texel of another layer among their
    eight neighbours (the map's edge clamped): those whose pixels' footprints cross a layer boundary."""
    h, w = layer.shape
    padded = np.pad(layer, 1, mode="edge")
    rim = np.zeros(layer.shape, dtype=bool)
    for dy in range(3):
        for dx in range(3):
            rim |= padded[dy:dy + h, dx:dx + w] != layer
    return rim


def cap_rim_kd(kd: np.ndarray, layer: np.ndarray) -> tuple:
    """``kd`` (H * W, 3) with each rim texel (:func:`rim_texels`) no brighter, per channel, than the
    brightest texel inside its layer; (capped kd, how many texels changed). Why: a layer's energy
    table is fitted for its brightest texel and scales every texel of the layer
    (:func:`hybridbrdf.fit.painting.bound_bright_kd`), and a rim texel is the least certain of all:
    what its pixels show is shared with another layer, and the footprint model extrapolates its
    values to explain it. On the light-stage bench one such texel, kd 0.91 against 0.87 inside its
    layer, made paper_white's pure texels 1.7x worse (docs/ACQUISITION_FOOTPRINT.md). A layer without
    inner texels keeps its kd."""
    kd = kd.copy()
    flat, rim = layer.reshape(-1), rim_texels(layer).reshape(-1)
    changed = 0
    for k in np.unique(flat):
        inner, edge = (flat == k) & ~rim, (flat == k) & rim
        if inner.any() and edge.any():
            capped = np.minimum(kd[edge], kd[inner].max(axis=0))
            changed += int((capped != kd[edge]).any(axis=1).sum())
            kd[edge] = capped
    return kd, changed


def filtered(maps: Dict[str, np.ndarray], uv: np.ndarray) -> Dict[str, np.ndarray]:
    """Each (H, W, c) map of ``maps`` read at uv (N, 2) as a texture unit reads it: bilinear between
    texel centres, clamped at the edges; {name: (N, c) float64}."""
    h, w = next(iter(maps.values())).shape[:2]
    taps = texel_taps(np.asarray(uv, dtype=np.float64), (w, h), "clamp", "bilinear")
    return {n: sum(t[:, None] * np.asarray(m, np.float64)[rows, cols] for rows, cols, t in taps) for n, m in maps.items()}
