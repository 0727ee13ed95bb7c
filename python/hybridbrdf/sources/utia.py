"""UTIA anisotropic BRDF ``.bin`` files (Filip & Vavra, "Template-Based
Sampling of Anisotropic BRDFs", Pacific Graphics 2014; btf.utia.cas.cz).

File layout: 3 * 6 * 48 * 6 * 48 = 248,832 float64 values (1,990,656 bytes,
little-endian, no header), a C-order array of shape

    (3, 6, 48, 6, 48) = (channel RGB, theta_i, phi_i, theta_v, phi_v)

that is, **channel-major**: the whole R table, then G, then B; within a
channel the illumination angles come first (theta_i slowest), then the view
angles (phi_v fastest). The flat index of (c, ti, pi, tv, pv) is
``c*nr*nc + nc*(48*ti + pi) + 48*tv + pv`` with nr = 6*48 (illumination
rows) and nc = 6*48 (view columns): the layout of the reference code
(Filip's TBRDF.cpp, as adapted in ALTA's data_utia plugin, and Sztrajman's
UTIA-brdf reader). Some descriptions list the shape as 6 x 48 x 6 x 48 x 3;
the published readers index the channel slowest, and so does this module.

Angles: theta_i = 15 * ti degrees (0..75), phi_i = 7.5 * pi degrees
(0..352.5), the same for theta_v, phi_v. Index "i" is the illumination
(light) direction, our ``wi``; "v" is the view direction, our ``wo``; both
point away from the surface and are spherical coordinates in the local frame
(phi measured from +x, the tangent, toward +y). The specular reflection of
(theta_i, phi_i) is (theta_i, phi_i + 180). Values are the BRDF (no cosine)
as stored, RGB; they are returned unchanged: no scale and no colour transfer
function. (One third-party reader decodes the values as sRGB-encoded; the
reference code and Sztrajman's reader use them as linear, as here.)

Interpolation: quadrilinear in (theta_i, phi_i, theta_v, phi_v) degrees, as
the reference code does, periodic in both phi. Past the last elevation node
(75 degrees) the reference extrapolates the last interval linearly; that can
turn a falling specular lobe negative at grazing angles, so the default
here is ``theta_beyond="clamp"`` (the 75-degree values are held up to 90);
``theta_beyond="extrapolate"`` reproduces the reference.

Missing data: the format has no missing marker. Values are returned as
stored, including any slightly negative measurement noise (metrics clamp it);
NaN or Inf in a file is an error.
"""

from __future__ import annotations

import os
from typing import Callable, Optional, Union

import numpy as np

from hybridbrdf.sources.base import (BRDFSource, check_choice, check_file_size, check_finite_table,
                                     read_file_bytes, source_name, table_array)
from hybridbrdf.files import atomic_write_bytes

N_THETA = 6
N_PHI = 48
THETA_STEP_DEG = 15.0
PHI_STEP_DEG = 7.5
N_PLANES = 3
#: Shape of the array in the file: (channel, theta_i, phi_i, theta_v, phi_v).
FILE_SHAPE = (N_PLANES, N_THETA, N_PHI, N_THETA, N_PHI)
#: Shape of the tables this module hands out and takes: (theta_i, phi_i, theta_v, phi_v, RGB).
TABLE_SHAPE = (N_THETA, N_PHI, N_THETA, N_PHI, N_PLANES)
N_VALUES = int(np.prod(FILE_SHAPE))
FILE_BYTES = N_VALUES * 8
THETA_BEYOND = ("clamp", "extrapolate")

_RAD2DEG = 180.0 / np.pi


def utia_node_angles():
    """(theta, phi) node angles in degrees: 6 elevations 0..75 and 48 azimuths
    0..352.5, shared by illumination and view."""
    return np.arange(N_THETA) * THETA_STEP_DEG, np.arange(N_PHI) * PHI_STEP_DEG


def _spherical_deg(w: np.ndarray):
    """(theta, phi) in degrees of unit (N,3) directions; phi in [0, 360)."""
    theta = np.arctan2(np.hypot(w[:, 0], w[:, 1]), w[:, 2]) * _RAD2DEG
    phi = np.mod(np.arctan2(w[:, 1], w[:, 0]) * _RAD2DEG, 360.0)
    return theta, phi


def _direction_deg(theta_deg, phi_deg) -> np.ndarray:
    t = np.radians(theta_deg)
    p = np.radians(phi_deg)
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)


def utia_grid_directions():
    """(wi, wo), each (6*48*6*48, 3), of every node in (theta_i, phi_i,
    theta_v, phi_v) C order (the order of :data:`TABLE_SHAPE`)."""
    th, ph = utia_node_angles()
    TI, PI, TV, PV = np.meshgrid(th, ph, th, ph, indexing="ij")
    return _direction_deg(TI.ravel(), PI.ravel()), _direction_deg(TV.ravel(), PV.ravel())


def read_utia_table(path) -> np.ndarray:
    """A UTIA file as a (6, 48, 6, 48, 3) float64 table indexed (theta_i, phi_i,
    theta_v, phi_v, RGB). Raises :class:`BRDFFormatError` for an unreadable
    file, a wrong size or non-finite values."""
    spec = os.fspath(path)
    data = read_file_bytes(spec, "UTIA", FILE_BYTES)  # the format has one size
    check_file_size(spec, data, "UTIA", FILE_BYTES, "3 x 6x48x6x48 float64")
    raw = np.frombuffer(data, dtype="<f8").reshape(FILE_SHAPE)
    check_finite_table(spec, raw, "UTIA", lambda c, ti, pi, tv, pv: (
        f"channel {'RGB'[c]}, theta_i {ti * THETA_STEP_DEG:g}, phi_i {pi * PHI_STEP_DEG:g}, "
        f"theta_v {tv * THETA_STEP_DEG:g}, phi_v {pv * PHI_STEP_DEG:g} degrees"))
    return np.moveaxis(raw, 0, -1).astype(np.float64)


class UTIASource(BRDFSource):
    """A UTIA table behind the :class:`BRDFSource` interface (conventions and
    interpolation in the module docstring)."""

    isotropic = False

    def __init__(self, table: np.ndarray, path: Optional[str] = None, name: Optional[str] = None,
                 theta_beyond: str = "clamp", origin: str = "UTIA measurement (raw .bin)"):
        """``table``: (6, 48, 6, 48, 3) f values indexed (theta_i, phi_i, theta_v, phi_v, RGB)."""
        check_choice("theta_beyond", theta_beyond, THETA_BEYOND)
        table = table_array(table, TABLE_SHAPE, "UTIA")
        self.path = path
        self.name = source_name(name, path, "utia")
        self.origin = origin
        self.theta_beyond = theta_beyond
        self._flat = np.ascontiguousarray(table.reshape(-1, N_PLANES))

    def _theta_corners(self, theta_deg):
        t = theta_deg / THETA_STEP_DEG
        if self.theta_beyond == "clamp":
            t = np.minimum(t, N_THETA - 1)
        # Past the last node the last interval is used (its weight exceeds 1 when extrapolating).
        i0 = np.minimum(np.floor(t), N_THETA - 2).astype(np.intp)
        return i0, t - i0

    @staticmethod
    def _phi_corners(phi_deg):
        p = phi_deg / PHI_STEP_DEG
        k0f = np.floor(p)
        k0 = k0f.astype(np.intp) % N_PHI  # phi can round to exactly 360
        return k0, (k0 + 1) % N_PHI, p - k0f

    def _eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        theta_i, phi_i = _spherical_deg(wi)
        theta_v, phi_v = _spherical_deg(wo)
        ti0, wti = self._theta_corners(theta_i)
        tv0, wtv = self._theta_corners(theta_v)
        pi0, pi1, wpi = self._phi_corners(phi_i)
        pv0, pv1, wpv = self._phi_corners(phi_v)
        out = np.zeros((wi.shape[0], N_PLANES))
        for ti, a in ((ti0, 1.0 - wti), (ti0 + 1, wti)):
            for pi, b in ((pi0, 1.0 - wpi), (pi1, wpi)):
                row = (ti * N_PHI + pi) * (N_THETA * N_PHI)
                ab = a * b
                for tv, c in ((tv0, 1.0 - wtv), (tv0 + 1, wtv)):
                    for pv, d in ((pv0, 1.0 - wpv), (pv1, wpv)):
                        out += (ab * c * d)[:, None] * self._flat[row + tv * N_PHI + pv]
        return out


def open_utia(path, theta_beyond: str = "clamp") -> UTIASource:
    """Open a UTIA ``.bin`` file as a :class:`BRDFSource` (anisotropic).

    Quadrilinear interpolation in the four angles; ``theta_beyond`` says what
    happens past the last elevation node, 75 degrees: ``"clamp"`` (default)
    or ``"extrapolate"`` (the reference code's linear extrapolation).
    Raises :class:`BRDFFormatError` for any problem with the file.
    """
    spec = os.fspath(path)
    return UTIASource(read_utia_table(spec), path=spec, theta_beyond=theta_beyond)


def write_utia(path, table_or_function: Union[np.ndarray, BRDFSource, Callable]) -> None:
    """Tabulate a BRDF into a UTIA ``.bin`` file (useful for tests and for users).

    ``table_or_function`` is either an array of f values (no cosine) of shape
    (6, 48, 6, 48, 3) indexed (theta_i, phi_i, theta_v, phi_v, RGB) at the
    nodes of :func:`utia_node_angles`, or a :class:`BRDFSource` or function
    ``f(wi, wo) -> (N, 3)`` of unit (N, 3) directions, evaluated at every node
    (all nodes are above the horizon: elevations stop at 75 degrees).

    Written channel-major as the format requires (see the module docstring),
    atomically (a temporary file in the same folder, then a rename). Raises
    ``ValueError`` for a wrong shape or non-finite values.
    """
    if isinstance(table_or_function, BRDFSource) or callable(table_or_function):
        fn = table_or_function.eval if isinstance(table_or_function, BRDFSource) else table_or_function
        wi, wo = utia_grid_directions()
        table = np.asarray(fn(wi, wo), dtype=np.float64)
        if table.shape != (wi.shape[0], N_PLANES):
            raise ValueError(f"the BRDF function returned shape {table.shape}, expected ({wi.shape[0]}, 3)")
        table = table.reshape(TABLE_SHAPE)
    else:
        table = table_array(table_or_function, TABLE_SHAPE, "UTIA")
    if not np.isfinite(table).all():
        raise ValueError("the BRDF table or function holds non-finite values")
    payload = np.ascontiguousarray(np.moveaxis(table, -1, 0), dtype="<f8").tobytes()

    atomic_write_bytes(path, payload)


__all__ = [
    "FILE_BYTES",
    "FILE_SHAPE",
    "TABLE_SHAPE",
    "UTIASource",
    "open_utia",
    "read_utia_table",
    "utia_grid_directions",
    "utia_node_angles",
    "write_utia",
]
