"""bench/acquire_compare.py's error functions (issue 46 step 3) against computations written out
here from docs/CONVENTIONS.md's definitions, so that the comparison's figures can be wrong and
be caught: a fit that is the truth scores 0, a fit twice the truth scores SMAPE 2/3 (on the
non-zero values) and cMAE mean(g cos theta_i), and its re-render a relative MAE of 1."""

from __future__ import annotations

import pathlib
import sys

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.simulation import radiance
from hybridbrdf.acquire.geometry import pixel_geometry

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
try:
    import acquire_compare as ac
finally:
    sys.path.pop(0)

W, H = 4, 3


@pytest.fixture(scope="module")
def sample():
    """Two exact sources under an asymmetric (H, W) weights map (a row/column swap would show)."""
    gold, plastic = hb.open_source("synthetic:gold"), hb.open_source("synthetic:plastic")
    w1 = np.array([[0.0, 0.2, 1.0, 1.0], [0.0, 0.0, 0.5, 1.0], [0.0, 0.0, 0.0, 0.7]])
    return Mixture([gold, plastic], np.stack([1 - w1, w1], axis=2)), (gold, plastic), w1


class ByHand:
    """A per-texel fit whose texel t = j * W + i is scale x (w0 g_gold + w1 g_plastic) with the
    weights map's (j, i) entry: the truth at the texel centre, written without the bench's code."""

    def __init__(self, sources, w1, scale=1.0):
        self.sources, self.w1, self.scale = sources, w1, scale

    def eval(self, texel, wi, wo):
        j, i = np.divmod(np.asarray(texel), W)
        w = self.w1[j, i][:, None]
        g = (1 - w) * np.maximum(self.sources[0].eval(wi, wo), 0) + w * np.maximum(self.sources[1].eval(wi, wo), 0)
        return self.scale * g

    def eval_uv(self, uv, wi, wo):
        # The weights map read bilinearly between texel centres, clamped, written out here.
        x = np.clip(uv[:, 0] * W - 0.5, 0, W - 1)
        y = np.clip(uv[:, 1] * H - 0.5, 0, H - 1)
        i0, j0 = np.minimum(np.floor(x).astype(int), W - 2), np.minimum(np.floor(y).astype(int), H - 2)
        fx, fy = x - i0, y - j0
        w = ((1 - fx) * (1 - fy) * self.w1[j0, i0] + fx * (1 - fy) * self.w1[j0, i0 + 1]
             + (1 - fx) * fy * self.w1[j0 + 1, i0] + fx * fy * self.w1[j0 + 1, i0 + 1])[:, None]
        g = (1 - w) * np.maximum(self.sources[0].eval(wi, wo), 0) + w * np.maximum(self.sources[1].eval(wi, wo), 0)
        return self.scale * g


def test_a_fit_that_is_the_truth_scores_zero(sample):
    mixture, sources, w1 = sample
    truth = ac.Truth(mixture, np.arange(W * H), (W, H), 2000)
    s, c = ac.texel_errors(ByHand(sources, w1), truth)
    assert np.abs(s).max() < 1e-12 and np.abs(c).max() < 1e-12


def test_a_fit_twice_the_truth_scores_the_definitions(sample):
    mixture, sources, w1 = sample
    texels = np.array([1, 6, 11])  # (i, j) = (1, 0), (2, 1), (3, 2): mixed texels
    truth = ac.Truth(mixture, texels, (W, H), 2000)
    s, c = ac.texel_errors(ByHand(sources, w1, 2.0), truth)
    for k, t in enumerate(texels):
        g = ByHand(sources, w1).eval(np.full(len(truth.wi), t), truth.wi, truth.wo)
        # SMAPE: 2 |g - 2g| / (g + 2g) = 2/3 wherever g > 0, 0 where both are 0; cMAE: |g - 2g| cos(theta_i).
        assert s[k] == pytest.approx(2 / 3 * (g > 0).mean(), rel=1e-12)
        assert c[k] == pytest.approx((g * truth.wi[:, 2:3]).mean(), rel=1e-12)


def test_nearest_texels_is_the_cell_holding_uv():
    uv = np.array([[0.0, 0.0], [0.99, 0.0], [0.4, 0.34], [1.0, 1.0], [0.5, 0.5]])
    # u * W = 0, 3.96, 1.6, 4 (clamped to 3), 2; v * H = 0, 0, 1.02, 3 (clamped to 2), 1.5.
    assert ac.nearest_texels(uv, (W, H)).tolist() == [0, 3, 1 * W + 1, 2 * W + 3, 1 * W + 2]


def test_rerender_error_is_the_relative_mae(sample):
    """The re-render of a per-texel fit on the two-material sample (its weights map asymmetric in u
    and v): each pixel's value written out here (the texel whose cell holds its uv, column from u,
    row from v; L = f cos(theta_i) I / d^2), and the relative MAE as the ratio of the means, on
    images where the mean of the per-pixel ratios differs."""
    mixture, sources, w1 = sample
    rig = ac.novel_rig(24)
    true = radiance(rig, 0, mixture)
    geo = pixel_geometry(rig, 0)
    mask = geo.mask
    assert mask.sum() > 100 and true[mask].mean() > 0
    fit = ByHand(sources, w1)
    image = ac.render_fit(fit, rig, (W, H), "nearest")
    # By hand, pixel by pixel.
    intensity = rig.lights[rig.shots[0].light].intensity
    expect = np.zeros_like(true)
    for (r, c), (u, v), wi, wo, d2 in zip(np.argwhere(mask), geo.uv, geo.wi, geo.wo, geo.distance2):
        i, j = min(max(int(np.floor(u * W)), 0), W - 1), min(max(int(np.floor(v * H)), 0), H - 1)
        w = w1[j, i]
        g = (1 - w) * np.maximum(sources[0].eval(wi[None], wo[None]), 0) + w * np.maximum(sources[1].eval(wi[None], wo[None]), 0)
        expect[r, c] = g[0] * max(wi[2], 0.0) / d2 * intensity
    np.testing.assert_allclose(image, expect, rtol=1e-12, atol=1e-15)
    # The fit is the truth at texel centres: its error is the map's resolution floor (0.054 here;
    # a lookup with u and v swapped scores 0.63).
    err = ac.relative_mae(image, true, mask)
    assert err == pytest.approx(np.abs(image[mask] - true[mask]).sum() / true[mask].sum(), rel=1e-12)
    assert 0.01 < err < 0.1, err
    assert ac.relative_mae(ac.render_fit(ByHand(sources, w1, 2.0), rig, (W, H), "nearest"), image, mask) == pytest.approx(1.0, rel=1e-12)
    # Read bilinearly, as the simulator reads its weights map, the truth's own map renders the
    # photograph itself: no floor.
    assert ac.relative_mae(ac.render_fit(fit, rig, (W, H)), true, mask) < 1e-12
    assert ac.relative_mae(ac.render_fit(ac.CentreTruth(mixture, (W, H)), rig, (W, H)), true, mask) < 1e-12
    # Ratio of means, not mean of ratios: errors 1 and 0 on references 1 and 3 give (1 + 0) / (1 + 3),
    # where the mean of the per-pixel ratios would be (1/1 + 0/3) / 2 = 0.5.
    ref = np.array([[[1.0] * 3, [3.0] * 3, [5.0] * 3]])
    got = np.array([[[2.0] * 3, [3.0] * 3, [0.0] * 3]])
    m = np.array([[True, True, False]])  # the third pixel is off the sample
    assert ac.relative_mae(got, ref, m) == pytest.approx(0.25, rel=1e-12)


def rows(values):
    """jsonl rows for one noise level from {model: {n: value}} (every metric the same value)."""
    return [{"noise": "low", "model": m, "n": n, "smape_median": v, "cmae_median": v, "render": v}
            for m, by_n in values.items() for n, v in by_n.items()]


def test_verdicts_follow_the_numbers():
    holds = {"analytic": {1: 1.0, 4: 1.0, 8: 1.0, 32: 1.0}, "neural_heldout": {1: 3.0, 4: 2.0, 8: 0.9, 32: 0.5},
             "hybrid_heldout": {1: 1.0, 4: 0.9, 8: 0.8, 32: 0.5}}
    lines = ac.verdicts(rows(holds))
    assert len(lines) == 3 and all("claim HOLDS" in line for line in lines)
    for broken in ({"hybrid_heldout": {4: 1.01}}, {"hybrid_heldout": {32: 0.51}}, {"hybrid_heldout": {8: 0.9}}):
        values = {m: dict(v) for m, v in holds.items()}
        for m, by_n in broken.items():
            values[m].update(by_n)
        assert all("claim FAILS" in line for line in ac.verdicts(rows(values))), broken
    partial = {m: {n: v for n, v in by_n.items() if m != "neural_heldout"} for m, by_n in holds.items()}
    assert all("not measured" in line for line in ac.verdicts(rows(partial)))
