"""The test suite's own conventions: tests are named by what they assert (no item numbers),
slow tests are marked where they are (no list of names in conftest.py), and the end-of-session
summary names an unmarked test that took too long."""
import ast
import re
from pathlib import Path
from types import SimpleNamespace

import conftest

TESTS = Path(__file__).resolve().parent
NUMBERED = re.compile(r"^test_item\d")


def test_no_test_module_or_function_is_named_by_an_item_number():
    numbered = [p.name for p in TESTS.glob("test_*.py") if NUMBERED.match(p.name)]
    for path in TESTS.glob("test_*.py"):
        tree = ast.parse(path.read_text(), filename=str(path))
        numbered += [f"{path.name}::{node.name}" for node in ast.walk(tree)
                     if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and NUMBERED.match(node.name)]
    assert numbered == []


def _names_of_tests(node: ast.AST) -> list[str]:
    """The strings of a literal set, list or tuple that name a test module or test."""
    if not isinstance(node, (ast.Set, ast.List, ast.Tuple)):
        return []
    return [e.value for e in node.elts if isinstance(e, ast.Constant) and isinstance(e.value, str)
            and (e.value.endswith(".py") or "::" in e.value or e.value.startswith("test_"))]


def test_conftest_keeps_no_list_of_test_names():
    tree = ast.parse((TESTS / "conftest.py").read_text())
    listed = [name for node in ast.walk(tree) if isinstance(node, (ast.Assign, ast.AnnAssign))
              for name in _names_of_tests(node.value)]
    assert listed == [], "mark slow tests where they are (@pytest.mark.slow), not in a list in conftest.py"


def test_the_names_check_finds_a_list_of_names():
    tree = ast.parse('SLOW = {"test_a.py", "test_b.py::test_c"}\nOTHER = ("x", 1)\n')
    found = [n for node in tree.body for n in _names_of_tests(node.value)]
    assert found == ["test_a.py", "test_b.py::test_c"]


def test_an_unmarked_test_over_the_limit_is_named_and_a_marked_one_is_not():
    limit = conftest.SLOW_UNMARKED_S
    reports = [SimpleNamespace(nodeid="t.py::long", duration=limit - 1.0),  # call
               SimpleNamespace(nodeid="t.py::long", duration=2.0),  # setup: together over the limit
               SimpleNamespace(nodeid="t.py::short", duration=limit / 2),
               SimpleNamespace(nodeid="t.py::marked", duration=2 * limit)]
    assert conftest.slow_unmarked(reports, {"t.py::marked"}) == [("t.py::long", limit + 1.0)]
