"""The optimiser of a fit and its learning-rate schedule (docs/LOSS.md, "The learning-rate decay").

AdamW in two parameter groups: the shared network (``mlp.``, ``frames.``) with the settings'
weight decay at ``lr * network_lr``, and the per-material parameters (p, z, output layers)
without decay (decay would pull kd, eta, alpha towards the middle of their ranges) at ``lr``.
A sparse fit (``frozen``) trains the per-material group only. Every rate follows
:func:`lr_factor`: cosine decay to 0 over the fit (the paper's) or exponential decay to
``lr_final``.
"""

from __future__ import annotations

import math

import torch

from hybridbrdf.fit.settings import FitSettings


def optimizer_and_schedule(module, settings: FitSettings, frozen: bool):
    """(AdamW, LambdaLR) for ``module``; with ``frozen`` the shared network stops requiring gradients."""
    net = [p for n, p in module.named_parameters() if n.startswith(("mlp.", "frames."))]
    per_material = [p for n, p in module.named_parameters() if not n.startswith(("mlp.", "frames."))]
    if frozen:
        for p in net:
            p.requires_grad_(False)
        groups = [{"params": per_material, "weight_decay": 0.0}]
    else:
        groups = [{"params": net, "weight_decay": settings.weight_decay, "lr": settings.lr * settings.network_lr},
                  {"params": per_material, "weight_decay": 0.0}]
    opt = torch.optim.AdamW(groups, lr=settings.lr)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda step: lr_factor(settings, step))
    return opt, sched


def lr_factor(settings: FitSettings, step: int) -> float:
    """The learning rate of step ``step`` (0-based) as a fraction of ``settings.lr``:
    cosine, 1/2 (1 + cos(pi t)), or exponential, lr_final^t, with t = step / steps."""
    t = min(step, settings.steps) / settings.steps
    if settings.lr_schedule == "exponential":
        return settings.lr_final ** t
    return 0.5 * (1.0 + math.cos(math.pi * t))

