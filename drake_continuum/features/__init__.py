"""From wraps to feature vectors: chord histograms and wrap descriptors (chords), and
[1]'s triangle histograms of an object's surface, the baseline (triangles)."""
