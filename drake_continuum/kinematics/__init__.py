"""The arm: constant-curvature sections, forward kinematics (arm) and constrained IK (ik)."""
