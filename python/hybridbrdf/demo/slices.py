"""``hbrdf demo``: look at the analytic BRDF f_a (its sizes: :mod:`hybridbrdf.demo.sizes`).

Plots, for a few built-in materials, in-plane slices of f_a(wi, wo) cos(theta_i)
(computed by the C++ library, with the float64 PyTorch implementation drawn
over it as a check) and the directional albedo as a function of the viewing
angle, estimated by importance sampling with each strategy. Prints the albedo
table. Needs nothing outside the package.
"""

from __future__ import annotations

import io
from typing import Dict

import numpy as np

from hybridbrdf._core import STRATEGIES
from hybridbrdf.brdf.analytic import AnalyticParams, analytic_eval, sample
from hybridbrdf.demo.sizes import BYTES_PER_SAMPLE, SAMPLES
from hybridbrdf.limits import check_count, count_argument
from hybridbrdf.files import atomic_write_bytes

#: Built-in analytic materials (no measured data needed).
DEMO_MATERIALS: Dict[str, AnalyticParams] = {
    "glossy white plastic": AnalyticParams(kd=0.8, eta=1.5, alpha=0.08),
    "matte terracotta": AnalyticParams(kd=[0.55, 0.25, 0.15], eta=1.4, alpha=0.7),
    "brushed dielectric": AnalyticParams(kd=0.02, eta=[3.0, 2.6, 2.2], alpha=[0.06, 0.35]),
    "black glass": AnalyticParams(kd=0.0, eta=1.52, alpha=0.02),
}


def in_plane(theta_i_deg: float, theta_o_deg: np.ndarray):
    """Direction pairs in the x-z plane: wi at +theta_i, wo at theta_o in [-90, 90]."""
    ti = np.radians(theta_i_deg)
    to = np.radians(theta_o_deg)
    wi = np.tile([np.sin(ti), 0.0, np.cos(ti)], (len(to), 1))
    wo = np.stack([np.sin(to), np.zeros_like(to), np.cos(to)], axis=1)
    return wi, wo


def directional_albedo(params: AnalyticParams, theta_o_deg: float, n: int, strategy: str, seed: int = 7) -> np.ndarray:
    """Monte Carlo estimate of a(wo) = integral of f cos over wi, RGB."""
    rng = np.random.default_rng(seed)
    t = np.radians(theta_o_deg)
    wo = np.tile([np.sin(t), 0.0, np.cos(t)], (n, 1))
    _, _, weight = sample(wo, rng.random((n, 2)), params, strategy)
    return weight.astype(np.float64).mean(axis=0)


def _write_png_atomically(fig, path: str) -> None:
    """The figure as a PNG at ``path``, by :func:`hybridbrdf.files.atomic_write_bytes` (the
    replaced file's mode kept, errors naming ``path``; docs/CONVENTIONS.md, "Writing files")."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    atomic_write_bytes(path, buf.getvalue())


def run_demo(out: str, samples: int = SAMPLES) -> None:
    """Write the slice plot to ``out`` (PNG) and print the albedo table. ``samples`` (--samples)
    is bounded by memory (:data:`BYTES_PER_SAMPLE`; hybridbrdf.limits), checked first."""
    check_count("--samples", count_argument("--samples", samples), BYTES_PER_SAMPLE)
    import matplotlib
    import torch  # the check drawn over the C++ slices; hbrdf --help should not wait for it

    from hybridbrdf.brdf.torch_brdf import eval_analytic as torch_eval

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    theta_o = np.linspace(-89.5, 89.5, 359)
    angles = (0.0, 30.0, 60.0, 75.0)
    fig, axes = plt.subplots(len(DEMO_MATERIALS), 2, figsize=(11, 3.1 * len(DEMO_MATERIALS)), squeeze=False)
    worst_rel = 0.0
    print(f"{'material':24s} {'theta_o':>7s}  " + "  ".join(f"{s:>20s}" for s in STRATEGIES))
    for row, (name, p) in enumerate(DEMO_MATERIALS.items()):
        ax = axes[row][0]
        for k, ti in enumerate(angles):
            wi, wo = in_plane(ti, theta_o)
            f = analytic_eval(wi, wo, p).astype(np.float64)
            ref = torch_eval(torch.from_numpy(wi), torch.from_numpy(wo), torch.tensor(p.kd),
                             torch.tensor(p.eta), torch.tensor(p.alpha)).numpy()
            worst_rel = max(worst_rel, float(np.max(np.abs(f - ref) / np.maximum(ref, 1e-12))))
            lum = (f * wi[:, 2:3]).mean(axis=1)
            colour = f"C{k}"
            ax.semilogy(theta_o, np.maximum(lum, 1e-6), color=colour, label=f"θi = {ti:.0f}°")
            ax.semilogy(theta_o[::12], np.maximum((ref * wi[:, 2:3]).mean(axis=1)[::12], 1e-6), "o", ms=3,
                        color=colour, mfc="none")
        ax.set_title(f"{name}: f·cos θi in the incidence plane")
        ax.set_xlabel("θo (degrees; negative = mirror side)")
        ax.set_ylabel("mean RGB")
        ax.legend(fontsize=7, loc="upper left")

        ax = axes[row][1]
        view = np.linspace(0.0, 85.0, 18)
        for s_i, strategy in enumerate(STRATEGIES):
            a = np.array([directional_albedo(p, v, max(samples // 10, 1000), strategy).mean() for v in view])
            ax.plot(view, a, marker="os^"[s_i], ms=3, label=strategy)
        ax.set_ylim(bottom=0)
        ax.set_title(f"{name}: directional albedo (mean RGB)")
        ax.set_xlabel("θo (degrees)")
        ax.legend(fontsize=7)
        for v in (0.0, 60.0):
            est = [directional_albedo(p, v, samples, s).mean() for s in STRATEGIES]
            print(f"{name:24s} {v:6.0f}°  " + "  ".join(f"{e:20.5f}" for e in est))
    fig.suptitle("hybridbrdf analytic component f_a (lines: C++ float32; circles: PyTorch float64)")
    fig.tight_layout()
    _write_png_atomically(fig, out)
    plt.close(fig)
    print(f"largest relative difference C++ float32 vs PyTorch float64 on the slices: {worst_rel:.2e}")
    print(f"wrote {out}")
