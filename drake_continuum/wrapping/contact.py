"""Contacts between the arm and an object: positions and frames, one row a contact."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Contacts", "FIELDS"]


@dataclass(frozen=True)
class Contacts:
    """A set of m contact regions {p, n, t, b} (the paper's section III).

    Args:
        p: (m, 3) contact centres (area-weighted centroid of a contact polygon), m.
        n: (m, 3) unit normals, pointing from the object into the arm.
        t: (m, 3) unit tangents: the arm's axis with its normal component removed.
        b: (m, 3) unit binormals, n x t.
        section: (m,) index (0-based) of the arm section in contact.
        arc_length: (m,) arc length along the arm of the contact, m.
        area: (m,) contact polygon area, m^2 (how deep the touch is).
    """

    p: np.ndarray
    n: np.ndarray
    t: np.ndarray
    b: np.ndarray
    section: np.ndarray
    arc_length: np.ndarray
    area: np.ndarray

    @classmethod
    def empty(cls) -> "Contacts":
        z3 = np.zeros((0, 3))
        return cls(z3, z3, z3, z3, np.zeros(0, int), np.zeros(0), np.zeros(0))

    def __len__(self) -> int:
        return len(self.p)

    @classmethod
    def concatenate(cls, items) -> "Contacts":
        items = [c for c in items if len(c)]
        if not items:
            return cls.empty()
        return cls(*(np.concatenate([getattr(c, f) for c in items]) for f in FIELDS))

    def to_arrays(self, prefix: str = "") -> dict:
        return {prefix + f: getattr(self, f) for f in FIELDS}

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "") -> "Contacts":
        return cls(*(np.asarray(arrays[prefix + f]) for f in FIELDS))


FIELDS = ("p", "n", "t", "b", "section", "arc_length", "area")
