"""docs/api.md documents the public API: a section for every name of drake_continuum.__all__
and none for a name that is not public, each with a Python example that mentions it,
parses, and calls the public functions and classes with keywords they accept; a row for
each subpackage's __all__, whose names are its modules' and load with them."""

import ast
import importlib
import inspect
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest

import drake_continuum

DOC = Path(__file__).resolve().parents[1] / "docs" / "api.md"
SECTION = re.compile(r"^### `([^`]+)`\n(.*?)(?=^#{2,3} |\Z)", re.M | re.S)
EXAMPLE = re.compile(r"```python\n(.*?)```", re.S)


def _sections() -> dict[str, str]:
    return {m.group(1): m.group(2) for m in SECTION.finditer(DOC.read_text())}


def test_every_public_name_has_a_section_and_no_other_does():
    names = set(_sections())
    public = set(drake_continuum.__all__)
    assert not public - names, f"public names missing from docs/api.md: {sorted(public - names)}"
    assert not names - public, f"docs/api.md documents non-public names: {sorted(names - public)}"


def test_each_example_mentions_its_name_and_parses():
    for name, body in _sections().items():
        examples = EXAMPLE.findall(body)
        assert len(examples) == 1, f"{name}: {len(examples)} examples, want one"
        assert name in examples[0], f"{name}: its example does not use it"
        ast.parse(examples[0], filename=f"api.md ({name})")


def test_examples_call_the_api_with_keywords_it_accepts():
    checked = 0
    for name, body in _sections().items():
        for node in ast.walk(ast.parse(EXAMPLE.findall(body)[0])):
            if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                    and node.func.id in drake_continuum.__all__ and node.keywords):
                continue
            target = getattr(drake_continuum, node.func.id)
            accepted = inspect.signature(target).parameters
            for kw in node.keywords:
                assert kw.arg in accepted, (f"api.md, {name}: {node.func.id}() takes no "
                                            f"keyword {kw.arg!r}")
                checked += 1
    assert checked >= 30  # the check ran over the examples' keywords


@pytest.mark.slow
def test_the_examples_run_in_order_as_one_script_from_another_folder(tmp_path):
    """Every ```python block of docs/api.md, in order, as written, run from a folder outside
    the checkout as one plain script (no __main__ guard)."""
    script = "\n".join(EXAMPLE.findall(DOC.read_text()))
    (tmp_path / "api_examples.py").write_text(script)
    done = subprocess.run([sys.executable, "api_examples.py"], cwd=tmp_path, text=True,
                          capture_output=True, timeout=3600)
    assert done.returncode == 0, done.stderr[-3000:]


# Subpackages that name their surface in __init__'s __all__; cli's surface is its commands.
SUBPACKAGES = sorted(
    m.name for m in pkgutil.iter_modules(drake_continuum.__path__)
    if m.ispkg and m.name != "cli"
    and "__all__" in (Path(drake_continuum.__path__[0]) / m.name / "__init__.py").read_text())
ROW = re.compile(r"^\| `(\w+)` \| [^|]+ \| (.+) \|$", re.M)


def test_the_subpackage_table_lists_each_subpackages_all():
    table = {m.group(1): re.findall(r"`(\w+)`", m.group(2))
             for m in ROW.finditer(DOC.read_text().split("## Subpackages", 1)[1].split("\n## ")[0])}
    assert sorted(table) == SUBPACKAGES
    for name in SUBPACKAGES:
        assert table[name] == importlib.import_module(f"drake_continuum.{name}").__all__, name


def test_a_subpackages_names_are_its_modules_and_load_with_them():
    """Importing a subpackage imports none of its modules; each name is its module's public
    name (in that module's __all__) and is not the name of a module of the subpackage."""
    lazy = [n for n in SUBPACKAGES if n != "station"]  # station's Diagram is its whole point
    code = ("import sys, importlib\n"
            f"for p in {lazy!r}:\n"
            "    importlib.import_module('drake_continuum.' + p)\n"
            "print(sorted(m for m in sys.modules if m.count('.') > 1\n"
            "             and m.startswith('drake_continuum.')))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "[]"
    for name in lazy:
        package = importlib.import_module(f"drake_continuum.{name}")
        modules = {m.name for m in pkgutil.iter_modules(package.__path__)}
        assert not set(package.__all__) & modules, name
        assert sorted(dir(package)) == dir(package) and set(package.__all__) <= set(dir(package))
        for public in package.__all__:
            module = next(importlib.import_module(f"{package.__name__}.{m}") for m in modules
                          if public in getattr(importlib.import_module(
                              f"{package.__name__}.{m}"), "__all__", ()))
            assert getattr(package, public) is getattr(module, public), (name, public)
        with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
            package.not_a_name  # noqa: B018
