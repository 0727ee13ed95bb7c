"""Where a sparse fit starts and which of its starts it keeps (paper Sec. 4.2; docs/ADDING.md,
"Sparse fitting"): each new material starts from the (p, z) of the frozen model's material with
the lowest training loss on it (:func:`start_from_nearest`), optionally from its k best ones at
once, of which the fit with the lowest training loss is kept (:func:`best_starts`,
:func:`keep_materials`). A warm start (``fit(init=...)``) places the sources its model lacks the
same way.
"""

from __future__ import annotations

from typing import List, Optional, Sequence

import torch

from hybridbrdf import spec
from hybridbrdf.fit.loss import training_loss
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.model.file import HybridModel
from hybridbrdf.model.networks import build_model
from hybridbrdf.fit.pool import TrainingPool


def start_from_nearest(module, frozen: HybridModel, pool: TrainingPool, eps, eps_analytic,
                       settings: FitSettings, n_pairs: int = 8192, chunk: int = 64, starts: int = 1,
                       rows: Optional[Sequence[int]] = None) -> List[int]:
    """Sparse fitting's starting point (FitSettings.sparse_init = "nearest"): give every new
    material the (p, z) of the frozen model's material with the lowest training loss on the
    new material's pool values, and return those materials' indices. With ``starts`` = k > 1
    the pool and the module hold each new material k times in a row (rows m k + j), and row
    m k + j starts from the j-th best material (FitSettings.sparse_starts).

    Only (p, z) move in a sparse fit, and the loss over them is far from convex: a glossy
    measurement started from the neutral grey rough lobe must first narrow alpha by orders of
    magnitude while z wanders through codes the network never saw. A collection that holds a
    similar material already knows a (p, z) the network decodes well. Scoring all of them
    costs one forward pass per candidate on ``n_pairs`` pool pairs (spread over the cosine and
    specular parts of the pool), a few training steps' worth. ``rows``: set only these
    materials (a warm start keeps the others' own (p, z)); every material is scored."""
    dev = pool.wi.device
    step = max(1, pool.wi.shape[0] // n_pairs)
    idx = torch.arange(0, pool.wi.shape[0], step, device=dev)[:n_pairs]
    wi, wo, ref = pool.wi[idx], pool.wo[idx], pool.ref[:, idx]
    cand = {k[len("materials."):]: torch.from_numpy(v).to(dev) for k, v in frozen.tensors.items()
            if k.startswith("materials.")}
    n_new, n_cand = ref.shape[0], cand["z"].shape[0]

    def for_material(e, m: int, k: int):
        """The new material m's epsilon (scalar or per material) for k candidates."""
        return e[m].expand(k) if isinstance(e, torch.Tensor) else e

    losses = torch.empty(n_new, n_cand, device=dev)
    with torch.no_grad():
        for lo in range(0, n_cand, chunk):
            c = {k: v[lo:lo + chunk] for k, v in cand.items()}
            if "kd" in c:
                head = (c["head_weight"], c["head_bias"]) if "head_weight" in c else None
                f_t, f_a = module.evaluate(wi, wo, c["kd"], c["eta"], c["alpha"], c["z"], head)
            else:
                f_t, f_a = module.evaluate(wi, wo, c["z"])
            k = f_t.shape[0]
            for m in range(n_new):
                losses[m, lo:lo + chunk] = training_loss(
                    ref[m].expand_as(f_t), f_t, f_a, wi[:, 2], for_material(eps, m, k),
                    for_material(eps_analytic, m, k), settings.loss_cos, settings.analytic_expectile)
        order = torch.argsort(losses, dim=1, stable=True)
        best = [int(order[m, m % starts]) for m in range(n_new)]
        for m, k in enumerate(best):
            if rows is not None and m not in rows:
                continue
            if "kd" in cand:
                module.set_analytic(m, cand["kd"][k], cand["eta"][k], cand["alpha"][k])
            module.z[m] = cand["z"][k]
            if "head_weight" in cand:
                module.head_weight[m] = cand["head_weight"][k]
                module.head_bias[m] = cand["head_bias"][k]
    return best


def best_starts(module, pool: TrainingPool, starts: int, eps, eps_analytic, settings: FitSettings,
                n_pairs: int = 65536, chunk: int = 16384) -> List[int]:
    """The row of each new material's best fit in a sparse fit from ``starts`` starts per
    material (rows m k .. m k + k - 1): the lowest training loss on ``n_pairs`` pool pairs
    spread over its cosine and specular parts, the loss the fit minimised."""
    dev = pool.wi.device
    step = max(1, pool.wi.shape[0] // n_pairs)
    idx = torch.arange(0, pool.wi.shape[0], step, device=dev)[:n_pairs]
    total = torch.zeros(pool.ref.shape[0], device=dev)
    with torch.no_grad():
        for lo in range(0, len(idx), chunk):
            i = idx[lo:lo + chunk]
            f_t, f_a = module(pool.wi[i], pool.wo[i])
            total += training_loss(pool.ref[:, i], f_t, f_a if spec.ARCHS[settings.arch]["analytic"] else None,
                                   pool.wi[i, 2], eps, eps_analytic,
                                   settings.loss_cos, settings.analytic_expectile) * len(i)
    per_start = total.reshape(-1, starts)
    return [m * starts + int(j) for m, j in enumerate(per_start.argmin(dim=1))]


def keep_materials(module, rows: List[int], settings: FitSettings, iso: List[bool]):
    """A module of the same network holding only the per-material parameters of ``rows``."""
    kept = build_model(settings.arch, len(rows), settings.width, settings.depth, settings.latent,
                       settings.activation, iso, output_layer=settings.network_output_layer())
    index = torch.tensor(rows, device=next(module.parameters()).device)
    shared = ("mlp.", "frames.")
    kept.load_state_dict({k: (v if k.startswith(shared) else v[index]) for k, v in module.state_dict().items()})
    return kept
