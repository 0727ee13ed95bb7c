"""The analytic BRDF f_a through the C++ library: parameters, evaluation, sampling.

All functions take and return NumPy arrays in the local shading frame
(normal +z, tangent +x along alpha_x), ``wi`` toward the light and ``wo``
toward the viewer. Arrays are converted to C-contiguous float32, the
library's working precision. Directions need not be unit length; zero-length,
NaN/Inf and below-horizon directions give 0 (see docs/CONVENTIONS.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Tuple, Union

import numpy as np

from hybridbrdf import _core
from hybridbrdf.limits import pair_arguments

#: Peak bytes per direction pair of analytic_eval / sample / pdf (float32 copies of the inputs,
#: the outputs), measured at 36 plus margin: what a call's row count is bounded by.
BYTES_PER_PAIR = 64

ArrayLike = Union[np.ndarray, "object"]


def _vector(value, n: int, name: str) -> np.ndarray:
    """`value` as a float64 vector of n entries; a scalar is broadcast. Strings and booleans are
    refused (TypeError naming the parameter): NumPy would read "0.5" as 0.5 and True as 1."""
    probe = np.asarray(value) if not isinstance(value, (str, bytes)) else None
    if probe is None or probe.dtype.kind not in "iuf":
        raise TypeError(f"{name} must be a number or {n} numbers, got {type(value).__name__} {value!r:.60}"
                        .replace("\n", " "))
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"{name} must be a scalar or have {n} entries, got shape {arr.shape}")
    return arr


def _check_range(arr: np.ndarray, lo: float, hi: float, name: str) -> None:
    # Compared in float32, as the model contract and both loaders compare (spec MATERIAL_RANGES):
    # a material stored at ALPHA_MIN holds float32(1e-4) = 9.99999975e-05, below the float64 bound.
    lo32, hi32 = np.float32(lo), np.float32(hi)
    for i, v in enumerate(arr):
        if not (lo32 <= np.float32(v) <= hi32):  # written so that NaN fails
            raise ValueError(f"{name}[{i}] = {float(v)!r} is outside [{lo:g}, {hi:g}]")


@dataclass(frozen=True)
class AnalyticParams:
    """Parameters p = (kd, eta, alpha) of f_a, checked on construction.

    - ``kd``: diffuse albedo, a scalar or 3 values in [0, 1]
    - ``eta``: real index of refraction, a scalar or 3 values in [1, 10]
    - ``alpha``: GGX roughness, a scalar (isotropic) or (alpha_x, alpha_y),
      each in [ALPHA_MIN, 1] = [1e-4, 1]

    Raises ``ValueError`` naming the first value out of range (or NaN).
    Stored as float64 arrays; the C++ library evaluates in float32.
    """

    kd: np.ndarray
    eta: np.ndarray
    alpha: np.ndarray

    def __init__(self, kd=0.5, eta=1.5, alpha=0.3):
        kd_v = _vector(kd, 3, "kd")
        eta_v = _vector(eta, 3, "eta")
        alpha_v = _vector(alpha, 2, "alpha")
        _check_range(kd_v, 0.0, 1.0, "kd")
        _check_range(eta_v, _core.ETA_MIN, _core.ETA_MAX, "eta")
        _check_range(alpha_v, _core.ALPHA_MIN, _core.ALPHA_MAX, "alpha")
        for name, v in (("kd", kd_v), ("eta", eta_v), ("alpha", alpha_v)):
            v.setflags(write=False)
            object.__setattr__(self, name, v)

    @property
    def isotropic(self) -> bool:
        """True when alpha_x == alpha_y (7 parameters instead of 8)."""
        return bool(self.alpha[0] == self.alpha[1])

    def to_core(self) -> "_core.AnalyticParams":
        """The float32 parameter struct of the C++ library."""
        return _core.AnalyticParams(self.kd.tolist(), self.eta.tolist(), self.alpha.tolist())

    def as_dict(self) -> dict:
        """Plain lists, for JSON."""
        return {"kd": self.kd.tolist(), "eta": self.eta.tolist(), "alpha": self.alpha.tolist()}

    def __repr__(self) -> str:
        return f"AnalyticParams(kd={self.kd.tolist()}, eta={self.eta.tolist()}, alpha={self.alpha.tolist()})"


def _rows(names, values, cols) -> list:
    """The row arrays of one call, checked (types, shapes, rows bounded by memory; hybridbrdf.limits)
    before they are copied to C-contiguous float32, the library's working precision."""
    return [np.ascontiguousarray(a, dtype=np.float32) for a in pair_arguments(names, values, cols, BYTES_PER_PAIR)]


def _strategy(strategy) -> str:
    if not isinstance(strategy, str):
        raise TypeError(f"strategy must be a str (one of {', '.join(_core.STRATEGIES)}), got {type(strategy).__name__}")
    return strategy


def _core_params(params) -> "_core.AnalyticParams":
    if isinstance(params, AnalyticParams):
        return params.to_core()
    if isinstance(params, _core.AnalyticParams):
        return params
    raise TypeError(f"params must be hybridbrdf.AnalyticParams, got {type(params).__name__}")


def analytic_eval(wi, wo, params: AnalyticParams) -> np.ndarray:
    """f_a(wi, wo) for (N,3) direction arrays; returns (N,3) float32 RGB, no cosine."""
    wi_a, wo_a = _rows(("wi", "wo"), (wi, wo), (3, 3))
    return _core.eval_analytic(wi_a, wo_a, _core_params(params))


def sample(wo, u, params: AnalyticParams, strategy: str = "mis") -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Importance-sample wi for each wo.

    ``u`` holds two uniform numbers per row, shape (N,2), in [0,1) (clamped).
    ``strategy`` (one of :data:`hybridbrdf.STRATEGIES`, the library's names; others raise
    ``ValueError``): ``"cosine"`` (cosine-weighted hemisphere), ``"ggx"`` (GGX
    visible normals, Dupuy & Benyoub 2023) or ``"mis"`` (one-sample mixture of
    both; the GGX lobe is picked with probability
    clamp(Fs / (Fs + Kd), 0.1, 0.9), Fs = mean Fresnel at wo, Kd = mean kd).

    Returns ``(wi (N,3), pdf (N,), weight (N,3))``: the solid-angle pdf and
    ``f * max(wi.z, 0) / pdf``. A row with pdf 0 is "no sample" (wo invalid or
    below the horizon); a GGX sample below the horizon has weight 0.
    """
    wo_a, u_a = _rows(("wo", "u"), (wo, u), (3, 2))
    return _core.sample(wo_a, u_a, _core_params(params), _strategy(strategy))  # ValueError for unknown names


def pdf(wi, wo, params: AnalyticParams, strategy: str = "mis") -> np.ndarray:
    """Solid-angle density with which ``sample(wo, ..., strategy)`` produces wi, (N,)."""
    wi_a, wo_a = _rows(("wi", "wo"), (wi, wo), (3, 3))
    return _core.pdf(wi_a, wo_a, _core_params(params), _strategy(strategy))


def simd_path() -> str:
    """Instruction set of the C++ batched kernels on this CPU: 'avx2+fma' or 'baseline'."""
    return _core.simd_path()
