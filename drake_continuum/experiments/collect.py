"""Every wrap of every object of a dataset, stored per object: resumable and parallel.

A collection folder (WRAPS) holds, for each finished object:

  <object_id>.npz   every WrapResult of the object, wrap k under the prefix "w{k}_"
                    (WrapResult.to_arrays; plain arrays, no pickle)
  <object_id>.json  {"format", "format_version", "object_id", "category", "mesh_file",
                     "mesh_sha256", "npz_sha256" (of the .npz), "n_wraps", "n_usable",
                     "time_s" and "cpu_s" (the object's wall and CPU time in its worker),
                     "wraps": [{"plane_index", "plane_label", "status", "time_s",
                                "n_contacts", "n_queries", "conformity", "wrap_angle_deg",
                                "message" (IK's, if it failed)}],
                     "bearing": how the plane set was turned onto the object (only with
                                planes.bearing "object": perception.bearing.Bearing.to_dict),
                     "centre": [x, y] the plane set was centred on (only with planes.centre
                               "camera": the depth camera's estimate),
                     "view": [height, long, short] (m): the object's size as the depth
                             camera sees it (perception.locate.view_extent), a block of the
                             classifier's features,
                     "placement": a placed copy's placement record, as in its dataset's
                                  manifest (objects/placement.py; its "side" names the
                                  classifier's rest class),
                     "params": the run's parameters (below)}

and one index.json:

  {"format", "format_version", "dataset", "params",
   "objects": [{"object_id", "category", "n_wraps", "n_usable", "npz_sha256"}],  finished
                                                                   objects only
   "failed": [{"object_id", "category", "error"}]}                 retried on the next run

`params` is {"wrap_params" (WrapParams as a dict), "alpha_deg", "planes" (plane indices or
null for all), "arm_yaml" (the arm description's text), "wraps_version" (WRAPS_VERSION),
"bearing" only when the plane set is oriented on the object ("object"; perception.bearing),
and "centre" only when it is centred on the camera's estimate ("camera")}. A run into a
folder made with other parameters is refused (CollectParamsError names what differs) rather
than mixing wraps of two settings.

Every file is written under a temporary name and renamed (os.replace), the .npz before the
.json, so a run killed at any moment leaves each object either finished (both files,
readable) or absent; it loses at most the objects in progress. An object counts as finished
when its .json is readable with the run's parameters and its own id, and its .npz has the
SHA-256 recorded there; a damaged or swapped file is redone. Stray temporary files of a
killed run are removed at the next start. Readers (learning.records) check every object
against index.json the same way.

Work runs as one task per object (one WrapScene for all its planes) on local processes
(concurrent.futures with the spawn context: pydrake and fork do not mix) or, given a
scheduler address, on a Dask distributed cluster. A task carries the mesh's bytes and the
arm's YAML text, so cluster workers need the package installed but not the dataset's files.
Results come back to this process, which alone writes the folder.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import logging
import os
import socket
import tempfile
import threading
import time
import traceback
import uuid
import zipfile
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import trimesh
import yaml
from threadpoolctl import threadpool_limits
from tqdm import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

from ..errors import DrakeContinuumError, InputError, MissingFileError
from ..files import json_text, plain_name, writable_folder, write_atomic
from ..kinematics.arm import DEFAULT_ARM_YAML, ContinuumArm, load_arm
from ..objects.dataset import load_manifest
from ..workers import main_not_rerun, sigint_held, stop_workers, worker_setup
from ..wrapping.planes import PAPER_ALPHA_DEG, enumerate_planes
from ..wrapping.scene import WrapScene
from ..wrapping.wrap import WrapParams, wrap
from ..wrapping.wrap_types import WRAPS_FORMAT, WRAPS_FORMAT_VERSION, WrapResult
from ..wrapping.wrap_types import params_difference as _params_difference
from ..wrapping.wrap_types import stored_params as _stored_params
from .timing import Work, object_work

__all__ = ["FORMAT", "FORMAT_VERSION", "INDEX_NAME", "LOCK_NAME", "WRAPS_VERSION",
           "CollectParamsError", "CollectLockError", "CollectReport", "select_planes",
           "wrap_object", "run_params", "wrapped_mesh_path", "prune_stale", "write_object",
           "select_objects", "collect"]

log = logging.getLogger(__name__)

FORMAT, FORMAT_VERSION = WRAPS_FORMAT, WRAPS_FORMAT_VERSION
# The release whose wrap code made the stored wraps: bumped only when a release changes the
# wraps themselves (Algorithm 1, the contact model), so a collection resumes across releases
# that change only what is done with the wraps. Collections made before 0.5.0 stored the
# package version as "package_version", which was then bumped exactly with the wrap code.
WRAPS_VERSION = "0.4.0"
INDEX_NAME = "index.json"
LOCK_NAME = ".collect.lock"


class CollectParamsError(DrakeContinuumError):
    """The collection folder was made with other parameters than this run's."""


class CollectLockError(DrakeContinuumError, RuntimeError):
    """Another collect run is writing the same folder."""


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
        work_s: seconds by kind of work (experiments.timing.KINDS), summed over the objects
            of this run in their workers.
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

def select_planes(arm, alpha_deg: float = PAPER_ALPHA_DEG, planes=None,
                  both_directions: bool = False) -> list:
    """The wrap planes of a run: enumerate_planes(alpha_deg, both_directions), or those of
    the given indices."""
    every = enumerate_planes(arm.base_position, alpha_deg, both_directions)
    if planes is None:
        return every
    bad = [i for i in planes if not 0 <= int(i) < len(every)]
    if bad:
        raise InputError(f"plane indices {bad} out of range: alpha = {alpha_deg} deg gives "
                         f"{len(every)} planes (0..{len(every) - 1})")
    return [every[int(i)] for i in planes]


def wrap_object(mesh_path, params: WrapParams = WrapParams(), alpha_deg: float = PAPER_ALPHA_DEG,
                planes=None, arm_path=None, both_directions: bool = False,
                turn: float = 0.0, centre=(0.0, 0.0)) -> list[WrapResult]:
    """Every wrap of one object, one WrapScene reused for all its planes.

    Args:
        mesh_path: the object's mesh (metres, standard pose): its file, or the mesh
            objects.mesh.load_mesh read from it.
        params: Algorithm 1's parameters.
        alpha_deg: plane spacing (planes.enumerate_planes).
        planes: indices of the planes to wrap (default: all).
        arm_path: arm description YAML (default: models/arm.yaml).
        both_directions: wrap every plane clockwise and counter-clockwise.
        turn: the plane set turned this far (rad) about the vertical through the point
            the arm is centred on: planes.bearing "object" turns it onto the object
            (perception.bearing; _wrap_task asks the depth camera).
        centre: (x, y) the plane set is centred on: the mark (0, 0), or with
            planes.centre "camera" the depth camera's position estimate.

    Returns:
        The WrapResults in plane order. Raises (MeshError, ...) only for an unusable object;
        a failing wrap is a status.
    """
    arm = load_arm(arm_path)
    if turn or np.any(np.asarray(centre, dtype=float) != 0.0):
        from ..objects.mesh import load_mesh
        from ..objects.placement import arm_frame
        loaded = mesh_path if isinstance(mesh_path, trimesh.Trimesh) else load_mesh(mesh_path)
        mesh = arm_frame(loaded, centre, turn)
    else:
        mesh = mesh_path
    scene = _scene(arm, mesh)
    return [wrap(scene, plane, params)
            for plane in select_planes(arm, alpha_deg, planes, both_directions)]


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


def _wrap_task(task: dict) -> dict:
    """One object's task, run in a worker: mesh and arm arrive as bytes and text."""
    t0, c0 = time.perf_counter(), time.process_time()
    with tempfile.TemporaryDirectory(prefix="drake-continuum-") as tmp:
        mesh = Path(tmp) / task["mesh_name"]
        write_atomic(mesh, task["mesh_bytes"])
        arm = Path(tmp) / "arm.yaml"
        write_atomic(arm, task["arm_yaml"].encode())
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
            t_camera = time.perf_counter()
            seen = camera_points(loaded, load_arm(arm))  # rendered once
            view = view_extent(seen)
            if task.get("centre", "mark") == "camera":
                centre = points_estimate(seen).xy
            if task.get("bearing", "world") != "world":
                bearing = points_bearing(seen)
            t_wraps = time.perf_counter()
            wraps = wrap_object(loaded, task["wrap_params"], task["alpha_deg"], task["planes"], arm,
                                task.get("both_directions", False),
                                0.0 if bearing is None else bearing.turn,
                                (0.0, 0.0) if centre is None else centre)
            work = object_work(t_wraps - t_camera, time.perf_counter() - t_wraps, wraps)
    return {"object_id": task["object_id"], "wraps": wraps, "time_s": time.perf_counter() - t0,
            "work": work,
            "cpu_s": time.process_time() - c0,
            "bearing": None if bearing is None else bearing.to_dict(),
            "centre": None if centre is None else [round(float(v), 6) for v in centre],
            "view": [round(float(v), 6) for v in view]}


# ---------------------------------------------------------------- parameters and files

def run_params(params: WrapParams = WrapParams(), alpha_deg: float = PAPER_ALPHA_DEG,
               planes=None, arm_path=None, both_directions: bool = False,
               arm_yaml: str | None = None, bearing: str = "world", centre: str = "mark") -> dict:
    """The parameters that determine a collection's wraps (stored with every object;
    "both_directions", "bearing" and "centre" only when set, so collections made before
    they existed still resume).
    The arm is the text `arm_yaml`, else the file `arm_path` (default models/arm.yaml)."""
    if arm_yaml is None:
        arm_path = Path(arm_path) if arm_path is not None else DEFAULT_ARM_YAML
        try:
            arm_yaml = arm_path.read_text()
        except OSError as e:
            raise MissingFileError(f"arm description {arm_path}: {e.strerror or e}") from None
    out = {"wrap_params": json.loads(json_text(dataclasses.asdict(params))),
           "alpha_deg": float(alpha_deg),
           "planes": None if planes is None else [int(i) for i in planes],
           "arm_yaml": arm_yaml, "wraps_version": WRAPS_VERSION}
    if both_directions:
        out["both_directions"] = True
    if bearing != "world":
        from ..perception.bearing import BEARINGS
        if bearing not in BEARINGS:
            raise InputError(f"planes.bearing must be one of {', '.join(BEARINGS)}, got "
                             f"{bearing!r}")
        out["bearing"] = bearing
    if centre != "mark":
        if centre != "camera":
            raise InputError(f"planes.centre must be one of mark, camera, got {centre!r}")
        out["centre"] = centre
    return out


def _refuse(where: Path, stored: dict, current: dict) -> None:
    diff = _params_difference(stored, current)
    raise CollectParamsError(
        f"{where}: made with other parameters than this run: {'; '.join(diff)}. Wraps of "
        f"two settings would be mixed; collect into a new folder, or run with the stored "
        f"parameters to resume")


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _json_bytes(obj) -> bytes:
    return (json_text(obj, indent=1) + "\n").encode()


def _read_json(path: Path):
    """Parsed JSON, or None when missing or unreadable (a damaged file means: redo)."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _finished(out: Path, object_id: str, params: dict) -> dict | None:
    """The stored metadata of a finished object, None if it is not finished. Raises
    CollectParamsError if it was made with other parameters."""
    meta = _read_json(out / f"{object_id}.json")
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        return None
    if meta.get("format_version") != FORMAT_VERSION:
        raise CollectParamsError(
            f"{out / object_id}.json: wrap file format version {meta.get('format_version')}; "
            f"this drake-continuum writes version {FORMAT_VERSION}; collect into a new folder")
    if _stored_params(meta.get("params")) != params:
        _refuse(out / f"{object_id}.json", _stored_params(meta.get("params")), params)
    if meta.get("object_id") != object_id or not _npz_intact(out / f"{object_id}.npz",
                                                             meta.get("npz_sha256")):
        return None  # another object's file, or damaged: redone
    return meta


def _npz_intact(path: Path, sha256: str | None) -> bool:
    """Whether an object's .npz is the one written: its SHA-256 is the one recorded, or,
    for objects stored before the digest was recorded, every array reads (CRC-checked)."""
    try:
        data = path.read_bytes()
        if sha256 is not None:
            return _sha256(data) == sha256
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            for name in z.files:
                z[name]
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        return False
    return True


def wrapped_mesh_path(folder, object_id: str, meta: dict, dataset=None) -> Path:
    """The mesh file an object of a collection was wrapped on: `<object's mesh_file>` in
    `dataset`, or in the dataset the collection's index.json records, checked against the
    SHA-256 stored with the object. Raises FileNotFoundError or ValueError naming the file."""
    folder = Path(folder)
    if dataset is None:
        index = _read_json(folder / INDEX_NAME)
        if not isinstance(index, dict) or "dataset" not in index:
            raise MissingFileError(f"{folder / INDEX_NAME}: names no dataset; give the "
                                    f"dataset folder")
        dataset = index["dataset"]
    path = Path(dataset) / plain_name(meta.get("mesh_file", f"{object_id}.obj"),
                                      f"{folder / object_id}.json: mesh_file")
    if meta.get("mesh_sha256") not in (None, _sha256(path.read_bytes())):
        raise InputError(f"{path}: not the mesh that was wrapped (its SHA-256 differs from "
                         f"the one recorded in {folder / object_id}.json)")
    return path


def prune_stale(out_dir, dataset_dir) -> list[str]:
    """Remove the stored objects of a collection that the dataset no longer holds as they
    were wrapped: an id its manifest does not list, or a mesh whose SHA-256 differs from
    the one stored. Returns their ids. Why: a placed dataset written again with other
    placement counts keeps most meshes byte for byte (drawn by seed, object and kind), and
    `collect` then resumes those and wraps only the new ones; a stale object would be
    refused by `collect` or, left beside the new ones, evaluated."""
    from ..objects.dataset import load_manifest
    out = Path(out_dir)
    if not out.is_dir():
        return []
    entries = {e.id: e for e in load_manifest(dataset_dir)}
    removed = []
    for meta_path in sorted(out.glob("*.json")):
        if meta_path.name == INDEX_NAME:
            continue
        meta = _read_json(meta_path)
        oid = meta.get("object_id", meta_path.stem) if isinstance(meta, dict) else None
        if oid is None:
            continue
        e = entries.get(oid)
        try:
            same = e is not None and meta.get("mesh_sha256") == _sha256(e.path.read_bytes())
        except OSError:
            same = False
        if not same:
            for suffix in (".json", ".npz"):
                (out / f"{meta_path.stem}{suffix}").unlink(missing_ok=True)
            removed.append(str(oid))
    return removed


def _index_entry(meta: dict) -> dict:
    return {"object_id": meta["object_id"], "category": meta["category"],
            "n_wraps": meta["n_wraps"], "n_usable": meta.get("n_usable"),
            "npz_sha256": meta.get("npz_sha256")}


def write_object(out: Path, entry, mesh_sha256: str, wraps: list[WrapResult], time_s: float,
                 cpu_s: float, params: dict, labels: dict, bearing: dict | None = None,
                 centre: list | None = None, view: list | None = None) -> dict:
    """Store one object's wraps (.npz, then .json); returns the metadata written."""
    plain_name(entry.id, f"{out}: object id")
    arrays = {}
    for k, w in enumerate(wraps):
        arrays.update(w.to_arrays(prefix=f"w{k}_"))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    npz_sha256 = _sha256(buf.getvalue())
    write_atomic(out / f"{entry.id}.npz", buf.getvalue())
    records = []
    for w in wraps:
        r = {"plane_index": int(w.plane_index), "plane_label": labels.get(int(w.plane_index)),
             "status": w.status, "time_s": float(w.time_s), "n_contacts": len(w.contacts),
             "n_queries": int(w.n_queries),
             "conformity": None if np.isnan(w.conformity) else float(w.conformity),
             "wrap_angle_deg": float(np.degrees(w.wrap_angle))}
        if w.extra.get("message"):
            r["message"] = str(w.extra["message"])
        records.append(r)
    meta = {"format": FORMAT, "format_version": FORMAT_VERSION, "object_id": entry.id,
            "category": entry.category, "mesh_file": entry.path.name,
            "mesh_sha256": mesh_sha256, "npz_sha256": npz_sha256, "n_wraps": len(wraps),
            "n_usable": int(sum(w.usable for w in wraps)), "time_s": float(time_s),
            "cpu_s": float(cpu_s),
            "wraps": records, "params": params}
    if bearing is not None:
        meta["bearing"] = bearing
    if centre is not None:
        meta["centre"] = centre
    if view is not None:
        meta["view"] = view
    if getattr(entry, "placement", None) is not None:
        meta["placement"] = entry.placement
    write_atomic(out / f"{entry.id}.json", _json_bytes(meta))
    return meta


# ---------------------------------------------------------------- selection, lock

def select_objects(dataset, ids=None, limit_per_category: int | None = None) -> list:
    """The objects of a run in manifest order: `ids` (all if None), then the first
    `limit_per_category` of each category."""
    entries = list(dataset)
    if ids is not None:
        ids = [str(i) for i in ids]
        if not ids:  # e.g. --ids "$EMPTY": not the same as no selection
            raise InputError("object ids: none given (an empty list selects no object); "
                             "give ids, or leave the selection out to take every object")
        known = {e.id for e in entries}
        unknown = [i for i in ids if i not in known]
        if unknown:
            raise InputError(f"{dataset.root / 'manifest.json'}: no object(s) "
                             f"{', '.join(map(repr, unknown))}")
        wanted = set(ids)
        entries = [e for e in entries if e.id in wanted]
    if limit_per_category is not None:
        if limit_per_category < 1:
            raise InputError(f"limit_per_category must be at least 1, got {limit_per_category}")
        taken = defaultdict(int)
        kept = []
        for e in entries:
            if taken[e.category] < limit_per_category:
                taken[e.category] += 1
                kept.append(e)
        entries = kept
    return entries


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


def _acquire_lock(out: Path) -> Path:
    """A lock file naming this process, so that two runs never write one folder."""
    path = out / LOCK_NAME
    me = f"{socket.gethostname()} {os.getpid()}"
    for _ in range(2):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            try:
                host, pid = path.read_text().split()
                pid = int(pid)
            except (OSError, ValueError):
                host, pid = socket.gethostname(), -1
            if host == socket.gethostname() and not _alive(pid):
                path.unlink(missing_ok=True)  # left by a killed run
                continue
            raise CollectLockError(
                f"{out}: another collect run (process {pid} on {host}) is writing this "
                f"folder; if it is not running, delete {path}") from None
        with os.fdopen(fd, "w") as f:
            f.write(me)
        return path
    raise CollectLockError(f"{out}: cannot take the lock {path}")


def _alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _remove_temporaries(out: Path) -> None:
    """Temporary files of a killed run (write_atomic's `.<name>.<random>.tmp`)."""
    for p in out.glob(".*.tmp"):
        p.unlink(missing_ok=True)


# ---------------------------------------------------------------- executors

def _error_text(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}"


def _run_inline(tasks: list, on_result, on_error) -> None:
    """One worker: every object in this process, one after the other (no process to start,
    so nothing of the caller's script runs again)."""
    for t in tasks:
        try:
            res = _wrap_task(t)
        except Exception as e:
            log.debug("%s failed:\n%s", t["object_id"], "".join(traceback.format_exception(e)))
            on_error(t["object_id"], _error_text(e))
        else:
            on_result(res)


def _run_local(tasks: list, workers: int, on_result, on_error) -> None:
    ctx = get_context("spawn")
    with main_not_rerun():  # a plain script without the __main__ guard is not rerun
        _run_pool(ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                                      initializer=worker_setup), tasks, on_result, on_error)


def _run_pool(pool: ProcessPoolExecutor, tasks: list, on_result, on_error) -> None:
    try:
        with sigint_held():  # the workers start (spawned on submit) with Ctrl-C held
            futures = {pool.submit(_wrap_task, t): t["object_id"] for t in tasks}
        for fut in as_completed(futures):
            oid = futures[fut]
            try:
                res = fut.result()
            except BrokenProcessPool as e:
                on_error(oid, f"worker process died (crash or out of memory) while this object "
                              f"was running or queued: {e}")
            except Exception as e:
                log.debug("%s failed:\n%s", oid, "".join(traceback.format_exception(e)))
                on_error(oid, _error_text(e))
            else:
                on_result(res)
    except BaseException:
        stop_workers(pool)
        raise
    pool.shutdown(wait=True)


def _run_dask(tasks: list, scheduler, on_result, on_error) -> None:
    from dask.distributed import Client
    from dask.distributed import as_completed as dask_as_completed
    own = isinstance(scheduler, str)
    client = Client(scheduler) if own else scheduler
    run = uuid.uuid4().hex[:8]
    futures, names = [], {}
    try:
        for t in tasks:
            fut = client.submit(_wrap_task, t, key=f"wrap-{t['object_id']}-{run}", pure=False)
            futures.append(fut)
            names[fut.key] = t["object_id"]
        for fut in dask_as_completed(futures):
            oid = names[fut.key]
            try:
                res = fut.result()
            except Exception as e:
                log.debug("%s failed:\n%s", oid, "".join(traceback.format_exception(e)))
                on_error(oid, _error_text(e))
            else:
                on_result(res)
            fut.release()
    except BaseException:
        client.cancel(futures)
        raise
    finally:
        if own:
            client.close()


# ---------------------------------------------------------------- the run

def collect(dataset_dir, out_dir, workers: int | None = None, scheduler=None, ids=None,
            limit_per_category: int | None = None, progress: bool = True,
            params: WrapParams = WrapParams(), alpha_deg: float = PAPER_ALPHA_DEG,
            planes=None, arm_path=None, both_directions: bool = False,
            arm_yaml: str | None = None, bearing: str = "world",
            centre: str = "mark", prune: bool = False) -> CollectReport:
    """Wrap every selected object of a dataset and store its wraps in out_dir; resumes.

    Args:
        dataset_dir: dataset folder (manifest.json + meshes).
        out_dir: collection folder, created if needed.
        workers: local worker processes (default: os.cpu_count()); ignored with scheduler.
            1 wraps in this process; more start spawned processes, which never rerun the
            caller's script (a plain script needs no `if __name__ == "__main__":` guard).
        scheduler: a Dask scheduler address ("tcp://host:8786") or a dask.distributed.Client
            to run on instead of local processes.
        ids: object ids to wrap (default: all).
        limit_per_category: only the first K objects of each category.
        progress: show a tqdm progress bar.
        params: Algorithm 1's parameters (default: the paper's).
        alpha_deg: plane spacing (default: the paper's 22.5 deg, 10 planes).
        planes: indices of the planes to wrap (default: all); a shortcut for quick runs.
        arm_path: arm description YAML (default: models/arm.yaml).
        both_directions: wrap every plane clockwise and counter-clockwise (20 planes for
            22.5 deg).
        arm_yaml: the arm description's text, instead of the file arm_path (e.g. a
            Config's arm_yaml).
        bearing: planes.bearing, "world" or "object" (wrap_object).
        centre: planes.centre, "mark" or "camera" (wrap_object).
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
    dataset = load_manifest(dataset_dir)
    entries = select_objects(dataset, ids, limit_per_category)
    if not entries:
        raise InputError(f"{dataset.root / 'manifest.json'}: the dataset holds no object to "
                         f"wrap")
    rp = run_params(params, alpha_deg, planes, arm_path, both_directions, arm_yaml, bearing,
                    centre)
    arm = ContinuumArm.from_dict(yaml.safe_load(rp["arm_yaml"]))
    labels = {p.index: p.label for p in select_planes(arm, alpha_deg, planes, both_directions)}
    out = writable_folder(out_dir)
    if scheduler is not None and not isinstance(scheduler, str):
        address = getattr(getattr(scheduler, "scheduler", None), "address", None)
    else:
        address = scheduler
    report = CollectReport(out_dir=out, scheduler=address)
    lock = _acquire_lock(out)
    try:
        index = _read_json(out / INDEX_NAME)
        if isinstance(index, dict) and index.get("format") == FORMAT \
                and _stored_params(index.get("params")) != rp:
            _refuse(out / INDEX_NAME, _stored_params(index.get("params")), rp)
        _remove_temporaries(out)
        if prune:
            report.pruned = prune_stale(out, dataset_dir)
        finished = {}
        for e in dataset:
            meta = _finished(out, e.id, rp)
            if meta is not None:
                finished[e.id] = meta
        # Entries of objects outside this dataset whose files are still there are kept.
        known = {e.id for e in dataset}
        foreign = []
        failed = {}
        if isinstance(index, dict):
            for item in index.get("objects", []):
                oid = item.get("object_id") if isinstance(item, dict) else None
                if oid:
                    plain_name(oid, f"{out / INDEX_NAME}: object id")
                if oid and oid not in known and _finished(out, oid, rp) is not None:
                    foreign.append(item)
            for item in index.get("failed", []):
                if isinstance(item, dict) and item.get("object_id"):
                    failed[item["object_id"]] = item
        selected = {e.id for e in entries}
        failed = {k: v for k, v in failed.items() if k not in selected and k not in finished}

        meshes, shas, unreadable = {}, {}, {}
        for e in entries:
            try:
                meshes[e.id] = e.path.read_bytes()
            except OSError as err:
                unreadable[e.id] = f"{e.path}: cannot be read ({err.strerror or err})"
                continue
            shas[e.id] = _sha256(meshes[e.id])
            if e.id in finished:
                if finished[e.id].get("mesh_sha256") != shas[e.id]:
                    raise CollectParamsError(
                        f"{out / (e.id + '.json')}: stored wraps were made from another mesh "
                        f"than {e.path} (its contents changed); collect into a new folder, "
                        f"or with `collect --prune` to remove the objects no longer held")
                report.skipped.append(e.id)
        by_id = {e.id: e for e in entries}
        tasks = [{"object_id": e.id, "mesh_name": e.path.name, "source": str(e.path),
                  "mesh_bytes": meshes[e.id], "arm_yaml": rp["arm_yaml"], "wrap_params": params,
                  "alpha_deg": float(alpha_deg), "planes": rp["planes"],
                  "both_directions": both_directions, "bearing": bearing, "centre": centre}
                 for e in _interleave(entries) if e.id not in finished and e.id in meshes]

        def write_index():
            order = [e.id for e in dataset if e.id in finished]
            write_atomic(out / INDEX_NAME, _json_bytes({
                "format": FORMAT, "format_version": FORMAT_VERSION,
                "dataset": str(Path(dataset_dir).resolve()), "params": rp,
                "objects": [_index_entry(finished[i]) for i in order] + foreign,
                "failed": list(failed.values())}))

        write_index()
        bar = tqdm(total=len(tasks) + len(unreadable), desc="objects", unit="obj",
                   disable=not progress, dynamic_ncols=True)

        def on_result(res):
            e = by_id[res["object_id"]]
            meta = write_object(out, e, shas[e.id], res["wraps"], res["time_s"], res["cpu_s"],
                                rp, labels, res.get("bearing"), res.get("centre"),
                                res.get("view"))
            finished[e.id] = meta
            failed.pop(e.id, None)
            write_index()
            report.done.append(e.id)
            report.n_wraps += len(res["wraps"])
            report.wrap_times_s += [float(w.time_s) for w in res["wraps"]]
            report.object_times_s[e.id] = float(res["time_s"])
            report.object_cpu_s[e.id] = float(res["cpu_s"])
            report.work_s.add(res.get("work", {}))
            bar.update()

        def on_error(oid, message):
            failed[oid] = {"object_id": oid, "category": by_id[oid].category, "error": message}
            write_index()
            report.failed[oid] = message
            log.error("object %s failed: %s", oid, message)
            bar.set_postfix(failed=len(report.failed))
            bar.update()

        try:
            with logging_redirect_tqdm():
                for oid, message in unreadable.items():
                    on_error(oid, message)
                if tasks and scheduler is not None:
                    _run_dask(tasks, scheduler, on_result, on_error)
                elif tasks:
                    report.workers = min(workers or os.cpu_count() or 1, len(tasks))
                    if report.workers == 1:
                        _run_inline(tasks, on_result, on_error)
                    else:
                        _run_local(tasks, report.workers, on_result, on_error)
        finally:
            bar.close()
    finally:
        lock.unlink(missing_ok=True)
    report.time_s = time.perf_counter() - t_start
    return report
