"""What a wrap produces: the record every later step (chords, collection, active) reads."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from ..kinematics.arm import ArmConfig
from .contact import Contacts

__all__ = ["WrapStatus", "STATUSES", "WrapResult", "WRAPS_FORMAT", "WRAPS_FORMAT_VERSION",
           "stored_params", "params_difference"]

# A wrap collection's files (collect.py): "format" and "format_version" in every JSON file.
WRAPS_FORMAT = "drake-continuum-wraps"
WRAPS_FORMAT_VERSION = 1


def stored_params(params) -> dict:
    """A collection's recorded run parameters (collect.run_params: in index.json and every
    object's JSON) in the current names: "package_version" of a collection made before
    0.5.0 is its "wraps_version". {} for anything but a mapping."""
    if not isinstance(params, dict):
        return {}
    if "package_version" in params and "wraps_version" not in params:
        params = {("wraps_version" if k == "package_version" else k): v
                  for k, v in params.items()}
    return params


def params_difference(stored: dict, current: dict, names=("stored", "now")) -> list[str]:
    """Readable names of the recorded run parameters that differ (wrap_params by field),
    each with both values labelled by `names`."""
    out = []
    for key in sorted(set(stored) | set(current)):
        a, b = stored.get(key), current.get(key)
        if a == b:
            continue
        if key == "wrap_params" and isinstance(a, dict) and isinstance(b, dict):
            out += [f"wrap_params.{k} ({names[0]} {a.get(k)!r}, {names[1]} {b.get(k)!r})"
                    for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
        elif key == "arm_yaml":
            out.append("arm_yaml (the arm description's text)")
        else:
            out.append(f"{key} ({names[0]} {a!r}, {names[1]} {b!r})")
    return out


class WrapStatus(StrEnum):
    """How a wrap ended (WrapResult.status holds the value; members equal the strings
    stored with a collection)."""

    COMPLETE = "complete"
    CLOSED = "closed"
    NO_IK = "no_ik"
    AT_LIMITS = "at_limits"
    NO_CONTACT = "no_contact"
    START_IN_COLLISION = "start_in_collision"
    EMPTY_CUT = "empty_cut"
    MAX_STEPS = "max_steps"


STATUSES = tuple(w.value for w in WrapStatus)


@dataclass(frozen=True)
class WrapResult:
    """One touch-driven wrap (Algorithm 1) on one plane.

    Args:
        plane_index: index of the wrap plane in planes.enumerate_planes(); -1 for a plane
            given by angles.
        plane_normal: (3,) unit normal of the wrap plane (world).
        base_rotation: (3, 3) orientation of the arm base for this wrap (configs are
            relative to it; the base position is the arm's, moved by base_offset).
        status: how the wrap ended, a WrapStatus (its string value is taken too and
            checked here); COMPLETE when the tip turned more than theta, CLOSED when the
            arm came round onto itself before that.
        configs: (k, 3n) configurations passed through, rows ArmConfig.as_vector().
        contacts: contacts of the final configuration, or when advancing lifted the arm off
            the object at the end, those of its last touch (about delta away).
        samples_arc_length: (m,) arc lengths of centre-line samples over the part of the arm
            that wraps the object (first contact to tip), m.
        samples_position, samples_tangent, samples_normal: (m, 3) centre-line points, unit
            tangents and unit normals (the bending direction: towards the object) there.
        tip_rotation: angle the tip's z axis turned from its start, rad.
        n_queries: contact queries made.
        time_s: wall time of the wrap, s (stored; Table I's time a wrap).
        extra: what else the wrap reports: the IK failure's message, and as it is made (not
            stored) "timing", the CPU seconds of its thread: "cpu_s" the whole wrap's, of
            which "ik", "pose", "prefilter", "contact_surfaces" and "rest".
        conformity: fraction of the wrapped centre line (the samples) whose tube lies within
            conformity.NEAR (5 mm) of the object's surface; 0 for no samples (nan when read
            from a file written before it was measured).
        wrap_angle: angle the samples sweep about the centroid of the plane's cut through
            the object, rad.
        base_offset: (3,) how far the base backed off in the plane for this wrap (world, m;
            wrap.base_backoff), None when it stayed at the arm's position.
    """

    plane_index: int
    plane_normal: np.ndarray
    base_rotation: np.ndarray
    status: WrapStatus
    configs: np.ndarray
    contacts: Contacts
    samples_arc_length: np.ndarray
    samples_position: np.ndarray
    samples_tangent: np.ndarray
    samples_normal: np.ndarray
    tip_rotation: float
    n_queries: int
    time_s: float
    extra: dict = field(default_factory=dict)
    conformity: float = 0.0
    wrap_angle: float = 0.0
    base_offset: np.ndarray | None = None

    def __post_init__(self):
        if not isinstance(self.status, WrapStatus):
            if self.status not in STATUSES:
                raise ValueError(f"wrap status must be one of {', '.join(STATUSES)}, got "
                                 f"{self.status!r}")
            object.__setattr__(self, "status", WrapStatus(self.status))

    def arm(self, arm):
        """`arm` as it stood for this wrap: base rotated and, if it backed off, moved."""
        position = None if self.base_offset is None else arm.base_position + self.base_offset
        return arm.with_base(position=position, rotation=self.base_rotation)

    @property
    def final_config(self) -> ArmConfig:
        return ArmConfig.from_vector(self.configs[-1])

    @property
    def contact_regions(self) -> int:
        """Contact regions of the final configuration (each a tactile patch)."""
        return len(self.contacts)

    @property
    def usable(self) -> bool:
        """A wrap with contacts whose shape describes the object (chords are taken from it)."""
        return len(self.contacts) > 0 and len(self.samples_position) >= 2

    _ARRAYS = ("plane_normal", "base_rotation", "configs", "samples_arc_length", "samples_position",
               "samples_tangent", "samples_normal")

    def to_arrays(self, prefix: str = "") -> dict:
        """Flat name -> array mapping for np.savez (no pickled objects)."""
        out = {prefix + k: np.asarray(getattr(self, k)) for k in self._ARRAYS}
        out.update(self.contacts.to_arrays(prefix + "contact_"))
        out[prefix + "scalars"] = np.array([self.plane_index, self.tip_rotation, self.n_queries,
                                            self.time_s, self.conformity, self.wrap_angle],
                                           dtype=float)
        out[prefix + "status"] = np.array(self.status.value)
        if self.base_offset is not None:
            out[prefix + "base_offset"] = np.asarray(self.base_offset, dtype=float)
        return out

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "") -> "WrapResult":
        sc = np.asarray(arrays[prefix + "scalars"], dtype=float)
        sc = np.concatenate([sc, np.full(6 - len(sc), np.nan)])  # older files: 4 scalars
        return cls(plane_index=int(sc[0]), status=str(arrays[prefix + "status"]),
                   contacts=Contacts.from_arrays(arrays, prefix + "contact_"),
                   tip_rotation=float(sc[1]), n_queries=int(sc[2]), time_s=float(sc[3]),
                   conformity=float(sc[4]), wrap_angle=float(sc[5]),
                   base_offset=(np.asarray(arrays[prefix + "base_offset"], dtype=float)
                                if prefix + "base_offset" in arrays else None),
                   **{k: np.asarray(arrays[prefix + k]) for k in cls._ARRAYS})
