"""The project's model descriptions: the arm (arm.yaml), the experiment configuration
(config.yaml), the standard object pose and the demo mug. They live at the top of the
checkout and are installed inside the package as `drake_continuum.models`; code finds them
with `importlib.resources` (drake_continuum.resources), so an installed wheel has them too."""
