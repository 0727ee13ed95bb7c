"""The cluster stage's choice of prior material made on **held-out photographs** (issue 61 part 2;
docs/ACQUISITION_GAP.md, "Selection on held-out photographs"): the standard remedy for a choice
that overfits the directions it sees.

1. **The split.** Shot k of the capture is held out when frac((k + 1/2) phi) < :data:`HELD_OUT_SHARE`,
   phi = (sqrt 5 - 1) / 2: a Weyl sequence, so about a fifth of the shots, a function of the shot's
   index only (the same capture always splits the same way, whatever the seed), spread over the
   rig's order without aliasing with its strides (a fixed stride of 5 would hold out one light for
   every camera of a stage of 5 or 10 lights; the 8x4 stage holds out shots 3, 6, 11, 16, 19 and 24:
   every camera, three lights). Every shot sees every texel on a light stage, so every cluster has
   held-out rows; a cluster without any keeps the training choice.
2. **Candidates.** Per cluster the :data:`SELECT_CANDIDATES` materials the cluster stage scores best
   on the training shots, each fitted to them (one set of values: :func:`~hybridbrdf.acquire.cluster_fit.fit_clusters`),
   then carried through the per-texel (p, z) fit of up to :data:`SELECT_TEXELS` of the cluster's
   purest texels (:func:`~hybridbrdf.acquire.texel_stage.refine_texels`, :data:`SELECT_STEPS` steps,
   training shots only): the fit the texel stage will run, on the texels that show one material.
3. **Choice.** Each candidate's *held-out loss*: the paper's mean squared log residual of those
   texels' fitted values on their held-out rows. The lowest wins.
4. **Refit.** The winner's values fitted again on all of the cluster's rows (all shots), from its
   training-shot values, by the cluster stage's objective (material_fits.map_objective): the
   cluster's values and residual variance for the stages after. From the training values, not the
   prior's: the cluster stage's screen starts a material at the cluster's colour, and 100 steps
   from a green material's own values do not reach a white paper (paper_white 10-12x the full
   measurement's cMAE when this refit started from the prior's). A cluster whose choice does not
   change thus moves a little (where its 100 steps end depends on where they start)."""

from __future__ import annotations

from typing import Dict, Optional

import numpy as np
import torch

from hybridbrdf.acquire.cluster_fit import CLUSTER_ROWS, _cluster_rows, fit_clusters, fit_material
from hybridbrdf.acquire.material_fits import value_spread
from hybridbrdf.acquire.network_tune import pure_rows, pure_texels
from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.texel_rows import ObservationTensors, Progress
from hybridbrdf.acquire.texel_stage import refine_texels

#: The share of the shots held out (frac((k + 1/2) phi) below it).
HELD_OUT_SHARE = 0.2
#: Materials per cluster carried to the held-out choice (the training-shot score's best first).
SELECT_CANDIDATES = 3
#: Pure texels of a cluster each candidate's per-texel fit runs on, and its steps.
SELECT_TEXELS, SELECT_STEPS = 64, 150
_PHI = (5 ** 0.5 - 1) / 2


def held_out_shots(n_shots: int) -> np.ndarray:
    """(n_shots,) bool: the shots held out (module docstring, step 1); none when fewer than 2 shots
    would be left to fit, or none falls in the share (a capture of a few shots: no selection)."""
    held = ((np.arange(n_shots) + 0.5) * _PHI) % 1.0 < HELD_OUT_SHARE
    return held if n_shots - held.sum() >= 2 else np.zeros(n_shots, dtype=bool)


def subset(obs: Observations, keep: np.ndarray) -> Observations:
    """The observations of rows ``keep`` ((M,) bool) only, on the same map (offsets rebuilt)."""
    texel = np.repeat(np.arange(len(obs.offsets) - 1), np.diff(obs.offsets))[keep]
    offsets = np.zeros_like(obs.offsets)
    np.cumsum(np.bincount(texel, minlength=len(obs.offsets) - 1), out=offsets[1:])
    return Observations(obs.size, offsets, obs.wi[keep], obs.wo[keep], obs.value[keep], obs.uv[keep],
                        obs.shot[keep], dict(obs.dropped))


def split_shots(obs: Observations) -> tuple:
    """(training observations, held-out observations, held-out shot indices) of ``obs``."""
    held = held_out_shots(int(obs.shot.max()) + 1 if len(obs.shot) else 0)
    rows = held[obs.shot] if len(held) else np.zeros(0, dtype=bool)
    return subset(obs, ~rows), subset(obs, rows), np.nonzero(held)[0]


def _held_out_loss(family, train: Observations, held: Observations, texels: np.ndarray, cand: Dict,
                   seed: int, tau2: Dict[str, torch.Tensor]) -> float:
    """Candidate ``cand``'s per-texel fit on ``texels``' training rows (``tau2``: the pull's variance
    per value, :func:`~hybridbrdf.acquire.material_fits.value_spread`), scored on their held-out rows."""
    keep = np.zeros(len(train.offsets) - 1, dtype=bool)
    keep[texels] = True
    mine = subset(train, np.repeat(keep, np.diff(train.offsets)))
    one = {"material": torch.tensor([cand["material"]]), "centres": {n: v[None] for n, v in cand["raw"].items()},
           "sigma2": torch.tensor([max(cand["loss"], 1e-8)])}
    zeros = np.zeros(len(keep), dtype=np.int64)
    raw = refine_texels(family, mine, ObservationTensors(mine), zeros, one, tau2, SELECT_STEPS, seed)
    rows = np.concatenate([np.arange(held.offsets[t], held.offsets[t + 1]) for t in texels] + [np.zeros(0, np.int64)])
    texel = torch.from_numpy(np.repeat(texels, np.diff(held.offsets)[texels]))
    data = ObservationTensors(held)
    with torch.no_grad():
        rows_t = torch.from_numpy(rows)
        f = family.evaluate(torch.full((len(rows),), int(cand["material"])), {n: v[texel] for n, v in raw.items()},
                            data.wi[rows_t], data.wo[rows_t])
        d = data.residual(rows_t, f)
    return float((d * d).mean())


def select_on_held_out(family, obs: Observations, data: ObservationTensors, labels: np.ndarray, seed: int,
                       progress: Optional[Progress] = None, colour: Optional[torch.Tensor] = None) -> Dict[str, object]:
    """The cluster stage with its choice made on held-out shots (module docstring): what
    :func:`~hybridbrdf.acquire.cluster_fit.fit_clusters` returns, the candidates ordered by held-out
    loss (the chosen first, its values and "loss" refitted on all shots from its training values; the others' on the
    training shots), each with "held_out_loss" and "training_loss", and "held_out_shots" (the
    indices). ``data`` holds all of ``obs``."""
    train, held, shots = split_shots(obs)
    if not len(shots):  # too few shots to hold any out: the training choice on all of them
        return {**fit_clusters(family, obs, data, labels, seed, progress, colour=colour), "held_out_shots": []}
    clusters = fit_clusters(family, train, ObservationTensors(train), labels, seed, progress, SELECT_CANDIDATES,
                            colour)
    chosen, done, total = [], 0, sum(len(f) for f in clusters["candidates"])
    every = family.raw_of_materials()
    tau2 = value_spread(every)
    for c, fitted in enumerate(clusters["candidates"]):
        texels = pure_texels(labels, obs.size, c)
        texels = texels[np.diff(held.offsets)[texels] > 0]
        if not len(texels):  # no pure texel photographed in a held-out shot: any of the cluster's
            texels = np.nonzero((labels == c) & (np.diff(held.offsets) > 0))[0]
        if len(texels) > SELECT_TEXELS:
            texels = np.sort(np.random.default_rng([seed, c]).choice(texels, SELECT_TEXELS, replace=False))
        for cand in fitted:
            cand["training_loss"] = cand["loss"]
            cand["held_out_loss"] = _held_out_loss(family, train, held, texels, cand, seed, tau2) if len(texels) else None
            done += 1
            if progress is not None:
                progress("held-out choice", done, total)
        if len(texels):
            fitted.sort(key=lambda cand: cand["held_out_loss"])  # stable: a tie keeps the training order
        if fitted:
            rows = _cluster_rows(obs, labels, c, CLUSTER_ROWS, seed)
            best = fitted[0]
            m = int(best["material"])
            own = {**{n: v[m] for n, v in every.items()}, "tau2": tau2}
            refit = fit_material(family, data, rows, m, best["raw"], seed, f"cluster{c}-{m}", own,
                                 len(np.unique(obs.shot[rows.numpy()])), data.pixel_noise(pure_rows(obs, labels, c)))
            best.update(loss=refit["loss"], score=refit["score"], raw=refit["raw"])
        chosen.append(fitted)
    first = [f[0] if f else None for f in chosen]
    fallback = next(f for f in first if f is not None)  # fit_clusters gives the first cluster rows
    pick = [f or fallback for f in first]
    return {"material": torch.tensor([p["material"] for p in pick]),
            "centres": {n: torch.stack([p["raw"][n] for p in pick]) for n in every},
            "sigma2": torch.tensor([max(p["loss"], 1e-8) for p in pick]), "candidates": chosen,
            "held_out_shots": [int(s) for s in shots]}
