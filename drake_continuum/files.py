"""Atomic file writes and standard JSON: every file the project writes appears whole or not
at all (written beside its name, flushed to disk, then renamed), so a run killed at any
moment, or a machine that loses power, leaves the old file or the new one, never half of
one; and every JSON file or printout is standard JSON (no NaN or Infinity tokens)."""

from __future__ import annotations

import errno
import hashlib
import json
import math
import os
import signal
import stat
import tempfile
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import BinaryIO, Callable

import numpy as np

from .errors import InputError, MissingFileError

__all__ = ["NotWritableError", "writable_folder", "write_atomic", "write_scratch", "jsonable",
           "json_text", "number_text", "percent_text", "write_json", "model_digest",
           "array_shapes", "read_yaml", "parse_yaml", "read_json",
           "check_input_file", "regular_file", "plain_name", "separate_folders"]

_UMASK = os.umask(0)
os.umask(_UMASK)

_NOT_WRITABLE = (errno.EACCES, errno.EPERM, errno.EROFS)
_NO_SPACE = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


class NotWritableError(InputError):
    """An output folder cannot be written (the message names the folder)."""


def _not_writable(folder: Path, e: OSError) -> NotWritableError:
    return NotWritableError(f"{folder}: cannot write into this folder "
                            f"({e.strerror or e}); choose another output folder")


def writable_folder(folder) -> Path:
    """Create `folder` if needed and check that files can be made in it, before a long run
    starts; raises NotWritableError naming the folder."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-test.", suffix=".tmp", dir=folder)
    except OSError as e:
        if e.errno in _NOT_WRITABLE:
            raise _not_writable(folder, e) from None
        raise
    os.close(fd)
    os.unlink(probe)
    return folder


def write_scratch(path, data: bytes) -> Path:
    """Write `data` to a file in a private temporary folder that is read back at once and
    removed with its folder: a result file goes through write_atomic, a scratch copy needs
    neither its fsync nor its rename (about 15 ms a file on a busy disk)."""
    path = Path(path)
    path.write_bytes(data)
    return path


def write_atomic(path, data: bytes | Callable[[BinaryIO], None]) -> Path:
    """Write `data` (bytes, or a function writing to a binary file, e.g. np.savez or
    savefig) to a temporary file beside `path`, fsync it, rename it over `path`, then fsync
    the folder so that the rename itself survives a crash. Raises NotWritableError naming
    the folder if it cannot be written."""
    path = Path(path)
    # Ctrl-C is held from creating the temporary file until the clean-up below covers it: a
    # KeyboardInterrupt landing in between left the file behind (seen in an interrupted
    # dataset generation). A held Ctrl-C lands at the unblock, inside the try.
    held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except BaseException as e:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
        if isinstance(e, OSError) and e.errno in _NOT_WRITABLE:
            raise _not_writable(path.parent, e) from None
        raise
    try:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
        with os.fdopen(fd, "wb") as fh:
            if callable(data):
                data(fh)
            else:
                fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp's 0600 would differ from a plain open()
        os.replace(tmp, path)
    except BaseException as e:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(e, OSError) and e.errno in _NO_SPACE:
            raise NotWritableError(f"{path}: cannot be written ({e.strerror or e}); the file "
                                   f"there, if any, is unchanged; free some space and run "
                                   f"again") from None
        raise
    _fsync_folder(path.parent)
    return path


def _fsync_folder(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:  # some file systems cannot sync a directory; the rename still happened
        pass
    finally:
        os.close(fd)


def jsonable(obj):
    """`obj` with numpy scalars and arrays as plain values, tuples as lists, and every
    non-finite float (NaN, +-inf: not JSON) as None."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def json_text(obj, indent: int | None = 2, *, sort_keys: bool = False,
              compact: bool = False) -> str:
    """Standard JSON of `obj` (jsonable: NaN and infinities become null), the one way the
    project writes JSON, to files and to stdout; `compact`: no spaces after separators (a
    value on a command line)."""
    return json.dumps(jsonable(obj), indent=indent, allow_nan=False, sort_keys=sort_keys,
                      separators=(",", ":") if compact else None)


def number_text(x, fmt: str = "{:.0f}") -> str:
    """A number of a Markdown table: `fmt` of it, or "n/a" when it is missing (None, NaN)."""
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else fmt.format(x)


def percent_text(x) -> str:
    """A fraction of a Markdown table as a percentage to 0.1, or "n/a" when it is missing."""
    return number_text(None if x is None else 100 * x, "{:.1f} %")


def write_json(path, obj, indent: int | None = 2) -> Path:
    """`obj` as standard JSON (json_text), written atomically."""
    return write_atomic(path, (json_text(obj, indent) + "\n").encode())


def model_digest(arrays: dict, meta: dict) -> str:
    """SHA-256 of a saved model: its JSON entries `meta` (as standard JSON, keys sorted) and
    its named arrays (names, dtypes, shapes and bytes, in name order). Written with the model
    so that a file edited, damaged or mixed with another model's after saving is detected at
    load."""
    h = hashlib.sha256(json_text(meta, indent=None, sort_keys=True).encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def array_shapes(arrays: dict) -> dict:
    """name -> shape list of named arrays, as stored beside them in a model's JSON."""
    return {name: list(np.shape(arrays[name])) for name in sorted(arrays)}


def parse_yaml(text: str):
    """yaml.safe_load's tree, parsed by libyaml where PyYAML was built with it (about ten
    times faster; a configuration is read by every command and every worker)."""
    import yaml

    return yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))


def read_yaml(path, what: str):
    """Parse a YAML file; a missing or malformed file is an error naming `what` and the path."""
    import yaml

    path = Path(path)
    try:
        regular_file(path, InputError, what)
        return parse_yaml(path.read_text())
    except FileNotFoundError:
        raise MissingFileError(f"{what} {path}: file not found") from None
    except UnicodeDecodeError:
        raise InputError(f"{what} {path}: not a text file (not UTF-8); expected YAML") from None
    except yaml.YAMLError as e:
        raise InputError(f"{what} {path}: not valid YAML ({e})") from None


def read_json(path):
    """Parsed JSON, or None when the file is missing or unreadable: a collection's damaged
    file means "redo it", not an error."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


def regular_file(path, error=InputError, what: str = "") -> Path:
    """`path` if it is a regular file (after symbolic links), else `error` naming it: a FIFO
    would block the reader (holding whatever lock it took) and a device such as /dev/zero
    never ends, so both are refused before they are opened. A missing file is left to the
    caller's own message (FileNotFoundError)."""
    path = Path(path)
    mode = path.stat().st_mode
    if not stat.S_ISREG(mode):
        kind = ("a folder" if stat.S_ISDIR(mode) else "a FIFO (named pipe)" if
                stat.S_ISFIFO(mode) else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
                else "a special file")
        raise error(f"{what + ' ' if what else ''}{path}: is {kind}, not a regular file")
    return path


def check_input_file(path, suffixes, error, *, kind: str) -> Path:
    """The checks every input file gets before parsing: it exists, its extension is one of
    `suffixes`, it is not empty. Raises `error` with a message naming the file."""
    path = Path(path)
    if not path.exists():
        raise error(f"{path}: file not found")
    regular_file(path, error)
    if path.suffix.lower() not in suffixes:
        raise error(f"{path}: unknown {kind} extension {path.suffix!r} "
                    f"(expected one of {', '.join(suffixes)})")
    if path.stat().st_size == 0:
        raise error(f"{path}: file is empty")
    return path


def plain_name(name, what: str, error=InputError) -> str:
    """`name` if it is one plain file name: a single path component on any system (no folder
    separator, not '.', '..', empty, absolute or a drive), without NUL. A name read from a
    file (an object id, a mesh file) then addresses only a file inside its folder. Else
    raises `error` naming `what`."""
    text = str(name)
    if (text in ("", ".", "..") or "\0" in text or PurePosixPath(text).name != text
            or PureWindowsPath(text).name != text):
        raise error(f"{what}: {text!r} is not a plain file name (one path component); "
                    f"refused, as it could address a file outside its folder")
    return text


def separate_folders(out, source, what: str, *, error=InputError) -> None:
    """Refuse an output folder `out` that is the input folder `source` or lies inside it:
    writing there would replace or mix with the input. `what` names the output option."""
    out_r, src_r = Path(out).resolve(), Path(source).resolve()
    if out_r == src_r or src_r in out_r.parents:
        raise error(f"{what} {out}: is the input folder {source} or inside it; writing there "
                    f"would overwrite or mix with the input; choose another folder")
