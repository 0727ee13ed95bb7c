"""What a cold TorchInductor compile of the fit step costs, and what the compiled step then costs.

Fits the two synthetic materials of tests/python/test_fitting.py's compiled-step test (16x2,
batch 512, per-material epsilon, expectile 0.8) with ``compile_step=True`` in an empty
TorchInductor cache folder (a first run on a fresh machine), and prints the CPU seconds of the
whole fit (this process and the compiler processes it waited for: the C++ compiles), the first
step's wall seconds, and the CPU milliseconds of each later step. CPU, not wall time: the
figures hold on a machine shared with other work (docs/FITTING.md, "Training speed").

    --steps N        steps of the fit (default 3: the compile and two steps; more for the step cost)
    --cache DIR      TorchInductor cache folder to use instead of a fresh one (a second run on
                     the same folder measures the step without compiling)
    --eager          no compile: the eager step, for comparison
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time


def _cpu_seconds() -> float:
    own, waited = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + waited.ru_utime + waited.ru_stime


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3, help="steps of the fit (at least 3)")
    parser.add_argument("--cache", help="TorchInductor cache folder (default: a new empty one)")
    parser.add_argument("--eager", action="store_true", help="eager steps, no compile")
    args = parser.parse_args(argv)
    if args.steps < 3:
        parser.error(f"--steps {args.steps}: at least 3 (the compile, then steps to time)")
    # Before torch is imported: TorchInductor reads its cache folder once.
    os.environ["TORCHINDUCTOR_CACHE_DIR"] = args.cache or tempfile.mkdtemp(prefix="hbrdf-inductor-")
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "python"))
    import hybridbrdf as hb
    from hybridbrdf.fit import fit
    from hybridbrdf.fit.settings import FitSettings
    from helpers import AnalyticTestSource

    sources = [AnalyticTestSource("plain", hb.AnalyticParams(kd=[0.4, 0.3, 0.2], eta=1.6, alpha=0.25)),
               AnalyticTestSource("retro", hb.AnalyticParams(kd=[0.1, 0.5, 0.2], eta=2.0, alpha=(0.15, 0.35)),
                                  retro=0.6)]
    settings = FitSettings.from_recipe("hybridbrdf", width=16, depth=2, steps=args.steps, batch=512, pool=1 << 12,
                                       eval_pairs=2000, seed=3, analytic_guard=False, energy_bound=False,
                                       loss_eps=0.05, loss_eps_relative=True, analytic_expectile=0.8)
    marks = {}

    def observe(step, module):  # CPU time after the first step (the compile) and after the last
        if step in (1, args.steps):
            marks[step] = _cpu_seconds()

    start, t0 = _cpu_seconds(), time.perf_counter()
    model = fit(sources, settings, progress=False, compile_step=not args.eager, observe=observe, log=lambda m: None)
    print(f"{'eager' if args.eager else 'compiled'} fit of {args.steps} steps: {_cpu_seconds() - start:.1f} s of CPU, "
          f"{time.perf_counter() - t0:.1f} s wall; first step {model.training.get('compile_seconds', 0.0):.1f} s wall; "
          f"later steps {1e3 * (marks[args.steps] - marks[1]) / (args.steps - 1):.2f} ms of CPU each; "
          f"cache {os.environ['TORCHINDUCTOR_CACHE_DIR']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
