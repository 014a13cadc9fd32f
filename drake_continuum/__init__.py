"""drake-continuum: object classification and recognition by continuum-arm wraps, on Drake.

The public API, imported on first use so that `import drake_continuum` (and the command
line) stays fast:

    from drake_continuum import MODELS_DIR, WrapScene, enumerate_planes, load_arm, wrap

    arm = load_arm()
    scene = WrapScene(arm, MODELS_DIR / "mug.obj")
    result = wrap(scene, enumerate_planes(arm.base_position)[0])

The modules live in subpackages along the data flow: `kinematics` (the arm, IK), `wrapping`
(scene, contacts, planes, Algorithm 1), `features` (chords, triangles), `learning` (the
classifier), `active` (recognition by tree search), `perception` (point clouds, the depth
camera), `objects`, `experiments` (collect, reproduce, report), `viz` and `cli`.
"""

import importlib

__version__ = "0.5.0"

# The public names, by the module (relative to the package) that defines them.
_MODULES = {
    "errors": ("DrakeContinuumError", "ConfigError", "InputError", "MissingFileError"),
    "config": ("Config", "load_config"),
    "kinematics.arm": ("MODELS_DIR", "ArmConfig", "ContinuumArm", "load_arm", "ArmLimitError"),
    "kinematics.ik": ("IKOptions",),
    "wrapping.scene": ("WrapScene", "SceneOptions"),
    "wrapping.contact": ("Contacts",),
    "wrapping.planes": ("WrapPlane", "enumerate_planes", "make_plane"),
    "wrapping.wrap": ("WrapParams", "wrap"),
    "wrapping.wrap_types": ("WrapResult",),
    "objects.mesh": ("load_mesh",),
    "objects.dataset": ("generate_dataset", "load_manifest"),
    "experiments.collect": ("collect", "CollectReport"),
    "features.chords": ("ChordParams", "wrap_chords", "object_chords"),
    "learning.pipeline": ("ClassifierParams",),
    "learning.model": (
        "ChordModel", "Classification", "train", "classify", "save_model", "load_model",
    ),
    "learning.records": ("load_wraps",),
    "learning.evaluation": ("evaluate",),
    "active.params": ("ActiveParams",),
    "active.observation": ("ActiveModel",),
    "active.policies": ("Recognition", "recognize", "simulated_execute"),
    "active.training": (
        "train_active", "evaluate_active", "save_active_model", "load_active_model",
    ),
    "perception.cloud": ("load_cloud", "SAMPLE_CLOUDS"),
    "perception.fitting": ("fit_cloud", "ArmFit"),
    "perception.comparison": ("compare_real",),
    "perception.depth_camera": ("render_cloud",),
    "perception.locate": ("camera_view",),
    "experiments.reproduce": ("reproduce", "RunSettings"),
}
# Public name -> its module.
_API = {name: module for module, names in _MODULES.items() for name in names}

__all__ = ["__version__", *_API]


def __getattr__(name):
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_API))

