"""Classification: reading wrap collections, the sklearn pipeline, evaluation over random
splits and the portable model file; accuracy on placed copies (placements)."""

from ..exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "params": ("ClassifierParams",),
    "records": ("ObjectRecord", "WrapDataWarning", "WrapFileError", "load_collection",
                "load_wraps", "object_record", "read_object_wraps"),
    "model": ("ChordModel", "Classification", "ModelFormatError", "classify", "classify_wraps",
              "load_model", "save_model", "train"),
    "evaluation": ("Evaluation", "evaluate", "evaluate_to_folder", "splits"),
    "placements": ("evaluate_placements", "placements_table"),
})
