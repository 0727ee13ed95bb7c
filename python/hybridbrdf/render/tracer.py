"""The reference path tracer from Python (docs/RENDERING.md).

    img, stats = hybridbrdf.render.tracer.render("scenes/sphere_env.json", out="out/sphere.exr", spp=64)

The scene is a JSON file (or a dict in the same schema); keyword overrides replace its top-level
settings (:data:`SETTINGS`: ``spp``, ``max_depth``, ``neural_max_depth``, ``sampler``, ...; the table
comes from the C++ library, :func:`settings`) and the camera's ``width``/``height``. Rendering runs in
libhybridbrdf (Embree, wavefront, multi-threaded, GIL released). Measured materials
(``{"type": "measured", "source": ...}``) are evaluated here, by :func:`hybridbrdf.sources.open_source`
readers, called once per batch of direction pairs.
"""

from __future__ import annotations

import copy
import json
import os
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

from hybridbrdf import _core
from hybridbrdf.errors import InputFileError
from hybridbrdf.inputs import (MAX_JSON_DEPTH, json_depth, read_input_text, refuse_output_over_input, same_file,
                               value_depth)
from hybridbrdf.sources import open_source

#: Largest scene file read (bytes). Scenes hold settings, materials and objects; meshes and
#: environment maps are files of their own. The example scenes are about 1 KB.
MAX_SCENE_BYTES = 16 << 20


def settings() -> List[Dict[str, Any]]:
    """The scene settings as libhybridbrdf defines them (cpp/include/hybridbrdf/render/settings.hpp):
    one dict per setting with name, type ("int", "float", "bool" or "str"), default, min and max
    (inclusive; None = unbounded), choices (None or the accepted strings) and a one-line doc.
    Empty for a build without the renderer."""
    return list(_core.render_settings()) if getattr(_core, "HAVE_RENDERER", False) else []


#: Names of the settings that :func:`render` accepts as overrides (and a scene file at its top level).
SETTINGS = tuple(s["name"] for s in settings())

#: Raised by :func:`render` when a measured material's callable fails while rendering (a RuntimeError
#: whose message is one line, "<scene>: <where>: measured material '<source>': eval(wi, wo) raised ...").
RenderMaterialError = getattr(_core, "RenderMaterialError", RuntimeError)


def open_measured(source: str):
    """f(wi, wo) -> (N, 3) float32 for a measured source (a path or synthetic:NAME).

    A missing or malformed source raises open_source's ValueError, which names the file; the library
    reports it as one line, "<scene>: <where>.source: <message>", without a traceback."""
    src = open_source(source)

    def evaluate(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(src.eval(wi, wo), dtype=np.float32)

    return evaluate


def load_scene_dict(scene: Union[str, os.PathLike, Dict[str, Any]]) -> Tuple[Dict[str, Any], str, str]:
    """(scene dict, base folder for relative paths, name used in errors)."""
    if isinstance(scene, dict):
        # The files' bound, before the copy: deepcopy and json.dumps recurse once per level.
        if value_depth(scene) > MAX_JSON_DEPTH:
            raise InputFileError("<scene dict>", f"scene dict: nested deeper than {MAX_JSON_DEPTH} levels")
        return copy.deepcopy(scene), os.getcwd(), "<scene dict>"
    path = os.fspath(scene)
    # A regular file of at most MAX_SCENE_BYTES, read with that bound (a FIFO, /dev/zero ... are
    # refused before opening), and nested no deeper than MAX_JSON_DEPTH: json.loads recurses.
    text = read_input_text(path, "scene file", MAX_SCENE_BYTES, InputFileError)
    if json_depth(text) > MAX_JSON_DEPTH:
        raise InputFileError(path, f"scene file: JSON nested deeper than {MAX_JSON_DEPTH} levels")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: invalid JSON: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object at the top level")
    return data, os.path.dirname(os.path.abspath(path)), path


def scene_inputs(data: Dict[str, Any], base_dir: str) -> List[str]:
    """The files a scene dict names (model files, measured sources, textured materials' files,
    environment maps, meshes),
    resolved against ``base_dir`` as the library resolves them. Read before the scene is
    validated, so anything that is not a path string is passed over (the library reports it)."""
    found: List[str] = []

    def add(value) -> None:
        if isinstance(value, str) and value and not value.startswith("synthetic:"):
            found.append(os.path.join(base_dir, value))

    def material(m) -> None:
        if isinstance(m, dict):
            add(m.get("file"))
            add(m.get("source"))
            folder = m.get("svbrdf")  # a textured material: its folder's files (index, model, maps)
            if isinstance(folder, str) and folder and os.path.isdir(os.path.join(base_dir, folder)):
                root = os.path.join(base_dir, folder)
                found.extend(os.path.join(root, f) for f in sorted(os.listdir(root)))

    materials = data.get("materials")
    if isinstance(materials, dict):
        for m in materials.values():
            material(m)
    environment = data.get("environment")
    if isinstance(environment, dict):
        add(environment.get("file"))
    objects = data.get("objects")
    if isinstance(objects, list):
        for obj in objects:
            if isinstance(obj, dict):
                add(obj.get("file"))
                material(obj.get("material"))
    return found


def _prepare_outputs(out, png, inputs=()) -> None:
    """Create the output files' folders, and fail now, in one line naming the path, when an output
    cannot be written: before the render, not after it. The library then checks that each file can
    be created (``check_output_path``: not a folder, a folder that takes new files). An output that
    is one of the ``inputs`` (the scene file, the files it names), or the other output, is refused
    whatever path reaches it (symlinks followed, hard links by inode): writing it would destroy it."""
    paths = [os.fspath(p) for p in (out, png) if p]
    refuse_output_over_input(out, inputs, "the EXR output")
    refuse_output_over_input(png, inputs, "the PNG output")
    if len(paths) == 2 and same_file(paths[0], paths[1]):
        raise ValueError(f"{paths[0]}: the EXR and the PNG output are the same file")
    for path in paths:
        parent = os.path.dirname(os.path.abspath(path))
        if os.path.exists(parent) and not os.path.isdir(parent):
            raise ValueError(f"{path}: {parent} is a file, not a folder")
        try:
            os.makedirs(parent, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"{path}: cannot create the folder {parent} ({exc.strerror})") from None


def render(scene: Union[str, os.PathLike, Dict[str, Any]], out: Optional[str] = None, png: Optional[str] = None, *,
           quiet: bool = True, exposure: float = 0.0, tonemap: str = "clamp", width: Optional[int] = None,
           height: Optional[int] = None, measured_factory=None, **overrides) -> Tuple[np.ndarray, Dict[str, Any]]:
    """Render a scene; returns (image (H, W, 3) float32 linear RGB, stats).

    out: OpenEXR file to write (linear float32); png: 8-bit sRGB PNG (``exposure`` in stops, ``tonemap``
    "clamp" or "aces"). Their folders are created, and both are checked before the render starts
    (ValueError "<path>: <problem>" for a folder, an unwritable place, ...); they are written under
    temporary names and renamed into place together once the image is complete. Overrides (``spp=``,
    ``threads=``, ...) replace the scene's settings; None values are ignored, bad ones raise ValueError
    "<setting>: <problem>". ``measured_factory(source) -> f(wi, wo)`` replaces the default
    (:func:`hybridbrdf.sources.open_source`) for measured materials. stats: seconds, samples_per_second,
    rays, shadow_rays, brdf_evals, network_evals, threads, tiles, spp, sampler, sampler_memory_bytes.

    Raises ValueError "<scene>: <where>: <problem>" for bad scenes, sizes beyond the documented limits
    included (docs/RENDERING.md); RenderMaterialError (a RuntimeError) "<scene>: <where>: ..." when a
    measured material's callable fails while rendering. Ctrl-C (SIGINT, or any signal whose Python
    handler raises) stops loading and rendering within about one tile and raises KeyboardInterrupt (the
    handler's exception); no output file is touched.
    """
    if not getattr(_core, "HAVE_RENDERER", False):
        raise RuntimeError("this build of hybridbrdf has no renderer (HBRDF_BUILD_RENDERER=OFF)")
    data, base_dir, origin = load_scene_dict(scene)
    for key, value in overrides.items():
        if key not in SETTINGS:
            raise TypeError(f"render() got an unexpected setting {key!r}; expected one of {', '.join(SETTINGS)}")
        if value is not None:
            # Checked here, by the loader's own rules, so that the error names the override, not the scene.
            data[key] = _core.check_render_setting(key, value)
    for key, value in (("width", width), ("height", height)):
        if value is not None:
            data.setdefault("camera", {})[key] = int(value)
    inputs = scene_inputs(data, base_dir) + ([] if isinstance(scene, dict) else [origin])
    _prepare_outputs(out, png, inputs)
    image, stats = _core.render_scene(json.dumps(data), base_dir, origin, measured=measured_factory or open_measured, quiet=quiet,
                                      exr=os.fspath(out) if out else "", png=os.fspath(png) if png else "",
                                      exposure=float(exposure), tonemap=tonemap)
    stats = dict(stats)
    stats["sampler_memory_bytes"] = dict(stats["sampler_memory_bytes"])
    return image, stats


def write_exr(image: np.ndarray, path: str) -> None:
    """Write (H, W, 3) linear RGB as float32 OpenEXR (atomically)."""
    _core.render_write_exr(np.asarray(image, dtype=np.float32), os.fspath(path))


#: The first four bytes of every OpenEXR file (the OpenEXR file layout's magic number 20000630).
EXR_MAGIC = b"\x76\x2f\x31\x01"


def read_exr(path) -> np.ndarray:
    """Read an OpenEXR file (what :func:`write_exr` writes, or any scanline RGB or RGBA EXR) as
    (H, W, 3) float32 linear RGB: ``write_exr`` then ``read_exr`` gives back the same floats.
    Raises :class:`~hybridbrdf.errors.InputFileError` naming ``path`` when it is not an EXR
    (checked by its magic number, not its name) or cannot be read."""
    path = os.fspath(path)
    try:
        with open(path, "rb") as fh:
            magic = fh.read(4)
    except OSError as exc:
        raise InputFileError(path, exc.strerror or str(exc)) from None
    if magic != EXR_MAGIC:
        raise InputFileError(path, "is not an OpenEXR file (its first bytes are not the EXR magic number)")
    return read_image(path)


def write_png(image: np.ndarray, path: str, exposure: float = 0.0, tonemap: str = "clamp") -> None:
    """Write (H, W, 3) linear RGB as an 8-bit sRGB PNG (atomically)."""
    _core.render_write_png(np.asarray(image, dtype=np.float32), os.fspath(path), exposure, tonemap)


def read_image(path: str) -> np.ndarray:
    """Read an .exr or .hdr file as (H, W, 3) float32."""
    return _core.render_read_image(os.fspath(path))
