"""Partly hidden arms: free space as evidence, several views, the commanded configuration and
the commanded wrap plane as priors, and how sure a fit says it is (against the true
configuration of simulated clouds)."""

import json

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from drake_continuum import cli
from drake_continuum.kinematics.arm import ArmConfig, load_arm
from drake_continuum.perception import depth_camera as dc
from drake_continuum.perception import freespace as fs
from drake_continuum.perception.cloud import Cloud, PointCloudError
from drake_continuum.perception.confidence import AMBIGUOUS_TIP
from drake_continuum.perception.fitting import fit_cloud
from drake_continuum.perception.residuals import FREE_OK, ConfigPrior, WrapPlane

ARM = load_arm()
CONFIG = ArmConfig([0.15, 0.20, 0.18], [2.0, 9.0, 14.0], [1.3, 1.4, 1.6])
TIP = ARM.tip_frame(CONFIG)[1]


def _cylinder():
    m = trimesh.creation.cylinder(radius=0.04, height=0.12)
    m.apply_translation((0, 0, 0.06))
    return m


def _arm_points(sim):
    return sim.points[sim.labels == dc.LABELS["arm"]]


def test_cameras_around_puts_the_second_opposite():
    first = dc.CameraPose()
    one, two = dc.cameras_around(2, first)
    assert one == first  # bit for bit: a fit given a rounded eye is another fit
    d = np.subtract(first.eye, first.target)
    assert np.subtract(two.eye, two.target) == pytest.approx([-d[0], -d[1], d[2]])
    four = dc.cameras_around(4, first)
    assert np.subtract(four[1].eye, first.target) == pytest.approx([-d[1], d[0], d[2]])


def test_ray_cast_and_smooth_free_space_term_agree():
    """At the true configuration no ray passes through the arm; swung where the camera saw
    the table, many do, and the exact ray cast (Open3D) and the fit's term (analytic
    distances of rays from the backbone) count the same rays."""
    sim = dc.render_cloud(ARM, CONFIG, _cylinder(), noise=False)
    rays = fs.free_rays(sim.points, sim.camera.eye, arm_points=_arm_points(sim))
    term = fs.FreeSpaceTerm(ARM, rays)
    assert fs.violations(ARM, CONFIG, rays).sum() == 0
    assert term.count(ARM.backbone(CONFIG, n=200)) == 0
    swung = ArmConfig(CONFIG.s, CONFIG.kappa, CONFIG.phi + np.array([np.pi / 2, 0, 0]))
    exact = int(fs.violations(ARM, swung, rays).sum())
    smooth = term.count(ARM.backbone(swung, n=200))
    assert exact > 100
    assert abs(exact - smooth) <= 0.1 * exact


def _hidden_tip_cloud(seed=4, hide=0.15, config=CONFIG):
    """A noisy cloud whose last `hide` m of arm returned no depth, and the arc length of
    every arm point."""
    sim = dc.render_cloud(ARM, config, _cylinder(), seed=seed)
    bb = ARM.backbone(config, n=600)
    arc = bb.arc_length[cKDTree(bb.position).query(sim.points)[1]]
    drop = (sim.labels == dc.LABELS["arm"]) & (arc > np.sum(config.s) - hide)
    return Cloud(sim.points[~drop], sim.colours[~drop]), sim.camera.eye


def _plane_normal(phi):
    """The world normal of the plane every section bends in when each bends towards phi."""
    return tuple(ARM.base_rotation @ np.array([-np.sin(phi), np.cos(phi), 0.0]))


def _off_plane(config, normal):
    """The farthest the centre line lies from the plane through the base, m."""
    p = ARM.backbone(config, n=200).position
    return float(np.abs((p - ARM.base_position) @ np.asarray(normal)).max())


def test_the_wrap_plane_holds_a_hidden_section_and_gives_way_to_a_seen_one():
    # A planar wrap whose last 0.15 m the camera did not see: without the plane the hidden
    # part turns out of it at no cost; with it, it stays in the plane.
    planar = ArmConfig(CONFIG.s, CONFIG.kappa, [1.4, 1.4, 1.4])
    normal = _plane_normal(1.4)
    assert _off_plane(planar, normal) < 1e-9
    cloud, _ = _hidden_tip_cloud(config=planar)
    _, free = fit_cloud(cloud, ARM, planar.s)
    _, held = fit_cloud(cloud, ARM, planar.s, plane=WrapPlane(normal))
    assert _off_plane(held.config, normal) < 1e-3 < _off_plane(free.config, normal)
    # An arm the camera sees whole, 40 mm out of the plane given: the points win.
    normal = _plane_normal(1.3)
    assert _off_plane(CONFIG, normal) > 0.03
    sim = dc.render_cloud(ARM, CONFIG, None, seed=2)
    _, fit = fit_cloud(Cloud(sim.points, sim.colours), ARM, CONFIG.s, eye=sim.camera.eye,
                       plane=WrapPlane(normal))
    assert np.linalg.norm(fit.tip - TIP) < 3e-3


def test_a_wrap_plane_is_three_finite_numbers():
    with pytest.raises(PointCloudError, match="normal must be 3 finite numbers"):
        WrapPlane((0.0, 0.0, 0.0))


def test_seen_cloud_is_confident_and_right():
    sim = dc.render_cloud(ARM, CONFIG, None, seed=2)  # nothing hides the arm
    seg, fit = fit_cloud(Cloud(sim.points, sim.colours), ARM, CONFIG.s,
                            eye=sim.camera.eye)
    c = fit.confidence
    assert np.linalg.norm(fit.tip - TIP) < 3e-3
    assert min(c.seen_fraction) > 0.9
    assert not c.ambiguous
    assert c.free_space_rays <= FREE_OK
    assert c.tip_uncertainty < 5e-3


def test_hidden_tip_is_flagged_and_the_prior_recovers_it():
    cloud, eye = _hidden_tip_cloud()
    seg, fit = fit_cloud(cloud, ARM, CONFIG.s, eye=eye)
    c = fit.confidence
    assert c.partly_unseen and c.seen_fraction[2] < 0.3
    assert c.ambiguous and c.tip_uncertainty > AMBIGUOUS_TIP
    # The command, off the truth by a little, with its uncertainty: the hidden tip follows it
    # as far as the points allow, and the fit says how far that is.
    command = ArmConfig(CONFIG.s, CONFIG.kappa + np.array([0.1, -0.1, 0.15]),
                        CONFIG.phi + np.array([0.01, -0.01, 0.01]))
    assert np.linalg.norm(ARM.tip_frame(command)[1] - TIP) < 3e-3
    prior = ConfigPrior(command, sigma_s=0.01, sigma_kappa=0.3, sigma_phi=0.05)
    seg, with_prior = fit_cloud(cloud, ARM, CONFIG.s, eye=eye, prior=prior)
    err_prior = np.linalg.norm(with_prior.tip - TIP)
    assert err_prior < 6e-3 < np.linalg.norm(fit.tip - TIP)
    assert err_prior < with_prior.confidence.tip_uncertainty


def test_prior_residuals_are_standard_deviations():
    """A prior residual is (value - command) / sigma in units of the points' noise."""
    prior = ConfigPrior(CONFIG, sigma_s=0.01, sigma_kappa=2.0, sigma_phi=0.1)
    s = CONFIG.s + np.array([0.01, 0.0, 0.0])
    k = CONFIG.kappa + np.array([0.0, 2.0, 0.0])
    phi = CONFIG.phi + np.array([0.0, 0.0, 0.05])
    u, v = k * np.cos(phi), k * np.sin(phi)
    r = prior.residuals(s, u, v) / prior.NOISE
    n = CONFIG.n_sections
    radial, across, lengths = r[:n], r[n:2 * n], r[2 * n:]
    assert lengths == pytest.approx([1, 0, 0])
    # Turning a 14 1/m bend by 0.05 rad moves (u, v) kappa sin 0.05 across and
    # kappa (cos 0.05 - 1) along it; across is measured against hypot(14 * 0.1, 2) 1/m.
    k3 = CONFIG.kappa[2]
    assert radial == pytest.approx([0, 1, k3 * (np.cos(0.05) - 1) / 2.0])
    assert across == pytest.approx([0, 0, k3 * np.sin(0.05) / np.hypot(k3 * 0.1, 2.0)])
    with pytest.raises(ValueError, match="positive"):
        ConfigPrior(CONFIG, sigma_s=0.0)


def test_cli_two_views_fit_and_bad_camera_or_prior(tmp_path, capsys):
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps(CONFIG.to_dict()))
    mesh = tmp_path / "cyl.obj"
    _cylinder().export(mesh)
    out = tmp_path / "c.pcd"
    assert cli.main(["simulate-cloud", str(mesh), "--arm-config", str(cfg), "--out", str(out),
                     "--cameras", "2", "--voxel", "0.004"]) == 0
    views = [tmp_path / "c_view0.pcd", tmp_path / "c_view1.pcd"]
    metas = [json.loads(v.with_suffix(".json").read_text()) for v in views]
    assert metas[0]["camera"]["eye"] != metas[1]["camera"]["eye"]
    assert metas[1]["views"] == ["c_view0.pcd", "c_view1.pcd"]
    capsys.readouterr()
    assert cli.main(["fit-cloud", *map(str, views), "--json",
                     "--lengths", ",".join(map(str, CONFIG.s))]) == 0
    res = json.loads(capsys.readouterr().out)
    assert np.linalg.norm(np.array(res["tip"]) - metas[0]["tip"]) < 3e-3
    assert res["confidence"]["free_space_rays"] is not None
    assert len(res["clouds"]) == 2
    assert cli.main(["fit-cloud", *map(str, views), "--camera", "0.3,-0.5,0.85"]) == 1
    assert "--camera given 1 times for 2 cloud(s)" in capsys.readouterr().err
    assert cli.main(["fit-cloud", str(views[0]), "--prior", str(tmp_path / "no.json")]) == 1
    assert "--prior" in capsys.readouterr().err and "no.json" not in ""
    assert cli.main(["fit-cloud", str(views[0]), "--prior", '{"s": [0.1]}']) == 1
    assert "--prior: not an arm configuration" in capsys.readouterr().err


def test_simulate_cloud_wraps_over_the_table_unless_told_otherwise(tmp_path):
    """A wrap of the cylinder on plane 3 runs 7 cm under the table top without the table;
    the cloud to compare with a real arm comes from the wrap that stops at the table (its
    backbone a tube radius above z = 0, within IK's tolerance), and the sidecar says so."""
    mesh = tmp_path / "cyl.obj"
    _cylinder().export(mesh)
    low = {}
    for name, extra in (("table", []), ("through", ["--set", "wrap.table=false"])):
        out = tmp_path / f"{name}.pcd"
        assert cli.main(["simulate-cloud", str(mesh), "--plane", "3", "--out", str(out),
                         "--voxel", "0.01", *extra]) == 0
        meta = json.loads(out.with_suffix(".json").read_text())
        from pydrake.math import RollPitchYaw
        arm = ARM.with_base(np.asarray(meta["base_position"]),
                            RollPitchYaw(meta["base_rpy"]).ToRotationMatrix().matrix())
        low[name] = (meta["wrap_table"], float(arm.backbone(
            ArmConfig.from_dict(meta["config"]), n=400).position[:, 2].min()))
    assert low["table"][0] is True and low["through"][0] is False
    assert low["table"][1] >= ARM.radius - 2e-3
    assert low["through"][1] < -0.01


@pytest.fixture(scope="module")
def ambiguous_case(tmp_path_factory):
    """A cloud whose tip returned no depth, its object and a small trained model; the
    compare-real arguments that call a category from it."""
    from drake_continuum.learning.model import save_model, train
    from drake_continuum.learning.records import object_record
    from synthetic_wraps import object_wraps, shape_contour

    tmp_path = tmp_path_factory.mktemp("ambiguous")
    rng = np.random.default_rng(5)
    objs = [object_record(f"{c}{i}", c, object_wraps(shape_contour(c, size, 1), 3, rng))
            for i in range(4) for c, size in (("circle", 0.03), ("square", 0.08))]
    save_model(train(objs, seed=0), tmp_path / "model")
    cloud, eye = _hidden_tip_cloud()
    path = tmp_path / "hidden.pcd"
    dc.write_cloud(path, cloud.points, cloud.colours)
    mesh = tmp_path / "cyl.obj"
    _cylinder().export(mesh)
    return tmp_path, ["compare-real", str(path), "--object", str(mesh), "--model",
                      str(tmp_path / "model"), "--camera", ",".join(map(str, eye)),
                      "--lengths", ",".join(map(str, CONFIG.s))]


def test_compare_real_refuses_a_category_from_an_ambiguous_fit(ambiguous_case, capsys):
    capsys.readouterr()
    assert cli.main(ambiguous_case[1]) == 1
    err = capsys.readouterr().err
    assert "ambiguous" in err and "--force" in err and "hidden.pcd" in err


@pytest.mark.slow
def test_compare_real_forced_against_the_commanded_wrap(ambiguous_case, capsys):
    """--force calls it anyway, and says so; with --prior the simulated wrap is the
    command's."""
    tmp_path, args = ambiguous_case
    cfg = tmp_path / "command.json"
    cfg.write_text(json.dumps({"config": CONFIG.to_dict()}))
    capsys.readouterr()
    assert cli.main(args + ["--force", "--json", "--prior", str(cfg)]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["forced"] and res["simulated_at"].startswith("commanded")
    assert res["chords"]["category_real"] in ("circle", "square")
    assert res["deviation"]["mean_mm"] < 3.0


def test_each_bins_nearest_point_is_lexsorts_and_row_norms_are_numpys():
    """free_rays' bins against np.lexsort on keys in runs with repeated distances (ties go to
    the first point), and row_norms against np.linalg.norm, to the bit."""
    from drake_continuum.perception.cloud import row_norms

    rng = np.random.default_rng(3)
    key = np.repeat(rng.integers(0, 400, 300), rng.integers(1, 30, 300)).astype(np.int64)
    dist = rng.integers(0, 5, len(key)) * 0.25  # many equal distances in a bin
    order = np.lexsort((dist, key))
    first = np.ones(len(order), bool)
    first[1:] = key[order][1:] != key[order][:-1]
    assert np.array_equal(fs._nearest_of_each(key, dist), order[first])
    assert len(fs._nearest_of_each(key[:0], dist[:0])) == 0
    d = rng.normal(size=(10_000, 3)) * rng.uniform(1e-3, 10.0, (10_000, 1))
    assert np.array_equal(row_norms(d), np.linalg.norm(d, axis=1))
