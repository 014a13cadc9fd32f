"""Objects to wrap: procedural categories, import of real meshes, the dataset manifest.

Import from the submodules (generators, dataset, importer, pose, mesh, gallery); this
package file stays empty of imports so that `objects.mesh` loads without manifold3d.
"""
