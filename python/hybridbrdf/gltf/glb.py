"""The GLB container (glTF 2.0, "Binary glTF Layout"), its bounds, and the reader's error.

    header   magic 0x46546C67 ("glTF"), version 2, length (the whole file), little-endian uint32s
    chunk    chunkLength, chunkType, data padded to 4 bytes; the first is JSON (0x4E4F534A), the
             optional second BIN (0x004E4942); chunks of other types are skipped

Every size is checked against the bytes present before anything is sliced or allocated.
"""

from __future__ import annotations

import struct
from typing import List, Optional, Tuple

from hybridbrdf.errors import InputFileError
from hybridbrdf.inputs import check_input_file, read_input_bytes

GLB_MAGIC = 0x46546C67
GLB_VERSION = 2
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942
HEADER_BYTES = 12
CHUNK_HEADER_BYTES = 8

#: The largest glTF/GLB file (and external buffer or image file) read: 1 GiB.
MAX_FILE_BYTES = 1 << 30
#: The largest JSON chunk or .gltf text: 64 MiB (a scene's JSON is kilobytes to a few megabytes).
MAX_JSON_BYTES = 64 << 20
#: The largest data: URI accepted (its text, before base64 decoding): 16 MiB.
MAX_DATA_URI_CHARS = 16 << 20
#: Images: each side at most 16384 texels, at most 2^26 texels in all (256 MiB as RGBA8).
MAX_IMAGE_SIDE = 16384
MAX_IMAGE_TEXELS = 1 << 26


def read_bounded(path, what: str, limit: int, error=InputFileError) -> bytes:
    """The bytes of the regular file ``path`` of at most ``limit`` bytes, read with its own size
    as the bound (Python's buffered ``read(n)`` allocates n bytes before reading: a 1 GiB bound
    would allocate 1 GiB for a file of a few bytes)."""
    size = check_input_file(path, what, limit, error)
    return read_input_bytes(path, what, size, error)


class GltfError(InputFileError):
    """A glTF/GLB asset refused: ``"<file>: <JSON path>: <problem>"`` on one line (the JSON path
    in RFC 6901 form, ``/accessors/3/count``; none for damage of the container itself)."""

    def __init__(self, path, problem: str, pointer: Optional[str] = None):
        self.pointer = pointer
        super().__init__(path, f"{pointer}: {problem}" if pointer else problem)


def glb_bytes(document: bytes, binary: bytes) -> bytes:
    """A GLB file of a JSON ``document`` (UTF-8, padded with spaces) and a BIN chunk (padded with
    zeros; omitted when empty)."""
    json_part = document + b" " * (-len(document) % 4)
    chunks = struct.pack("<II", len(json_part), CHUNK_JSON) + json_part
    if binary:
        bin_part = binary + b"\0" * (-len(binary) % 4)
        chunks += struct.pack("<II", len(bin_part), CHUNK_BIN) + bin_part
    return struct.pack("<III", GLB_MAGIC, GLB_VERSION, HEADER_BYTES + len(chunks)) + chunks


def split_glb(data: bytes, path) -> Tuple[bytes, Optional[bytes]]:
    """(JSON chunk, BIN chunk or None) of GLB ``data``, every length checked against the file."""
    size = len(data)
    if size < HEADER_BYTES + CHUNK_HEADER_BYTES:
        raise GltfError(path, f"truncated GLB: {size} bytes, less than a header and one chunk header")
    magic, version, length = struct.unpack_from("<III", data, 0)
    if magic != GLB_MAGIC:
        raise GltfError(path, f"not a GLB file (magic 0x{magic:08x}, expected 0x{GLB_MAGIC:08x} 'glTF')")
    if version != GLB_VERSION:
        raise GltfError(path, f"GLB version {version}, only version 2 is read")
    if length != size:
        raise GltfError(path, f"GLB header says {length} bytes but the file has {size}")
    chunks: List[Tuple[int, bytes]] = []
    at = HEADER_BYTES
    while at < size:
        if size - at < CHUNK_HEADER_BYTES:
            raise GltfError(path, f"chunk {len(chunks)} at byte {at}: truncated chunk header ({size - at} bytes)")
        n, kind = struct.unpack_from("<II", data, at)
        if n % 4:
            raise GltfError(path, f"chunk {len(chunks)}: length {n} is not a multiple of 4")
        if n > size - at - CHUNK_HEADER_BYTES:
            raise GltfError(path, f"chunk {len(chunks)}: length {n} exceeds the {size - at - CHUNK_HEADER_BYTES} "
                                  f"bytes left in the file")
        chunks.append((kind, data[at + CHUNK_HEADER_BYTES: at + CHUNK_HEADER_BYTES + n]))
        at += CHUNK_HEADER_BYTES + n
    if chunks[0][0] != CHUNK_JSON:
        raise GltfError(path, f"chunk 0 has type 0x{chunks[0][0]:08x}, expected JSON (0x{CHUNK_JSON:08x})")
    if len(chunks[0][1]) > MAX_JSON_BYTES:
        raise GltfError(path, f"JSON chunk of {len(chunks[0][1])} bytes, more than {MAX_JSON_BYTES}")
    bins = [i for i, (kind, _) in enumerate(chunks) if kind == CHUNK_BIN]
    if any(i != 1 for i in bins):
        raise GltfError(path, f"BIN chunk at position {bins[-1]}: only the second chunk may be BIN")
    extra = [i for i, (kind, _) in enumerate(chunks) if kind == CHUNK_JSON and i]
    if extra:
        raise GltfError(path, f"chunk {extra[0]}: a second JSON chunk")
    return chunks[0][1], (chunks[1][1] if bins else None)
