"""The energy bound: every directional albedo of a material at most :data:`TARGET`, reciprocity kept.

A fitted hybrid material f_t = f_c + f_g f_a can reflect more light than it receives: f_a is the
paper's Lambert + GGX without coupling between the lobes, and the network's correction f_c is
unbounded (docs/ENERGY.md measures both). The bound scales f_t by a separable, symmetric factor

    f(wi, wo) = k(wi.z) k(wo.z) f_t(wi, wo),    0 <= k <= 1,

with k piecewise linear in cos theta over spec.ENERGY_NODES nodes, one table per material
(spec/model.json, ``energy_bounds``). Why this form:

- k(wi.z) k(wo.z) is symmetric, so a reciprocal f_t stays reciprocal bit for bit (the product
  of two floats commutes);
- k <= 1 only removes light, and for a direction w the albedo of f is
  k(w) * integral k(w') f_t(w', w) cos dw' <= k(w) rho_t(w): a k at or below TARGET / rho_t(w)
  bounds it. Where rho_t <= TARGET the table stays 1 and the material is untouched: the bound costs
  fidelity only where a material was wrong (more light out than in), and only at the elevations
  where it was;
- the factor is outside the network, so a fit trains f_t as before and the bound is computed
  after it (and after every edit and blend), for any architecture.

The table is fitted on a Monte Carlo estimate: for each of ``ELEVATIONS_PER_INTERVAL`` elevations
per node interval and ``AZIMUTHS`` azimuths (both in :mod:`hybridbrdf.model.sizes`; both albedos,
over wi and over wo, unless the architecture is reciprocal), the contributions f_t cos / pdf of ``samples`` stratified MIS samples
of the material's f_a. k starts at 1 where the estimate allows it; damped multiplicative steps
(k_j <- min(1, k_j sqrt(s_j)), s_j the smallest TARGET / albedo of the directions next to node j)
raise it where the first pass was too cautious, and a last step k_j <- k_j min(1, s_j) makes
every estimated albedo at most TARGET: linear interpolation between two nodes each at most
s_d k gives at most s_d k at d, and lowering k elsewhere only lowers the integral.
"""

from __future__ import annotations

import copy
import math
import os
from typing import Any, Callable, Dict, Optional, Sequence

import numpy as np

from hybridbrdf import spec
from hybridbrdf.brdf.analytic import AnalyticParams, sample
from hybridbrdf.limits import check_count, count_argument
from hybridbrdf.model.sizes import (AZIMUTHS, ELEVATIONS_PER_INTERVAL, HORIZON_COS, SAMPLES,
                                    energy_bytes_per_sample)
from hybridbrdf.files import scratch_folder

#: Largest directional albedo the bound leaves (spec.ENERGY_TARGET: 1 less a margin for the estimate).
TARGET = spec.ENERGY_TARGET
#: Table nodes, at cos theta = j / (NODES - 1).
NODES = spec.ENERGY_NODES
#: Samples per direction of the first look: a material whose largest estimate stays below
#: SCREEN_MARGIN TARGET with them keeps a table of ones without the full estimate (most fitted
#: materials). The first look is noisy where the MIS of f_a samples the correction poorly (one
#: prior material: 0.58 at 512 samples, 0.42 at 4,096), but its largest estimate over ~2,000
#: directions errs upward; bench/energy_bound.py checks the result from outside.
SCREEN_SAMPLES = 512
SCREEN_MARGIN = 0.85
#: Smallest cos theta of the regular elevations: the horizon itself is outside every hemisphere (f = 0 there).
MIN_COS = 0.004
#: Damped steps after the first pass.
ITERATIONS = 24


def nodes() -> np.ndarray:
    """The table's nodes x_j = j / (NODES - 1) in cos theta."""
    return np.arange(NODES, dtype=np.float64) / (NODES - 1)


def scale(table: np.ndarray, cos_theta: np.ndarray) -> np.ndarray:
    """k(cos_theta) of one table (linear between the nodes), float64."""
    return np.interp(np.asarray(cos_theta, dtype=np.float64), nodes(), np.asarray(table, dtype=np.float64))


def _elevations() -> np.ndarray:
    x = np.concatenate([np.arange((NODES - 1) * ELEVATIONS_PER_INTERVAL) / ((NODES - 1) * ELEVATIONS_PER_INTERVAL), [1.0]])
    return np.concatenate([HORIZON_COS, np.maximum(x, MIN_COS)])


def _directions() -> np.ndarray:
    """Every (elevation, azimuth) direction, (n_x * n_phi, 3), grouped by elevation."""
    x = _elevations()[:, None]
    phi = np.radians(np.asarray(AZIMUTHS))[None, :]
    s = np.sqrt(np.maximum(0.0, 1.0 - x * x))
    d = np.stack([s * np.cos(phi), s * np.sin(phi), x * np.ones_like(phi)], axis=-1)
    return d.reshape(-1, 3)


def stratified_u(n: int, seed: int) -> np.ndarray:
    """n 2-D points in [0, 1)^2: one jittered point per cell of an nx x (n // nx) grid (nx about
    sqrt(n)), the n mod nx left over uniform; a fixed seed makes every estimate reproducible
    (the albedo estimates of the energy bound and of model.albedo)."""
    nx = 1 << (int(math.log2(n)) // 2)
    ny = n // nx
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    u = np.stack([(i.ravel() + rng.random(nx * ny)) / nx, (j.ravel() + rng.random(nx * ny)) / ny], axis=-1)
    u = np.concatenate([u, rng.random((n - nx * ny, 2))])
    return np.minimum(u, np.nextafter(1.0, 0.0))


def _contributions(model, material: int, samples: int, seed: int):
    """(c, z, side_x): per direction and side, the samples' f_t cos / pdf (n_dir, samples, 3),
    the sampled directions' cos theta (n_dir, samples), and each direction's cos theta (n_dir,)."""
    fixed = _directions()
    u = stratified_u(samples, seed)
    params = model.analytic_params(material) if model.has_analytic else AnalyticParams()
    strategy = "mis" if model.has_analytic else "cosine"
    # float32, the library's working precision (sample and eval would each convert a float64 copy)
    w_fixed = np.repeat(fixed.astype(np.float32), samples, axis=0)
    w_s, pdf, _ = sample(w_fixed, np.tile(u.astype(np.float32), (len(fixed), 1)), params, strategy)
    ok = pdf > 0
    weight = np.where(ok, np.maximum(w_s[:, 2], 0.0) / np.where(ok, pdf, 1.0), 0.0)[:, None]
    sides = [model.eval(w_s, w_fixed, material)]  # albedo over wi for a fixed wo
    if spec.ARCHS[model.kind]["directions"] != "reciprocal":
        sides.append(model.eval(w_fixed, w_s, material))  # albedo over wo for a fixed wi
    c = np.concatenate([np.maximum(f, 0.0) * weight for f in sides]).reshape(-1, samples, 3)
    z = np.tile(np.where(ok, w_s[:, 2], 0.0), len(sides)).reshape(-1, samples)
    x = np.tile(fixed[:, 2], len(sides))
    return c, z, x


def on_file(model, folder: str, name: str):
    """``model`` itself when it was read from (or saved to) a file, else a copy written to
    ``folder``/``name`` and read back: libhybridbrdf evaluates files, in float32 like every engine,
    tens of times faster than PyTorch on the CPU (a path-less model, as an edit or a fit returns
    it, would be evaluated by PyTorch). ``model`` is not changed (its ``path`` stays None)."""
    if model.path is not None:
        return model
    return copy.copy(model).save_checked(os.path.join(folder, name))


def _node_minimum(values: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Per node j, the smallest of ``values`` over the directions whose cos theta lies in an
    interval next to j (each direction counts for both ends of its interval)."""
    t = x * (NODES - 1)
    lo = np.clip(np.floor(t).astype(int), 0, NODES - 1)
    hi = np.clip(np.ceil(t).astype(int), 0, NODES - 1)
    out = np.full(NODES, np.inf)
    np.minimum.at(out, lo, values)
    np.minimum.at(out, hi, values)
    return out


def moments(c: np.ndarray, z: np.ndarray) -> np.ndarray:
    """M[d, j, rgb] = mean over the samples s of hat_j(z[d, s]) c[d, s, rgb], (n_dir, NODES, 3):
    k(z) = sum_j k_j hat_j(z) (hat_j(x) = max(0, 1 - |(NODES - 1) x - j|), cos theta clamped to
    [0, 1] as :func:`scale` clamps it), so the estimate mean_s(k(z_s) c_s) of the bounded
    integral is sum_j k_j M[d, j] for every table k, exactly: one pass over the samples instead
    of one per table tried."""
    n, samples = z.shape
    t = np.clip(np.asarray(z, dtype=np.float64), 0.0, 1.0) * (NODES - 1)  # the sampler's cos theta is float32
    lo = np.minimum(t.astype(np.intp), NODES - 2)  # t >= 0: truncation is floor; t = NODES - 1 in the last interval
    upper = t - lo  # the weight of node lo + 1; 1 - upper that of node lo
    index = (lo + (np.arange(n, dtype=np.intp) * NODES)[:, None]).ravel()
    del t, lo
    out = np.empty((n * NODES, 3))
    for ch in range(3):
        cc = c[..., ch]
        hi_part = (upper * cc).ravel()
        lo_part = cc.ravel() - hi_part  # (1 - upper) c, rounded once
        out[:, ch] = np.bincount(index, lo_part, n * NODES)
        out[1:, ch] += np.bincount(index, hi_part, n * NODES)[:-1]  # index + 1 < n NODES: lo <= NODES - 2
    return out.reshape(n, NODES, 3) / samples


def _albedo(m: np.ndarray, x: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The estimated albedo (max over RGB) of f = k k f_t per direction, from :func:`moments`."""
    return scale(k, x) * np.einsum("njc,j->nc", m, k).max(axis=1)


def fit_table(c: np.ndarray, z: np.ndarray, x: np.ndarray, target: float = TARGET,
              iterations: int = ITERATIONS) -> np.ndarray:
    """The table (NODES,) from the contributions of :func:`_contributions`: as large as the damped
    steps reach, with every estimated albedo k(x) mean(k(z) c) at most ``target`` (max over RGB)."""
    return fit_table_from_moments(moments(c, z), x, target, iterations)


def fit_table_from_moments(m: np.ndarray, x: np.ndarray, target: float = TARGET,
                           iterations: int = ITERATIONS) -> np.ndarray:
    """:func:`fit_table` from the contributions' :func:`moments` ``m``: each step costs
    O(n_dir NODES), not O(n_dir samples)."""
    def room(k):
        rho = _albedo(m, x, k)
        with np.errstate(divide="ignore"):
            return _node_minimum(np.where(rho > 0, target / rho, np.inf), x)

    k = np.ones(NODES)
    if _albedo(m, x, k).max() <= target:
        return k
    k = np.minimum(1.0, room(k))  # the first, cautious pass: every direction within target
    for _ in range(iterations):
        k = np.minimum(1.0, k * np.sqrt(room(k)))
    k = k * np.minimum(1.0, room(k))  # the last step: within target again
    return k


def tables(model, materials: Optional[Sequence] = None, samples: int = SAMPLES, seed: int = 7,
           progress: Optional[Callable[[], object]] = None) -> Dict[str, Any]:
    """Energy-bound tables of ``model``'s materials (default all), fitted to its unbounded f_t.

    Returns ``{"table": (n, NODES) float32, "max_albedo_unbounded": [...], "max_albedo": [...]}``,
    the maxima being the estimates over the directions used (max over RGB). ``samples`` is
    bounded by memory (:func:`~hybridbrdf.model.sizes.energy_bytes_per_sample`; ValueError naming it). ``progress()`` is called
    after each material (``hbrdf bound``'s progress bar)."""
    samples = count_argument("samples", samples)
    check_count("samples", samples, energy_bytes_per_sample())
    f_t = unbounded(model)
    idx = [model.index(m) for m in (range(len(model.materials)) if materials is None else materials)]
    out = {"table": np.ones((len(idx), NODES), np.float32), "max_albedo_unbounded": [], "max_albedo": []}
    with scratch_folder() as tmp:  # removed on SIGTERM too; after SIGKILL by the next one
        f_t = on_file(f_t, tmp, "unbounded.safetensors")
        for r, i in enumerate(idx):
            c, z, x = _contributions(f_t, i, min(samples, SCREEN_SAMPLES), seed)
            m = moments(c, z)
            del c, z
            if _max_albedo(m, x, np.ones(NODES)) > SCREEN_MARGIN * TARGET and samples > SCREEN_SAMPLES:
                c, z, x = _contributions(f_t, i, samples, seed)
                m = moments(c, z)
                del c, z
            k = fit_table_from_moments(m, x)
            # Rounding to float32 could lift a node by half an ulp: round down, never up.
            k32 = k.astype(np.float32)
            k32 = np.where(k32.astype(np.float64) > k, np.nextafter(k32, np.float32(0)), k32)
            out["table"][r] = k32
            out["max_albedo_unbounded"].append(_max_albedo(m, x, np.ones(NODES)))
            out["max_albedo"].append(_max_albedo(m, x, k32.astype(np.float64)))
            if progress is not None:
                progress()
    return out


def _max_albedo(m, x, k) -> float:
    """The largest estimated directional albedo (max over RGB) of f = k k f_t, from :func:`moments`."""
    return float(_albedo(m, x, k).max())


def attach(model, table: np.ndarray):
    """A copy of ``model`` (unbounded or not) whose materials use the tables ``table`` (M, NODES)."""
    tensors = {k: v for k, v in model.tensors.items() if k != "materials.energy_bound"}
    tensors["materials.energy_bound"] = np.asarray(table, np.float32)
    return type(model)(dict(model.arch, energy_bound="albedo_table"), [dict(m) for m in model.material_info],
                       tensors, dict(model.training) if isinstance(model.training, dict) else {})


def unbounded(model):
    """``model`` with its f_t only: the energy bound removed (the same object if it has none)."""
    if model.arch.get("energy_bound", "none") == "none" and "materials.energy_bound" not in model.tensors:
        return model
    tensors = {k: v for k, v in model.tensors.items() if k != "materials.energy_bound"}
    return type(model)(dict(model.arch, energy_bound="none"), [dict(m) for m in model.material_info], tensors,
                       dict(model.training) if isinstance(model.training, dict) else {})


def with_bound(model, materials: Optional[Sequence] = None, samples: int = SAMPLES,
               progress: Optional[Callable[[], object]] = None):
    """A copy of ``model`` with energy-bound tables (spec/model.json ``albedo_table``): fitted for
    ``materials`` (default all), the others keeping theirs (1 where the model had none). Each
    fitted material's record gains ``energy_bound``: its estimated maximum albedo before and after
    and the table's smallest factor."""
    n = len(model.materials)
    table = (model.tensors["materials.energy_bound"].copy() if "materials.energy_bound" in model.tensors
             else np.ones((n, NODES), np.float32))
    idx = list(range(n)) if materials is None else [model.index(m) for m in materials]
    fitted = tables(model, idx, samples, progress=progress)
    infos = [dict(m) for m in model.material_info]
    for r, i in enumerate(idx):
        table[i] = fitted["table"][r]
        infos[i]["energy_bound"] = {"max_albedo_unbounded": round(fitted["max_albedo_unbounded"][r], 5),
                                    "max_albedo": round(fitted["max_albedo"][r], 5),
                                    "min_factor": round(float(table[i].min()), 5)}
    tensors = dict(model.tensors)
    tensors["materials.energy_bound"] = table
    return type(model)(dict(model.arch, energy_bound="albedo_table"), infos, tensors,
                       dict(model.training) if isinstance(model.training, dict) else {})


__all__ = ["NODES", "TARGET", "attach", "fit_table", "fit_table_from_moments", "moments", "on_file", "scale", "stratified_u", "tables", "unbounded", "with_bound"]
