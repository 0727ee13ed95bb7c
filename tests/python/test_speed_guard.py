"""The speed guard (bench/speed_guard.py, run by CI) can fail, on the regressions it exists for.

A guard that always passes guards nothing. It counts each kernel's instructions per evaluation
under callgrind, so its verdict is the same on every x86-64 CPU; these tests require it to fail
(exit 1, naming the ratios and their floors) on
- HBRDF_SIMD=baseline: every batched kernel the baseline one, as after a change that loses the
  vector kernels;
- the struct-return regression (tests/data/speed_guard/struct_return_regression.patch applied to a
  copy of the C++ tree, whose f_a kernels' translation unit is recompiled into a copy of
  build/libhybridbrdf.a): the change that once stopped f_a's loop vectorising with every test green.
That it passes on a healthy tree is what CI's own run of it shows (scripts/test.sh's speed-guard stage).

Without the build tree or valgrind the guard's tests skip, unless HBRDF_REQUIRE_BUILD=1 (scripts/test.sh's
python stage): then they fail."""

import os
import pathlib
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
GUARD = ROOT / "bench" / "speed_guard.py"
PATCH = ROOT / "tests" / "data" / "speed_guard" / "struct_return_regression.patch"



@pytest.fixture
def guard_tools():
    """Skips without the Release build tree or valgrind; HBRDF_REQUIRE_BUILD=1 (scripts/test.sh,
    where both are always there) turns the skip into a failure, so that a full test run cannot
    pass without these tests having run."""
    missing = []
    if not (ROOT / "build" / "libhybridbrdf.a").exists():
        missing.append(f"the Release build tree ({ROOT / 'build'}; scripts/test.sh builds it first)")
    if shutil.which("valgrind") is None:
        missing.append("valgrind (scripts/setup.sh installs it)")
    if not missing:
        return
    why = "the speed guard's tests need " + " and ".join(missing)
    if os.environ.get("HBRDF_REQUIRE_BUILD") == "1":
        pytest.fail(f"{why}; HBRDF_REQUIRE_BUILD=1 does not allow skipping them", pytrace=False)
    pytest.skip(why)


def run_guard(*args, **env):
    # 1,024 pairs (the guard's least; CI's run counts 4,096): the counts are steady-state differences
    # (2N less N pairs), within 8% of 4,096's, while the regressions below take ratios from 2.5-4.3
    # to 1.0-1.4; callgrind runs 3 s instead of 8.
    return subprocess.run([sys.executable, str(GUARD), "--pairs", "1024", *args], capture_output=True, text=True,
                          env=dict(os.environ, **env), timeout=900)


def failed_ratios(r):
    failed = [ln for ln in r.stderr.splitlines() if ln.startswith("speed guard: FAILED: ")]
    assert failed and all("below its floor" in ln for ln in failed), r.stdout + r.stderr
    return " ".join(failed)


def test_the_guard_fails_when_the_vector_kernels_are_lost(guard_tools):
    r = run_guard(HBRDF_SIMD="baseline")
    assert r.returncode == 1, r.stdout + r.stderr
    assert "kernels baseline (f_a) / baseline (model)" in r.stdout
    names = failed_ratios(r)
    # Each vector kernel's instruction ratio to its baseline collapses to ~1, below its floor, and says so.
    for ratio in ("f_a eval SoA: baseline / AVX2+FMA kernel instructions",
                  "f_a eval AoS: baseline / AVX2+FMA kernel instructions",
                  "f_a MIS sampling: baseline / AVX2+FMA kernel instructions",
                  "hybrid batched: baseline / AVX2+FMA kernel instructions",
                  "hybrid 32x2 batched, AVX2+FMA kernel: flops per instruction"):
        assert ratio in names, r.stderr


# The translation unit of libhybridbrdf that holds every kernel whose ratio the struct-return test
# names: f_a's SoA and AoS kernels (batch.cpp). The patch reaches the hybrid kernels too
# (model.cpp, model_batch.cpp and svbrdf.cpp include analytic.hpp), but no assertion reads their
# ratios, and recompiling them cost 17 of the test's ~26 s of CPU (g++ 1.7 + 10.0 + 5.7 s against
# batch.cpp's 8.5; four units until 2026-11-29). A unit missing here after code moves cannot make the
# test pass wrongly: its healthy object would be counted, the guard would pass, and the test fails.
KERNEL_UNITS = ("batch.cpp",)


def patched_library(source: pathlib.Path, work: pathlib.Path) -> pathlib.Path:
    """build/libhybridbrdf.a with KERNEL_UNITS recompiled from ``source`` at the library's own
    flags (bench/speed_guard.py's library_flags, the ones CMake uses, plus -fPIC): what a full
    rebuild of the patched tree gives the kernels the test reads, at a fraction of its compile time."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("speed_guard", GUARD)
    guard = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = guard  # its dataclasses look their module up there
    spec.loader.exec_module(guard)
    flags = guard.library_flags(source) + ["-fPIC", "-I", str(source / "cpp" / "include")]
    compiles = [subprocess.Popen(["g++", *flags, "-c", str(source / "cpp" / "src" / unit),
                                  "-o", str(work / f"{unit}.o")], stderr=subprocess.PIPE, text=True)
                for unit in KERNEL_UNITS]
    for unit, c in zip(KERNEL_UNITS, compiles):
        assert c.wait(timeout=600) == 0, f"{unit} of the patched copy does not compile: {c.stderr.read()}"
    library = work / "libhybridbrdf.a"
    shutil.copy(ROOT / "build" / "libhybridbrdf.a", library)
    members = subprocess.run(["ar", "t", str(library)], capture_output=True, text=True, check=True).stdout.split()
    assert all(f"{unit}.o" in members for unit in KERNEL_UNITS), (
        f"build/libhybridbrdf.a's members {members} no longer include every one of {KERNEL_UNITS}")
    subprocess.run(["ar", "r", str(library), *(f"{unit}.o" for unit in KERNEL_UNITS)], cwd=work, check=True)
    return library


@pytest.mark.slow
def test_the_guard_fails_on_the_struct_return_regression(tmp_path, guard_tools):
    source = tmp_path / "src"
    source.mkdir()
    shutil.copy(ROOT / "CMakeLists.txt", source)
    shutil.copytree(ROOT / "cpp", source / "cpp")
    applied = subprocess.run(["git", "apply", str(PATCH)], cwd=source, capture_output=True, text=True)
    assert applied.returncode == 0, (
        f"{PATCH.name} no longer applies to cpp/ (re-make it against the current analytic.hpp): {applied.stderr}")
    r = run_guard("--source", str(source), "--library", str(patched_library(source, tmp_path)))
    assert r.returncode == 1, r.stdout + r.stderr
    names = failed_ratios(r)
    for ratio in ("f_a eval SoA: baseline / AVX2+FMA kernel instructions",
                  "f_a eval AoS: baseline / AVX2+FMA kernel instructions",
                  "f_a eval SoA, AVX2+FMA kernel: evaluations per 1,000 instructions"):
        assert ratio in names, r.stderr


def test_an_unknown_simd_cap_is_reported_and_ignored():
    from hybridbrdf import _core

    r = subprocess.run([sys.executable, "-c", "from hybridbrdf import _core; print(_core.simd_path())"],
                       capture_output=True, text=True, env=dict(os.environ, HBRDF_SIMD="sse9"), timeout=60)
    assert r.returncode == 0
    assert "HBRDF_SIMD='sse9' is not avx512, avx2+fma or baseline; ignored" in r.stderr
    assert r.stdout.strip() == _core.simd_path()
