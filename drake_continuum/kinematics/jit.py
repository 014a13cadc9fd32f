"""numba's disk cache, decided once for every compiled module of the package (compiled,
proximity): beside the package or in the user's cache folder, else in a private folder under the
temporary folder, else none (compiled.py's docstring says why)."""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

import numba
from numba import njit

__all__ = ["CACHE", "cached", "private_cache_folder"]


def private_cache_folder() -> str | None:
    """A folder under the temporary folder that only this user can write (created 0700, or
    found owned by the user and closed to others: a folder someone else planted there could
    hold compiled code), else None."""
    folder = Path(tempfile.gettempdir()) / f"drake-continuum-numba-{os.getuid()}"
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        info = folder.lstat()
    except OSError:
        return None
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid() or info.st_mode & 0o077:
        return None
    return str(folder)


def cached(function):
    """(`function` compiled, whether with numba's disk cache): the cache beside this file or
    in the user's cache folder, else in private_cache_folder(), else none. numba raises
    "cannot cache function ...: no locator available" when it can write neither."""
    try:
        return njit(cache=True)(function), True
    except RuntimeError:
        numba.config.CACHE_DIR = private_cache_folder() or ""
    if numba.config.CACHE_DIR:
        try:
            return njit(cache=True)(function), True
        except RuntimeError:
            pass
    return njit(function), False


def _probe(x):
    return x


_, CACHE = cached(_probe)  # whether kernels are cached on disk, decided at import
