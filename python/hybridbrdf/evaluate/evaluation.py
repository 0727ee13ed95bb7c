"""A fitted model measured against its sources (docs/CONVENTIONS.md, "Measuring quality"), and
the tables ``hbrdf fit`` and ``hbrdf eval`` print: SMAPE and cMAE of the model and of its
analytic part per material, and on request MAE, reciprocity and albedo at 45 degrees.
"""

from __future__ import annotations

import math
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np
import torch

from hybridbrdf.evaluate.metrics import cmae, directional_albedo, mae, metric_directions, reciprocity_error, smape
from hybridbrdf.model.file import HybridModel
from hybridbrdf.sources.base import BYTES_PER_PAIR as SOURCE_BYTES_PER_PAIR, BRDFSource
from hybridbrdf.sources.names import source_material

#: Bytes per metric pair of :func:`evaluate` besides the source's and the model's evaluations:
#: the float64 directions, the reference, f_t and f_a, the metrics' temporaries (an estimate).
BYTES_PER_PAIR = 256


def bytes_per_pair(model: HybridModel) -> int:
    """Peak memory of :func:`evaluate` per metric pair, what ``hbrdf eval --pairs`` is bounded by
    (hybridbrdf.limits): its own arrays, one source's evaluation and the model's in PyTorch."""
    return BYTES_PER_PAIR + SOURCE_BYTES_PER_PAIR + model.bytes_per_pair(torch.float32)


def evaluate(model: HybridModel, sources: Sequence[BRDFSource], n_pairs: int = 1_000_000,
             seed: int = 7, names: Optional[Sequence[str]] = None, extended: bool = False,
             progress: Optional[Callable[[], object]] = None) -> List[Dict[str, object]]:
    """Per-material metrics of CONVENTIONS on ``n_pairs`` seeded cosine-weighted pairs:
    SMAPE and cMAE of the full model and (hybrid kinds) of its analytic part.
    Sources are matched to the model's materials by name (``<name>`` or
    ``<name>.<format>``, see material_names), or by the given ``names``.

    ``extended`` adds MAE, the reciprocity error (SMAPE between f(wi, wo) and
    f(wo, wi) on min(n_pairs, 10^5) pairs) and the directional albedo at
    theta_o = 45 degrees (mean RGB), for the reference, the analytic part and the model."""
    wi, wo = metric_directions(n_pairs, seed)
    rows = []
    for i, src in enumerate(sources):
        if names is not None:
            name = names[i]
        else:
            name = source_material(model, src)
            if name is None:
                raise KeyError(f"material {src.name!r} is not in the model (it has {', '.join(model.materials)})")
        ref = src.eval(wi, wo)
        f, fa = model._eval(wi, wo, name, torch.float32)
        row: Dict[str, object] = {"material": name, "origin": src.origin,
                                  "smape": smape(ref, f), "cmae": cmae(ref, f, wi[:, 2])}
        if fa is not None:
            row["smape_analytic"] = smape(ref, fa)
            row["cmae_analytic"] = cmae(ref, fa, wi[:, 2])
        if extended:
            row.update(_extended_metrics(model, name, src, ref, f, fa, min(n_pairs, 100_000), seed))
        rows.append(row)
        if progress is not None:  # after each source (hbrdf eval's progress bar)
            progress()
    return rows


def _extended_metrics(model, name, src, ref, f, fa, n_small, seed) -> Dict[str, float]:
    full = lambda a, b: model._eval(a, b, name, torch.float32)[0]  # noqa: E731
    analytic = lambda a, b: model._eval(a, b, name, torch.float32)[1]  # noqa: E731
    out = {"mae": mae(ref, f), "reciprocity_reference": reciprocity_error(src.eval, n_small, seed),
           "reciprocity": reciprocity_error(full, n_small, seed),
           "albedo45_reference": float(directional_albedo(src.eval, math.pi / 4, n_small, seed).mean()),
           "albedo45": float(directional_albedo(full, math.pi / 4, n_small, seed).mean())}
    # The largest directional albedo over the outgoing grid and where it occurs (the model's own
    # MIS estimate, hbrdf info's): above 1, the material reflects more light than it receives.
    profile = model.albedo(name)
    out["albedo_max"], out["albedo_max_deg"] = profile["max"], profile["argmax_deg"]
    if fa is not None:
        out["mae_analytic"] = mae(ref, fa)
        out["reciprocity_analytic"] = reciprocity_error(analytic, n_small, seed)
        out["albedo45_analytic"] = float(directional_albedo(analytic, math.pi / 4, n_small, seed).mean())
    return out


def format_extended_table(rows: List[Dict[str, object]]) -> str:
    """MAE, reciprocity error and albedo at 45 degrees: reference (ref), analytic part (a), model (m);
    then the model's largest directional albedo and its outgoing direction (theta_o, phi_o degrees)."""
    has_a = any("mae_analytic" in r for r in rows)
    dash = float("nan")
    lines = [f"{'material':28s} {'MAE a':>9s} {'MAE m':>9s} {'recip ref':>9s} {'recip a':>9s} {'recip m':>9s} "
             f"{'alb45 ref':>9s} {'alb45 a':>9s} {'alb45 m':>9s} {'max alb m':>9s} at (theta_o, phi_o)"]
    for r in rows:
        lines.append(f"{r['material'][:28]:28s} {r.get('mae_analytic', dash) if has_a else dash:9.5f} {r['mae']:9.5f} "
                     f"{r['reciprocity_reference']:9.4f} {r.get('reciprocity_analytic', dash):9.2e} "
                     f"{r['reciprocity']:9.4f} {r['albedo45_reference']:9.4f} {r.get('albedo45_analytic', dash):9.4f} "
                     f"{r['albedo45']:9.4f} {r['albedo_max']:9.4f} ({r['albedo_max_deg'][0]:g}, {r['albedo_max_deg'][1]:g})")
    return "\n".join(lines)


#: A model metric counts as worse than its analytic part's (the table's "!") beyond these margins:
#: 10% of the analytic part's value plus a floor, SMAPE 0.001 (0.1% relative error) and cMAE 5e-5
#: (a twentieth of a percent of a mid-grey diffuse value), below which two fits of the same exact
#: material differ by their optimiser's noise alone.
WORSE_MARGIN = {"smape": (0.1, 1e-3), "cmae": (0.1, 5e-5)}


def worse_than_analytic(row: Dict[str, object], metric: str) -> bool:
    """True when the model's ``metric`` (smape or cmae) is worse than its analytic part's beyond
    :data:`WORSE_MARGIN`."""
    rel, floor = WORSE_MARGIN[metric]
    a = float(row[metric + "_analytic"])
    return float(row[metric]) > a + rel * a + floor


def format_table(rows: List[Dict[str, object]], n_pairs: int) -> str:
    """The per-material table `hbrdf fit` and `hbrdf eval` print. A model metric worse than its
    own analytic part's (beyond :data:`WORSE_MARGIN`) is marked "!" and a note under the table
    says what to do about it."""
    has_a = any("smape_analytic" in r for r in rows)
    head = f"{'material':28s} {'reference':32s} " + (
        f"{'SMAPE analytic':>14s} {'SMAPE model':>12s} {'cMAE analytic':>14s} {'cMAE model':>11s}" if has_a
        else f"{'SMAPE model':>12s} {'cMAE model':>11s}")
    lines = [f"metrics on {n_pairs} cosine-weighted pairs (seed 7); negatives in references clamped to 0", head]
    worse = []
    for r in rows:
        if has_a:
            mark_s = "!" if worse_than_analytic(r, "smape") else " "
            mark_c = "!" if worse_than_analytic(r, "cmae") else " "
            if mark_s + mark_c != "  ":
                worse.append(str(r["material"]))
            lines.append(f"{r['material'][:28]:28s} {str(r['origin'])[:32]:32s} {r['smape_analytic']:14.4f} "
                         f"{r['smape']:11.4f}{mark_s} {r['cmae_analytic']:14.5f} {r['cmae']:10.5f}{mark_c}")
        else:
            lines.append(f"{r['material'][:28]:28s} {str(r['origin'])[:32]:32s} {r['smape']:12.4f} {r['cmae']:11.5f}")
    if rows:
        mean = lambda k: np.mean([r[k] for r in rows])  # noqa: E731
        if has_a:
            lines.append(f"{'mean':28s} {'':32s} {mean('smape_analytic'):14.4f} {mean('smape'):12.4f} "
                         f"{mean('cmae_analytic'):14.5f} {mean('cmae'):11.5f}")
        else:
            lines.append(f"{'mean':28s} {'':32s} {mean('smape'):12.4f} {mean('cmae'):11.5f}")
    if worse:
        shown = ", ".join(worse[:6]) + (f" and {len(worse) - 6} more" if len(worse) > 6 else "")
        lines.append(f"! the model is less accurate than its own analytic part on {shown}: the network's correction "
                     f"has not converged there (fit longer: --steps), or the material needs no correction (render it "
                     f"with f_a alone: a scene material with \"evaluate\": \"analytic\", docs/RENDERING.md)")
    return "\n".join(lines)
