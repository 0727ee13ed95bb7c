#!/usr/bin/env python3
"""How long an energy-bound table takes to fit, before and after the moment form (issue 56), and
that the two forms give the same table (docs/ENERGY.md, "How the table is fitted").

    python bench/energy_table_speed.py [MODEL] [--materials A B ...] [--edits N]

Before: each of the fit's ~27 albedo evaluations (first pass, 24 damped steps, last step, and the
two maxima recorded) interpolated k at every sample, (n_dir, samples, 3) float64 arrays: the
reference below is that code, kept verbatim. After: ``energy.moments`` reduces the samples once to
M[d, j, rgb] = mean_s hat_j(z_s) c_s, and every step is sum_j k_j M[d, j] (exact: k is linear in
its nodes). Both run on the same contributions (``energy._contributions``, 4,096 samples, the
product's seed); per material the script prints the seconds of the contributions, of the old fit
and of the new one, the largest difference between the two tables in float64, and how many of the
16 float32 nodes the product would store differ (by how many ulps). Then the product's own
``energy.tables`` per material (wall clock, screen pass included) against the old total
(contributions + old fit + old maxima).

MODEL: default the shipped prior; materials default to the prior's four most dimmed; ``--edits
N``: add N corner edits (kd = 1, eta = 10) of the first materials, the bound's hardest inputs.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import time

import numpy as np

import hybridbrdf as hb
from hybridbrdf.model import energy
from hybridbrdf.files import scratch_folder


# ---- the fit before issue 56, verbatim (hybridbrdf 2026-11-27) ------------------------------------

def old_fit_table(c, z, x, target=energy.TARGET, iterations=energy.ITERATIONS):
    def albedo(k):
        inner = (energy.scale(k, z)[..., None] * c).mean(axis=1).max(axis=1)
        return energy.scale(k, x) * inner

    def room(k):
        rho = albedo(k)
        with np.errstate(divide="ignore"):
            return energy._node_minimum(np.where(rho > 0, target / rho, np.inf), x)

    k = np.ones(energy.NODES)
    if albedo(k).max() <= target:
        return k
    k = np.minimum(1.0, room(k))
    for _ in range(iterations):
        k = np.minimum(1.0, k * np.sqrt(room(k)))
    k = k * np.minimum(1.0, room(k))
    return k


def old_max_albedo(c, z, x, k):
    return float(((energy.scale(k, z)[..., None] * c).mean(axis=1).max(axis=1) * energy.scale(k, x)).max())


def round_down(k):
    k32 = k.astype(np.float32)
    return np.where(k32.astype(np.float64) > k, np.nextafter(k32, np.float32(0)), k32)


def machine() -> str:
    try:
        name = [line.split(":", 1)[1].strip() for line in subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines()
                if line.startswith("Model name")][0]
    except (OSError, IndexError):
        name = platform.processor()
    return f"{name}, {os.cpu_count()} cores, SIMD path {hb.simd_path()}, load average {os.getloadavg()[0]:.1f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", nargs="?", default=None)
    ap.add_argument("--materials", nargs="*", default=None)
    ap.add_argument("--edits", type=int, default=2)
    args = ap.parse_args()
    model = hb.load_prior() if args.model is None else hb.load_model(args.model)
    if args.materials is None:
        t = model.tensors.get("materials.energy_bound")
        order = np.argsort(t.min(axis=1)) if t is not None else np.arange(len(model.materials))
        args.materials = [model.materials[i] for i in order[:4]]
    names = list(args.materials)
    for i, src in enumerate(names[:args.edits]):
        model = model.edit(src, f"corner{i}", kd=1.0, eta=10.0)
        names.append(f"corner{i}")
    print(machine())
    f_t = energy.unbounded(model)
    rows = []
    with scratch_folder() as tmp:
        f_t = energy.on_file(f_t, tmp, "unbounded.safetensors")
        for name in names:
            i = f_t.index(name)
            t0 = time.perf_counter()
            c, z, x = energy._contributions(f_t, i, energy.SAMPLES, 7)
            t1 = time.perf_counter()
            k_old = old_fit_table(c, z, x)
            t2 = time.perf_counter()
            a_old = (old_max_albedo(c, z, x, np.ones(energy.NODES)), old_max_albedo(c, z, x, round_down(k_old).astype(np.float64)))
            t3 = time.perf_counter()
            m = energy.moments(c, z)
            k_new = energy.fit_table_from_moments(m, x)
            t4 = time.perf_counter()
            a_new = (energy._max_albedo(m, x, np.ones(energy.NODES)), energy._max_albedo(m, x, round_down(k_new).astype(np.float64)))
            del c, z, m
            t5 = time.perf_counter()
            energy.tables(f_t, [name])
            t6 = time.perf_counter()
            o32, n32 = round_down(k_old), round_down(k_new)
            ulps = np.abs(o32.view(np.int32).astype(np.int64) - n32.view(np.int32).astype(np.int64))
            rows.append((name, t1 - t0, t2 - t1, t4 - t3, np.abs(k_old - k_new).max(), int((ulps > 0).sum()), int(ulps.max()),
                         max(abs(a - b) for a, b in zip(a_old, a_new)), k_new.min(), (t1 - t0) + (t3 - t1), t6 - t5))
            print(f"{name:28s} contributions {t1 - t0:5.2f} s  old fit {t2 - t1:6.2f} s  new fit {t4 - t3:5.2f} s  "
                  f"max |dk| {rows[-1][4]:.1e}  float32 nodes differing {rows[-1][5]} (max {rows[-1][6]} ulp)  "
                  f"max albedo diff {rows[-1][7]:.1e}  min k {k_new.min():.4f}  "
                  f"table before {rows[-1][9]:6.2f} s  after (energy.tables) {t6 - t5:5.2f} s", flush=True)
    r = np.array([row[1:] for row in rows], dtype=np.float64)
    print(f"\nmean over {len(rows)} materials: old fit {r[:, 1].mean():.2f} s, new fit {r[:, 2].mean():.3f} s "
          f"(x{r[:, 1].mean() / r[:, 2].mean():.0f}); a table before {r[:, 8].mean():.2f} s, after {r[:, 9].mean():.2f} s "
          f"(x{r[:, 8].mean() / r[:, 9].mean():.1f}); largest |dk| {r[:, 3].max():.1e}, float32 nodes differing "
          f"{int(r[:, 4].sum())} of {16 * len(rows)}")


if __name__ == "__main__":
    main()
