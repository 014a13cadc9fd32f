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


# Functions taking more than MAX_POSITIONAL positional parameters (self and cls not counted;
# numba kernels, which take arrays positionally, and protocol methods such as __exit__ are
# exempt), as "module.py:function": the rest are keyword-only (`*`).
MAX_POSITIONAL = 3
POSITIONAL = {
    "experiments/observed.py:_evaluate",
    "experiments/observed.py:_observe_conditions",
    "experiments/observed.py:_split_models",
    "experiments/observed.py:_write_cache",
    "experiments/observed.py:evaluate_held_out",
    "experiments/observed.py:evaluate_observed",
    "features/chords.py:chord_parameters",
    "kinematics/arm.py:ContinuumArm.batch_points",
    "kinematics/ik.py:_SQP.__init__",
    "kinematics/ik.py:_accepted",
    "kinematics/ik.py:_checked",
    "kinematics/ik.py:_newton",
    "kinematics/ik.py:_newton_at_limits",
    "kinematics/ik.py:_solve",
    "kinematics/ik.py:_sqp",
    "kinematics/ik.py:solve_ik",
    "perception/captures.py:_need",
    "perception/captures.py:captured_result",
    "perception/captures.py:recognise_captures",
    "perception/captures.py:write_captures",
    "perception/comparison.py:at_config",
    "perception/comparison.py:compare_real",
    "perception/comparison.py:fig8",
    "perception/comparison.py:fig8_figure",
    "perception/comparison.py:first_contact_arc_length",
    "perception/comparison.py:object_check",
    "perception/comparison.py:real_and_simulated_wraps",
    "perception/comparison.py:surface_deviation",
    "perception/confidence.py:_hidden_alternatives",
    "perception/confidence.py:_length_spread",
    "perception/fitting.py:fit_arm",
    "perception/fitting.py:fit_cloud",
    "perception/observe.py:centre_line",
    "perception/observe.py:contact_frames",
    "perception/observe.py:observed_execute",
    "perception/residuals.py:ConfigPrior.residuals",
    "perception/residuals.py:Residuals._at",
    "perception/residuals.py:Residuals._residuals",
    "perception/residuals.py:Residuals.along_jac",
    "perception/residuals.py:Residuals.at",
    "perception/residuals.py:Residuals.residuals",
    "perception/residuals.py:centre_lines",
    "perception/residuals.py:uv_config",
    "station/_station.py:ArmPoser.__init__",
    "station/_station.py:Station.__init__",
    "station/_station.py:TouchPins.__init__",
    "station/_station.py:TouchSensor.__init__",
    "wrapping/scene.py:WrapScene.__init__",
    "wrapping/scene.py:capsule_poses",
    "wrapping/scene.py:register_scene",
}
# Modules that import each other (at module level or inside a function), as groups: every
# cycle found must lie within one group.
IMPORT_CYCLES = [
]


def _positional(tree):
    """Qualified names of the functions over MAX_POSITIONAL positional parameters."""
    out = set()
    for qual, fn in _functions(tree):
        params = fn.args.posonlyargs + fn.args.args
        method = bool(params) and "." in qual and params[0].arg in ("self", "cls")
        compiled = any("jit" in ast.unparse(d) for d in fn.decorator_list)
        protocol = fn.name.startswith("__") and fn.name.endswith("__") and fn.name != "__init__"
        if len(params) - method > MAX_POSITIONAL and not compiled and not protocol:
            out.add(qual)
    return out


def test_functions_over_three_positional_parameters_are_only_those_listed():
    found = {f"{name}:{q}" for name, _, tree in _modules() for q in _positional(tree)}
    new = sorted(found - POSITIONAL)
    assert not new, f"new functions over {MAX_POSITIONAL} positional parameters (make the " \
                    f"rest keyword-only): {new}"
    stale = sorted(POSITIONAL - found)
    if stale:
        warnings.warn(f"allow-listed functions that now keep the rule (drop them): {stale}",
                      stacklevel=2)


def _import_graph():
    """{module: modules of the package it imports anywhere in its text}, as dotted names
    below the package ("wrapping.wrap"); `from . import x` counts module x."""
    graph = {}
    for name, _, tree in _modules():
        parts = name[:-3].split("/")
        me = parts[:-1] if parts[-1] == "__init__" else parts
        package = me if parts[-1] == "__init__" else me[:-1]
        deps = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package[:len(package) - node.level + 1]
                elif (node.module or "").startswith("drake_continuum"):
                    base = node.module.split(".")[1:]
                    node = ast.ImportFrom(module=None, names=node.names, level=0)
                else:
                    continue
                module = base + (node.module.split(".") if node.module else [])
                deps.add(".".join(module))
                deps |= {".".join(module + [a.name]) for a in node.names}
            elif isinstance(node, ast.Import):
                deps |= {a.name.split(".", 1)[1] for a in node.names
                         if a.name.startswith("drake_continuum.")}
        graph[".".join(me)] = deps
    return {m: {d for d in deps if d in graph and d != m} for m, deps in graph.items()}


def _cycles(graph):
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while not component or v not in component:
                component.add(stack.pop())
            on.difference_update(component)
            if len(component) > 1:
                out.append(component)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_cycles_graph_finds_a_cycle_through_a_function_level_import():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(graph) == [{"a", "b", "c"}]
    tree = ast.parse("def f():\n    from .b import g\n")
    assert any(isinstance(n, ast.ImportFrom) and n.level == 1 for n in ast.walk(tree))


def test_import_cycles_are_only_those_listed():
    cycles = _cycles(_import_graph())
    new = [sorted(c) for c in cycles if not any(c <= group for group in IMPORT_CYCLES)]
    assert not new, f"modules importing each other (imports point down the data flow): {new}"
    stale = [sorted(g) for g in IMPORT_CYCLES if not any(c & g for c in cycles)]
    if stale:
        warnings.warn(f"allow-listed import cycles that are gone (drop them): {stale}",
                      stacklevel=2)
