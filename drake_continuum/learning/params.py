"""The chord classifier's settings (ClassifierParams: models/config.yaml, section
classifier), apart from the pipeline that reads them so the configuration loads without it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..checks import FieldError, between, check_fields, count
from ..features.chords import TIE_WIDTH, HistogramEdges

__all__ = ["VARIANCE_KEPT", "ClassifierParams"]

VARIANCE_KEPT = 0.95  # the paper's PCA


@dataclass(frozen=True)
class ClassifierParams:
    """The chord classifier's settings (models/config.yaml, section classifier; what each
    is worth: BENCHMARKS.md, Classification and Placements).

    Args:
        bins: histogram bins a dimension (the paper's 7).
        edges: "quantile" (equal-frequency bins learned on the training split) or "uniform"
            (the paper's reading).
        power: exponent of the normalised histogram; 0.5 is the Hellinger map, 1 none.
        variance: PCA variance kept (the paper's 95 %).
        svm_c: the linear SVM's C (default 3): against 10, a prediction flips under a
            1 mm / 1 deg nudge a quarter less often for 0.2 points as generated (measured:
            BENCHMARKS.md, Decisions).
        coarse: bins a dimension of the nested coarse histogram appended to the 7-D one
            (0: none).
        tie_width: how far the quantile edges keep off a value many chords share (the
            horizontal chords of wraps in horizontal planes), m or rad: 1 mrad for
            simulated wraps; about 3 mrad for wraps fitted to a depth camera's cloud, which
            tilt such chords by 1-2 mrad (measured: BENCHMARKS.md, Point clouds).
        wrap_weight: weight of the per-plane wrap descriptors against the histograms (0:
            none).
        extent_weight: weight of the contact extent block (0: none).
        view_weight: weight of the camera's view block (0: none; without a view in the
            training objects there is none either).
        turn_invariant: wrap descriptors pooled over planes and the contact extent's
            horizontal ranges along the contacts' own axes, so that they do not change when
            the object is turned about the vertical (ObjectFeatures). It helps turned
            objects and costs accuracy on objects as generated, so it is off by default
            (measured: BENCHMARKS.md, Decisions).
        rest_classes: a category's training objects on another side (ObjectRecord.side
            "other") form a class of their own, whose probability counts for the category
            (module docstring; chords only). Off, they share their category's class.
        standing_model: with rest classes learnt, a second model learns the training
            objects standing as generated only, and a prediction mixes the two by the
            first's probability that the object lies on another side (SideMixture), so
            lying copies in training do not pull standing objects' boundaries (a standing
            banana read as a lying bottle; measured: BENCHMARKS.md, Placements).
    """

    bins: int = 7
    edges: HistogramEdges = HistogramEdges.QUANTILE
    power: float = 0.5
    variance: float = VARIANCE_KEPT
    svm_c: float = 3.0
    coarse: int = 0
    tie_width: float = TIE_WIDTH
    wrap_weight: float = 0.4
    extent_weight: float = 0.8
    view_weight: float = 1.0
    turn_invariant: bool = False
    rest_classes: bool = True
    standing_model: bool = True

    def __post_init__(self):
        weight = between(0, 1e3, open_low=False)
        check_fields(self, bins=count(100), power=between(0, 1), variance=between(0, 1),
                     svm_c=between(0, 1e6), coarse=count(100, lo=0),
                     tie_width=between(0, 0.1, open_low=False), wrap_weight=weight,
                     extent_weight=weight, view_weight=weight)
        if self.coarse > self.bins:
            raise FieldError(type(self).__name__, "coarse", f"must be at most bins "
                             f"({self.bins}), got {self.coarse}")

    def touch_only(self) -> "ClassifierParams":
        """These settings without the blocks that need the object visible (BLOCKS): the
        classifier of a transparent object."""
        return replace(self, view_weight=0.0)
