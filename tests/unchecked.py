"""Parameters past their range checks, for the tests that drive a failure path on purpose."""

import copy


def unchecked(params, **changes):
    """A copy of frozen parameters holding values their checks refuse (a tolerance that accepts
    any error, a start inside the object, a step beyond reach)."""
    new = copy.copy(params)
    for key, value in changes.items():
        object.__setattr__(new, key, value)
    return new
