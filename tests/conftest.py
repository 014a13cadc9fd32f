import os
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")

TESTS = Path(__file__).resolve().parent
# `make test` runs the files on two workers (pytest-xdist, --dist loadfile), each worker
# taking the next file in collection order. The longest files go first (their share of the
# suite's test time in BENCHMARKS.md, The suite), so that the other worker runs the many
# short ones meanwhile and both finish together.
FIRST = (
    "experiments/test_reproduce.py",
    "experiments/test_collect.py",
    "cli/test_cli.py",
    "experiments/test_observed.py",
    "test_package.py",
    "active/test_active.py",
    "test_faults.py",
    "wrapping/test_bound.py",
    "test_tutorial.py",
)


def pytest_collection_modifyitems(items):
    def rank(item):
        name = item.path.relative_to(TESTS).as_posix() if item.path.is_relative_to(TESTS) else ""
        return FIRST.index(name) if name in FIRST else len(FIRST)

    items.sort(key=rank)  # stable: the other files keep their order
