"""What a glTF asset points at: URIs (files beside it, data: URIs) and images, each bounded
before it is read or decoded (docs/GLTF.md, "What the reader refuses").

- A URI naming a network location or any scheme other than ``data:`` is refused; so is an
  absolute path, and a relative one that leaves the asset's folder once ``..`` and symlinks are
  resolved. Percent-escapes are decoded first (RFC 3986), so ``%2e%2e/`` is ``../``.
- A data: URI longer than :data:`~hybridbrdf.gltf.glb.MAX_DATA_URI_CHARS` is refused before it
  is decoded; only base64 data: URIs are read.
- An image's size comes from its header (PNG's IHDR, KTX2's pixelWidth/pixelHeight, JPEG's
  start-of-frame) before any decoder sees it, and is bounded by ``MAX_IMAGE_SIDE`` and
  ``MAX_IMAGE_TEXELS``.
"""

from __future__ import annotations

import base64
import binascii
import os
import re
import struct
import urllib.parse

from hybridbrdf.gltf.glb import (MAX_DATA_URI_CHARS, MAX_FILE_BYTES, MAX_IMAGE_SIDE, MAX_IMAGE_TEXELS, GltfError,
                                 read_bounded)

_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")
_DATA = re.compile(r"^data:([^;,]*)(;base64)?,", re.IGNORECASE)
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
KTX2_IDENTIFIER = b"\xabKTX 20\xbb\r\n\x1a\n"


def read_uri(uri, asset_path: str, pointer: str) -> bytes:
    """The bytes a glTF ``uri`` names, relative to the asset at ``asset_path``; GltfError naming
    ``pointer`` (the JSON path of the uri) for every refusal of the module docstring."""
    if not isinstance(uri, str) or not uri:
        raise GltfError(asset_path, f"must be a non-empty string, got {type(uri).__name__}", pointer)
    if uri.lower().startswith("data:"):
        return _data_uri(uri, asset_path, pointer)
    if uri.startswith("//") or _SCHEME.match(uri):
        raise GltfError(asset_path, f"names a network location or another scheme ({uri[:40]!r}); only files beside "
                                    f"the asset and data: URIs are read", pointer)
    relative = urllib.parse.unquote(uri.split("#")[0].split("?")[0])
    if "\0" in relative or os.path.isabs(relative) or relative.startswith("\\"):
        raise GltfError(asset_path, f"is an absolute path or holds a NUL ({uri[:40]!r}); only relative paths are "
                                    f"read", pointer)
    folder = os.path.realpath(os.path.dirname(os.path.abspath(asset_path)))
    target = os.path.realpath(os.path.join(folder, relative))
    if os.path.commonpath([folder, target]) != folder:
        raise GltfError(asset_path, f"{uri[:60]!r} leaves the asset's folder", pointer)
    try:
        return read_bounded(target, "glTF resource", MAX_FILE_BYTES)
    except GltfError:
        raise
    except Exception as exc:  # InputFileError of the resource: reported at the asset's JSON path
        problem = getattr(exc, "problem", str(exc))
        raise GltfError(asset_path, f"{uri[:60]!r}: {problem}", pointer) from None


def _data_uri(uri: str, asset_path: str, pointer: str) -> bytes:
    if len(uri) > MAX_DATA_URI_CHARS:
        raise GltfError(asset_path, f"data: URI of {len(uri)} characters, more than {MAX_DATA_URI_CHARS}", pointer)
    m = _DATA.match(uri)
    if not m or not m.group(2):
        raise GltfError(asset_path, "data: URI is not base64 (data:<type>;base64,<data>)", pointer)
    try:
        return base64.b64decode(uri[m.end():], validate=True)
    except (binascii.Error, ValueError) as exc:
        raise GltfError(asset_path, f"data: URI's base64 is damaged ({exc})", pointer) from None


def _jpeg_size(data: bytes):
    """(width, height) from a JPEG's first start-of-frame marker, or None."""
    at = 2
    while at + 4 <= len(data):
        if data[at] != 0xFF:
            return None
        marker = data[at + 1]
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            at += 2
            continue
        (seg,) = struct.unpack_from(">H", data, at + 2)
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            if at + 9 > len(data):
                return None
            h, w = struct.unpack_from(">HH", data, at + 5)
            return w, h
        if seg < 2:
            return None
        at += 2 + seg
    return None


def image_size(data: bytes, asset_path: str, pointer: str):
    """(kind, width, height) of an image from its header alone: "png", "ktx2" or "jpeg"; GltfError
    for another format, a truncated header or a size past the bounds."""
    if data.startswith(PNG_SIGNATURE):
        if len(data) < 24 or data[12:16] != b"IHDR":
            raise GltfError(asset_path, "PNG without its IHDR header", pointer)
        kind, (w, h) = "png", struct.unpack_from(">II", data, 16)
    elif data.startswith(KTX2_IDENTIFIER):
        if len(data) < 28:
            raise GltfError(asset_path, f"KTX2 header truncated ({len(data)} bytes)", pointer)
        kind, (w, h) = "ktx2", struct.unpack_from("<II", data, 20)
        h = max(h, 1)  # a 1D KTX2 texture has pixelHeight 0
    elif data.startswith(b"\xff\xd8"):
        size = _jpeg_size(data)
        if size is None:
            raise GltfError(asset_path, "JPEG without a readable start-of-frame header", pointer)
        kind, (w, h) = "jpeg", size
    else:
        raise GltfError(asset_path, f"image is neither PNG, JPEG nor KTX2 (starts {data[:8]!r})", pointer)
    if not (1 <= w <= MAX_IMAGE_SIDE and 1 <= h <= MAX_IMAGE_SIDE) or w * h > MAX_IMAGE_TEXELS:
        raise GltfError(asset_path, f"{kind} image of {w}x{h} texels; at most {MAX_IMAGE_SIDE} a side and "
                                    f"{MAX_IMAGE_TEXELS} texels are decoded", pointer)
    return kind, w, h
