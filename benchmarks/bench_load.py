"""CPU time to read wrap collections (learning.records.load_collection: each object's files
checked and read, its chords and descriptors computed), as a reproduction reads its originals
and placed copies. Each repeat runs in a fresh process, so that nothing read or parsed by an
earlier one is reused; prints JSON with the median. The code measured is the one imported:
run it with PYTHONPATH at another tree to compare two versions.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time


def once(folders: list[str]) -> dict:
    """One process's load of every folder: CPU and wall seconds, objects read."""
    from drake_continuum.learning.records import load_collection
    c0, t0 = time.process_time(), time.perf_counter()
    n, skipped = 0, 0
    for folder in folders:
        records, left_out = load_collection(folder)
        n, skipped = n + len(records), skipped + len(left_out)
    return {"cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - t0,
            "n_objects": n, "n_skipped": skipped}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("folders", nargs="+", help="wrap collections (WRAPS folders)")
    parser.add_argument("--repeat", type=int, default=3, help="fresh processes (default: 3)")
    parser.add_argument("--once", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.once:
        print(json.dumps(once(args.folders)))
        return
    runs = [json.loads(subprocess.run([sys.executable, __file__, "--once", *args.folders],
                                      check=True, capture_output=True, text=True).stdout)
            for _ in range(args.repeat)]
    print(json.dumps({"folders": args.folders, "n_objects": runs[0]["n_objects"],
                      "n_skipped": runs[0]["n_skipped"],
                      "cpu_s_median": round(statistics.median(r["cpu_s"] for r in runs), 2),
                      "wall_s_median": round(statistics.median(r["wall_s"] for r in runs), 2),
                      "cpu_s": [round(r["cpu_s"], 2) for r in runs],
                      "load": round(os.getloadavg()[0], 1)}, indent=1))


if __name__ == "__main__":
    main()
