"""Objects to wrap: procedural categories, import of real meshes, the dataset manifest,
placed copies.

The public names load on first use (exports.lazy_exports), so that `objects.mesh` loads
without manifold3d.
"""

from ..exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "generators": ("CATEGORIES", "CATEGORY_COUNTS", "GeneratedObject", "generate_object"),
    "dataset": ("Dataset", "DatasetError", "ObjectEntry", "generate_dataset", "load_manifest",
                "manifest_record", "select_objects", "write_manifest"),
    "importer": ("ImportReport", "import_folder", "import_mesh"),
    "mesh": ("MeshError", "load_mesh", "simplify_mesh"),
    "pose": ("PoseLimits", "obj_bytes"),
    "placement_kinds": ("KINDS", "PlacementError", "parse_counts"),
    "placement": ("Placement", "place", "place_dataset", "rest_poses"),
    "gallery": ("render_gallery",),
})
