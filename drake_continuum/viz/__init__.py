"""Pictures of wraps: Meshcat scenes and pages (meshcat), matplotlib figures (plots)."""

from ..exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "meshcat": ("animate", "make_meshcat", "save_html", "show_wrap"),
    "plots": ("plot_object_wraps", "plot_wrap", "plot_wraps_grid", "wrap_figure",
              "wrap_gallery"),
})
