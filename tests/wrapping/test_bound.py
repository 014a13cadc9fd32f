"""The best conformity an in-plane arm can reach (wrapping.bound): a cylinder it can hug
(closed form: the hugging arc's curvature 1/(R + r)), and never below a wrap's own."""

import numpy as np
import pytest
import trimesh

from drake_continuum.kinematics.arm import load_arm
from drake_continuum.wrapping.bound import (
    BoundParams,
    _Search,
    best_wrap,
    measure,
    planar_arm,
)
from drake_continuum.wrapping.conformity import NEAR
from drake_continuum.wrapping.planes import enumerate_planes
from drake_continuum.wrapping.scene import WrapScene
from drake_continuum.wrapping.wrap import wrap

# The bound's search cut short (30 generations, one member polished; it runs 250 and 3):
# the cylinder's closed form and the box's own wrap are met by the shorter search already.
SHORT = BoundParams(maxiter=30, polish=1)


def _standing(mesh, height=0.15):
    mesh.apply_translation([0.0, 0.0, height / 2])
    return mesh


def test_a_cylinder_the_arm_can_hug_is_all_near_on_arcs_of_its_curvature():
    R = 0.04  # 1/(R + r) = 20 1/m, within the arm's 40
    arm = load_arm()
    scene = WrapScene(arm, _standing(trimesh.creation.cylinder(radius=R, height=0.15,
                                                               sections=128)))
    plane = enumerate_planes(arm.base_position)[0]  # horizontal: the cut is a circle
    params = SHORT
    found = best_wrap(scene, plane, params=params)
    m = found.measure
    assert found.feasible and m.feasible(params)
    assert m.conformity >= 0.98
    assert m.turn >= params.theta and m.press <= params.press_depth + 1e-5
    # The sections carrying the measured part hug: concentric arcs stay near and press no
    # deeper than allowed only for curvatures in [1/(R + r + near), 1/(R + r - press)].
    ends = np.concatenate([[0.0], np.cumsum(found.arm.s)])
    overlap = np.minimum(ends[1:], ends[-1]) - np.maximum(ends[:-1], m.start)
    kappa = found.arm.bend / found.arm.s
    hugging = kappa[overlap > 0.03]
    assert len(hugging) >= 2  # 270 deg at 20 1/m is 0.24 m: two sections (bend <= 180 deg)
    r = arm.radius
    assert np.all(hugging >= 1 / (R + r + NEAR) - 0.3)
    assert np.all(hugging <= 1 / (R + r - params.press_depth) + 0.3)
    # The measure is WrapResult's: every 5 mm from the first contact, all near.
    assert np.all(scene.signed_distance(m.samples) - r <= NEAR)


def test_the_bound_is_at_least_a_wrap_of_the_same_plane():
    """A box's square-ish cut, which Algorithm 1 wraps in its plane, touching no deeper than
    the bound allows and turning theta after its first contact: a point the bound's search
    must match or beat without being given it."""
    arm = load_arm()
    scene = WrapScene(arm, _standing(trimesh.creation.box([0.08, 0.05, 0.15])))
    plane = enumerate_planes(arm.base_position)[0]
    params = SHORT
    actual = wrap(scene, plane)
    flat, off = planar_arm(arm, plane, actual.base_rotation, config=actual.final_config)
    mine = measure(scene, plane, flat, params=params)
    assert off < 1e-6, "the wrap left its plane"
    assert mine.press <= 1.5e-3 and mine.turn >= params.theta - np.radians(10.0)
    # From its first contact the measure is WrapResult's (the contact from distances, not
    # Drake's surfaces: within a sample or two).
    assert abs(mine.from_contact - actual.conformity) <= 0.02
    found = best_wrap(scene, plane, params=params)
    assert found.measure.feasible(params)
    assert found.measure.conformity >= mine.conformity


@pytest.mark.parametrize("params", [BoundParams(), BoundParams(
    signed=True, start="contact", turn="from_base", per_section=155)])
def test_one_point_compiled_gives_the_vectorised_terms(params):
    """Nelder-Mead's objective of one point (compiled, sample by sample) against the search's
    vectorised objective: the same terms to 1e-12 on the seeds that hug a bowl's cut (near,
    touching, pressing) and on random configurations (far, crossing themselves)."""
    arm = load_arm()
    bowl = trimesh.creation.annulus(r_min=0.05, r_max=0.06, height=0.05)
    scene = WrapScene(arm, _standing(bowl, height=0.05))
    search = _Search(scene, enumerate_planes(arm.base_position)[3], params)
    lo, hi = np.array(search.bounds).T
    X = np.vstack([search.seeds()[::97], np.random.default_rng(1).uniform(lo, hi, (60, len(lo)))])
    expected = np.stack(search.terms(X), 1)
    found = np.array([search.one(x) for x in X])
    assert np.ptp(expected[:, 0]) > 0.5 and expected[:, 2].max() > 0.0  # near and pressing
    np.testing.assert_allclose(found, expected, rtol=0, atol=1e-12)
    assert search.penalised(tuple(found.T)) == pytest.approx(search.objective(X), abs=1e-10)
