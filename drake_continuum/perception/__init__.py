"""The real robot: point clouds (loading, segmenting the arm, fitting its configuration,
comparing a real wrap with its simulation), the depth camera, free space, the fit's
confidence and locating an object on the table; a wrap observed through the camera
(observe) and a folder of captured wraps classified (captures)."""
