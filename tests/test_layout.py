"""The package's layout rules, by AST over its sources (DESIGN.md, Layout; STYLE.md).

Each rule has an allow-list: the debt still to pay, by name. Anything new over a rule fails
the test; an entry that no longer applies gives a warning to drop it (the list only shrinks).
"""

import ast
import warnings
from fnmatch import fnmatchcase
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "drake_continuum"

MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80

# Modules over MAX_MODULE_LINES lines.
LONG_MODULES = set()
# Functions over MAX_FUNCTION_LINES lines, as "module.py:function".
LONG_FUNCTIONS = set()
# Functions holding `nonlocal`, as "module.py:function".
NONLOCAL = set()
# Underscore names imported from another module, as "importer.py:module:name" (module as
# written in the import). Entries of every list may be glob patterns (fnmatch).
UNDERSCORE_IMPORTS = {
    "perception/freespace.py:.depth_camera:_to_legacy",
}


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        text = path.read_text()
        yield path.relative_to(PACKAGE).as_posix(), text, ast.parse(text)


def _functions(tree):
    """(qualified name, node) of every function, methods and nested ones included."""
    def walk(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield prefix + child.name, child
                yield from walk(child, prefix + child.name + ".")
            elif isinstance(child, ast.ClassDef):
                yield from walk(child, prefix + child.name + ".")
            else:
                yield from walk(child, prefix)
    yield from walk(tree, "")


def _own_nodes(fn):
    """The nodes of a function's body, not those of the functions and classes inside it."""
    todo = list(ast.iter_child_nodes(fn))
    while todo:
        node = todo.pop()
        yield node
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            todo.extend(ast.iter_child_nodes(node))


def _found():
    long_modules, long_functions, nonlocal_, underscore = set(), set(), set(), set()
    for name, text, tree in _modules():
        if len(text.splitlines()) > MAX_MODULE_LINES:
            long_modules.add(name)
        for qual, fn in _functions(tree):
            if fn.end_lineno - fn.lineno + 1 > MAX_FUNCTION_LINES:
                long_functions.add(f"{name}:{qual}")
            if any(isinstance(n, ast.Nonlocal) for n in _own_nodes(fn)):
                nonlocal_.add(f"{name}:{qual}")
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                module = "." * node.level + (node.module or "")
                underscore |= {f"{name}:{module}:{a.name}" for a in node.names
                               if a.name.startswith("_") and not a.name.startswith("__")}
    return {"modules": long_modules, "functions": long_functions, "nonlocal": nonlocal_,
            "underscore imports": underscore}


FOUND = {}


def _check(kind, allowed):
    if not FOUND:
        FOUND.update(_found())
    found = FOUND[kind]
    new = sorted(f for f in found if not any(fnmatchcase(f, a) for a in allowed))
    assert not new, f"new {kind} over the rule: {new}"
    stale = sorted(a for a in allowed if not any(fnmatchcase(f, a) for f in found))
    if stale:
        warnings.warn(f"allow-listed {kind} that now keep the rule (drop them from the "
                      f"list): {stale}", stacklevel=2)


@pytest.mark.parametrize("kind, allowed", [
    ("modules", LONG_MODULES), ("functions", LONG_FUNCTIONS), ("nonlocal", NONLOCAL),
    ("underscore imports", UNDERSCORE_IMPORTS)])
def test_layout_debt_is_only_what_is_listed(kind, allowed):
    _check(kind, allowed)
