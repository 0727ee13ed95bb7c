"""Fits of one set of values of a prior's material to a cluster's rows, many at once: the unit of
work of the cluster stage (:mod:`~hybridbrdf.acquire.cluster_fit`: each cluster's candidates) and
of its merge (:mod:`~hybridbrdf.acquire.cluster_merge`: both fits of every pair it tests).

Each fit minimises its own objective (its MAP objective, :func:`map_objective`, or its mean squared
residual) over its own rows, from its own start. The fits are independent, so their objectives'
sum has each fit's gradient in that fit's values alone, and Adam, which updates every value from
its own gradient's moments, takes on the sum the steps it would take on each fit alone: one
batched problem is the separate fits, rounded alike up to the order of sums. What it buys is one
pass of the network a step for all of them instead of a pass per fit, whose fixed cost (Python,
autograd, a few hundred small tensors) was as large as a 2,048-row fit's arithmetic: the merge of
issue 61's budget capture ran 44 fits of 100 steps one after the other."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Optional

import torch

from hybridbrdf.acquire.texel_rows import ObservationTensors, Progress, adam_texels

#: Adam's rate of every fit of a material's values (a value set starts at the material's own or
#: at the screen's, :func:`~hybridbrdf.acquire.screen.screen_materials`, close to its optimum).
FIT_LR = 0.03


def loss_rows(family, data: ObservationTensors, materials: torch.Tensor, raw: Dict[str, torch.Tensor],
              rows: torch.Tensor) -> torch.Tensor:
    """Mean squared residual per row and channel of ``family`` with per-row values ``raw``."""
    d = data.residual(rows, family.evaluate(materials, raw, data.wi[rows], data.wo[rows]))
    return (d * d).mean()


def map_objective(loss: torch.Tensor, raw: Dict[str, torch.Tensor], own: Dict[str, torch.Tensor],
                  tau2: Dict[str, torch.Tensor], shots=1, noise=0.0, rows=1) -> torch.Tensor:
    """The cluster stage's objective per fit, (F,) from mean squared residuals ``loss`` (F,) over
    ``rows`` rows of values ``raw`` {name: (F, c)} of materials whose own values are ``own``
    {name: (F, c)}: the negative log posterior of the cluster stage's model (:mod:`~hybridbrdf.acquire.cluster_fit`) divided by its data
    term's weight, L (1 + sum_j (theta_j - own_j)^2 / tau_j^2 / (3 n) * w / L), n the photographs the
    rows come from. ``shots``, ``noise`` and ``rows`` are numbers or (F,) tensors, one per fit.
    w is the variance of the residual's mean over one photograph's rows (held fixed):
    the fit's misfit L - nu^2, which a photograph's pixels share (they see about one direction pair),
    plus the pixels' own noise nu^2 (``noise``, :meth:`~hybridbrdf.acquire.texel_rows.ObservationTensors.pixel_noise`,
    at most L) over the rows a photograph gives, rows / n. Without the noise's split (w = L), a
    capture of 200 photons a pixel let its noise, which 2,000 rows average away, weigh a move 25x
    what its misfit did: colodur_napoli's cluster chose a material by its closeness to the prior's
    values over its fit (docs/ACQUISITION_GAP.md). Why the move counts: a material fitted far from
    its own values is less likely than one that explains the rows as they are (a flash capture's
    collocated slice is explained by almost any shape once its colour is refitted, and only the move
    tells the white paper photographed from a red one painted white)."""
    move = sum((((raw[n] - own[n]) ** 2) / tau2[n]).sum(-1) for n in raw)
    held = loss.detach()
    shots, rows = (torch.as_tensor(x, dtype=held.dtype).clamp_min(1) for x in (shots, rows))
    pixel = torch.minimum(torch.as_tensor(noise, dtype=held.dtype), held)
    return loss + (held - pixel + pixel * shots / rows) * move / (3 * shots)


def value_spread(every: Dict[str, torch.Tensor]) -> Dict[str, torch.Tensor]:
    """tau^2 per value component: its variance over the prior's materials (how far materials differ),
    the MAP prior's variance of the texel stage and of the cluster stage's score."""
    return {n: v.var(dim=0).clamp_min(1e-4) for n, v in every.items()}


@dataclass
class MaterialFit:
    """One fit of :func:`fit_materials`: material ``material``'s values, one set {name: (c,)} from
    ``start``, on ``rows``; with ``own`` (the material's own values and their spread ``own["tau2"]``)
    its :func:`map_objective` for ``shots`` photographs and the rows' ``noise``, else its loss. The fits
    of one :func:`fit_materials` call share one prior's spread (``tau2``: every caller's value_spread)."""
    rows: torch.Tensor
    material: int
    start: Dict[str, torch.Tensor]
    own: Optional[Dict[str, torch.Tensor]] = None
    shots: int = 1
    noise: float = 0.0


def fit_materials(family, data: ObservationTensors, fits: List[MaterialFit], steps: int, seed: int, stage: str,
                  progress: Optional[Progress] = None) -> List[Dict[str, object]]:
    """Every fit of ``fits`` (Adam, ``steps`` steps at :data:`FIT_LR`, all in one batched problem: the
    module docstring) on ``data``: per fit {"material", "loss" (its mean squared residual after),
    "score" (its objective after), "raw" {name: (c,)}}. ``progress(stage, step, steps)`` after each step."""
    if not fits:
        return []
    # Fits ordered by material, so that each material's rows are one slice (HybridFamily.evaluate_values).
    order = sorted(range(len(fits)), key=lambda i: int(fits[i].material))
    if order != list(range(len(fits))):
        done = dict(zip(order, fit_materials(family, data, [fits[i] for i in order], steps, seed, stage, progress)))
        return [done[i] for i in range(len(fits))]
    names = list(fits[0].start)
    sizes = torch.tensor([len(f.rows) for f in fits])
    job = torch.repeat_interleave(torch.arange(len(fits)), sizes)
    rows = torch.cat([f.rows for f in fits])
    material = torch.repeat_interleave(torch.tensor([int(f.material) for f in fits]), sizes)
    raw = {n: torch.stack([f.start[n].reshape(-1) for f in fits]).clone().requires_grad_() for n in names}
    wi, wo = data.wi[rows], data.wo[rows]
    priced = [i for i, f in enumerate(fits) if f.own is not None]
    if priced:
        own = {n: torch.stack([fits[i].own[n] for i in priced]) for n in names}
        tau2 = fits[priced[0]].own["tau2"]
        shots, noise = (torch.tensor([float(getattr(fits[i], k)) for i in priced]) for k in ("shots", "noise"))
        counts = sizes[priced].to(torch.float32)
    index = torch.tensor(priced, dtype=torch.long)

    def losses():
        values = {n: v[job] for n, v in family.values(raw).items()}  # decoded per fit, then read per row
        d = data.residual(rows, family.evaluate_decoded(material, values, wi, wo))
        per_row = (d * d).sum(1)
        return torch.zeros(len(fits), dtype=per_row.dtype).index_add(0, job, per_row) / (3 * sizes)

    def objectives():
        loss = losses()
        if not priced:
            return loss, loss
        scored = map_objective(loss[index], {n: v[index] for n, v in raw.items()}, own, tau2, shots, noise, counts)
        return loss, loss.index_put((index,), scored)

    adam_texels(raw, lambda gen: objectives()[1].sum(), steps, FIT_LR, seed, stage, progress)
    with torch.no_grad():
        loss, score = objectives()
    return [{"material": int(f.material), "loss": float(loss[i]), "score": float(score[i]),
             "raw": {n: raw[n].detach()[i] for n in names}} for i, f in enumerate(fits)]
