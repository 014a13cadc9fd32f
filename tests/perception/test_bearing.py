"""The plane set oriented on the object (perception/bearing.py): the turn follows a turn of
the object (closed form), a near-round footprint keeps the world bearing, the
turn is continuous across the old round / oriented threshold (closed form of the blend; an
ellipsoid seen by the camera), the camera's cloud gives a box's axis, and a wrap of a
turned object with the plane set turned alike is the wrap of the object unturned."""

import math

import numpy as np
import pytest
import trimesh

from drake_continuum.errors import ConfigError, InputError
from drake_continuum.kinematics.arm import load_arm
from drake_continuum.objects.placement import Placement, arm_frame, place
from drake_continuum.perception.bearing import (
    ROUND_FROM,
    ROUND_TO,
    bearing_turn,
    camera_bearing,
    footprint_bearing,
    points_bearing,
    roundness_weight,
)
from drake_continuum.perception.locate import camera_points


def _turned(xy, angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.asarray(xy) @ np.array([[c, -s], [s, c]]).T


def _rectangle(a, b, n=41):
    """Points filling an a x b rectangle centred on the origin, a along x."""
    x, y = np.meshgrid(np.linspace(-a / 2, a / 2, n), np.linspace(-b / 2, b / 2, n))
    return np.stack([x.ravel(), y.ravel()], axis=1)


def _difference(a, b, period):
    """a - b wrapped into (-period / 2, period / 2]."""
    return (a - b + period / 2) % period - period / 2


@pytest.mark.parametrize("deg", [0.0, 20.0, 75.0, 110.0, 160.0, -40.0])
def test_a_box_turned_turns_the_plane_set_alike_mod_180(deg):
    """A 12 x 4 cm footprint, symmetric about both axes: its turn is the box's turn modulo
    180 deg (which of the two the deterministic smallest turn takes), exact to the raster."""
    b = footprint_bearing(_turned(_rectangle(0.12, 0.04), math.radians(deg)))
    assert abs(math.degrees(_difference(b.turn, math.radians(deg), math.pi))) < 0.5
    assert -90.0 < math.degrees(b.turn) <= 90.0
    assert b.source == "depth camera: axis"
    assert b.ratio == pytest.approx((0.04 / 0.12) ** 2, rel=0.05)  # second moments b^2/a^2


@pytest.mark.parametrize("deg", [0.0, 35.0, 150.0, -100.0, 180.0])
def test_a_one_sided_shape_gives_the_full_turn(deg):
    """A 12 x 4 cm bar with a 3 x 8 cm head across its +x end (a hammer): the head
    decides the side, so the turn follows the shape's turn modulo 360 deg."""
    shape = np.vstack([_rectangle(0.12, 0.04), _rectangle(0.03, 0.08) + [0.06, 0.0]])
    b0 = footprint_bearing(shape)
    b = footprint_bearing(_turned(shape, math.radians(deg)))
    assert b.source == "depth camera: axis and side"
    assert abs(math.degrees(_difference(b0.turn, 0.0, math.pi))) < 0.5  # the bar's axis
    assert abs(math.degrees(_difference(b.turn, b0.turn + math.radians(deg), 2 * math.pi))) \
        < 0.5


def _ellipse(a, b, n=400, rings=30):
    """Points filling an ellipse of semi-axes a (along x) and b, on rings - 1 rings (the
    outermost its edge)."""
    r = np.sqrt(np.linspace(0.0, 1.0, rings))[1:]
    t = np.linspace(0, 2 * math.pi, n, endpoint=False)
    return np.concatenate([np.stack([a * k * np.cos(t), b * k * np.sin(t)], axis=1)
                           for k in r])


@pytest.mark.parametrize("deg", [0.0, 33.0, 90.0, 127.0])
def test_a_near_round_footprint_keeps_the_world_bearing(deg):
    """An ellipse of axes 10 and 9.6 cm (second-moment ratio 0.92 > ROUND_TO) has no
    axis worth following: turn 0 at every turn, and the result says why."""
    assert (0.048 / 0.05) ** 2 > ROUND_TO
    b = footprint_bearing(_turned(_ellipse(0.05, 0.048), math.radians(deg)))
    assert b.turn == 0.0 and b.source == "round: world bearing"
    assert b.ratio == pytest.approx((0.048 / 0.05) ** 2, abs=0.02)


def _blended_axis(axis, s):
    """The blend's closed form: half the direction of s e^(2i axis) + (1 - s)."""
    z = s * np.exp(2j * axis) + (1 - s)
    return 0.5 * math.atan2(z.imag, z.real)


def test_the_turn_is_continuous_across_the_old_round_threshold():
    """Ellipses turned 40 deg whose second-moment ratio runs from 0.5 to 0.8 through the
    old hard threshold (0.65: world bearing above, axis below, a 40 deg jump here): the
    turn is the closed-form blend of axis and world x (mod 180: an ellipse is symmetric), no
    step between ratios 0.0025 apart moves it by more than 2 deg, and a 1 deg turn of the
    ellipse at ratio 0.65 moves it by 1 deg or less."""
    axis = math.radians(40.0)
    turns = []
    for ratio in np.arange(0.50, 0.80, 0.0025):  # 10 rings: the same hull, 1/7 the time
        xy = _turned(_ellipse(0.05, 0.05 * math.sqrt(ratio), rings=10), axis)
        b = footprint_bearing(xy)
        expected = _blended_axis(axis, roundness_weight(b.ratio))
        assert abs(math.degrees(_difference(b.turn, expected, math.pi))) < 0.5
        turns.append(b.turn)
    steps = np.degrees(np.abs(_difference(np.diff(turns), 0.0, math.pi)))
    assert steps.max() < 2.0
    assert roundness_weight(ROUND_FROM) == 1.0 and roundness_weight(ROUND_TO) == 0.0
    one = [footprint_bearing(_turned(_ellipse(0.05, 0.05 * math.sqrt(0.65)), math.radians(d))
                             ).turn for d in (40.0, 41.0)]
    moved = abs(math.degrees(_difference(one[1], one[0], math.pi)))
    assert 0.2 < moved <= 1.05


@pytest.mark.parametrize("deg", [0.0, 50.0, 130.0, -100.0])
def test_a_near_round_footprint_with_a_handle_follows_its_turn(deg):
    """A 9 cm disc with a 2 x 2 cm handle on its +x side (a mug from above): its ratio is in
    the blend band, but the handle's third moment makes it one-sided, so the turn is the
    mug's turn exactly (mod 360), not blended towards world x."""
    mug = np.vstack([_ellipse(0.045, 0.045), _rectangle(0.02, 0.02) + [0.053, 0.0]])
    b = footprint_bearing(_turned(mug, math.radians(deg)))
    assert ROUND_FROM < b.ratio < ROUND_TO
    assert "blended" not in b.source and b.source.endswith("and side")
    b0 = footprint_bearing(mug)
    assert abs(math.degrees(_difference(b.turn, b0.turn + math.radians(deg), 2 * math.pi))) \
        < 0.5
    assert abs(math.degrees(_difference(b0.turn, 0.0, 2 * math.pi))) < 0.5


def _ellipsoid(a, b, c):
    mesh = trimesh.creation.icosphere(4)
    mesh.apply_scale((a, b, c))
    mesh.apply_translation((0, 0, c))
    return mesh


def test_an_ellipsoid_turned_through_the_old_threshold_turns_the_planes_less():
    """A 10 x 8 x 6 cm ellipsoid seen by the depth camera, turned 86..92 deg in 1 deg
    steps: its footprint's ratio crosses the old hard threshold 0.65 (the old rule jumped
    between world x and the axis: 69 deg at 88 -> 89 deg). Its axis is near the blend's
    worst direction (across world x, where the two blended axes are 180 deg apart as
    doubled angles) and the camera's own ratio moves by up to 0.05 a degree, so the new
    turn (mod 180: the ellipsoid is symmetric) still moves, but by less than 25 deg a step,
    where the ratio reads near round the turn leans towards world x, as the old rule's
    world bearing did (the camera foreshortens the ellipsoid along its line of sight)."""
    arm = load_arm()
    mesh = _ellipsoid(0.05, 0.04, 0.03)
    bearings = [points_bearing(camera_points(place(mesh, Placement(None, math.radians(d))),
                                             arm)) for d in range(86, 93)]
    ratios = [b.ratio for b in bearings]
    assert min(ratios) < 0.65 < max(ratios)
    turns = [b.turn for b in bearings]
    steps = np.degrees(np.abs(_difference(np.diff(turns), 0.0, math.pi)))
    assert steps.max() < 25.0


@pytest.mark.parametrize("deg", [0.0, 37.0, 90.0])
def test_the_camera_gives_a_cylinder_the_world_bearing_at_any_turn(deg):
    """A 7 cm wide, 10 cm tall cylinder is round: whatever its turn, the plane set keeps
    the world bearing."""
    cyl = trimesh.creation.cylinder(radius=0.035, height=0.10, sections=64)
    cyl.apply_translation((0, 0, 0.05))
    b = camera_bearing(place(cyl, Placement(None, math.radians(deg), (0.01, -0.02))),
                       load_arm())
    assert b.source == "round: world bearing" and b.turn == 0.0


def test_flying_pixels_do_not_turn_the_axis():
    """Isolated points off the silhouette (a depth camera's flying pixels) are dropped."""
    box = _rectangle(0.12, 0.04)
    stray = np.array([[0.0, 0.06], [0.005, -0.07]])
    b = footprint_bearing(np.vstack([box, stray]))
    assert abs(math.degrees(_difference(b.turn, 0.0, math.pi))) < 0.5


def test_bad_footprints_and_settings_are_refused():
    with pytest.raises(InputError, match="at least 3"):
        footprint_bearing([[0.0, 0.0], [1.0, 0.0]])
    with pytest.raises(InputError, match="collinear"):
        footprint_bearing([[0.0, 0.0], [0.01, 0.0], [0.02, 0.0], [0.03, 0.0]])
    with pytest.raises(InputError, match="planes.bearing"):
        bearing_turn("north", None, None)


def _box(height=0.04):
    """A 14 x 5 cm box `height` tall on the table, footprint centred."""
    box = trimesh.creation.box(extents=(0.14, 0.05, height))
    box.apply_translation((0, 0, height / 2))
    return box


@pytest.mark.parametrize("deg", [25.0, 100.0])
def test_the_depth_camera_gives_a_turned_box_its_turn_mod_180(deg):
    """From the simulated Kinect's cloud (not the mesh) a box turned by deg gives a plane
    set turned by deg, modulo 180, within 3 deg."""
    arm = load_arm()
    b = camera_bearing(place(_box(), Placement(None, math.radians(deg))), arm)
    assert b.source.startswith("depth camera")
    assert abs(math.degrees(_difference(b.turn, math.radians(deg), math.pi))) < 3.0


def test_arm_frame_turns_the_object_back_by_the_bearing():
    """arm_frame(mesh, centre, turn) is the mesh moved by -centre and turned by -turn about
    the vertical: a box placed turned by t and offset comes back as the box at the origin."""
    box = _box()
    placed = place(box, Placement(None, 0.7, (0.02, -0.01)))
    np.testing.assert_allclose(arm_frame(placed, (0.02, -0.01), 0.7).vertices, box.vertices,
                               atol=1e-12)


def test_a_turned_object_wrapped_by_a_turned_plane_set_is_the_object_unturned(tmp_path):
    """wrap_object(turn=t) of a box turned by t about the mark gives the wraps of the box
    unturned (the same contacts): turning the plane set is turning the object back."""
    from drake_continuum.experiments.collect import wrap_object
    box = _box(0.08)  # cut by plane 0, the table's plane through the base (5 cm up)
    a, b = tmp_path / "box.obj", tmp_path / "turned.obj"
    box.export(a)
    place(box, Placement(None, 1.1)).export(b)
    plain = wrap_object(a, planes=[0])[0]
    turned = wrap_object(b, planes=[0], turn=1.1)[0]
    assert plain.status == turned.status and len(plain.contacts) == len(turned.contacts) > 0
    np.testing.assert_allclose(turned.contacts.p, plain.contacts.p, atol=1e-6)


def test_the_bearing_is_recorded_with_a_collection_and_its_models():
    """A collection records "bearing" only when oriented (older folders still resume), a
    model's configuration takes it from there, and an unknown value is refused by name."""
    from dataclasses import replace

    from drake_continuum.config import load_config
    from drake_continuum.experiments.collection import collection_tree, run_params
    shipped = load_config()
    world = replace(shipped, planes=replace(shipped.planes, bearing="world"))
    assert "bearing" not in run_params(world)
    params = run_params(shipped)
    assert params["bearing"] == "object"
    assert collection_tree(params)["planes"]["bearing"] == "object"
    assert collection_tree(run_params(world))["planes"]["bearing"] == "world"
    with pytest.raises(ConfigError, match="PlaneParams.bearing: must be one of"):
        replace(shipped.planes, bearing="north")


def test_a_cluster_near_the_largest_joins_it_a_far_one_does_not():
    from drake_continuum.perception.locate import JOIN_GAP, joined_clusters
    rng = np.random.default_rng(3)
    body = rng.uniform(-0.04, 0.04, (500, 3))
    handle = rng.uniform(0, 0.01, (40, 3)) + [0.04 + JOIN_GAP * 0.6, 0, 0]  # 15 mm away
    far = rng.uniform(0, 0.01, (60, 3)) + [0.04 + JOIN_GAP * 2, 0, 0]       # 50 mm away
    noise = np.array([[0.0, 0.0, 0.3]])
    points = np.vstack([body, handle, far, noise])
    labels = np.r_[np.zeros(500), np.ones(40), np.full(60, 2), [-1]].astype(int)
    kept = joined_clusters(points, labels)
    assert len(kept) == 540
    assert np.array_equal(kept, np.vstack([body, handle]))


# ---------------------------------------------------------------- the camera's view

def test_the_view_of_a_uniform_rectangle_is_its_height_and_4_sigma_extents():
    """Points filling an a x b rectangle at height h: the view is (h, 4 a / sqrt 12,
    4 b / sqrt 12) (a uniform strip's standard deviation is its width / sqrt 12), the same
    turned by any angle and moved anywhere on the table."""
    from drake_continuum.perception.locate import view_extent
    a, b, h = 0.12, 0.05, 0.07
    g = np.stack(np.meshgrid(np.linspace(-a / 2, a / 2, 241), np.linspace(-b / 2, b / 2, 101)),
                 axis=-1).reshape(-1, 2)
    # n grid points across a width w: variance w^2 (n + 1) / (12 (n - 1)), w^2 / 12 as n grows
    expected = [h, 4 * a * math.sqrt(242 / 240 / 12), 4 * b * math.sqrt(102 / 100 / 12)]
    for deg, off in ((0.0, (0, 0)), (37.0, (0.05, -0.02)), (120.0, (-0.1, 0.03))):
        c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
        xy = g @ np.array([[c, s], [-s, c]]) + off
        pts = np.column_stack([xy, np.full(len(xy), h)])
        np.testing.assert_allclose(view_extent(pts), expected, rtol=1e-9)
    with pytest.raises(InputError, match="at least 3 finite points, got 2"):
        view_extent(np.zeros((2, 3)))
    with pytest.raises(InputError, match="finite"):
        view_extent(np.full((5, 3), np.nan))


def test_the_camera_sees_a_box_standing_and_lying():
    """A 14 x 5 x 20 cm box standing, then lying on its broad side (5 cm tall), then turned:
    the camera's height is the box's within 5 mm, its footprint's long extent is the
    longer, and a turn about the vertical changes neither by more than 5 mm."""
    from drake_continuum.perception.locate import camera_view
    arm = load_arm()
    standing = _box(0.20)
    lying = trimesh.creation.box(extents=(0.20, 0.14, 0.05))
    lying.apply_translation((0, 0, 0.025))
    v_stand = camera_view(standing, arm)
    v_lie = camera_view(lying, arm)
    v_turned = camera_view(place(lying, Placement(None, math.radians(70))), arm)
    assert abs(v_stand[0] - 0.20) < 0.005 and abs(v_lie[0] - 0.05) < 0.005
    assert v_stand[1] > v_stand[2] and v_lie[1] > v_lie[2]
    assert v_lie[1] > v_stand[1]  # lying, its 20 cm lie along the table
    np.testing.assert_allclose(v_turned, v_lie, atol=0.005)


def test_skews_are_scipys_standardised_third_moments():
    """_skews against scipy.stats.skew (its docstring's figure)."""
    from scipy.stats import skew

    from drake_continuum.perception.bearing import _skews
    rng = np.random.default_rng(7)
    for _ in range(50):
        d = rng.gamma(2.0, size=(400, 2)) * 0.02
        d -= d.mean(axis=0)
        theta = rng.uniform(-math.pi, math.pi)
        axis = np.array([math.cos(theta), math.sin(theta)])
        expected = skew(d @ np.stack([axis, [-axis[1], axis[0]]], axis=1), axis=0)
        np.testing.assert_allclose(_skews(d, theta), expected, rtol=2e-11, atol=1e-14)
