"""The kd caps before a layer's energy table (hybridbrdf.acquire.hybrid_fit.cap_outlier_kd): the
table is fitted for the layer's brightest texel, so an outlier must not set it."""

import numpy as np

from hybridbrdf.acquire import hybrid_fit


def test_an_outlier_texel_is_capped_at_its_layers_upper_fence_and_a_gradient_is_kept():
    # hybrid_fit.cap_outlier_kd: a layer's energy table is fitted for its brightest texel, so one
    # outlier would darken the whole layer. A uniform layer (kd 0.80 +- 0.005, 12x12) with one inner
    # texel at 0.90: that texel comes down to the fence (within the layer's spread of the rest), the
    # others keep theirs but the few beyond the fence by noise; a painted ramp 0.2-0.8 keeps every
    # texel; a layer of 4 inner texels is left as it is (too few to trust a fence).
    rng = np.random.default_rng(5)
    layer = np.zeros((12, 12), np.int64)
    layer[:, 9:] = 1  # a second layer: 3 columns, 2 of them rim or edge
    kd = np.clip(0.80 + 0.005 * rng.standard_normal((144, 3)), 0, 1)
    kd[layer.reshape(-1) == 1] = np.linspace(0.2, 0.8, 36)[:, None]
    outlier = 5 * 12 + 4
    kd[outlier] = 0.90
    capped, changed = hybrid_fit.cap_outlier_kd(kd, layer)
    base = layer.reshape(-1) == 0
    assert capped[outlier].max() < 0.80 + 4 * 0.005, capped[outlier]
    assert capped[base].max() < 0.80 + 4 * 0.005
    assert 1 <= changed <= 8, changed  # the outlier and the Gaussian's own tail beyond 2.7 sigma
    np.testing.assert_array_equal(capped[~base], kd[~base])
    np.testing.assert_array_equal(np.minimum(capped, kd), capped)  # only ever darker
    small = np.zeros((12, 12), np.int64)
    small[:3, :3] = 1  # a corner: 4 inner texels (the map's edge clamped), 2x2 away from the other layer
    kd2 = kd.copy()
    kd2[0] = 0.95
    capped2, _ = hybrid_fit.cap_outlier_kd(kd2, small)
    assert capped2[0].min() == 0.95
