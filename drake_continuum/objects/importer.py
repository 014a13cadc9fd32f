"""Import of real meshes (3DNet Cat10 / Archive3D layout) into a dataset in the standard pose.

Source layout: `<root>/<label>/<name>.{obj,stl,ply,off}`: each folder name is a category label,
kept as given (the paper's ten are recognised in 3DNet's spellings, "Toilet Paper" ->
toilet_paper). Each mesh is read, converted to metres (`units`, or guessed from its size: for
the paper's categories the unit that brings it nearest that category's usual size, for any
other label the one unit that makes it an object the arm can wrap, else it is skipped asking
for --units), cleaned (vertices merged, the
largest connected piece kept, holes filled, winding and normals made consistent), stood on the
table at the standard pose (scaled down only if it would break the pose limits) and written as
OBJ with a manifest like a generated dataset's. A mesh that cannot be made watertight is
skipped with a message naming the file and the reason; the rest is imported.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from ..errors import DrakeContinuumError, InputError, MissingFileError
from ..files import write_atomic
from .dataset import check_new_dataset, manifest_record, write_manifest
from .generators import CATEGORIES
from .mesh import MESH_SUFFIXES
from .pose import closed_as_obj, obj_bytes, to_standard_pose

__all__ = ["UNITS", "TYPICAL_SIZE", "WRAPPABLE_EXTENT", "ImportReport", "ImportSkip",
           "category_from_folder", "units_by_size", "guess_units", "repair", "import_mesh",
           "read_list", "scan_source", "import_folder"]

log = logging.getLogger(__name__)

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}

# Typical largest extent (m) of a real object of each category, for guessing units.
TYPICAL_SIZE = {"apple": 0.08, "banana": 0.19, "bottle": 0.25, "bowl": 0.18, "cup": 0.11,
                "donut": 0.1, "hammer": 0.3, "mug": 0.11, "teapot": 0.2, "toilet_paper": 0.11}

# Largest extent (m) of an object the arm wraps at its real size: the tube is 2 cm across and
# bends round 1.5 cm at its tightest; the standard pose holds 26 cm across and 34 cm high.
# Units differ tenfold, so at most one unit puts a mesh in this range unless it lies near an end.
WRAPPABLE_EXTENT = (0.03, 0.45)


@dataclass
class ImportReport:
    """What an import did: ids written, (path, reason) skipped, list entries not found."""
    imported: list[str] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    manifest: Path | None = None


class ImportSkip(DrakeContinuumError):
    """This mesh cannot be imported; the message is the reason."""


def category_from_folder(name: str) -> str:
    """The category label of a source folder: one of the paper's ten in its canonical spelling
    ("toilet paper", "ToiletPaper", "mugs" -> toilet_paper, mug), else the name as given."""
    key = re.sub(r"[^a-z]", "", name.lower())
    for category in CATEGORIES:
        plain = category.replace("_", "")
        if key in (plain, plain + "s", plain + "es"):
            return category
    return name


def units_by_size(extent: float) -> list[str]:
    """The units in which a mesh `extent` across is an object the arm wraps at its real size."""
    low, high = WRAPPABLE_EXTENT
    return [u for u in UNITS if low <= extent * UNITS[u] <= high]


def guess_units(extent: float, category: str) -> str | None:
    """The unit of a mesh `extent` across: for one of the paper's categories the unit that
    brings it nearest the category's usual size; for any other label the one unit of
    units_by_size, or None when none or several fit (the caller asks for units)."""
    typical = TYPICAL_SIZE.get(category)
    if typical is None:
        fitting = units_by_size(extent)
        return fitting[0] if len(fitting) == 1 else None
    return min(UNITS, key=lambda u: abs(np.log(max(extent, 1e-12) * UNITS[u] / typical)))


def _units_unclear(extent: float) -> str:
    low, high = WRAPPABLE_EXTENT
    fitting = units_by_size(extent)
    sizes = ", ".join(f"{extent * UNITS[u]:.3g} m in {u}" for u in (fitting or UNITS))
    what = (f"could be {' or '.join(fitting)}" if fitting else
            f"is no object the arm wraps ({low:g} to {high:g} m across) in any unit")
    return f"units unclear: {extent:.4g} across {what} ({sizes}); give --units"


def _units_misfit(extent: float, units: str) -> str:
    """Why a mesh is refused in the units given when other units fit it: the standard pose
    would scale it to its frame (every such mesh one size), or keep it too small to wrap."""
    low, high = WRAPPABLE_EXTENT
    size = extent * UNITS[units]
    return (f"{size:.4g} m across with --units {units}, {'larger' if size > high else 'smaller'}"
            f" than the objects the arm wraps at their size ({1000 * low:g} mm to {high:g} m);"
            f" its size fits {' or '.join(units_by_size(extent))} (leave --units out to guess "
            f"each mesh's units)")


def _read(path: Path) -> trimesh.Trimesh:
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as e:  # trimesh raises many types for unreadable files
        raise ImportSkip(f"cannot be read as a mesh ({type(e).__name__}: {e})") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise ImportSkip("holds no triangles")
    if not np.all(np.isfinite(loaded.vertices)):
        raise ImportSkip("has NaN or infinite vertex coordinates")
    return loaded


def repair(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Merged, largest piece, holes filled, consistent outward winding; ImportSkip if unusable."""
    mesh = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True, validate=True)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    pieces = mesh.split(only_watertight=False)
    if len(pieces) > 1:
        mesh = max(pieces, key=lambda p: p.area)
    if not mesh.is_watertight:
        trimesh.repair.fill_holes(mesh)
    trimesh.repair.fix_winding(mesh)
    trimesh.repair.fix_inversion(mesh)
    if not mesh.is_watertight:
        open_edges = int((trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)).size)
        raise ImportSkip(f"not watertight after repair ({open_edges} open edges)")
    if not mesh.is_winding_consistent:
        raise ImportSkip("inconsistent face winding after repair (non-manifold)")
    if mesh.volume <= 0:
        raise ImportSkip("encloses no volume after repair")
    return mesh


def import_mesh(path, category: str, *, units: str | None = None, up: str = "z"):
    """One source mesh in the standard pose: (PosedMesh, details dict) or ImportSkip."""
    path = Path(path)
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise ImportSkip(f"unknown mesh extension {path.suffix!r} "
                         f"(expected one of {', '.join(MESH_SUFFIXES)})")
    if path.stat().st_size == 0:
        raise ImportSkip("file is empty")
    mesh = repair(_read(path))
    if up == "y":
        mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    extent = float(np.ptp(mesh.vertices, axis=0).max())
    unit = units or guess_units(extent, category)
    if unit is None:
        raise ImportSkip(_units_unclear(extent))
    fitting = units_by_size(extent) if units is not None else []
    if fitting and units not in fitting:
        raise ImportSkip(_units_misfit(extent, units))  # not scaled to the standard pose
    mesh.apply_scale(UNITS[unit])
    posed = to_standard_pose(mesh)
    details = {"source_file": str(path), "units": unit, "units_guessed": units is None,
               "up": up, "pose_scale": posed.scale}
    return posed, details, UNITS[unit] * posed.scale


def read_list(list_file) -> list[tuple[str, str]]:
    """(category, name) for each entry of a list like data/zhang2016_185_objects.txt.

    Lines are paths ending in `<category>/<name>.<ext>`; `#` starts a comment line.
    """
    entries = []
    for line in Path(list_file).read_text().splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        p = Path(line)
        category = category_from_folder(p.parent.name)
        entries.append((category, p.stem))
    return entries


def _name_key(stem: str) -> str:
    """Names in the paper's list carry point-cloud suffixes the mesh files may lack."""
    return re.sub(r"_insideremoved$", "", stem.lower())


def scan_source(root) -> tuple[list[tuple[str, Path]], list[tuple[str, str]]]:
    """(category, file) for every mesh under root, and (path, reason) for files not usable."""
    root = Path(root)
    found, skipped = [], []
    for folder in sorted(p for p in root.iterdir() if p.is_dir()):
        category = category_from_folder(folder.name)
        for f in sorted(p for p in folder.rglob("*") if p.is_file()):
            if f.suffix.lower() in MESH_SUFFIXES:
                found.append((category, f))
            elif not f.name.startswith("."):
                skipped.append((str(f), f"unknown mesh extension {f.suffix!r} "
                                        f"(expected one of {', '.join(MESH_SUFFIXES)})"))
    return found, skipped


def _object_id(category: str, stem: str, taken: set) -> str:
    base = re.sub(r"[^A-Za-z0-9_.-]", "_", f"{category}_{stem}")
    oid, k = base, 1
    while oid in taken:
        k += 1
        oid = f"{base}_{k}"
    taken.add(oid)
    return oid


def import_folder(src, out_dir, *, units: str | None = None, list_file=None,
                  up: str = "z", overwrite: bool = False) -> ImportReport:
    """Import every usable mesh of `src` (or only those named in list_file) into out_dir,
    which must not be `src` or inside it, nor hold a dataset already unless `overwrite`."""
    src, out = Path(src), Path(out_dir)
    if not src.is_dir():
        raise MissingFileError(f"{src}: source folder not found")
    check_new_dataset(out, overwrite, src)
    if units is not None and units not in UNITS:
        raise InputError(f"units {units!r} unknown (use one of {', '.join(UNITS)})")
    found, skipped = scan_source(src)
    report = ImportReport(skipped=skipped)
    if list_file is not None:
        wanted = read_list(list_file)
        index = {(c, _name_key(f.stem)): (c, f) for c, f in found}
        by_name = {_name_key(f.stem): (c, f) for c, f in found}
        selected = []
        for category, name in wanted:
            hit = index.get((category, _name_key(name))) or by_name.get(_name_key(name))
            if hit is None:
                report.missing.append(f"{category}/{name}")
            else:
                selected.append((category, hit[1]))
        found = selected
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    records, taken = [], set()
    for category, path in found:
        try:
            posed, details, scale = import_mesh(path, category, units=units, up=up)
        except ImportSkip as e:
            report.skipped.append((str(path), str(e)))
            log.debug("skipped %s: %s", path, e)
            continue
        closed = closed_as_obj(posed.mesh)
        if closed is None:
            report.skipped.append((str(path), "not a closed surface once written as OBJ "
                                              "(vertices under 0.1 um apart)"))
            continue
        oid = _object_id(category, path.stem, taken)
        write_atomic(out / f"{oid}.obj", obj_bytes(closed))
        records.append(manifest_record(oid, category, f"{oid}.obj", params=details, mesh=closed,
                                       scale=scale))
        report.imported.append(oid)
    if not records:
        if created:
            out.rmdir()
        raise InputError(_nothing_imported(src, report))
    report.manifest = write_manifest(out, records, "imported", seed=None)
    return report


def _nothing_imported(src: Path, report: ImportReport) -> str:
    """The one line for an import that found no usable mesh: why, with the first reasons."""
    reasons = [f"{Path(p).name}: {r}" for p, r in report.skipped[:3]]
    more = len(report.skipped) - len(reasons)
    why = ("; ".join(reasons) + (f"; and {more} more" if more > 0 else "")) if reasons else \
        f"no {'/'.join(MESH_SUFFIXES)} file in a <label>/ folder under it"
    if report.missing:
        why += f"; {len(report.missing)} listed meshes not found"
    return f"{src}: no mesh imported ({why})"
