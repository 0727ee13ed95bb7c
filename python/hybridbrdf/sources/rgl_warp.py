"""The interpolation of RGL tables: Mitsuba 3's ``Marginal2D`` (continuous 2-D marginal warp) and
the bilinear and sliced lookups the ``measured`` plugin evaluates with, redone in float64 NumPy
(Dupuy & Jakob 2018)."""

from __future__ import annotations

from typing import Tuple

import numpy as np

def lerp(a, b, t):
    return a + (b - a) * t


def find_interval(values: np.ndarray, x: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Index i of the interval [values[i], values[i+1]] holding x (clamped to
    the first/last interval) and the clamped weight of values[i+1]. A single
    value gives index 0 and weight 0 (no interpolation along that axis)."""
    n = len(values)
    if n == 1:
        return np.zeros(x.shape, dtype=np.intp), np.zeros(x.shape)
    i = np.clip(np.searchsorted(values, x, side="left") - 1, 0, n - 2)
    p0, p1 = values[i], values[i + 1]
    return i, np.clip((x - p0) / (p1 - p0), 0.0, 1.0)


def grid_cell(u: np.ndarray, n: int) -> Tuple[np.ndarray, np.ndarray]:
    """Cell index and fraction of u in [0,1] on a grid of n nodes spanning [0,1]
    (n - 1 patches); u = 1 falls into the last patch with fraction 1."""
    x = np.clip(u, 0.0, 1.0) * (n - 1)
    i = np.minimum(x.astype(np.intp), n - 2)
    return i, x - i


def bilinear(table: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear interpolant of a (rows, cols) table at (u along cols, v along
    rows), both in [0,1] (Mitsuba's Marginal2D<0>::eval without normalisation)."""
    h, w = table.shape
    col, fx = grid_cell(u, w)
    row, fy = grid_cell(v, h)
    t = table.ravel()
    base = row * w + col
    top = lerp(t[base], t[base + 1], fx)
    bottom = lerp(t[base + w], t[base + w + 1], fx)
    return lerp(top, bottom, fy)


class Slices:
    """Per-query linear interpolation weights over the (phi_i, theta_i)
    parameter grid: up to four (slice index, weight) corners, where a slice is
    one (phi_i, theta_i) entry of a table of shape (n_phi, n_theta, ...)."""

    def __init__(self, phi_values, theta_values, phi_i, theta_i):
        n_phi, n_theta = len(phi_values), len(theta_values)
        ip, tp = find_interval(phi_values, phi_i)
        it, tt = find_interval(theta_values, theta_i)
        phi_corners = [(ip, 1.0 - tp)] + ([(ip + 1, tp)] if n_phi > 1 else [])
        theta_corners = [(it, 1.0 - tt)] + ([(it + 1, tt)] if n_theta > 1 else [])
        self.corners = [(a * n_theta + b, wa * wb) for a, wa in phi_corners for b, wb in theta_corners]

    def gather(self, table: np.ndarray, index: np.ndarray) -> np.ndarray:
        """sum over corners of weight * table[slice, index]; table is
        (n_slices, K) or (n_slices, K, C), giving (M,) or (M, C)."""
        out = None
        for s, w in self.corners:
            v = table[s, index]
            term = v * (w if v.ndim == 1 else w[:, None])
            out = term if out is None else out + term
        return out


class ContinuousMarginal2D:
    """The inverse of Mitsuba's continuous marginal 2D warp for a stack of
    tables (one per incident direction), the VNDF warp of the adaptive
    parameterisation.

    Each slice's bilinear interpolant p(x, y) on [0,1]^2 is normalised to
    integrate to 1; ``cond[y, j]`` integrates row y over x in [0, x_{j+1}]
    (trapezoids), ``marg[j]`` integrates the row totals over y in
    [0, y_{j+1}]. :meth:`invert` maps a point (x, y) to (P(X <= x | y),
    P(Y <= y)), both in [0,1]; the CDF values are interpolated linearly in
    the parameters, exactly as Mitsuba's lookups do."""

    def __init__(self, data: np.ndarray):
        # data: (n_slices, H, W) float64, non-negative, each slice with positive integral
        s, h, w = data.shape
        self.h, self.w = h, w
        cond = np.cumsum(0.5 / (w - 1) * (data[:, :, :-1] + data[:, :, 1:]), axis=2)  # (S, H, W-1)
        row_total = cond[:, :, -1]
        marg = np.cumsum(0.5 / (h - 1) * (row_total[:, :-1] + row_total[:, 1:]), axis=1)  # (S, H-1)
        norm = 1.0 / marg[:, -1]
        self.data = (data * norm[:, None, None]).reshape(s, h * w)
        self.cond = (cond * norm[:, None, None]).reshape(s, h * (w - 1))
        self.marg = marg * norm[:, None]

    def invert(self, u: np.ndarray, v: np.ndarray, sl: Slices) -> Tuple[np.ndarray, np.ndarray]:
        """Warp the points (u along x/columns, v along y/rows) to the unit square."""
        h, w = self.h, self.w
        col, fx = grid_cell(u, w)
        row, fy = grid_cell(v, h)
        base = row * w + col
        v00 = sl.gather(self.data, base)
        v10 = sl.gather(self.data, base + 1)
        v01 = sl.gather(self.data, base + w)
        v11 = sl.gather(self.data, base + w + 1)
        c0 = lerp(v00, v01, fy)  # density along the left edge of the patch at height fy
        c1 = lerp(v10, v11, fy)

        # x: mass of the linear segment c0 -> c1 over [0, fx] of this patch,
        # plus the conditional CDF of all patches to the left, over the row total.
        x = fx * lerp(c0, c1, 0.5 * fx) / (w - 1)
        cbase = row * (w - 1)
        left = np.maximum(col - 1, 0)
        cdf_left = lerp(sl.gather(self.cond, cbase + left), sl.gather(self.cond, cbase + (w - 1) + left), fy)
        x = x + np.where(col > 0, cdf_left, 0.0)
        r0 = sl.gather(self.cond, cbase + (w - 2))  # row totals of the patch's two rows
        r1 = sl.gather(self.cond, cbase + (w - 1) + (w - 2))
        row_total = lerp(r0, r1, fy)
        # A row pair without mass (never in the RGL data) would divide 0 by 0;
        # put such points at x = 0 instead of producing NaN.
        x = np.divide(x, row_total, out=np.zeros_like(x), where=row_total > 0)

        # y: mass of the linear segment r0 -> r1 over [0, fy], plus the marginal CDF below.
        y = fy * lerp(r0, r1, 0.5 * fy) / (h - 1)
        below = np.maximum(row - 1, 0)
        y = y + np.where(row > 0, sl.gather(self.marg, below), 0.0)
        return x, y
