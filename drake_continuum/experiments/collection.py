"""A wrap collection's folder: its files, the parameters it records, the lock, and what
a run finds finished.

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

  {"format", "format_version", "dataset", "dataset_relative" (the same from the collection:
   found there when both were moved together), "params",
   "objects": [{"object_id", "category", "n_wraps", "n_usable", "npz_sha256"}],  finished
                                                                   objects only
   "failed": [{"object_id", "category", "error"}]}                 retried on the next run

`params` is {"wrap_params" (WrapParams as a dict; a collection made before WrapParams kept
its angles in degrees records "theta" and "stall_turn" in radians there: it resumes, and
keeps that layout, in_stored_layout), "alpha_deg", "planes" (plane indices or
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
"""

from __future__ import annotations

import copy
import dataclasses
import fcntl
import hashlib
import io
import json
import os
import socket
import zipfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import yaml

from ..config import Config, config_to_tree, load_config, tree_difference
from ..errors import ConfigError, DrakeContinuumError, InputError, MissingFileError
from ..files import json_text, plain_name, read_json, write_atomic
from ..npz import npz_arrays
from ..objects.dataset import load_manifest
from ..perception.bearing import PlaneBearing
from ..wrapping.params import WrapParams
from ..wrapping.planes import PlaneCentre
from ..wrapping.wrap_types import (
    WRAPS_FORMAT,
    WRAPS_FORMAT_VERSION,
    WrapResult,
    params_difference,
    stored_params,
)

__all__ = ["FORMAT", "FORMAT_VERSION", "INDEX_NAME", "LOCK_NAME", "WRAPS_VERSION",
           "CollectParamsError", "CollectLockError", "run_params", "in_stored_layout",
           "check_index", "finished_object", "wrapped_mesh_path", "prune_stale",
           "index_entry", "write_object", "write_index", "collection_lock",
           "remove_temporaries", "sha256", "collection_tree", "training_settings"]

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


# ---------------------------------------------------------------- parameters

def run_params(scenario: Config | None = None, *, planes=None) -> dict:
    """The parameters that determine a collection's wraps (stored with every object): the
    scenario's arm, planes and wrap sections (default: models/config.yaml) and the plane
    indices `planes` (None: all). "both_directions", "bearing" and "centre" are stored only
    when they differ from the paper's setting (one direction, planes fixed to the robot,
    centred on the mark), and the adaptive advancing step's wrap parameters only when it
    is on (delta_max_factor above 1), so collections made before they existed still
    resume."""
    scenario = load_config() if scenario is None else scenario
    wrap = dataclasses.asdict(scenario.wrap)
    if wrap["delta_max_factor"] == 1:  # the fixed step: delta_turn_deg plays no part
        del wrap["delta_max_factor"], wrap["delta_turn_deg"]
    out = {"wrap_params": json.loads(json_text(wrap)),
           "alpha_deg": float(scenario.alpha_deg),
           "planes": None if planes is None else [int(i) for i in planes],
           "arm_yaml": scenario.arm_yaml, "wraps_version": WRAPS_VERSION}
    if scenario.both_directions:
        out["both_directions"] = True
    if scenario.bearing != PlaneBearing.WORLD:
        out["bearing"] = str(scenario.bearing)
    if scenario.centre != PlaneCentre.MARK:
        out["centre"] = str(scenario.centre)
    return out


# WrapParams' angles as collections made before they were fields in degrees record them
# (radians, under the field's name without "_deg").
_RADIAN_KEYS = {"theta_deg": "theta", "stall_turn_deg": "stall_turn"}


def _older_layout(params: dict) -> bool:
    wrap = params.get("wrap_params")
    return isinstance(wrap, dict) and any(k in wrap for k in _RADIAN_KEYS.values())


def _arm(params: dict):
    """The arm description a run's parameters record, parsed (None if unreadable)."""
    try:
        return yaml.safe_load(params.get("arm_yaml") or "")
    except yaml.YAMLError:
        return None


def in_stored_layout(current: dict, stored: dict) -> dict:
    """This run's parameters `current` (run_params) in the layout of the stored ones: with
    the angles in radians, as the loader made them then (float(np.radians(deg))), when the
    collection was made before WrapParams kept degrees, and with the stored arm text when
    the arm is the same written otherwise (a comment, another spelling of a number, inline
    in a configuration). Equal settings then compare equal to the bit, and the folder keeps
    one layout; `current` itself when it is in that layout already."""
    same_arm_respelt = stored.get("arm_yaml") != current.get("arm_yaml") \
        and _arm(current) is not None and _arm(stored) == _arm(current)
    if not (same_arm_respelt or _older_layout(stored)):
        return current
    out = copy.deepcopy(current)
    if same_arm_respelt:
        out["arm_yaml"] = stored["arm_yaml"]
    if _older_layout(stored):
        out["wrap_params"] = {_RADIAN_KEYS.get(k, k): (float(np.radians(v))
                                                        if k in _RADIAN_KEYS else v)
                              for k, v in current["wrap_params"].items()}
    return out


def _refuse(where: Path, stored: dict, current: dict) -> None:
    diff = [d for d in params_difference(stored, current) if not d.startswith("arm_yaml")]
    if stored.get("arm_yaml") != current.get("arm_yaml"):  # which of the arm's keys
        arms = {"stored": _arm(stored), "now": _arm(current)}
        keys = tree_difference({"arm": arms["stored"]}, {"arm": arms["now"]}) \
            if all(isinstance(a, dict) for a in arms.values()) else []
        diff += keys or ["arm_yaml (the arm description's text)"]
    raise CollectParamsError(
        f"{where}: made with other parameters than this run: {'; '.join(diff)}. Wraps of "
        f"two settings would be mixed; collect into a new folder, or run with the stored "
        f"parameters to resume")


def check_index(out: Path, params: dict) -> tuple[dict | None, dict]:
    """The folder's index.json (None if missing or damaged) and this run's parameters in
    its layout (in_stored_layout); CollectParamsError if it was made with others."""
    index = read_json(out / INDEX_NAME)
    if not isinstance(index, dict) or index.get("format") != FORMAT:
        return index, params
    stored = stored_params(index.get("params"))
    params = in_stored_layout(params, stored)
    if stored != params:
        _refuse(out / INDEX_NAME, stored, params)
    return index, params


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _json_bytes(obj) -> bytes:
    return (json_text(obj, indent=1) + "\n").encode()


def finished_object(out: Path, object_id: str, params: dict) -> dict | None:
    """The stored metadata of a finished object, None if it is not finished. Raises
    CollectParamsError if it was made with other parameters."""
    meta = read_json(out / f"{object_id}.json")
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        return None
    if meta.get("format_version") != FORMAT_VERSION:
        raise CollectParamsError(
            f"{out / object_id}.json: wrap file format version {meta.get('format_version')}; "
            f"this drake-continuum writes version {FORMAT_VERSION}; collect into a new folder")
    if stored_params(meta.get("params")) != params:
        _refuse(out / f"{object_id}.json", stored_params(meta.get("params")), params)
    if meta.get("object_id") != object_id or not _npz_intact(out / f"{object_id}.npz",
                                                             meta.get("npz_sha256")):
        return None  # another object's file, or damaged: redone
    return meta


def _npz_intact(path: Path, digest: str | None) -> bool:
    """Whether an object's .npz is the one written: its SHA-256 is the one recorded, or,
    for objects stored before the digest was recorded, every array reads (CRC-checked, as
    the collection's readers read it: npz_arrays)."""
    try:
        data = path.read_bytes()
        if digest is not None:
            return sha256(data) == digest
        npz_arrays(data)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        return False
    return True


def wrapped_mesh_path(folder, object_id: str, meta: dict, *, dataset=None) -> Path:
    """The mesh file an object of a collection was wrapped on: `<object's mesh_file>` in
    `dataset`, or in the dataset the collection's index.json records, checked against the
    SHA-256 stored with the object. Raises FileNotFoundError or ValueError naming the file."""
    folder = Path(folder)
    if dataset is None:
        index = read_json(folder / INDEX_NAME)
        if not isinstance(index, dict) or "dataset" not in index:
            raise MissingFileError(f"{folder / INDEX_NAME}: names no dataset; give the "
                                    f"dataset folder")
        dataset = _recorded_dataset(folder, index)
    path = Path(dataset) / plain_name(meta.get("mesh_file", f"{object_id}.obj"),
                                      f"{folder / object_id}.json: mesh_file")
    if meta.get("mesh_sha256") not in (None, sha256(path.read_bytes())):
        raise InputError(f"{path}: not the mesh that was wrapped (its SHA-256 differs from "
                         f"the one recorded in {folder / object_id}.json)")
    return path



def _recorded_dataset(folder: Path, index: dict) -> Path:
    """The dataset index.json names: its absolute path, or, when the collection and its
    dataset were moved together (a reproduction folder copied elsewhere), the same path
    relative to the collection."""
    recorded = Path(index["dataset"])
    if recorded.is_dir():
        return recorded
    relative = index.get("dataset_relative")
    if isinstance(relative, str) and (folder / relative).is_dir():
        return folder / relative
    raise MissingFileError(f"{folder / INDEX_NAME}: the dataset it was collected from, "
                           f"{recorded}, is not there (moved?); give the dataset folder")


def prune_stale(out_dir, dataset_dir) -> list[str]:
    """Remove the stored objects of a collection that the dataset no longer holds as they
    were wrapped: an id its manifest does not list, or a mesh whose SHA-256 differs from
    the one stored. Returns their ids. Why: a placed dataset written again with other
    placement counts keeps most meshes byte for byte (drawn by seed, object and kind), and
    `collect` then resumes those and wraps only the new ones; a stale object would be
    refused by `collect` or, left beside the new ones, evaluated."""
    out = Path(out_dir)
    if not out.is_dir():
        return []
    entries = {e.id: e for e in load_manifest(dataset_dir)}
    removed = []
    for meta_path in sorted(out.glob("*.json")):
        if meta_path.name == INDEX_NAME:
            continue
        meta = read_json(meta_path)
        oid = meta.get("object_id", meta_path.stem) if isinstance(meta, dict) else None
        if oid is None:
            continue
        e = entries.get(oid)
        try:
            same = e is not None and meta.get("mesh_sha256") == sha256(e.path.read_bytes())
        except OSError:
            same = False
        if not same:
            for suffix in (".json", ".npz"):
                (out / f"{meta_path.stem}{suffix}").unlink(missing_ok=True)
            removed.append(str(oid))
    return removed


def index_entry(meta: dict) -> dict:
    return {"object_id": meta["object_id"], "category": meta["category"],
            "n_wraps": meta["n_wraps"], "n_usable": meta.get("n_usable"),
            "npz_sha256": meta.get("npz_sha256")}



def write_object(out: Path, entry, mesh_sha256: str, *, wraps: list[WrapResult], time_s: float,
                 cpu_s: float, params: dict, labels: dict, bearing: dict | None = None,
                 centre: list | None = None, view: list | None = None) -> dict:
    """Store one object's wraps (.npz, then .json); returns the metadata written."""
    plain_name(entry.id, f"{out}: object id")
    arrays = {}
    for k, w in enumerate(wraps):
        arrays.update(w.to_arrays(prefix=f"w{k}_"))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    npz_sha256 = sha256(buf.getvalue())
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



def write_index(out: Path, dataset_dir, params: dict, *, objects: list, failed: list) -> None:
    """index.json: the finished objects' entries (index_entry) and the failed ones."""
    write_atomic(out / INDEX_NAME, _json_bytes({
        "format": FORMAT, "format_version": FORMAT_VERSION,
        "dataset": str(Path(dataset_dir).resolve()),
        "dataset_relative": os.path.relpath(Path(dataset_dir).resolve(), out.resolve()),
        "params": params,
        "objects": objects, "failed": failed}))


# ---------------------------------------------------------------- lock, temporaries

@contextmanager
def collection_lock(out: Path):
    """Hold the folder's lock (an flock on its lock file) while a run writes it, so that two
    runs never write one folder; the kernel frees the lock of a run that is killed. The lock
    file names its holder for the error a second run gets; it is removed on release."""
    path = out / LOCK_NAME
    while True:
        fd = os.open(path, os.O_CREAT | os.O_RDWR, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 256, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise CollectLockError(f"{out}: another collect run ({holder}) is writing this "
                                   f"folder; wait for it to end or stop it") from None
        try:  # locked; unless the holder before us removed the file as it released it
            if os.stat(path).st_ino == os.fstat(fd).st_ino:
                break
        except FileNotFoundError:
            pass
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"process {os.getpid()} on {socket.gethostname()}".encode())
        yield path
    finally:
        path.unlink(missing_ok=True)  # while still held: a waiting run then locks a new file
        os.close(fd)


def remove_temporaries(out: Path) -> None:
    """Temporary files of a killed run (write_atomic's `.<name>.<random>.tmp`)."""
    for p in out.glob(".*.tmp"):
        p.unlink(missing_ok=True)


# ---------------------------------------------------------------- settings a model records

def collection_tree(params: dict) -> dict:
    """The arm, planes and wrap sections of a wrap collection's recorded parameters
    (run_params, in its index.json, in either layout), as a configuration tree's
    sections."""
    wrap = copy.deepcopy(params["wrap_params"])
    for deg, rad in _RADIAN_KEYS.items():
        if rad in wrap:  # older layout; rounded: degrees(radians(7.5)) is 7.499999999999999
            wrap[deg] = round(float(np.degrees(wrap.pop(rad))), 10)
    if "delta_max_factor" not in wrap:  # the fixed step, which run_params records without them
        fixed = WrapParams()
        wrap.update(delta_max_factor=fixed.delta_max_factor, delta_turn_deg=fixed.delta_turn_deg)
    return {"arm": yaml.safe_load(params["arm_yaml"]), "wrap": wrap,
            "planes": {"alpha_deg": params["alpha_deg"],
                       "both_directions": bool(params.get("both_directions", False)),
                       "bearing": params.get("bearing", PlaneBearing.WORLD.value),
                       "centre": params.get("centre", PlaneCentre.MARK.value)}}


def training_settings(config: Config, wraps_dir) -> dict:
    """What a trained model records of how it was made: the training configuration, its
    arm, planes and wrap sections those the collection at `wraps_dir` was made with (its
    index.json), so that classify and recognize wrap a new object as the training objects
    were."""
    tree = config_to_tree(config)
    index = read_json(Path(wraps_dir) / INDEX_NAME)
    params = index.get("params") if isinstance(index, dict) else None
    if not isinstance(params, dict) or "wrap_params" not in params:
        raise ConfigError(f"{Path(wraps_dir) / INDEX_NAME}: records no collection parameters "
                          f"(not a collection made by drake-continuum collect?)")
    tree.update(collection_tree(params))
    return {"config": tree, "collection": str(wraps_dir)}
