"""The Python stage's probe for tests/python/test_test_script.py (never collected by the suite:
its name does not start with test_). It records that scripts/test.sh reached pytest."""

import os
import pathlib


def test_the_python_stage_ran():
    path = pathlib.Path(os.environ["HBRDF_PROBE_FILE"])
    path.write_text("python stage ran\n")
    assert path.read_text() == "python stage ran\n"
