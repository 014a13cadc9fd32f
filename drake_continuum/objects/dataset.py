"""Object datasets on disk: a folder of meshes in the standard pose plus `manifest.json`.

The manifest is the one description of a dataset that the rest of the project reads (through
`load_manifest`), whether the meshes were generated here or imported from 3DNet/Archive3D.

manifest.json:
    {"format": "drake-continuum-objects", "format_version": 1,
     "source": "generated" | "imported" | "placed", "seed": int | null, "units": "m",
     "pose": {"footprint_radius_max", "height_max", "table_height"},
     "objects": [{"id", "category", "file" (relative), "params" (generator parameters or
                  import details), "bbox": [[xmin, ymin, zmin], [xmax, ymax, zmax]],
                  "scale" (applied to the source), "n_triangles", "volume",
                  placed copies only: "source_id", "placement" (objects/placement.py)}],
     placed datasets only: "placed_from", "placements"}
"""

from __future__ import annotations

import json
import os
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh
from tqdm import tqdm

from ..errors import DrakeContinuumError, InputError
from ..files import (
    json_text,
    plain_name,
    regular_file,
    separate_folders,
    writable_folder,
    write_atomic,
)
from ..workers import sigint_held, stop_workers, worker_setup
from .generators import CATEGORIES, CATEGORY_COUNTS, generate_object
from .mesh import load_mesh
from .pose import PoseLimits, obj_bytes

__all__ = ["MANIFEST_NAME", "MANIFEST_FORMAT", "MANIFEST_VERSION", "DatasetError", "ObjectEntry",
           "Dataset", "manifest_record", "write_manifest", "check_new_dataset", "dataset_jobs",
           "generate_dataset", "load_manifest", "select_objects"]

MANIFEST_NAME = "manifest.json"
MANIFEST_FORMAT = "drake-continuum-objects"
MANIFEST_VERSION = 1


class DatasetError(DrakeContinuumError):
    """A dataset folder or its manifest cannot be used; the message names the file."""


@dataclass(frozen=True)
class ObjectEntry:
    """One object of a dataset. path is absolute; bbox is (2, 3) in metres."""
    id: str
    category: str
    path: Path
    params: dict
    bbox: np.ndarray
    scale: float
    n_triangles: int
    source_id: str | None = None    # a placed copy's original object (objects/placement.py)
    placement: dict | None = None   # a placed copy's placement record

    def load(self) -> trimesh.Trimesh:
        """The object's mesh (metres, standard pose), checked watertight."""
        return load_mesh(self.path)


@dataclass(frozen=True)
class Dataset:
    """A dataset read from a manifest: objects in manifest order, looked up by id or category."""
    root: Path
    source: str
    seed: int | None
    objects: tuple[ObjectEntry, ...]
    _by_id: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        self._by_id.update({o.id: o for o in self.objects})

    def __len__(self) -> int:
        return len(self.objects)

    def __iter__(self):
        return iter(self.objects)

    def by_id(self, object_id: str) -> ObjectEntry:
        try:
            return self._by_id[object_id]
        except KeyError:
            raise KeyError(f"{self.root / MANIFEST_NAME}: no object {object_id!r}") from None

    def by_category(self, category: str) -> list[ObjectEntry]:
        return [o for o in self.objects if o.category == category]

    @property
    def categories(self) -> list[str]:
        """Categories present, in the canonical order."""
        present = {o.category for o in self.objects}
        return [c for c in CATEGORIES if c in present] + sorted(present - set(CATEGORIES))

    def counts(self) -> dict[str, int]:
        return {c: len(self.by_category(c)) for c in self.categories}


def _pose_record() -> dict:
    limits = PoseLimits.load()
    return {"footprint_radius_max": limits.footprint_radius_max,
            "height_max": limits.height_max, "table_height": limits.table_height}


def manifest_record(object_id: str, category: str, file: str, *, params: dict,
                    mesh: trimesh.Trimesh, scale: float) -> dict:
    """The manifest entry for one mesh already in the standard pose."""
    return {"id": object_id, "category": category, "file": file, "params": params,
            "bbox": np.round(np.asarray(mesh.bounds), 7).tolist(), "scale": float(scale),
            "n_triangles": int(len(mesh.faces)), "volume": round(float(mesh.volume), 10)}


def write_manifest(out_dir, records: list[dict], source: str, *, seed: int | None,
                   extra: dict | None = None) -> Path:
    """Write manifest.json atomically; records in the given order; `extra` top-level
    entries (a placed dataset's "placed_from" and "placements")."""
    manifest = {"format": MANIFEST_FORMAT, "format_version": MANIFEST_VERSION,
                "source": source, "seed": seed, "units": "m", "pose": _pose_record(),
                "objects": records, **(extra or {})}
    path = Path(out_dir) / MANIFEST_NAME
    write_atomic(path, (json_text(manifest, indent=1, sort_keys=True) + "\n").encode())
    return path


def check_new_dataset(out_dir, overwrite: bool = False, source=None) -> None:
    """Refuse, before anything is written, an output folder that is the input dataset or
    folder `source` (or inside it), or that already holds a dataset (its manifest.json)
    unless `overwrite`: its meshes and manifest would be replaced."""
    out = Path(out_dir)
    if source is not None:
        separate_folders(out, source, "output folder", error=DatasetError)
    if not overwrite and (out / MANIFEST_NAME).exists():
        raise DatasetError(f"{out}: already holds a dataset ({MANIFEST_NAME}); choose another "
                           f"output folder, or pass --force to replace it")


def _generate_one(job: tuple[str, int, int]) -> tuple[str, bytes, dict]:
    category, index, seed = job
    g = generate_object(category, index, seed)
    file = f"{g.id}.obj"
    return file, obj_bytes(g.mesh), manifest_record(g.id, category, file, params=g.params_dict(),
                                                    mesh=g.mesh, scale=g.posed.scale)


def dataset_jobs(seed: int, counts: dict[str, int] | None = None) -> list[tuple[str, int, int]]:
    """(category, index, seed) for every object, in manifest order."""
    counts = CATEGORY_COUNTS if counts is None else counts
    return [(c, i, int(seed)) for c in counts for i in range(counts[c])]


def generate_dataset(out_dir, *, seed: int = 0, counts: dict[str, int] | None = None,
                     workers: int | None = None, progress: bool = True,
                     overwrite: bool = False) -> Path:
    """Generate the paper's 185 objects (or `counts`) into out_dir; returns the manifest path.

    Objects are independent of each other and of the worker count, so the same seed gives the
    same bytes. Meshes are written as they finish, the manifest last. A folder that already
    holds a dataset is refused unless `overwrite` (check_new_dataset).
    """
    check_new_dataset(out_dir, overwrite)
    out = writable_folder(out_dir)
    jobs = dataset_jobs(seed, counts)
    workers = workers or min(len(jobs), os.cpu_count() or 1)
    records = []
    with tqdm(total=len(jobs), desc="objects", unit="obj", disable=not progress) as bar:
        if workers > 1:
            pool = ProcessPoolExecutor(max_workers=workers, initializer=worker_setup)
            try:
                with sigint_held():  # forked here: a Ctrl-C waits until the workers exist
                    results = pool.map(_generate_one, jobs, chunksize=4)
                for file, data, record in results:
                    write_atomic(out / file, data)
                    records.append(record)
                    bar.update()
            except BaseException:
                stop_workers(pool)
                raise
            pool.shutdown(wait=True)
        else:
            for job in jobs:
                file, data, record = _generate_one(job)
                write_atomic(out / file, data)
                records.append(record)
                bar.update()
    return write_manifest(out, records, "generated", seed=int(seed))


def load_manifest(root) -> Dataset:
    """Read a dataset folder's manifest.json; DatasetError names the file and the problem."""
    root = Path(root)
    path = root / MANIFEST_NAME
    if not root.is_dir():
        raise DatasetError(f"{root}: not a dataset folder (does not exist)")
    if not path.exists():
        raise DatasetError(f"{path}: missing; create a dataset with `drake-continuum objects "
                           f"generate --out {root}` or `objects import`")
    regular_file(path, DatasetError)
    try:
        manifest = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise DatasetError(f"{path}: corrupt JSON ({e})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != MANIFEST_FORMAT:
        raise DatasetError(f"{path}: not a drake-continuum object manifest")
    if manifest.get("format_version") != MANIFEST_VERSION:
        raise DatasetError(f"{path}: format_version {manifest.get('format_version')!r} is not "
                           f"supported (expected {MANIFEST_VERSION})")
    entries = []
    for k, rec in enumerate(manifest.get("objects", [])):
        try:
            where = f"{path}: object {k}"
            entries.append(ObjectEntry(
                id=plain_name(rec["id"], f"{where} id", DatasetError),
                category=str(rec["category"]),
                path=root / plain_name(rec["file"], f"{where} file", DatasetError),
                params=dict(rec.get("params", {})), bbox=np.asarray(rec["bbox"], float),
                scale=float(rec.get("scale", 1.0)), n_triangles=int(rec.get("n_triangles", 0)),
                source_id=rec.get("source_id"), placement=rec.get("placement")))
        except DatasetError:
            raise
        except (KeyError, TypeError, ValueError) as e:
            raise DatasetError(f"{path}: object {k} is malformed ({type(e).__name__}: {e})") \
                from None
    ids = [e.id for e in entries]
    if len(set(ids)) != len(ids):
        raise DatasetError(f"{path}: duplicate object ids")
    missing = [e.path.name for e in entries if not e.path.exists()]
    if missing:
        raise DatasetError(f"{path}: {len(missing)} mesh file(s) missing, e.g. {missing[0]}")
    for e in entries:  # before any is read: a FIFO would block, a device never end
        regular_file(e.path, DatasetError)
    seed = manifest.get("seed")
    return Dataset(root=root, source=str(manifest.get("source", "")),
                   seed=None if seed is None else int(seed), objects=tuple(entries))


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
