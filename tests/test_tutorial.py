"""docs/tutorial.ipynb runs from top to bottom in a fresh kernel (nbclient), from a folder
outside the checkout, so the tutorial never rots; and it is committed with the outputs of
such a run, so a reader sees its results (chord histograms included) without running it."""

from pathlib import Path

import nbformat
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "docs" / "tutorial.ipynb"


def _stdout(nb) -> str:
    return "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code"
                   for o in c.outputs if o.get("name") == "stdout")


def _check_outputs(nb) -> None:
    """Every step printed its result: wraps, chords, the collection, a class, a recognition,
    a fit (whose tip error the notebook itself asserts under 2 cm); the chords drawn."""
    out = _stdout(nb)
    for text in ("plane rx0-cw:", "chords of this wrap", "6 objects, 24 wraps", "failed: none",
                 "classes: ['apple', 'bottle', 'mug']", "recognised as", "tip error"):
        assert text in out, f"{text!r} not printed"
    assert any(o.get("output_type") == "display_data" and "image/png" in o.get("data", {})
               for c in nb.cells for o in c.get("outputs", [])), "no chord histogram drawn"
    assert not any(o.get("output_type") == "error" for c in nb.cells
                   for o in c.get("outputs", []))


def test_tutorial_is_committed_with_its_outputs():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(nb)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert len(code) >= 7
    assert [c.execution_count for c in code] == list(range(1, len(code) + 1))  # one run
    _check_outputs(nb)


def test_tutorial_runs_from_top_to_bottom_outside_the_checkout(monkeypatch, tmp_path):
    monkeypatch.delenv("MPLBACKEND", raising=False)  # the kernel draws inline, as in Jupyter
    monkeypatch.setenv("TMPDIR", str(tmp_path))  # the notebook's work folder goes with the test's
    nb = nbformat.read(NOTEBOOK, as_version=4)
    # A failing cell raises CellExecutionError naming it and its traceback.
    NotebookClient(nb, timeout=900, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    _check_outputs(nb)
