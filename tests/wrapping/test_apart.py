"""The capsules proven apart from an object against Drake: no capsule with a contact
surface is ever proven apart, and the hull's planes hold every vertex of the object."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig, load_arm
from drake_continuum.wrapping.apart import APART_MARGIN, ApartTest
from drake_continuum.wrapping.scene import SceneOptions, WrapScene


def _objects():
    """The shipped mug, a standing torus and a thin bowl-like annulus."""
    torus = trimesh.creation.torus(major_radius=0.06, minor_radius=0.015)
    torus.apply_transform(trimesh.transformations.euler_matrix(0.2, np.pi / 2, 0.0))
    torus.apply_translation([0.0, 0.0, 0.08])  # the straight arm passes through its hole
    ring = trimesh.creation.annulus(r_min=0.04, r_max=0.05, height=0.06)
    ring.apply_translation([0.0, 0.0, 0.03])
    return {"mug": MODELS_DIR / "mug.obj", "torus": torus, "ring": ring}


@pytest.fixture(scope="module")
def arm():
    return load_arm()


@pytest.mark.parametrize("name", ["mug", "torus", "ring"])
def test_hull_planes_hold_every_vertex(name):
    """Each plane lies beyond every vertex of the object (by far less than the margin the
    test keeps), and on the hull: a vertex lies on it."""
    mesh = _objects()[name]
    mesh = trimesh.load(mesh) if not isinstance(mesh, trimesh.Trimesh) else mesh
    test = ApartTest(mesh, 60, reach=0.01, half=0.01)
    beyond = mesh.vertices @ test.planes[:, :3].T + test.planes[:, 3]
    assert beyond.max() < 1e-3 * APART_MARGIN
    assert np.abs(beyond.max(axis=0)).max() < 1e-12


@pytest.mark.parametrize("name", ["mug", "torus", "ring"])
def test_no_capsule_drake_finds_touching_is_proven_apart(arm, name):
    """Random curls round the object, each posed in a scene that asks Drake about every
    capsule: every capsule with a contact surface is near; and the test proves apart most
    capsules that lie in the object's hull without touching it."""
    scene = WrapScene(arm, _objects()[name], options=SceneOptions(hull_prefilter=False))
    test = ApartTest(scene.object_trimesh, scene.n_links, reach=arm.radius,
                     half=scene.link_length / 2)
    rng = np.random.default_rng(4)
    touching = in_hull = proven = 0
    for _ in range(120):
        s = rng.uniform(0.1, 0.3, 3)
        scene.set_config(ArmConfig(s, rng.uniform(0, 1, 3) * arm.curvature_limit(s),
                                   rng.normal(0, 0.3, 3)))
        position, tangent, _ = scene._link_frame
        near = test.near(position, tangent, 0)
        links = scene.touching_links()
        assert near[links].all()
        hull = {scene._link_of_geometry.get(p.id_A, scene._link_of_geometry.get(p.id_B))
                for p in scene._query_port.Eval(scene._sg_context).ComputePointPairPenetration()}
        hull = np.array(sorted(hull - set(links.tolist())), int)
        touching += len(links)
        in_hull += len(hull)
        proven += int((~near[hull]).sum())
    assert touching > 40 and in_hull > 5
    assert proven > 0.3 * in_hull
