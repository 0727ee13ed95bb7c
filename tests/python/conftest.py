"""Fixtures of the Python test suite. Plain helpers shared by the tests live in helpers.py."""

import os

# Under pytest-xdist (scripts/test.sh runs one worker per core) each worker gets its share of the
# cores for torch's and OpenMP's thread pools, and so do the processes it starts (the CLI tests):
# two workers each running two spinning OpenMP threads on two cores made the fitting tests 3-10x
# slower than alone. Set before torch is imported anywhere in the worker.
if "PYTEST_XDIST_WORKER_COUNT" in os.environ:
    _threads = str(max(1, (os.cpu_count() or 1) // int(os.environ["PYTEST_XDIST_WORKER_COUNT"])))
    for _name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, _threads)

import numpy as np  # noqa: E402
import pytest  # noqa: E402


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def pytest_collection_modifyitems(config, items):
    """Tests marked ``slow`` (pyproject.toml: more than a few seconds) run first. pytest-xdist's
    worksteal gives each worker a share of the list and lets an idle worker take half of another's
    remaining tests; a long test left at the end of a share would set the wall time alone, so the
    long ones start first and the short ones fill in around them. The order within each group is
    pytest's."""
    items[:] = sorted(items, key=lambda item: item.get_closest_marker("slow") is None)
