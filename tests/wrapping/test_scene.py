"""The contact scene against closed forms: an analytic cylinder contact, a sphere touching
one section only, a mug's handle hole and cavity (where the convex-hull trap would report
contact), and clear errors for bad meshes and configurations."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig, ArmLimitError, load_arm
from drake_continuum.objects.mesh import MeshError
from drake_continuum.wrapping.scene import WrapScene

STRAIGHT = ArmConfig.straight([0.1, 0.1, 0.1])  # along +x from (-0.18, 0, 0.05) to x = 0.12


def _rx(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _angle_deg(u, v):
    u, v = np.asarray(u, float), np.asarray(v, float)
    return np.degrees(np.arccos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v), -1, 1)))


@pytest.fixture(scope="module")
def arm():
    return load_arm()


@pytest.fixture(scope="module")
def mug():
    """The shipped mug and its measured features (handle hole, cavity)."""
    return MODELS_DIR / "mug.obj", json.loads((MODELS_DIR / "mug.json").read_text())


# ----------------------------------------------------------------- distances
def test_distance_field_equals_signed_distance_and_its_gradient(arm, mug):
    """The closest-point field gives the same signed distance as Open3D's own query, and a
    gradient equal to central differences of it (away from the medial axis)."""
    scene = WrapScene(arm, mug[0])
    m = scene.object_trimesh
    rng = np.random.default_rng(0)
    p = m.bounds[0] - 0.02 + rng.random((3000, 3)) * (m.bounds[1] - m.bounds[0] + 0.04)
    d, grad = scene.distance_field(p)
    np.testing.assert_allclose(d, scene.signed_distance(p), atol=1e-6)
    assert np.mean(d < 0) > 0.05  # points inside are in the sample
    h = 1e-4
    fd = np.stack([(scene.signed_distance(p + h * e) - scene.signed_distance(p - h * e)) / (2 * h)
                   for e in np.eye(3)], axis=1)
    agree = np.linalg.norm(fd - grad, axis=1) < 1e-2
    assert agree.mean() > 0.97  # the rest lie within h of a crease of the distance field
    np.testing.assert_allclose(np.linalg.norm(grad, axis=1), 1.0, atol=1e-6)


def test_hull_prefilter_never_changes_the_answer(arm, mug):
    """The capsules proven apart (the hull, then the triangles) only leave out queries, and
    capsules in a query, that would find no contact: random curls around the mug (through
    its handle and cavity too) give the same touching capsules and the same contact
    regions, to the bit, with the prefilter and without it."""
    from drake_continuum.wrapping.contact import FIELDS
    from drake_continuum.wrapping.scene import SceneOptions
    fast = WrapScene(arm, mug[0])
    full = WrapScene(arm, mug[0], options=SceneOptions(hull_prefilter=False))
    rng = np.random.default_rng(1)
    skipped = touching = left_out = in_hull_apart = 0
    for _ in range(150):
        s = rng.uniform(0.1, 0.3, 3)
        config = ArmConfig(s, rng.uniform(0, 1, 3) * arm.curvature_limit(s),
                           rng.normal(0, 0.3, 3))
        fast.set_config(config)
        full.set_config(config)
        a, b = fast.touching_links(), full.touching_links()
        np.testing.assert_array_equal(a, b)
        mine, theirs = fast.contacts(), full.contacts()
        for field in FIELDS:
            np.testing.assert_array_equal(getattr(mine, field), getattr(theirs, field))
        touching += len(a) > 0
        asked = fast._not_apart(0)
        n_asked = 0 if asked is None else int(asked.sum())
        skipped += n_asked == 0
        left_out += 0 < n_asked < fast.n_links
        whole = fast.scene_graph.GetMyContextFromRoot(fast.context)  # the whole arm posed
        in_hull = len(fast._query_port.Eval(whole).ComputePointPairPenetration())
        in_hull_apart += n_asked < in_hull  # in the hull, proven apart by the triangles
    # every kind of configuration was tried: no capsule asked, some, and touching ones
    assert touching > 20 and skipped > 20 and left_out > 20 and in_hull_apart > 20


def test_the_context_shows_the_posed_arm_between_queries(arm, mug):
    """A query poses only the capsules it asks about, and posing waits for the next query;
    read between queries, the scene's context holds every capsule on the arc of the last
    configuration posed (its centre and axis from the arm's backbone), and its contact
    regions' binormals are n x t (numpy.cross)."""
    scene = WrapScene(arm, mug[0])
    rng = np.random.default_rng(5)
    k, touched = scene.options.links_per_section, 0
    for trial in range(12):
        s = rng.uniform(0.1, 0.3, 3)
        config = ArmConfig(s, rng.uniform(0, 1, 3) * arm.curvature_limit(s),
                           rng.normal(0, 0.3, 3))
        scene.set_config(config)
        scene.touching_links(first=(trial % 3) * k)  # some capsules left out, or parked
        contacts = scene.contacts()
        touched += len(contacts) > 0
        np.testing.assert_array_equal(contacts.b, np.cross(contacts.n, contacts.t))
        bb = arm.backbone(config, scene.link_arc_lengths(config))
        plant_context = scene.plant.GetMyContextFromRoot(scene.context)
        for j in range(0, scene.n_links, 7):
            X = scene.plant.EvalBodyPoseInWorld(plant_context, scene._bodies[j])
            np.testing.assert_allclose(X.translation(), bb.position[j], atol=1e-12)
            np.testing.assert_allclose(X.rotation().matrix()[:, 2], bb.tangent[j], atol=1e-9)
    assert touched >= 3


def test_kept_surfaces_are_what_a_fresh_query_finds(arm, mug):
    """Each capsule keeps its contact surfaces by its pose: curving the later sections of a
    configuration, or posing one again, gives what a scene asked afresh every time finds
    (the same touching capsules and contact regions) with fewer Drake queries; turning the
    table on asks again."""
    kept, fresh = WrapScene(arm, mug[0]), WrapScene(arm, mug[0])
    rng = np.random.default_rng(3)
    k = kept.options.links_per_section
    touching = 0
    for _ in range(30):
        s = rng.uniform(0.1, 0.3, 3)
        base = ArmConfig(s, rng.uniform(0, 1, 3) * arm.curvature_limit(s), rng.normal(0, 0.3, 3))
        sequence = [base]
        for _ in range(3):  # section 3, then sections 2 and 3, curve on
            kappa = sequence[-1].kappa.copy()
            kappa[-2:] = np.minimum(kappa[-2:] + rng.uniform(0, 4, 2), arm.curvature_limit(s[-2:]))
            sequence.append(ArmConfig(s, kappa, base.phi))
        for config, first in [*zip(sequence, (0, 2 * k - 1, k - 1, k - 1)), (base, 0)]:
            kept.set_config(config)
            fresh.set_config(config)
            fresh._forget()
            a, b = kept.touching_links(first), fresh.touching_links(first)
            np.testing.assert_array_equal(a, b)
            ca, cb = kept.contacts(), fresh.contacts()
            np.testing.assert_array_equal(ca.p, cb.p)
            np.testing.assert_array_equal(ca.n, cb.n)
            touching += len(a) > 0
    assert touching > 20
    assert kept.n_queries < 0.7 * fresh.n_queries
    down = ArmConfig([0.2, 0.1, 0.1], [8.0, 0.0, 0.0], [0.0, 0.0, 0.0])  # bends into the table
    for scene in (kept, fresh):
        scene.set_config(down)
        scene.touching_links()
        scene.set_table(True)
    assert len(kept.touching_table()) > 0
    np.testing.assert_array_equal(kept.touching_table(), fresh.touching_table())


# ----------------------------------------------------------------- analytic contacts
@pytest.mark.parametrize("penetration", [0.0005, 0.0015])
def test_cylinder_contact_matches_closed_form(arm, penetration):
    """A vertical cylinder of radius R beside the straight arm: the contact lies on the line
    joining the two axes, on the cylinder's surface, with the normal from the cylinder's
    axis to the arm's axis."""
    R, x0 = 0.03, -0.03  # axis beside arc length 0.15 (the middle of section 2)
    d = R + arm.radius - penetration  # axis-to-axis distance
    cylinder = trimesh.creation.cylinder(radius=R, height=0.10, sections=256)
    cylinder.apply_translation([x0, d, 0.05])
    scene = WrapScene(arm, cylinder)
    scene.set_config(STRAIGHT)
    c = scene.contacts()
    assert len(c) == 1
    expected = np.array([x0, d - R, 0.05])
    tol = 0.001 + penetration  # the patch is a curved strip of width ~ sqrt(8 R pen)
    assert np.linalg.norm(c.p[0] - expected) < tol, (c.p[0], expected)
    assert _angle_deg(c.n[0], [0, -1, 0]) < 3.0
    assert c.section[0] == 1
    assert c.arc_length[0] == pytest.approx(x0 - arm.base_position[0], abs=0.002)
    assert _angle_deg(c.t[0], [1, 0, 0]) < 3.0
    np.testing.assert_allclose(c.b[0], np.cross(c.n[0], c.t[0]), atol=1e-12)


@pytest.mark.parametrize("depth", [0.0003, 0.001, 0.003])
def test_touching_depth_is_how_far_the_surface_reaches_into_the_tube(arm, depth):
    """A box whose top reaches `depth` into the straight arm's tube from below: every
    touching capsule reports that depth (from Drake's pressure, radius * p / E)."""
    box = trimesh.creation.box([0.1, 0.1, 0.05])
    box.apply_translation([0.0, 0.0, 0.05 - arm.radius + depth - 0.025])
    scene = WrapScene(arm, box)
    scene.set_config(STRAIGHT)
    links = scene.touching_links()
    depths = scene.touching_depths(links)
    assert len(links) >= 10
    inner = (scene.link_arc_lengths(STRAIGHT)[links] > 0.13 + 0.02) & (
        scene.link_arc_lengths(STRAIGHT)[links] < 0.23 - 0.02)  # away from the box's edges
    np.testing.assert_allclose(depths[inner], depth, rtol=1e-6)
    assert np.all(depths <= depth + 1e-9)
    # A capsule that does not touch reports no depth.
    assert scene.touching_depths([scene.n_links - 1]).tolist() == [0.0]


def test_no_contact_just_outside_cylinder(arm):
    cylinder = trimesh.creation.cylinder(radius=0.03, height=0.10, sections=256)
    cylinder.apply_translation([-0.03, 0.03 + arm.radius + 0.002, 0.05])  # 2 mm gap
    scene = WrapScene(arm, cylinder)
    scene.set_config(STRAIGHT)
    assert not scene.in_contact()
    assert len(scene.contacts()) == 0


def test_only_the_touched_section_is_reported(arm):
    """A sphere touching a bent, twisted arm at the middle of section 2 only."""
    config = ArmConfig([0.12, 0.15, 0.12], [5.0, 10.0, 20.0], [0.0, 1.0, 2.0])
    arc = 0.12 + 0.075
    bb = arm.backbone(config, [arc])
    radius, penetration = 0.02, 0.0008
    centre = bb.position[0] + bb.normal[0] * (radius + arm.radius - penetration)
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=radius)
    sphere.apply_translation(centre)
    scene = WrapScene(arm, sphere)
    scene.set_config(config)
    c = scene.contacts()
    assert len(c) == 1
    assert c.section.tolist() == [1]
    assert c.arc_length[0] == pytest.approx(arc, abs=0.002)
    # Normal from the object into the arm: from the sphere's centre towards the arm's axis.
    assert _angle_deg(c.n[0], bb.position[0] - centre) < 3.0
    assert np.linalg.norm(c.p[0] - (bb.position[0] + bb.normal[0] * arm.radius)) < 0.002


def test_normals_point_from_object_into_arm_on_a_mug_wrap(arm, mug):
    """Every contact of a curl around the mug body: the arm's axis lies on the normal's side,
    and stepping from p against the normal goes into the object."""
    path, _ = mug
    config = ArmConfig([0.1402, 0.1373, 0.1373], [4.408, 19.42, 19.42],
                       [-np.pi / 2, np.pi / 2, np.pi / 2])
    scene = WrapScene(arm, path)
    scene.set_config(config)
    c = scene.contacts()
    assert len(c) >= 1
    axis = arm.backbone(config, c.arc_length).position
    assert np.all(np.einsum("mi,mi->m", axis - c.p, c.n) > 0.5 * arm.radius)
    assert np.all(scene.signed_distance(c.p - 0.002 * c.n) < 0)
    assert np.all(scene.signed_distance(c.p + 0.002 * c.n) > 0)


# ----------------------------------------------------------------- the convex-hull trap
def _hull_query_reports_contact(scene: WrapScene) -> bool:
    """What Drake's point-contact queries say: they see the object's convex hull."""
    query = scene._query_port.Eval(scene._sg_context)
    return query.HasCollisions() and len(query.ComputePointPairPenetration()) > 0


def test_link_through_the_mug_handle_hole_touches_nothing(arm, mug):
    path, info = mug
    hx, hy, hz = info["handle_hole_center"]
    # The hole lies in the y = 0 plane: thread the straight arm through it along +y.
    threaded = arm.with_base(position=[hx, hy - 0.15, hz], rotation=_rx(-np.pi / 2))
    scene = WrapScene(threaded, path)
    scene.set_config(STRAIGHT)
    assert scene.clearance(STRAIGHT).min() > 0.001  # the real surface is clear of the tube
    hull = scene.object_trimesh.convex_hull
    assert hull.contains(threaded.backbone(STRAIGHT, n=60).position).any()  # through the hole
    assert not scene.in_contact()
    assert len(scene.contacts()) == 0
    assert _hull_query_reports_contact(scene), "the convex hull should have reported contact"


def test_link_inside_the_mug_cavity_touches_nothing(arm, mug):
    path, info = mug
    cx, cy = info["cavity_axis_xy"]
    # Straight down the cavity axis; the tip stops 2 cm above the floor.
    lowered = arm.with_base(position=[cx, cy, info["cavity_floor_z"] + arm.radius + 0.31],
                            rotation=_rx(np.pi))
    scene = WrapScene(lowered, path)
    scene.set_config(STRAIGHT)
    assert lowered.tip_frame(STRAIGHT)[1][2] < info["rim_z"] - 0.05  # deep inside the cup
    assert scene.clearance(STRAIGHT).min() > 0.005
    assert not scene.in_contact()
    assert len(scene.contacts()) == 0
    assert _hull_query_reports_contact(scene), "the convex hull should have reported contact"


# ----------------------------------------------------------------- bad input
def _write(path, text):
    path.write_text(text)
    return path


def _open_box_obj(path):
    box = trimesh.creation.box([0.05, 0.05, 0.05])
    box.update_faces(np.arange(len(box.faces)) != 0)  # one triangle missing: a hole
    box.export(path)
    return path


@pytest.mark.parametrize("make, problem", [
    (lambda d: d / "missing.obj", "not found"),
    (lambda d: _write(d / "empty.obj", ""), "empty"),
    (lambda d: _open_box_obj(d / "open.obj"), "not a closed surface"),
    (lambda d: _write(d / "nan.obj", "v 0 0 0\nv 1 0 0\nv 0 nan 0\nv 0 0 1\n"
                      "f 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n"), "NaN"),
])
def test_bad_mesh_files_name_file_and_problem(arm, tmp_path, make, problem):
    path = make(tmp_path)
    with pytest.raises(MeshError) as err:
        WrapScene(arm, path)
    assert str(path) in str(err.value) and problem in str(err.value)


def test_object_beyond_reach_is_rejected(arm, tmp_path):
    path = tmp_path / "far.obj"
    far = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    far.apply_translation([2.0, 0.0, 0.05])
    far.export(path)
    with pytest.raises(MeshError) as err:
        WrapScene(arm, path)
    assert str(path) in str(err.value) and "beyond the arm's reach" in str(err.value)


def test_replaced_object_wraps_as_in_a_scene_built_for_it(arm, mug, tmp_path):
    # A collection swaps each object into one scene (replace_object); every answer must
    # be the one a scene built for that object gives: contacts, distances and whole wraps.
    from drake_continuum.wrapping.planes import enumerate_planes
    from drake_continuum.wrapping.wrap import wrap
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.04)
    ball.apply_translation([0.0, 0.0, 0.05])
    shared = WrapScene(arm, mug[0])
    shared.replace_object(ball)
    fresh = WrapScene(arm, ball)
    planes = enumerate_planes(arm.base_position)
    for plane in (planes[0], planes[7]):
        a, b = wrap(fresh, plane), wrap(shared, plane)
        assert a.status == b.status and np.array_equal(a.configs, b.configs)
        assert np.array_equal(a.samples_position, b.samples_position)
    probe = np.array([[0.0, 0.0, 0.05], [0.0, 0.0, 0.1], [0.05, 0.02, 0.05]])
    assert np.allclose(shared.signed_distance(probe), [-0.04, 0.01, np.hypot(0.05, 0.02) - 0.04],
                       atol=1e-3)
    # A refused object changes nothing: the ball is still the one touched.
    far = ball.copy()
    far.apply_translation([2.0, 0.0, 0.0])
    with pytest.raises(MeshError, match="beyond the arm's reach"):
        shared.replace_object(far)
    shared.set_config(ArmConfig.straight([0.1, 0.1, 0.1]))
    fresh.set_config(ArmConfig.straight([0.1, 0.1, 0.1]))
    assert np.array_equal(shared.touching_links(), fresh.touching_links())
    assert len(shared.touching_links()) > 0  # the straight arm runs through the ball


@pytest.mark.parametrize("config, words", [
    (ArmConfig([0.5, 0.2, 0.2], [0, 0, 0], [0, 0, 0]), ["section 1", "length", "0.4"]),
    (ArmConfig([0.2, 0.05, 0.2], [0, 0, 0], [0, 0, 0]), ["section 2", "length", "0.1"]),
    (ArmConfig([0.2, 0.2, 0.2], [0, 0, 55.0], [0, 0, 0]), ["section 3", "curvature", "40"]),
    (ArmConfig([0.2, 0.2, 0.2], [-1.0, 0, 0], [0, 0, 0]), ["section 1", "curvature"]),
])
def test_config_outside_limits_names_section_and_limit(arm, config, words):
    cylinder = trimesh.creation.cylinder(radius=0.03, height=0.1)
    scene = WrapScene(arm, cylinder)
    with pytest.raises(ArmLimitError) as err:
        scene.set_config(config)
    assert all(w in str(err.value) for w in words), str(err.value)


@pytest.mark.parametrize("gap_off, touching", [(-4e-3, True), (4e-3, False)])
def test_self_touching_when_a_circle_comes_back_to_the_straight_section(arm, gap_off,
                                                                        touching):
    """Sections 2 and 3 bend one circle of radius rho from the end of straight section 1.
    Stopping the circle an angle g short of closing leaves its tip rho (1 - cos g) from the
    line of section 1 (the nearest part of the arm that far along it): the tube touches
    itself iff that is below a diameter. The capsules' axes are tangents at their centres,
    within (l/2)^2 kappa / 2 = 1 mm of the arc: +-4 mm either side of the diameter."""
    scene = WrapScene(arm, trimesh.creation.icosphere(radius=0.02))  # the object is moot
    rho = 0.05
    g = np.arccos(1.0 - (2 * arm.radius + gap_off) / rho)
    half = (2 * np.pi - g) * rho / 2
    config = ArmConfig(np.array([0.2, half, half]), np.array([0.0, 1 / rho, 1 / rho]),
                       np.zeros(3))
    assert scene.self_touching(config) is touching
    # A point anywhere on the arm is a candidate, so asking from section 3 on finds it too;
    # asking from beyond the tip finds nothing.
    assert scene.self_touching(config, first=2 * scene.options.links_per_section) is touching
    assert scene.self_touching(config, first=scene.n_links) is False
    straight = ArmConfig(np.array([0.2, half, half]), np.zeros(3), np.zeros(3))
    assert scene.self_touching(straight) is False
