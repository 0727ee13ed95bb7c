"""The fuzz suite's glTF surface (docs/GLTF.md, "What the reader refuses"; issue 59): damaged and
forged glTF/GLB assets through the bounded reader, hybridbrdf.gltf.read_gltf.

Invariant: the reader refuses with a one-line error naming the file (GltfError, an
InputFileError), or reads an asset whose every accessor, buffer view and image it then hands out
without another exception; within fuzz_surfaces' time and address-space bounds (a forged count
must be refused, not allocated); the file is never changed. Inputs: :func:`mutate_gltf`,
structure-aware damage of a valid asset (a field of an accessor, buffer, bufferView, image,
mesh primitive or node set to an extreme, a neighbour, another type, or removed; an image's
header size forged; the GLB header or a chunk length forged; a URI pointed outside the folder)
or fuzz_surfaces' byte damage. tests/python/test_fuzz.py drives it with Hypothesis;
bench/fuzz_scale.py at scale. :func:`check_gltf_tracer` puts the same mutants through the tracer's
own C++ reader (its images decoded: the seed's material has a baseColor PNG), driven by
tests/python/test_gltf_textures.py.
"""

from __future__ import annotations

import base64
import copy
import io
import json
import pathlib
import struct

import numpy as np
from PIL import Image

import fuzz_surfaces as fs
from hybridbrdf.gltf import GltfMaterial, plane, read_gltf
from hybridbrdf.gltf.glb import glb_bytes, split_glb
from hybridbrdf.gltf.writer import ExportMaterial, glb_document

EXTREMES = [-1, 0, 1, 2, 3, 4, 5, 12, 255, 256, 4095, 4096, 2**31 - 1, 2**32, 2**53, 10**30, 5126, 5125, 34962]
ODD_VALUES = [None, True, 1.5, "0", [], {}, "../x.bin", "http://example.com/x.bin", "data:;base64,AAAA",
              "data:application/octet-stream;base64,!!", "/etc/passwd", "%2e%2e/x.bin", float("nan")]
ARRAYS = ("accessors", "buffers", "bufferViews", "images", "meshes", "nodes", "textures", "materials")
#: How often each array is damaged: the ones whose sizes bound an allocation most.
ARRAY_WEIGHTS = np.array([4, 2, 3, 2, 2, 1, 1, 1]) / 16
SIZE_FIELDS = ("count", "byteLength", "byteOffset", "byteStride", "componentType", "type")


def _png(w: int = 4, h: int = 4) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.full((h, w, 3), 128, np.uint8), "RGB").save(buf, format="PNG")
    return buf.getvalue()


def seed_assets() -> dict:
    """Valid small assets: "glb" (a plane, one material with a baseColor PNG and a carried
    file) and "gltf" (the same as .gltf JSON, its buffer in a data: URI)."""
    entry = ExportMaterial("m", GltfMaterial(base_color=(0.5, 0.4, 0.3), metallic=0.0, roughness=0.5),
                           {"kind": "model", "material": "m"}, [("model.safetensors", b"\1" * 40)],
                           {"baseColor": _png()})
    glb = glb_document(plane(), [entry])
    doc_bytes, binary = split_glb(glb, "seed")
    doc = json.loads(doc_bytes)
    doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(binary).decode()
    return {"glb": glb, "gltf": json.dumps(doc).encode()}


def _document(data: bytes):
    """(JSON document, BIN chunk or None, is GLB) of a valid seed."""
    if data[:4] == b"glTF":
        text, binary = split_glb(data, "seed")
        return json.loads(text), binary, True
    return json.loads(data), None, False


def _pack(doc: dict, binary, glb: bool) -> bytes:
    text = json.dumps(doc, allow_nan=True).encode()
    return glb_bytes(text, binary or b"") if glb else text


def _json_damage(doc: dict, rng: np.random.Generator) -> None:
    """One field of one object of a top-level array set to an extreme, a neighbour, another type,
    or removed; or an index list entry pointed elsewhere."""
    key = ARRAYS[int(rng.choice(len(ARRAYS), p=ARRAY_WEIGHTS))]
    items = doc.get(key) or []
    if not items:
        return
    obj = items[int(rng.integers(0, len(items)))]
    if key == "meshes":
        prims = obj.get("primitives") if isinstance(obj, dict) else None
        obj = prims[0] if isinstance(prims, list) and prims else obj
        if rng.random() < 0.5 and isinstance(obj, dict):
            obj = obj.get("attributes")
    if not isinstance(obj, dict):  # an earlier damage replaced it
        return
    fields = sorted(obj) + ["byteStride", "byteOffset", "sparse", "uri", "bufferView", "children"]
    sizes = [f for f in SIZE_FIELDS if f in obj]
    pool = sizes if sizes and rng.random() < 0.5 else fields  # half the time a size a bound depends on
    name = pool[int(rng.integers(0, len(pool)))]
    old = obj.get(name)
    choice = int(rng.integers(0, 4))
    if choice == 0:
        obj[name] = EXTREMES[int(rng.integers(0, len(EXTREMES)))]
    elif choice == 1 and isinstance(old, int) and not isinstance(old, bool):
        obj[name] = old + int(rng.integers(-8, 9))
    elif choice == 2:
        obj[name] = ODD_VALUES[int(rng.integers(0, len(ODD_VALUES)))]
    else:
        obj.pop(name, None)


def _image_damage(binary: bytearray, doc: dict, rng: np.random.Generator) -> None:
    """The PNG's IHDR width or height forged (the image's header, before any decode)."""
    view = doc["bufferViews"][doc["images"][0]["bufferView"]]
    at = view.get("byteOffset", 0) + 16 + 4 * int(rng.integers(0, 2))
    struct.pack_into(">I", binary, at, [0, 1, 16384, 16385, 2**31, 2**32 - 1][int(rng.integers(0, 6))])


def mutate_gltf(seed: bytes, rng: np.random.Generator) -> bytes:
    """One structure-aware damage of ``seed`` (a valid asset), or a byte-level one."""
    kind = int(rng.integers(0, 6))
    if kind == 5:
        return fs.mutate_bytes(seed, rng)
    doc, binary, glb = _document(seed)
    doc = copy.deepcopy(doc)
    if kind <= 2:
        for _ in range(int(rng.integers(1, 3))):
            _json_damage(doc, rng)
        return _pack(doc, binary, glb)
    if kind == 3 and glb:
        b = bytearray(binary)
        _image_damage(b, doc, rng)
        return _pack(doc, bytes(b), glb)
    data = bytearray(_pack(doc, binary, glb))
    if glb:  # the GLB header's length or a chunk's length forged
        offset = [8, 12, 20 + int.from_bytes(data[12:16], "little")][int(rng.integers(0, 3))]
        if offset + 4 <= len(data):
            struct.pack_into("<I", data, offset, EXTREMES[int(rng.integers(0, len(EXTREMES)))] % 2**32)
    return bytes(data)


def check_gltf(data: bytes, path: pathlib.Path) -> str:
    """The bounded reader on ``data`` written at ``path``: a one-line error naming the file, or an
    asset whose parts all read."""
    path.write_bytes(data)
    try:
        with fs._memory_bound():  # noqa: SLF001 - the suite's shared bound
            asset = read_gltf(path)
            for i in range(len(asset.document.get("accessors", []))):
                asset.accessor(i)
            for i in range(len(asset.document.get("bufferViews", []))):
                asset.view_bytes(i)
            for i in range(len(asset.document.get("images", []))):
                asset.image_bytes(i)
        result = fs.VALID
    except Exception as exc:  # noqa: BLE001
        result = fs.expect_clean_error("glTF file", exc, str(path))
    if path.read_bytes() != data:
        raise fs.Violation("glTF file: the file was changed by reading it")
    return result


def check_gltf_tracer(data: bytes, path: pathlib.Path) -> str:
    """The tracer's glTF reader (C++, images decoded) on ``data`` written at ``path``, through a
    4 x 4 direct-light render: a one-line error naming the file, or a finite image."""
    from hybridbrdf.render import render
    path.write_bytes(data)
    scene = {"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "fov_deg": 40, "width": 4, "height": 4},
             "environment": {"type": "constant", "radiance": 0},
             "lights": [{"type": "directional", "direction": [0, 0, 1], "irradiance": 1}],
             "objects": [{"type": "gltf", "file": str(path)}], "max_depth": 1, "spp": 1, "pixel_jitter": False,
             "threads": 1}
    scene_path = path.with_suffix(".json")
    scene_path.write_text(json.dumps(scene))
    try:
        with fs._memory_bound():  # noqa: SLF001 - the suite's shared bound
            image, _ = render(str(scene_path))
        if not np.isfinite(image).all():
            raise fs.Violation("glTF file (tracer): a non-finite pixel")
        result = fs.VALID
    except fs.Violation:
        raise
    except Exception as exc:  # noqa: BLE001
        result = fs.expect_clean_error("glTF file (tracer)", exc, str(path))
    if path.read_bytes() != data:
        raise fs.Violation("glTF file (tracer): the file was changed by reading it")
    return result
