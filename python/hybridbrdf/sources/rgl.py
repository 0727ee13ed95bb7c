"""Reader for RGL measured BRDFs: Mitsuba 3 ``tensor_file`` ``.bsdf`` files
(Dupuy & Jakob 2018, "An Adaptive Parameterization for Efficient Material
Acquisition and Rendering", ACM TOG 37(6)).

    src = open_rgl("../shared/data/rgl/paper_white_rgb.bsdf")
    f = src.eval(wi, wo)          # (N,3) RGB, no cosine

File layout: a ``tensor_file`` v1.0 (:mod:`hybridbrdf.sources.tensor_file` reads it); the tables
are interpolated as Mitsuba's ``Marginal2D`` (:mod:`hybridbrdf.sources.rgl_warp`).

Fields of an RGB file (n_phi x n_theta incident directions, tables of N x N):

    version      u32 (2,)          RGL format version, 1.0
    description  u8  (k,)          material name, UTF-8
    phi_i        f32 (n_phi,)      azimuths of the measured incident directions
    theta_i      f32 (n_theta,)    elevations of the measured incident directions
    ndf          f32 (a, b)        microfacet NDF D(m): rows phi_m, columns theta_m (unit coordinates)
    sigma        f32 (c, d)        projected microfacet area sigma(w_in): rows phi_i, columns theta_i
    vndf         f32 (n_phi, n_theta, H, W)   visible NDF per incident direction
    luminance    f32 (n_phi, n_theta, N, N)   luminance, for importance sampling
    rgb          f32 (n_phi, n_theta, 3, N, N) reflectance in the warped domain
    jacobian     u8  (1,)          1: rgb is divided by the warp's Jacobian
    valid        u8  (N*N,)        which samples were measured (not used to evaluate)

Evaluation (the math of Mitsuba 3's ``measured`` plugin, redone in float64
NumPy). Let ``w_in`` be the direction the file's theta_i/phi_i describe (the
viewer: our ``wo``) and ``w_out`` the other one (the light: our ``wi``);
see docs/CONVENTIONS.md, "RGL .bsdf files".

1. Half vector ``m = normalize(w_in + w_out)``; spherical angles of ``w_in``
   and ``m`` (elevation ``2 asin(|w - n| / 2)`` with n the normal: stable
   near the pole, where acos is not).
2. Angles go to unit coordinates: ``u = sqrt(theta / (pi/2))`` (the
   square-root elevation mapping concentrates samples near the pole) and
   ``v = (phi + pi) / (2 pi)``; for files with at most 2 phi_i values the
   half vector's azimuth is taken relative to ``phi_i`` and wrapped into [0, 1).
3. The VNDF of the incident direction, a continuous 2D distribution (bilinear
   interpolant of ``vndf``, linearly interpolated in phi_i and theta_i), maps
   the half vector ``(u_m, v_m)`` to the unit square: its inverse
   marginal/conditional CDF warp (Mitsuba's ``Marginal2D<.., true>::invert``).
   This is the adaptive parameterisation: the rgb table is regular in that
   warped square, so the samples crowd where the VNDF is large.
4. ``rgb`` is interpolated bilinearly at the warped position (and linearly in
   phi_i, theta_i); with ``jacobian == 1`` it is multiplied by
   ``ndf(u_m, v_m) / (4 sigma(u_i, v_i))``. That gives Mitsuba's value, which
   holds the cosine of ``w_out``; ``f`` is that value divided by ``w_out.z``.

Anisotropic files (more than 2 phi_i values) whose phi_i cover a half or a
quarter of the circle are folded by symmetry first, as Mitsuba does.

Files with at most 2 phi_i values use the azimuth of the half vector relative
to phi_i (Mitsuba's switch). For them Mitsuba's source leaves the fold
(``m_reduction``) unset; the Mitsuba 3.9 binary behaves as if it were 2,
i.e. it rotates the pair by 180 degrees when phi_i > 0. That changes nothing
when sigma (and, with 2 azimuths, vndf and rgb) do not depend on phi_i, as in
every RGL file (the two sigma rows are identical), so this reader follows the
source and does not fold; files whose sigma varies with phi_i would differ.

Negative values: measured rgb entries are sometimes slightly negative
(measurement noise; 26% of the entries of cg_sunflower_rgb). The data are kept
as they are and :meth:`eval` returns the interpolated value, which may then be
negative; Mitsuba 3 does the same (it does not clamp). The project's metrics
clamp both sides to 0 (docs/CONVENTIONS.md).

Agreement with Mitsuba 3.9 (``scalar_rgb``, ``measured``): SMAPE on 10^5
cosine-weighted pairs (seed 7), negatives clamped to 0 first, measured by
tests/python/test_sources_rgl.py:

    cc_ibiza_sunset_rgb      1.8e-6
    cg_sunflower_rgb         6.5e-7
    colodur_napoli_4f_rgb    3.3e-7
    paper_white_rgb          4.2e-7
    vch_golden_yellow_rgb    7.1e-7

The residual is float32 (Mitsuba) against float64 (here) rounding: Mitsuba
stores the normalised VNDF tables and their CDFs in float32 and evaluates in
float32, so the warped position differs in the 6th-7th digit. The median
relative difference per value is below 1e-6; it is larger (up to ~1e-2) only
where the value is near 0, e.g. where interpolated rgb crosses 0.
"""

from __future__ import annotations

import os
from typing import Dict, Optional, Tuple

import numpy as np

from hybridbrdf.sources.base import BRDFFormatError, BRDFSource
from hybridbrdf.sources.rgl_warp import ContinuousMarginal2D, Slices, bilinear, grid_cell, lerp
from hybridbrdf.sources.tensor_file import read_tensor_file

#: The RGL format version held in the ``version`` field.
RGL_VERSION = (1, 0)

_F32 = np.dtype("<f4")
_U8 = np.dtype("<u1")
_U32 = np.dtype("<u4")

ORIGIN = "RGL measurement (raw .bsdf)"


# ----------------------------------------------------------------------------
# the source
# ----------------------------------------------------------------------------


def _theta2u(theta):
    """Elevation -> unit coordinate of the tables: sqrt(theta / (pi/2))."""
    return np.sqrt(theta * (2.0 / np.pi))


def _phi2u(phi):
    """Azimuth in [-pi, pi] -> unit coordinate (phi + pi) / (2 pi)."""
    return (phi + np.pi) * (0.5 / np.pi)


def _elevation(d: np.ndarray) -> np.ndarray:
    """theta = acos(d.z) for unit d, computed as 2 asin(|d - n|/2) (n the normal): accurate
    near the pole, where acos loses half the digits."""
    dist = np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + (d[:, 2] - 1.0) ** 2)
    return 2.0 * np.arcsin(np.minimum(0.5 * dist, 1.0))


def _mulsign_neg(a: np.ndarray, s: np.ndarray) -> np.ndarray:
    """a * -sign(s), with the sign taken from the sign bit (as Dr.Jit does)."""
    return np.where(np.signbit(s), a, -a)


class RGLSource(BRDFSource):
    """An RGL measured BRDF read from a ``.bsdf`` file; see the module docstring.

    Besides the :class:`BRDFSource` attributes: ``description`` (the file's
    material description), ``jacobian`` (the file's flag), ``phi_i`` and
    ``theta_i`` (the measured incident directions, radians), ``resolution``
    (N of the N x N rgb tables) and ``valid`` (the file's mask of measured
    samples, or None)."""

    origin = ORIGIN

    def __init__(self, path, fields: Dict[str, np.ndarray]):
        self.path = os.fspath(path)
        self.name = os.path.splitext(os.path.basename(self.path))[0]
        t = _validate(self.path, fields)
        self.description = t["description"]
        self.jacobian = t["jacobian"]
        self.phi_i = t["phi_i"]
        self.theta_i = t["theta_i"]
        self.resolution = t["rgb"].shape[-1]
        self.valid = t["valid"]
        n_phi, n_theta = len(self.phi_i), len(self.theta_i)
        # The attribute means "f depends on phi_i - phi_o only": one measured azimuth.
        self.isotropic = n_phi == 1
        # Mitsuba's parameterisation switch: with at most 2 azimuths the half
        # vector's azimuth is stored relative to phi_i.
        self._relative_phi = n_phi <= 2
        # Mitsuba folds anisotropic data measured over a half (2) or a quarter
        # (4) of the circle by symmetry.
        self._reduction = 0
        if not self._relative_phi:
            self._reduction = int(np.rint(2.0 * np.pi / (float(self.phi_i[-1]) - float(self.phi_i[0]))))
        self._ndf = t["ndf"].astype(np.float64)
        self._sigma = t["sigma"].astype(np.float64)
        vndf = t["vndf"].astype(np.float64)
        self._vndf = ContinuousMarginal2D(vndf.reshape(n_phi * n_theta, *vndf.shape[2:]))
        rgb = t["rgb"].astype(np.float64)  # (n_phi, n_theta, 3, N, N)
        n = rgb.shape[-1]
        # (slices, N*N, 3): one gather per corner fetches all three channels.
        self._rgb = np.ascontiguousarray(rgb.reshape(n_phi * n_theta, 3, n * n).transpose(0, 2, 1))
        self._phi_values = self.phi_i.astype(np.float64)
        self._theta_values = self.theta_i.astype(np.float64)

    def _eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f for unit directions above the horizon; see the module docstring.

        The file's incident direction is the viewer (our ``wo``); Mitsuba's
        value holds the cosine of the light direction (our ``wi``), which is
        divided out at the end."""
        w_in = wo.copy()
        w_out = wi.copy()
        cos_out = wi[:, 2].copy()

        if self._reduction >= 2:
            # Fold w_in into the measured range of azimuths; w_out follows.
            sy = w_in[:, 1].copy()
            sx = w_in[:, 0].copy() if self._reduction == 4 else sy
            for w in (w_in, w_out):
                w[:, 0] = _mulsign_neg(w[:, 0], sx)
                w[:, 1] = _mulsign_neg(w[:, 1], sy)

        m = w_in + w_out
        m /= np.sqrt((m * m).sum(axis=1))[:, None]  # |w_in + w_out| > 0: both above the horizon

        theta_i = _elevation(w_in)
        phi_i = np.arctan2(w_in[:, 1], w_in[:, 0])
        theta_m = _elevation(m)
        phi_m = np.arctan2(m[:, 1], m[:, 0])

        u_i, v_i = _theta2u(theta_i), _phi2u(phi_i)
        u_m = _theta2u(theta_m)
        v_m = _phi2u(phi_m - phi_i if self._relative_phi else phi_m)
        v_m = v_m - np.floor(v_m)

        sl = Slices(self._phi_values, self._theta_values, phi_i, theta_i)
        x, y = self._vndf.invert(u_m, v_m, sl)

        # rgb: bilinear in the warped square, linear in (phi_i, theta_i).
        n = self.resolution
        col, fx = grid_cell(x, n)
        row, fy = grid_cell(y, n)
        base = row * n + col
        fx, fy = fx[:, None], fy[:, None]
        top = lerp(sl.gather(self._rgb, base), sl.gather(self._rgb, base + 1), fx)
        bottom = lerp(sl.gather(self._rgb, base + n), sl.gather(self._rgb, base + n + 1), fx)
        value = lerp(top, bottom, fy)

        if self.jacobian:
            # The table was divided by the warp's Jacobian; undo it: D(m) / (4 sigma(w_in)).
            value = value * (bilinear(self._ndf, u_m, v_m) / (4.0 * bilinear(self._sigma, u_i, v_i)))[:, None]
        return value / cos_out[:, None]


#: The float32 tables of an RGL RGB file and their ranks, in the order they are checked.
_TABLES = (("phi_i", 1), ("theta_i", 1), ("sigma", 2), ("ndf", 2), ("vndf", 4), ("luminance", 4), ("rgb", 5))
_REQUIRED = ("version", "description", "phi_i", "theta_i", "sigma", "ndf", "vndf", "luminance", "rgb", "jacobian")


def _validate(path: str, fields: Dict[str, np.ndarray]) -> Dict[str, object]:
    """Check the fields of an RGL RGB file and return them (``description`` as
    str, ``jacobian`` as bool, ``valid`` as array or None). Raises
    BRDFFormatError naming the file and the problem."""
    _check_present(path, fields)
    t = _read_header_fields(path, fields)
    t.update({name: _field(path, fields, name, _F32, ndim) for name, ndim in _TABLES})
    _check_table_shapes(path, t)
    t["valid"] = _read_valid(path, fields, t["rgb"].shape[-1])
    _check_table_values(path, t)
    return t


def _check_present(path: str, fields: Dict[str, np.ndarray]) -> None:
    """An RGB (not spectral) file with every required field."""
    if "rgb" not in fields and ("spectra" in fields or "wavelengths" in fields):
        raise BRDFFormatError(path, "spectral RGL file (fields 'spectra' and 'wavelengths'); this reader reads the "
                                    "RGB variant (*_rgb.bsdf)")
    for name in _REQUIRED:
        if name not in fields:
            raise BRDFFormatError(path, f"missing field {name!r} (the file has: "
                                        f"{', '.join(sorted(fields)) or 'no fields'})")


def _field(path: str, fields: Dict[str, np.ndarray], name: str, dtype: np.dtype, ndim: int) -> np.ndarray:
    """Field ``name``, checked to have ``dtype`` and rank ``ndim``."""
    arr = fields[name]
    if arr.dtype != dtype:
        raise BRDFFormatError(path, f"field {name!r} has dtype {arr.dtype.name}, expected {dtype.name}")
    if arr.ndim != ndim:
        raise BRDFFormatError(path, f"field {name!r} has shape {arr.shape} (rank {arr.ndim}), expected rank {ndim}")
    return arr


def _expect_shape(path: str, name: str, arr: np.ndarray, shape: Tuple[int, ...]) -> None:
    if arr.shape != shape:
        raise BRDFFormatError(path, f"field {name!r} has shape {arr.shape}, expected {shape}")


def _read_header_fields(path: str, fields: Dict[str, np.ndarray]) -> Dict[str, object]:
    """``description`` (str) and ``jacobian`` (bool), after the RGL format version."""
    version = _field(path, fields, "version", _U32, 1)
    _expect_shape(path, "version", version, (2,))
    if tuple(int(v) for v in version) != RGL_VERSION:
        raise BRDFFormatError(path, f"unsupported RGL format version {version[0]}.{version[1]} "
                                    f"(this reader reads 1.0)")
    description = bytes(_field(path, fields, "description", _U8, 1)).decode("utf-8", errors="replace")
    jacobian = _field(path, fields, "jacobian", _U8, 1)
    _expect_shape(path, "jacobian", jacobian, (1,))
    return dict(description=description, jacobian=bool(jacobian[0]))


def _check_table_shapes(path: str, t: Dict[str, object]) -> None:
    """The tables' extents agree: n_phi x n_theta incident directions, N x N rgb tables."""
    def fail(problem: str):
        raise BRDFFormatError(path, problem)

    n_phi, n_theta = len(t["phi_i"]), len(t["theta_i"])
    if n_phi < 1 or n_theta < 1:
        fail(f"fields 'phi_i' and 'theta_i' must not be empty (they hold {n_phi} and {n_theta} values)")
    for name in ("sigma", "ndf"):
        if min(t[name].shape) < 2:
            fail(f"field {name!r} has shape {t[name].shape}, expected at least 2 x 2")
    vndf, rgb = t["vndf"], t["rgb"]
    if vndf.shape[:2] != (n_phi, n_theta) or min(vndf.shape[2:]) < 2:
        fail(f"field 'vndf' has shape {vndf.shape}, expected ({n_phi}, {n_theta}, H >= 2, W >= 2) "
             f"for {n_phi} phi_i and {n_theta} theta_i")
    n = rgb.shape[-1]
    if rgb.shape[:3] != (n_phi, n_theta, 3) or rgb.shape[3] != n or n < 2:
        fail(f"field 'rgb' has shape {rgb.shape}, expected ({n_phi}, {n_theta}, 3, N, N) with N >= 2 "
             f"for {n_phi} phi_i and {n_theta} theta_i")
    _expect_shape(path, "luminance", t["luminance"], (n_phi, n_theta, n, n))


def _read_valid(path: str, fields: Dict[str, np.ndarray], n: int) -> Optional[np.ndarray]:
    """The optional mask of measured samples as an N x N bool array, or None."""
    valid = fields.get("valid")
    if valid is None:
        return None
    if valid.dtype != _U8 or valid.size != n * n:
        raise BRDFFormatError(path, f"field 'valid' has dtype {valid.dtype.name} and shape {valid.shape}, "
                                    f"expected uint8 with {n * n} entries")
    return valid.reshape(n, n) != 0


def _check_table_values(path: str, t: Dict[str, object]) -> None:
    """Finite tables, increasing angles, non-negative densities with a normalisable warp for every
    incident direction, and (with the Jacobian flag) a positive divisor sigma."""
    def fail(problem: str):
        raise BRDFFormatError(path, problem)

    for name, _ in _TABLES:
        bad = int(np.count_nonzero(~np.isfinite(t[name])))
        if bad:
            fail(f"field {name!r} holds {bad} NaN or infinite value{'s' if bad > 1 else ''}")
    for name in ("phi_i", "theta_i"):
        if np.any(np.diff(t[name].astype(np.float64)) <= 0):
            fail(f"field {name!r} must be strictly increasing, got {t[name].tolist()}")
    vndf, n_theta = t["vndf"], len(t["theta_i"])
    if np.any(vndf < 0) or np.any(t["ndf"] < 0):
        fail("fields 'vndf' and 'ndf' are densities and must not be negative")
    vndf_mass = vndf.reshape(len(t["phi_i"]) * n_theta, -1).astype(np.float64).sum(axis=1)
    if np.any(vndf_mass <= 0):
        k = int(np.argmin(vndf_mass))
        fail(f"field 'vndf' is zero for incident direction #{k} (phi_i {k // n_theta}, theta_i {k % n_theta}); "
             "its warp cannot be normalised")
    if t["jacobian"] and np.any(t["sigma"] <= 0):
        fail("field 'sigma' (projected area, a divisor) must be positive")


def open_rgl(path) -> RGLSource:
    """Open an RGL ``.bsdf`` (RGB tensor_file) as a :class:`BRDFSource`.

    Raises :class:`BRDFFormatError` ("<path>: <problem>") for a missing,
    truncated or malformed file."""
    return RGLSource(path, read_tensor_file(path))


__all__ = ["ORIGIN", "RGLSource", "open_rgl"]
