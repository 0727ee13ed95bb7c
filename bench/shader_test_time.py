"""CPU seconds of test files (issue 56): each FILE of tests/python run by pytest in a process of its own
(``-n 0``), with the CPU seconds of its whole process tree (pytest and what it starts: g++, slangc,
glslang, hbrdf_vk_runner, chromium's GPU and renderer processes; a cpuacct cgroup of its own where
/sys/fs/cgroup/cpuacct is writable, else the reaped children's rusage, which misses processes nobody
waits for, such as chromium's, and says so), the wall seconds and the sum of pytest's per-test durations. Mesa's shader cache is off (``MESA_SHADER_CACHE_DISABLE=true``), as
on CI's fresh machine, unless ``--mesa-cache``.

With ``--before REV`` the whole tree of the commit REV (``git archive``; this checkout's build/ linked,
../shared beside it as beside this checkout) runs the same files too, in interleaved rounds (REV, this
tree, REV, ...): only figures of one run compare (CONVENTIONS.md, "Testing"). Both use the installed
package, so REV may differ from this tree in its tests, docs and C++ sources, not in python/.

    python bench/shader_test_time.py --before HEAD --rounds 2 -k "cpp or fp16_header" test_codegen.py
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
CGROUPS = "/sys/fs/cgroup/cpuacct"


def checkout(rev, into):
    """REV's whole tree under ``into``, its build/ this checkout's."""
    archive = subprocess.run(["git", "-C", REPO, "archive", rev], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", into], input=archive, check=True)
    os.symlink(os.path.join(REPO, "build"), os.path.join(into, "build"))


def run(label, root, files, select, mesa_cache, env_extra=None):
    """One pytest process over ``files`` under ``root`` (``env_extra`` added to its environment):
    (its line of figures, exit status)."""
    env = dict(os.environ, **(env_extra or {}))
    if not mesa_cache:
        env["MESA_SHADER_CACHE_DISABLE"] = "true"
    cmd = [sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider", "--durations=0",
           *(["-k", select] if select else []), *[os.path.join("tests", "python", f) for f in files]]
    group = os.path.join(CGROUPS, f"hbrdf-test-time-{os.getpid()}")
    try:
        os.mkdir(group)
    except OSError:
        group = None

    def enter():  # in the child: into the cgroup before pytest starts anything
        if group:
            with open(os.path.join(group, "cgroup.procs"), "w") as f:
                f.write(str(os.getpid()))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.monotonic()
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
    return (f"{label}: {' '.join(files)}: {summary} | CPU {cpu:.1f} s ({how}) | test time {durations:.1f} s | "
            f"wall {wall:.1f} s | load {' '.join(load)} | {time.strftime('%H:%M', time.gmtime())} UTC"), r.returncode


def interleaved(before, rounds, groups, run_group):
    """``run_group(label, root, files)`` for each group of files, round after round, REV ``before``'s
    tree (when given) before this one's; prints each line; 1 if any run failed, else 0."""
    # beside this checkout, so that REV's tests find ../shared/data as this tree's do
    with tempfile.TemporaryDirectory(prefix="hbrdf-test-time-", dir=os.path.dirname(REPO)) as scratch:
        roots = [("this tree", REPO)]
        if before:
            checkout(before, scratch)
            roots.insert(0, (before, scratch))
        failed = 0
        for k in range(rounds):
            for files in groups:
                for label, root in roots:
                    line, code = run_group(f"round {k + 1}, {label}", root, files)
                    print(line, flush=True)
                    failed |= code
    return 1 if failed else 0


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("files", nargs="+", metavar="FILE", help="test files of tests/python (test_codegen.py)")
    p.add_argument("-k", dest="select", help="pytest's -k: only the tests whose names match")
    p.add_argument("--together", action="store_true", help="all FILEs in one pytest process (default: one each)")
    p.add_argument("--before", metavar="REV", help="also run REV's tree, interleaved with this one's")
    p.add_argument("--rounds", type=int, default=1, help="rounds (REV's run, then this tree's; default 1)")
    p.add_argument("--mesa-cache", action="store_true", help="keep Mesa's shader cache on")
    a = p.parse_args(argv)
    if a.rounds < 1:
        p.error(f"--rounds {a.rounds}: must be at least 1")
    missing = [f for f in a.files if not os.path.isfile(os.path.join(REPO, "tests", "python", f))]
    if missing:
        p.error(f"no such file in tests/python: {', '.join(missing)}")
    groups = [a.files] if a.together else [[f] for f in a.files]
    return interleaved(a.before, a.rounds, groups,
                       lambda label, root, files: run(label, root, files, a.select, a.mesa_cache))


if __name__ == "__main__":
    sys.exit(main())
