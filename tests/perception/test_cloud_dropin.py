"""docs/clouds.md's contract: a lab's capture in the documented form (here a shipped cloud
re-saved in millimetres with a minimal real sidecar) drops into the report's comparison, is
fitted as well as the original and is not called simulated."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import open3d as o3d

from drake_continuum.perception.comparison import compare_shipped_clouds

ROOT = Path(__file__).resolve().parents[2]
DOC = (ROOT / "docs" / "clouds.md").read_text()


def test_a_capture_in_the_documented_form_drops_in(tmp_path):
    shipped = json.loads((ROOT / "real" / "data" / "cylinder_0.json").read_text())
    pcd = o3d.io.read_point_cloud(str(ROOT / "real" / "data" / "cylinder_0.pcd"))
    pcd.points = o3d.utility.Vector3dVector(1000.0 * np.asarray(pcd.points))  # millimetres
    data = tmp_path / "data"
    data.mkdir()
    o3d.io.write_point_cloud(str(data / "lab_0.pcd"), pcd)
    # The keys the document says the report's comparison needs, and no simulator's keys.
    sidecar = {"capture": "kinect", "object": "real/data/cylinder.obj",
               **{k: shipped[k] for k in ("base_position", "base_rpy", "config")}}
    for key in sidecar:
        assert f"`{key}`" in DOC
    (data / "lab_0.json").write_text(json.dumps(sidecar))

    rows = compare_shipped_clouds(tmp_path / "out", data_dir=data)["clouds"]
    assert [r["cloud"] for r in rows] == ["lab_0.pcd"]
    assert rows[0]["capture"] == "real"
    assert rows[0]["camera"] == "none"  # no camera in the sidecar: no free-space term
    # read as millimetres, the fit finds the true tip (the shipped cloud's fit is within a
    # few millimetres; a cloud left 1000x too large would find no arm at all)
    assert rows[0]["tip_error_mm"] < 15
    assert (tmp_path / "out" / "fig8_lab_0.png").stat().st_size > 10_000


def test_shipped_sidecars_name_their_mesh_inside_the_checkout():
    """Fig. 8 loads each sidecar's mesh relative to the project folder: an absolute path
    (a developer's worktree) works only on the machine that wrote it."""
    sidecars = sorted((ROOT / "real" / "data").glob("*.json"))
    assert sidecars
    for path in sidecars:
        mesh = Path(json.loads(path.read_text())["object"])
        assert not mesh.is_absolute(), f"{path.name}: {mesh}"
        assert (ROOT / mesh).is_file(), f"{path.name}: {mesh}"


def test_the_shipped_clouds_are_fitted_with_their_sidecars_camera(tmp_path, monkeypatch):
    # As `fit-cloud` does: the free space the sidecar's camera saw through is evidence, and
    # the table says so; a sidecar without a camera (the lab's above) fits without it.
    from drake_continuum.perception import comparison

    shipped = json.loads((ROOT / "real" / "data" / "cylinder_0.json").read_text())
    data = tmp_path / "data"
    data.mkdir()
    (data / "sim_0.pcd").write_bytes((ROOT / "real" / "data" / "cylinder_0.pcd").read_bytes())
    (data / "sim_0.json").write_text(json.dumps({**shipped, "object": "real/data/cylinder.obj"}))
    eyes, fit_cloud = [], comparison.fit_cloud

    def spy(*args, **kwargs):
        eyes.append(kwargs.get("eye"))
        return fit_cloud(*args, **kwargs)

    monkeypatch.setattr(comparison, "fit_cloud", spy)
    rows = compare_shipped_clouds(tmp_path / "out", data_dir=data)["clouds"]
    np.testing.assert_allclose(eyes[0], shipped["camera"]["eye"])
    assert rows[0]["camera"] == "sidecar"
    assert rows[0]["tip_error_mm"] < 3


def test_a_cached_comparison_fits_no_cloud_again_and_a_changed_cloud_is_fitted(tmp_path,
                                                                             monkeypatch):
    from drake_continuum.perception import comparison

    shipped = json.loads((ROOT / "real" / "data" / "cylinder_0.json").read_text())
    data, out, cache = tmp_path / "data", tmp_path / "out", tmp_path / "cache"
    data.mkdir()
    (data / "sim_0.pcd").write_bytes((ROOT / "real" / "data" / "cylinder_0.pcd").read_bytes())
    (data / "sim_0.json").write_text(json.dumps({**shipped, "object": "real/data/cylinder.obj"}))
    fits, fit_cloud = [], comparison.fit_cloud

    def counted(*args, **kwargs):
        fits.append(args[0].source)
        return fit_cloud(*args, **kwargs)

    monkeypatch.setattr(comparison, "fit_cloud", counted)
    first = compare_shipped_clouds(out, data_dir=data, cache=cache)
    assert len(fits) == 1 and first["clouds"][0]["histogram_distance"] is not None
    (out / "fig8_sim_0.png").unlink()
    # The chords are taken again from the cached samples: the same figures, no fit.
    assert compare_shipped_clouds(out, data_dir=data, cache=cache) == first
    assert len(fits) == 1 and (out / "fig8_sim_0.png").stat().st_size > 10_000
    pcd = o3d.io.read_point_cloud(str(data / "sim_0.pcd"))
    pcd.points = o3d.utility.Vector3dVector(np.asarray(pcd.points)[:-1])
    pcd.colors = o3d.utility.Vector3dVector(np.asarray(pcd.colors)[:-1])
    o3d.io.write_point_cloud(str(data / "sim_0.pcd"), pcd)
    compare_shipped_clouds(out, data_dir=data, cache=cache)
    assert len(fits) == 2
