"""bench/acquire_verdict.py (issue 61 step 1): its verdict rule on constructed seed values (a gap
of the seed means inside either model's seed range is a tie, outside both a win or a loss), and
its rigs' directions: the flash rig sees only the collocated slice, the multi-view flash rig and
the light stage mostly other slices (wi far from wo)."""

from __future__ import annotations

import pathlib
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
try:
    import acquire_verdict as av
finally:
    sys.path.pop(0)

#: A shot is on the collocated slice when its pixels' median angle between wi and wo is below this.
COLLOCATED_DEG = 5.0


@pytest.mark.parametrize("hybrid, other, expect", [
    # Means 1.0 and 2.0, ranges 0.2 and 0.2: the gap 1.0 is beyond both: better (lower is better).
    ([0.9, 1.0, 1.1], [1.9, 2.0, 2.1], "better"),
    ([1.9, 2.0, 2.1], [0.9, 1.0, 1.1], "worse"),
    # Means 1.0 and 1.1 (gap 0.1), the hybrid's range 0.4: inside it: a tie, whichever side is lower.
    ([0.8, 1.0, 1.2], [1.1, 1.1, 1.1], "tie"),
    ([1.1, 1.1, 1.1], [0.8, 1.0, 1.2], "tie"),
    # The other model's range alone (0.6) holds the gap 0.5: a tie.
    ([1.0, 1.0, 1.0], [1.2, 1.5, 1.8], "tie"),
    # Gap 0.5 against ranges 0.4 and 0.2: beyond both.
    ([0.8, 1.0, 1.2], [1.4, 1.5, 1.6], "better"),
    # No spread on either side: any gap counts, none is a tie.
    ([1.0, 1.0], [1.0, 1.0], "tie"),
    ([1.0, 1.0], [1.0 + 1e-9, 1.0 + 1e-9], "better"),
    # One seed: no spread to compare the gap with.
    ([1.0], [2.0, 2.1], "n/a"),
])
def test_verdict_rule(hybrid, other, expect):
    assert av.verdict(hybrid, other) == expect


def test_verdict_table_counts_each_point_and_metric():
    """Two points; hybrid better than analytic on every metric at the first, tied at the second;
    worse than the neural model on cMAE only at the first."""
    def row(point, model, seed, smape, cmae, render):
        return {"rig": "light-stage", "point": point, "n": 8, "noise": "low", "model": model, "seed": seed,
                "smape_median": smape, "cmae_median": cmae, "render": render}

    rows = []
    for s, d in enumerate((-0.01, 0.0, 0.01)):
        rows += [row("4x2", "hybrid_heldout", s, 1 + d, 1 + d, 1 + d), row("4x2", "analytic", s, 2 + d, 2 + d, 2 + d),
                 row("4x2", "neural_heldout", s, 2 + d, 0.5 + d, 2 + d)]
    for s, d in enumerate((-0.1, 0.0, 0.1)):
        rows += [row("8x1", "hybrid_heldout", s, 1 + d, 1 + d, 1 + d), row("8x1", "analytic", s, 1.05, 1.05, 1.05),
                 row("8x1", "neural_heldout", s, 1.05, 1.05, 1.05)]
    lines = av.verdict_lines(rows)
    body = [[cell.strip() for cell in line.split("|")[1:]] for line in lines if line.startswith("light-stage")]
    assert body == [["better/better/better", "better/worse/better"], ["tie/tie/tie", "tie/tie/tie"]]
    assert lines[-2].endswith("better 3, tie 3")
    assert lines[-1].endswith("better 2, worse 1, tie 3")
    # --hybrid: another model judged against the same others (the rows renamed, the same words).
    renamed = [{**r, "model": "hybrid_tuned" if r["model"] == "hybrid_heldout" else r["model"]} for r in rows]
    tuned = av.verdict_lines(renamed, "hybrid_tuned")
    assert [line for line in tuned if line.startswith("light-stage")] == [line for line in lines if line.startswith("light-stage")]
    assert tuned[-1] == lines[-1].replace("hybrid_heldout", "hybrid_tuned")
    assert all(cell.strip() == "not measured" for line in av.verdict_lines(renamed) if line.startswith("light-stage")
               for cell in line.split("|")[1:])


def collocated(kind: str, point: str) -> tuple:
    """(shots on the collocated slice, shots) of the bench's rig ``kind`` at ``point``."""
    angles = av.shot_angles(av.build_rig(kind, point, 16))
    return int((angles < COLLOCATED_DEG).sum()), len(angles)


def test_flash_rig_sees_only_the_collocated_slice():
    assert collocated("flash", "8") == (8, 8)


def test_multiview_flash_rig_sees_v_collocated_shots_of_v_squared():
    # Each phone's own flash is collocated; the other V - 1 flashes it photographs under are not.
    assert collocated("flash-multiview", "3") == (3, 9)
    assert collocated("flash-multiview", "4") == (4, 16)


def test_light_stage_sees_other_slices_than_the_collocated():
    # acquire.rigs.light_stage_rig puts its first camera and its first light both at the zenith
    # (the golden-angle turn of the cameras' cap leaves +z where it is): one collocated shot.
    for point, shots in (("4x2", 8), ("8x4", 32)):
        on_slice, n = collocated("light-stage", point)
        assert n == shots and on_slice <= 1, (point, on_slice)


def test_the_verdicts_hybrid_is_the_products_default_fit(monkeypatch):
    """hybrid_heldout is fitted as ``hbrdf acquire fit`` fits by default: its network frozen below 32
    photographs and fine-tuned from 32 on (acquire.sizes); hybrid_frozen stays frozen at every N.
    The verdict once judged the frozen fit at every N, which the product never ran from 32 on."""
    from hybridbrdf.acquire import sizes

    calls = []

    def fit_hybrid_texels(obs, model, seed=0, **kw):
        calls.append(kw.get("finetune_network"))

    monkeypatch.setattr(av.ac, "find_fit", lambda name: fit_hybrid_texels)
    fits = av.fitters(["hybrid_heldout", "hybrid_frozen"], 10, 64)
    for shots in (8, 31, 32, 128):
        fits["hybrid_heldout"](None, 0, shots)
        fits["hybrid_frozen"](None, 0, shots)
    tuned = sizes.FINETUNE_STEPS
    assert tuned > 0
    assert calls == [0, 0, 0, 0, tuned, 0, tuned, 0]


def test_every_texel_is_scored_alike_for_every_seed_and_a_draw_differs_by_seed():
    # --texels 0: the seeds' spread must be the capture's and the fit's, so every seed scores the
    # same texels, all of the map's; a count draws half pure, half mixed, differently per seed.
    weights = np.zeros((8, 8, 2))
    weights[..., 0] = 1.0
    weights[:, 4:, 0], weights[:, 4:, 1] = 0.5, 0.5  # half the map mixed
    every = [av.scored_texels(weights, 0, s) for s in (0, 1, 2)]
    assert all(np.array_equal(e, np.arange(64)) for e in every)
    drawn = [av.scored_texels(weights, 8, s) for s in (0, 1, 2)]
    assert all(len(d) == 8 and len(np.unique(d)) == 8 for d in drawn)
    assert not all(np.array_equal(drawn[0], d) for d in drawn[1:])
    pure = [int((weights.reshape(-1, 2)[d].max(axis=1) > 0.99).sum()) for d in drawn]
    assert pure == [4, 4, 4]


def test_the_ceiling_keeps_the_true_weights_and_puts_each_layers_fit_in_its_place():
    # Each layer's "full-measurement fit" here a prior material of its own; the ceiling must evaluate
    # every texel as the true weights mix those materials (an independent sum here), whatever the
    # layer's source was.
    import torch

    import hybridbrdf as hb
    from hybridbrdf.acquire.mixture import Mixture
    from hybridbrdf.model.prior import prior_path

    prior = hb.load_model(str(prior_path()))
    names = prior.materials[:3]
    weights = np.random.default_rng(1).dirichlet(np.ones(3), size=(4, 4))
    truth = Mixture([hb.open_source(f"synthetic:{n}") for n in ("gold", "plastic", "velvet")], weights)

    class OneMaterial:  # a "reference" whose last material is the layer's
        def __init__(self, name):
            self.materials, self.material_info, self.path = [name], [prior.material_info[prior.index(name)]], None

        def index(self, name):
            return 0

        def eval(self, wi, wo, material, dtype=None):
            return prior.eval(wi, wo, self.materials[0], dtype=dtype)
    ceiling = av.ceiling_of(truth, [OneMaterial(n) for n in names])
    rng = np.random.default_rng(2)
    uv = rng.random((64, 2))
    wi = np.tile([0.3, 0.1, 0.948], (64, 1)) / np.linalg.norm([0.3, 0.1, 0.948])
    wo = np.tile([-0.4, 0.2, 0.894], (64, 1)) / np.linalg.norm([-0.4, 0.2, 0.894])
    w = truth.weights_at(uv)
    expect = sum(w[:, k:k + 1] * np.maximum(prior.eval(wi, wo, n, dtype=torch.float64), 0) for k, n in enumerate(names))
    assert np.allclose(ceiling.eval(uv, wi, wo), expect, rtol=1e-9, atol=1e-12)
    assert np.allclose(ceiling.weights, truth.weights)
