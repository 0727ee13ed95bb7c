"""The acquisition's forward model and bookkeeping against what docs/ACQUISITION.md states, written
out here (issue 56: bench/mutation.py found changes to these that no test noticed): a mixture's
weights a convex combination, the rig generators' documented geometry and intensities, the image
size's two numbers, a capture's four layers, the exposure rule's "more than half", the row
sampler's uniform draw over a texel's own rows, and the fit loop's checkpoint cadence."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf.acquire.capture import write_capture
from hybridbrdf.acquire.exposure import usable_pixels
from hybridbrdf.acquire.geometry import pixel_geometry
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.observations import Observations, texel_observations
from hybridbrdf.acquire.rig import RigError, rig_from_dict
from hybridbrdf.acquire.rigs import flash_rig, light_stage_rig
from hybridbrdf.acquire import simulate
from hybridbrdf.acquire.texel_rows import RowSampler, adam_texels


@pytest.fixture(scope="module")
def gold():
    return hb.open_source("synthetic:gold")


@pytest.mark.parametrize("weights", [[0.5, 0.5], [1.0, 1.0], [0.25, 0.25], [-0.5, 1.5], [np.nan, 1.0]],
                         ids=["convex", "sum 2", "sum 0.5", "negative", "nan"])
def test_a_mixture_is_a_convex_combination(gold, weights):
    w = np.tile(np.array(weights, np.float64), (2, 3, 1))
    if weights == [0.5, 0.5]:
        assert Mixture([gold, gold], w).weights.shape == (2, 3, 2)
        return
    with pytest.raises(ValueError, match="non-negative and sum to 1"):
        Mixture([gold, gold], w)


def test_the_flash_rig_is_the_documented_phone():
    """flash_rig(n) with its documented defaults: a 0.1 x 0.1 sample, 256 x 256 photographs, the
    lens 0.3 from the sample's centre, the flash 0.01 to its right, intensity pi d^2 (a white
    Lambertian lit head-on from d reads 1)."""
    rig = flash_rig(3)
    assert rig.sample_extent == (0.1, 0.1) and rig.image_size == (256, 256)
    for cam, light in zip(rig.cameras, rig.lights):
        np.testing.assert_allclose(np.linalg.norm(cam.position), 0.3, rtol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(light.position - cam.position), 0.01, rtol=1e-9)
        np.testing.assert_allclose(light.intensity, math.pi * 0.3 ** 2, rtol=1e-12)


def test_the_flash_is_to_the_right_of_the_lens():
    """docs/ACQUISITION.md's rig example: the lens straight above at 0.3, the flash at (0.01, 0, 0.3);
    from every position the flash sits along the image's right, forward x up (up +y)."""
    rig = flash_rig(5)
    np.testing.assert_allclose(rig.lights[0].position, [0.01, 0.0, 0.3], atol=1e-15)
    for cam, light in zip(rig.cameras, rig.lights):
        forward = -cam.position / np.linalg.norm(cam.position)
        right = np.cross(forward, [0.0, 1.0, 0.0])
        np.testing.assert_allclose(light.position - cam.position, 0.01 * right / np.linalg.norm(right), atol=1e-12)


def _cap(n, theta_deg, turn=0.0):
    """docs/ACQUISITION.md's spread over a cap: cos(theta) linear in the index from 1 (straight
    above) to cos(theta_max), phi advancing by the golden angle pi (3 - sqrt 5), turned by ``turn``."""
    i = np.arange(n)
    z = 1 - (1 - math.cos(math.radians(theta_deg))) * i / max(n - 1, 1)
    phi = math.pi * (3 - math.sqrt(5)) * i + turn
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)


def test_rig_positions_spread_over_their_caps_as_documented():
    """flash_rig's positions over its 50 degree cap; light_stage_rig's lights over 75 degrees and its
    cameras over 60 (the defaults) with the cameras' cap turned by half a golden angle."""
    phone = flash_rig(6, flash_offset=0.0)
    np.testing.assert_allclose([c.position for c in phone.cameras], 0.3 * _cap(6, 50), atol=1e-12)
    stage = light_stage_rig(5, 4)
    np.testing.assert_allclose([l.position for l in stage.lights], _cap(5, 75), atol=1e-12)
    np.testing.assert_allclose([c.position for c in stage.cameras], _cap(4, 60, math.pi * (3 - math.sqrt(5)) / 2),
                               atol=1e-12)


def test_the_light_stage_is_the_documented_rig():
    """Lights at light_distance within light_theta_deg of the normal, intensity pi d^2; cameras at
    camera_distance within camera_theta_deg (their cap turned about the normal: still on the sphere)."""
    rig = light_stage_rig(7, 5, light_distance=1.5, camera_distance=0.8, light_theta_deg=70, camera_theta_deg=55)
    lights = np.array([l.position for l in rig.lights])
    cams = np.array([c.position for c in rig.cameras])
    np.testing.assert_allclose(np.linalg.norm(lights, axis=1), 1.5, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(cams, axis=1), 0.8, rtol=1e-12)
    for light in rig.lights:
        np.testing.assert_allclose(light.intensity, math.pi * 1.5 ** 2, rtol=1e-12)
    assert np.degrees(np.arccos(lights[:, 2] / 1.5)).max() <= 70 + 1e-9
    assert np.degrees(np.arccos(cams[:, 2] / 0.8)).max() <= 55 + 1e-9


def test_a_head_on_camera_frames_the_sample_with_the_stated_margin():
    """The field of view holds the sample's half diagonal times 1.1: from straight above, a square
    sample of side s fills s^2 / (2 * 1.1 * s / sqrt(2))^2 = 1 / 2.42 of a square photograph."""
    rig = flash_rig(1, size=(128, 128), flash_offset=0.0)
    np.testing.assert_allclose(rig.cameras[0].position, [0, 0, 0.3], atol=1e-15)
    covered = pixel_geometry(rig, 0).mask.mean()
    assert covered == pytest.approx(1 / 2.42, abs=0.01)


def test_an_image_size_is_two_numbers():
    doc = flash_rig(1, size=(16, 12)).to_dict()
    assert rig_from_dict(doc).image_size == (16, 12)
    for bad in ([16, 12, 3], [16]):
        doc["image_size"] = bad
        with pytest.raises(RigError, match="image_size"):
            rig_from_dict(doc)


def test_a_capture_holds_at_most_four_layers(tmp_path, gold):
    rig = flash_rig(1, size=(8, 8))
    for n, ok in ((4, True), (5, False)):
        capture = simulate(rig, Mixture([gold] * n, np.full((1, 1, n), 1.0 / n)))
        if ok:
            write_capture(capture, tmp_path / f"c{n}")
        else:
            with pytest.raises(ValueError, match="at most 4 layers"):
                write_capture(capture, tmp_path / f"c{n}")


def test_a_photograph_is_under_exposed_when_more_than_half_its_sample_pixels_are_dark():
    """Exactly half the finite sample pixels dark: kept; one more: left out. Non-finite pixels
    are counted, one per pixel."""
    rig = flash_rig(2, size=(24, 24))
    sample = pixel_geometry(rig, 0).mask
    photo = np.where(sample[..., None], 1.0, 0.0).repeat(3, axis=2)
    rows, cols = np.nonzero(sample)
    if len(rows) % 2:  # make the finite sample pixels even: one of them NaN
        photo[rows[-1], cols[-1], 1] = np.nan
        rows, cols = rows[:-1], cols[:-1]
    half = len(rows) // 2
    photo[rows[:half], cols[:half]] = 0.0
    other = np.where(pixel_geometry(rig, 1).mask[..., None], 1.0, 0.0).repeat(3, axis=2)
    other[0, 0] = np.nan
    other[1, 2, 0] = np.inf
    masks, report = usable_pixels(rig, [photo, other], floor=0.01)
    assert report["under-exposed"] == [] and masks[0].sum() == photo.shape[0] * photo.shape[1] - (sample.sum() % 2)
    assert report["not finite"] == 2 + sample.sum() % 2
    photo[rows[half], cols[half]] = 0.0
    masks, report = usable_pixels(rig, [photo, other], floor=0.01)
    assert report["under-exposed"] == [0] and not masks[0].any() and masks[1].sum() == 24 * 24 - 2


def test_the_row_sampler_draws_each_texels_own_rows_uniformly():
    counts = np.array([5, 0, 1, 12])
    offsets = np.concatenate([[0], np.cumsum(counts)])
    m = int(offsets[-1])
    obs = Observations((2, 2), offsets, np.zeros((m, 3)), np.zeros((m, 3)), np.zeros((m, 3)), np.zeros((m, 2)),
                       np.zeros(m, np.int64))
    sampler = RowSampler(obs, per_texel=8)
    gen = torch.Generator().manual_seed(0)
    seen = np.zeros(m, np.int64)
    for _ in range(500):
        texel, row = sampler.draw(gen)
        texel, row = texel.numpy(), row.numpy()
        assert np.all(row >= offsets[texel]) and np.all(row < offsets[texel + 1])
        np.add.at(seen, row, 1)
    assert set(np.unique(texel)) == {0, 2, 3}
    for t in (0, 2, 3):
        got = seen[offsets[t]:offsets[t + 1]]
        expect = 500 * 8 / counts[t]
        # every row of the texel, each about as often (binomial: 4 standard deviations)
        assert np.all(np.abs(got - expect) <= 4 * math.sqrt(expect) + 1), (t, got, expect)


def test_the_fit_loop_saves_its_state_every_every_steps():
    x = torch.zeros(3, requires_grad=True)
    saved = []
    adam_texels({"x": x}, lambda gen: ((x - 1.0) ** 2).sum(), steps=120, lr=0.05, seed=0, stage="s",
                save_state=lambda state: saved.append(state["step"]), every=50)
    assert saved == [50, 100]
    assert float((x.detach() - 1.0).abs().max()) < 0.5  # it did descend


def test_a_mixture_evaluates_each_source_only_where_it_weighs(gold):
    """Mixture.eval's promise: a source is evaluated on the pairs where its weight is above 0 only
    (a measured file's evaluation is the cost of a simulation)."""

    class Counting:
        def __init__(self):
            self.rows = 0

        def eval(self, wi, wo):
            self.rows += len(wi)
            return gold.eval(wi, wo)

    a, b = Counting(), Counting()
    w1 = np.array([[0.0, 0.0, 1.0, 1.0]])  # (1, 4): b only in the right half
    mixture = Mixture([a, b], np.stack([1 - w1, w1], axis=2))
    u = np.array([0.05, 0.2, 0.8, 0.95])  # bilinear between texel centres, clamped: a, a, b, b pure
    uv = np.stack([u, np.full(4, 0.5)], axis=1)
    wi = np.tile([0.0, 0.0, 1.0], (4, 1))
    mixture.eval(uv, wi, wi)
    assert (a.rows, b.rows) == (2, 2)


def test_observations_of_a_capture_of_many_photographs():
    """Hundreds of photographs (a light stage of 20 x 15), each with its usable mask."""
    rig = light_stage_rig(20, 15, size=(4, 4))
    photos = [np.full((4, 4, 3), 0.5)] * len(rig.shots)
    assert len(photos) == 300
    obs = texel_observations(rig, photos, (2, 2), usable=[np.ones((4, 4), bool)] * len(photos))
    assert len(obs.value) > 0 and set(np.unique(obs.shot)) <= set(range(300))
