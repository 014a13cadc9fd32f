"""The sample clouds: simulated depth-camera clouds of wraps (`<name>.pcd`), each with its
sidecar (`<name>.json`: base pose, true configuration, camera, the object's mesh file) and the
object meshes. They live in real/data of the checkout and are installed inside the package as
`drake_continuum.clouds`, read with importlib.resources (perception.cloud.SAMPLE_CLOUDS)."""
