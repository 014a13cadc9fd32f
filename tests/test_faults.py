"""Faults and damaged data (issue 15): each case a careful user can hit, with what must
happen. No silent wrong answer, no traceback, the file or folder named.

The collection cases use the synthetic wraps of synthetic_wraps.py (no Drake needed); the
command-line cases run `drake_continuum.cli.main` in this process, except where a signal or
another user is involved (a subprocess). New names are imported inside each test so that
each fails on its own on code without them.
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from drake_continuum import cli
from drake_continuum.kinematics.arm import MODELS_DIR
from synthetic_wraps import separable_objects, write_collection

PACKAGE = Path(cli.__file__).resolve().parent.parent


def _run(capsys, *argv):
    """(exit code, stdout, stderr) of the command line in this process."""
    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture(scope="module")
def collection(tmp_path_factory):
    """A synthetic wrap collection: 5 circles and 5 squares, 3 wraps each."""
    folder = tmp_path_factory.mktemp("wraps")
    write_collection(folder, separable_objects(5, 3))
    return folder


@pytest.fixture
def copy(collection, tmp_path):
    out = tmp_path / "wraps"
    shutil.copytree(collection, out)
    return out


@pytest.fixture(scope="module")
def trained(collection, tmp_path_factory):
    """A classifier model folder and an active-recognition model folder of the collection."""
    from drake_continuum.active.training import save_active_model, train_active
    from drake_continuum.learning.model import save_model, train
    from drake_continuum.learning.records import load_wraps
    root = tmp_path_factory.mktemp("models")
    save_model(train(load_wraps(collection)), root / "model")
    save_active_model(train_active(collection), root / "active")
    return root


def _rewrite_npz(path, change):
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    change(arrays)
    np.savez(path, **arrays)


# ------------------------------------------------------------------ models

def test_model_whose_class_list_no_longer_matches_its_arrays_is_refused(trained, tmp_path):
    """Seen: a model.json cut to 2 classes loaded and classified at p = 0.99, exit 0."""
    from drake_continuum.learning.model import ModelFormatError, load_model
    model = tmp_path / "model"
    shutil.copytree(trained / "model", model)
    meta = json.loads((model / "model.json").read_text())
    assert len(meta["classes"]) == 2
    for classes in (meta["classes"][:1] + ["cup", "mug"],   # 3 names for 2 classes' arrays
                    meta["classes"][::-1]):                   # same count, swapped meaning
        (model / "model.json").write_text(json.dumps({**meta, "classes": classes}))
        with pytest.raises(ModelFormatError) as e:
            load_model(model)
        assert str(model) in str(e.value) and "damaged model" in str(e.value) \
            and "retrain" in str(e.value)
    (model / "model.json").write_text(json.dumps(meta))
    load_model(model)  # the untouched model loads


def test_model_arrays_changed_after_saving_are_refused(trained, tmp_path):
    from drake_continuum.learning.model import ModelFormatError, load_model
    model = tmp_path / "model"
    shutil.copytree(trained / "model", model)
    good = (model / "model.npz").read_bytes()
    # Same shapes, other numbers: only the checksum tells.
    _rewrite_npz(model / "model.npz", lambda a: a.update(coef=a["coef"] * 2.0))
    with pytest.raises(ModelFormatError, match="SHA-256 differs.*retrain"):
        load_model(model)
    # A number of model.json changed (the scale of the features before the SVM).
    (model / "model.npz").write_bytes(good)
    meta = json.loads((model / "model.json").read_text())
    (model / "model.json").write_text(json.dumps({**meta, "scale": meta["scale"] * 1.01}))
    with pytest.raises(ModelFormatError, match="SHA-256 differs.*retrain"):
        load_model(model)
    (model / "model.json").write_text(json.dumps(meta))
    # Another shape than model.json records.
    (model / "model.npz").write_bytes(good)
    _rewrite_npz(model / "model.npz", lambda a: a.update(coef=np.vstack([a["coef"]] * 2)))
    with pytest.raises(ModelFormatError, match="'coef' has shape .*retrain"):
        load_model(model)


def test_model_of_the_previous_format_is_refused_with_the_retrain_message(trained, tmp_path):
    """Format 5 added the shapes and the checksum: a format-4 model must be retrained; so
    must a format-6 one (7 added the standing model)."""
    from drake_continuum.learning.model import FORMAT_VERSION, ModelFormatError, load_model
    assert FORMAT_VERSION == 7
    model = tmp_path / "model"
    shutil.copytree(trained / "model", model)
    meta = json.loads((model / "model.json").read_text())
    meta["format_version"] = 4
    for key in ("array_shapes", "sha256"):
        meta.pop(key)
    (model / "model.json").write_text(json.dumps(meta))
    with pytest.raises(ModelFormatError, match="version 4 .*retrain with `drake-continuum train`"):
        load_model(model)
    shutil.rmtree(model)
    shutil.copytree(trained / "model", model)
    meta = json.loads((model / "model.json").read_text())
    (model / "model.json").write_text(json.dumps({**meta, "format_version": 6}))
    with pytest.raises(ModelFormatError, match="version 6 .*reads format version 7"):
        load_model(model)


def test_recognize_with_a_truncated_observations_file_says_damaged_retrain(trained, tmp_path,
                                                                           capsys):
    """Seen: a zipfile.BadZipFile traceback."""
    model = tmp_path / "active"
    shutil.copytree(trained / "active", model)
    npz = model / "observations.npz"
    npz.write_bytes(npz.read_bytes()[: npz.stat().st_size // 2])
    rc, out, err = _run(capsys, "recognize", model, MODELS_DIR / "mug.obj")
    assert rc == 1 and out == ""
    line, = err.strip().splitlines()
    assert "damaged model" in line and str(npz) in line and "retrain" in line \
        and "train-active" in line


def test_observation_model_arrays_changed_after_saving_are_refused(trained, tmp_path):
    from drake_continuum.active.observation import load_observation_model
    from drake_continuum.learning.model import ModelFormatError
    model = tmp_path / "active"
    shutil.copytree(trained / "active", model)
    _rewrite_npz(model / "observations.npz",
                 lambda a: a.update(obs_counts=a["obs_counts"] + 1))
    with pytest.raises(ModelFormatError, match="SHA-256 differs.*train-active"):
        load_observation_model(model)


# ------------------------------------------------------------------ wrap collections

def test_wrap_file_of_another_format_version_is_refused_by_name(copy, tmp_path, capsys):
    """Seen: accepted silently by `evaluate`."""
    path = copy / "circle_02.json"
    meta = json.loads(path.read_text())
    path.write_text(json.dumps({**meta, "format_version": 99}))
    rc, out, err = _run(capsys, "evaluate", copy, "--splits", 2, "--out", tmp_path / "ev")
    assert rc == 1 and out == ""
    line, = err.strip().splitlines()
    assert str(path) in line and "version 99" in line and "version 1" in line
    assert not (tmp_path / "ev").exists()
    # The index of a newer collection too.
    path.write_text(json.dumps(meta))
    index = json.loads((copy / "index.json").read_text())
    (copy / "index.json").write_text(json.dumps({**index, "format_version": 2}))
    rc, _, err = _run(capsys, "train", copy, "--out", tmp_path / "m")
    assert rc == 1 and str(copy / "index.json") in err and "version 2" in err


def test_object_with_nan_arrays_is_named_and_left_out(copy, tmp_path, capsys):
    """Seen: `evaluate` aborted with "cannot convert float NaN to integer", no object named."""
    def nan(arrays):  # every number of the wraps' geometry (the plane index etc. kept)
        for k, a in arrays.items():
            if a.dtype.kind == "f" and not k.endswith("_scalars"):
                arrays[k] = np.full_like(a, np.nan)
    _rewrite_npz(copy / "square_03.npz", nan)
    out_dir = tmp_path / "ev"
    rc, out, err = _run(capsys, "evaluate", copy, "--splits", 2, "--out", out_dir)
    assert rc == 0
    assert "square_03" in err and "NaN" in err and "square_03" in out
    evaluation = json.loads((out_dir / "evaluation.json").read_text())
    skipped, = evaluation["skipped"]
    assert skipped["object_id"] == "square_03" and "non-finite" in skipped["reason"]
    assert evaluation["chords"]["n_objects"] == 9

    rc, _, err = _run(capsys, "evaluate", copy, "--splits", 2, "--out", tmp_path / "ev2",
                      "--strict")
    assert rc == 1 and "square_03" in err and "--strict" in err
    assert not (tmp_path / "ev2").exists()


def test_damaged_and_missing_object_files_are_listed_or_refused_with_strict(copy, tmp_path,
                                                                            capsys):
    """Seen: skipped with a warning on stderr, exit 0, but absent from evaluation.json."""
    (copy / "circle_01.npz").unlink()
    npz = copy / "square_00.npz"
    npz.write_bytes(npz.read_bytes()[:300])
    out_dir = tmp_path / "ev"
    rc, out, err = _run(capsys, "evaluate", copy, "--splits", 2, "--out", out_dir, "--json")
    assert rc == 0
    summary = json.loads(out)
    evaluation = json.loads((out_dir / "evaluation.json").read_text())
    for listed in (summary["skipped"], evaluation["skipped"]):
        reasons = {s["object_id"]: s["reason"] for s in listed}
        assert sorted(reasons) == ["circle_01", "square_00"]
        assert "circle_01.npz" in reasons["circle_01"] and "square_00.npz" in reasons["square_00"]
    assert evaluation["chords"]["n_objects"] == 8
    assert "circle_01" in err and "square_00" in err

    rc, out, err = _run(capsys, "evaluate", copy, "--splits", 2, "--out", tmp_path / "ev2",
                        "--strict")
    assert rc == 1 and out == ""
    line, = err.strip().splitlines()
    assert "circle_01" in line and "square_00" in line and "--strict" in line


def test_report_lists_the_objects_left_out(tmp_path):
    from drake_continuum.experiments.report import _skipped
    text = _skipped([{"object_id": "mug_003", "reason": "mug_003.npz: damaged | truncated"}])
    assert "mug_003" in text and "1 object(s)" in text and "damaged / truncated" in text
    assert _skipped([]) == ""


# ------------------------------------------------------------------ output folders

@pytest.fixture
def read_only(tmp_path):
    """A folder nobody may write into, root included: immutable (chattr +i) when we are
    root, who writes through any permission bits, else mode 0555."""
    folder = tmp_path / "locked"
    folder.mkdir()
    if os.getuid() == 0:
        if subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode:
            pytest.skip("running as root and cannot make a folder immutable (chattr +i)")
        yield folder
        subprocess.run(["chattr", "-i", str(folder)], check=True)
    else:
        folder.chmod(0o555)
        yield folder
        folder.chmod(0o755)


def test_collect_and_reproduce_into_a_read_only_folder_say_so_in_one_line(read_only, tmp_path,
                                                                         capsys):
    """Seen: a PermissionError traceback."""
    from drake_continuum.objects.dataset import generate_dataset
    dataset = tmp_path / "objects"
    generate_dataset(dataset, counts={"apple": 1}, workers=1, progress=False)
    for argv in (["collect", dataset, "--out", read_only / "wraps", "--no-progress"],
                 ["collect", dataset, "--out", read_only, "--no-progress"],
                 ["reproduce", "--quick", "--out", read_only / "results"],
                 ["objects", "generate", "--out", read_only]):
        rc, out, err = _run(capsys, *argv)
        assert rc == 1 and out == ""
        line, = err.strip().splitlines()
        assert line.startswith(f"drake-continuum {argv[0]}: error: {read_only}") \
            and "cannot write" in line, line
    assert list(read_only.iterdir()) == []


# ------------------------------------------------------------------ Ctrl-C

def _interrupt_when(argv, ready, cwd, timeout=300):
    """Run the command line in its own process group and, once `ready()` holds, press Ctrl-C
    as an impatient user does: SIGINT to the whole group (as a terminal sends it), again at
    once (it lands while the first is being handled: workers stopping, lock and temporary
    files going), and once more after the run has said it was interrupted (it lands while the
    interpreter shuts down). (exit code, stdout, stderr). Nothing here waits on a clock: the
    signals follow what the run has written."""
    proc = subprocess.Popen([sys.executable, "-m", "drake_continuum", *map(str, argv)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=cwd, start_new_session=True)
    err, said = [], threading.Event()

    def read_stderr():
        for line in proc.stderr:
            err.append(line)
            if ": interrupted" in line:
                said.set()
    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    try:
        t0 = time.monotonic()
        while not ready() and proc.poll() is None and time.monotonic() - t0 < timeout:
            time.sleep(0.05)  # polls a file the run writes; the run's pace does not matter
        assert proc.poll() is None, "the command ended before it could be interrupted: " + \
            "".join(err)
        os.killpg(proc.pid, signal.SIGINT)
        os.killpg(proc.pid, signal.SIGINT)
        assert said.wait(timeout), "no 'interrupted' message: " + "".join(err)
        try:
            os.killpg(proc.pid, signal.SIGINT)
        except ProcessLookupError:  # it had already ended
            pass
        out = proc.stdout.read()
        proc.wait(timeout)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    reader.join(timeout)
    return proc.returncode, out, "".join(err)


def _stored(out: Path) -> list[str]:
    """Objects index.json lists as stored (it is written as the run ends, atomically)."""
    try:
        return [o["object_id"] for o in json.loads((out / "index.json").read_text())["objects"]]
    except (OSError, ValueError, KeyError):
        return []


def _object_files(out: Path) -> list[str]:
    """Objects whose .json is written (the last of an object's files, atomically)."""
    return sorted(p.stem for p in out.glob("*.json") if p.name != "index.json")


def test_ctrl_c_in_collect_says_how_to_resume_and_exits_130(tmp_path, monkeypatch):
    """Seen: a KeyboardInterrupt traceback (resuming worked); then, on a loaded machine, the
    process killed by a second Ctrl-C during its shutdown (exit -2) instead of exit 130."""
    from drake_continuum.learning.records import read_object_wraps
    from drake_continuum.objects.dataset import generate_dataset
    dataset = tmp_path / "objects"
    generate_dataset(dataset, counts={"apple": 1, "cup": 1, "mug": 2, "bottle": 2},
                     workers=1, progress=False)
    out = tmp_path / "wraps"
    argv = ["collect", dataset, "--out", out, "--workers", 1, "--no-progress",
            "--set", "planes.alpha_deg=90"]  # 4 planes an object
    # Once the first object is stored and the next begun (its mesh unpacked into a
    # temporary folder of TMPDIR: a private one shows it): four more to go, seconds each.
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setenv("TMPDIR", str(scratch))
    rc, stdout, err = _interrupt_when(
        argv, lambda: bool(_object_files(out) and list(scratch.glob("drake-continuum-*/*"))),
        tmp_path)
    assert rc == 130, err
    assert err.strip().splitlines()[-1] == \
        "drake-continuum collect: interrupted; rerun the same command to resume"
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    assert stdout == ""
    assert not list(out.glob(".*"))  # no lock, no temporary file left
    stored = _stored(out)
    assert 1 <= len(stored) < 6 and sorted(stored) == _object_files(out)  # none left out
    for oid in stored:  # whole: every listed object reads back with all its wraps
        meta, wraps = read_object_wraps(out, oid)
        assert len(wraps) == meta["n_wraps"] == 4


def test_ctrl_c_in_reproduce_says_how_to_resume_and_exits_130(tmp_path):
    out = tmp_path / "results"
    argv = ["reproduce", "--quick", "--out", out, "--workers", 2]
    # Once the dataset's (forked) workers have written a mesh.
    rc, stdout, err = _interrupt_when(argv, lambda: any((out / "dataset").glob("*.obj")),
                                      tmp_path)
    assert rc == 130, err
    assert err.strip().splitlines()[-1] == \
        "drake-continuum reproduce: interrupted; rerun the same command to resume"
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    assert stdout == ""
    assert not list((out / "dataset").glob(".*.tmp"))


# ------------------------------------------------------------------ angles and JSON

@pytest.mark.parametrize("option,value", [("--rx", "nan"), ("--ry", "inf"), ("--ry=-inf", None)])
def test_wrap_refuses_non_finite_angles(option, value, capsys):
    """Seen: exit 0, status empty_cut, and JSON with bare NaN / Infinity."""
    given = [option] if value is None else [option, value]  # "--ry=-inf": not an option
    rc, out, err = _run(capsys, "wrap", MODELS_DIR / "mug.obj", *given, "--json")
    assert rc == 1 and out == ""
    line, = err.strip().splitlines()
    assert option[:4] in line and "finite" in line


def test_make_plane_refuses_non_finite_angles():
    from drake_continuum.wrapping.planes import make_plane
    for angle in (float("nan"), float("inf")):
        with pytest.raises(ValueError, match="finite"):
            make_plane(np.zeros(3), "y", angle)


def test_json_output_is_always_standard(capsys):
    """One helper writes every JSON file and printout: NaN and infinities become null."""
    from drake_continuum.cli.common import print_json
    from drake_continuum.files import json_text

    def strict(text):
        return json.loads(text, parse_constant=lambda c: pytest.fail(f"non-standard {c}"))

    data = {"a": float("nan"), "b": np.array([np.inf, 1.5]), "c": np.float32(-np.inf),
            "d": (1, np.int64(2))}
    assert strict(json_text(data)) == {"a": None, "b": [None, 1.5], "c": None, "d": [1, 2]}
    print_json(data)
    assert strict(capsys.readouterr().out) == {"a": None, "b": [None, 1.5], "c": None,
                                               "d": [1, 2]}


def test_no_json_is_written_around_the_helper():
    """Every json.dump(s) of the package goes through files.json_text (allow_nan=False)."""
    offenders = [f"{p.relative_to(PACKAGE)}:{i}" for p in sorted(PACKAGE.rglob("*.py"))
                 if p.name != "files.py"
                 for i, line in enumerate(p.read_text().splitlines(), 1)
                 if "json.dump" in line]
    assert offenders == []


# ------------------------------------------------------------------ atomic writes

def test_every_file_is_written_through_write_atomic():
    """No hand-written temporary-and-rename, no plain write of a result file."""
    patterns = ("os.replace(", ".replace(tmp", "tmp.replace(", ".write_text(", ".write_bytes(",
                "savefig(path", "savefig(tmp", "savefig(png", "open(path, \"w")
    offenders = [f"{p.relative_to(PACKAGE)}:{i}: {line.strip()}"
                 for p in sorted(PACKAGE.rglob("*.py")) if p.name != "files.py"
                 for i, line in enumerate(p.read_text().splitlines(), 1)
                 if any(s in line for s in patterns)]
    assert offenders == []


def test_write_atomic_syncs_before_the_rename_and_keeps_the_old_file_on_failure(
        tmp_path, monkeypatch):
    from drake_continuum import files
    events = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(files.os, "fsync", lambda fd: (events.append("fsync"), real_fsync(fd)))
    monkeypatch.setattr(files.os, "replace",
                        lambda a, b: (events.append("rename"), real_replace(a, b)))
    path = tmp_path / "a.json"
    files.write_atomic(path, b"old")
    assert events[:2] == ["fsync", "rename"]  # the data is on disk before it gets the name

    def crash(f):
        f.write(b"half of the new")
        raise OSError("disk full")
    with pytest.raises(OSError, match="disk full"):
        files.write_atomic(path, crash)
    assert path.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == ["a.json"]


# ------------------------------------------------------------------ large meshes

def test_a_large_mesh_is_warned_about(tmp_path, capsys, monkeypatch):
    """Seen: a 442k-triangle mesh took 15.7 s and 1.43 GB a wrap, without a word."""
    from drake_continuum.objects import mesh as mesh_module
    big = trimesh.load(MODELS_DIR / "mug.obj").subdivide().subdivide().subdivide()
    warning = mesh_module.size_warning(big, "scan.obj")
    assert f"{len(big.faces):,} triangles" in warning and "--simplify" in warning
    assert mesh_module.size_warning(trimesh.load(MODELS_DIR / "mug.obj"), "mug.obj") is None
    # The command line gives it before wrapping (a lowered limit keeps the wrap cheap).
    monkeypatch.setattr(mesh_module, "TRIANGLE_LIMIT", 2000)
    rc, out, err = _run(capsys, "wrap", MODELS_DIR / "mug.obj", "--plane", 1)
    assert rc == 0 and "warning: " in err and "2,194 triangles" in err and "--simplify" in err


def test_simplify_keeps_a_sphere_within_the_stated_tolerance():
    """Open3D quadric decimation, checked against the sphere itself (not the tool's own
    distance): every vertex and every face centre of the result within the tolerance of
    radius r."""
    from drake_continuum.objects.mesh import simplify_mesh
    r, tol = 0.05, 0.0005
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=r)  # 81,920 triangles
    low, deviation = simplify_mesh(sphere, tol)
    assert low.is_watertight and len(low.faces) <= len(sphere.faces) // 8
    assert 0 < deviation <= tol
    for points in (low.vertices, low.triangles_center):
        assert np.abs(np.linalg.norm(points, axis=1) - r).max() <= tol
    with pytest.raises(ValueError, match="positive"):
        simplify_mesh(sphere, 0.0)


def test_wrap_with_simplify_wraps_the_decimated_mesh(tmp_path, capsys):
    """A mesh subdivided 64-fold (140k triangles, the same surface) is decimated back to a
    few thousand triangles and wraps as the original does."""
    mug = trimesh.load(MODELS_DIR / "mug.obj")
    big = tmp_path / "mug_fine.obj"
    big.write_bytes(trimesh.exchange.obj.export_obj(
        mug.subdivide().subdivide().subdivide()).encode())
    rc, out, err = _run(capsys, "wrap", big, "--plane", 1, "--simplify", "0.5", "--json")
    assert rc == 0, err
    assert "simplified" in err and "140,416 -> " in err and "warning" not in err
    done = json.loads(out)
    rc, out, _ = _run(capsys, "wrap", MODELS_DIR / "mug.obj", "--plane", 1, "--json")
    original = json.loads(out)
    assert done["status"] == original["status"] == "complete"
    assert abs(done["tip_rotation_deg"] - original["tip_rotation_deg"]) < 5.0
    rc, _, err = _run(capsys, "wrap", big, "--plane", 1, "--simplify", "nan")
    assert rc == 1 and "--simplify" in err


# ------------------------------------------------------------------ issue 36: names, folders

def _box_dataset(folder, ids=("box_000",), files=None):
    """A dataset of small boxes written by hand: manifest records with the given ids and
    file names (default <id>.obj), so that a manifest can name anything."""
    from drake_continuum.objects.dataset import manifest_record, write_manifest
    folder.mkdir(parents=True, exist_ok=True)
    mesh = trimesh.creation.box((0.05, 0.05, 0.08))
    mesh.apply_translation((0, 0, 0.04))
    records = []
    for k, oid in enumerate(ids):
        file = (files or {}).get(oid, f"box_{k}.obj")
        mesh.export(folder / f"box_{k}.obj")
        records.append(manifest_record(oid, "box", file, params={}, mesh=mesh, scale=1.0))
    write_manifest(folder, records, "imported", seed=None)
    return folder


@pytest.mark.parametrize("oid", ["../../../ESCAPED", "/tmp/ESCAPED", "a/b", "..", "C:x"])
def test_manifest_object_id_that_is_a_path_is_refused(tmp_path, capsys, oid):
    """Seen: collect wrote <id>.npz and .json wherever a manifest's id pointed."""
    from drake_continuum.objects.dataset import DatasetError, load_manifest
    data = _box_dataset(tmp_path / "a" / "b" / "data", [oid])
    with pytest.raises(DatasetError, match="object 0 id.*not a plain file name"):
        load_manifest(data)
    rc, out, err = _run(capsys, "collect", data, "--out", tmp_path / "a" / "b" / "wraps",
                        "--no-progress")
    assert rc == 1 and "manifest.json" in err and len(err.strip().splitlines()) == 1
    assert not list(tmp_path.rglob("ESCAPED*")) and not (tmp_path / "a" / "b" / "wraps").exists()


def test_manifest_file_outside_the_dataset_is_refused(tmp_path):
    from drake_continuum.objects.dataset import DatasetError, load_manifest
    data = _box_dataset(tmp_path / "data", ["box_000"], {"box_000": "../box_0.obj"})
    shutil.copy(data / "box_0.obj", tmp_path / "box_0.obj")
    with pytest.raises(DatasetError, match="object 0 file.*'../box_0.obj'"):
        load_manifest(data)


def test_collection_index_id_that_is_a_path_is_refused_by_every_reader(copy, tmp_path, capsys):
    """Seen: train followed `../` ids listed in a collection's index.json."""
    from drake_continuum.experiments.collect import write_object
    from drake_continuum.learning.records import load_collection, read_object_wraps
    outside = tmp_path / "outside"
    shutil.copytree(copy, outside)  # the escaped id would find readable files there
    index = json.loads((copy / "index.json").read_text())
    first = index["objects"][0]["object_id"]
    index["objects"][0]["object_id"] = f"../outside/{first}"
    (copy / "index.json").write_text(json.dumps(index))
    with pytest.raises(ValueError, match="index.json: object id.*not a plain file name"):
        load_collection(copy)
    rc, out, err = _run(capsys, "train", copy, "--out", tmp_path / "model")
    assert rc == 1 and "index.json" in err and "not a plain file name" in err
    assert not (tmp_path / "model").exists()
    with pytest.raises(ValueError, match="not a plain file name"):
        read_object_wraps(copy, f"../outside/{first}")
    entry = type("E", (), {"id": "../escaped", "category": "box", "path": Path("x.obj")})()
    with pytest.raises(ValueError, match="not a plain file name"):
        write_object(copy, entry, "0", wraps=[], time_s=0.0, cpu_s=0.0, params={}, labels={})
    assert not (tmp_path / "escaped.npz").exists()


def _manifest_bytes(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_an_output_folder_that_is_an_input_is_refused_before_writing(tmp_path, capsys):
    """Seen: `objects place DS --out DS` replaced a 185-object manifest with a 1-object one;
    `objects import --out SRC` wrote into the source."""
    data = _box_dataset(tmp_path / "data", ["box_000", "box_001"])
    before = _manifest_bytes(data)
    for out in (data, data / "inside"):
        rc, _, err = _run(capsys, "objects", "place", data, "--out", out, "--rest-pose", "0",
                          "--force")
        assert rc == 1 and "is the input folder" in err and str(data) in err
        assert len(err.strip().splitlines()) == 1
    src = tmp_path / "src"
    (src / "mug").mkdir(parents=True)
    shutil.copy(data / "box_0.obj", src / "mug" / "one.obj")
    rc, _, err = _run(capsys, "objects", "import", src, "--out", src, "--units", "m")
    assert rc == 1 and "is the input folder" in err
    assert sorted(p.relative_to(src).as_posix() for p in src.rglob("*")) == ["mug", "mug/one.obj"]
    assert _manifest_bytes(data) == before


def test_an_existing_dataset_is_not_overwritten_without_force(tmp_path, capsys, monkeypatch):
    """Seen: `objects generate` over an existing dataset overwrote every mesh silently."""
    from drake_continuum.objects import dataset as ds
    data = _box_dataset(tmp_path / "data", ["box_000"])
    before = _manifest_bytes(data)
    monkeypatch.setattr(ds, "CATEGORY_COUNTS", {"apple": 1})
    rc, out, err = _run(capsys, "objects", "generate", "--out", data, "--workers", "1")
    assert rc == 1 and out == "" and "already holds a dataset" in err and "--force" in err
    assert _manifest_bytes(data) == before
    placed = tmp_path / "placed"
    assert _run(capsys, "objects", "place", data, "--out", placed, "--rest-pose", "0",
                "-q")[0] == 0
    placed_before = _manifest_bytes(placed)
    rc, _, err = _run(capsys, "objects", "place", data, "--out", placed, "--turn", "30")
    assert rc == 1 and "already holds a dataset" in err
    assert _manifest_bytes(placed) == placed_before
    assert _run(capsys, "objects", "generate", "--out", data, "--workers", "1", "--force",
                "-q")[0] == 0
    assert [e.id for e in ds.load_manifest(data)] == ["apple_000"]


# ------------------------------------------------------------------ issue 36: arm and settings

def _arm_tree():
    import yaml
    return yaml.safe_load((MODELS_DIR / "arm.yaml").read_text())


@pytest.mark.parametrize("key, value, says", [
    ("n_sections", 2.7, "n_sections: must be a whole number"),
    ("n_sections", 1, "n_sections: must be from 2 .*to 20, got 1"),
    ("curvature_max", float("nan"), "curvature_max: must be a finite number > 0"),
    ("curvature_max", float("inf"), "curvature_max: must be a finite number > 0"),
    ("bend_max", float("nan"), "bend_max: must be a finite number > 0"),
    ("bend_max", 0.0, "bend_max: must be a finite number > 0"),
    ("base_rpy", [float("nan"), 1.57, 0.0], "base_rpy: must be 3 finite numbers"),
    ("base_rpy", [0.0, 1.57], "base_rpy: must be 3 finite numbers"),
    ("radius", float("nan"), "radius: must be a finite number > 0"),
    ("radius", 0.5, r"radius: must be below 1 / curvature_max = 0.025 m .*got 0.5"),
    ("base_position", [3.0, 0.0, 0.05], "base_position: .*farther .*than the arm reaches"),
])
def test_an_arm_description_out_of_range_is_refused_naming_the_key(tmp_path, capsys, key,
                                                                   value, says):
    """Seen: NaN or inf curvature_max, bend_max NaN or 0 gave no_contact for a mug within
    reach; a NaN base_rpy wrote a cloud with no arm in it; n_sections 2.7 became 2 and 1 was
    a ZeroDivisionError; radius NaN a Drake failure; a 0.5 m radius ran for 400 s."""
    import yaml

    from drake_continuum.errors import ConfigError
    from drake_continuum.kinematics.arm import ContinuumArm
    arm = {**_arm_tree(), key: value}
    with pytest.raises(ConfigError, match=f"arm X: {says}"):
        ContinuumArm.from_dict(arm, "arm X")
    (tmp_path / "arm.yaml").write_text(yaml.safe_dump(arm))
    config = (MODELS_DIR / "config.yaml").read_text()
    (tmp_path / "config.yaml").write_text(config)
    rc, out, err = _run(capsys, "wrap", MODELS_DIR / "mug.obj", "--plane", "0", "--config",
                        tmp_path / "config.yaml")
    line, = err.strip().splitlines()
    assert rc == 1 and out == "" and key in line and str(tmp_path / "arm.yaml") in line


def test_every_arm_key_swept_is_refused_or_valid():
    """NaN, inf, 0, -1 and 1e9 in every key of the arm: a ConfigError naming the key, except
    base poses that stay within reach and any finite base angle."""
    from drake_continuum.errors import ConfigError
    from drake_continuum.kinematics.arm import ContinuumArm
    accepted = []
    for key in _arm_tree():
        for v in (float("nan"), float("inf"), 0, -1, 1e9):
            arm = _arm_tree()
            arm[key] = [v, 0.0, 0.0] if isinstance(arm[key], list) else v
            try:
                ContinuumArm.from_dict(arm)
                accepted.append((key, v))
            except ConfigError as e:
                assert key in str(e), (key, v, str(e))
    assert accepted == [("base_position", 0), ("base_position", -1), ("base_rpy", 0),
                        ("base_rpy", -1), ("base_rpy", 1e9)]


def _numeric_keys(node, prefix=""):
    for k, v in node.items():
        if isinstance(v, dict):
            yield from _numeric_keys(v, f"{prefix}{k}.")
        elif isinstance(v, (int, float, list)) and not isinstance(v, bool):
            yield f"{prefix}{k}"


def test_every_numeric_setting_swept_is_refused_naming_it_or_accepted_by_rule():
    """NaN, inf, 0, -1, 1e9 (as a float and a whole number) in every numeric setting: a
    ConfigError naming the key, or a value the setting's rule accepts (0 meaning none, a
    stop ratio never reached, a seed)."""
    from drake_continuum.config import load_config, read_config_tree
    from drake_continuum.errors import ConfigError
    tree, _ = read_config_tree()
    accepted = set()
    for key in _numeric_keys(tree):
        for v in (".nan", ".inf", "0", "-1", "1.0e+9", "1000000000"):
            value = f"[{v}, 0.12]" if key == "wrap.start_lengths" else v
            try:
                load_config(overrides=[f"{key}={value}"])
                accepted.add((key, v))
            except ConfigError as e:
                line, = str(e).splitlines()
                assert f"{key.split('.')[-1]}" in line, (key, v, line)
    zero = {"wrap.start_clearance", "wrap.stall_turn_deg", "wrap.press_depth",
            "wrap.ik.penetration_tolerance", "chords.min_length", "classifier.coarse",
            "classifier.tie_width", "observed.tie_width",
            "classifier.wrap_weight", "classifier.extent_weight", "classifier.view_weight",
            "active.exploration", "active.cost_weight", "active.strong_probability",
            "active.start_plane", "active.seed"}
    assert accepted == ({(k, "0") for k in zero} | {("active.strong_ratio", "1.0e+9"),
                        ("active.strong_ratio", "1000000000"), ("active.seed", "1000000000"),
                        ("active.seed", "1.0e+9")})  # a whole float reads as an int (Drake)


@pytest.mark.parametrize("assignment, says", [
    ("wrap.delta=1.0e+9", r"wrap.delta: must be in \(0, 0.1\] m"),
    ("active.start_plane=99", r"active.start_plane: must be below the number of planes \(10"),
    ("active.neighbours=1000000000", "active.neighbours: must be from 1 to 1,000"),
    ("classifier.coarse=8", r"classifier.coarse: must be at most bins \(7\)"),
])
def test_settings_beyond_what_the_run_can_use_are_refused(assignment, says):
    """Seen: active.start_plane=99 an IndexError, wrap.delta=1e9 an OSQP error."""
    from drake_continuum.config import load_config
    from drake_continuum.errors import ConfigError
    with pytest.raises(ConfigError, match=says):
        load_config(overrides=[assignment])


def test_a_number_without_a_dot_is_a_number(tmp_path):
    """Seen: --set wrap.delta=1e-3 refused as not a number (YAML 1.1 reads it as text)."""
    from drake_continuum.config import load_config
    assert load_config(overrides=["wrap.delta=1e-3", "wrap.start_lengths=[1e-1, 2E-1]"]
                       ).wrap.delta == 0.001
    text = (MODELS_DIR / "config.yaml").read_text().replace("delta: 1.0e-3", "delta: 2e-3")
    assert "delta: 2e-3" in text
    (tmp_path / "config.yaml").write_text(text)
    (tmp_path / "arm.yaml").write_text((MODELS_DIR / "arm.yaml").read_text()
                                       .replace("radius: 0.010", "radius: 1e-2"))
    config = load_config(tmp_path / "config.yaml")
    assert config.wrap.delta == 0.002 and config.arm().radius == 0.01


def test_a_binary_configuration_is_refused_in_one_line(tmp_path, capsys):
    """Seen: a UnicodeDecodeError."""
    bad = tmp_path / "config.yaml"
    bad.write_bytes(bytes(range(256)))
    rc, out, err = _run(capsys, "wrap", MODELS_DIR / "mug.obj", "--plane", "0", "--config", bad)
    line, = err.strip().splitlines()
    assert rc == 1 and str(bad) in line and "not a text file" in line


# ------------------------------------------------------------------ issue 36: mixed collections

def _collected(folder, objects, params=None):
    """A collection written by collect's own writer (write_object: each object's params and
    .npz SHA-256) and index entries, from synthetic wraps; returns the run's params."""
    from types import SimpleNamespace

    from drake_continuum.experiments.collection import (
        FORMAT,
        FORMAT_VERSION,
        INDEX_NAME,
        index_entry,
        run_params,
        write_object,
    )
    from drake_continuum.files import write_json
    folder.mkdir(parents=True, exist_ok=True)
    params = run_params() if params is None else params
    metas = [write_object(folder, SimpleNamespace(id=oid, category=cat, path=Path(f"{oid}.obj"),
                                                  placement=None),
                          "0" * 64, wraps=wraps, time_s=1.0, cpu_s=1.0, params=params, labels={})
             for oid, cat, wraps in objects]
    write_json(folder / INDEX_NAME, {"format": FORMAT, "format_version": FORMAT_VERSION,
                                     "dataset": str(folder), "params": params,
                                     "objects": [index_entry(m) for m in metas], "failed": []})
    return params


@pytest.fixture(scope="module")
def collected(tmp_path_factory):
    folder = tmp_path_factory.mktemp("collected") / "wraps"
    _collected(folder, separable_objects(4, 3))
    return folder


def test_an_object_made_with_other_parameters_is_refused_by_every_reader(collected, tmp_path,
                                                                         capsys):
    """Seen: train and evaluate accepted a collection into which one object made with
    wrap.delta=0.004 was copied, though collect refuses the same folder."""
    from dataclasses import replace

    from drake_continuum.config import load_config
    from drake_continuum.experiments.collection import run_params
    from drake_continuum.learning.records import MixedCollectionError, load_collection
    wraps = tmp_path / "wraps"
    shutil.copytree(collected, wraps)
    other = tmp_path / "other"
    shipped = load_config()
    _collected(other, separable_objects(4, 3)[:1],
               run_params(replace(shipped, wrap=replace(shipped.wrap, delta=0.004))))
    for suffix in (".json", ".npz"):
        shutil.copy(other / f"circle_00{suffix}", wraps / f"circle_00{suffix}")
    with pytest.raises(MixedCollectionError, match=r"circle_00.json: made with other "
                       r"parameters .*wrap_params.delta \(collection 0.001, object 0.004\)"):
        load_collection(wraps)
    for argv in (["train", wraps, "--out", tmp_path / "model"],
                 ["evaluate", wraps, "--splits", 2, "--out", tmp_path / "ev"],
                 ["train-active", wraps, "--out", tmp_path / "active"]):
        rc, out, err = _run(capsys, *argv)
        line, = err.strip().splitlines()
        assert rc == 1 and "circle_00.json: made with other parameters" in line, argv
    assert not (tmp_path / "model").exists() and not (tmp_path / "ev").exists()


def test_swapped_object_files_are_named_and_left_out(collected, tmp_path):
    """Seen: two objects' .npz files swapped were trained under each other's labels."""
    from drake_continuum.learning.records import load_collection
    wraps = tmp_path / "wraps"
    shutil.copytree(collected, wraps)
    a, b = wraps / "circle_01.npz", wraps / "square_02.npz"
    data = a.read_bytes()
    a.write_bytes(b.read_bytes())
    b.write_bytes(data)
    records, skipped = load_collection(wraps)
    assert sorted(r.object_id for r in records) == sorted(
        f"{c}_0{i}" for c in ("circle", "square") for i in range(4)
        if f"{c}_0{i}" not in ("circle_01", "square_02"))
    reasons = {s["object_id"]: s["reason"] for s in skipped}
    assert sorted(reasons) == ["circle_01", "square_02"]
    assert all("SHA-256 differs" in r for r in reasons.values())
    # Both files of each renamed as the other's: the id recorded inside names them.
    shutil.rmtree(wraps)
    shutil.copytree(collected, wraps)
    for suffix in (".json", ".npz"):
        (wraps / f"circle_01{suffix}").rename(wraps / f"tmp{suffix}")
        (wraps / f"square_02{suffix}").rename(wraps / f"circle_01{suffix}")
        (wraps / f"tmp{suffix}").rename(wraps / f"square_02{suffix}")
    reasons = {s["object_id"]: s["reason"] for s in load_collection(wraps)[1]}
    assert sorted(reasons) == ["circle_01", "square_02"]
    assert "records object 'square_02', not 'circle_01'" in reasons["circle_01"]


def test_collect_redoes_an_object_whose_npz_is_damaged(collected, tmp_path):
    """Seen: after one .npz was damaged, collect reported it done and never redid it."""
    from drake_continuum.experiments.collection import finished_object, run_params
    wraps = tmp_path / "wraps"
    shutil.copytree(collected, wraps)
    params = run_params()
    assert finished_object(wraps, "circle_00", params) is not None
    npz = wraps / "circle_00.npz"
    good = npz.read_bytes()
    middle = len(good) // 2  # inside an array: still a zip archive
    npz.write_bytes(good[:middle] + bytes([good[middle] ^ 0xFF]) + good[middle + 1:])
    import zipfile
    assert zipfile.is_zipfile(npz)
    assert finished_object(wraps, "circle_00", params) is None
    # An object stored before the digest was recorded: every array is read (CRC-checked).
    meta = json.loads((wraps / "circle_00.json").read_text())
    del meta["npz_sha256"]
    (wraps / "circle_00.json").write_text(json.dumps(meta))
    assert finished_object(wraps, "circle_00", params) is None
    npz.write_bytes(good)
    assert finished_object(wraps, "circle_00", params) is not None
    shutil.copy(wraps / "circle_01.json", wraps / "circle_00.json")  # another object's
    assert finished_object(wraps, "circle_00", params) is None


# ------------------------------------------------------------------ issue 36: the rest

def test_an_empty_id_list_is_refused_not_taken_as_all(tmp_path, capsys):
    """Seen: `--ids ""` (an empty shell variable) started a full collection."""
    data = _box_dataset(tmp_path / "data", ["box_000", "box_001"])
    for argv in (["collect", data, "--out", tmp_path / "wraps", "--ids", "", "--no-progress"],
                 ["objects", "place", data, "--out", tmp_path / "placed", "--ids", " , "]):
        rc, out, err = _run(capsys, *argv)
        line, = err.strip().splitlines()
        assert rc == 1 and "object ids: none given" in line, argv
    assert not (tmp_path / "wraps").exists() and not (tmp_path / "placed").exists()


@pytest.mark.parametrize("kind", ["fifo", "dev_zero"])
def test_special_files_are_refused_before_reading(tmp_path, capsys, kind):
    """Seen: a FIFO as a mesh hung collect with its lock held; a symlink to /dev/zero was
    read whole into memory."""
    mesh = tmp_path / "special.obj"
    if kind == "fifo":
        os.mkfifo(mesh)
    else:
        mesh.symlink_to("/dev/zero")
    what = "a FIFO (named pipe)" if kind == "fifo" else "a device"
    rc, out, err = _run(capsys, "wrap", mesh, "--plane", "0")
    line, = err.strip().splitlines()
    assert rc == 1 and f"{mesh}: is {what}, not a regular file" in line
    data = _box_dataset(tmp_path / "data", ["box_000"])
    (data / "box_0.obj").unlink()
    os.symlink(mesh, data / "box_0.obj")
    rc, out, err = _run(capsys, "collect", data, "--out", tmp_path / "wraps", "--no-progress")
    assert rc == 1 and "not a regular file" in err and not (tmp_path / "wraps").exists()
    config = tmp_path / "config.yaml"
    config.symlink_to(mesh)
    rc, out, err = _run(capsys, "wrap", MODELS_DIR / "mug.obj", "--plane", "0", "--config",
                        config)
    assert rc == 1 and "not a regular file" in err


def _plus_one(x):
    return x + 1.0


def test_compiled_kernels_fall_back_to_a_private_cache_or_none(monkeypatch, tmp_path):
    """The decision compiled.py takes at import, where numba can write no cache folder."""
    import numba
    import numba.core.caching as caching

    from drake_continuum.kinematics import compiled
    monkeypatch.setattr(numba.config, "CACHE_DIR", "")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(caching.CacheImpl, "_locator_classes",
                        [caching.UserProvidedCacheLocator])
    f, cached = compiled._cached(_plus_one)
    folder = tmp_path / f"drake-continuum-numba-{os.getuid()}"
    assert cached and numba.config.CACHE_DIR == str(folder) and f(1.0) == 2.0
    assert folder.stat().st_mode & 0o777 == 0o700
    folder.chmod(0o777)  # open to others: could hold someone else's code, not used
    monkeypatch.setattr(numba.config, "CACHE_DIR", "")
    f, cached = compiled._cached(_plus_one)
    assert not cached and numba.config.CACHE_DIR == "" and f(2.0) == 3.0
    monkeypatch.setattr(caching.CacheImpl, "_locator_classes", [])
    f, cached = compiled._cached(_plus_one)
    assert not cached and f(3.0) == 4.0


@pytest.mark.slow
@pytest.mark.parametrize("locators, cached", [("[c.UserProvidedCacheLocator]", True),
                                              ("[]", False)])
def test_a_read_only_install_still_imports_and_computes(locators, cached, tmp_path):
    """Seen: run by a user who can write neither into the installed package nor a home
    folder, every command died at import with numba's "cannot cache function '_sinc': no
    locator available". Simulated by taking away numba's folder locators: the kernels are
    cached in the user's own temporary folder, or not cached, and still agree with numpy."""
    code = f"""
import numba.core.caching as c
c.CacheImpl._locator_classes = {locators}
import numpy as np
from drake_continuum.kinematics import compiled
from drake_continuum.kinematics.arm import ArmConfig, ContinuumArm
arm = ContinuumArm()
q = ArmConfig([0.2, 0.25, 0.3], [5.0, 10.0, 2.0], [0.0, 1.0, -2.0])
tip = arm.backbone(q, np.array([0.75])).position[-1]
print(compiled._CACHE, np.abs(tip - arm.tip_frame(q)[1]).max())
"""
    env = {**os.environ, "NUMBA_CACHE_DIR": "", "TMPDIR": str(tmp_path)}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, timeout=300)
    assert run.returncode == 0, run.stderr
    flag, error = run.stdout.split()
    assert flag == str(cached) and float(error) < 1e-12
    assert (tmp_path / f"drake-continuum-numba-{os.getuid()}").is_dir()


def _interrupted_after(delay: float | None):
    """(exit status, stdout, stderr) of a wrap given Ctrl-C `delay` s after its start
    (None: left to finish)."""
    run = subprocess.Popen([sys.executable, "-m", "drake_continuum", "wrap",
                            str(MODELS_DIR / "mug.obj"), "--plane", "0", "--json"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if delay is not None:
        time.sleep(delay)
        run.send_signal(signal.SIGINT)
    out, err = run.communicate(timeout=300)
    return run.returncode, out, err


def _assert_interrupted(rc, out, err):
    line, = err.strip().splitlines()
    assert rc == 130 and out == "" and line in ("drake-continuum: interrupted",
                                                "drake-continuum wrap: interrupted"), err


def test_ctrl_c_while_the_command_line_imports_exits_130_in_one_line():
    """Seen: Ctrl-C in the first ~1.2 s of a command was swallowed (the run completed with
    exit 0), a raw traceback or an internal error."""
    _assert_interrupted(*_interrupted_after(0.5))


@pytest.mark.slow
def test_ctrl_c_at_any_moment_of_the_start_exits_130_in_one_line():
    """The moments stay within the start: a Ctrl-C once the wrap has ended its work (about
    3 s on a quiet core) meets the interpreter's exit, which restores the kernel's default."""
    t0 = time.monotonic()
    rc, out, err = _interrupted_after(None)
    assert rc == 0 and out, err
    for delay in np.linspace(0.3, min(2.5, 0.6 * (time.monotonic() - t0)), 12):
        _assert_interrupted(*_interrupted_after(float(delay)))


def test_readers_name_what_they_were_given_instead(collection, trained, tmp_path, capsys):
    """Seen: `evaluate objects` leaked KeyError: 'n_wraps'; `show-wraps` with an unknown id
    leaked [Errno 2]; `recognize` given a `train` model said observations.json: file not
    found; evaluate's "at least 4 objects" misstated its rule."""
    data = _box_dataset(tmp_path / "objects", ["box_000"])
    rc, out, err = _run(capsys, "evaluate", data, "--out", tmp_path / "ev")
    line, = err.strip().splitlines()
    assert rc == 1 and "an object dataset (manifest.json), not a wrap collection" in line \
        and f"collect {data} --out" in line
    rc, out, err = _run(capsys, "show-wraps", collection, "circle_99", "--png", tmp_path / "x.png")
    line, = err.strip().splitlines()
    assert rc == 1 and "no object 'circle_99'" in line and "Errno" not in line
    rc, out, err = _run(capsys, "recognize", trained / "model", MODELS_DIR / "mug.obj")
    line, = err.strip().splitlines()
    assert rc == 1 and "made by `drake-continuum train`" in line and "train-active" in line
    few = tmp_path / "few"
    write_collection(few, [o for o in separable_objects(5, 2)  # 5 circles, 3 squares
                           if o[1] == "circle" or o[0] < "square_03"])
    rc, out, err = _run(capsys, "evaluate", few, "--splits", 2, "--out", tmp_path / "ev")
    line, = err.strip().splitlines()
    assert rc == 1 and "every category needs at least 4 objects" in line \
        and "too few in {'square': 3}" in line


@pytest.mark.parametrize("argv, says", [
    (["--splits", "0"], "splits must be at least 1, got 0"),
    (["--splits", "-3"], "splits must be at least 1, got -3"),
])
def test_reproduce_refuses_no_splits_before_anything_starts(tmp_path, capsys, argv, says):
    """Seen: `--splits 0` started a collection before it was refused."""
    out_dir = tmp_path / "results"
    rc, out, err = _run(capsys, "reproduce", "--quick", "--out", out_dir, *argv)
    line, = err.strip().splitlines()
    assert rc == 1 and says in line and not out_dir.exists()


def test_reproduce_quick_keeps_the_splits_it_is_given():
    """Seen: `reproduce --splits 50 --quick` was silently cut to 20."""
    from drake_continuum.experiments.settings import RunSettings, run_command
    assert RunSettings(quick=True, splits=50).effective_splits == 50
    assert RunSettings(quick=True).effective_splits == 20
    assert RunSettings().effective_splits == 100
    assert "--splits 50" in run_command({"quick": True, "splits": 50})
    assert "--splits" not in run_command({"quick": True, "splits": 20})


@pytest.mark.parametrize("argv, key", [
    (["collect", "DATA", "--out", "OUT", "--bearing", "object", "--set",
      "planes.bearing=world"], "planes.bearing"),
    (["collect", "DATA", "--out", "OUT", "--both-directions", "--set",
      "planes.both_directions=false"], "planes.both_directions"),
    (["train", "WRAPS", "--out", "OUT", "--frame", "wrap", "--set", "chords.frame=world"],
     "chords.frame"),
])
def test_a_flag_and_a_set_that_disagree_are_refused(collection, tmp_path, capsys, argv, key):
    """Seen: command-line flags silently overridden by --set."""
    data = _box_dataset(tmp_path / "data", ["box_000"])
    argv = [{"DATA": data, "OUT": tmp_path / "out", "WRAPS": collection}.get(a, a)
            for a in argv]
    rc, out, err = _run(capsys, *argv)
    line, = err.strip().splitlines()
    assert rc == 1 and f"contradicts the command's own option, which sets {key}" in line
    assert not (tmp_path / "out").exists()


def test_a_set_the_command_does_not_use_is_named_in_a_warning(collection, tmp_path, capsys):
    """Seen: `train --set wrap.delta=...` silently ignored (train takes the collection's wrap
    settings); agreeing flags and --set pass."""
    rc, out, err = _run(capsys, "train", collection, "--out", tmp_path / "model", "--frame",
                        "world", "--set", "chords.frame=world", "--set", "wrap.delta=0.004")
    assert rc == 0
    assert err.strip().splitlines() == ["warning: --set wrap.delta=0.004: `train` does not use "
                                        "the wrap settings; it changes nothing"]


def test_an_inside_out_mesh_is_turned_outward_with_a_warning(tmp_path, caplog):
    """Seen: an inside-out mesh was accepted and its wraps sank 4.2 mm into the surface."""
    from drake_continuum.objects.mesh import load_mesh
    box = trimesh.creation.box((0.06, 0.05, 0.08))
    inside_out = trimesh.Trimesh(box.vertices, box.faces[:, ::-1], process=False)
    assert inside_out.volume < 0
    path = tmp_path / "inside_out.obj"
    inside_out.export(path)
    with caplog.at_level("WARNING"):
        mesh = load_mesh(path)
    assert "inside out" in caplog.text and str(path) in caplog.text
    assert mesh.volume == pytest.approx(0.06 * 0.05 * 0.08)
    outward = np.einsum("ij,ij->i", mesh.face_normals, mesh.triangles_center - mesh.centroid)
    assert np.all(outward > 0)
    caplog.clear()
    box.export(tmp_path / "box.obj")
    load_mesh(tmp_path / "box.obj")
    assert "inside out" not in caplog.text


@pytest.fixture
def box_views(tmp_path):
    """The shipped box_0 cloud and its sidecar, copied twice as two views."""
    from importlib.resources import files
    clouds = Path(str(files("drake_continuum.clouds")))
    views = []
    for k in range(2):
        for suffix in (".pcd", ".json"):
            shutil.copy(clouds / f"box_0{suffix}", tmp_path / f"view{k}{suffix}")
        views.append(tmp_path / f"view{k}.pcd")
    return views


@pytest.mark.parametrize("change, says", [
    (lambda m: m.update(base_rpy=[float("nan"), 0.3, -1.0]), "base_rpy must be 3 finite"),
    (lambda m: m.pop("base_position"), "base_position and base_rpy come together"),
    (lambda m: m.update(camera={"eye": [0.3, "x", 0.8]}), "camera.eye must be 3 finite"),
    (None, "damaged sidecar (not JSON"),
])
def test_fit_cloud_refuses_a_damaged_sidecar(box_views, capsys, change, says):
    """Seen: a damaged sidecar was ignored and the fit on the default base reported a wrong
    configuration as confident."""
    side = box_views[0].with_suffix(".json")
    if change is None:
        side.write_text(side.read_text()[:200])
    else:
        meta = json.loads(side.read_text())
        change(meta)
        side.write_text(json.dumps(meta))
    rc, out, err = _run(capsys, "fit-cloud", box_views[0])
    line, = err.strip().splitlines()
    assert rc == 1 and out == "" and str(side) in line and says in line


def test_fused_views_of_different_base_poses_are_refused(box_views, capsys):
    """Seen: `fit-cloud A.pcd B.pcd` fused two wraps with different base poses (residual
    12 mm, 33 % inliers), exit 0."""
    from drake_continuum.perception.cloud import sidecar_base
    position, rpy, _ = sidecar_base(box_views)  # two views of one wrap agree
    side = box_views[1].with_suffix(".json")
    meta = json.loads(side.read_text())
    meta["base_rpy"] = [meta["base_rpy"][0] + 0.2, *meta["base_rpy"][1:]]
    side.write_text(json.dumps(meta))
    rc, out, err = _run(capsys, "fit-cloud", *box_views)
    line, = err.strip().splitlines()
    assert rc == 1 and str(side) in line and "views fused into one fit must be of one wrap" \
        in line


def test_a_full_disk_names_the_file_and_keeps_the_old_one(tmp_path):
    """Seen: full-disk errors named no path."""
    import errno

    from drake_continuum.files import NotWritableError, write_atomic
    target = tmp_path / "index.json"
    target.write_text("old")

    def full(fh):
        fh.write(b"new, half")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(NotWritableError, match=f"{target}: cannot be written \\(No space left"):
        write_atomic(target, full)
    assert target.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == \
        ["index.json"]


def test_compare_real_with_another_object_than_the_sidecars_is_named(box_views, tmp_path):
    """Seen: compare-real against the wrong object reported a closer match than against the
    right one, without a word."""
    from importlib.resources import files

    from drake_continuum.perception.comparison import other_object
    clouds = Path(str(files("drake_continuum.clouds")))
    side = box_views[0].with_suffix(".json")
    meta = json.loads(side.read_text())
    meta["object"] = str(clouds / "box.obj")
    side.write_text(json.dumps(meta))
    assert other_object(str(box_views[0]), clouds / "box.obj") is None
    shutil.copy(clouds / "box.obj", tmp_path / "renamed.obj")  # the same mesh by content
    assert other_object(str(box_views[0]), tmp_path / "renamed.obj") is None
    says = other_object(str(box_views[0]), clouds / "cylinder.obj")
    assert says == (f"{side} records the wrap of {clouds / 'box.obj'}, not of "
                    f"{clouds / 'cylinder.obj'}: the comparison is with another object")
    meta["object"] = "elsewhere/box.obj"  # not readable here: compared by name
    side.write_text(json.dumps(meta))
    assert other_object(str(box_views[0]), clouds / "box.obj") is None
    assert other_object(str(box_views[0]), clouds / "cylinder.obj") is not None


def test_wrap_and_fit_cloud_name_a_set_they_do_not_use(box_views, capsys):
    rc, out, err = _run(capsys, "wrap", MODELS_DIR / "mug.obj", "--plane", "0", "--set",
                        "classifier.bins=5", "--set", "wrap.theta_deg=1000")
    assert rc == 1 and err.strip().splitlines() == [
        "warning: --set classifier.bins=5: `wrap` does not use the classifier settings; it "
        "changes nothing",
        "drake-continuum wrap: error: --set 'wrap.theta_deg=1000': "
        "wrap.theta_deg: must be in (0, 720] deg, got 1000"]
    side = box_views[0].with_suffix(".json")
    side.write_text("{")
    rc, out, err = _run(capsys, "fit-cloud", box_views[0], "--set", "wrap.delta=0.002")
    assert rc == 1 and err.strip().splitlines()[0] == (
        "warning: --set wrap.delta=0.002: `fit-cloud` does not use the wrap settings; it "
        "changes nothing")


def test_a_ctrl_c_a_library_turned_into_its_own_error_is_an_interruption(monkeypatch, capsys):
    """Seen (1 of 30 trials at 0.2-4 s): a Ctrl-C while pydrake initialised a module became
    "internal error: ImportError: initialization failed" (pybind11 raises it from the
    KeyboardInterrupt)."""
    def interrupted_import(args):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as e:
            raise ImportError("initialization failed") from e

    handler = signal.getsignal(signal.SIGINT)  # an interrupted run ignores further Ctrl-Cs
    monkeypatch.setattr(signal, "signal", lambda *a: handler)
    monkeypatch.setattr(cli, "COMMANDS", [(n, a, interrupted_import if n == "wrap" else r)
                                          for n, a, r in cli.COMMANDS])
    rc, out, err = _run(capsys, "wrap", MODELS_DIR / "mug.obj", "--plane", "0")
    assert rc == 130 and err == "drake-continuum wrap: interrupted\n"
    monkeypatch.setattr(cli, "COMMANDS", [(n, a, (lambda args: 1 / 0) if n == "wrap" else r)
                                          for n, a, r in cli.COMMANDS])
    rc, out, err = _run(capsys, "wrap", MODELS_DIR / "mug.obj", "--plane", "0")
    assert rc == cli.INTERNAL_ERROR and "internal error: ZeroDivisionError" in err


def test_a_ctrl_c_a_library_swallowed_still_ends_the_run_as_interrupted(monkeypatch, capsys):
    """Seen: a Ctrl-C whose KeyboardInterrupt Python ignored (raised in rtree's ctypes
    callback) let the run complete with exit 0."""
    def swallowing(args):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1)
        except KeyboardInterrupt:  # as Python does with an exception in a ctypes callback
            pass
        return 0

    monkeypatch.setattr(cli, "COMMANDS", [(n, a, swallowing if n == "collect" else r)
                                          for n, a, r in cli.COMMANDS])
    handler = signal.getsignal(signal.SIGINT)
    try:
        rc, out, err = _run(capsys, "collect", "DATA", "--out", "OUT")
    finally:
        signal.signal(signal.SIGINT, handler)
    assert rc == 130 and err == ("drake-continuum collect: interrupted; rerun the same command "
                                 "to resume\n")


def test_a_ctrl_c_inside_an_import_ends_the_process_in_one_line(tmp_path):
    """Seen: a Ctrl-C during pydrake's initialisation printed Drake's 'Could not initialize
    pydrake' and its stack; one during Open3D's import ended with its memory statistics and
    status 1."""
    (tmp_path / "slow_to_import.py").write_text(
        "import os, signal, time\nos.kill(os.getpid(), signal.SIGINT)\ntime.sleep(5)\n")
    code = ("from drake_continuum import workers\n"
            "workers.interruptible_once('drake-continuum demo: interrupted')\n"
            "import slow_to_import\nprint('not reached')\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=tmp_path, timeout=60)
    assert (run.returncode, run.stdout, run.stderr) == (130, "",
                                                        "drake-continuum demo: interrupted\n")


def test_scene_queries_before_a_configuration_is_posed_say_to_call_set_config():
    """Seen: contacts() before set_config() was a bare AttributeError ('_link_arc'), and
    touching_links() answered about capsules all sitting at the origin."""
    from drake_continuum.kinematics.arm import ArmConfig, load_arm
    from drake_continuum.wrapping.scene import WrapScene

    scene = WrapScene(load_arm(), MODELS_DIR / "mug.obj")
    for ask in (scene.contacts, scene.touching_links, scene.in_contact,
                lambda: scene.touching_depths([0]), lambda: scene.posed_link_arcs):
        with pytest.raises(RuntimeError, match=r"call set_config\(config\) first"):
            ask()
    scene.set_config(ArmConfig.straight([0.15, 0.15, 0.15]))
    assert isinstance(scene.touching_links(), np.ndarray)
