"""A reproduction's settings (RunSettings), what settings.json records of them
(settings_record) and the command line that makes a run of recorded settings (run_command).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..config import Config, config_to_tree, load_config
from ..errors import InputError
from ..files import json_text

__all__ = ["PLACEMENTS", "QUICK_PLACEMENTS", "QUICK_PLACED_PER_CATEGORY", "SPLITS",
           "QUICK_SPLITS", "RunSettings",
           "checked_categories", "settings_record", "run_command"]

# The placed copies of each object a run makes unless told: every kind, and for a quick run
# two copies an object instead of eight: turned, and its likeliest other side (`side`). A
# held-out object's side copy is tested as its `rest` copy would be (the same side, turned
# its own way: both rows agree within their noise), so a quick run wraps no `rest` copy.
PLACEMENTS = "side=3,turned=1,rest=1,lying=1,nudged=1,jitter=1"
QUICK_PLACEMENTS = "side=1,turned=1"
# A quick run places the first two objects of each category only (40 copies, not 80). Two,
# not one: a 50/50 split by object then mostly trains on a placed object of each category
# that it tests on, where with one the category's placed object is either trained on or
# tested, never both, and the other side's row falls far beyond its noise. A full run
# places every object (measured: BENCHMARKS.md, The suite).
QUICK_PLACED_PER_CATEGORY = 2
SPLITS, QUICK_SPLITS = 100, 20  # random 50/50 splits unless given: a full run, a quick one


@dataclass(frozen=True)
class RunSettings:
    """What a reproduction runs.

    Args:
        out: results folder.
        quick: a subset for a first look (per_category objects a category, fewer splits).
        per_category: objects a category in quick mode.
        splits: random 50/50 splits for classification (None: SPLITS, or QUICK_SPLITS
            when quick).
        workers: local processes for wrapping and active recognition (None: all cores).
        scheduler: Dask scheduler address for wrapping, or None.
        seed: seed of the dataset, the splits and the tree search.
        config: the experiment's parameters (default: models/config.yaml).
        redo: with other settings than the folder's run, redo the steps they change
            (default: refuse).
        placements: placed copies of each object (objects/placement.py KINDS, "KIND=N,..."):
            "train" and "side" ones are trained on, the others tested (splits by object).
        second_dataset: also generate, place and evaluate a dataset of seed + 1, never used
            to choose a setting.
        observed: also recognise from what the simulated camera sees of the arm (the
            `observed` step: minutes of fitting even in a quick run).
        categories: generate only these of the ten categories (None: all), each with the
            paper's count or per_category when quick; at least two. A cheaper run.
        placed_per_category: place only the first K objects a category (None: every
            object, or QUICK_PLACED_PER_CATEGORY when quick). The evaluation still trains on
            every training object as generated; the placed kinds are tested on the placed
            test objects only. A cheaper run.
        results_md: where to write the results page (default: OUT/results.md); elsewhere,
            its images are copied into an images/ folder beside it (docs/results.md).
    """

    out: Path = Path("results")
    quick: bool = False
    per_category: int = 4
    splits: int | None = None
    workers: int | None = None
    scheduler: str | None = None
    seed: int = 0
    config: Config | None = None
    redo: bool = False
    placements: str = PLACEMENTS
    second_dataset: bool = True
    observed: bool = True
    categories: tuple[str, ...] | None = None
    placed_per_category: int | None = None
    results_md: Path | None = None

    @property
    def cfg(self) -> Config:
        return self.config if self.config is not None else load_config()

    def __post_init__(self):
        if self.splits is not None and (isinstance(self.splits, bool) or self.splits < 1):
            raise InputError(f"splits must be at least 1, got {self.splits}")
        if self.categories is not None:
            object.__setattr__(self, "categories", checked_categories(self.categories))

    @property
    def effective_placed_per_category(self) -> int | None:
        if self.placed_per_category is not None:
            return self.placed_per_category
        return QUICK_PLACED_PER_CATEGORY if self.quick else None

    @property
    def effective_splits(self) -> int:
        if self.splits is not None:
            return self.splits
        return QUICK_SPLITS if self.quick else SPLITS


def checked_categories(names) -> tuple[str, ...]:
    """`names` as a tuple of generated categories, refused by name when one is unknown,
    repeated, or fewer than two are given (a classifier needs two)."""
    from ..objects.generators import CATEGORIES
    names = tuple(str(n) for n in names)
    unknown = [n for n in names if n not in CATEGORIES]
    if unknown:
        raise InputError(f"categories: unknown {', '.join(unknown)}; the generated ones are "
                         f"{', '.join(CATEGORIES)}")
    if len(set(names)) != len(names) or len(names) < 2:
        raise InputError(f"categories: give at least two, each once, got {', '.join(names)}")
    return names


def settings_record(settings: RunSettings) -> dict:
    """What settings.json records of a run (run_command turns it back into a command line)."""
    return {"quick": settings.quick, "per_category": settings.per_category,
            "splits": settings.effective_splits, "seed": settings.seed,
            "placements": settings.placements, "second_dataset": settings.second_dataset,
            "config": config_to_tree(settings.cfg),
            # recorded only when set, so that a folder of a run before it existed still
            # matches a run of every object
            **({} if settings.categories is None
               else {"categories": list(settings.categories)}),
            **({} if settings.effective_placed_per_category is None
               else {"placed_per_category": settings.effective_placed_per_category}),
            **({} if settings.observed else {"observed": False})}


def run_command(settings: dict, out: str = "results") -> str:
    """The `drake-continuum reproduce` command line that makes a run of these settings
    (settings.json's keys; the configuration's entries other than the default's as --set)."""
    d = RunSettings()
    parts = ["drake-continuum reproduce"]
    if settings.get("quick"):
        parts.append("--quick")
        if settings.get("per_category", d.per_category) != d.per_category:
            parts.append(f"--per-category {settings['per_category']}")
    default_splits = QUICK_SPLITS if settings.get("quick") else SPLITS
    if settings.get("splits", default_splits) != default_splits:
        parts.append(f"--splits {settings['splits']}")
    if settings.get("seed", d.seed) != d.seed:
        parts.append(f"--seed {settings['seed']}")
    if settings.get("categories"):
        parts.append(f"--categories {','.join(settings['categories'])}")
    if settings.get("placements", d.placements) != d.placements:
        parts.append(f"--placements {settings['placements']}")
    if not settings.get("second_dataset", True):
        parts.append("--no-second-dataset")
    if "config" in settings:
        parts += _set_options(settings["config"], config_to_tree(load_config()))
    parts.append(f"--out {out}")
    return " ".join(parts)


def _set_options(tree: dict, default: dict, prefix: str = "") -> list[str]:
    """`--set KEY=VALUE` for every entry of a configuration tree that differs from the
    default's (another arm: `--set arm=ARM.yaml`, the arm being a file of its own)."""
    out = []
    for key in sorted(set(tree) | set(default), key=str):
        name, a, b = f"{prefix}{key}", default.get(key), tree.get(key)
        if a == b:
            continue
        if name == "arm":
            out.append("--set arm=ARM.yaml")
        elif isinstance(a, dict) and isinstance(b, dict):
            out += _set_options(b, a, f"{name}.")
        else:
            out.append(f"--set {name}={json_text(b, indent=None, compact=True)}")
    return out
