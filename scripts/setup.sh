#!/usr/bin/env bash
# Installs everything hybridbrdf needs on a fresh Debian 12 machine, then the
# package itself (with its test extras). Idempotent; run from anywhere.
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi

apt_packages=(
  build-essential cmake ninja-build pkg-config
  ccache                           # compiles shared by the build trees (CMakeLists.txt, HBRDF_CCACHE)
  libglm-dev                       # vector math in libhybridbrdf
  libembree-dev                    # Embree 3: the reference path tracer
  glslang-tools spirv-tools        # shader validation
  mesa-vulkan-drivers libvulkan-dev vulkan-validationlayers   # lavapipe + loader + validation layer
  doctest-dev                      # C++ unit tests
  valgrind                         # the speed guard counts instructions under callgrind (bench/speed_guard.py)
  nlohmann-json3-dev               # model-file header parsing in libhybridbrdf
  libassimp-dev libtinyexr-dev libstb-dev   # the path tracer: OBJ/PLY meshes, EXR and HDR/PNG images
  libllvm19                        # Mitsuba's llvm_ad_rgb (the plugin's tests): Dr.Jit needs LLVM >= 16 here
  chromium                         # hbrdf view's page in a real browser (tests/python/test_view.py, SwiftShader WebGL2)
)
missing=()
for p in "${apt_packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" > /dev/null
fi

PY=${PYTHON:-python3}
# torch first, pinned: an unpinned torch would pull a multi-GB CUDA build. The
# package itself only declares a range, which this satisfies. (Read from its metadata: importing
# torch to ask would cost seconds of every run.)
if ! "$PY" -c 'import importlib.metadata as m, sys; sys.exit(m.version("torch").split("+")[0] != "2.13.0")' 2>/dev/null; then
  echo "setup: installing torch==2.13.0 (CPU)"
  "$PY" -m pip install -q "torch==2.13.0"
fi
# slangc for the Slang target's tests (tests/python/slang_wgsl_tools.py): the slangtorch wheel ships
# it; --no-deps because its own requirements (torch, ninja, hatchling) serve its PyTorch extension
# builder, which is not used. (wgpu, for the WGSL target's tests, is among the test extras.)
if ! "$PY" -c 'import importlib.metadata as m, sys; sys.exit(m.version("slangtorch") != "1.3.22")' 2>/dev/null; then
  echo "setup: installing slangtorch==1.3.22 (for slangc, without its dependencies)"
  "$PY" -m pip install -q --no-deps "slangtorch==1.3.22"
fi
# The package: nothing to do when the installed hybridbrdf was built from exactly this tree's sources
# and toolchain (the hash its build recorded in the wheel, scripts/source_hash.py) and every
# requirement of hybridbrdf[test] and of the build is installed. A change of any source the wheel is
# built from reinstalls (tests/python/test_setup_skip.py).
if check=$("$PY" scripts/source_hash.py --check 2>&1); then
  echo "setup: skipping pip install: ${check#source hash: }"
else
  echo "setup: building and installing hybridbrdf: ${check#source hash: }"
  "$PY" -m pip install -q "scikit-build-core>=0.10" "pybind11>=2.12"
  # No build isolation: reuses build-py/ for incremental rebuilds and the
  # scikit-build-core/pybind11 installed just above.
  "$PY" -m pip install -q --no-build-isolation ".[test]"
fi
echo "setup: done ($("$PY" -c 'import hybridbrdf as h; print("hybridbrdf", h.__version__, "simd", h.simd_path())'))"
