"""From wraps to feature vectors: chord histograms and wrap descriptors (chords), and
[1]'s triangle histograms of an object's surface, the baseline (triangles)."""

from ..exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "chords": ("ChordFrame", "ChordHistogram", "ChordParams", "ChordSet", "HistogramEdges",
               "object_chords", "wrap_chords", "wrap_descriptors"),
    "triangles": ("sample_triangles", "triangle_parameters"),
})
