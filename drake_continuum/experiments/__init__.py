"""Experiments: collect every wrap of a dataset, reproduce the paper end to end, write
the report. The functions `collect` and `reproduce` share their modules' names, so they are
`experiments.collect.collect` and `experiments.reproduce.reproduce` (or the package root's)."""

from ..exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "collect": ("CollectLockError", "CollectParamsError", "CollectReport", "wrap_object"),
    "settings": ("PLACEMENTS", "QUICK_PLACEMENTS", "RunSettings", "run_command"),
    "report": ("write_report",),
    "results": ("write_results",),
    "observed": ("observed_study",),
    "timing": ("Work",),
})
