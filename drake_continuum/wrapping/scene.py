"""The contact scene: the arm and one object in a Drake MultibodyPlant + SceneGraph.

Drake's point-pair, signed-distance and HasCollisions queries see a Mesh only through its
convex hull (docs/contact.md, "the convex-hull trap"): a mug's handle hole and cavity vanish. Only
hydroelastic contact surfaces see the real surface, so the object is a *rigid* hydroelastic
Mesh, the arm a chain of *compliant* hydroelastic capsules, and every contact query goes
through ComputeContactSurfaces. The arm is kinematic: each capsule is a free body posed from
our own constant-curvature forward kinematics with one SetPositions call, which keeps every
link exactly on the arc (a jointed chain could only approximate the arc and would need IK).

Capsules have a fixed length (section_length_max / links_per_section) while sections change
length, so within a section the capsules are spread evenly from its start to its end and
overlap more when the section is short; the tube never has a gap.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cache
from operator import itemgetter

import numpy as np
import trimesh
from pydrake.common import MemoryFile
from pydrake.geometry import (
    AddCompliantHydroelasticProperties,
    AddRigidHydroelasticProperties,
    Box,
    Capsule,
    CollisionFilterDeclaration,
    Cylinder,
    GeometrySet,
    HydroelasticContactRepresentation,
    InMemoryMesh,
    Mesh,
    MeshcatVisualizer,
    ProximityProperties,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import SpatialInertia
from pydrake.systems.framework import DiagramBuilder

from ..errors import ConfigError
from ..kinematics.arm import ARM_COLOUR, ArmConfig, BackboneSamples, ContinuumArm
from ..kinematics.compiled import capsule_frames, far_segments_within
from ..objects.mesh import MeshError, closed_mesh
from .apart import ApartTest
from .contact import Contacts, contact_regions
from .distance import DistanceField, SurfaceDistance

__all__ = ["OBJECT_COLOR", "SceneOptions", "SceneGeometry", "WrapScene", "object_shape",
           "register_scene", "capsule_poses"]

OBJECT_COLOR = np.array([0.55, 0.6, 0.7, 1.0])
_NO_CONTACT = ((), False, False)  # a capsule's answer: (contact surfaces, object?, table?)


@dataclass(frozen=True)
class SceneOptions:
    """Contact-model settings.

    Args:
        links_per_section: capsules a section; 20 keeps a capsule within 2 mm of the arc at
            the curvature limit (sagitta l^2 kappa / 8).
        resolution_hint: compliant capsule mesh resolution, m; about half the arm radius keeps
            contact onset within 0.15 mm of an exact capsule (docs/contact.md).
        hydroelastic_modulus: compliant modulus, Pa; only the contact patch size depends on it.
        table: add the table top (a rigid box under z = 0, where objects stand) to the
            scene, for wraps that treat it as an obstacle (WrapParams.table).
        hull_prefilter: prove capsules apart from the object before computing contact
            surfaces (~0.07 ms for each capsule asked that touches nothing): `apart.ApartTest`
            tests the exact capsules against the object's convex hull, then against its
            triangles near them, and a query that leaves no capsule ends there; otherwise
            only the capsules left are posed for Drake's contact surfaces, the others parked
            far from everything (BENCHMARKS.md, Wrapping). With the table taking part,
            Drake's point-contact test (ComputePointPairPenetration: the table and the
            object's hull) decides whether to ask, and every capsule is asked.
    """

    links_per_section: int = 20
    resolution_hint: float = 0.005
    hydroelastic_modulus: float = 5e6
    table: bool = True
    hull_prefilter: bool = True


class WrapScene:
    """The arm and one rigid object, answering "where does the arm touch the object?".

    Args:
        arm: the continuum arm.
        object_mesh: path of a closed triangle mesh (OBJ, STL, PLY, OFF) or a trimesh.Trimesh,
            in metres.
        object_pose: pose of the mesh in the world (default: identity; generated and imported
            objects are stored in the standard pose already).
        options: contact-model settings.
        meshcat: a pydrake Meshcat to draw the scene in (a MeshcatVisualizer is added to the
            diagram; see viz.py), or None.
    """

    def __init__(self, arm: ContinuumArm, object_mesh, object_pose: RigidTransform | None = None,
                 options: SceneOptions = SceneOptions(), meshcat=None):
        self.arm = arm
        self.options = options
        self.meshcat = meshcat
        mesh = self._take_object(object_mesh, object_pose)
        self._build(mesh)
        self.n_queries = 0  # contact questions asked (one a configuration)
        self.n_contact_surfaces = 0  # of those, answered by Drake's ComputeContactSurfaces
        self.timing = {"pose": 0.0, "prefilter": 0.0, "contact_surfaces": 0.0}  # CPU s

    def replace_object(self, object_mesh, object_pose: RigidTransform | None = None) -> None:
        """Put another object in this scene (arguments as the constructor's).

        Building a scene costs ~0.3 s of CPU, most of it Drake meshing the 60 compliant
        capsules and cloning them into a context; a collection wraps one object after
        another with the same arm, so it swaps the object's shape in the context instead
        (SceneGraph.ChangeShape): the capsules, their filters and the table stay. Wraps in
        the new scene are those of a scene built for the object (a test compares them).
        """
        if self.meshcat is not None:
            raise ConfigError("replace_object: a scene drawn in Meshcat keeps its object")
        mesh = self._take_object(object_mesh, object_pose)
        self.scene_graph.ChangeShape(
            self.scene_graph.GetMyMutableContextFromRoot(self.context),
            self.plant.get_source_id(), self.object_geometry, object_shape(mesh),
            self.object_pose)
        self._forget()
        self.config = None

    def _take_object(self, object_mesh, object_pose) -> trimesh.Trimesh:
        """Load and check the object (reach, base outside it); returns the mesh in its own
        frame and keeps it posed in the world as object_trimesh."""
        pose = object_pose if object_pose is not None else RigidTransform()
        name = "mesh" if isinstance(object_mesh, trimesh.Trimesh) else str(object_mesh)
        mesh = closed_mesh(object_mesh)
        posed = mesh.copy()
        posed.apply_transform(pose.GetAsMatrix4())
        self._check_reach(posed, name)  # before anything changes: a refused object leaves
        self.object_pose, self.object_name, self.object_trimesh = pose, name, posed  # none
        self._sdf = self._apart = None
        return mesh

    # ----------------------------------------------------------------- construction
    def _check_reach(self, mesh: trimesh.Trimesh, name: str) -> None:
        """MeshError if the object lies beyond the arm's reach or around its base. A vertex
        within reach proves the first fine, and a base outside the bounding box the second,
        without the searches (a tree of the triangles, a ray test) that decide otherwise."""
        base = np.asarray(self.arm.base_position, dtype=float)
        v = np.asarray(mesh.vertices)
        nearest_vertex = float(np.sqrt(((v - base) ** 2).sum(axis=1).min()))
        if nearest_vertex > self.arm.length_max - 1e-9:
            closest = mesh.nearest.on_surface([base])[1][0]
            if closest > self.arm.length_max:
                raise MeshError(f"{name}: object lies beyond the arm's reach (nearest "
                                f"point {closest:.3f} m from the base; the arm is at most "
                                f"{self.arm.length_max:.3f} m long)")
        lo, hi = mesh.bounds
        inside_box = np.all(base > lo - 1e-9) and np.all(base < hi + 1e-9)
        if inside_box and mesh.contains([base])[0]:
            raise MeshError(f"{name}: the arm base lies inside the object")

    def _build(self, mesh: trimesh.Trimesh) -> None:
        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
        k = self.options.links_per_section
        self.link_length = self.arm.section_length_max / k
        self.n_links = self.arm.n_sections * k
        geometry = register_scene(plant, scene_graph, self.arm, object_shape(mesh),
                                  self.object_pose, self.options)
        self._bodies, arm_ids = geometry.bodies, geometry.arm_ids
        self.object_geometry = geometry.object_geometry
        self.table_geometry = geometry.table_geometry
        self._arm_ids = arm_ids

        self.visualizer = None
        if self.meshcat is not None:
            self.visualizer = MeshcatVisualizer.AddToBuilder(builder, scene_graph, self.meshcat)
        self.diagram = builder.Build()
        self.plant, self.scene_graph = plant, scene_graph
        self._context = self.diagram.CreateDefaultContext()
        self._stale = False  # whether the context's positions are not the posed arm's
        self._plant_context = plant.GetMyMutableContextFromRoot(self._context)
        self._sg_context = scene_graph.GetMyContextFromRoot(self._context)
        self._query_port = scene_graph.get_query_output_port()
        self._q_start = np.array([b.floating_positions_start() for b in self._bodies])
        self._q_index = self._q_start[:, None] + np.arange(7)[None, :]  # each capsule's q
        self._link_of_geometry = {gid: j for j, gid in enumerate(arm_ids)}
        self.table_active = self.table_geometry is not None
        self.set_table(False)
        self._q = np.zeros(plant.num_positions())
        # Capsules left out of a query are parked 100 m up, a metre apart (never near each
        # other, the object or the table): a parked capsule costs Drake nothing.
        self._park = np.zeros((self.n_links, 7))
        self._park[:, 0], self._park[:, 4], self._park[:, 6] = 1.0, np.arange(self.n_links), 100.0
        # A query's positions, selected from the posed and the parked (`_posed_only`): the
        # capsule each position belongs to (n_links: none, always posed).
        self._parked_q = self._q.copy()
        self._parked_q[self._q_index] = self._park
        self._owner_q = np.full(len(self._q), self.n_links)
        self._owner_q[self._q_index] = np.arange(self.n_links)[:, None]
        self._pose_key = np.dtype((np.void, 7 * self._q.itemsize))  # a capsule's 7 positions
        self.config = None
        self._self_arc = self._far_along_arm()
        self._forget()

    @property
    def context(self):
        """The diagram's context, showing the arm as posed (set_config). A query poses only
        the capsules it asks about (`_posed_only`), and posing waits for the next query,
        so the context's positions are set here when it is read between queries."""
        if self._stale:
            self.plant.SetPositions(self._plant_context, self._q)
            self._stale = False
        return self._context

    def set_table(self, active: bool) -> None:
        """Whether the table top takes part in contact queries. Off, the arm passes through
        it untested (a filter in this scene's context), so a wrap that ignores the table
        costs no more than one without it."""
        if active and self.table_geometry is None:
            raise ConfigError("a wrap with the table needs a scene built with one "
                              "(SceneOptions(table=True))")
        if self.table_geometry is None or active == self.table_active:
            return
        self._filter(self._arm_ids, self.table_geometry, allow=active)
        self.table_active = active
        self._forget()  # the answers kept were asked with the table in or out

    def _filter(self, capsules, geometry, allow: bool) -> None:
        """Allow or exclude contact between `capsules` and `geometry` in this scene's
        context (its queries change; the model does not)."""
        pair = (GeometrySet(list(capsules)), GeometrySet(geometry))
        declaration = CollisionFilterDeclaration()
        (declaration.AllowBetween if allow else declaration.ExcludeBetween)(*pair)
        self._apply(declaration)

    def _apply(self, declaration) -> None:
        self.scene_graph.collision_filter_manager(
            self.scene_graph.GetMyMutableContextFromRoot(self.context)).Apply(declaration)

    # ----------------------------------------------------------------- posing
    def link_arc_lengths(self, config: ArmConfig) -> np.ndarray:
        """(n_links,) arc length of each capsule's centre: spread evenly within each section,
        the first capsule's start on the section's start and the last's end on its end."""
        return _link_arcs(config, self.options.links_per_section, self.link_length)

    @property
    def posed_link_arcs(self) -> np.ndarray:
        """link_arc_lengths of the configuration the scene is posed at (set_config)."""
        self._require_pose("posed_link_arcs")
        return self._link_arc

    def _require_pose(self, what: str) -> None:
        """Refuse a question about the posed arm before set_config: every capsule would
        sit at the origin, and its answers would be about no configuration at all."""
        if self.config is None:
            raise RuntimeError(f"WrapScene {what} query before any configuration is posed: "
                               f"call set_config(config) first")

    def set_config(self, config: ArmConfig) -> None:
        """Pose every capsule on the arc of `config` (after checking the arm's limits)."""
        t0 = time.thread_time()
        self.arm.check(config)
        arc, bb, poses = capsule_poses(self.arm, config, self.options.links_per_section,
                                       self.link_length)
        self._q[self._q_index] = poses
        self._stale = True  # set by the next query's own positions, or by `context`
        self._link_pose = poses.view(self._pose_key).ravel().tolist()  # a capsule's key: bytes
        self._posed = None  # this pose's answers, looked up when first asked (`_answers`)
        self.config = config
        self._link_arc = arc
        self._link_frame = (bb.position, bb.tangent, bb.normal)
        self.timing["pose"] += time.thread_time() - t0

    # ----------------------------------------------------------------- queries
    def _forget(self) -> None:
        """Drop every capsule's kept contact surfaces (the object or the table changed)."""
        # per capsule: its pose -> (surfaces, touches the object, touches the table)
        self._kept = [{} for _ in range(self.n_links)]
        self._link_pose = [b""] * self.n_links
        self._posed = None
        self._summaries = {}  # contact surface -> its summary (contact_regions' `kept`)

    def _surfaces(self, first: int = 0) -> list:
        """Contact surfaces of the capsules from `first` on, in the current configuration."""
        kept = self._answers(first)
        return [s for answer in kept for s in answer[0]]

    def _answers(self, first: int = 0) -> list:
        """Each capsule's answer from `first` on in the current configuration: (its contact
        surfaces, whether one pairs it with the object, whether one with the table).

        A capsule's contact surfaces depend on its own pose only, so each capsule keeps
        those it had at its last few poses: capsules that did not move since they were asked
        about (the sections before the one curving; a configuration posed again, as the
        bisection's last contact step is when enclosing ends) are not asked again, and a
        Drake query is built only from the first capsule without a kept answer on. The
        answers are Drake's own; nothing is predicted.
        """
        self._require_pose("contact")
        keep, pose, first = self._kept, self._link_pose, max(int(first), 0)
        if self._posed is None:  # once a pose: each capsule's kept answer, or None
            self._posed = list(map(dict.get, keep, pose))
        posed = self._posed
        if None in posed[first:]:
            missing = posed.index(None, first)
            found = {}
            for s in self._query_surfaces(missing):
                j = self._capsule_of(s)
                surfaces, on_object, on_table = found.get(j, _NO_CONTACT)
                pair = (s.id_M(), s.id_N())
                found[j] = (surfaces + (s,), on_object or self.object_geometry in pair,
                            on_table or self.table_geometry in pair)
            answers = [_NO_CONTACT] * (self.n_links - missing)
            for j, answer in found.items():
                if j >= missing:  # (earlier capsules are parked: none pairs)
                    answers[j - missing] = answer
            for kept, key, answer in zip(keep[missing:], pose[missing:], answers):
                if len(kept) >= 8:  # a capsule's poses of the last few steps suffice
                    kept.clear()
                kept[key] = answer
            posed[missing:] = answers
        return posed[first:]

    def _query_surfaces(self, first: int) -> list:
        """One contact query of the current configuration: Drake's contact surfaces of the
        capsules from `first` on not proven apart (`SceneOptions.hull_prefilter`)."""
        self.n_queries += 1
        t0 = time.thread_time()
        asked = self._not_apart(first)
        t1 = time.thread_time()
        self.timing["prefilter"] += t1 - t0
        if asked is None:
            return []
        self.n_contact_surfaces += 1
        surfaces = self._posed_only(asked).ComputeContactSurfaces(
            HydroelasticContactRepresentation.kPolygon)
        self.timing["contact_surfaces"] += time.thread_time() - t1
        return surfaces

    def _not_apart(self, first: int) -> np.ndarray | None:
        """(n_links,) the capsules from `first` on a query asks about, or None when every
        one of them is proven apart from the object."""
        if not self.options.hull_prefilter:
            return np.arange(self.n_links) >= first
        if self.table_active:  # Drake's own test, the table's and the hull's
            asked = np.arange(self.n_links) >= first
            return asked if self._posed_only(asked).ComputePointPairPenetration() else None
        if self._apart is None:
            self._apart = ApartTest(self.object_trimesh, self.n_links, reach=self.arm.radius,
                                    half=self.link_length / 2)
        position, tangent, _ = self._link_frame
        asked = self._apart.near(position, tangent, first)
        return asked if asked.any() else None

    def _posed_only(self, asked: np.ndarray):
        """Drake's query object with the capsules `asked` posed and the others parked."""
        q = np.where(np.append(asked, True)[self._owner_q], self._q, self._parked_q)
        self.plant.SetPositions(self._plant_context, q)
        self._stale = True  # (the whole arm's positions are set when `context` is read)
        return self._query_port.Eval(self._sg_context)

    def touching_links(self, first: int = 0) -> np.ndarray:
        """Sorted indices of the capsules touching the object: the cheap question the
        enclosing loop asks at every step (no contact geometry is built). Capsule j lies on
        section j // links_per_section.

        Args:
            first: ask only about the capsules from this one on. Curving a section moves
                none of the capsules before it, so the enclosing loop leaves out those whose
                touches cannot change its answer.
        """
        return self._links_touching(self.object_geometry, first)

    def _links_touching(self, geometry, first: int = 0) -> np.ndarray:
        """Sorted indices of the capsules from `first` on whose contact surfaces pair them
        with `geometry`."""
        which = 1 if geometry == self.object_geometry else 2
        first = max(int(first), 0)
        answers = self._answers(first)
        return np.flatnonzero(np.fromiter(map(itemgetter(which), answers), bool,
                                          len(answers))) + first

    def _capsule_of(self, surface) -> int:
        """The capsule of a contact surface: every surface pairs one capsule with the object
        or the table (capsules never touch each other: they are filtered)."""
        link = self._link_of_geometry
        return link[surface.id_M()] if surface.id_M() in link else link[surface.id_N()]

    def self_touching(self, config: ArmConfig, first: int = 0) -> bool:
        """Whether the tube of `config` touches itself: two capsules, one of them from
        `first` on, far enough apart along the arm that they cannot overlap as neighbours,
        whose axes come closer than a diameter.

        A wrap that turns a full circle runs into its own first section (without this
        test, 226 of the seed-0 collection's 1,233 wraps end a median 18.4 mm inside it).
        Capsules are convex, so their distance has a closed form, exact for the capsules
        Drake holds (the convex-hull trap is the object's). Drake's arm-arm
        hydroelastic contact would answer the same question, but a capsule's kept surfaces
        would then depend on other capsules' poses too, and every query would pay for the
        compliant pairs.
        """
        if config is self.config:  # posed: the capsules are placed already
            (position, tangent, _), arc = self._link_frame, self._link_arc
        else:
            arc = self.link_arc_lengths(config)
            bb = self.arm.backbone(config, arc)
            position, tangent = bb.position, bb.tangent
        return bool(far_segments_within(position, tangent, arc, int(first),
                                        self.link_length / 2, self._self_arc,
                                        2 * self.arm.radius))

    def _far_along_arm(self) -> float:
        """Centre spacing along the arm beyond which two capsules can touch only by the arm
        coming round: at the curvature limit, capsule axes (chords, a sagitta l^2 kappa / 8
        inside the arc) whose nearest points lie d apart along the arm are
        2 sin(kappa d / 2) / kappa apart, more than a diameter beyond the d solved here.
        The arm's limits and capsules are the scene's own (a wrap swaps only its base), so
        it is worked out once, when the scene is built."""
        kappa = self.arm.curvature_max
        reach = kappa * (self.arm.radius + self.link_length ** 2 * kappa / 8)
        d = np.pi / kappa if reach >= 1.0 else 2.0 * np.arcsin(reach) / kappa
        return d + self.link_length + 1e-3

    def in_contact(self) -> bool:
        """Whether any capsule touches the object's real (non-convex) surface."""
        return len(self.touching_links()) > 0

    def _is_object_pair(self, surface) -> bool:
        return self.object_geometry in (surface.id_M(), surface.id_N())

    def touching_table(self, first: int = 0) -> np.ndarray:
        """Sorted indices of the capsules from `first` on touching the table top (none
        without a table, or while it takes no part: `set_table`)."""
        if not self.table_active:
            return np.zeros(0, int)
        return self._links_touching(self.table_geometry, first)

    def touching_depths(self, links) -> np.ndarray:
        """How deep the object's surface reaches into each of the capsules `links`, m (0
        for one that does not touch it).

        Read from Drake's contact surface: a compliant capsule's pressure rises linearly
        from 0 on its surface to the modulus E on its centre line, so a point of the rigid
        surface under pressure p lies radius * p / E inside the tube (exact; a test checks it
        against a box at known depths). Only the capsules asked about are read: reading a
        surface's field costs a Python call a vertex.
        """
        wanted = {int(j): 0.0 for j in np.asarray(links, int)}
        first = min(wanted, default=self.n_links)
        answers = self._answers(first)
        for link in wanted:
            for s in answers[link - first][0]:
                if self._is_object_pair(s):
                    field, n = s.poly_e_MN(), s.poly_mesh_W().num_vertices()
                    wanted[link] = max(wanted[link], *map(field.EvaluateAtVertex, range(n)))
        scale = self.arm.radius / self.options.hydroelastic_modulus
        return np.array([wanted[int(j)] * scale for j in np.asarray(links, int)])

    def contacts(self) -> Contacts:
        """The contact regions of the current configuration.

        Capsules touching the object in an unbroken run form one region, as a tactile skin
        would report it, split where the run's normal has turned by more than
        REGION_TURN_MAX (a long run hugging a curved body is several contacts). Per region: p
        is the area-weighted centroid of its contact polygons, n their area-weighted normal
        turned to point from the object into the arm (Drake's face normals point out of N into
        M), t the arm's tangent there with its normal component removed, b = n x t.
        """
        if len(self._summaries) > 1024:  # (a capsule keeps the surfaces of a few poses)
            self._summaries.clear()
        return contact_regions(self._surfaces(), self.object_geometry, self._capsule_of,
                               config=self.config, arcs=self._link_arc, frames=self._link_frame,
                               k=self.options.links_per_section, kept=self._summaries)

    # ----------------------------------------------------------------- distances
    def _distances(self) -> SurfaceDistance:
        if self._sdf is None:
            self._sdf = SurfaceDistance(self.object_trimesh)
        return self._sdf

    def signed_distance(self, points, table: bool = False) -> np.ndarray:
        """SurfaceDistance.signed_distance to this scene's object."""
        return self._distances().signed_distance(points, table)

    def distance_bound(self, points, at_least, *, hint, table: bool = False) -> np.ndarray:
        """SurfaceDistance.lower_bound of this scene's object."""
        return self._distances().lower_bound(points, at_least, hint=hint, table=table)

    def distance_field(self, points, table: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """SurfaceDistance.distance_field of this scene's object."""
        return self._distances().distance_field(points, table)

    def field(self, table: bool = False) -> DistanceField:
        """The object's DistanceField, with the table top or not (a wrap's IK asks it)."""
        return DistanceField(self._distances(), table)

    def clearance(self, config: ArmConfig, n: int = 200) -> np.ndarray:
        """SurfaceDistance.clearance of this scene's arm at `config` from its object."""
        return self._distances().clearance(self.arm, config, n)


# ----------------------------------------------------------------- shared with the station
@dataclass(frozen=True)
class SceneGeometry:
    """What `register_scene` registered: the capsules' bodies and geometry ids (capsule j on
    section j // links_per_section), the object's and the table's (None without) ids."""

    bodies: list
    arm_ids: list
    object_geometry: object
    table_geometry: object


def object_shape(mesh: trimesh.Trimesh, normals: bool = False) -> Mesh:
    """The object as Drake's rigid hydroelastic mesh (an in-memory OBJ); a renderer (VTK)
    needs its vertex `normals`."""
    obj_data = trimesh.exchange.obj.export_obj(mesh, include_normals=normals,
                                               include_texture=False)
    return Mesh(InMemoryMesh(mesh_file=MemoryFile(obj_data, ".obj", "object.obj")))


def register_scene(plant, scene_graph, arm: ContinuumArm, shape: Mesh,
                   X_WO: RigidTransform, options: SceneOptions,
                   visual: Mesh | None = None) -> SceneGeometry:
    """Register the arm's compliant capsules (free bodies, filtered against each other), the
    rigid object posed at X_WO and, with options.table, the table's rigid top under z = 0
    (collision only: its contact is a wrap's obstacle) in `plant`, and finalize it. `plant`
    must be registered with `scene_graph`. The object is drawn as `visual` (default:
    `shape`). Visual geometry carries Drake's default
    illustration and perception roles, so a Meshcat or an RgbdSensor sees the arm and the
    object."""
    k = options.links_per_section
    link_length = arm.section_length_max / k
    arm_props = ProximityProperties()
    AddCompliantHydroelasticProperties(options.resolution_hint, options.hydroelastic_modulus,
                                       arm_props)
    capsule = Capsule(arm.radius, link_length)
    inertia = SpatialInertia.SolidCapsuleWithDensity(1000.0, arm.radius, link_length,
                                                     [0, 0, 1])
    # Drawn, the arm's first and last links are cylinders: the tube ends flat at its base
    # and tip, where a capsule's cap would reach a radius beyond them (a camera would see the
    # arm 1 cm longer).
    ends = Cylinder(arm.radius, link_length)
    n_links = arm.n_sections * k
    bodies, arm_ids = [], []
    for j in range(n_links):
        body = plant.AddRigidBody(f"link{j}", inertia)
        arm_ids.append(plant.RegisterCollisionGeometry(body, RigidTransform(), capsule,
                                                       f"link{j}", arm_props))
        plant.RegisterVisualGeometry(body, RigidTransform(),
                                     ends if j in (0, n_links - 1) else capsule,
                                     f"link{j}_visual", np.array([*ARM_COLOUR, 1.0]))
        bodies.append(body)
    obj_props = ProximityProperties()
    AddRigidHydroelasticProperties(obj_props)
    world = plant.world_body()
    object_geometry = plant.RegisterCollisionGeometry(world, X_WO, shape, "object", obj_props)
    plant.RegisterVisualGeometry(world, X_WO, shape if visual is None else visual,
                                 "object_visual", OBJECT_COLOR)
    table_geometry = None
    if options.table:
        table_props = ProximityProperties()
        AddRigidHydroelasticProperties(table_props)
        table_geometry = plant.RegisterCollisionGeometry(
            world, RigidTransform([0, 0, -0.025]), Box(1.5, 1.5, 0.05), "table", table_props)
    plant.Finalize()
    scene_graph.collision_filter_manager().Apply(
        CollisionFilterDeclaration().ExcludeWithin(GeometrySet(arm_ids)))
    return SceneGeometry(bodies, arm_ids, object_geometry, table_geometry)


def _link_arcs(config: ArmConfig, k: int, link_length: float) -> np.ndarray:
    """WrapScene.link_arc_lengths for k capsules a section of `link_length`."""
    half = link_length / 2
    starts = np.concatenate([[0.0], np.cumsum(config.s)[:-1]])
    u = _spread(k)
    return (starts[:, None] + half + u * (config.s[:, None] - 2 * half)).ravel()


@cache
def _spread(k: int) -> np.ndarray:
    """(1, k) positions of k capsules within a section, 0 to 1 (made once, read-only)."""
    u = np.linspace(0.0, 1.0, k)[None, :]
    u.flags.writeable = False
    return u


def capsule_poses(arm: ContinuumArm, config: ArmConfig, k: int, link_length: float):
    """(arc (n_links,), backbone samples at the capsules' centres, poses (n_links, 7) as a
    free body's positions [qw, qx, qy, qz, x, y, z]): each capsule's axis along the arc's
    tangent at its centre (`WrapScene.link_arc_lengths`)."""
    arc, *frames, poses = capsule_frames(arm.base_rotation, arm.base_position, config.s,
                                         config.kappa, config.phi, _spread(k)[0],
                                         link_length / 2)
    return arc, BackboneSamples(arc, *frames), poses
