"""Writing a GLB: one mesh per material (the same geometry), each with its fallback
metallic-roughness material and the HBRDF_hybrid_material extension (docs/GLTF.md, "The asset").

The file is assembled in memory, written to a temporary beside the target, read back by the
bounded reader (:func:`hybridbrdf.gltf.reader.read_gltf`) and only then renamed over the target
(:func:`hybridbrdf.files.atomic_write_bytes`): nothing half-written, nothing the reader refuses.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import json
import math
import os
from typing import Dict, List, Optional, Tuple

import numpy as np

from hybridbrdf.files import atomic_write_bytes
from hybridbrdf.gltf.brdf import GltfMaterial
from hybridbrdf.gltf.glb import GltfError, glb_bytes
from hybridbrdf.gltf.meshes import Mesh
from hybridbrdf.gltf.reader import read_gltf
from hybridbrdf.version import __version__

EXTENSION = "HBRDF_hybrid_material"
#: The extension's format version (its JSON fields, docs/GLTF.md).
EXTENSION_VERSION = 1
#: Spacing of the materials' nodes along +X, in mesh units (the sphere has radius 1).
NODE_SPACING = 2.5


@dataclass
class ExportMaterial:
    """One material of an export: the glTF ``name``, its ``fallback``, the ``hybrid`` extension's
    JSON fields (kind, material, layers, fallback report) and ``files`` [(name, bytes)] carried
    in buffer views; optional PNG ``images`` {"baseColor": bytes, "normal": bytes}."""

    name: str
    fallback: GltfMaterial
    hybrid: dict
    files: List[Tuple[str, bytes]]
    images: Dict[str, bytes] = field(default_factory=dict)


class _Builder:
    """The BIN chunk and the JSON arrays that index into it."""

    def __init__(self):
        self.bin = bytearray()
        self.doc = {"asset": {"version": "2.0", "generator": f"hybridbrdf {__version__}"},
                    "buffers": [], "bufferViews": [], "accessors": []}
        self._views_by_content: Dict[bytes, int] = {}

    def view(self, data: bytes, target: Optional[int] = None, share: bool = False) -> int:
        """A bufferView of ``data`` (4-byte aligned); ``share``: one view per distinct content."""
        if share and data in self._views_by_content:
            return self._views_by_content[data]
        self.bin += b"\0" * (-len(self.bin) % 4)
        view = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        self.bin += data
        self.doc["bufferViews"].append(view)
        index = len(self.doc["bufferViews"]) - 1
        if share:
            self._views_by_content[data] = index
        return index

    def accessor(self, arr: np.ndarray, kind: str, component: int, target: int, bounds: bool = False) -> int:
        acc = {"bufferView": self.view(np.ascontiguousarray(arr).tobytes(), target), "componentType": component,
               "count": int(arr.shape[0]), "type": kind}
        if bounds:  # POSITION must state min and max (glTF 2.0, "Meshes")
            acc["min"] = [float(v) for v in arr.min(axis=0)]
            acc["max"] = [float(v) for v in arr.max(axis=0)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1


def _attributes(b: _Builder, mesh: Mesh) -> dict:
    array_buffer = 34962
    return {"POSITION": b.accessor(mesh.positions, "VEC3", 5126, array_buffer, bounds=True),
            "NORMAL": b.accessor(mesh.normals, "VEC3", 5126, array_buffer),
            "TEXCOORD_0": b.accessor(mesh.uvs, "VEC2", 5126, array_buffer),
            "TANGENT": b.accessor(mesh.tangents, "VEC4", 5126, array_buffer)}


def _texture(b: _Builder, png: bytes) -> int:
    doc = b.doc
    doc.setdefault("images", []).append({"bufferView": b.view(png), "mimeType": "image/png"})
    doc.setdefault("samplers", [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}])
    doc.setdefault("textures", []).append({"sampler": 0, "source": len(doc["images"]) - 1})
    return len(doc["textures"]) - 1


def _round(x: float) -> float:
    return float(f"{float(x):.9g}")


def material_json(b: _Builder, entry: ExportMaterial) -> Tuple[dict, set]:
    """The glTF material of ``entry`` and the extensions it uses."""
    f = entry.fallback
    pbr = {"baseColorFactor": [_round(c) for c in f.base_color] + [1.0], "metallicFactor": _round(f.metallic),
           "roughnessFactor": _round(f.roughness)}
    mat = {"name": entry.name, "pbrMetallicRoughness": pbr}
    ext = {"KHR_materials_ior": {"ior": _round(f.ior)},
           "KHR_materials_specular": {"specularFactor": _round(f.specular),
                                      "specularColorFactor": [_round(c) for c in f.specular_color]}}
    if f.anisotropy > 0:
        ext["KHR_materials_anisotropy"] = {"anisotropyStrength": _round(f.anisotropy),
                                           "anisotropyRotation": _round(f.anisotropy_rotation)}
    if "baseColor" in entry.images:
        pbr["baseColorTexture"] = {"index": _texture(b, entry.images["baseColor"])}
    if "normal" in entry.images:
        mat["normalTexture"] = {"index": _texture(b, entry.images["normal"])}
    hybrid = dict(entry.hybrid, version=EXTENSION_VERSION,
                  files=[{"name": n, "bufferView": b.view(data, share=True)} for n, data in entry.files])
    ext[EXTENSION] = hybrid
    mat["extensions"] = ext
    return mat, set(ext)


def glb_document(mesh: Mesh, entries: List[ExportMaterial]) -> bytes:
    """The GLB bytes of ``entries`` on ``mesh`` (the meshes share its accessors)."""
    b = _Builder()
    attributes = _attributes(b, mesh)
    indices = b.accessor(mesh.indices, "SCALAR", 5125, 34963)
    used = set()
    doc = b.doc
    doc["materials"], doc["meshes"], doc["nodes"] = [], [], []
    for k, entry in enumerate(entries):
        mat, exts = material_json(b, entry)
        used |= exts
        doc["materials"].append(mat)
        doc["meshes"].append({"name": entry.name, "primitives": [{"attributes": attributes, "indices": indices,
                                                                  "material": k, "mode": 4}]})
        offset = (k - 0.5 * (len(entries) - 1)) * NODE_SPACING
        doc["nodes"].append({"name": entry.name, "mesh": k, "translation": [offset, 0.0, 0.0]})
    doc["scenes"] = [{"nodes": list(range(len(entries)))}]
    doc["scene"] = 0
    doc["extensionsUsed"] = sorted(used)  # none required: a viewer without them shows the fallback
    doc["buffers"] = [{"byteLength": len(b.bin)}]
    text = json.dumps(doc, separators=(",", ":"), allow_nan=False).encode("utf-8")
    return glb_bytes(text, bytes(b.bin))


def write_glb(path, mesh: Mesh, entries: List[ExportMaterial]) -> None:
    """Write the GLB of ``entries`` to ``path`` atomically, read back by the bounded reader first."""
    path = os.fspath(path)
    data = glb_document(mesh, entries)

    def verify(tmp: str) -> None:
        try:
            read_gltf(tmp)
        except GltfError as exc:  # the writer's own bug: name the file asked for
            raise GltfError(path, f"written asset refused by the reader: {exc.problem}") from None

    if not all(math.isfinite(v) for e in entries for v in (*e.fallback.base_color, e.fallback.metallic)):
        raise ValueError(f"{path}: a fallback parameter is not finite; nothing written")
    atomic_write_bytes(path, data, verify=verify)
