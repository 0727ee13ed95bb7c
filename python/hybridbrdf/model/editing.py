"""Editing and interpolation of fitted materials (paper Sec. 5.1, "Material Exploration").

The network corrects an analytic base, f_t = f_c + f_g f_a (paper Eq. 1), and its input is
(wi, wo, z) only: the analytic parameters p = (kd, eta, alpha) do not reach it. So an edit of p
changes f_a and keeps the network's correction for that material's z, and a blend of two
materials' (p, z) moves both the base and the correction between theirs. The paper shows both
(figures "Editing the satin-gold BRDF" and "BRDF interpolation") and warns that neither is
guaranteed far from the fitted values; :func:`albedo_profile` and ``bench/edit_guarantees.py``
measure what an edit does to energy and reciprocity.

An edited or blended material is an ordinary row of the model (its analytic parameters and
latent code), so codegen, libhybridbrdf and the tracer treat it as a fitted one. Its record in
the model file says where it came from (``origin`` and ``edit``).

Energy. Because f_c and f_g do not depend on kd and f_a is linear in it, the directional albedo
is linear in kd, rho(wo) = rho_0(wo) + kd rho_1(wo) per channel: ``conserve_energy`` uses that to
scale kd (all channels alike, so the hue stays) to the largest value whose estimated albedo
stays at or below :data:`ALBEDO_TARGET` for every outgoing direction of the grid.
"""

from __future__ import annotations

from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np

from hybridbrdf import spec
from hybridbrdf.brdf.analytic import AnalyticParams, sample
from hybridbrdf.limits import bool_argument, check_count, count_argument, real_argument
from hybridbrdf.model import energy
from hybridbrdf.model.sizes import ALBEDO_PHI_DEG, ALBEDO_THETA_DEG, albedo_bytes_per_sample
from hybridbrdf.names import names_problem
from hybridbrdf.files import scratch_folder

#: Incident samples per outgoing direction (MIS between the cosine and GGX lobes of the
#: material's own f_a, stratified): enough that the estimate's relative standard error stays
#: well inside ALBEDO_TARGET's margin for the shipped prior's materials.
ALBEDO_SAMPLES = 1 << 13
#: What ``conserve_energy`` holds the maximum estimated albedo to: 1 less a margin that covers
#: the estimate's noise (the energy bound's target, spec/model.json).
ALBEDO_TARGET = spec.ENERGY_TARGET


def _check_name(name) -> None:
    if not isinstance(name, str):
        raise TypeError(f"name (the new material's) must be a str, got {type(name).__name__}")


def _lerp(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    """(1 - t) a + t b in float64, rounded once to float32: exactly a at t = 0 and b at t = 1
    (a float32 value is exact in float64, and x * 1 + y * 0 = x)."""
    return ((1.0 - t) * a.astype(np.float64) + t * b.astype(np.float64)).astype(np.float32)


def _shortest(values: np.ndarray) -> list:
    """float32 values as the shortest decimals that read back to them (0.2, not 0.200000003)."""
    return [float(str(np.float32(v))) for v in values]


def _with_material(model, name: str, row: Dict[str, np.ndarray], info: Dict[str, Any]):
    """A new model of ``model``'s class: its materials, then one more with the given tensors.
    (Built through ``type(model)`` so that this module does not import model.file, which
    imports it for ``HybridModel.edit``/``mix``/``albedo``.)"""
    if name in model.materials:
        raise ValueError(f"material '{name}' is already in the model; choose another name")
    problem = names_problem(list(model.materials) + [name])
    if problem:
        raise ValueError(f"new material name '{name}': {problem}")
    tensors = {k: (np.concatenate([v, row[k.split(".", 1)[1]][None].astype(np.float32)])
                   if k.startswith("materials.") else v.copy())
               for k, v in model.tensors.items()}
    materials = [dict(m) for m in model.material_info] + [dict(info, name=name)]
    training = dict(model.training) if isinstance(model.training, dict) else {}
    return type(model)(dict(model.arch), materials, tensors, training)


def _material_row(model, material) -> Dict[str, np.ndarray]:
    i = model.index(material)
    return {k.split(".", 1)[1]: v[i].copy() for k, v in model.tensors.items() if k.startswith("materials.")}


def edit(model, material, name: str, *, kd=None, eta=None, alpha=None, conserve_energy: bool = False):
    """A model holding ``model``'s materials and a new one, ``name``: ``material`` with the given
    analytic parameters replaced (its latent code kept).

    - ``kd``: diffuse albedo, a scalar or 3 values in [0, 1]
    - ``eta``: index of refraction, a scalar or 3 values in [1, 10]
    - ``alpha``: GGX roughness, a scalar (isotropic) or (alpha_x, alpha_y) (anisotropic), in
      [1e-4, 1]
    - ``conserve_energy``: scale the new kd (all channels alike) down until the maximum
      directional albedo (:func:`albedo_profile`) is at most :data:`ALBEDO_TARGET`; raises
      ValueError when even kd = 0 reflects more (lower eta or the correction cannot be removed
      by kd). The kd actually used is recorded in the material's ``edit`` record.

    Raises ValueError (one line) for an out-of-range or NaN value, an unknown material, a taken
    or invalid name, or a model without an analytic part (the neural baseline); TypeError naming
    the argument for one of the wrong type (a name that is not a str, a parameter given as a
    string, a conserve_energy that is not a bool)."""
    _check_name(name)
    bool_argument("conserve_energy", conserve_energy)
    model.index(material)  # KeyError / TypeError before anything else
    if not model.has_analytic:
        raise ValueError("the neural baseline has no analytic parameters to edit (hbrdf mix blends its latent codes)")
    if kd is None and eta is None and alpha is None:
        raise ValueError("an edit needs at least one of kd, eta, alpha")
    old = model.analytic_params(material)
    source = model.materials[model.index(material)]
    new = AnalyticParams(kd=old.kd if kd is None else kd, eta=old.eta if eta is None else eta,
                         alpha=old.alpha if alpha is None else alpha)  # the range checks
    row = _material_row(model, material)
    row.update(kd=new.kd.astype(np.float32), eta=new.eta.astype(np.float32), alpha=new.alpha.astype(np.float32))
    isotropic = bool(row["alpha"][0] == row["alpha"][1])
    record: Dict[str, Any] = {"from": source}
    for key, value in (("kd", kd), ("eta", eta), ("alpha", alpha)):
        if value is not None:
            record[key] = _shortest(row[key])
    info = {"origin": f"edit of {source}", "isotropic": isotropic, "metrics": {}, "edit": record}
    return _add_material(model, name, row, info, record, conserve_energy)


def _add_material(model, name, row, info, record, conserve_energy: bool):
    """``model`` plus the material ``row`` with its energy-bound table fitted
    (:mod:`hybridbrdf.model.energy`: every directional albedo at most its target, whatever the edit);
    with ``conserve_energy``, first its kd scaled (and the scale recorded in ``record``) so that
    its f_t's maximum directional albedo is at most ALBEDO_TARGET where kd can do it."""
    row = {k: v for k, v in row.items() if k != "energy_bound"}  # fitted below, for the new f_t
    unbounded = energy.unbounded(model)
    new = _with_material(unbounded, name, row, info)
    if conserve_energy:
        if "kd" not in row:
            raise ValueError("the neural baseline has no kd to scale: conserve_energy needs a hybrid model")
        dark = _with_material(unbounded, name, dict(row, kd=np.zeros(3, np.float32)), info)
        with scratch_folder() as tmp:  # evaluated by libhybridbrdf, as the energy bound's tables are
            scale = _energy_conserving_kd_scale(energy.on_file(new, tmp, "kd.safetensors"),
                                                energy.on_file(dark, tmp, "dark.safetensors"), name)
        if scale is None:
            record["kd_scaled_for_energy"] = None  # kd cannot do it: the table alone bounds the material
        elif scale < 1.0:
            row = dict(row, kd=(row["kd"].astype(np.float64) * scale).astype(np.float32))
            record["kd"] = _shortest(row["kd"])
            record["kd_scaled_for_energy"] = scale
            new = _with_material(unbounded, name, row, info)
    # The other materials keep their tables (ones where the model had none); the new one's is fitted.
    old = model.tensors.get("materials.energy_bound", np.ones((len(model.materials), energy.NODES), np.float32))
    return energy.with_bound(energy.attach(new, np.concatenate([old, np.ones((1, energy.NODES), np.float32)])), [name])


def mix(model, a, b, t: float, name: str, conserve_energy: bool = False):
    """A model holding ``model``'s materials and a new one, ``name``: the linear blend
    (1 - t) x_a + t x_b of the analytic parameters and latent codes of materials ``a`` and ``b``
    (paper Sec. 5.1, "BRDF interpolation"). t = 0 and t = 1 reproduce ``a`` and ``b`` bit for bit.
    The blend is isotropic when both are. A latent code between two fitted ones can make the
    network's correction brighter than either end (bench/edit_guarantees.py measures how often);
    ``conserve_energy`` then scales the blend's kd as :func:`edit` does. Raises ValueError for t
    outside [0, 1] (or NaN), TypeError for a t that is not a number (a string, a bool) and for
    the other arguments' wrong types as :func:`edit` does."""
    t = real_argument("t", t)
    _check_name(name)
    bool_argument("conserve_energy", conserve_energy)
    if not 0.0 <= t <= 1.0:  # written so that NaN fails
        raise ValueError(f"t = {t!r} is outside [0, 1]: a blend does not extrapolate")
    ra, rb = _material_row(model, a), _material_row(model, b)
    row = {k: _lerp(ra[k], rb[k], t) for k in ra}
    name_a, name_b = model.materials[model.index(a)], model.materials[model.index(b)]
    iso = [model.material_info[model.index(m)].get("isotropic", True) for m in (a, b)]
    isotropic = bool(all(iso)) if "alpha" not in row else bool(row["alpha"][0] == row["alpha"][1])
    record = {"a": name_a, "b": name_b, "t": t}
    info = {"origin": f"mix of {name_a} and {name_b} at t = {t:g}", "isotropic": isotropic, "metrics": {},
            "mix": record}
    return _add_material(model, name, row, info, record, conserve_energy)


# ---- directional albedo --------------------------------------------------------------------------

def _outgoing_grid() -> np.ndarray:
    """The albedo grid's outgoing directions, (len(THETA) * len(PHI), 3)."""
    th = np.radians(np.asarray(ALBEDO_THETA_DEG))[:, None]
    ph = np.radians(np.asarray(ALBEDO_PHI_DEG))[None, :]
    wo = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th) * np.ones_like(ph)], axis=-1)
    return wo.reshape(-1, 3)


def _albedo_samples(model, material, samples: int, seed: int) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Incident directions for every outgoing direction of the grid, drawn by the MIS sampler of
    the material's f_a (cosine sampling for the neural baseline): (wi, wo, pdf), rows grouped
    by outgoing direction."""
    samples = count_argument("samples", samples)
    check_count("samples", samples, albedo_bytes_per_sample(model.bytes_per_pair()))
    wo_grid = _outgoing_grid()
    # float32: the sampler and libhybridbrdf would each convert a float64 copy
    wo = np.repeat(wo_grid.astype(np.float32), samples, axis=0)
    u = np.tile(energy.stratified_u(samples, seed).astype(np.float32), (len(wo_grid), 1))
    if model.has_analytic:
        params, strategy = model.analytic_params(material), "mis"
    else:
        params, strategy = AnalyticParams(), "cosine"
    wi, pdf, _ = sample(wo, u, params, strategy)
    return wi, wo, pdf


def _albedo_estimate(f: np.ndarray, wi: np.ndarray, pdf: np.ndarray, n_wo: int) -> np.ndarray:
    """Mean of f cos(theta_i) / pdf per outgoing direction: (n_wo, 3)."""
    w = np.where(pdf[:, None] > 0, np.maximum(f, 0.0) * np.maximum(wi[:, 2:3], 0.0)
                 / np.where(pdf > 0, pdf, 1.0)[:, None], 0.0)
    return w.reshape(n_wo, -1, 3).mean(axis=1)


def albedo_profile(model, material, samples: int = ALBEDO_SAMPLES, seed: int = 1) -> Dict[str, Any]:
    """Directional albedo rho(wo) = integral of f_t(wi, wo) cos(theta_i) dwi of a material over
    the outgoing grid (:data:`ALBEDO_THETA_DEG` x :data:`ALBEDO_PHI_DEG`), estimated with
    ``samples`` stratified MIS samples of the material's own f_a per direction.

    Returns ``{"theta_deg", "phi_deg", "albedo" (n_wo, 3), "max" (float), "argmax_deg"
    (theta, phi)}``; ``max`` > 1 means the material reflects more light than it receives from
    some direction (an edit can do that; :func:`edit` with ``conserve_energy`` prevents it)."""
    wi, wo, pdf = _albedo_samples(model, material, samples, seed)
    if model.path is None:  # an edit, a blend: libhybridbrdf (float32, the runtime) reads a copy
        with scratch_folder() as tmp:
            f = energy.on_file(model, tmp, "albedo.safetensors").eval(wi, wo, material)
    else:
        f = model.eval(wi, wo, material)
    rho = _albedo_estimate(f, wi, pdf, len(wo) // samples)
    k = int(np.argmax(rho.max(axis=1)))
    theta, phi = np.meshgrid(ALBEDO_THETA_DEG, ALBEDO_PHI_DEG, indexing="ij")
    return {"theta_deg": theta.ravel(), "phi_deg": phi.ravel(), "albedo": rho, "max": float(rho.max()),
            "argmax_deg": (float(theta.ravel()[k]), float(phi.ravel()[k]))}


def _energy_conserving_kd_scale(edited, dark, material) -> Optional[float]:
    """The largest s in [0, 1] with max albedo of (kd -> s kd) <= ALBEDO_TARGET, from the
    albedo's linearity in kd: one sample set, evaluated for the edited material and for the same
    material with kd = 0 (``dark``); None when even kd = 0 reflects more."""
    samples = ALBEDO_SAMPLES
    wi, wo, pdf = _albedo_samples(edited, material, samples, seed=1)
    n_wo = len(wo) // samples
    rho_kd = _albedo_estimate(edited.eval(wi, wo, material), wi, pdf, n_wo)
    rho_0 = _albedo_estimate(dark.eval(wi, wo, material), wi, pdf, n_wo)
    if rho_0.max() > ALBEDO_TARGET:
        return None  # with kd = 0 the specular part and the network's correction alone reflect too much
    diffuse = rho_kd - rho_0  # the kd-proportional part, >= 0 up to rounding
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(diffuse > 1e-9, (ALBEDO_TARGET - rho_0) / diffuse, np.inf)
    return float(min(1.0, room.min()))


def parse_assignments(items: Sequence[str]) -> Dict[str, Any]:
    """``["kd=0.8,0.2,0.1", "alpha=0.3"]`` -> ``{"kd": [0.8, 0.2, 0.1], "alpha": 0.3}`` (the
    ``hbrdf edit --set`` syntax). Raises ValueError naming the item for an unknown key, a
    repeated key or a value that is not 1, 2 or 3 numbers."""
    out: Dict[str, Any] = {}
    sizes = {"kd": (1, 3), "eta": (1, 3), "alpha": (1, 2)}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in sizes:
            raise ValueError(f"--set {item!r}: expected kd=..., eta=... or alpha=... (comma-separated numbers)")
        if key in out:
            raise ValueError(f"--set {key} given twice")
        try:
            numbers = [float(v) for v in value.split(",")]
        except ValueError:
            raise ValueError(f"--set {item!r}: {value!r} is not a comma-separated list of numbers") from None
        if len(numbers) not in sizes[key]:
            raise ValueError(f"--set {item!r}: {key} takes " + " or ".join(str(n) for n in sizes[key]) + " numbers")
        out[key] = numbers[0] if len(numbers) == 1 else numbers
    return out


__all__ = ["ALBEDO_SAMPLES", "ALBEDO_TARGET", "albedo_profile", "edit", "mix",
           "parse_assignments"]
