"""The acquisition fit's network fine-tune (issue 61 part 2; docs/ACQUISITION_GAP.md): after the
cluster stage, the prior's shared network (its hidden layers), each cluster's output layer (head)
and each cluster's values trained together on the capture's observations of each cluster's
purest texels, with the prior's own materials replayed against the prior's output so that the
network cannot forget them, as ``hbrdf add --refine`` replays a base's materials
(:class:`~hybridbrdf.sources.model.ModelMaterialSource`). The texel stage then fits every texel's
(p, z) on the tuned network, and the written model carries it.

Per step, with d the fits' residual log(eps + cos g) - log(eps + cos f) (docs/CONVENTIONS.md; eps
:data:`~hybridbrdf.acquire.texel_rows.LOSS_EPS`):

    L = (1/K) sum_c [mean_{rows of c's pure texels} d^2 + ANCHOR_WEIGHT mean_{anchor pairs} min(0, a_c)^2]
        + REPLAY_WEIGHT mean_{replayed rows} d^2,

a_c = log(eps + cos f_c,start) - log(eps + cos f_c) on :data:`ANCHOR_PAIRS` fixed cosine-distributed
pairs over the whole hemisphere, f_c,start the cluster as it started (the frozen prior, its start
head and values): the *anchor*, one-sided, so a cluster may darken or change its shape freely but
pays for becoming brighter than it started. The photographs see a few direction pairs; where none
looked, nothing else held the tuned network, and one vch_golden_yellow capture's layer rose by
orders of magnitude there, which its energy-bound table then crushed to near black toward normal
incidence (15.9x the full measurement's cMAE; docs/ACQUISITION_GAP.md). A two-sided anchor of the
same weight also held it but took back most of what the fine-tune buys colodur_napoli. The
replayed rows :data:`REPLAY_MATERIALS` of the prior's materials a step (their (p, z) and head
fixed at the prior's), each on :data:`REPLAY_PAIRS` fixed cosine-distributed direction pairs with
the prior's own f as the target. Each cluster starts from its head and values as the head refit
leaves them, or from its material's (cluster_fit.start_heads). A texel is *pure* when its 8 neighbours share its cluster: the
fit sees one material there, where a texel on a boundary is photographed as a mix (the bench's
footprint, docs/ACQUISITION_GAP.md). The drift is what the fine-tune cost the prior: per prior
material, SMAPE and cMAE of the tuned network against the prior on :data:`DRIFT_PAIRS` pairs."""

from __future__ import annotations

import copy
from typing import Dict, Optional, Tuple

import numpy as np
import torch

from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.texel_rows import ObservationTensors, Progress, loss_log, step_generator
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.evaluate.metrics import cmae, smape

#: Capture rows of each cluster per step (drawn from its pure texels' rows, with replacement).
CAPTURE_ROWS = 2048
#: Prior materials replayed per step, and the fixed direction pairs each is replayed on.
REPLAY_MATERIALS, REPLAY_PAIRS = 16, 256
#: The replay term's weight against the capture's (both are a mean squared residual per row and channel).
REPLAY_WEIGHT = 1.0
#: Adam rates at the first step (decaying linearly to a tenth): the hidden layers', and the heads'
#: and cluster values' (the head refit's and cluster stage's order of rate).
NETWORK_LR, HEAD_LR = 2e-3, 1e-2
#: The heads' pull toward their start, a multiple of its MAP weight (0: none, the default measured in
#: docs/ACQUISITION_GAP.md; the bench's finetune_pull sets 1).
HEAD_PULL = 0.0
#: The clusters' anchor (module docstring): per cluster, :data:`ANCHOR_PAIRS` fixed cosine-distributed
#: pairs with its own start as the ceiling, weighed ANCHOR_WEIGHT against the capture; 0: none (the
#: bench's finetune200_free).
ANCHOR_PAIRS, ANCHOR_WEIGHT = 512, 0.1
#: Direction pairs of the drift report per prior material.
DRIFT_PAIRS = 2000


def cosine_pairs(n: int, seed: int) -> tuple:
    """``n`` (wi, wo) pairs, each direction cosine-distributed over the upper hemisphere, (n, 3) float32."""
    rng = np.random.default_rng(seed)
    wi, wo = cosine_directions(rng, n), cosine_directions(rng, n)
    return torch.from_numpy(wi.astype(np.float32)), torch.from_numpy(wo.astype(np.float32))


def pure_texels(labels: np.ndarray, size, c: int) -> np.ndarray:
    """Cluster ``c``'s pure texels: those whose 8 neighbours are in it too (the map's edges clamped),
    where the photographs show one material (a boundary texel is photographed as a mix). A cluster
    without one (a layer of stripes two or three texels wide, the verdict sample's base at 16x16)
    falls back to its texels whose 4 edge neighbours are in it: a bilinear footprint reaches a
    diagonal neighbour only in a pixel's corner, and a rim one texel wide still has none."""
    w, h = size
    mine = (labels == c).reshape(h, w)
    padded = np.pad(mine, 1, mode="edge")

    def inner(offsets):  # texels whose neighbours at every (dj, di) of offsets are in the cluster
        return np.all([padded[1 + dj:1 + dj + h, 1 + di:1 + di + w] for dj, di in offsets], axis=0).reshape(-1)
    block = [(dj, di) for dj in (-1, 0, 1) for di in (-1, 0, 1)]  # the texel and its 8 neighbours
    texels = np.nonzero(inner(block))[0]
    return texels if len(texels) else np.nonzero(inner([(dj, di) for dj, di in block if dj * di == 0]))[0]


def pure_rows(obs: Observations, labels: np.ndarray, c: int) -> torch.Tensor:
    """The rows of cluster ``c``'s pure texels (:func:`pure_texels`); all of ``c``'s rows when no
    pure texel was photographed."""
    texels = pure_texels(labels, obs.size, c)
    if not len(np.nonzero(np.diff(obs.offsets)[texels])[0]):
        texels = np.nonzero((labels == c).reshape(-1))[0]
    return torch.from_numpy(np.concatenate([np.arange(obs.offsets[t], obs.offsets[t + 1]) for t in texels]
                                           + [np.zeros(0, np.int64)]).astype(np.int64))


def _log_f(family, material: torch.Tensor, raw: Dict[str, torch.Tensor], wi, wo) -> torch.Tensor:
    """log(eps + cos(theta_i) f) - log(eps) of rows (the fits' loss domain, :func:`~hybridbrdf.acquire.texel_rows.loss_log`)."""
    return loss_log(wi[:, 2:3].clamp_min(0) * family.evaluate(material, raw, wi, wo))


def _replay_pool(family, seed: int) -> Dict[str, torch.Tensor]:
    """Every prior material's fixed replay pairs and the prior's f on them in the loss domain."""
    every = family.raw_of_materials()
    n_mat = len(every["kd"])
    wi, wo = cosine_pairs(n_mat * REPLAY_PAIRS, seed)
    material = torch.arange(n_mat).repeat_interleave(REPLAY_PAIRS)
    raw = {n: v[material] for n, v in every.items()}
    with torch.no_grad():
        target = _log_f(family, material, raw, wi, wo)
    return {"wi": wi, "wo": wo, "material": material, "raw": raw, "target": target, "n": n_mat}


def _anchor_pool(family, clusters: Dict, start: Tuple, seed: int) -> Dict[str, torch.Tensor]:
    """The clusters' anchor pairs and, per cluster, its start's f on them in the loss domain (K, P, 3)."""
    wi, wo = cosine_pairs(ANCHOR_PAIRS, seed + 2)
    targets = []
    with torch.no_grad():
        for c in range(len(clusters["material"])):
            own = family.with_heads(clusters["material"][c:c + 1], start[0][c:c + 1], start[1][c:c + 1])
            raw = {n: v[c:c + 1].expand(ANCHOR_PAIRS, -1) for n, v in start[2].items()}
            targets.append(_log_f(own, torch.zeros(ANCHOR_PAIRS, dtype=torch.long), raw, wi, wo))
    return {"wi": wi, "wo": wo, "target": torch.stack(targets) if targets else torch.zeros(0)}


def tuned_family(family, network: Dict[str, torch.Tensor]):
    """``family`` evaluating with the hidden layers ``network`` (state-dict tensors by name)."""
    view = copy.copy(family)
    view.module = copy.deepcopy(family.module)
    view.module.load_state_dict(network, strict=False)
    return view


def finetune_network(family, obs: Observations, data: ObservationTensors, labels: np.ndarray, clusters: Dict,
                     start: Tuple, steps: int, seed: int, progress: Optional[Progress] = None) -> Dict[str, object]:
    """``steps`` Adam steps of the module docstring's loss from ``start`` = (head weight (K, o, w),
    head bias (K, o), values {name: (K, c)}) per cluster (cluster_fit.start_heads). Returns {"network" {name: tensor} (the
    tuned hidden layers), "weight" (K, o, w), "bias" (K, o), "centres" {name: (K, c)}, "sigma2" (K,),
    "drift" (:func:`replay_drift`), "loss" [first, last] capture term}: what the texel stage then
    uses per cluster, as after the head refit (cluster_fit.fit_on_prior)."""
    k = len(clusters["material"])
    tuned = tuned_family(family, {})
    hidden = [p for p in tuned.module.mlp.hidden.parameters()]
    for p in hidden:
        p.requires_grad_(True)
    weight, bias = (v.clone() for v in start[:2])
    centres = {n: v.clone() for n, v in start[2].items()}
    heads = {"weight": weight.requires_grad_(), "bias": bias.requires_grad_(),
             **{"raw_" + n: v.requires_grad_() for n, v in centres.items()}}
    rows = [pure_rows(obs, labels, c) for c in range(k)]
    pool = _replay_pool(family, seed)
    opt = torch.optim.Adam([{"params": hidden, "lr": NETWORK_LR}, {"params": list(heads.values()), "lr": HEAD_LR}])
    rates = [NETWORK_LR, HEAD_LR]

    def capture_term(gen, c, n=CAPTURE_ROWS):
        r = rows[c] if gen is None else rows[c][torch.randint(len(rows[c]), (n,), generator=gen)]
        own = tuned.with_heads(clusters["material"][c:c + 1], heads["weight"][c:c + 1], heads["bias"][c:c + 1])
        raw = {n_: heads["raw_" + n_][c:c + 1].expand(len(r), -1) for n_ in centres}
        d = data.residual(r, own.evaluate(torch.zeros(len(r), dtype=torch.long), raw, data.wi[r], data.wo[r]))
        return (d * d).mean()

    seen = [c for c in range(k) if len(rows[c])]
    anchor = _anchor_pool(family, clusters, start, seed)

    def anchor_term(c):
        own = tuned.with_heads(clusters["material"][c:c + 1], heads["weight"][c:c + 1], heads["bias"][c:c + 1])
        raw = {n_: heads["raw_" + n_][c:c + 1].expand(ANCHOR_PAIRS, -1) for n_ in centres}
        d = anchor["target"][c] - _log_f(own, torch.zeros(ANCHOR_PAIRS, dtype=torch.long), raw, anchor["wi"], anchor["wo"])
        d = d.clamp(max=0.0)  # one-sided: only where the cluster became brighter than it started
        return (d * d).mean()
    # The heads' MAP pull toward where they started (the head refit's, cluster_fit.refit_heads_of):
    # each element a draw around its start with the spread of that element over the prior's materials,
    # weighed against the cluster's residual variance over 3 x its photographs; HEAD_PULL times that.
    t = family.tensors
    tau2 = [t["materials." + n].var(dim=0).clamp_min(1e-6) for n in ("head_weight", "head_bias")]
    start_head = [weight.detach().clone(), bias.detach().clone()]
    shots = [max(1, len(np.unique(obs.shot[rows[c].numpy()]))) if len(rows[c]) else 1 for c in range(k)]
    pull = torch.tensor([HEAD_PULL * float(clusters["sigma2"][c]) / (3 * shots[c]) / max(1, len(seen))
                         for c in range(k)])

    def head_pull():
        if HEAD_PULL == 0:
            return 0.0
        return ((pull[:, None, None] * (heads["weight"] - start_head[0]) ** 2 / tau2[0]).sum()
                + (pull[:, None] * (heads["bias"] - start_head[1]) ** 2 / tau2[1]).sum())
    losses = []
    for step in range(steps):
        gen = step_generator(seed, "network", step)
        for group, rate in zip(opt.param_groups, rates):
            group["lr"] = rate * (1.0 - 0.9 * step / steps)
        opt.zero_grad()
        fit = sum(capture_term(gen, c) for c in seen) / max(1, len(seen))
        anchored = 0.0 if ANCHOR_WEIGHT == 0 else ANCHOR_WEIGHT * sum(anchor_term(c) for c in seen) / max(1, len(seen))
        pick = torch.randperm(pool["n"], generator=gen)[:REPLAY_MATERIALS]
        r = (pick[:, None] * REPLAY_PAIRS + torch.arange(REPLAY_PAIRS)).reshape(-1)
        d = pool["target"][r] - _log_f(tuned, pool["material"][r], {n: v[r] for n, v in pool["raw"].items()},
                                       pool["wi"][r], pool["wo"][r])
        (fit + anchored + REPLAY_WEIGHT * (d * d).mean() + head_pull()).backward()
        opt.step()
        losses.append(float(fit.detach()))
        if progress is not None:
            progress("network", step + 1, steps)
    with torch.no_grad():
        sigma2 = [max(float(capture_term(None, c)), 1e-8) if len(rows[c]) else float(clusters["sigma2"][c])
                  for c in range(k)]
    network = {n: v.detach().clone() for n, v in tuned.module.state_dict().items() if n.startswith("mlp.")}
    return {"network": network, "weight": heads["weight"].detach(), "bias": heads["bias"].detach(),
            "centres": {n: heads["raw_" + n].detach() for n in centres}, "sigma2": torch.tensor(sigma2),
            "drift": replay_drift(family, tuned_family(family, network), seed),
            "loss": [losses[0], losses[-1]] if losses else []}


def replay_drift(prior, tuned, seed: int) -> Dict[str, object]:
    """Per prior material, SMAPE and cMAE (docs/CONVENTIONS.md) of ``tuned`` against ``prior`` (two
    families of one model's materials) on :data:`DRIFT_PAIRS` cosine-distributed pairs:
    {"smape" [M floats], "cmae" [M floats]}, in the model's material order."""
    every = prior.raw_of_materials()
    wi, wo = cosine_pairs(DRIFT_PAIRS, seed + 1)
    out = {"smape": [], "cmae": []}
    materials = torch.arange(len(every["kd"]))
    with torch.no_grad():
        if hasattr(prior, "evaluate_shared"):  # every material on the same pairs: one pass of the network
            both = [f.evaluate_shared(materials, every, wi, wo).double().numpy() for f in (prior, tuned)]
        else:
            both = [np.stack([f.evaluate(torch.full((DRIFT_PAIRS,), m), {n: v[m:m + 1].expand(DRIFT_PAIRS, -1)
                                                                        for n, v in every.items()}, wi, wo).double().numpy()
                              for m in materials.tolist()]) for f in (prior, tuned)]
        for a, b in zip(*both):
            out["smape"].append(float(smape(a, b)))
            out["cmae"].append(float(cmae(a, b, wi[:, 2].double().numpy())))
    return out
