"""Placements: how an object is set down on the table (a rest pose, a turn, an offset).

The paper trains and tests every object in one pose relative to the robot. A robot meets
objects as they were put down: standing or lying on one of their stable sides, turned any
way about the vertical, a little off the mark it aims at. A `Placement` is that, as data:

  rest_pose  None (standing as generated or imported) or the index of one of the mesh's
             stable poses (trimesh.poses.compute_stable_poses: the sides a dropped object
             comes to rest on, each with its probability), most probable first;
  turn       rotation about the vertical through the footprint centre, rad;
  offset     (x, y) of the footprint centre on the table, m.

A rest pose is kept as the direction of the mesh that points up, rotated up by the smallest
rotation (no extra twist), then re-stood on the table with its footprint centred as in the
standard pose: the placement with rest_pose None, turn 0 and offset 0 is the mesh itself.

The arm is lined up on a position the robot believes (a user's rough position, a depth
camera's estimate), never on the mesh's own geometry: `arm_frame` expresses a placed mesh
relative to that position (and, with the plane set oriented on the object, turned back by
the depth camera's bearing), which is the same as moving the arm's planes onto it, so the
wrap code needs no change. `check_clear` refuses a mesh that would reach into the arm's base.

Datasets of placed copies (`place_dataset`, `drake-continuum objects place`) hold, for each
object, placements of named kinds drawn from a seed (KINDS); their ids are
`<object_id>@<kind><k>`, so every placed copy names the object it came from and an
evaluation can keep all placements of one object in the same half of a split.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from trimesh.triangles import points_to_barycentric
from trimesh.util import diagonal_dot

from .mesh import standard_pose
from .placement_kinds import (
    ID_SEPARATOR,
    KINDS,
    SIDES,
    TRAINING_KINDS,
    PlacementError,
    parse_counts,
    placed_id,
    placement_kind,
    source_id,
)

__all__ = ["KINDS", "TRAINING_KINDS", "SIDES", "NUDGE_OFFSET", "NUDGE_TURN", "JITTER_OFFSET",
           "JITTER_TURN", "SAME_SIDE", "ARM_CLEARANCE", "ID_SEPARATOR", "TIED_PROBABILITY",
           "PlacementError",
           "offset_max", "Placement", "RestPose", "stable_poses", "rest_poses", "other_side",
           "drawn_side",
           "check_placement", "place", "arm_frame", "check_clear", "check_reachable", "side_of",
           "draw", "jittered",
           "object_placements", "placed_id", "source_id", "placement_kind", "parse_counts",
           "place_dataset"]

NUDGE_OFFSET = 0.02              # m: the robot knows where an object is to within 2 cm
NUDGE_TURN = math.radians(5.0)
JITTER_OFFSET = 0.001            # m
JITTER_TURN = math.radians(1.0)
SAME_SIDE = math.radians(30.0)   # rest poses whose up directions differ less are one side
ARM_CLEARANCE = 0.01             # m, between the object and the arm base's tube
TIED_PROBABILITY = 1e-12         # sides whose probabilities differ less are equally likely


def offset_max() -> float:
    """How far from the mark (m) an object may be set down: the table the arm serves
    (models/object_pose.yaml)."""
    return float(standard_pose().get("placement_offset_max", 0.25))


@dataclass(frozen=True)
class Placement:
    """How one object is set down (module docstring). turn in rad, offset (x, y) in m."""
    rest_pose: int | None = None
    turn: float = 0.0
    offset: tuple = (0.0, 0.0)

    def to_dict(self) -> dict:
        return {"rest_pose": self.rest_pose, "turn": float(self.turn),
                "turn_deg": round(math.degrees(self.turn), 6),
                "offset": [float(v) for v in self.offset]}

    @classmethod
    def from_dict(cls, d: dict) -> "Placement":
        r = d.get("rest_pose")
        return cls(None if r is None else int(r), float(d.get("turn", 0.0)),
                   tuple(float(v) for v in d.get("offset", (0.0, 0.0))))


@dataclass(frozen=True)
class RestPose:
    """A stable side: rotation (3, 3) standing it up, its probability, and its tilt (rad)
    from the mesh as generated (the angle its up direction makes with the mesh's +z)."""
    rotation: np.ndarray
    probability: float
    tilt: float


def _rotation_up(v: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector v to +z (half a turn about x if v is -z).

    trimesh's `align_vectors` also takes v to +z but adds a twist about z (its SVD's frame,
    up to 2.0 apart entry-wise); scipy's `Rotation.align_vectors` is this rotation to 1e-14,
    not to the bit, and turns a -z half about y, so placed meshes would move (tests).
    """
    z = np.array([0.0, 0.0, 1.0])
    v = v / np.linalg.norm(v)
    axis = np.cross(v, z)
    s, c = np.linalg.norm(axis), float(v @ z)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    return trimesh.transformations.rotation_matrix(math.atan2(s, c), axis / s)[:3, :3]


def _rows_dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of (n, 3) arrays, summed left to right as np.dot sums two
    3-vectors (so each equals np.dot of its rows to the bit)."""
    return (a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]) + a[:, 2] * b[:, 2]


def _orient(plane: tuple, pd: np.ndarray) -> np.ndarray:
    """trimesh.poses._orient3dfast on rows: > 0 where pd lies above the plane through the
    rows of plane = (pa, pb, pc)."""
    pa, pb, pc = plane
    adx, bdx, cdx = pa[:, 0] - pd[:, 0], pb[:, 0] - pd[:, 0], pc[:, 0] - pd[:, 0]
    ady, bdy, cdy = pa[:, 1] - pd[:, 1], pb[:, 1] - pd[:, 1], pc[:, 1] - pd[:, 1]
    adz, bdz, cdz = pa[:, 2] - pd[:, 2], pb[:, 2] - pd[:, 2], pc[:, 2] - pd[:, 2]
    return (adx * (bdy * cdz - bdz * cdy) + bdx * (cdy * adz - cdz * ady)
            + cdx * (ady * bdz - adz * bdy))


def _landing_probabilities(hull: trimesh.Trimesh, com: np.ndarray) -> np.ndarray:
    """Each hull face's probability of landing first when the object is dropped at random
    (the solid angle it subtends from com over 4 pi, L'Huilier's formula)."""
    sv = [d / np.sqrt(_rows_dot(d, d))[:, None] for d in (hull.triangles[:, k] - com
                                                          for k in range(3))]
    a, b, c = (np.arccos(np.clip(_rows_dot(u, v), -1, 1))
               for u, v in ((sv[0], sv[1]), (sv[1], sv[2]), (sv[2], sv[0])))
    s = (a + b + c) / 2.0
    return 1.0 / np.pi * np.arctan(np.sqrt(np.tan(s / 2) * np.tan((s - a) / 2)
                                           * np.tan((s - b) / 2) * np.tan((s - c) / 2)))


def _topples_to(hull: trimesh.Trimesh, com: np.ndarray) -> np.ndarray:
    """The face each hull face topples to (-1 for a stable one): its first neighbour (in
    face-adjacency order) across whose shared edge com projects, else its last."""
    normals, centres = hull.face_normals, hull.triangles_center
    proj = com - diagonal_dot(normals, com - hull.triangles[:, 0])[:, None] * normals
    unstable = np.any(points_to_barycentric(hull.triangles, proj) < 0, axis=1)
    pairs, edges = np.asarray(hull.face_adjacency), np.asarray(hull.face_adjacency_edges)
    src, dst = np.r_[pairs[:, 0], pairs[:, 1]], np.r_[pairs[:, 1], pairs[:, 0]]
    rank, ev = np.r_[np.arange(len(pairs)), np.arange(len(pairs))], np.r_[edges, edges]
    keep = unstable[src]
    src, dst, rank, ev = src[keep], dst[keep], rank[keep], ev[keep]
    v1, v2 = hull.vertices[ev[:, 0]], hull.vertices[ev[:, 1]]
    cen, nrm, pd = centres[src], normals[src], proj[src]
    flip = (_rows_dot(np.cross(v1 - cen, v2 - cen), nrm) < 0)[:, None]
    v1, v2 = np.where(flip, v2, v1), np.where(flip, v1, v2)
    ok = (_orient((cen, v1, v1 + nrm), pd) >= 0) & (_orient((cen, v2 + nrm, v2), pd) >= 0)
    order = np.lexsort((rank, src))
    src, dst, ok = src[order], dst[order], ok[order]
    succ = np.full(len(normals), -1)
    starts = np.flatnonzero(np.diff(src, prepend=-1))  # each face's first neighbour
    for st, en in zip(starts, np.r_[starts[1:], len(src)]):
        hit = np.flatnonzero(ok[st:en])
        succ[src[st]] = dst[st + hit[0]] if len(hit) else dst[en - 1]
    return succ


def stable_poses(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """(up directions (k, 3), probabilities (k,)) of the mesh's stable poses, most probable
    first: the poses and probabilities of trimesh.poses.compute_stable_poses(mesh) (its
    toppling graph of the convex hull, Goldberg et al.; a test compares them), its per-face
    loops as array operations, 30 times faster (0.3 s for the 40 quick-run objects). The up
    direction is the one the pose turns to +z. Sides of equal probability (a symmetric
    object's) come in the order of their up directions (`_most_probable_first`)."""
    hull = mesh.convex_hull
    com = np.asarray(mesh.center_mass, dtype=float)
    if not np.all(diagonal_dot(com - hull.triangles_center, hull.face_normals) < 0):
        raise PlacementError("the mesh's centre of mass is not inside its convex hull, so "
                             "it has no stable pose")
    prob = [float(p) for p in _landing_probabilities(hull, com)]
    succ = _topples_to(hull, com)
    # The probability flows down the toppling graph into the stable faces, in the order
    # and with the sums compute_stable_poses makes.
    indegree = np.bincount(succ[succ >= 0], minlength=len(succ))
    nodes, rounds = [i for i in range(len(succ)) if indegree[i] == 0], 0
    while nodes and rounds <= len(mesh.faces):
        moved = []
        for node in nodes:
            if succ[node] >= 0:
                prob[succ[node]] += prob[node]
                prob[node] = 0.0
                moved.append(succ[node])
        nodes, rounds = moved, rounds + 1
    found = {}  # faces of one side (normals equal to 3 decimals) are one pose
    for face in range(len(succ)):
        if prob[face] > 0.0:
            key = tuple(np.around(hull.face_normals[face], decimals=3))
            found.setdefault(key, [hull.face_normals[face], 0.0])[1] += prob[face]
    up = np.array([-1.0 * v[0] for v in found.values()]).reshape(-1, 3)
    p = np.array([v[1] for v in found.values()])
    order = _most_probable_first(up, p)
    return up[order], p[order]


def _most_probable_first(up: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The order of the sides, most probable first; a run of sides whose probabilities step
    down by at most TIED_PROBABILITY is one tie, ordered by the up directions (x, then y,
    then z, descending). The last bits of the probability sums differ between CPUs (their
    vector units add in other orders), so sorting on them alone would order a symmetric
    object's equal sides, and hence its placed copies, differently on another machine."""
    by_p = np.argsort(-p, kind="stable")
    tie = np.zeros(len(p), dtype=int)
    tie[by_p[1:]] = np.cumsum(-np.diff(p[by_p]) > TIED_PROBABILITY)
    keys = np.round(up, 6)
    return np.lexsort((-keys[:, 2], -keys[:, 1], -keys[:, 0], tie))


def rest_poses(mesh: trimesh.Trimesh) -> list[RestPose]:
    """The mesh's stable poses, most probable first (stable_poses)."""
    out = []
    for up, p in zip(*stable_poses(mesh)):
        R = _rotation_up(up)
        out.append(RestPose(R, float(p), float(np.arccos(np.clip(up[2] / np.linalg.norm(up),
                                                                 -1, 1)))))
    return out


def other_side(poses: list[RestPose]) -> int | None:
    """The most probable rest pose on a side other than as generated (tilted more than
    SAME_SIDE), or None if the object has no other side."""
    for i, p in enumerate(poses):
        if p.tilt > SAME_SIDE:
            return i
    return None


def drawn_side(poses: list[RestPose], rng) -> int | None:
    """A rest pose on a side other than as generated, drawn by its probability among those
    poses (how the object lies when it does not stand), or None if it has no other side."""
    other = [i for i, p in enumerate(poses) if p.tilt > SAME_SIDE]
    if not other:
        return None
    p = np.array([poses[i].probability for i in other])
    return other[int(rng.choice(len(other), p=p / p.sum()))]


def _stand(vertices: np.ndarray) -> np.ndarray:
    """Footprint bounding-box centre to x = y = 0, lowest point on the table."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    return vertices - [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2,
                       lo[2] - float(standard_pose().get("table_height", 0.0))]


def check_placement(placement: Placement, poses: list[RestPose] | None = None,
                    where: str = "placement") -> None:
    """PlacementError naming the value if the rest pose does not exist (poses given), the
    turn or offset is not a finite number, or the offset leaves the table the arm serves."""
    r = placement.rest_pose
    if r is not None and poses is not None and not 0 <= r < len(poses):
        raise PlacementError(f"{where}: rest pose {r} does not exist (the object has "
                             f"{len(poses)} stable poses, 0..{len(poses) - 1})")
    if not math.isfinite(placement.turn):
        raise PlacementError(f"{where}: turn {placement.turn} is not a finite number")
    off = np.asarray(placement.offset, dtype=float)
    if off.shape != (2,) or not np.all(np.isfinite(off)):
        raise PlacementError(f"{where}: offset {list(placement.offset)} is not two finite "
                             f"numbers (x, y in m)")
    limit = offset_max()
    if np.hypot(*off) > limit:
        raise PlacementError(f"{where}: offset {off.tolist()} m puts the object out of reach "
                             f"({np.hypot(*off):.3f} m from the mark; at most {limit} m)")


def place(mesh: trimesh.Trimesh, placement: Placement, poses: list[RestPose] | None = None,
          *, where: str = "placement") -> trimesh.Trimesh:
    """The mesh set down by `placement`, in world coordinates: stood on the table at the
    mark (footprint centre at x = y = 0) on its rest pose, turned, moved by the offset
    (checked by check_placement; poses: rest_poses(mesh), computed if needed)."""
    if placement.rest_pose is not None and poses is None:
        poses = rest_poses(mesh)
    check_placement(placement, poses, where)
    v = np.asarray(mesh.vertices, dtype=float)
    if placement.rest_pose is not None:
        v = v @ poses[placement.rest_pose].rotation.T
    v = _stand(v)  # at the mark: a no-op for a mesh in the standard pose
    c, s = math.cos(placement.turn), math.sin(placement.turn)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    v = v @ Rz.T + [placement.offset[0], placement.offset[1], 0.0]
    return trimesh.Trimesh(v, np.asarray(mesh.faces), process=False)


def arm_frame(world_mesh: trimesh.Trimesh, centre, turn: float = 0.0) -> trimesh.Trimesh:
    """A mesh where it stands, expressed relative to the position the arm is centred on
    (x, y): moving the mesh by -centre is moving the arm's planes onto centre; turning it
    by -turn about the vertical there is moving the arm base `turn` rad about the object
    (the plane set oriented on it, perception.bearing)."""
    c = np.asarray(centre, dtype=float).reshape(-1)[:2]
    out = world_mesh.copy()
    out.apply_translation([-c[0], -c[1], 0.0])
    if turn:
        out.apply_transform(trimesh.transformations.rotation_matrix(-float(turn), [0, 0, 1]))
    return out


def side_of(placement: Placement, poses: list[RestPose] | None) -> str:
    """SIDES entry of a placement: "other" when its rest pose is tilted more than SAME_SIDE
    from the mesh as generated (poses: rest_poses(mesh), needed for a rest pose)."""
    if placement.rest_pose is None:
        return "generated"
    return "other" if poses[placement.rest_pose].tilt > SAME_SIDE else "generated"


def _box_distance(mesh: trimesh.Trimesh, point: np.ndarray) -> float:
    """Distance from a point to the mesh's bounding box: no point of the mesh is nearer."""
    lo, hi = mesh.bounds
    return float(np.linalg.norm(np.maximum(np.maximum(lo - point, point - hi), 0.0)))


def check_clear(mesh: trimesh.Trimesh, arm, where: str = "placement") -> None:
    """PlacementError if the mesh (in the arm's frame) reaches behind the arm base or
    within ARM_CLEARANCE of its tube: the standard a placed copy is drawn to."""
    base = np.asarray(arm.base_position, dtype=float)
    lowest_x = float(np.asarray(mesh.vertices)[:, 0].min())
    if lowest_x > base[0] and _box_distance(mesh, base) - arm.radius > ARM_CLEARANCE + 1e-9:
        return  # the bounding box is clear, so the mesh is (no search of its triangles)
    gap = float(trimesh.proximity.closest_point(mesh, [base])[1][0]) - arm.radius
    if lowest_x <= base[0] or gap < ARM_CLEARANCE or mesh.contains([base])[0]:
        raise PlacementError(f"{where}: puts the object into the arm (it comes "
                             f"{max(gap, 0.0) * 1000:.1f} mm from the arm base's tube, "
                             f"reaching x = {lowest_x:.3f} m; the base is at x = {base[0]} m "
                             f"and needs {ARM_CLEARANCE * 1000:.0f} mm)")


def check_reachable(mesh: trimesh.Trimesh, arm, where: str = "object") -> None:
    """PlacementError if the arm cannot wrap the mesh (in the arm's frame) at all: it
    touches or encloses the base's tube, or lies behind the base. Looser than check_clear:
    an object whose end merely comes near the base is wrapped from a base backed off along
    each plane that needs it (wrap.base_backoff), as a robot would."""
    base = np.asarray(arm.base_position, dtype=float)
    centre_x = float(mesh.bounds.mean(axis=0)[0])
    gap = float(trimesh.proximity.closest_point(mesh, [base])[1][0]) - arm.radius
    if centre_x <= base[0] or gap <= 0.0 or mesh.contains([base])[0]:
        raise PlacementError(f"{where}: puts the object into the arm (it comes "
                             f"{max(gap, 0.0) * 1000:.1f} mm from the arm base's tube, its "
                             f"centre at x = {centre_x:.3f} m; the base is at x = {base[0]} m)")


# ---------------------------------------------------------------- drawing placements

def _uniform_turn(rng) -> float:
    return float(rng.uniform(0.0, 2.0 * math.pi))


def _nudge(rng, offset: float, turn: float) -> tuple[float, tuple]:
    """(turn, offset): a turn in [-turn, turn], an offset of length up to `offset` (uniform
    over the disc)."""
    r, a = offset * math.sqrt(rng.uniform()), rng.uniform(0.0, 2.0 * math.pi)
    return float(rng.uniform(-turn, turn)), (r * math.cos(a), r * math.sin(a))


def draw(kind: str, poses: list[RestPose], rng, *, k: int = 0) -> Placement | None:
    """Random placement number k of a kind (KINDS; not "jitter", which follows a "turned"
    placement); None if the object has no such placement (no other side for "rest",
    "side" or "lying")."""
    if kind == "turned":
        return Placement(None, _uniform_turn(rng))
    if kind == "nudged":
        turn, off = _nudge(rng, NUDGE_OFFSET, NUDGE_TURN)
        return Placement(None, turn, off)
    if kind in ("rest", "side", "lying"):
        likeliest = kind == "rest" or (kind == "side" and k == 0)
        i = other_side(poses) if likeliest else drawn_side(poses, rng)
        return None if i is None else Placement(i, _uniform_turn(rng))
    if kind == "train":
        p = np.array([q.probability for q in poses])
        i = int(rng.choice(len(p), p=p / p.sum()))
        # As generated (tilt under SAME_SIDE) keeps the exact standing pose.
        return Placement(None if poses[i].tilt <= SAME_SIDE else i, _uniform_turn(rng))
    raise PlacementError(f"placement kind must be one of {sorted(KINDS)} (not jitter), "
                         f"got {kind!r}")


def jittered(placement: Placement, rng) -> Placement:
    """The same placement moved JITTER_OFFSET in a random direction and turned JITTER_TURN
    either way."""
    a = rng.uniform(0.0, 2.0 * math.pi)
    sign = 1.0 if rng.uniform() < 0.5 else -1.0
    return Placement(placement.rest_pose, placement.turn + sign * JITTER_TURN,
                     (placement.offset[0] + JITTER_OFFSET * math.cos(a),
                      placement.offset[1] + JITTER_OFFSET * math.sin(a)))


def object_placements(mesh: trimesh.Trimesh, counts: dict, seed: int, *, index: int, arm,
                      where: str, poses: list[RestPose] | None = None, tries: int = 50
                      ) -> list[tuple[str, Placement, trimesh.Trimesh]]:
    """(tag, placement, placed mesh) of every placement of one object: counts[kind] of each
    kind, in KINDS order, drawn from seed and the object's index (the same for a seed);
    a draw that reaches into the arm is redrawn (at most `tries` times)."""
    unknown = set(counts) - set(KINDS)
    if unknown:
        raise PlacementError(f"placement kinds {sorted(unknown)} unknown (known: "
                             f"{', '.join(KINDS)})")
    poses = rest_poses(mesh) if poses is None else poses
    out = []
    turned = {}
    for kind in KINDS:
        for k in range(int(counts.get(kind, 0))):
            rng = np.random.default_rng([int(seed), int(index), list(KINDS).index(kind), k])
            for _ in range(tries):
                if kind == "jitter":
                    base = turned.get(k)
                    if base is None:
                        raise PlacementError(f"{where}: jitter {k} needs turned {k} "
                                             f"(ask for at least as many turned placements)")
                    p = jittered(base, rng)
                else:
                    p = draw(kind, poses, rng, k=k)
                if p is None:
                    break
                placed = place(mesh, p, poses, where=f"{where} {kind}{k}")
                try:
                    check_clear(placed, arm, f"{where} {kind}{k}")
                except PlacementError:
                    if kind == "jitter":
                        raise
                    continue
                if kind == "turned":
                    turned[k] = p
                out.append((f"{kind}{k}", p, placed))
                break
            else:
                raise PlacementError(f"{where}: no {kind} placement clear of the arm in "
                                     f"{tries} draws")
    return out


def place_dataset(src, out_dir, counts: dict, *, seed: int = 0, ids=None,
                  limit_per_category: int | None = None, arm=None,
                  given: Placement | None = None, progress: bool = True,
                  overwrite: bool = False) -> Path:
    """Write placed copies of a dataset's objects into out_dir (a dataset of its own:
    meshes plus manifest.json, each record with its "source_id" and "placement").

    counts: kind -> placements of each object (KINDS); given: one explicit placement for
    every object instead (kind "given"). Every placement is drawn and checked before any
    file is written: a bad one raises PlacementError naming the object and the value, and
    nothing is written. `out_dir` must not be the source (check_new_dataset), nor hold a
    dataset already unless `overwrite`. Returns the manifest path.
    """
    from tqdm import tqdm

    from ..files import write_atomic
    from ..kinematics.arm import load_arm
    from .dataset import (
        check_new_dataset,
        load_manifest,
        manifest_record,
        select_objects,
        write_manifest,
    )
    from .pose import closed_obj
    check_new_dataset(out_dir, overwrite, src)
    arm = arm or load_arm()
    dataset = load_manifest(src)
    entries = select_objects(dataset, ids, limit_per_category)
    index = {e.id: k for k, e in enumerate(dataset)}
    planned = []
    for e in tqdm(entries, desc="placements", unit="obj", disable=not progress):
        mesh = e.load()
        where = f"{e.id}"
        poses = rest_poses(mesh) if given is None or given.rest_pose is not None else None
        if given is not None:
            placed = place(mesh, given, poses, where=where)
            check_clear(placed, arm, where)
            items = [("given0", given, placed)]
        else:
            items = object_placements(mesh, counts, seed, index=index[e.id], arm=arm,
                                      where=where, poses=poses)
        for tag, p, placed in items:
            closed = closed_obj(placed)
            if closed is None:
                raise PlacementError(f"{where} {tag}: the placed mesh is not a closed surface "
                                     f"once written as OBJ (vertices under 0.1 um apart)")
            planned.append((e, tag, p, closed,
                            None if p.rest_pose is None else poses[p.rest_pose].probability,
                            side_of(p, poses)))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    records = []
    for e, tag, p, (placed, data), prob, side in planned:
        oid = placed_id(e.id, tag)
        write_atomic(out / f"{oid}.obj", data)
        rec = manifest_record(oid, e.category, f"{oid}.obj", params=e.params, mesh=placed,
                              scale=e.scale)
        rec["source_id"] = e.id
        rec["placement"] = {"kind": placement_kind(oid), **p.to_dict(), "probability": prob,
                            "side": side, "centre": [0.0, 0.0]}
        records.append(rec)
    return write_manifest(out, records, "placed", seed=int(seed), extra={
        "placed_from": str(Path(src).resolve()),
        "placements": {"counts": {k: int(v) for k, v in counts.items()},
                       "given": None if given is None else given.to_dict()}})
