"""One experiment configuration: every parameter of planes, wrap, chords and active
recognition, read from models/config.yaml (the arm from its own description), with command-line
overrides `section.key=value`."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np
import yaml

from .active import ActiveParams
from .arm import MODELS_DIR, ContinuumArm
from .chords import ChordParams
from .classify import ClassifierParams
from .files import read_yaml
from .ik import IKOptions
from .wrap import WrapParams

DEFAULT_CONFIG = MODELS_DIR / "config.yaml"


@dataclass(frozen=True)
class Config:
    """A whole experiment's parameters.

    Args:
        arm_path: the arm description (YAML).
        alpha_deg: plane spacing, deg.
        both_directions: wrap every plane both ways.
        wrap: Algorithm 1's parameters.
        chords: the descriptor's parameters.
        classifier: the histogram, PCA and SVM settings.
        active: active recognition's constants.
    """

    arm_path: Path
    alpha_deg: float
    both_directions: bool
    wrap: WrapParams
    chords: ChordParams
    classifier: ClassifierParams
    active: ActiveParams

    def arm(self) -> ContinuumArm:
        return ContinuumArm.from_yaml(self.arm_path)


def _build(cls, values: dict, where: str):
    names = {f.name for f in fields(cls)}
    unknown = set(values) - names
    if unknown:
        raise ValueError(f"{where}: unknown keys {sorted(unknown)} (known: {sorted(names)})")
    try:
        return cls(**values)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{where}: {e}") from None


def _set(tree: dict, assignment: str) -> None:
    if "=" not in assignment:
        raise ValueError(f"--set {assignment!r}: expected section.key=value")
    key, value = assignment.split("=", 1)
    parts = key.strip().split(".")
    node = tree
    for p in parts[:-1]:
        if not isinstance(node.get(p), dict):
            raise ValueError(f"--set {assignment!r}: no section {p!r} in the configuration")
        node = node[p]
    if parts[-1] not in node:
        raise ValueError(f"--set {assignment!r}: no key {parts[-1]!r} in section "
                         f"{'.'.join(parts[:-1]) or 'top level'}")
    node[parts[-1]] = yaml.safe_load(value)


def load_config(path=None, overrides=()) -> Config:
    """Read a configuration file (default models/config.yaml) and apply `overrides`, each
    "section.key=value" with a YAML value."""
    path = Path(path) if path is not None else DEFAULT_CONFIG
    tree = read_yaml(path, "configuration")
    expected = {"arm", "planes", "wrap", "chords", "classifier", "active"}
    if not isinstance(tree, dict) or set(tree) != expected:
        raise ValueError(f"configuration {path}: needs exactly the sections {sorted(expected)}")
    for assignment in overrides:
        _set(tree, assignment)
    wrap = dict(tree["wrap"])
    ik = _build(IKOptions, dict(wrap.pop("ik", {})), f"{path}: wrap.ik")
    for name in ("theta", "stall_turn"):
        if f"{name}_deg" in wrap:
            wrap[name] = float(np.radians(wrap.pop(f"{name}_deg")))
    wrap["start_lengths"] = tuple(wrap.get("start_lengths", WrapParams.start_lengths))
    planes = tree["planes"]
    arm_path = Path(tree["arm"])
    return Config(arm_path=arm_path if arm_path.is_absolute() else path.parent / arm_path,
                  alpha_deg=float(planes["alpha_deg"]),
                  both_directions=bool(planes.get("both_directions", False)),
                  wrap=replace(_build(WrapParams, wrap, f"{path}: wrap"), ik=ik),
                  chords=_build(ChordParams, tree["chords"], f"{path}: chords"),
                  classifier=_build(ClassifierParams, tree["classifier"], f"{path}: classifier"),
                  active=_build(ActiveParams, tree["active"], f"{path}: active"))
