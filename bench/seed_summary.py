#!/usr/bin/env python3
"""Targets (a) and (b) of the hybrid-vs-neural comparison over several training seeds.

Reads per-material tables written by ``bench/compare_models.py`` (one per seed) and
prints, for each cell (a collection at one MLP size): per seed, on how many materials
the hybrid beats its analytic part and the neural baseline on SMAPE; the spread of those
counts; the counts on the seed-averaged SMAPE of each material; and the materials that
lose in some seed. A single seed's count moves by several materials between seeds (the
neural baseline's mean SMAPE alone moved 0.11 -> 0.15 between two MERL 16x3 seeds), so
the targets are judged on all seeds.

    python bench/seed_summary.py --cell "RGL 16x3" T0.txt T1.txt T2.txt --cell "MERL 32x3" U0.txt U1.txt
"""

from __future__ import annotations

import argparse
import sys
from typing import Dict, List, Tuple

import numpy as np

Row = Tuple[float, float, float]  # SMAPE of the analytic part, the hybrid, the neural baseline


def read_table(path: str) -> Dict[str, Row]:
    """Material -> (SMAPE analytic, hybrid, neural) from a compare_models.py table."""
    rows: Dict[str, Row] = {}
    with open(path) as f:
        lines = f.read().splitlines()
    header = [i for i, line in enumerate(lines) if line.startswith("material") and "SMAPE" in line]
    if not header:
        raise SystemExit(f"{path}: no 'material ... SMAPE' header line; is it a compare_models.py table?")
    for line in lines[header[0] + 1:]:
        parts = line.split()
        if not parts or parts[0] == "mean" or line.startswith(("hybrid ", "#")):
            continue
        if len(parts) != 7:
            raise SystemExit(f"{path}: expected material + 6 numbers, got {line!r}")
        rows[parts[0]] = (float(parts[1]), float(parts[2]), float(parts[3]))
    if not rows:
        raise SystemExit(f"{path}: no material rows")
    return rows


def summarise(label: str, paths: List[str]) -> None:
    tables = [read_table(p) for p in paths]
    names = sorted(tables[0])
    for p, t in zip(paths, tables):
        if sorted(t) != names:
            raise SystemExit(f"{p}: other materials than {paths[0]}")
    s = np.array([[t[n] for n in names] for t in tables])  # (seeds, materials, 3)
    over_analytic = (s[..., 1] < s[..., 0]).sum(1)
    over_neural = (s[..., 1] < s[..., 2]).sum(1)
    n = len(names)
    print(f"{label}: {len(paths)} seeds, {n} materials")
    for p, a, b, t in zip(paths, over_analytic, over_neural, s):
        print(f"  {p}: > analytic {a}/{n}, > neural {b}/{n} ({100 * b / n:.0f}%), "
              f"mean SMAPE hybrid {t[:, 1].mean():.4f} neural {t[:, 2].mean():.4f}")
    print(f"  per seed: > analytic min {over_analytic.min()} mean {over_analytic.mean():.1f}; "
          f"> neural min {over_neural.min()} ({100 * over_neural.min() / n:.0f}%) mean {over_neural.mean():.1f} "
          f"({100 * over_neural.mean() / n:.0f}%)")
    m = s.mean(0)
    print(f"  seed-averaged SMAPE: > analytic {(m[:, 1] < m[:, 0]).sum()}/{n}, "
          f"> neural {(m[:, 1] < m[:, 2]).sum()}/{n} ({100 * (m[:, 1] < m[:, 2]).sum() / n:.0f}%)")
    lost_a = [f"{names[i]} ({(s[:, i, 1] >= s[:, i, 0]).sum()})" for i in range(n) if (s[:, i, 1] >= s[:, i, 0]).any()]
    print("  below its analytic part in some seed (how many): " + (", ".join(lost_a) or "none"))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cell", nargs="+", action="append", required=True, metavar=("LABEL", "TABLE"),
                    help="a label and the tables of its seeds (repeat for each cell)")
    args = ap.parse_args()
    for cell in args.cell:
        if len(cell) < 2:
            ap.error(f"--cell {cell[0]!r} needs at least one table")
        summarise(cell[0], cell[1:])
    return 0


if __name__ == "__main__":
    sys.exit(main())
