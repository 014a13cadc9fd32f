"""A folder of captured wraps, classified and recognised in the order they were made.

A capture is one wrap plane's point cloud (or several views of it) with the sidecar of
docs/clouds.md, which for classification also holds `plane` (the wrap plane's index in the
model's plane set) and `contact_arc_length` (where along the arm the tactile skin felt
the object, m) and, for a model that uses the camera's view of the object, `object_view` (its
height, long and short footprint extent, m). Each capture's arm is fitted
(fitting.fit_cloud, section lengths from the sidecar's `config`, free space from its
camera) and rebuilt as a WrapResult on the fitted arm (`captured_result`); the wraps so far
are classified as one object after each capture: the category of all of them, and the one
recognised where the paper's strong-prediction rule first held. `write_captures` makes
such a folder from simulated wraps.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..features.chords import turning_axis
from ..kinematics.arm import ArmConfig, ContinuumArm
from ..wrapping.contact import Contacts
from ..wrapping.wrap import tip_heading
from ..wrapping.wrap_types import WrapResult
from .cloud import CLOUD_SUFFIXES, PointCloudError, load_cloud, sidecar_eyes
from .observe import Observation, centre_line, contact_frames
from .residuals import WrapPlane

__all__ = ["CaptureError", "Capture", "read_captures", "captured_result", "fit_capture",
           "write_captures", "recognise_captures"]

SAMPLE_SPACING = 0.005  # m, centre-line samples of a captured wrap (wrap.sample_spacing's)


class CaptureError(InputError):
    """A capture folder cannot be used (the message names the file and the key)."""


@dataclass(frozen=True)
class Capture:
    """One wrap as captured: its cloud files (one a view) and their sidecars' entries.

    Args:
        paths: the cloud of each view.
        plane: the wrap plane's index.
        arm: the arm with the sidecar's base pose.
        lengths: (n,) section lengths from the sidecar's config, m (None: fitted too).
        eyes: camera position of each view, or None when a sidecar has none.
        contact_arc_length: (m,) arc lengths the arm felt the object at, m.
        view: (3,) the camera's view of the object, or None.
    """

    paths: tuple
    plane: int
    arm: ContinuumArm
    lengths: np.ndarray | None
    eyes: list | None
    contact_arc_length: np.ndarray
    view: np.ndarray | None


def _sidecar(path: Path) -> dict:
    side = path.with_suffix(".json")
    try:
        meta = json.loads(side.read_text())
    except FileNotFoundError:
        raise CaptureError(f"{side}: missing (each capture's cloud needs its sidecar)") from None
    except (OSError, ValueError) as e:
        raise CaptureError(f"{side}: unreadable: {e}") from None
    if not isinstance(meta, dict):
        raise CaptureError(f"{side}: not a JSON object")
    return meta


def _need(meta: dict, key: str, side: Path, what: str):
    if key not in meta:
        raise CaptureError(f"{side}: no {key!r} ({what})")
    return meta[key]


def _capture(paths: list[Path], metas: list[dict], arm: ContinuumArm) -> Capture:
    from pydrake.math import RollPitchYaw

    meta, side = metas[0], paths[0].with_suffix(".json")
    try:
        plane = int(_need(meta, "plane", side, "the wrap plane's index"))
        arcs = np.asarray(_need(meta, "contact_arc_length", side,
                                "where along the arm it touched, m"), dtype=float).reshape(-1)
        R = RollPitchYaw(np.asarray(_need(meta, "base_rpy", side, "the base's roll, pitch, "
                                          "yaw, rad"), float)).ToRotationMatrix().matrix()
        based = arm.with_base(np.asarray(_need(meta, "base_position", side,
                                               "the base's position, m"), float), R)
        lengths = None if "config" not in meta else ArmConfig.from_dict(meta["config"]).s
        view = None if meta.get("object_view") is None else \
            np.asarray(meta["object_view"], float).reshape(3)
    except (TypeError, ValueError, KeyError) as e:
        raise CaptureError(f"{side}: {type(e).__name__}: {e}") from None
    if not len(arcs) or not np.all(np.isfinite(arcs)) or np.any(arcs < 0):
        raise CaptureError(f"{side}: 'contact_arc_length' must be one or more arc lengths "
                           f">= 0 m, got {meta['contact_arc_length']!r}")
    try:
        eyes = sidecar_eyes(paths)
    except PointCloudError as e:
        raise CaptureError(str(e)) from None
    return Capture(tuple(paths), plane, based, lengths, eyes, arcs, view)


def read_captures(folder, arm: ContinuumArm) -> list[Capture]:
    """The captures of a folder in the order of their file names; the views of one wrap
    (the sidecar's "views", as depth_camera.simulate_clouds writes them) are one capture."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CaptureError(f"{folder}: no such capture folder")
    paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in CLOUD_SUFFIXES)
    if not paths:
        raise CaptureError(f"{folder}: holds no point cloud ({', '.join(CLOUD_SUFFIXES)})")
    groups: dict[tuple, list] = {}
    for p in paths:
        meta = _sidecar(p)
        key = tuple(meta.get("views") or [p.name])
        groups.setdefault(key, []).append((p, meta))
    return [_capture([p for p, _ in g], [m for _, m in g], arm) for g in groups.values()]


def captured_result(arm: ContinuumArm, config: ArmConfig, plane_index: int, plane_normal,
                    contact_arc_length) -> WrapResult:
    """A WrapResult of a fitted arm and where it felt the object: centre-line samples from
    the first contact to the tip (observe.centre_line), each contact on the tube's surface
    at its arc length, on the side the wrap turns to (towards the object; the normal in the
    wrap's plane, observe.contact_frames)."""
    total = float(np.sum(config.s))
    arcs = np.clip(np.sort(np.asarray(contact_arc_length, dtype=float)), 0.0, total)
    samples = centre_line(arm, config, float(arcs[0]), SAMPLE_SPACING)
    p, F = contact_frames(arm, config, arcs, turning_axis(samples["samples_tangent"]))
    t, n = F[..., 0], -F[..., 1]  # n: from the object into the arm
    contacts = Contacts(p=p + arm.radius * F[..., 1], n=n, t=t, b=np.cross(n, t),
                        section=arm.backbone(config, arcs).section, arc_length=arcs,
                        area=np.zeros(len(arcs)))
    return WrapResult(plane_index=int(plane_index), plane_normal=np.asarray(plane_normal, float),
                      base_rotation=arm.base_rotation, status="complete",
                      configs=config.as_vector()[None], contacts=contacts,
                      tip_rotation=tip_heading(arm, config), n_queries=0, time_s=0.0,
                      **samples)


def fit_capture(capture: Capture, plane_normal) -> Observation:
    """Fit one capture's arm and rebuild its wrap (an Observation with the fit's flags); the
    plane the sidecar names (`plane_normal`, the model's plane) holds the sections the camera
    did not see (residuals.WrapPlane)."""
    from .fitting import fit_cloud

    t0 = time.process_time()
    clouds = [load_cloud(p) for p in capture.paths]
    seg, fit = fit_cloud(clouds, capture.arm, capture.lengths, eye=capture.eyes,
                         plane=WrapPlane(tuple(np.asarray(plane_normal, float))))
    wrap = captured_result(capture.arm, fit.config, capture.plane, plane_normal,
                           capture.contact_arc_length)
    flags = fit.confidence.to_dict() if fit.confidence is not None else {}
    return Observation(wrap, flags, n_points=fit.n_points, cpu_s=time.process_time() - t0)


def recognise_captures(model, captures: list[Capture], planes, stop=None) -> dict:
    """Fit every capture in order and classify the wraps so far after each: the category
    from all of them, and where the paper's strong-prediction rule (`stop`,
    active.params.ActiveParams) first held, the category recognised there. A model that
    uses the camera's view of the object needs the first capture's "object_view"."""
    from ..active.params import ActiveParams
    from ..active.search import strong_prediction
    from ..learning.model import classify

    stop = stop or ActiveParams()
    bad = [c for c in captures if not 0 <= c.plane < len(planes)]
    if bad:
        raise CaptureError(f"{bad[0].paths[0]}: plane {bad[0].plane} is not one of the "
                           f"model's {len(planes)} planes")
    view = captures[0].view
    if model.uses_view and view is None:
        raise CaptureError(f"{captures[0].paths[0].with_suffix('.json')}: no 'object_view' (the "
                           f"camera's view of the object: height, long, short, m), which "
                           f"this model uses; or classify with a --touch-only model")
    wraps, steps, observations = [], [], []
    for c in captures:
        seen = fit_capture(c, planes[c.plane].normal)
        observations.append({"clouds": [p.name for p in c.paths], **seen.to_dict()})
        wraps.append(seen.wrap)
        result = classify(model, sorted(wraps, key=lambda w: w.plane_index),
                          view if model.uses_view else None)
        steps.append({"n_captures": len(wraps), "category": result.category,
                      "probabilities": result.probabilities,
                      "strong": strong_prediction(np.array(list(result.probabilities.values())),
                                                  stop)})
    first = next((s for s in steps if s["strong"]), None)
    return {"category": steps[-1]["category"], "probabilities": steps[-1]["probabilities"],
            "n_captures": len(captures),
            "recognised": None if first is None else
            {"category": first["category"], "n_captures": first["n_captures"]},
            "steps": steps, "observations": observations}


def write_captures(arm: ContinuumArm, wraps, obj, out, *, views: int = 1, seed: int = 0,
                   view=None, deform_mm: float = 0.0) -> list[Path]:
    """A capture folder of simulated wraps: each usable wrap's cloud(s) (capture_<k>.pcd, or
    capture_<k>_view<j>.pcd) with sidecars holding the plane, the contacts' arc lengths and
    `object_view` (view). arm: the scene's arm (each wrap's base applied here)."""
    from .depth_camera import simulate_clouds

    out = Path(out)
    written = []
    for k, w in enumerate(x for x in wraps if x.usable):
        meta = {"capture": "simulated", "plane": int(w.plane_index),
                "contact_arc_length": [float(a) for a in w.contacts.arc_length]}
        if view is not None:
            meta["object_view"] = [float(v) for v in view]
        written += [path for path, _, _ in simulate_clouds(
            w.arm(arm), w.final_config, obj, out=out / f"capture_{k:02d}.pcd", cameras=views,
            deform_mm=deform_mm, seed=seed + 100 * k, meta=meta)]
    return written
