"""Mitsuba 3's ``tensor_file`` container (the RGL ``.bsdf`` files' format), read into
``{name: array}``, every size checked against the file before anything is allocated::

    "tensor_file\\0"  u8 major = 1  u8 minor = 0  u32 field_count
    field_count times: u16 name_len, name, u16 ndim, u8 dtype, u64 offset, ndim x u64 shape
    the field data, each at its offset, C order
"""

from __future__ import annotations

import os
import struct
from typing import Dict, List, Tuple

import numpy as np

from hybridbrdf.inputs import read_input_bytes
from hybridbrdf.sources.base import BRDFFormatError

#: The 12 bytes every tensor_file starts with.
TENSOR_MAGIC = b"tensor_file\x00"
#: The container version this reader understands (header bytes major, minor).
TENSOR_VERSION = (1, 0)

# Mitsuba's Struct type codes as written into tensor files.
_DTYPES = {
    1: np.dtype("<u1"),
    2: np.dtype("<i1"),
    3: np.dtype("<u2"),
    4: np.dtype("<i2"),
    5: np.dtype("<u4"),
    6: np.dtype("<i4"),
    7: np.dtype("<u8"),
    8: np.dtype("<i8"),
    9: np.dtype("<f2"),
    10: np.dtype("<f4"),
    11: np.dtype("<f8"),
}

_F32 = np.dtype("<f4")
_U8 = np.dtype("<u1")
_U32 = np.dtype("<u4")


#: Largest field rank the reader takes (RGL's tables have rank 4 or 5; numpy allows 64).
_MAX_RANK = 8
#: Largest .bsdf file read (bytes): the published RGL files are 0.6-1.1 MB; this leaves room for
#: far finer tables, and keeps a sparse or endless file from filling memory.
MAX_FILE_BYTES = 256 << 20
#: Longest field name quoted in an error message.
_MAX_NAME_CHARS = 40


def read_tensor_file(path) -> Dict[str, np.ndarray]:
    """Read a Mitsuba ``tensor_file`` into ``{name: array}`` (arrays are copies,
    in the file's dtype and shape).

    Raises :class:`BRDFFormatError` naming the file for an unreadable or
    truncated file, a wrong magic or version, an unknown dtype code, a
    duplicate field or a field whose data lie outside the file."""
    path = os.fspath(path)
    cursor = _Cursor(path, read_input_bytes(path, ".bsdf file", MAX_FILE_BYTES, BRDFFormatError))
    _read_preamble(cursor)
    headers = _read_field_headers(cursor)
    return {name: _read_field_data(cursor, name, dtype, shape, offset) for name, dtype, shape, offset in headers}


class _Cursor:
    """A position in a tensor_file's bytes; reading past the end is a "truncated file" error."""

    def __init__(self, path: str, buf: bytes):
        self.path, self.buf, self.size, self.pos = path, buf, len(buf), 0

    def fail(self, problem: str):
        raise BRDFFormatError(self.path, problem)

    def check_room(self, need: int, what: str):
        if self.pos + need > self.size:
            self.fail(f"truncated file: {what} needs bytes {self.pos}..{self.pos + need} but the file has "
                      f"{self.size} bytes")

    def take(self, fmt: str, what: str) -> tuple:
        """Unpack ``fmt`` at the cursor and advance."""
        need = struct.calcsize(fmt)
        self.check_room(need, what)
        vals = struct.unpack_from(fmt, self.buf, self.pos)
        self.pos += need
        return vals


def _read_preamble(cursor: _Cursor) -> None:
    """The magic and the container version; leaves the cursor at the field count."""
    buf, size = cursor.buf, cursor.size
    if size < len(TENSOR_MAGIC):
        if TENSOR_MAGIC.startswith(buf):
            cursor.fail(f"truncated file: {size} bytes, shorter than the tensor_file header")
        cursor.fail(f"not a tensor_file (.bsdf): the file starts with {buf[:12]!r}")
    if buf[: len(TENSOR_MAGIC)] != TENSOR_MAGIC:
        cursor.fail(f"not a tensor_file (.bsdf): wrong magic {buf[:12]!r}, expected {TENSOR_MAGIC!r}")
    cursor.pos = len(TENSOR_MAGIC)
    version = cursor.take("<BB", "the container version")
    if tuple(version) != TENSOR_VERSION:
        cursor.fail(f"unsupported tensor_file version {version[0]}.{version[1]} (this reader reads 1.0)")


def _read_field_headers(cursor: _Cursor) -> List[Tuple[str, np.dtype, Tuple[int, ...], int]]:
    """(name, dtype, shape, offset) of each field, in file order; names distinct."""
    (count,) = cursor.take("<I", "the field count")
    headers: List[Tuple[str, np.dtype, Tuple[int, ...], int]] = []
    seen = set()
    for k in range(count):
        name = _read_field_name(cursor, k)
        (ndim,) = cursor.take("<H", f"the rank of field {name!r}")
        if ndim > _MAX_RANK:
            cursor.fail(f"field {name!r} has rank {ndim}; RGL fields have at most {_MAX_RANK}")
        code, offset = cursor.take("<BQ", f"the dtype and offset of field {name!r}")
        shape = cursor.take("<" + "Q" * ndim, f"the shape of field {name!r}")
        if code not in _DTYPES:
            cursor.fail(f"field {name!r} has unknown dtype code {code} (expected 1..11)")
        if name in seen:
            cursor.fail(f"field {name!r} appears twice")
        seen.add(name)
        headers.append((name, _DTYPES[code], shape, offset))
    return headers


def _read_field_name(cursor: _Cursor, k: int) -> str:
    """Field #k's name (UTF-8), cut to _MAX_NAME_CHARS for messages."""
    (name_len,) = cursor.take("<H", f"the name length of field #{k}")
    cursor.check_room(name_len, f"the name of field #{k}")
    raw = cursor.buf[cursor.pos: cursor.pos + name_len]
    try:
        name = raw.decode("utf-8")
    except UnicodeDecodeError:
        name = None
    if name is None:
        cursor.fail(f"field #{k} has a name that is not UTF-8: {raw[:_MAX_NAME_CHARS]!r}")
    cursor.pos += name_len
    if len(name) > _MAX_NAME_CHARS:  # RGL's names are a few letters; keep messages short
        name = name[:_MAX_NAME_CHARS] + "..."
    return name


def _read_field_data(cursor: _Cursor, name: str, dtype: np.dtype, shape: Tuple[int, ...], offset: int) -> np.ndarray:
    """A copy of one field's data, which must lie inside the file."""
    count_items = 1
    for s in shape:
        count_items *= s  # Python ints: a corrupt shape cannot overflow
    nbytes = count_items * dtype.itemsize
    # (a huge extent beside a 0 is damage too)
    if offset + nbytes > cursor.size or max(shape, default=0) > cursor.size:
        cursor.fail(f"truncated file: field {name!r} {dtype.name}{list(shape)} needs bytes "
                    f"{offset}..{offset + nbytes} but the file has {cursor.size} bytes")
    arr = np.frombuffer(cursor.buf, dtype=dtype, count=count_items, offset=offset)
    return arr.reshape(shape).copy()
