"""The browser tests' time (issue 56): tests/python's four test_view*.py files run by pytest in one
process (``-n 0``), with the CPU seconds of the whole process tree (chromium's GPU and renderer
processes included: a cpuacct cgroup of its own where /sys/fs/cgroup/cpuacct is writable, else the
reaped children's rusage, which misses chromium's grandchildren and says so), the wall seconds and
the sum of pytest's per-test durations.

With ``--before REV`` the same files of the commit REV (its tests/python and results/; this
checkout's build/ and ../shared/data) run too, in interleaved rounds (REV, this tree, REV, ...):
only figures of one run compare (CONVENTIONS.md, "Testing"). Both use the installed package.

    python bench/browser_test_time.py --before HEAD~1 --rounds 2
"""

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FILES = ["tests/python/test_view.py", "tests/python/test_view_sources.py", "tests/python/test_view_svbrdf.py",
         "tests/python/test_view_webgpu.py"]
CGROUPS = "/sys/fs/cgroup/cpuacct"


def checkout(rev, into):
    """REV's tests/python, results/ and pyproject.toml under ``into`` (build/ linked to this checkout's)."""
    archive = subprocess.run(["git", "-C", REPO, "archive", rev, "tests/python", "results", "pyproject.toml"],
                             check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", into], input=archive, check=True)
    os.symlink(os.path.join(REPO, "build"), os.path.join(into, "build"))


def run(label, root):
    """One pytest run of FILES under ``root``: its line of figures."""
    env = dict(os.environ, HBRDF_REQUIRE_BROWSER="1", HBRDF_REQUIRE_WEBGPU="1")
    cmd = [sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider", "--durations=0", *FILES]
    group = os.path.join(CGROUPS, f"hbrdf-browser-tests-{os.getpid()}")
    try:
        os.mkdir(group)
    except OSError:
        group = None
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.monotonic()

    def enter():  # in the child: into the cgroup before pytest starts chromium
        if group:
            with open(os.path.join(group, "cgroup.procs"), "w") as f:
                f.write(str(os.getpid()))
    r = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True, preexec_fn=enter)
    wall = time.monotonic() - start
    if group:
        with open(os.path.join(group, "cpuacct.usage")) as f:
            cpu, how = int(f.read()) / 1e9, "process tree"
        os.rmdir(group)
    else:
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu, how = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, "reaped children only"
    durations = sum(float(m.group(1)) for m in re.finditer(r"^([\d.]+)s (?:call|setup|teardown) ", r.stdout, re.M))
    summary = r.stdout.strip().splitlines()[-1] if r.stdout.strip() else r.stderr.strip()[-300:]
    load = open("/proc/loadavg").read().split()[:3]
    return (f"{label}: {summary} | test time {durations:.1f} s | CPU {cpu:.1f} s ({how}) | wall {wall:.1f} s | "
            f"load {' '.join(load)} | {time.strftime('%H:%M', time.gmtime())} UTC"), r.returncode


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--before", metavar="REV", help="also run REV's test files, interleaved with this tree's")
    p.add_argument("--rounds", type=int, default=1, help="rounds (each REV's run, then this tree's; default 1)")
    a = p.parse_args(argv)
    if a.rounds < 1:
        p.error(f"--rounds {a.rounds}: must be at least 1")
    # beside this checkout, so that REV's tests find ../shared/data as this tree's do
    with tempfile.TemporaryDirectory(prefix="hbrdf-browser-tests-", dir=os.path.dirname(REPO)) as scratch:
        roots = [("this tree", REPO)]
        if a.before:
            checkout(a.before, scratch)
            roots.insert(0, (a.before, scratch))
        failed = 0
        for k in range(a.rounds):
            for label, root in roots:
                line, code = run(f"round {k + 1}, {label}", root)
                print(line, flush=True)
                failed |= code
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
