"""What every per-texel fit of docs/ACQUISITION.md shares: rows sampled per texel per step, the
loss per pair (the paper's, with an epsilon: :func:`loss_log`), and the Adam loop over every texel's parameters at once.

A step reads ``rows_per_texel`` rows of every texel that has observations (drawn uniformly from
its own rows, with replacement), not every observation: a 128x128 map of a 512x512 16-photograph
capture holds 1.45 M observations, 71 to 108 per texel, and 8 rows per texel per step is 131 k
rows, 11x fewer, with each texel's loss an unbiased estimate of its mean over all its rows.
The draw of step ``k`` of stage ``s`` depends only on (seed, s, k), so a resumed fit draws what
the uninterrupted one would have."""

from __future__ import annotations

import copy
import hashlib
from typing import Callable, Dict, Optional

import numpy as np
import torch

from hybridbrdf.acquire.observations import Observations

#: Rows of each texel read per step (the budget unit: a step of every fit reads this many).
ROWS_PER_TEXEL = 8

#: The least cos(theta_i) g a row's target is taken at, in units of the loss's eps. Not 0: a photograph's noise makes a dark
#: pixel's reading negative (a raw frame less its black level), and clamped at 0 the darkest rows
#: read brighter than they are. On the light-stage bench at high noise (200 photons at radiance 1,
#: read noise 4), the darkest tenth of colodur_napoli's rows read 17% brighter on average and the
#: next 5%; unclamped, none differs from the noiseless photograph's by more than its error
#: (docs/ACQUISITION_GAP.md, "The target unclamped"). A floor all the same, so that log(eps + x)
#: stays defined (x > -eps) and its slope 1 / (eps + x) at most 2 / eps: at eps 0.1, -0.05 is 2.5
#: standard deviations of the bench's noisiest dark pixel; a reading further below 0 is a bad black level.
TARGET_FLOOR = -0.5

#: The loss domain's epsilon: every acquisition fit compares log(eps + cos(theta_i) f)
#: (:func:`loss_log`), relative down to cos f ~ eps (docs/LOSS.md, "Dark regions"). The paper's
#: 1 is absolute below cos f ~ 1, where a glossy layer spends most of its domain: on the
#: light-stage verdict's vinyl disc the gate of the chosen material closed the blue channel to
#: 3e-4 where the photographs (and the truth) read 4e-3, for a loss of 1e-5 (docs/ACQUISITION_LOSS.md).
#: 0.1 is ``hbrdf fit``'s default (``--loss-eps``), and at the bench's high
#: noise (a dark pixel's standard deviation 0.02 in cos f) the log of a noisy reading is biased by
#: about (0.02 / 0.1)^2 / 2 = 2%; at 0.03 (``hbrdf add``'s) by 22%.
LOSS_EPS = 0.1


def loss_log(cos_f: torch.Tensor, eps: Optional[float] = None) -> torch.Tensor:
    """The acquisition fits' loss domain of cos(theta_i) f: log(1 + cos f / eps) = log(eps + cos f)
    - log(eps), eps ``eps`` or :data:`LOSS_EPS` (the constant cancels in every residual)."""
    return torch.log1p(cos_f / (LOSS_EPS if eps is None else eps))


#: (stage, steps done, steps of the stage) after each step; what a progress bar shows.
Progress = Callable[[str, int, int], None]


def step_generator(seed: int, stage: str, step: int) -> torch.Generator:
    """A generator for step ``step`` of ``stage``, a function of (seed, stage, step) only."""
    digest = hashlib.sha256(f"{seed}:{stage}:{step}".encode()).digest()
    return torch.Generator().manual_seed(int.from_bytes(digest[:8], "little") & (2 ** 63 - 1))


class RowSampler:
    """Rows of a texel set drawn per step: ``draw(gen)`` gives (texel (N,), row (N,)) tensors,
    ``per_texel`` rows of each texel in ``texels`` (default: every texel with observations)."""

    def __init__(self, obs: Observations, per_texel: int = ROWS_PER_TEXEL, texels: Optional[np.ndarray] = None):
        counts = np.diff(obs.offsets)
        active = np.nonzero(counts > 0)[0] if texels is None else np.asarray(texels, dtype=np.int64)
        active = active[counts[active] > 0]
        self.texels = torch.from_numpy(active)
        self.start = torch.from_numpy(obs.offsets[active])
        self.count = torch.from_numpy(counts[active])
        self.per_texel = int(per_texel)

    def draw(self, gen: torch.Generator):
        u = torch.rand((len(self.texels), self.per_texel), generator=gen, dtype=torch.float64)
        pick = torch.minimum((u * self.count[:, None]).long(), self.count[:, None] - 1)
        return self.texels.repeat_interleave(self.per_texel), (self.start[:, None] + pick).reshape(-1)


class ObservationTensors:
    """The observations as tensors: ``wi``, ``wo`` (M, 3), ``target`` = :func:`loss_log` of
    cos(theta_i) g, in the domain of ``eps`` (None: :data:`LOSS_EPS`), with cos(theta_i) g at
    least :data:`TARGET_FLOOR` eps (noise may make it negative), ``cos_i``
    (M, 1); ``cell`` (M,) each row's (texel, photograph) as one number, for :meth:`pixel_noise`."""

    def __init__(self, obs: Observations, eps: Optional[float] = None):
        self.wi, self.wo = torch.from_numpy(obs.wi), torch.from_numpy(obs.wo)
        self.cos_i = self.wi[:, 2:3]
        self.eps = LOSS_EPS if eps is None else float(eps)
        self.target = loss_log(torch.clamp(self.cos_i * torch.from_numpy(obs.value), min=TARGET_FLOOR * self.eps), self.eps)
        texel = np.repeat(np.arange(len(obs.offsets) - 1), np.diff(obs.offsets))
        self.cell = texel * (int(obs.shot.max(initial=0)) + 1) + np.asarray(obs.shot, dtype=np.int64)
        self._averaged = None  # cell_averaged's copy, made on first use

    def pixel_noise(self, rows: torch.Tensor) -> float:
        """The photographs' noise in the loss domain: the variance of one row's ``target`` about its
        expectation, per channel, over ``rows``, estimated from pairs of rows next to each other that
        belong to the same texel and photograph (neighbouring pixels: they see one direction pair
        to within a texel's footprint, so half their squared difference is the sensor's noise, plus
        what the BRDF changes across a texel, which makes it an upper bound). 0 without such pairs.
        Why it is needed: a fit's mean squared residual is this noise plus what its model misses, and
        only the second is shared by a photograph's pixels (:func:`~hybridbrdf.acquire.material_fits.map_objective`)."""
        r = np.sort(np.asarray(rows, dtype=np.int64))
        pair = (np.diff(r) == 1) & (self.cell[r[1:]] == self.cell[r[:-1]])
        if not pair.any():
            return 0.0
        d = (self.target[r[1:][pair]] - self.target[r[:-1][pair]]).double()
        return float((d * d).mean() / 2)

    def cell_averaged(self) -> "ObservationTensors":
        """A copy whose every row's ``target`` is the mean target of the rows of its (texel,
        photograph) cell, with ``cell_size`` (M,) those rows' count: the pixels of a cell see one
        direction pair to within a texel's footprint (each row turned about the normal by its own
        azimuth by default, :mod:`~hybridbrdf.acquire.isotropy`: for an isotropic material still the
        same pair), so the mean keeps a row's expectation (the
        loss domain's, the target's own) and divides its noise's variance by the cell's size. What
        the final clusters' choice scores materials on (:func:`~hybridbrdf.acquire.cluster_fit.fit_clusters`).
        Computed once and kept."""
        if self._averaged is None:
            _, cell = np.unique(self.cell, return_inverse=True)
            cell = torch.from_numpy(cell.reshape(-1))
            size = torch.bincount(cell).to(self.target.dtype)
            sums = torch.zeros(len(size), self.target.shape[1], dtype=self.target.dtype).index_add_(0, cell, self.target)
            averaged = copy.copy(self)
            averaged.target, averaged.cell_size = (sums / size[:, None])[cell], size[cell]
            self._averaged = averaged
        return self._averaged

    def residual(self, rows: torch.Tensor, f: torch.Tensor) -> torch.Tensor:
        """The residual per pair and channel, log(eps + cos g) - log(eps + cos f), (N, 3) (the paper's with eps 1)."""
        return self.target[rows] - loss_log(self.cos_i[rows] * f, self.eps)


def adam_texels(params: Dict[str, torch.Tensor], loss_fn: Callable[[torch.Generator], torch.Tensor], steps: int,
                lr: float, seed: int, stage: str, progress: Optional[Progress] = None, state: Optional[dict] = None,
                save_state: Optional[Callable[[dict], None]] = None, every: int = 50,
                stop: Optional[int] = None) -> dict:
    """Adam on ``params`` (leaf tensors, changed in place) for ``steps`` steps of
    ``loss_fn(generator)``, the rate decaying linearly from ``lr`` to ``lr / 10``; ``state`` (a dict :func:`adam_texels` passed to ``save_state``) resumes
    at its step with its parameters and moments. ``save_state`` gets {"step", "params", "adam"}
    every ``every`` steps. ``stop``: the steps end there (the rate's schedule still that of
    ``steps``), to be resumed from the state returned: {"step", "params", "adam"} after the last step."""
    names = sorted(params)
    opt = torch.optim.Adam([params[n] for n in names], lr=lr)
    start = 0
    if state is not None:
        with torch.no_grad():
            for n in names:
                params[n].copy_(state["params"][n])
        opt.load_state_dict(state["adam"])
        start = int(state["step"])
    done = start
    for k in range(start, steps if stop is None else min(stop, steps)):
        for group in opt.param_groups:  # linear decay to a tenth: the last steps average the draws' noise
            group["lr"] = lr * (1.0 - 0.9 * k / steps)
        opt.zero_grad()
        loss = loss_fn(step_generator(seed, stage, k))
        loss.backward()
        opt.step()
        done = k + 1
        if progress is not None:
            progress(stage, k + 1, steps)
        if save_state is not None and (k + 1) % every == 0 and k + 1 < steps:
            save_state({"step": k + 1, "params": {n: params[n].detach().clone() for n in names},
                        "adam": opt.state_dict()})
    return {"step": done, "params": {n: params[n].detach() for n in names}, "adam": opt.state_dict()}
