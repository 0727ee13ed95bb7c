"""scripts/test.sh, the README's test command: every stage runs even after one fails, each
reports a summary line, and the command exits non-zero when any failed.

The ctest stage is made to fail for real: the C++ suite's deliberate_failure_probe case
(tests/cpp/CMakeLists.txt) fails when HBRDF_DELIBERATE_FAILURE=1. The Python stage then runs a
probe (tests/data/test_script/probe_stage.py) that writes a file, so the test sees that pytest
ran after the failed ctest."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "test.sh"
PROBE = ROOT / "tests" / "data" / "test_script" / "probe_stage.py"


@pytest.fixture
def build_tree():
    """Skips without the Release build tree (its ctest file); HBRDF_REQUIRE_BUILD=1 (scripts/test.sh,
    which builds it first) turns the skip into a failure."""
    if (ROOT / "build" / "CTestTestfile.cmake").exists():
        return
    why = f"needs the Release build tree ({ROOT / 'build'}; scripts/test.sh builds it first)"
    if os.environ.get("HBRDF_REQUIRE_BUILD") == "1":
        pytest.fail(f"{why}; HBRDF_REQUIRE_BUILD=1 does not allow skipping it", pytrace=False)
    pytest.skip(why)


needs_build = pytest.mark.usefixtures("build_tree")


def run_script(tmp_path, **env):
    settings = dict(HBRDF_TEST_SETUP="0", HBRDF_PROBE_FILE=str(tmp_path / "probe"),
                    PYTEST_ARGS=f"-q -p no:cacheprovider {PROBE}")
    settings.update(env)
    return subprocess.run(["bash", str(SCRIPT)], capture_output=True, text=True, timeout=600,
                          env=dict(os.environ, **settings))


def summary(r):
    lines = r.stdout.split("== summary ==\n", 1)
    assert len(lines) == 2, r.stdout[-3000:] + r.stderr[-3000:]
    return lines[1]


@needs_build
def test_a_failed_ctest_does_not_stop_pytest_and_the_command_fails(tmp_path):
    r = run_script(tmp_path, HBRDF_TEST_STAGES="ctest python", CTEST_ARGS="-R ^deliberate_failure_probe$",
                   HBRDF_DELIBERATE_FAILURE="1")
    assert r.returncode == 1, r.stdout[-3000:] + r.stderr[-3000:]
    assert "deliberate_failure_probe" in r.stdout and "(Failed)" in r.stdout
    assert (tmp_path / "probe").read_text() == "python stage ran\n"
    text = summary(r)
    assert "test: ctest      FAILED" in text
    assert "test: python     passed" in text
    assert "test: FAILED" in text


@needs_build
def test_the_same_stages_pass_without_the_deliberate_failure(tmp_path):
    r = run_script(tmp_path, HBRDF_TEST_STAGES="ctest python", CTEST_ARGS="-R ^deliberate_failure_probe$",
                   HBRDF_DELIBERATE_FAILURE="")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    text = summary(r)
    assert "test: ctest      passed" in text and "test: python     passed" in text
    assert "test: all stages passed" in text


def test_a_failed_python_stage_fails_the_command(tmp_path):
    r = run_script(tmp_path, HBRDF_TEST_STAGES="python", HBRDF_PROBE_FILE=str(tmp_path / "missing" / "probe"))
    assert r.returncode == 1
    assert "test: python     FAILED" in summary(r)


def test_an_unknown_stage_is_refused(tmp_path):
    r = run_script(tmp_path, HBRDF_TEST_STAGES="ctest lint")
    assert r.returncode == 2
    assert "unknown stage 'lint'" in r.stderr


def test_the_python_stage_prints_its_slowest_tests_and_warns_over_its_budget(tmp_path):
    """After the stages: the slowest tests of the Python stage (here the probe alone) and their total;
    a warning line, not a failure, when the stage took longer than its budget, and none within it."""
    junit = str(tmp_path / "junit.xml")
    over = run_script(tmp_path, HBRDF_TEST_STAGES="python", HBRDF_PYTHON_BUDGET_S="0", HBRDF_JUNIT=junit)
    assert over.returncode == 0, over.stdout[-3000:] + over.stderr[-3000:]
    slowest = over.stdout.split("== slowest tests ==\n", 1)[1].split("\n\n", 1)[0].splitlines()
    assert slowest[0].endswith(" s  tests/data/test_script/probe_stage.py::test_the_python_stage_ran"), slowest
    assert slowest[1].startswith("1 tests, ") and slowest[1].endswith(" s of test time in all"), slowest
    warning = [ln for ln in over.stdout.splitlines() if ln.startswith("test: WARNING: the python stage took")]
    assert len(warning) == 1 and "over its budget of 0 s" in warning[0], over.stdout[-2000:]
    assert "test: all stages passed" in summary(over)
    within = run_script(tmp_path, HBRDF_TEST_STAGES="python", HBRDF_PYTHON_BUDGET_S="100000", HBRDF_JUNIT=junit)
    assert within.returncode == 0 and "== slowest tests ==" in within.stdout
    assert "WARNING" not in within.stdout, within.stdout[-2000:]
