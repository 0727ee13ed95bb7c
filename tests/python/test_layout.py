"""The Python package's folders are its architecture, and the code keeps to the drawing.

- Layers: docs/ARCHITECTURE.md draws the package as lines of folders (and top-level modules);
  a module imports only from its own line or lines below it, function-level imports included.
- No import circles between modules (a circle hidden by a function-level import counts).
- One home per name: ``from hybridbrdf.X import name`` only where X defines ``name`` (or ``name``
  is X's submodule); no module re-exports another's names. The public faces are the one documented
  exception: ``hybridbrdf`` itself and each package's ``__init__.py``, whose ``__all__`` lists the
  names it exports one import deep (``from hybridbrdf.render import render``).
- The public API and the console scripts are what the README documents.

The import graph is read with ``ast`` from the source tree, so a test fails on the code as written,
whatever is installed."""

import ast
import functools
import importlib
import pathlib
import re
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "python" / "hybridbrdf"


@functools.lru_cache(maxsize=None)
def parsed(text: str) -> ast.Module:
    """The syntax tree of a source text. Keyed by the text itself, so an edited file is parsed
    anew: test_every_name_is_imported_from_its_home asks for the names of the same few homes
    once per import statement (2,000-odd), 12 s of parsing a run before this cache."""
    return ast.parse(text)


def parse(path: pathlib.Path) -> ast.Module:
    return parsed(path.read_text())


def statements(tree: ast.Module):
    """Every statement of a module, those inside functions, classes and blocks included. Imports
    are statements, so this walk skips expressions, most of a tree's nodes (ast.walk visits them)."""
    todo = list(tree.body)
    while todo:
        node = todo.pop()
        yield node
        for field in ("body", "orelse", "finalbody", "handlers", "cases"):
            for child in getattr(node, field, ()):  # ExceptHandler and match_case hold statements
                todo.extend(child.body if isinstance(child, (ast.excepthandler, ast.match_case)) else [child])


def module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def module_path(name: str):
    base = PACKAGE.parent / name.replace(".", "/")
    for p in (base / "__init__.py", base.with_suffix(".py")):
        if p.is_file():
            return p
    return None


def unit(name: str) -> str:
    """The layer unit of a module: its folder under hybridbrdf/, or its own name at the top."""
    parts = name.split(".")
    if len(parts) == 1:
        return "__init__"
    if (PACKAGE / parts[1]).is_dir():
        return parts[1]
    return parts[1].removesuffix(".py")


def imports(path: pathlib.Path):
    """[(imported hybridbrdf module, line, [names or None])] of every import statement in the file."""
    out = []
    for node in statements(parse(path)):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno, None) for a in node.names if a.name.split(".")[0] == "hybridbrdf"]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                and node.module.split(".")[0] == "hybridbrdf":
            names = [a.name for a in node.names]
            if node.module == "hybridbrdf":  # from hybridbrdf import _core, spec: those modules
                out += [(f"hybridbrdf.{n}", node.lineno, None) for n in names]
                continue
            submodules = [f"{node.module}.{n}" for n in names if module_path(f"{node.module}.{n}")]
            out.append((node.module, node.lineno, names))
            out += [(m, node.lineno, None) for m in submodules]
    return out


MODULES = {module_name(p): p for p in PACKAGE.rglob("*.py")}


def drawn_layers():
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text()
    block = re.search(r"<!-- layers -->\n(.*?)<!-- /layers -->", text, re.S)
    assert block, "docs/ARCHITECTURE.md has no <!-- layers --> drawing"
    rows = [re.split(r"\s{2,}", line.strip()) for line in block.group(1).splitlines() if line.strip()]
    # Each row: the units (two or more spaces apart), then the description (after 5+ spaces in the
    # drawing; the last field). Units are identifiers.
    layers = {}
    for height, row in enumerate(reversed(rows)):
        for name in row:
            if re.fullmatch(r"[_a-z][_a-z0-9]*", name):
                layers[name] = height
    return layers


def test_the_drawing_names_every_folder_and_top_level_module():
    layers = drawn_layers()
    units = {unit(m) for m in MODULES} | {"_core"}
    assert units == set(layers), (sorted(units - set(layers)), sorted(set(layers) - units))


def test_every_import_goes_down_the_drawing():
    layers = drawn_layers()
    wrong = []
    for name, path in MODULES.items():
        for target, line, _ in imports(path):
            a, b = unit(name), unit(target)
            if a != b and layers[b] >= layers[a]:
                wrong.append(f"{path.relative_to(ROOT)}:{line}: {a} imports {target} ({b} is not below it)")
    assert not wrong, "\n".join(wrong)


def test_no_import_circles():
    # A package's __init__ importing its own submodules is not a circle of two modules' code.
    graph = {name: {t for t, _, _ in imports(path) if t in MODULES and t != name
                    and not (path.name == "__init__.py" and t.startswith(name + "."))}
             for name, path in MODULES.items()}
    state, stack, circles = {}, [], []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for m in sorted(graph[n]):
            if state.get(m) == 1:
                circles.append(stack[stack.index(m):] + [m])
            elif m not in state:
                visit(m)
        stack.pop()
        state[n] = 2

    for n in sorted(graph):
        if n not in state:
            visit(n)
    assert not circles, "\n".join(" -> ".join(c) for c in circles)


def defined_names(path: pathlib.Path):
    return names_defined_in(path.read_text())


@functools.lru_cache(maxsize=None)
def names_defined_in(text: str) -> frozenset:
    """The names a module's text defines at its top level (functions, classes, assignments); keyed
    by the text, as :func:`parsed`: the same homes are asked about once per import statement."""
    names = set()
    for node in ast.walk(parsed(text)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.col_offset == 0:
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)) and node.col_offset == 0:
            for target in (node.targets if isinstance(node, ast.Assign) else [node.target]):
                names |= {x.id for x in ast.walk(target) if isinstance(x, ast.Name)}
    return frozenset(names)


def exported_names(path: pathlib.Path):
    """The ``__all__`` of a package's ``__init__.py`` (its public face), as written; empty for a module."""
    if path.name != "__init__.py":
        return set()
    for node in parse(path).body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            return set(ast.literal_eval(node.value))
    return set()


def test_every_name_is_imported_from_its_home():
    files = [p for folder in ("python", "tests", "bench", "scripts") for p in (ROOT / folder).rglob("*.py")]
    wrong = []
    for path in files:
        for module, line, names in imports(path):
            if names is None or module == "hybridbrdf" or module.startswith("hybridbrdf._core"):
                continue
            home = module_path(module)
            assert home is not None, f"{path.relative_to(ROOT)}:{line}: no module {module}"
            defined = defined_names(home) | exported_names(home)
            for n in names:
                if n not in defined and not module_path(f"{module}.{n}"):
                    wrong.append(f"{path.relative_to(ROOT)}:{line}: {n} is not defined in {module}")
    assert not wrong, "\n".join(wrong)


# The documented public namespace (README, "Python API"): a name leaves or joins it on purpose.
PUBLIC = {"ALPHA_MAX", "ALPHA_MIN", "CONVENTIONS_VERSION", "ETA_MAX", "ETA_MIN", "MIS_MIN_LOBE_PROBABILITY",
          "STRATEGIES", "AnalyticParams", "BRDFFormatError", "BRDFSource", "FitSettings", "HybridModel", "add",
          "InputFileError", "ModelFileError", "expand_sources", "load_model", "load_prior", "prior_path",
          "open_source", "analytic_eval", "pdf", "sample", "simd_path", "load_svbrdf", "SVBRDF"}


def test_the_public_namespace():
    import hybridbrdf

    assert set(hybridbrdf.__all__) == PUBLIC
    assert all(hasattr(hybridbrdf, n) for n in PUBLIC)
    assert re.fullmatch(r"\d+\.\d+\.\d+", hybridbrdf.__version__)


#: The packages under hybridbrdf/ whose ``__init__.py`` is a public face (all but the command line,
#: whose front door is ``hbrdf`` and ``hybridbrdf.cli.main``).
FACES = sorted(p.parent for p in PACKAGE.glob("*/__init__.py") if p.parent.name != "cli")


@pytest.mark.parametrize("folder", FACES, ids=lambda p: p.name)
def test_each_package_init_is_its_public_face(folder):
    """Each package's __init__ exports its own package's public names (``__all__``), none of them
    the name of one of its submodules: importing ``hybridbrdf.fit.X`` sets the package's attribute
    ``X`` to the module, so a function ``X`` would be the module after any such import (hence
    ``fit/joint.py`` for :func:`hybridbrdf.fit.fit`)."""
    init = folder / "__init__.py"
    name = module_name(init)
    exported = exported_names(init)
    assert exported, f"{init.relative_to(ROOT)} has no __all__"
    submodules = sorted(n for n in exported if module_path(f"{name}.{n}"))
    assert not submodules, f"{name} exports names of its submodules: {submodules}"
    others = [f"{init.relative_to(ROOT)}:{line}: {module}" for module, line, _ in imports(init)
              if not module.startswith(name + ".") and module != "hybridbrdf.exports"]
    assert not others, "a face imports only its own package's modules:\n" + "\n".join(others)


@pytest.mark.parametrize("script", ["hbrdf", "hbrdf-codegen"])
def test_console_scripts_resolve(script):
    text = (ROOT / "pyproject.toml").read_text()
    target = re.search(rf'^{re.escape(script)} = "([\w.]+):(\w+)"', text, re.M)
    assert target, f"pyproject.toml names no console script {script}"
    module = importlib.import_module(target.group(1))
    assert callable(getattr(module, target.group(2)))
    last = target.group(1).split(".")[-1]
    assert sys.modules[target.group(1)].__file__.endswith((f"{last}.py", f"{last}/__init__.py"))


# The only imports inside functions: dependencies that one command or one file format needs and
# the rest of the package does not (docs/ARCHITECTURE.md, "The Python package's layers"), PyTorch
# and the package's modules that import it (seconds: ``import hybridbrdf`` imports none of them),
# and in the command line (hybridbrdf.cli) whatever a command runs: ``hbrdf --help`` builds every
# command's parser and should answer at once.
LAZY = {"matplotlib", "mitsuba", "drjit", "h5py", "torch"}


def top_level_imports(path: pathlib.Path):
    """The modules a module's own top-level import statements name (not its functions')."""
    out = set()
    for node in parse(path).body:
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out |= {node.module} | {f"{node.module}.{a.name}" for a in node.names if module_path(f"{node.module}.{a.name}")}
    return out


def importing_torch():
    """The package's modules whose import imports torch: by their top-level imports, their
    packages' and those of the modules they import."""
    edges = {}
    for name, path in MODULES.items():
        named = top_level_imports(path) | {name.rsplit(".", 1)[0]} if "." in name else top_level_imports(path)
        edges[name] = {".".join(m.split(".")[:i + 1]) for m in named for i in range(len(m.split(".")))}
    heavy = {n for n, e in edges.items() if "torch" in e}
    while True:
        more = {n for n, e in edges.items() if n not in heavy and e & heavy}
        if not more:
            return heavy
        heavy |= more


def test_imports_are_at_the_top_of_modules():
    heavy = importing_torch()
    wrong = []
    for name, path in MODULES.items():
        if name == "hybridbrdf.cli" or name.startswith("hybridbrdf.cli."):
            continue
        tree = parse(path)
        top = {id(n) for n in tree.body}
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in top:
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif node.module in heavy:
                    names = [node.module]
                else:  # from package import module, ...: the modules
                    names = [f"{node.module}.{a.name}" for a in node.names]
                if not all(n.split(".")[0] in LAZY or n in heavy for n in names):
                    wrong.append(f"{path.relative_to(ROOT)}:{node.lineno}: {ast.unparse(node)}")
    assert not wrong, "\n".join(wrong)


def test_import_hybridbrdf_imports_no_torch():
    """The public namespace loads the names whose modules import torch on first use (PEP 562)."""
    import hybridbrdf

    heavy = importing_torch()
    assert "hybridbrdf" not in heavy and "hybridbrdf.cli" not in heavy, sorted(heavy)
    # Every package's public face too: its names whose modules import torch load on first access.
    assert not heavy & {module_name(folder / "__init__.py") for folder in FACES}, sorted(heavy)
