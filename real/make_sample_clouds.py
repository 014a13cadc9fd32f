"""Regenerate the sample clouds in real/data/: true wraps (wrap.py, Algorithm 1) of a
cylinder, a box (the paper's Fig. 8 objects) and the demo mug, rendered by the simulated
Kinect with a 2 mm flattening of the tube at contacts, downsampled to 4 mm voxels and
cropped to the table around the scene (under 1 MB each). Each cloud has a JSON sidecar with
the true configuration, base pose and camera. The wraps treat the table top as an obstacle
(wrap.table), as the real arm over a table must.
"""

import sys
from pathlib import Path

import numpy as np
import open3d as o3d
import trimesh

from drake_continuum import WrapScene, enumerate_planes, load_config, load_mesh, wrap
from drake_continuum.perception.depth_camera import simulate_clouds, write_cloud

CROP = 0.32  # m: keep |x|, |y| below this (the arm and the object; most of the table goes)

PROJECT = Path(__file__).resolve().parent.parent
DATA = PROJECT / "real" / "data"


def make_objects() -> None:
    cyl = trimesh.creation.cylinder(radius=0.04, height=0.14, sections=48)
    cyl.apply_translation((0, 0, 0.07))
    cyl.export(DATA / "cylinder.obj")
    box = trimesh.creation.box(extents=(0.08, 0.10, 0.14))
    box.apply_translation((0, 0, 0.07))
    box.export(DATA / "box.obj")


def main_() -> int:
    DATA.mkdir(parents=True, exist_ok=True)
    make_objects()
    mug = PROJECT / "models" / "mug.obj"
    jobs = [("cylinder_0", DATA / "cylinder.obj", 1), ("cylinder_1", DATA / "cylinder.obj", 6),
            ("box_0", DATA / "box.obj", 1), ("mug_0", mug, 2)]
    cfg = load_config(overrides=["wrap.table=true"])
    for i, (name, mesh, plane) in enumerate(jobs):
        arm = cfg.arm()
        planes = enumerate_planes(arm.base_position, cfg.alpha_deg, cfg.both_directions)
        result = wrap(WrapScene(arm, mesh), planes[plane], cfg.wrap)
        arm = arm.with_base(rotation=result.base_rotation)
        path = DATA / f"{name}.pcd"
        simulate_clouds(arm, result.final_config, load_mesh(mesh), out=path, deform_mm=2.0,
                        seed=i, voxel=0.004, meta={"object": str(mesh.relative_to(PROJECT)),
                                                   "plane": plane,
                                                   "wrap_status": result.status,
                                                   "wrap_table": cfg.wrap.table})
        pcd = o3d.io.read_point_cloud(str(path))
        pts, cols = np.asarray(pcd.points), np.asarray(pcd.colors)
        keep = np.all(np.abs(pts[:, :2]) < CROP, axis=1)
        write_cloud(path, pts[keep], cols[keep])
    return 0


if __name__ == "__main__":
    sys.exit(main_())
