"""Algorithm 1's parameters (WrapParams: models/config.yaml, section wrap) and its
enclosing methods (WrapMethod), apart from the loop that reads them."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from ..checks import GAP, STEP, between, check_fields, count
from ..kinematics.ik import IKOptions

__all__ = ["WrapMethod", "WrapParams"]


class WrapMethod(StrEnum):
    """How enclosing finds a section's first contact (WrapParams.method; members equal the
    configuration's strings): every step queried (the paper's loop), or steps a distance
    bound proves contact-free skipped."""

    FAST = "fast"
    REFERENCE = "reference"


@dataclass(frozen=True)
class WrapParams:
    """Algorithm 1's parameters, the paper's values in SI units.

    Args:
        theta_deg: stop when the tip's z axis has turned this much, deg (paper: 270;
            radians: the property theta).
        d_kappa: curvature step, 1/m (paper: 1e-3 1/cm).
        d_s: length step, m (paper: 1e-4 cm).
        delta: advancing distance, m (paper: 0.1 cm).
        delta_max_factor, delta_turn_deg: the adaptive advancing step (`advancing_step`),
            as an ODE solver lengthens its step where the solution changes slowly: a round
            advances by delta times the tip's turn left to theta over delta_turn_deg, from
            delta up to delta_max_factor * delta, so the arm slides in longer steps while
            its tip is far from theta and in steps of delta within delta_turn_deg of it.
            delta_max_factor = 1 is the paper's fixed step.
        max_step_motion: cap on a centre-line point's motion in one enclosing step, m.
        start_clearance: gap between the straight arm's surface and the object at the
            start, m.
        start_lengths: initial section lengths beyond the first, m; the first section ends
            where the start ray passes the object (clipped to the limits).
        start_fit: size sections 2.. from the cut instead, together theta * R long, R the
            radius of a circle as long as the cut's convex hull plus the tube's radius: the
            length that goes theta round it. Fixed 12 cm sections are too long for a cup
            (the tip overshoots theta in free air) and too short for a bowl.
        use_binormal: advance along n + t + b as the paper; False advances along n + t.
        max_iterations: cap on enclosing/advancing rounds.
        stall_rounds, stall_turn_deg: end the wrap (status MAX_STEPS) when the tip has not
            turned further than before by stall_turn_deg in the last stall_rounds rounds:
            the arm slides without wrapping (measured: 6 of 66 wraps of ten objects ran all
            400 rounds, 5-20 s each, turning less than 20 deg or backwards). Default 20
            rounds (measured: BENCHMARKS.md, Decisions).
            A stalled wrap reports the enclosing configuration at which its tip had turned
            furthest, with that enclosing's contacts, not the one sliding left it in: a
            wrap whose first enclosing stopped just short of theta then gave the same shape
            as one just past it, and a 1 mm nudge does not flip the prediction.
            The rounds are counted in steps of delta (an adaptive step of 3 delta counts
            3), so a stall is the same slide whatever the step.
        press_depth: how far a section may press into the object along the contact it
            rests on before that contact stops it curving, m (`_touch`; the IK's default
            penetration tolerance, so the configurations it leaves are ones IK accepts).
        table: the table top the object stands on (z = 0) is an obstacle: a section that
            touches it stops curving and IK keeps the arm above it; its touches are not the
            object's, so they are neither advanced along nor stored. Without it 9 of 40
            wraps of a fitting benchmark passed below the table, where no camera sees them.
        sample_spacing: spacing of the centre-line samples stored for chords, m.
        method: a WrapMethod, "fast" or "reference" enclosing.
        ik: IK settings.
    """

    theta_deg: float = 270.0
    d_kappa: float = 0.1
    d_s: float = 1e-6
    delta: float = 1e-3
    delta_max_factor: float = 1.0
    delta_turn_deg: float = 10.0
    max_step_motion: float = 1e-3
    start_clearance: float = 0.001
    start_lengths: tuple = (0.12, 0.12)
    start_fit: bool = True
    use_binormal: bool = False
    max_iterations: int = 400
    stall_rounds: int = 20
    stall_turn_deg: float = 5.0
    press_depth: float = 1e-3
    table: bool = False
    sample_spacing: float = 0.005
    method: WrapMethod = WrapMethod.FAST
    ik: IKOptions = IKOptions(one_sided=True)

    def __post_init__(self):
        check_fields(self, theta_deg=between(0, 720, " deg"), d_kappa=between(0, 10, " 1/m"),
                     d_s=STEP, delta=STEP, delta_max_factor=between(1, 100, open_low=False),
                     delta_turn_deg=between(0, 360, " deg"), max_step_motion=STEP,
                     start_clearance=GAP,
                     start_lengths=between(0, 1, " m"), max_iterations=count(100_000),
                     stall_rounds=count(100_000),
                     stall_turn_deg=between(0, 360, " deg", open_low=False),
                     press_depth=GAP, sample_spacing=STEP)

    def advancing_step(self, turn_left: float) -> float:
        """The advancing distance of a round whose tip has `turn_left` rad to turn to theta,
        m: delta * turn_left / delta_turn, clipped to [delta, delta_max_factor * delta]."""
        grown = min(turn_left / np.radians(self.delta_turn_deg), self.delta_max_factor)
        return self.delta * max(1.0, float(grown))

    # The angles are kept as the configuration gives them, in degrees (one field, one
    # key, one value recorded); the algorithm reads radians from these properties.
    @property
    def theta(self) -> float:
        """theta_deg in radians."""
        return np.radians(self.theta_deg)

    @property
    def stall_turn(self) -> float:
        """stall_turn_deg in radians."""
        return np.radians(self.stall_turn_deg)
