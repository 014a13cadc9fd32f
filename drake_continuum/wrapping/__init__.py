"""Wrapping an object: the Drake scene and its hydroelastic contacts (scene, contact), the
wrap planes (planes), Algorithm 1 (wrap, wrap_types) and how closely a wrap hugs (conformity)."""
