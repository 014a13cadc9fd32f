"""The results page (results.md, published as docs/results.md): the headline of a reproduction,
one row a claim with the paper's figure beside ours, then the paper's tables, the placed
objects, active recognition and the real-versus-simulated comparison, each section with the
command and package version that made it.

It is written from the same figures as report.md (`reproduce`'s step markers, summary.json)
but is short enough to publish: report.md keeps every per-category row and per-object list.
`reproduce` writes OUT/results.md; `reproduce --results-md docs/results.md` writes it there and
copies the images it shows into docs/images/.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from ..files import number_text, percent_text, write_atomic
from ..markdown import markdown_table
from .observed import observed_markdown
from .report import PAPER, clouds_table
from .settings import run_command

__all__ = ["HEADLINE", "IMAGES", "results_markdown", "write_results"]

# The headline's rows, in order: (label, step the figure comes from). The README's results
# table repeats these labels and numbers.
HEADLINE = (
    ("classifier accuracy", "classification"),
    ("triangle baseline [1]", "classification"),
    ("active recognition at stop", "active"),
    ("recognised through the camera", "observed"),
    ("usable wraps an object", "collect"),
    ("chords an object", "collect"),
    ("time a wrap", "collect"),
)
# The images the page shows: published name -> where `reproduce` writes it under OUT.
IMAGES = {"wraps.png": "figures/wraps.png", "confusion.png": "classification/confusion.png",
          "active_curves.png": "active/curves.png", "fig8.png": None}  # fig8: real's "png"
_POLICY_NAMES = {"mcts": "MCTS (eq. 1-3)", "greedy": "greedy information gain",
                 "random": "random plane order"}
_KIND_NAMES = {"generated": "as generated", "turned": "turned any way about the vertical",
               "rest": "on its likeliest other side, turned",
               "lying": "on another side drawn by its probability, turned",
               "nudged": "nudged (up to 2 cm, 5 deg)",
               "jitter": "turned, then moved 1 mm and 1 deg",
               "train": "dropped at random"}


def _made(figures: dict, steps, command: str) -> str:
    """Which command and package version made these steps' figures (the step markers'
    `version` and `date`; a step that records its own `command` was made by that), one line;
    steps of different versions are named."""
    made = {}
    for step in steps:
        if step not in figures:
            continue
        f = figures[step] or {}
        stamp = (f"drake-continuum {f['version']}" if f.get("version")
                 else "package version not recorded") + (f", {f['date']}" if f.get("date")
                                                         else "")
        made.setdefault(f.get("command", command), {}).setdefault(stamp, []).append(step)
    return "Made by " + " and ".join(
        f"`{c}` (" + "; ".join(stamp if len(stamps) == 1 else f"{', '.join(st)}: {stamp}"
                               for stamp, st in stamps.items()) + ")"
        for c, stamps in made.items()) + ".\n"


def _name(category: str) -> str:
    return category.replace("_", " ")


def _range(rows, key: str, fmt: str, *, unit: str = "") -> str | None:
    """'low (category) to high (category)' of a Table I column over categories; a category
    is named only when it alone holds the extreme."""
    vals = [(r[key], r["category"]) for r in rows if r.get(key) is not None]
    if not vals:
        return None

    def one(v):
        holders = [c for x, c in vals if x == v]
        name = f" ({_name(holders[0])})" if len(holders) == 1 else ""
        return fmt.format(v) + unit + name
    return f"{one(min(v for v, _ in vals))} to {one(max(v for v, _ in vals))}"


def _paper_rows():
    return [{"category": c, "mean_chords": ch, "mean_wraps": w, "mean_wrap_ms": ms}
            for c, (ch, w, ms) in PAPER["table1"].items()]


def _headline(figures: dict) -> list[tuple[str, str, str]]:
    cls, act = figures.get("classification") or {}, figures.get("active") or {}
    rows = cls.get("table1") or []
    paper = _paper_rows()
    cells = {}
    if "accuracy_mean" in cls:
        cells["classifier accuracy"] = (f"**{_mean_std(cls)}**", percent_text(PAPER["accuracy"]))
        cells["triangle baseline [1]"] = (_mean_std(cls, "baseline_accuracy"),
                                          percent_text(PAPER["baseline_accuracy"]))
    policies = act.get("policies") or {}
    if "mcts" in policies:
        m = policies["mcts"]
        others = ", ".join(f"{n} {percent_text(policies[n]['accuracy_at_stop'])}"
                           for n in ("greedy", "random") if n in policies)
        cells["active recognition at stop"] = (
            f"**{percent_text(m['accuracy_at_stop'])}** (MCTS) after "
            f"{m['wraps_to_stop']:.1f} wraps, "
            f"{m['movement_cost_to_stop_rad']:.2f} rad" + (f" ({others})" if others else ""),
            "5 to 8 wraps (accuracy not given)")
    study = figures.get("observed") or {}
    seen = study.get("conditions") or {}
    if {"exact", "one_view", "transparent"} <= set(seen):
        acc = {k: percent_text(seen[k]["accuracy_mean"]) for k in seen}
        cells["recognised through the camera"] = (  # a smaller study than Table I's
            f"**{acc['one_view']}** from one view of the arm, **{acc['transparent']}** with "
            f"the object transparent, against {acc['exact']} on exact configurations "
            f"({study.get('n_objects', 'n/a')} objects seen; each split trains on half of "
            f"{study.get('n_collection', study.get('n_objects', 'n/a'))})",
            "transparent objects, while the arm is seen (no figure)")
    for label, key, fmt, unit, tail in (
            ("usable wraps an object", "mean_wraps", "{:.1f}", "", ""),
            ("chords an object", "mean_chords", "{:,.0f}", "", ""),
            ("time a wrap", "mean_wrap_ms", "{:,.0f}", " ms", ", mean by category")):
        ours = _range(rows, key, fmt, unit=unit)
        if ours is not None:
            cells[label] = (ours + (", Python" if key == "mean_wrap_ms" else "") + tail,
                            _range(paper, key, fmt, unit=unit) + (", C++" if unit else ""))
    return [(label, *cells[label]) for label, _ in HEADLINE if label in cells]


def _mean_std(r: dict, key: str = "accuracy") -> str:
    """'mean ± std' of a figure over splits (the std left out where it is not recorded)."""
    std = r.get(f"{key}_std")
    return percent_text(r.get(f"{key}_mean")) + ("" if std is None else f" ± {percent_text(std)}")


def _policies(active: dict) -> str:
    return "\n".join(markdown_table(
        ("policy", "accuracy at stop", "wraps to stop", "movement to stop (rad)"),
        [(_POLICY_NAMES.get(name, name), percent_text(r["accuracy_at_stop"]),
          number_text(r.get("wraps_to_stop"), "{:.1f}"),
          number_text(r.get("movement_cost_to_stop_rad"), "{:.2f}"))
         for name, r in active["policies"].items()],
        align=("---", "---:", "---:", "---:"))) + "\n"


def _placed(results: dict) -> str:
    """One row a placement kind, one column a method (chords, triangles), then the flips."""
    methods = list(results)
    kinds = [k for k in _KIND_NAMES if any(k in results[m]["kinds"] for m in methods)]
    rows = [(_KIND_NAMES[k],
             *(_mean_std(r) if (r := results[m]["kinds"].get(k)) else "" for m in methods))
            for k in kinds]
    flips = [results[m].get("flips") or {} for m in methods]
    if any(f.get("rate") is not None for f in flips):
        rows.append(("flip rate (a prediction that changes under 1 mm / 1 deg)", *(
            "" if f.get("rate") is None else percent_text(f["rate"]) + (
                f" ({f['flips']:,} of {f['pairs']:,})" if f.get("pairs") else "")
            for f in flips)))
    return "\n".join(markdown_table(("objects placed", *methods), rows,
                                     align=("---", *["---:"] * len(methods)))) + "\n"


def _img(link, alt: str) -> str:
    """An image, its link relative to the page, or (link, note) for one made otherwise than
    the section's figures (the note says how)."""
    if isinstance(link, (tuple, list)):
        link, note = link
        alt = f"{alt} ({note})"
    return f"![{alt}]({link})\n" if link else f"*({alt}: not produced in this run)*\n"


def results_markdown(figures: dict, settings: dict, images: dict | None = None, *,
                     out_name: str = "results") -> str:
    """The results page from a reproduction's figures (summary.json: one entry a step) and
    settings (settings.json). `images` maps IMAGES' names to links relative to the page, or
    to (link, note) (missing: said not produced); `out_name` is the --out the page's commands
    name."""
    images = images or {}
    command = run_command(settings, out_name)
    cls = figures.get("classification") or {}
    act, real = figures.get("active") or {}, figures.get("real") or {}
    placed, act_placed = figures.get("placements") or {}, figures.get("active_placed") or {}
    second = figures.get("second") or {}
    mode = (f"a quick subset, {settings.get('per_category')} objects a category"
            if settings.get("quick") else "the full generated dataset")
    parts = [
        "# Results\n",
        f"The paper's figures beside ours, on {mode} (seed {settings.get('seed', 0)}, "
        f"{cls.get('n_objects', 'n/a')} objects, {cls.get('n_splits', 'n/a')} random 50/50 "
        "splits by object). `drake-continuum reproduce` writes this page as results.md beside "
        "its report.md, which holds every per-category row; `--results-md docs/results.md` "
        "writes it here.\n",
        "## Headline\n",
        "\n".join(markdown_table(("claim", "ours", "paper"), _headline(figures))) + "\n",
        "The classifier is a linear SVM over PCA (95 %) of chord histograms (section IV-B/C) "
        "joined by per-plane wrap descriptors, the contact extent and the depth camera's view "
        "of the object (models/config.yaml, `classifier`); the baseline is the triangle "
        "histograms of tactile contacts of [1] (the paper's reference, Zhang et al. 2016) on "
        "the same wraps' contacts and splits. Active recognition is the "
        "tree search of section IV-D on the held-out objects; wraps, chords and times are "
        "means by category over the wrap planes of Fig. 4.\n",
        "## Classification (Table I, Fig. 5, Fig. 7)\n",
        _made(figures, ("collect", "classification"), command),
    ]
    if cls.get("per_class"):
        parts.append("Per category (recall over all splits' test objects): " + ", ".join(
            f"{_name(k)} {percent_text(v)}" for k, v in cls["per_class"].items()) + ".\n")
    parts += [_img(images.get("wraps.png"), "two wraps a category (Fig. 5)"),
              _img(images.get("confusion.png"), "confusion matrix over all splits (Fig. 7)")]
    if act.get("policies"):
        parts += ["## Active recognition (Table II)\n", _made(figures, ("active",), command),
                  f"Trained on {act['n_train']} objects, tested on the {act['n_test']} held "
                  "out; the stop rule is section IV-D's (top probability over 0.5 and three "
                  "times the next), movement the rotation between consecutive wrap planes.\n",
                  _policies(act),
                  _img(images.get("active_curves.png"),
                       "accuracy against wraps and against movement, per policy")]
    if placed.get("results"):
        parts += ["## Objects placed as a robot meets them\n",
                  _made(figures, ("placements", "active_placed"), command),
                  "The paper tests every object in one pose. Each held-out object is also "
                  "tested turned, on another side and nudged off the mark, splits by object "
                  f"(trained on: {', '.join(placed.get('train_kinds', []))} copies).\n",
                  _placed(placed["results"])]
        if act_placed.get("policies"):
            parts += [f"Active recognition of the {act_placed['n_test']} placed copies of "
                      "the held-out objects:\n", _policies(act_placed)]
        if second.get("results"):
            c = second.get("classification") or {}
            parts += [f"### A second dataset (seed {second['seed']}, never used to choose a "
                      f"setting)\n", _made(figures, ("second",), command),
                      f"As generated: chords {_mean_std(c)}, triangles "
                      f"{_mean_std(c, 'baseline_accuracy')}. Placed:\n",
                      _placed(second["results"])]
    if (figures.get("observed") or {}).get("conditions"):
        parts += ["## Recognition from what the camera sees of the arm\n",
                  _made(figures, ("observed",), command),
                  "Trained on exact wraps, tested by object on the exact configurations and on "
                  "configurations fitted to simulated depth-camera clouds (experiments/"
                  "observed.py); active recognition on one split's held-out half. Both "
                  "answer under a uniform category prior: the objects seen come evenly by "
                  "category, while a training half holds each as often as the collection "
                  "does (the models' probabilities reweighted by Bayes' rule).\n",
                  observed_markdown(figures["observed"])]
    if real.get("clouds"):
        parts += ["## Point clouds against simulated wraps (Fig. 8)\n",
                  _made(figures, ("real",), command), clouds_table(real),
                  _img(images.get("fig8.png"), "cloud, segmented arm, reconstruction (Fig. 8)")]
    return "\n".join(parts)


def write_results(out: Path, figures: dict, settings: dict, *, dest: Path | None = None) -> Path:
    """Write the results page of the run in `out` to `dest` (default: OUT/results.md). A page
    outside `out` gets copies of its images in an images/ folder beside it."""
    out = Path(out)
    dest = Path(dest) if dest is not None else out / "results.md"
    sources = dict(IMAGES, **{"fig8.png": (figures.get("real") or {}).get("png")})
    inside = dest.parent.resolve() == out.resolve()
    images = {}
    for name, rel in sources.items():
        if not rel or not (out / rel).exists():
            continue
        if inside:
            images[name] = rel
        else:
            (dest.parent / "images").mkdir(parents=True, exist_ok=True)
            shutil.copyfile(out / rel, dest.parent / "images" / name)
            images[name] = f"images/{name}"
    md = results_markdown(figures, settings, images, out_name=os.path.basename(out.resolve()))
    write_atomic(dest, md.encode())
    return dest
