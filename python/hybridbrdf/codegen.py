"""Code generation: a model file becomes self-contained GLSL, HLSL or C++ code.

    hbrdf-codegen MODEL --target glsl|hlsl|cpp [--materials a,b | --scene SCENE.json] -o OUT

One Jinja2 template (``codegen/hbrdf.j2``) serves every target; a small
dialect table (:data:`DIALECTS`) holds what differs between the languages.
The generated code defines, with the same names in every dialect:

- ``struct HbrdfMaterial { kd, eta, alpha_x, alpha_y, z[] }`` and one constant
  ``HBRDF_MATERIAL_<NAME>`` per material (name upper-cased, other characters ``_``);
- ``hbrdf_eval(wi, wo, m)`` (the full model, f without the cosine),
  ``hbrdf_eval_analytic(wi, wo, m)``, ``hbrdf_eval_depth(wi, wo, m, depth)`` (f_a from depth
  ``HBRDF_NEURAL_MAX_DEPTH`` on, the scene's neural_max_depth), ``hbrdf_pdf(wi, wo, m)`` and
  ``hbrdf_sample(wo, u, m, out pdf)`` (MIS of cosine and GGX lobes, as the library);
- in C++ everything lives in namespace ``hbrdf`` with its own ``hbrdf::float3``.

Weights are printed with 9 significant digits, which round-trips float32 exactly.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import re
import sys
from typing import Dict, List, Optional, Sequence

import numpy as np

from hybridbrdf import _core, spec
from hybridbrdf.errors import InputFileError, one_line_text
from hybridbrdf.inputs import refuse_output_over_input, same_file as _same_file
from hybridbrdf.model_file import HybridModel, load_model
from hybridbrdf.names import names_problem, shader_constant_key
from hybridbrdf.shaders import render_shader
from hybridbrdf.util import atomic_write_bytes, check_writable, package_data_dir

TARGETS = ("glsl", "hlsl", "cpp", "brdfexplorer")
MLP_FORMS = ("auto", "unrolled", "loops")


def _template_dir() -> pathlib.Path:
    return package_data_dir("codegen", "hbrdf.j2")


def comment_text(text: str) -> str:
    """``text`` made safe inside a ``//`` comment of every target: printable ASCII stays, and
    every other character, as well as '%', '?' and '\\', is percent-encoded (its UTF-8 bytes as
    %XX). Why those three: a newline or carriage return ends the comment and a backslash at the
    end of a line (or the trigraph ``??/`` in a C++ compiler that honours trigraphs) splices the
    next line into it; '%' keeps the encoding unambiguous. File names and scene keys reach the
    generated headers' comments only through here."""
    out = []
    for ch in text:
        if " " <= ch <= "~" and ch not in "%?\\":
            out.append(ch)
        else:
            out.extend(f"%{b:02X}" for b in ch.encode("utf-8", "surrogateescape"))
    return "".join(out)


def float_literal(x: float) -> str:
    """A float32 value as a literal every dialect reads back to the same float32.
    Raises ValueError for NaN and for values that are infinite in float32 (no dialect has a
    literal for them: the code would not compile)."""
    with np.errstate(over="ignore"):
        finite = np.isfinite(np.float32(x))
    if not finite:
        raise ValueError(f"cannot write {float(x)!r} as a float32 literal (not finite in float32)")
    s = f"{float(np.float32(x)):.9g}"
    if "e" not in s and "." not in s:
        s += ".0"
    return s + "f"


def _glsl_array(n: int, values) -> str:
    return f"float[{n}](" + ", ".join(float_literal(v) for v in values) + ")"


def _brace_array(n: int, values) -> str:
    return "{" + ", ".join(float_literal(v) for v in values) + "}"


def half_pairs(values) -> List[int]:
    """float32 values rounded to IEEE binary16 and packed two per uint32 (even index low)."""
    with np.errstate(over="ignore"):  # only --precision fp16 uses them, and it refuses such weights first
        bits = np.asarray(values, dtype=np.float32).astype(np.float16).view(np.uint16).astype(np.uint32)
    if len(bits) % 2:
        bits = np.append(bits, np.uint32(0))
    return [int(lo | (hi << 16)) for lo, hi in zip(bits[0::2], bits[1::2])]


def _hex_list(values) -> str:
    return ", ".join(f"0x{v:08x}u" for v in values)


CPP_PRELUDE = """#pragma once
#include <cmath>

namespace hbrdf {

using std::cos;
using std::exp;
using std::log;
using std::sin;
using std::sqrt;

struct float3 {
    float x, y, z;
    float3() = default;
    constexpr float3(float a, float b, float c) : x(a), y(b), z(c) {}
};
struct float2 {
    float x, y;
    float2() = default;
    constexpr float2(float a, float b) : x(a), y(b) {}
};
inline float3 operator+(const float3 a, const float3 b) { return float3(a.x + b.x, a.y + b.y, a.z + b.z); }
inline float3 operator-(const float3 a, const float3 b) { return float3(a.x - b.x, a.y - b.y, a.z - b.z); }
inline float3 operator*(const float3 a, const float3 b) { return float3(a.x * b.x, a.y * b.y, a.z * b.z); }
inline float3 operator*(const float3 a, float s) { return float3(a.x * s, a.y * s, a.z * s); }
inline float3 operator*(float s, const float3 a) { return float3(a.x * s, a.y * s, a.z * s); }
inline float3 operator/(const float3 a, float s) { return float3(a.x / s, a.y / s, a.z / s); }
inline float dot(const float3 a, const float3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
// IEEE binary16 (low 16 bits of h) to float, subnormals included; used for fp16 weights.
inline float hbrdf_half_to_float(unsigned h) {
    const unsigned sign = (h & 0x8000u) << 16, exponent = (h >> 10) & 0x1fu, mantissa = h & 0x3ffu;
    float magnitude;
    if (exponent == 0) magnitude = std::ldexp(float(mantissa), -24);
    else if (exponent == 31) magnitude = mantissa ? NAN : INFINITY;
    else magnitude = std::ldexp(float(mantissa | 0x400u), int(exponent) - 25);
    return sign ? -magnitude : magnitude;
}
inline float3 cross(const float3 a, const float3 b) {
    return float3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
"""

DIALECTS: Dict[str, Dict[str, object]] = {
    "glsl": {"name": "GLSL 4.50", "comment": "//", "prelude": "", "epilogue": "", "v3": "vec3", "v2": "vec2",
             "const": "const", "fn": "", "out_array": "out ", "out_float": lambda n: f"out float {n}",
             "unused": lambda n: "",
             "array": _glsl_array, "struct_open": lambda t: f"{t}(", "struct_close": ")", "uint": "uint",
             "uint_array": lambda n, v: f"uint[{n}](" + _hex_list(v) + ")",
             "weight": lambda a, i: f"unpackHalf2x16({a}[({i}) >> 1])[({i}) & 1]"},
    "hlsl": {"name": "HLSL (Shader Model 5+, glslang/DXC)", "comment": "//", "prelude": "", "epilogue": "",
             "v3": "float3", "v2": "float2", "const": "static const", "fn": "", "out_array": "out ",
             "unused": lambda n: "",
             "out_float": lambda n: f"out float {n}", "array": _brace_array,
             "struct_open": lambda t: "{", "struct_close": "}", "uint": "uint",
             "uint_array": lambda n, v: "{" + _hex_list(v) + "}",
             "weight": lambda a, i: f"f16tof32({a}[({i}) >> 1] >> (16u * (uint({i}) & 1u)))"},
    "cpp": {"name": "C++17, dependency-free", "comment": "//", "prelude": CPP_PRELUDE,
            "epilogue": "}  // namespace hbrdf", "v3": "float3", "v2": "float2", "const": "inline constexpr",
            "fn": "inline ", "out_array": "", "out_float": lambda n: f"float& {n}", "array": _brace_array,
            "unused": lambda n: f"(void){n}; ",  # a parameter the code ignores, without -Wunused-parameter
            "struct_open": lambda t: "{", "struct_close": "}", "uint": "unsigned",
            "uint_array": lambda n, v: "{" + _hex_list(v) + "}",
            "weight": lambda a, i: f"hbrdf_half_to_float({a}[({i}) >> 1] >> (16u * unsigned(({i}) & 1)))"},
}


def unrolled_layer(layer: Dict[str, object], index: int, last: bool, fp16: bool = False) -> List[str]:
    """Statements of one fully connected layer with its weights as literals:
    ``float h<index>_<j> = hbrdf_activation(b + w * x + ...);`` (``o[j] = ...`` for the
    output layer). Inputs are ``x[k]`` for the first layer and the previous layer's
    ``h`` otherwise; exactly-zero weights are left out (the inputs are finite).
    ``fp16`` rounds the weights (not the bias) to binary16 first."""
    n_in, n_out = layer["n_in"], layer["n_out"]
    w = np.asarray(layer["weight"], dtype=np.float32).reshape(n_out, n_in)
    if fp16:
        w = w.astype(np.float16).astype(np.float32)
    b = np.asarray(layer["bias"], dtype=np.float32)
    inputs = [f"x[{k}]" for k in range(n_in)] if index == 0 else [f"h{index - 1}_{k}" for k in range(n_in)]
    lines = []
    for j in range(n_out):
        terms = [float_literal(b[j])]
        for k in range(n_in):
            if w[j, k] != 0.0:
                terms.append(f"{'-' if w[j, k] < 0 else '+'} {float_literal(abs(w[j, k]))} * {inputs[k]}")
        expr = " ".join(terms)
        lines.append(f"o[{j}] = {expr};" if last else f"float h{index}_{j} = hbrdf_activation({expr});")
    return lines


def unrolled_head(width: int, n_out: int, depth: int) -> List[str]:
    """The output layer of a model with material output layers, read from the material:
    ``o[j] = m.head_b[j] + m.head_w[j * width + k] * h<depth-1>_k + ...`` with constant indices
    (shader compilers then address the material's constants directly, no dynamic indexing)."""
    lines = []
    for j in range(n_out):
        terms = [f"m.head_b[{j}]"] + [f"+ m.head_w[{j * width + k}] * h{depth - 1}_{k}" for k in range(width)]
        lines.append(f"o[{j}] = {' '.join(terms)};")
    return lines


def _unrolled_frames(tensors) -> List[str]:
    """``raw_frames[j] = b + W z`` for the neural baseline's 18 frame outputs, weights as literals."""
    w = np.asarray(tensors["frames.weight"], dtype=np.float32)
    b = np.asarray(tensors["frames.bias"], dtype=np.float32)
    lines = []
    for j in range(w.shape[0]):
        terms = [float_literal(b[j])] + [f"{'-' if w[j, k] < 0 else '+'} {float_literal(abs(w[j, k]))} * m.z[{k}]"
                                         for k in range(w.shape[1]) if w[j, k] != 0.0]
        lines.append(f"raw_frames[{j}] = {' '.join(terms)};")
    return lines


def contract_literals() -> Dict[str, str]:
    """The model contract's constants (spec/model.json) as float literals for the template."""
    c = {k: float_literal(getattr(spec, k.upper())) for k in
         ("kd_min", "kd_max", "eta_min", "eta_max", "alpha_max", "hardgelu_knee",
                                                    "mis_min_lobe_probability")}
    c["hardgelu_inv_width"] = float_literal(np.float32(1.0) / np.float32(2.0 * spec.HARDGELU_KNEE))
    return c


def material_constant(name: str) -> str:
    """HBRDF_MATERIAL_<NAME>: upper-cased, every non-identifier character turned into '_'
    (hybridbrdf.names.shader_constant_key; the model contract keeps them distinct)."""
    return "HBRDF_MATERIAL_" + shader_constant_key(name)


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


_HALF_MAX = 65504.0  # largest finite IEEE binary16 value


def _check_half_range(layers) -> None:
    """--precision fp16 rounds layer weights to binary16: one beyond +-65504 would become Inf and
    every output NaN, so it is an error, not a silent overflow."""
    for i, layer in enumerate(layers):
        top = float(np.abs(layer["weight"]).max(initial=0.0))
        if top > _HALF_MAX:
            raise ValueError(f"--precision fp16: layer {i} has a weight of magnitude {top:.6g}, beyond the "
                             f"half-precision range (65504); use --precision fp32")


_F_SUFFIX = re.compile(r"(?<=[0-9.])f\b")


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
    the ``scene`` argument of :func:`generate`. Raises ValueError "<scene>: <where>: <problem>"."""
    import json

    from hybridbrdf.render import load_scene_dict

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


def generate(model: HybridModel, target: str, materials: Optional[Sequence[str]] = None,
             model_path: str = "MODEL", extra_args: str = "", scene: Optional[Dict[str, object]] = None,
             precision: str = "fp32", mlp_form: str = "auto", literal_head: Optional[str] = None) -> str:
    """Source code of ``model`` for ``target`` (glsl, hlsl, cpp or brdfexplorer), for all or
    the named materials. For brdfexplorer the first (or only) material gives the parameters'
    default values; kd, eta, alpha and the latent code become sliders.

    ``mlp_form`` is "unrolled" (straight-line code, weights as literals), "loops"
    (weights in constant arrays, loops over them) or "auto": unrolled for GLSL and HLSL
    (shader compilers turn constant arrays indexed in loops into per-invocation memory;
    see docs/CODEGEN.md), loops for C++ (the C++ compiler vectorises the loops).
    With ``precision="fp16"`` the layer weights are rounded to IEEE binary16: unrolled
    code prints the rounded values (exactly), loops store them packed two per 32-bit word.
    ``scene`` is the plan :func:`load_scene` makes of a path-tracer scene: ``{"name", "materials":
    [{"name", "evaluate"}], "neural_max_depth" (optional), "not_emitted" (optional)}``."""
    if target == "brdfexplorer":
        return _generate_brdfexplorer(model, materials, model_path, extra_args)
    if target not in DIALECTS:
        raise ValueError(f"unknown target {target!r}; expected one of {', '.join(TARGETS)}")
    if precision not in ("fp32", "fp16"):
        raise ValueError(f"unknown precision {precision!r}; expected fp32 or fp16")
    if mlp_form not in MLP_FORMS:
        raise ValueError(f"unknown MLP form {mlp_form!r}; expected one of {', '.join(MLP_FORMS)}")
    unrolled = mlp_form == "unrolled" or (mlp_form == "auto" and target != "cpp")
    import jinja2

    names = list(materials) if materials else model.materials
    analytic_only = isotropic_only = fold_latent = mixed = False
    flags = {}
    neural_max_depth = NO_DEPTH_LIMIT
    if scene is not None:
        # Simulate only what the scene calls for (docs/CODEGEN.md, "Specialisation").
        names = [m["name"] for m in scene["materials"]]
        if scene.get("neural_max_depth") is not None:
            neural_max_depth = int(scene["neural_max_depth"])
        # neural_max_depth 0: the tracer renders f_a at every depth, so no network at all (the
        # neural baseline has no f_a; the tracer, and so hbrdf_eval_depth, always runs its network).
        analytic_only = all(m["evaluate"] == "analytic" for m in scene["materials"]) or (
            neural_max_depth == 0 and model.has_analytic)
        # Some materials full, others analytic-only: the network stays, and a per-material
        # flag makes hbrdf_eval skip it (a branch that is uniform across a draw call).
        mixed = not analytic_only and any(m["evaluate"] == "analytic" for m in scene["materials"])
        if any(m["evaluate"] == "analytic" for m in scene["materials"]) and not model.has_analytic:
            raise ValueError("the scene asks for analytic-only evaluation but the model is the neural baseline")
        isotropic_only = model.has_analytic and all(
            model.material_info[model.index(n)].get("isotropic", True) for n in names)
        fold_latent = len(names) == 1 and not analytic_only
        flags = {m["name"]: m["evaluate"] == "analytic" for m in scene["materials"]}
    check_material_selection(model, names)
    consts = [material_constant(n) for n in names]
    a = model.arch
    latent = a["latent"]
    t = model.tensors
    layers = []
    for i in range(a["depth"]):
        w = t[f"mlp.hidden.{i}.weight"]
        layers.append({"n_in": w.shape[1], "n_out": w.shape[0], "weight": w.ravel(), "bias": t[f"mlp.hidden.{i}.bias"]})
    # The output layer: the shared one; with material output layers (spec/model.json) each
    # material's own, held in HbrdfMaterial as engines hold per-material constants, or as
    # literals where one material is emitted for a scene (or literal_head names it).
    heads = a.get("output_layer", "shared") == "material"
    head_in_material = False
    if not heads:
        w = t["mlp.out.weight"]
        layers.append({"n_in": w.shape[1], "n_out": w.shape[0], "weight": w.ravel(), "bias": t["mlp.out.bias"]})
    elif literal_head is not None or (fold_latent and not analytic_only):
        i = model.index(literal_head if literal_head is not None else names[0])
        w = t["materials.head_weight"][i]
        layers.append({"n_in": w.shape[1], "n_out": w.shape[0], "weight": w.ravel(), "bias": t["materials.head_bias"][i]})
    elif not analytic_only:
        head_in_material = True
    n_in, latent_in = a["n_in"], latent
    if fold_latent and latent:
        # One material: its latent inputs are constants, so W0[:, z] z joins the first bias.
        z_start = spec.ARCHS[model.kind]["direction_count"]
        w0 = t["mlp.hidden.0.weight"].astype(np.float64)
        z = t["materials.z"][model.index(names[0])].astype(np.float64)
        bias = (t["mlp.hidden.0.bias"].astype(np.float64) + w0[:, z_start:z_start + latent] @ z).astype(np.float32)
        w0 = np.delete(w0, np.s_[z_start:z_start + latent], axis=1).astype(np.float32)
        layers[0] = {"n_in": w0.shape[1], "n_out": w0.shape[0], "weight": w0.ravel(), "bias": bias}
        n_in, latent_in = n_in - latent, 0
    if precision == "fp16":
        _check_half_range(layers)
    for i, layer in enumerate(layers):
        layer["weight_half_pairs"] = half_pairs(layer["weight"])
        layer["unrolled"] = (unrolled_layer(layer, i, i == len(layers) - 1 and not head_in_material,
                                            precision == "fp16") if unrolled else [])
    # The neural baseline's network predicts shading frames from the latent code (spec: 'frames').
    predicts_frames = spec.ARCHS[model.kind]["directions"] == "frames"
    mats = []
    for n, c in zip(names, consts):
        i = model.index(n)
        z = list(t["materials.z"][i]) or [0.0]
        if not model.has_analytic:
            kd, eta, alpha = [0.0] * 3, [1.0] * 3, [1.0, 1.0]
        else:
            kd, eta, alpha = t["materials.kd"][i], t["materials.eta"][i], t["materials.alpha"][i]
        mats.append({"const_name": c, "kd": [float_literal(v) for v in kd], "eta": [float_literal(v) for v in eta],
                     "alpha": [float_literal(v) for v in alpha], "z": z,
                     "head_w": t["materials.head_weight"][i].ravel() if head_in_material else [],
                     "head_b": t["materials.head_bias"][i] if head_in_material else [],
                     "analytic_only": "true" if flags.get(n, False) else "false"})
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(_template_dir())), undefined=jinja2.StrictUndefined,
                             keep_trailing_newline=True)
    d = DIALECTS[target]
    text = env.get_template("hbrdf.j2").render(
        d=d, target=target, model_path=comment_text(model_path), extra_args=comment_text(extra_args), kind=model.kind, width=a["width"],
        depth=a["depth"], activation=a["activation"], latent=latent, latent_in=latent_in, z_len=max(latent, 1),
        n_in=n_in, n_out=a["n_out"], max_width=max(n_in, a["width"]), conventions_version=_core.CONVENTIONS_VERSION,
        specialised=scene is not None, scene_name=comment_text((scene or {}).get("name", "")), analytic_only=analytic_only,
        not_emitted=[comment_text(n) for n in (scene or {}).get("not_emitted", [])], neural_max_depth=neural_max_depth,
        depth_limited=neural_max_depth != NO_DEPTH_LIMIT,
        isotropic_only=isotropic_only, fold_latent=fold_latent, fp16=precision == "fp16", unrolled=unrolled,
        mixed=mixed, head_in_material=head_in_material,
        head_unrolled=unrolled_head(a["width"], a["n_out"], a["depth"]) if head_in_material and unrolled else [],
        material_names=[comment_text(n) for n in names], materials=mats, layers=layers, alpha_min=float_literal(spec.ALPHA_MIN), arch=spec.ARCHS[model.kind], c=contract_literals(),
        pre_exp_max=float_literal(a["pre_exp_max"]),
        frames_unrolled=_unrolled_frames(t) if unrolled and predicts_frames else [],
        frames_weight=t["frames.weight"].ravel() if predicts_frames else [],
        frames_bias=t["frames.bias"] if predicts_frames else [])
    return text


def _param_line_value(x: float) -> str:
    s = f"{float(np.float32(x)):.9g}"
    return s if ("." in s or "e" in s) else s + ".0"


def _generate_brdfexplorer(model: HybridModel, materials, model_path: str, extra_args: str) -> str:
    import jinja2

    names = list(materials) if materials else model.materials
    check_material_selection(model, names)
    default = model.index(names[0])
    # The GLSL body without material constants; BRDF Explorer's GLSL takes no 'f' suffixes.
    # A model with material output layers: the default material's head as literals (the sliders
    # move p and z; a head has 6 x width numbers, no slider's worth).
    literal = names[0] if model.arch.get("output_layer", "shared") == "material" else None
    body = generate(model, "glsl", [names[0]], model_path, extra_args, literal_head=literal)
    body = "\n".join(line for line in body.splitlines()
                      if not line.startswith(("const HbrdfMaterial", "// hybridbrdf generated", "//   hbrdf-codegen")))
    body = _F_SUFFIX.sub("", body)
    t = model.tensors
    latent = model.arch["latent"]
    params = []
    if model.has_analytic:
        for label, key, lo, hi in (("kd", "materials.kd", 0.0, 1.0), ("eta", "materials.eta", 1.0, 10.0)):
            for c, ch in enumerate("rgb"):
                params.append({"name": f"{label}_{ch}", "min": _param_line_value(lo), "max": _param_line_value(hi),
                               "default": _param_line_value(t[key][default, c])})
        for c, ax in enumerate("xy"):
            params.append({"name": f"alpha_{ax}", "min": _param_line_value(_core.ALPHA_MIN), "max": "1.0",
                           "default": _param_line_value(t["materials.alpha"][default, c])})
    else:
        for label, value in (("kd", 0.0), ("eta", 1.0)):
            for ch in "rgb":
                params.append({"name": f"{label}_{ch}", "min": "0.0", "max": "10.0", "default": _param_line_value(value)})
        for ax in "xy":
            params.append({"name": f"alpha_{ax}", "min": "0.0001", "max": "1.0", "default": "1.0"})
    z = t["materials.z"]
    span = float(np.abs(z).max()) * 2.0 + 1.0 if z.size else 1.0
    for k in range(latent):
        params.append({"name": f"z{k}", "min": _param_line_value(-span), "max": _param_line_value(span),
                       "default": _param_line_value(z[default, k])})
    z_args = ", ".join(f"z{k}" for k in range(latent)) if latent else "0.0"
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(_template_dir())), undefined=jinja2.StrictUndefined,
                             keep_trailing_newline=True)
    a = model.arch
    return env.get_template("brdfexplorer.j2").render(
        model_path=comment_text(model_path), extra_args=comment_text(extra_args), kind=model.kind, width=a["width"],
        depth=a["depth"], activation=a["activation"], latent=latent, conventions_version=_core.CONVENTIONS_VERSION,
        default_material=comment_text(names[0]), material_names=[comment_text(n) for n in model.materials], params=params, body=body,
        z_len=max(latent, 1), z_args=z_args)


def eval_compute_shader(function: str, material_constant_name: str, include: str, target: str = "glsl",
                        n: Optional[int] = None, directions: str = "buffer") -> str:
    """A compute shader (64 invocations per workgroup, GLSL or HLSL for glslang's HLSL front end)
    that includes the generated file ``include`` and writes ``function(wi, wo, MATERIAL)``
    (hbrdf_eval or hbrdf_eval_analytic) for pairs read from binding 0 (6 floats each) to
    binding 1 (3 floats each); with ``n`` set, invocations past the n-th pair return early.
    The kernel of spirv_size, bench/bench_inference.py and the shader conformance tests; its
    source is glsl/eval.comp.glsl or glsl/eval.comp.hlsl.

    ``directions="synthetic"`` (GLSL only, for speed measurements) makes each invocation's pair
    in the shader from a hash of its index instead of reading it (glsl/eval_synthetic.comp.glsl):
    under lavapipe (AVX2 only) the six per-lane buffer loads take about a quarter of a 32x2's
    evaluation time (docs/CODEGEN.md), which is the harness's cost, not the BRDF's. There ``function`` may also be "hbrdf_harness_only"
    (the kernel without the BRDF)."""
    if target not in ("glsl", "hlsl"):
        raise ValueError(f"eval_compute_shader: target must be glsl or hlsl, got {target!r}")
    if directions not in ("buffer", "synthetic"):
        raise ValueError(f"eval_compute_shader: directions must be buffer or synthetic, got {directions!r}")
    if directions == "synthetic":
        if target != "glsl" or n is not None:
            raise ValueError("eval_compute_shader: synthetic directions are GLSL only and take no pair count")
        return render_shader("eval_synthetic.comp.glsl", include=include, function=function,
                             material=material_constant_name, n=None)
    return render_shader(f"eval.comp.{target}", include=include, function=function,
                         material=material_constant_name, n=n)


def spirv_size(glsl_code: str, material_constant_name: str, workdir) -> int:
    """Bytes of the SPIR-V (glslangValidator -V, optimised with -Os) of a compute shader
    that evaluates ``hbrdf_eval`` for one material of the given generated GLSL."""
    import subprocess

    workdir = pathlib.Path(workdir)
    (workdir / "probe_model.glsl").write_text(glsl_code)
    src = workdir / "probe.comp"
    src.write_text(eval_compute_shader("hbrdf_eval", material_constant_name, "probe_model.glsl"))
    spv = workdir / "probe.spv"
    r = subprocess.run(["glslangValidator", "-V", "-Os", "--target-env", "vulkan1.1", "-I" + str(workdir), str(src),
                        "-o", str(spv)], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"glslangValidator failed: {r.stdout[-2000:]}")
    return spv.stat().st_size


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="hbrdf-codegen", description="Generate GLSL, HLSL or C++ code from a model file.")
    ap.add_argument("model", help="model file written by hbrdf fit")
    ap.add_argument("--target", required=True, choices=TARGETS, help="output language")
    ap.add_argument("--materials", help="comma-separated material names to include (default: all)")
    ap.add_argument("--scene", help="path-tracer scene file (docs/RENDERING.md): emit only its materials of type "
                                    "\"model\" in MODEL and specialise the code (isotropic-only GGX, no network for "
                                    "analytic-only scenes, latent folded for one material, neural_max_depth as "
                                    "HBRDF_NEURAL_MAX_DEPTH and hbrdf_eval_depth)")
    ap.add_argument("--precision", choices=("fp32", "fp16"), default="fp32",
                    help="layer weights: fp32 (exact) or fp16 (rounded to IEEE half: exact half values as literals "
                         "in unrolled code, two per 32-bit word in loops)")
    ap.add_argument("--mlp-form", choices=MLP_FORMS, default="auto",
                    help="network code: unrolled (weights as literals), loops (weights in constant arrays) or auto "
                         "(default: unrolled for GLSL/HLSL, loops for C++)")
    ap.add_argument("-o", "--out", required=True, help="file to write (written atomically)")
    args = ap.parse_args(argv)
    try:
        # Before any work: -o naming the model or the scene (by any path) would replace it with code.
        refuse_output_over_input(args.out, [args.model, args.scene], "-o/--out")
        model = load_model(args.model)
        materials = [m for m in args.materials.split(",") if m] if args.materials else None
        if args.scene and materials:
            raise ValueError("give either --materials or --scene, not both")
        if args.scene and args.target == "brdfexplorer":
            raise ValueError("--scene specialises shader code for a path-tracer scene; a BRDF Explorer file "
                             "shows one material: give --materials NAME instead")
        check_writable(args.out, "generated code")
        scene = load_scene(args.scene, model, args.model) if args.scene else None
        extra = (f" --materials {args.materials}" if args.materials else "") + (f" --scene {args.scene}" if args.scene else "")
        if args.precision != "fp32":
            extra += f" --precision {args.precision}"
        if args.mlp_form != "auto":
            extra += f" --mlp-form {args.mlp_form}"
        if args.target == "brdfexplorer" and args.precision != "fp32":
            raise ValueError("--precision fp16 is not available for brdfexplorer")
        text = generate(model, args.target, materials, model_path=os.path.basename(args.model), extra_args=extra,
                        scene=scene, precision=args.precision, mlp_form=args.mlp_form)
        if scene is not None:
            materials = [m["name"] for m in scene["materials"]]
        atomic_write_bytes(args.out, text.encode("utf-8"))
    except (InputFileError, ValueError, KeyError, OSError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        print(f"hbrdf-codegen: error: {one_line_text(str(msg))}", file=sys.stderr)
        return 1
    print(f"wrote {args.out} ({args.target}, {len(materials or model.materials)} materials)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
