"""What the fit on a frozen prior chose, and how well (docs/ACQUISITION.md, "What the fit says"):
per cluster of texels, the prior's material it chose and the runner-up, each with

- its **loss**, the cluster stage's (the mean squared log residual per row and channel in the
  fits' loss domain, log(eps + cos f) with :data:`~hybridbrdf.acquire.texel_rows.LOSS_EPS`, after fitting the material's values to the cluster: :func:`~hybridbrdf.acquire.cluster_fit.fit_clusters`);
- its **relative error**, photometric and readable: the mean of |L_fit - L_obs| over the
  cluster's rows and channels divided by their mean L_obs, L = g cos(theta_i) I / d^2 the
  pixel's radiance (the row's photograph read back; the re-render's measure in bench/acquire_compare.py);
- the **noise** the capture's noise model predicts for those rows in the same units,
  mean E|N(0, Var[L])| / mean L_obs: Var[L] = L / P + (read_noise / P)^2 with the capture's stated
  model (``capture.json``), else each photograph's background floor squared
  (:func:`~hybridbrdf.acquire.exposure.background_floor`: read noise only, so an unstated
  capture's shot noise counts as error);
- the **excess**, the relative error noise does not explain, sqrt(max(0, error^2 - noise^2))
  (exact for independent Gaussian errors in root mean squares; a close enough split here).

A cluster is explained **poorly** when its chosen material's excess is above :data:`POOR_EXCESS`:
no material of the prior, fitted with one set of values to the cluster, comes within that of its
photographs beyond what noise accounts for. The per-texel stage still fits each texel, but from a
start (and with a pull toward it) that does not describe the sample, and with an output layer and
energy table that are not the sample's."""

from __future__ import annotations

from typing import Callable, Dict, List, Optional, Sequence

import numpy as np
import torch

from hybridbrdf.acquire.cluster_fit import CLUSTER_ROWS, _cluster_rows
from hybridbrdf.acquire.noise import NoiseModel
from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.rig import Rig

#: The chosen material's relative error beyond noise above which a cluster is explained poorly
#: (docs/ACQUISITION.md, "What the fit says": the prior's own materials and the measurements it
#: was trained on measured 0.04-0.26, borders mixing two of them 0.12-0.25; a retroreflector, which
#: no material of the prior resembles, above 0.4).
POOR_EXCESS = 0.35


def row_radiance_scale(rig: Rig, obs: Observations, rows: np.ndarray) -> np.ndarray:
    """(n, 3) I / d^2 of each row's light: the sample lies in z = 0, so the light at height h is
    d = h / cos(theta_i) from the row's point (wi is unit, in the world frame)."""
    lights = np.array([rig.lights[s.light].position for s in rig.shots], np.float64)
    intensity = np.array([rig.lights[s.light].intensity for s in rig.shots], np.float64)
    shot = obs.shot[rows]
    d = lights[shot, 2] / obs.wi[rows, 2].astype(np.float64)
    return intensity[shot] / (d * d)[:, None]


def _photometric(rows, obs, rig, f: np.ndarray, noise: Optional[NoiseModel], floors: Optional[Sequence[float]]):
    """(relative error, relative noise) of the BRDF values ``f`` (n, 3) on ``rows``."""
    cos = obs.wi[rows, 2:3].astype(np.float64)
    scale = row_radiance_scale(rig, obs, rows)
    l_obs = obs.value[rows].astype(np.float64) * cos * scale
    l_fit = f * cos * scale
    if noise is not None and noise.photons is not None:
        var = noise.variance(l_fit)
    elif floors is not None:
        var = np.broadcast_to((np.asarray(floors, np.float64)[obs.shot[rows]] ** 2)[:, None], l_fit.shape)
    else:
        var = np.zeros_like(l_fit)
    mean = max(float(l_obs.mean()), 1e-12)
    # Mean absolute errors (the re-render's measure), the noise's E|N(0, var)| = sqrt(2 var / pi).
    return float(np.abs(l_fit - l_obs).mean()) / mean, float(np.sqrt(2 * var / np.pi).mean()) / mean


def cluster_report(family, names: Sequence[str], obs: Observations, rig: Rig, labels: np.ndarray, clusters: Dict,
                   seed: int, noise: Optional[NoiseModel] = None,
                   floors: Optional[Sequence[float]] = None) -> List[dict]:
    """Per cluster: {"cluster", "texels", "share", "candidates": [{"material" (name), "loss",
    "relative_error", "noise", "excess"} (and "held_out_loss", "training_loss" when the choice was
    made on held-out photographs; "tied", "consensus" from the final choice,
    :mod:`~hybridbrdf.acquire.consensus`), the chosen first], "poor"}. ``family`` evaluates the prior
    (:class:`~hybridbrdf.acquire.hybrid_fit.HybridFamily`), ``names`` its materials; ``noise`` the
    capture's stated model, ``floors`` each photograph's floor when it states none. The rows are
    the ones the cluster stage fitted (the same seeded draw)."""
    n_texels = len(labels)
    report = []
    for c, fitted in enumerate(clusters.get("candidates") or []):
        entry = {"cluster": c, "texels": int((labels == c).sum()), "candidates": [], "poor": False}
        entry["share"] = entry["texels"] / max(n_texels, 1)
        rows = _cluster_rows(obs, labels, c, CLUSTER_ROWS, seed)
        data_rows = rows.numpy()
        for cand in fitted:
            m = int(cand["material"])
            with torch.no_grad():
                wi, wo = torch.from_numpy(obs.wi[data_rows]), torch.from_numpy(obs.wo[data_rows])
                raw = {n: v.expand(len(data_rows), -1) for n, v in cand["raw"].items()}
                f = family.evaluate(torch.full((len(data_rows),), m), raw, wi, wo).double().numpy()
            err, sigma = _photometric(data_rows, obs, rig, f, noise, floors)
            entry["candidates"].append({"material": names[m], "loss": float(cand["loss"]), "relative_error": err,
                                        "noise": sigma, "excess": float(np.sqrt(max(0.0, err * err - sigma * sigma))),
                                        **{k: cand[k] for k in ("held_out_loss", "training_loss", "tied", "consensus")
                                           if k in cand}})
        entry["poor"] = bool(entry["candidates"]) and entry["candidates"][0]["excess"] > POOR_EXCESS
        report.append(entry)
    return report


def report_lines(report: Sequence[dict]) -> List[str]:
    """One line per cluster: its texels and share, the chosen material with its loss and relative
    error (and the noise's), the runner-up with its own; when the chosen is the consensus of tied
    candidates (:mod:`~hybridbrdf.acquire.consensus`) rather than the best score, how many tied;
    when the choice was made on held-out photographs, every candidate's held-out loss, the chosen first."""
    lines = []
    for e in report:
        if not e["candidates"]:
            lines.append(f"cluster {e['cluster']}: {e['texels']:,} texels ({100 * e['share']:.1f}%), no observations: "
                         f"the largest cluster's material")
            continue
        best = e["candidates"][0]
        line = (f"cluster {e['cluster']}: {e['texels']:,} texels ({100 * e['share']:.1f}%): {best['material']}, "
                f"loss {best['loss']:.3g}, relative error {100 * best['relative_error']:.1f}% "
                f"(noise {100 * best['noise']:.1f}%)")
        if len(e["candidates"]) > 1:
            second = e["candidates"][1]
            line += (f"; runner-up {second['material']}, loss {second['loss']:.3g}, "
                     f"relative error {100 * second['relative_error']:.1f}%")
        if best.get("consensus"):
            line += f"; chosen as the consensus of {best['tied']} candidates the photographs cannot tell apart"
        if best.get("held_out_loss") is not None:  # the choice made on held-out photographs (acquire/select.py)
            line += "; held-out losses: " + ", ".join(
                f"{c['material']} {c['held_out_loss']:.3g}" + (" (chosen)" if i == 0 else "")
                for i, c in enumerate(e["candidates"]))
        lines.append(line)
    return lines


def poor_fit_warnings(report: Sequence[dict]) -> List[str]:
    """One line per cluster explained poorly (:data:`POOR_EXCESS`)."""
    return [f"warning: cluster {e['cluster']} ({e['texels']:,} texels): its best prior material "
            f"{e['candidates'][0]['material']} leaves a relative error of {100 * e['candidates'][0]['relative_error']:.0f}% "
            f"against {100 * e['candidates'][0]['noise']:.0f}% from noise (excess "
            f"{100 * e['candidates'][0]['excess']:.0f}% > {100 * POOR_EXCESS:.0f}%): no material of the prior "
            f"explains it (a material the prior lacks, or texels mixing several)"
            for e in report if e["poor"]]


def report_logger(log: Callable[[str], None], warn: Callable[[str], None]) -> Callable[[List[dict]], None]:
    """What ``hbrdf acquire fit`` does with a report: its lines to ``log``, its warnings to ``warn``."""
    def emit(report):
        for line in report_lines(report):
            log(line)
        for line in poor_fit_warnings(report):
            warn(line)
    return emit
