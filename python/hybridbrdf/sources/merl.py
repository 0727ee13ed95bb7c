"""MERL ``.binary`` files (Matusik, Pfister, Brand, McMillan 2003): isotropic
RGB BRDFs tabulated on Rusinkiewicz half/difference angles.

File layout (little-endian, no padding):

    int32  dims[3] = 90 90 180            (theta_h, theta_d, phi_d)
    float64 R[90][90][180], G[...], B[...] channel-major, phi_d fastest

f = stored value * scale, scale = (1/1500, 1.15/1500, 1.66/1500) for R, G, B.
Cell (i, j, k) of a channel is the table node

    theta_h = (i / 90)^2 * pi/2     square-root parameterisation: dense near the specular peak
    theta_d = j / 90 * pi/2         linear
    phi_d   = k / 180 * pi          phi_d in [0, pi): f(phi_d) = f(phi_d + pi) by reciprocity

with (theta_h, theta_d, phi_d) from :mod:`hybridbrdf.sources.rusinkiewicz`,
phi_h ignored (isotropy). These are the conventions of the published reading
code (BRDFRead.cpp): the continuous index of theta_h is
sqrt(theta_h / (pi/2)) * 90, of theta_d theta_d / (pi/2) * 90, of phi_d
phi_d / pi * 180 after folding phi_d < 0 by + pi; BRDFRead.cpp truncates each
to an integer and clamps it to the table.

Missing measurements. Measured files mark cells that could not be measured
(configurations with a direction below the horizon) with negative values,
-1 in every channel. This reader treats a cell as missing when any channel is
negative, and fills it at load time from its nearest valid cells in index
space: rings of missing cells next to valid ones are filled, one ring at a
time, with the mean of their already-known 6-neighbours (phi_d wraps
around). Evaluation therefore never returns NaN or the -1 marker; where the
file has data it returns them as they are. ``missing`` (a boolean
(90, 90, 180) mask) and ``n_missing`` say what was filled.

Interpolation (``open_merl(path, interpolation=...)``):

- ``"linear"`` (default): trilinear in the three continuous indices (so
  linear in sqrt(theta_h), theta_d and phi_d), periodic in phi_d, clamped at
  the last node of theta_h (88.0 degrees) and theta_d (89 degrees).
- ``"nearest"``: BRDFRead.cpp's lookup, each continuous index truncated
  (the cell whose node is at or below the query), for comparison with work
  that used the original code.
"""

from __future__ import annotations

import os
from typing import Callable, Optional, Union

import numpy as np

from hybridbrdf.sources.base import (BRDFFormatError, BRDFSource, check_choice, check_file_size, check_finite_table,
                                     read_file_bytes, source_name, table_array)
from hybridbrdf.sources.rusinkiewicz import dirs_from_half_diff, half_diff_angles
from hybridbrdf.files import atomic_write_bytes

#: Table resolution (theta_h, theta_d, phi_d) of every MERL file.
MERL_DIMS = (90, 90, 180)
N_THETA_H, N_THETA_D, N_PHI_D = MERL_DIMS
N_CELLS = N_THETA_H * N_THETA_D * N_PHI_D
#: f = stored value * scale, per channel (R, G, B), as in the published code.
MERL_SCALES = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
HEADER_BYTES = 12
FILE_BYTES = HEADER_BYTES + 3 * N_CELLS * 8
#: Stored value written for a missing cell, as the measured files do.
MISSING_MARKER = -1.0
INTERPOLATIONS = ("linear", "nearest")

_HALF_PI = 0.5 * np.pi


# ---- grid <-> angles ---------------------------------------------------------


def merl_node_angles():
    """Node angles (theta_h, theta_d, phi_d) in radians, each a 1-D array of
    90, 90 and 180 entries, of table cell (i, j, k)."""
    i = np.arange(N_THETA_H, dtype=np.float64)
    j = np.arange(N_THETA_D, dtype=np.float64)
    k = np.arange(N_PHI_D, dtype=np.float64)
    return (i / N_THETA_H) ** 2 * _HALF_PI, j / N_THETA_D * _HALF_PI, k / N_PHI_D * np.pi


def merl_continuous_indices(wi: np.ndarray, wo: np.ndarray):
    """Continuous table indices (u, v, w) of unit direction pairs, before any
    clamping: u = sqrt(theta_h / (pi/2)) * 90, v = theta_d / (pi/2) * 90,
    w = phi_d / pi * 180 with phi_d folded into [0, pi)."""
    theta_h, _, theta_d, phi_d = half_diff_angles(wi, wo)
    # Reciprocity: phi_d and phi_d + pi are the same configuration with wi and wo swapped.
    phi_d = np.where(phi_d < 0.0, phi_d + np.pi, phi_d)
    u = np.sqrt(np.maximum(theta_h, 0.0) / _HALF_PI) * N_THETA_H
    v = theta_d / _HALF_PI * N_THETA_D
    w = phi_d / np.pi * N_PHI_D
    return u, v, w


def merl_grid_directions():
    """(wi, wo), each (90*90*180, 3), of every table node in file order
    (theta_h slowest, phi_d fastest), built with phi_h = 0. Nodes with a
    direction at or below the horizon are included; see :func:`write_merl`."""
    th, td, pd = merl_node_angles()
    TH, TD, PD = np.meshgrid(th, td, pd, indexing="ij")
    return dirs_from_half_diff(TH.ravel(), 0.0, TD.ravel(), PD.ravel())


# ---- missing cells -----------------------------------------------------------


def _neighbour_indices(flat: np.ndarray) -> np.ndarray:
    """(M, 6) flat indices of the 6-neighbours of cells ``flat``; -1 past the
    theta_h / theta_d edges; phi_d wraps around (it is periodic)."""
    i, rem = np.divmod(flat, N_THETA_D * N_PHI_D)
    j, k = np.divmod(rem, N_PHI_D)

    def at(ii, jj, kk, ok):
        return np.where(ok, (ii * N_THETA_D + jj) * N_PHI_D + kk, -1)

    return np.stack(
        [
            at(i - 1, j, k, i > 0),
            at(i + 1, j, k, i < N_THETA_H - 1),
            at(i, j - 1, k, j > 0),
            at(i, j + 1, k, j < N_THETA_D - 1),
            at(i, j, (k - 1) % N_PHI_D, np.ones_like(k, dtype=bool)),
            at(i, j, (k + 1) % N_PHI_D, np.ones_like(k, dtype=bool)),
        ],
        axis=1,
    )


def _fill_missing(values: np.ndarray, missing: np.ndarray) -> np.ndarray:
    """``values`` ((N_CELLS, 3)) with every missing cell replaced by the mean of
    its known neighbours, working outward from the valid cells one ring at a
    time (a discrete nearest-valid-neighbour fill). Requires a valid cell."""
    out = values.copy()
    known = ~missing
    todo = np.flatnonzero(missing)
    if todo.size == 0:
        return out
    nbr = _neighbour_indices(todo)
    while todo.size:
        has = nbr >= 0
        nbr_known = has & known[np.where(has, nbr, 0)]
        cnt = nbr_known.sum(axis=1)
        ready = cnt > 0
        if not ready.any():  # unreachable when a valid cell exists (the grid is connected)
            raise RuntimeError("missing cells not connected to any valid cell")
        acc = np.zeros((todo.size, 3))
        for c in range(6):
            sel = nbr_known[:, c]
            acc[sel] += out[nbr[sel, c]]
        cells = todo[ready]
        # All of this ring is computed from the previous rings only, then published.
        out[cells] = acc[ready] / cnt[ready, None]
        known[cells] = True
        todo, nbr = todo[~ready], nbr[~ready]
    return out


# ---- reading -----------------------------------------------------------------


def read_merl_raw(path) -> np.ndarray:
    """The stored values of a MERL file as a (3, 90, 90, 180) float64 array
    (channel, theta_h, theta_d, phi_d), unscaled. Raises :class:`BRDFFormatError`
    for an unreadable file, a wrong dims header, a wrong size or non-finite data."""
    spec = os.fspath(path)
    data = read_file_bytes(spec, "MERL", FILE_BYTES)  # the format has one size
    if len(data) < HEADER_BYTES:
        raise BRDFFormatError(spec, f"truncated MERL file: {len(data)} bytes, shorter than the 12-byte dims header")
    dims = tuple(int(x) for x in np.frombuffer(data, dtype="<i4", count=3))
    if dims != MERL_DIMS:
        raise BRDFFormatError(
            spec, f"MERL dims header is {dims[0]} {dims[1]} {dims[2]}, expected 90 90 180 (theta_h, theta_d, phi_d)"
        )
    check_file_size(spec, data, "MERL", FILE_BYTES, "header + 3 x 90x90x180 float64")
    raw = np.frombuffer(data, dtype="<f8", offset=HEADER_BYTES).reshape(3, *MERL_DIMS).astype(np.float64)
    check_finite_table(spec, raw, "MERL", lambda c, i, j, k: f"channel {'RGB'[c]}, theta_h index {i}, "
                                                            f"theta_d index {j}, phi_d index {k}")
    return raw


class MERLSource(BRDFSource):
    """A MERL table behind the :class:`BRDFSource` interface (see the module
    docstring for the conventions, the missing-cell fill and interpolation)."""

    isotropic = True

    def __init__(self, raw: np.ndarray, path: Optional[str] = None, name: Optional[str] = None,
                 interpolation: str = "linear", origin: str = "MERL measurement (raw .binary)"):
        """``raw``: stored values (3, 90, 90, 180) as in the file (unscaled, negative = missing)."""
        check_choice("interpolation", interpolation, INTERPOLATIONS)
        raw = table_array(raw, (3, *MERL_DIMS), "MERL")
        self.path = path
        self.name = source_name(name, path, "merl")
        self.origin = origin
        self.interpolation = interpolation
        # (cells, RGB) with the physical scale applied: one gather per corner at eval time.
        values = raw.reshape(3, N_CELLS).T * MERL_SCALES
        missing = (raw < 0.0).any(axis=0)
        self.missing = missing
        self.n_missing = int(missing.sum())
        if self.n_missing == N_CELLS:
            raise BRDFFormatError(path, "every MERL cell is missing (negative): no data to evaluate")
        self._table = _fill_missing(values, missing.ravel())

    def _eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        u, v, w = merl_continuous_indices(wi, wo)
        if self.interpolation == "nearest":
            # BRDFRead.cpp: truncate, clamp to the table (theta_h <= 0 gives 0 there too).
            i = np.clip(np.floor(u), 0, N_THETA_H - 1).astype(np.intp)
            j = np.clip(np.floor(v), 0, N_THETA_D - 1).astype(np.intp)
            k = np.clip(np.floor(w), 0, N_PHI_D - 1).astype(np.intp)
            return self._table[(i * N_THETA_D + j) * N_PHI_D + k]
        # Trilinear; theta_h and theta_d clamp at their last node, phi_d is periodic.
        u = np.clip(u, 0.0, N_THETA_H - 1)
        v = np.clip(v, 0.0, N_THETA_D - 1)
        i0 = np.minimum(np.floor(u), N_THETA_H - 2).astype(np.intp)
        j0 = np.minimum(np.floor(v), N_THETA_D - 2).astype(np.intp)
        k0f = np.floor(w)
        tu, tv, tw = u - i0, v - j0, w - k0f
        k0 = k0f.astype(np.intp) % N_PHI_D  # w can round to exactly 180
        k1 = (k0 + 1) % N_PHI_D
        out = np.zeros((u.shape[0], 3))
        for di, wu in ((0, 1.0 - tu), (1, tu)):
            for dj, wv in ((0, 1.0 - tv), (1, tv)):
                base = ((i0 + di) * N_THETA_D + (j0 + dj)) * N_PHI_D
                wuv = wu * wv
                out += (wuv * (1.0 - tw))[:, None] * self._table[base + k0]
                out += (wuv * tw)[:, None] * self._table[base + k1]
        return out


def open_merl(path, interpolation: str = "linear") -> MERLSource:
    """Open a MERL ``.binary`` file as a :class:`BRDFSource`.

    ``interpolation`` is ``"linear"`` (trilinear in the table's indices, the
    default) or ``"nearest"`` (the original BRDFRead.cpp truncating lookup).
    Missing (negative) cells are filled from their nearest valid neighbours.
    Raises :class:`BRDFFormatError` for any problem with the file.
    """
    spec = os.fspath(path)
    raw = read_merl_raw(spec)
    return MERLSource(raw, path=spec, interpolation=interpolation)


# ---- writing -----------------------------------------------------------------


def _evaluate_at_nodes(fn: Callable, chunk: int = 1 << 18):
    """(values (N_CELLS, 3), measurable (N_CELLS,) bool): f at the nodes with
    both directions above the horizon; other rows are 0 and not measurable."""
    wi, wo = merl_grid_directions()
    # A node exactly on the horizon comes out with |z| ~ 1e-17 from rounding:
    # it is not measurable either, so it is treated like one below.
    above = (wi[:, 2] > 1e-12) & (wo[:, 2] > 1e-12)
    out = np.zeros((N_CELLS, 3))
    idx = np.flatnonzero(above)
    for s in range(0, idx.size, chunk):
        sel = idx[s:s + chunk]
        vals = np.asarray(fn(wi[sel], wo[sel]), dtype=np.float64)
        if vals.shape != (sel.size, 3):
            raise ValueError(f"the BRDF function returned shape {vals.shape}, expected ({sel.size}, 3)")
        out[sel] = vals
    return out, above


def write_merl(path, table_or_function: Union[np.ndarray, BRDFSource, Callable]) -> None:
    """Tabulate a BRDF into a MERL ``.binary`` file (useful for tests and for users).

    ``table_or_function`` is either

    - an array of f values (no cosine) of shape (90, 90, 180, 3) indexed
      (theta_h, theta_d, phi_d, RGB) at the nodes of :func:`merl_node_angles`;
      a cell negative in any channel is written as the missing marker -1; or
    - a :class:`BRDFSource` or a function ``f(wi, wo) -> (N, 3)`` of unit
      (N, 3) directions. It is evaluated at every node with phi_h = 0 (so it
      should be isotropic); nodes with a direction at or below the horizon
      are written as missing (-1), as the measured files mark them, and so
      is a node where the function is negative in any channel.

    Values are divided by the channel scales. The file is written atomically
    (a temporary file in the same folder, then a rename). Raises ``ValueError``
    for a wrong shape or non-finite values.
    """
    if isinstance(table_or_function, BRDFSource):
        values, measurable = _evaluate_at_nodes(table_or_function.eval)
    elif callable(table_or_function):
        values, measurable = _evaluate_at_nodes(table_or_function)
    else:
        table = table_array(table_or_function, (*MERL_DIMS, 3), "MERL")
        values, measurable = table.reshape(N_CELLS, 3), np.ones(N_CELLS, dtype=bool)
    if not np.isfinite(values).all():
        raise ValueError("the BRDF table or function holds non-finite values")
    # The format has one way to say "no value": negative. Negative f cannot be stored.
    missing = ~measurable | (values < 0.0).any(axis=1)
    raw = values / MERL_SCALES
    raw[missing] = MISSING_MARKER
    payload = np.asarray(MERL_DIMS, dtype="<i4").tobytes() + np.ascontiguousarray(raw.T, dtype="<f8").tobytes()

    atomic_write_bytes(path, payload)


__all__ = [
    "FILE_BYTES",
    "MERL_DIMS",
    "MERL_SCALES",
    "MERLSource",
    "merl_continuous_indices",
    "merl_grid_directions",
    "merl_node_angles",
    "open_merl",
    "read_merl_raw",
    "write_merl",
]
