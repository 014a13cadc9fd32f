"""Reading a wrap collection (learning.records) against a second reading by numpy's own
.npz reader: the same WrapResults and ObjectRecords to the bit, stored or compressed
archives alike; a damaged archive is a WrapFileError naming its file."""

import dataclasses
import io
import re
import struct
import zipfile

import numpy as np
import pytest

from drake_continuum.learning.records import (
    WrapFileError,
    load_collection,
    object_record,
    read_object_wraps,
)
from drake_continuum.wrapping.wrap_types import WrapResult
from synthetic_wraps import separable_objects, write_collection


def numpy_wraps(folder, object_id: str, n_wraps: int) -> list[WrapResult]:
    """An object's wraps read with np.load: the second implementation."""
    with np.load(folder / f"{object_id}.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    return [WrapResult.from_arrays(arrays, f"w{k}_") for k in range(n_wraps)]


def assert_same_arrays(a, b, what: str) -> None:
    """Equal dtype, shape, bytes (NaN included) and the layout flags compiled kernels see."""
    assert a.dtype == b.dtype and a.shape == b.shape, what
    assert a.tobytes(order="A") == b.tobytes(order="A"), what
    for flag in ("C_CONTIGUOUS", "F_CONTIGUOUS", "WRITEABLE", "ALIGNED"):
        assert a.flags[flag] == b.flags[flag], (what, flag)


def assert_same_value(a, b, what: str) -> None:
    """Every field of two dataclasses (WrapResult, ObjectRecord, ChordSet) equal to the bit."""
    if isinstance(a, np.ndarray):
        assert_same_arrays(a, b, what)
    elif dataclasses.is_dataclass(a):
        assert type(a) is type(b), what
        for f in dataclasses.fields(a):
            assert_same_value(getattr(a, f.name), getattr(b, f.name), f"{what}.{f.name}")
    elif isinstance(a, float) and np.isnan(a):
        assert isinstance(b, float) and np.isnan(b), what
    else:
        assert type(a) is type(b) and a == b, what


@pytest.fixture(scope="module")
def objects():
    return separable_objects(2, 3)


@pytest.mark.parametrize("compressed", [False, True])
def test_a_collection_reads_as_numpy_reads_it(objects, tmp_path, compressed):
    write_collection(tmp_path, objects)
    if compressed:  # the same arrays through np.savez_compressed
        for object_id, _, _ in objects:
            path = tmp_path / f"{object_id}.npz"
            with np.load(path) as z:
                arrays = {k: z[k] for k in z.files}
            np.savez_compressed(path, **arrays)
    records, skipped = load_collection(tmp_path)
    assert not skipped and [r.object_id for r in records] == [o[0] for o in objects]
    for (object_id, category, written), record in zip(objects, records):
        _, wraps = read_object_wraps(tmp_path, object_id)
        expected = numpy_wraps(tmp_path, object_id, len(written))
        for k, (got, want) in enumerate(zip(wraps, expected, strict=True)):
            assert_same_value(got, want, f"{object_id} wrap {k}")
        assert_same_value(record, object_record(object_id, category, expected,
                                                side="generated"), object_id)


def _rewritten(path, name: str, change) -> None:
    """Write `path` again as a valid archive (CRCs right) with member `name`'s bytes
    changed: the damage is inside the .npy, where only its own checks see it."""
    with zipfile.ZipFile(path) as z:
        members = {i.filename: z.read(i) for i in z.infolist()}
    members[name] = change(members[name])
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for n, data in members.items():
            z.writestr(n, data)
    path.write_bytes(buf.getvalue())


@pytest.mark.parametrize("change, message", [
    (lambda b: b[:-8], r"ValueError: member 'w0_configs.npy': EOF: reading array data"),
    (lambda b: b.replace(b"'descr': '<f8'", b"'descr': '<x8'"),
     r"ValueError: member 'w0_configs.npy': .*descr"),
    (lambda b: b"\x93NUMPY\x07\x00" + b[8:],
     r"ValueError: member 'w0_configs.npy': .npy format version 7\.0"),
])
def test_a_damaged_member_is_a_wrap_file_error_naming_the_file(objects, tmp_path, change,
                                                                 message):
    write_collection(tmp_path, objects)
    damaged = tmp_path / f"{objects[1][0]}.npz"
    _rewritten(damaged, "w0_configs.npy", change)
    with pytest.raises(WrapFileError, match=rf"^{re.escape(str(damaged))}: {message}"):
        read_object_wraps(tmp_path, objects[1][0])
    records, skipped = load_collection(tmp_path)
    assert [s["object_id"] for s in skipped] == [objects[1][0]]
    assert skipped[0]["reason"].startswith(f"{damaged}: ")
    assert len(records) == len(objects) - 1


def test_a_flipped_bit_is_a_wrap_file_error_naming_the_file(objects, tmp_path):
    """Without a recorded SHA-256 (write_collection records none) the member's CRC-32
    finds it, as zipfile's reader does."""
    write_collection(tmp_path, objects)
    damaged = tmp_path / f"{objects[0][0]}.npz"
    data = bytearray(damaged.read_bytes())
    info = zipfile.ZipFile(damaged).getinfo("w0_samples_position.npy")
    at = info.header_offset  # its local header: 30 bytes, then the name and extra field
    name_length, extra_length = struct.unpack("<2H", data[at + 26:at + 30])
    data[at + 30 + name_length + extra_length + info.file_size - 5] ^= 0x10  # a number's bit
    damaged.write_bytes(bytes(data))
    with pytest.raises(WrapFileError, match=rf"^{re.escape(str(damaged))}: BadZipFile: bad CRC-32"):
        read_object_wraps(tmp_path, objects[0][0])
