"""The raster frame's shaders for one scene: the generated GLSL (or HLSL) of its model materials
inside the frame template (``codegen/raster.frag.j2`` or ``raster.hlsl.j2``, with the GLSL vertex
stage ``codegen/raster.vert.j2``), compiled to SPIR-V by glslangValidator and checked by spirv-val.

Which code: the scene's materials of type "model" evaluated in full (``"evaluate": "full"`` and a
``neural_max_depth`` other than 0) are each a case of the fragment shader's switch, a constant of the
code generated from their model file (one file per scene: the generated files of two models define
the same names). Every other material the frame draws ("analytic", or a model material evaluated
as f_a) is case 0: f_a of the parameters the tool reads from the scene, through the generated
``hbrdf_eval_analytic``. A scene without full model materials takes that code from its model
file, or from the shipped prior (no network runs). A scene with a textured material (one folder)
takes the folder's code (``hbrdf-codegen DIR``), with the scene's full model materials emitted
beside its layers when they come from the folder's model (the same tensors): its maps are
sampler2D bindings 3, 4, ... read with the pixel's uv derivatives, its normal map (when it has one)
the next binding, read and applied by the frame itself; the textured names are the last cases.
A scene with glTF objects declares one more sampler2D per texture its assets' materials name
(baseColor, metallicRoughness, normal; the tool fills them from the tracer's decoded images): a
glTF material with textures is f_a of docs/GLTF.md's mapping per pixel, and a normalTexture tilts
any row's shading frame. The HLSL stage declares each of these as a Texture2D and a SamplerState at
one binding (the tool's combined image sampler).
"""

from __future__ import annotations

import json
import os
import pathlib
import re
import shutil
import subprocess
from dataclasses import dataclass, field
from typing import List, Optional

import jinja2
import numpy as np

from hybridbrdf import _core
from hybridbrdf.codegen import generate, generate_textured
from hybridbrdf.codegen.source import pixel_split_problem
from hybridbrdf.codegen.textured import textured_plan
from hybridbrdf.codegen.literals import material_constant
from hybridbrdf.errors import InputFileError
from hybridbrdf.files.package_data import package_data_dir
from hybridbrdf.gltf import read_gltf
from hybridbrdf.inputs import same_file
from hybridbrdf.model.file import load_model
from hybridbrdf.model.prior import prior_path
from hybridbrdf.spec import ALPHA_MIN
from hybridbrdf.render.tracer import load_scene_dict


#: A glTF object's bind as the scene's declaration names it (read_scene_decl's "where").
_BIND = re.compile(r"^(objects\[\d+\])\.bind\.(.*)$", re.S)


def _loaded_name(where: str, name: str) -> str:
    """The loaded scene's name for a declared material (the tool matches --model-material by it): a
    glTF object's bind is "objects[i]:KEY" there (scene_loader.cpp's label for the asset's
    materials), "objects[i].bind.KEY" in the declaration; other materials keep their names."""
    match = _BIND.match(where)
    return f"{match.group(1)}:{match.group(2)}" if match else name


@dataclass
class FramePlan:
    """What the fragment shader holds: ``model_file`` the model its code comes from; ``emitted`` the
    model materials generated (in order); ``cases`` the scene materials of cases 1, 2, ... (the
    tool's ``--model-material`` order) and ``case_constants`` their constants; ``carrier`` the
    constant whose struct case 0 fills with f_a parameters."""
    model_file: str
    emitted: List[str]
    cases: List[str]
    case_constants: List[str]
    carrier: str
    textured: Optional[str] = None  #: a textured material's folder: its code, and the frame's only case
    maps: List[dict] = field(default_factory=list)  #: its maps in binding order (textured_plan's)
    addressing: str = "repeat"  #: its maps' addressing
    normal: Optional[str] = None  #: its normal map's file (in the folder), read by the frame's own code
    gltf_slots: int = 0  #: sampler2D slots for the glTF assets' textures (the tool's --gltf-slots)


def frame_plan(scene: str) -> FramePlan:
    """The plan of scene file ``scene``, read by the tracer's own reader (same errors:
    ``<scene>: <where>: <problem>``). Raises InputFileError for scenes the frame cannot draw with
    one generated file (full model materials of two model files, the neural baseline)."""
    data, base_dir, origin = load_scene_dict(scene)
    decl = _core.read_scene_decl(json.dumps(data), base_dir, origin)
    settings = decl["settings"]
    networked = settings["neural_max_depth"] != 0  # 0: the tracer renders f_a everywhere
    full = [m for m in decl["model_materials"] if networked and m["evaluate"] == "full"]
    for m in full[1:]:
        if not same_file(m["file"], full[0]["file"]):
            raise InputFileError(origin, f"{m['where']}: the raster frame draws the full model materials of one "
                                         f"model file; {full[0]['where']} uses {full[0]['file']}, this one {m['file']}")
    textured = _textured_materials(data, base_dir, origin, decl)
    if textured:
        tplan = textured_plan(textured[0][1], own_normal=True)
        for m in full:
            if not _same_model(load_model(m["file"]), tplan["model"]):
                raise InputFileError(origin, f"{m['where']}: a frame with a textured material draws full model materials "
                                             f"of the folder's own model only; {m['file']} is not the model of "
                                             f"{textured[0][1]} (the generated files would define the same names)")
            if m["material"] not in tplan["model"].materials:
                raise InputFileError(origin, f"{m['where']}.material: no material {m['material']!r} in {m['file']}")
        return FramePlan(gltf_slots=_gltf_texture_slots(data, base_dir), model_file=os.fspath(tplan["model"].path),
                         emitted=list(dict.fromkeys(list(tplan["materials"]) + [m["material"] for m in full])),
                         cases=[_loaded_name(m["where"], m["name"]) for m in full] + [name for name, _ in textured],
                         case_constants=[material_constant(m["material"]) for m in full], textured=textured[0][1],
                         carrier=material_constant(tplan["layers"][0]), maps=tplan["maps"],
                         addressing=tplan["addressing"], normal=tplan["normal"])
    files = [m["file"] for m in full] or [m["file"] for m in decl["model_materials"]] or [prior_path()]
    model = load_model(files[0])
    if not model.has_analytic:
        raise InputFileError(origin, f"{files[0]}: the raster frame draws hybrid models (f_a in every material); "
                                     "this one is the neural baseline")
    emitted = list(dict.fromkeys(m["material"] for m in full))
    for m in full:
        if m["material"] not in model.materials:
            raise InputFileError(origin, f"{m['where']}.material: no material {m['material']!r} in {files[0]}")
    if not emitted:
        emitted = [model.materials[0]]
    return FramePlan(gltf_slots=_gltf_texture_slots(data, base_dir), model_file=os.fspath(files[0]), emitted=emitted, cases=[_loaded_name(m["where"], m["name"]) for m in full],
                     case_constants=[material_constant(m["material"]) for m in full],
                     carrier=material_constant(emitted[0]))


def _gltf_texture_slots(data: dict, base_dir: str) -> int:
    """How many textures the scene's glTF assets' materials name (baseColor, metallicRoughness and
    normal, counted per material: at least the slots the tool fills), read by the bounded reader."""
    slots = 0
    for obj in data["objects"]:
        if obj.get("type") != "gltf":
            continue
        doc = read_gltf(os.path.join(base_dir, obj["file"])).document
        for material in doc.get("materials", []):
            pbr = material.get("pbrMetallicRoughness", {})
            slots += sum(key in pbr for key in ("baseColorTexture", "metallicRoughnessTexture"))
            slots += "normalTexture" in material
    return slots


def _same_model(a, b) -> bool:
    """Whether two loaded models hold the same network and materials (a painted folder's
    model.safetensors is its source's copy): the same architecture, names and tensors."""
    if a.arch != b.arch or list(a.materials) != list(b.materials) or a.tensors.keys() != b.tensors.keys():
        return False
    return all(np.array_equal(np.asarray(a.tensors[k]), np.asarray(b.tensors[k])) for k in a.tensors)


def _textured_materials(data: dict, base_dir: str, origin: str, decl: dict) -> list:
    """[(scene name, folder)] of the scene's textured materials; InputFileError unless they share
    one folder and evaluate in full."""
    found = []
    for m in decl["other_materials"]:
        if m["type"] != "textured":
            continue
        where, bind = m["where"], _BIND.match(m["where"])
        obj = None if where.startswith("materials.") else data["objects"][int(where.split("[")[1].split("]")[0])]
        spec = (data["materials"][m["name"]] if obj is None else
                {"svbrdf": obj["bind"][bind.group(2)]} if bind else obj["material"])
        if spec.get("evaluate", "full") != "full":
            raise InputFileError(origin, f"{where}.evaluate: the raster frame draws textured materials in full")
        found.append((_loaded_name(where, m["name"]), os.path.join(base_dir, spec["svbrdf"])))
    for name, folder in found[1:]:
        if not same_file(folder, found[0][1]):
            raise InputFileError(origin, f"{name}: the raster frame draws one textured folder; {found[0][0]} uses "
                                         f"{found[0][1]}, this one {folder}")
    return found


def _templates() -> jinja2.Environment:
    folder = package_data_dir("codegen", "raster.frag.j2")
    return jinja2.Environment(loader=jinja2.FileSystemLoader(str(folder)), undefined=jinja2.StrictUndefined,
                              keep_trailing_newline=True)


def write_frame_sources(plan: FramePlan, folder: pathlib.Path, language: str = "glsl", per_pixel: bool = True) -> tuple:
    """Writes the generated code (``model.glsl`` or ``model.hlsl``), ``frame.vert`` and the fragment
    stage (``frame.frag``, or ``frame.hlsl`` for ``language`` "hlsl") into ``folder``; returns the
    two shader paths. The vertex stage is GLSL in both. ``per_pixel``: the model cases take the
    generated per-pixel form (``hbrdf_pixel`` once per pixel, ``hbrdf_eval_pixel`` per light) where
    their architecture has one (wi and wo apart in the inputs), else ``hbrdf_eval`` per light."""
    if language not in ("glsl", "hlsl"):
        raise ValueError(f"language: expected 'glsl' or 'hlsl', got {language!r}")
    per_pixel = per_pixel and bool(plan.case_constants) and pixel_split_problem(load_model(plan.model_file)) is None
    if plan.textured is not None:
        code = generate_textured(plan.textured, language, own_normal=True, materials=plan.emitted, pixel_split=per_pixel)
    else:
        code = generate(load_model(plan.model_file), language, materials=plan.emitted, model_path=plan.model_file,
                        pixel_split=per_pixel)
    (folder / f"model.{language}").write_text(code)
    gltf = None if not plan.gltf_slots else {
        "first_binding": 3 + len(plan.maps) + (plan.normal is not None), "slots": plan.gltf_slots,
        "alpha_min": repr(float(ALPHA_MIN))}
    textured = None if plan.textured is None else {
        "maps": [m["param"] for m in plan.maps], "first_case": len(plan.case_constants) + 1,
        "normal_binding": 3 + len(plan.maps) if plan.normal is not None else None}
    env = _templates()
    vert, frag = folder / "frame.vert", folder / ("frame.frag" if language == "glsl" else "frame.hlsl")
    vert.write_text(env.get_template("raster.vert.j2").render())
    template = "raster.frag.j2" if language == "glsl" else "raster.hlsl.j2"
    frag.write_text(env.get_template(template).render(model_file=f"model.{language}", carrier=plan.carrier,
                                                      cases=plan.case_constants, textured=textured,
                                                      per_pixel=per_pixel, gltf=gltf))
    return vert, frag


def compile_stage(source: pathlib.Path, spirv: pathlib.Path) -> None:
    """GLSL to SPIR-V for Vulkan 1.1 (glslangValidator), then spirv-val; RuntimeError naming the
    source and the tools' first complaint when either refuses, or when a tool is missing."""
    for tool in ("glslangValidator", "spirv-val"):
        if shutil.which(tool) is None:
            raise RuntimeError(f"{tool} not found: the raster frame compiles its shaders with it "
                               "(Debian: glslang-tools, spirv-tools)")
    hlsl = ["-D", "-S", "frag", "-e", "main"] if source.suffix == ".hlsl" else []  # glslang's HLSL front end
    r = subprocess.run(["glslangValidator", *hlsl, "-V", "--target-env", "vulkan1.1", str(source), "-o", str(spirv)],
                       capture_output=True, text=True)
    if r.returncode != 0:
        errors = [line for line in r.stdout.splitlines() if "ERROR" in line] or r.stdout.splitlines()[-1:]
        raise RuntimeError(f"{source}: glslangValidator: {errors[0] if errors else r.returncode}")
    r = subprocess.run(["spirv-val", "--target-env", "vulkan1.1", str(spirv)], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{spirv}: spirv-val: {(r.stderr or r.stdout).strip().splitlines()[0]}")


def build_frame_shaders(plan: FramePlan, folder: pathlib.Path, language: str = "glsl", per_pixel: bool = True) -> tuple:
    """The plan's sources written into ``folder`` (the fragment stage in ``language``, "glsl" or
    "hlsl"; ``per_pixel`` as :func:`write_frame_sources`'s) and compiled: (vert.spv, frag.spv)."""
    vert, frag = write_frame_sources(plan, folder, language, per_pixel)
    spirv = folder / "vert.spv", folder / "frag.spv"
    compile_stage(vert, spirv[0])
    compile_stage(frag, spirv[1])
    return spirv
