"""Build the API reference from the docstrings: one HTML page a module, into docs/reference/
(or the folder given), with pdoc (`pip install pdoc`, in the test extra).

    python scripts/reference.py [OUT]

The package root names its public API in `__all__` and loads it lazily, so pdoc is given
every public module by name: a package with an `__all__` would otherwise hide its submodules.
The pages are not kept in the repository; tests/test_reference.py builds them and checks
that every name of every `__all__` is documented.
"""

from __future__ import annotations

import pkgutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def modules() -> list[str]:
    """The package and every module under it whose name has no part starting with an
    underscore, by import name."""
    import drake_continuum
    return ["drake_continuum"] + sorted(
        m.name for m in pkgutil.walk_packages(drake_continuum.__path__, "drake_continuum.")
        if not any(part.startswith("_") for part in m.name.split(".")))


def build(out: Path, search: bool = True, show_source: bool = True) -> Path:
    """Write the reference into `out` (index.html and one page a module; `search`: a search
    box and its index, `show_source`: each function's source beside it); return `out`."""
    import pdoc
    import pdoc.render
    pdoc.render.configure(docformat="google", search=search, show_source=show_source)
    pdoc.pdoc(*modules(), output_directory=Path(out))
    return Path(out)


if __name__ == "__main__":
    target = build(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "reference")
    print(f"wrote {target / 'index.html'}")
