"""Touch-driven whole-arm wrapping: the paper's Algorithm 1 (section IV-A).

The arm starts straight in the wrap plane, passing the object at a small clearance, and
alternates two motions until its tip has turned more than theta or IK fails:

- enclosing: curve section i by d_kappa (and extend it by d_s) while it is below its
  curvature limit, moving on to the section after the furthest contact, until the last
  section touches or reaches its limit;
- advancing: move the tip along n + t + b (see below) by delta once for every contact on
  the last section, the other section ends likewise from the contacts nearest them and the
  rest along their tangents, then solve constrained IK for the new configuration. With
  `delta_max_factor` above 1 the step grows while the tip is far from theta
  (`WrapParams.advancing_step`); it changes the wraps (BENCHMARKS.md, Wrapping).

`WrapStepper` holds one wrap between its motions: `wrap()` drives it to the end, and the
station's WrapController (drake_continuum.station) makes each motion a discrete update.

Two enclosing implementations: `reference` queries hydroelastic contact at every step as
the paper does; `fast` skips the steps that a distance bound proves contact-free (clearance
to the real surface from Open3D against the largest motion of the arm per step), asks
further ahead after each query that finds nothing (galloping), then bisects the first
contact step. They take the same steps wherever contact, once made, persists as a section
curves on (tests: within 1 mm and 2 deg of tip turning).

Deviations from the paper, each for a stated reason:
- A step of d_kappa = 0.1 1/m turns a 0.3 m section's end by 0.03 rad and moves points 0.6 m
  beyond it by 18 mm, so a literal step can plunge into the object. Each enclosing step is
  therefore capped to move no centre-line point more than `max_step_motion` (default delta).
- The paper's contact set accumulates every enclosing step, so one touch counts many times;
  advancing here uses the contact regions of the last enclosing step, each once.
- Advancing goes along n + t by default (`use_binormal`): b = n x t is the wrap plane's
  normal for an in-plane contact, and adding it pushed the arm out of its plane by delta a
  round (measured: a section's bending plane turned 90 deg within one wrap).
- A section also obeys the arm's bend limit (kappa s <= bend_max), or it coils.
- Enclosing grows a section's curvature vector towards the wrap's side in the wrap plane
  (`_Curving.advance`), which is kappa += d_kappa for a section bending in the plane. IK
  leaves phi arbitrary on a nearly straight section, and curving along phi would coil the
  section out of the wrap plane (and make the tip's turning about the plane's normal jump).
- When enclosing curls the arm to its limits without touching, the wrap ends at its last
  touch: a free-air curl says nothing of the object. A wrap that stalls (stall_rounds)
  likewise ends at the enclosing that turned its tip furthest.
- The tip's rotation (the theta stop) is the tip direction's angle from the start
  direction about the plane's normal, unwrapped along the arm (`tip_heading`): a property
  of the configuration, so a tip's back-and-forth between rounds is not turning.
- The arm's own tube is an obstacle (`WrapScene.self_touching`): a section that brings the
  arm round onto itself stops curving there and enclosing ends; a wrap that closes on
  itself before its tip turns theta ends with status CLOSED, instead of passing
  through its own first section (measured: BENCHMARKS.md, Wrapping).
- A contact at a joint (within a capsule's reach of a section's start) stops the section
  before the joint, not the one after (`_touch`): curving a section barely moves its base.
"""

from __future__ import annotations

import time
from enum import Enum

import numpy as np

from ..kinematics.arm import ArmConfig, arc_rotations
from ..kinematics.ik import solve_ik
from .conformity import near_fraction, swept_angle
from .contact import Contacts
from .params import WrapMethod, WrapParams
from .planes import BaseClearanceError, WrapPlane, cut_centroid
from .scene import WrapScene
from .start import BACKOFF_MARGIN, base_backoff, start_configuration  # noqa: F401 (also here)
from .step_bound import StepBound
from .wrap_types import WrapResult, WrapStatus

__all__ = ["WrapMethod", "WrapParams", "WrapPhase", "WrapStepper", "tip_heading", "wrap"]


class _Curving:
    """Enclosing steps of one section, shared by both methods so both take the same steps."""

    def __init__(self, scene: WrapScene, params: WrapParams):
        self.scene, self.params, self.arm = scene, params, scene.arm
        self._in_plane = (None, None)  # (section base, its in-plane bending direction)
        self.bound = StepBound(scene, params.table)  # the fast method's distance bound

    def step_size(self, config: ArmConfig, i: int) -> float:
        """d_kappa capped so that no centre-line point moves more than max_step_motion: a
        curvature change dk moves points at most dk * s_i * (s_i / 2 + rest of the arm)."""
        s = config.s
        reach = s[i] * (s[i] / 2 + s[i + 1:].sum())
        return min(self.params.d_kappa, self.params.max_step_motion / max(reach, 1e-12))

    def advance(self, config: ArmConfig, i: int, dk: float, *, k: int = 1) -> ArmConfig:
        """`k` steps of section i: its curvature vector (kappa cos phi, kappa sin phi) grows
        by dk a step towards the wrap's side in the wrap plane (to the curvature limit), s by
        d_s (to its limit).

        Growing the curvature vector rather than kappa along the section's own phi is what
        curves a section in the plane: IK leaves phi arbitrary where kappa is near zero (a
        straight section has no bending plane), and curving along such a phi coiled the
        section out of the plane (cup_000 plane 4: phi 88 deg at kappa 0.2 1/m, then 18 1/m
        across the plane, its tip turned "362 deg" about the plane's normal). Where the
        section already bends in the plane this is the paper's kappa += d_kappa.
        """
        arm = self.arm
        kappa, s, phi = config.kappa.copy(), config.s.copy(), config.phi.copy()
        s[i] = min(s[i] + k * self.params.d_s, arm.section_limits()[1][i])
        u, v = kappa[i] * np.cos(phi[i]), kappa[i] * np.sin(phi[i])
        c, sn = self.in_plane(config, i)
        u, v = u + k * dk * c, v + k * dk * sn
        norm = np.hypot(u, v)
        kappa[i] = min(norm, arm.curvature_limit(s[i], section=i))
        phi[i] = np.arctan2(v, u) if norm > 0 else phi[i]
        return ArmConfig.of_arrays(s, kappa, phi)

    def in_plane(self, config: ArmConfig, i: int):
        """(cos, sin) of the bending angle that curves section i towards the wrap's side in
        the wrap plane: along N x z_i (N the plane's normal, the base's y; z_i the section's
        start tangent), in the section's base frame. Depends on sections before i only."""
        key = (i, config.s[:i].tobytes(), config.kappa[:i].tobytes(), config.phi[:i].tobytes())
        if self._in_plane[0] != key:  # curving one section asks with the same base: once
            # Section i's base frame, as section_frames makes it (its products, in order)
            R = np.array(self.arm.base_rotation, dtype=float)
            for turn in arc_rotations(config.s[:i], config.kappa[:i], config.phi[:i]):
                R = R @ turn
            w = _cross(self.arm.base_rotation[:, 1], R[:, 2])
            angle = np.arctan2(w @ R[:, 1], w @ R[:, 0])
            self._in_plane = (key, (np.cos(angle), np.sin(angle)))
        return self._in_plane[1]


def _cross(a, b) -> np.ndarray:
    """a x b of two 3-vectors: numpy.cross's products and differences, without its ~25 us
    of axis handling (enclosing asks at every section it curves)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


def _pose(scene: WrapScene, config: ArmConfig) -> None:
    """Pose the arm at `config`, unless the scene is posed there already (its query is then
    reused)."""
    if scene.config is not config:
        scene.set_config(config)


def _query(scene: WrapScene, config: ArmConfig) -> Contacts:
    """The contacts of `config`."""
    _pose(scene, config)
    return scene.contacts()


def _touch(scene: WrapScene, config: ArmConfig, i: int, *, params: WrapParams) -> int:
    """The furthest section of `config` whose contact stops section i from curving
    further, or a value below i when nothing does.

    Contacts are runs of touching capsules. Two rules decide which stop section i:

    - A run that begins before section i's joint (within one capsule's reach of its start,
      or on an earlier section) is the contact section i rests on. Curving section i lays
      more of it onto the object (the run grows along it), which is the arm conforming, not
      being stopped; it stops section i only once a capsule of section i beyond the joint
      presses more than `press_depth` into the object (how deep, from Drake's contact
      pressure: `WrapScene.touching_depths`). Counting every touching capsule of the
      section as a stop, as before, stopped a section whose base rests on the object as
      soon as the run grew 3 cm along it (apple_000 plane 5: section 2 at 10.5 1/m where
      the apple needs 22), so the next section curled to its limit in free air.
    - Any other run is a new touch: it stops section i at once, counted for the section it
      lies on, except that a capsule within a capsule's reach of a section's start counts
      for the section before (the joint touching: curving a section moves its base by at
      most dk r^2 / 2, so a touch there does not stop it). A touch of the table (with
      `params.table`) is always a new touch.
    """
    _pose(scene, config)
    k = scene.options.links_per_section
    if scene.self_touching(config, first=i * k):
        return scene.arm.n_sections - 1  # the arm came round to itself: enclosing ends
    # Touches wholly before section i cannot stop it; a run reaching its joint is seen
    # from the capsule before the section on.
    links = scene.touching_links(first=i * k - 1)
    table = scene.touching_table(first=i * k - 1) if params.table else np.zeros(0, int)
    if not len(links) and not len(table):
        return -1
    starts = np.concatenate([[0.0], np.cumsum(config.s)[:-1]])
    joint = scene.link_length / 2 + 2 * scene.arm.radius
    all_arcs = scene.posed_link_arcs  # of `config`, posed above

    def owner(touching):
        """The section each touching capsule counts for (the joint rule)."""
        section = touching // k
        at_joint = all_arcs[touching] - starts[section] < joint
        return np.where(at_joint & (section > 0), section - 1, section)

    stop = int(owner(table).max()) if len(table) else -1
    if not len(links):
        return stop
    whose = owner(links)
    past_joint = all_arcs[links] >= starts[i] + joint  # beyond section i's joint
    cuts = (np.flatnonzero(np.diff(links) > 1) + 1).tolist()
    for a, b in zip([0, *cuts], [*cuts, len(links)]):  # each run, links[a:b]
        if past_joint[a]:
            stop = max(stop, int(whose[a:b].max()))  # a new touch
            continue
        beyond = np.arange(a, b)[past_joint[a:b]]
        pressed = beyond[scene.touching_depths(links[beyond]) > params.press_depth]
        stop = max(stop, int(whose[pressed].max()) if len(pressed)
                   else min(i - 1, int(whose[a:b].max())))
    return stop


def _steps_left(arm, config: ArmConfig, i: int, *, dk: float) -> int:
    return int(np.ceil((arm.curvature_limit(config.s[i], section=i) - config.kappa[i]) / dk
                       - 1e-9))


def _curve_until_contact(scene, stepper, config, *, i, method):
    """Curve section i step by step until a contact on section i or beyond, or its limit.

    Contacts on earlier sections do not stop it: the paper's loop would find them at every
    step and carry on curving the section after them. Returns (config, furthest touching
    section or -1).

    The fast method finds the same first step with far fewer queries. It asks about the
    first step as the reference does (after an advancing step the arm usually touches again
    at once). Beyond it, a distance bound skips steps: a point with clearance g that moves at
    most m a step cannot touch within (g - margin) / m steps. Where a point lies within the
    margin (e.g. the joint beside the contact that stopped the previous section, which does
    not move as this section curves) one query at the bound's end rules out every step
    before it, and a contact there is bisected: exact wherever contact, once made, persists
    as the section curves on. Where the bound stays short (an arm lying along the surface:
    its points close in by a fraction of a step each step), queries that find no contact
    double in length, up to a tube radius of motion of any point, so that a capsule cannot
    pass a touch between two queries (measured on 66 wraps: 135.5 -> 78 queries a wrap,
    every status the same as the reference's).
    """
    arm = scene.arm
    dk = stepper.step_size(config, i)
    if method == WrapMethod.REFERENCE:
        while config.kappa[i] < arm.curvature_limit(config.s[i], section=i) - 1e-12:
            config = stepper.advance(config, i, dk)
            j = _touch(scene, config, i, params=stepper.params)
            if j >= i:
                return config, j
        return config, _touch(scene, config, i, params=stepper.params)

    if _steps_left(arm, config, i, dk=dk) > 0:
        config = stepper.advance(config, i, dk)
        j = _touch(scene, config, i, params=stepper.params)
        if j >= i:
            return config, j
    gallop = 0  # steps of the last query that found no contact
    while (left := _steps_left(arm, config, i, dk=dk)) > 0:
        nxt = stepper.advance(config, i, dk)  # one step on: reused below wherever k is 1
        # With one step left that step is asked whatever the bound would say.
        cap, near, longest = (1, True, 1) if left == 1 else stepper.bound((config, nxt), i=i,
                                                                           left=left)
        if not near and cap >= 2:
            skip = nxt if cap == 2 else stepper.advance(config, i, dk, k=cap - 1)
            # The bound is the object's; the arm coming round to itself is checked here.
            if not scene.self_touching(skip, first=i * scene.options.links_per_section):
                config, gallop = skip, 0
                continue
        cap = min(left, max(cap, min(2 * gallop, longest)))
        trial = nxt if cap == 1 else stepper.advance(config, i, dk, k=cap)
        j = _touch(scene, trial, i, params=stepper.params)
        if j < i:
            config = trial
            gallop = cap
            continue
        lo, hi, hit = 0, cap, j
        tried = {cap: trial}  # configurations queried, by step
        while hi - lo > 1:
            mid = (lo + hi) // 2
            tried[mid] = nxt if mid == 1 else stepper.advance(config, i, dk, k=mid)
            j = _touch(scene, tried[mid], i, params=stepper.params)
            if j >= i:
                hi, hit = mid, j
            else:
                lo = mid
        return tried[hi], hit
    return config, _touch(scene, config, i, params=stepper.params)


def _enclose(scene, stepper, config, *, method):
    """Enclosing motion: returns (config, contacts)."""
    n = scene.arm.n_sections
    i = 0
    while True:
        if config.kappa[i] < scene.arm.curvature_limit(config.s[i], section=i) - 1e-12:
            config, j = _curve_until_contact(scene, stepper, config, i=i, method=method)
            if j == n - 1:
                return config, _query(scene, config)
            if j >= i:
                i = j + 1
                continue
        if i == n - 1:
            return config, _query(scene, config)
        i += 1


def _advance_targets(scene: WrapScene, config: ArmConfig, contacts: Contacts,
                     *, params: WrapParams, step: float | None = None) -> np.ndarray:
    """New section end points (the advancing step of Algorithm 1), each moved `step`
    (default params.delta) per contact it owns."""
    step = params.delta if step is None else step
    arm = scene.arm
    R, p = arm.section_frames(config)
    ends, tangents = p[1:].copy(), R[1:, :, 2]
    n = arm.n_sections
    push = contacts.n + contacts.t + (contacts.b if params.use_binormal else 0.0)
    moved = np.zeros(n, bool)
    last = contacts.section == n - 1
    owner = np.where(last, n - 1,
                     np.argmin(np.linalg.norm(contacts.p[:, None, :] - p[None, 1:, :], axis=2),
                               axis=1))
    for m in range(n):  # a loop over section ends
        sel = owner == m
        if sel.any():
            ends[m] += step * push[sel].sum(0)
            moved[m] = True
    ends[~moved] += step * tangents[~moved]
    return ends


def _samples(scene: WrapScene, config: ArmConfig, contacts: Contacts, *, spacing: float):
    """Centre-line samples from the first contact to the tip."""
    if not len(contacts):
        return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3))
    arc = np.arange(float(contacts.arc_length.min()), float(config.s.sum()) + 1e-12, spacing)
    bb = scene.arm.backbone(config, arc)
    return arc, bb.position, bb.tangent, bb.normal


def tip_heading(arm, config: ArmConfig, n: int = 256) -> float:
    """How far the tip's z axis has turned from the start direction (the base's z axis),
    about the wrap plane's normal and positive towards the bending side, rad.

    Algorithm 1 stops when this exceeds theta (270 deg, so it must be unwrapped past 180
    deg). It is unwrapped along the arm, where the tangent turns smoothly (at most 0.1 rad
    between samples at the curvature limit), so it is a property of the configuration: a
    tip swinging back and forth between rounds does not count as turning, and a turn of
    more than 180 deg within one enclosing (the first often curls the tip 185-250 deg) is
    not taken the short way round.
    """
    t = arm.backbone(config, n=n).tangent
    R = arm.base_rotation
    return float(np.unwrap(np.arctan2(t @ R[:, 0], t @ R[:, 2]))[-1])


class WrapPhase(Enum):
    """The motion a WrapStepper makes next."""

    kEnclose = "enclose"
    kAdvance = "advance"
    kDone = "done"


class WrapStepper:
    """One wrap in progress: Algorithm 1 as alternating motions, driven by `wrap()` and by
    the station's WrapController (each motion one discrete update).

    Invariants between motions:
      - `phase` is the motion to make next; kDone once `status` (a WrapStatus) is set.
      - `config` is the arm's current configuration, the last of `configs`.
      - while phase is kAdvance, `contacts` are the contact regions of `config` (the
        enclosing that just ended touched the object).
      - `felt` are the contacts of the last enclosing that touched; `rotation` the tip's
        turning (`tip_heading`) at the last configuration asked.
      - `scene.arm` is the arm on this wrap's base until `result()` restores the scene's own.

    Args:
        scene: the contact scene; its arm is re-based for the wrap and restored by result().
        plane: the wrap plane.
        params: Algorithm 1's parameters.
    """

    def __init__(self, scene: WrapScene, plane: WrapPlane, params: WrapParams = WrapParams()):
        self.scene, self.plane, self.params = scene, plane, params
        self._t0, self._c0 = time.perf_counter(), time.thread_time()
        self._q0, self._s0, self._scene0 = (scene.n_queries, scene.n_contact_surfaces,
                                            dict(scene.timing))
        self.timing = {"ik": 0.0, "ik_solves": 0, "ik_programs": 0}
        self.base_arm = scene.arm
        self.phase, self.status, self.message = WrapPhase.kEnclose, None, ""
        self.rotation, self.rounds = 0.0, 0
        self.contacts = self.felt = Contacts.empty()
        self.best = []  # the furthest the tip had turned after each round
        self.slid = []  # how far the arm had advanced after each round, in steps of delta
        self.furthest = None  # (tip heading, configuration, contacts) of the furthest enclosing
        self._final = None  # contacts to report when they are not those of the final config
        arm = self.base_arm
        straight = ArmConfig.straight(arm.section_limits()[0])
        self.config, self.configs = straight, [straight]
        try:
            start = start_configuration(scene, plane, params)
        except BaseClearanceError as e:  # this plane cannot be wrapped; the others may
            self._end(WrapStatus.START_IN_COLLISION, str(e), Contacts.empty())
            return
        if start is None:
            self._end(WrapStatus.EMPTY_CUT, final=Contacts.empty())
            return
        R, self.config, position = start
        self.configs = [self.config]
        scene.arm = arm.with_base(position=position, rotation=R)
        scene.set_table(params.table)
        self._curving = _Curving(scene, params)
        self._field = scene.field(params.table)
        contacts = _query(scene, self.config)
        if len(contacts):
            self._end(WrapStatus.START_IN_COLLISION, final=contacts)
        elif len(scene.touching_table()):
            self._end(WrapStatus.START_IN_COLLISION,
                      "the straight start arm passes through the table", contacts)

    @property
    def done(self) -> bool:
        return self.phase is WrapPhase.kDone

    def step(self, contacts: Contacts | None = None) -> None:
        """The next motion; `contacts` of the current configuration for an advancing one
        (default: the scene's, as the enclosing found them)."""
        if self.phase is WrapPhase.kEnclose:
            self.enclose()
        elif self.phase is WrapPhase.kAdvance:
            self.advance(self.contacts if contacts is None else contacts)

    def _end(self, status: WrapStatus, message: str = "", final: Contacts | None = None) -> None:
        self.status, self.message, self.phase, self._final = status, message, WrapPhase.kDone, final

    def _turned(self, config: ArmConfig) -> bool:
        """Whether the tip has turned past theta (`tip_heading`), keeping the turning."""
        self.rotation = tip_heading(self.scene.arm, config)
        return self.rotation > self.params.theta

    def enclose(self) -> None:
        """The enclosing motion (`_enclose`), ending the wrap if it curls in free air, turns
        the tip past theta or closes the arm on itself; or the end of a stalled wrap."""
        p = self.params
        if self.rounds == p.max_iterations:
            self._end(WrapStatus.MAX_STEPS)
            return
        best, slid = self.best, self.slid
        # The round that ended stall_rounds steps of delta back (the same round for a fixed
        # step; exact, as the slides are counted in deltas).
        back = np.searchsorted(slid, slid[-1] - p.stall_rounds, side="right") - 1 if slid else -1
        if back >= 0 and best[-1] < best[back] + p.stall_turn:
            # The arm slid without wrapping: report the enclosing that wrapped furthest.
            self.rotation, self.config, self.felt = self.furthest
            self.configs.append(self.config)
            self._end(WrapStatus.MAX_STEPS, f"stalled: the tip turned less than "
                      f"{np.degrees(p.stall_turn):g} deg further in {p.stall_rounds} steps "
                      f"of delta", self.felt)
            return
        curled, contacts = _enclose(self.scene, self._curving, self.config, method=p.method)
        if len(contacts) == 0:
            # The arm curled to its limits in free air: that shape says nothing of the
            # object, so the wrap ends where it last touched.
            self._end(WrapStatus.AT_LIMITS if len(self.felt) else WrapStatus.NO_CONTACT)
            return
        self.config, self.felt, self.contacts = curled, contacts, contacts
        self.configs.append(curled)
        if self._turned(curled):
            self._end(WrapStatus.COMPLETE)
        elif self.scene.self_touching(curled):
            self._end(WrapStatus.CLOSED)  # round the object and onto itself short of theta
        else:
            if self.furthest is None or self.rotation > self.furthest[0]:
                self.furthest = (self.rotation, curled, contacts)
            self.phase = WrapPhase.kAdvance

    def advance(self, contacts: Contacts) -> None:
        """The advancing motion from `contacts` (the current configuration's): new section
        ends, then constrained IK; ends the wrap when IK fails or the tip turns past theta."""
        p = self.params
        step = p.advancing_step(p.theta - self.rotation)
        while True:
            targets = _advance_targets(self.scene, self.config, contacts, params=p, step=step)
            t_ik = time.thread_time()
            ik = solve_ik(self.scene.arm, targets, self.config, self._field, p.ik)
            self.timing["ik"] += time.thread_time() - t_ik
            self.timing["ik_solves"] += 1
            self.timing["ik_programs"] += not ik.newton
            if ik.success or step <= p.delta:
                break
            step = p.delta  # a longer step IK cannot follow is rejected, as an ODE solver's
        self.rounds += 1
        if not ik.success:
            self._end(WrapStatus.NO_IK, ik.message)
            return
        self.config = ik.config
        self.configs.append(self.config)
        if self._turned(self.config):
            self._end(WrapStatus.COMPLETE)
            return
        self.best.append(max(self.rotation, self.best[-1]) if self.best else self.rotation)
        self.slid.append((self.slid[-1] if self.slid else 0.0) + step / self.params.delta)
        self.phase = WrapPhase.kEnclose

    def result(self, contacts: Contacts | None = None) -> WrapResult:
        """The finished wrap (restores the scene's arm). Its contacts are those of the final
        configuration, `contacts` when given (default: the scene's query), or, where the arm
        ends lifted off the object, those of its last touch."""
        scene, params, plane, base_arm = self.scene, self.params, self.plane, self.base_arm
        if self._final is not None:
            contacts = self._final
        else:
            # Advancing lifts the arm about delta off the object; a wrap that ends there
            # reports the contacts of its last touch.
            contacts = _query(scene, self.config) if contacts is None else contacts
            contacts = contacts if len(contacts) else self.felt
        final = self.configs[-1]
        arc, pos, tan, nor = _samples(scene, final, contacts, spacing=params.sample_spacing)
        R_base = scene.arm.base_rotation
        offset = scene.arm.base_position - base_arm.base_position
        scene.arm = base_arm
        conformity, angle = 0.0, 0.0  # no wrapped arm: none of it near the object
        if len(pos):
            conformity = near_fraction(pos, scene.signed_distance, base_arm.radius)
            angle = swept_angle(pos, plane.normal, cut_centroid(scene.object_trimesh, plane))
        elapsed, cpu = time.perf_counter() - self._t0, time.thread_time() - self._c0
        timing = dict(self.timing)
        timing.update({k: v - self._scene0[k] for k, v in scene.timing.items()})
        timing["cpu_s"] = cpu
        timing["rest"] = cpu - sum(timing[k] for k in ("ik", *scene.timing))
        timing["contact_surfaces_queries"] = scene.n_contact_surfaces - self._s0
        extra = {"message": self.message} if self.message else {}
        return WrapResult(plane_index=plane.index, plane_normal=plane.normal,
                          base_rotation=R_base, status=self.status,
                          configs=np.array([c.as_vector() for c in self.configs]),
                          contacts=contacts, samples_arc_length=arc, samples_position=pos,
                          samples_tangent=tan, samples_normal=nor,
                          tip_rotation=float(self.rotation),
                          n_queries=scene.n_queries - self._q0, time_s=elapsed,
                          extra={**extra, "timing": timing}, conformity=conformity,
                          wrap_angle=angle, base_offset=offset if np.any(offset) else None)


def wrap(scene: WrapScene, plane: WrapPlane, params: WrapParams = WrapParams()) -> WrapResult:
    """Wrap the scene's object in one plane. Never raises for a failing wrap: the status
    says what happened ("No IK found" is WrapStatus.NO_IK)."""
    stepper = WrapStepper(scene, plane, params)
    while not stepper.done:
        stepper.step()
    return stepper.result()
