"""Touch-driven wrapping (Algorithm 1): fast against reference enclosing, statuses, depth of
penetration, the stop rule, and the analytic cylinder."""

import numpy as np
import pytest
import trimesh

from drake_continuum.errors import ConfigError
from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig, load_arm
from drake_continuum.kinematics.ik import IKOptions
from drake_continuum.objects.generators import generate_object
from drake_continuum.objects.mesh import MeshError
from drake_continuum.wrapping.contact import REGION_TURN_MAX
from drake_continuum.wrapping.planes import enumerate_planes, make_plane
from drake_continuum.wrapping.scene import WrapScene
from drake_continuum.wrapping.wrap import WrapParams, wrap
from drake_continuum.wrapping.wrap_types import STATUSES
from unchecked import unchecked

# Fast and reference enclosing take the same steps wherever contact, once made, persists as
# a section curves on (the fast path brackets and bisects the first contact step). Where a
# contact at a section's joint flickers on and off within hundredths of a millimetre, the
# reference stops at the flicker and bisection may not; on the cases below they agree
# exactly, and the stated tolerance is half an advancing step.
SAME_TOL = 5e-4  # m, on final centre-line points and contact positions
NORMAL_TOL = np.radians(3.0)
MAX_PENETRATION = 2.5e-3  # m, deepest the tube may sink into the object along a wrap


@pytest.fixture(scope="module")
def arm():
    return load_arm()


@pytest.fixture(scope="module")
def planes(arm):
    return enumerate_planes(arm.base_position)


_scenes, _wraps = {}, {}


def scene_of(arm, name):
    if name not in _scenes:
        if name == "mug":
            mesh = MODELS_DIR / "mug.obj"
        else:
            category, index = name.rsplit("_", 1)
            mesh = generate_object(category, int(index), seed=0).mesh
        _scenes[name] = WrapScene(arm, mesh)
    return _scenes[name]


def wrap_of(arm, planes, name, k, method):
    """Each wrap once a test session: later tests reuse it."""
    key = (name, k, method)
    if key not in _wraps:
        _wraps[key] = wrap(scene_of(arm, name), planes[k], WrapParams(method=method))
    return _wraps[key]


def centre_line(arm, result, config=None, n=400):
    config = result.final_config if config is None else config
    return arm.with_base(rotation=result.base_rotation).backbone(config, n=n).position


def assert_same_wrap(arm, fast, ref):
    assert fast.status == ref.status
    np.testing.assert_allclose(fast.base_rotation, ref.base_rotation)
    np.testing.assert_allclose(fast.tip_rotation, ref.tip_rotation, atol=np.radians(1.0))
    np.testing.assert_allclose(centre_line(arm, fast), centre_line(arm, ref), atol=SAME_TOL)
    assert len(fast.contacts) == len(ref.contacts)
    np.testing.assert_allclose(fast.contacts.p, ref.contacts.p, atol=SAME_TOL)
    np.testing.assert_array_equal(fast.contacts.section, ref.contacts.section)
    angle = np.arccos(np.clip(np.einsum("mi,mi->m", fast.contacts.n, ref.contacts.n), -1, 1))
    assert np.all(angle < NORMAL_TOL)
    # The point of the fast path: fewer contact queries for the same wrap.
    assert fast.n_queries < ref.n_queries


CASES = [("mug", 1), ("cup_000", 0), ("cup_000", 1), ("apple_000", 0)]
SLOW_CASES = [("donut_000", 1), ("mug", 0), ("mug", 2), ("teapot_000", 0), ("apple_000", 1),
              ("bottle_000", 0)]


@pytest.mark.parametrize("name,k", CASES)
def test_fast_equals_reference(arm, planes, name, k):
    fast = wrap_of(arm, planes, name, k, "fast")
    ref = wrap_of(arm, planes, name, k, "reference")
    assert fast.status == "complete"
    assert_same_wrap(arm, fast, ref)


@pytest.mark.slow
@pytest.mark.parametrize("name,k", SLOW_CASES)
def test_fast_equals_reference_more(arm, planes, name, k):
    fast = wrap_of(arm, planes, name, k, "fast")
    ref = wrap_of(arm, planes, name, k, "reference")
    assert_same_wrap(arm, fast, ref)


@pytest.mark.parametrize("name,k", CASES)
def test_complete_wrap_turns_past_theta(arm, planes, name, k):
    r = wrap_of(arm, planes, name, k, "fast")
    assert r.status == "complete"
    assert r.tip_rotation > WrapParams().theta
    assert r.usable and len(r.contacts) >= 1
    assert r.n_queries > 0 and r.time_s > 0
    assert r.configs.shape[1] == 3 * arm.n_sections
    # Every configuration passed through is within the arm's limits.
    for q in r.configs:
        arm.check(ArmConfig.from_vector(q), tol=1e-6)


@pytest.mark.parametrize("name,k", CASES)
def test_wrap_never_steps_deep_into_object(arm, planes, name, k):
    scene = scene_of(arm, name)
    for method in ("fast", "reference"):
        r = wrap_of(arm, planes, name, k, method)
        worst = min(float(np.min(scene.signed_distance(
            centre_line(arm, r, ArmConfig.from_vector(q))) - arm.radius)) for q in r.configs)
        assert worst > -MAX_PENETRATION, f"{method}: {worst * 1000:.2f} mm deep"


def test_contact_frames(arm, planes):
    r = wrap_of(arm, planes, "mug", 0, "fast")
    c = r.contacts
    for v in (c.n, c.t, c.b):
        np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.einsum("mi,mi->m", c.n, c.t), 0.0, atol=1e-9)
    np.testing.assert_allclose(c.b, np.cross(c.n, c.t), atol=1e-12)
    # Samples run from the first contact to the tip, the normals towards the object.
    assert r.samples_arc_length[0] == pytest.approx(c.arc_length.min())
    assert r.samples_arc_length[-1] == pytest.approx(r.final_config.s.sum(), abs=0.006)


def test_cylinder_contacts_lie_on_its_surface(arm):
    """A vertical cylinder wrapped in the horizontal plane: contacts at the cylinder's radius
    from its axis, at the plane's height, with radial normals."""
    radius = 0.04
    cylinder = trimesh.creation.cylinder(radius=radius, height=0.15, sections=128)
    cylinder.apply_translation([0.0, 0.0, 0.075])
    scene = WrapScene(arm, cylinder)
    r = wrap(scene, make_plane(arm.base_position, "x", 0.0), WrapParams())
    assert r.status == "complete"
    p, n = r.contacts.p, r.contacts.n
    assert len(p) >= 1
    rho = np.hypot(p[:, 0], p[:, 1])
    # Contact polygons lie on the 128-gon's facets, within a fraction of a mm of the circle.
    # A region hugging the cylinder spans up to REGION_TURN_MAX between its capsules' mean
    # normals, plus one capsule's own patch (a link length along the surface), and the
    # centroid of an arc of angle a lies at radius * sin(a / 2) / (a / 2) from the axis.
    half = (REGION_TURN_MAX + scene.link_length / radius) / 2
    assert np.all(rho > radius * np.sin(half) / half - 3e-4) and np.all(rho < radius + 3e-4)
    np.testing.assert_allclose(p[:, 2], arm.base_position[2], atol=1e-3)
    radial = np.column_stack([p[:, :2] / rho[:, None], np.zeros(len(p))])
    angle = np.arccos(np.clip(np.einsum("mi,mi->m", n, radial), -1, 1))
    assert np.all(angle < np.radians(2.0))
    # The wrapped part of the centre line hugs the cylinder at the tube's radius, pressing in
    # at most press_depth plus the one enclosing step that went past it (give or take the
    # capsule mesh's 0.15 mm and the 128-gon's facets).
    rho_bb = np.hypot(r.samples_position[:, 0], r.samples_position[:, 1])
    p = WrapParams()
    assert rho_bb.min() > radius + arm.radius - p.press_depth - p.max_step_motion - 3e-4
    assert np.median(rho_bb) < radius + arm.radius + 1e-3


# ----------------------------------------------------------------- statuses
def test_object_beyond_reach_is_refused_at_scene_build(arm):
    far = generate_object("cup", 0, seed=0).mesh.copy()
    far.apply_translation([2.0, 0.0, 0.0])
    with pytest.raises(MeshError, match="beyond the arm's reach"):
        WrapScene(arm, far)


def test_plane_missing_object_is_empty_cut(arm, planes):
    r = wrap(scene_of(arm, "mug"), planes[9], WrapParams())  # ry90: behind the mug
    assert r.status == "empty_cut"
    assert len(r.contacts) == 0 and r.n_queries == 0 and not r.usable
    assert r.status in STATUSES


def test_blocked_start_is_start_in_collision(arm, planes):
    """A start ray that passes 5 mm inside the surface: the straight arm already touches."""
    r = wrap(scene_of(arm, "mug"), planes[0], unchecked(WrapParams(), start_clearance=-0.015))
    assert r.status == "start_in_collision"
    assert len(r.contacts) > 0
    assert len(r.configs) == 1
    cfg = r.final_config
    np.testing.assert_allclose(cfg.kappa, 0.0)


def test_ik_failure_is_no_ik_status(arm, planes):
    """An advancing step of 5 m puts the section ends beyond the 1.2 m arm: IK fails and the
    wrap stops with the solver's reason, without raising."""
    params = unchecked(WrapParams(ik=IKOptions(mode="exact")), delta=5.0)
    r = wrap(scene_of(arm, "mug"), planes[0], params)
    assert r.status == "no_ik"
    assert r.extra["message"].startswith("No IK found")
    assert len(r.contacts) > 0  # it felt the mug before it failed


def test_bad_method_is_refused(arm, planes):
    with pytest.raises(ValueError, match="WrapParams.method: must be one of 'fast', "
                                         "'reference', got 'quick'"):
        wrap(scene_of(arm, "mug"), planes[0], WrapParams(method="quick"))


def test_scene_arm_restored_after_wrap(arm, planes):
    scene = scene_of(arm, "mug")
    wrap_of(arm, planes, "mug", 0, "fast")
    np.testing.assert_allclose(scene.arm.base_rotation, arm.base_rotation)


def test_result_round_trips_through_arrays(arm, planes):
    from drake_continuum.wrapping.wrap_types import WrapResult
    r = wrap_of(arm, planes, "mug", 1, "fast")
    back = WrapResult.from_arrays(r.to_arrays("w_"), "w_")
    assert back.status == r.status and back.n_queries == r.n_queries
    np.testing.assert_array_equal(back.configs, r.configs)
    np.testing.assert_array_equal(back.contacts.p, r.contacts.p)


# ----------------------------------------------------------------- the table
def test_table_stops_the_arm_that_would_pass_below_it(arm, planes):
    """A cup wrapped in a vertical plane: without the table the arm passes below z = 0
    (the paper's simulation); with it, no configuration of the wrap sinks into the table
    deeper than it may into the object."""
    scene = scene_of(arm, "cup_000")
    free = wrap(scene, planes[3], WrapParams())
    lowest_free = min(centre_line(arm, free, ArmConfig.from_vector(q))[:, 2].min()
                      for q in free.configs)
    assert lowest_free < 0.0
    held = wrap(scene, planes[3], WrapParams(table=True))
    lowest = min(centre_line(arm, held, ArmConfig.from_vector(q))[:, 2].min()
                 for q in held.configs)
    assert lowest > arm.radius - MAX_PENETRATION
    assert held.usable and held.status != "start_in_collision"
    # The table's touches are not the object's: every stored contact lies on the cup.
    assert np.all(np.abs(scene.signed_distance(held.contacts.p)) < 2e-3)
    # The scene is left as a wrap without the table expects it.
    assert wrap(scene, planes[3], WrapParams()).final_config.kappa.tolist() == \
        free.final_config.kappa.tolist()


def test_fitted_start_lengths_go_theta_round_a_cylinder(arm):
    """start_fit: sections 2.. together theta * (r + tube radius) long on a cylinder of
    radius r cut across (its hull is the 128-gon, its perimeter 2 pi r to 0.02 %)."""
    from drake_continuum.wrapping.start import start_configuration

    for radius in (0.03, 0.05, 0.09):
        cylinder = trimesh.creation.cylinder(radius=radius, height=0.15, sections=128)
        cylinder.apply_translation([0.03, 0.0, 0.075])
        scene = WrapScene(arm, cylinder)
        plane = make_plane(arm.base_position, "x", 0.0)
        _, fixed, _ = start_configuration(scene, plane, WrapParams(start_fit=False))
        assert fixed.s[1:].tolist() == [0.12, 0.12]
        _, fitted, _ = start_configuration(scene, plane, WrapParams(start_fit=True))
        want = np.clip(WrapParams().theta * (radius + arm.radius) / 2,
                       arm.section_length_min, arm.section_length_max)
        np.testing.assert_allclose(fitted.s[1:], want, rtol=1e-3)


def test_fixed_start_lengths_are_one_a_section_or_one_for_all():
    """start_fit off on an arm of four sections: three lengths are sections 2 to 4's, one is
    each's, and two (the shipped list, for three sections) are refused naming the key, the
    arm's four sections and the two given, where they were repeated round to [a, b, a]."""
    from drake_continuum.kinematics.arm import ContinuumArm
    from drake_continuum.wrapping.start import start_configuration

    four = ContinuumArm.from_dict({
        "n_sections": 4, "section_length_min": 0.075, "section_length_max": 0.30,
        "curvature_max": 40.0, "radius": 0.010, "bend_max": np.pi,
        "base_position": [-0.18, 0.0, 0.05], "base_rpy": [0.0, np.pi / 2, 0.0]})
    cylinder = trimesh.creation.cylinder(radius=0.05, height=0.15, sections=64)
    cylinder.apply_translation([0.03, 0.0, 0.075])
    scene = WrapScene(four, cylinder)
    plane = make_plane(four.base_position, "x", 0.0)

    def lengths(given):
        params = WrapParams(start_fit=False, start_lengths=given)
        return start_configuration(scene, plane, params)[1].s[1:].tolist()

    assert lengths((0.1, 0.11, 0.12)) == [0.1, 0.11, 0.12]
    assert lengths((0.11,)) == [0.11, 0.11, 0.11]
    with pytest.raises(ConfigError, match=r"wrap\.start_lengths: the arm has 4 sections, so "
                                          r"give 3 lengths .* got 2 \(0\.1, 0\.12\)"):
        lengths((0.1, 0.12))
    fitted = WrapParams(start_fit=True, start_lengths=(0.1, 0.12))  # unused: no refusal
    assert len(start_configuration(scene, plane, fitted)[1].s) == 4


def test_enclosing_curves_a_section_in_the_wrap_plane(arm):
    """A section left nearly straight with its bending plane across the wrap plane (phi 90
    deg at 0.2 1/m, as IK leaves one) curves in the wrap plane: its curvature vector grows
    along the in-plane bending side, so it ends (20, 0.2) 1/m in the base frame and its
    tangent stays within atan(0.2 / 20) of the plane (closed form); growing kappa along its
    own phi would have turned it right across."""
    from drake_continuum.wrapping.wrap import _Curving

    scene = WrapScene(arm, trimesh.creation.box([0.02, 0.02, 0.02]))  # out of the way
    stepper = _Curving(scene, WrapParams())
    start = ArmConfig([0.1, 0.15, 0.15], [0.0, 0.2, 0.0], [0.0, np.pi / 2, 0.0])
    assert stepper.in_plane(start, 1) == pytest.approx((1.0, 0.0), abs=1e-12)
    bent = stepper.advance(start, 1, 0.1, k=200)
    assert bent.kappa[1] == pytest.approx(np.hypot(20.0, 0.2), rel=1e-12)
    assert bent.phi[1] == pytest.approx(np.arctan2(0.2, 20.0), rel=1e-12)
    normal = arm.base_rotation[:, 1]
    tangents = arm.backbone(bent, n=200).tangent
    assert np.abs(tangents @ normal).max() < 2 * np.sin(np.arctan2(0.2, 20.0))
    # After a section bent in the plane, the next one's in-plane side is its own x again.
    curled = ArmConfig([0.1, 0.15, 0.15], [10.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    assert stepper.in_plane(curled, 1) == pytest.approx((1.0, 0.0), abs=1e-12)
    # After one bent across the plane, the in-plane side is turned in the section's frame.
    across = ArmConfig([0.1, 0.15, 0.15], [5.0, 0.0, 0.0], [np.pi / 2, 0.0, 0.0])
    c, s = stepper.in_plane(across, 1)
    R, _ = arm.section_frames(across)
    side = c * R[1][:, 0] + s * R[1][:, 1]
    assert abs(side @ normal) < 1e-12  # in the plane
    assert side @ np.cross(normal, R[1][:, 2]) > 0  # on the wrap's side


def test_in_plane_is_the_direction_section_frames_gives_to_the_bit(arm):
    """The in-plane side read from section i's base frame built of its rotations alone is
    the one read from section_frames' frame (positions and all), to the bit, on random
    configurations of every section."""
    from drake_continuum.wrapping.wrap import _cross, _Curving

    scene = WrapScene(arm, trimesh.creation.box([0.02, 0.02, 0.02]))
    rng = np.random.default_rng(8)
    for _ in range(50):
        s = rng.uniform(0.1, 0.3, 3)
        config = ArmConfig(s, rng.uniform(0, 1, 3) * arm.curvature_limit(s),
                           rng.uniform(-np.pi, np.pi, 3))
        for i in range(3):
            R = arm.section_frames(config)[0][i]
            w = _cross(arm.base_rotation[:, 1], R[:, 2])
            angle = np.arctan2(w @ R[:, 1], w @ R[:, 0])
            assert _Curving(scene, WrapParams()).in_plane(config, i) == (np.cos(angle),
                                                                         np.sin(angle))


def test_a_stalled_wrap_reports_the_enclosing_that_turned_its_tip_furthest():
    """A 6 cm cylinder in plane 1: after its first enclosing the arm slides without wrapping
    further and the stall rule ends the wrap. It reports the enclosing configuration at
    which the tip had turned furthest, and that configuration's own contacts, not the
    configuration sliding left it in (issue 14: those made a 1 mm nudge change the wrap)."""
    from drake_continuum.wrapping.wrap import tip_heading

    arm = load_arm()
    cyl = trimesh.creation.cylinder(radius=0.06, height=0.15, sections=128)
    cyl.apply_translation([0.0, 0.0, 0.075])
    scene = WrapScene(arm, cyl)
    result = wrap(scene, enumerate_planes(arm.base_position)[1])
    assert result.status == "max_steps" and "stalled" in result.extra["message"]
    based = arm.with_base(rotation=result.base_rotation)
    # configs: start, then each round's enclosing and IK configurations, then the reported.
    enclosing = result.configs[1:-1:2]
    heading = [tip_heading(based, ArmConfig.from_vector(q)) for q in enclosing]
    k = int(np.argmax(heading))
    assert np.array_equal(result.configs[-1], enclosing[k])
    assert np.isclose(result.tip_rotation, heading[k])
    assert heading[k] < WrapParams().theta  # never complete
    # Its contacts are the contacts of that configuration, queried again here.
    scene.arm = based
    scene.set_config(ArmConfig.from_vector(result.configs[-1]))
    again = scene.contacts()
    assert len(result.contacts) == len(again) > 0
    assert np.allclose(np.sort(result.contacts.p, axis=0), np.sort(again.p, axis=0))


def _self_penetration(arm, result, far=0.06, n=800):
    """How far the wrapped tube sinks into itself, m: a diameter less the least distance
    between centre-line points more than `far` apart along the arm (dense samples, a second
    measure independent of the capsules)."""
    line = centre_line(arm, result, n=n)
    arc = np.linspace(0.0, result.final_config.s.sum(), n)
    d = np.linalg.norm(line[:, None] - line[None], axis=2)
    d[np.abs(arc[:, None] - arc[None]) < far] = np.inf
    return 2 * arm.radius - d.min()


def test_a_wrap_stops_where_the_arm_comes_round_onto_itself(arm, planes, monkeypatch):
    """Round a 1.5 cm ball the arm's tip curls to a full circle before it turns theta: the
    wrap ends closed, touching itself by at most a step, not passing through itself."""
    ball = trimesh.creation.icosphere(radius=0.015, subdivisions=3)
    ball.apply_translation([0.0, 0.0, 0.05])
    scene = WrapScene(arm, ball)
    r = wrap(scene, planes[0])
    assert r.status == "closed" and r.usable
    assert -1e-3 < _self_penetration(arm, r) < 1.5e-3
    monkeypatch.setattr(WrapScene, "self_touching", lambda self, config, first=0: False)
    blind = wrap(scene, planes[0])
    assert _self_penetration(arm, blind) > 5e-3


def test_base_backoff_is_the_least_that_clears_the_cut():
    """Closed form: a point on the approach line at x needs c + margin - x; one beside it
    at y beyond c + margin needs none; a cut already clear of c needs no move at all."""
    from drake_continuum.wrapping.start import BACKOFF_MARGIN, base_backoff

    c = 0.011
    assert base_backoff(np.array([[0.05, 0.0], [0.2, 0.03]]), c) == 0.0
    cut = np.array([[0.005, 0.0], [0.0, 0.02], [0.1, -0.03]])
    t = base_backoff(cut, c)
    assert t == pytest.approx(c + BACKOFF_MARGIN - 0.005, abs=1e-12)
    moved = np.linalg.norm(cut + [t, 0.0], axis=1)
    assert moved.min() == pytest.approx(c + BACKOFF_MARGIN, abs=1e-12)
    # A point off the line: |(x + t, y)| = c + margin exactly.
    x, y = 0.002, 0.008
    t = base_backoff(np.array([[x, y]]), c)
    assert np.hypot(x + t, y) == pytest.approx(c + BACKOFF_MARGIN, abs=1e-12)


# ----------------------------------------------------------------- adaptive advancing step
def test_advancing_step_grows_with_the_turn_left_between_delta_and_delta_max():
    p = WrapParams(delta=1e-3, delta_max_factor=4.0, delta_turn_deg=10.0)
    assert p.advancing_step(np.radians(5.0)) == 1e-3  # within delta_turn of theta
    assert p.advancing_step(np.radians(25.0)) == pytest.approx(2.5e-3)  # 1 mm a 10 deg
    assert p.advancing_step(np.radians(200.0)) == pytest.approx(4e-3)
    assert p.advancing_step(-1.0) == 1e-3  # past theta
    assert WrapParams().advancing_step(np.radians(200.0)) == WrapParams().delta  # fixed
    with pytest.raises(ConfigError, match="delta_max_factor"):
        WrapParams(delta_max_factor=0.5)


@pytest.mark.parametrize("radius", [0.04, 0.06])
def test_adaptive_step_stalls_on_a_cylinder_where_the_fixed_step_does(radius):
    """A cylinder in plane 1: after the first enclosing the arm slides round it without
    wrapping further. The stall rule counts the slide in steps of delta, so longer steps
    end the wrap after the same slide in fewer rounds and report the same enclosing
    configuration: its wrapped centre line at the cylinder's radius plus the tube's."""
    arm = load_arm()
    cyl = trimesh.creation.cylinder(radius=radius, height=0.15, sections=128)
    cyl.apply_translation([0.0, 0.0, 0.075])
    scene = WrapScene(arm, cyl)
    plane = enumerate_planes(arm.base_position)[1]
    fixed = wrap(scene, plane, WrapParams())
    adaptive = wrap(scene, plane, WrapParams(delta_max_factor=4.0))
    for r in (fixed, adaptive):
        assert r.status == "max_steps" and "stalled" in r.extra["message"]
        rho = np.hypot(r.samples_position[:, 0], r.samples_position[:, 1])
        p = WrapParams()
        assert rho.min() > radius + arm.radius - p.press_depth - p.max_step_motion - 3e-4
        assert np.median(rho) < radius + arm.radius + 3e-3
    assert len(adaptive.configs) < len(fixed.configs)
    np.testing.assert_allclose(adaptive.configs[-1], fixed.configs[-1], atol=1e-9)
    assert adaptive.tip_rotation == pytest.approx(fixed.tip_rotation, abs=1e-9)


def test_the_enclosing_cross_product_is_numpys_to_the_bit():
    """Enclosing's cross product of two 3-vectors (wrap._cross) equals numpy.cross exactly:
    a rounding difference would move the wraps (their loop is chaotic)."""
    from drake_continuum.wrapping import wrap as wrapping

    rng = np.random.default_rng(6)
    for a, b in rng.normal(size=(500, 2, 3)) * 10.0 ** rng.integers(-6, 3, (500, 2, 1)):
        assert np.array_equal(wrapping._cross(a, b), np.cross(a, b))
