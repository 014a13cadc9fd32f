"""scripts/wrap_pages.py, the docs' Meshcat page of one wrap a category, run as a user would
(its main with the user's arguments, in this process: a second interpreter would only import
the package again): one page a category asked for, titled with its object, plane and how the
wrap ended."""

import json
import runpy
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_wrap_pages_writes_a_titled_page_a_category(tmp_path, monkeypatch, capsys):
    main = runpy.run_path(str(ROOT / "scripts" / "wrap_pages.py"))["main"]
    monkeypatch.chdir(ROOT)
    monkeypatch.setattr(sys, "argv", ["wrap_pages.py", "--out", str(tmp_path),
                                      "--categories", "cup"])
    assert main() == 0
    out = capsys.readouterr().out
    rows = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
    assert [r["category"] for r in rows] == ["cup"]
    html = (tmp_path / "cup.html").read_text()
    title = f"cup_000 (seed 0), {rows[0]['plane']}: {rows[0]['status']}"
    assert f"<title>{title}" in html and 'id="wrap-overlay"' in html
    assert rows[0]["bytes"] == (tmp_path / "cup.html").stat().st_size > 100_000

    # A category it does not know: refused before anything is made.
    monkeypatch.setattr(sys, "argv", ["wrap_pages.py", "--out", str(tmp_path / "bad"),
                                      "--categories", "cup,spoon"])
    assert main() == 2 and "unknown spoon" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()
