"""Placements (objects/placement.py), splits by object, accuracy on placed objects
(learning/placements.py) and the depth camera's position estimate (perception/locate.py)."""

import json
import math

import numpy as np
import pytest
import trimesh

from drake_continuum import cli
from drake_continuum.kinematics.arm import load_arm
from drake_continuum.learning.evaluation import object_groups, splits
from drake_continuum.learning.placements import evaluate_placements, placements_table
from drake_continuum.learning.records import object_record
from drake_continuum.objects.dataset import (
    generate_dataset,
    load_manifest,
    manifest_record,
    write_manifest,
)
from drake_continuum.objects.generators import generate_object
from drake_continuum.objects.mesh import load_mesh
from drake_continuum.objects.placement import (
    Placement,
    PlacementError,
    check_clear,
    drawn_side,
    object_placements,
    other_side,
    place,
    placement_kind,
    rest_poses,
    side_of,
    source_id,
)
from drake_continuum.objects.pose import obj_bytes, survives_obj
from synthetic_wraps import object_wraps, shape_contour


def _brick():
    """A 10 x 6 x 20 cm box standing on its 10 x 6 face, footprint centred, on the table."""
    box = trimesh.creation.box(extents=(0.10, 0.06, 0.20))
    box.apply_translation((0, 0, 0.10))
    return box


def test_the_identity_placement_is_the_mesh_itself():
    box = _brick()
    np.testing.assert_allclose(place(box, Placement()).vertices, box.vertices, atol=1e-12)


def test_turn_and_offset_move_a_brick_as_a_rigid_motion():
    """Turned 90 deg the footprint's 10 x 6 cm becomes 6 x 10 cm; turned 30 deg its
    bounding box is 10 cos 30 + 6 sin 30 wide (closed form); the offset moves it exactly."""
    box = _brick()
    ext = place(box, Placement(None, math.pi / 2)).extents
    np.testing.assert_allclose(ext, [0.06, 0.10, 0.20], atol=1e-12)
    a = math.radians(30)
    ext = place(box, Placement(None, a)).extents
    np.testing.assert_allclose(ext[:2], [0.10 * math.cos(a) + 0.06 * math.sin(a),
                                         0.10 * math.sin(a) + 0.06 * math.cos(a)], atol=1e-12)
    moved = place(box, Placement(None, 0.0, (0.03, -0.01)))
    np.testing.assert_allclose(moved.bounds.mean(axis=0), [0.03, -0.01, 0.10], atol=1e-12)


def test_rest_poses_of_a_brick():
    """A brick has three pairs of sides; the broadest (10 x 20 cm, height 6 cm) is the most
    probable rest and the standing one (height 20 cm) the least. Every rest pose stands on
    the table with its footprint centred."""
    box = _brick()
    poses = rest_poses(box)
    assert abs(sum(p.probability for p in poses) - 1.0) < 1e-9
    heights = [place(box, Placement(i, 0.0), poses).extents[2] for i in range(len(poses))]
    assert sorted({round(h, 6) for h in heights}) == [0.06, 0.1, 0.2]
    assert round(heights[0], 6) == 0.06 and round(heights[-1], 6) == 0.2
    lying = place(box, Placement(0, 0.0), poses)
    assert abs(lying.bounds[0, 2]) < 1e-12
    np.testing.assert_allclose(lying.bounds[:, :2].mean(axis=0), 0.0, atol=1e-12)
    side = other_side(poses)
    assert side is not None and poses[side].tilt > math.radians(30)
    # The side a placement records: "generated" only where the brick's own +z still points
    # up (standing 20 cm tall, not upside down), every lying pose is another side.
    assert side_of(Placement(None, 1.0), poses) == "generated"
    sides = [side_of(Placement(i, 0.0), poses) for i in range(len(poses))]
    for i, h in enumerate(heights):
        up = poses[i].rotation @ [0.0, 0.0, 1.0]
        assert sides[i] == ("generated" if round(h, 6) == 0.2 and up[2] > 0.99 else "other")
    assert "other" in sides


@pytest.mark.parametrize("placement, words", [
    (Placement(99, 0.0), "rest pose 99 does not exist"),
    (Placement(None, float("nan")), "turn nan"),
    (Placement(None, 0.0, (float("nan"), 0.0)), "offset [nan, 0.0]"),
    (Placement(None, 0.0, (0.4, 0.0)), "out of reach"),
])
def test_bad_placements_are_refused_by_value(placement, words):
    with pytest.raises(PlacementError, match=None) as e:
        place(_brick(), placement)
    assert words in str(e.value)


def test_an_object_set_into_the_arm_is_refused():
    arm = load_arm()
    check_clear(_brick(), arm)  # the mark leaves 13 cm to the base
    with pytest.raises(PlacementError, match="into the arm"):
        check_clear(place(_brick(), Placement(None, 0.0, (-0.12, 0.0))), arm)


def test_placements_are_the_same_for_a_seed_and_clear_of_the_arm():
    box, arm = _brick(), load_arm()
    counts = {"train": 2, "turned": 2, "rest": 1, "nudged": 1, "jitter": 2, "side": 1}
    a = object_placements(box, counts, 3, index=0, arm=arm, where="brick")
    b = object_placements(box, counts, 3, index=0, arm=arm, where="brick")
    c = object_placements(box, counts, 4, index=0, arm=arm, where="brick")
    assert [t for t, _, _ in a] == ["train0", "train1", "turned0", "turned1", "rest0",
                                    "nudged0", "jitter0", "jitter1", "side0"]
    # Asking for "side" too leaves every other kind's draws as they were.
    without = object_placements(box, {k: v for k, v in counts.items() if k != "side"}, 3, index=0,
                                arm=arm, where="brick")
    assert [p for _, p, _ in without] == [p for _, p, _ in a[:-1]]
    assert [p for _, p, _ in a] == [p for _, p, _ in b] != [p for _, p, _ in c]
    by = {t: p for t, p, _ in a}
    for k in (0, 1):  # jitter k is turned k moved 1 mm and turned 1 deg
        j, t = by[f"jitter{k}"], by[f"turned{k}"]
        assert abs(abs(j.turn - t.turn) - math.radians(1)) < 1e-12
        assert abs(np.hypot(*np.subtract(j.offset, t.offset)) - 0.001) < 1e-12
    assert np.hypot(*by["nudged0"].offset) <= 0.02 and abs(by["nudged0"].turn) <= \
        math.radians(5)
    assert by["rest0"].rest_pose == by["side0"].rest_pose == other_side(rest_poses(box))
    assert by["side0"].turn != by["rest0"].turn  # the same side, its own turn
    for _, _, mesh in a:
        check_clear(mesh, arm)


def test_further_sides_are_drawn_by_their_probability_among_the_other_sides():
    """`lying` and side copies after the first draw a side other than standing as
    generated with the probability trimesh gives it, renormalised over those sides: on a
    brick, 4,000 draws match each pose's share within 4 standard errors, and the standing
    pose is never drawn."""
    box = _brick()
    poses = rest_poses(box)
    other = [i for i, p in enumerate(poses) if p.tilt > math.radians(30)]
    standing = [i for i in range(len(poses)) if i not in other]
    assert len(standing) == 1 and len(other) == len(poses) - 1
    share = np.array([poses[i].probability for i in other])
    share /= share.sum()
    rng = np.random.default_rng(5)
    n = 4000
    drawn = np.array([drawn_side(poses, rng) for _ in range(n)])
    assert not np.isin(drawn, standing).any()
    freq = np.array([np.mean(drawn == i) for i in other])
    assert np.all(np.abs(freq - share) < 4 * np.sqrt(share * (1 - share) / n))
    # A copy's kind and number decide how its side is chosen: side0 is the likeliest other
    # side (as `rest`), side1.. and lying0 are drawn, on the brick not always the likeliest.
    arm = load_arm()
    tags = {t: p for t, p, _ in object_placements(box, {"side": 12, "lying": 1}, 3, index=0,
                                                   arm=arm, where="brick")}
    assert tags["side0"].rest_pose == other_side(poses)
    later = {tags[f"side{k}"].rest_pose for k in range(1, 12)}
    assert later <= set(other) and len(later) > 1
    assert tags["lying0"].rest_pose in other
    assert drawn_side([poses[i] for i in standing], rng) is None  # no other side


def test_ids_name_their_object_and_kind():
    assert source_id("mug_003@turned12") == "mug_003" and source_id("mug_003") == "mug_003"
    assert placement_kind("mug_003@turned12") == "turned"
    assert placement_kind("mug_003") == "generated"


def test_objects_place_writes_placed_copies_deterministically(tmp_path):
    src = tmp_path / "objects"
    generate_dataset(src, seed=0, counts={"mug": 1, "bottle": 1}, workers=1, progress=False)
    args = ["objects", "place", str(src), "--placements", "turned=1,rest=1", "--seed", "2"]
    assert cli.main(args + ["--out", str(tmp_path / "a")]) == 0
    assert cli.main(args + ["--out", str(tmp_path / "b")]) == 0
    ds = load_manifest(tmp_path / "a")
    assert sorted(e.id for e in ds) == ["bottle_000@rest0", "bottle_000@turned0",
                                        "mug_000@rest0", "mug_000@turned0"]
    for e in ds:
        assert e.source_id == source_id(e.id) and e.placement["kind"] == placement_kind(e.id)
        assert e.placement["side"] == ("other" if e.id.endswith("rest0") else "generated")
        assert (tmp_path / "a" / e.path.name).read_bytes() == \
            (tmp_path / "b" / e.path.name).read_bytes()
    # The placed mesh is the original set down by the recorded placement.
    e = ds.by_id("bottle_000@rest0")
    p = Placement.from_dict(e.placement)
    again = place(load_manifest(src).by_id("bottle_000").load(), p)
    np.testing.assert_allclose(np.sort(e.load().vertices, axis=0),
                               np.sort(again.vertices, axis=0), atol=2e-7)
    assert e.load().extents[2] < 0.6 * load_manifest(src).by_id("bottle_000").load().extents[2]


def test_a_placed_copy_that_the_files_rounding_would_tear_is_written_closed(tmp_path):
    """hammer_026 of seed 71 on its side 1, turned 31.3 deg: two of its vertices under
    0.1 um apart round onto one in the placed file and tear the surface (collect then failed
    on it). The copy written is welded as the file would weld it: closed, and within 1 um of
    the placement computed here."""
    g = generate_object("hammer", 26, seed=71)
    src = tmp_path / "objects"
    src.mkdir()
    (src / "hammer_026.obj").write_bytes(obj_bytes(g.posed.mesh))
    write_manifest(src, [manifest_record(g.id, "hammer", "hammer_026.obj",
                                         params=g.params_dict(), mesh=g.posed.mesh,
                                         scale=1.0)], "generated", seed=71)
    original = load_manifest(src).by_id("hammer_026").load()
    placement = Placement(1, math.radians(31.309683))
    expected = place(original, placement)
    assert not survives_obj(expected)  # the case: written as it is, the file tears
    out = tmp_path / "placed"
    assert cli.main(["objects", "place", str(src), "--out", str(out), "--rest-pose", "1",
                     "--turn", "31.309683", "-q"]) == 0
    written = load_mesh(out / "hammer_026@given0.obj")  # raises if not closed
    assert written.is_watertight
    d = trimesh.proximity.closest_point(expected, written.vertices)[1]
    assert d.max() < 1e-6 and abs(written.volume - expected.volume) < 1e-9


def test_objects_place_with_a_bad_value_writes_nothing(tmp_path, capsys):
    src = tmp_path / "objects"
    generate_dataset(src, seed=0, counts={"mug": 1, "cup": 1}, workers=1, progress=False)
    out = tmp_path / "placed"
    assert cli.main(["objects", "place", str(src), "--out", str(out), "--rest-pose",
                     "999"]) == 1
    assert "rest pose 999 does not exist" in capsys.readouterr().err
    assert not out.exists()
    assert cli.main(["objects", "place", str(src), "--out", str(out), "--offset",
                     "0.01,nan"]) == 1
    assert "offset [0.01, nan]" in capsys.readouterr().err and not out.exists()


# ---------------------------------------------------------------- splits by object

def test_group_splits_never_put_one_object_in_both_halves():
    rng = np.random.default_rng(0)
    groups, labels = [], []
    for g in range(24):
        for _ in range(rng.integers(1, 5)):  # each object with 0 to 3 placed copies
            groups.append(f"o{g}")
            labels.append("abc"[g % 3])
    for train, test in splits(labels, n_splits=20, seed=1, groups=groups):
        assert set(np.array(groups)[train]).isdisjoint(np.array(groups)[test])
        assert len(train) + len(test) == len(groups)
        assert len(set(np.array(groups)[train])) == 12  # half of the objects
    # One item a group: the plain split, index for index.
    plain = splits(labels[:24], n_splits=5, seed=2)
    grouped = splits(labels[:24], n_splits=5, seed=2, groups=[f"g{i}" for i in range(24)])
    assert all(np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
               for a, b in zip(plain, grouped))


def _copies(n_objects=24, seed=9):
    """Objects with random labels whose placed copies have exactly the original's wraps:
    a split that leaked copies of a test object into training would classify them by
    memory (100 %); split by object, nothing is learnable (chance, 1 / 3)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n_objects):
        label = "abc"[rng.integers(3)]
        wraps = object_wraps(shape_contour("circle", rng.uniform(0.03, 0.06)), 3, rng)
        for tag in ("", "@train0", "@turned0", "@jitter0"):
            out.append(object_record(f"o{i}{tag}", label, wraps))
    return out


def test_no_placement_of_a_test_object_is_trained_on():
    objects = _copies()
    assert len(set(object_groups(objects))) == 24
    r = evaluate_placements(objects, n_splits=10, seed=0, train_kinds=("generated", "train"),
                            progress=False)
    # Identical wraps give identical predictions: the copies score as the originals, and
    # no prediction flips.
    assert r["kinds"]["turned"]["accuracies"] == r["kinds"]["generated"]["accuracies"]
    assert r["flips"]["rate"] == 0.0 and r["flips"]["pairs"] == 10 * 12
    assert r["kinds"]["turned"]["accuracy_mean"] < 0.7  # chance, not memory
    assert "| flip rate" in placements_table({"chords": r})


def test_another_datasets_objects_are_tested_every_split_and_never_trained_on():
    pool = [o for o in _copies() if "@" not in o.object_id or "@train" in o.object_id]
    # Another dataset's objects: the same ids as the pool's first six (a collision that
    # must not merge them with the pool's objects), a label no pool object has, and the
    # pool objects' own wraps. Trained on even once, they would be recognised by memory.
    other = [type(o)(**{**o.__dict__, "category": "z"}) for o in _copies(6, seed=9)]
    r = evaluate_placements(pool, n_splits=10, seed=0, train_kinds=("generated", "train"),
                            progress=False, test_objects=other)
    assert r["n_test_objects"] == 6 * 4
    for kind in ("generated", "turned", "jitter", "train"):
        assert r["kinds"][kind]["accuracies"] == [0.0] * 10  # never label z: never trained
    assert r["flips"]["pairs"] == 10 * 6  # every split tests every turned/jitter pair
    assert r["flips"]["rate"] == 0.0  # identical wraps


def test_train_all_is_one_classifier_of_every_pool_record():
    """train_all: one round, trained on every pool record of the training kinds; its
    predictions are those of fit_pipeline on those records, done here by hand."""
    from drake_continuum.errors import InputError
    from drake_continuum.learning.pipeline import fit_pipeline
    from synthetic_wraps import separable_objects
    pool = [object_record(i, c, w) for i, c, w in separable_objects(5, 3)]
    test = [object_record(i, c, w) for i, c, w in separable_objects(4, 3, seed=4)]
    r = evaluate_placements(pool, seed=0, progress=False, test_objects=test, train_all=True)
    assert r["n_splits"] == 1 and len(r["kinds"]["generated"]["accuracies"]) == 1
    pred = fit_pipeline(pool, [o.category for o in pool]).predict(test)
    assert r["kinds"]["generated"]["accuracy_mean"] == pytest.approx(
        np.mean(pred == np.array([o.category for o in test])))
    with pytest.raises(InputError, match="train_all needs test_objects"):
        evaluate_placements(pool, progress=False, train_all=True)


# ---------------------------------------------------------------- the camera's estimate

def test_the_depth_camera_finds_a_brick_within_a_centimetre():
    from drake_continuum.perception.locate import camera_estimate, footprint_centre
    arm = load_arm()
    brick = place(_brick(), Placement(None, 0.4, (0.03, -0.02)))
    est = camera_estimate(brick, arm, seed=1)
    assert np.linalg.norm(est.xy - footprint_centre(brick)) < 0.01
    assert np.linalg.norm(footprint_centre(brick) - [0.03, -0.02]) < 1e-9


def test_classify_lines_the_arm_up_on_the_given_position_not_the_mesh(tmp_path):
    """The scene classify wraps is the mesh set down (turn, offset) and moved by minus the
    --position given, not re-centred on its own bounding box: 7 mm of error stays in."""
    import argparse

    from drake_continuum.cli.common import placed_scene
    from drake_continuum.kinematics.arm import MODELS_DIR, load_arm
    mug = trimesh.load(MODELS_DIR / "mug.obj", process=True)
    args = argparse.Namespace(mesh=str(MODELS_DIR / "mug.obj"), units="m", rest_pose=None,
                              turn=90.0, offset="0.05,0.02", position="0.057,0.02",
                              simplify=None)
    scene, world, position = placed_scene(args, load_arm())
    expected = place(mug, Placement(None, math.pi / 2, (0.05, 0.02)))
    np.testing.assert_allclose(world.vertices, expected.vertices, atol=1e-12)
    np.testing.assert_allclose(scene.object_trimesh.vertices,
                               expected.vertices - [0.057, 0.02, 0.0], atol=1e-12)
    assert position["from"] == "--position" and position["error_mm"] == pytest.approx(7.0,
                                                                                     abs=0.01)


def test_classify_wraps_an_object_near_the_base_from_a_base_backed_off(tmp_path):
    """A brick lined up 10.5 mm from the base point (0.5 mm from the tube) is wrapped: the
    horizontal plane's base backs off by clearance + margin - 10.5 mm; 5.5 mm closer, the
    brick touches the tube and is refused by value."""
    import argparse

    from drake_continuum.cli.common import UserError, placed_scene
    from drake_continuum.wrapping.planes import enumerate_planes
    from drake_continuum.wrapping.wrap import BACKOFF_MARGIN, WrapParams, wrap

    arm = load_arm()
    path = tmp_path / "brick.obj"
    # Triangles of at most 1 cm: a plane's cut is known by its segments' end points, and
    # halving the edges puts one at y = 0, in front of the base (the 12-triangle box has none).
    v, f = trimesh.remesh.subdivide_to_size(_brick().vertices, _brick().faces, 0.01)
    path.write_bytes(obj_bytes(trimesh.Trimesh(v, f)))

    def scene_at(x):
        args = argparse.Namespace(mesh=str(path), units="m", rest_pose=None, turn=None,
                                  offset=None, position=f"{x},0", simplify=None)
        return placed_scene(args, arm)

    # The brick's near face is at x = -0.05 - position; the base at x = -0.18, z = 0.05.
    scene, _, _ = scene_at(0.1195)
    result = wrap(scene, enumerate_planes(arm.base_position)[0], WrapParams())
    clearance = arm.radius + WrapParams().start_clearance
    want = clearance + BACKOFF_MARGIN - 0.0105
    np.testing.assert_allclose(result.base_offset, [-want, 0.0, 0.0], atol=1e-6)
    assert result.usable
    with pytest.raises(UserError, match="into the arm"):
        scene_at(0.125)


def test_cli_evaluate_on_placed_copies(tmp_path, capsys):
    """`evaluate WRAPS --placed PLACED` reports every kind, chords beside triangles; copies
    with their original's wraps score as the originals and never flip."""
    from synthetic_wraps import separable_objects, write_collection
    objects = separable_objects(6, 3)
    write_collection(tmp_path / "wraps", objects)
    write_collection(tmp_path / "placed", [(f"{i}@{tag}", c, w) for i, c, w in objects
                                           for tag in ("turned0", "jitter0", "train0",
                                                       "side0")])
    out = tmp_path / "ev"
    assert cli.main(["evaluate", str(tmp_path / "wraps"), "--placed", str(tmp_path / "placed"),
                     "--train-kinds", "generated,train,side", "--splits", "4", "--out",
                     str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    chords = summary["placements"]["chords"]
    assert chords["kinds"]["turned"] == chords["kinds"]["generated"] == 1.0
    assert chords["flip_rate"] == 0.0
    assert set(summary["placements"]) == {"chords", "triangles"}
    table = (out / "placements.md").read_text()
    assert "| objects placed | chords | triangles |" in table and "flip rate" in table
    assert cli.main(["evaluate", str(tmp_path / "wraps"), "--placed", str(tmp_path / "placed"),
                     "--train-kinds", "rest", "--out", str(tmp_path / "refused")]) == 1
    assert "--train-kinds must name generated and/or train / side" in capsys.readouterr().err
    assert not (tmp_path / "refused").exists()  # refused before the evaluation


def test_turn_invariant_features_do_not_change_when_the_object_turns():
    """Contacts turned about the vertical keep their turn-invariant extent (a 10 x 4 cm
    rectangle's ranges are 10 and 4 cm however turned; world x, y ranges are not), and the
    pooled descriptors do not depend on which plane saw which wrap."""
    from drake_continuum.features.chords import contact_extent
    from drake_continuum.learning.pipeline import pooled_descriptors, wrap_slots
    rng = np.random.default_rng(3)
    corners = np.array([[-0.05, -0.02], [0.05, -0.02], [0.05, 0.02], [-0.05, 0.02]])
    edge = np.concatenate([a + np.linspace(0, 1, 20)[:, None] * (b - a)
                           for a, b in zip(corners, np.roll(corners, -1, axis=0))])
    pts = np.column_stack([edge, rng.uniform(0, 0.1, len(edge))])
    a = math.radians(35)
    R = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    plain, turned = contact_extent(pts, True), contact_extent(pts @ R.T, True)
    np.testing.assert_allclose(plain, turned, atol=1e-12)
    np.testing.assert_allclose(plain[:2], [0.10, 0.04], atol=1e-12)
    # The world x range changes: 10 cos 35 + 4 sin 35 cm.
    assert contact_extent(pts @ R.T)[0] == pytest.approx(0.1 * math.cos(a) + 0.04 * math.sin(a))
    desc = rng.uniform(0.01, 1, (4, 7))
    desc[2] = 0.0  # an unusable wrap: left out
    pooled = pooled_descriptors(desc)
    np.testing.assert_allclose(pooled, np.r_[desc[[0, 1, 3]].mean(0), desc[[0, 1, 3]].max(0)])
    np.testing.assert_allclose(wrap_slots(desc, [0, 1, 2, 3], 10, turn_invariant=True),
                               wrap_slots(desc[::-1], [3, 2, 1, 0], 10, turn_invariant=True))
    assert np.isnan(pooled_descriptors(np.zeros((3, 7)))).all()


def test_balanced_accuracy_weighs_each_category_the_same():
    """6 circles recognised and 2 objects of a never-trained label: 6 of 8 right by record,
    (1 + 0) / 2 with each category weighing the same."""
    from drake_continuum.learning.records import object_record
    from synthetic_wraps import separable_objects
    pool = [object_record(i, c, w) for i, c, w in separable_objects(6, 3)]
    test = [object_record(i, c, w) for i, c, w in separable_objects(6, 3, seed=4)]
    test = [o for o in test if o.category == "circle"] + [
        type(o)(**{**o.__dict__, "category": "z"}) for o in test if o.category == "square"][:2]
    r = evaluate_placements(pool, n_splits=3, seed=0, progress=False, test_objects=test)
    assert r["kinds"]["generated"]["accuracy_mean"] == pytest.approx(6 / 8)
    assert r["kinds"]["generated"]["balanced_mean"] == pytest.approx(0.5)


def test_rotation_up_is_the_smallest_rotation_and_not_a_library_twin():
    """_rotation_up against scipy's and trimesh's vector alignment (its docstring's claims)."""
    from scipy.spatial.transform import Rotation
    from trimesh.geometry import align_vectors

    from drake_continuum.objects.placement import _rotation_up
    z = np.array([0.0, 0.0, 1.0])
    twisted = 0.0
    for v in np.random.default_rng(5).normal(size=(300, 3)):
        R = _rotation_up(v)
        u = v / np.linalg.norm(v)
        np.testing.assert_allclose(R @ u, z, atol=1e-14)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)
        np.testing.assert_allclose(R, Rotation.align_vectors(z[None], u[None])[0].as_matrix(),
                                   atol=1e-13)
        twisted = max(twisted, np.abs(R - align_vectors(u, z)[:3, :3]).max())
    assert twisted > 0.5  # trimesh's adds a twist about z
    np.testing.assert_array_equal(_rotation_up(np.array([0.0, 0.0, 2.0])), np.eye(3))
    np.testing.assert_array_equal(_rotation_up(np.array([0.0, 0.0, -1.0])),
                                  np.diag([1.0, -1.0, -1.0]))
