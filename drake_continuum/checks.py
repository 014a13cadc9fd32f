"""The checks of the configuration's parameter dataclasses (WrapParams, IKOptions,
ChordParams, ClassifierParams, ActiveParams, PlaneParams, ObservedParams), run by each class's
`__post_init__`: a value is checked once, however the object is made (from a file by
config.load_config, or in code), and a bad one is a FieldError naming its field.

Each field must have its annotated type: a finite number for `float`, a whole number for
`int`, true or false for `bool`, a member's value for a str-valued Enum (the field then holds
the member), finite numbers for `tuple` (held as a tuple of floats). A Rule adds a range.
"""

from __future__ import annotations

import enum
import functools
import math
import numbers
import typing
from dataclasses import dataclass, fields
from typing import Callable

from .errors import ConfigError

__all__ = ["FieldError", "Rule", "between", "count", "at_least", "check_fields", "STEP_MAX",
           "STEP", "GAP"]


class FieldError(ConfigError):
    """A parameter dataclass's field of the wrong type or out of range.

    Args:
        owner: the class's name.
        name: the field's name.
        reason: what it must be and what it got.
    """

    def __init__(self, owner: str, name: str, reason: str):
        super().__init__(f"{owner}.{name}: {reason}")
        self.owner, self.name, self.reason = owner, name, reason


@dataclass(frozen=True)
class Rule:
    """A range beyond the type: `test(value)` holds for a good value; `text` says what it
    requires ("in (0, 0.1] m")."""

    test: Callable[[object], bool]
    text: str


def between(lo: float, hi: float, unit: str = "", *, open_low: bool = True) -> Rule:
    """lo < value <= hi (lo <= value <= hi when not open_low); a tuple: every element."""
    def one(v):
        return lo < v <= hi if open_low else lo <= v <= hi

    def test(v):
        return all(one(x) for x in v) if isinstance(v, tuple) else one(v)

    return Rule(test, f"in {'(' if open_low else '['}{lo:g}, {hi:g}]{unit}")


def count(hi: int, lo: int = 1) -> Rule:
    """A whole number from lo to hi."""
    return Rule(lambda v: lo <= v <= hi, f"from {lo} to {hi:,}")


def at_least(lo: float) -> Rule:
    return Rule(lambda v: v >= lo, f">= {lo:g}")


# A step, gap or tolerance in metres is at most STEP_MAX, a third of the largest tabletop
# object: larger ones are typing errors (a value in mm or cm).
STEP_MAX = 0.1  # m
STEP = between(0, STEP_MAX, " m")
GAP = between(0, STEP_MAX, " m", open_low=False)


@functools.cache
def _hints(cls) -> dict:
    return typing.get_type_hints(cls)


def _typed(kind, value):
    """(value as the field holds it, None) or (None, what was expected)."""
    if isinstance(kind, type) and issubclass(kind, enum.Enum):
        try:
            return kind(value), None
        except ValueError:
            return None, f"one of {', '.join(repr(m.value) for m in kind)}"
    if kind is bool:
        return (value, None) if isinstance(value, bool) else (None, "true or false")
    if kind is int:
        ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
        return (value, None) if ok else (None, "a whole number")
    if kind is float:
        ok = isinstance(value, numbers.Real) and not isinstance(value, bool)
        return (value, None) if ok and math.isfinite(value) else (None, "a finite number")
    if kind is str:
        return (value, None) if isinstance(value, str) else (None, "a string")
    if kind is tuple or typing.get_origin(kind) is tuple:
        items = [_typed(float, v) for v in value] if isinstance(value, (list, tuple)) else None
        if items is None or any(err for _, err in items):
            return None, "a list of finite numbers"
        return tuple(float(v) for v, _ in items), None
    return value, None  # a nested dataclass: checked by its own class


def _shown(value) -> str:
    """A value as the user wrote it: a whole float without its ".0" (a file's 1000 reads as
    1000.0)."""
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
        return str(int(value))
    return repr(value)


def check_fields(obj, **rules: Rule) -> None:
    """Check every field of the dataclass `obj` against its type and its rule in `rules`;
    an Enum field is set to its member, a tuple field to a tuple of floats. Raises
    FieldError."""
    owner = type(obj).__name__
    hints = _hints(type(obj))
    for f in fields(obj):
        value = getattr(obj, f.name)
        held, expected = _typed(hints[f.name], value)
        if expected is not None:
            raise FieldError(owner, f.name, f"must be {expected}, got {_shown(value)}")
        rule = rules.get(f.name)
        if rule is not None and not rule.test(held):
            raise FieldError(owner, f.name, f"must be {rule.text}, got {_shown(value)}")
        if held is not value:
            object.__setattr__(obj, f.name, held)
    unknown = set(rules) - {f.name for f in fields(obj)}
    if unknown:
        raise TypeError(f"{owner}: rules for no field: {sorted(unknown)}")
