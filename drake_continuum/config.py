"""One experiment configuration: every parameter of the arm, planes, wrap, chords, classifier
and active recognition, read from models/config.yaml (or another file) with command-line
overrides `section.key=value`.

Loading is generic over the parameter dataclasses' fields, so a field added to WrapParams (or
any section's class) is read, type-checked and recorded without a change here: a value must
have its field's type (a float field takes a finite number, an int field a whole number, a
bool field true/false, ...), a key `<field>_deg` gives a radian field in degrees, unknown keys
are refused, and RULES adds the ranges (delta > 0, ...). Errors are ConfigErrors naming the
file and the key.

`config_to_tree` is the inverse: the whole configuration as the YAML's tree, with the arm's
description inlined, so that a collection, a model or a reproduction records every setting it
was made with and a later run can compare or rebuild them (`config_from_tree`).
"""

from __future__ import annotations

import copy
import dataclasses
import math
import re
import typing
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import yaml

from .active.params import ActiveParams
from .errors import ConfigError
from .features.chords import FRAMES, ChordParams
from .files import read_yaml
from .kinematics.arm import MODELS_DIR, ContinuumArm
from .learning.pipeline import ClassifierParams
from .wrapping.planes import PAPER_ALPHA_DEG, enumerate_planes
from .wrapping.wrap import WrapParams

__all__ = ["Config", "PlaneParams", "DEFAULT_CONFIG", "RULES", "arm_file", "load_config",
           "config_from_tree", "config_to_tree", "tree_difference", "parse_override",
           "apply_overrides",
           "collection_tree", "training_settings", "model_config"]

DEFAULT_CONFIG = MODELS_DIR / "config.yaml"
SECTIONS = ("arm", "planes", "wrap", "chords", "classifier", "active")


@dataclass(frozen=True)
class PlaneParams:
    """The wrap planes (Fig. 4).

    Args:
        alpha_deg: rotation step about x and about y, deg (paper: 22.5, 10 planes).
        both_directions: wrap every plane clockwise and counter-clockwise (twice the planes).
        bearing: "object" (the plane set turned about the object onto its horizontal axis as
            the depth camera sees it: perception.bearing) or "world" (fixed to the robot,
            the paper's). models/config.yaml's default is "object" (measured:
            BENCHMARKS.md, Placements); the library's collect() and run_params() keep
            "world" unless given.
        centre: where the plane set is centred when collecting: "camera" (the depth
            camera's position estimate, as classify and recognize centre it:
            locate.points_estimate) or "mark" (x = y = 0, where a dataset's objects are set
            down). models/config.yaml's default is "camera"; collect() and run_params() keep
            "mark" unless given.
    """

    alpha_deg: float = PAPER_ALPHA_DEG
    both_directions: bool = False
    bearing: str = "object"
    centre: str = "camera"


@dataclass(frozen=True)
class Config:
    """A whole experiment's parameters.

    Args:
        arm_yaml: the arm's description, the text of its YAML (a collection records it
            verbatim, so a rerun compares it with the text it was made with).
        planes: the wrap planes.
        wrap: Algorithm 1's parameters.
        chords: the descriptor's parameters.
        classifier: the histogram, PCA and SVM settings.
        active: active recognition's constants.
    """

    arm_yaml: str
    planes: PlaneParams
    wrap: WrapParams
    chords: ChordParams
    classifier: ClassifierParams
    active: ActiveParams

    @property
    def alpha_deg(self) -> float:
        return self.planes.alpha_deg

    @property
    def both_directions(self) -> bool:
        return self.planes.both_directions

    @property
    def bearing(self) -> str:
        return self.planes.bearing

    @property
    def centre(self) -> str:
        return self.planes.centre

    @property
    def arm_description(self) -> dict:
        return yaml.safe_load(self.arm_yaml)

    def arm(self) -> ContinuumArm:
        return ContinuumArm.from_dict(self.arm_description, "arm description")


# Ranges beyond the type, by dotted key: (test, what it requires). A key not listed is only
# type-checked (and, for numbers, required finite). Upper bounds keep a value to what the
# arm and a tabletop object can use: a step, gap or tolerance in metres at most STEP_MAX (a
# third of the largest object); a count at most what memory or the 64-bit cell index holds.
STEP_MAX = 0.1  # m


def _non_negative(v):
    return v >= 0


def _between(lo, hi, unit: str = "", open_low: bool = True):
    """(test, text) of lo < v <= hi (lo <= v <= hi when not open_low)."""
    test = (lambda v: lo < v <= hi) if open_low else (lambda v: lo <= v <= hi)
    return test, f"in {'(' if open_low else '['}{lo:g}, {hi:g}]{unit}"


def _count(hi: int, lo: int = 1):
    """(test, text) of a whole number from lo to hi."""
    return (lambda v: lo <= v <= hi), f"from {lo} to {hi:,}"


def _one_of(*choices):
    return (lambda v: v in choices), f"one of {', '.join(map(repr, choices))}"


_STEP = _between(0, STEP_MAX, " m")
_GAP = _between(0, STEP_MAX, " m", open_low=False)

RULES = {
    "planes.alpha_deg": _between(0, 90, " deg"),
    "planes.bearing": _one_of("world", "object"),
    "planes.centre": _one_of("mark", "camera"),
    "wrap.theta_deg": _between(0, 720, " deg"),
    "wrap.theta": _between(0, 4 * math.pi, " rad"),
    "wrap.d_kappa": _between(0, 10, " 1/m"),
    "wrap.d_s": _STEP,
    "wrap.delta": _STEP,
    "wrap.max_step_motion": _STEP,
    "wrap.start_clearance": _GAP,
    "wrap.start_lengths": (lambda v: all(0 < x <= 1 for x in v), "lengths in (0, 1] m"),
    "wrap.max_iterations": _count(100_000),
    "wrap.sample_spacing": _STEP,
    "wrap.method": _one_of("fast", "reference"),
    "wrap.stall_rounds": _count(100_000),
    "wrap.stall_turn_deg": _between(0, 360, " deg", open_low=False),
    "wrap.stall_turn": _between(0, 2 * math.pi, " rad", open_low=False),
    "wrap.press_depth": _GAP,
    "wrap.ik.mode": _one_of("exact", "least_squares", "auto"),
    "wrap.ik.tolerance": _STEP,
    "wrap.ik.penetration_tolerance": _GAP,
    "wrap.ik.n_collision_points": _count(1000),
    "chords.spacing": _STEP,
    "chords.min_length": _between(0, 1, " m", open_low=False),
    "chords.frame": _one_of(*FRAMES),
    "classifier.bins": _count(100),
    "classifier.edges": _one_of("quantile", "uniform"),
    "classifier.power": _between(0, 1),
    "classifier.variance": _between(0, 1),
    "classifier.svm_c": _between(0, 1e6),
    "classifier.coarse": _count(100, lo=0),
    "classifier.wrap_weight": _between(0, 1e3, open_low=False),
    "classifier.extent_weight": _between(0, 1e3, open_low=False),
    "classifier.view_weight": _between(0, 1e3, open_low=False),
    "active.exploration": _between(0, 1e3, open_low=False),
    "active.horizon": _count(100),
    "active.cost_weight": _between(0, 1, open_low=False),
    "active.discount": _between(0, 1),
    "active.n_simulations": _count(1_000_000),
    "active.max_iterations": _count(1000),
    "active.neighbours": _count(1000),
    "active.strong_probability": _between(0, 1, open_low=False),
    "active.strong_ratio": (lambda v: v >= 1, ">= 1"),
    "active.start_plane": (_non_negative, ">= 0 (and below the number of planes)"),
    "active.seed": (_non_negative, ">= 0"),
}


_NUMBER = re.compile(r"[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?")


def _value(kind, value, key: str):
    """`value` as the field type `kind`, or a ConfigError naming `key`."""
    def bad(expected):
        return ConfigError(f"{key}: expected {expected}, got {value!r}")

    origin = typing.get_origin(kind)
    if kind is bool:
        if not isinstance(value, bool):
            raise bad("true or false")
        return value
    if kind is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise bad("a whole number")
        return value
    if kind is float:
        if isinstance(value, str) and _NUMBER.fullmatch(value.strip()):
            value = float(value)  # YAML 1.1 reads 1e-3 (no dot) as text; YAML 1.2 as a number
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise bad("a number")
        if not math.isfinite(value):
            raise bad("a finite number")
        return float(value)
    if kind is str:
        if not isinstance(value, str):
            raise bad("a string")
        return value
    if kind is tuple or origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise bad("a list of numbers")
        return tuple(_value(float, v, f"{key}[{i}]") for i, v in enumerate(value))
    return value  # a type this loader does not know: passed on as written


def _build(cls, values, key: str):
    """An instance of the dataclass `cls` from a mapping; nested dataclass fields from
    nested mappings; `<name>_deg` keys fill radian fields `name`."""
    if not isinstance(values, dict):
        raise ConfigError(f"{key}: expected a mapping of settings, got {values!r}")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in fields(cls)}
    kwargs = {}
    for k, v in values.items():
        name, degrees = k, False
        if k not in names and k.endswith("_deg") and k[:-4] in names:
            name, degrees = k[:-4], True
        if name not in names:
            raise ConfigError(f"{key}.{k}: unknown key (known: {', '.join(sorted(names))})")
        kind = hints[name]
        if dataclasses.is_dataclass(kind):
            kwargs[name] = _build(kind, v, f"{key}.{k}")
            continue
        value = _value(kind, v, f"{key}.{k}")
        rule = RULES.get(f"{key}.{k}") or RULES.get(f"{key}.{name}")
        if rule is not None and not rule[0](value):
            raise ConfigError(f"{key}.{k}: must be {rule[1]}, got {v!r}")
        kwargs[name] = float(np.radians(value)) if degrees else value
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as e:  # the class's own checks
        raise ConfigError(f"{key}: {e}") from None


# WrapParams' radian fields that the YAML gives in degrees (as `<name>_deg`).
DEGREE_FIELDS = ("theta", "stall_turn")


def _tree(obj) -> dict:
    """A parameter dataclass as the YAML's mapping (radian fields that the YAML gives in
    degrees written back in degrees)."""
    out = {}
    for f in fields(obj):
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v):
            out[f.name] = _tree(v)
        elif isinstance(v, tuple):
            out[f.name] = [float(x) for x in v]
        else:
            out[f.name] = v
    if isinstance(obj, WrapParams):
        out = {(f"{k}_deg" if k in DEGREE_FIELDS else k):
               (float(np.degrees(v)) if k in DEGREE_FIELDS else v) for k, v in out.items()}
    return out


def config_to_tree(config: Config) -> dict:
    """The whole configuration as a YAML/JSON tree, the arm inlined; config_from_tree(tree)
    gives it back."""
    return {"arm": config.arm_description,
            "planes": _tree(config.planes), "wrap": _tree(config.wrap),
            "chords": _tree(config.chords), "classifier": _tree(config.classifier),
            "active": _tree(config.active)}


def arm_file(name: str, base_dir: Path | None = None) -> Path:
    """The arm description a configuration names: an absolute path as given; a relative one
    in `base_dir` (the configuration file's folder; the working folder for `--set arm=...`),
    else among the shipped arms (models/arm.yaml, arm_5sections.yaml). ConfigError lists
    the paths tried."""
    path = Path(name).expanduser()
    tried = [path] if path.is_absolute() else \
        list(dict.fromkeys(d / path for d in (base_dir, MODELS_DIR) if d is not None))
    for candidate in tried:
        if candidate.is_file():
            return candidate
    raise ConfigError(f"arm: {name!r} not found (tried {', '.join(map(str, tried))})")


def config_from_tree(tree, where: str = "configuration", base_dir: Path | None = None
                     ) -> Config:
    """A Config from the YAML's tree; `arm` is a path (arm_file, relative to base_dir) or
    the arm's description itself."""
    if not isinstance(tree, dict) or set(tree) != set(SECTIONS):
        got = sorted(tree) if isinstance(tree, dict) else type(tree).__name__
        raise ConfigError(f"{where}: needs exactly the sections {sorted(SECTIONS)}, got {got}")
    arm = tree["arm"]
    if isinstance(arm, str):
        path = arm_file(arm, base_dir)
        read_yaml(path, "arm description")  # a malformed file named
        arm_yaml, arm_where = path.read_text(), f"arm description {path}"
    else:
        arm_yaml, arm_where = yaml.safe_dump(arm, sort_keys=False), f"{where}: arm"
    arm_model = ContinuumArm.from_dict(yaml.safe_load(arm_yaml), arm_where)  # now, not at a wrap
    config = Config(arm_yaml=arm_yaml,
                    planes=_build(PlaneParams, tree["planes"], "planes"),
                    wrap=_build(WrapParams, tree["wrap"], "wrap"),
                    chords=_build(ChordParams, tree["chords"], "chords"),
                    classifier=_build(ClassifierParams, tree["classifier"], "classifier"),
                    active=_build(ActiveParams, tree["active"], "active"))
    n_planes = len(enumerate_planes(arm_model.base_position, config.alpha_deg,
                                    config.both_directions))
    if config.active.start_plane >= n_planes:
        raise ConfigError(f"active.start_plane: must be below the number of planes "
                          f"({n_planes} for planes.alpha_deg = {config.alpha_deg:g}), got "
                          f"{config.active.start_plane}")
    if config.classifier.coarse > config.classifier.bins:
        raise ConfigError(f"classifier.coarse: must be at most classifier.bins "
                          f"({config.classifier.bins}), got {config.classifier.coarse}")
    return config


def parse_override(assignment: str) -> tuple[str, object]:
    """("section.key", value) of a "section.key=value" override, the value parsed as YAML."""
    if "=" not in assignment:
        raise ConfigError(f"--set {assignment!r}: expected section.key=value")
    key, value = assignment.split("=", 1)
    try:
        return key.strip(), yaml.safe_load(value)
    except yaml.YAMLError as e:
        raise ConfigError(f"--set {assignment!r}: not a YAML value ({e})") from None


def apply_overrides(tree: dict, overrides=()) -> dict:
    """A copy of `tree` with each "section.key=value" (a YAML value) set; the key must exist."""
    tree = copy.deepcopy(tree)
    for assignment in overrides:
        key, value = parse_override(assignment)
        parts = key.split(".")
        node = tree
        for p in parts[:-1]:
            if not isinstance(node.get(p), dict):
                raise ConfigError(f"--set {assignment!r}: no section {p!r} in the configuration")
            node = node[p]
        if parts[-1] not in node:
            raise ConfigError(f"--set {assignment!r}: no key {parts[-1]!r} in section "
                              f"{'.'.join(parts[:-1]) or 'top level'}")
        node[parts[-1]] = value
    return tree


def read_config_tree(path=None) -> tuple[dict, Path]:
    """The YAML tree of a configuration file (default models/config.yaml) and its path."""
    path = Path(path) if path is not None else DEFAULT_CONFIG
    return read_yaml(path, "configuration"), path


def load_config(path=None, overrides=(), base: dict | None = None) -> Config:
    """Read a configuration file (default models/config.yaml), or start from the recorded
    tree `base` when no file is given, and apply `overrides`, each "section.key=value" with
    a YAML value. Raises ConfigError naming the file and the key. An arm file is looked for
    beside the configuration file, or, given as an override (`arm=PATH`), from the working
    folder (arm_file)."""
    if base is not None and path is None:
        tree, where, base_dir = base, "recorded settings", None
    else:
        tree, path = read_config_tree(path)
        where, base_dir = f"configuration {path}", path.parent
    if any(o.split("=", 1)[0].strip() == "arm" for o in overrides):
        base_dir = Path.cwd()
    try:
        return config_from_tree(apply_overrides(tree or {}, overrides), where, base_dir)
    except ConfigError as e:
        if str(e).startswith(where) or str(e).startswith("--set"):
            raise
        raise ConfigError(f"{where}: {e}") from None


def tree_difference(old: dict, new: dict, prefix: str = "") -> list[str]:
    """The dotted keys whose values differ between two trees, each as
    "key (old -> new)"; a whole missing subtree is one entry."""
    out = []
    for k in sorted(set(old) | set(new), key=str):
        a, b = old.get(k), new.get(k)
        name = f"{prefix}{k}"
        if isinstance(a, dict) and isinstance(b, dict):
            out += tree_difference(a, b, f"{name}.")
        elif a != b:
            out.append(f"{name} ({'not recorded' if k not in old else _short(a)} -> "
                       f"{'not given' if k not in new else _short(b)})")
    return out


def _short(value) -> str:
    return "{...}" if isinstance(value, dict) else repr(value)


# ------------------------------------------------------------------ settings a model records

def collection_tree(params: dict) -> dict:
    """The arm, planes and wrap sections of a wrap collection's recorded parameters
    (collect.run_params, in its index.json), as a configuration tree's sections."""
    wrap = copy.deepcopy(params["wrap_params"])
    for name in DEGREE_FIELDS:
        if name in wrap:  # stall_turn: not recorded by collections made before it existed
            wrap[f"{name}_deg"] = float(np.degrees(wrap.pop(name)))
    return {"arm": yaml.safe_load(params["arm_yaml"]), "wrap": wrap,
            "planes": {"alpha_deg": params["alpha_deg"],
                       "both_directions": bool(params.get("both_directions", False)),
                       "bearing": params.get("bearing", "world"),
                       "centre": params.get("centre", "mark")}}


def training_settings(config: Config, wraps_dir) -> dict:
    """What a trained model records of how it was made: the training configuration, its
    arm, planes and wrap sections those the collection at `wraps_dir` was made with (its
    index.json), so that classify and recognize wrap a new object as the training objects
    were."""
    from .experiments.collect import INDEX_NAME, _read_json

    tree = config_to_tree(config)
    index = _read_json(Path(wraps_dir) / INDEX_NAME)
    params = index.get("params") if isinstance(index, dict) else None
    if not isinstance(params, dict) or "wrap_params" not in params:
        raise ConfigError(f"{Path(wraps_dir) / INDEX_NAME}: records no collection parameters "
                          f"(not a collection made by drake-continuum collect?)")
    tree.update(collection_tree(params))
    return {"config": tree, "collection": str(wraps_dir)}


def model_config(info: dict, path=None, overrides=()) -> tuple[Config, list[str]]:
    """The configuration to wrap and recognise with for a model: the settings it records
    (training_settings), or the file `path` when given, then `overrides`. Also returns
    warnings: the arm, planes and wrap keys in which the result differs from the recorded
    ones (such wraps are not those the model was trained on), or that the model records no
    settings (made before models recorded them: the file's settings are used)."""
    recorded = (info or {}).get("settings", {}).get("config")
    if recorded is None:
        config = load_config(path, overrides)
        return config, [f"the model records no settings (trained before models recorded "
                        f"them); wrapping with {path or DEFAULT_CONFIG}"]
    config = load_config(path, overrides, base=recorded)
    now = config_to_tree(config)
    differ = [d for section in ("arm", "planes", "wrap")
              for d in tree_difference({section: recorded[section]}, {section: now[section]})]
    return config, [f"wraps differ from the training collection's in {d}" for d in differ]
