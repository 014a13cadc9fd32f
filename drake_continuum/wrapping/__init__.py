"""Wrapping an object: the Drake scene and its hydroelastic contacts (scene, contact, and
the capsules proven apart before Drake is asked: apart), the wrap planes (planes), where a
wrap starts (start), Algorithm 1 (wrap, wrap_types), how closely a wrap hugs (conformity)
and how closely any in-plane configuration of the arm can (bound)."""
