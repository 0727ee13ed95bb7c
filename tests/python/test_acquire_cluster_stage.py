"""The acquisition fit's cluster stage (acquire/cluster_fit.py; docs/ACQUISITION_GAP.md, "The
cluster stage on pure texels, every material screened"): which rows a cluster is fitted on, and
how the prior's materials are ranked before the best are fitted, and the k-means that groups the
texels first."""

import numpy as np
import pytest
import torch

from hybridbrdf.acquire import cluster_fit, clustering, material_fits, network_tune
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


def test_a_layer_of_diagonal_stripes_reads_the_texels_whose_edge_neighbours_share_it():
    # Diagonal stripes three texels wide (the verdict sample's base at 16x16): no texel has its 8
    # neighbours in its stripe, the middle diagonal of each has its 4 edge neighbours there; a
    # stripe one texel wide (a rim) has neither and reads all its texels.
    size = (8, 8)
    i, j = np.meshgrid(np.arange(8), np.arange(8))
    band = (i + j + 1) % 6
    labels = (band < 3).astype(np.int64).reshape(-1)
    assert not np.any([np.all(labels.reshape(8, 8)[max(0, y - 1):y + 2, max(0, x - 1):x + 2] == 1)
                       for y in range(8) for x in range(8)])  # the construction: no 8-pure texel
    texels = network_tune.pure_texels(labels, size, 1)
    middle = np.nonzero((band == 1).reshape(-1))[0]
    assert set(texels.tolist()) == set(middle.tolist()), (texels, middle)
    rim = ((i + j) % 6 == 0).astype(np.int64).reshape(-1)
    texels = network_tune.pure_texels(rim, size, 1)
    assert len(texels) == 0
    texel_of_row = np.repeat(np.arange(64), 2)
    obs = _observations(np.ones((128, 3)), np.tile([[0, 0, 1.0]], (128, 1)), np.tile([[0, 0, 1.0]], (128, 1)), size)
    rows = cluster_fit._cluster_rows(obs, rim, 1, 10 ** 6, seed=0).numpy()
    assert set(texel_of_row[rows].tolist()) == set(np.nonzero(rim)[0].tolist())


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
        own = torch.stack([material_fits.loss_rows(family, data, torch.full((256,), m),
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


def test_pixel_noise_is_the_variance_of_one_rows_target_and_pairs_only_one_texels_photograph():
    # 400 texels x 2 photographs x 8 pixels, each cell one direction pair and one true value, each
    # pixel its own Gaussian noise: the estimate against the delta method's variance of log(eps + cos g).
    rng = np.random.default_rng(3)
    cells, pixels, sigma = 800, 8, 0.02
    wi, wo = (np.repeat(v.numpy().astype(np.float64), pixels, 0) for v in cosine_pairs(cells, 5))
    truth = np.repeat(rng.uniform(0.1, 0.4, (cells, 3)), pixels, 0)
    values = truth + rng.normal(0.0, sigma, truth.shape)
    obs = _observations(values, wi, wo, size=(20, 20))
    obs.shot = np.tile(np.repeat(np.arange(2), pixels), 400)
    for eps in (1.0, 0.1):  # the paper's loss domain and the fits' (log(eps + cos g): slope 1 / (eps + cos g))
        data = ObservationTensors(obs, eps)
        expected = float(np.mean((wi[:, 2:3] / (eps + wi[:, 2:3] * truth)) ** 2 * sigma ** 2))
        estimate = data.pixel_noise(torch.arange(len(values)))
        assert abs(estimate / expected - 1) < 0.05, (eps, estimate, expected)
    # Rows of different photographs (or texels) never pair: every row its own cell leaves no pair.
    obs.shot = np.arange(len(values)) % pixels
    assert ObservationTensors(obs).pixel_noise(torch.arange(len(values))) == 0.0


def test_cell_averaged_rows_keep_their_cells_expectation_and_divide_its_noise():
    # 400 texels x 2 photographs x 8 pixels as above, each texel's 16 rows shuffled so that a cell's
    # rows are not next to each other: every averaged row is its own cell's mean, which keeps the
    # noiseless target's expectation and has an eighth of one row's noise variance (the delta method's).
    rng = np.random.default_rng(4)
    cells, pixels, sigma = 800, 8, 0.02
    wi, wo = (np.repeat(v.numpy().astype(np.float64), pixels, 0) for v in cosine_pairs(cells, 6))
    truth = np.repeat(rng.uniform(0.1, 0.4, (cells, 3)), pixels, 0)
    shot = np.tile(np.repeat(np.arange(2), pixels), 400)
    order = np.concatenate([16 * t + rng.permutation(16) for t in range(400)])
    wi, wo, truth, shot = wi[order], wo[order], truth[order], shot[order]
    obs = _observations(truth + rng.normal(0.0, sigma, truth.shape), wi, wo, size=(20, 20))
    obs.shot = shot
    data = ObservationTensors(obs)  # the fits' loss domain, log(eps + cos g) - log(eps)
    averaged = data.cell_averaged()
    assert averaged is data.cell_averaged() and torch.equal(averaged.wi, data.wi)
    assert torch.all(averaged.cell_size == pixels)
    clean = np.log1p(wi[:, 2:3] * truth / data.eps)
    per_row = float(np.mean((wi[:, 2:3] / (data.eps + wi[:, 2:3] * truth)) ** 2 * sigma ** 2))
    error = averaged.target.double().numpy() - clean
    assert abs(error.mean()) < 4 * np.sqrt(per_row / pixels / (cells * 3))
    assert abs(np.mean(error ** 2) / (per_row / pixels) - 1) < 0.1
    # Rows of one cell read one value; of different cells (one texel's two photographs) not.
    first = np.nonzero((np.arange(len(shot)) // 16 == 0) & (shot == 0))[0]
    other = np.nonzero((np.arange(len(shot)) // 16 == 0) & (shot == 1))[0]
    assert torch.all(averaged.target[first] == averaged.target[first[0]])
    assert not torch.equal(averaged.target[first[0]], averaged.target[other[0]])


def test_a_dark_rows_target_is_unbiased_under_the_sensors_noise():
    # A dark row (g = 0.01 at cos 0.5) photographed 100,000 times under the bench's high noise
    # (NoiseModel: 200 photons at radiance 1, read noise 4): about half its readings are negative.
    # The targets' mean is the noiseless target's within the delta method's bias (-var / 2) and its
    # error; clamped at 0 (the rule before) the same readings average 40% too bright.
    from hybridbrdf.acquire.noise import NoiseModel

    n, cos, g = 100_000, 0.5, 0.01
    wi = np.tile([[np.sqrt(1 - cos ** 2), 0.0, cos]], (n, 1))
    values = NoiseModel(photons=200.0, read_noise=4.0).apply(np.full((n, 3), g), np.random.default_rng(1))
    assert (values < 0).mean() > 0.3
    for eps in (1.0, 0.1):  # the paper's loss domain and the fits': log(eps + x), slope 1 / (eps + x)
        target = ObservationTensors(_observations(values, wi, wi.copy()), eps).target.double().numpy()
        clean = np.log1p(cos * g / eps)
        spread = float(np.std(cos * values)) / (eps + cos * g)
        assert abs(target.mean() - clean) < spread ** 2 / 2 + 4 * spread / np.sqrt(values.size), eps
    assert np.log1p(cos * np.maximum(values, 0)).mean() > 1.3 * np.log1p(cos * g)


def test_declared_pixel_noise_leaves_the_choice_as_without_noise():
    # Two fits of a cluster: a closer fit moved further from its material's values, and a looser fit
    # that stayed home. Noise the photographs' pixels add to both residuals (and that thousands of
    # rows average away) must not decide between them: declared, the objectives differ as the
    # noiseless ones do; undeclared, the noise weighs the move 30x and turns the choice.
    own = {"kd": torch.zeros(2, 3)}
    raw = {"kd": torch.tensor([[0.6, 0.6, 0.6], [0.2, 0.2, 0.2]])}
    tau2 = {"kd": torch.ones(3)}
    misfit, nu2, shots, rows = torch.tensor([2.0e-6, 2.6e-6]), 6.0e-5, 32, 10 ** 7
    clean = material_fits.map_objective(misfit, raw, own, tau2, shots)
    noisy = material_fits.map_objective(misfit + nu2, raw, own, tau2, shots, noise=nu2, rows=rows)
    undeclared = material_fits.map_objective(misfit + nu2, raw, own, tau2, shots)
    assert torch.argmin(clean) == 0 and torch.argmin(noisy) == 0
    assert torch.allclose(noisy - nu2, clean, rtol=1e-4)
    assert torch.argmin(undeclared) == 1


def test_kmeans_keeps_the_start_of_least_within_cluster_squares(monkeypatch):
    # Five tight groups on a line (two close pairs and one far), four clusters: one k-means++ start
    # merges the wrong pair for many seeds (a local optimum of Lloyd's algorithm); the least sum of
    # squares over KMEANS_STARTS starts is the global one for every seed (the default stays one start:
    # docs/ACQUISITION_CONSENSUS.md, "The fit's own seed").
    rng = np.random.default_rng(7)
    groups = np.array([[0, 0], [1, 0], [5, 0], [6, 0], [12, 0]], float)
    features = np.concatenate([g + 0.05 * rng.standard_normal((40, 2)) for g in groups])

    def within(labels):
        return sum(((features[labels == c] - features[labels == c].mean(0)) ** 2).sum() for c in np.unique(labels))
    monkeypatch.setattr(clustering, "KMEANS_STARTS", 1)
    one = np.array([within(clustering.kmeans(features, 4, s)) for s in range(30)])
    monkeypatch.setattr(clustering, "KMEANS_STARTS", 8)
    many = np.array([within(clustering.kmeans(features, 4, s)) for s in range(30)])
    best = min(one.min(), many.min())
    assert (one > best * 1.01).sum() >= 5  # the trap is real for single starts
    assert np.allclose(many, best)
    labels = clustering.kmeans(features, 4, 0)
    assert list(np.bincount(labels)) == sorted(np.bincount(labels), reverse=True)  # numbered by decreasing size
