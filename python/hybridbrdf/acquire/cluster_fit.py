"""Per-texel fits on a frozen prior that share work between texels (docs/ACQUISITION.md, "The
fit on a frozen prior"): the hybrid (p, z per texel) and the neural-only (a latent per texel)
fits run the same three stages, on a *family* (the model's network and its per-material values):

1. **analytic**: the analytic-only fit (:func:`fit_analytic_texels`), half the steps: per-texel
   features (log kd, log alpha, log(eta - 1) per channel) cheap to get and good enough to group texels by.
   Each texel fitted to the pixels of its own cell (the ``nearest`` observation model, not the
   footprint of :mod:`~hybridbrdf.acquire.footprint`): features to group by want each texel's
   average, and a map fitted through its footprint undoes the blur between texels, which at 8
   photographs left the features noisy enough to group worse (the light-stage verdict at 4x2, low
   noise, seeds 0 and 1: the hybrid's median cMAE 0.0302 and 0.0282 after a footprint-fitted
   stage, 0.0216 and 0.0194 after this one; diagnostics, not kept). The later stages fit through the footprint.
2. **clusters**: k-means on the standardised features (:mod:`~hybridbrdf.acquire.clustering`), into :data:`MAX_CLUSTERS` (a textured
   material holds a base and up to 3 layers) or, given ``merge`` (the hybrid's and neural-only
   fits pass :mod:`~hybridbrdf.acquire.cluster_merge`), into more and merged after the fits below
   where one fit explains a pair; per cluster, on rows of its pure texels (:func:`_cluster_rows`), every
   material of the prior screened by a short fit of its values (:func:`screen_materials`), the
   screen's best :data:`CANDIDATES` and the best as photographed fitted (all of the family's
   per-texel values, one set for the cluster, on the frozen network), the lowest
   :func:`map_objective` kept, and after a merge every final cluster's chosen again on more rows
   (:data:`FINAL_ROWS`; among candidates that tie there, their consensus: :mod:`~hybridbrdf.acquire.consensus`); or (``choose``) the choice made on held-out photographs (:mod:`~hybridbrdf.acquire.select`).
   Then each texel moves to the cluster whose choice explains its photographs clearly best
   (:mod:`~hybridbrdf.acquire.texel_assign`).
3. **heads** (``refit_heads``): each cluster's output layer (its material's head) refitted with
   its values on up to :data:`HEAD_ROWS` of its rows, the hidden layers frozen: pure texels of one
   material share one BRDF, so a cluster pools every texel's observations for the one shape a
   material the prior never saw needs (an option: docs/ACQUISITION_GAP.md).
4. **network** (``finetune_network`` steps): the hidden layers, each cluster's head and values
   trained on the clusters' pure texels with the prior's materials replayed
   (:mod:`~hybridbrdf.acquire.network_tune`); the texel stage then runs on the tuned network.
5. **texels** (:mod:`~hybridbrdf.acquire.texel_stage`): every texel's values refined from its
   cluster's, each texel with its cluster's material (output layer, energy table) and a Gaussian
   pull toward the cluster's values, then shrunk toward them by as much as the cluster's texels
   say their differences are noise."""

from __future__ import annotations

import functools
from typing import Callable, Dict, Optional, Tuple

import numpy as np
import torch

from hybridbrdf.acquire import consensus, network_tune, texel_assign
from hybridbrdf.acquire.clustering import cluster_colours, texel_clusters
from hybridbrdf.acquire.material_fits import MaterialFit, fit_materials, loss_rows, map_objective, value_spread
from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.screen import screen_materials
from hybridbrdf.acquire.texel_fit import AnalyticMaps, fit_analytic_texels
from hybridbrdf.acquire.texel_rows import ROWS_PER_TEXEL, ObservationTensors, Progress, adam_texels
from hybridbrdf.acquire.texel_stage import refine_texels

#: Clusters of texels at most (a textured material's base and 3 layers).
MAX_CLUSTERS = 4
#: The loss domain's epsilon of the *partition* (which texels go together: the analytic features
#: k-means groups, the split clusters' fits that decide the merges, and the moves of
#: :mod:`~hybridbrdf.acquire.texel_assign`): the paper's 1, where the bright lobes (eta, alpha)
#: decide. What each group is (the final choice of its material, its values, the network and the
#: texels) is fitted at :data:`~hybridbrdf.acquire.texel_rows.LOSS_EPS`. Partitioned at 0.1 too,
#: the verdict's two dark glossy layers drew together: features at 0.1 grouped them worse (8x4, low
#: noise, seed 0: SMAPE 0.71, re-render 0.18 against 0.38 and 0.145), and merges at 0.1 joined the
#: disc with the stripes and split the white base in two (16x8, low noise, seeds 1 and 2: cMAE
#: 0.0167 and 0.0174 against 0.0118 and 0.0123; docs/ACQUISITION_LOSS.md).
PARTITION_LOSS_EPS = 1.0
#: Materials of the prior fitted per cluster (the best scored with their own values).
CANDIDATES = 2
#: Rows of a cluster its materials are scored and fitted on, and the steps of each candidate's fit.
CLUSTER_ROWS, CLUSTER_STEPS = 2048, 100
#: Rows and steps of the screen that fits every material's values briefly to rank them
#: (:func:`~hybridbrdf.acquire.screen.screen_materials`).
SCREEN_ROWS, SCREEN_STEPS = 256, 40
#: The final clusters' choice (``final``, after the merge: the clusters the texel stage keeps): the
#: screen's rows and steps, the candidates' rows and how many are fitted. More than the split
#: clusters' (whose fits only decide the merges): 40 steps on 256 rows rank materials by how far
#: their values got, and in one capture colodur_napoli's best material after fitting stood 7th
#: there (docs/ACQUISITION_GAP.md, "The final clusters chosen again"). 1,024 and 8,192 rows
#: measured no better on the bench and cost twice the time.
FINAL_SCREEN_ROWS, FINAL_SCREEN_STEPS, FINAL_ROWS, FINAL_CANDIDATES = 512, 80, 4096, 4
#: Whether the final choice scores materials on rows averaged per texel and photograph
#: (:meth:`~hybridbrdf.acquire.texel_rows.ObservationTensors.cell_averaged`): materials that tie on
#: the photographs are ranked by the rows' noise otherwise, and at 200 photons a pixel the fit's
#: own seed chose among them (docs/ACQUISITION_GAP.md, "The final choice on averaged cells").
FINAL_CELL_AVERAGED = True
#: Whether the final choice takes, among the candidates that tie on the photographs, the one whose
#: predictions lie closest to the others' (:mod:`~hybridbrdf.acquire.consensus`).
CONSENSUS = True
#: Rows of a cluster its output layer is refitted on (``refit_heads``), the refit's steps and rate.
HEAD_ROWS, HEAD_STEPS, HEAD_LR = 8192, 200, 0.01
#: The head refit's pull toward the prior's head, a multiple of its MAP weight (see :func:`refit_heads_of`).
HEAD_PULL = 1.0
#: A refit starts a gated head's f_c biases at -HEAD_START or above and its f_g biases at HEAD_START
#: or below: the guard's f_t = f_a head (weights 0, biases -200 and 200: exp(-200) + sigmoid(200) f_a)
#: has no gradient; from -8 and 8 it has, and f_t differs from f_a by about 3e-4 of f_a + 3e-4.
HEAD_START = 8.0


def _cluster_rows(obs: Observations, labels: np.ndarray, c: int, n: int, seed: int) -> torch.Tensor:
    """Up to ``n`` rows of cluster ``c``'s pure texels (:func:`~hybridbrdf.acquire.network_tune.pure_rows`:
    its 8 neighbours in the cluster too, or its 4 edge neighbours where no texel has 8; every texel
    of ``c`` when none is pure), drawn without
    replacement (seeded). Why pure texels: a texel on a layer's boundary is photographed as a mix
    that no material of the prior explains (bench/acquire_gap.py --footprint), and a few of them
    dominate a cluster's squared log residual: fitted on all its texels, paper3's paper_white cluster
    chose a material that explains the rims and its own texels worse (docs/ACQUISITION_GAP.md, "The
    cluster stage on pure texels, every material screened")."""
    rows = network_tune.pure_rows(obs, labels, c).numpy()
    if len(rows) > n:
        rows = np.sort(np.random.default_rng([seed, c]).choice(rows, n, replace=False))
    return torch.from_numpy(rows)


def _scored_data(data: ObservationTensors, rows: torch.Tensor, noise: float) -> Tuple[ObservationTensors, float]:
    """``data`` averaged per texel and photograph (:meth:`~hybridbrdf.acquire.texel_rows.ObservationTensors.cell_averaged`)
    and the pixels' ``noise`` as its ``rows`` read it: a row's noise is its cell's mean's, nu^2 / cell size."""
    averaged = data.cell_averaged()
    return averaged, noise * float((1.0 / averaged.cell_size[rows]).mean())


def _pixel_loss(family, data: ObservationTensors, rows: torch.Tensor, fitted: Dict[str, object]) -> float:
    """The mean squared residual per row and channel of a fit of :func:`fit_material` on ``rows`` of ``data``."""
    raw = {n: v.expand(len(rows), -1) for n, v in fitted["raw"].items()}
    with torch.no_grad():
        return float(loss_rows(family, data, torch.full((len(rows),), int(fitted["material"])), raw, rows))


def _has_pure_texels(obs: Observations, labels: np.ndarray, c: int) -> bool:
    """Whether cluster ``c`` has a photographed pure texel (:func:`~hybridbrdf.acquire.network_tune.pure_texels`)."""
    texels = network_tune.pure_texels(labels, obs.size, c)
    return bool((np.diff(obs.offsets)[texels] > 0).any())


def fit_material(family, data: ObservationTensors, rows: torch.Tensor, m: int, start: Dict[str, torch.Tensor],
                 seed: int, stage: str, own: Optional[Dict[str, torch.Tensor]] = None, shots: int = 1,
                 noise: float = 0.0) -> Dict[str, object]:
    """Material ``m``'s values (one set, from ``start`` {name: (c,)}) fitted to ``rows`` on the frozen
    network, :data:`CLUSTER_STEPS` Adam steps: {"material", "loss" (its mean squared residual after),
    "score" (:func:`map_objective` after, given ``own`` = the material's own values and their spread
    ``own["tau2"]`` and the rows' ``noise``; else the loss), "raw" {name: (c,)}}; with ``own`` the fit
    minimises the objective. One fit of :func:`~hybridbrdf.acquire.material_fits.fit_materials`."""
    return fit_materials(family, data, [MaterialFit(rows, m, start, own, shots, noise)], CLUSTER_STEPS, seed, stage)[0]


def fit_clusters(family, obs: Observations, data: ObservationTensors, labels: np.ndarray, seed: int,
                 progress: Optional[Progress] = None, candidates: int = CANDIDATES,
                 colour: Optional[torch.Tensor] = None, final: bool = False) -> Dict[str, object]:
    """Per cluster: the prior's material that explains its rows best after fitting (see the module
    docstring; the best ``candidates`` of :func:`screen_materials` fitted from the values the screen
    reached, ``colour`` (K, 3) each cluster's raw kd for the screen's second start), its fitted values and the fit's residual
    variance. Returns {"material" (K,), "centres" {name: (K, c)}, "sigma2" (K,), "candidates": per
    cluster the fitted candidates, best first, each {"material", "loss", "raw" {name: (c,)}} (what
    :mod:`~hybridbrdf.acquire.cluster_report` prints)}. ``final``: with the final clusters' rows
    and screen (:data:`FINAL_ROWS`) where a cluster has pure texels (one without keeps the split
    clusters' rule and counts), scored on rows averaged per texel and photograph
    (:data:`FINAL_CELL_AVERAGED`; each candidate's "loss" then per pixel, as the stages after read
    it), the progress stage "final clusters", and the candidates that tie reordered by
    :func:`~hybridbrdf.acquire.consensus.medoid_first` (:data:`CONSENSUS`)."""
    n_rows, n_screen, screen_steps, bar = ((FINAL_ROWS, FINAL_SCREEN_ROWS, FINAL_SCREEN_STEPS, "final clusters") if final
                                           else (CLUSTER_ROWS, SCREEN_ROWS, SCREEN_STEPS, "clusters"))
    k = int(labels.max()) + 1
    every = family.raw_of_materials()
    tau2 = value_spread(every)
    total = k + CLUSTER_STEPS  # the bar: a unit per cluster's screen, then one per step of the candidates' fit
    plans = []
    for c in range(k):
        plans.append(_candidates_of(family, obs, data, labels, c, every, tau2, seed, n_rows, n_screen, screen_steps,
                                    candidates, final, None if colour is None else colour[c]))
        if progress is not None:
            progress(bar, c + 1, total)
    # Every cluster's candidates fitted at once (material_fits: the same fits, one pass a step), in a
    # problem per set of targets (the final clusters' pure ones score on cell-averaged rows).
    fitted_of = {}
    groups = list({id(plan["scored"]): plan["scored"] for plan in plans if plan is not None}.values())
    for g, scored in enumerate(groups):
        jobs = [(c, job) for c, plan in enumerate(plans) if plan is not None and plan["scored"] is scored
                for job in plan["jobs"]]

        def step(_, done, steps, g=g):
            if progress is not None:
                progress(bar, k + (g * steps + done) * CLUSTER_STEPS // (len(groups) * steps), total)
        results = fit_materials(family, scored, [job for _, job in jobs], CLUSTER_STEPS, seed, f"{bar}-{g}", step)
        for (c, job), fit in zip(jobs, results):
            if scored is not data:  # the loss per pixel, as every stage after reads it (sigma^2, the report)
                fit["loss"] = _pixel_loss(family, data, job.rows, fit)
            fitted_of.setdefault(c, []).append(fit)
    if progress is not None and not groups:
        progress(bar, total, total)
    materials, centres, sigma2, fitted_all = [], {name: [] for name in every}, [], []
    for c in range(k):
        if plans[c] is None:  # a cluster of texels without observations only: the largest's values
            materials.append(materials[0] if materials else 0)
            for name in every:
                centres[name].append(centres[name][0] if centres[name] else every[name][0])
            sigma2.append(sigma2[0] if sigma2 else 1.0)
            fitted_all.append([])
            continue
        fitted = sorted(fitted_of[c], key=lambda cand: cand["score"])  # stable: a tie keeps the better-screened
        if final and CONSENSUS:
            job = plans[c]["jobs"][0]
            fitted = consensus.medoid_first(family, fitted, job.shots, job.noise)
        best = fitted[0]
        materials.append(best["material"])
        for name in every:
            centres[name].append(best["raw"][name])
        sigma2.append(max(best["loss"], 1e-8))
        fitted_all.append(fitted)
    return {"material": torch.tensor(materials), "centres": {n: torch.stack(v) for n, v in centres.items()},
            "sigma2": torch.tensor(sigma2), "candidates": fitted_all}


def _candidates_of(family, obs: Observations, data: ObservationTensors, labels: np.ndarray, c: int,
                   every: Dict[str, torch.Tensor], tau2: Dict[str, torch.Tensor], seed: int, n_rows: int,
                   n_screen: int, screen_steps: int, candidates: int, final: bool,
                   colour: Optional[torch.Tensor]) -> Optional[Dict[str, object]]:
    """Cluster ``c``'s candidates, screened as :func:`fit_clusters` says: {"scored" (the data they are
    fitted on), "jobs" [:class:`~hybridbrdf.acquire.material_fits.MaterialFit`] in the screen's order};
    None for a cluster without rows."""
    pure = _has_pure_texels(obs, labels, c)
    rows = _cluster_rows(obs, labels, c, n_rows if pure else CLUSTER_ROWS, seed)
    if not len(rows):
        return None
    shots = len(np.unique(obs.shot[rows.numpy()]))
    # The pixels' noise enters the MAP objective only, which scores pure clusters alone.
    noise = data.pixel_noise(network_tune.pure_rows(obs, labels, c)) if pure else 0.0
    scored, noise = _scored_data(data, rows, noise) if pure and final and FINAL_CELL_AVERAGED else (data, noise)
    if pure:
        score_rows = rows[::max(1, len(rows) // n_screen)][:n_screen]  # spread over the cluster's texels
        scores, screened, as_is = screen_materials(family, scored, score_rows, every, seed, f"screen{c}",
                                                   colour, shots, noise, screen_steps)
        # The screen's best, and the best with its own values: where the photographs cannot tell
        # shapes apart (a flash capture's collocated slice), the screen's order among near-ties is
        # chance, and a material photographed as it is keeps its lead as it is.
        ranked = torch.argsort(scores)[:candidates].tolist()
        ranked += [m for m in torch.argsort(as_is)[:1].tolist() if m not in ranked]
        starts, by_objective = screened, True
    else:  # only texels on a boundary: rows of mixes, which the screen would explain with whichever
        # material's refitted values imitate the mix best, a layer of its own for a boundary
        # (tests/python/test_acquire_fit.py's halves: a white paper's rim took cm_white, a third
        # layer); so the rule before the screen, the materials as they are, by their loss alone,
        # and as many as before when final (more candidates on mixes chose worse: the verdict's 4x2).
        score_rows = rows[::max(1, len(rows) // 1024)][:1024]
        with torch.no_grad():
            as_is = torch.stack([loss_rows(family, data, torch.full((len(score_rows),), m),
                                            {n: v[m].expand(len(score_rows), -1) for n, v in every.items()},
                                            score_rows) for m in range(len(every["z"]))])
        ranked = torch.argsort(as_is)[:CANDIDATES if final else candidates].tolist()
        starts, by_objective = every, False
    jobs = [MaterialFit(rows, m, {n: v[m] for n, v in starts.items()},
                        {**{n: v[m] for n, v in every.items()}, "tau2": tau2} if by_objective else None, shots, noise)
            for m in ranked]
    return {"scored": scored, "jobs": jobs}


def start_bias(family, bias: torch.Tensor) -> torch.Tensor:
    """A copy of head biases ``bias`` (K, o) to refit from: a gated head's f_c biases at
    -:data:`HEAD_START` or above, its f_g biases at :data:`HEAD_START` or below."""
    bias = bias.clone()
    if getattr(family.module, "combine_rule", None) == "gated":
        bias[:, :3], bias[:, 3:] = bias[:, :3].clamp_min(-HEAD_START), bias[:, 3:].clamp_max(HEAD_START)
    return bias


def start_heads(family, clusters: Dict) -> Tuple[torch.Tensor, torch.Tensor, Dict[str, torch.Tensor]]:
    """Each cluster's head (weight (K, o, w), bias (K, o)) and values to fine-tune from: the head
    refit's when it ran, else the cluster's material's head (:func:`start_bias`) and the cluster's values."""
    if "heads" in clusters:
        h = clusters["heads"]
        return h["weight"], h["bias"], h["centres"]
    t, m = family.tensors, clusters["material"]
    return t["materials.head_weight"][m], start_bias(family, t["materials.head_bias"][m]), clusters["centres"]


def refit_heads_of(family, obs: Observations, data: ObservationTensors, labels: np.ndarray, clusters: Dict,
                seed: int, progress: Optional[Progress] = None) -> Dict[str, object]:
    """Per cluster, its material's output layer (head weight and bias) and the cluster's values fitted
    together (Adam, :data:`HEAD_STEPS` steps from the prior's head and the cluster stage's values)
    on up to :data:`HEAD_ROWS` of its rows, the hidden layers frozen. Returns {"weight" (K, o, w),
    "bias" (K, o), "centres" {name: (K, c)}, "sigma2" (K,)}: what the texel stage then uses per
    cluster instead of the material's head and the cluster stage's values.

    The head is pulled toward the prior's as the texel stage pulls a texel's values toward its
    cluster's (a MAP prior): each element a Gaussian draw around the prior material's with the
    variance of that element over the prior's materials, weighed against the rows' residual
    variance sigma^2 (the cluster stage's) over 3 n_eff, n_eff the photographs the rows come from:
    a texel's rows in one photograph see one direction pair, so the cluster's rows hold about one
    independent pair per photograph, and a head on a few photographs stays near the prior's."""
    t = family.tensors
    tau2 = {n: t["materials." + n].var(dim=0).clamp_min(1e-6) for n in ("head_weight", "head_bias")}
    k = len(clusters["material"])
    weights, biases, sigma2 = [], [], []
    centres = {n: [] for n in clusters["centres"]}
    for c in range(k):
        m = int(clusters["material"][c])
        bias = start_bias(family, t["materials.head_bias"][m:m + 1])
        params = {"head_weight": t["materials.head_weight"][m:m + 1].clone().requires_grad_(),
                  "head_bias": bias.requires_grad_(),
                  **{"raw_" + n: v[c:c + 1].clone().requires_grad_() for n, v in clusters["centres"].items()}}
        rows = _cluster_rows(obs, labels, c, HEAD_ROWS, seed)
        prior_head = {"head_weight": t["materials.head_weight"][m:m + 1], "head_bias": bias.detach().clone()}
        pull = HEAD_PULL * float(clusters["sigma2"][c]) / (3 * max(1, len(np.unique(obs.shot[rows.numpy()]))))

        def loss(gen, params=params, rows=rows, m=m, prior_head=prior_head, pull=pull):
            own = family.with_heads(torch.tensor([m]), params["head_weight"], params["head_bias"])
            raw = {n: params["raw_" + n].expand(len(rows), -1) for n in clusters["centres"]}
            d2 = loss_rows(own, data, torch.zeros(len(rows), dtype=torch.long), raw, rows)
            if gen is None:  # the residual alone (sigma^2 for the texel stage)
                return d2
            return d2 + pull * sum((((params[n] - prior_head[n]) ** 2) / tau2[n]).sum() for n in tau2)

        if len(rows):
            adam_texels(params, loss, HEAD_STEPS, HEAD_LR, seed, f"head{c}")
        if progress is not None:
            progress("heads", c + 1, k)
        with torch.no_grad():
            sigma2.append(max(float(loss(None)), 1e-8) if len(rows) else float(clusters["sigma2"][c]))
        weights.append(params["head_weight"].detach()[0])
        biases.append(params["head_bias"].detach()[0])
        for n in centres:
            centres[n].append(params["raw_" + n].detach()[0])
    return {"weight": torch.stack(weights), "bias": torch.stack(biases),
            "centres": {n: torch.stack(v) for n, v in centres.items()}, "sigma2": torch.tensor(sigma2)}


def _check_rows(rows_per_texel) -> None:
    """A fit on a prior's ``rows_per_texel``: an int >= 1, as the texel stage's twins draw rows (the
    analytic fit alone reads every row a step with None)."""
    if not isinstance(rows_per_texel, int) or rows_per_texel < 1:
        raise ValueError(f"rows_per_texel must be an int >= 1 for a fit on a prior, got {rows_per_texel!r}")


def _cluster_stage(family, obs: Observations, data: ObservationTensors, partition: ObservationTensors,
                   maps: AnalyticMaps, labels: np.ndarray, seed: int, progress: Optional[Progress],
                   choose: Optional[Callable], merge) -> Dict:
    """Stage 2 of the module docstring: the clusters fitted (or chosen by ``choose``); given ``merge``,
    merged, then each final cluster's material chosen again on more rows (:data:`FINAL_ROWS`; ``choose``
    again where given), the merge's "merges" kept, and texels moved to the cluster that explains
    them (:mod:`~hybridbrdf.acquire.texel_assign`): "labels" then the moved labels, "moved" their count.
    The split clusters, merges and moves read ``partition`` (the loss domain of
    :data:`PARTITION_LOSS_EPS`), the final choice ``data``; without ``merge`` the one choice is final."""
    if merge is None:
        return (choose or fit_clusters)(family, obs, data, labels, seed, progress, colour=cluster_colours(maps, labels))
    fitted = (choose or fit_clusters)(family, obs, partition, labels, seed, progress, colour=cluster_colours(maps, labels))
    fitted = merge.merge_clusters(family, obs, partition, labels, fitted, seed, MAX_CLUSTERS, progress=progress)[1]
    merged = fitted["labels"].numpy()
    final = choose or functools.partial(fit_clusters, candidates=FINAL_CANDIDATES, final=True)
    fitted = {**fitted, **final(family, obs, data, merged, seed, progress, colour=cluster_colours(maps, merged))}
    if not texel_assign.MOVE:
        return fitted
    moved, count = texel_assign.move_texels(family, obs, partition, merged, fitted)
    return {**fitted, "labels": torch.from_numpy(moved), "moved": count}


def fit_on_prior(family, obs: Observations, steps: int, seed: int, rows_per_texel: int = ROWS_PER_TEXEL,
                 progress: Optional[Progress] = None, state: Optional[dict] = None,
                 save_state: Optional[Callable[[dict], None]] = None,
                 on_clusters: Optional[Callable[[np.ndarray, Dict], None]] = None,
                 refit_heads: bool = False, finetune_network: int = 0,
                 choose: Optional[Callable] = None, merge=None) -> Tuple[np.ndarray, Dict, Dict]:
    """The stages (module docstring): (labels (n_texels,), clusters, per-texel raw values); with
    ``refit_heads`` (a family with material output layers) the heads stage too, and clusters["heads"]
    holds what :func:`refit_heads_of` returned (the texel stage's per-cluster heads and centres).
    ``finetune_network`` > 0 (material output layers): that many steps of the network stage after
    them (:func:`hybridbrdf.acquire.network_tune.finetune_network`): clusters["heads"] then holds
    its heads and centres, clusters["network"] its tuned hidden layers and the replay's drift, and
    the texel stage runs on the tuned network.
    ``state`` (what ``save_state`` was last given) resumes after the last finished stage or within
    the analytic and texel stages at their last checkpoint (every 50 steps). ``on_clusters(labels,
    clusters)`` is called once the clusters are known (fitted or restored), before the texel stage.
    ``choose``: the cluster stage, called as :func:`fit_clusters` is (None: :func:`fit_clusters`;
    :func:`hybridbrdf.acquire.select.select_on_held_out` chooses on held-out shots). ``merge``:
    :mod:`hybridbrdf.acquire.cluster_merge` (passed in: it fits with this module); None: none merged."""
    _check_rows(rows_per_texel)
    state = dict(state or {})

    def saver(key):
        def save(partial):
            if save_state is not None:
                save_state({**state, key: partial})
        return save

    def finish(key, value):
        state[key] = value
        state.pop(key + "_partial", None)
        if save_state is not None:
            save_state(dict(state))

    if "analytic" not in state:
        maps = fit_analytic_texels(obs, steps=max(1, steps // 2), seed=seed, rows_per_texel=rows_per_texel,
                                   progress=progress, state=state.get("analytic_partial"),
                                   save_state=saver("analytic_partial"), observation_model="nearest",
                                   loss_eps=PARTITION_LOSS_EPS)
        finish("analytic", {"kd": torch.from_numpy(maps.kd), "eta": torch.from_numpy(maps.eta),
                            "alpha": torch.from_numpy(maps.alpha)})
    a = state["analytic"]
    maps = AnalyticMaps(a["kd"].numpy(), a["eta"].numpy(), a["alpha"].numpy(), obs.counts())
    k = MAX_CLUSTERS if merge is None else merge.split_count(int((obs.counts() > 0).sum()), MAX_CLUSTERS)
    labels = texel_clusters(maps, k, seed)
    data = ObservationTensors(obs)
    if "clusters" not in state:
        partition = ObservationTensors(obs, PARTITION_LOSS_EPS)
        finish("clusters", _cluster_stage(family, obs, data, partition, maps, labels, seed, progress, choose, merge))
    clusters = state["clusters"]
    labels = clusters["labels"].numpy() if "labels" in clusters else labels
    if on_clusters is not None:
        on_clusters(labels, clusters)
    stage_family, stage_clusters = family, clusters
    if refit_heads and "materials.head_weight" in getattr(family, "tensors", {}):
        if "heads" not in state:
            finish("heads", refit_heads_of(family, obs, data, labels, clusters, seed, progress))
        heads = state["heads"]
        # The texel stage's "materials" are then the clusters: cluster k's head and its material's energy table.
        stage_family = family.with_heads(clusters["material"], heads["weight"], heads["bias"])
        stage_clusters = {**clusters, "material": torch.arange(len(clusters["material"])),
                          "centres": heads["centres"], "sigma2": heads["sigma2"]}
        clusters = {**clusters, "heads": heads}
    if finetune_network > 0 and "materials.head_weight" in getattr(family, "tensors", {}):
        if "network" not in state:
            finish("network", network_tune.finetune_network(family, obs, data, labels, clusters,
                                                            start_heads(family, clusters), finetune_network, seed,
                                                            progress))
        tuned = state["network"]
        stage_family = network_tune.tuned_family(family, tuned["network"]).with_heads(
            clusters["material"], tuned["weight"], tuned["bias"])
        stage_clusters = {**clusters, "material": torch.arange(len(clusters["material"])),
                          "centres": tuned["centres"], "sigma2": tuned["sigma2"]}
        clusters = {**clusters, "heads": {n: tuned[n] for n in ("weight", "bias", "centres", "sigma2")},
                    "network": tuned}
    raw = refine_texels(stage_family, obs, data, labels, stage_clusters, value_spread(family.raw_of_materials()),
                        steps, seed, rows_per_texel, progress=progress, state=state.get("texels_partial"),
                        save_state=saver("texels_partial"))
    return labels, clusters, raw

