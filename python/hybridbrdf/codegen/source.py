"""The source of a model for one dialect (GLSL, HLSL, Slang, WGSL or C++): ``codegen/hbrdf.j2`` rendered
with the model's network, its materials' constants and the scene's specialisation."""

from __future__ import annotations

import functools
from typing import Any, Dict, List, Optional, Sequence

import jinja2

from hybridbrdf import _core, spec
from hybridbrdf.codegen.literals import DIALECTS, comment_text, contract_literals, float_literal, material_constant
from hybridbrdf.codegen.network import network_layers, split_first_layer, unrolled_frames, unrolled_head
from hybridbrdf.codegen.scene import NO_DEPTH_LIMIT, Specialisation, specialisation
from hybridbrdf.codegen.textured import textured_code
from hybridbrdf.model.file import HybridModel
from hybridbrdf.names import names_problem
from hybridbrdf.files import package_data_dir

MLP_FORMS = ("auto", "unrolled", "loops")


@functools.lru_cache(maxsize=None)
def _environment(folder: str) -> jinja2.Environment:
    """One Jinja environment per template folder, so that its compiled templates are reused:
    compiling hbrdf.j2 is ~0.2 s, nearly all of a small model's generate(). Jinja's auto_reload
    (on by default) checks each template's file on every get_template, so an edited template is
    compiled again, never served stale."""
    return jinja2.Environment(loader=jinja2.FileSystemLoader(folder), undefined=jinja2.StrictUndefined,
                              keep_trailing_newline=True, auto_reload=True)


def template(name: str) -> jinja2.Template:
    """``codegen/<name>`` (inside the package in a wheel, at the top of the source tree);
    a variable the caller leaves unset is an error, not an empty string."""
    return _environment(str(package_data_dir("codegen", "hbrdf.j2"))).get_template(name)


def check_material_selection(model: HybridModel, names: Sequence[str]) -> None:
    """Raises ValueError unless ``names`` are distinct materials of ``model`` (one line naming
    the first unknown or repeated one, and the model's materials when one is unknown)."""
    seen = set()
    for n in names:
        if n not in model.materials:
            listed = ", ".join(comment_text(m) for m in model.materials[:20])
            more = f" and {len(model.materials) - 20} more" if len(model.materials) > 20 else ""
            raise ValueError(f"no material {comment_text(n)!r} in the model (it has: {listed}{more})")
        if n in seen:
            raise ValueError(f"material {n!r} is listed twice")
        seen.add(n)
    problem = names_problem(list(names))
    if problem:  # a model built in memory, not loaded, may break the contract's name rule
        raise ValueError(problem)


def _material_constants(model: HybridModel, plan: Specialisation, head_in_material: bool) -> List[Dict[str, Any]]:
    """What the template needs of each emitted material for its HBRDF_MATERIAL_<NAME> constant."""
    t = model.tensors
    mats = []
    for n in plan.names:
        i = model.index(n)
        z = list(t["materials.z"][i]) or [0.0]
        if not model.has_analytic:
            kd, eta, alpha = [0.0] * 3, [1.0] * 3, [1.0, 1.0]
        else:
            kd, eta, alpha = t["materials.kd"][i], t["materials.eta"][i], t["materials.alpha"][i]
        mats.append({"const_name": material_constant(n), "kd": [float_literal(v) for v in kd],
                     "eta": [float_literal(v) for v in eta], "alpha": [float_literal(v) for v in alpha], "z": z,
                     "head_w": t["materials.head_weight"][i].ravel() if head_in_material else [],
                     "head_b": t["materials.head_bias"][i] if head_in_material else [],
                     "energy": t["materials.energy_bound"][i] if "materials.energy_bound" in t else [],
                     "analytic_only": "true" if plan.flags.get(n, False) else "false"})
    return mats


def generate_source(model: HybridModel, target: str, materials: Optional[Sequence[str]] = None,
                    model_path: str = "MODEL", extra_args: str = "", scene: Optional[Dict[str, object]] = None,
                    precision: str = "fp32", mlp_form: str = "auto", literal_head: Optional[str] = None,
                    textured: Optional[Dict[str, Any]] = None, pixel_split: bool = False) -> str:
    """:func:`hybridbrdf.codegen.main.generate` for the dialects of :data:`DIALECTS` (glsl, hlsl,
    slang, wgsl, cpp). ``literal_head`` (a material's name) writes that material's output layer as literals
    even without a scene, as BRDF Explorer files do. ``textured`` (the plan of
    :func:`hybridbrdf.codegen.textured.textured_plan`) adds its decode, lookup and evaluation
    (``codegen/textured.j2``); ``materials`` must then be its layers' materials. ``pixel_split`` adds
    the per-pixel form ``hbrdf_pixel`` / ``hbrdf_eval_pixel`` (``codegen/pixel.j2``)."""
    if target not in DIALECTS:
        raise ValueError(f"unknown target {target!r}; expected one of {', '.join(DIALECTS)}")
    if precision not in ("fp32", "fp16"):
        raise ValueError(f"unknown precision {precision!r}; expected fp32 or fp16")
    if mlp_form not in MLP_FORMS:
        raise ValueError(f"unknown MLP form {mlp_form!r}; expected one of {', '.join(MLP_FORMS)}")
    unrolled = mlp_form == "unrolled" or (mlp_form == "auto" and target != "cpp")
    plan = specialisation(model, materials, scene)
    check_material_selection(model, plan.names)
    a, t = model.arch, model.tensors
    layers, head_in_material, n_in, latent_in = network_layers(
        model, plan.names, fold_latent=plan.fold_latent, analytic_only=plan.analytic_only,
        literal_head=literal_head, precision=precision, unrolled=unrolled,
        let=DIALECTS[target]["let"])
    px = _pixel_split(model, target, unrolled, plan, layers, latent_in, precision) if pixel_split else None
    # The neural baseline's network predicts shading frames from the latent code (spec: 'frames').
    predicts_frames = spec.ARCHS[model.kind]["directions"] == "frames"
    return template("hbrdf.j2").render(
        d=DIALECTS[target], target=target, model_path=comment_text(model_path), extra_args=comment_text(extra_args),
        kind=model.kind, width=a["width"], depth=a["depth"], activation=a["activation"], latent=a["latent"],
        latent_in=latent_in, z_len=max(a["latent"], 1), n_in=n_in, n_out=a["n_out"], max_width=max(n_in, a["width"]),
        conventions_version=_core.CONVENTIONS_VERSION, specialised=scene is not None,
        scene_name=comment_text((scene or {}).get("name", "")), analytic_only=plan.analytic_only,
        not_emitted=[comment_text(n) for n in (scene or {}).get("not_emitted", [])],
        neural_max_depth=plan.neural_max_depth, depth_limited=plan.neural_max_depth != NO_DEPTH_LIMIT,
        isotropic_only=plan.isotropic_only, fold_latent=plan.fold_latent, fp16=precision == "fp16",
        unrolled=unrolled, mixed=plan.mixed, head_in_material=head_in_material,
        energy_bound=a.get("energy_bound", "none") == "albedo_table", energy_nodes=spec.ENERGY_NODES,
        head_unrolled=unrolled_head(a["width"], a["n_out"], a["depth"]) if head_in_material and unrolled else [],
        material_names=[comment_text(n) for n in plan.names], materials=_material_constants(model, plan, head_in_material),
        layers=layers, alpha_min=float_literal(spec.ALPHA_MIN), arch=spec.ARCHS[model.kind], c=contract_literals(),
        pre_exp_max=float_literal(a["pre_exp_max"]),
        frames_unrolled=unrolled_frames(t) if unrolled and predicts_frames else [],
        frames_weight=t["frames.weight"].ravel() if predicts_frames else [],
        frames_bias=t["frames.bias"] if predicts_frames else [],
        tx=textured_code(textured, target) if textured is not None else None, px=px)


def pixel_split_problem(model: HybridModel, target: str = "glsl", unrolled: bool = True,
                        analytic_only: bool = False) -> Optional[str]:
    """Why ``model``'s code for ``target`` has no per-pixel form (``generate(..., pixel_split=True)``),
    or None where it has one: GLSL or HLSL, unrolled, a network, direction inputs with wi and wo apart."""
    directions = spec.ARCHS[model.kind]["directions"]
    return ("GLSL and HLSL only" if target not in ("glsl", "hlsl") else
            "the unrolled form only" if not unrolled else
            "no network to split (analytic only)" if analytic_only else
            f"the {directions!r} direction inputs mix wi and wo" if directions not in ("local", "local_half") else None)


def _pixel_split(model: HybridModel, target: str, unrolled: bool, plan: Specialisation, layers, latent_in: int,
                 precision: str) -> Dict[str, List[str]]:
    """The statements of the per-pixel form (codegen/pixel.j2): the first layer split into what a
    pixel's lights share (latent code, wo) and what each light adds (wi and what depends on it).
    ValueError where there is no such split or it is not written (one line naming why)."""
    why = pixel_split_problem(model, target, unrolled, plan.analytic_only)
    if why:
        raise ValueError(f"pixel_split: {why} (the per-pixel form needs wo's first-layer terms apart from wi's)")
    n_dir = spec.ARCHS[model.kind]["direction_count"]
    pixel_inputs = {n_dir + k: f"m.z[{k}]" for k in range(latent_in)}  # latent first: constants fold
    pixel_inputs.update({3: "wo.x", 4: "wo.y", 5: "wo.z"})
    pixel, light = split_first_layer(layers[0], pixel_inputs, precision == "fp16", DIALECTS[target]["let"])
    return {"pixel": pixel, "light": light}
