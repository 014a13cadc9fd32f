"""Time to generate the paper's 185 objects (10 categories) into a fresh folder, with the
triangle counts and file sizes that contact queries and disks will see. Prints JSON; the goal
is at most 60 s on a 2-core machine."""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from drake_continuum.files import json_text
from drake_continuum.objects.dataset import generate_dataset, load_manifest


def run(seed: int, workers: int | None) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        generate_dataset(tmp, seed=seed, workers=workers, progress=False)
        seconds = time.perf_counter() - start
        ds = load_manifest(tmp)
        size = sum(p.stat().st_size for p in Path(tmp).iterdir())
    per_category = {}
    for category in ds.categories:
        tris = np.array([o.n_triangles for o in ds.by_category(category)])
        per_category[category] = {"n": int(len(tris)), "triangles_min": int(tris.min()),
                                  "triangles_median": int(np.median(tris)),
                                  "triangles_max": int(tris.max())}
    return {"n_objects": len(ds), "seconds": round(seconds, 2), "seed": seed,
            "workers": workers or os.cpu_count(), "cpus": os.cpu_count(),
            "megabytes": round(size / 1e6, 1), "per_category": per_category}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seed", type=int, default=0, help="generator seed (default: 0)")
    parser.add_argument("--workers", type=int, default=None,
                        help="worker processes (default: number of CPUs)")
    args = parser.parse_args()
    print(json_text(run(args.seed, args.workers), indent=1))


if __name__ == "__main__":
    main()
