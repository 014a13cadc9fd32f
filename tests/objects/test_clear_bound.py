"""check_clear and the scene's reach check decide from the bounding box or a vertex where
that proves the answer: the same decisions as the exact searches (trimesh's closest point
and containment) over a sweep of positions near, around and beyond the arm base."""

import numpy as np
import pytest
import trimesh

from drake_continuum.errors import DrakeContinuumError
from drake_continuum.kinematics.arm import load_arm
from drake_continuum.objects.placement import ARM_CLEARANCE, PlacementError, check_clear
from drake_continuum.wrapping.scene import WrapScene


def _sphere_at(x: float) -> trimesh.Trimesh:
    s = trimesh.creation.icosphere(subdivisions=2, radius=0.04)
    s.apply_translation((x, 0.0, 0.05))
    return s


def _exact_clear(mesh, arm) -> bool:
    base = np.asarray(arm.base_position, dtype=float)
    gap = float(trimesh.proximity.closest_point(mesh, [base])[1][0]) - arm.radius
    return (mesh.vertices[:, 0].min() > base[0] and gap >= ARM_CLEARANCE
            and not mesh.contains([base])[0])


def test_check_clear_decides_as_the_exact_search():
    arm = load_arm()
    x0 = float(arm.base_position[0])
    decisions = []
    for x in x0 + np.linspace(-0.06, 0.2, 27):
        mesh = _sphere_at(x)
        try:
            check_clear(mesh, arm)
            clear = True
        except PlacementError:
            clear = False
        assert clear == _exact_clear(mesh, arm), x
        decisions.append(clear)
    assert any(decisions) and not all(decisions)  # the sweep crosses the boundary


def _reach_ok(mesh, arm) -> bool:
    base = np.asarray(arm.base_position, dtype=float)
    closest = mesh.nearest.on_surface([base])[1][0]
    return closest <= arm.length_max and not mesh.contains([base])[0]


@pytest.mark.parametrize("dx", [0.0, 0.02, 0.3, 1.2, 1.4])
def test_the_scene_refuses_what_the_exact_search_refuses(dx):
    """A sphere around the base, beside it, in reach and beyond it."""
    arm = load_arm()
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    mesh.apply_translation(np.asarray(arm.base_position, dtype=float) + [dx, 0.0, 0.0])
    try:
        WrapScene(arm, mesh)
        ok = True
    except DrakeContinuumError:
        ok = False
    assert ok == _reach_ok(mesh, arm)
