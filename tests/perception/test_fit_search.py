"""search.FitSearch: candidates ranked by (over, cost, order), all scored by one cost that a
start showing more of the arm seen raises for every candidate."""

import numpy as np

from drake_continuum.kinematics.arm import ArmConfig, load_arm
from drake_continuum.perception.medial import FitParams
from drake_continuum.perception.residuals import OVERRUN, soft_l1_cost
from drake_continuum.perception.search import Candidate, FitProblem, FitSearch, Start

ARM = load_arm()
CONFIG = ArmConfig([0.15, 0.20, 0.18], [2.0, 9.0, 14.0], [1.3, 1.4, 1.6])


def _points(step=0.004):
    sigma = np.arange(0.0, float(np.sum(CONFIG.s)), step)
    bb = ARM.backbone(CONFIG, arc_length=sigma)
    ang = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    return (bb.position[:, None] + ARM.radius * (np.cos(ang)[None, :, None] * bb.normal[:, None]
            + np.sin(ang)[None, :, None] * bb.binormal[:, None])).reshape(-1, 3)


def _scored_by_the_search(search):
    loss = search.problem.params.loss_scale
    assert search.scorer.length_cap == search.total + OVERRUN
    for c in search.fits:
        assert c.cost == soft_l1_cost(search.scorer(c.refined.sol.x), loss)


def test_candidates_are_ranked_and_rescored_when_more_is_seen():
    seen = float(np.sum(CONFIG.s))
    search = FitSearch(FitProblem(ARM, _points(), None, FitParams(max_nfev=20)),
                       total=seen - 0.1)
    near = ArmConfig(CONFIG.s, CONFIG.kappa * 0.9, CONFIG.phi + 0.05)
    straight = ArmConfig(CONFIG.s, np.zeros(3), CONFIG.phi)
    first = search.attempt(Start(straight, None), prefit=False)
    second = search.attempt(Start(near, None), prefit=False)
    assert [c.order for c in search.fits] == [0, 1] and first.start is straight
    assert search.best() == min(search.fits, key=Candidate.rank)
    _scored_by_the_search(search)
    search.attempt(Start(near, None, seen), prefit=False)  # shows the whole arm seen
    assert search.total == seen and len(search.fits) == 3
    _scored_by_the_search(search)
    assert search.fits[1].refined is second.refined
    assert search.nfev == sum(c.refined.nfev for c in search.fits)


def test_a_u_turn_bent_the_other_way_round_is_started_again_in_the_plane():
    """A wrap's U-turn (section 2 half a turn) seen from one camera, as Algorithm 1 left it
    round seed 3's hammer_001 in plane 1: the orderings' starts bend the first section and
    send the rest the other way round (tip 26 mm off, cameras seeing through it); started
    again with every section bent in the wrap's plane, the fit finds the arm."""
    from pydrake.math import RotationMatrix

    from drake_continuum.perception import depth_camera as dc
    from drake_continuum.perception.cloud import Cloud
    from drake_continuum.perception.fitting import fit_cloud
    from drake_continuum.perception.residuals import WrapPlane

    R = np.array([[0.1495727324654246, 0.0, 0.9887507257660176],
                  [-0.9134865582909039, 0.38268343236508984, 0.13818718614659223],
                  [-0.37837852148961326, -0.9238795325112867, 0.05723900664809398]])
    arm = ARM.with_base(np.array([-0.18, 0.0, 0.05]), R)  # the wrap's base, as stored
    truth = ArmConfig([0.178305, 0.10047, 0.100093], [0.29097, 31.268962, 9.3], [0.0, 0.0, 0.0])
    normal = RotationMatrix.MakeXRotation(np.radians(22.5)).matrix()[:, 2]
    eye = np.asarray(dc.CameraPose().eye, float)
    sim = dc.render_cloud(arm, truth, None, seed=1)
    _, fit = fit_cloud(Cloud(sim.points, sim.colours), arm, truth.s, eye=eye,
                       plane=WrapPlane(tuple(normal)))
    assert np.linalg.norm(fit.tip - arm.tip_frame(truth)[1]) < 1e-3
