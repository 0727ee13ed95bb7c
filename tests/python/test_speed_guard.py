"""The speed guard (bench/speed_guard.py, run by CI) can fail.

A guard that always passes guards nothing: with HBRDF_SIMD=baseline every batched kernel is the
baseline one, as after a change that loses the vector kernels, and the guard must then exit 1
naming the vector kernels' ratios and their floors. (That it passes on a healthy tree is what
CI's own run of it shows: scripts/test.sh.)"""

import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
GUARD = ROOT / "bench" / "speed_guard.py"

pytestmark = pytest.mark.skipif(not (ROOT / "build" / "libhybridbrdf.a").exists(),
                                reason="needs the Release build tree (scripts/test.sh builds it first)")


def run_guard(**env):
    return subprocess.run([sys.executable, str(GUARD), "--pairs", "65536", "--rounds", "3"], capture_output=True,
                          text=True, env=dict(os.environ, **env), timeout=600)


def test_the_guard_fails_when_the_vector_kernels_are_lost():
    r = run_guard(HBRDF_SIMD="baseline")
    assert r.returncode == 1, r.stdout + r.stderr
    assert "kernels baseline (f_a) / baseline (model)" in r.stdout
    failed = [ln for ln in r.stderr.splitlines() if ln.startswith("speed guard: FAILED: ")]
    names = " ".join(failed)
    # Each vector kernel's ratio to its baseline collapses to ~1, below its floor, and says so.
    for ratio in ("f_a eval SoA: AVX2+FMA / baseline kernel", "f_a eval AoS: AVX2+FMA / baseline kernel",
                  "hybrid batched: best kernel / baseline kernel", "hybrid batched: AVX2+FMA kernel / baseline kernel"):
        assert ratio in names, r.stderr
    assert all("below its floor" in ln for ln in failed)


def test_an_unknown_simd_cap_is_reported_and_ignored():
    from hybridbrdf import _core

    r = subprocess.run([sys.executable, "-c", "from hybridbrdf import _core; print(_core.simd_path())"],
                       capture_output=True, text=True, env=dict(os.environ, HBRDF_SIMD="sse9"), timeout=60)
    assert r.returncode == 0
    assert "HBRDF_SIMD='sse9' is not avx512, avx2+fma or baseline; ignored" in r.stderr
    assert r.stdout.strip() == _core.simd_path()
