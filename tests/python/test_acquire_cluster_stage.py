"""The acquisition fit's cluster stage (acquire/cluster_fit.py; docs/ACQUISITION_GAP.md, "The
cluster stage on pure texels, every material screened"): which rows a cluster is fitted on, and
how the prior's materials are ranked before the best are fitted."""

import numpy as np
import pytest
import torch

from hybridbrdf.acquire import cluster_fit
from hybridbrdf.acquire.hybrid_fit import HybridFamily
from hybridbrdf.acquire.network_tune import cosine_pairs
from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.texel_fit import fit_analytic_texels
from hybridbrdf.acquire.texel_rows import ObservationTensors
from hybridbrdf.model.prior import load_prior

#: A red diffuse material of the shipped prior, photographed with its kd's channels reversed (blue).
SHAPE = "red-plastic"


@pytest.fixture(autouse=True)
def one_thread():
    torch.set_num_threads(1)


def _observations(values: np.ndarray, wi: np.ndarray, wo: np.ndarray, size=(1, 1), per_texel=None) -> Observations:
    n_tex = size[0] * size[1]
    per_texel = per_texel or [len(values) // n_tex] * n_tex
    offsets = np.concatenate([[0], np.cumsum(per_texel)]).astype(np.int64)
    n = int(offsets[-1])
    return Observations(size, offsets, wi[:n].astype(np.float32), wo[:n].astype(np.float32),
                        values[:n].astype(np.float32), np.zeros((n, 2), np.float32), np.zeros(n, np.int64))


def test_the_cluster_stage_reads_only_its_pure_texels_rows():
    # A 6x6 map, cluster 1 the left three columns: its pure texels (8 neighbours in it, edges
    # clamped) are columns 0 and 1; column 2 borders cluster 0.
    size = (6, 6)
    labels = np.tile((np.arange(6) >= 3).astype(np.int64), 6) ^ 1
    texel_of_row = np.repeat(np.arange(36), 5)
    obs = _observations(np.ones((180, 3)), np.tile([[0, 0, 1.0]], (180, 1)), np.tile([[0, 0, 1.0]], (180, 1)), size)
    rows = cluster_fit._cluster_rows(obs, labels, 1, 10 ** 6, seed=0).numpy()
    columns = set((texel_of_row[rows] % 6).tolist())
    assert columns == {0, 1}, columns
    assert len(rows) == 12 * 5
    assert len(cluster_fit._cluster_rows(obs, labels, 1, 7, seed=0)) == 7  # a draw when there are more
    # A cluster without a pure texel (a single column in the middle) reads all of its rows.
    labels = (np.tile(np.arange(6), 6) == 2).astype(np.int64)
    rows = cluster_fit._cluster_rows(obs, labels, 1, 10 ** 6, seed=0).numpy()
    assert set((texel_of_row[rows] % 6).tolist()) == {2} and len(rows) == 6 * 5


def test_every_material_is_screened_with_fitted_values_so_a_recoloured_shape_is_chosen():
    prior = load_prior()
    family = HybridFamily(prior)
    every = family.raw_of_materials()
    a = prior.index(SHAPE)
    recoloured = {k: v[a].clone() for k, v in every.items()}
    recoloured["kd"] = recoloured["kd"].flip(0)  # red -> blue: the same shape in another colour
    wi, wo = cosine_pairs(512, 0)
    with torch.no_grad():
        g = family.evaluate(torch.full((512,), a), {k: v[None].expand(512, -1) for k, v in recoloured.items()}, wi, wo)
    obs = _observations(g.numpy(), wi.numpy(), wo.numpy())
    data = ObservationTensors(obs)
    rows = torch.arange(256)
    with torch.no_grad():  # the construction: scored with its own (red) values, SHAPE ranks far down
        own = torch.stack([cluster_fit._loss_rows(family, data, torch.full((256,), m),
                                                  {k: v[m][None].expand(256, -1) for k, v in every.items()}, rows)
                           for m in range(len(prior.materials))])
    assert int((own < own[a]).sum()) >= 10 * cluster_fit.CANDIDATES
    labels = np.zeros(1, np.int64)
    colour = cluster_fit.cluster_colours(fit_analytic_texels(obs, steps=100, seed=0), labels)
    clusters = cluster_fit.fit_clusters(family, obs, data, labels, seed=0, colour=colour)
    assert prior.materials[int(clusters["material"][0])] == SHAPE, \
        [(prior.materials[c["material"]], c["loss"]) for c in clusters["candidates"][0]]
    # The cluster's fitted values reproduce the photographed colour: kd's channels reversed.
    kd = torch.sigmoid(clusters["centres"]["kd"][0])
    assert kd[2] > 2 * kd[0], kd


def test_the_shared_evaluation_is_the_per_material_one():
    prior = load_prior()
    family = HybridFamily(prior)
    every = family.raw_of_materials()
    m = torch.arange(len(prior.materials))
    wi, wo = cosine_pairs(16, 1)
    with torch.no_grad():
        shared = family.evaluate_shared(m, every, wi, wo)  # (M, 16, 3)
        one = torch.stack([family.evaluate(torch.full((16,), k), {n: v[k][None].expand(16, -1) for n, v in every.items()},
                                           wi, wo) for k in m.tolist()])
    assert shared.shape == one.shape and torch.allclose(shared, one, rtol=1e-5, atol=1e-7), \
        float((shared - one).abs().max())
