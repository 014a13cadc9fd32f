"""A wrap as the depth camera sees it: the arm's shape measured, not known.

A real soft arm's configuration is known only from the camera. `observe_wrap` renders the
simulated Kinect cloud of a finished wrap (depth_camera.render_cloud: noise, flying pixels,
the object and the arm hiding parts of the arm, the table), cuts the arm out of it and fits
its configuration (fitting.fit_cloud, free space as evidence, the section lengths and the
wrap's plane, the way it turned and where it touched known unless told otherwise:
commanded_plane), and returns the wrap rebuilt on the fitted arm
(`observed_result`): everything the classifier reads (centre line, tip rotation, contact
centres) then comes from what the camera measured. Touch says where along the arm it
touches (each contact's arc length, the tactile skin's reading); the fitted arm says where
that is in space.

With `transparent` the object is left out of the depth image: the camera sees the whole arm
and nothing of the object, as with a glass. Several views (`views`) are cameras spread round
the object (depth_camera.cameras_around), each with its own noise, fitted together.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ..errors import InputError
from ..features.chords import plane_normals, turning_axis
from ..kinematics.arm import ArmConfig, ContinuumArm
from ..wrapping.contact import Contacts
from ..wrapping.wrap import tip_heading
from ..wrapping.wrap_types import WrapResult
from .cloud import Cloud, PointCloudError
from .depth_camera import CameraPose, KinectModel, cameras_around, render_cloud
from .residuals import WrapPlane

__all__ = ["OBSERVE_MODES", "Observation", "centre_line", "commanded_plane", "contact_frames",
           "observed_result", "observe_wrap",
           "observe_wraps", "observed_execute"]

OBSERVE_MODES = ("exact", "camera")  # how a wrap's configuration is known


@dataclass(frozen=True)
class Observation:
    """One wrap seen through the camera.

    Args:
        wrap: the WrapResult rebuilt on the fitted configuration (observed_result); the
            exact one unchanged when there was nothing to observe (an unusable wrap), and
            an unusable one (no samples) when the camera did not find the arm.
        flags: the fit's confidence (confidence.FitConfidence.to_dict: ambiguous, partly
            unseen, poor fit, tip uncertainty), or {"error": why} when no fit was made.
        n_points: arm points fitted.
        cpu_s: CPU time of rendering, segmenting and fitting, s.
    """

    wrap: WrapResult
    flags: dict
    n_points: int = 0
    cpu_s: float = 0.0

    def to_dict(self) -> dict:
        return {"plane": int(self.wrap.plane_index), "usable": bool(self.wrap.usable),
                "n_points": int(self.n_points), "cpu_s": round(self.cpu_s, 4), **self.flags}


def centre_line(arm: ContinuumArm, config: ArmConfig, start: float, spacing: float) -> dict:
    """WrapResult's centre-line fields (samples_arc_length, _position, _tangent, _normal) of
    `config`, from arc length `start` to the tip every `spacing` m: a wrap rebuilt on a
    fitted arm (observed_result, captures.captured_result) describes the object from the
    first contact on, as a simulated wrap does."""
    arc = np.arange(float(start), float(np.sum(config.s)) + 1e-12, float(spacing))
    bb = arm.backbone(config, arc)
    return {"samples_arc_length": arc, "samples_position": bb.position,
            "samples_tangent": bb.tangent, "samples_normal": bb.normal}


def contact_frames(arm: ContinuumArm, config: ArmConfig, arc, axis) -> tuple:
    """Centre-line positions (m, 3) and frames (m, 3, 3; columns tangent, normal,
    binormal) at arc lengths `arc`, the normal in the wrap's plane (chords.plane_normals
    about the wrap's turning `axis`): a fitted section that runs nearly straight has no
    well-determined bending direction, and a contact carried round its tangent by that
    would move by up to a tube diameter."""
    bb = arm.backbone(config, arc)
    n = plane_normals(bb.tangent, bb.normal, axis)
    return bb.position, np.stack([bb.tangent, n, np.cross(bb.tangent, n)], axis=-1)


def observed_result(result: WrapResult, arm: ContinuumArm, config: ArmConfig) -> WrapResult:
    """`result` with its final configuration replaced by `config` (a fitted one).

    arm: the arm as it stood for the wrap (WrapResult.arm). The centre-line samples run
    from the first contact's arc length to the fitted tip at the wrap's own spacing
    (centre_line); each contact keeps its arc length and its offset from the centre line
    in the arm's local frame (contact_frames: tangent, normal in the wrap's plane,
    binormal), which moves with the fitted arm; the tip rotation is the fitted arm's. Only
    the final configuration is kept: the camera sees where the wrap ended."""
    total = float(np.sum(config.s))
    c = result.contacts
    arc_c = np.clip(np.asarray(c.arc_length, dtype=float), 0.0, total)
    old = result.final_config
    arc_old = np.clip(np.asarray(c.arc_length, dtype=float), 0.0, float(np.sum(old.s)))
    s = np.asarray(result.samples_arc_length, dtype=float)
    spacing = float(np.median(np.diff(s))) if len(s) > 1 else 0.005
    samples = centre_line(arm, config, float(arc_c.min()) if len(c) else total + 1.0,
                          spacing)
    p0, F0 = contact_frames(arm, old, arc_old, turning_axis(result.samples_tangent))
    p1, F1 = contact_frames(arm, config, arc_c, turning_axis(samples["samples_tangent"]))
    R = F1 @ np.transpose(F0, (0, 2, 1))  # exact local frame -> fitted one, a contact each
    moved = Contacts(p=p1 + np.einsum("kij,kj->ki", R, c.p - p0),
                     n=np.einsum("kij,kj->ki", R, c.n), t=np.einsum("kij,kj->ki", R, c.t),
                     b=np.einsum("kij,kj->ki", R, c.b), section=c.section, arc_length=arc_c,
                     area=c.area)
    return replace(result, configs=config.as_vector()[None], contacts=moved,
                   tip_rotation=tip_heading(arm, config), **samples)


def _unseen(result: WrapResult, why: str) -> WrapResult:
    """`result` with no centre line: the camera gave nothing to describe the object by."""
    z3 = np.zeros((0, 3))
    return replace(result, samples_arc_length=np.zeros(0), samples_position=z3,
                   samples_tangent=z3, samples_normal=z3, extra={**result.extra, "unseen": why})


def commanded_plane(result: WrapResult) -> WrapPlane:
    """What the robot knows of a wrap's shape without the camera (residuals.WrapPlane): the
    plane it was commanded in, the way it turned about the plane's normal (the command's
    direction, which the tip's turning follows: planes.WrapPlane.direction; none for a
    wrap that did not turn), and its last section curled to the bend limit when the
    tactile skin reads no contact on that section (Algorithm 1 curls it until it touches)."""
    normal = np.asarray(result.plane_normal, float)
    axis = turning_axis(result.samples_tangent)
    turn = 0 if axis is None else int(np.sign(axis @ normal))
    last = result.final_config.n_sections - 1
    touched = set(np.asarray(result.contacts.section, int).tolist())
    curled = (last,) if turn and last not in touched else ()
    return WrapPlane(tuple(normal.tolist()), turn=turn, curled=curled)


def observe_wrap(result: WrapResult, arm: ContinuumArm, obj, *, views: int = 1,
                 transparent: bool = False, seed: int = 0, camera: CameraPose = CameraPose(),
                 sensor: KinectModel = KinectModel(), lengths_known: bool = True,
                 deform: float = 0.0, plane_known: bool = True) -> Observation:
    """The wrap `result` as the depth camera sees it (module docstring).

    Args:
        result: a wrap of `obj` by `arm` (in the frame it was wrapped in: scene.arm, the
            scene's object_trimesh).
        arm: the arm the wrap was made with (its base as the scene's; the wrap's own base
            rotation and offset are applied here).
        obj: the object's mesh in that frame (trimesh), drawn in the depth image unless
            `transparent`.
        views: cameras spread round the object (1: `camera` alone).
        seed: the sensor noise's; view k draws with seed + k.
        lengths_known: the fit is given the section lengths (a robot knows what it
            commanded); False fits them too.
        deform: how far the tube flattens against the object where it touches, m.
        plane_known: the fit is given the wrap's plane (result.plane_normal), which holds
            the sections the camera does not see (residuals.WrapPlane); a robot knows the
            plane it commanded.
    """
    if views < 1:
        raise InputError(f"views must be at least 1, got {views}")
    if not result.usable:
        return Observation(result, {"error": f"wrap not usable ({result.status})"})
    from threadpoolctl import threadpool_limits

    from .fitting import fit_cloud
    t0 = time.process_time()
    wrap_arm = result.arm(arm)
    config = result.final_config
    poses = cameras_around(views, camera)
    try:
        with threadpool_limits(limits=1):
            sims = [render_cloud(wrap_arm, config, None if transparent else obj, camera=c,
                                 model=sensor, deform=deform, seed=seed + k)
                    for k, c in enumerate(poses)]
        clouds = [Cloud(s.points, s.colours, source=f"plane {result.plane_index} view {k}")
                  for k, s in enumerate(sims)]
        seg, fit = fit_cloud(clouds, wrap_arm, config.s if lengths_known else None,
                             eye=[np.asarray(c.eye, float) for c in poses],
                             plane=commanded_plane(result) if plane_known else None,
                             touches=result.contacts.arc_length)
    except PointCloudError as e:
        return Observation(_unseen(result, str(e)), {"error": str(e)},
                           cpu_s=time.process_time() - t0)
    observed = observed_result(result, wrap_arm, fit.config)
    flags = fit.confidence.to_dict() if fit.confidence is not None else {}
    return Observation(observed, flags, n_points=fit.n_points, cpu_s=time.process_time() - t0)


def observe_wraps(wraps, arm: ContinuumArm, obj, **options) -> list[Observation]:
    """observe_wrap of each wrap of one object, the noise seeded seed + 100 * plane (each
    wrap is its own capture)."""
    seed = int(options.pop("seed", 0))
    return [observe_wrap(w, arm, obj, seed=seed + 100 * max(int(w.plane_index), 0),
                         **options) for w in wraps]


def observed_execute(scene, planes, chord_params, wrap_params=None, log=None, **options):
    """active.policies.simulated_execute with each wrap seen through the camera
    (observe_wrap's options): the chords of the fitted arm and its contact centres (moved
    with it, observed_result), or None when the wrap or its observation is unusable. `log`
    collects every Observation."""
    from ..features.chords import wrap_chords
    from ..wrapping.wrap import WrapParams, wrap

    seed = int(options.pop("seed", 0))
    base = scene.arm

    def execute(plane_index: int):
        result = wrap(scene, planes[plane_index], wrap_params or WrapParams())
        seen = observe_wrap(result, base, scene.object_trimesh,
                            seed=seed + 100 * int(plane_index), **options)
        if log is not None:
            log.append(seen)
        if not seen.wrap.usable:
            return None
        return wrap_chords(seen.wrap, chord_params), np.asarray(seen.wrap.contacts.p, float)
    return execute
