"""The browser tests' time (issue 56): tests/python's four test_view*.py files run by pytest in one
process (``-n 0``), with the CPU seconds of the whole process tree (chromium's GPU and renderer
processes included), the wall seconds and the sum of pytest's per-test durations:
bench/shader_test_time.py's measurement (its ``--together`` over these files, Mesa's cache kept,
chromium and its WebGPU required).

With ``--before REV`` the same files of the commit REV (its tree; this checkout's build/ and
../shared/data) run too, in interleaved rounds (REV, this tree, REV, ...): only figures of one run
compare (CONVENTIONS.md, "Testing"). Both use the installed package.

    python bench/browser_test_time.py --before HEAD~1 --rounds 2
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from shader_test_time import interleaved, run  # noqa: E402

FILES = ["test_view.py", "test_view_sources.py", "test_view_svbrdf.py", "test_view_webgpu.py"]
BROWSER_REQUIRED = {"HBRDF_REQUIRE_BROWSER": "1", "HBRDF_REQUIRE_WEBGPU": "1"}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--before", metavar="REV", help="also run REV's test files, interleaved with this tree's")
    p.add_argument("--rounds", type=int, default=1, help="rounds (each REV's run, then this tree's; default 1)")
    a = p.parse_args(argv)
    if a.rounds < 1:
        p.error(f"--rounds {a.rounds}: must be at least 1")
    return interleaved(a.before, a.rounds, [FILES],
                       lambda label, root, files: run(label, root, files, None, True, BROWSER_REQUIRED))


if __name__ == "__main__":
    sys.exit(main())
