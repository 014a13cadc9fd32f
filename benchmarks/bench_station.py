"""The station against the batch path, in one run on this machine.

1. Wraps: each (object, plane) is wrapped by wrap() on a WrapScene and by the station's
   WrapController in a Simulator (its own WrapScene, so neither reuses the other's kept
   contact answers). Reports whether they are equal (status; final centre lines, max
   distance in m) and the time ratio station / wrap(), per wrap and in total. Each object's
   first wrap is run once untimed on both sides (Drake's first queries in a new context).
2. Camera: the time of one noisy point cloud from the station's RgbdSensor (VTK), and of
   perception.depth_camera.render_cloud (Open3D ray casting) for the same configuration,
   object and camera.
3. Fits (--fit): each wrap (with the table as an obstacle, as bench_pointcloud.py wraps) is
   seen by both cameras (same pose, sensor model and noise seed) and fitted by
   perception.fitting.fit_cloud with the camera's position, section lengths known and free:
   tip error median / p90 / p95 for each renderer.

Times are wall clock with BLAS/OpenMP threads pinned to 1. Prints one JSON object.

    python benchmarks/bench_station.py [--objects mug cup_000 apple_000] [--planes 0 1 2]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from pydrake.math import RigidTransform, RotationMatrix  # noqa: E402
from pydrake.systems.analysis import Simulator  # noqa: E402
from pydrake.systems.framework import DiagramBuilder  # noqa: E402

from drake_continuum.config import load_config  # noqa: E402
from drake_continuum.files import json_text  # noqa: E402
from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig  # noqa: E402
from drake_continuum.objects.generators import generate_object  # noqa: E402
from drake_continuum.objects.mesh import load_mesh  # noqa: E402
from drake_continuum.perception.cloud import Cloud  # noqa: E402
from drake_continuum.perception.depth_camera import CameraPose, render_cloud  # noqa: E402
from drake_continuum.perception.fitting import fit_cloud  # noqa: E402
from drake_continuum.station import WrapController, make_station  # noqa: E402
from drake_continuum.wrapping.planes import enumerate_planes  # noqa: E402
from drake_continuum.wrapping.scene import WrapScene  # noqa: E402
from drake_continuum.wrapping.wrap import wrap  # noqa: E402


def _mesh(name):
    if name == "mug":
        return load_mesh(MODELS_DIR / "mug.obj")
    category, index = name.rsplit("_", 1)
    return generate_object(category, int(index), seed=0).mesh


def _wraps(config, name, plane_indices):
    arm, params = config.arm(), config.wrap
    planes = enumerate_planes(arm.base_position)
    mesh = _mesh(name)
    scene = WrapScene(arm, mesh)
    builder = DiagramBuilder()
    station = builder.AddSystem(make_station(config, object_mesh=mesh, camera=False))
    controller = WrapController.AddToBuilder(builder, station, scene=WrapScene(arm, mesh),
                                             plane=planes[plane_indices[0]], params=params)
    simulator = Simulator(builder.Build())

    def simulate(plane):
        controller.set_plane(plane)
        simulator.get_mutable_context().SetTime(0.0)
        simulator.Initialize()
        t, c = time.perf_counter(), time.process_time()
        simulator.AdvanceTo(np.inf)
        return controller.result(), time.perf_counter() - t, time.process_time() - c

    simulate(planes[plane_indices[0]])  # untimed: first queries of each side
    wrap(scene, planes[plane_indices[0]], params)
    rows = []
    for k in plane_indices:
        t, c = time.perf_counter(), time.process_time()
        want = wrap(scene, planes[k], params)
        t_wrap, c_wrap = time.perf_counter() - t, time.process_time() - c
        got, t_station, c_station = simulate(planes[k])
        based = arm.with_base(rotation=want.base_rotation)
        gap = float(np.abs(based.backbone(got.final_config, n=400).position
                           - based.backbone(want.final_config, n=400).position).max())
        rows.append({"object": name, "plane": k, "status": want.status,
                     "same_status": got.status == want.status, "centre_line_gap_m": gap,
                     "wrap_ms": 1000 * t_wrap, "station_ms": 1000 * t_station,
                     "ratio": t_station / t_wrap, "wrap_cpu_ms": 1000 * c_wrap,
                     "station_cpu_ms": 1000 * c_station, "cpu_ratio": c_station / c_wrap})
    return rows


def _camera(config, n=5):
    arm = config.arm()
    mesh = load_mesh(MODELS_DIR / "mug.obj")
    result = wrap(WrapScene(arm, mesh), enumerate_planes(arm.base_position)[1], config.wrap)
    based = arm.with_base(rotation=result.base_rotation)
    c = ArmConfig.from_vector(result.configs[-1])
    station = make_station(config, object_mesh=mesh, table=True)
    context = station.CreateDefaultContext()
    station.GetInputPort("arm_configuration").FixValue(context, c.as_vector())
    station.GetInputPort("base_pose").FixValue(context, RigidTransform(
        RotationMatrix(based.base_rotation), based.base_position))
    times = {"station": [], "open3d": []}  # (wall, CPU) s
    for i in range(n + 1):  # the first of each untimed
        context.SetTime(0.05 * i)  # new noise: the whole chain is computed again
        t, cpu = time.perf_counter(), time.process_time()
        station.GetOutputPort("point_cloud").Eval(context)
        times["station"].append((time.perf_counter() - t, time.process_time() - cpu))
        t, cpu = time.perf_counter(), time.process_time()
        render_cloud(based, c, mesh, seed=i)
        times["open3d"].append((time.perf_counter() - t, time.process_time() - cpu))
    out = {"clouds": n, "station_first_cloud_ms": 1000 * times["station"][0][0]}
    for name, rows in times.items():
        wall, cpu = np.array(rows[1:]).T
        out[f"{name}_cloud_ms_median"] = 1000 * float(np.median(wall))
        out[f"{name}_cloud_cpu_ms_median"] = 1000 * float(np.median(cpu))
    return out


def _fits(config, names, plane_indices):
    """Tip errors (mm) of fits to both renderers' clouds of the same wraps."""
    arm = config.arm()
    params = config.wrap.__class__(**{**config.wrap.__dict__, "table": True})
    planes = enumerate_planes(arm.base_position)
    eye = np.asarray(CameraPose().eye, float)
    errors = {f"{r}_{k}": [] for r in ("station", "open3d") for k in ("known", "free")}
    for name in names:
        mesh = _mesh(name)
        scene = WrapScene(arm, mesh)
        station = make_station(config, object_mesh=mesh, table=True)
        context = station.CreateDefaultContext()
        for i, k in enumerate(plane_indices):
            result = wrap(scene, planes[k], params)
            if not result.usable:
                continue
            based = result.arm(arm)
            c = result.final_config
            station.GetInputPort("arm_configuration").FixValue(context, c.as_vector())
            station.GetInputPort("base_pose").FixValue(context, RigidTransform(
                RotationMatrix(based.base_rotation), based.base_position))
            context.SetTime(0.05 * i)
            drake_cloud = station.GetOutputPort("point_cloud").Eval(context)
            seen = np.isfinite(drake_cloud.xyzs()).all(axis=0)
            clouds = {"station": Cloud(drake_cloud.xyzs().T[seen].astype(float),
                                       drake_cloud.rgbs().T[seen] / 255.0),
                      "open3d": Cloud(*(lambda s: (s.points, s.colours))(
                          render_cloud(based, c, mesh, seed=i)))}
            truth = based.tip_frame(c)[1]
            for renderer, cloud in clouds.items():
                for known, lengths in (("known", c.s), ("free", None)):
                    try:
                        fit = fit_cloud(cloud, based, lengths=lengths, eye=eye)[1]
                        e = 1e3 * float(np.linalg.norm(fit.tip - truth))
                    except Exception as err:  # a failed fit counts as a miss, named
                        print(f"{name} plane {k} {renderer} {known}: {err}")
                        e = np.inf
                    errors[f"{renderer}_{known}"].append(e)
    return {key: {"n": len(e), "median_mm": float(np.median(e)),
                  "p90_mm": float(np.percentile(e, 90)), "p95_mm": float(np.percentile(e, 95))}
            for key, e in errors.items()}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", nargs="+", default=["mug", "cup_000", "apple_000"])
    parser.add_argument("--planes", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--no-camera", action="store_true", help="skip the camera timing")
    parser.add_argument("--fit", action="store_true", help="also fit both renderers' clouds")
    parser.add_argument("--no-wraps", action="store_true", help="skip the wrap comparison")
    args = parser.parse_args()
    config = load_config()
    out = {}
    if not args.no_wraps:
        rows = [row for name in args.objects for row in _wraps(config, name, args.planes)]
        ratios = np.array([r["ratio"] for r in rows])
        out = {"wraps": rows,
               "all_equal": all(r["same_status"] and r["centre_line_gap_m"] <= 1e-6
                                for r in rows),
               "ratio_median": float(np.median(ratios)),
               "cpu_ratio_median": float(np.median([r["cpu_ratio"] for r in rows])),
               "ratio_total": sum(r["station_ms"] for r in rows) / sum(r["wrap_ms"]
                                                                       for r in rows)}
    if args.fit:
        out["fits"] = _fits(config, args.objects, args.planes)
    if not args.no_camera:
        out["camera"] = _camera(config)
    print(json_text(out))


if __name__ == "__main__":
    main()
