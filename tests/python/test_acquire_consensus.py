"""The consensus among a cluster's tied candidates (acquire/consensus.py; docs/ACQUISITION_CONSENSUS.md):
the probe pairs it compares them on, the margin within which scores tie, and the medoid that leads."""

import math

import numpy as np
import torch

from hybridbrdf.acquire import consensus


class ConstantFamily:
    """A family whose material m is the constant BRDF value[m] in every channel."""

    def __init__(self, values):
        self.values = torch.tensor(values, dtype=torch.float32)

    def evaluate(self, material, raw, wi, wo):
        return self.values[material][:, None].expand(-1, 3)


#: Scores in units of a capture's (mean squared log residuals): the best score's root, 0.01, is the
#: least lead in mean distance for which the medoid overturns it.
SCALE = 1e-4


def _candidates(scores):
    return [{"material": m, "score": s * SCALE, "raw": {"kd": torch.zeros(3)}} for m, s in enumerate(scores)]


def test_probe_pairs_mirror_about_half_vectors_within_the_stated_cones():
    wi, wo = (x.double().numpy() for x in consensus.probe_pairs(2000, seed=3))
    assert len(wi) > 1000
    assert np.allclose(np.linalg.norm(wi, axis=1), 1, atol=1e-5) and np.allclose(np.linalg.norm(wo, axis=1), 1, atol=1e-5)
    assert (wi[:, 2] >= consensus.MIN_COS - 1e-6).all() and (wo[:, 2] >= consensus.MIN_COS - 1e-6).all()
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=1, keepdims=True)
    theta_h = np.degrees(np.arccos(np.clip(h[:, 2], -1, 1)))
    theta_d = np.degrees(np.arccos(np.clip((wi * h).sum(1), -1, 1)))
    assert theta_h.max() <= 60.0 + 1e-3 and theta_d.max() <= 80.0 + 1e-3
    # The highlight's neighbourhood is probed: uniform theta_h puts about 1/12 of the draws below 5 deg.
    assert (theta_h < 5.0).mean() > 0.04


def test_the_tie_margin_narrows_as_one_over_the_root_of_the_photographs():
    assert math.isclose(consensus.tie_margin(8) / consensus.tie_margin(32), 2.0)
    assert math.isclose(consensus.tie_margin(32) / consensus.tie_margin(128), 2.0)
    assert 0.25 < consensus.tie_margin(32) < 0.35


def test_among_tied_candidates_the_median_prediction_leads():
    # Tied (within 29% at 32 photographs): 4.0 (the best score, far from the others), 1.0 and 1.3;
    # 1.25 and 1.27 score far worse and must not vote: with them the median would be 1.27.
    family = ConstantFamily([4.0, 1.0, 1.3, 1.25, 1.27])
    fitted = _candidates([1.0, 1.1, 1.2, 5.0, 5.0])
    out = consensus.medoid_first(family, fitted, shots=32)
    assert [c["material"] for c in out] == [2, 0, 1, 3, 4]
    assert out[0]["consensus"] is True and all(c["tied"] == 3 for c in out)


def test_fewer_than_three_tied_candidates_keep_the_scores_order():
    family = ConstantFamily([4.0, 1.0, 1.3])
    two_tied = consensus.medoid_first(family, _candidates([1.0, 1.1, 9.0]), shots=32)
    assert [c["material"] for c in two_tied] == [0, 1, 2] and "consensus" not in two_tied[0]
    # At 128 photographs the margin is 0.14: 1.2 no longer ties with 1.0.
    narrow = consensus.medoid_first(family, _candidates([1.0, 1.1, 1.2]), shots=128)
    assert [c["material"] for c in narrow] == [0, 1, 2] and narrow[0]["tied"] == 2


def test_one_far_candidate_does_not_drag_the_choice_toward_itself():
    # Five tied: the median is 1.2; summed squared distances would choose the value nearest the
    # mean, which 6.0 drags up to 1.25.
    family = ConstantFamily([6.0, 1.0, 1.1, 1.2, 1.25])
    out = consensus.medoid_first(family, _candidates([1.0, 1.01, 1.02, 1.03, 1.04]), shots=32)
    assert out[0]["material"] == 3


def test_the_best_score_leads_when_it_is_the_median():
    family = ConstantFamily([1.3, 1.0, 4.0])
    out = consensus.medoid_first(family, _candidates([1.0, 1.1, 1.2]), shots=32)
    assert out[0]["material"] == 0 and out[0]["consensus"] is False


def test_the_pixels_noise_is_taken_from_the_scores_before_they_are_compared():
    # Scores 1.0 and 1.2 and 1.25 tie at 32 photographs (margin 0.29); with a noise floor of 0.8 in
    # each, their excesses 0.2, 0.4 and 0.45 do not: the best score stands.
    family = ConstantFamily([4.0, 1.0, 1.3])
    fitted = _candidates([1.0, 1.2, 1.25])
    assert consensus.medoid_first(family, fitted, shots=32)[0]["material"] == 2
    kept = consensus.medoid_first(family, fitted, shots=32, noise=0.8 * SCALE)
    assert [c["material"] for c in kept] == [0, 1, 2] and kept[0]["tied"] == 1


def test_a_medoid_the_photographs_cannot_resolve_from_the_best_score_does_not_overturn_it():
    # Tied 1.00, 1.02 and 0.98: the medoid (1.00) leads the best score (1.02) in mean distance by
    # about 0.005 in log(1 + f cos): under the best fit's residual, sqrt(score) = 0.01, so it stays.
    family = ConstantFamily([1.02, 1.0, 0.98])
    kept = consensus.medoid_first(family, _candidates([1.0, 1.1, 1.2]), shots=32)
    assert kept[0]["material"] == 0 and kept[0]["consensus"] is False
    # The same candidates fitted to photographs 100x better resolve it: the medoid leads.
    sharp = [dict(c, score=c["score"] / 100) for c in _candidates([1.0, 1.1, 1.2])]
    assert consensus.medoid_first(family, sharp, shots=32)[0]["material"] == 1
