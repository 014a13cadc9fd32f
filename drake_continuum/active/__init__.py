"""Active recognition: the observation model, the posterior and Monte-Carlo tree search
that chooses the next wrap, the policies, and training/evaluation on wrap collections."""

from ..exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "params": ("ActiveParams",),
    "observation": ("ActiveModel", "ObservationModel"),
    "search": ("SearchResult", "TreeSearch"),
    "policies": ("POLICIES", "Recognition", "RecognitionStep", "evaluate_policies", "recognize",
                 "simulated_execute"),
    "training": ("evaluate_active", "load_active_model", "save_active_model", "train_active"),
})
