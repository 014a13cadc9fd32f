"""Collections on a pool the caller keeps (reproduce's one pool for its steps): the same
wraps as a collection in one process, and the second collection on the same workers."""

from contextlib import ExitStack
from dataclasses import replace

import numpy as np

from drake_continuum.config import load_config
from drake_continuum.experiments import reproduce
from drake_continuum.experiments.collect import collect
from drake_continuum.experiments.settings import RunSettings
from drake_continuum.objects.dataset import generate_dataset

SHIPPED = load_config()
FIXED = replace(SHIPPED, planes=replace(SHIPPED.planes, bearing="world", centre="mark"))
PLANES = [0, 7]


def _arrays(folder, object_id):
    """The stored arrays with the wall times (scalars[3]) zeroed."""
    with np.load(folder / f"{object_id}.npz", allow_pickle=False) as z:
        out = {k: z[k].copy() for k in z.files}
    for k in out:
        if k.endswith("_scalars"):
            out[k][3] = 0.0
    return out


def test_two_collections_on_the_runs_pool_equal_one_process(tmp_path):
    generate_dataset(tmp_path / "objects", counts={"apple": 1, "cup": 1}, workers=1,
                     progress=False)
    inline = collect(tmp_path / "objects", tmp_path / "inline", FIXED, workers=1,
                     planes=PLANES, progress=False)
    s = RunSettings(out=tmp_path, workers=2)
    assert reproduce._where(s) is None  # outside a run: collect makes its own pool
    with ExitStack() as stack:
        reproduce._POOL.update(stack=stack, pool=None)
        try:
            pool = reproduce._where(s)
            first = collect(tmp_path / "objects", tmp_path / "a", FIXED, scheduler=pool,
                            planes=PLANES, progress=False)
            workers = set(pool._processes)
            assert reproduce._where(s) is pool
            second = collect(tmp_path / "objects", tmp_path / "b", FIXED, scheduler=pool,
                             planes=PLANES, progress=False)
            assert set(pool._processes) == workers  # the same processes served both
        finally:
            reproduce._POOL.clear()
    assert first.workers == second.workers == 2 and not first.failed and not second.failed
    for oid in inline.done:
        for folder in ("a", "b"):
            a, b = _arrays(tmp_path / "inline", oid), _arrays(tmp_path / folder, oid)
            assert sorted(a) == sorted(b)
            for k in a:
                np.testing.assert_array_equal(a[k], b[k], err_msg=k)
