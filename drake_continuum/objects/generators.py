"""Procedural objects for the paper's 10 categories, with real-world sizes and real variety.

Each category is a frozen parameter dataclass, a `sample_<category>(rng)` that draws one
plausible instance, and a `make_<category>(params)` that builds its watertight solid in
metres (categories.py; re-exported here). Ranges overlap on purpose where people confuse
classes (cup, mug and bowl; bottle and toilet paper roll; apple and donut from the side): a
dataset every descriptor gets right teaches nothing. `generate_object` ties it together and
puts the result in the standard pose.
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass

import numpy as np
import trimesh

from ..errors import InputError
from . import categories, shapes
from .categories import (
    AppleParams,
    BananaParams,
    BottleParams,
    BowlParams,
    CupParams,
    DonutParams,
    HammerParams,
    MugParams,
    TeapotParams,
    ToiletPaperParams,
    make_apple,
    make_banana,
    make_bottle,
    make_bowl,
    make_cup,
    make_donut,
    make_hammer,
    make_mug,
    make_teapot,
    make_toilet_paper,
    mug_landmarks,
    sample_apple,
    sample_banana,
    sample_bottle,
    sample_bowl,
    sample_cup,
    sample_donut,
    sample_hammer,
    sample_mug,
    sample_teapot,
    sample_toilet_paper,
)
from .pose import PosedMesh, closed_as_obj, to_standard_pose

__all__ = ["CATEGORY_COUNTS", "CATEGORIES", "MugParams", "sample_mug", "make_mug", "mug_landmarks",
           "CupParams", "sample_cup", "make_cup", "BowlParams", "sample_bowl", "make_bowl",
           "BottleParams", "sample_bottle", "make_bottle", "ToiletPaperParams",
           "sample_toilet_paper", "make_toilet_paper", "AppleParams", "sample_apple", "make_apple",
           "DonutParams", "sample_donut", "make_donut", "BananaParams", "sample_banana",
           "make_banana", "HammerParams", "sample_hammer", "make_hammer", "TeapotParams",
           "sample_teapot", "make_teapot", "SAMPLERS", "MAKERS", "GeneratedObject", "object_rng",
           "generate_object"]

CATEGORY_COUNTS = {"apple": 12, "banana": 6, "bottle": 51, "bowl": 21, "cup": 10,
                   "donut": 10, "hammer": 28, "mug": 32, "teapot": 6, "toilet_paper": 9}
CATEGORIES = tuple(CATEGORY_COUNTS)


# --- registry ------------------------------------------------------------------------------

SAMPLERS = {c: getattr(categories, f"sample_{c}") for c in CATEGORIES}
MAKERS = {c: getattr(categories, f"make_{c}") for c in CATEGORIES}


@dataclass(frozen=True)
class GeneratedObject:
    """One generated object in the standard pose.

    Attributes: category, index (within the category), id (e.g. "mug_007"), params (the
    generator's dataclass), posed (mesh, scale and translation applied).
    """
    category: str
    index: int
    id: str
    params: object
    posed: PosedMesh

    @property
    def mesh(self) -> trimesh.Trimesh:
        return self.posed.mesh

    def params_dict(self) -> dict:
        return dataclasses.asdict(self.params)


def object_rng(category: str, index: int, seed: int) -> np.random.Generator:
    """An independent stream per (seed, category, index): objects do not depend on each other."""
    key = int.from_bytes(hashlib.sha256(category.encode()).digest()[:4], "little")
    return np.random.default_rng([int(seed), key, int(index)])


def generate_object(category: str, index: int, seed: int = 0) -> GeneratedObject:
    """Sample and build object `index` of `category`, in the standard pose."""
    if category not in SAMPLERS:
        raise InputError(f"unknown category {category!r} (known: {', '.join(CATEGORIES)})")
    params = SAMPLERS[category](object_rng(category, index, seed))
    solid = MAKERS[category](params)
    posed = to_standard_pose(shapes.manifold_to_trimesh(solid))
    closed = closed_as_obj(posed.mesh)  # vertices nm apart: welded as the file would
    if closed is None:  # a generator defect: say so here, not at wrapping
        raise RuntimeError(f"{category}_{index:03d} (seed {seed}): the generated solid is "
                           f"not a closed surface once written as OBJ")
    posed = dataclasses.replace(posed, mesh=closed)
    return GeneratedObject(category, index, f"{category}_{index:03d}", params, posed)
