"""Time one contact-scene cycle (set_config + contacts()) over a wrap-like sweep.

The sweep imitates what a touch-driven wrap asks the scene: the arm curls around the mug
body in the horizontal plane of its base, and for each curl the first section's bend is
bisected (on the exact signed distance) so that the arm either just touches the body
(penetration 0-1.5 mm: the paper's delta is 1 mm) or just misses it (gap 0-5 mm). Two
meshes: the shipped 2k-triangle mug and the same mug subdivided to about 20k triangles.
Prints one JSON object; record it in BENCHMARKS.md ("Wrapping").

    python benchmarks/bench_scene.py [--n 200] [--seed 0]
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np
import trimesh

from drake_continuum.files import json_text
from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig, load_arm
from drake_continuum.objects.mesh import load_mesh
from drake_continuum.wrapping.scene import SceneOptions, WrapScene

PHI = np.array([-np.pi / 2, np.pi / 2, np.pi / 2])  # S-curve: out to -y, then around +y


def _config(kappa1: float, curl: float, s23: float) -> ArmConfig:
    return ArmConfig([0.14, s23, s23], [kappa1, curl, curl], PHI)


def wrap_like_sweep(scene: WrapScene, n: int, seed: int) -> list[ArmConfig]:
    """n configurations: a curl and a first-section bend that touches or nearly touches."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        curl, s23 = rng.uniform(12.0, 30.0), rng.uniform(0.10, 0.16)
        target = rng.uniform(-0.0015, 0.0) if rng.random() < 0.6 else rng.uniform(0.0, 0.005)
        lo, hi = 0.0, 15.0  # more kappa1 swings the arm further out to -y, away from the mug

        def gap(k1):
            return scene.clearance(_config(k1, curl, s23), n=300).min()

        if not scene.arm.within_limits(_config(lo, curl, s23)):
            continue
        if gap(lo) > target or gap(hi) < target:
            continue
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if gap(mid) < target else (lo, mid)
        out.append(_config(hi, curl, s23))
    return out


def time_cycle(scene: WrapScene, configs) -> dict:
    for c in configs[:5]:  # warm up
        scene.set_config(c)
        scene.contacts()
    ms, cpu_ms, n_contacts = [], [], []
    for c in configs:
        t, t_cpu = time.perf_counter(), time.process_time()
        scene.set_config(c)
        contacts = scene.contacts()
        ms.append(1e3 * (time.perf_counter() - t))
        cpu_ms.append(1e3 * (time.process_time() - t_cpu))
        n_contacts.append(len(contacts))
    ms = np.asarray(ms)
    # CPU time too: on a shared machine the wall time mostly measures the other processes.
    return {"median_ms": round(float(np.median(ms)), 3),
            "p95_ms": round(float(np.percentile(ms, 95)), 3),
            "median_cpu_ms": round(float(np.median(cpu_ms)), 3),
            "p95_cpu_ms": round(float(np.percentile(cpu_ms, 95)), 3),
            "n": len(ms),
            "touching_fraction": round(float(np.mean(np.asarray(n_contacts) > 0)), 3)}


def run(n: int = 200, seed: int = 0, options: SceneOptions = SceneOptions()) -> dict:
    arm = load_arm()
    mug = load_mesh(MODELS_DIR / "mug.obj")
    fine = mug.subdivide_to_size(0.011) if len(mug.faces) < 20000 else mug
    fine = trimesh.Trimesh(fine.vertices, fine.faces, process=True)
    result = {"benchmark": "contact scene: set_config + contacts()",
              "python": platform.python_version(), "machine": platform.machine(),
              "links_per_section": options.links_per_section,
              "resolution_hint": options.resolution_hint, "meshes": {}}
    configs = None
    for name, mesh in (("mug_2k", mug), ("mug_20k", fine)):
        scene = WrapScene(arm, mesh, options=options)
        if configs is None:
            configs = wrap_like_sweep(scene, n, seed)
        result["meshes"][name] = {"triangles": int(len(mesh.faces)), **time_cycle(scene, configs)}
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=200, help="configurations timed (default: 200)")
    parser.add_argument("--seed", type=int, default=0, help="sweep seed (default: 0)")
    args = parser.parse_args()
    print(json_text(run(args.n, args.seed), indent=2))


if __name__ == "__main__":
    main()
