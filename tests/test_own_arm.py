"""Arms of 2 to 6 sections described in a file of one's own: wraps, cloud fits and the command
line give results, not only no error."""

import json

import numpy as np
import pytest
import trimesh
import yaml

from drake_continuum import cli
from drake_continuum.config import load_config
from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig
from drake_continuum.perception import depth_camera as dc
from drake_continuum.perception.cloud import Cloud
from drake_continuum.perception.fitting import fit_cloud
from drake_continuum.wrapping.planes import make_plane
from drake_continuum.wrapping.scene import WrapScene
from drake_continuum.wrapping.wrap import WrapParams, wrap

RADIUS = 0.04  # the cylinder wrapped


def arm_file(folder, n: int):
    """The shipped arm's reach (1.2 m), tube and base cut into n sections."""
    d = yaml.safe_load((MODELS_DIR / "arm.yaml").read_text())
    d.update(n_sections=n, section_length_min=0.3 / n, section_length_max=1.2 / n)
    path = folder / f"arm{n}.yaml"
    path.write_text(yaml.safe_dump(d))
    return path


@pytest.mark.parametrize("n", [2, 4, 5])
def test_an_arm_of_n_sections_wraps_a_cylinder(tmp_path, monkeypatch, n):
    """In the horizontal plane: four or five sections close round the cylinder (the tip turns
    theta = 270 deg, the centre line hugging the surface at the tube's radius); two cannot,
    as the second section bends at most half a turn (bend_max)."""
    monkeypatch.chdir(tmp_path)
    arm = load_config(overrides=[f"arm={arm_file(tmp_path, n).name}"]).arm()
    assert arm.n_sections == n
    cylinder = trimesh.creation.cylinder(radius=RADIUS, height=0.15, sections=128)
    cylinder.apply_translation([0.0, 0.0, 0.075])
    r = wrap(WrapScene(arm, cylinder), make_plane(arm.base_position, "x", 0.0), WrapParams())
    assert r.final_config.n_sections == n
    rho = np.hypot(r.contacts.p[:, 0], r.contacts.p[:, 1])
    assert len(rho) and np.all(np.abs(rho - RADIUS) < 2e-3)
    if n == 2:
        assert np.degrees(r.wrap_angle) < 185.0
        final = r.final_config
        assert final.kappa[1] * final.s[1] <= arm.bend_max + 1e-9
        return
    assert r.status == "complete" and np.degrees(r.wrap_angle) > 240.0
    assert r.conformity > 0.9  # the arm's centre line lies along the surface
    rho_bb = np.hypot(r.samples_position[:, 0], r.samples_position[:, 1])
    hugging = np.abs(rho_bb - RADIUS - arm.radius) < 2e-3
    assert np.ptp(np.unwrap(np.arctan2(r.samples_position[hugging, 1],
                                       r.samples_position[hugging, 0]))) > np.radians(240)


@pytest.mark.parametrize("n, truth", [
    (4, ArmConfig([0.12, 0.15, 0.14, 0.13], [2.0, 8.0, 12.0, 14.0], [1.3, 1.4, 1.5, 1.6])),
    (2, ArmConfig([0.2, 0.3], [3.0, 9.0], [1.3, 1.5])),
])
def test_a_cloud_fit_recovers_a_configuration_of_n_sections(tmp_path, n, truth):
    arm = load_config(overrides=[f"arm={arm_file(tmp_path, n)}"]).arm()
    sim = dc.render_cloud(arm, truth, None, seed=3)  # Kinect noise
    _, fit = fit_cloud(Cloud(sim.points, sim.colours), arm)  # lengths free
    assert fit.config.n_sections == n
    assert np.linalg.norm(fit.tip - arm.tip_frame(truth)[1]) < 3e-3
    np.testing.assert_allclose(fit.config.s, truth.s, atol=0.01)
    np.testing.assert_allclose(fit.config.kappa, truth.kappa, atol=1.0)


def test_the_cloud_commands_take_the_arm_as_every_command_does(tmp_path, capsys, monkeypatch):
    """simulate-cloud with --set arm=..., fit-cloud with --config naming the arm beside it,
    and --arm, the same as --set arm=..."""
    monkeypatch.chdir(tmp_path)
    arm_file(tmp_path, 4)
    (tmp_path / "lab.yaml").write_text(
        (MODELS_DIR / "config.yaml").read_text().replace("arm: arm.yaml", "arm: arm4.yaml"))
    truth = ArmConfig([0.12, 0.15, 0.14, 0.13], [2.0, 8.0, 12.0, 14.0], [1.3, 1.4, 1.5, 1.6])
    cylinder = trimesh.creation.cylinder(radius=0.03, height=0.1)
    cylinder.apply_translation([0.3, 0.3, 0.05])  # out of the arm's way
    cylinder.export(tmp_path / "far.obj")
    assert cli.main(["simulate-cloud", "far.obj", "--arm-config", json.dumps(truth.to_dict()),
                     "--set", "arm=arm4.yaml", "--out", "c.pcd", "--json"]) == 0
    capsys.readouterr()
    tip = json.loads((tmp_path / "c.json").read_text())["tip"]  # the sidecar's truth
    lengths = ",".join(map(str, truth.s))
    for how in (["--config", "lab.yaml"], ["--arm", "arm4.yaml"]):
        assert cli.main(["fit-cloud", "c.pcd", "--lengths", lengths, "--json", *how]) == 0
        fit = json.loads(capsys.readouterr().out)
        assert len(fit["config"]["s"]) == 4
        assert np.linalg.norm(np.array(fit["tip"]) - tip) < 3e-3
    assert cli.main(["fit-cloud", "c.pcd", "--arm", "nowhere.yaml"]) == 1
    err = capsys.readouterr().err
    assert f"arm: 'nowhere.yaml' not found (tried {tmp_path / 'nowhere.yaml'}" in err


@pytest.mark.parametrize("n", [2, 5])
def test_collect_and_train_with_an_arm_of_n_sections(tmp_path, n):
    """Two jars and two rings wrapped in the horizontal plane by the arm of a config that
    names it; the collection records the arm, the model tells the labels apart."""
    from drake_continuum import collect, load_wraps, train
    from drake_continuum.learning.records import read_object_wraps
    from drake_continuum.objects.importer import import_folder
    for label, mesh in (("jar", lambda k: trimesh.creation.cylinder(0.04 + 0.005 * k, 0.12)),
                        ("ring", lambda k: trimesh.creation.torus(0.05 + 0.005 * k, 0.015))):
        (tmp_path / "src" / label).mkdir(parents=True)
        for k in range(2):
            mesh(k).export(tmp_path / "src" / label / f"{k}.stl")
    import_folder(tmp_path / "src", tmp_path / "objects")
    cfg = load_config(overrides=[f"arm={arm_file(tmp_path, n)}"])
    report = collect(tmp_path / "objects", tmp_path / "wraps", cfg, workers=1, planes=[0],
                     progress=False)
    assert report.n_wraps == 4 and not report.failed
    records = load_wraps(tmp_path / "wraps")
    for r in records:
        _, wraps = read_object_wraps(tmp_path / "wraps", r.object_id)
        assert [w.final_config.n_sections for w in wraps] == [n]
    model = train(records)
    assert list(model.classes) == ["jar", "ring"]
    best = model.predict_proba(records).argmax(axis=1)
    assert [model.classes[i] for i in best] == [r.category for r in records]
