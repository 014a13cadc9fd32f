"""The API reference is generated from the docstrings (scripts/reference.py, pdoc) and every
public name is in it: each name of each public module's `__all__`, the package root's
included, has its entry on that module's page. Built into a temporary folder, never kept."""

import importlib
import pkgutil
import runpy
import warnings
from pathlib import Path

import pytest

import drake_continuum

ROOT = Path(__file__).resolve().parents[1]


def public_modules():
    """(import name, module) of the package and every module under it whose name has no part
    starting with an underscore."""
    yield "drake_continuum", drake_continuum
    for info in pkgutil.walk_packages(drake_continuum.__path__, "drake_continuum."):
        if not any(part.startswith("_") for part in info.name.split(".")):
            yield info.name, importlib.import_module(info.name)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    pytest.importorskip("pdoc", reason="pdoc is in the test extra: pip install -e '.[test]'")
    build = runpy.run_path(str(ROOT / "scripts" / "reference.py"))["build"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # pdoc on annotations it cannot evaluate
        return build(tmp_path_factory.mktemp("reference"), search=False, show_source=False)


def test_every_public_name_has_its_entry_in_the_reference(reference):
    missing, pages = [], 0
    for name, module in public_modules():
        page = reference / (name.replace(".", "/") + ".html")
        assert page.exists(), f"no reference page for {name}"
        pages += 1
        html = page.read_text()
        missing += [f"{name}.{n}" for n in getattr(module, "__all__", ())
                    if f'id="{n}"' not in html]
    assert pages > 50
    assert not missing, "public names without an entry in the reference: " + ", ".join(missing)


def test_an_entry_carries_its_docstring(reference):
    from drake_continuum.wrapping.wrap import wrap
    html = (reference / "drake_continuum" / "wrapping" / "wrap.html").read_text()
    first = wrap.__doc__.strip().split()[:4]
    assert " ".join(first) in " ".join(html.split())
