"""A cluster's material chosen among the candidates its photographs cannot tell apart: the one whose
predictions lie closest to the others' (docs/ACQUISITION_CONSENSUS.md).

**Why.** A capture sees a material in a few direction pairs; materials of the prior fitted to those
photographs can explain them equally well and still disagree where no photograph looked. On the
light stage's 8x4 rig (32 photographs), the colour-changing stripes' four best candidates scored
within 15-21% of the best, and their error against the measurement over the highlight (theta_h <
25 deg) ranged 0.23-0.80: in two seeds of three the best score fell on vch_ultra_pink, the farthest
from the others and from the truth (diagnostic, not kept). The score's order among ties is the noise's.

**The rule** (minimum Bayes risk, as in choosing among a posterior's samples): the candidates whose
score less the pixels' noise is within :func:`tie_margin` of the best's are taken as equally likely given the photographs, and
the one with the least summed distance to the others is chosen (the medoid), the distance the
fit's own measure: the root mean squared difference of log(eps + f cos theta_i) (the fits' loss
domain, :func:`~hybridbrdf.acquire.texel_rows.loss_log`) over
:func:`probe_pairs`; but only where the best score stands farther from the others, on average,
than the medoid does by more than the best fit's own root mean squared residual on the
photographs (the square root of its score, in the same log units): a difference the photographs
cannot resolve does not overturn them. Tied white diffuse materials (the gap bench's colodur_napoli
at high noise: mean distances 0.0073-0.0086, the fit's residual 0.0043) keep the best score; the
stripes' (mean distances 0.17-0.23, residual 0.020) do not.

A distance, not its square: summed squares would favour the candidate nearest the mean, which one
far-off candidate drags toward itself; summed distances choose as a median does. With two tied
candidates the distances are symmetric and the score's order stands.
"""

from __future__ import annotations

import math
from typing import Dict, List

import numpy as np
import torch

from hybridbrdf.sources.rusinkiewicz import dirs_from_half_diff
from hybridbrdf.acquire.texel_rows import loss_log

#: Candidates tie when their scores differ by less than TIE_Z standard errors (:func:`tie_margin`).
TIE_Z = 2.0
#: Direction pairs the tied candidates are compared on.
PROBES = 4096
#: The probes' half vectors reach THETA_H_MAX from the normal and their difference angle
#: THETA_D_MAX: candidates of a glossy material differ most on and beside the highlight, which
#: pairs drawn uniformly over both hemispheres rarely meet (a half vector within 5 deg of the
#: normal: wo in a 10 deg cone about wi's mirror, about 1.5% of them; 8% of the probes).
THETA_H_MAX, THETA_D_MAX = math.radians(60.0), math.radians(80.0)
#: The lowest cos(theta) of either direction: pairs at grazing angles weigh little in any image.
MIN_COS = 0.1


def probe_pairs(n: int = PROBES, seed: int = 0) -> tuple:
    """(wi, wo), (m, 3) float32 each, m <= ``n``: half vectors uniform in theta_h <= :data:`THETA_H_MAX`
    and azimuth, wi at a difference angle uniform in [0, :data:`THETA_D_MAX`] about the half vector
    (Rusinkiewicz's parametrisation), pairs with either cosine below :data:`MIN_COS` left out."""
    rng = np.random.default_rng(seed)
    theta_h, phi_h = rng.uniform(0, THETA_H_MAX, n), rng.uniform(0, 2 * math.pi, n)
    theta_d, phi_d = rng.uniform(0, THETA_D_MAX, n), rng.uniform(0, 2 * math.pi, n)
    wi, wo = dirs_from_half_diff(theta_h, phi_h, theta_d, phi_d)
    keep = (wi[:, 2] >= MIN_COS) & (wo[:, 2] >= MIN_COS)
    return torch.from_numpy(wi[keep].astype(np.float32)), torch.from_numpy(wo[keep].astype(np.float32))


def tie_margin(shots: int) -> float:
    """The relative margin within which two scores tie for a cluster photographed in ``shots``
    photographs: :data:`TIE_Z` times sqrt(2 / (3 n)), the relative standard error of a mean of
    squares of 3 n independent Gaussian residuals, n = ``shots``: a cluster's rows hold about one
    independent direction pair per photograph (its pixels in one photograph see about one), as the
    head refit counts them (:func:`~hybridbrdf.acquire.cluster_fit.refit_heads_of`). 0.29 at 32
    photographs, 0.58 at 8, 0.14 at 128."""
    return TIE_Z * math.sqrt(2.0 / (3.0 * max(1, shots)))


def tied(fitted: List[Dict[str, object]], margin: float, noise: float = 0.0) -> int:
    """How many of ``fitted`` (sorted by score, best first) score at most (1 + ``margin``) times the
    first, each score less the rows' ``noise`` (the pixels' variance, which every candidate's
    residual holds alike: counted, it would make a noisy capture's candidates tie by its floor)."""
    excess = [max(float(c["score"]) - noise, 0.0) for c in fitted]
    return sum(e <= excess[0] * (1 + margin) for e in excess)


def summed_distances(family, candidates: List[Dict[str, object]]) -> torch.Tensor:
    """(k,) each candidate's summed distance to the others: the root mean squared difference of
    log(eps + f cos theta_i) (:func:`~hybridbrdf.acquire.texel_rows.loss_log`) over :func:`probe_pairs`."""
    wi, wo = probe_pairs()
    cos_i = wi[:, 2:3]
    with torch.no_grad():
        logs = torch.stack([loss_log(cos_i * family.evaluate(
            torch.full((len(wi),), int(c["material"])), {n: v.reshape(1, -1).expand(len(wi), -1) for n, v in c["raw"].items()},
            wi, wo).clamp_min(0.0)) for c in candidates])
    return ((logs[:, None] - logs[None]) ** 2).mean(dim=(2, 3)).sqrt().sum(1)


def medoid_first(family, fitted: List[Dict[str, object]], shots: int, noise: float = 0.0) -> List[Dict[str, object]]:
    """``fitted`` (a cluster's candidates, each {"material", "score", "raw" {name: (c,)}}, best score
    first, fitted to rows of ``shots`` photographs whose pixels' variance is ``noise``) reordered so
    that among the first :func:`tied` ones (within :func:`tie_margin`) the medoid of their predictions leads (the module docstring);
    the others keep their order; unless the medoid's lead over the best score, in mean distance
    to the others, is within the best's root mean squared residual (sqrt of its score). Each
    candidate gains "tied" (how many were compared) and the leader "consensus" (True when it is
    not the best score)."""
    k = tied(fitted, tie_margin(shots), noise)
    out = [dict(c, tied=k) for c in fitted]
    if k < 3:
        return out
    distance = summed_distances(family, out[:k]) / (k - 1)
    lead = int(torch.argmin(distance))
    if float(distance[0] - distance[lead]) <= math.sqrt(max(float(out[0]["score"]), 0.0)):
        lead = 0  # the best score no farther from the others than the photographs resolve
    out.insert(0, out.pop(lead))
    out[0]["consensus"] = lead != 0
    return out
