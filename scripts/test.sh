#!/usr/bin/env bash
# Runs every test: sets up first (idempotent), then
#   1. the C++ unit tests and the installed-package consumer (ctest, Release),
#   2. the speed guard: the kernels' speed ratios in one run against their floors
#      (bench/speed_guard.py; fails when a kernel stops vectorising),
#   3. the C++ unit tests again under AddressSanitizer + UndefinedBehaviorSanitizer,
#   4. the Python suite (pytest).
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/setup.sh
PY=${PYTHON:-python3}
JOBS=${JOBS:-$(nproc)}

echo "== C++ tests (Release) =="
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build build -j "$JOBS" > /dev/null
ctest --test-dir build --output-on-failure

echo "== Speed guard (Release build, one core) =="
"$PY" bench/speed_guard.py

echo "== C++ tests under ASan + UBSan =="
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DHBRDF_SANITIZE=address,undefined > /dev/null
cmake --build build-asan -j "$JOBS" --target hbrdf_tests hbrdf_render_tests > /dev/null
# Guard against a silently unsanitised build (a flag typo would pass everything).
# (grep reads all of nm's output: with -q and pipefail, nm's SIGPIPE would fail the check.)
symbols=$(nm -C build-asan/tests/cpp/hbrdf_tests)
grep __asan_init <<< "$symbols" > /dev/null || { echo "test: ASan build is not instrumented" >&2; exit 1; }
grep __ubsan_handle <<< "$symbols" > /dev/null || { echo "test: UBSan build is not instrumented" >&2; exit 1; }
# The consumer test links an installed static library and is not sanitised. The renderer's
# tests run too (Embree, TBB and assimp are not instrumented; tests/cpp/lsan.supp says which
# third-party leak is suppressed and why).
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  LSAN_OPTIONS=suppressions=$PWD/tests/cpp/lsan.supp \
  ctest --test-dir build-asan --output-on-failure -R "cpp_unit_tests|cpp_render_tests"

echo "== Python tests =="
HBRDF_REQUIRE_VULKAN=1 HBRDF_REQUIRE_BROWSER=1 HBRDF_REQUIRE_WEBGPU=1 "$PY" -m pytest tests/python
