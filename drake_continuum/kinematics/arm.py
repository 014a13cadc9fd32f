"""Constant-curvature continuum arm: configuration, limits and forward kinematics.

Each section i is a circular arc of length s_i, curvature kappa_i >= 0, bending towards the
direction at angle phi_i about the section's base z axis. A section's end frame is its base
frame moved along the arc and parallel-transported (no torsion), so sections that share phi
bend in one plane. Frames carry x = the bending direction (towards the centre of curvature),
y = binormal, z = tangent. All formulas are exact and continuous through kappa = 0: they use
sin(x)/x and (1 - cos x)/x written with numpy's sinc, which has no division by zero.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from importlib.resources import files
from pathlib import Path

import numpy as np

from ..errors import ConfigError, DrakeContinuumError, InputError
from ..files import read_yaml
from . import compiled

__all__ = ["MODELS_DIR", "DEFAULT_ARM_YAML", "ARM_COLOUR", "ArmLimitError", "ArmConfig",
           "BackboneSamples", "ContinuumArm", "arc_rotations", "arc_transforms", "load_arm"]

# The shipped models/ folder (package drake_continuum.models), as a file-system path: Drake
# and trimesh open files by name, and pip installs packages unzipped.
MODELS_DIR = Path(str(files("drake_continuum.models")))
DEFAULT_ARM_YAML = MODELS_DIR / "arm.yaml"
# Bounds of a description beyond positivity: IK solves for 3 numbers a section; the wraps'
# planes, the depth camera and the objects are tabletop-sized.
SECTIONS_MAX = 20
SECTION_LENGTH_MAX = 2.0  # m
# The limits a description may give a section at a time: one number holds for every section,
# a list gives one a section (a lab's distal section is often thinner, shorter or stiffer).
LIMIT_KEYS = ("section_length_min", "section_length_max", "curvature_max", "bend_max")
ARM_COLOUR = (0.95, 0.45, 0.05)  # the arm's orange paint, RGB in [0, 1]: the clouds' colour gate


class ArmLimitError(DrakeContinuumError):
    """An ArmConfig lies outside the arm's limits."""


@dataclass(frozen=True)
class ArmConfig:
    """Arm configuration, one entry a section.

    Args:
        s: (n,) section lengths, m.
        kappa: (n,) curvatures, 1/m, >= 0.
        phi: (n,) bending-plane angles about each section's base z axis, rad.
    """

    s: np.ndarray
    kappa: np.ndarray
    phi: np.ndarray

    def __post_init__(self):
        arrays = [np.array(getattr(self, name), dtype=float, ndmin=1) for name in
                  ("s", "kappa", "phi")]
        if not (arrays[0].shape == arrays[1].shape == arrays[2].shape) or arrays[0].ndim != 1:
            raise ValueError(
                f"ArmConfig: s, kappa, phi must be 1-D of one length, got shapes "
                f"{[a.shape for a in arrays]}")
        if not np.isfinite(arrays).all():
            bad = [n for n, a in zip(("s", "kappa", "phi"), arrays) if not np.isfinite(a).all()]
            raise InputError(f"ArmConfig: {', '.join(bad)} has non-finite entries")
        for name, arr in zip(("s", "kappa", "phi"), arrays):
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)

    @classmethod
    def of_arrays(cls, s, kappa, phi) -> "ArmConfig":
        """The configuration of three new (n,) float arrays that this package's arithmetic
        made finite from a checked configuration (they are frozen, not copied or checked
        again): enclosing makes one a step."""
        config = object.__new__(cls)
        for name, arr in (("s", s), ("kappa", kappa), ("phi", phi)):
            arr.flags.writeable = False
            object.__setattr__(config, name, arr)
        return config

    @property
    def n_sections(self) -> int:
        return len(self.s)

    def as_vector(self) -> np.ndarray:
        """(3n,) vector [s_1, kappa_1, phi_1, s_2, ...]."""
        return np.stack([self.s, self.kappa, self.phi], axis=1).ravel()

    @classmethod
    def from_vector(cls, q) -> "ArmConfig":
        q = np.asarray(q, dtype=float).reshape(-1, 3)
        return cls(q[:, 0], q[:, 1], q[:, 2])

    def to_dict(self) -> dict:
        return {"s": self.s.tolist(), "kappa": self.kappa.tolist(), "phi": self.phi.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> "ArmConfig":
        return cls(d["s"], d["kappa"], d["phi"])

    @classmethod
    def straight(cls, lengths) -> "ArmConfig":
        lengths = np.asarray(lengths, dtype=float)
        return cls(lengths, np.zeros_like(lengths), np.zeros_like(lengths))


def _number(value):
    """A float of a description's number (YAML 1.1 leaves 1e-3 as text); other values are
    passed on for ContinuumArm's checks to name."""
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            return value
    return value


def _numbers(value):
    """_number of a description's limit, one number or a list of them (one a section)."""
    return [_number(v) for v in value] if isinstance(value, list) else _number(value)


def _arc_positions(s, kappa, phi):
    """Position of the arc's end in its base frame, for arrays of arcs: (..., 3)."""
    x = kappa * s  # bend angle
    along = s * np.sinc(x / np.pi)  # s sin(x)/x
    radial = s * 0.5 * x * np.sinc(x / (2 * np.pi)) ** 2  # s (1 - cos x)/x, towards the bend
    return np.stack([radial * np.cos(phi), radial * np.sin(phi), along], axis=-1)


def arc_transforms(s, kappa, phi):
    """Pose of the arc's end in its base frame, for arrays of arcs.

    Args:
        s, kappa, phi: broadcastable arrays of arc lengths, curvatures and angles.

    Returns:
        R (..., 3, 3) and p (..., 3).
    """
    s, kappa, phi = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (s, kappa, phi)))
    return arc_rotations(s, kappa, phi), _arc_positions(s, kappa, phi)


def arc_rotations(s, kappa, phi) -> np.ndarray:
    """R (..., 3, 3) of `arc_transforms` alone, for arrays s, kappa, phi of one shape (the
    enclosing asks a section's base frame, and the positions cost as much again)."""
    x = kappa * s
    cphi, sphi = np.cos(phi), np.sin(phi)
    cx, sx = np.cos(x), np.sin(x)
    # R = Rz(phi) Ry(x) Rz(-phi), written out.
    c2, s2, cs = cphi * cphi, sphi * sphi, cphi * sphi
    R = np.empty(x.shape + (3, 3))
    R[..., 0, 0] = c2 * cx + s2
    R[..., 0, 1] = cs * (cx - 1.0)
    R[..., 0, 2] = cphi * sx
    R[..., 1, 0] = R[..., 0, 1]
    R[..., 1, 1] = s2 * cx + c2
    R[..., 1, 2] = sphi * sx
    R[..., 2, 0] = -cphi * sx
    R[..., 2, 1] = -sphi * sx
    R[..., 2, 2] = cx
    return R


@dataclass(frozen=True)
class BackboneSamples:
    """Points on the arm's centre line with their frames.

    Args:
        arc_length: (m,) arc length from the base, m.
        section: (m,) index of the section each sample lies on.
        position: (m, 3) world positions.
        tangent: (m, 3) unit tangents (towards the tip).
        normal: (m, 3) unit normals: the section's bending direction, towards the centre of
            curvature when kappa > 0 (the side an object being wrapped lies on).
        binormal: (m, 3) unit binormals, right-handed: normal x binormal = tangent.
    """

    arc_length: np.ndarray
    section: np.ndarray
    position: np.ndarray
    tangent: np.ndarray
    normal: np.ndarray
    binormal: np.ndarray


def _frozen(values) -> np.ndarray:
    out = np.array(values, float)
    out.setflags(write=False)
    return out


@dataclass(frozen=True)
class ContinuumArm:
    """A fixed-base continuum arm of n constant-curvature sections.

    Each limit is one number for every section, or a sequence of n (one a section); the
    per-section values are `section_limits()`. After construction the four limit fields hold
    their envelope over the sections (the shortest minimum, the longest maximum, the largest
    curvature and bend), the bound of any section, and `per_section` the sequences given.

    Args:
        n_sections: number of sections.
        section_length_min, section_length_max: bounds on each s_i, m.
        curvature_max: bound on each kappa_i, 1/m.
        radius: tube radius, m.
        bend_max: bound on each section's bend angle kappa_i * s_i, rad: a real section
            cannot coil, whatever its curvature limit.
        base_position: (3,) world position of the base, m.
        base_rotation: (3, 3) world orientation of the base frame; the straight arm
            points along its z axis.
        per_section: (key, (n values)) pairs of the limits given a section at a time (set
            from sequences given for the limit fields; kept by dataclasses.replace).
    """

    n_sections: int = 3
    section_length_min: float = 0.10
    section_length_max: float = 0.40
    curvature_max: float = 40.0
    radius: float = 0.01
    bend_max: float = np.pi
    base_position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    base_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    per_section: tuple = ()

    def __post_init__(self):
        """Every field in range: a NaN limit or a coiling section would make every wrap end
        without contact rather than fail."""
        n = self.n_sections
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ConfigError(f"n_sections: must be a whole number >= 1, got {n!r}")
        if n > SECTIONS_MAX:  # before anything is sized by it (limits are n long)
            raise ConfigError(f"n_sections: must be at most {SECTIONS_MAX} (IK solves for 3 "
                              f"numbers a section), got {n}")
        v = self.radius
        if isinstance(v, bool) or not isinstance(v, (int, float, np.number)) \
                or not np.isfinite(v) or v <= 0:
            raise ConfigError(f"radius: must be a finite number > 0 (one tube for the whole "
                              f"arm), got {v!r}")
        limits = self._limits_given()
        lo, hi, kappa, bend = (limits[k] for k in LIMIT_KEYS)
        for i in range(n):
            at = f" (section {i + 1})" if self.per_section else ""
            if lo[i] > hi[i]:
                raise ConfigError(f"section_length_min: must be at most section_length_max "
                                  f"({hi[i]}){at}, got {lo[i]}")
            if self.radius * kappa[i] >= 1:
                raise ConfigError(f"radius: must be below 1 / curvature_max = "
                                  f"{1 / kappa[i]:.4g} m{at} (a tube that thick folds on "
                                  f"its inner side at the tightest bend), got {self.radius}")
            if bend[i] > 2 * np.pi:
                raise ConfigError(f"bend_max: must be at most 2 pi rad (a section cannot "
                                  f"coil through itself){at}, got {bend[i]}")
        # Every section's limits, read on every step of a wrap: made once, read-only.
        object.__setattr__(self, "_section_limits", tuple(
            _frozen(limits[k]) for k in LIMIT_KEYS))
        for name, values in limits.items():  # the envelope: the bound of any section
            object.__setattr__(self, name, float(values.min() if name == "section_length_min"
                                                 else values.max()))
        for name, shape in (("base_position", (3,)), ("base_rotation", (3, 3))):
            try:
                v = np.asarray(getattr(self, name), float).reshape(shape)
            except (TypeError, ValueError):
                raise ConfigError(f"{name}: must be {np.prod(shape)} numbers, got "
                                  f"{getattr(self, name)!r}") from None
            if not np.isfinite(v).all():
                raise ConfigError(f"{name}: must be finite numbers, got {v.tolist()}")
            object.__setattr__(self, name, v)
        if not np.allclose(self.base_rotation @ self.base_rotation.T, np.eye(3), atol=1e-9):
            raise ConfigError("base_rotation: must be a rotation matrix")

    def _limits_given(self) -> dict:
        """key -> (n,) values of each limit, checked (finite, > 0, n of them); sequences
        given for the fields move into `per_section`."""
        n, kept = self.n_sections, dict(self.per_section)
        if set(kept) - set(LIMIT_KEYS):
            raise ConfigError(f"per_section: unknown keys {sorted(set(kept) - set(LIMIT_KEYS))}")
        out = {}
        for name in LIMIT_KEYS:
            v = getattr(self, name)
            if isinstance(v, (list, tuple, np.ndarray)):
                kept[name] = v
            elif name in kept and np.isclose(v, np.max(kept[name]) if name != LIMIT_KEYS[0]
                                             else np.min(kept[name])):
                v = kept[name]  # the envelope of a replace(): the sections' values hold
            else:
                kept.pop(name, None)  # one number given: it holds for every section
            values = np.atleast_1d(np.asarray(v, dtype=object))
            if values.ndim != 1 or len(values) not in ((1, n) if np.ndim(v) == 0 else (n,)):
                raise ConfigError(f"{name}: must be one number or a list of n_sections = {n} "
                                  f"numbers (one a section), got {len(values)}: {list(values)}")
            for x in values:
                if isinstance(x, bool) or not isinstance(x, (int, float, np.number)) \
                        or not np.isfinite(x) or x <= 0:
                    raise ConfigError(f"{name}: must be a finite number > 0"
                                      f"{' for every section' if len(values) > 1 else ''}, "
                                      f"got {v!r}")
            out[name] = np.broadcast_to(values.astype(float), (n,)).copy()
        object.__setattr__(self, "per_section", tuple(
            (k, tuple(float(x) for x in out[k])) for k in LIMIT_KEYS if k in kept))
        return out

    def section_limits(self) -> tuple:
        """(length min, length max, curvature max, bend max), each (n,): every section's own
        limits (m, m, 1/m, rad); read-only."""
        return self._section_limits

    @classmethod
    def from_yaml(cls, path=DEFAULT_ARM_YAML) -> "ContinuumArm":
        path = Path(path)
        return cls.from_dict(read_yaml(path, "arm description"), f"arm description {path}")

    @classmethod
    def from_dict(cls, d, where: str = "arm description") -> "ContinuumArm":
        """The arm of a description mapping (the arm YAML's keys); `where` names it in
        errors."""
        from pydrake.math import RollPitchYaw

        keys = {"n_sections", "section_length_min", "section_length_max", "curvature_max",
                "radius", "bend_max", "base_position", "base_rpy"}
        if not isinstance(d, dict) or keys - set(d):
            missing = sorted(keys - set(d)) if isinstance(d, dict) else sorted(keys)
            raise ConfigError(f"{where}: missing keys {missing}")
        unknown = set(d) - keys
        if unknown:
            raise ConfigError(f"{where}: unknown keys {sorted(unknown)}")
        try:
            rpy = np.asarray(d["base_rpy"], dtype=float).reshape(3)
        except (TypeError, ValueError):
            rpy = np.full(3, np.nan)
        if not np.isfinite(rpy).all():
            raise ConfigError(f"{where}: base_rpy: must be 3 finite numbers (rad), got "
                              f"{d['base_rpy']!r}")
        try:
            n = d["n_sections"]
            arm = cls(n_sections=int(n) if isinstance(n, float) and n.is_integer() else n,
                      section_length_min=_numbers(d["section_length_min"]),
                      section_length_max=_numbers(d["section_length_max"]),
                      curvature_max=_numbers(d["curvature_max"]), radius=_number(d["radius"]),
                      bend_max=_numbers(d["bend_max"]), base_position=d["base_position"],
                      base_rotation=RollPitchYaw(rpy).ToRotationMatrix().matrix())
            arm._check_description()
            return arm
        except ConfigError as e:
            raise ConfigError(f"{where}: {e}") from None
        except (TypeError, ValueError) as e:
            raise ConfigError(f"{where}: {e}") from None

    def _check_description(self) -> None:
        """The bounds of an arm a user describes, beyond ContinuumArm's own checks (which
        allow the one-section arms and far bases that fitting builds internally)."""
        if not 2 <= self.n_sections <= SECTIONS_MAX:
            raise ConfigError(f"n_sections: must be from 2 (Algorithm 1 reaches the object "
                              f"with section 1 and wraps with the rest) to {SECTIONS_MAX}, "
                              f"got {self.n_sections}")
        if self.section_length_max > SECTION_LENGTH_MAX:  # the longest section
            raise ConfigError(f"section_length_max: must be at most {SECTION_LENGTH_MAX} m (a "
                              f"tabletop arm), got {self.section_length_max}")
        if np.linalg.norm(self.base_position) >= self.length_max:
            raise ConfigError(f"base_position: {self.base_position.tolist()} m is farther from "
                              f"the mark objects stand on (the origin) than the arm reaches "
                              f"({self.length_max:g} m)")

    def with_base(self, position=None, rotation=None) -> "ContinuumArm":
        """The same arm on another base pose."""
        return replace(self,
                       base_position=self.base_position if position is None else position,
                       base_rotation=self.base_rotation if rotation is None else rotation)

    @property
    def length_max(self) -> float:
        return float(np.sum(self.section_limits()[1]))

    def check(self, config: ArmConfig, tol: float = 1e-9) -> None:
        """Raise ArmLimitError naming the section and the limit a config violates."""
        if config.n_sections != self.n_sections:
            raise ArmLimitError(f"ArmConfig has {config.n_sections} sections; the arm has "
                                f"{self.n_sections}")
        # Python floats (the same doubles): asked before every contact query
        lo, hi, kappa_max, bend_max = (a.tolist() for a in self.section_limits())
        for i, (s, k) in enumerate(zip(config.s.tolist(), config.kappa.tolist())):
            if s < lo[i] - tol or s > hi[i] + tol:
                raise ArmLimitError(
                    f"section {i + 1}: length s = {s:.4g} m outside [{lo[i]:g}, {hi[i]:g}] m")
            if k < -tol or k > kappa_max[i] + tol:
                raise ArmLimitError(f"section {i + 1}: curvature kappa = {k:.4g} 1/m outside "
                                    f"[0, {kappa_max[i]:g}] 1/m")
            if k * s > bend_max[i] + tol:
                raise ArmLimitError(f"section {i + 1}: bend angle kappa * s = {k * s:.4g} rad "
                                    f"above bend_max = {bend_max[i]:.4g} rad")

    def curvature_limit(self, s, section=None) -> np.ndarray:
        """Largest curvature a section of length s may take: the curvature or bend limit.

        Args:
            s: a length, or lengths (..., n) of every section in turn.
            section: the section index of a single length s (needed when the limits differ
                by section; ignored when they do not).
        """
        _, _, kappa_max, bend_max = self.section_limits()
        if section is not None and isinstance(s, float):  # one section's (enclosing's steps)
            bend = bend_max[section] / s
            return kappa_max[section] if kappa_max[section] <= bend else bend
        s = np.asarray(s, float)
        if section is not None:
            kappa_max, bend_max = kappa_max[section], bend_max[section]
        elif not self.per_section:
            kappa_max, bend_max = self.curvature_max, self.bend_max
        elif s.shape[-1:] != (self.n_sections,):
            raise ValueError(f"curvature_limit: the arm's limits differ by section; give "
                             f"the lengths of all {self.n_sections} sections or section=")
        return np.minimum(kappa_max, bend_max / s)

    def within_limits(self, config: ArmConfig, tol: float = 1e-9) -> bool:
        try:
            self.check(config, tol)
        except ArmLimitError:
            return False
        return True

    def section_frames(self, config: ArmConfig):
        """World poses of the base and every section end.

        Returns:
            R (n+1, 3, 3) and p (n+1, 3): index 0 is the base, index i the end of section i.
        """
        Rl, pl = arc_transforms(config.s, config.kappa, config.phi)
        R = np.empty((config.n_sections + 1, 3, 3))
        p = np.empty((config.n_sections + 1, 3))
        R[0], p[0] = self.base_rotation, self.base_position
        for i in range(config.n_sections):  # a loop over sections (3), not over points
            p[i + 1] = p[i] + R[i] @ pl[i]
            R[i + 1] = R[i] @ Rl[i]
        return R, p

    def tip_frame(self, config: ArmConfig):
        R, p = self.section_frames(config)
        return R[-1], p[-1]

    def backbone(self, config: ArmConfig, arc_length=None, n: int = 60) -> BackboneSamples:
        """Centre-line samples at the given arc lengths (default: n evenly spaced, base to tip)."""
        total = float(config.s.sum())
        if arc_length is None:
            arc_length = np.linspace(0.0, total, n)
        arc_length = np.ascontiguousarray(arc_length, dtype=float)
        if len(arc_length) and (arc_length.min() < -1e-12 or arc_length.max() > total + 1e-12):
            raise ValueError(f"arc lengths must lie in [0, {total:.4g}] m")
        sec, position, tangent, normal, binormal = compiled.backbone_samples(
            self.base_rotation, self.base_position, config.s, config.kappa, config.phi,
            arc_length)
        return BackboneSamples(arc_length=arc_length, section=sec, position=position,
                               tangent=tangent, normal=normal, binormal=binormal)

    def batch_points(self, s, kappa, phi, fractions):
        """Section ends and centre-line points of many configurations at once.

        Args:
            s, kappa, phi: (B, n) arrays, one row a configuration.
            fractions: (F,) positions within each section, 0 = its start, 1 = its end.

        Returns:
            ends (B, n, 3) and points (B, n * F, 3), section by section. Numerical
            Jacobians for IK evaluate all perturbed configurations in this one call.
        """
        s, kappa, phi = (np.ascontiguousarray(a, float) for a in (s, kappa, phi))
        return compiled.batch_points(self.base_rotation, self.base_position, s, kappa, phi,
                                     np.ascontiguousarray(fractions, float))


def load_arm(path=None) -> ContinuumArm:
    """The arm described by `path`, default models/arm.yaml."""
    return ContinuumArm.from_yaml(DEFAULT_ARM_YAML if path is None else path)
