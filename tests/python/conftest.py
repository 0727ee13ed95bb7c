"""Fixtures of the Python test suite. Plain helpers shared by the tests live in helpers.py."""

import numpy as np
import pytest


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
