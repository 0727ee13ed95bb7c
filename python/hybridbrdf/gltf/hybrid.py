"""The HBRDF_hybrid_material extension: a hybrid material carried inside a glTF material, as the
bytes of its files (docs/GLTF.md, "The extension").

    "HBRDF_hybrid_material": {"version": 1, "kind": "model" | "textured",
        "material": NAME (kind "model": the material of the model file),
        "layers": [NAMES] (kind "textured": informative),
        "files": [{"name": "model.safetensors", "bufferView": 7}, ...],
        "fallback": {the fit's report: start, kept, SMAPE/cMAE against f_a and the hybrid}}

A "model" material carries its model file (shared by the materials of one model: one buffer
view), a "textured" one every file of its folder (svbrdf.json, the model, the maps). The files
are read back byte for byte, so the model or folder read from them evaluates bit for bit as the
original. Both are checked by their own loaders before they are embedded (the exact bytes
embedded: read once, copied into a scratch folder, loaded from there) and after they are read back.
"""

from __future__ import annotations

from dataclasses import dataclass
import os
from typing import Dict, List, Optional, Tuple

from hybridbrdf import spec
from hybridbrdf.errors import InputFileError
from hybridbrdf.files import atomic_folder, scratch_folder
from hybridbrdf.gltf.glb import MAX_FILE_BYTES, GltfError, read_bounded
from hybridbrdf.gltf.reader import read_gltf
from hybridbrdf.gltf.writer import EXTENSION, EXTENSION_VERSION
from hybridbrdf.inputs import check_input_file
from hybridbrdf.model.file import HybridModel, load_model
from hybridbrdf.svbrdf.asset import SVBRDF, load_svbrdf

KINDS = ("model", "textured")
#: The model file's name inside a "model" material's files.
MODEL_FILE = "model.safetensors"
#: Most files a textured folder may carry (index, model, up to 4 layers x 5 maps, weights and
#: normal maps, each with its mip levels): generous.
MAX_FILES = 1024


@dataclass
class HybridMaterial:
    """A hybrid material read back from a glTF asset: ``name`` (the glTF material's), ``kind``,
    and ``model`` with ``material`` (kind "model") or ``svbrdf`` (kind "textured"); ``path``:
    the model file or folder written for it."""

    name: str
    kind: str
    path: str
    model: Optional[HybridModel] = None
    material: Optional[str] = None
    svbrdf: Optional[SVBRDF] = None


def model_payload(path) -> Tuple[bytes, HybridModel]:
    """The bytes of the model file at ``path`` and the model they hold (checked by load_model on
    exactly these bytes; the model returned reads a scratch copy that is gone after the call, so
    it evaluates through PyTorch or a later save, not libhybridbrdf)."""
    limit = 8 + spec.MAX_DATA_BYTES + (100 << 20)
    data = read_bounded(path, "model file", limit)
    with scratch_folder() as tmp:
        copy = os.path.join(tmp, MODEL_FILE)
        with open(copy, "wb") as fh:
            fh.write(data)
        try:
            model = load_model(copy)
        except InputFileError as exc:
            raise type(exc)(path, exc.problem) from None
    return data, model


def folder_payload(folder) -> List[Tuple[str, bytes]]:
    """Every regular, non-hidden file of a textured material's folder as (name, bytes), checked by
    load_svbrdf on a copy of exactly these bytes."""
    folder = os.fspath(folder)
    check_input_file(os.path.join(folder, "svbrdf.json"), "textured material index")
    names = sorted(n for n in os.listdir(folder) if not n.startswith(".")
                   and os.path.isfile(os.path.join(folder, n)))
    if len(names) > MAX_FILES:
        raise InputFileError(folder, f"{len(names)} files, more than the {MAX_FILES} a textured material carries")
    files, total = [], 0
    for n in names:
        data = read_bounded(os.path.join(folder, n), "textured material file", MAX_FILE_BYTES)
        total += len(data)
        if total > MAX_FILE_BYTES:
            raise InputFileError(folder, f"files of more than {MAX_FILE_BYTES} bytes in all")
        files.append((n, data))
    with scratch_folder() as tmp:
        _write_files(tmp, files)
        try:
            load_svbrdf(tmp)
        except InputFileError as exc:
            raise type(exc)(folder, exc.problem) from None
    return files


def _write_files(folder: str, files) -> None:
    for name, data in files:
        with open(os.path.join(folder, name), "wb") as fh:
            fh.write(data)


def _extension_files(asset, k: int, ext: dict) -> List[Tuple[str, bytes]]:
    """The (name, bytes) files of material ``k``'s extension, every field checked."""
    p = f"/materials/{k}/extensions/{EXTENSION}"
    files = ext.get("files")
    if not isinstance(files, list) or not files or len(files) > MAX_FILES:
        raise GltfError(asset.path, f"must be an array of 1 to {MAX_FILES} files", f"{p}/files")
    out, seen = [], set()
    n_views = len(asset.document.get("bufferViews", []))
    for j, item in enumerate(files):
        q = f"{p}/files/{j}"
        name = item.get("name") if isinstance(item, dict) else None
        if not isinstance(name, str) or not name or os.path.basename(name) != name or name in (".", "..") \
                or name.startswith(".") or "\\" in name or "\0" in name or name in seen:
            raise GltfError(asset.path, f"must be a plain, distinct file name, got {str(name)[:60]!r}", f"{q}/name")
        view = item.get("bufferView")
        if isinstance(view, bool) or not isinstance(view, int) or not 0 <= view < n_views:
            raise GltfError(asset.path, f"must name one of the {n_views} bufferViews, got {str(view)[:20]}",
                            f"{q}/bufferView")
        seen.add(name)
        out.append((name, asset.view_bytes(view)))
    return out


def _read_one(asset, k: int, mat: dict, ext: dict, target: str) -> HybridMaterial:
    p = f"/materials/{k}/extensions/{EXTENSION}"
    if not isinstance(ext, dict):
        raise GltfError(asset.path, "must be an object", p)
    if ext.get("version") != EXTENSION_VERSION:
        raise GltfError(asset.path, f"version {str(ext.get('version'))[:20]}, only {EXTENSION_VERSION} is read",
                        f"{p}/version")
    kind = ext.get("kind")
    if kind not in KINDS:
        raise GltfError(asset.path, f"{str(kind)[:20]!r} is not one of {', '.join(KINDS)}", f"{p}/kind")
    files = _extension_files(asset, k, ext)
    os.makedirs(target, exist_ok=True)
    _write_files(target, files)
    name = mat.get("name") if isinstance(mat.get("name"), str) else f"material{k}"
    try:
        if kind == "textured":
            return HybridMaterial(name, kind, target, svbrdf=load_svbrdf(target))
        model_path = os.path.join(target, MODEL_FILE)
        if MODEL_FILE not in dict(files):
            raise GltfError(asset.path, f"a model material carries {MODEL_FILE}", f"{p}/files")
        model = load_model(model_path)
        material = ext.get("material")
        if not isinstance(material, str) or material not in model.materials:
            raise GltfError(asset.path, f"{str(material)[:60]!r} is not a material of the carried model",
                            f"{p}/material")
        return HybridMaterial(name, kind, model_path, model=model, material=material)
    except GltfError:
        raise
    except InputFileError as exc:  # the carried file refused by its loader
        raise GltfError(asset.path, f"carried {kind}: {exc.problem}", p) from None


def _check_replaceable(folder: str) -> None:
    """Refuse to replace a folder that holds anything but an earlier read_hybrid's materials."""
    if not os.path.exists(folder):
        return
    if not os.path.isdir(folder):
        raise InputFileError(folder, "exists and is not a folder; read_hybrid writes a folder there")
    others = [n for n in os.listdir(folder) if not (n.startswith("material") and n[8:].isdigit())]
    if others:
        raise InputFileError(folder, f"holds {others[0]!r}, not only read_hybrid's material<k> folders; "
                                     f"not replaced")


def read_hybrid(path, folder) -> Dict[str, HybridMaterial]:
    """The hybrid materials of the glTF asset at ``path`` (its materials with the extension),
    keyed by glTF material name (``material<k>`` when unnamed; a repeated name gets ``#k``).
    Their files are written under ``folder`` (one subfolder per material, ``material<k>``;
    the folder is replaced as a whole, atomically, only when everything has been read), from
    where the returned models and textured materials read them. GltfError (one line: the file,
    the JSON path) for anything refused."""
    asset = read_gltf(path)
    out: Dict[str, HybridMaterial] = {}
    folder = os.fspath(folder)
    _check_replaceable(folder)
    with atomic_folder(folder) as tmp:
        for k, mat in enumerate(asset.document.get("materials", [])):
            ext = (mat.get("extensions") or {}).get(EXTENSION) if isinstance(mat.get("extensions"), dict) else None
            if ext is None:
                continue
            found = _read_one(asset, k, mat, ext, os.path.join(tmp, f"material{k}"))
            key = found.name if found.name not in out else f"{found.name}#{k}"
            out[key] = found
    for found in out.values():  # the paths after the rename
        rel = os.path.relpath(found.path, tmp)
        found.path = os.path.join(folder, rel)
        if found.model is not None:
            found.model = load_model(found.path)
        if found.svbrdf is not None:
            found.svbrdf = load_svbrdf(found.path)
    return out
