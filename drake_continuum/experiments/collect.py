"""Every wrap of every object of a dataset, stored per object: resumable and parallel.

`collect(dataset, out, scenario)` wraps each selected object in every plane of the scenario
(config.Config: its arm, planes and wrap sections) and stores its wraps in a collection
folder (experiments.collection: the files, the recorded parameters, the lock). A run into a
folder made with other parameters is refused (CollectParamsError names what differs) rather
than mixing wraps of two settings; a run killed at any moment loses at most the objects in
progress.

A finished object is known by its own files, which the next run finds: index.json, which
lists them for readers, is written as a run starts, at most every INDEX_INTERVAL_S while
objects finish, and as the run ends, Ctrl-C and errors included (written after every
object, its writes would grow quadratically: 280 KB each at 1,480 objects). A run killed by
SIGKILL leaves it valid but without the objects of its last seconds, until the next run
resumes.

Work runs as one task per object (one WrapScene for all its planes) on a concurrent.futures
executor: local processes (the spawn context: pydrake and fork do not mix) or, given a
scheduler address, a Dask distributed cluster's (Client.get_executor). A task carries the
mesh's bytes and the scenario, so cluster workers need the package installed but not the
dataset's files. Results come back to this process, which alone writes the folder.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import queue
import tempfile
import threading
import time
import traceback
from collections import defaultdict
from concurrent.futures import Executor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh
from threadpoolctl import threadpool_limits
from tqdm import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

from ..config import Config, load_config
from ..errors import InputError
from ..files import plain_name, writable_folder, write_scratch
from ..kinematics.arm import ContinuumArm
from ..objects.dataset import load_manifest, select_objects
from ..perception.bearing import PlaneBearing
from ..workers import local_pool, sigint_held, sigint_received
from ..wrapping.planes import PlaneCentre, enumerate_planes
from ..wrapping.scene import WrapScene
from ..wrapping.start import start_lengths
from ..wrapping.wrap import wrap
from ..wrapping.wrap_types import WrapResult
from .collection import (
    FORMAT,
    FORMAT_VERSION,
    INDEX_NAME,
    LOCK_NAME,
    WRAPS_VERSION,
    CollectLockError,
    CollectParamsError,
    check_index,
    collection_lock,
    finished_object,
    index_entry,
    prune_stale,
    remove_temporaries,
    run_params,
    sha256,
    wrapped_mesh_path,
    write_index,
    write_object,
)
from .timing import Work, object_work

__all__ = ["FORMAT", "FORMAT_VERSION", "INDEX_NAME", "LOCK_NAME", "WRAPS_VERSION",
           "CollectParamsError", "CollectLockError", "CollectReport", "select_planes",
           "wrap_object", "run_params", "wrapped_mesh_path", "prune_stale", "write_object",
           "collect"]

log = logging.getLogger(__name__)

INDEX_INTERVAL_S = 10.0  # s: how far index.json may fall behind a run's stored objects


@dataclass
class CollectReport:
    """What one collect run did.

    Args:
        out_dir: the collection folder.
        done: ids of the objects wrapped and stored by this run.
        skipped: ids of the selected objects that were already finished.
        failed: id -> error message of the objects that failed in this run.
        pruned: ids of the stored objects removed first (collect's `prune`).
        n_wraps: wraps stored by this run.
        wrap_times_s: wall time of each wrap stored by this run, s.
        object_times_s: id -> wall time of the object in its worker (scene + wraps), s.
        object_cpu_s: id -> CPU time of the object in its worker, s (its wall time on an
            idle core).
        work_s: CPU seconds by kind of work (experiments.timing.KINDS), summed over the
            objects of this run in their workers.
        inline: the objects were wrapped in the calling thread (one worker), so its own
            CPU time includes theirs.
        time_s: wall time of the run, s.
        workers: local processes used, or None on a Dask cluster.
        scheduler: the Dask scheduler address, or None.
    """

    out_dir: Path
    done: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    failed: dict = field(default_factory=dict)
    pruned: list = field(default_factory=list)
    n_wraps: int = 0
    wrap_times_s: list = field(default_factory=list)
    object_times_s: dict = field(default_factory=dict)
    object_cpu_s: dict = field(default_factory=dict)
    work_s: Work = field(default_factory=Work)
    inline: bool = False
    time_s: float = 0.0
    workers: int | None = None
    scheduler: str | None = None

    def to_dict(self) -> dict:
        t = np.asarray(self.wrap_times_s, float)
        return {"out_dir": str(self.out_dir), "n_done": len(self.done),
                "n_skipped": len(self.skipped), "n_failed": len(self.failed),
                "n_pruned": len(self.pruned),
                "failed": dict(self.failed), "n_wraps": self.n_wraps,
                "wrap_ms_median": float(np.median(t) * 1e3) if len(t) else None,
                "wrap_ms_p95": float(np.percentile(t, 95) * 1e3) if len(t) else None,
                "time_s": self.time_s, "workers": self.workers, "scheduler": self.scheduler,
                "work_s": dict(self.work_s)}


# ---------------------------------------------------------------- the work of one object

def select_planes(arm, scenario: Config, planes=None) -> list:
    """The wrap planes of a run: the scenario's (enumerate_planes with its alpha_deg and
    both_directions), or those of the given indices."""
    every = enumerate_planes(arm.base_position, scenario.alpha_deg, scenario.both_directions)
    if planes is None:
        return every
    bad = [i for i in planes if not 0 <= int(i) < len(every)]
    if bad:
        raise InputError(f"plane indices {bad} out of range: alpha = {scenario.alpha_deg} "
                         f"deg gives {len(every)} planes (0..{len(every) - 1})")
    return [every[int(i)] for i in planes]


def wrap_object(mesh_path, scenario: Config | None = None, *, planes=None, turn: float = 0.0,
                centre=(0.0, 0.0)) -> list[WrapResult]:
    """Every wrap of one object, one WrapScene reused for all its planes.

    Args:
        mesh_path: the object's mesh (metres, standard pose): its file, or the mesh
            objects.mesh.load_mesh read from it.
        scenario: its arm, planes and wrap sections (default: models/config.yaml).
        planes: indices of the planes to wrap (default: all).
        turn: the plane set turned this far (rad) about the vertical through the point
            the arm is centred on: planes.bearing "object" turns it onto the object
            (perception.bearing; _wrap_task asks the depth camera).
        centre: (x, y) the plane set is centred on: the mark (0, 0), or with
            planes.centre "camera" the depth camera's position estimate.

    Returns:
        The WrapResults in plane order. Raises (MeshError, ...) only for an unusable object;
        a failing wrap is a status.
    """
    scenario = load_config() if scenario is None else scenario
    arm = scenario.arm()
    if turn or np.any(np.asarray(centre, dtype=float) != 0.0):
        from ..objects.mesh import load_mesh
        from ..objects.placement import arm_frame
        loaded = mesh_path if isinstance(mesh_path, trimesh.Trimesh) else load_mesh(mesh_path)
        mesh = arm_frame(loaded, centre, turn)
    else:
        mesh = mesh_path
    scene = _scene(arm, mesh)
    return [wrap(scene, plane, scenario.wrap) for plane in select_planes(arm, scenario, planes)]


_LAST_SCENE = threading.local()  # this thread's last scene: (its arm's fields, WrapScene)


def _scene(arm: ContinuumArm, mesh) -> WrapScene:
    """A scene of `mesh` for `arm`: the thread's last one with the object swapped in when
    it was built for the same arm (WrapScene.replace_object: ~0.03 s instead of ~0.3 s of
    CPU an object), else a new one."""
    key = tuple((f.name, np.asarray(getattr(arm, f.name)).tobytes())
                for f in dataclasses.fields(arm))
    last = getattr(_LAST_SCENE, "value", None)
    if last is not None and last[0] == key:
        scene = last[1]
        scene.arm = arm  # as built, whatever a wrap interrupted by an error left
        scene.replace_object(mesh)
        return scene
    _LAST_SCENE.value = None  # a failing build must not leave the old scene behind
    scene = WrapScene(arm, mesh)
    _LAST_SCENE.value = (key, scene)
    return scene



def warm_worker() -> tuple:
    """A task that only imports what `_wrap_task` needs (seconds in a new process): a pool
    given it first starts its workers while the caller does other work. Returns (the
    worker's process id, the CPU seconds it has taken so far: its start)."""
    from ..objects.mesh import load_mesh  # noqa: F401
    from ..perception.bearing import points_bearing  # noqa: F401
    from ..perception.locate import camera_points  # noqa: F401
    return os.getpid(), time.process_time()


def _wrap_task(task: dict) -> dict:
    """One object's task, run in a worker: the mesh arrives as bytes."""
    t0, c0 = time.perf_counter(), time.process_time()
    scenario: Config = task["scenario"]
    with tempfile.TemporaryDirectory(prefix="drake-continuum-") as tmp:
        mesh = Path(tmp) / task["mesh_name"]
        write_scratch(mesh, task["mesh_bytes"])  # read back at once, removed with tmp
        # One thread a worker: the pool already uses every core.
        with threadpool_limits(1):
            from ..objects.mesh import MeshError, load_mesh
            from ..perception.bearing import points_bearing
            from ..perception.locate import camera_points, points_estimate, view_extent
            bearing, centre = None, None
            try:
                loaded = load_mesh(mesh)  # read once: the camera and the wraps see it
            except MeshError as err:  # name the dataset's file, not this temporary copy
                raise MeshError(str(err).replace(str(mesh), task.get("source", str(mesh)))
                                ) from None
            camera_c0 = time.process_time()
            seen = camera_points(loaded, scenario.arm())  # rendered once
            view = view_extent(seen)
            if scenario.centre == PlaneCentre.CAMERA:
                centre = points_estimate(seen).xy
            if scenario.bearing != PlaneBearing.WORLD:
                bearing = points_bearing(seen)
            camera_s = time.process_time() - camera_c0
            wraps = wrap_object(loaded, scenario, planes=task["planes"],
                                turn=0.0 if bearing is None else bearing.turn,
                                centre=(0.0, 0.0) if centre is None else centre)
    cpu_s = time.process_time() - c0
    return {"object_id": task["object_id"], "wraps": wraps, "time_s": time.perf_counter() - t0,
            "work": object_work(camera_s, cpu_s, wraps), "cpu_s": cpu_s,
            "bearing": None if bearing is None else bearing.to_dict(),
            "centre": None if centre is None else [round(float(v), 6) for v in centre],
            "view": [round(float(v), 6) for v in view]}


# ---------------------------------------------------------------- selection

def _interleave(entries: list) -> list:
    """Round-robin over categories, so that the progress bar's rate (and the time left it
    shows) is a mix of categories from the start."""
    groups = defaultdict(list)
    for e in entries:
        groups[e.category].append(e)
    queues = list(groups.values())
    out = []
    for k in range(max((len(q) for q in queues), default=0)):
        out += [q[k] for q in queues if k < len(q)]
    return out



# ---------------------------------------------------------------- executors

def _error_text(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}"


def _settle(run: _Run, oid: str, result) -> None:
    """Store an object's result (`result()` gives it), or record its error: one object's
    failure is its own."""
    try:
        res = result()
    except BrokenProcessPool as e:
        run.on_error(oid, f"worker process died (crash or out of memory) while this object "
                          f"was running or queued: {e}")
    except Exception as e:
        if sigint_received():  # a library turned the Ctrl-C into its own error: not a failure
            raise KeyboardInterrupt from e
        log.debug("%s failed:\n%s", oid, "".join(traceback.format_exception(e)))
        run.on_error(oid, _error_text(e))
    else:
        run.on_result(res)


def _run_inline(tasks: list, run: _Run) -> None:
    """One worker: every object in this process, one after the other (no process to start,
    so nothing of the caller's script runs again)."""
    for t in tasks:
        _settle(run, t["object_id"], lambda t=t: _wrap_task(t))


@contextmanager
def _executor(workers: int, scheduler):
    """Where the objects run: spawned local processes, an executor the caller keeps (its
    owner ends it), or a Dask cluster's executor (Client.get_executor). On an exception
    (Ctrl-C included) what is queued is cancelled and local workers end at once; the next
    run redoes their objects."""
    if scheduler is None:
        with local_pool(workers) as pool:
            yield pool
        return
    if isinstance(scheduler, Executor):
        yield scheduler
        return
    from dask.distributed import Client
    client = Client(scheduler) if isinstance(scheduler, str) else scheduler
    executor = client.get_executor(pure=False)
    try:
        yield executor
    except BaseException:
        executor.shutdown(wait=False)  # cancels the cluster's queued and running tasks
        raise
    finally:
        if client is not scheduler:
            client.close()


def _run(executor, tasks: list, run: _Run) -> None:
    """Every task on the executor, each result stored as it comes, in any order.

    Each future reports itself done through a callback, which runs also when the executor
    cancels it: a pool shut down with cancel_futures (stop_workers) cancels what is queued
    without waking `concurrent.futures.wait`, which would then wait for ever in a thread
    other than the one interrupted (reproduce's collection run ahead)."""
    finished = queue.SimpleQueue()
    names = {}
    with sigint_held():  # local workers start (spawned on submit) with Ctrl-C held
        for t in tasks:
            fut = executor.submit(_wrap_task, t)
            names[fut] = t["object_id"]
    for fut in list(names):
        fut.add_done_callback(finished.put)
    while names:
        fut = finished.get()  # dropped once stored: results are not all held to the end
        _settle(run, names.pop(fut), fut.result)



# ---------------------------------------------------------------- the run

class _Run:
    """One collect run's view of its collection folder, which only this process writes.

    Invariants: `finished` holds the stored metadata of every object finished in the folder
    with this run's parameters `params` (run_params, in the folder's layout); `failed` the
    entries of the objects whose last attempt failed and that are not finished; `foreign`
    the index entries of finished objects the dataset does not list (kept); index.json
    records them as they were at most INDEX_INTERVAL_S ago, and exactly once the run ends.
    """

    def __init__(self, out: Path, dataset, params: dict, *, labels: dict, report: CollectReport):
        self.out, self.dataset, self.params, self.labels = out, dataset, params, labels
        self.report = report
        self.finished, self.failed, self.foreign = {}, {}, []
        self.shas, self.by_id, self.bar = {}, {}, None
        self.index_time, self.index_stale = -np.inf, False  # its last write (monotonic, s)

    def resume(self, index, entries: list, prune: bool) -> tuple[list, dict]:
        """Read what the folder holds; returns the tasks still to run and the selected
        objects whose mesh cannot be read (id -> message)."""
        out, report = self.out, self.report
        remove_temporaries(out)
        if prune:
            report.pruned = prune_stale(out, self.dataset.root)
        for e in self.dataset:
            meta = finished_object(out, e.id, self.params)
            if meta is not None:
                self.finished[e.id] = meta
        known = {e.id for e in self.dataset}
        if isinstance(index, dict):
            for item in index.get("objects", []):
                oid = item.get("object_id") if isinstance(item, dict) else None
                if oid:
                    plain_name(oid, f"{out / INDEX_NAME}: object id")
                if oid and oid not in known and finished_object(out, oid, self.params):
                    self.foreign.append(item)
            for item in index.get("failed", []):
                if isinstance(item, dict) and item.get("object_id"):
                    self.failed[item["object_id"]] = item
        selected = {e.id for e in entries}
        self.failed = {k: v for k, v in self.failed.items()
                       if k not in selected and k not in self.finished}
        meshes, unreadable = {}, {}
        for e in entries:
            try:
                meshes[e.id] = e.path.read_bytes()
            except OSError as err:
                unreadable[e.id] = f"{e.path}: cannot be read ({err.strerror or err})"
                continue
            self.shas[e.id] = sha256(meshes[e.id])
            if e.id in self.finished:
                if self.finished[e.id].get("mesh_sha256") != self.shas[e.id]:
                    raise CollectParamsError(
                        f"{out / (e.id + '.json')}: stored wraps were made from another mesh "
                        f"than {e.path} (its contents changed); collect into a new folder, "
                        f"or with `collect --prune` to remove the objects no longer held")
                report.skipped.append(e.id)
        self.by_id = {e.id: e for e in entries}
        return [{"object_id": e.id, "mesh_name": e.path.name, "source": str(e.path),
                 "mesh_bytes": meshes[e.id], "planes": self.params["planes"]}
                for e in _interleave(entries) if e.id not in self.finished and e.id in meshes
                ], unreadable

    def write_index(self) -> None:
        order = [e.id for e in self.dataset if e.id in self.finished]
        write_index(self.out, self.dataset.root, self.params,
                    objects=[index_entry(self.finished[i]) for i in order] + self.foreign,
                    failed=list(self.failed.values()))
        self.index_time, self.index_stale = time.monotonic(), False

    def changed(self) -> None:
        """`finished` or `failed` changed: index.json is written again once it is
        INDEX_INTERVAL_S old (and as the run ends: execute)."""
        self.index_stale = True
        if time.monotonic() - self.index_time >= INDEX_INTERVAL_S:
            self.write_index()

    def on_result(self, res: dict) -> None:
        e, report = self.by_id[res["object_id"]], self.report
        meta = write_object(self.out, e, self.shas[e.id], wraps=res["wraps"],
                            time_s=res["time_s"], cpu_s=res["cpu_s"], params=self.params,
                            labels=self.labels, bearing=res.get("bearing"),
                            centre=res.get("centre"), view=res.get("view"))
        self.finished[e.id] = meta
        self.failed.pop(e.id, None)
        self.changed()
        report.done.append(e.id)
        report.n_wraps += len(res["wraps"])
        report.wrap_times_s += [float(w.time_s) for w in res["wraps"]]
        report.object_times_s[e.id] = float(res["time_s"])
        report.object_cpu_s[e.id] = float(res["cpu_s"])
        report.work_s.add(res.get("work", {}))
        self.bar.update()

    def on_error(self, oid: str, message: str) -> None:
        self.failed[oid] = {"object_id": oid, "category": self.by_id[oid].category,
                            "error": message}
        self.changed()
        self.report.failed[oid] = message
        log.error("object %s failed: %s", oid, message)
        self.bar.set_postfix(failed=len(self.report.failed))
        self.bar.update()

    def execute(self, tasks: list, unreadable: dict, *, workers: int | None, scheduler,
                progress: bool) -> None:
        """Run the tasks (inline, on local processes or on Dask), storing each result."""
        self.write_index()
        self.bar = tqdm(total=len(tasks) + len(unreadable), desc="objects", unit="obj",
                        disable=not progress, dynamic_ncols=True)
        try:
            # Without a bar the log needs no redirecting (a collection run in a thread of
            # its own, as reproduce runs one ahead, leaves the process's handlers alone).
            with logging_redirect_tqdm() if progress else nullcontext():
                for oid, message in unreadable.items():
                    self.on_error(oid, message)
                if tasks and scheduler is None:
                    self.report.workers = min(workers or os.cpu_count() or 1, len(tasks))
                elif isinstance(scheduler, Executor):
                    self.report.workers = getattr(scheduler, "_max_workers", None)
                if self.report.workers == 1 and scheduler is None:
                    self.report.inline = True
                    _run_inline(tasks, self)
                elif tasks:
                    with _executor(self.report.workers, scheduler) as executor:
                        _run(executor, tasks, self)
        finally:
            self.bar.close()
            if self.index_stale:  # also on Ctrl-C: whatever was stored is listed
                self.write_index()


def _address(scheduler) -> str | None:
    """The Dask scheduler's address: the string given, or that of a Client (None for a
    local executor)."""
    if isinstance(scheduler, Executor):
        return None
    if scheduler is not None and not isinstance(scheduler, str):
        return getattr(getattr(scheduler, "scheduler", None), "address", None)
    return scheduler


def collect(dataset_dir, out_dir, scenario: Config | None = None, *,
            workers: int | None = None, scheduler=None, ids=None,
            limit_per_category: int | None = None, planes=None, progress: bool = True,
            prune: bool = False) -> CollectReport:
    """Wrap every selected object of a dataset and store its wraps in out_dir; resumes.

    Args:
        dataset_dir: dataset folder (manifest.json + meshes).
        out_dir: collection folder, created if needed.
        scenario: the arm, planes and wrap sections to wrap with (config.Config; default:
            models/config.yaml, as the command line).
        workers: local worker processes (default: os.cpu_count()); ignored with scheduler.
            1 wraps in this process; more start spawned processes, which never rerun the
            caller's script (a plain script needs no `if __name__ == "__main__":` guard).
        scheduler: a Dask scheduler address ("tcp://host:8786") or a dask.distributed.Client
            to run on instead of local processes, or a concurrent.futures executor the
            caller keeps (local_pool's: reproduce's collections share one, whose workers
            keep their imports, numba kernels and last scene, seconds a worker).
        ids: object ids to wrap (default: all).
        limit_per_category: only the first K objects of each category.
        planes: indices of the scenario's planes to wrap (default: all); a shortcut for
            quick runs.
        progress: show a tqdm progress bar.
        prune: first remove the stored objects the dataset no longer holds as they were
            wrapped (prune_stale), once the folder is locked and its parameters match.

    Returns:
        A CollectReport. Failed objects are reported there, logged by name and listed under
        "failed" in index.json; the next run retries them. Raises CollectParamsError if the
        folder holds wraps made with other parameters, CollectLockError if another run
        writes it.
    """
    t_start = time.perf_counter()
    if workers is not None and workers < 1:
        raise InputError(f"workers must be at least 1, got {workers}")
    scenario = load_config() if scenario is None else scenario
    dataset = load_manifest(dataset_dir)
    entries = select_objects(dataset, ids, limit_per_category)
    if not entries:
        raise InputError(f"{dataset.root / 'manifest.json'}: the dataset holds no object to "
                         f"wrap")
    arm = scenario.arm()
    if not scenario.wrap.start_fit:  # refused once here, not as every object's failure
        start_lengths(scenario.wrap, arm.n_sections)
    labels = {p.index: p.label for p in select_planes(arm, scenario, planes)}
    out = writable_folder(out_dir)
    report = CollectReport(out_dir=out, scheduler=_address(scheduler))
    with collection_lock(out):
        index, params = check_index(out, run_params(scenario, planes=planes))
        run = _Run(out, dataset, params, labels=labels, report=report)
        tasks, unreadable = run.resume(index, entries, prune)
        for task in tasks:
            task["scenario"] = scenario
        run.execute(tasks, unreadable, workers=workers, scheduler=scheduler, progress=progress)
    report.time_s = time.perf_counter() - t_start
    return report
