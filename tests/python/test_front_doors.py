"""Front doors (issue 57): ``import hybridbrdf`` and ``hbrdf --help`` or a mistyped command line
import no PyTorch, and no NumPy either. Importing torch costs 2-3 s of CPU and NumPy 0.1 s; the CLI
tests start ``hbrdf`` in subprocesses dozens of times, and a user's typo should be answered at once
(0.3 s at most; the measurements are in CHANGELOG.md: these tests check module sets, not times).

Each case runs a fresh interpreter: this one has imported torch long ago."""

import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
#: The packages whose __init__ is a public face (docs/ARCHITECTURE.md): every folder but the CLI's.
FACES = sorted(p.parent.name for p in (ROOT / "python" / "hybridbrdf").glob("*/__init__.py") if p.parent.name != "cli")

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


#: Command lines whose parsing needs no NumPy: ``hbrdf --help``, a mistyped command, and an argument
#: error of every command. The memory sizes and defaults that bound, info, demo, view and acquire
#: state in their help come from plain-Python modules (model/sizes.py, demo/sizes.py,
#: viewer/sizes.py, acquire/sizes.py; test_sizes_are_what_the_estimates_use below).
NO_NUMPY_ARGV = [["--help"], ["--version"], [], ["nosuchcommand"], ["fit", "--help"], ["fit", "--no-such-flag"],
                 ["fit", "a", "--out", "m", "--steps", "x"], ["add", "--x"], ["eval", "--x"], ["edit", "--x"],
                 ["mix", "--x"], ["paint", "--x"], ["render", "scene.json"], ["render", "--help"],
                 ["bound", "--x"], ["bound", "m", "--out", "o", "--samples", "0"], ["info", "--x"],
                 ["info", "--albedo-samples", "x", "m"], ["demo", "--x"], ["demo", "--help"], ["view", "--x"],
                 ["view", "m", "--source-size", "x", "-o", "p.html"], ["acquire", "--x"], ["acquire", "simulate", "--x"],
                 ["acquire", "simulate", "--flash", "0", "--base", "s", "--out", "d"], ["acquire", "fit", "--x"],
                 ["acquire", "fit", "c", "--out", "d", "--steps", "0"], ["acquire", "--help"], ["convert", "--x"]]


@pytest.mark.parametrize("argv", NO_NUMPY_ARGV, ids=lambda a: " ".join(a) or "nothing")
def test_help_and_argument_errors_import_no_numpy(argv):
    """hbrdf's start-up is Python's and argparse's (issue 57: 0.3 s at most): ``import hybridbrdf``
    loads no NumPy (0.1 s) and the command line builds only the named command's parser."""
    r = python(f"import sys\nfrom hybridbrdf.cli import main\ntry:\n    main({argv!r})\nexcept SystemExit as exc:\n"
               f"    assert exc.code in (0, 2), exc.code\nelse:\n    raise AssertionError('no exit')\n"
               "heavy = sorted(m for m in ('numpy', 'torch', 'PIL', 'jinja2') if m in sys.modules)\n"
               "assert not heavy, (heavy, sorted(m for m in sys.modules if m.startswith('hybridbrdf')))")
    assert r.returncode == 0, r.stderr[-2000:]


def test_only_the_named_command_is_built_and_help_is_unchanged():
    """``main`` builds the named command's parser only (the others are placeholders of their name
    and line): ``hbrdf --help`` and each command's help read as with every parser built."""
    from hybridbrdf.cli import COMMANDS, build_parser

    full = build_parser()
    assert build_parser(only="").format_help() == full.format_help()
    commands = next(a for a in full._actions if a.dest == "command").choices
    assert list(commands) == list(COMMANDS)
    for name in COMMANDS:
        lazy = next(a for a in build_parser(only=name)._actions if a.dest == "command").choices
        assert lazy[name].format_help() == commands[name].format_help(), name


def test_sizes_are_what_the_estimates_use():
    """The plain-Python sizes the parsers state are the ones the NumPy code runs with: the energy
    bound's direction count against the directions it builds, the albedo grid against the one
    ``albedo_profile`` evaluates, the model's library cost against ``bytes_per_pair``, and the
    defaults of the functions the commands call."""
    import inspect

    from hybridbrdf.acquire import sizes as acquire_sizes
    from hybridbrdf.acquire.acquisition import acquire
    from hybridbrdf.demo import sizes as demo_sizes
    from hybridbrdf.demo.slices import run_demo
    from hybridbrdf.model import energy, load_model, prior_path, sizes
    from hybridbrdf.viewer import sizes as viewer_sizes
    from hybridbrdf.viewer.measured import panels

    assert sizes.energy_directions() == len(energy._directions()) == 1024  # docs/CONVENTIONS.md's table
    assert sizes.energy_bytes_per_sample() == 256 * 1024
    model = load_model(prior_path())
    assert model.bytes_per_pair() == sizes.LIBRARY_BYTES_PER_PAIR
    profile = model.albedo(0, samples=64)
    assert len(profile["albedo"]) == len(sizes.ALBEDO_THETA_DEG) * len(sizes.ALBEDO_PHI_DEG) == 44
    assert sorted(set(profile["theta_deg"].tolist())) == list(sizes.ALBEDO_THETA_DEG)
    assert inspect.signature(energy.tables).parameters["samples"].default == sizes.SAMPLES
    assert inspect.signature(run_demo).parameters["samples"].default == demo_sizes.SAMPLES
    assert inspect.signature(acquire).parameters["steps"].default == acquire_sizes.STEPS == 300
    params = inspect.signature(panels).parameters
    assert (params["size"].default, params["spp"].default) == (viewer_sizes.DEFAULT_SOURCE_SIZE,
                                                                 viewer_sizes.DEFAULT_SOURCE_SPP)


def test_import_hybridbrdf_imports_no_numpy():
    r = python("import sys, hybridbrdf\nassert 'numpy' not in sys.modules\n"
               "assert hybridbrdf.load_model and hybridbrdf.brdf.analytic and 'numpy' in sys.modules")
    assert r.returncode == 0, r.stderr


def test_python_m_hybridbrdf_cli_imports_no_torch_for_help():
    r = subprocess.run([sys.executable, "-X", "importtime", "-m", "hybridbrdf.cli", "--help"], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0 and "usage: hbrdf" in r.stdout, r.stderr[-2000:]
    imported = [line.rsplit("|", 1)[-1].strip() for line in r.stderr.splitlines() if line.startswith("import time:")]
    assert "hybridbrdf.cli" in imported and not [m for m in imported if m.split(".")[0] in ("torch", "numpy")]


def test_every_package_imports_no_torch():
    """``import hybridbrdf.<package>`` for each package: its names whose modules import torch are lazy,
    its __all__ is in its dir(), and the Mitsuba plugin (which imports mitsuba) is not loaded."""
    r = python(f"import importlib, sys\nfor p in {FACES!r}:\n"
               "    m = importlib.import_module('hybridbrdf.' + p)\n"
               "    assert set(m.__all__) <= set(dir(m)), (p, set(m.__all__) - set(dir(m)))\n"
               f"{NO_TORCH}\nassert 'hybridbrdf.render.mitsuba' not in sys.modules and 'mitsuba' not in sys.modules")
    assert r.returncode == 0, r.stderr


def test_every_public_name_resolves_to_its_own_package():
    """Every name of every face's __all__ resolves (the lazy ones import torch here), to an object
    of the package's own modules (or of the C++ extension), never to a module."""
    r = python(f"FACES = {FACES!r}\n" + """
import importlib, types
for p in FACES:
    m = importlib.import_module('hybridbrdf.' + p)
    for n in m.__all__:
        v = getattr(m, n)
        assert not isinstance(v, types.ModuleType), (p, n)
        home = getattr(v, '__module__', None) or m.__name__  # constants have none
        assert home.split('.')[:2] == m.__name__.split('.') or home in ('hybridbrdf._core', 'builtins'), (p, n, home)
import hybridbrdf.render, hybridbrdf.render.tracer, hybridbrdf.brdf.torch_brdf
from hybridbrdf.render import render, write_exr
assert render is hybridbrdf.render.tracer.render and write_exr is hybridbrdf.render.tracer.write_exr
from hybridbrdf.brdf import eval_analytic
assert eval_analytic is hybridbrdf.brdf.torch_brdf.eval_analytic
""")
    assert r.returncode == 0, r.stderr


def test_moved_names_raise_import_errors_naming_their_new_home():
    """The modules of the last layout (hybridbrdf.exports.MOVED_MODULES) and the old names of the
    packages that were modules (hybridbrdf.render, .codegen, .viewer: their ``_MOVED``) raise an
    ImportError that names the new home, however they are reached; the new homes exist."""
    r = python("""
import importlib, importlib.util, sys
import hybridbrdf
from hybridbrdf.exports import MOVED_MODULES

assert MOVED_MODULES['hybridbrdf.mitsuba'] == 'hybridbrdf.render.mitsuba'
assert MOVED_MODULES['hybridbrdf.model_file'] == 'hybridbrdf.model'
moved = dict(MOVED_MODULES)
for p in ('render', 'codegen', 'viewer'):
    package = importlib.import_module('hybridbrdf.' + p)
    assert package._MOVED, p
    moved.update({f'hybridbrdf.{p}.{n}': home for n, home in package._MOVED.items()})
# Modules that were named like their function: the name is the function now, the module import raises.
for old in ('hybridbrdf.fit.fit', 'hybridbrdf.fit.paint', 'hybridbrdf.acquire.simulate'):
    parent, leaf = old.rsplit('.', 1)
    assert callable(getattr(importlib.import_module(parent), leaf)) and leaf in sys.modules[parent].__all__, old
for old, new in sorted(moved.items()):
    assert importlib.util.find_spec(new) is not None, (old, new)
    parent, leaf = old.rsplit('.', 1)
    attempts = [] if leaf in getattr(importlib.import_module(parent), '__all__', ()) else \
        [f'from {parent} import {leaf}', f'import {parent}; {old}']
    if old in MOVED_MODULES:
        attempts += [f'import {old}', f'from {old} import x', f'importlib.import_module({old!r})']
    for code in attempts:
        try:
            exec(code)
        except ImportError as exc:
            assert f'{old} moved to {new}' in str(exc) and 'CHANGELOG.md' in str(exc), (code, str(exc))
        else:
            raise AssertionError(f'{code}: no ImportError')
        assert old not in sys.modules, old
""")
    assert r.returncode == 0, r.stderr
