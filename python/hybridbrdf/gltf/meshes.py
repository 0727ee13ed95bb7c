"""The meshes an export carries: a UV sphere, a plane, or a user's OBJ; each with normals, UVs and
glTF TANGENTs (xyz along increasing u, w the handedness: bitangent = cross(normal, tangent) w).

glTF's uv has v down (docs/SVBRDF.md, "Texture coordinates"), so a tangent frame consistent with
MikkTSpace as glTF exporters apply it (tangents computed with v up, the image's up) has its
bitangent toward decreasing v. For the sphere and the plane the tangent is the analytic dP/du,
normalised, and w = +1: what MikkTSpace computes for these parameterisations, up to the
per-triangle discretisation. OBJ tangents are the per-triangle dP/du (Lengyel's method)
accumulated per vertex and made orthogonal to the normal (Gram-Schmidt), with w from the sign
of the triangles' dP/dv: close to MikkTSpace on smooth meshes, not identical (MikkTSpace splits
vertices MikkTSpace-specifically).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import os

import numpy as np

from hybridbrdf.errors import InputFileError
from hybridbrdf.gltf.glb import read_bounded

#: The largest OBJ file read: 256 MiB.
MAX_OBJ_BYTES = 256 << 20


@dataclass
class Mesh:
    """Triangle mesh arrays: positions, normals (unit), uvs (glTF's, v down), tangents (xyz unit,
    w = +-1), all float32 per vertex, and uint32 triangle indices (counter-clockwise seen from
    the side the normals point to)."""

    positions: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    tangents: np.ndarray
    indices: np.ndarray


def _grid_indices(columns: int, rows: int) -> np.ndarray:
    """Two triangles per cell of a (rows + 1) x (columns + 1) vertex grid, row-major, wound
    counter-clockwise when u runs right and v runs down on the front face."""
    r, c = np.meshgrid(np.arange(rows), np.arange(columns), indexing="ij")
    a = r * (columns + 1) + c
    b, d = a + 1, a + columns + 1
    e = d + 1
    return np.stack([a, d, b, b, d, e], axis=-1).reshape(-1).astype(np.uint32)


def uv_sphere(segments: int = 64, rings: int = 32) -> Mesh:
    """A unit sphere, Y up: u = phi / 2 pi around Y from +Z towards +X, v = theta / pi from the
    north pole; tangent dP/du = (cos phi, 0, -sin phi) (defined at the poles too), w = +1."""
    u = np.linspace(0.0, 1.0, segments + 1)
    v = np.linspace(0.0, 1.0, rings + 1)
    vv, uu = np.meshgrid(v, u, indexing="ij")
    phi, theta = 2.0 * np.pi * uu, np.pi * vv
    pos = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), np.sin(theta) * np.cos(phi)], axis=-1)
    tangent = np.stack([np.cos(phi), np.zeros_like(phi), -np.sin(phi), np.ones_like(phi)], axis=-1)
    pos, tangent = pos.reshape(-1, 3), tangent.reshape(-1, 4)
    normals = pos.copy()
    poles = np.abs(normals[:, 1]) > 1.0 - 1e-12
    normals[poles] = np.array([0.0, 1.0, 0.0]) * np.sign(normals[poles, 1:2])
    uvs = np.stack([uu.reshape(-1), vv.reshape(-1)], axis=-1)
    return Mesh(pos.astype(np.float32), normals.astype(np.float32), uvs.astype(np.float32),
                tangent.astype(np.float32), _grid_indices(segments, rings))


def plane(size: float = 2.0) -> Mesh:
    """A square of side ``size`` in the XY plane facing +Z, uv (0, 0) at the top left (-x, +y);
    tangent +X, w = +1."""
    h = 0.5 * size
    pos = np.array([[-h, h, 0.0], [h, h, 0.0], [-h, -h, 0.0], [h, -h, 0.0]])
    uvs = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    tangents = np.tile([1.0, 0.0, 0.0, 1.0], (4, 1))
    return Mesh(pos.astype(np.float32), normals.astype(np.float32), uvs.astype(np.float32),
                tangents.astype(np.float32), _grid_indices(1, 1))


def _obj_index(token: str, n: int, path: str, line_no: int) -> int:
    """A 1-based (or negative, relative) OBJ index as a 0-based one, checked against ``n``."""
    try:
        k = int(token)
    except ValueError:
        raise InputFileError(path, f"line {line_no}: {token[:20]!r} is not an index") from None
    k = k - 1 if k > 0 else n + k
    if not 0 <= k < n:
        raise InputFileError(path, f"line {line_no}: index {token[:20]} out of range (1..{n})")
    return k


def _parse_obj(path: str):
    try:
        text = read_bounded(path, "OBJ file", MAX_OBJ_BYTES).decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputFileError(path, f"the OBJ file is not UTF-8 text (byte {exc.start})") from None
    lists = {"v": [], "vt": [], "vn": []}
    corners = []  # (position, uv or -1, normal or -1) per triangle corner
    for line_no, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        if parts[0] in lists:
            need = 2 if parts[0] == "vt" else 3
            try:
                values = [float(x) for x in parts[1:1 + need]]
            except ValueError:
                raise InputFileError(path, f"line {line_no}: {parts[0]} with a value that is not a number") from None
            if len(values) < need or not all(math.isfinite(x) for x in values):
                raise InputFileError(path, f"line {line_no}: {parts[0]} needs {need} finite numbers")
            lists[parts[0]].append(values)
        elif parts[0] == "f":
            if len(parts) < 4:
                raise InputFileError(path, f"line {line_no}: a face needs at least 3 vertices")
            face = []
            for token in parts[1:]:
                fields = (token.split("/") + ["", ""])[:3]
                face.append((_obj_index(fields[0], len(lists["v"]), path, line_no),
                             _obj_index(fields[1], len(lists["vt"]), path, line_no) if fields[1] else -1,
                             _obj_index(fields[2], len(lists["vn"]), path, line_no) if fields[2] else -1))
            for k in range(1, len(face) - 1):  # a fan
                corners += [face[0], face[k], face[k + 1]]
    if not corners:
        raise InputFileError(path, "no faces")
    return {k: np.asarray(v, dtype=np.float64).reshape(-1, 2 if k == "vt" else 3) for k, v in lists.items()}, corners


def _tangents(pos, normals, uvs, tris) -> np.ndarray:
    """Per-vertex tangents (xyz, w) from the triangles' dP/du and dP/dv (Lengyel)."""
    p0, p1, p2 = (pos[tris[:, k]] for k in range(3))
    t0, t1, t2 = (uvs[tris[:, k]] for k in range(3))
    e1, e2, d1, d2 = p1 - p0, p2 - p0, t1 - t0, t2 - t0
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    r = np.where(np.abs(det) > 1e-20, 1.0 / np.where(det == 0, 1, det), 0.0)[:, None]
    dpdu = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * r
    dpdv = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * r
    tan, bit = np.zeros_like(pos), np.zeros_like(pos)
    for k in range(3):
        np.add.at(tan, tris[:, k], dpdu)
        np.add.at(bit, tris[:, k], dpdv)
    tan -= normals * np.sum(tan * normals, axis=1, keepdims=True)
    length = np.linalg.norm(tan, axis=1, keepdims=True)
    fallback = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    fallback -= normals * np.sum(fallback * normals, axis=1, keepdims=True)
    tan = np.where(length > 1e-12, tan / np.maximum(length, 1e-300), fallback / np.linalg.norm(fallback, axis=1,
                                                                                              keepdims=True))
    # v runs down in glTF: the bitangent cross(n, t) w points towards decreasing v.
    w = np.where(np.sum(np.cross(normals, tan) * bit, axis=1) > 0, -1.0, 1.0)
    return np.concatenate([tan, w[:, None]], axis=1)


def read_obj(path) -> Mesh:
    """A triangle mesh from a Wavefront OBJ (v, vt, vn, f; polygons as fans; other lines
    ignored), one glTF vertex per face corner: InputFileError naming the file and line for a bad
    number or index. Missing normals: the face's; missing uvs: 0 (tangents then any unit vector
    orthogonal to the normal). OBJ's vt has v up; glTF's v = 1 - vt.v."""
    path = os.fspath(path)
    lists, corners = _parse_obj(path)
    c = np.asarray(corners, dtype=np.int64)
    pos = lists["v"][c[:, 0]]
    tris = np.arange(len(c)).reshape(-1, 3)
    face_n = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
    face_n = np.repeat(face_n, 3, axis=0)
    normals = np.where((c[:, 2:3] >= 0), lists["vn"][np.maximum(c[:, 2], 0)] if len(lists["vn"]) else face_n, face_n)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.where(length > 0, normals / np.maximum(length, 1e-300), [[0.0, 0.0, 1.0]])
    uvs = np.zeros((len(c), 2))
    if len(lists["vt"]):
        has = c[:, 1] >= 0
        uvs[has] = lists["vt"][c[has, 1]] * [1.0, -1.0] + [0.0, 1.0]
    tangents = _tangents(pos, normals, uvs, tris)
    return Mesh(pos.astype(np.float32), normals.astype(np.float32), uvs.astype(np.float32),
                tangents.astype(np.float32), tris.reshape(-1).astype(np.uint32))
