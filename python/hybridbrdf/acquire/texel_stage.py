"""The texel stage of the fits on a frozen prior (:mod:`~hybridbrdf.acquire.cluster_fit`, stage 5):
every texel's values refined from its cluster's, then shrunk toward the cluster's by as much as
the cluster's texels say their differences are noise (docs/ACQUISITION.md, "The fit on a frozen prior", step 3).

**The fit.** Each texel's values are a MAP estimate: its rows' log residuals (variance sigma^2,
the cluster fit's mean squared residual per row and channel) and a Gaussian pull toward the
cluster's values with variance tau_j^2 per component (the spread of that component over the
prior's materials). Divided by 3 n_t / sigma^2:

    L_t = mean_{rows, channels} d^2 + sigma^2 / (3 n_t) sum_j (theta_tj - theta_cj)^2 / tau_j^2.

That pull is weak by design: it knows only how far *materials* differ, so a texel seen 500 times
follows its own rows, noise and all. Pure texels of one material photographed under noise then
scatter around their material, and on the light-stage bench (docs/ACQUISITION_GAP.md) that
scatter was most of what high noise cost.

**Twins.** How far texels of one cluster truly differ is what the capture must say. Each texel
is fitted twice in the same pass, on disjoint halves of its rows (even and odd rows: each pixel's
noise is its own, and both halves see the same directions), each half ``rows_per_texel / 2`` rows
a step, so the stage costs what one fit of ``rows_per_texel`` rows does. Their mean m_t is the
texel's estimate, and their difference d_t = a_t - b_t measures its noise, the photographs' and
the stochastic steps' together: Var(m_t) = E[d_t^2] / 4.

**Shrinkage** (empirical Bayes, as James and Stein's estimator, per cluster c and component j,
on the raw values), toward the cluster's median texel mu_cj (not the cluster stage's values:
those were fitted on fewer rows, and a texel's optimum sits apart from them): with nu^2 the mean
of d_tj^2 / 4 and s^2 the mean of (m_tj - mu_cj)^2 over the cluster's texels, each mean taken
over the lowest :data:`TRIM` of its squares (so texels on a layer's rim, photographed as
mixtures, do not decide how much the pure ones shrink; trimmed alike, the two keep their ratio;
medians would too, but a median of squares is the less efficient estimate),

    b_cj = min(1, nu^2 / s^2),    theta_tj = mu_cj + (1 - b_cj) (m_tj - mu_cj):

a cluster whose texels differ by no more than their noise collapses onto its values, one whose
texels differ far more (a painted gradient, wear) keeps its texels' own. The move is limited to
:data:`SHRINK_LIMIT` noise deviations (Efron and Morris's limited translation), so a texel far
out of its cluster, a real feature, is not pulled in with the crowd.
"""

from __future__ import annotations

from typing import Callable, Dict, Optional

import numpy as np
import torch

from hybridbrdf.acquire import footprint
from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.texel_rows import ROWS_PER_TEXEL, ObservationTensors, Progress, adam_texels

#: The texel stage's pull toward the cluster's values, a multiple of its MAP weight (module docstring).
TEXEL_PULL = 1.0
#: Shrink the texels toward their cluster's values after the fit (module docstring); False: the
#: twins' mean as it is (a bench knob: bench/acquire_gap.py's ``no_shrink``).
SHRINK = True
#: The share of a cluster's texels whose squares enter its noise and spread estimates (the lowest).
TRIM = 0.8
#: The most a texel's value moves in the shrink, in noise deviations nu (limited translation).
SHRINK_LIMIT = 2.0


class TwinSampler:
    """Rows of every texel with observations, drawn per step for its two twins: ``draw(gen)`` gives
    (fit (N,), texel (N,), row (N,)): fit t (twin a of texel ``texels[t]``) reads its even rows,
    fit n + t (twin b) its odd rows, ``per_twin`` of each. A texel with one row lends it to both."""

    def __init__(self, obs: Observations, per_twin: int):
        counts = np.diff(obs.offsets)
        active = np.nonzero(counts > 0)[0]
        self.texels = torch.from_numpy(active)
        start, count = torch.from_numpy(obs.offsets[active]), torch.from_numpy(counts[active])
        even = (count + 1) // 2
        odd = torch.where(count >= 2, count // 2, even)  # one row: twin b reads it too
        self.start = torch.cat([start, start + (count >= 2).long()])
        self.count = torch.cat([even, odd])
        self.per_twin = int(per_twin)

    def draw(self, gen: torch.Generator):
        u = torch.rand((len(self.count), self.per_twin), generator=gen, dtype=torch.float64)
        pick = torch.minimum((u * self.count[:, None]).long(), self.count[:, None] - 1)
        fit = torch.arange(len(self.count)).repeat_interleave(self.per_twin)
        return fit, self.texels.repeat(2).repeat_interleave(self.per_twin), (self.start[:, None] + 2 * pick).reshape(-1)


def _trimmed_mean(squares: torch.Tensor) -> torch.Tensor:
    """Per column of ``squares`` (n, c) >= 0, the mean of those at or below its :data:`TRIM` quantile."""
    cut = torch.quantile(squares, TRIM, dim=0, keepdim=True)
    keep = (squares <= cut).to(squares.dtype)
    return (squares * keep).sum(0) / keep.sum(0)


def shrink_to_clusters(a: Dict[str, torch.Tensor], b: Dict[str, torch.Tensor], cluster: torch.Tensor) -> tuple:
    """The twins' values ``a``, ``b`` {name: (n, c)} shrunk toward their cluster's median texel as
    the module docstring says, clusters given per texel by ``cluster`` (n,): (values {name: (n, c)},
    shrink factors {name: (clusters, c)} in the order of ``torch.unique(cluster)``)."""
    ids = torch.unique(cluster)
    where = torch.searchsorted(ids, cluster)
    out, factors = {}, {}
    for n in a:
        mean, noise = (a[n] + b[n]) / 2, (a[n] - b[n]) ** 2 / 4
        target = torch.stack([mean[cluster == c].median(0).values for c in ids])
        dev = mean - target[where]
        nu2 = torch.stack([_trimmed_mean(noise[cluster == c]) for c in ids])
        s2 = torch.stack([_trimmed_mean(dev[cluster == c] ** 2) for c in ids])
        factor = torch.where(s2 > 0, (nu2 / s2.clamp_min(1e-30)).clamp(max=1.0), torch.ones_like(s2))
        limit = SHRINK_LIMIT * nu2[where].sqrt()
        move = torch.maximum(torch.minimum(factor[where] * dev, limit), -limit)
        out[n], factors[n] = (mean - move) if SHRINK else mean, factor
    return out, factors


def _footprint_model(family, obs: Observations, lab: torch.Tensor, seen: torch.Tensor, clusters: Dict):
    """predict(raw twins {name: (2 n_seen, c)}, half (N,), rows, wi, wo) = f (N, 3): each row as its
    footprint shows the twin map of its ``half`` (:mod:`~hybridbrdf.acquire.footprint`); the map's
    texels without observations hold their cluster's values, as the fill outside each layer."""
    n_tex = len(lab)
    base = {n: v[lab].repeat(2, 1) for n, v in clusters["centres"].items()}
    where = torch.cat([seen, seen + n_tex])
    model = footprint.Footprint(obs.uv, obs.size, lab.numpy(), family.values(clusters["centres"]))
    material = clusters["material"]

    def predict(raw, half, rows, wi, wo):
        table = family.values({n: base[n].index_put((where,), raw[n]) for n in base})
        return model.predict(lambda layer, values, a, b: family.evaluate_decoded(material[layer], values, a, b),
                             table, half * n_tex, rows, wi, wo)
    return predict


def refine_texels(family, obs: Observations, data: ObservationTensors, labels: np.ndarray, clusters: Dict,
                  tau2: Dict[str, torch.Tensor], steps: int, seed: int, rows_per_texel: int = ROWS_PER_TEXEL,
                  lr: float = 0.01, progress: Optional[Progress] = None, state: Optional[dict] = None,
                  save_state: Optional[Callable[[dict], None]] = None) -> Dict[str, torch.Tensor]:
    """Every texel's values (n_texels, c) refined from its cluster's (``clusters``: "material",
    "centres", "sigma2" per cluster; ``labels`` each texel's) with the pull of the module docstring
    (``tau2``: its variance per component), as twins of ``rows_per_texel / 2`` rows a step each for
    ``steps`` steps, then shrunk (:func:`shrink_to_clusters`); texels without observations keep
    their cluster's values."""
    lab = torch.from_numpy(labels)
    centre = {n: v[lab] for n, v in clusters["centres"].items()}
    sampler = TwinSampler(obs, max(1, rows_per_texel // 2))
    seen, n_seen = sampler.texels, len(sampler.texels)
    counts = torch.from_numpy(np.diff(obs.offsets))[seen].double()
    weight = (TEXEL_PULL * clusters["sigma2"][lab[seen]].double() / (3 * (counts / 2).clamp_min(1))).float()
    twin_centre = {n: v[seen].repeat(2, 1) for n, v in centre.items()}
    raw = {n: v.clone().requires_grad_() for n, v in twin_centre.items()}
    weight = weight.repeat(2)
    material_of_twin = clusters["material"][lab[seen]].repeat(2)
    predict = _footprint_model(family, obs, lab, seen, clusters) if footprint.MODEL == "bilinear" else None

    def loss(gen):
        fit, texel, rows = sampler.draw(gen)
        if predict is None:
            f = family.evaluate(material_of_twin[fit], {n: v[fit] for n, v in raw.items()}, data.wi[rows], data.wo[rows])
        else:
            f = predict(raw, (fit >= n_seen).long(), rows, data.wi[rows], data.wo[rows])
        d = data.residual(rows, f)
        data_term = (d * d).sum() / (3 * sampler.per_twin)  # sum over twins of each twin's mean
        pull = sum((((raw[n] - twin_centre[n]) ** 2) / tau2[n]).sum(1) * weight for n in raw).sum()
        return data_term + pull

    values = {n: v.clone() for n, v in centre.items()}
    if n_seen:
        adam_texels(raw, loss, steps, lr, seed, "texels", progress, state, save_state)
        a, b = ({n: v.detach()[half * n_seen:(half + 1) * n_seen] for n, v in raw.items()} for half in (0, 1))
        shrunk, _ = shrink_to_clusters(a, b, lab[seen])
        for n in values:
            values[n][seen] = shrunk[n]
    return values
