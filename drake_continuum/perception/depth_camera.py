"""A Kinect-like depth camera looking at the arm wrapping an object on the table.

It makes the clouds the real-robot module is developed and benchmarked on: the arm (painted
arm.ARM_COLOUR), the object and the table are rendered into a 640x480 depth and colour
image, the Kinect v1 error model is applied, and the image is back-projected into a world-frame
point cloud.

Renderer: Open3D's RaycastingScene rather than Drake's RgbdSensor. The scene is three static
triangle meshes (arm tube, object, table plus the arm's mount) rendered once per cloud; ray
casting needs no diagram and no temporary mesh file for a tube that changes with every
configuration, gives exact per-pixel geometry ids (ground-truth labels for tests) and renders
a frame in tens of milliseconds against about 0.6 s for VTK's first render. The sensor errors
are applied afterwards in numpy and would be the same behind either renderer.

Error model (Khoshelham and Elberink 2012, Kinect v1): depth comes from disparity
d = f b / z, so a constant disparity error gives a depth error growing as z^2. The disparity
gets Gaussian noise and is quantised to 1/8 pixel; the two together have the standard deviation
sigma_coeff * f * b pixels, i.e. a depth error sigma(z) = sigma_coeff * z^2 (1.5 mm at 1 m).
Pixels on depth edges become flying pixels (a random mix of foreground and background).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import open3d as o3d
import trimesh

from ..errors import DrakeContinuumError
from ..kinematics.arm import ARM_COLOUR, ArmConfig, ContinuumArm

__all__ = ["OBJECT_COLOUR", "TABLE_COLOUR", "MOUNT_COLOUR", "LABELS", "DepthCameraError",
           "KinectModel", "CameraPose", "SimulatedCloud", "tube_mesh", "contact_squash",
           "table_and_mount", "raycast_mesh", "render_cloud", "scene_parts", "render_image",
           "sensor_errors", "measured_depth",
           "write_cloud", "downsample", "curled_configs", "cameras_around", "simulate_clouds"]

OBJECT_COLOUR = (0.55, 0.60, 0.70)  # scene.OBJECT_COLOR: grey-blue
TABLE_COLOUR = (0.58, 0.55, 0.52)  # unsaturated grey-brown
MOUNT_COLOUR = (0.25, 0.25, 0.28)
LABELS = {"arm": 0, "object": 1, "table": 2, "mount": 3}  # per-pixel ground truth; -1 = mixed


class DepthCameraError(DrakeContinuumError):
    """A scene cannot be rendered (e.g. the camera sees nothing)."""


@dataclass(frozen=True)
class KinectModel:
    """Kinect v1 intrinsics and error model.

    Args:
        width, height: image size, pixels.
        focal: focal length, pixels (both axes); the principal point is the image centre.
        baseline: projector-camera baseline, m.
        disparity_step: disparity quantisation, pixels.
        sigma_coeff: depth noise standard deviation over z^2, 1/m.
        z_min, z_max: measurable depth range, m.
        edge_jump: depth step between neighbouring pixels that marks a depth edge, m.
        flying_prob: probability that a pixel on a depth edge is a flying pixel.
        colour_noise: standard deviation of the colour noise (colours in [0, 1]).
    """

    width: int = 640
    height: int = 480
    focal: float = 525.0
    baseline: float = 0.075
    disparity_step: float = 0.125
    sigma_coeff: float = 1.5e-3
    z_min: float = 0.5
    z_max: float = 4.0
    edge_jump: float = 0.02
    flying_prob: float = 0.5
    colour_noise: float = 0.03

    def depth_sigma(self, z):
        """Standard deviation of the depth error at depth z (m)."""
        return self.sigma_coeff * np.asarray(z, dtype=float) ** 2

    def add_depth_noise(self, z, rng: np.random.Generator) -> np.ndarray:
        """Noisy, quantised measurement of true depths z (m), through disparity."""
        fb = self.focal * self.baseline
        sigma_d = self.sigma_coeff * fb  # disparity std, pixels, independent of z
        # Quantisation contributes step^2/12 of variance; the Gaussian part makes up the rest.
        gauss = np.sqrt(max(sigma_d ** 2 - self.disparity_step ** 2 / 12.0, 0.0))
        d = fb / np.asarray(z, dtype=float) + gauss * rng.standard_normal(np.shape(z))
        d = np.round(d / self.disparity_step) * self.disparity_step
        return fb / d


@dataclass(frozen=True)
class CameraPose:
    """Camera placement: eye position looking at a target (OpenCV frame: x right, y down,
    z forward). The default is a Kinect on a stand 1 m from the object, looking down at about
    60 degrees from in front of and to the right of the arm's base: from there a wrap's tip is
    hidden behind the object less often than from a lower, side-on view."""

    eye: tuple = (0.30, -0.50, 0.85)
    target: tuple = (0.0, 0.0, 0.06)
    up: tuple = (0.0, 0.0, 1.0)

    def rotation(self) -> np.ndarray:
        """World-from-camera rotation (columns: camera x, y, z in world)."""
        z = np.asarray(self.target, float) - np.asarray(self.eye, float)
        z /= np.linalg.norm(z)
        x = np.cross(z, np.asarray(self.up, float))
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        return np.stack([x, y, z], axis=1)


    def to_dict(self) -> dict:
        return {"eye": list(map(float, self.eye)), "target": list(map(float, self.target)),
                "up": list(map(float, self.up))}

    @classmethod
    def from_dict(cls, d: dict) -> "CameraPose":
        return cls(tuple(map(float, d["eye"])), tuple(map(float, d.get("target", cls.target))),
                   tuple(map(float, d.get("up", cls.up))))


def cameras_around(n: int, first: CameraPose = CameraPose()) -> list[CameraPose]:
    """n cameras at the first one's height and distance from the target, spread evenly in
    azimuth about the vertical through the target: n = 2 puts the second opposite the first,
    where it sees what the object hides from the first. The first is `first` itself, not
    turned by a zero angle: eye - target + target rounds, and a fit given the rounded eye
    is not the fit of the pose a caller passed."""
    if n < 1:
        raise DepthCameraError(f"need at least one camera, got {n}")
    eye, target = np.asarray(first.eye, float), np.asarray(first.target, float)
    out = [first]
    for k in range(1, n):
        a = 2 * np.pi * k / n
        c, s = np.cos(a), np.sin(a)
        d = eye - target
        rotated = np.array([c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]])
        out.append(CameraPose(tuple((target + rotated).tolist()), first.target, first.up))
    return out


@dataclass(frozen=True)
class SimulatedCloud:
    """A back-projected depth image.

    Args:
        points: (N, 3) world positions, m.
        colours: (N, 3) RGB in [0, 1].
        labels: (N,) ground truth per point (LABELS; -1 for flying pixels).
        true_depth: (N,) noiseless depth along the camera axis, m.
        depth: (N,) measured depth, m.
        camera: the camera pose; model: the sensor model.
    """

    points: np.ndarray
    colours: np.ndarray
    labels: np.ndarray
    true_depth: np.ndarray
    depth: np.ndarray
    camera: CameraPose
    model: KinectModel


def _transported_frames(arm: ContinuumArm, config: ArmConfig, n: int):
    """Backbone samples with torsion-free cross-section axes, continuous across sections
    (the bending-direction normal jumps where phi changes; the transported frame does not)."""
    bb = arm.backbone(config, n=n)
    phi = config.phi[bb.section][:, None]
    e1 = np.cos(phi) * bb.normal - np.sin(phi) * bb.binormal
    e2 = np.sin(phi) * bb.normal + np.cos(phi) * bb.binormal
    return bb, e1, e2


def tube_mesh(arm: ContinuumArm, config: ArmConfig, *, spacing: float = 0.004,
              n_around: int = 24, radial_offset=None) -> trimesh.Trimesh:
    """Closed triangle mesh of the arm's tube (flat end caps).

    Args:
        spacing: ring spacing along the backbone, m.
        radial_offset: optional callable (centres (m,3), directions (m,k,3)) -> (m,k,3)
            displacement of each ring vertex, for deformed arms.
    """
    n = max(int(np.ceil(np.sum(config.s) / spacing)) + 1, 2)
    bb, e1, e2 = _transported_frames(arm, config, n)
    ang = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    dirs = np.cos(ang)[None, :, None] * e1[:, None] + np.sin(ang)[None, :, None] * e2[:, None]
    ring = bb.position[:, None] + arm.radius * dirs
    if radial_offset is not None:
        ring = ring + radial_offset(bb.position, dirs)
    verts = np.concatenate([ring.reshape(-1, 3), bb.position[[0, -1]]])
    i = np.arange(n - 1)[:, None] * n_around
    j = np.arange(n_around)[None, :]
    a, b = i + j, i + (j + 1) % n_around
    c, d = a + n_around, b + n_around
    side = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                           np.stack([a, d, c], -1).reshape(-1, 3)])
    c0, c1 = n * n_around, n * n_around + 1
    jj = np.arange(n_around)
    cap0 = np.stack([np.full(n_around, c0), (jj + 1) % n_around, jj], -1)
    last = (n - 1) * n_around
    cap1 = np.stack([np.full(n_around, c1), last + jj, last + (jj + 1) % n_around], -1)
    return trimesh.Trimesh(verts, np.concatenate([side, cap0, cap1]), process=False)


def contact_squash(arm: ContinuumArm, obj: trimesh.Trimesh, amount: float):
    """radial_offset for tube_mesh: the tube flattens against the object by `amount` (m).

    Near the object (backbone within radius + 3 mm of its surface, weight falling off smoothly
    over 2 cm of arc) the side away from the object moves towards it by up to `amount` and the
    flanks bulge by half that, as a soft tube pressed onto a surface does; the contact face
    stays on the surface.
    """
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(raycast_mesh(obj))

    def offset(centres, dirs):
        q = o3d.core.Tensor(centres.astype(np.float32))
        closest = scene.compute_closest_points(q)["points"].numpy().astype(float)
        to_obj = closest - centres
        dist = np.linalg.norm(to_obj, axis=1)
        towards = to_obj / np.maximum(dist, 1e-9)[:, None]
        gap = np.maximum(dist - arm.radius, 0.0)
        w = np.exp(-(gap / 0.003) ** 2)
        step = np.linalg.norm(np.diff(centres, axis=0), axis=1).mean() if len(centres) > 1 else 1
        k = max(int(0.02 / max(step, 1e-6)), 1)
        kernel = np.exp(-0.5 * (np.arange(-2 * k, 2 * k + 1) / k) ** 2)
        w = np.minimum(np.convolve(w, kernel / kernel.max(), mode="same"), 1.0)
        cos = np.einsum("mkj,mj->mk", dirs, towards)
        far = np.maximum(-cos, 0.0)  # 1 on the far side, 0 from the flanks to the contact
        flank = 1.0 - cos ** 2
        disp = (amount * w[:, None, None]
                * (far[..., None] * towards[:, None] + 0.5 * flank[..., None] * dirs))
        return disp

    return offset


def raycast_mesh(mesh: trimesh.Trimesh) -> o3d.t.geometry.TriangleMesh:
    """`mesh` as the Open3D tensor mesh a RaycastingScene takes (add_triangles)."""
    legacy = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.asarray(mesh.vertices, float)),
                                       o3d.utility.Vector3iVector(np.asarray(mesh.faces, np.int32)))
    return o3d.t.geometry.TriangleMesh.from_legacy(legacy)


def table_and_mount(arm: ContinuumArm) -> list[trimesh.Trimesh]:
    """The table top (1.2 m x 1.0 m, top face at z = 0) and a block behind the arm's base."""
    table = trimesh.creation.box(extents=(1.2, 1.0, 0.03))
    table.apply_translation((0.05, 0.0, -0.015))
    mount = trimesh.creation.box(extents=(0.06, 0.06, 0.06))
    back = arm.base_rotation[:, 2]  # the arm leaves its base along +z of the base frame
    mount.apply_translation(arm.base_position - back * 0.03)
    return [table, mount]


def render_cloud(arm: ContinuumArm, config: ArmConfig, obj: trimesh.Trimesh | None,
                 *, camera: CameraPose = CameraPose(), model: KinectModel = KinectModel(),
                 deform: float = 0.0, seed: int = 0, noise: bool = True) -> SimulatedCloud:
    """Render the arm at `config` against `obj` on the table and return the measured cloud.

    Args:
        deform: how far the tube flattens against the object where it touches, m.
        noise: False gives the noiseless, unquantised cloud without flying pixels.
    """
    rng = np.random.default_rng(seed)
    offset = contact_squash(arm, obj, deform) if (deform > 0 and obj is not None) else None
    image = render_image(scene_parts(arm, config, obj, radial_offset=offset), camera=camera,
                         model=model, rng=rng if noise else None)
    valid = image["valid"]
    return SimulatedCloud(points=image["points"], colours=image["colour"][valid],
                          labels=image["label"][valid], true_depth=image["true_z"][valid],
                          depth=image["z"][valid], camera=camera, model=model)


def scene_parts(arm: ContinuumArm, config: ArmConfig, obj: trimesh.Trimesh | None, *,
                radial_offset=None) -> dict:
    """The meshes the camera sees by LABELS name, in the order their geometry ids follow:
    the arm's tube at `config`, the table, the mount and the object (if any)."""
    table, mount = table_and_mount(arm)
    parts = {"arm": tube_mesh(arm, config, radial_offset=radial_offset), "table": table,
             "mount": mount}
    if obj is not None:
        parts["object"] = obj
    return parts


def render_image(parts: dict, *, camera: CameraPose, model: KinectModel, rng,
                 window=None) -> dict:
    """The camera's images of `parts` (scene_parts): per pixel z (measured depth, m), true_z,
    colour, label and valid, and `points`, the world positions of the valid pixels in row
    order. `rng` draws the sensor errors (None: none). `window` (first row, end row, first
    column, end column) renders only those pixels, measured as in the whole image: the
    rays of the ring round it are cast too, for the flying pixels on its edge."""
    inner = window or (0, model.height, 0, model.width)
    outer = (max(inner[0] - 1, 0), min(inner[1] + 1, model.height),
             max(inner[2] - 1, 0), min(inner[3] + 1, model.width))
    R = camera.rotation()
    eye = np.asarray(camera.eye, float)
    ray_cam, rays, ray_dir = _rays(tuple(map(float, camera.eye)),
                                   tuple(map(float, camera.target)),
                                   tuple(map(float, camera.up)), model=model)
    rows, cols = slice(outer[0], outer[1]), slice(outer[2], outer[3])
    scene = o3d.t.geometry.RaycastingScene()
    geom_label = {}
    for name, mesh in parts.items():
        gid = scene.add_triangles(raycast_mesh(mesh))
        geom_label[gid] = LABELS[name]
    # The whole image shares the cached array; a window is copied into rows cast_rays takes.
    hit = scene.cast_rays(o3d.core.Tensor.from_numpy(np.ascontiguousarray(rays[rows, cols])))
    z = hit["t_hit"].numpy().astype(float)
    gid = hit["geometry_ids"].numpy().astype(np.int64)
    nrm = hit["primitive_normals"].numpy().astype(float)
    valid = np.isfinite(z) & (z >= model.z_min) & (z <= model.z_max)
    if window is None and not valid.any():
        raise DepthCameraError("the camera sees nothing within its depth range")
    label = np.full(z.shape, -1, dtype=np.int64)
    lookup = np.full(max(geom_label) + 1, -1, dtype=np.int64)  # geometry id -> label
    lookup[list(geom_label)] = list(geom_label.values())
    label[valid] = lookup[gid[valid]]
    shade = 0.35 + 0.65 * np.abs(np.einsum("hwi,hwi->hw", nrm, ray_dir[rows, cols]))
    colour = _COLOUR_OF[np.maximum(label, 0)] * shade[..., None]
    around = None
    if window is not None:  # the depths round the window, NaN beyond the image
        around = np.full((inner[1] - inner[0] + 2, inner[3] - inner[2] + 2), np.nan)
        r, c = 1 - (inner[0] - outer[0]), 1 - (inner[2] - outer[2])
        around[r:r + z.shape[0], c:c + z.shape[1]] = np.where(valid, z, np.nan)
        cut = (slice(inner[0] - outer[0], inner[1] - outer[0]),
               slice(inner[2] - outer[2], inner[3] - outer[2]))
        z, colour, label, valid = z[cut], colour[cut], label[cut], valid[cut]
    true_z = z.copy()
    if rng is not None:
        z, colour, label, valid = sensor_errors(z, colour, label, valid=valid, model=model,
                                                rng=rng, around=around)
    colour = np.clip(colour, 0.0, 1.0)
    ray_cam = ray_cam[inner[0]:inner[1], inner[2]:inner[3]]
    pts = eye + (ray_cam[valid] * z[valid][:, None]) @ R.T
    return {"z": z, "true_z": true_z, "colour": colour, "label": label, "valid": valid,
            "points": pts}


def sensor_errors(z, colour, label, *, valid, model: KinectModel, rng, around=None):
    """The Kinect's errors on rendered images: flying pixels on depth edges, disparity
    noise and quantisation, colour noise; returns (z, colour, label, valid). `around`, the
    depths of the pixels and of the ring round them ((h + 2, w + 2), NaN where nothing is
    measured), lets a window of a larger image see its neighbours; without it the image's
    edge has none."""
    z, colour, label, valid = _flying_pixels(z, colour, label, valid=valid, model=model,
                                             rng=rng, around=around)
    z = np.where(valid, model.add_depth_noise(np.where(valid, z, 1.0), rng), z)
    colour = colour + model.colour_noise * rng.standard_normal(colour.shape)
    return z, colour, label, valid


_COLOUR_OF = np.zeros((len(LABELS), 3))  # a label's paint, before shading
_COLOUR_OF[LABELS["arm"]] = ARM_COLOUR
_COLOUR_OF[LABELS["object"]] = OBJECT_COLOUR
_COLOUR_OF[LABELS["table"]] = TABLE_COLOUR
_COLOUR_OF[LABELS["mount"]] = MOUNT_COLOUR
_COLOUR_OF.flags.writeable = False


@functools.lru_cache(maxsize=4)
def _rays(eye: tuple, target: tuple, up: tuple, *, model: KinectModel):
    """The camera's rays, made once for a pose and a model (read-only): (h, w, 3) directions
    in the camera frame with z = 1, the float32 (origin, world direction) rows for
    cast_rays, and the (h, w, 3) unit world directions. Numpy only: an Open3D tensor held
    here until the interpreter exits makes Open3D report leaked memory and the process exit
    with status 1."""
    R = CameraPose(eye, target, up).rotation()
    u, v = np.meshgrid(np.arange(model.width), np.arange(model.height))
    cx, cy = (model.width - 1) / 2.0, (model.height - 1) / 2.0
    ray_cam = np.stack([(u - cx) / model.focal, (v - cy) / model.focal, np.ones(u.shape)], -1)
    ray_world = ray_cam @ R.T  # z component 1 in the camera frame, so t_hit is the depth
    rays = np.concatenate([np.broadcast_to(np.asarray(eye), ray_world.shape), ray_world], -1)
    ray_dir = ray_world / np.linalg.norm(ray_world, axis=-1, keepdims=True)
    ray_cam.flags.writeable = ray_dir.flags.writeable = False
    return ray_cam, np.ascontiguousarray(rays, dtype=np.float32), ray_dir


def _flying_pixels(z, colour, label, *, valid, model: KinectModel, rng, around=None):
    """Mix foreground and background at depth edges, as a Kinect's correlation window does
    (`around`: sensor_errors)."""
    zf = np.where(valid, z, np.nan)
    pad = np.pad(zf, 1, constant_values=np.nan) if around is None else around
    up, down, left, right = pad[:-2, 1:-1], pad[2:, 1:-1], pad[1:-1, :-2], pad[1:-1, 2:]
    # The deepest and nearest of a pixel and its valid neighbours (NaN ignored).
    hi = np.fmax(np.fmax(np.fmax(up, down), np.fmax(left, right)), zf)
    lo = np.fmin(np.fmin(np.fmin(up, down), np.fmin(left, right)), zf)
    edge = valid & (hi - lo > model.edge_jump)
    fly = edge & (rng.random(z.shape) < model.flying_prob)
    t = rng.random(z.shape)
    z = np.where(fly, lo + t * (hi - lo), z)
    dim = 0.5 + 0.5 * rng.random(z.shape)
    colour = colour.copy()
    colour[fly] *= dim[fly][:, None]
    label = np.where(fly, -1, label)
    return z, colour, label, valid


def measured_depth(z, model: KinectModel, rng: np.random.Generator) -> np.ndarray:
    """A Kinect's measurement of the true depth image z ((h, w), m; 0 or inf where nothing
    lies within range): flying pixels on depth edges, then disparity noise and quantisation,
    as `render_cloud` applies them; inf where nothing is measured. The station's camera
    (drake_continuum.station) applies it to Drake's rendered depth."""
    z = np.asarray(z, dtype=float)
    valid = np.isfinite(z) & (z >= model.z_min) & (z <= model.z_max)
    z, _, _, valid = _flying_pixels(z, np.zeros(z.shape + (3,)), np.zeros(z.shape, np.int64),
                                    valid=valid, model=model, rng=rng)
    return np.where(valid, model.add_depth_noise(np.where(valid, z, 1.0), rng), np.inf)


def write_cloud(path, points, colours=None) -> None:
    """Write a cloud as .pcd or .ply (binary, metres), atomically."""
    import tempfile
    from pathlib import Path

    from ..files import write_atomic

    path = Path(path)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, float)))
    if colours is not None:
        pcd.colors = o3d.utility.Vector3dVector(np.asarray(colours, float))
    # Open3D writes only to a file name: write it in a private folder, then atomically.
    with tempfile.TemporaryDirectory(prefix="drake-continuum-") as scratch:
        tmp = Path(scratch) / f"cloud{path.suffix}"
        if not o3d.io.write_point_cloud(str(tmp), pcd, write_ascii=False, compressed=False):
            raise OSError(f"{path}: cannot write the point cloud")
        write_atomic(path, tmp.read_bytes())


def downsample(points, colours, voxel: float):
    """Voxel-grid downsampling (colours averaged), to keep shipped clouds small."""
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, float)))
    pcd.colors = o3d.utility.Vector3dVector(np.asarray(colours, float))
    d = pcd.voxel_down_sample(voxel)
    return np.asarray(d.points), np.asarray(d.colors)


def simulate_clouds(arm: ContinuumArm, config: ArmConfig, obj: trimesh.Trimesh, *, out,
                    cameras: int = 1, deform_mm: float = 0.0, seed: int = 0,
                    voxel: float = 0.0, meta: dict | None = None) -> list[tuple]:
    """Render the arm at `config` round `obj` from `cameras` views spread round the object
    and write each cloud (OUT, or OUT_view<k> with several views) with a JSON sidecar
    holding the true configuration, base pose and camera (what `fit-cloud` and
    `compare-real` read). Each view has its own noise (seed + k): two Kinects do not share
    their errors. Returns (cloud path, sidecar path, points) a view."""
    from pathlib import Path

    from pydrake.math import RollPitchYaw, RotationMatrix

    from ..files import write_json

    out = Path(out)
    if out.suffix.lower() not in (".pcd", ".ply"):
        raise DepthCameraError(f"{out}: a cloud must end in .pcd or .ply")
    if deform_mm < 0:
        raise DepthCameraError(f"deform must be >= 0 mm, got {deform_mm}")
    if cameras < 1:
        raise DepthCameraError(f"cameras must be at least 1, got {cameras}")
    meta = dict(meta or {})
    poses = cameras_around(cameras)
    paths = [out] if len(poses) == 1 else \
        [out.with_name(f"{out.stem}_view{k}{out.suffix}") for k in range(len(poses))]
    out.parent.mkdir(parents=True, exist_ok=True)
    written = []
    for k, (camera, path) in enumerate(zip(poses, paths)):
        sim = render_cloud(arm, config, obj, camera=camera, deform=deform_mm / 1000.0,
                           seed=seed + k)
        pts, cols = sim.points, sim.colours
        if voxel > 0:
            pts, cols = downsample(pts, cols, voxel)
        write_cloud(path, pts, cols)
        meta.update(config=config.to_dict(), tip=arm.tip_frame(config)[1].tolist(),
                    base_position=arm.base_position.tolist(),
                    base_rpy=RollPitchYaw(RotationMatrix(arm.base_rotation)).vector().tolist(),
                    camera=sim.camera.to_dict(), view=k, views=[p.name for p in paths],
                    sensor=vars(sim.model) if hasattr(sim.model, "__dict__") else {},
                    deform_mm=deform_mm, seed=seed + k, voxel=voxel,
                    n_points=len(pts), arm_colour=list(ARM_COLOUR), units="m")
        written.append((path, write_json(path.with_suffix(".json"), meta), len(pts)))
    return written


def curled_configs(arm: ContinuumArm, obj: trimesh.Trimesh, n: int, *, rng: np.random.Generator,
                   batch: int = 60) -> list[ArmConfig]:
    """Random valid configurations that curl round `obj`, as a touch-driven wrap does.

    A stand-in for true wraps where none are at hand. Section 1 reaches past the object,
    bending slightly away from it; section 2 and then section 3 bend towards it, each until
    it first touches (bisection on its curvature; a section that cannot touch keeps the
    previous one's curvature), in nearly one plane. Kept: within the arm's limits, above the
    table, not entering the object by more than 1 mm, 120 to 330 degrees of bending in all
    (a wrap stops at a 270-degree tip rotation) and clear of itself.
    """
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(raycast_mesh(obj))
    reach = float(np.linalg.norm(obj.nearest.on_surface([arm.base_position])[0][0]
                                 - arm.base_position))
    out: list[ArmConfig] = []
    n_bb = 90

    def backbones(s, k, phi):
        cfgs = [ArmConfig(s[i], k[i], phi[i]) for i in range(len(s))]
        return cfgs, [arm.backbone(c, n=n_bb) for c in cfgs]

    def section_gaps(bbs, section, skip=0.0):
        """Least clearance of each arm's given section (from `skip` m into it) to the object."""
        pos = np.stack([b.position for b in bbs])
        sd = scene.compute_signed_distance(o3d.core.Tensor(
            pos.reshape(-1, 3).astype(np.float32))).numpy().reshape(len(bbs), -1)
        sec = np.stack([b.section for b in bbs])
        arc = np.stack([b.arc_length for b in bbs])
        start = np.stack([np.concatenate([[0.0], np.cumsum(c)])[section] for c in s_cur])
        mask = (sec == section) & (arc >= start[:, None] + skip)
        return np.where(mask, sd, np.inf).min(1) - arm.radius, sd.min(1) - arm.radius

    while len(out) < n:
        psi = rng.uniform(0, 2 * np.pi, batch)
        s = np.column_stack([rng.uniform(max(arm.section_length_min, reach - 0.02),
                                         reach + 0.10, batch),
                             rng.uniform(0.12, 0.24, (batch, 2))])
        s = np.clip(s, arm.section_length_min, arm.section_length_max)
        s_cur = s
        phi = np.column_stack([psi + np.pi, psi + rng.normal(0, 0.15, batch),
                               psi + rng.normal(0, 0.25, batch)])
        k = np.column_stack([rng.uniform(1, 6, batch), np.zeros(batch), np.zeros(batch)])
        limit = arm.curvature_limit(s)  # curvature and bend limits, a section each
        for j in (1, 2):  # sections 2 and 3 in turn close on the object
            lo, hi = np.zeros(batch), limit[:, j].copy()
            kk = k.copy()
            kk[:, j:] = limit[:, j:]
            touches = section_gaps(backbones(s, kk, phi)[1], j, 0.02 * (j == 2))[0] < 0
            for _ in range(12):
                mid = 0.5 * (lo + hi)
                kk[:, j:] = np.minimum(mid[:, None], limit[:, j:])
                hit = section_gaps(backbones(s, kk, phi)[1], j, 0.02 * (j == 2))[0] < 0
                hi, lo = np.where(hit, mid, hi), np.where(hit, lo, mid)
            k[:, j] = np.minimum(np.where(touches, lo, k[:, j - 1]), limit[:, j])
            if j == 1:
                ok = touches
        cfgs, bbs = backbones(s, k, phi)
        pos = np.stack([b.position for b in bbs])
        gap = section_gaps(bbs, 0)[1]
        turn = np.degrees((s[:, 1:] * k[:, 1:]).sum(1))
        # Self-clearance: parts of the arm more than 4 radii apart along it stay 1.5 cm apart.
        arc = np.stack([b.arc_length for b in bbs])
        far = np.abs(arc[:, :, None] - arc[:, None, :]) > 4 * arm.radius
        d = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
        self_gap = np.where(far, d, np.inf).min((1, 2)) - 2 * arm.radius
        ok &= ((pos[..., 2].min(1) > arm.radius + 0.005) & (gap > -0.001)
               & (turn >= 120) & (turn <= 330) & (self_gap > 0.015)
               & np.array([arm.within_limits(c) for c in cfgs]))
        out.extend(cfgs[i] for i in np.flatnonzero(ok))
    return out[:n]
