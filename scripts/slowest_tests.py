#!/usr/bin/env python3
"""The slowest tests of a pytest JUnit report (scripts/test.sh prints them after its stages).

    python scripts/slowest_tests.py REPORT.xml [N]

Prints N (default 15) lines ``seconds  test id``, slowest first, then one line with the number of
tests and the sum of their times (setup, call and teardown: pytest's ``time`` attribute). With
several xdist workers the sum exceeds the wall time. A missing or unreadable report is one line on
stderr and exit status 1."""

import sys
import xml.etree.ElementTree as ET


def slowest(path: str, n: int):
    """(rows, count, total): the ``n`` slowest (seconds, id) of the report, the number of test
    cases and the sum of their seconds."""
    root = ET.parse(path).getroot()
    rows = []
    for case in root.iter("testcase"):
        module = case.get("classname", "").replace(".", "/")
        rows.append((float(case.get("time", 0.0)), f"{module}.py::{case.get('name', '')}"))
    rows.sort(key=lambda r: -r[0])
    return rows[:n], len(rows), sum(r[0] for r in rows)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv or len(argv) > 2:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    try:
        n = int(argv[1]) if len(argv) > 1 else 15
        rows, count, total = slowest(argv[0], n)
    except (OSError, ET.ParseError, ValueError) as e:
        print(f"slowest_tests: {argv[0]}: {e}", file=sys.stderr)
        return 1
    for seconds, name in rows:
        print(f"{seconds:8.1f} s  {name}")
    print(f"{count} tests, {total:.0f} s of test time in all")
    return 0


if __name__ == "__main__":
    sys.exit(main())
