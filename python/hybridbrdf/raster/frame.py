"""A frame as an engine draws it: :func:`draw_frame` runs ``hbrdf_raster`` (cpp/tools/raster) on a
scene with the shaders of :mod:`~hybridbrdf.raster.shaders`, and reads back what it printed.

The tool is not part of the wheel: it is found as ``tool``, else ``$HBRDF_RASTER``, else
``hbrdf_raster`` on ``PATH`` (a source build: ``build/hbrdf_raster``).
"""

from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
import tempfile
from typing import Dict, Optional, Union

from hybridbrdf.inputs import refuse_output_over_input
from hybridbrdf.raster.shaders import build_frame_shaders, frame_plan
from hybridbrdf.raster.sizes import LAVAPIPE_ICD, SPHERE_SEGMENTS
from hybridbrdf.raster.textures import texture_args

PathLike = Union[str, os.PathLike]


def find_tool(tool: Optional[PathLike] = None) -> str:
    """The ``hbrdf_raster`` executable; RuntimeError saying how to get one when there is none."""
    candidate = tool if tool is not None else os.environ.get("HBRDF_RASTER") or shutil.which("hbrdf_raster")
    if candidate is None or not os.path.isfile(candidate) or not os.access(candidate, os.X_OK):
        where = f"{candidate} is not an executable" if candidate is not None else "not found on PATH"
        raise RuntimeError(f"hbrdf_raster: {where}; build it (cmake --build build --target hbrdf_raster, which needs "
                           "Vulkan's headers) and give --tool build/hbrdf_raster or set HBRDF_RASTER")
    return os.fspath(candidate)


def _environment(lavapipe: bool) -> Dict[str, str]:
    env = dict(os.environ)
    if lavapipe:
        if not os.path.isfile(LAVAPIPE_ICD):
            raise RuntimeError(f"lavapipe is not installed ({LAVAPIPE_ICD} is missing; Debian: mesa-vulkan-drivers)")
        env["VK_DRIVER_FILES"] = LAVAPIPE_ICD
    return env


def _parse_report(stdout: str) -> Dict[str, object]:
    stats: Dict[str, object] = {}
    for line in stdout.splitlines():
        key, _, value = line.partition(" ")
        try:
            stats[key] = float(value) if key not in ("device", "size") else value
        except ValueError:
            stats[key] = value
    return stats


def frame_inputs(plan, folder: pathlib.Path, language: str = "glsl", per_pixel: bool = True) -> list:
    """hbrdf_raster's arguments after the scene for the frame ``plan`` (:func:`frame_plan`'s): the
    vertex and fragment SPIR-V, the model materials' cases, the glTF slots and the textures, the
    shaders and texture files written into ``folder``. bench/gpu_raster.py prepares a GPU's frames
    with the same list."""
    vert, frag = build_frame_shaders(plan, folder, language, per_pixel)
    args = [str(vert), str(frag)]
    for name in plan.cases:
        args += ["--model-material", name]
    args += ["--gltf-slots", str(plan.gltf_slots)] if plan.gltf_slots else []
    if plan.textured is not None:
        args += texture_args(plan.textured, {"maps": plan.maps, "addressing": plan.addressing,
                                             "normal": plan.normal}, folder)
    return args


def draw_frame(scene: PathLike, out: PathLike, png: Optional[PathLike] = None, validation: bool = False,
               repeat: int = 0, sphere_segments: int = SPHERE_SEGMENTS, lavapipe: bool = False,
               tool: Optional[PathLike] = None, keep_shaders: Optional[PathLike] = None,
               language: str = "glsl", per_pixel: bool = True) -> Dict[str, object]:
    """Draws scene file ``scene`` into ``out`` (linear OpenEXR) and optionally ``png`` (8-bit sRGB).

    ``validation`` runs under the Khronos validation layer (any message is an error); ``repeat``
    draws that many more frames for timing; ``lavapipe`` pins Mesa's CPU driver (else the Vulkan
    loader's choice, a discrete GPU first); ``keep_shaders`` a folder that receives the generated
    sources and SPIR-V; ``language`` the fragment stage's, "glsl" or "hlsl" (the generated HLSL through
    glslang's HLSL front end, textured and glTF maps included); ``per_pixel`` the model materials'
    generated per-pixel form (what a pixel's lights share computed once per pixel; docs/RASTER.md
    "Cost"), False for the generic ``hbrdf_eval`` per light. Returns the tool's report: ``device``, ``size``, ``triangles``, ``draws``,
    ``sphere_gap`` (world units), ``best_ms`` and, where the device has timestamps, ``best_gpu_ms``
    and ``median_gpu_ms``. Raises InputFileError / ValueError for bad scenes, RuntimeError (one
    line, the tool's words) when the tool, the shader compilers or Vulkan fail."""
    if not isinstance(repeat, int) or isinstance(repeat, bool) or not 0 <= repeat <= 100_000:
        raise ValueError(f"repeat: expected an integer in [0, 100000], got {repeat!r}")
    if not isinstance(sphere_segments, int) or isinstance(sphere_segments, bool) or not (
            8 <= sphere_segments <= 8192 and sphere_segments % 2 == 0):
        raise ValueError(f"sphere_segments: expected an even integer in [8, 8192], got {sphere_segments!r}")
    for flag, path in (("out", out), ("png", png)):
        if path is not None:
            refuse_output_over_input(path, [scene], flag)
    exe = find_tool(tool)
    plan = frame_plan(os.fspath(scene))
    env = _environment(lavapipe)
    with tempfile.TemporaryDirectory(prefix="hbrdf_raster_") as tmp:
        folder = pathlib.Path(keep_shaders) if keep_shaders is not None else pathlib.Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        args = [exe, os.fspath(scene), *frame_inputs(plan, folder, language, per_pixel), "--out", os.fspath(out),
                "--sphere-segments", str(sphere_segments), "--repeat", str(repeat)]
        args += ["--png", os.fspath(png)] if png is not None else []
        args += ["--validation"] if validation else []
        r = subprocess.run(args, capture_output=True, text=True, env=env)
    if r.returncode != 0:
        # The tool's own line; the validation layer's messages (multi-line dumps) come before it.
        # (A tool that cannot start, e.g. without libvulkan, says so in the loader's words: its last line.)
        lines = [line for line in r.stderr.splitlines() if line.startswith("hbrdf_raster:")]
        other = [line.strip() for line in r.stderr.splitlines() if line.strip()]
        status = f"killed by signal {-r.returncode}" if r.returncode < 0 else f"failed with status {r.returncode}"
        raise RuntimeError(lines[-1] if lines else f"hbrdf_raster: {status}" + (f": {other[-1]}" if other else ""))
    return _parse_report(r.stdout)
