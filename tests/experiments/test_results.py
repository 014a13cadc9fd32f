"""The results page: written from a reproduction's figures, its numbers are the figures'; the
README's results table agrees with the published docs/results.md."""

import re
from pathlib import Path

from drake_continuum.experiments.results import HEADLINE, results_markdown, write_results
from drake_continuum.experiments.settings import RunSettings, run_command

ROOT = Path(__file__).resolve().parents[2]
NUMBER = re.compile(r"\d[\d,]*(?:\.\d+)?")


def synthetic_figures() -> dict:
    """A small reproduction's figures, shaped as summary.json, with numbers unlike the
    shipped ones."""
    def policy(acc, wraps, rad):
        return {"accuracy_at_stop": acc, "wraps_to_stop": wraps,
                "movement_cost_to_stop_rad": rad}

    stamp = {"version": "9.8.7", "date": "2030-01-02"}
    kinds = {k: {"accuracy_mean": a, "accuracy_std": 0.031, "n_records": 40}
             for k, a in (("generated", 0.812), ("turned", 0.776), ("nudged", 0.701))}
    return {
        "collect": {"time_s": 12.0, **stamp},
        "classification": {
            "accuracy_mean": 0.8771, "accuracy_std": 0.0432, "baseline_accuracy_mean": 0.6543,
            "baseline_accuracy_std": 0.0211, "n_objects": 12, "n_splits": 7,
            "per_class": {"cup": 0.9, "toilet_paper": 0.55},
            "table1": [{"category": "cup", "n_objects": 6, "mean_chords": 2345.0,
                        "mean_wraps": 6.3, "mean_wrap_ms": 321.0},
                       {"category": "toilet_paper", "n_objects": 6, "mean_chords": 987.0,
                        "mean_wraps": 4.5, "mean_wrap_ms": 77.0}], **stamp},
        "active": {"n_train": 6, "n_test": 6, **stamp,
                   "policies": {"mcts": policy(0.833, 2.4, 0.87),
                                "greedy": policy(0.667, 1.6, 1.31),
                                "random": policy(0.5, 2.2, 1.74)}},
        "placements": {"train_kinds": ["generated", "side"], **stamp, "results": {
            "chords": {"kinds": kinds, "flips": {"pairs": 40, "flips": 3, "rate": 0.075}},
            "triangles": {"kinds": kinds, "flips": {"pairs": 40, "flips": 9, "rate": 0.225}}}},
        "real": {"clouds": [], "png": None},
        "observed": {**stamp, "n_objects": 8, "n_collection": 12, "n_splits": 7,
                     "frame": "plane",
                     "conditions": {k: {"accuracy_mean": a, "accuracy_std": 0.1}
                                    for k, a in (("exact", 0.911), ("one_view", 0.844),
                                                 ("two_views", 0.855),
                                                 ("transparent", 0.822))},
                     "confusion_one_view": {"cup": {"cup": 3, "mug": 1}, "mug": {"mug": 4}}},
    }


SETTINGS = {"quick": True, "per_category": 6, "splits": 7, "seed": 3,
            "placements": "side=1,turned=1", "second_dataset": False}


def _table(md: str, heading: str) -> dict:
    """The first table after `heading`: first cell (links unwrapped) -> the other cells."""
    lines = []
    for line in md.split(heading, 1)[1].splitlines():
        if line.startswith("|"):
            lines.append(line)
        elif lines:
            break
    rows = {}
    for line in lines[2:]:  # under the header and its rule
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        rows[re.sub(r"\[(.*?)\]\(.*?\)", r"\1", cells[0])] = cells[1:]
    return rows


def _numbers(text: str) -> list[float]:
    return [float(n.replace(",", "")) for n in NUMBER.findall(text)]


def test_the_page_holds_the_figures_numbers_and_the_command_that_made_them():
    md = results_markdown(synthetic_figures(), SETTINGS,
                          {"confusion.png": "images/c.png",
                           "active_curves.png": ("images/a.png", "made by hand")},
                          out_name="tiny")
    head = _table(md, "## Headline")
    assert [label for label, _ in HEADLINE] == list(head)
    assert _numbers(head["classifier accuracy"][0]) == [87.7, 4.3]
    assert _numbers(head["classifier accuracy"][1]) == [75.9]
    assert _numbers(head["triangle baseline [1]"][0]) == [65.4, 2.1]
    assert _numbers(head["active recognition at stop"][0]) == [83.3, 2.4, 0.87, 66.7, 50.0]
    assert _numbers(head["recognised through the camera"][0]) == [84.4, 82.2, 91.1, 8, 12]
    assert _numbers(head["usable wraps an object"][0]) == [4.5, 6.3]
    assert head["chords an object"][0].startswith("987 (toilet paper) to 2,345 (cup)")
    assert _numbers(head["time a wrap"][0]) == [77, 321]
    cmd = "drake-continuum reproduce --quick --per-category 6 --splits 7 --seed 3 " \
          "--placements side=1,turned=1 --no-second-dataset --out tiny"
    assert run_command(SETTINGS, "tiny") == cmd
    assert md.count(f"Made by `{cmd}` (drake-continuum 9.8.7, 2030-01-02).") == 4
    seen = _table(md, "## Recognition from what the camera sees of the arm")
    assert _numbers(seen["fitted, object transparent (touch-only model)"][0]) == [82.2, 10.0]
    placed = _table(md, "## Objects placed")
    assert _numbers(placed["nudged (up to 2 cm, 5 deg)"][0]) == [70.1, 3.1]
    assert _numbers(placed["flip rate (a prediction that changes under 1 mm / 1 deg)"][1]) \
        == [22.5, 9, 40]
    assert "![confusion matrix over all splits (Fig. 7)](images/c.png)" in md
    assert "per policy (made by hand)](images/a.png)" in md
    assert "two wraps a category (Fig. 5): not produced" in md
    assert "Fig. 8" not in md  # no cloud compared, no section


def test_defaults_make_the_plain_command():
    assert run_command({"quick": False, "splits": 100, "seed": 0,
                        "placements": RunSettings().placements, "second_dataset": True},
                       "results-full") == "drake-continuum reproduce --out results-full"


def test_the_command_sets_every_entry_that_differs_from_the_default_configuration():
    from drake_continuum.config import config_to_tree, load_config
    tree = config_to_tree(load_config(overrides=["planes.alpha_deg=45", "wrap.table=true",
                                                 "wrap.start_lengths=[0.1,0.2]"]))
    sets = re.findall(r"--set (\S+)", run_command({"config": tree}))
    assert len(sets) == 3
    assert config_to_tree(load_config(overrides=sets)) == tree


def test_a_page_outside_the_run_gets_its_images_beside_it(tmp_path):
    out = tmp_path / "run"
    (out / "classification").mkdir(parents=True)
    (out / "classification" / "confusion.png").write_bytes(b"png")
    inside = write_results(out, synthetic_figures(), SETTINGS)
    assert "](classification/confusion.png)" in inside.read_text()
    page = write_results(out, synthetic_figures(), SETTINGS, dest=tmp_path / "docs" / "results.md")
    assert "](images/confusion.png)" in page.read_text()
    assert (tmp_path / "docs" / "images" / "confusion.png").read_bytes() == b"png"


def test_readme_results_table_agrees_with_docs_results():
    """Every number of a README results row is in the same row of docs/results.md's
    headline, in order, and every row links to the page."""
    readme = (ROOT / "README.md").read_text()
    results = _table((ROOT / "docs" / "results.md").read_text(), "## Headline")
    ours = _table(readme, "## Results")
    assert len(ours) >= 5, "README.md has no results table under '## Results'"
    for label, cells in ours.items():
        assert "docs/results.md" in readme.split(f"[{label}](", 1)[1].split(")", 1)[0], label
        assert label in results, f"README row {label!r} is not in docs/results.md"
        page = _numbers(results[label][0])
        for n in _numbers(cells[0]):
            assert n in page, f"{label}: README's {n} is not in docs/results.md ({page})"
            page = page[page.index(n) + 1:]
