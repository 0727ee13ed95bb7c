"""The **hybrid** per-texel fit (docs/ACQUISITION.md, issue 46 step 2): p = (kd, eta, alpha) and z
per texel on a frozen hybrid prior, each texel with the output layer and energy table of its
cluster's prior material (:mod:`~hybridbrdf.acquire.cluster_fit`), written as a textured material
(docs/SVBRDF.md): the clusters' materials are the layers, the weights map the (one-hot) cluster
assignment, and each layer's kd, eta, alpha and latent maps the texels' values.

    maps = fit_hybrid_texels(texel_observations(rig, photos, (128, 128)), load_prior(), steps=300)
    maps.eval(texel, wi, wo)   # (M, 3) the fitted BRDF at those texels
    maps.save("out/acquired")  # the folder hbrdf paint writes; loads in libhybridbrdf"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np
import torch

from hybridbrdf.acquire import cluster_merge, footprint
from hybridbrdf.acquire.cluster_fit import fit_on_prior
from hybridbrdf.acquire.evaluation import eval_chunked
from hybridbrdf.acquire.observations import Observations
from hybridbrdf.acquire.select import select_on_held_out
from hybridbrdf.acquire.texel_rows import ROWS_PER_TEXEL, Progress
from hybridbrdf.brdf.torch_brdf import _normalize
from hybridbrdf.fit.painting import bound_bright_kd
from hybridbrdf.model import energy
from hybridbrdf.model.file import HybridModel
from hybridbrdf.model.networks import alpha_from_raw, energy_bound_scale, eta_from_raw, kd_from_raw, raw_from_analytic
from hybridbrdf.svbrdf.asset import SVBRDF

class HybridFamily:
    """A hybrid model's frozen network and per-material values, as the per-texel fits use them:
    raw values per row (kd, eta, alpha, z; HybridBRDF's reparameterisation, so every value stays
    in the contract's range) and ``evaluate(material, raw, wi, wo)`` = f (N, 3), each row with its
    material's output layer and energy table."""

    def __init__(self, model: HybridModel):
        if not model.has_analytic:
            raise ValueError(f"the hybrid fit needs a hybrid model; {model.path or 'this one'} is '{model.kind}'")
        self.model = model
        self.module = model._module(torch.float32)
        for p in self.module.parameters():
            p.requires_grad_(False)
        t = {k: torch.from_numpy(v) for k, v in model.tensors.items() if k.startswith("materials.")}
        self.tensors = t

    def raw_of_materials(self) -> Dict[str, torch.Tensor]:
        """Every material's raw values (M, c)."""
        t = self.tensors
        kd, eta, alpha = raw_from_analytic(t["materials.kd"], t["materials.eta"], t["materials.alpha"])
        return {"kd": kd, "eta": eta, "alpha": alpha, "z": t["materials.z"].clone()}

    def with_heads(self, materials: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor) -> "HybridFamily":
        """The same family whose material k evaluates with output layer (``weight[k]``, ``bias[k]``)
        and material ``materials[k]``'s energy table (the refitted heads of
        :func:`~hybridbrdf.acquire.cluster_fit.refit_heads_of`); ``raw_of_materials`` stays the prior's."""
        view = copy.copy(self)
        view.tensors = dict(self.tensors, **{"materials.head_weight": weight, "materials.head_bias": bias})
        if "materials.energy_bound" in self.tensors:
            view.tensors["materials.energy_bound"] = self.tensors["materials.energy_bound"][materials]
        return view

    @staticmethod
    def decode(raw: Dict[str, torch.Tensor]):
        """(kd, eta, alpha, z) of raw values, as HybridBRDF decodes its parameters."""
        return kd_from_raw(raw["kd"]), eta_from_raw(raw["eta"]), alpha_from_raw(raw["alpha"]), raw["z"]

    def evaluate(self, material: torch.Tensor, raw: Dict[str, torch.Tensor], wi, wo) -> torch.Tensor:
        return self.evaluate_values(material, *self.decode(raw), wi, wo)

    def values(self, raw: Dict[str, torch.Tensor]) -> Dict[str, torch.Tensor]:
        """The decoded values {kd, eta, alpha, z} of raw values: what a textured material's maps hold."""
        return dict(zip(("kd", "eta", "alpha", "z"), self.decode(raw)))

    def evaluate_decoded(self, material: torch.Tensor, values: Dict[str, torch.Tensor], wi, wo) -> torch.Tensor:
        """f (N, 3) of rows with decoded ``values`` (:meth:`values`)."""
        return self.evaluate_values(material, *(values[n] for n in ("kd", "eta", "alpha", "z")), wi, wo)

    def evaluate_values(self, material, kd, eta, alpha, z, wi, wo) -> torch.Tensor:
        """f (N, 3) of rows with decoded values, grouped by material (one output layer each)."""
        out = torch.zeros((len(wi), 3), dtype=wi.dtype)
        wi, wo = wi.to(torch.float32), wo.to(torch.float32)
        t = self.tensors
        counts = torch.bincount(material)
        # Rows sorted by material (the texel stage's, material_fits'): each material's rows are a
        # slice, read without a gather and written by one concatenation.
        ends = torch.cumsum(counts, 0).tolist() if bool((material[1:] >= material[:-1]).all()) else None
        pieces = []
        for m in torch.nonzero(counts)[:, 0].tolist():  # torch.unique, without its sort
            rows = slice(ends[m] - int(counts[m]), ends[m]) if ends is not None else torch.nonzero(material == m)[:, 0]
            head = (t["materials.head_weight"][m], t["materials.head_bias"][m]) if "materials.head_weight" in t else None
            a, b = wi[rows], wo[rows]
            f, _ = self.module.evaluate_pairs(a, b, kd[rows], eta[rows], alpha[rows], z[rows], head)
            if "materials.energy_bound" in t:  # as HybridModel.eval scales a material's f_t
                table = t["materials.energy_bound"][m]
                ci, co = (_normalize(w)[0][:, 2] for w in (a, b))
                f = f * (energy_bound_scale(table, ci) * energy_bound_scale(table, co))[:, None]
            if ends is not None:
                pieces.append(f.to(out.dtype))
            else:
                out = out.index_copy(0, rows, f.to(out.dtype))
        return out if ends is None or not pieces else pieces[0] if len(pieces) == 1 else torch.cat(pieces)

    def evaluate_shared(self, material: torch.Tensor, raw: Dict[str, torch.Tensor], wi, wo) -> torch.Tensor:
        """f (G, R, 3): G fits, fit g material ``material[g]`` with values ``raw`` {name: (G, c)}, all
        on the same R direction pairs ``wi``, ``wo`` (R, 3), in one pass (the network's own
        many-materials evaluation, as the joint fit runs it: one batched product per output layer,
        not a pass per material); what :meth:`evaluate` gives for each fit's rows. The screen of
        every prior material, :func:`~hybridbrdf.acquire.screen.screen_materials`."""
        t = self.tensors
        kd, eta, alpha, z = self.decode(raw)
        wi, wo = wi.to(torch.float32), wo.to(torch.float32)
        head = (t["materials.head_weight"][material], t["materials.head_bias"][material]) \
            if "materials.head_weight" in t else None
        f, _ = self.module.evaluate(wi, wo, kd, eta, alpha, z, head)
        if "materials.energy_bound" in t:
            table = t["materials.energy_bound"][material][:, None]  # (G, 1, K) against (R,) cosines
            ci, co = (_normalize(w)[0][:, 2] for w in (wi, wo))
            f = f * (energy_bound_scale(table, ci[None]) * energy_bound_scale(table, co[None]))[..., None]
        return f


@dataclass
class HybridMaps:
    """A hybrid fit: ``model`` (the prior, with an edit per layer whose kd map is brighter than its
    material: :func:`hybridbrdf.fit.painting.bound_bright_kd`), ``layers`` (material names, at most 4),
    ``layer`` (H, W) each texel's layer, per texel ``kd``, ``eta`` (H, W, 3), ``alpha`` (H, W, 2),
    ``z`` (H, W, l) float32, ``counts`` (H, W) observations per texel (0: its cluster's values),
    ``report`` what :func:`~hybridbrdf.acquire.acquisition.acquire` wrote as acquisition.json."""
    model: HybridModel
    layers: List[str]
    layer: np.ndarray
    kd: np.ndarray
    eta: np.ndarray
    alpha: np.ndarray
    z: np.ndarray
    counts: np.ndarray
    report: Optional[dict] = None  # hbrdf acquire fit's clusters and choices (acquire/cluster_report.py)

    def eval(self, texel: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """The fitted BRDF (no cosine) at texels ``texel`` ((M,) int, j * W + i) for ``wi``, ``wo``
        (M, 3): (M, 3) float64, evaluated in chunks without gradients (float32 network)."""
        family = HybridFamily(self.model)
        index = torch.tensor([self.model.index(n) for n in self.layers])
        flat = {k: torch.from_numpy(np.ascontiguousarray(getattr(self, k).reshape(-1, getattr(self, k).shape[-1])))
                for k in ("kd", "eta", "alpha", "z")}
        material = index[torch.from_numpy(self.layer.reshape(-1).astype(np.int64))]

        def fn(t, a, b):
            t = torch.from_numpy(t)
            return family.evaluate_values(material[t], flat["kd"][t], flat["eta"][t], flat["alpha"][t],
                                          flat["z"][t], a, b)
        return eval_chunked(texel, wi, wo, self.layer.size, fn)

    def eval_uv(self, uv: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """The fit at uv (M, 2) as its textured material (:meth:`svbrdf`) shows it, read bilinearly:
        (M, 3) float64 (PyTorch, float64)."""
        return self.svbrdf().eval(np.asarray(uv, np.float64), wi, wo, dtype=torch.float64)

    def svbrdf(self) -> SVBRDF:
        """The textured material (docs/SVBRDF.md): layer k's maps hold its texels' values and, at
        the other texels, its texels' mean (what a bilinear tap across a layer boundary mixes in)."""
        h, w = self.layer.shape
        weights = np.zeros((h, w, 3), np.float32)
        maps = []
        for k in range(len(self.layers)):
            mine = self.layer == k
            if k > 0:
                weights[..., k - 1] = mine
            layer_maps = {}
            for q, arr in (("kd", self.kd), ("eta", self.eta), ("alpha", self.alpha), ("latent", self.z)):
                filled = np.where(mine[..., None], arr, arr[mine].mean(axis=0)).astype(np.float32)
                layer_maps[q] = filled
            maps.append(layer_maps)
        return SVBRDF(self.model, self.layers, (w, h), weights if len(self.layers) > 1 else None, maps, "clamp")

    def save(self, folder, format: str = "exr", extra: Optional[Dict[str, bytes]] = None) -> SVBRDF:
        """Write the textured-material folder (:meth:`SVBRDF.save`: atomic, an existing folder replaced
        only when it is a textured material's, ``extra`` files with it); EXR keeps the fitted values
        exactly (float32), so the folder evaluates as :meth:`eval` does."""
        sv = self.svbrdf()
        sv.save(folder, format=format, extra=extra)
        return sv


def with_cluster_heads(model: HybridModel, family: HybridFamily, clusters: Dict) -> Tuple[HybridModel, List[str]]:
    """The prior plus one material per cluster of a fit with refitted heads: the cluster's material
    with its refitted output layer and the cluster's values, named ``<material>.acq<k>``, its energy
    table fitted for that head (hbrdf add's bound: :func:`hybridbrdf.model.energy.with_bound`)."""
    heads, chosen = clusters["heads"], clusters["material"].tolist()
    with torch.no_grad():
        values = dict(zip(("kd", "eta", "alpha", "z"), (v.numpy() for v in family.decode(heads["centres"]))))
    values.update(head_weight=heads["weight"].numpy(), head_bias=heads["bias"].numpy())
    names, taken = [], set(model.materials)
    for k, m in enumerate(chosen):  # a prior that is itself an acquisition's model may hold <material>.acq<k>
        j = k
        while f"{model.materials[m][:50]}.acq{j}" in taken:
            j += len(chosen)
        names.append(f"{model.materials[m][:50]}.acq{j}")
        taken.add(names[-1])
    plain = energy.unbounded(model)
    tensors = {key: (np.concatenate([v, values[key.split(".", 1)[1]].astype(np.float32)]) if key.startswith("materials.")
                     else v.copy()) for key, v in plain.tensors.items()}
    infos = [dict(i) for i in plain.material_info] + [
        {"name": n, "origin": f"{model.materials[m]} with its output layer refitted to a capture (hbrdf acquire fit)",
         "isotropic": bool(values["alpha"][k][0] == values["alpha"][k][1]), "metrics": {}}
        for k, (n, m) in enumerate(zip(names, chosen))]
    grown = type(model)(dict(plain.arch), infos, tensors, dict(model.training) if isinstance(model.training, dict) else {})
    old = model.tensors.get("materials.energy_bound", np.ones((len(model.materials), energy.NODES), np.float32))
    table = np.concatenate([old, np.ones((len(names), energy.NODES), np.float32)])
    return energy.with_bound(energy.attach(grown, table), names), names


def with_network(model: HybridModel, tuned: Dict) -> HybridModel:
    """``model`` with the fine-tuned hidden layers ``tuned["network"]`` (state-dict tensors by name)
    and the fine-tune recorded in its training record (the capture loss at its first and last step, the
    replay's median and worst drift).
    Its materials' (p, z), heads and energy tables are kept: the fine-tune replayed them on this network."""
    tensors = {k: (tuned["network"][k].numpy().astype(np.float32) if k in tuned["network"] else v)
               for k, v in model.tensors.items()}
    training = dict(model.training) if isinstance(model.training, dict) else {}
    smape, cmae = (np.asarray(tuned["drift"][k], np.float64) for k in ("smape", "cmae"))
    worst = int(np.argmax(smape))
    drift = {"median_smape": float(np.median(smape)), "median_cmae": float(np.median(cmae)),
             "worst_smape": float(smape[worst]), "worst_cmae": float(cmae[worst]), "worst_material": model.materials[worst]}
    training["acquisition_finetune"] = {"capture_loss": [float(x) for x in tuned["loss"]], "drift": drift}
    return type(model)(dict(model.arch), [dict(i) for i in model.material_info], tensors, training)


#: Inner texels a layer needs before its upper fence is trusted (:func:`cap_outlier_kd`).
FENCE_MIN_TEXELS = 8


def cap_outlier_kd(kd: np.ndarray, layer: np.ndarray) -> tuple:
    """``kd`` (H * W, 3) with every texel of a layer no brighter, per channel, than the upper fence of
    the layer's inner texels (footprint.rim_texels), q3 + 1.5 (q3 - q1) (Tukey's outlier rule); layers
    with fewer than :data:`FENCE_MIN_TEXELS` inner texels keep theirs. Returns (capped kd, how many
    texels changed). Why: a layer's energy table is fitted for its brightest texel and scales every
    texel of the layer (bound_bright_kd), so one outlier darkens them all: on the light-stage bench one
    paper_white texel at kd 0.896 (blue) against its layer's fence 0.874 left the layer 2% dark on its
    own photographs and its pure texels 1.83x the full measurement's cMAE; capped, 1.29x
    (docs/ACQUISITION_GAP.md). A painted gradient's spread widens the fence and keeps it."""
    kd = kd.copy()
    flat, rim = layer.reshape(-1), footprint.rim_texels(layer).reshape(-1)
    changed = 0
    for k in np.unique(flat):
        inner, mine = (flat == k) & ~rim, flat == k
        if inner.sum() < FENCE_MIN_TEXELS:
            continue
        q1, q3 = np.percentile(kd[inner], [25, 75], axis=0)
        capped = np.minimum(kd[mine], q3 + 1.5 * (q3 - q1))
        changed += int((capped != kd[mine]).any(axis=1).sum())
        kd[mine] = capped
    return kd, changed


def fit_hybrid_texels(obs: Observations, model: HybridModel, steps: int = 300, seed: int = 0,
                      progress: Optional[Progress] = None, rows_per_texel: int = ROWS_PER_TEXEL,
                      state: Optional[dict] = None, save_state: Optional[Callable[[dict], None]] = None,
                      log: Callable[[str], None] = lambda msg: None,
                      on_clusters: Optional[Callable[[HybridFamily, np.ndarray, Dict], None]] = None,
                      refit_heads: bool = False, finetune_network: int = 0, select: bool = False) -> HybridMaps:
    """Fit (p, z) per texel on ``model``'s frozen network (a hybrid prior with its materials):
    the stages of :func:`hybridbrdf.acquire.cluster_fit.fit_on_prior` (analytic ``steps // 2``
    steps, the clusters, ``steps`` per-texel steps of ``rows_per_texel`` rows each), then the
    energy tables of the layers whose kd map is brighter than their material (stage "energy
    tables", one step a layer: about 5 s each). ``progress`` gets (stage, done, total) after each
    step; ``save_state`` a resumable state, ``state`` resumes; ``on_clusters(family, labels,
    clusters)`` runs once the clusters are known (:mod:`~hybridbrdf.acquire.cluster_report`).
    ``refit_heads``: each cluster's output layer refitted to its rows (the heads stage of
    :func:`~hybridbrdf.acquire.cluster_fit.fit_on_prior`); each cluster is then a layer of its own,
    a material of the prior with that head (:func:`with_cluster_heads`). ``finetune_network`` > 0:
    that many steps of the network stage (:mod:`~hybridbrdf.acquire.network_tune`), a layer per
    cluster as with ``refit_heads``, and the written model carries the tuned network
    (:func:`with_network`). ``select``: each cluster's material chosen on held-out photographs
    (:mod:`~hybridbrdf.acquire.select`)."""
    family = HybridFamily(model)
    def hook(labels, clusters):
        log(cluster_merge.merge_line(clusters))
        if on_clusters is not None:
            on_clusters(family, labels, clusters)
    labels, clusters, raw = fit_on_prior(family, obs, steps, seed, rows_per_texel, progress, state, save_state, hook,
                                         refit_heads=refit_heads, finetune_network=finetune_network,
                                         choose=select_on_held_out if select else None, merge=cluster_merge)
    w, h = obs.size
    with torch.no_grad():
        kd, eta, alpha, z = (v.numpy().astype(np.float32) for v in family.decode(raw))
    if "network" in clusters:
        model = with_network(model, clusters["network"])
    if "heads" in clusters:  # a layer per cluster: its own head
        model, names = with_cluster_heads(model, family, clusters)
        layer = labels
    else:  # clusters that chose the same material share its layer (p and z are per texel anyway)
        cluster_material = clusters["material"].tolist()
        chosen = list(dict.fromkeys(cluster_material))
        layer = np.array([chosen.index(m) for m in cluster_material])[labels]
        names = [model.materials[m] for m in chosen]
    kd, capped = footprint.cap_rim_kd(kd, layer.reshape(h, w))
    if capped:
        log(f"{capped} rim texel(s) brighter than their layer's inner texels: kd capped at the layer's brightest inner texel")
    kd, capped = cap_outlier_kd(kd, layer.reshape(h, w))
    if capped:
        log(f"{capped} texel(s) above their layer's upper fence (Tukey's, over its inner texels): kd capped at it")
    for k in range(len(names)):  # one layer at a time: a step of the "energy tables" bar each
        model, names = bound_bright_kd(model, names, {k: kd[layer == k]}, log)
        if progress is not None:
            progress("energy tables", k + 1, len(names))
    shape = (h, w)
    return HybridMaps(model, names, layer.reshape(shape), kd.reshape(*shape, 3), eta.reshape(*shape, 3),
                      alpha.reshape(*shape, 2), z.reshape(*shape, -1), obs.counts())
