"""The scene plan of code generation: what a path-tracer scene (docs/RENDERING.md) asks of a
model's generated code. :func:`load_scene` reads the scene through the tracer's own reader and
keeps its materials of type "model" in the model's file; :func:`specialisation` turns that plan
into what the template emits (which materials, network or not, isotropic-only GGX, latent folded,
the depth from which the network is skipped)."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence

from hybridbrdf import _core
from hybridbrdf.errors import InputFileError
from hybridbrdf.inputs import same_file as _same_file
from hybridbrdf.model.file import HybridModel
from hybridbrdf.render.tracer import load_scene_dict

NO_DEPTH_LIMIT = 2**31 - 1  # HBRDF_NEURAL_MAX_DEPTH without a scene: the network at every depth


def load_scene(scene, model: HybridModel, model_path=None) -> Dict[str, object]:
    """The specialisation plan of a path-tracer scene (docs/RENDERING.md) for ``model``.

    ``scene`` is a scene file, or a dict in its schema (relative paths then resolve against the
    current folder). It is read and checked by the tracer's own reader (``_core.read_scene_decl``:
    one schema, the same errors), which opens none of the files it names. The code is emitted for
    the scene's materials of type "model" whose "file" is ``model_path`` (default ``model.path``):
    each is the model material named by its "material", analytic-only with ``"evaluate": "analytic"``.
    Analytic and measured materials and models of other files are not emitted (listed in
    "not_emitted"). The scene's ``neural_max_depth`` (-1 = ``max_depth``) is the tracer's rule 1.

    Returns ``{"name", "materials": [{"name", "evaluate"}], "neural_max_depth", "not_emitted"}``,
    the ``scene`` argument of :func:`hybridbrdf.codegen.main.generate`. Raises ValueError
    "<scene>: <where>: <problem>"."""
    data, base_dir, origin = load_scene_dict(scene)
    if isinstance(data.get("materials"), list):
        raise InputFileError(origin, "materials: the list form of hbrdf-codegen scenes was removed; --scene reads "
                                     "the path tracer's scene files (docs/RENDERING.md): \"materials\": {\"name\": "
                                     "{\"type\": \"model\", \"file\": \"MODEL.safetensors\", \"material\": \"...\"}}")
    if not hasattr(_core, "read_scene_decl"):
        raise InputFileError(origin, "--scene needs the renderer's scene reader, and this build of hybridbrdf has "
                                     "no renderer (HBRDF_BUILD_RENDERER=OFF)")
    decl = _core.read_scene_decl(json.dumps(data), base_dir, origin)
    target = model_path if model_path is not None else model.path
    if target is None:
        raise ValueError("load_scene: the model has no file to match the scene's materials against; give model_path")
    emitted: Dict[str, Dict[str, str]] = {}  # model material -> its first declaration
    not_emitted = [f"{m['name']} ({m['type']})" for m in decl["other_materials"]]
    for m in decl["model_materials"]:
        if not _same_file(m["file"], os.fspath(target)):
            not_emitted.append(f"{m['name']} (model {os.path.basename(m['file'])})")
            continue
        if m["material"] not in model.materials:
            raise InputFileError(origin, f"{m['where']}.material: no material {m['material']!r} in {target}")
        if m["evaluate"] == "analytic" and not model.has_analytic:
            raise InputFileError(origin, f"{m['where']}.evaluate: \"analytic\" is not possible: the neural baseline "
                                         "has no analytic part")
        first = emitted.setdefault(m["material"], m)
        if first["evaluate"] != m["evaluate"]:
            # One constant per model material, so it cannot be both.
            raise InputFileError(origin, f"{m['where']}.evaluate: {m['material']!r} is also used by {first['where']} "
                                         f"with \"evaluate\": \"{first['evaluate']}\"; the generated code has one "
                                         "constant per model material")
    if not emitted:
        raise InputFileError(origin, f"materials: no material of type \"model\" uses {target}"
                                     + (f" (the scene has: {', '.join(not_emitted)})" if not_emitted else ""))
    settings = decl["settings"]
    depth = settings["neural_max_depth"] if settings["neural_max_depth"] >= 0 else settings["max_depth"]
    return {"name": os.path.basename(origin), "neural_max_depth": depth, "not_emitted": not_emitted,
            "materials": [{"name": n, "evaluate": m["evaluate"]} for n, m in emitted.items()]}


@dataclass
class Specialisation:
    """What the generated code holds: ``names`` the materials emitted, in order; ``analytic_only``
    no network at all; ``mixed`` the network stays and a per-material flag (``flags``: name ->
    analytic-only) skips it; ``isotropic_only`` GGX without its anisotropic terms; ``fold_latent``
    one material, its latent code folded into the first bias; ``neural_max_depth`` the value of
    HBRDF_NEURAL_MAX_DEPTH."""
    names: List[str]
    analytic_only: bool = False
    isotropic_only: bool = False
    fold_latent: bool = False
    mixed: bool = False
    flags: Dict[str, bool] = field(default_factory=dict)
    neural_max_depth: int = NO_DEPTH_LIMIT


def specialisation(model: HybridModel, materials: Optional[Sequence[str]],
                   scene: Optional[Dict[str, object]]) -> Specialisation:
    """Without ``scene``: ``materials`` (default all of the model's), nothing specialised. With
    the plan of :func:`load_scene`, simulate only what the scene calls for (docs/CODEGEN.md,
    "Specialisation"). Raises ValueError for analytic-only evaluation of the neural baseline."""
    if scene is None:
        return Specialisation(names=list(materials) if materials else model.materials)
    s = Specialisation(names=[m["name"] for m in scene["materials"]])
    if scene.get("neural_max_depth") is not None:
        s.neural_max_depth = int(scene["neural_max_depth"])
    analytic = [m["evaluate"] == "analytic" for m in scene["materials"]]
    # neural_max_depth 0: the tracer renders f_a at every depth, so no network at all (the
    # neural baseline has no f_a; the tracer, and so hbrdf_eval_depth, always runs its network).
    s.analytic_only = all(analytic) or (s.neural_max_depth == 0 and model.has_analytic)
    # Some materials full, others analytic-only: the network stays, and a per-material
    # flag makes hbrdf_eval skip it (a branch that is uniform across a draw call).
    s.mixed = not s.analytic_only and any(analytic)
    if any(analytic) and not model.has_analytic:
        raise ValueError("the scene asks for analytic-only evaluation but the model is the neural baseline")
    s.isotropic_only = model.has_analytic and all(
        model.material_info[model.index(n)].get("isotropic", True) for n in s.names)
    s.fold_latent = len(s.names) == 1 and not s.analytic_only
    s.flags = {m["name"]: m["evaluate"] == "analytic" for m in scene["materials"]}
    return s
