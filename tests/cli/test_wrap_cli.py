"""`drake-continuum wrap`: JSON summary, PNG, dataset ids and clear errors."""

import json

import pytest

from drake_continuum.cli import main
from drake_continuum.kinematics.arm import MODELS_DIR

MUG = str(MODELS_DIR / "mug.obj")


def test_wrap_json_and_png(tmp_path, capsys):
    png = tmp_path / "wrap.png"
    # In plane 1 (22.5 deg about x) the mug's wrap completes; in plane 0 the handle stops it
    # at the arm's limits (tip turned 254 deg).
    assert main(["wrap", MUG, "--plane", "1", "--json", "--png", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("status", "n_contacts", "tip_rotation_deg", "n_queries", "time_ms", "config"):
        assert key in out
    assert out["status"] == "complete" and out["n_contacts"] > 0
    assert out["tip_rotation_deg"] > 270
    assert set(out["config"]) == {"s", "kappa", "phi"}
    assert png.stat().st_size > 10_000


def test_wrap_plane_by_angle_missing_object(capsys):
    assert main(["wrap", MUG, "--ry", "90", "--direction", "ccw", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["status"] == "empty_cut" and out["n_contacts"] == 0
    assert out["plane"]["label"] == "ry90-ccw"


def test_wrap_dataset_id(tmp_path, capsys):
    from drake_continuum.objects.dataset import generate_dataset
    generate_dataset(tmp_path, seed=0, counts={"cup": 1}, workers=1)
    assert main(["wrap", "cup_000", "--dataset", str(tmp_path), "--plane", "0", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["object"] == "cup_000"
    assert main(["wrap", "cup_999", "--dataset", str(tmp_path), "--plane", "0"]) == 1
    assert "no object 'cup_999'" in capsys.readouterr().err


@pytest.mark.parametrize("argv,message", [
    (["wrap", "no/such.obj", "--plane", "0"], "no such mesh file"),
    (["wrap", MUG, "--plane", "12"], "--plane must lie in 0..9"),
    (["wrap", MUG, "--plane", "1", "--direction", "cw"], "--direction goes with"),
])
def test_wrap_bad_input(argv, message, capsys):
    assert main(argv) == 1
    assert message in capsys.readouterr().err


def test_wrap_needs_a_plane(capsys):
    with pytest.raises(SystemExit):
        main(["wrap", MUG])


def test_wrap_gallery(tmp_path):
    from drake_continuum.objects.dataset import generate_dataset
    from drake_continuum.viz.plots import wrap_gallery
    generate_dataset(tmp_path / "objects", seed=0, counts={"cup": 2, "hammer": 1}, workers=1)
    png = wrap_gallery(tmp_path / "objects", tmp_path / "fig5.png", seed=0, plane=0)
    assert png.stat().st_size > 20_000
