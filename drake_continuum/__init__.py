"""drake-continuum: object classification and recognition by continuum-arm wraps, on Drake.

The public API, imported on first use so that `import drake_continuum` (and the command
line) stays fast:

    from drake_continuum import MODELS_DIR, WrapScene, enumerate_planes, load_arm, wrap

    arm = load_arm()
    scene = WrapScene(arm, MODELS_DIR / "mug.obj")
    result = wrap(scene, enumerate_planes(arm.base_position)[0])

A few functions share their module's name (`wrap`, `classify`, `collect`, `reproduce`): here
the name is the function; the module is `from drake_continuum.wrap import ...` or
`importlib.import_module("drake_continuum.wrap")`.
"""

import importlib
import sys
import types

__version__ = "0.1.0"

# Public name -> the module (relative to the package) that defines it.
_API = {
    # errors
    "DrakeContinuumError": "errors", "ConfigError": "errors", "InputError": "errors",
    "MissingFileError": "errors",
    # configuration
    "Config": "config", "load_config": "config",
    # the arm
    "MODELS_DIR": "arm", "ArmConfig": "arm", "ContinuumArm": "arm", "load_arm": "arm",
    "ArmLimitError": "arm", "IKOptions": "ik",
    # wrapping
    "WrapScene": "scene", "SceneOptions": "scene", "Contacts": "contact",
    "WrapPlane": "planes", "enumerate_planes": "planes", "make_plane": "planes",
    "WrapParams": "wrap", "wrap": "wrap", "WrapResult": "wrap_types",
    # objects
    "load_mesh": "objects.mesh", "generate_dataset": "objects.dataset",
    "load_manifest": "objects.dataset",
    # collections, features, classification
    "collect": "collect", "CollectReport": "collect",
    "ChordParams": "chords", "wrap_chords": "chords", "object_chords": "chords",
    "ClassifierParams": "classify", "ChordModel": "classify", "Classification": "classify",
    "load_wraps": "classify", "train": "classify", "classify": "classify",
    "evaluate": "classify", "save_model": "classify", "load_model": "classify",
    # active recognition
    "ActiveParams": "active", "ActiveModel": "active", "Recognition": "active",
    "train_active": "active", "recognize": "active", "simulated_execute": "active",
    "evaluate_active": "active", "save_active_model": "active", "load_active_model": "active",
    # point clouds
    "load_cloud": "pointcloud", "fit_cloud": "pointcloud", "ArmFit": "pointcloud",
    "compare_real": "pointcloud", "render_cloud": "depth_camera",
    # the reproduction
    "reproduce": "reproduce", "RunSettings": "reproduce",
}

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


class _Package(types.ModuleType):
    """Importing a submodule binds it as an attribute of the package; where the submodule
    shares its name with a public function (wrap.wrap), the function keeps the name."""

    def __setattr__(self, name, value):
        if (_API.get(name) == name and isinstance(value, types.ModuleType)
                and value.__name__ == f"{__name__}.{name}"):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
