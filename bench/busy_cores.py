"""How many cores a command keeps busy: runs it and counts, every PERIOD seconds, the threads of its
process tree that are runnable (state R in /proc: running, or waiting for a core). A sample with
fewer runnable threads than cores is a moment the command leaves a core idle (a wait on a socket,
a timer, a child's start-up), whatever else runs on the machine; the share of such samples is
the headroom a restructured run (stages side by side, another pytest worker) could use.

Other work on a shared machine stretches the command's CPU phases but not its waits, so a loaded
machine understates the idle share by up to the load's factor (docs/CONVENTIONS.md, "Testing").

    python bench/busy_cores.py [--period S] [--cores N] -- COMMAND...
    e.g. python bench/busy_cores.py -- python -m pytest tests/python -n 2 --dist load --maxschedchunk 1

Prints the command's exit status, then the share of samples with 0, 1, 2 and more runnable
threads, the mean idle cores, and the programs the runnable threads belonged to.
"""

from __future__ import annotations

import argparse
import collections
import os
import subprocess
import sys
import time


def _processes() -> dict:
    """pid -> (parent pid, program name) of every process now, from /proc."""
    out = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        head, rest = stat.rsplit(")", 1)
        out[int(entry)] = (int(rest.split()[1]), head.split("(", 1)[1])
    return out


def _tree(root: int, procs: dict) -> set:
    """``root`` and every process whose chain of parents reaches it."""
    mine = {root}
    for pid in procs:
        chain, q = [], pid
        while q in procs and q not in mine and q > 1:
            chain.append(q)
            q = procs[q][0]
        if q in mine:
            mine.update(chain)
    return mine


def runnable(root: int) -> collections.Counter:
    """Runnable threads of ``root``'s process tree, counted by program name."""
    procs = _processes()
    count = collections.Counter()
    for pid in _tree(root, procs):
        try:
            for tid in os.listdir(f"/proc/{pid}/task"):
                with open(f"/proc/{pid}/task/{tid}/stat") as f:
                    if f.read().rsplit(")", 1)[1].split()[0] == "R":
                        count[procs.get(pid, (0, "?"))[1]] += 1
        except OSError:
            continue  # the process ended between the listing and the read
    return count


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--period", type=float, default=0.5, help="seconds between samples (default 0.5)")
    parser.add_argument("--cores", type=int, default=os.cpu_count(), help="cores to compare with (default: all)")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="the command, after --")
    args = parser.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("no command: give it after --")
    proc = subprocess.Popen(command)
    samples, names = [], collections.Counter()
    while proc.poll() is None:
        t = time.monotonic()
        count = runnable(proc.pid)
        samples.append(sum(count.values()))
        names.update(count)
        time.sleep(max(0.0, args.period - (time.monotonic() - t)))
    n = max(1, len(samples))
    shares = collections.Counter(min(s, args.cores + 1) for s in samples)
    print(f"busy_cores: exit {proc.returncode}, {len(samples)} samples every {args.period} s")
    print("busy_cores: runnable threads " + ", ".join(
        f"{k if k <= args.cores else f'>{args.cores}'}: {v / n:.1%}" for k, v in sorted(shares.items())))
    idle = sum(max(0, args.cores - s) for s in samples) / n
    print(f"busy_cores: mean runnable {sum(samples) / n:.2f}, mean idle cores {idle:.3f} of {args.cores}")
    print("busy_cores: by program " + ", ".join(f"{k} {v / n:.2f}" for k, v in names.most_common(8)))
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
