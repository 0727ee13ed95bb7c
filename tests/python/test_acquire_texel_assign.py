"""Texels moved to the cluster that explains them (acquire/texel_assign.py): a stray texel moves,
a texel that mixes two clusters stays, a texel without photographs stays, a texel moves only when
most of its photographs agree (a sign test), and the score is taken on cell means (a cell's pixels
averaged before the square)."""

import numpy as np
import torch

from hybridbrdf.acquire import texel_assign
from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.texel_rows import ObservationTensors


class ConstantFamily:
    """A family whose material values are its BRDF: f = kd, whatever the directions."""

    def evaluate(self, material, raw, wi, wo):
        return raw["kd"].to(wi.dtype)


def _capture(values_per_texel, pixels=4, shots=8, noise=0.0, seed=0):
    """Observations of texels each photographed ``shots`` times, ``pixels`` pixels a photograph, every
    row head-on (cos 1); ``values_per_texel[t]`` its BRDF, one or one per photograph (None: never
    photographed); and their tensors in the loss domain of eps 1."""
    rng = np.random.default_rng(seed)
    counts = [0 if v is None else pixels * shots for v in values_per_texel]
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    value = np.concatenate([np.repeat(np.broadcast_to(np.asarray(v if v is not None else 0.0, float), (shots,)), pixels)
                            [:c, None].repeat(3, 1) for v, c in zip(values_per_texel, counts)])
    value = value + noise * rng.standard_normal(value.shape)
    shot = np.concatenate([np.repeat(np.arange(shots), pixels) for c in counts if c])
    n = int(offsets[-1])
    up = np.tile([[0.0, 0.0, 1.0]], (n, 1)).astype(np.float32)
    obs = Observations((len(values_per_texel), 1), offsets, up, up.copy(), value.astype(np.float32),
                       np.zeros((n, 2), np.float32), shot.astype(np.int64))
    return obs, ObservationTensors(obs, 1.0)  # the paper's loss domain, log(1 + cos f): the tests' midpoints are in it


def _clusters(*kd):
    return {"material": torch.arange(len(kd)), "centres": {"kd": torch.tensor([[v] * 3 for v in kd])}}


def test_a_stray_texel_moves_and_a_mixed_or_unseen_one_stays():
    # Clusters A (f = 0.2) and B (f = 0.8). Texel 1 is A's material filed under B; texel 3 sits half
    # way in the loss's log domain (explained equally badly by both); texel 4 has no photograph.
    half = float(np.sqrt(1.2 * 1.8) - 1.0)
    obs, data = _capture([0.2, 0.2, 0.8, half, None])
    labels = np.array([0, 1, 1, 0, 1])
    moved, count = texel_assign.move_texels(ConstantFamily(), obs, data, labels, _clusters(0.2, 0.8))
    assert moved.tolist() == [0, 0, 1, 0, 1] and count == 1
    scores = texel_assign.texel_scores(ConstantFamily(), obs, data, _clusters(0.2, 0.8))
    assert np.isinf(scores[4]).all() and scores[0, 0] < 1e-12
    np.testing.assert_allclose(scores[3, 0], scores[3, 1], rtol=1e-5)


def test_a_texel_moves_only_by_the_margin():
    # Texel 0 (f = 0.5) under cluster 0 (0.45); cluster 1 (0.52) explains it better, its score a
    # fraction of the own one's: the texel moves when MOVE_RATIO is above that fraction, not below.
    obs, data = _capture([0.5])
    clusters = _clusters(0.45, 0.52)
    scores = texel_assign.texel_scores(ConstantFamily(), obs, data, clusters)[0]
    ratio = scores[1] / scores[0]
    assert 0.1 < ratio < 0.3, ratio
    for limit, expect in ((ratio * 0.9, 0), (ratio * 1.1, 1)):
        old = texel_assign.MOVE_RATIO
        texel_assign.MOVE_RATIO = limit
        try:
            moved, _ = texel_assign.move_texels(ConstantFamily(), obs, data, np.array([0]), clusters)
        finally:
            texel_assign.MOVE_RATIO = old
        assert moved.tolist() == [expect], (limit, moved)


def test_the_score_reads_cell_means_not_pixels():
    # Pixel noise that averages out within each photograph's cell: the score of the right cluster
    # is the squared residual of the cell means (tiny), not the pixels' variance.
    obs, data = _capture([0.3], pixels=64, shots=2, noise=0.05, seed=1)
    score = texel_assign.texel_scores(ConstantFamily(), obs, data, _clusters(0.3))[0, 0]
    target = np.log1p(np.clip(obs.value, 1e-6, None).astype(np.float64))
    per_pixel = float(((target - np.log1p(0.3)) ** 2).mean())
    cell_means = np.stack([target[obs.shot == s].mean(0) for s in (0, 1)])
    expect = float(((cell_means - np.log1p(0.3)) ** 2).mean())
    assert score < per_pixel / 10, (score, per_pixel)
    np.testing.assert_allclose(score, expect, rtol=1e-3)


def test_a_texel_most_of_whose_photographs_disagree_stays():
    # Cluster 1 (0.6) explains the texel's mean error three times better than its own cluster 0
    # (0.2), but only 6 of its 8 photographs say so (the other two say the opposite as strongly):
    # a sign test at 2 standard deviations wants 7 of 8, and 7 move it.
    clusters = _clusters(0.2, 0.6)
    for per_shot, expect in (([0.6] * 6 + [0.2] * 2, 0), ([0.6] * 7 + [0.2], 1)):
        obs, data = _capture([per_shot])
        scores = texel_assign.texel_scores(ConstantFamily(), obs, data, clusters)[0]
        assert scores[1] < texel_assign.MOVE_RATIO * scores[0]
        moved, _ = texel_assign.move_texels(ConstantFamily(), obs, data, np.array([0]), clusters)
        assert moved.tolist() == [expect], per_shot
