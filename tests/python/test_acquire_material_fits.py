"""Fits of a prior's materials many at once (acquire/material_fits.py) and the screen pruned after
a quarter of its steps (acquire/screen.py): what makes the cluster stage cheaper must leave its
choices as they were. The references are the same fits run one at a time and the screen unpruned."""

import numpy as np
import pytest
import torch

from hybridbrdf.acquire import screen
from hybridbrdf.acquire.hybrid_fit import HybridFamily
from hybridbrdf.acquire.material_fits import MaterialFit, fit_materials, value_spread
from hybridbrdf.acquire.network_tune import cosine_pairs
from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.texel_rows import ObservationTensors, adam_texels
from hybridbrdf.model.prior import load_prior


@pytest.fixture(autouse=True)
def one_thread():
    torch.set_num_threads(1)


def _photographed(family, names, prior, rows_each: int, seed: int):
    """Observations of the prior's materials ``names`` as they are, each on its own cosine pairs, and
    a little noise: one texel per material."""
    wi, wo, g = [], [], []
    every = family.raw_of_materials()
    for k, name in enumerate(names):
        m = prior.index(name)
        a, b = cosine_pairs(rows_each, seed + k)
        with torch.no_grad():
            f = family.evaluate(torch.full((rows_each,), m), {n: v[m][None].expand(rows_each, -1) for n, v in every.items()}, a, b)
        wi.append(a), wo.append(b), g.append(f * torch.exp(0.05 * torch.randn(f.shape, generator=torch.Generator().manual_seed(k))))
    wi, wo, g = (torch.cat(x).numpy() for x in (wi, wo, g))
    n = len(g)
    offsets = np.arange(0, n + 1, rows_each, dtype=np.int64)
    return Observations((len(names), 1), offsets, wi.astype(np.float32), wo.astype(np.float32), g.astype(np.float32),
                        np.zeros((n, 2), np.float32), np.zeros(n, np.int64))


def test_fits_in_one_batched_problem_are_the_fits_one_at_a_time():
    prior = load_prior()
    family = HybridFamily(prior)
    every = family.raw_of_materials()
    tau2 = value_spread(every)
    names = ["red-plastic", "gold-metallic-paint", "white-fabric2"]
    data = ObservationTensors(_photographed(family, names, prior, 300, 3))
    fits = []
    for k, name in enumerate(names):  # each texel fitted with another material, from another start
        m = prior.index(names[(k + 1) % 3])
        own = {**{n: v[m] for n, v in every.items()}, "tau2": tau2} if k != 1 else None  # one by its loss alone
        rows = torch.arange(k * 300, k * 300 + 200 + 50 * k)  # fits of different sizes
        fits.append(MaterialFit(rows, m, {n: v[m] for n, v in every.items()}, own, shots=4 + k, noise=1e-4 * k))
    together = fit_materials(family, data, fits, 60, 0, "together")
    for fit, batched in zip(fits, together):
        alone = fit_materials(family, data, [fit], 60, 0, "alone")[0]
        assert batched["material"] == alone["material"]
        assert batched["score"] == pytest.approx(alone["score"], rel=1e-4) and batched["loss"] == pytest.approx(alone["loss"], rel=1e-4)
        for n in alone["raw"]:
            assert torch.allclose(batched["raw"][n], alone["raw"][n], atol=1e-4), (n, batched["raw"][n], alone["raw"][n])
    # The fits moved: a test of fits that stay at their start would pass without any batching right.
    assert any(not torch.allclose(t["raw"]["kd"], f.start["kd"], atol=1e-2) for t, f in zip(together, fits))


def test_adam_stopped_and_resumed_is_adam_uninterrupted():
    target = torch.linspace(-1, 1, 12).reshape(4, 3)

    def run(stops):
        params = {"x": torch.zeros(4, 3, requires_grad=True)}
        state = None
        for stop in stops:
            state = adam_texels(params, lambda gen: ((params["x"] - target) ** 2).sum(), 40, 0.1, 0, "s",
                                state=state, stop=stop)
            params = {"x": state["params"]["x"].clone().requires_grad_()}
        return state["params"]["x"], state["step"]
    whole, steps = run([None])
    split, split_steps = run([10, 40])
    assert steps == split_steps == 40 and torch.equal(whole, split)
    assert not torch.allclose(whole, torch.zeros(4, 3))


def test_the_pruned_screen_ranks_its_leaders_as_the_whole_screen(monkeypatch):
    # A cluster photographed from a prior material recoloured: the screen's best few (what the
    # candidates' fits start from) are the same materials pruned after a quarter as screened to the end.
    prior = load_prior()
    family = HybridFamily(prior)
    every = family.raw_of_materials()
    data = ObservationTensors(_photographed(family, ["gold-metallic-paint"], prior, 512, 7))
    rows = torch.arange(512)
    colour = every["kd"][prior.index("red-plastic")]
    pruned, _, as_is = screen.screen_materials(family, data, rows, every, 0, "s", colour, shots=16, steps=40)
    monkeypatch.setattr(screen, "SCREEN_KEEP", 10 ** 6)
    whole, _, as_is_whole = screen.screen_materials(family, data, rows, every, 0, "s", colour, shots=16, steps=40)
    assert torch.equal(as_is, as_is_whole)
    leaders = torch.argsort(whole)[:4].tolist()
    assert torch.argsort(pruned)[:4].tolist() == leaders
    assert torch.allclose(pruned[leaders], whole[leaders])
    # Pruned fits keep their score at the cut: never better than the whole screen's for them.
    assert bool((pruned >= whole - 1e-6).all())
