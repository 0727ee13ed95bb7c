"""Per-texel fits from a capture's observations (docs/ACQUISITION.md, issue 46 step 2, begun).

Built so far: the **analytic-only** model, f_a's parameters p = (kd, eta, alpha) per texel (the
same Lambert + GGX as the hybrid's analytic part; isotropic alpha), all texels fitted at once in
one batched PyTorch problem (each texel's parameters see only its own rows, so a step is one
vectorised evaluation over every observation, not a loop over texels). The loss is the paper's
per pair, L = || log(1 + cos(theta_i) g_obs) - log(1 + cos(theta_i) f_a) ||^2 (docs/CONVENTIONS.md),
observations below 0 (noise) clamped to 0 first. The hybrid (p, z on a frozen prior) and the
neural-only fits of issue 46 are not built yet."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from hybridbrdf import spec
from hybridbrdf.acquire.evaluation import eval_chunked
from hybridbrdf.acquire.observations import Observations
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


def _logit(p: np.ndarray) -> np.ndarray:
    p = np.clip(p, 1e-4, 1 - 1e-4)
    return np.log(p / (1 - p))


def fit_analytic_texels(obs: Observations, steps: int = 400, lr: float = 0.05, seed: int = 0) -> AnalyticMaps:
    """Fit f_a per texel to ``obs`` by Adam on every observation at once (``steps`` steps, rate
    ``lr``). Parameters are reparameterised to stay in range: kd = sigmoid, eta = 1 + 9 sigmoid,
    alpha = ALPHA_MIN + (1 - ALPHA_MIN) sigmoid^2 (a perceptual roughness). kd starts at pi times
    the texel's mean observed value (the Lambertian that explains it), eta and alpha at
    :data:`START_ETA`, :data:`START_ALPHA`."""
    w, h = obs.size
    n_tex = w * h
    counts = np.diff(obs.offsets)
    texel = torch.from_numpy(np.repeat(np.arange(n_tex), counts))
    wi, wo = torch.from_numpy(obs.wi), torch.from_numpy(obs.wo)
    g = torch.from_numpy(np.maximum(obs.value, 0.0))
    sums = np.zeros((n_tex, 3))
    np.add.at(sums, texel.numpy(), np.maximum(obs.value, 0.0))
    mean = sums / np.maximum(counts, 1)[:, None]
    torch.manual_seed(seed)
    kd_u = torch.tensor(_logit(np.clip(np.pi * mean, 0.02, 0.98)), dtype=torch.float32, requires_grad=True)
    eta_u = torch.full((n_tex, 3), float(_logit(np.array((START_ETA - 1) / 9))), requires_grad=True)
    rough_u = torch.full((n_tex, 1), float(_logit(np.sqrt(np.array(START_ALPHA)))), requires_grad=True)
    params = [kd_u, eta_u, rough_u]

    def decoded():
        kd = torch.sigmoid(kd_u)
        eta = 1 + (spec.ETA_MAX - 1) * torch.sigmoid(eta_u)
        r = torch.sigmoid(rough_u)
        alpha = spec.ALPHA_MIN + (1 - spec.ALPHA_MIN) * r * r
        return kd, eta, torch.cat([alpha, alpha], dim=1)

    if len(g):
        opt = torch.optim.Adam(params, lr=lr)
        cos_i = wi[:, 2:3]
        target = torch.log1p(cos_i * g)
        for _ in range(steps):
            opt.zero_grad()
            kd, eta, alpha = decoded()
            f = eval_analytic(wi, wo, kd[texel], eta[texel], alpha[texel])
            d = target - torch.log1p(cos_i * f)
            loss = (d * d).sum()
            loss.backward()
            opt.step()
    with torch.no_grad():
        kd, eta, alpha = decoded()
    shape = (h, w)
    return AnalyticMaps(kd.numpy().reshape(*shape, 3), eta.numpy().reshape(*shape, 3),
                        alpha.numpy().reshape(*shape, 2), counts.reshape(shape))
