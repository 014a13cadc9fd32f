""".npz archives read in one pass over their bytes, giving the arrays np.load gives.

np.load opens each member through ZipFile.open twice and parses each .npy header with
ast.literal_eval: about 40 us an array, 11 s CPU for the 266,000 small arrays of a full
reproduction's wrap collections (7 us here). Here each stored member's bytes are sliced from
the archive's bytes behind its local header (its name and CRC-32 checked, as ZipFile checks
them), and each distinct header is parsed once by numpy's own header reader (489 distinct
among those 266,000). Every array is a fresh, aligned, writeable copy of the same dtype,
shape and memory order as np.load's, so compiled kernels see the layouts they were compiled
for. Compressed members (np.savez_compressed) are inflated by zipfile.
"""

from __future__ import annotations

import functools
import io
import math
import struct
import zipfile
import zlib

import numpy as np
from numpy.lib import format as npy_format

__all__ = ["npz_arrays"]

_LOCAL_HEADER = struct.Struct("<4s2B4HL2L2H")  # zipfile's local file header
_LOCAL_MAGIC = b"PK\x03\x04"
_NAME_LENGTH, _EXTRA_LENGTH = 10, 11  # their fields in _LOCAL_HEADER
_ENCRYPTED, _UTF8_NAME = 0x1, 0x800  # general purpose flag bits
_NPY_PREFIX = len(npy_format.MAGIC_PREFIX) + 2  # magic string and version bytes
_LENGTH_SIZE = {(1, 0): 2, (2, 0): 4}  # bytes of the header's length, by .npy version


def npz_arrays(data: bytes) -> dict[str, np.ndarray]:
    """name -> array of every member of the .npz archive `data` (names without ".npy"), as
    np.load(..., allow_pickle=False) reads them. Raises zipfile.BadZipFile for a damaged
    archive or member (as zipfile does), ValueError for a member that is not an .npy array
    or is damaged inside, an object array, or two members of one name."""
    view = memoryview(data)
    out = {}
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        for info in archive.infolist():
            name = info.filename.removesuffix(".npy")
            if name in out:
                raise ValueError(f"two members named {name!r}")
            member = (_stored_member(info, view) if info.compress_type == zipfile.ZIP_STORED
                      else _inflated_member(archive, info))
            try:
                out[name] = npy_array(member)
            except ValueError as e:
                raise ValueError(f"member {info.filename!r}: {e}") from None
    return out


def _inflated_member(archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> bytes:
    """The bytes of a compressed member, read by zipfile; damaged deflate data (zlib.error,
    or EOFError for a cut stream) is a BadZipFile naming the member, as a stored one's is."""
    try:
        return archive.read(info)
    except (zlib.error, EOFError) as e:
        raise zipfile.BadZipFile(f"member {info.filename!r}: {type(e).__name__}: {e}") from None


def _stored_member(info: zipfile.ZipInfo, view: memoryview) -> memoryview:
    """The bytes of an uncompressed member, checked as ZipFile.open and its reader check
    them: local header signature, the same name, the whole length, the CRC-32."""
    if info.flag_bits & _ENCRYPTED:
        raise ValueError(f"member {info.filename!r} is encrypted")
    at = info.header_offset
    head = view[at:at + _LOCAL_HEADER.size]
    if len(head) < _LOCAL_HEADER.size:
        raise zipfile.BadZipFile(f"member {info.filename!r}: truncated file header")
    fields = _LOCAL_HEADER.unpack(head)
    if fields[0] != _LOCAL_MAGIC:
        raise zipfile.BadZipFile(f"member {info.filename!r}: bad magic number for file "
                                 f"header")
    start = at + _LOCAL_HEADER.size
    raw_name = bytes(view[start:start + fields[_NAME_LENGTH]])
    name = raw_name.decode("utf-8" if info.flag_bits & _UTF8_NAME else "cp437")
    if name != info.orig_filename:
        raise zipfile.BadZipFile(f"file name in directory {info.orig_filename!r} and header "
                                 f"{name!r} differ")
    start += fields[_NAME_LENGTH] + fields[_EXTRA_LENGTH]
    member = view[start:start + info.compress_size]
    if len(member) != info.compress_size or info.file_size != info.compress_size:
        raise zipfile.BadZipFile(f"member {info.filename!r}: truncated ({len(member)} of "
                                 f"{info.file_size} bytes)")
    if zlib.crc32(member) != info.CRC:
        raise zipfile.BadZipFile(f"bad CRC-32 for member {info.filename!r}")
    return member


def npy_array(member) -> np.ndarray:
    """The array of one .npy file's bytes, as numpy.lib.format.read_array reads it without
    pickles (ValueError for anything it refuses)."""
    if (len(member) < _NPY_PREFIX
            or bytes(member[:len(npy_format.MAGIC_PREFIX)]) != npy_format.MAGIC_PREFIX):
        raise ValueError("not an .npy array (no .npy magic string)")
    version = (member[_NPY_PREFIX - 2], member[_NPY_PREFIX - 1])
    if version not in _LENGTH_SIZE:
        raise ValueError(f".npy format version {version[0]}.{version[1]} is not read here "
                         f"(np.savez writes 1.0, or 2.0 for a large header)")
    length_size = _LENGTH_SIZE[version]
    if len(member) < _NPY_PREFIX + length_size:
        raise ValueError("truncated .npy header")
    header_length = int.from_bytes(member[_NPY_PREFIX:_NPY_PREFIX + length_size], "little")
    data_start = _NPY_PREFIX + length_size + header_length
    if len(member) < data_start:
        raise ValueError("truncated .npy header")
    shape, fortran_order, dtype = _header(bytes(member[:data_start]))
    count = math.prod(shape)
    size = count * dtype.itemsize
    if len(member) - data_start < size:
        raise ValueError(f"EOF: reading array data, expected {size} bytes got "
                         f"{len(member) - data_start}")
    array = (np.frombuffer(member, dtype=dtype, count=count, offset=data_start).copy()
             if size else np.ndarray(count, dtype=dtype))
    return array.reshape(shape[::-1]).transpose() if fortran_order else array.reshape(shape)


@functools.lru_cache(maxsize=8192)
def _header(prefix: bytes) -> tuple[tuple, bool, np.dtype]:
    """(shape, fortran_order, dtype) of an .npy file's magic string, version (1.0 or 2.0)
    and header, by numpy's own reader (its checks included), once for each distinct
    header."""
    fp = io.BytesIO(prefix)
    read = (npy_format.read_array_header_1_0 if npy_format.read_magic(fp) == (1, 0)
            else npy_format.read_array_header_2_0)
    shape, fortran_order, dtype = read(fp)
    if dtype.hasobject:
        raise ValueError("Object arrays cannot be loaded when allow_pickle=False")
    return shape, fortran_order, dtype
