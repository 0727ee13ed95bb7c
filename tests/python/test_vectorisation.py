"""The batched kernels' hot loops vectorise, by the compiler's own report.

f_a's batched kernel once ran 7x slower with every test green: a refactor made GCC
copy a struct as an aggregate inside the loop body, and the loop stopped vectorising.
Speed is guarded by bench/speed_guard.py (ratios measured in one run); this test
names the cause. It compiles the kernels' translation units with the library's flags and
GCC's ``-fopt-info-vec-optimized`` and requires, for each loop marked
``// vectorises: NAME`` in the source, a "loop vectorized" line at that loop for every vector
width its instantiations must use (16 bytes: the baseline x86-64 kernel; 32: AVX2+FMA; 64:
AVX-512)."""

import pathlib
import re
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]

# Loop name -> vector widths (bytes) that must be reported at it.
REQUIRED = {
    "cpp/src/batch.cpp": {
        "eval_soa": {16, 32},       # f_a inlined whole; SoA in and out
        "aos_to_soa": {16, 32},     # the AoS kernels' transposes around it (eval and pdf)
        "soa_to_aos": {16, 32},
        "sample_soa": {16, 32},     # MIS/GGX/cosine sampling: both warps per lane, polynomial sincos
        "sample_aos_to_soa": {16, 32},
        "sample_soa_to_aos": {16, 32},
        "pdf_soa": {16, 32},
    },
    "cpp/src/model_batch.cpp": {
        "dense_portable": {16},     # the baseline layer kernel (the AVX2/AVX-512 ones are intrinsics)
        "normalise_rows": {16, 32, 64},
        "analytic_rows": {16, 32, 64},
        "half_angle_rows": {16, 32, 64},
        "reciprocal_rows": {16, 32, 64},
        "neural_frames": {16, 32, 64},
        "soa_to_aos": {16, 32, 64},
    },
}

pytestmark = pytest.mark.skipif(shutil.which("g++") is None, reason="needs GCC (-fopt-info)")


def library_flags():
    """The library's Release flags, as the speed guard reads them from CMakeLists.txt, and -fPIC."""
    sys.path.insert(0, str(ROOT / "bench"))
    try:
        from speed_guard import library_flags as release_flags
    finally:
        sys.path.pop(0)
    return release_flags() + ["-fPIC"]


def marked_loops(path: pathlib.Path):
    """{name: line of the loop} for each '// vectorises: NAME' comment (the loop is the next line)."""
    out = {}
    for i, line in enumerate(path.read_text().splitlines(), start=1):
        m = re.search(r"// vectorises: (\w+)", line)
        if m:
            out[m.group(1)] = i + 1
    return out


def vectorised_widths(source: str, tmp_path):
    """{line: set of vector widths in bytes} from GCC's report on ``source``."""
    r = subprocess.run(["g++", *library_flags(), "-I", str(ROOT / "cpp/include"), "-c", str(ROOT / source),
                        "-o", str(tmp_path / "k.o"), "-fopt-info-vec-optimized"],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-3000:]
    name = pathlib.Path(source).name
    widths = {}
    for m in re.finditer(rf"{re.escape(name)}:(\d+):\d+: optimized: loop vectorized using (\d+) byte vectors",
                         r.stderr):
        widths.setdefault(int(m.group(1)), set()).add(int(m.group(2)))
    return widths


@pytest.mark.parametrize("source", sorted(REQUIRED))
def test_marked_loops_vectorise(source, tmp_path):
    loops = marked_loops(ROOT / source)
    assert set(loops) == set(REQUIRED[source]), f"{source}: marked loops {sorted(loops)}, table {sorted(REQUIRED[source])}"
    widths = vectorised_widths(source, tmp_path)
    missing = {name: sorted(REQUIRED[source][name] - widths.get(line, set()))
               for name, line in loops.items() if REQUIRED[source][name] - widths.get(line, set())}
    assert not missing, (f"{source}: loops that no longer vectorise (name: missing widths in bytes): {missing}; "
                         f"rerun g++ with -fopt-info-vec-missed to see why")
