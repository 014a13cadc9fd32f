"""The project's text speaks of the software, not of the work that made it.

README, CHANGELOG, BENCHMARKS, docs, the model files, pyproject.toml and the Makefile, and
the comments and docstrings of every .py file of the package, benchmarks, sim, real, scripts
and tests carry no work-history labels: no numbered sessions, no branch names, no commit
hashes as provenance, no paths outside the repository. History lives in git and in the
CHANGELOG by version. A failure lists file:line of every hit.
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# Files read whole, as prose (globs under the repository's root).
PROSE = ("README.md", "CHANGELOG.md", "BENCHMARKS.md", "docs/**/*.md", "docs/**/*.ipynb",
         "models/*.yaml", "real/**/*.md", "pyproject.toml", "Makefile")
# Folders whose .py files are read for their comments and docstrings only.
CODE = ("drake_continuum", "benchmarks", "sim", "real", "scripts", "tests")
SKIP = {Path(__file__).resolve()}  # this file spells the patterns out

# The project's branch names (letters, then the number, then a letter for a pass).
_BRANCHES = r"(?:place14[a-e]?|conform19|bound19|fits16[a-z]?|ik13|cli17|docs17)"
LABELS = (
    ("work session", re.compile(r"\bsessions? \d", re.IGNORECASE)),
    ("branch name", re.compile(rf"\bbranch(?:es)? [`'\"]?[A-Za-z]+\d+[a-z]?\b|\b{_BRANCHES}\b")),
    ("path outside the repository", re.compile(r"\.\./shared|/work/|/root/|/home/")),
    # 7 to 40 hexadecimal digits with at least one digit and one letter: a commit hash
    ("commit hash", re.compile(r"\b(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b")),
)


def _docstrings(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if (body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                    and isinstance(body[0].value.value, str)):
                yield body[0].value


def python_prose(text: str) -> list[tuple[int, str]]:
    """(line number, text) of every comment and every line of every docstring."""
    lines = [(tok.start[0], tok.string)
             for tok in tokenize.generate_tokens(io.StringIO(text).readline)
             if tok.type == tokenize.COMMENT]
    for doc in _docstrings(ast.parse(text)):
        # the constant's source lines: its value's lines, from the line it starts on
        lines += [(doc.lineno + i, line) for i, line in enumerate(doc.value.splitlines())]
    return sorted(lines)


def project_text(patterns=PROSE, folders=CODE) -> list[tuple[Path, list[tuple[int, str]]]]:
    files = [p for pattern in patterns for p in sorted(ROOT.glob(pattern))]
    files += [p for folder in folders for p in sorted((ROOT / folder).rglob("*.py"))]
    out = []
    for path in files:
        if path.resolve() in SKIP or ".venv" in path.parts or not path.is_file():
            continue
        text = path.read_text(encoding="utf-8")
        lines = (python_prose(text) if path.suffix == ".py"
                 else list(enumerate(text.splitlines(), start=1)))
        out.append((path, lines))
    return out


def hits(files) -> list[str]:
    found = []
    for path, lines in files:
        for number, line in lines:
            for name, pattern in LABELS:
                if pattern.search(line):
                    found.append(f"{path.relative_to(ROOT)}:{number}: {name}: {line.strip()[:120]}")
    return found


def test_the_checks_find_what_they_are_for():
    sample = [(ROOT / "x.md", list(enumerate([
        "measured in session 9 of the work", "on branch conform19", "merged place14e",
        "see ../shared/data/x.txt", "in /work/data/ds0", "commit 5597ad1 gave 92.3 %",
        # what may stay: versions, dates, seeds, units, issue links, hex-free words
        "0.5.0 (2026-11-24), seed 71, 1.2e-06 m, issue 19, a decade of accepted faces",
    ], start=1)))]
    assert [h.split(": ")[1] for h in hits(sample)] == [
        "work session", "branch name", "branch name", "path outside the repository",
        "path outside the repository", "commit hash"]


def test_comments_and_docstrings_are_read_from_python():
    text = ('"""Module, session 3."""\nx = "session 4"  # session 5\n\n'
            'def f():\n    """a\n    b"""\n')
    assert python_prose(text) == [(1, "Module, session 3."), (2, "# session 5"),
                                  (5, "a"), (6, "    b")]


def test_the_project_text_carries_no_work_history_labels():
    found = hits(project_text())
    assert not found, "work-history labels in the project's text:\n" + "\n".join(found)



def test_readme_stays_a_page():
    """The README is a first page, not the manual: at most 150 lines (the rest is in docs/)."""
    n = len((ROOT / "README.md").read_text().splitlines())
    assert n <= 150, f"README.md has {n} lines; move detail to docs/"
