"""The imports the documentation shows work (issue 57): every ``import ...`` and ``from ... import ...``
line of a fenced code block of README.md and docs/*.md, and every inline code span that is such an
import of hybridbrdf (`` `from hybridbrdf.model import edit, mix` ``), runs in one fresh interpreter,
so a documented name that leaves its public face (``from hybridbrdf.render import render``) fails here.

A line that needs a third-party package that is not installed (mitsuba, on a machine without it)
is skipped, and says so; nothing here reads ../shared."""

import ast
import json
import pathlib
import re
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
FENCE = re.compile(r"^ *(```|~~~)[^\n]*\n(.*?)^ *\1 *$", re.S | re.M)
IMPORT = re.compile(r"^\s*(import\s+[A-Za-z_]|from\s+[A-Za-z_.]+\s+import\s)")
INLINE = re.compile(r"`((?:from hybridbrdf[\w.]* import [\w, ]+)|(?:import hybridbrdf[\w., ]*))`")


def documented_imports():
    """[(file:line, statement)] of each import statement in the fenced code blocks, in order (a
    parenthesised import over several lines is one statement), then of the inline spans."""
    out = []
    for doc in DOCS:
        text = doc.read_text()
        for block in FENCE.finditer(text):
            first = text.count("\n", 0, block.start(2)) + 1
            lines = block.group(2).splitlines()
            i = 0
            while i < len(lines):
                if IMPORT.match(lines[i]):
                    statement, j = lines[i].split("#")[0].strip(), i
                    while statement.count("(") > statement.count(")") and j + 1 < len(lines):
                        j += 1
                        statement += " " + lines[j].split("#")[0].strip()
                    out.append((f"{doc.relative_to(ROOT)}:{first + i}", statement))
                    i = j
                i += 1
        outside = FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), text)  # the prose, lines kept
        for span in INLINE.finditer(outside):
            out.append((f"{doc.relative_to(ROOT)}:{outside.count(chr(10), 0, span.start()) + 1}", span.group(1)))
    return out


RUNNER = r"""
import importlib.util, json, sys
results = []
for where, statement in json.load(sys.stdin):
    try:
        exec(statement, {})
    except ModuleNotFoundError as exc:
        top = (exc.name or "").split(".")[0]
        if top and top != "hybridbrdf" and importlib.util.find_spec(top) is None:
            results.append([where, statement, "skipped", f"{top} is not installed"])
        else:
            results.append([where, statement, "failed", f"{type(exc).__name__}: {exc}"])
    except Exception as exc:
        results.append([where, statement, "failed", f"{type(exc).__name__}: {exc}"])
    else:
        results.append([where, statement, "ran", ""])
print(json.dumps(results))
"""


def run_imports(statements):
    r = subprocess.run([sys.executable, "-c", RUNNER], input=json.dumps(statements), capture_output=True, text=True,
                       timeout=300, cwd=ROOT / "tests")  # not the repository root: the installed package
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_the_documents_show_imports():
    statements = documented_imports()
    assert all(ast.parse(s) for _, s in statements)  # each a whole statement
    hybridbrdf = [s for _, s in statements if "hybridbrdf" in s]
    assert len(hybridbrdf) >= 5, statements
    assert any(s == "from hybridbrdf.render import render" for s in hybridbrdf), hybridbrdf


def test_every_documented_import_runs():
    results = run_imports(documented_imports())
    failed = [f"{where}: {statement}: {why}" for where, statement, status, why in results if status == "failed"]
    assert not failed, "\n".join(failed)
    ran = [statement for _, statement, status, _ in results if status == "ran"]
    assert any("hybridbrdf" in s for s in ran), results


def test_a_name_missing_from_a_face_fails():
    """The runner reports an import of a name a face does not export (as it would a documented
    name that left its face), and an old module's error names the new home."""
    results = run_imports([("x.md:1", "from hybridbrdf.render import no_such_name"),
                           ("x.md:2", "import hybridbrdf.mitsuba"),
                           ("x.md:3", "import no_such_package_hbrdf")])
    assert [status for *_, status, _ in results] == ["failed", "failed", "skipped"], results
    assert "cannot import name 'no_such_name'" in results[0][3]
    assert "hybridbrdf.render.mitsuba" in results[1][3]
