"""Mutation testing of the texel lookup and the acquisition's forward model (issue 56, "every test
able to fail"): cosmic-ray (PyPI ``cosmic-ray``, 8.x) makes one small change at a time to a module
(``<`` for ``<=``, ``-`` for ``+``, a number plus one, ``and`` for ``or``, a loop run zero times,
...), runs the tests that cover it, and counts the changes no test notices (survivors). Not part
of the test run (scripts/test.sh): the default samples (90 + 70 mutants) take about 25 minutes of
one core (about 10 s a mutant); all 3,319 mutants would take about 9 hours.

    python3 -m venv /tmp/crvenv && /tmp/crvenv/bin/pip install cosmic-ray
    /tmp/crvenv/bin/python bench/mutation.py                       # both groups, the listed sample
    /tmp/crvenv/bin/python bench/mutation.py --groups svbrdf --sample 0   # every svbrdf mutant

Run it from the repository root with cosmic-ray's interpreter (a venv of its own keeps cosmic-ray's
dependencies out of the project's); the tests run with ``--python`` (default: ``python3`` on PATH,
the one the package is installed for).

Nothing installed is touched: the installed package (``import hybridbrdf``) is copied into
``--work`` (default a fresh ``$TMPDIR/hbrdf-mutation-*``), without ``__pycache__``; cosmic-ray
mutates that copy's files in place, one mutant at a time, and the tests find it first on
PYTHONPATH (cosmic-ray sets PYTHONDONTWRITEBYTECODE, so no mutant's bytecode outlives it). Other
test runs on the machine keep seeing the installed package. At the end every file of the copy is
compared with the installed one (a mutated file left behind is an error) and the copy removed
(``--keep`` keeps it with the sessions). Reinstall first (``pip install --no-build-isolation .``)
so that the installed package is the source under test.

Figures (2026-11-28, seed 56, the default samples; after = the same sample with the tests added
for its survivors, ``--rerun-survivors``):

    group    mutants  survived before  survived after
    acquire       90     23 (25.6%)       3 (3.3%)
    svbrdf        70     18 (25.7%)       9 (12.9%)

The survivors left are equivalent mutants (no input the code can receive tells them apart):
svbrdf: ``head_weight[-1]`` for ``[0]`` (a single material's slice), ``format > "png"`` / ``<=``
for the unused weight channels (the PNG and float decodes of them are the same dict),
``first % 3 <= 0`` (a remainder is never negative), ``format_version is not 1`` (JSON's 1 is
the cached int), the sRGB EOTF's ``maximum(v, -0.96)`` (only in the branch ``np.where`` discards),
and three in the padding at the end of ``_read_entry`` (dead code: a weights map uses all three
channels; a latent map's padding is cut off again); acquire: ``light_jitter != 0`` for ``> 0``
(negative jitter is refused before), ``~keep // ~masked`` for ``&`` (the same on booleans), and
the step generator's seed from 9 digest bytes instead of 8 (still a function of seed, stage
and step only).

Groups (``GROUPS``): the modules mutated and the tests run against each mutant (``-x``, stopping
at the first failure; slow fits deselected: they test the fits, not these modules):
- ``svbrdf``: svbrdf/decode.py, maps.py, asset.py; tests/python/test_svbrdf.py without paint's fits.
- ``acquire``: the modules a re-render, a texel lookup or an observation depends on (geometry,
  mixture, observations, simulate, texel_rows, noise, exposure, rig, rigs, capture; not the fits,
  cluster_fit / hybrid_fit / neural_fit / texel_fit, nor command.py); tests/python/test_acquire_simulate.py
  (without the analytic texel fit), test_acquire_compare.py, test_acquire_references.py and
  test_acquire_fit.py's two exposure tests.

Operators: cosmic-ray's core set less the replacements of arithmetic by bitwise or shift
operators (a float operand raises at once: killed without telling anything), the random
variable inserter/replacer, the exception replacer and decorator removal (``EXCLUDED_OPERATORS``).

By default each group runs the mutants bench/mutation_sample.json lists (module, operator,
occurrence: the sample of the figures above, 90 + 70 drawn at random from the 1,880 + 1,439);
mutants the current source no longer has are reported and left out. ``--sample N`` draws N
mutants per group at random with ``--seed`` instead (``--save-sample`` writes them to that file);
0 runs all. ``--rerun-survivors --work DIR`` runs an earlier ``--keep`` run's survivors again. The report (stdout and ``WORK/report.txt``) gives per module the mutants
run, killed, survived, incompetent (the mutant does not import) and the survival rate
(survived / run), then each survivor (module, line, operator) with its diff.
"""

from __future__ import annotations

import argparse
import filecmp
import json
import os
import random
import shlex
import shutil
import sqlite3
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The sample the figures below were measured on: per group, [module, operator, occurrence] of each mutant.
SAMPLE_FILE = ROOT / "bench" / "mutation_sample.json"

GROUPS = {
    "svbrdf": {
        "modules": ["svbrdf/decode.py", "svbrdf/maps.py", "svbrdf/asset.py"],
        "tests": ["tests/python/test_svbrdf.py"],
        "deselect": "not paint",
        "sample": 70,
    },
    "acquire": {
        "modules": [f"acquire/{m}.py" for m in ("geometry", "mixture", "observations", "simulation", "texel_rows",
                                                 "noise", "exposure", "rig", "rigs", "capture")],
        "tests": ["tests/python/test_acquire_simulate.py", "tests/python/test_acquire_compare.py",
                  "tests/python/test_acquire_references.py",
                  "tests/python/test_acquire_fit.py::test_nan_pixels_are_masked_and_counted",
                  "tests/python/test_acquire_fit.py::"
                  "test_an_under_exposed_capture_is_refused_in_one_line_and_one_dark_photograph_left_out"],
        "deselect": "not analytic_texel_fit",
        "sample": 90,
    },
}

EXCLUDED_OPERATORS = [
    r"core/ReplaceBinaryOperator_.*_(RShift|LShift|BitOr|BitAnd|BitXor)$",
    r"core/VariableInserter", r"core/VariableReplacer", r"core/ExceptionReplacer", r"core/RemoveDecorator",
]


def installed_package(python: str):
    """(the installed package's folder, the interpreter's own path: no pyenv shim per mutant)."""
    out = subprocess.run([python, "-c", "import hybridbrdf, os, sys; print(os.path.dirname(hybridbrdf.__file__)); "
                                        "print(sys.executable)"],
                         capture_output=True, text=True, check=True, env=dict(os.environ, PYTHONPATH=""))
    package, exe = out.stdout.split()
    return Path(package), exe


def toml_list(items) -> str:
    return "[" + ", ".join('"' + str(i).replace("\\", "\\\\").replace('"', '\\"') + '"' for i in items) + "]"


def write_config(path: Path, modules, command: str, timeout: float) -> None:
    path.write_text(
        "[cosmic-ray]\n"
        f"module-path = {toml_list(modules)}\n"
        f"timeout = {timeout}\n"
        "excluded-modules = []\n"
        f"test-command = {toml_list([command])[1:-1]}\n\n"
        "[cosmic-ray.distributor]\n"
        'name = "local"\n\n'
        "[cosmic-ray.filters.operators-filter]\n"
        f"exclude-operators = {toml_list(EXCLUDED_OPERATORS)}\n")


def tool(name: str) -> str:
    exe = Path(sys.executable).parent / name
    if not exe.exists():
        sys.exit(f"mutation.py: {exe} not found: run this script with the interpreter cosmic-ray is installed for")
    return str(exe)


def _key(item, copy_root: Path):
    """A mutant's name that survives a new session: (module, operator, occurrence)."""
    m = item.mutations[0]
    return [os.path.relpath(m.module_path, copy_root), m.operator_name, int(m.occurrence)]


def write_samples(samples) -> None:
    """SAMPLE_FILE with one mutant a line."""
    groups = [f' "{name}": [\n' + ",\n".join("  " + json.dumps(k) for k in keys) + "\n ]" for name, keys in sorted(samples.items())]
    SAMPLE_FILE.write_text("{\n" + ",\n".join(groups) + "\n}\n")


def sample_mutants(session: Path, copy_root: Path, count: int, seed: int, listed=None):
    """Mark all but the sample skipped: ``listed`` mutants ([module, operator, occurrence]) or
    ``count`` drawn at random with ``seed`` from the pending ones in a fixed order (0: all).
    Returns (the sample's keys, how many listed ones this session does not have)."""
    from cosmic_ray.work_db import use_db
    from cosmic_ray.work_item import WorkerOutcome, WorkResult

    with use_db(str(session)) as db:
        pending = sorted((_key(item, copy_root), item.job_id) for item in db.pending_work_items)
        if listed is not None:
            wanted = {tuple(k) for k in listed}
            keep = {job for key, job in pending if tuple(key) in wanted}
            missing = len(wanted) - len(keep)
        elif count <= 0 or count >= len(pending):
            keep, missing = {job for _, job in pending}, 0
        else:
            keep, missing = {job for _, job in random.Random(seed).sample(pending, count)}, 0
        drop = [job for _, job in pending if job not in keep]
        if drop:
            db.set_multiple_results(drop, WorkResult(output="not in the sample", worker_outcome=WorkerOutcome.SKIPPED))
        return [key for key, job in pending if job in keep], missing


def summarise(session: Path, copy_root: Path):
    """(per-module rows, survivors) of a finished session."""
    from cosmic_ray.work_db import use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome

    counts = defaultdict(lambda: defaultdict(int))
    survivors = []
    with use_db(str(session)) as db:
        for item, result in db.completed_work_items:
            if result.worker_outcome == WorkerOutcome.SKIPPED:
                continue
            m = item.mutations[0]
            module = os.path.relpath(m.module_path, copy_root)
            c = counts[module]
            if result.worker_outcome == WorkerOutcome.NORMAL and result.test_outcome == TestOutcome.INCOMPETENT:
                c["incompetent"] += 1
            elif result.worker_outcome == WorkerOutcome.NORMAL and result.test_outcome == TestOutcome.SURVIVED:
                c["run"] += 1
                c["survived"] += 1
                survivors.append((module, m.start_pos[0], m.operator_name, m.occurrence, result.diff or ""))
            elif result.worker_outcome == WorkerOutcome.NORMAL:
                c["run"] += 1
                c["killed"] += 1
            else:  # exception / abnormal / no-test: the mutant could not be run
                c["incompetent"] += 1
    return counts, sorted(survivors)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--groups", nargs="+", choices=sorted(GROUPS), default=sorted(GROUPS))
    ap.add_argument("--sample", type=int, default=None,
                    help=f"mutants per group drawn at random (0: all; default: the mutants {SAMPLE_FILE.name} lists, "
                         "or each group's GROUPS 'sample')")
    ap.add_argument("--save-sample", action="store_true", help=f"with --sample: write the sample to {SAMPLE_FILE.name}")
    ap.add_argument("--seed", type=int, default=56)
    ap.add_argument("--python", default="python3", help="the interpreter the tests run with")
    ap.add_argument("--timeout", type=float, default=240.0, help="seconds per mutant's test run (then killed)")
    ap.add_argument("--work", type=Path, default=None, help="scratch folder (default: a fresh one under $TMPDIR)")
    ap.add_argument("--keep", action="store_true", help="keep the scratch folder (sessions, the copy)")
    ap.add_argument("--rerun-survivors", action="store_true",
                    help="with --work of an earlier run: run that run's survivors again (after new tests; a "
                         "killed mutant stays killed when tests are only added) and report the whole sample again")
    ap.add_argument("--count", action="store_true", help="only count each group's mutants (after the operator filter)")
    args = ap.parse_args(argv)

    installed, python = installed_package(shutil.which(args.python) or args.python)
    samples = json.loads(SAMPLE_FILE.read_text()) if SAMPLE_FILE.exists() else {}
    work = args.work or Path(tempfile.mkdtemp(prefix="hbrdf-mutation-"))
    work.mkdir(parents=True, exist_ok=True)
    site = work / "site"
    copy = site / "hybridbrdf"
    if copy.exists():
        shutil.rmtree(copy)
    shutil.copytree(installed, copy, ignore=shutil.ignore_patterns("__pycache__"))
    lines = [f"package under test: {installed} (copied to {copy}); tests run by {python}"]
    try:
        for name in args.groups:
            g = GROUPS[name]
            modules = [copy / m for m in g["modules"]]
            command = " ".join(["env", f"PYTHONPATH={shlex.quote(str(site))}", shlex.quote(python), "-m", "pytest",
                                *g["tests"], "-x", "-q", "-p", "no:cacheprovider", "-k", shlex.quote(g["deselect"])])
            config, session = work / f"{name}.toml", work / f"{name}.sqlite"
            write_config(config, modules, command, args.timeout)
            if args.rerun_survivors:
                if not session.exists():
                    sys.exit(f"mutation.py: --rerun-survivors needs {session} (an earlier run with --work {work} --keep)")
                with sqlite3.connect(session) as db:
                    n = db.execute("DELETE FROM work_results WHERE upper(test_outcome) = 'SURVIVED'").rowcount
            else:
                if session.exists():
                    session.unlink()
                subprocess.run([tool("cosmic-ray"), "init", str(config), str(session)], check=True, cwd=ROOT)
                subprocess.run([tool("cr-filter-operators"), str(session), str(config)], check=True, cwd=ROOT)
                if args.count:
                    lines.append(f"{name}: {len(sample_mutants(session, copy, 0, args.seed)[0])} mutants")
                    continue
                listed = samples.get(name) if args.sample is None else None
                keys, missing = sample_mutants(session, copy, g["sample"] if args.sample is None else args.sample,
                                               args.seed, listed)
                n = len(keys)
                if missing:
                    print(f"{name}: {missing} mutants of {SAMPLE_FILE.name} are not in this source (it changed); "
                          f"running the {n} that are", flush=True)
                if args.sample is not None and args.save_sample:
                    samples[name] = keys
            print(f"{name}: {n} mutants to run; baseline first", flush=True)
            base = subprocess.run(shlex.split(command), cwd=ROOT, capture_output=True, text=True)
            if base.returncode != 0:
                sys.exit(f"mutation.py: {name}'s tests fail without a mutant:\n{base.stdout[-3000:]}")
            subprocess.run([tool("cosmic-ray"), "exec", str(config), str(session)], check=True, cwd=ROOT)
            counts, survivors = summarise(session, copy)
            lines.append(f"\n== {name}: tests {' '.join(g['tests'])} -k '{g['deselect']}'; "
                         f"sample {g['sample'] if args.sample is None else args.sample} (seed {args.seed})")
            lines.append(f"{'module':32} {'run':>5} {'killed':>7} {'survived':>9} {'incompetent':>12} {'survival':>9}")
            total = defaultdict(int)
            for module in sorted(counts):
                c = counts[module]
                for k, v in c.items():
                    total[k] += v
                rate = c["survived"] / c["run"] if c["run"] else 0.0
                lines.append(f"{module:32} {c['run']:5d} {c['killed']:7d} {c['survived']:9d} {c['incompetent']:12d} {rate:9.1%}")
            rate = total["survived"] / total["run"] if total["run"] else 0.0
            lines.append(f"{'all':32} {total['run']:5d} {total['killed']:7d} {total['survived']:9d} "
                         f"{total['incompetent']:12d} {rate:9.1%}")
            for module, line, op, occ, diff in survivors:
                lines.append(f"-- survivor {module}:{line} {op} #{occ}\n{diff.strip()}")
        if args.save_sample and args.sample is not None and not args.rerun_survivors:
            write_samples(samples)
            lines.append(f"wrote the sample to {SAMPLE_FILE}")
    finally:
        left = [str(p) for p in copy.rglob("*.py")
                if not filecmp.cmp(p, installed / p.relative_to(copy), shallow=False)]
        if left:
            lines.append("MUTATED FILES LEFT IN THE COPY: " + ", ".join(left))
        text = "\n".join(lines) + "\n"
        print(text)
        (work / "report.txt").write_text(text)
        if not args.keep and not left:
            shutil.rmtree(copy, ignore_errors=True)
        print(f"sessions and report in {work}" + ("" if args.keep else " (the package copy removed)"))
    return 1 if left else 0


if __name__ == "__main__":
    sys.exit(main())
