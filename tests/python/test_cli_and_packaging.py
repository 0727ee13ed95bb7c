"""The hbrdf command line and packaging facts (versions agree everywhere)."""

import pathlib
import re
import subprocess
import sys

import numpy as np

import hybridbrdf as hb

ROOT = pathlib.Path(__file__).resolve().parents[2]


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "hybridbrdf.cli", *args], capture_output=True, text=True)


def test_demo_writes_a_png(tmp_path):
    out = tmp_path / "sub" / "slices.png"
    r = run_cli("demo", "--out", str(out), "--samples", "2000")
    assert r.returncode == 0, r.stderr
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    assert "wrote" in r.stdout
    # The demo's own check of C++ float32 against PyTorch float64.
    m = re.search(r"PyTorch float64 on the slices: ([0-9.e+-]+)", r.stdout)
    assert m and float(m.group(1)) < 2e-4
    assert not list(out.parent.glob("*.png.tmp*")) and len(list(out.parent.iterdir())) == 1


def test_bad_arguments_give_one_line_and_nonzero_exit(tmp_path):
    r = run_cli("demo", "--out", str(tmp_path / "x.png"), "--samples", "0")
    assert r.returncode != 0
    assert r.stderr.strip().count("\n") == 0 and "samples" in r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "x.png").exists()


def test_versions_agree():
    pyproject = (ROOT / "pyproject.toml").read_text()
    cmake = (ROOT / "CMakeLists.txt").read_text()
    header = (ROOT / "cpp/include/hybridbrdf/version.hpp").read_text()
    v_py = re.search(r'^version = "([^"]+)"', pyproject, re.M).group(1)
    v_cmake = re.search(r"project\(hybridbrdf VERSION ([0-9.]+)", cmake).group(1)
    v_hdr = re.search(r'kVersion = "([^"]+)"', header).group(1)
    assert v_py == v_cmake == v_hdr == hb.__version__ == hb._core.__version__


def test_alpha_min_is_one_constant():
    header = (ROOT / "cpp/include/hybridbrdf/params.hpp").read_text()
    assert float(re.search(r"kAlphaMin = ([0-9.e-]+);", header).group(1)) == hb.ALPHA_MIN == 1e-4
    p = hb.AnalyticParams(alpha=hb.ALPHA_MIN)
    f = hb.analytic_eval(np.array([[0.0, 0, 1]]), np.array([[0.0, 0, 1]]), p)
    assert np.isfinite(f).all() and f[0, 0] > 1e5  # a near-mirror lobe, still finite
