"""What placed copies are called: the kinds of placement, the sides, the ids
`<object_id>@<kind><k>` and the `--placements` counts.

Kept apart from the geometry of placement.py (which loads trimesh), so that the command line
and the learning code name placed copies without loading it.
"""

from __future__ import annotations

from ..errors import InputError

__all__ = ["KINDS", "TRAINING_KINDS", "SIDES", "ID_SEPARATOR", "PlacementError", "placed_id",
           "source_id", "placement_kind", "parse_counts"]

# Kinds of placement a placed dataset can hold (what `--placements` and evaluate use):
KINDS = {
    "train": "a rest pose drawn by its probability (or as generated), any turn: for training",
    "turned": "standing as generated, turned any way about the vertical",
    "rest": "on its most probable side other than as generated, turned any way",
    "nudged": "standing as generated, up to NUDGE_OFFSET off the mark and NUDGE_TURN turned",
    "jitter": "the `turned` placement of the same number moved JITTER_OFFSET and JITTER_TURN "
              "(a prediction that changes between the two is a flip)",
    "side": "the first: on its most probable side other than as generated (the side `rest` "
            "tests), turned its own way; each further one on another side drawn as `lying` "
            "draws it: for training",
    "lying": "on a side other than as generated drawn by its probability (among those "
             "sides), turned any way",
}
# Kinds trained on (the others are tested). "side" puts every object's most probable other
# side in training: "train" draws it too seldom for bowls, cups and toilet rolls (their
# single most probable other side is upside down, while lying on one of many sides is
# likelier in all). Further side copies draw their side by its probability: a cup's
# likeliest single pose other than standing is upside down, but it lies on its flank 9
# times in 10 (over its many rolled flank poses), which `lying` tests. reproduce places
# side=3 (measured: BENCHMARKS.md, Placements).
TRAINING_KINDS = ("train", "side")
# The side a placed copy stands on (recorded with it; the classifier's rest classes): as
# generated (no rest pose, or one tilted at most SAME_SIDE), or another side.
SIDES = ("generated", "other")
ID_SEPARATOR = "@"


class PlacementError(InputError):
    """A placement that cannot be used; the message names the value and the problem."""


def placed_id(object_id: str, tag: str) -> str:
    return f"{object_id}{ID_SEPARATOR}{tag}"


def source_id(object_id: str) -> str:
    """The object a (possibly placed) object id came from: the part before '@'."""
    return str(object_id).split(ID_SEPARATOR, 1)[0]


def placement_kind(object_id: str) -> str:
    """'generated' for an object as generated, else its placement's kind (the tag's
    letters)."""
    parts = str(object_id).split(ID_SEPARATOR, 1)
    return "generated" if len(parts) == 1 else parts[1].rstrip("0123456789")


def parse_counts(text: str) -> dict:
    """'turned=2,rest=1' -> {"turned": 2, "rest": 1}; PlacementError naming the entry."""
    out = {}
    for item in filter(None, (t.strip() for t in str(text).split(","))):
        kind, _, n = item.partition("=")
        if kind not in KINDS:
            raise PlacementError(f"placement kind {kind!r} unknown (known: {', '.join(KINDS)})")
        try:
            out[kind] = int(n)
        except ValueError:
            raise PlacementError(f"placements {item!r}: expected KIND=N") from None
        if out[kind] < 0:
            raise PlacementError(f"placements {item!r}: N must be >= 0")
    return out
