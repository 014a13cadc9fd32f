"""Generate a small dataset (4 objects a category), collect every wrap, and evaluate.

The same three steps as `drake-continuum reproduce`, spelled out on the library.
"""

import argparse
from pathlib import Path

from drake_continuum.experiments.collect import collect
from drake_continuum.learning.evaluation import evaluate
from drake_continuum.learning.records import load_wraps
from drake_continuum.objects.dataset import generate_dataset
from drake_continuum.objects.generators import CATEGORIES


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default="sim-results", help="output folder (default: sim-results)")
    parser.add_argument("--per-category", type=int, default=4,
                        help="objects a category, at least 4 for 50/50 splits (default: 4)")
    args = parser.parse_args()

    out = Path(args.out)
    generate_dataset(out / "dataset", seed=0, counts={c: args.per_category for c in CATEGORIES})
    collect(out / "dataset", out / "wraps")
    result = evaluate(load_wraps(out / "wraps"), n_splits=10, seed=0)
    print(f"accuracy over 10 splits: {result.accuracy_mean:.1%} +- {result.accuracy_std:.1%}")


if __name__ == "__main__":
    main()
