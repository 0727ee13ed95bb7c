#!/usr/bin/env bash
# Runs every test. Each stage runs even when an earlier one failed, so that one run shows all
# that is wrong; the run ends with one summary line per stage and exits 1 if any failed.
#   setup       scripts/setup.sh (idempotent; its pip install only when the installed package was not
#               built from this tree, scripts/source_hash.py; HBRDF_TEST_SETUP=0 skips the stage)
#   build       the Release build (libhybridbrdf, tools, C++ tests, renderer; Ninja, and ccache when
#               installed, which hands it the objects setup's wheel build compiled alike)
#   ctest       the C++ unit tests and the installed-package consumer
#   guard       the speed guard: each kernel's instructions per evaluation under callgrind,
#               as ratios against floors (bench/speed_guard.py; fails when a kernel stops vectorising)
#   sanitizers  the C++ unit tests again under AddressSanitizer + UndefinedBehaviorSanitizer
#   python      the Python suite (pytest on every core: pytest-xdist)
# HBRDF_TEST_STAGES="build ctest ..." runs a subset (default: all, in the order above);
# PYTEST_ARGS replaces pytest's arguments (default: tests/python -n JOBS); CTEST_ARGS adds to ctest's.
# Before the summary: the Python stage's 15 slowest tests and their total (from pytest's JUnit report,
# written to HBRDF_JUNIT, default build/pytest-junit.xml), and a warning line (not a failure) when the
# stage took longer than PYTHON_BUDGET_S, the budget the README states (HBRDF_PYTHON_BUDGET_S overrides it).
set -uo pipefail
cd "$(dirname "$0")/.."

PY=${PYTHON:-python3}
JOBS=${JOBS:-$(nproc)}
STAGES=${HBRDF_TEST_STAGES:-setup build ctest guard sanitizers python}
# The Python stage's budget in seconds, as the README states it (2-core machine, fresh clone).
PYTHON_BUDGET_S=${HBRDF_PYTHON_BUDGET_S:-420}
JUNIT=${HBRDF_JUNIT:-build/pytest-junit.xml}
python_seconds=
python_ms=  # the Python stage's wall time in milliseconds, for the budget (whole seconds would let a
            # stage of 0.6 s pass a budget of 0 s: test_test_script's probe on a fast machine)
if [ "${HBRDF_TEST_SETUP:-1}" = 0 ]; then STAGES=${STAGES//setup/}; fi

stage_setup() { bash scripts/setup.sh; }

# Configures build tree $1 with the rest as cmake's arguments. A new tree gets Ninja when it is
# installed (scripts/setup.sh installs it: it schedules both cores across targets) and, unless $CXX
# names one, the C++ compiler Python's sysconfig names, which scikit-build-core builds the wheel with
# (g++ here, where CMake alone picks c++): ccache keys on the compiler's name too, so only then do
# build/'s library objects come from build-py/'s compiles (CMakeLists.txt, HBRDF_CCACHE). A tree
# configured before keeps its generator and compiler (cmake refuses to switch them).
configure() {
  local dir=$1 args=() cxx
  shift
  if [ ! -f "$dir/CMakeCache.txt" ]; then
    if command -v ninja > /dev/null; then args+=(-G Ninja); fi
    cxx=$("$PY" -c 'import sysconfig; print((sysconfig.get_config_var("CXX") or "").split(" -")[0])' 2>/dev/null)
    if [ -z "${CXX:-}" ] && [[ -n "$cxx" && "$cxx" != *" "* ]] && command -v "$cxx" > /dev/null; then
      args+=(-DCMAKE_CXX_COMPILER="$cxx")
    fi
  fi
  cmake -S . -B "$dir" "${args[@]}" "$@" > /dev/null
}

stage_build() {
  configure build -DCMAKE_BUILD_TYPE=Release && cmake --build build -j "$JOBS" > /dev/null
}

stage_ctest() {
  local args=()
  if [ -n "${CTEST_ARGS:-}" ]; then read -r -a args <<< "$CTEST_ARGS"; fi
  ctest --test-dir build --output-on-failure -j "$JOBS" "${args[@]}"
}

stage_guard() { "$PY" bench/speed_guard.py; }

stage_sanitizers() {
  # -O1 -g1: the optimisation level ASan's documentation recommends, with line tables for its stack
  # traces; it builds in half of -O2 -g's time (61 s against 130 s on 2 cores, one-off, 2026-11-27).
  # -O0 builds these two targets in 190 s of CPU against -O1's 324, but the sanitized tests then run
  # 3.5x longer (cpp_unit_tests 50 s of CPU against 14), which eats the saving on 2 cores. The cold
  # sources (the JSON readers and doctest's runner: CMakeLists.txt, HBRDF_SANITIZE_COLD_OPTIONS) are
  # compiled at -Og, still instrumented: 311 s of CPU for the build against 389 s, and the tests'
  # CPU unchanged (X1 under load, back to back, 2026-11-29; docs/CONVENTIONS.md, "Testing"). Since
  # then they are batched in one object per target, and they and the renderer tests' sources take
  # ASan's checks as calls (HBRDF_SANITIZE_TEST_OPTIONS): nlohmann's parser is instrumented once a target.
  # Without ccache: nothing else compiles these objects (and another clone's paths differ), so on a
  # fresh clone every compile would be a miss, paying ccache's preprocessor pass on top (the stage
  # took 521 s of CPU through a cold ccache against 391 s without, one run each under load).
  # A unity build (CMake's, batches of 8 sources): the headers' inline functions and templates (doctest's,
  # glm's, the library's own) are then instrumented and optimised once per batch, not once per source.
  # The same flags, warnings and instrumentation as one object per source; the cold sources keep their
  # own objects (a source with COMPILE_OPTIONS is left out of CMake's batches). Each source still
  # compiles alone in build/. Figures: docs/CONVENTIONS.md, "Testing".
  configure build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
    -DHBRDF_SANITIZE=address,undefined -DHBRDF_CCACHE=OFF -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=8 || return
  cmake --build build-asan -j "$JOBS" --target hbrdf_tests hbrdf_render_tests > /dev/null || return
  # Guard against a silently unsanitised build (a flag typo would pass everything).
  # (grep reads all of nm's output: with -q and pipefail, nm's SIGPIPE would fail the check.)
  local symbols
  symbols=$(nm -C build-asan/tests/cpp/hbrdf_tests) || return
  grep __asan_init <<< "$symbols" > /dev/null || { echo "test: ASan build is not instrumented" >&2; return 1; }
  grep __ubsan_handle <<< "$symbols" > /dev/null || { echo "test: UBSan build is not instrumented" >&2; return 1; }
  # The consumer test links an installed static library and is not sanitised. The renderer's
  # tests run too (Embree, TBB and assimp are not instrumented; tests/cpp/lsan.supp says which
  # third-party leak is suppressed and why). Four shards on both cores (tests/cpp/CMakeLists.txt):
  # 44 s wall against 63 s as three, back to back on X1.
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    LSAN_OPTIONS=suppressions=$PWD/tests/cpp/lsan.supp \
    ctest --test-dir build-asan --output-on-failure -j "$JOBS" -R "cpp_unit_tests|cpp_tabulated|cpp_render_tests"
}

# The Python suite: tests marked slow first (tests/python/conftest.py), handed to the workers one
# at a time as each becomes free (--dist load --maxschedchunk 1): the longest tests start at once
# on both workers, the short ones fill in around them, and no long test is left for the end.
stage_python() {
  local args
  if [ -n "${PYTEST_ARGS:-}" ]; then read -r -a args <<< "$PYTEST_ARGS"; else args=(tests/python -n "$JOBS" --dist load --maxschedchunk 1); fi
  mkdir -p "$(dirname "$JUNIT")" && rm -f "$JUNIT"
  HBRDF_REQUIRE_VULKAN=1 HBRDF_REQUIRE_BROWSER=1 HBRDF_REQUIRE_WEBGPU=1 HBRDF_REQUIRE_BUILD=1 \
    "$PY" -m pytest "${args[@]}" --junitxml="$JUNIT" -o junit_family=xunit1
}

for stage in $STAGES; do
  if ! declare -F "stage_$stage" > /dev/null; then
    echo "test: unknown stage '$stage' (stages: setup build ctest guard sanitizers python)" >&2
    exit 2
  fi
done

summary=()
failed=0
for stage in $STAGES; do
  echo "== $stage =="
  start=$SECONDS
  start_ms=$(date +%s%3N)
  "stage_$stage"
  rc=$?
  took=$((SECONDS - start))
  if [ "$stage" = python ]; then python_seconds=$took; python_ms=$(($(date +%s%3N) - start_ms)); fi
  if [ "$rc" = 0 ]; then
    summary+=("$(printf 'test: %-10s passed  %4d s' "$stage" "$took")")
  else
    summary+=("$(printf 'test: %-10s FAILED  %4d s (exit %d)' "$stage" "$took" "$rc")")
    failed=1
  fi
done

if [ -n "$python_seconds" ]; then
  echo
  echo "== slowest tests =="
  "$PY" scripts/slowest_tests.py "$JUNIT" 15 || true
  if [ "$python_ms" -gt $((PYTHON_BUDGET_S * 1000)) ]; then
    echo "test: WARNING: the python stage took $python_seconds s, over its budget of $PYTHON_BUDGET_S s (README; docs/CONVENTIONS.md, \"Testing\")"
  fi
fi

echo
echo "== summary =="
printf '%s\n' "${summary[@]}"
if [ "$failed" = 1 ]; then
  echo "test: FAILED (every stage above ran; see each FAILED one's output)"
  exit 1
fi
echo "test: all stages passed ($SECONDS s)"
