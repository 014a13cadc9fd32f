"""Reading a wrap collection: each object's wraps, checked against the format this code
reads, as an ObjectRecord (its chords, wrap descriptors and contact extent).
"""

from __future__ import annotations

import hashlib
import io
import json
import warnings
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import DrakeContinuumError, InputError, MissingFileError
from ..features.chords import (
    WRAP_DESCRIPTORS,
    ChordParams,
    ChordSet,
    object_chords,
    wrap_descriptors,
)
from ..files import plain_name
from ..npz import npz_arrays
from ..objects.placement_kinds import ID_SEPARATOR, SIDES
from ..perception.locate import VIEW_EXTENT
from ..wrapping.wrap_types import (
    WRAPS_FORMAT,
    WRAPS_FORMAT_VERSION,
    WrapResult,
    params_difference,
    stored_params,
)

__all__ = ["WrapDataWarning", "WrapFileError", "WrapFormatError", "MixedCollectionError",
           "ObjectRecord", "object_record",
           "recorded_side", "recorded_view", "check_wraps_format", "read_object_wraps",
           "load_collection", "load_wraps"]


class WrapDataWarning(UserWarning):
    """A wrap file could not be read and was skipped."""


class WrapFileError(DrakeContinuumError):
    """One object's wrap files are missing or damaged (the message names the file)."""


class WrapFormatError(InputError):
    """A wrap file of another format version than this code reads (the message names it)."""


class MixedCollectionError(InputError):
    """An object of a collection was made with other parameters than its index.json records
    (copied in from another collection): its wraps are not comparable with the others'."""

# ---------------------------------------------------------------- objects and loading

@dataclass(frozen=True)
class ObjectRecord:
    """What classification needs of one object's wraps.

    Args:
        object_id: the object's name.
        category: its category (the label).
        chords: chords of its usable wraps; ChordSet.wrap is the position of the wrap in
            the object's list (plane_index[wrap] is its plane).
        contact_points: (m, 3) contact centres of all its usable wraps (the baseline's input).
        plane_index: (w,) plane index of each of its wraps, in order.
        usable: (w,) whether each wrap gave chords.
        wrap_time_s: (w,) wall time of each wrap, s.
        descriptors: (w, 7) chords.wrap_descriptors of each wrap (zeros for unusable ones);
            (0, 7) if unknown, as for an object known only by its chords.
        conformity: (w,) each wrap's WrapResult.conformity (nan where not measured).
        contact_regions: (w,) contact regions of each wrap's final configuration.
        side: the side the object stood on when wrapped (objects.placement.SIDES):
            "generated" for an original or a copy standing as generated, "other" for a
            copy on another rest pose, None for a placed copy whose placement was not
            recorded (collected before 0.4.0); the classifier's rest classes need it.
        view: (3,) the object's height and footprint extents as the depth camera saw it
            (perception.locate.view_extent, recorded by collect), NaN where unknown.
        chord_params: the ChordParams its chords were taken with (None: unknown); train
            refuses a scenario whose chords section differs, which would label the model
            with chords it was not trained on.
    """

    object_id: str
    category: str
    chords: ChordSet
    contact_points: np.ndarray
    plane_index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    usable: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    wrap_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    descriptors: np.ndarray = field(
        default_factory=lambda: np.zeros((0, len(WRAP_DESCRIPTORS))))
    conformity: np.ndarray = field(default_factory=lambda: np.zeros(0))
    contact_regions: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    side: str | None = "generated"
    view: np.ndarray = field(default_factory=lambda: np.full(len(VIEW_EXTENT), np.nan))
    chord_params: ChordParams | None = None

    @property
    def n_wraps(self) -> int:
        """Wraps that describe the object (usable ones)."""
        return int(np.count_nonzero(self.usable))


def object_record(object_id: str, category: str, wraps, *, params: ChordParams = ChordParams(),
                  side: str | None = "generated", view=None) -> ObjectRecord:
    """An ObjectRecord from in-memory WrapResults (side, view: ObjectRecord's; view None:
    unknown, NaN entries too)."""
    wraps = list(wraps)
    usable = np.array([w.usable for w in wraps], dtype=bool)
    points = [w.contacts.p for w, u in zip(wraps, usable) if u]
    return ObjectRecord(
        object_id=object_id, category=category, chords=object_chords(wraps, params),
        contact_points=np.concatenate(points) if points else np.zeros((0, 3)),
        plane_index=np.array([w.plane_index for w in wraps], dtype=np.int64),
        usable=usable, wrap_time_s=np.array([w.time_s for w in wraps], dtype=float),
        descriptors=np.array([wrap_descriptors(w) for w in wraps],
                             dtype=float).reshape(-1, len(WRAP_DESCRIPTORS)),
        conformity=np.array([w.conformity for w in wraps], dtype=float),
        contact_regions=np.array([w.contact_regions for w in wraps], dtype=np.int64),
        side=side, view=(np.full(len(VIEW_EXTENT), np.nan) if view is None
                         else np.asarray(view, dtype=float).reshape(len(VIEW_EXTENT))),
        chord_params=params)


def recorded_view(view, where: str = "view") -> np.ndarray:
    """(3,) a camera view (ObjectRecord.view): all NaN for None (unknown); WrapFileError
    naming `where` for anything but 3 finite non-negative numbers."""
    if view is None:
        return np.full(len(VIEW_EXTENT), np.nan)
    try:
        v = np.asarray(view, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        v = np.zeros(0)
    if v.shape != (len(VIEW_EXTENT),) or not np.all(np.isfinite(v)) or np.any(v < 0):
        raise WrapFileError(f"{where}: the camera's view {view!r} is not "
                            f"{len(VIEW_EXTENT)} finite non-negative numbers "
                            f"({', '.join(VIEW_EXTENT)}, m)")
    return v


def recorded_side(object_id: str, meta: dict) -> str | None:
    """The side an object of a collection stood on (ObjectRecord.side): "generated" for an
    original (no '@' in its id), else its recorded placement's "side", None if none is
    recorded or it is not one of SIDES."""
    if ID_SEPARATOR not in str(object_id):
        return "generated"
    placement = meta.get("placement")
    side = placement.get("side") if isinstance(placement, dict) else None
    return side if side in SIDES else None


def check_wraps_format(path, meta) -> None:
    """A collection's JSON file (object or index.json) must be of the wrap format version
    this code reads: raises WrapFormatError naming the file, as a model of another version
    is refused, rather than reading numbers whose meaning may have changed."""
    version = meta.get("format_version") if isinstance(meta, dict) else None
    if version != WRAPS_FORMAT_VERSION or meta.get("format") != WRAPS_FORMAT:
        raise WrapFormatError(
            f"{path}: wrap file format {meta.get('format') if isinstance(meta, dict) else None!r}"
            f" version {version} cannot be read by this drake-continuum, which reads "
            f"{WRAPS_FORMAT!r} version {WRAPS_FORMAT_VERSION}; collect the wraps again "
            f"with this version")


def read_object_wraps(folder, object_id: str) -> tuple[dict, list[WrapResult]]:
    """(metadata, wraps) of one object from `<folder>/<object_id>.json` and `.npz`.

    Raises WrapFileError naming the file if one is missing, damaged, another object's (its
    recorded id, or the .npz's SHA-256 recorded in the .json, differs) or holds non-finite
    numbers (NaN, infinity: no wrap stores them), WrapFormatError if it is of another format
    version, InputError if `object_id` is not a plain file name."""
    folder = Path(folder)
    plain_name(object_id, f"{folder}: object id")
    json_path, npz_path = folder / f"{object_id}.json", folder / f"{object_id}.npz"
    try:
        meta = json.loads(json_path.read_text())
        n = int(meta["n_wraps"])
    except FileNotFoundError:
        raise WrapFileError(f"{folder}: no object {object_id!r} ({json_path.name} not "
                            f"found)") from None
    except KeyError as e:
        raise WrapFileError(f"{json_path}: not an object's wrap file (no {e} entry)") from None
    except (OSError, ValueError, TypeError) as e:
        raise WrapFileError(f"{json_path}: {type(e).__name__}: {e}") from None
    check_wraps_format(json_path, meta)
    if str(meta.get("object_id", object_id)) != str(object_id):
        raise WrapFileError(f"{json_path}: records object {meta.get('object_id')!r}, not "
                            f"{object_id!r} (files renamed or swapped)")
    try:
        data = npz_path.read_bytes()
        recorded = meta.get("npz_sha256")
        if recorded is not None and hashlib.sha256(data).hexdigest() != recorded:
            raise ValueError(f"its SHA-256 differs from the one recorded in {json_path.name} "
                             f"(damaged, or another object's file)")
        if not zipfile.is_zipfile(io.BytesIO(data)):
            raise ValueError("not an .npz archive (damaged or truncated)")
        arrays = npz_arrays(data)  # np.load's arrays, read in one pass
        _check_finite(arrays)
        wraps = [WrapResult.from_arrays(arrays, f"w{k}_") for k in range(n)]
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as e:
        raise WrapFileError(f"{npz_path}: {type(e).__name__}: {e}") from None
    return meta, wraps


def _check_finite(arrays: dict) -> None:
    """ValueError naming the arrays that hold a NaN or an infinity (no wrap stores them);
    one test over all of them first, as nearly every object holds none."""
    numbers = [a.ravel() for a in arrays.values() if a.dtype.kind in "fc"]
    if not numbers or np.isfinite(np.concatenate(numbers)).all():
        return
    bad = sorted(k for k, a in arrays.items()
                 if a.dtype.kind in "fc" and not np.all(np.isfinite(a)))
    raise ValueError(f"non-finite numbers (NaN or infinity) in {', '.join(bad)}")


def _object_ids(folder: Path) -> tuple[list[str], list[dict], dict]:
    """(ids of the collection's finished objects, index.json's failed entries, index.json);
    every object file and {} when index.json is missing or unreadable."""
    every = sorted(p.stem for p in folder.glob("*.json") if p.name != "index.json"), [], {}
    index = folder / "index.json"
    if not index.is_file():
        return every
    try:
        data = json.loads(index.read_text())
    except (OSError, ValueError) as e:
        warnings.warn(f"{index}: unreadable ({e}); reading every object file instead",
                      WrapDataWarning, stacklevel=3)
        return every
    check_wraps_format(index, data)
    try:
        ids = [plain_name(e if isinstance(e, str) else e["object_id"], f"{index}: object id")
               for e in data["objects"]]
        failed = [f for f in data.get("failed", []) if isinstance(f, dict) and f.get("object_id")]
    except (KeyError, TypeError, AttributeError) as e:
        warnings.warn(f"{index}: unreadable ({type(e).__name__}: {e}); reading every object "
                      f"file instead", WrapDataWarning, stacklevel=3)
        return every
    return (ids, failed, data) if ids or failed else every


def _check_against_index(folder: Path, object_id: str, meta: dict, *, index: dict,
                         entry: dict | None) -> None:
    """An object must be the one index.json lists: made with the collection's parameters
    (MixedCollectionError: collect refuses to mix them, and so does every reader) and with
    the .npz digest the index recorded (WrapFileError: another collection's file)."""
    if "params" in index and "params" in meta:
        differ = params_difference(stored_params(index["params"]),
                                   stored_params(meta["params"]), ("collection", "object"))
        if differ:
            raise MixedCollectionError(
                f"{folder / object_id}.json: made with other parameters than its collection "
                f"({folder / 'index.json'}): {'; '.join(differ)}; its wraps cannot be compared "
                f"with the others'. Remove it, or collect it again into this folder")
    recorded = (entry or {}).get("npz_sha256")
    if recorded is not None and recorded != meta.get("npz_sha256"):
        raise WrapFileError(f"{folder / object_id}.npz: not the file index.json lists for "
                            f"{object_id!r} (its SHA-256 differs)")


def load_collection(folder, params: ChordParams = ChordParams()
                    ) -> tuple[list[ObjectRecord], list[dict]]:
    """Every readable object of a wrap collection (WRAPS folder), chords computed once, and
    the objects left out: [{"object_id", "reason"}] for each whose files are missing,
    damaged or hold non-finite numbers, and each index.json lists as failed in collection.

    Raises WrapFormatError if a file is of another format version, FileNotFoundError if
    the folder holds no readable object.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise MissingFileError(f"{folder}: no such wrap folder")
    if (folder / "manifest.json").is_file() and not (folder / "index.json").exists():
        raise InputError(f"{folder}: an object dataset (manifest.json), not a wrap "
                         f"collection; collect its wraps first: drake-continuum collect "
                         f"{folder} --out WRAPS")
    ids, failed, index = _object_ids(folder)
    entries = {str(e.get("object_id")): e for e in index.get("objects", [])
               if isinstance(e, dict)}
    records, skipped = [], []
    for object_id in ids:
        try:
            meta, wraps = read_object_wraps(folder, object_id)
            _check_against_index(folder, object_id, meta, index=index, entry=entries.get(object_id))
            if "category" not in meta:
                raise WrapFileError(f"{folder / object_id}.json: no 'category'")
            oid = str(meta.get("object_id", object_id))
            records.append(object_record(
                oid, str(meta["category"]), wraps, params=params, side=recorded_side(oid, meta),
                view=recorded_view(meta.get("view"), f"{folder / object_id}.json")))
        except WrapFileError as e:
            skipped.append({"object_id": str(object_id), "reason": str(e)})
    skipped += [{"object_id": str(f["object_id"]),
                 "reason": f"failed in collection: {f.get('error', 'no reason recorded')}"}
                for f in failed]
    if not records:
        raise MissingFileError(
            f"{folder}: no readable objects (<object_id>.json + .npz)"
            + (f"; skipped {'; '.join(s['object_id'] + ': ' + s['reason'] for s in skipped)}"
               if skipped else ""))
    return records, skipped


def load_wraps(folder, params: ChordParams = ChordParams()) -> list[ObjectRecord]:
    """load_collection's objects; each object left out is named in a WrapDataWarning."""
    records, skipped = load_collection(folder, params)
    for s in skipped:
        warnings.warn(f"skipped object {s['object_id']!r}: {s['reason']}", WrapDataWarning,
                      stacklevel=2)
    return records


