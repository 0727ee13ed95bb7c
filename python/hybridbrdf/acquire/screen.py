"""The cluster stage's screen (:mod:`~hybridbrdf.acquire.cluster_fit`, stage 2; docs/ACQUISITION_GAP.md,
"The cluster stage on pure texels, every material screened"): every material of the prior fitted
briefly to a cluster's rows, all in one batched problem, to rank them; the best few are then fitted
in full (:func:`~hybridbrdf.acquire.material_fits.fit_materials`).

**Pruned after a quarter.** Only the screen's best few (2 for the split clusters, 4 for the final
ones) are fitted after it, so after :data:`SCREEN_PRUNE_AT` of the steps the fits that trail stop
and the :data:`SCREEN_KEEP` that lead (of 2 starts x 132 materials) go on; each fit's score is its
best objective so far, so a pruned fit keeps the score it had at the cut. The trailing fits' later
steps could only matter if one of them overtook 44 or more fits that led it; on the budget capture
of issue 61 (512x512, 64 photographs, 4 final clusters) the final clusters' stage, screens pruned and
candidates batched (material_fits), took 43 s of CPU against 65 s before (X1), and
tests/python/test_acquire_material_fits.py checks that the leaders are those of the unpruned screen.
"""

from __future__ import annotations

from typing import Dict, Optional, Tuple

import torch

from hybridbrdf.acquire.material_fits import map_objective, value_spread
from hybridbrdf.acquire.texel_rows import ObservationTensors, adam_texels

#: The screen's Adam rate: above the candidates' fit's (material_fits.FIT_LR) because a colour far
#: from the material's own is several logits away in each of kd's channels (red to blue).
SCREEN_LR = 0.1
#: The fits that go on after the first :data:`SCREEN_PRUNE_AT` of the screen's steps (module docstring).
SCREEN_KEEP, SCREEN_PRUNE_AT = 48, 0.25


def screen_materials(family, data: ObservationTensors, rows: torch.Tensor, every: Dict[str, torch.Tensor], seed: int,
                     stage: str, colour: Optional[torch.Tensor] = None, shots: int = 1, noise: float = 0.0,
                     steps: int = 40) -> Tuple[torch.Tensor, Dict[str, torch.Tensor], torch.Tensor]:
    """Every material's :func:`~hybridbrdf.acquire.material_fits.map_objective` on ``rows`` (``shots``
    photographs, ``noise``), the best over ``steps`` Adam steps of its values on it (over the first
    :data:`SCREEN_PRUNE_AT` of them for a fit pruned there: module docstring), (M,), the values reached {name: (M, c)},
    and its loss with its own values (M,) (the rule before the screen):
    all materials in one batched problem (their objectives are separate, so one Adam over all of
    them is an Adam per material). Each material starts twice, from its own values and, given
    ``colour`` (a raw kd (3,): the cluster's analytic fit), from its own values with that kd; the
    lower of the two counts.

    Why fitted and not scored with its own values: a material's values (its colour, above all) are
    what the texel fit changes anyway, so the material to choose is the one whose *shape* explains
    the rows: scored with its own values, a red material photographed blue ranks far down
    (tests/python/test_acquire_cluster_stage.py), and paper3's paper_white cluster chose cm_white_rgb
    in one capture (results/acquire_gap_M2.txt's layers), which the frozen network extrapolates worse
    than spectralon (bench/acquire_gap.py --ceiling: fitted to the truth itself, 2.30x the full
    measurement's cMAE against 1.38x). Why the
    second start: from its own red, 40 steps do not bring that material to blue (several logits in
    each of kd's channels) before materials already blue overtake it (the test, seen failing)."""
    n_mat, n_rows = len(next(iter(every.values()))), len(rows)
    starts = [every] if colour is None or "kd" not in every else [every, {**every, "kd": colour.expand_as(every["kd"])}]
    start = {name: torch.cat([s[name] for s in starts]) for name in every}
    n_fit = n_mat * len(starts)
    material = torch.arange(n_mat).repeat(len(starts))
    wi, wo = data.wi[rows], data.wo[rows]
    own, tau2 = {n: v.repeat(len(starts), 1) for n, v in every.items()}, value_spread(every)
    best = {"objective": torch.full((n_fit,), float("inf")), **{n: v.clone() for n, v in start.items()}}
    live = torch.arange(n_fit)  # the fits still screened
    state = {"step": 0, "params": start, "adam": None}
    cut = max(1, round(steps * SCREEN_PRUNE_AT)) if n_fit > SCREEN_KEEP else steps
    for stop in sorted({cut, steps}):
        raw = {n: v.clone().requires_grad_() for n, v in state["params"].items()}
        per_fit = _screen_objective(family, data, rows, wi, wo, material[live], raw,
                                    {n: v[live] for n, v in own.items()}, tau2, shots, noise, best, live, n_mat)
        state = adam_texels(raw, lambda gen: per_fit(gen).sum(), steps, SCREEN_LR, seed, stage,
                            state=state if state["adam"] is not None else None, stop=stop)
        if stop < steps:  # the rest of the steps for the fits that lead
            keep = torch.argsort(best["objective"][live])[:SCREEN_KEEP]
            live, state = live[keep], _kept_state(state, keep)
    with torch.no_grad():
        per_fit(None)
    objective = best["objective"].reshape(len(starts), n_mat)
    pick = torch.argmin(objective, dim=0) * n_mat + torch.arange(n_mat)  # the start that reached the lower
    return objective.min(dim=0).values, {n: best[n][pick] for n in start}, best["as_is"]


def _screen_objective(family, data, rows, wi, wo, material, raw, own, tau2, shots, noise, best, live, n_mat):
    """per_fit(gen) = the screen's objective (F,) of the fits ``live`` (their ``material``, values
    ``raw``, ``own`` values) on ``rows``, each fit's best objective and values so far kept in ``best``
    (indexed by fit), and on the first call the first ``n_mat`` fits' objective as "as_is"."""
    n_fit, n_rows = len(material), len(rows)
    if hasattr(family, "evaluate_shared"):  # every fit on the same rows: one pass
        def evaluate():
            return family.evaluate_shared(material, raw, wi, wo).reshape(n_fit * n_rows, -1)
    else:
        def evaluate():
            per_row = material.repeat_interleave(n_rows)
            return family.evaluate(per_row, {n: v.repeat_interleave(n_rows, 0) for n, v in raw.items()},
                                   wi.repeat(n_fit, 1), wo.repeat(n_fit, 1))
    batch = rows.repeat(n_fit)

    def per_fit(gen):
        d = data.residual(batch, evaluate())
        objective = map_objective((d * d).reshape(n_fit, -1).mean(1), raw, own, tau2, shots, noise, n_rows)
        # Each fit's best values so far: at this rate Adam's first steps move every value by about the
        # rate whatever its gradient, so a material photographed exactly as it is leaves its optimum.
        held = objective.detach()
        best.setdefault("as_is", held[:n_mat].clone())  # the first start's first step: own values
        better = held < best["objective"][live]
        best["objective"][live] = torch.where(better, held, best["objective"][live])
        for n, v in raw.items():
            best[n][live] = torch.where(better[:, None], v.detach(), best[n][live])
        return objective
    return per_fit


def _kept_state(state: dict, keep: torch.Tensor) -> dict:
    """An :func:`~hybridbrdf.acquire.texel_rows.adam_texels` state of the fits ``keep`` only (rows of
    every parameter and of Adam's moments)."""
    adam = {"param_groups": state["adam"]["param_groups"],
            "state": {i: {k: (v[keep] if torch.is_tensor(v) and v.dim() > 0 else v) for k, v in s.items()}
                      for i, s in state["adam"]["state"].items()}}
    return {"step": state["step"], "params": {n: v[keep] for n, v in state["params"].items()}, "adam": adam}
