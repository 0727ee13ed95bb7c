"""The hash of what hybridbrdf's wheel is built from, and whether the installed package was built
from exactly this tree (issue 56: scripts/setup.sh skips its pip install only then).

    python3 scripts/source_hash.py [--root DIR] [--compiler CXX]   prints the tree's hash
    python3 scripts/source_hash.py --check [--root DIR]            exit 0 when the installed hybridbrdf
        records this tree's hash and every requirement of hybridbrdf[test] and of the build is
        installed; otherwise exit 1 with one line saying what differs

What the hash covers: every file of the wheel's inputs (SOURCES below: the build files, the C++
library and bindings, the templates, the Python package, the metadata) by path and content, and the
toolchain that turns them into the wheel (Python's version, the build backend's and pybind11's
versions, the C++ compiler's version and target, the versions of the Debian -dev packages whose
headers are compiled). CMakeLists.txt runs this script when it configures the Python extension and
installs the result into the wheel as hybridbrdf/_source_hash.txt, so the record is exactly as
current as the installed package: pip removes it with the package, and a stamp left in the folder
but missing from the package's RECORD does not count. A change the hash does not cover can only
cost a needless reinstall, never skip a needed one, as long as what is covered is a superset of
what the wheel reads; when in doubt a path belongs in SOURCES.
"""

import argparse
import hashlib
import importlib.metadata as metadata
import os
import pathlib
import shutil
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
# The wheel's inputs: pyproject.toml (and the README it names), the CMake files, the C++ sources,
# headers and bindings, the templates installed into the wheel and the Python package.
SOURCES = ("pyproject.toml", "README.md", "CMakeLists.txt", "cmake", "cpp", "codegen", "python/hybridbrdf",
           "scripts/source_hash.py")
STAMP = "hybridbrdf/_source_hash.txt"
# The Debian packages whose headers the wheel compiles (scripts/setup.sh installs them).
DEV_PACKAGES = ("libglm-dev", "nlohmann-json3-dev", "libembree-dev", "libassimp-dev", "libtinyexr-dev", "libstb-dev")


def tree_files(root: pathlib.Path):
    """Every file under SOURCES, sorted; Python's byte-code caches aside (written by whoever imports
    the tree, not read by the build)."""
    for name in SOURCES:
        path = root / name
        if path.is_file():
            yield path
        elif path.is_dir():
            for p in sorted(path.rglob("*")):
                if p.is_file() and "__pycache__" not in p.parts:
                    yield p


def toolchain(compiler: str) -> str:
    """The versions of what turns the sources into the wheel, one per line."""
    lines = [f"python {sys.version}", f"platform {sys.platform}"]
    for dist in ("scikit-build-core", "pybind11"):
        try:
            lines.append(f"{dist} {metadata.version(dist)}")
        except metadata.PackageNotFoundError:
            lines.append(f"{dist} absent")
    cxx = shutil.which(compiler)
    if cxx:
        r = subprocess.run([cxx, "-dumpfullversion", "-dumpmachine"], capture_output=True, text=True)
        lines.append(f"c++ {r.stdout.split()}")
    if shutil.which("dpkg-query"):
        r = subprocess.run(["dpkg-query", "-W", "-f", "${Package} ${Version}\n", *DEV_PACKAGES],
                           capture_output=True, text=True)
        lines.append(r.stdout.strip())
    return "\n".join(lines)


def source_hash(root: pathlib.Path, compiler: str) -> str:
    """SHA-256 over each file's path (relative to root) and content, then the toolchain."""
    h = hashlib.sha256()
    for p in tree_files(root):
        data = p.read_bytes()
        h.update(f"{p.relative_to(root).as_posix()}\0{len(data)}\0".encode())
        h.update(data)
    h.update(toolchain(compiler).encode())
    return h.hexdigest()


def installed_hash():
    """The hash recorded in the installed hybridbrdf, or None with the reason."""
    try:
        dist = metadata.distribution("hybridbrdf")
    except metadata.PackageNotFoundError:
        return None, "hybridbrdf is not installed"
    if not any(f.as_posix() == STAMP for f in dist.files or ()):
        return None, f"the installed hybridbrdf has no {STAMP} in its RECORD (installed before the stamp existed, or not by pip)"
    return pathlib.Path(dist.locate_file(STAMP)).read_text().strip(), ""


def missing_requirements(root: pathlib.Path):
    """The requirements of hybridbrdf[test] and of pyproject.toml's build system that are not installed
    at a version they accept (what `pip install --no-build-isolation .[test]` would install)."""
    from packaging.requirements import Requirement

    import tomllib

    build = tomllib.loads((root / "pyproject.toml").read_text())["build-system"]["requires"]
    missing = []
    for text in [*build, *(metadata.requires("hybridbrdf") or [])]:
        req = Requirement(text)
        if req.marker and not req.marker.evaluate({"extra": "test"}):
            continue
        try:
            version = metadata.version(req.name)
        except metadata.PackageNotFoundError:
            missing.append(f"{req.name} (not installed)")
            continue
        if not req.specifier.contains(version, prereleases=True):
            missing.append(f"{req.name} {version} (needs {req.specifier})")
    return missing


def check(root: pathlib.Path, compiler: str) -> int:
    recorded, why = installed_hash()
    if recorded is None:
        print(f"source hash: {why}")
        return 1
    current = source_hash(root, compiler)
    if recorded != current:
        print(f"source hash: the installed hybridbrdf was built from other sources ({recorded[:12]}, this tree {current[:12]})")
        return 1
    try:
        missing = missing_requirements(root)
    except ImportError as e:  # packaging or tomllib absent: let pip decide
        print(f"source hash: cannot check the requirements ({e})")
        return 1
    if missing:
        print(f"source hash: requirements not installed: {', '.join(missing)}")
        return 1
    print(f"source hash: the installed hybridbrdf was built from exactly this tree ({current[:12]})")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--root", type=pathlib.Path, default=ROOT, help="the source tree (default: this checkout)")
    parser.add_argument("--compiler", default=os.environ.get("CXX", "c++"),
                        help="the C++ compiler the wheel is built with (default: $CXX, else c++)")
    parser.add_argument("--check", action="store_true",
                        help="exit 0 when the installed hybridbrdf was built from this tree and its requirements are installed")
    args = parser.parse_args(argv)
    if args.check:
        return check(args.root.resolve(), args.compiler)
    print(source_hash(args.root.resolve(), args.compiler))
    return 0


if __name__ == "__main__":
    sys.exit(main())
