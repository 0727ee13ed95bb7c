"""scripts/setup.sh skips its pip install only when the installed hybridbrdf was built from exactly
this tree (scripts/source_hash.py, issue 56): any change of a source the wheel is built from
reinstalls.

The tests run the real setup.sh and source_hash.py on a copy of the tree's wheel inputs against a
stand-in installed package (a dist-info folder first on PYTHONPATH, with the stamp in its RECORD);
pip itself is replaced by a recorder, so nothing is installed."""

import importlib.util
import os
import pathlib
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "source_hash.py"

spec = importlib.util.spec_from_file_location("source_hash", SCRIPT)
source_hash = importlib.util.module_from_spec(spec)
spec.loader.exec_module(source_hash)

# One edit of each kind of wheel input: a C++ source, a public header, a binding, a Python module, a
# template, the build files, the package metadata, a new file and a deleted one.
EDITS = {
    "cpp/src/batch.cpp": "append", "cpp/include/hybridbrdf/ggx.hpp": "append",
    "cpp/bindings/module.cpp": "append", "python/hybridbrdf/errors.py": "append",
    "codegen/hbrdf.j2": "append", "CMakeLists.txt": "append", "pyproject.toml": "append",
    "cmake/hybridbrdfConfig.cmake.in": "append", "README.md": "append",
    "python/hybridbrdf/brand_new.py": "create", "python/hybridbrdf/limits.py": "delete",
}


# What the wheel is built from, stated here rather than read from source_hash.SOURCES: pyproject.toml
# and the README it names, the CMake files, the C++ library and bindings, the templates, the package.
WHEEL_INPUTS = ("pyproject.toml", "README.md", "CMakeLists.txt", "cmake", "cpp", "codegen", "python/hybridbrdf")


@pytest.fixture
def tree(tmp_path):
    """A copy of the wheel's inputs and the two scripts, at another path."""
    root = tmp_path / "tree"
    for name in WHEEL_INPUTS + ("scripts/source_hash.py", "scripts/setup.sh"):
        src, dst = ROOT / name, root / name
        dst.parent.mkdir(parents=True, exist_ok=True)
        if src.is_dir():
            shutil.copytree(src, dst, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(src, dst)
    return root


def install_stand_in(site: pathlib.Path, stamp: str, in_record: bool = True, requires=()):
    """A dist-info of hybridbrdf recording ``stamp``, and a package that answers setup.sh's last line."""
    info = site / "hybridbrdf-0.1.0.dist-info"
    info.mkdir(parents=True, exist_ok=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: hybridbrdf\nVersion: 0.1.0\n"
                                   + "".join(f"Requires-Dist: {r}\n" for r in requires))
    (info / "RECORD").write_text("hybridbrdf/__init__.py,,\n" + ("hybridbrdf/_source_hash.txt,,\n" if in_record else ""))
    (site / "hybridbrdf").mkdir(exist_ok=True)
    (site / "hybridbrdf" / "__init__.py").write_text("__version__ = '0.1.0'\ndef simd_path():\n    return 'stand-in'\n")
    (site / "hybridbrdf" / "_source_hash.txt").write_text(stamp + "\n")


def check(root, site):
    return subprocess.run([sys.executable, str(root / "scripts" / "source_hash.py"), "--check"], capture_output=True,
                          text=True, timeout=120, env=dict(os.environ, PYTHONPATH=str(site)))


def run_setup(root, site, tmp_path):
    """setup.sh with python behind a recorder that logs pip's command lines instead of running them,
    and a dpkg-query that reports every Debian package installed (so that apt is never run; the
    versions source_hash.py reads are the real ones)."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir(exist_ok=True)
    log = tmp_path / "pip.log"
    python = bin_dir / "python-recorder"
    python.write_text(f'#!/bin/sh\nif [ "$1" = -m ] && [ "$2" = pip ]; then echo "$*" >> {log}; exit 0; fi\n'
                      f'exec {sys.executable} "$@"\n')
    real = shutil.which("dpkg-query") or "false"
    (bin_dir / "dpkg-query").write_text(f'#!/bin/sh\ncase "$*" in *Status*) echo "install ok installed";; *) exec {real} "$@";; esac\n')
    for p in (python, bin_dir / "dpkg-query"):
        p.chmod(0o755)
    r = subprocess.run(["bash", str(root / "scripts" / "setup.sh")], capture_output=True, text=True, timeout=300,
                       env=dict(os.environ, PYTHON=str(python), PYTHONPATH=str(site),
                                PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}"))
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout, (log.read_text() if log.exists() else "")


def test_setup_skips_pip_for_the_tree_it_was_built_from_and_installs_after_a_change(tree, tmp_path):
    site = tmp_path / "site"
    install_stand_in(site, source_hash.source_hash(tree, os.environ.get("CXX", "c++")))
    out, pip = run_setup(tree, site, tmp_path)
    assert "setup: skipping pip install: the installed hybridbrdf was built from exactly this tree" in out, out
    assert pip == "", pip
    with open(tree / "cpp" / "src" / "model.cpp", "a") as f:
        f.write("// changed\n")
    out, pip = run_setup(tree, site, tmp_path)
    assert "setup: building and installing hybridbrdf: the installed hybridbrdf was built from other sources" in out, out
    assert "-m pip install -q --no-build-isolation .[test]" in pip, pip


def test_every_kind_of_wheel_input_changes_the_hash(tree, monkeypatch):
    monkeypatch.setattr(source_hash, "toolchain", lambda compiler: "the same toolchain")  # the files' part alone
    compiler = "c++"
    before = source_hash.source_hash(tree, compiler)
    assert source_hash.source_hash(tree, compiler) == before  # deterministic, whatever the tree's path
    for name, how in EDITS.items():
        path = tree / name
        saved = path.read_bytes() if path.exists() else None
        if how == "append":
            path.write_bytes(saved + b" ")
        elif how == "create":
            path.write_text("x = 1\n")
        else:
            path.unlink()
        assert source_hash.source_hash(tree, compiler) != before, f"{how} {name} left the hash unchanged"
        if saved is None:
            path.unlink()
        else:
            path.write_bytes(saved)
        assert source_hash.source_hash(tree, compiler) == before, name


def test_check_refuses_a_stamp_outside_the_record_and_a_missing_requirement(tree, tmp_path):
    current = source_hash.source_hash(tree, os.environ.get("CXX", "c++"))
    site = tmp_path / "site"
    install_stand_in(site, current)
    r = check(tree, site)
    assert r.returncode == 0 and "built from exactly this tree" in r.stdout, r.stdout + r.stderr
    # A stamp left in the folder by an install the RECORD does not list (pip would not remove it) does not count.
    install_stand_in(site, current, in_record=False)
    r = check(tree, site)
    assert r.returncode == 1 and "has no hybridbrdf/_source_hash.txt in its RECORD" in r.stdout, r.stdout
    # The test extra's requirements count (pip install .[test] would install them); others' extras do not.
    install_stand_in(site, current, requires=['hbrdf-no-such-package>=1; extra == "test"',
                                              'hbrdf-other-extra>=1; extra == "gpu"'])
    r = check(tree, site)
    assert r.returncode == 1, r.stdout
    assert r.stdout.strip() == "source hash: requirements not installed: hbrdf-no-such-package (not installed)", r.stdout


def test_the_installed_package_records_the_hash_of_its_sources():
    """The wheel carries its stamp (CMakeLists.txt writes it at configure): a 64-digit SHA-256 in RECORD."""
    import importlib.metadata as metadata

    dist = metadata.distribution("hybridbrdf")
    assert any(f.as_posix() == source_hash.STAMP for f in dist.files), "the installed wheel has no source-hash stamp"
    stamp = pathlib.Path(dist.locate_file(source_hash.STAMP)).read_text().strip()
    assert len(stamp) == 64 and int(stamp, 16) >= 0, stamp
