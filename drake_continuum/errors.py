"""The project's exceptions: one base class for every error a user can fix (bad input,
settings, files), so the command line prints those as one line and keeps a traceback for
anything else, which is a bug."""

from __future__ import annotations

__all__ = ["DrakeContinuumError", "ConfigError", "InputError", "MissingFileError"]


class DrakeContinuumError(ValueError):
    """Base of every error the user can fix; a ValueError, so older callers still catch it."""


class ConfigError(DrakeContinuumError):
    """A setting of the configuration (file or --set) of the wrong type or out of range;
    the message names the key."""


class InputError(DrakeContinuumError):
    """Input that cannot be used (a file's contents, an argument); the message names it."""


class MissingFileError(DrakeContinuumError, FileNotFoundError):
    """A file or folder the user named does not exist (also a FileNotFoundError)."""
