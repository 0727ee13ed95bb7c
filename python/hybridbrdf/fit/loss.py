"""The loss a fit minimises (paper Sec. 3.3, docs/CONVENTIONS.md "Fitting"):

    loss = sum_materials mean_batch  L(f_ref, f_a) + L(f_ref, f_t)
    L(f1, f2) = || log(1 + cos(theta_i) f1) - log(1 + cos(theta_i) f2) ||^2   (squared norm over RGB)

with this project's variants (FitSettings, "loss" section): another epsilon than 1, one per
material scaled by its brightness, the analytic term's own epsilon, no cos(theta_i) weight,
an asymmetric analytic term. The neural baseline has no analytic term.
"""

from __future__ import annotations

from typing import Callable, Optional

import torch

from hybridbrdf import spec
from hybridbrdf.fit.settings import FitSettings


def log_cos_loss(f_ref: torch.Tensor, f: torch.Tensor, cos_i: torch.Tensor, eps=1.0,
                 expectile: float = 0.5) -> torch.Tensor:
    """Per-material L: mean over the batch of the squared RGB norm of
    d = log(eps + cos f_ref) - log(eps + cos f). (M,). eps = 1 is the paper's loss; a tensor of
    shape (M,) gives every material its own epsilon. ``expectile`` tau != 0.5 weighs each squared
    channel difference by 2 tau where f is below f_ref (d > 0) and 2 (1 - tau) where it is above."""
    c = cos_i[None, :, None]
    if isinstance(eps, torch.Tensor):
        e = eps[:, None, None]
        d = torch.log(e + c * f_ref) - torch.log(e + c * f)
    elif eps == 1.0:
        d = torch.log1p(c * f_ref) - torch.log1p(c * f)
    else:
        d = torch.log(eps + c * f_ref) - torch.log(eps + c * f)
    if expectile == 0.5:
        return (d * d).sum(-1).mean(-1)
    w = torch.where(d > 0, d.new_tensor(2.0 * expectile), d.new_tensor(2.0 * (1.0 - expectile)))
    return (w * d * d).sum(-1).mean(-1)


def training_loss(ref: torch.Tensor, f_t: torch.Tensor, f_a: Optional[torch.Tensor], cos_i: torch.Tensor,
                  eps, eps_analytic=None, loss_cos: bool = True, analytic_expectile: float = 0.5) -> torch.Tensor:
    """Per-material loss of one batch (M,): L(f_ref, f_t) + L(f_ref, f_a) (CONVENTIONS, paper
    Sec. 3.3), the analytic term left out when ``f_a`` is None (the neural baseline).
    ``eps_analytic`` (default ``eps``) is the analytic term's epsilon; ``loss_cos=False`` drops
    the cos(theta_i) weight inside the logarithm (FitSettings.loss_cos); ``analytic_expectile`` makes
    the analytic term asymmetric (FitSettings.analytic_expectile)."""
    weight = cos_i if loss_cos else torch.ones_like(cos_i)
    loss = log_cos_loss(ref, f_t, weight, eps)
    if f_a is not None:
        loss = loss + log_cos_loss(ref, f_a, weight, eps if eps_analytic is None else eps_analytic,
                                   analytic_expectile)
    return loss


def loss_epsilons(settings: FitSettings, pool):
    """(eps, eps_analytic) of a fit on ``pool`` (a :class:`~hybridbrdf.fit.pool.TrainingPool`):
    the settings' numbers, or with ``loss_eps_relative`` tensors (M,) scaled by each material's
    brightness (mean cos f_ref, or mean f_ref without the cos weight)."""
    # A black material (brightness 0) falls back to the smallest epsilon float32 keeps well above
    # the cos f values it is compared with (1e-6 of a typical 0.1-1 brightness).
    scale = (torch.clamp(pool.brightness if settings.loss_cos else pool.mean_f, min=1e-6)
             if settings.loss_eps_relative else 1.0)
    eps = settings.loss_eps * scale
    eps_analytic = (settings.loss_eps if settings.analytic_loss_eps is None else settings.analytic_loss_eps) * scale
    return eps, eps_analytic


def batch_loss_function(net, settings: FitSettings, eps, eps_analytic,
                        compile_step: bool = False) -> Callable[[torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor]:
    """``batch_loss(wi, wo, ref)``: the summed loss of ``net`` (the module, or its
    DistributedDataParallel wrapper) on one batch; run through ``torch.compile`` when ``compile_step``."""
    has_analytic = spec.ARCHS[settings.arch]["analytic"]

    def batch_loss(wi: torch.Tensor, wo: torch.Tensor, ref: torch.Tensor) -> torch.Tensor:
        f_t, f_a = net(wi, wo)
        return training_loss(ref, f_t, f_a if has_analytic else None, wi[:, 2], eps, eps_analytic,
                             settings.loss_cos, settings.analytic_expectile).sum()

    if compile_step:
        # Every batch has the same shapes, so one static graph serves the whole fit.
        batch_loss = torch.compile(batch_loss, dynamic=False)
    return batch_loss
