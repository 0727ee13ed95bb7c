"""The cluster stage's merge (acquire/cluster_merge.py; docs/ACQUISITION_GAP.md, "Clusters split
finely, then merged"): clusters that one material fell into merge, clusters of different
materials do not, and the merge count obeys the limit."""

import numpy as np
import pytest
import torch

from hybridbrdf.acquire import cluster_fit, material_fits
from hybridbrdf.acquire.cluster_merge import merge_clusters
from hybridbrdf.acquire.hybrid_fit import HybridFamily
from hybridbrdf.acquire.network_tune import cosine_pairs
from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.texel_rows import ObservationTensors
from hybridbrdf.model.prior import load_prior

#: The left half of the map (a diffuse plastic) and the right half (a metal); WRONG is the material
#: a second cluster of the left half chose, as colodur_napoli's second cluster did on the bench.
LEFT, RIGHT, WRONG = "red-plastic", "brass", "pink-fabric2"
#: 12 x 4 texels: the left half split in two clusters of three columns, the right half one; 48 rows a texel.
W, H, ROWS = 12, 4, 48


@pytest.fixture(autouse=True)
def one_thread():
    torch.set_num_threads(1)


@pytest.fixture(scope="module")
def split_capture():
    """(prior, family, obs, data, labels, clusters): each half photographed (5% noise), the left half
    split in two clusters; clusters 0 and 2 carry their half's material, cluster 1 the wrong one, each
    with values fitted to its rows as the cluster stage fits them (cluster_fit.fit_material)."""
    torch.set_num_threads(1)
    prior = load_prior()
    family = HybridFamily(prior)
    every = family.raw_of_materials()
    n = W * H * ROWS
    wi, wo = cosine_pairs(n, 7)
    column = np.tile(np.arange(W), H)
    texel_material = np.where(column < W // 2, prior.index(LEFT), prior.index(RIGHT))
    material = torch.from_numpy(np.repeat(texel_material, ROWS))
    with torch.no_grad():
        g = family.evaluate(material, {k: v[material] for k, v in every.items()}, wi, wo).numpy()
    g = g * (1 + 0.05 * np.random.default_rng(3).standard_normal(g.shape))
    offsets = np.arange(0, n + 1, ROWS, dtype=np.int64)
    obs = Observations((W, H), offsets, wi.numpy(), wo.numpy(), g.astype(np.float32), np.zeros((n, 2), np.float32),
                       np.tile(np.arange(ROWS), W * H).astype(np.int64))
    labels = np.minimum(column // 3, 2).astype(np.int64)
    chosen = [prior.index(m) for m in (LEFT, WRONG, RIGHT)]
    data = ObservationTensors(obs)
    tau2 = material_fits.value_spread(every)
    fits = []
    for c, m in enumerate(chosen):
        rows = cluster_fit._cluster_rows(obs, labels, c, cluster_fit.CLUSTER_ROWS, 0)
        own = {**{k: v[m] for k, v in every.items()}, "tau2": tau2}
        fits.append(cluster_fit.fit_material(family, data, rows, m, {k: v[m] for k, v in every.items()}, 0,
                                             f"cluster{c}", own, ROWS))
    clusters = {"material": torch.tensor(chosen), "centres": {k: torch.stack([f["raw"][k] for f in fits]) for k in every},
                "sigma2": torch.tensor([f["loss"] for f in fits]), "candidates": [[f] for f in fits]}
    return prior, family, obs, data, labels, clusters


def test_clusters_of_one_material_merge_and_different_materials_stay_apart(split_capture):
    prior, family, obs, data, labels, clusters = split_capture
    merged_labels, merged = merge_clusters(family, obs, data, labels, clusters, seed=0, limit=3)
    assert len(merged["material"]) == 2, merged["merges"]
    halves = merged_labels.reshape(H, W)
    assert len(set(halves[:, :W // 2].ravel().tolist())) == 1 and len(set(halves[:, W // 2:].ravel().tolist())) == 1
    assert halves[0, 0] != halves[0, -1]
    # The left half's merged cluster kept the material that explains it, not the wrong one.
    assert prior.materials[int(merged["material"][halves[0, 0]])] == LEFT
    assert prior.materials[int(merged["material"][halves[0, -1]])] == RIGHT
    assert all(ratio <= 1.2 for _, _, ratio in merged["merges"]), merged["merges"]
    assert torch.equal(merged["labels"], torch.from_numpy(merged_labels))


def test_the_limit_forces_the_closest_pair_and_a_strict_ratio_merges_nothing(split_capture):
    prior, family, obs, data, labels, clusters = split_capture
    one_labels, one = merge_clusters(family, obs, data, labels, clusters, seed=0, limit=1)
    assert len(one["material"]) == 1 and set(one_labels.tolist()) == {0}
    # The forced last merge is of the two halves: its ratio is far above the merge of one material's.
    assert len(one["merges"]) == 2 and one["merges"][1][2] > 5 * one["merges"][0][2], one["merges"]
    kept_labels, kept = merge_clusters(family, obs, data, labels, clusters, seed=0, limit=3, merge_ratio=0.0)
    assert len(kept["material"]) == 3 and kept["merges"] == [] and np.array_equal(kept_labels, labels)
