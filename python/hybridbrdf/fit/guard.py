"""Never worse than f_a: what a fit does for a material whose hybrid ends worse than its own
analytic part (issue 49; docs/FITTING.md, "Never worse than f_a").

The network corrects f_a; a material whose corrected f_t measures worse than f_a alone (SMAPE or
cMAE above f_a's on the metric pairs; the table's "!" marks it beyond a margin) has a correction
that hurts on that metric, while it usually helps on the other (a correction that halves cMAE can
raise SMAPE in dark regions). With material output layers (each material its own head) the fit
can act on that material alone, the shared hidden layers untouched. Candidates:

- **restart**: the material's (p, z, head) fitted again on the fitted network (a sparse fit of
  that material alone, ``GUARD_STEPS`` steps or the fit's own if fewer) from its own p and z and a neutral head: weights 0
  and the biases a fit starts from (spec FC_INIT, FG_INIT: a small correction, an open gate),
  with the fit's loss epsilon and with a tenth of it (:data:`RESTART_EPS_SCALES`);
- **tempered**: the fitted head with its biases shifted, the correction's by dc <= 0 (f_c scaled
  by exp(dc), exactly) and the gate's by dg >= 0 (more of f_a), on the grid :data:`TEMPER_GRID`;
- **analytic**: the head that makes f_t equal f_a exactly: weights 0, the correction's bias -200
  (exp(-200) is 0 in float32, 1e-87 in float64) and the gate's +200 (sigmoid(200) is 1 in both).

The guard acts on every material whose hybrid is worse than its f_a on either metric at all (on
the metric pairs), not only beyond the table's margin. Each candidate is scored on pairs other
than the metrics' (seed :data:`CHOICE_SEED`); of those at most f_a's on both metrics (analytic always
is: equal) the one with the lowest cMAE is kept, the correction's gain on the metric it helps kept
as far as the other allows; if the kept one is worse than f_a on the metric pairs after all, the
material is set to its f_a. The material's record says what was done (``guard``: the action, the shifts, and
the metrics before). A shared output layer cannot be changed for one material: the fit leaves
such a material as it is and says so in the log (the table's "!" stays)."""

from __future__ import annotations

import dataclasses
from typing import Callable, List, Sequence

import torch

from hybridbrdf import spec
from hybridbrdf.evaluate.evaluation import evaluate, worse_than_analytic
from hybridbrdf.evaluate.metrics import cmae, metric_directions, smape
from hybridbrdf.model import energy
from hybridbrdf.model.file import HybridModel

#: Steps of the restart (the sparse fit of one material on the fitted network).
GUARD_STEPS = 2000
#: (dc, dg) shifts of the tempered candidates: f_c scaled by exp(dc), the gate moved toward 1.
TEMPER_GRID = tuple((dc, dg) for dc in (0.0, -0.5, -1.0, -2.0, -3.0, -5.0, -8.0) for dg in (0.0, 1.0, 2.0, 4.0, 8.0, 16.0)
                    if (dc, dg) != (0.0, 0.0))
#: The restarts' loss epsilons, as multiples of the fit's: its own, and a tenth of it (a loss more
#: relative in dark regions, where a correction that helps cMAE raises SMAPE).
RESTART_EPS_SCALES = (1.0, 0.1)
#: Seed of the pairs the candidates are scored on (the metrics use evaluate's seed 7).
CHOICE_SEED = 11
#: The analytic head's biases: f_c = exp(-200) = 0 and f_g = sigmoid(200) = 1 in float32.
ANALYTIC_BIAS = 200.0


def is_worse(metrics, margin: bool = True) -> bool:
    """Whether a material's metrics (its record's ``metrics``) are worse than its f_a's on either:
    beyond the table's margin (``margin``, the table's "!"), or at all (what the guard acts on)."""
    keys = [k for k in ("smape", "cmae") if k + "_analytic" in metrics]
    if margin:
        return any(worse_than_analytic(metrics, k) for k in keys)
    return any(metrics[k] > metrics[k + "_analytic"] for k in keys)


def _not_worse(row) -> bool:
    """Both metrics at most f_a's (on the pairs the row was measured on)."""
    return all(row[k] <= row[k + "_analytic"] for k in ("smape", "cmae"))


def analytic_head(model: HybridModel, i: int, fc: float = -ANALYTIC_BIAS, fg: float = ANALYTIC_BIAS) -> HybridModel:
    """``model`` with material ``i``'s head replaced by weights 0 and biases ``fc`` (the correction's)
    and ``fg`` (the gate's): by default the head that makes its f_t equal its f_a."""
    tensors = dict(model.tensors)
    w, b = tensors["materials.head_weight"].copy(), tensors["materials.head_bias"].copy()
    w[i] = 0.0
    b[i, 0:3], b[i, 3:6] = fc, fg
    tensors["materials.head_weight"], tensors["materials.head_bias"] = w, b
    return type(model)(dict(model.arch), [dict(m) for m in model.material_info], tensors, model.training)


def _only(model: HybridModel, i: int) -> HybridModel:
    """``model``'s network with material ``i`` alone (the one start a sparse fit can pick)."""
    tensors = {k: (v[i:i + 1].copy() if k.startswith("materials.") else v) for k, v in model.tensors.items()}
    return type(model)(dict(model.arch), [dict(model.material_info[i])], tensors, model.training)


def _with_row(model: HybridModel, i: int, other: HybridModel, j: int) -> HybridModel:
    """``model`` with material ``i``'s tensors (p, z, head) taken from ``other``'s material ``j``."""
    tensors = dict(model.tensors)
    for k, v in model.tensors.items():
        if k.startswith("materials.") and k != "materials.energy_bound":
            v = v.copy()
            v[i] = other.tensors[k][j]
            tensors[k] = v
    return type(model)(dict(model.arch), [dict(m) for m in model.material_info], tensors, model.training)


def _shifted(model: HybridModel, i: int, dc: float, dg: float) -> HybridModel:
    """``model`` with material ``i``'s head biases shifted: the correction's by ``dc``, the gate's by ``dg``."""
    tensors = dict(model.tensors)
    b = tensors["materials.head_bias"].copy()
    b[i, 0:3] += dc
    b[i, 3:6] += dg
    tensors["materials.head_bias"] = b
    return type(model)(dict(model.arch), [dict(m) for m in model.material_info], tensors, model.training)


def _described(what) -> str:
    if what["action"] == "restart":
        return f"restarted from a neutral head (loss eps {what['loss_eps']:g})"
    if what["action"] == "tempered":
        return f"correction tempered (f_c x exp({what['dc']:g}), gate bias +{what['dg']:g})"
    return "its correction removed (f_t = f_a)"


def apply(model: HybridModel, sources: Sequence, names: List[str], settings, fit: Callable,
          log: Callable[[str], None] = print, steps: int = GUARD_STEPS) -> HybridModel:
    """``model`` (its records holding each material's metrics against ``sources``, in the order of
    ``names``) with every material worse than its f_a restarted or set to its f_a; returns the
    model (the same object when none is worse). Energy-bound tables and metrics of the changed
    materials are refitted and re-measured. ``fit``: :func:`hybridbrdf.fit.fit` (which calls
    this at the end of every fit, so it cannot be imported here)."""
    infos = {m["name"]: m for m in model.material_info}
    worse = [k for k, n in enumerate(names) if is_worse(infos[n].get("metrics", {}), margin=False)]
    if not worse:
        return model
    if model.output_layer != "material" or not model.has_analytic:
        log("worse than its f_a (the table's '!'): " + ", ".join(names[k] for k in worse)
            + "; a shared output layer cannot be changed for one material (docs/FITTING.md, \"Never worse than f_a\")")
        return model
    bounded = model.arch.get("energy_bound", "none") == "albedo_table"
    free = energy.unbounded(model)
    for k in worse:
        name, src = names[k], sources[k]
        i = free.index(name)
        before = dict(infos[name]["metrics"])
        wi, wo = metric_directions(settings.eval_pairs, CHOICE_SEED)
        ref = src.eval(wi, wo)

        def score(m: HybridModel, j: int):
            f, fa = m._eval(wi, wo, j, torch.float32)
            row = {"smape": smape(ref, f), "cmae": cmae(ref, f, wi[:, 2]),
                   "smape_analytic": smape(ref, fa), "cmae_analytic": cmae(ref, fa, wi[:, 2])}
            return row, row["cmae"]

        sparse = dataclasses.replace(settings, steps=min(steps, settings.steps), sparse_init="nearest", sparse_starts=1, analytic_guard=False,
                                     energy_bound=False, frozen_from="(the fit itself)", init_from=None)
        start = _only(analytic_head(free, i, spec.FC_INIT, spec.FG_INIT), i)
        candidates = []
        for eps_scale in RESTART_EPS_SCALES:
            tuned = dataclasses.replace(sparse, loss_eps=settings.loss_eps * eps_scale)
            refit = fit([src], tuned, frozen=start, progress=False, log=lambda msg: None)
            candidates.append(({"action": "restart", "loss_eps": tuned.loss_eps}, _with_row(free, i, refit, 0)))
        candidates += [({"action": "tempered", "dc": dc, "dg": dg}, _shifted(free, i, dc, dg)) for dc, dg in TEMPER_GRID]
        candidates.append(({"action": "analytic"}, analytic_head(free, i)))
        scored = [(what, m) + score(m, i) for what, m in candidates]
        feasible = [c for c in scored if _not_worse(c[2])]
        what, chosen, _, _ = min(feasible, key=lambda c: c[3])
        after = evaluate(chosen, [src], n_pairs=settings.eval_pairs, names=[name])[0]
        if not _not_worse(after):  # better on the scoring pairs, not on the metric pairs: f_a itself
            what, chosen = candidates[-1]
            after = evaluate(chosen, [src], n_pairs=settings.eval_pairs, names=[name])[0]
        free = chosen
        after = {k2: v for k2, v in after.items() if k2 not in ("material", "origin")}
        info = free.material_info[i]
        info["metrics"] = after
        info["guard"] = dict(what, before={k2: before[k2] for k2 in ("smape", "cmae", "smape_analytic", "cmae_analytic")
                                           if k2 in before})
        log(f"{name}: worse than its f_a (SMAPE {before['smape']:.4f} vs {before['smape_analytic']:.4f}, cMAE "
            f"{before['cmae']:.5f} vs {before['cmae_analytic']:.5f}); {_described(what)}: SMAPE {after['smape']:.4f}, "
            f"cMAE {after['cmae']:.5f}")
    if bounded:  # the changed materials' tables refitted, and their metrics measured with them
        changed = [names[k] for k in worse]
        free = energy.with_bound(energy.attach(free, model.tensors["materials.energy_bound"]), changed)
        rows = evaluate(free, [sources[k] for k in worse], n_pairs=settings.eval_pairs, names=changed)
        for name, row in zip(changed, rows):
            free.material_info[free.index(name)]["metrics"] = {k2: v for k2, v in row.items()
                                                               if k2 not in ("material", "origin")}
    return free


__all__ = ["ANALYTIC_BIAS", "CHOICE_SEED", "RESTART_EPS_SCALES", "GUARD_STEPS", "TEMPER_GRID", "analytic_head", "apply", "is_worse"]
