"""The cluster stage's merge (docs/ACQUISITION_GAP.md, "Clusters split finely, then merged"):
k-means on the analytic fit's features (:func:`~hybridbrdf.acquire.clustering.texel_clusters`)
knows nothing of noise, so with a fixed count it splits one material photographed under noise
into two clusters as readily as it keeps two materials in one. Both happened on the light-stage
bench: colodur_napoli, one uniform material, fell into two clusters that chose different
materials of the prior (the texels of the worse scored 2.4x the full measurement's cMAE, of the
better 1.6x, and which of the two held more texels decided the capture's score), while paper3's
two coated layers shared one cluster because paper_white had taken two.

So the stage clusters finely (:data:`SPLIT_CLUSTERS`, on maps with :data:`SPLIT_TEXELS` texels a
cluster: :func:`split_count`), fits every cluster as before
(:func:`~hybridbrdf.acquire.cluster_fit.fit_clusters`), then merges what the photographs cannot
tell apart. For a pair (a, b): one set of values of a's material, and one of b's, each fitted to
the rows of the pair's pure texels (:func:`~hybridbrdf.acquire.cluster_fit.fit_material`, its MAP objective),
the better kept; the pair's *ratio* is the worse of the two clusters' mean squared residual on
its own rows under that pooled fit over the same under its own fit (each plus :data:`MERGE_FLOOR`). The worse of the two, not
their mean: a cluster of rim texels beside a large pure one would otherwise merge into it unseen.
The pair of lowest ratio merges while its ratio is at most :data:`MERGE_RATIO`; while more than
``limit`` clusters remain after that, the pair whose merge adds the least residual over both
clusters' photographed rows merges (a ratio would merge a cluster of rim texels, which no fit
explains, with whatever it is tested against). On the bench's captures, pairs of one material's clusters read
0.3-1.0 and pairs of different materials 1.3 and above."""

from __future__ import annotations

from typing import Dict, Optional, Tuple

import numpy as np
import torch

from hybridbrdf.acquire import cluster_fit
from hybridbrdf.acquire.material_fits import MaterialFit, fit_materials, loss_rows, value_spread
from hybridbrdf.acquire.network_tune import pure_rows
from hybridbrdf.acquire.texel_rows import Progress

#: Clusters k-means makes before the merge (a textured material's base and 3 layers, each of
#: them allowed a split that the merge undoes).
SPLIT_CLUSTERS = 6
#: Photographed texels per cluster below which k-means does not split finer than the limit: a
#: cluster's material is chosen on its pure texels (8 neighbours in it too), a 3x3 block at least
#: (after the merge, the final clusters' materials are chosen again: cluster_fit.FINAL_ROWS).
SPLIT_TEXELS = 9
#: A pair of clusters merges when the pooled fit explains each cluster's rows within this factor
#: of the residual its own fit leaves (module docstring).
MERGE_RATIO = 1.2
#: Added to both residuals of the ratio: the mean squared log residual of a photometric error of
#: about 0.3%. Below it two fits differ by their optimiser's last steps, not by what they explain
#: (one noiseless material's two clusters read 1.9 without it, in the merge's test).
MERGE_FLOOR = 1e-5


def split_count(photographed: int, limit: int) -> int:
    """The clusters k-means makes for a map of ``photographed`` texels with observations, ``limit``
    the most the fit keeps: :data:`SPLIT_CLUSTERS` where each can hold :data:`SPLIT_TEXELS`, else ``limit``."""
    return max(limit, min(SPLIT_CLUSTERS, photographed // SPLIT_TEXELS))


def _loss_on(family, data, rows: torch.Tensor, material: int, values: Dict[str, torch.Tensor]) -> float:
    """Mean squared residual of ``material`` with one set of ``values`` {name: (c,)} on ``rows``."""
    with torch.no_grad():
        return float(loss_rows(family, data, torch.full((len(rows),), int(material)),
                                {n: v.reshape(1, -1).expand(len(rows), -1) for n, v in values.items()}, rows))


def pooled_fits(family, obs, data, labels: np.ndarray, clusters: Dict, pairs, seed: int,
                progress: Optional[Progress] = None) -> Dict[Tuple[int, int], Tuple[float, float, list]]:
    """The merge test of every pair (a, b) of ``pairs`` (module docstring), their fits all in one
    batched problem (:func:`~hybridbrdf.acquire.material_fits.fit_materials`: the same fits as one
    after the other): {pair: (ratio, cost, the two pooled fits best first, each as
    :func:`~hybridbrdf.acquire.cluster_fit.fit_material` returns it)}; the cost is the residual the
    merge adds over both clusters' photographed rows (a forced merge's measure: see :func:`merge_clusters`).
    ``progress("merge", step, steps)`` after each step of the fits."""
    every = family.raw_of_materials()
    tau2 = value_spread(every)
    centres = clusters["centres"]
    jobs, own_rows = [], []
    for a, b in pairs:
        own_rows.append([cluster_fit._cluster_rows(obs, labels, c, cluster_fit.CLUSTER_ROWS, seed) for c in (a, b)])
        # Fitted as the merged cluster would be: on rows of its pure texels, so each cluster weighs as its
        # size (a forced merge of a rim's cluster into a layer leaves the layer's fit nearly as it was).
        union = np.where(labels == b, a, labels)
        both = cluster_fit._cluster_rows(obs, union, a, cluster_fit.CLUSTER_ROWS, seed)
        shots = len(np.unique(obs.shot[both.numpy()]))
        noise = data.pixel_noise(pure_rows(obs, union, a))
        for c in (a, b):
            m = int(clusters["material"][c])
            jobs.append(MaterialFit(both, m, {n: v[c] for n, v in centres.items()},
                                    {**{n: v[m] for n, v in every.items()}, "tau2": tau2}, shots, noise))
    fitted = fit_materials(family, data, jobs, cluster_fit.CLUSTER_STEPS, seed, "merge", progress)
    counts = np.diff(obs.offsets)
    out = {}
    for i, (a, b) in enumerate(pairs):
        fits = sorted(fitted[2 * i:2 * i + 2], key=lambda f: f["score"])
        best = fits[0]
        pooled = [_loss_on(family, data, r, best["material"], best["raw"]) for r in own_rows[i]]
        own = [_loss_on(family, data, r, int(clusters["material"][c]), {n: v[c] for n, v in centres.items()})
               for c, r in zip((a, b), own_rows[i])]
        photographed = [float(counts[labels == c].sum()) for c in (a, b)]
        cost = sum(n * (p - o) for n, p, o in zip(photographed, pooled, own))
        out[(a, b)] = (max((p + MERGE_FLOOR) / (o + MERGE_FLOOR) for p, o in zip(pooled, own)), cost, fits)
    return out


def _own_fit(clusters: Dict, c: int) -> dict:
    """Cluster ``c``'s own fit as :func:`~hybridbrdf.acquire.cluster_fit.fit_material` returns one."""
    loss = float(clusters["sigma2"][c])
    return {"material": int(clusters["material"][c]), "loss": loss, "score": loss,
            "raw": {n: v[c] for n, v in clusters["centres"].items()}}


def _merged(labels: np.ndarray, clusters: Dict, a: int, b: int, fits: list) -> Tuple[np.ndarray, Dict, np.ndarray]:
    """Labels and clusters with ``b`` merged into ``a`` (its entry the pooled fit ``fits[0]``), renumbered
    by decreasing size as :func:`~hybridbrdf.acquire.clustering.kmeans` numbers them, and the
    renumbering (old cluster -> new; ``b`` -> ``a``'s)."""
    labels = np.where(labels == b, a, labels)
    best = fits[0]
    material, sigma2 = clusters["material"].clone(), clusters["sigma2"].clone()
    centres = {n: v.clone() for n, v in clusters["centres"].items()}
    candidates = list(clusters["candidates"])
    material[a], sigma2[a], candidates[a] = best["material"], max(best["loss"], 1e-8), fits
    for n in centres:
        centres[n][a] = best["raw"][n]
    keep = [c for c in range(len(material)) if c != b]
    sizes = np.bincount(labels, minlength=len(material))
    order = sorted(keep, key=lambda c: -sizes[c])
    renumber = np.zeros(len(material), dtype=np.int64)
    renumber[order] = np.arange(len(order))
    renumber[b] = renumber[a]
    index = torch.tensor(order)
    out = {**clusters, "material": material[index], "sigma2": sigma2[index],
           "centres": {n: v[index] for n, v in centres.items()}, "candidates": [candidates[c] for c in order]}
    return renumber[labels], out, renumber


def merge_clusters(family, obs, data, labels: np.ndarray, clusters: Dict, seed: int, limit: int,
                   merge_ratio: Optional[float] = None, progress: Optional[Progress] = None) -> Tuple[np.ndarray, Dict]:
    """(labels, clusters) after the module docstring's merges: the pair of lowest ratio merges while
    it is at most ``merge_ratio`` (default :data:`MERGE_RATIO`); then, while more than ``limit``
    clusters remain, the pair of least added residual. Clusters without rows (texels never photographed) are not tested; the largest
    cluster takes them when too many remain. Returns clusters with "merges": [(a, b, ratio)] per
    merge in the numbering of its time, and "labels" the merged labels (a tensor: resumed fits
    restore them with the clusters). ``progress`` gets ("merge", step, steps) per step of a round's fits."""
    ratio_bar = MERGE_RATIO if merge_ratio is None else merge_ratio
    merges, tested = [], {}
    while len(clusters["material"]) > 1:
        k = len(clusters["material"])
        photographed = [c for c in range(k) if len(pure_rows(obs, labels, c))]
        todo = [(a, b) for a in photographed for b in photographed if a < b and (a, b) not in tested]
        if todo:
            tested.update(pooled_fits(family, obs, data, labels, clusters, todo, seed, progress))
        natural = [(v[0], pair) for pair, v in tested.items() if v[0] <= ratio_bar]
        if natural:  # the pair the photographs tell apart least
            a, b = min(natural)[1]
        elif k <= limit:
            break
        elif tested:  # too many clusters: the merge that adds the least residual (a rim's cluster into
            a, b = min(tested, key=lambda pair: tested[pair][1])  # its neighbour, not two large layers)
        else:
            a, b = 0, k - 1
        ratio, fits = (tested[(a, b)][0], tested[(a, b)][2]) if (a, b) in tested else (float("nan"), [_own_fit(clusters, 0)])
        merges.append((a, b, float(ratio)))
        labels, clusters, renumber = _merged(labels, clusters, a, b, fits)
        # Pairs of the clusters left keep their tests, renumbered; pairs with the merged one are redone.
        tested = {tuple(sorted((int(renumber[x]), int(renumber[y])))): v for (x, y), v in tested.items()
                  if a not in (x, y) and b not in (x, y)}
    return labels, {**clusters, "merges": merges, "labels": torch.from_numpy(np.asarray(labels, dtype=np.int64))}


def merge_line(clusters: Dict) -> str:
    """What the merge did, a line for the fit's log (``hbrdf acquire fit`` prints it)."""
    merges = clusters.get("merges", [])
    moved = ("" if "moved" not in clusters else
             f"; {clusters['moved']:,} texel(s) moved to the cluster whose material explains their photographs best")
    if not merges:
        return f"clusters: {len(clusters['material'])}, none merged" + moved
    return (f"clusters: k-means made {len(clusters['material']) + len(merges)}, merged to {len(clusters['material'])} "
            f"(a pair merges when one fit explains both within {MERGE_RATIO}x, or when too many are left; the "
            f"merges' ratios: " + ", ".join(f"{r:.2f}" for _, _, r in merges) + ")" + moved)
