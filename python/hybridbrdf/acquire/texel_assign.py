"""Texels moved to the cluster that explains them (docs/ACQUISITION_CONSENSUS.md, "Texels moved to
the cluster that explains them"): after the final clusters' materials are chosen, each texel goes
to the cluster whose material and values explain its own photographs best, when they do so by a
clear margin, before the heads, the network and the texel stage read the clusters.

Why: k-means groups texels by their analytic-only features (:mod:`~hybridbrdf.acquire.clustering`),
and at 200 photons a pixel those features are noisy enough that texels of one material land in
another's cluster. The light stage's layers have soft rims, so k-means also makes a cluster of
the rim's mixed texels, and it drew pure texels in: on the verdict's sample (light stage 8x4, high
noise) one seed put 26 pure paper_white texels with 24 rim texels under a material the network
fine-tune then bent toward the rim's mixture, another put 13 pure paper_white texels under
satin_gold, and the stripes' texels sat in the disc's cluster. Which texels strayed changed with
the seed, and so did the results: the fit's own seed spread them as much as the photographs'
noise. A cluster's chosen material scored on the texel's own photographs says where it belongs,
as a hard-EM step (k-means' assignment, in the fit's loss rather than in the features).

The score: the mean squared residual of the loss (log(eps + cos g) - log(eps + cos f), in the domain
of the data it is given: the partition's, eps 1, in the fit) over
the texel's cells, one row per (texel, photograph) cell with the cell's mean target
(:meth:`~hybridbrdf.acquire.texel_rows.ObservationTensors.cell_averaged`: the noise of a cell's
pixels averaged, and one network evaluation per cell rather than per pixel). A texel moves when
another cluster's score is below :data:`MOVE_RATIO` times its own, and that cluster explains
more of its cells better than chance would (a sign test, :data:`MOVE_Z`): a rim texel that mixes
two layers is explained about as poorly by each, and stays; a texel seen in 8 photographs stays
unless 7 of them say so."""

from __future__ import annotations

from typing import Dict, Tuple

import numpy as np
import torch

from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.texel_rows import ObservationTensors

#: Whether the cluster stage moves texels (a bench knob: off, the clusters are k-means' as merged).
MOVE = True
#: A texel moves when another cluster explains its cells with at most this times its own cluster's
#: mean squared residual (measured: docs/ACQUISITION_CONSENSUS.md).
MOVE_RATIO = 0.8
#: ... and when it explains more of the texel's cells better than a fair coin would, by this many
#: standard deviations of the coin's count (a sign test).
MOVE_Z = 2.0
#: Cells evaluated per network pass (bounds the memory of a 128x128 map's million cells).
CHUNK = 65536


def cell_rows(obs: Observations, data: ObservationTensors) -> Tuple[np.ndarray, np.ndarray]:
    """One row per (texel, photograph) cell: (rows (C,), texel (C,)), the first row of each cell."""
    _, first = np.unique(data.cell, return_index=True)
    texel_of_row = np.repeat(np.arange(len(obs.offsets) - 1), np.diff(obs.offsets))
    return first, texel_of_row[first]


def cell_errors(family, obs: Observations, data: ObservationTensors, clusters: Dict) -> Tuple[np.ndarray, np.ndarray]:
    """(errors (C, K), texel (C,)): per (texel, photograph) cell, its mean target's squared residual
    (mean over channels) under each cluster's material and values (``clusters["material"]`` (K,),
    ``clusters["centres"]`` {name: (K, c)} raw), and the cell's texel."""
    averaged = data.cell_averaged()
    rows, texel = cell_rows(obs, data)
    errors = np.zeros((len(rows), len(clusters["material"])))
    with torch.no_grad():
        for c in range(errors.shape[1]):
            for s in range(0, len(rows), CHUNK):
                r = torch.from_numpy(rows[s:s + CHUNK])
                raw = {n: v[c:c + 1].expand(len(r), -1) for n, v in clusters["centres"].items()}
                f = family.evaluate(torch.full((len(r),), int(clusters["material"][c])), raw,
                                    averaged.wi[r], averaged.wo[r])
                d = averaged.residual(r, f)
                errors[s:s + CHUNK, c] = (d * d).mean(1).double().numpy()
    return errors, texel


def _per_texel(values: np.ndarray, texel: np.ndarray, n_texels: int) -> np.ndarray:
    """Sums of ``values`` (C,) per texel."""
    return np.bincount(texel, weights=values, minlength=n_texels)


def _texel_sums(errors: np.ndarray, texel: np.ndarray, n_texels: int) -> Tuple[np.ndarray, np.ndarray]:
    """(cells (texels,), sums (texels, K)): each texel's cell count and its cells' errors summed per cluster."""
    cells = np.bincount(texel, minlength=n_texels).astype(np.float64)
    return cells, np.stack([_per_texel(errors[:, c], texel, n_texels) for c in range(errors.shape[1])], axis=1)


def texel_scores(family, obs: Observations, data: ObservationTensors, clusters: Dict) -> np.ndarray:
    """(texels, K): each texel's mean of :func:`cell_errors` over its cells under each cluster; inf
    for a texel without observations."""
    errors, texel = cell_errors(family, obs, data, clusters)
    cells, sums = _texel_sums(errors, texel, len(obs.offsets) - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        scores = sums / cells[:, None]
    scores[cells == 0] = np.inf
    return scores


def move_texels(family, obs: Observations, data: ObservationTensors, labels: np.ndarray,
                clusters: Dict) -> Tuple[np.ndarray, int]:
    """(labels, moved): each texel given the cluster whose score (its cells' mean error,
    :func:`texel_scores`) is lowest, where that is below :data:`MOVE_RATIO` times its own cluster's
    and that cluster explains more of its cells better than its own than chance would, by
    :data:`MOVE_Z` standard deviations of a fair coin's count (a sign test: n/2 + MOVE_Z sqrt(n)/2
    of n cells; 7 of 8, 22 of 32, 76 of 128). Why a count, not the mean's standard error: a cell's
    squared residual is heavy-tailed (a highlight's cells dominate), so the mean's error bar is
    wide where most cells agree, and a texel mixing two layers can have a lower mean under a
    cluster that is worse at most of its cells. Texels with fewer than 2 cells stay. Cluster
    numbers, materials and values are unchanged."""
    errors, texel = cell_errors(family, obs, data, clusters)
    n_texels = len(labels)
    cells, sums = _texel_sums(errors, texel, n_texels)
    best = sums.argmin(axis=1)
    own_sum, best_sum = sums[np.arange(n_texels), labels], sums[np.arange(n_texels), best]
    better = errors[np.arange(len(texel)), best[texel]] < errors[np.arange(len(texel)), labels[texel]]
    wins = _per_texel(better.astype(np.float64), texel, n_texels)
    move = ((cells >= 2) & (best != labels) & (best_sum < MOVE_RATIO * own_sum)
            & (wins > cells / 2 + MOVE_Z * np.sqrt(cells) / 2))
    out = np.where(move, best, labels).astype(labels.dtype)
    return out, int(move.sum())
