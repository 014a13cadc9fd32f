"""CPU time to read each kind of .npz a reproduction writes, with np.load as a reader would
call it and with npz.npz_arrays, the arrays checked equal (dtype, shape, bytes, memory order).
Files are read once before timing (warm page cache); prints one JSON line a kind with the
median of --repeat passes over its files.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np

from drake_continuum.npz import npz_arrays

KINDS = {  # the files of a run folder each reader reads
    "wraps (collect's check of an object without a digest)": "wraps/*.npz",
    "observed_cache (the camera study's cache)": "observed_cache/*.npz",
    "real_cache (the real-versus-simulated comparison's cache)": "real_cache/*.npz",
    "model/model.npz (load_model)": "model/model.npz",
    "active-model/model.npz (load_model)": "active-model/model.npz",
    "active-model/observations.npz (load_observation_model)": "active-model/observations.npz",
}


def with_np_load(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def with_npz_arrays(path: Path) -> dict:
    return npz_arrays(path.read_bytes())


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(
        a[k].dtype == b[k].dtype and a[k].shape == b[k].shape and a[k].tobytes() == b[k].tobytes()
        and a[k].flags.c_contiguous == b[k].flags.c_contiguous for k in a)


def _cpu_s(read, files: list, repeat: int) -> float:
    passes = []
    for _ in range(repeat):
        c0 = time.process_time()
        for f in files:
            read(f)
        passes.append(time.process_time() - c0)
    return statistics.median(passes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("run", type=Path, help="a `drake-continuum reproduce` output folder")
    parser.add_argument("--repeat", type=int, default=5, help="passes a kind (default: 5)")
    args = parser.parse_args()
    for kind, pattern in KINDS.items():
        files = sorted(args.run.glob(pattern))
        if not files:
            continue
        loaded = [with_np_load(f) for f in files]
        if not all(_same(a, with_npz_arrays(f)) for a, f in zip(loaded, files)):
            raise SystemExit(f"{kind}: npz_arrays' arrays differ from np.load's")
        base = _cpu_s(with_np_load, files, args.repeat)
        ours = _cpu_s(with_npz_arrays, files, args.repeat)
        print(json.dumps({"kind": kind, "files": len(files),
                          "arrays": sum(len(a) for a in loaded),
                          "mb": round(sum(f.stat().st_size for f in files) / 1e6, 1),
                          "np_load_cpu_s": round(base, 4), "npz_arrays_cpu_s": round(ours, 4),
                          "ratio": round(base / ours, 2)}), flush=True)


if __name__ == "__main__":
    main()
