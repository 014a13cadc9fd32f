"""The reproduction report: every table and figure with the paper's numbers beside ours, as
Markdown (report.md) and a self-contained-folder HTML page (report.html, images beside it)."""

from __future__ import annotations

import platform
from pathlib import Path

import markdown

from ..files import number_text, percent_text, write_atomic, write_json
from ..markdown import markdown_table
from .observed import observed_markdown
from .timing import run_work, step_table, work_table

__all__ = ["PAPER", "build_markdown", "clouds_table", "observed_section", "HTML_HEAD",
           "write_report"]


# The paper's figures the report sets ours beside.
PAPER = {
    "accuracy": 0.759, "baseline_accuracy": 0.747,
    "table1": {  # category: (mean chords, mean wraps, ms a wrap), paper Table I (C++)
        "apple": (2676, 10, 400), "banana": (1816, 9.7, 190), "bottle": (1760, 10, 130),
        "bowl": (2090, 9.6, 230), "cup": (2317, 10, 540), "donut": (1365, 5.1, 200),
        "hammer": (1711, 10, 110), "mug": (2557, 10, 530), "teapot": (2350, 9.8, 1200),
        "toilet_paper": (2944, 10, 260)},
}


def _img(out: Path, rel: str | None, alt: str) -> str:
    if rel and (out / rel).exists():
        return f"![{alt}]({rel})\n"
    return f"*({alt}: not produced in this run)*\n"


def _table1(rows) -> str:
    header = ("category", "objects", "chords (ours)", "chords (paper)", "wraps (ours)",
              "wraps (paper)", "ms a wrap (ours, Python)", "ms a wrap (paper, C++)",
              "arm near the surface (median)", "contact regions a wrap")
    cells = []
    for r in rows:
        p = PAPER["table1"].get(r["category"], (None, None, None))
        near = r.get("median_conformity")  # absent in tables of older runs
        cells.append((r["category"], r["n_objects"], number_text(r["mean_chords"]),
                      number_text(p[0]), number_text(r["mean_wraps"], "{:.1f}"),
                      number_text(p[1], "{:.1f}"), number_text(r["mean_wrap_ms"]),
                      number_text(p[2]), percent_text(near),
                      number_text(r.get("mean_contact_regions"), "{:.1f}")))
    return "\n".join(markdown_table(header, cells)) + "\n"


def _policies(policies: dict) -> str:
    header = ("policy", "accuracy at stop", "wraps to stop", "movement cost to stop (rad)",
              "strong predictions", "median search (s)")
    return "\n".join(markdown_table(header, [
        (name, percent_text(r.get("accuracy_at_stop")),
         number_text(r.get("wraps_to_stop"), "{:.2f}"),
         number_text(r.get("movement_cost_to_stop_rad"), "{:.2f}"),
         percent_text(r.get("strong_fraction")),
         number_text(r.get("median_search_time_s"), "{:.3f}"))
        for name, r in policies.items()])) + "\n"


def clouds_table(real: dict) -> str:
    """The clouds' table, said to be simulated where they are (until real captures exist the
    shipped clouds are the depth-camera simulator's)."""
    rows = real.get("clouds", [])
    if not rows:
        return "*(no clouds compared)*\n"
    keys = [k for k in rows[0] if k not in ("cloud", "png", "capture")]
    simulated = [r["cloud"] for r in rows if r.get("capture") == "simulated"]
    parts = []
    if simulated:
        parts.append(f"**{len(simulated)} of these {len(rows)} clouds are simulated, not "
                     "captured**: a Kinect model (perception/depth_camera.py) renders true "
                     "wraps with a 2 mm flattening at contacts (real/make_sample_clouds.py). "
                     "They test the fitting and the comparison, not the real arm. A lab's "
                     "capture drops in as described in docs/clouds.md.\n")
    lines = markdown_table(("cloud", "capture", *keys), [
        (r["cloud"], r.get("capture", "real"),
         *(number_text(r[k], "{:.4g}") if isinstance(r[k], (int, float)) else r[k]
           for k in keys)) for r in rows])
    return "\n".join(parts + lines) + "\n"


def _misclassified(rows, top: int = 8) -> str:
    """The objects most often wrong over the splits, with the command that draws one."""
    if not rows:
        return ""
    lines = [f"Objects most often misclassified ({len(rows)} were wrong at least once; all "
             f"in classification/evaluation.json):\n",
             *markdown_table(("object", "category", "wrong / tested", "taken for"), [
                 (r["object_id"], r["category"], f"{r['wrong']} / {r['tested']}",
                  ", ".join(f"{c} {n}" for c, n in r["as"].items())) for r in rows[:top]])]
    lines.append(f"\nTo see one: `drake-continuum show-wraps wraps {rows[0]['object_id']} "
                 f"--png {rows[0]['object_id']}.png` in this folder.\n")
    return "\n".join(lines) + "\n"


def _placed_section(out: Path, figures: dict) -> str:
    """Objects as a robot meets them: the placements table of this dataset and of the
    second one, active recognition of placed objects, and the recommended models."""
    placed, active, second = (figures.get(k) for k in ("placements", "active_placed",
                                                       "second"))
    if not placed:
        return ""
    parts = ["## Objects placed as a robot meets them\n",
             "The paper trains and tests every object in one pose. Here each held-out object "
             "is also tested turned any way about the vertical, lying on its most probable "
             "other side (trimesh's stable poses) and on one drawn by its probability among "
             "the other sides, and nudged (up to 2 cm and 5 deg off the "
             "mark the arm is centred on), with chord histograms and the triangle baseline, "
             f"over the same random splits by object (trained on: "
             f"{' and '.join(placed['train_kinds'])} placements). A flip is a prediction "
             "that changes when the object is moved 1 mm and turned 1 deg.\n"]
    table = out / placed["table"]
    parts.append(table.read_text() if table.exists() else "*(table not produced)*\n")
    if active and active.get("policies"):
        parts.append(f"\nActive recognition of the {active['n_test']} placed copies of the "
                     f"held-out objects (trained on {active['n_train']} records): accuracy at "
                     "its stop, by placement:\n")
        kinds = sorted(next(iter(active["policies"].values())).get("by_kind", {}))
        rows = markdown_table(
            ("policy", "at stop", *kinds, "wraps", "movement (rad)"),
            [(name, percent_text(r["accuracy_at_stop"]),
              *(percent_text(r.get("by_kind", {}).get(k)) for k in kinds),
              f"{r['wraps_to_stop']:.1f}", f"{r['movement_cost_to_stop_rad']:.2f}")
             for name, r in active["policies"].items()],
            align=("---", "---:", *["---:"] * len(kinds), "---:", "---:"))
        parts.append("\n".join(rows) + "\n")
    if second and not second.get("skipped"):
        c = second["classification"]
        parts.append(f"\n### A second dataset (seed {second['seed']}, never used to choose a "
                     f"setting)\n\nAs generated, {c['n_objects']} objects, {c['n_splits']} "
                     f"splits: chords {percent_text(c['accuracy_mean'])} ± "
                     f"{percent_text(c['accuracy_std'])}, "
                     f"triangles {percent_text(c['baseline_accuracy_mean'])}. Placed:\n")
        table = out / second["table"]
        parts.append(table.read_text() if table.exists() else "*(table not produced)*\n")
    elif second:
        parts.append("\n### A second dataset\n\nNot run here (`--no-second-dataset`): "
                     "`reproduce` without it adds a dataset of seed + 1, never used to choose "
                     "a setting, its classification and its placed copies.\n")
    parts.append(f"\nThe recommended models, trained on every object and its training "
                 f"placements: `{placed['model']}` (`drake-continuum classify "
                 f"{out.name}/{placed['model']} MESH --turn 45`) and `{placed['active_model']}` "
                 f"(`drake-continuum recognize {out.name}/{placed['active_model']} MESH`).\n")
    return "\n".join(parts)


def _skipped(rows) -> str:
    """The collection's objects left out of the figures, and why."""
    if not rows:
        return ""
    lines = [f"**{len(rows)} object(s) of the collection left out** (missing or damaged "
             f"files, or failed in collection; also in classification/evaluation.json):\n",
             *markdown_table(("object", "reason"), [
                 (r["object_id"], str(r["reason"]).replace("|", "/")) for r in rows])]
    return "\n".join(lines) + "\n"


def observed_section(observed: dict | None) -> str:
    """The camera study (experiments/observed.py) from its step's figures, its table read by
    observed_markdown as the results page reads it."""
    heading = "## Recognition from what the camera sees of the arm\n\n"
    if observed and observed.get("skipped"):
        return heading + "Not run (`--no-observed`); a run without that option adds it.\n"
    if not (observed or {}).get("conditions"):
        return ""
    return (heading +
            f"Trained on exact wraps; tested by object on {observed['n_objects']} objects, "
            f"{observed['n_splits']} random 50/50 splits, on the exact configurations and on "
            f"configurations fitted to simulated depth-camera clouds (chords in the "
            f"{observed['frame']!r} frame); active recognition (tree search, the stop rule) "
            "on one split's held-out half.\n\n" + observed_markdown(observed))


def build_markdown(out: Path, figures: dict, settings: dict) -> str:
    ds, col = figures["dataset"], figures["collect"]
    cls, act, real = figures["classification"], figures["active"], figures["real"]
    mode = (f"**quick** subset: {settings['per_category']} objects a category, "
            f"{settings['splits']} splits" if settings["quick"]
            else f"full dataset, {settings['splits']} splits")
    table2 = (out / "active" / "table2.md")
    parts = [
        "# drake-continuum: reproduction of Mao, Zhang, Xiao and Daniilidis\n",
        f"Run: {mode}, seed {settings['seed']}; Python {platform.python_version()} on "
        f"{platform.machine()}. Every number below is read from the files of this folder.\n",
        "## Headline\n",
        "\n".join(markdown_table(("result", "ours", "paper"), [
            (f"linear SVM on chord histograms and wrap features (config: classifier), "
             f"{cls['n_splits']} random 50/50 splits",
             f"{percent_text(cls['accuracy_mean'])} ± {percent_text(cls['accuracy_std'])}",
             "75.9 %"),
            ("triangle histograms of [1] on the same wraps and splits",
             f"{percent_text(cls['baseline_accuracy_mean'])} ± "
             f"{percent_text(cls['baseline_accuracy_std'])}", "74.7 %"),
            ("objects, categories", f"{cls['n_objects']}, {len(cls['per_class'])}",
             "185, 10")])) + "\n",
        "## Dataset\n",
        f"{ds['n_objects']} generated objects "
        f"({', '.join(f'{k} {v}' for k, v in ds['counts'].items())}).\n",
        _img(out, figures["gallery"].get("png"), "every object of the dataset"),
        "## Wraps (Fig. 5, Table I)\n",
        f"Collected in {col.get('time_s', float('nan')):.0f} s.\n",
        _img(out, figures["wrap_figure"].get("png"), "one wrap a category (Fig. 5)"),
        _table1(cls["table1"]),
        "## Classification (Fig. 7)\n",
        "Per-category accuracy (recall over all splits' test objects): " +
        ", ".join(f"{k} {percent_text(v)}" for k, v in cls["per_class"].items()) + ".\n",
        _img(out, "classification/confusion.png", "confusion matrix, chord histograms (Fig. 7)"),
        _img(out, "classification/confusion_triangles.png",
             "confusion matrix, triangle histograms"),
        _misclassified(cls.get("misclassified", [])),
        _skipped(cls.get("skipped", [])),
        "## Active recognition (Table II)\n",
        f"Trained on {act['n_train']} objects, tested on the {act['n_test']} held out.\n",
        table2.read_text() if table2.exists() else "*(Table II not produced)*\n",
        "\n### Lookahead against greedy and random plane choice\n",
        _policies(act["policies"]),
        _img(out, "active/curves.png", "accuracy against wraps and movement cost"),
        observed_section(figures.get("observed")),
        "## Point clouds against simulated wraps (Fig. 8)\n",
        clouds_table(real),
        _img(out, real.get("png"), "cloud, segmented arm, reconstruction (Fig. 8)"),
        _placed_section(out, figures),
        "## Times\n",
        "Wall time by step, as the run waited at it (work queued on the run's workers "
        "before its step, such as the placed copies or the camera study's fits, counts "
        "there only as long as it was waited on; it grows with the machine's load), and "
        "the work by kind in CPU seconds (user and system, summed over this process and "
        "its workers: about the run's CPU time, which the load barely changes, and over "
        "the wall time when several cores work):\n",
        step_table(figures),
        work_table(run_work(figures)),
    ]
    return "\n".join(parts)


HTML_HEAD = """<!DOCTYPE html><html><head><meta charset="utf-8">
<title>drake-continuum report</title>
<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em}
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px}
img{max-width:100%}</style></head><body>
"""


def write_report(out: Path, figures: dict, settings: dict) -> Path:
    out = Path(out)
    md = build_markdown(out, figures, settings)
    write_atomic(out / "report.md", md.encode())
    html = HTML_HEAD + markdown.markdown(md, extensions=["tables"]) + "\n</body></html>\n"
    write_atomic(out / "report.html", html.encode())
    write_json(out / "summary.json", figures)
    return out / "report.md"
