"""npz.npz_arrays against numpy's own reader (np.load): the same names, dtypes, shapes, bytes,
memory order and flags for every kind of array a writer may store, stored or compressed;
and a damaged archive or member refused (zipfile.BadZipFile or ValueError, naming the
member)."""

import io
import struct
import zipfile

import numpy as np
import pytest

from drake_continuum.npz import npz_arrays


def _every_kind():
    rng = np.random.default_rng(3)
    return {"floats": rng.normal(size=(7, 3)), "status": np.array("complete"),
            "empty": np.zeros(0), "empty_rows": np.zeros((0, 3)),
            "fortran": np.asfortranarray(rng.normal(size=(4, 5))),
            "ints": np.arange(9, dtype=np.int64), "flags": np.array([True, False, True]),
            "big_endian": rng.normal(size=(2, 3)).astype(">f4"),
            "scalar": np.array(2.5), "nan": np.array([np.nan, -np.inf]),
            "wide": rng.normal(size=(3, 2, 2)), "text": np.array(["a", "bcd"]),
            "complex": rng.normal(size=3) + 1j, "large": rng.normal(size=70_000)}


def _archive(arrays, write=np.savez) -> bytes:
    buf = io.BytesIO()
    write(buf, **arrays)
    return buf.getvalue()


def _numpy_reads(data: bytes) -> dict:
    with np.load(io.BytesIO(data), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _assert_as_numpy(got: dict, expected: dict) -> None:
    assert list(got) == list(expected)
    for k, e in expected.items():
        g = got[k]
        assert type(g) is np.ndarray and g.dtype == e.dtype and g.shape == e.shape, k
        assert g.tobytes(order="A") == e.tobytes(order="A"), k  # bit for bit, NaN included
        assert g.strides == e.strides, k
        for flag in ("C_CONTIGUOUS", "F_CONTIGUOUS", "WRITEABLE", "ALIGNED", "OWNDATA"):
            assert g.flags[flag] == e.flags[flag], (k, flag)


@pytest.mark.parametrize("write", [np.savez, np.savez_compressed])
def test_every_kind_of_array_reads_as_numpy_reads_it(write):
    data = _archive(_every_kind(), write)
    _assert_as_numpy(npz_arrays(data), _numpy_reads(data))


def test_arrays_are_their_own_copies():
    """Writeable and not sharing the archive's bytes: writing into one changes nothing else."""
    data = _archive({"a": np.zeros(4), "b": np.zeros(4)})
    got = npz_arrays(data)
    got["a"][:] = 1.0
    assert np.all(got["b"] == 0.0) and np.all(npz_arrays(data)["a"] == 0.0)


def _member_offset(data: bytes, name: str) -> tuple[int, int]:
    """(offset of the .npy bytes of member `name` in the archive, their length)."""
    info = zipfile.ZipFile(io.BytesIO(data)).getinfo(name)
    fields = struct.unpack("<4s2B4HL2L2H", data[info.header_offset:info.header_offset + 30])
    return info.header_offset + 30 + fields[10] + fields[11], info.compress_size


def _damaged(data: bytes, at: int, new: bytes) -> bytes:
    return data[:at] + new + data[at + len(new):]


def test_a_damaged_member_is_refused():
    data = _archive({"a": np.arange(40.0), "b": np.ones(3)})
    at, size = _member_offset(data, "a.npy")
    one_bit = _damaged(data, at + size - 3, bytes([data[at + size - 3] ^ 1]))
    with pytest.raises(zipfile.BadZipFile, match="CRC-32.*a.npy"):
        npz_arrays(one_bit)
    with pytest.raises(zipfile.BadZipFile):
        npz_arrays(data[:at + size // 2])  # cut inside the member


def test_a_damaged_compressed_member_is_refused_naming_it():
    """Inflating is zipfile's: damaged deflate data raises zlib.error or EOFError there,
    which npz_arrays gives as the BadZipFile a damaged stored member gives."""
    data = _archive({"a": np.arange(4000.0) % 7}, np.savez_compressed)
    at, _ = _member_offset(data, "a.npy")
    garbled = _damaged(data, at, bytes(b ^ 0xFF for b in data[at:at + 16]))
    with pytest.raises(zipfile.BadZipFile, match="member 'a.npy': error: .*decompressing"):
        npz_arrays(garbled)


def _with_member(name: str, member: bytes) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("ok.npy", _npy(np.ones(2)))
        z.writestr(name, member)
    return buf.getvalue()


def _npy(array) -> bytes:
    buf = io.BytesIO()
    np.save(buf, array)
    return buf.getvalue()


@pytest.mark.parametrize("member, message", [
    (_npy(np.arange(10.0))[:-8], "EOF: reading array data, expected 80 bytes got 72"),
    (_npy(np.arange(10.0)).replace(b"'descr': '<f8'", b"'descr': 'x8'"), "descr"),
    (_npy(np.arange(10.0)).replace(b"'shape': (10,)", b"'shape': 10   "), "shape"),
    (_npy(np.arange(10.0)).replace(b"{'descr'", b"['descr'"), "header"),
    (b"\x93NUMPY\x03\x00" + _npy(np.arange(3.0))[8:], "version 3.0"),
    (b"not an array at all", "not an .npy array"),
    (_npy(np.arange(3.0))[:9], "truncated .npy header"),
    (_npy(np.array([{}], dtype=object), ), "Object arrays"),
])
def test_a_wrong_npy_header_or_body_is_refused_naming_the_member(member, message):
    data = _with_member("bad.npy", member)
    with pytest.raises(ValueError, match=rf"member 'bad.npy': .*{message}"):
        npz_arrays(data)


def test_a_member_whose_header_names_another_file_is_refused():
    data = _archive({"aa": np.ones(2), "bb": np.ones(2)})
    at, _ = _member_offset(data, "bb.npy")
    swapped = data.replace(b"bb.npy", b"cc.npy", 1)  # the local header's name only
    assert swapped.index(b"cc.npy") < at
    with pytest.raises(zipfile.BadZipFile, match="'bb.npy' and header 'cc.npy' differ"):
        npz_arrays(swapped)


def test_not_an_archive_is_refused():
    with pytest.raises(zipfile.BadZipFile):
        npz_arrays(b"not an archive")


def test_a_version_2_header_reads_as_numpy_reads_it():
    """np.save writes .npy version 2.0 for a header over 65,535 bytes."""
    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.arange(6.0).reshape(2, 3), version=(2, 0))
    data = _with_member("v2.npy", buf.getvalue())
    _assert_as_numpy(npz_arrays(data), _numpy_reads(data))
