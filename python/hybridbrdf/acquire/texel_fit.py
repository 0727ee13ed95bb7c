"""The **analytic-only** per-texel fit (docs/ACQUISITION.md, issue 46): f_a's parameters
p = (kd, eta, alpha) per texel (the same Lambert + GGX as the hybrid's analytic part; isotropic
alpha), all texels fitted at once in one batched PyTorch problem (each texel's parameters see only
its own rows, so a step is one vectorised evaluation over rows of every texel, not a loop over
texels; :mod:`~hybridbrdf.acquire.texel_rows`). The loss per pair is
L = || log(eps + cos(theta_i) g_obs) - log(eps + cos(theta_i) f_a) ||^2 (docs/CONVENTIONS.md; the
paper's with eps 1; :data:`~hybridbrdf.acquire.texel_rows.LOSS_EPS`), observations below
:data:`~hybridbrdf.acquire.texel_rows.TARGET_FLOOR` eps (noise) raised to it first. The hybrid
and neural-only fits start from it (their partition of the texels at eps 1: ``cluster_fit.PARTITION_LOSS_EPS``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Dict, Optional

import numpy as np
import torch

from hybridbrdf import spec
from hybridbrdf.acquire import footprint
from hybridbrdf.acquire.evaluation import eval_chunked
from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.texel_rows import ROWS_PER_TEXEL, ObservationTensors, Progress, RowSampler, adam_texels
from hybridbrdf.brdf.torch_brdf import eval_analytic

#: kd, eta, alpha of a texel without observations (and a fit's start for eta and alpha).
START_ETA, START_ALPHA = 1.5, 0.3


@dataclass
class AnalyticMaps:
    """(H, W, 3) kd, (H, W, 3) eta, (H, W, 2) alpha per texel, float32, and (H, W) the count of
    observations each was fitted to (0: the start values, nothing seen)."""
    kd: np.ndarray
    eta: np.ndarray
    alpha: np.ndarray
    counts: np.ndarray

    def eval(self, texel: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """The fitted f_a (no cosine) at texels ``texel`` ((M,) int, j * W + i) for directions
        ``wi``, ``wo`` (M, 3) in the sample's frame: (M, 3) float64, evaluated in chunks."""
        texel = np.asarray(texel, dtype=np.int64)
        kd, eta, alpha = (m.reshape(-1, m.shape[-1]) for m in (self.kd, self.eta, self.alpha))
        return eval_chunked(texel, wi, wo, kd.shape[0],
                            lambda t, a, b: eval_analytic(a, b, torch.from_numpy(kd[t]).double(),
                                                          torch.from_numpy(eta[t]).double(),
                                                          torch.from_numpy(alpha[t]).double()))

    def eval_uv(self, uv: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """The fit at uv (M, 2) as its maps show there, read bilinearly between texel centres
        (:func:`~hybridbrdf.acquire.footprint.filtered`, the fits' observation model): (M, 3) float64."""
        v = footprint.filtered({"kd": self.kd, "eta": self.eta, "alpha": self.alpha}, uv)
        return eval_chunked(np.arange(len(uv)), wi, wo, len(uv),
                            lambda t, a, b: eval_analytic(a, b, *(torch.from_numpy(v[n][t]) for n in ("kd", "eta", "alpha"))))


def _logit(p: np.ndarray) -> np.ndarray:
    p = np.clip(p, 1e-4, 1 - 1e-4)
    return np.log(p / (1 - p))


def analytic_start(obs: Observations) -> Dict[str, torch.Tensor]:
    """Raw (unconstrained) start values per texel: kd at pi times the texel's mean observed value
    (the Lambertian that explains it), eta and alpha at :data:`START_ETA`, :data:`START_ALPHA`."""
    n_tex = obs.size[0] * obs.size[1]
    counts = np.diff(obs.offsets)
    sums = np.zeros((n_tex, 3))
    np.add.at(sums, np.repeat(np.arange(n_tex), counts), np.maximum(obs.value, 0.0))
    mean = sums / np.maximum(counts, 1)[:, None]
    return {"kd": torch.tensor(_logit(np.clip(np.pi * mean, 0.02, 0.98)), dtype=torch.float32),
            "eta": torch.full((n_tex, 3), float(_logit(np.array((START_ETA - 1) / (spec.ETA_MAX - 1))))),
            "rough": torch.full((n_tex, 1), float(_logit(np.sqrt(np.array(START_ALPHA)))))}


def decode_analytic(raw: Dict[str, torch.Tensor]):
    """(kd, eta, alpha (., 2)) of raw values: kd = sigmoid, eta = 1 + 9 sigmoid,
    alpha = ALPHA_MIN + (1 - ALPHA_MIN) sigmoid^2 (a perceptual roughness, isotropic)."""
    kd = torch.sigmoid(raw["kd"])
    eta = 1 + (spec.ETA_MAX - 1) * torch.sigmoid(raw["eta"])
    r = torch.sigmoid(raw["rough"])
    alpha = spec.ALPHA_MIN + (1 - spec.ALPHA_MIN) * r * r
    return kd, eta, torch.cat([alpha, alpha], dim=1)


def fit_analytic_texels(obs: Observations, steps: int = 400, lr: float = 0.05, seed: int = 0,
                        rows_per_texel: Optional[int] = ROWS_PER_TEXEL, progress: Optional[Progress] = None,
                        state: Optional[dict] = None, save_state: Optional[Callable[[dict], None]] = None,
                        observation_model: Optional[str] = None, loss_eps: Optional[float] = None) -> AnalyticMaps:
    """Fit f_a per texel to ``obs``: ``steps`` Adam steps (rate ``lr`` decaying to a tenth), each
    on ``rows_per_texel`` rows drawn from every texel's own (None: every observation every step).
    Parameters are reparameterised to stay in range (:func:`decode_analytic`) and start at
    :func:`analytic_start`. ``progress`` is called after each step with ("analytic", done,
    steps); ``save_state`` gets a resumable state every 50 steps, ``state`` resumes one.
    ``observation_model``: "bilinear" (each row as its footprint shows the map,
    :mod:`~hybridbrdf.acquire.footprint`) or "nearest" (each row credited to its cell's texel);
    None: :data:`hybridbrdf.acquire.footprint.MODEL`. ``loss_eps``: the loss domain's epsilon
    (:func:`~hybridbrdf.acquire.texel_rows.loss_log`; None: :data:`~hybridbrdf.acquire.texel_rows.LOSS_EPS`)."""
    model = observation_model or footprint.MODEL
    if model not in footprint.MODELS:
        raise ValueError(f"observation_model must be one of {', '.join(footprint.MODELS)}, got {observation_model!r}")
    w, h = obs.size
    counts = np.diff(obs.offsets)
    raw = {k: v.requires_grad_() for k, v in analytic_start(obs).items()}
    data = ObservationTensors(obs, loss_eps)
    sampler = RowSampler(obs, rows_per_texel or 1)
    every_row = (torch.from_numpy(np.repeat(np.arange(w * h), counts)), torch.arange(len(obs.value)))

    one_layer = footprint.Footprint(obs.uv, obs.size, np.zeros(w * h, np.int64), {}) if model == "bilinear" else None

    def loss(gen):
        texel, rows = every_row if rows_per_texel is None else sampler.draw(gen)
        kd, eta, alpha = decode_analytic(raw)
        wi, wo = data.wi[rows], data.wo[rows]
        if one_layer is None:
            f = eval_analytic(wi, wo, kd[texel], eta[texel], alpha[texel])
        else:  # each row as its footprint shows the map (:mod:`~hybridbrdf.acquire.footprint`)
            f = one_layer.predict(lambda _, v, a, b: eval_analytic(a, b, v["kd"], v["eta"], v["alpha"]),
                                  {"kd": kd, "eta": eta, "alpha": alpha}, torch.zeros_like(rows), rows, wi, wo)
        d = data.residual(rows, f)
        return (d * d).sum() / (rows_per_texel or 1)

    if len(obs.value):
        adam_texels(raw, loss, steps, lr, seed, "analytic", progress, state, save_state)
    with torch.no_grad():
        kd, eta, alpha = decode_analytic(raw)
    shape = (h, w)
    return AnalyticMaps(kd.numpy().reshape(*shape, 3), eta.numpy().reshape(*shape, 3),
                        alpha.numpy().reshape(*shape, 2), counts.reshape(shape))
