"""The fallback: a glTF metallic-roughness material fitted to a hybrid material's f_a, for
viewers that do not know the HBRDF_hybrid_material extension (docs/GLTF.md, "The fallback").

The fit starts from the closed-form mapping (:func:`hybridbrdf.gltf.mapping.fa_to_material`) and
minimises, by bounded least squares (scipy's trust-region reflective), the project's fitting
residual ``log(1 + cos(theta_i) f_gltf) - log(1 + cos(theta_i) f_a)`` (docs/CONVENTIONS.md,
"Fitting") over cosine-weighted direction pairs. The fitted material is kept only when it is no
worse than the start on the two metrics together against f_a on separate evaluation pairs (the
mean of SMAPE_fit / SMAPE_start and cMAE_fit / cMAE_start at most 1: :func:`relative_change`);
the report says which was kept.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
from typing import Callable, Optional

import numpy as np
from scipy.optimize import least_squares

from hybridbrdf.brdf.microfacet import fresnel_dielectric, ggx_microfacet
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.evaluate.metrics import cmae, smape
from hybridbrdf.gltf.brdf import GltfMaterial, gltf_eval
from hybridbrdf.gltf.mapping import ALPHA_MIN, fa_to_material

#: Direction pairs the fit's residuals use, and the seed they are drawn with.
FIT_PAIRS = 2048
FIT_SEED = 59
#: Direction pairs of the reported metrics (cosine-weighted, CONVENTIONS' metric pairs' kind).
EVAL_PAIRS = 50_000
EVAL_SEED = 7
#: Function evaluations the least-squares fit may take (10 parameters, 2-point Jacobian; LSMR steps,
#: not an SVD of the Jacobian: threaded BLAS made each SVD 20x slower on a loaded 2-core machine).
MAX_EVALS = 200


def fa_eval(wi: np.ndarray, wo: np.ndarray, kd, eta, alpha) -> np.ndarray:
    """f_a in float64 (docs/CONVENTIONS.md, the package's NumPy microfacet forms), (N, 3)."""
    above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    out = np.zeros((len(wi), 3))
    lobe, c = ggx_microfacet(wi[above], wo[above], float(alpha[0]), float(alpha[1]))
    out[above] = np.asarray(kd)[None, :] / np.pi + fresnel_dielectric(c, np.asarray(eta, dtype=np.float64)) * lobe[:, None]
    return out


def pairs(n: int, seed: int):
    """``n`` cosine-weighted (wi, wo) pairs drawn with ``seed`` (one (u1, u2) row per direction)."""
    rng = np.random.default_rng(seed)
    return cosine_directions(rng, n), cosine_directions(rng, n)


# The fit's parameter vector: baseColor (3), metallic, roughness, dielectric F0 colour d (3, the
# product min(f0(ior) specularColor, 1)), specular, anisotropy strength. d is split into ior and
# specularColor afterwards (ior carries max(d)), as fa_to_material does.
_LOWER = np.array([0, 0, 0, 0, math.sqrt(ALPHA_MIN), 0, 0, 0, 0, 0], dtype=np.float64)
_UPPER = np.array([1, 1, 1, 1, 1, 0.999, 0.999, 0.999, 1, 1], dtype=np.float64)


def _vector(mat: GltfMaterial) -> np.ndarray:
    d = np.minimum(mat.dielectric_f0_scale() * np.asarray(mat.specular_color, dtype=np.float64), 1.0)
    x = np.concatenate([mat.base_color, [mat.metallic, mat.roughness], d, [mat.specular, mat.anisotropy]])
    return np.clip(x.astype(np.float64), _LOWER, _UPPER)


def _material(x: np.ndarray, rotation: float) -> GltfMaterial:
    d = x[5:8]
    level = float(d.max())
    ior = (1.0 + math.sqrt(level)) / (1.0 - math.sqrt(level)) if level > 0 else 1.0
    color = d / level if level > 0 else np.ones(3)
    return GltfMaterial(base_color=tuple(float(v) for v in x[0:3]), metallic=float(x[3]), roughness=float(x[4]),
                        ior=float(ior), specular=float(x[8]), specular_color=tuple(float(v) for v in color),
                        anisotropy=float(x[9]), anisotropy_rotation=rotation)


@dataclass
class FallbackReport:
    """A fitted fallback and its errors: ``metrics[(which, against)] = (SMAPE, cMAE)`` with which
    in ("closed_form", "fitted") and against in ("f_a", "hybrid") ("hybrid" only when a hybrid
    evaluation was given); ``material`` is the one kept (``kept``: "fitted" or "closed_form")."""

    material: GltfMaterial
    start: GltfMaterial
    kept: str
    metrics: dict


def _metrics(f_ref: np.ndarray, f_hat: np.ndarray, cos_i: np.ndarray):
    return smape(f_ref, f_hat), cmae(f_ref, f_hat, cos_i)


def relative_change(new, old) -> float:
    """The mean over SMAPE and cMAE of new / old: <= 1 when ``new`` is no worse than ``old`` on the
    two metrics together (a metric at 0 in ``old`` counts 1 when ``new`` is 0 too, else infinity)."""
    ratios = [n / o if o > 0 else (1.0 if n == 0 else math.inf) for n, o in zip(new, old)]
    return sum(ratios) / len(ratios)


def fit_fallback(kd, eta, alpha, hybrid: Optional[Callable] = None, fit_pairs: int = FIT_PAIRS,
                 eval_pairs: int = EVAL_PAIRS, max_evals: int = MAX_EVALS) -> FallbackReport:
    """The glTF fallback of f_a's (kd, eta, alpha): the closed-form start, then the fit of the
    module docstring. ``hybrid(wi, wo) -> (N, 3)``, when given, is the hybrid material's
    evaluation, against which both materials' errors are reported too."""
    kd, eta, alpha = (np.asarray(v, dtype=np.float64) for v in (kd, eta, alpha))
    start = fa_to_material(kd, eta, alpha)
    rotation = start.anisotropy_rotation
    wi, wo = pairs(fit_pairs, FIT_SEED)
    target = np.log1p(wi[:, 2:3] * fa_eval(wi, wo, kd, eta, alpha))

    def residuals(x):
        f = gltf_eval(wi, wo, _material(x, rotation), alpha_min=ALPHA_MIN)
        return (np.log1p(wi[:, 2:3] * f) - target).ravel()

    x0 = _vector(start)
    result = least_squares(residuals, x0, bounds=(_LOWER, _UPPER), method="trf", max_nfev=max_evals,
                           x_scale="jac", tr_solver="lsmr")
    fitted = _material(result.x, rotation)
    ei, eo = pairs(eval_pairs, EVAL_SEED)
    refs = {"f_a": fa_eval(ei, eo, kd, eta, alpha)}
    if hybrid is not None:
        refs["hybrid"] = np.asarray(hybrid(ei, eo), dtype=np.float64)
    metrics = {}
    for which, mat in (("closed_form", start), ("fitted", fitted)):
        f = gltf_eval(ei, eo, mat, alpha_min=ALPHA_MIN)
        for against, ref in refs.items():
            metrics[(which, against)] = _metrics(ref, f, ei[:, 2])
    better = relative_change(metrics[("fitted", "f_a")], metrics[("closed_form", "f_a")]) <= 1.0
    kept = "fitted" if better else "closed_form"
    return FallbackReport(material=fitted if better else replace(start), start=start, kept=kept, metrics=metrics)
