"""A real wrap against its simulation: the fitted arm's surface against the points, the
chords of the real and the simulated wrap, Fig. 8, and the shipped sample clouds.
"""

from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError, MissingFileError
from ..files import jsonable, write_atomic, write_json
from ..kinematics.arm import ARM_COLOUR, MODELS_DIR, ArmConfig, ContinuumArm
from .cloud import SAMPLE_CLOUDS, Cloud, load_cloud, read_sidecar
from .fitting import ArmFit, fit_cloud
from .medial import FitParams
from .residuals import Residuals, centre_line
from .search import unseen_intervals
from .segmentation import Segmentation

__all__ = ["surface_deviation", "WrapSamples", "real_and_simulated_wraps", "chord_comparison",
           "first_contact_arc_length", "OBJECT_TOLERANCE", "object_check", "simulated_cloud",
           "SIMULATED_NOTE", "fig8_figure", "fig8", "compare_real", "compare_shipped_clouds",
           "at_config"]


# --------------------------------------------------------------------------- real vs simulated

def surface_deviation(arm: ContinuumArm, fit: ArmFit, points, spacing: float = 0.005) -> dict:
    """How far the measured arm lies from the simulated arm's surface at the fitted config.

    mean: mean |distance| of the points to the tube surface. Hausdorff: the larger of the
    farthest point from the surface and the farthest seen part of the surface from the
    points (backbone samples on seen arc lengths; the unseen parts and the tube's far side
    cannot be compared with what the camera did not see).
    """
    a = np.abs(fit.residual)
    total = float(np.sum(fit.config.s))
    grid = np.arange(0.0, total, spacing)
    seen = np.ones(len(grid), bool)
    for lo, hi in fit.unseen:
        seen &= ~((grid >= lo) & (grid <= hi))
    pos, _ = centre_line(arm, fit.config, grid[seen])
    back = cKDTree(points).query(pos)[0] - arm.radius if len(pos) else np.zeros(1)
    return {"mean_mm": 1e3 * float(a.mean()), "median_mm": 1e3 * float(np.median(a)),
            "points_to_surface_max_mm": 1e3 * float(a.max()),
            "surface_to_points_max_mm": 1e3 * float(np.max(back)),
            "hausdorff_mm": 1e3 * float(max(a.max(), np.max(back)))}


@dataclass(frozen=True)
class WrapSamples:
    """Centre-line samples of a wrap (first contact to tip), as chords.py reads them.

    Args:
        arc_length: (m,) arc lengths, m; position, normal: (m, 3).
    """

    arc_length: np.ndarray
    position: np.ndarray
    normal: np.ndarray


def real_and_simulated_wraps(arm: ContinuumArm, fit: ArmFit, points, first_contact: float,
                             spacing: float = 0.01, simulated: ArmConfig | None = None):
    """(real, simulated) WrapSamples on the arc lengths from first contact to the tip where
    the camera saw the arm, `spacing` apart.

    The real centre line is measured: each point moved one radius inwards along its
    direction from the fitted backbone, averaged per arc-length bin. The simulated one is the
    backbone of `simulated` (the commanded configuration; default the fitted one) at the same
    arc lengths. Both use that configuration's bending direction as normal (the arm's
    curvature, which a real arm reports, not the object's).
    """
    total = float(np.sum(fit.config.s))
    pos, tan = centre_line(arm, fit.config, fit.arc_length)
    d = points - pos
    perp = d - np.einsum("mi,mi->m", d, tan)[:, None] * tan
    centre = points - arm.radius * perp / np.maximum(np.linalg.norm(perp, axis=1), 1e-9)[:, None]
    inl = (np.abs(fit.residual) <= 2 * FitParams().inlier) & (fit.arc_length >= first_contact)
    b = np.floor((fit.arc_length[inl] - first_contact) / spacing).astype(int)
    nb = int(np.floor((total - first_contact) / spacing)) + 1
    counts = np.bincount(b, minlength=nb)
    sums = np.stack([np.bincount(b, weights=centre[inl][:, i], minlength=nb) for i in range(3)], 1)
    ok = counts >= 3
    arc = first_contact + spacing * (np.arange(nb)[ok] + 0.5)
    arc = np.minimum(arc, total)
    real = sums[ok] / counts[ok, None]
    sim_cfg = fit.config if simulated is None else simulated
    bb = arm.backbone(sim_cfg, arc_length=np.minimum(arc, float(np.sum(sim_cfg.s))))
    return (WrapSamples(arc, real, bb.normal), WrapSamples(arc, bb.position, bb.normal))


def chord_comparison(real: WrapSamples, sim: WrapSamples, model=None) -> dict:
    """Chord-histogram distance (total variation, 0 = same, 1 = disjoint) between the real
    and the simulated wrap and, with a trained model, the category each yields. Without a
    model the histogram's bins span both wraps' chords (7 a dimension, as the paper's)."""
    from ..features.chords import ChordHistogram, ChordParams, chords_from_points

    params = model.chord_params if model is not None else ChordParams()
    cr = chords_from_points(real.position, real.normal, params.min_length)
    cs = chords_from_points(sim.position, sim.normal, params.min_length)
    out = {"n_chords_real": len(cr), "n_chords_simulated": len(cs)}
    if len(cr) == 0 or len(cs) == 0:
        out["histogram_distance"] = None
        out["note"] = "too few seen centre-line points after the first contact for chords"
        return out
    if model is not None:
        from ..features.chords import histogram_rows
        n_cells = int((model.edges.shape[1] - 1) ** model.edges.shape[0])
        H = histogram_rows([model.bin_index(cr), model.bin_index(cs)], n_cells)
        proba = model.predict_proba([cr, cs])
        out["category_real"] = str(model.classes[int(np.argmax(proba[0]))])
        out["category_simulated"] = str(model.classes[int(np.argmax(proba[1]))])
        out["probabilities_real"] = dict(zip(map(str, model.classes), proba[0].tolist()))
        out["probabilities_simulated"] = dict(zip(map(str, model.classes), proba[1].tolist()))
        out["bins"] = "model"
    else:
        H = ChordHistogram(bins=7).fit([cr, cs]).transform([cr, cs])
        out["bins"] = "both wraps, 7 a dimension"
    out["histogram_distance"] = 0.5 * float(abs(H[0] - H[1]).sum())
    return out


def first_contact_arc_length(arm: ContinuumArm, config: ArmConfig, mesh,
                             tolerance: float = 0.003, n: int = 400) -> float | None:
    """Arc length where the arm at `config` first comes within `tolerance` of the object in
    the simulation scene (its signed distance to the real surface, distance.py), or None.

    A tolerance, not exact touch: a fitted configuration is a millimetre or two off the wrap
    that produced it and may stop just short of the surface (or, for a deformed real arm,
    pass into it).
    """
    gap = _surface(mesh).clearance(arm, config, n)
    hit = np.flatnonzero(gap <= tolerance)
    return float(np.sum(config.s) * hit[0] / (n - 1)) if len(hit) else None


def _surface(mesh):
    """The distances to `mesh` (a closed trimesh, or its file) without a Drake scene."""
    from ..objects.mesh import closed_mesh
    from ..wrapping.distance import SurfaceDistance
    return SurfaceDistance(closed_mesh(mesh))


# m: the fitted arm's touching part lies on the object's surface within this (a fit is a
# millimetre or two off the wrap, and a real tube squashes a millimetre or two against it).
OBJECT_TOLERANCE = 0.003


def object_check(arm: ContinuumArm, config: ArmConfig, mesh, n: int = 400) -> dict:
    """Whether the arm at `config` lies against `mesh` as a wrap of that object must: some
    part of its tube within OBJECT_TOLERANCE of the surface (it touches) and none deeper than
    OBJECT_TOLERANCE inside it (it does not pass through). Signed distances to the real
    surface (distance.SurfaceDistance.clearance). A wrap compared with another object fails
    one or the other: it floats beside it or cuts through it.

    Returns {"first_contact_m" (None without a touch), "closest_gap_mm" (negative: inside),
    "matches", "why" (None when it matches)}.
    """
    gap = _surface(mesh).clearance(arm, config, n)
    hit = np.flatnonzero(gap <= OBJECT_TOLERANCE)
    first = float(np.sum(config.s) * hit[0] / (n - 1)) if len(hit) else None
    worst = float(gap.min())
    why = None
    if first is None:
        why = (f"the fitted arm does not touch the object (closest {1e3 * worst:.1f} mm from "
               f"its surface)")
    elif worst < -OBJECT_TOLERANCE:
        why = f"the fitted arm passes {-1e3 * worst:.1f} mm into the object"
    return {"first_contact_m": first, "closest_gap_mm": 1e3 * worst, "matches": why is None,
            "why": why}


def simulated_cloud(path) -> bool:
    """Whether the cloud at `path` was made by the simulated depth camera, not captured: its
    sidecar (`<cloud>.json`) says `"capture": "simulated"` or holds the simulator's sensor
    model (depth_camera.simulate_clouds writes it). A cloud without a sidecar counts as real."""
    sidecar = Path(path).with_suffix(".json")
    try:
        meta = json.loads(sidecar.read_text())
    except (OSError, ValueError):
        return False
    return isinstance(meta, dict) and (meta.get("capture") == "simulated" or "sensor" in meta)


SIMULATED_NOTE = "simulated Kinect cloud (real/make_sample_clouds.py), not a real capture"


def fig8_figure(cloud: Cloud, seg: Segmentation, fit: ArmFit, arm: ContinuumArm, mesh=None,
                title: str = ""):
    """The matplotlib Figure of fig8 (the caller closes it). Constrained layout gives the
    title its own row; three ticks an axis keep the labels apart. A simulated cloud (see
    simulated_cloud) says so in the title."""
    import textwrap

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from .depth_camera import tube_mesh

    lo = seg.points.min(0) - 0.05
    hi = seg.points.max(0) + 0.05
    if mesh is not None:
        lo, hi = np.minimum(lo, mesh.bounds[0]), np.maximum(hi, mesh.bounds[1])
    lo[2] = min(lo[2], 0.0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2
    fig = plt.figure(figsize=(15, 5.5), dpi=110, layout="constrained")
    rng = np.random.default_rng(0)

    def axes(k, name):
        ax = fig.add_subplot(1, 3, k, projection="3d")
        ax.set_title(textwrap.fill(name, 40), fontsize=11)
        for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
            set_lim(c - half, c + half)
        ax.set_box_aspect((1, 1, 1), zoom=0.9)  # room for the 3-D axis labels
        ax.view_init(elev=35, azim=-60)
        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
            axis.set_major_locator(MaxNLocator(3))
        ax.tick_params(labelsize=8, pad=1)
        ax.set_xlabel("x (m)", fontsize=9, labelpad=8)
        ax.set_ylabel("y (m)", fontsize=9, labelpad=8)
        ax.set_zlabel("z (m)", fontsize=9, labelpad=8)
        return ax

    ax = axes(1, "point cloud")
    inside = np.all((cloud.points >= centre - half) & (cloud.points <= centre + half), axis=1)
    idx = np.flatnonzero(inside)
    idx = rng.choice(idx, min(len(idx), 15000), replace=False) if len(idx) else idx
    cols = cloud.colours[idx] if cloud.colours is not None else "0.4"
    ax.scatter(*cloud.points[idx].T, c=cols, s=0.5, depthshade=False)
    ax = axes(2, f"segmented arm ({seg.n_pieces} piece{'s' * (seg.n_pieces != 1)})")
    ax.scatter(*seg.points.T, c=seg.piece, cmap="tab10", vmin=0, vmax=9, s=1.5,
               depthshade=False)
    ax = axes(3, "reconstruction (simulated arm at the fitted configuration)")
    tube = tube_mesh(arm, fit.config, spacing=0.01, n_around=12)
    ax.add_collection3d(Poly3DCollection(tube.vertices[tube.faces], facecolor=ARM_COLOUR,
                                         edgecolor="none", alpha=0.9))
    if mesh is not None:
        ax.add_collection3d(Poly3DCollection(mesh.vertices[mesh.faces], facecolor="0.7",
                                             edgecolor="none", alpha=0.35))
    lines = [title] if title else []
    if simulated_cloud(cloud.source):
        lines.append(SIMULATED_NOTE)
    if lines:
        fig.suptitle("\n".join(lines), fontsize=12)
    return fig


def fig8(path, cloud: Cloud, seg: Segmentation, fit: ArmFit, arm: ContinuumArm, mesh=None,
         title: str = "") -> Path:
    """The paper's Fig. 8 for one wrap: the cloud, the segmented arm, the reconstruction
    (the arm at the fitted configuration, with the object) in three 3-D panels."""
    import matplotlib.pyplot as plt
    path = Path(path)
    fig = fig8_figure(cloud, seg, fit, arm, mesh, title)
    try:
        write_atomic(path, lambda f: fig.savefig(f, format=path.suffix.lstrip(".") or "png"))
    finally:
        plt.close(fig)
    return path


def at_config(arm: ContinuumArm, fit: ArmFit, points, config: ArmConfig,
              params: FitParams = FitParams()) -> ArmFit:
    """The fit's points measured against the arm at another configuration (the commanded
    one): their residuals, arc lengths and unseen intervals there."""
    fun = Residuals(arm, np.asarray(points, float), None)
    near = fun.nearest(config)
    res = fun.at(config, *near[:3])
    return replace(fit, config=config, residual=res, arc_length=near[0],
                   unseen=unseen_intervals(float(np.sum(config.s)), near[0], res,
                                            params=params),
                   tip=arm.tip_frame(config)[1])


log = logging.getLogger(__name__)


def other_object(cloud_source, object_path) -> str | None:
    """Why the cloud's sidecar says it wrapped another object than `object_path` (its
    "object" file differs in content, or, where that file cannot be read here, in name),
    else None. A wrap compared with the wrong object can match it closer than the right one."""
    if not cloud_source:
        return None
    named = read_sidecar(cloud_source).get("object")
    if not named:
        return None
    side = Path(cloud_source).with_suffix(".json")
    given = Path(object_path)
    try:
        same = (hashlib.sha256(Path(named).read_bytes()).digest()
                == hashlib.sha256(given.read_bytes()).digest())
    except OSError:
        same = Path(named).name == given.name
    return None if same else (f"{side} records the wrap of {named}, not of {given}: the "
                              f"comparison is with another object")


def compare_real(cloud: Cloud, seg: Segmentation, fit: ArmFit, arm: ContinuumArm, object_path,
                 model=None, png=None, simulated: ArmConfig | None = None) -> dict:
    """Real against simulated wrap (section V-D): per-point deviation of the segmented arm from
    the simulated arm, the chord-histogram distance between the two wraps and, with a trained
    model, the category each yields; Fig. 8 to `png`.

    The simulated arm is at `simulated`, the commanded configuration when the arm saved it
    (as the paper did, "we also save the arm configurations of the wraps"), else at the
    fitted configuration.
    """
    out, samples = _compared(cloud, seg, fit, arm=arm, object_path=object_path, png=png,
                             simulated=simulated)
    out["chords"] = _chords(samples, model)
    return out


def _compared(cloud, seg, fit, *, arm, object_path, png, simulated) -> tuple[dict, tuple | None]:
    """compare_real's figures but the chords (none of them depends on the model), and the
    (real, simulated) WrapSamples the chords are taken from (None: no touch)."""
    from ..objects.mesh import load_mesh
    mesh = load_mesh(object_path)
    sim_fit = fit if simulated is None else at_config(arm, fit, seg.points, simulated)
    dev = surface_deviation(arm, sim_fit, seg.points)
    check = object_check(arm, fit.config, object_path)
    first = check["first_contact_m"] if simulated is None else \
        first_contact_arc_length(arm, sim_fit.config, object_path)
    out = {"cloud": cloud.source, "object": str(object_path), "fit": fit.to_dict(),
           "simulated_at": "fitted configuration" if simulated is None else
           "commanded configuration (--prior)", "deviation": dev, "first_contact_m": first,
           "object_check": check, "object_matches": check["matches"]}
    warnings = [w for w in (other_object(cloud.source, object_path),
                            None if check["matches"] else
                            f"{cloud.source}: {check['why']}: the cloud is not a wrap of "
                            f"{object_path}") if w is not None]
    for w in warnings:
        log.warning("%s", w)
    if warnings:
        out["warning"] = "; ".join(warnings)
    samples = None if first is None else \
        real_and_simulated_wraps(arm, fit, seg.points, first, simulated=simulated)
    if png is not None:
        out["png"] = str(fig8(png, cloud, seg, fit, arm, mesh,
                              title=f"{Path(cloud.source).name}: deviation mean "
                                    f"{dev['mean_mm']:.1f} mm, Hausdorff "
                                    f"{dev['hausdorff_mm']:.1f} mm"))
    return out, samples


def _chords(samples, model) -> dict:
    """chord_comparison of the (real, simulated) samples, or why there are none."""
    if samples is None:
        return {"histogram_distance": None, "note": "the simulated arm does not touch the object"}
    return chord_comparison(*samples, model)


def compare_shipped_clouds(out_dir, model=None, data_dir=None, *, cache=None) -> dict:
    """compare_real on every sample cloud (SAMPLE_CLOUDS, or the clouds of `data_dir`), each
    with its sidecar JSON: the object mesh (its file beside the cloud), base pose and true
    configuration, whose section lengths are taken as known, and the camera, whose free
    space is evidence as in `fit-cloud`, when the sidecar has one; one Fig. 8 a cloud in
    out_dir; a table of figures. A folder without clouds, or a cloud without its sidecar or
    mesh, is a MissingFileError (never an empty table). With `cache` (a folder) what the
    model does not change (the fit, the deviations, Fig. 8, the chords' samples) is kept
    there a cloud, keyed by what it is made of (_shipped_key), so another model only
    classifies."""
    data_dir = Path(data_dir) if data_dir is not None else SAMPLE_CLOUDS
    clouds = sorted(data_dir.glob("*.pcd"))
    if not clouds:
        raise MissingFileError(f"{data_dir}: no sample cloud (*.pcd) found")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows, first_png = [], None
    for path in clouds:
        sidecar = path.with_suffix(".json")
        if not sidecar.is_file():
            raise MissingFileError(f"{sidecar}: the sidecar of {path.name} is missing")
        meta = json.loads(sidecar.read_text())
        name = Path(meta["object"]).name  # beside the cloud, else a shipped sample or model
        mesh = next((d / name for d in (data_dir, SAMPLE_CLOUDS, MODELS_DIR)
                     if (d / name).is_file()), None)
        if mesh is None:
            raise MissingFileError(f"{data_dir / name}: the object mesh {sidecar.name} names "
                                   f"is missing")
        png = out_dir / f"fig8_{path.stem}.png"
        key = _shipped_key(path, mesh)
        held = _read_shipped(cache, path.stem, key=key, png=png)
        if held is None:
            held = _compare_shipped(path, meta, mesh, png=png)
            if cache is not None:
                _write_shipped(cache, path.stem, key=key, held=held, png=png)
        row = dict(held["row"])
        chords = _chords(held["samples"], model)
        row.update(histogram_distance=chords.get("histogram_distance"), fit_s=row.pop("fit_s"),
                   png=png.name)
        for name in ("category_real", "category_simulated"):
            if name in chords:
                row[name] = chords[name]
        rows.append(row)
        first_png = first_png or png
    return {"clouds": rows, "png": None if first_png is None else
            f"{out_dir.name}/{first_png.name}"}


def _compare_shipped(path: Path, meta: dict, mesh: Path, *, png: Path) -> dict:
    """One shipped cloud fitted and compared (its Fig. 8 to `png`): its row but the chords,
    the chords' (real, simulated) samples and the comparison's warning."""
    from pydrake.math import RollPitchYaw

    from ..kinematics.arm import load_arm
    arm = load_arm().with_base(np.asarray(meta["base_position"], float),
                               RollPitchYaw(meta["base_rpy"]).ToRotationMatrix().matrix())
    truth = ArmConfig.from_dict(meta["config"])
    cloud = load_cloud(path)
    eye = meta.get("camera", {}).get("eye")
    seg, fit = fit_cloud(cloud, arm, truth.s, eye=None if eye is None else np.asarray(eye, float))
    r, samples = _compared(cloud, seg, fit, arm=arm, object_path=mesh, png=png, simulated=None)
    row = {"cloud": path.name, "capture": "simulated" if simulated_cloud(path) else "real",
           "camera": "sidecar" if eye is not None else "none",
           "tip_error_mm": float(1000 * np.linalg.norm(fit.tip - arm.tip_frame(truth)[1])),
           "deviation_mean_mm": r["deviation"]["mean_mm"],
           "hausdorff_mm": r["deviation"]["hausdorff_mm"], "fit_s": fit.time_s}
    return {"row": row, "samples": samples, "warning": r.get("warning")}


def _shipped_key(path: Path, mesh: Path) -> dict:
    """What a shipped cloud's comparison is made of: the cloud, its sidecar, the object, the
    arm, the segmentation's and the fit's parameters and the package's version (its code)."""
    from .. import __version__
    from ..kinematics.arm import DEFAULT_ARM_YAML
    from .segmentation import SegmentParams

    def sha(p):
        return hashlib.sha256(Path(p).read_bytes()).hexdigest()

    return jsonable({"cloud": sha(path), "sidecar": sha(path.with_suffix(".json")),
                     "object": sha(mesh), "arm": sha(DEFAULT_ARM_YAML),
                     "segment": asdict(SegmentParams()), "fit": asdict(FitParams()),
                     "version": __version__})


_SAMPLES = ("real", "simulated")


def _read_shipped(cache, stem: str, *, key: dict, png: Path) -> dict | None:
    """The cached _compare_shipped of a cloud, its Fig. 8 copied to `png`; None when there
    is none or it was made of something else."""
    if cache is None:
        return None
    json_path = Path(cache) / f"{stem}.json"
    try:
        held = json.loads(json_path.read_text())
        if held.get("key") != key:
            return None
        samples = None
        if held["touch"]:
            with np.load(Path(cache) / f"{stem}.npz", allow_pickle=False) as z:
                samples = tuple(WrapSamples(*(z[f"{s}_{f}"] for f in WrapSamples.__annotations__))
                                for s in _SAMPLES)
        image = (Path(cache) / png.name).read_bytes()
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise InputError(f"{json_path}: unreadable comparison cache ({type(e).__name__}: "
                         f"{e}); remove it to fit the clouds again") from None
    write_atomic(png, image)
    if held["warning"]:
        log.warning("%s", held["warning"])
    return {"row": held["row"], "samples": samples, "warning": held["warning"]}


def _write_shipped(cache, stem: str, *, key: dict, held: dict, png: Path) -> None:
    folder = Path(cache)
    folder.mkdir(parents=True, exist_ok=True)
    samples = held["samples"]
    if samples is not None:
        arrays = {f"{s}_{f}": getattr(w, f) for s, w in zip(_SAMPLES, samples)
                  for f in WrapSamples.__annotations__}
        write_atomic(folder / f"{stem}.npz", lambda f: np.savez(f, **arrays))
    write_atomic(folder / png.name, png.read_bytes())
    write_json(folder / f"{stem}.json", {"key": key, "row": held["row"],
                                         "warning": held["warning"],
                                         "touch": samples is not None})
