"""The KTX 2.0 texture container (Khronos KTX File Format Specification 2.0), written and read
from the specification: one 2D texture, its mip chain, no supercompression (docs/TEXTURES.md).

Public names:

- :func:`write_ktx2` ``(path, levels, vk_format)``: ``levels`` a list of arrays, level 0 first,
  each the previous one's size halved (rounded down, at least 1): a complete or partial chain.
  uint8 (H, W, C) for the 8-bit and BC formats (BC-encoded here, ``hybridbrdf.svbrdf.bcenc``),
  float (H, W, C) for the float formats; C at most the format's channels (a missing colour
  channel is stored as 0, a missing alpha as 255 or 1.0). Written atomically.
- :func:`read_ktx2` ``(path) -> Ktx2``: the stored values of each level, decoded from the blocks
  (uint8 (H, W, C) for the 8-bit and BC formats, float32 (H, W, 4) for the float ones). Every
  size in the file is checked against the file's length and the format before anything is
  allocated; a file this reader cannot use raises ``InputFileError`` ("<path>: <problem>", one
  line), with the words of libhybridbrdf's ``render::read_ktx2``.
- :func:`encode_decode` ``(texels_uint8, vk_format) -> uint8``: what a map stored in an 8-bit or
  BC format reads back (for benchmarks).
- :class:`Ktx2` (vk_format, name, width, height, levels, srgb, channels) and :data:`FORMATS`
  (the formats read and written, by VkFormat value: R8G8B8A8_UNORM/SRGB 37/43,
  R16G16B16A16_SFLOAT 97, R32G32B32A32_SFLOAT 109, BC1_RGB_UNORM/SRGB 131/132, BC4_UNORM 139,
  BC5_UNORM 141, BC7_UNORM/SRGB 145/146); :func:`vk_format` turns a name into its value.

File layout (written): the 80-byte header, the level index, the data format descriptor (one
Khronos basic block), key/value data (``KTXorientation`` "rd": texel (0, 0) is the top-left, as
the maps' uv convention; ``KTXwriter``), then the levels, smallest first, each at a multiple of
lcm(bytes per block, 4).
"""

from __future__ import annotations

import math
import os
import struct
from dataclasses import dataclass
from typing import List

import numpy as np

from hybridbrdf.errors import InputFileError
from hybridbrdf.files import atomic_write_bytes
from hybridbrdf.inputs import check_input_file
from hybridbrdf.svbrdf import bcenc
from hybridbrdf.version import __version__

IDENTIFIER = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])
HEADER_BYTES = 80
LEVEL_INDEX_ENTRY_BYTES = 24
MAX_SIDE = 16384  # pixelWidth and pixelHeight at most this (Vulkan's common maxImageDimension2D)

# Khronos Data Format Specification values the descriptors use.
MODEL_RGBSDA, MODEL_BC1A, MODEL_BC4, MODEL_BC5, MODEL_BC7 = 1, 128, 131, 132, 134
PRIMARIES_BT709 = 1
TRANSFER_LINEAR, TRANSFER_SRGB = 1, 2
QUALIFIER_LINEAR, QUALIFIER_SIGNED, QUALIFIER_FLOAT = 0x10, 0x40, 0x80
CHANNEL_ALPHA = 15
UINT32_MAX = 0xFFFFFFFF
FLOAT_MINUS_ONE, FLOAT_ONE = 0xBF800000, 0x3F800000


@dataclass(frozen=True)
class Format:
    """One VkFormat as this reader and writer handle it. ``kind``: ``"unorm8"``, ``"float16"``,
    ``"float32"`` or a block format of ``bcenc`` (``"bc1"``, ...). ``samples``: the DFD's sample
    information, (bitOffset, bitLength - 1, channelType with qualifiers, sampleLower, sampleUpper)."""

    vk: int
    name: str
    kind: str
    srgb: bool
    block: int          # texels per block side: 1 or 4
    block_bytes: int    # bytes per block (per texel when block is 1)
    type_size: int
    channels: int
    color_model: int
    samples: tuple

    @property
    def alignment(self) -> int:
        """Level offsets are multiples of lcm(texel block size, 4)."""
        return self.block_bytes * 4 // math.gcd(self.block_bytes, 4)

    def level_bytes(self, width: int, height: int) -> int:
        return -(-width // self.block) * -(-height // self.block) * self.block_bytes


def _rgba_samples(bits: int, qualifiers: int, lower: int, upper: int, srgb: bool) -> tuple:
    alpha = CHANNEL_ALPHA | qualifiers | (QUALIFIER_LINEAR if srgb else 0)  # alpha is never sRGB-encoded
    return tuple((i * bits, bits - 1, (i | qualifiers) if i < 3 else alpha, lower, upper) for i in range(4))


def _block_samples(*channels) -> tuple:
    return tuple((64 * i, bits - 1, channel, 0, UINT32_MAX) for i, (channel, bits) in enumerate(channels))


FORMATS = {f.vk: f for f in (
    Format(37, "R8G8B8A8_UNORM", "unorm8", False, 1, 4, 1, 4, MODEL_RGBSDA, _rgba_samples(8, 0, 0, 255, False)),
    Format(43, "R8G8B8A8_SRGB", "unorm8", True, 1, 4, 1, 4, MODEL_RGBSDA, _rgba_samples(8, 0, 0, 255, True)),
    Format(97, "R16G16B16A16_SFLOAT", "float16", False, 1, 8, 2, 4, MODEL_RGBSDA,
           _rgba_samples(16, QUALIFIER_FLOAT | QUALIFIER_SIGNED, FLOAT_MINUS_ONE, FLOAT_ONE, False)),
    Format(109, "R32G32B32A32_SFLOAT", "float32", False, 1, 16, 4, 4, MODEL_RGBSDA,
           _rgba_samples(32, QUALIFIER_FLOAT | QUALIFIER_SIGNED, FLOAT_MINUS_ONE, FLOAT_ONE, False)),
    Format(131, "BC1_RGB_UNORM_BLOCK", "bc1", False, 4, 8, 1, 3, MODEL_BC1A, _block_samples((0, 64))),
    Format(132, "BC1_RGB_SRGB_BLOCK", "bc1", True, 4, 8, 1, 3, MODEL_BC1A, _block_samples((0, 64))),
    Format(139, "BC4_UNORM_BLOCK", "bc4", False, 4, 8, 1, 1, MODEL_BC4, _block_samples((0, 64))),
    Format(141, "BC5_UNORM_BLOCK", "bc5", False, 4, 16, 1, 2, MODEL_BC5, _block_samples((0, 64), (1, 64))),
    Format(145, "BC7_UNORM_BLOCK", "bc7", False, 4, 16, 1, 4, MODEL_BC7, ((0, 127, 0, 0, UINT32_MAX),)),
    Format(146, "BC7_SRGB_BLOCK", "bc7", True, 4, 16, 1, 4, MODEL_BC7, ((0, 127, 0, 0, UINT32_MAX),)),
)}


def vk_format(value) -> int:
    """A VkFormat value from an int or a name (``"BC7_SRGB_BLOCK"``, ``"VK_FORMAT_BC7_SRGB_BLOCK"``)."""
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        if int(value) in FORMATS:
            return int(value)
    elif isinstance(value, str):
        name = value.upper().removeprefix("VK_FORMAT_")
        for f in FORMATS.values():
            if f.name == name:
                return f.vk
    raise ValueError(f"vk_format {value!r} is not one of the formats written: "
                     + ", ".join(f"{f.name} ({f.vk})" for f in FORMATS.values()))


@dataclass
class Ktx2:
    """A read KTX2 texture: ``levels[p]`` the stored values of level p (uint8 or float32
    (H, W, channels)); ``srgb`` whether the format's colour channels are sRGB-encoded."""

    vk_format: int
    name: str
    width: int
    height: int
    levels: List[np.ndarray]
    srgb: bool
    channels: int


def level_sizes(width: int, height: int, count: int) -> list:
    """(width, height) of levels 0 .. count - 1: each side halved, rounded down, at least 1."""
    return [(max(1, width >> p), max(1, height >> p)) for p in range(count)]


def max_levels(width: int, height: int) -> int:
    """floor(log2(max(width, height))) + 1: the levels of a complete chain."""
    return max(width, height).bit_length()


# ---- the data format descriptor ------------------------------------------------------------

def dfd_words(fmt: Format) -> list:
    """The basic descriptor block of ``fmt`` as 32-bit words (dfdTotalSize not included)."""
    block_size = 24 + 16 * len(fmt.samples)
    transfer = TRANSFER_SRGB if fmt.srgb else TRANSFER_LINEAR
    dim = fmt.block - 1
    words = [0,                                    # vendorId 0 (Khronos), descriptorType 0 (basic)
             2 | block_size << 16,                 # versionNumber 2 (Data Format 1.3), descriptorBlockSize
             fmt.color_model | PRIMARIES_BT709 << 8 | transfer << 16,  # flags 0: alpha straight
             dim | dim << 8,                       # texelBlockDimension0..3 (size - 1)
             fmt.block_bytes, 0]                   # bytesPlane0..7
    for offset, length, channel, lower, upper in fmt.samples:
        words += [offset | length << 16 | channel << 24, 0, lower, upper]
    return words


def dfd_fields(words: list) -> list:
    """The fields a reader compares, named as the specification names them, from a block's words.
    colorPrimaries and flags are not compared: they do not change the stored values."""
    fields = [("vendorId", words[0] & 0x1FFFF), ("descriptorType", words[0] >> 17),
              ("versionNumber", words[1] & 0xFFFF), ("descriptorBlockSize", words[1] >> 16),
              ("colorModel", words[2] & 0xFF), ("transferFunction", (words[2] >> 16) & 0xFF),
              ("texelBlockDimension", words[3]), ("bytesPlane0..3", words[4]), ("bytesPlane4..7", words[5])]
    for k in range((len(words) - 6) // 4):
        w = words[6 + 4 * k:10 + 4 * k]
        fields += [(f"sample {k} bitOffset", w[0] & 0xFFFF), (f"sample {k} bitLength", (w[0] >> 16) & 0xFF),
                   (f"sample {k} channelType", w[0] >> 24), (f"sample {k} samplePosition", w[1]),
                   (f"sample {k} sampleLower", w[2]), (f"sample {k} sampleUpper", w[3])]
    return fields


def check_dfd(data: bytes, fmt: Format, fail) -> None:
    """Refuses (``fail(problem)``) a descriptor that does not describe ``fmt``: the first field
    that differs from the one this writer writes, by name."""
    total = struct.unpack_from("<I", data, 0)[0]
    if total != len(data):
        fail(f"data format descriptor: dfdTotalSize {total} differs from dfdByteLength {len(data)}")
    want = dfd_words(fmt)
    if len(data) < 4 + 4 * len(want):
        fail(f"data format descriptor: {len(data)} bytes, {fmt.name} needs {4 + 4 * len(want)}")
    got = list(struct.unpack_from(f"<{len(want)}I", data, 4))
    for (name, value), (_, expected) in zip(dfd_fields(got), dfd_fields(want)):
        if value != expected:
            if name == "transferFunction":
                fail(f"data format descriptor: transferFunction {value}, {fmt.name} needs {expected} "
                     f"({'sRGB' if fmt.srgb else 'linear'})")
            fail(f"data format descriptor: {name} {value}, {fmt.name} needs {expected}")


# ---- writing ---------------------------------------------------------------------------------

def _key_value_data(pairs) -> bytes:
    out = b""
    for key, value in sorted(pairs):  # sorted by key, as the specification asks
        entry = key.encode() + b"\0" + value
        out += struct.pack("<I", len(entry)) + entry + b"\0" * (-len(entry) % 4)
    return out


def _level_payload(level: np.ndarray, fmt: Format) -> bytes:
    h, w, c = level.shape
    if fmt.kind in bcenc.BLOCK_FORMATS:
        return bcenc.encode_blocks(level, fmt.kind)
    dtype = {"unorm8": np.uint8, "float16": np.dtype("<f2"), "float32": np.dtype("<f4")}[fmt.kind]
    out = np.zeros((h, w, 4), dtype)
    out[..., 3] = 255 if fmt.kind == "unorm8" else 1.0
    out[..., :c] = level
    return out.tobytes()


def _checked_levels(levels, fmt: Format) -> list:
    if not isinstance(levels, (list, tuple)) or not levels:
        raise ValueError("levels must be a non-empty list of arrays, level 0 first")
    arrays = [np.asarray(level) for level in levels]
    first = arrays[0]
    if first.ndim != 3 or not 1 <= first.shape[2] <= fmt.channels:
        raise ValueError(f"level 0 has shape {first.shape}: {fmt.name} takes (H, W, C), 1 <= C <= {fmt.channels}")
    h, w, c = first.shape
    if not (1 <= w <= MAX_SIDE and 1 <= h <= MAX_SIDE):
        raise ValueError(f"level 0 is {w} x {h}: each side must be in 1..{MAX_SIDE}")
    if len(arrays) > max_levels(w, h):
        raise ValueError(f"{len(arrays)} levels: a {w} x {h} texture has at most {max_levels(w, h)}")
    for p, (array, (lw, lh)) in enumerate(zip(arrays, level_sizes(w, h, len(arrays)))):
        if array.shape != (lh, lw, c):
            raise ValueError(f"level {p} has shape {array.shape}, expected {(lh, lw, c)} (each level halves the last)")
        if fmt.kind in ("float16", "float32"):
            if array.dtype.kind != "f" or not np.isfinite(array).all():
                raise ValueError(f"level {p}: {fmt.name} takes finite float values, got {array.dtype}")
        elif array.dtype != np.uint8:
            raise ValueError(f"level {p}: {fmt.name} takes uint8 values, got {array.dtype}")
    return arrays


def ktx2_bytes(levels, vk) -> bytes:
    """The bytes of a KTX2 file holding ``levels`` in format ``vk`` (see :func:`write_ktx2`)."""
    fmt = FORMATS[vk_format(vk)]
    arrays = _checked_levels(levels, fmt)
    h, w = arrays[0].shape[:2]
    n = len(arrays)
    payloads = [_level_payload(a, fmt) for a in arrays]
    dfd_block = struct.pack(f"<{len(dfd_words(fmt))}I", *dfd_words(fmt))
    dfd = struct.pack("<I", 4 + len(dfd_block)) + dfd_block
    kvd = _key_value_data([("KTXorientation", b"rd\0"), ("KTXwriter", f"hybridbrdf {__version__}\0".encode())])
    dfd_offset = HEADER_BYTES + LEVEL_INDEX_ENTRY_BYTES * n
    kvd_offset = dfd_offset + len(dfd)
    position = kvd_offset + len(kvd)
    index, data = [None] * n, b""
    for p in reversed(range(n)):  # the smallest level first
        pad = -position % fmt.alignment
        data += b"\0" * pad + payloads[p]
        index[p] = (position + pad, len(payloads[p]))
        position += pad + len(payloads[p])
    header = IDENTIFIER + struct.pack("<9I", fmt.vk, fmt.type_size, w, h, 0, 0, 1, n, 0)
    header += struct.pack("<4I2Q", dfd_offset, len(dfd), kvd_offset, len(kvd), 0, 0)
    header += b"".join(struct.pack("<3Q", offset, length, length) for offset, length in index)
    return header + dfd + kvd + data


def encode_decode(texels, vk) -> np.ndarray:
    """What uint8 ``texels`` ((H, W, C) or (H, W), C at most the format's channels) read back
    after being stored in VkFormat ``vk`` (a value or name) of an 8-bit or BC format: the same
    array for the RGBA8 formats, the chosen encoder's blocks decoded for the BC ones (the same
    shape and dtype as given). The benchmarks' entry point (docs/TEXTURES.md)."""
    fmt = FORMATS[vk_format(vk)]
    texels = np.asarray(texels)
    if texels.dtype != np.uint8:
        raise ValueError(f"texels must be uint8, got {texels.dtype}")
    if fmt.kind == "unorm8":
        return texels.copy()
    if fmt.kind not in bcenc.BLOCK_FORMATS:
        raise ValueError(f"{fmt.name} stores floats: encode_decode takes an 8-bit or BC format")
    return bcenc.encode_decode(texels, fmt.kind)


def write_ktx2(path, levels, vk) -> None:
    """Writes ``levels`` (level 0 first) in VkFormat ``vk`` (a value or name) to ``path``,
    atomically (``hybridbrdf.files.atomic_write_bytes``)."""
    atomic_write_bytes(path, ktx2_bytes(levels, vk))


# ---- reading ---------------------------------------------------------------------------------

def _check_header(fields: tuple, size: int, fail) -> tuple:
    """(format, level count) from the header's nine fields after the identifier, or fail."""
    vk, type_size, w, h, depth, layers, faces, count, scheme = fields
    fmt = FORMATS.get(vk)
    if fmt is None:
        fail(f"vkFormat {vk} is not supported (docs/TEXTURES.md lists the formats read)")
    if type_size != fmt.type_size:
        fail(f"typeSize {type_size} does not match {fmt.name} (needs {fmt.type_size})")
    if not (1 <= w <= MAX_SIDE and 1 <= h <= MAX_SIDE):
        fail(f"pixelWidth x pixelHeight {w} x {h} outside 1..{MAX_SIDE}")
    if depth != 0 or layers != 0 or faces != 1:
        fail(f"pixelDepth {depth}, layerCount {layers}, faceCount {faces}: only a single 2D texture "
             "(0, 0, 1) is read")
    if scheme != 0:
        fail(f"supercompressionScheme {scheme} is not supported (only 0, none)")
    if count == 0 and fmt.block > 1:
        fail(f"levelCount 0 (levels left to the loader) is not allowed for {fmt.name}")
    if count > max_levels(w, h):
        fail(f"levelCount {count} exceeds the {max_levels(w, h)} levels of a {w} x {h} texture")
    return fmt, max(count, 1)


def _check_metadata(f, index: tuple, metadata_start: int, size: int, fmt: Format, fail) -> int:
    """Checks the DFD, the key/value data and the global data; returns where they end."""
    dfd_offset, dfd_length, kvd_offset, kvd_length, sgd_offset, sgd_length = index
    if dfd_offset < metadata_start or dfd_length < 4 or dfd_offset + dfd_length > size:
        fail(f"data format descriptor at {dfd_offset}, {dfd_length} bytes, lies outside the file's {size} "
             f"bytes past the level index")
    if dfd_length > 4 + 4 * (6 + 4 * 16):  # a basic block has at most 16 samples here
        fail(f"data format descriptor: dfdByteLength {dfd_length} is larger than any format read needs")
    f.seek(dfd_offset)
    check_dfd(f.read(dfd_length), fmt, fail)
    end = dfd_offset + dfd_length
    if kvd_length:
        if kvd_offset < metadata_start or kvd_offset + kvd_length > size:
            fail(f"key/value data at {kvd_offset}, {kvd_length} bytes, lies outside the file's {size} bytes "
                 "past the level index")
        if kvd_length > 1 << 20:
            fail(f"key/value data of {kvd_length} bytes (at most 1 MiB is read)")
        f.seek(kvd_offset)
        kvd = f.read(kvd_length)
        position = 0
        while position < kvd_length:
            entry = struct.unpack_from("<I", kvd, position)[0] if position + 4 <= kvd_length else kvd_length
            if position + 4 + entry > kvd_length:
                fail(f"key/value data: the entry at {kvd_offset + position} runs past the key/value data's end")
            position += 4 + entry + (-entry % 4)
        end = max(end, kvd_offset + kvd_length)
    if sgd_length:
        fail(f"sgdByteLength {sgd_length}: no supercompression takes global data")
    return end


def _check_levels(entries: list, sizes: list, metadata_end: int, size: int, fmt: Format, fail) -> None:
    for p, ((offset, length, uncompressed), (w, h)) in enumerate(zip(entries, sizes)):
        expected = fmt.level_bytes(w, h)
        if length != expected:
            fail(f"level {p}: byteLength {length}, a {w} x {h} {fmt.name} level is {expected} bytes")
        if uncompressed != length:
            fail(f"level {p}: uncompressedByteLength {uncompressed} differs from byteLength {length}")
        if offset > size or length > size - offset:
            fail(f"level {p}: byteOffset {offset} + byteLength {length} lies outside the file's {size} bytes")
        if offset % fmt.alignment:
            fail(f"level {p}: byteOffset {offset} is not a multiple of {fmt.alignment}")
        if offset < metadata_end:
            fail(f"level {p}: byteOffset {offset} lies inside the header and metadata (which end at {metadata_end})")
        if p > 0 and offset + length > entries[p - 1][0]:
            fail(f"level {p}: stored after level {p - 1} (KTX2 stores the smallest level first)")


def _decode_level(data: bytes, fmt: Format, w: int, h: int) -> np.ndarray:
    if fmt.kind in bcenc.BLOCK_FORMATS:
        return bcenc.decode_blocks(data, fmt.kind, w, h)
    dtype = {"unorm8": np.uint8, "float16": np.dtype("<f2"), "float32": np.dtype("<f4")}[fmt.kind]
    values = np.frombuffer(data, dtype).reshape(h, w, 4)
    return values.copy() if fmt.kind == "unorm8" else values.astype(np.float32)


def read_ktx2(path) -> Ktx2:
    """Reads and checks a KTX2 file (see the module's docstring); raises ``InputFileError``."""
    path = os.fspath(path)

    def fail(problem):
        raise InputFileError(path, problem)

    size = check_input_file(path, "KTX2 file")
    try:
        with open(path, "rb") as f:
            head = f.read(HEADER_BYTES)
            if len(head) < HEADER_BYTES:
                fail(f"truncated: {len(head)} bytes, a KTX2 header needs {HEADER_BYTES}")
            if head[:12] != IDENTIFIER:
                fail("not a KTX 2.0 file (its first 12 bytes are not the KTX 2.0 identifier)")
            fmt, count = _check_header(struct.unpack_from("<9I", head, 12), size, fail)
            w, h = struct.unpack_from("<2I", head, 20)
            index_end = HEADER_BYTES + LEVEL_INDEX_ENTRY_BYTES * count
            if index_end > size:
                fail(f"truncated: {size} bytes, the level index ends at {index_end}")
            entries = [struct.unpack("<3Q", f.read(LEVEL_INDEX_ENTRY_BYTES)) for _ in range(count)]
            metadata_end = _check_metadata(f, struct.unpack_from("<4I2Q", head, 48), index_end, size, fmt, fail)
            sizes = level_sizes(w, h, count)
            _check_levels(entries, sizes, metadata_end, size, fmt, fail)
            levels = []
            for p, ((offset, length, _), (lw, lh)) in enumerate(zip(entries, sizes)):
                f.seek(offset)
                data = f.read(length)
                if len(data) != length:
                    fail(f"truncated while reading level {p}")
                levels.append(_decode_level(data, fmt, lw, lh))
    except OSError as err:
        raise InputFileError(path, f"cannot read the KTX2 file: {err.strerror or err}") from None
    return Ktx2(fmt.vk, fmt.name, w, h, levels, fmt.srgb, fmt.channels)
