"""The package stays readable (issue 57): no module of python/hybridbrdf over 500 lines and no
function over 80 (a class defined in a function's body counts as that function's lines)."""

import ast
import pathlib

PACKAGE = pathlib.Path(__file__).resolve().parents[2] / "python" / "hybridbrdf"
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 80


def sources():
    return sorted(PACKAGE.rglob("*.py"))


def test_no_module_over_500_lines():
    long = {str(p.relative_to(PACKAGE)): n for p in sources() if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, long


def test_no_function_over_80_lines():
    long = []
    for p in sources():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long.append(f"{p.relative_to(PACKAGE)}:{node.lineno} {node.name} ({n} lines)")
    assert not long, long


def test_the_counter_sees_a_long_function(tmp_path):
    # The check must be able to fail: a 90-line function is counted as one.
    body = "\n".join(f"    x{i} = {i}" for i in range(89))
    tree = ast.parse(f"def f():\n{body}\n")
    node = tree.body[0]
    assert node.end_lineno - node.lineno + 1 == 90 > MAX_FUNCTION_LINES
