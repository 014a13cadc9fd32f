"""The linear program of one step of IK's sequential convex programming (`ik._sqp`):
minimise the summed |end-point error| of the linearised kinematics plus a penetration
slack's price, within the trust region, the linearised gaps and the linearised limits.
Clarabel solves it (OSQP when Clarabel fails)."""

from __future__ import annotations

from functools import cache

import numpy as np
from pydrake.solvers import ClarabelSolver, MathematicalProgram, OsqpSolver

__all__ = ["W_GAP", "StepProgram", "step_program"]

_CLARABEL, _OSQP = ClarabelSolver(), OsqpSolver()
W_GAP = 100.0  # merit of a mm of penetration beyond the tolerance, in mm of summed error


class StepProgram:
    """The SQP step's linear program in z (the step), e (bounds on |r + J z|) and t (the
    penetration slack); each step sets its coefficients (~40 us; building it anew took
    ~100)."""

    def __init__(self, d: int):
        self.prog = prog = MathematicalProgram()
        self.d = d
        self.z, t = prog.NewContinuousVariables(d, "z"), prog.NewContinuousVariables(1, "t")
        e = prog.NewContinuousVariables(d, "e")
        prog.AddLinearCost(np.ones(d), 0.0, e)
        prog.AddLinearCost([W_GAP], 0.0, t)
        prog.AddBoundingBoxConstraint(0.0, np.inf, t)
        self.box = prog.AddBoundingBoxConstraint(-np.ones(d), np.ones(d), self.z).evaluator()
        self.errors = prog.AddLinearConstraint(np.zeros((2 * d, 2 * d)), np.zeros(2 * d),
                                               np.zeros(2 * d),
                                               np.concatenate([self.z, e])).evaluator()
        self.gaps = prog.AddLinearConstraint(np.zeros((1, d + 1)), [-np.inf], [np.inf],
                                             np.concatenate([self.z, t])).evaluator()
        self.limits = prog.AddLinearConstraint(np.zeros((1, d)), [-np.inf], [np.inf],
                                               self.z).evaluator()

    def solve(self, J, r, *, lower, upper, G, gap_lower, L, limit_upper):
        """Minimise sum |r + J z| + w t subject to lower <= z <= upper, G z + t >= gap_lower,
        L z <= limit_upper, t >= 0: (z, model merit), or (None, message)."""
        d, eye = self.d, np.eye(self.d)
        # -e <= r + J z <= e
        self.errors.UpdateCoefficients(np.block([[J, -eye], [J, eye]]),
                                       np.concatenate([np.full(d, -np.inf), -r]),
                                       np.concatenate([-r, np.full(d, np.inf)]))
        self.box.set_bounds(lower, upper)
        if len(G):
            self.gaps.UpdateCoefficients(np.hstack([G, np.ones((len(G), 1))]), gap_lower,
                                         np.full(len(G), np.inf))
        else:  # a row that binds nothing: the constraint keeps its place in the program
            self.gaps.UpdateCoefficients(np.zeros((1, d + 1)), [-np.inf], [np.inf])
        if len(L):
            self.limits.UpdateCoefficients(L, np.full(len(L), -np.inf), limit_upper)
        else:
            self.limits.UpdateCoefficients(np.zeros((1, d)), [-np.inf], [np.inf])
        result = _CLARABEL.Solve(self.prog)
        if not result.is_success():
            result = _OSQP.Solve(self.prog)
        if not result.is_success():
            return None, (f"No IK found: the step program reports "
                          f"{result.get_solution_result().name}")
        x = result.get_x_val()
        return x[:d], np.abs(r + J @ x[:d]).sum() + W_GAP * x[d]


@cache
def step_program(d: int) -> StepProgram:
    """The step program of d decision variables, built once a process (~0.2 ms): every step
    sets each of its coefficients and bounds, so a program used before solves as a new one
    would (the wraps are the same to the bit)."""
    return StepProgram(d)
