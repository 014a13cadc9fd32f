"""What keeping a collection's index.json costs a collect run: written after every finished
object, against at most every collect.INDEX_INTERVAL_S at the run's pace (objects a second).
Replays the writes of a run of a stored collection's objects (its index.json's entries, in
order) into a temporary folder, with the same write (collection.write_index: JSON, fsync,
rename, folder fsync); prints JSON with the CPU and wall seconds of each way.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
from pathlib import Path

from drake_continuum.experiments.collect import INDEX_INTERVAL_S
from drake_continuum.experiments.collection import write_index


def replay(index: dict, counts: list[int]) -> dict:
    """Write index.json once for each count of finished objects in `counts`."""
    with tempfile.TemporaryDirectory(prefix="bench-index-") as tmp:
        c0, t0, size = time.process_time(), time.perf_counter(), 0
        for n in counts:
            write_index(Path(tmp), index["dataset"], index["params"],
                        objects=index["objects"][:n], failed=[])
            size += (Path(tmp) / "index.json").stat().st_size
        return {"writes": len(counts), "cpu_s": round(time.process_time() - c0, 2),
                "wall_s": round(time.perf_counter() - t0, 2), "megabytes_written": size / 1e6}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("collection", help="a wrap collection (its index.json is replayed)")
    parser.add_argument("--per-second", type=float, default=2.7,
                        help="objects finished a second (default: 2.7, the full run's 1,480 "
                             "placed copies in about 9 min on 2 cores)")
    args = parser.parse_args()
    index = json.loads((Path(args.collection) / "index.json").read_text())
    n = len(index["objects"])
    every = max(1, math.floor(INDEX_INTERVAL_S * args.per_second))  # objects between writes
    print(json.dumps({
        "objects": n,
        "every_object": replay(index, [0, *range(1, n + 1)]),
        "every_interval": replay(index, [0, *range(every, n, every), n]),
        "interval_s": INDEX_INTERVAL_S, "per_second": args.per_second,
        "load": round(os.getloadavg()[0], 1)}, indent=1))


if __name__ == "__main__":
    main()
