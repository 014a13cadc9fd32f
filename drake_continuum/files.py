"""Atomic file writes: every file the project writes appears whole or not at all, so a run
killed at any moment leaves no half-written file under a real name."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import BinaryIO, Callable

from .errors import InputError, MissingFileError

__all__ = ["write_atomic", "read_yaml", "check_input_file"]

_UMASK = os.umask(0)
os.umask(_UMASK)


def write_atomic(path, data: bytes | Callable[[BinaryIO], None]) -> Path:
    """Write `data` (bytes, or a function writing to a binary file, e.g. np.savez or
    savefig) to a temporary file beside `path`, then rename it over `path`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            if callable(data):
                data(fh)
            else:
                fh.write(data)
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp's 0600 would differ from a plain open()
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def read_yaml(path, what: str):
    """Parse a YAML file; a missing or malformed file is an error naming `what` and the path."""
    import yaml

    path = Path(path)
    try:
        return yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise MissingFileError(f"{what} {path}: file not found") from None
    except yaml.YAMLError as e:
        raise InputError(f"{what} {path}: not valid YAML ({e})") from None


def check_input_file(path, suffixes, error, kind: str) -> Path:
    """The checks every input file gets before parsing: it exists, its extension is one of
    `suffixes`, it is not empty. Raises `error` with a message naming the file."""
    path = Path(path)
    if not path.exists():
        raise error(f"{path}: file not found")
    if path.suffix.lower() not in suffixes:
        raise error(f"{path}: unknown {kind} extension {path.suffix!r} "
                    f"(expected one of {', '.join(suffixes)})")
    if path.stat().st_size == 0:
        raise error(f"{path}: file is empty")
    return path
