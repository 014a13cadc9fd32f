"""Every compiled (numba) kernel of the package, compiled ahead into numba's disk cache.

numba compiles one version of a kernel for each layout of its arguments (C or Fortran order,
read-only or writeable), 1-12 s of CPU each, in every new process that meets it first: the
workers of a first collection would each pay it at once. scripts/setup.sh calls
`compile_all` after each install or change of a module that imports numba, so that a run
loads every version from the cache (about 0.3 s a process); tests/test_kernels.py wraps,
poses the station, searches a bound and recognises after it, and finds no other layout.
"""

from __future__ import annotations

__all__ = ["compile_all"]


def compile_all() -> bool:
    """Compile (or load from the disk cache) every kernel for every layout a run passes, and
    say whether they are cached on disk. The kinematics kernels are compiled by calling them
    (their layouts follow from Drake's and numpy's arrays); the others, called with one
    layout only, by their signature."""
    from numba import types

    from .active import observation
    from .kinematics import compiled
    from .learning import projection
    from .wrapping import bound

    f1, f2, i1 = types.float64[::1], types.float64[:, ::1], types.int64[::1]
    cached = compiled.compile_kernels()  # proximity's too
    bound._terms_of_one.compile((f1, types.int64, types.float64, f1, f2, f1, types.float64,
                                 types.float64, types.UniTuple(types.float64, 4),
                                 types.UniTuple(types.boolean, 2)))
    projection._merge.compile((i1,) * 7)
    projection._project.compile((i1, i1, f1, f2, i1, f2, f2))
    i2, i3 = types.int64[:, ::1], types.int64[:, :, ::1]
    observation._first_successors.compile((i3, i2, types.int64[:, :, :, ::1], i3))
    return cached


if __name__ == "__main__":
    compile_all()
