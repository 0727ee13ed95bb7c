"""The bounded glTF 2.0 reader: a .glb or .gltf checked whole before anything in it is trusted
(docs/GLTF.md, "What the reader refuses").

Order of the checks: the file (regular, at most ``MAX_FILE_BYTES``), the GLB container
(:mod:`hybridbrdf.gltf.glb`), the JSON (UTF-8, depth, no NaN), ``asset.version``, buffers
(byteLength against their data), bufferViews (inside their buffers, strides), accessors (types,
alignment, count x stride inside their views), meshes (attribute accessors, indices below the
vertex count), images (sizes from their headers), textures, materials' texture references,
nodes and scenes (indices, one parent each, no cycles), required extensions. Every refusal is
one line, ``"<file>: <JSON path>: <problem>"`` (:class:`~hybridbrdf.gltf.glb.GltfError`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import os
from typing import Dict, List, Optional

import numpy as np

from hybridbrdf.gltf.glb import MAX_FILE_BYTES, GltfError, read_bounded, split_glb
from hybridbrdf.gltf.resources import image_size, read_uri
from hybridbrdf.inputs import loads_json
from hybridbrdf.limits import check_count

COMPONENTS = {5120: ("b", 1), 5121: ("B", 1), 5122: ("<h", 2), 5123: ("<H", 2), 5125: ("<I", 4), 5126: ("<f", 4)}
TYPES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
INDEX_COMPONENTS = (5121, 5123, 5125)
#: Extensions this reader understands, so an asset may list them in extensionsRequired.
KNOWN_EXTENSIONS = ("KHR_materials_ior", "KHR_materials_specular", "KHR_materials_anisotropy",
                    "KHR_texture_basisu", "HBRDF_hybrid_material")
_TOP_ARRAYS = ("buffers", "bufferViews", "accessors", "meshes", "images", "textures", "samplers", "materials",
               "nodes", "scenes")


@dataclass
class GltfAsset:
    """A checked asset: its JSON ``document``, its buffers' bytes, and the accessors' arrays
    (``accessor(i)``) and images' bytes (``image_bytes(i)``), each already bounded."""

    path: str
    document: dict
    buffers: List[bytes]
    image_info: List[tuple] = field(default_factory=list)  # (kind, width, height) per image
    _accessors: Dict[int, np.ndarray] = field(default_factory=dict)

    def view_bytes(self, index: int) -> bytes:
        """The bytes of bufferView ``index``."""
        view = self.document["bufferViews"][index]
        start = view.get("byteOffset", 0)
        return self.buffers[view["buffer"]][start:start + view["byteLength"]]

    def accessor(self, index: int) -> np.ndarray:
        """Accessor ``index`` as an array (count,) or (count, components), its component type's
        dtype (float32 for FLOAT, unnormalized integers otherwise)."""
        return self._accessors[index]

    def image_bytes(self, index: int) -> bytes:
        """The encoded bytes of image ``index`` (from its bufferView or its URI)."""
        image = self.document["images"][index]
        if "bufferView" in image:
            return self.view_bytes(image["bufferView"])
        return read_uri(image["uri"], self.path, f"/images/{index}/uri")


class _Checker:
    """The checks of one asset, each raising GltfError at a JSON path."""

    def __init__(self, path: str, doc):
        self.path, self.doc = path, doc

    def fail(self, pointer: str, problem: str):
        raise GltfError(self.path, problem, pointer)

    def array(self, key: str) -> list:
        value = self.doc.get(key, [])
        if not isinstance(value, list):
            self.fail(f"/{key}", f"must be an array, got {type(value).__name__}")
        for i, item in enumerate(value):
            if not isinstance(item, dict):
                self.fail(f"/{key}/{i}", f"must be an object, got {type(item).__name__}")
        return value

    def integer(self, obj: dict, key: str, pointer: str, lo: int = 0, default=None, hi: Optional[int] = None):
        value = obj.get(key, default)
        if value is None:
            self.fail(f"{pointer}/{key}", "missing")
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(f"{pointer}/{key}", f"must be an integer, got {type(value).__name__} {str(value)[:40]}")
        if value < lo or (hi is not None and value > hi):
            bound = f"in [{lo}, {hi}]" if hi is not None else f">= {lo}"
            self.fail(f"{pointer}/{key}", f"{value} is not {bound}")
        return value

    def index(self, obj: dict, key: str, pointer: str, target: str, default=None):
        """An index into the top-level array ``target``, checked to exist."""
        n = len(self.doc.get(target, []))
        value = self.integer(obj, key, pointer, default=default)
        if value >= n:
            self.fail(f"{pointer}/{key}", f"{target} {value} does not exist (the asset has {n})")
        return value


def _load_document(path: str):
    """(JSON document, BIN chunk or None) of the file at ``path``."""
    data = read_bounded(path, "glTF file", MAX_FILE_BYTES, GltfError)
    binary = None
    glb = data[:4] == b"glTF" or path.lower().endswith(".glb")  # a .glb with another magic is refused as such
    if glb:
        text, binary = split_glb(data, path)
    else:
        text = data
    what = "GLB JSON chunk" if glb else "glTF JSON"

    def no_constant(name):
        raise ValueError(f"{name} is not a JSON number")

    doc = loads_json(text, path, what, GltfError, parse_constant=no_constant)
    if not isinstance(doc, dict):
        raise GltfError(path, f"{what} must be an object, got {type(doc).__name__}")
    return doc, binary


def _check_asset(c: _Checker) -> None:
    asset = c.doc.get("asset")
    if not isinstance(asset, dict):
        c.fail("/asset", "missing or not an object")
    if asset.get("version") != "2.0":
        c.fail("/asset/version", f"{str(asset.get('version'))[:20]!r}, only glTF 2.0 is read")
    for key in _TOP_ARRAYS:
        c.array(key)
    for key in ("extensionsUsed", "extensionsRequired"):
        names = c.doc.get(key, [])
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            c.fail(f"/{key}", "must be an array of strings")
    for i, name in enumerate(c.doc.get("extensionsRequired", [])):
        if name not in c.doc.get("extensionsUsed", []):
            c.fail(f"/extensionsRequired/{i}", f"{name[:60]!r} is not in extensionsUsed")
        if name not in KNOWN_EXTENSIONS:
            c.fail(f"/extensionsRequired/{i}", f"requires {name[:60]!r}, which this reader does not read")


def _check_buffers(c: _Checker, binary: Optional[bytes]) -> List[bytes]:
    buffers = []
    for i, buf in enumerate(c.array("buffers")):
        p = f"/buffers/{i}"
        n = c.integer(buf, "byteLength", p, lo=1)
        if "uri" in buf:
            data = read_uri(buf["uri"], c.path, f"{p}/uri")
        elif i == 0 and binary is not None:
            data = binary
            if len(data) > n + 3:
                c.fail(f"{p}/byteLength", f"{n} bytes, but the BIN chunk holds {len(data)} (more than 3 of padding)")
        else:
            c.fail(p, "has no uri and is not the GLB's BIN chunk")
        if len(data) < n:
            c.fail(f"{p}/byteLength", f"{n} bytes, but its data has {len(data)}")
        buffers.append(bytes(data[:n]))
    return buffers


def _check_views(c: _Checker, buffers: List[bytes]) -> None:
    for i, view in enumerate(c.array("bufferViews")):
        p = f"/bufferViews/{i}"
        b = c.index(view, "buffer", p, "buffers")
        offset = c.integer(view, "byteOffset", p, default=0)
        n = c.integer(view, "byteLength", p, lo=1)
        if offset + n > len(buffers[b]):
            c.fail(f"{p}/byteLength", f"{n} bytes at offset {offset} exceed buffer {b} ({len(buffers[b])} bytes)")
        if "byteStride" in view:
            stride = c.integer(view, "byteStride", p, lo=4, hi=252)
            if stride % 4:
                c.fail(f"{p}/byteStride", f"{stride} is not a multiple of 4")


def _check_accessor(c: _Checker, i: int, acc: dict, buffers: List[bytes]) -> np.ndarray:
    p = f"/accessors/{i}"
    ctype = c.integer(acc, "componentType", p)
    if ctype not in COMPONENTS:
        c.fail(f"{p}/componentType", f"{ctype} is not one of {', '.join(map(str, COMPONENTS))}")
    kind = acc.get("type")
    if not isinstance(kind, str) or kind not in TYPES:
        c.fail(f"{p}/type", f"{str(kind)[:20]!r} is not one of {', '.join(TYPES)}")
    count = c.integer(acc, "count", p, lo=1)
    if "sparse" in acc:
        c.fail(f"{p}/sparse", "sparse accessors are not read")
    fmt, size = COMPONENTS[ctype]
    width = TYPES[kind]
    element = size * width
    if "bufferView" not in acc:  # all zeros (glTF 2.0, "Accessors"); its size bounded by memory
        try:
            check_count(f"{p}/count", count, element)
        except ValueError as exc:
            c.fail(f"{p}/count", str(exc))
        return np.zeros((count, width) if width > 1 else count, dtype=np.dtype(fmt))
    v = c.index(acc, "bufferView", p, "bufferViews")
    view = c.doc["bufferViews"][v]
    offset = c.integer(acc, "byteOffset", p, default=0)
    if offset % size:
        c.fail(f"{p}/byteOffset", f"{offset} is not a multiple of the component size {size}")
    stride = view.get("byteStride", element)
    if stride < element:
        c.fail(p, f"elements of {element} bytes do not fit bufferView {v}'s byteStride {stride}")
    n = view["byteLength"]
    if offset + stride * (count - 1) + element > n:
        c.fail(f"{p}/count", f"{count} elements of {element} bytes exceed bufferView {v} ({n} bytes)")
    data = buffers[view["buffer"]]
    start = view.get("byteOffset", 0) + offset
    arr = np.ndarray((count, width), dtype=np.dtype(fmt), buffer=data, offset=start, strides=(stride, size)).copy()
    if ctype == 5126 and not np.isfinite(arr).all():
        c.fail(p, "holds a value that is not finite")
    return arr[:, 0] if width == 1 else arr


def _check_meshes(c: _Checker, accessors: Dict[int, np.ndarray]) -> None:
    for i, mesh in enumerate(c.array("meshes")):
        prims = mesh.get("primitives")
        if not isinstance(prims, list) or not prims:
            c.fail(f"/meshes/{i}/primitives", "must be a non-empty array")
        for j, prim in enumerate(prims):
            p = f"/meshes/{i}/primitives/{j}"
            if not isinstance(prim, dict) or not isinstance(prim.get("attributes"), dict):
                c.fail(p, "must be an object with an attributes object")
            counts = {}
            for name, _ in prim["attributes"].items():
                a = c.index(prim["attributes"], name, f"{p}/attributes", "accessors")
                counts[name] = len(accessors[a])
            if "POSITION" not in counts:
                c.fail(f"{p}/attributes", "has no POSITION")
            if len(set(counts.values())) > 1:
                c.fail(f"{p}/attributes", f"attributes of different counts: {counts}")
            c.integer(prim, "mode", p, default=4, hi=6)
            if "material" in prim:
                c.index(prim, "material", p, "materials")
            if "indices" in prim:
                a = c.index(prim, "indices", p, "accessors")
                acc = c.doc["accessors"][a]
                if acc["componentType"] not in INDEX_COMPONENTS or acc["type"] != "SCALAR":
                    c.fail(f"{p}/indices", f"accessor {a} is not SCALAR of unsigned byte, short or int")
                idx = accessors[a]
                vertices = counts["POSITION"]
                if idx.size and int(idx.max()) >= vertices:
                    k = int(np.argmax(idx >= vertices))
                    c.fail(f"{p}/indices", f"index {int(idx[k])} (element {k} of accessor {a}) is not below the "
                                           f"vertex count {vertices}")


def _check_images(c: _Checker, buffers: List[bytes]) -> List[tuple]:
    info = []
    for i, image in enumerate(c.array("images")):
        p = f"/images/{i}"
        if ("uri" in image) == ("bufferView" in image):
            c.fail(p, "must have exactly one of uri and bufferView")
        if "bufferView" in image:
            v = c.index(image, "bufferView", p, "bufferViews")
            if not isinstance(image.get("mimeType"), str):
                c.fail(f"{p}/mimeType", "required with a bufferView")
            view = c.doc["bufferViews"][v]
            start = view.get("byteOffset", 0)
            data = buffers[view["buffer"]][start:start + view["byteLength"]]
        else:
            data = read_uri(image["uri"], c.path, f"{p}/uri")
        info.append(image_size(data, c.path, p))
    return info


def _texture_refs(c: _Checker, value, pointer: str) -> None:
    """Every ``{"index": ...}`` under a key ending in "Texture" inside a material."""
    if isinstance(value, dict):
        for key, item in value.items():
            p = f"{pointer}/{key}"
            if key.endswith("Texture") and isinstance(item, dict):
                c.index(item, "index", p, "textures")
                c.integer(item, "texCoord", p, default=0, hi=7)
            _texture_refs(c, item, p)
    elif isinstance(value, list):
        for k, item in enumerate(value):
            _texture_refs(c, item, f"{pointer}/{k}")


def _check_references(c: _Checker) -> None:
    for i, tex in enumerate(c.array("textures")):
        if "source" in tex:
            c.index(tex, "source", f"/textures/{i}", "images")
        if "sampler" in tex:
            c.index(tex, "sampler", f"/textures/{i}", "samplers")
    for i, mat in enumerate(c.array("materials")):
        _texture_refs(c, mat, f"/materials/{i}")
    nodes = c.array("nodes")
    parent = {}
    for i, node in enumerate(nodes):
        p = f"/nodes/{i}"
        if "mesh" in node:
            c.index(node, "mesh", p, "meshes")
        children = node.get("children", [])
        if not isinstance(children, list):
            c.fail(f"{p}/children", "must be an array")
        for k, _ in enumerate(children):
            child = c.index({"i": children[k]}, "i", f"{p}/children/{k}", "nodes")
            if child in parent or child == i:
                c.fail(f"{p}/children/{k}", f"node {child} has a second parent")
            parent[child] = i
    for i in range(len(nodes)):  # one parent each: a cycle is a walk up that comes back
        seen, at = {i}, i
        while at in parent:
            at = parent[at]
            if at in seen:
                c.fail(f"/nodes/{i}", "is its own ancestor (the node hierarchy has a cycle)")
            seen.add(at)
    for i, scene in enumerate(c.array("scenes")):
        roots = scene.get("nodes", [])
        if not isinstance(roots, list):
            c.fail(f"/scenes/{i}/nodes", "must be an array")
        for k, _ in enumerate(roots):
            c.index({"i": roots[k]}, "i", f"/scenes/{i}/nodes/{k}", "nodes")
    if "scene" in c.doc:
        c.index(c.doc, "scene", "", "scenes")


def read_gltf(path) -> GltfAsset:
    """Read and check the glTF 2.0 asset at ``path`` (.glb or .gltf): a :class:`GltfAsset`, or
    :class:`~hybridbrdf.gltf.glb.GltfError` naming the file, the JSON path and the problem."""
    path = os.fspath(path)
    doc, binary = _load_document(path)
    c = _Checker(path, doc)
    _check_asset(c)
    buffers = _check_buffers(c, binary)
    _check_views(c, buffers)
    accessors = {i: _check_accessor(c, i, acc, buffers) for i, acc in enumerate(c.array("accessors"))}
    _check_meshes(c, accessors)
    info = _check_images(c, buffers)
    _check_references(c)
    return GltfAsset(path, doc, buffers, info, accessors)
