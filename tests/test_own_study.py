"""A study of one's own, as a user runs it from the command line: five labels that are not
the paper's, meshes made here (in millimetres), a four-section arm described in a
configuration kept in the study's folder (outside the checkout): import, collect, train,
evaluate, classify."""

import json

import numpy as np
import pytest
import trimesh
import yaml

from drake_continuum import cli
from drake_continuum.kinematics.arm import MODELS_DIR


def shape(label: str, u) -> trimesh.Trimesh:
    """One mesh of a label, its sizes scaled by the three factors u, in millimetres."""
    return {"jar": lambda: trimesh.creation.cylinder(40 * u[0], 120 * u[1], sections=48),
            "box": lambda: trimesh.creation.box((80 * u[0], 60 * u[1], 100 * u[2])),
            "cone": lambda: trimesh.creation.cone(50 * u[0], 120 * u[1], sections=48),
            "ring": lambda: trimesh.creation.torus(50 * u[0], 15 * u[1]),
            "rod": lambda: trimesh.creation.capsule(200 * u[1], 15 * u[0])}[label]()


def make_study(folder, labels, per_label: int):
    """meshes/<label>/*.stl, my_arm.yaml (four sections of the shipped arm's reach) and
    my_config.yaml naming it."""
    rng = np.random.default_rng(0)
    for label in labels:
        (folder / "meshes" / label).mkdir(parents=True)
        for i in range(per_label):
            shape(label, rng.uniform(0.9, 1.1, 3)).export(folder / "meshes" / label / f"{i}.stl")
    arm = yaml.safe_load((MODELS_DIR / "arm.yaml").read_text())
    arm.update(n_sections=4, section_length_min=0.075, section_length_max=0.30)
    (folder / "my_arm.yaml").write_text(yaml.safe_dump(arm))
    (folder / "my_config.yaml").write_text(
        (MODELS_DIR / "config.yaml").read_text().replace("arm: arm.yaml", "arm: my_arm.yaml"))


def run(capsys, *argv) -> dict:
    """One command with --json: exit 0, its JSON document."""
    capsys.readouterr()
    code = cli.main([*map(str, argv), "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def study(tmp_path, capsys, monkeypatch, labels, per_label, config_sets=()):
    monkeypatch.chdir(tmp_path)
    make_study(tmp_path, labels, per_label)
    sets = [a for s in config_sets for a in ("--set", s)]
    imported = run(capsys, "objects", "import", "meshes", "--out", "objects")
    assert imported["counts"] == {label: per_label for label in sorted(labels)}
    assert all(u == ["mm"] for u in imported["units"].values())  # from the meshes' sizes
    collected = run(capsys, "collect", "objects", "--out", "wraps", "--config", "my_config.yaml",
                    "--workers", "1", *sets)
    assert collected["n_wraps"] > 0 and not collected["failed"]
    trained = run(capsys, "train", "wraps", "--out", "model")
    assert trained["classes"] == sorted(labels)
    evaluated = run(capsys, "evaluate", "wraps", "--splits", 10, "--out", "evaluation")
    index = json.loads((tmp_path / "wraps" / "index.json").read_text())
    assert yaml.safe_load(index["params"]["arm_yaml"])["n_sections"] == 4
    return evaluated


def test_a_study_of_two_labels_with_a_four_section_arm(tmp_path, capsys, monkeypatch):
    """Quick: jars and rings, four meshes each, on four planes; a new ring classified and
    recognised by the tree search."""
    evaluated = study(tmp_path, capsys, monkeypatch, ["ring", "jar"], 4,
                      ["planes.alpha_deg=90"])
    assert evaluated["accuracy_mean"] >= 0.9
    shape("ring", [1.05, 0.95, 1.0]).export(tmp_path / "new_ring.stl")
    answer = run(capsys, "classify", "model", "new_ring.stl", "--units", "mm", "--turn", 0)
    assert answer["category"] == "ring"
    run(capsys, "train-active", "wraps", "--out", "active-model", "--simulations", 40)
    found = run(capsys, "recognize", "active-model", "new_ring.stl", "--units", "mm",
                "--turn", 0, "--no-wait")
    assert found["category"] == "ring"


@pytest.mark.slow
def test_the_goal_study_five_labels_25_meshes_four_sections(tmp_path, capsys, monkeypatch):
    labels = ["jar", "box", "cone", "ring", "rod"]
    evaluated = study(tmp_path, capsys, monkeypatch, labels, 5)
    assert evaluated["accuracy_mean"] > 0.6  # chance: 0.2
    for label in labels:
        shape(label, [1.02, 0.97, 1.0]).export(tmp_path / f"new_{label}.stl")
        answer = run(capsys, "classify", "model", f"new_{label}.stl", "--units", "mm",
                     "--turn", 0)
        assert answer["category"] in labels
