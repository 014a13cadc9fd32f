"""The arm: constant-curvature sections, forward kinematics (arm) and constrained IK (ik)."""

from ..exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "arm": ("MODELS_DIR", "ArmConfig", "ArmLimitError", "BackboneSamples", "ContinuumArm",
            "load_arm"),
    "ik": ("IKMode", "IKOptions", "IKResult", "solve_ik"),
})
