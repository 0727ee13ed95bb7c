"""Front doors (issue 57): ``import hybridbrdf`` and ``hbrdf --help`` or a mistyped command line
import no PyTorch. Importing torch costs 2-3 s of CPU; the CLI tests start ``hbrdf`` in
subprocesses dozens of times, and a user's typo should be answered at once.

Each case runs a fresh interpreter: this one has imported torch long ago."""

import subprocess
import sys

import pytest

NO_TORCH = "assert 'torch' not in sys.modules, sorted(m for m in sys.modules if m.startswith('hybridbrdf'))"


def python(code: str):
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)


def test_import_hybridbrdf_imports_no_torch():
    r = python(f"import sys, hybridbrdf\n{NO_TORCH}\n"
               "assert set(hybridbrdf.__all__) <= set(dir(hybridbrdf))\n"
               "from hybridbrdf import add\n"  # a lazy name still imports, and brings torch with it
               "assert callable(add) and 'torch' in sys.modules and hybridbrdf.add is add")
    assert r.returncode == 0, r.stderr


def test_a_model_file_loads_without_torch():
    r = python("import sys, hybridbrdf\nm = hybridbrdf.load_model(hybridbrdf.prior_path())\n"
               "assert m.materials and m.albedo(0, samples=64)['max'] > 0\n" + NO_TORCH)
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("argv,code", [(["--help"], 0), (["fit", "--help"], 0), (["acquire", "fit", "--help"], 0),
                                       (["fit", "--no-such-flag"], 2), (["nosuchcommand"], 2),
                                       (["render", "scene.json"], 2), (["info", "--albedo-samples", "x", "m"], 2)])
def test_help_and_argument_errors_import_no_torch(argv, code):
    r = python(f"import sys\nfrom hybridbrdf.cli import main\nsys.argv = ['hbrdf'] + {argv!r}\n"
               f"try:\n    main()\nexcept SystemExit as exc:\n    assert exc.code == {code}, exc.code\n"
               f"else:\n    raise AssertionError('no exit')\n{NO_TORCH}")
    assert r.returncode == 0, r.stderr[-2000:]
    assert ("usage: hbrdf" in r.stdout) if code == 0 else ("error:" in r.stderr)


def test_python_m_hybridbrdf_cli_imports_no_torch_for_help():
    r = subprocess.run([sys.executable, "-X", "importtime", "-m", "hybridbrdf.cli", "--help"], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0 and "usage: hbrdf" in r.stdout, r.stderr[-2000:]
    imported = [line.rsplit("|", 1)[-1].strip() for line in r.stderr.splitlines() if line.startswith("import time:")]
    assert "hybridbrdf.cli" in imported and not [m for m in imported if m.split(".")[0] == "torch"]
