"""classify --observe camera / --transparent on the command line: the fits' flags travel with
the result, and a model that needs the object visible is refused for a transparent one."""

import json

import pytest

from drake_continuum import cli
from drake_continuum.kinematics.arm import MODELS_DIR
from drake_continuum.learning.model import save_model, train
from drake_continuum.learning.records import object_record
from synthetic_wraps import separable_objects, write_collection

MUG = MODELS_DIR / "mug.obj"


@pytest.fixture(scope="module")
def touch_model(tmp_path_factory):
    folder = tmp_path_factory.mktemp("wraps")
    write_collection(folder, separable_objects(4, 3))
    out = folder.parent / "touch-model"
    assert cli.main(["train", str(folder), "--out", str(out), "--touch-only"]) == 0
    return out


def test_a_model_with_the_view_block_is_refused_for_a_transparent_object(tmp_path, capsys):
    records = [object_record(oid, cat, wraps, view=[0.03 if cat == "circle" else 0.08, .1, .1])
               for oid, cat, wraps in separable_objects(4, 3)]
    save_model(train(records), tmp_path / "m")
    capsys.readouterr()
    assert cli.main(["classify", str(tmp_path / "m"), str(MUG), "--transparent",
                     "--position", "0,0"]) == 1
    err = capsys.readouterr().err
    assert "view block needs the object visible" in err and "--touch-only" in err


def test_a_transparent_object_needs_a_position(touch_model, capsys):
    capsys.readouterr()
    assert cli.main(["classify", str(touch_model), str(MUG), "--transparent"]) == 1
    assert "give --position" in capsys.readouterr().err


def test_classify_through_the_camera_prints_each_fit_s_flags(touch_model, capsys):
    capsys.readouterr()
    rc = cli.main(["classify", str(touch_model), str(MUG), "--observe", "camera",
                   "--transparent", "--position", "0,0", "--set", "planes.alpha_deg=90",
                   "--json"])
    out, err = capsys.readouterr()
    assert rc == 0, err
    result = json.loads(out)
    assert result["observe"] == "camera" and result["transparent"]
    seen = result["observations"]
    assert [o["plane"] for o in seen] == sorted(o["plane"] for o in seen)
    fitted = [o for o in seen if o["usable"]]
    assert fitted and all("confident" in o and o["cpu_s"] > 0 for o in fitted)
    assert result["n_wraps"] == len(fitted)


def test_recognize_through_the_camera_lists_the_fits_of_the_wraps_it_made(tmp_path, capsys):
    folder = tmp_path / "wraps"
    write_collection(folder, separable_objects(4, 3))
    assert cli.main(["train-active", str(folder), "--out", str(tmp_path / "am"),
                     "--touch-only"]) == 0
    capsys.readouterr()
    rc = cli.main(["recognize", str(tmp_path / "am"), str(MUG), "--observe", "camera",
                   "--transparent", "--position", "0,0", "--set", "active.n_simulations=20",
                   "--json"])
    out, err = capsys.readouterr()
    assert rc == 0, err
    result = json.loads(out)
    made = [p for it in result["iterations"] for p in it["planes"]]
    assert [o["plane"] for o in result["observations"]] == made
    assert result["transparent"] and result["observe"] == "camera"
