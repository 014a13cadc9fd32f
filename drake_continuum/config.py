"""One experiment's scenario: every parameter of the arm, planes, wrap, chords, classifier,
active recognition and the camera study, read from models/config.yaml (or another file) with
command-line overrides `section.key=value`.

The scenario (Config) is a frozen dataclass of the parameter dataclasses (PlaneParams,
WrapParams with its IKOptions, ChordParams, ClassifierParams, ActiveParams, ObservedParams),
each of which checks its own fields' types and ranges when it is made (checks.check_fields).
A file is read with pydrake's `yaml_load_typed` (unknown keys refused; a key left out keeps
the class's default, a section left out all its defaults) into a mutable twin of each class,
`_schema`, since Drake's loader sets fields one by one; the twin's values then make the
frozen class, whose checks run once. Errors are ConfigErrors naming the file and the key.
`config_to_tree` writes the scenario back with `yaml_dump_typed` as the YAML's tree, the
arm's description inlined, so that a collection, a model or a reproduction records every
setting it was made with and a later run can compare or rebuild them (`config_from_tree`).

Angles are fields in degrees, as the file gives them (`alpha_deg`, `theta_deg`,
`stall_turn_deg`): one name and one value from the file to the recorded tree; the code reads
radians from a property (WrapParams.theta).
"""

from __future__ import annotations

import copy
import dataclasses
import enum
import functools
import typing
from dataclasses import dataclass, fields
from pathlib import Path

import yaml
from pydrake.common.yaml import yaml_dump_typed, yaml_load, yaml_load_typed

from .active.params import ActiveParams
from .checks import FieldError, between, check_fields
from .errors import ConfigError
from .features.chords import ChordFrame, ChordParams
from .files import parse_yaml, read_yaml
from .kinematics.arm import DEFAULT_ARM_YAML, MODELS_DIR, ContinuumArm
from .learning.params import ClassifierParams
from .perception.bearing import PlaneBearing
from .wrapping.planes import PAPER_ALPHA_DEG, PlaneCentre, enumerate_planes
from .wrapping.wrap import WrapParams

__all__ = ["Config", "PlaneParams", "ObservedParams", "DEFAULT_CONFIG", "SECTIONS", "arm_file",
           "load_config", "config_from_tree", "config_to_tree", "tree_difference", "parse_override",
           "apply_overrides", "read_config_tree", "model_config"]

DEFAULT_CONFIG = MODELS_DIR / "config.yaml"
SECTIONS = ("arm", "planes", "wrap", "chords", "classifier", "active", "observed")


@dataclass(frozen=True)
class PlaneParams:
    """The wrap planes (Fig. 4).

    Args:
        alpha_deg: rotation step about x and about y, deg (paper: 22.5, 10 planes).
        both_directions: wrap every plane clockwise and counter-clockwise (twice the planes).
        bearing: a PlaneBearing: "object" (the plane set turned about the object onto its
            horizontal axis as the depth camera sees it: perception.bearing) or "world"
            (fixed to the robot, the paper's). Measured: BENCHMARKS.md, Placements.
        centre: a PlaneCentre: "camera" (the depth camera's position estimate, as classify
            and recognize centre it: locate.points_estimate) or "mark" (x = y = 0, where a
            dataset's objects are set down). Measured: BENCHMARKS.md, Placements.
    """

    alpha_deg: float = PAPER_ALPHA_DEG
    both_directions: bool = False
    bearing: PlaneBearing = PlaneBearing.OBJECT
    centre: PlaneCentre = PlaneCentre.CAMERA

    def __post_init__(self):
        check_fields(self, alpha_deg=between(0, 90, " deg"))


@dataclass(frozen=True)
class ObservedParams:
    """What the camera study (`reproduce`'s recognition from what the camera sees of the
    arm) changes in the chords and classifier sections for all its models, so that its four
    conditions are compared with one setting.

    Args:
        frame: the chord frame (chords.frame): "plane", because a fit determines the wrap's
            plane, not the bending direction of a section that runs nearly straight.
        tie_width: the quantile edges' tie width (classifier.tie_width), m or rad: a fitted
            arm tilts the horizontal chords of a wrap by a median of 1-2 mrad, which the
            simulator's 1 mrad would split over two bins. Measured: BENCHMARKS.md, Point
            clouds.
    """

    frame: ChordFrame = ChordFrame.PLANE
    tie_width: float = 0.003

    def __post_init__(self):
        check_fields(self, tie_width=between(0, 0.1, open_low=False))


@dataclass(frozen=True)
class Config:
    """A whole experiment's parameters: the scenario every command and library entry point
    (collect, train, recognize, reproduce, make_station) takes whole.

    Every default is models/config.yaml's (Config() == load_config(): one set of
    defaults), so `Config(classifier=...)` is the shipped scenario with one section changed.

    Args:
        arm_yaml: the arm's description, the text of its YAML (a collection records it
            verbatim, and a rerun compares the description it reads as); default
            models/arm.yaml's.
        planes: the wrap planes.
        wrap: Algorithm 1's parameters.
        chords: the descriptor's parameters.
        classifier: the histogram, PCA and SVM settings.
        active: active recognition's constants.
        observed: the camera study's chord frame and tie width.
    """

    arm_yaml: str = dataclasses.field(default_factory=lambda: DEFAULT_ARM_YAML.read_text())
    planes: PlaneParams = PlaneParams()
    wrap: WrapParams = WrapParams()
    chords: ChordParams = ChordParams()
    classifier: ClassifierParams = ClassifierParams()
    active: ActiveParams = ActiveParams()
    observed: ObservedParams = ObservedParams()

    @property
    def alpha_deg(self) -> float:
        return self.planes.alpha_deg

    @property
    def both_directions(self) -> bool:
        return self.planes.both_directions

    @property
    def bearing(self) -> PlaneBearing:
        return self.planes.bearing

    @property
    def centre(self) -> PlaneCentre:
        return self.planes.centre

    @property
    def arm_description(self) -> dict:
        return parse_yaml(self.arm_yaml)

    def arm(self) -> ContinuumArm:
        return ContinuumArm.from_dict(self.arm_description, "arm description")


# The sections yaml_load_typed reads (the arm is a path or an inline description: read apart).
_SECTION_CLASSES = {"planes": PlaneParams, "wrap": WrapParams, "chords": ChordParams,
                    "classifier": ClassifierParams, "active": ActiveParams,
                    "observed": ObservedParams}


@dataclass
class _Sections:
    planes: PlaneParams = PlaneParams()
    wrap: WrapParams = WrapParams()
    chords: ChordParams = ChordParams()
    classifier: ClassifierParams = ClassifierParams()
    active: ActiveParams = ActiveParams()
    observed: ObservedParams = ObservedParams()


def _field_schema(kind):
    """The type yaml_load_typed reads a field of type `kind` as."""
    if isinstance(kind, type) and issubclass(kind, enum.Enum):
        return str
    if kind is tuple or typing.get_origin(kind) is tuple:
        return list[float]
    if dataclasses.is_dataclass(kind):
        return _schema(kind)
    return kind


@functools.cache
def _schema(cls) -> type:
    """A mutable dataclass with the fields, types and defaults of the dataclass `cls`, as
    yaml_load_typed reads and yaml_dump_typed writes it (an Enum as its value, a tuple as a
    list)."""
    hints = typing.get_type_hints(cls)
    default = cls()
    specs = []
    for f in fields(cls):
        value = _loadable(getattr(default, f.name))
        specs.append((f.name, _field_schema(hints[f.name]),
                      dataclasses.field(default_factory=functools.partial(copy.deepcopy,
                                                                          value))))
    return dataclasses.make_dataclass(f"{cls.__name__}Schema", specs)


def _loadable(value):
    """A parameter value as its schema holds it."""
    if dataclasses.is_dataclass(value):
        return _schema(type(value))(**{f.name: _loadable(getattr(value, f.name))
                                       for f in fields(value)})
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, tuple):
        return list(value)
    return value


def _frozen(cls, loaded, key: str):
    """The dataclass `cls` from its schema's instance `loaded`, nested classes first; a
    FieldError of a class's checks becomes a ConfigError naming the dotted key."""
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for f in fields(cls):
        value = getattr(loaded, f.name)
        if dataclasses.is_dataclass(hints[f.name]):
            value = _frozen(hints[f.name], value, f"{key}.{f.name}")
        kwargs[f.name] = value
    try:
        return cls(**kwargs)
    except FieldError as e:
        raise ConfigError(f"{key}.{e.name}: {e.reason}") from None


def _leaves(tree: dict, prefix: tuple = ()):
    """(path, value) of every leaf of a nested mapping."""
    for k, v in tree.items():
        if isinstance(v, dict):
            yield from _leaves(v, prefix + (k,))
        else:
            yield prefix + (k,), v


_EXPECTED = {float: "a number", int: "a whole number", bool: "true or false", str: "a string"}


def _dump(tree) -> str:
    """yaml.safe_dump's text, emitted by libyaml where PyYAML has it (for yaml_load_typed)."""
    return yaml.dump(tree, Dumper=getattr(yaml, "CSafeDumper", yaml.SafeDumper))


def _typed_sections(tree: dict) -> _Sections:
    """The sections of a configuration tree read by yaml_load_typed; a value it refuses is
    a ConfigError naming its dotted key (found by reading each key alone)."""
    def load(part):
        return yaml_load_typed(schema=_schema(_Sections), data=_dump(part),
                               defaults=_loadable(_Sections()))

    sections = {k: tree[k] for k in _SECTION_CLASSES if tree.get(k) is not None}
    for name, value in sections.items():
        if not isinstance(value, dict):
            raise ConfigError(f"{name}: expected a mapping of settings, got {value!r}")
    try:
        return load(sections)
    except (RuntimeError, ValueError, TypeError, AssertionError):
        pass
    for path, value in _leaves(sections):
        part = value
        for k in reversed(path):
            part = {k: part}
        try:
            load(part)
        except (RuntimeError, ValueError, TypeError, AssertionError) as e:
            raise ConfigError(_refusal(path, value, e)) from None
    raise ConfigError("the settings do not read as a configuration")  # not reached


def _refusal(path: tuple, value, error: Exception) -> str:
    """What is wrong with the one setting `path` = `value` that yaml_load_typed refused."""
    key, cls = ".".join(map(str, path)), _Sections
    for name in path[:-1]:
        cls = _field_type(cls, name)
    kind = _field_type(cls, path[-1])
    if kind is None:
        known = ", ".join(f.name for f in fields(cls)) if dataclasses.is_dataclass(cls) else ""
        return f"{key}: unknown key (known: {known})"
    if dataclasses.is_dataclass(kind):
        return f"{key}: expected a mapping of settings, got {value!r}"
    expected = _EXPECTED.get(_field_schema(kind), f"a {_field_schema(kind)}")
    if _field_schema(kind) == list[float]:
        expected = "a list of numbers"
    return f"{key}: expected {expected}, got {value!r} ({error})"


def config_to_tree(config: Config) -> dict:
    """The whole configuration as a YAML/JSON tree (yaml_dump_typed), the arm inlined;
    config_from_tree(tree) gives it back."""
    sections = _Sections(**{k: getattr(config, k) for k in _SECTION_CLASSES})
    tree = yaml_load(data=yaml_dump_typed(_loadable(sections)))
    return {"arm": config.arm_description, **tree}


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
    the arm's description itself. A section left out, or left empty, keeps its defaults
    (the shipped arm; a tree recorded before a section existed reads as it was made)."""
    if not isinstance(tree, dict):
        raise ConfigError(f"{where}: expected a mapping of sections, got "
                          f"{type(tree).__name__}")
    unknown = sorted(set(map(str, tree)) - set(SECTIONS))
    if unknown:
        raise ConfigError(f"{where}: unknown section {', '.join(unknown)} (known: "
                          f"{', '.join(SECTIONS)})")
    arm = tree.get("arm")
    if arm is None:
        arm_yaml, arm_where = DEFAULT_ARM_YAML.read_text(), f"arm description {DEFAULT_ARM_YAML}"
    elif isinstance(arm, str):
        path = arm_file(arm, base_dir)
        read_yaml(path, "arm description")  # a malformed file named
        arm_yaml, arm_where = path.read_text(), f"arm description {path}"
    else:
        arm_yaml, arm_where = yaml.safe_dump(arm, sort_keys=False), f"{where}: arm"
    arm_model = ContinuumArm.from_dict(parse_yaml(arm_yaml), arm_where)  # now, not at a wrap
    loaded = _typed_sections(tree)
    config = Config(arm_yaml=arm_yaml, **{k: _frozen(cls, getattr(loaded, k), k)
                                          for k, cls in _SECTION_CLASSES.items()})
    n_planes = len(enumerate_planes(arm_model.base_position, config.alpha_deg,
                                    config.both_directions))
    if config.active.start_plane >= n_planes:
        raise ConfigError(f"active.start_plane: must be below the number of planes "
                          f"({n_planes} for planes.alpha_deg = {config.alpha_deg:g}), got "
                          f"{config.active.start_plane}")
    return config


def parse_override(assignment: str) -> tuple[str, object]:
    """("section.key", value) of a "section.key=value" override, the value parsed as YAML."""
    if "=" not in assignment:
        raise ConfigError(f"--set {assignment!r}: expected section.key=value")
    key, value = assignment.split("=", 1)
    try:
        return key.strip(), parse_yaml(value)
    except yaml.YAMLError as e:
        raise ConfigError(f"--set {assignment!r}: not a YAML value ({e})") from None


def apply_overrides(tree: dict, overrides=()) -> dict:
    """A copy of `tree` with each "section.key=value" (a YAML value) set; the key must exist
    (in the tree, or as a field of its section's class)."""
    tree = copy.deepcopy(tree)
    for assignment in overrides:
        key, value = parse_override(assignment)
        parts = key.split(".")
        node, schema = tree, _Sections
        for p in parts[:-1]:
            if node.get(p) is None and dataclasses.is_dataclass(_field_type(schema, p)):
                node[p] = {}  # a section the file leaves out or empty
            if not isinstance(node.get(p), dict):
                raise ConfigError(f"--set {assignment!r}: no section {p!r} in the configuration")
            node = node[p]
            schema = _field_type(schema, p)
        if parts[-1] not in node and _field_type(schema, parts[-1]) is None and key != "arm":
            raise ConfigError(f"--set {assignment!r}: no key {parts[-1]!r} in section "
                              f"{'.'.join(parts[:-1]) or 'top level'}")
        node[parts[-1]] = value
    return tree


def _field_type(cls, name: str):
    """The type of the field `name` of the dataclass `cls`, None if it has none."""
    if cls is None or not dataclasses.is_dataclass(cls):
        return None
    return typing.get_type_hints(cls).get(name)


def read_config_tree(path=None) -> tuple[dict, Path]:
    """The YAML tree of a configuration file (default models/config.yaml) and its path."""
    path = Path(path) if path is not None else DEFAULT_CONFIG
    return read_yaml(path, "configuration"), path


def load_config(path=None, overrides=(), base: dict | None = None) -> Config:
    """Read a configuration file (default models/config.yaml), or start from the recorded
    tree `base` (with a file too: the file's settings on top of it, a section or key the
    file leaves out keeping the recorded one), and apply `overrides`, each
    "section.key=value" with a YAML value. Raises ConfigError naming the file and the key.
    An arm file is looked for beside the configuration file, or, given as an override
    (`arm=PATH`), from the working folder (arm_file)."""
    if base is not None and path is None:
        tree, where, base_dir = base, "recorded settings", None
    else:
        tree, path = read_config_tree(path)
        where, base_dir = f"configuration {path}", path.parent
        if base is not None and isinstance(tree or {}, dict):
            tree = _layered(base, tree or {})
    if any(o.split("=", 1)[0].strip() == "arm" for o in overrides):
        base_dir = Path.cwd()
    try:
        return config_from_tree(apply_overrides(tree or {}, overrides), where, base_dir)
    except ConfigError as e:
        if str(e).startswith(where) or str(e).startswith("--set"):
            raise
        given = [o for o in overrides if _refused_key(str(e), o.split("=", 1)[0].strip())]
        raise ConfigError(f"{f'--set {given[-1]!r}' if given else where}: {e}") from None


def _layered(base: dict, top: dict) -> dict:
    """`top`'s settings over `base`'s, key by key: what `top` leaves out or empty keeps
    `base`'s; an arm `top` names replaces the recorded one whole."""
    out = copy.deepcopy(base)
    for key, value in top.items():
        if value is None:
            continue
        if key != "arm" and isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _layered(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def _refused_key(message: str, key: str) -> bool:
    """Whether a refusal names the setting `key` (or a key under it): the error of a value
    a --set gave names that --set, not the file it overrides."""
    return message.startswith(key) and message[len(key):len(key) + 1] in (":", ".", " ")


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

def model_config(info: dict, path=None, overrides=()) -> tuple[Config, list[str]]:
    """The configuration to wrap and recognise with for a model: the settings it records
    (experiments.collection.training_settings), the file `path` on top of them when given
    (a section or key it leaves out keeps the recorded one), then `overrides`. Also returns
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
