"""Code generation: a model file becomes self-contained GLSL, HLSL or C++ code.

    hbrdf-codegen MODEL --target glsl|hlsl|cpp [--materials a,b] -o OUT

One Jinja2 template (``codegen/hbrdf.j2``) serves every target; a small
dialect table (:data:`DIALECTS`) holds what differs between the languages.
The generated code defines, with the same names in every dialect:

- ``struct HbrdfMaterial { kd, eta, alpha_x, alpha_y, z[] }`` and one constant
  ``HBRDF_MATERIAL_<NAME>`` per material (name upper-cased, other characters ``_``);
- ``hbrdf_eval(wi, wo, m)`` (the full model, f without the cosine),
  ``hbrdf_eval_analytic(wi, wo, m)``, ``hbrdf_pdf(wi, wo, m)`` and
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

from hybridbrdf import _core
from hybridbrdf.errors import InputFileError
from hybridbrdf.model_file import HybridModel, load_model
from hybridbrdf.util import atomic_write_bytes

TARGETS = ("glsl", "hlsl", "cpp")


def _template_dir() -> pathlib.Path:
    here = pathlib.Path(__file__).resolve().parent
    for candidate in (here / "codegen", here.parents[1] / "codegen"):
        if (candidate / "hbrdf.j2").is_file():
            return candidate
    raise FileNotFoundError("codegen templates (hbrdf.j2) not found next to the package or in the source tree")


def float_literal(x: float) -> str:
    """A float32 value as a literal every dialect reads back to the same float32."""
    s = f"{float(np.float32(x)):.9g}"
    if "e" not in s and "." not in s:
        s += ".0"
    return s + "f"


def _glsl_array(n: int, values) -> str:
    return f"float[{n}](" + ", ".join(float_literal(v) for v in values) + ")"


def _brace_array(n: int, values) -> str:
    return "{" + ", ".join(float_literal(v) for v in values) + "}"


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
inline float3 cross(const float3 a, const float3 b) {
    return float3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
"""

DIALECTS: Dict[str, Dict[str, object]] = {
    "glsl": {"name": "GLSL 4.50", "comment": "//", "prelude": "", "epilogue": "", "v3": "vec3", "v2": "vec2",
             "const": "const", "fn": "", "out_array": "out ", "out_float": lambda n: f"out float {n}",
             "array": _glsl_array, "struct_open": lambda t: f"{t}(", "struct_close": ")"},
    "hlsl": {"name": "HLSL (Shader Model 5+, glslang/DXC)", "comment": "//", "prelude": "", "epilogue": "",
             "v3": "float3", "v2": "float2", "const": "static const", "fn": "", "out_array": "out ",
             "out_float": lambda n: f"out float {n}", "array": _brace_array,
             "struct_open": lambda t: "{", "struct_close": "}"},
    "cpp": {"name": "C++17, dependency-free", "comment": "//", "prelude": CPP_PRELUDE,
            "epilogue": "}  // namespace hbrdf", "v3": "float3", "v2": "float2", "const": "inline constexpr",
            "fn": "inline ", "out_array": "", "out_float": lambda n: f"float& {n}", "array": _brace_array,
            "struct_open": lambda t: "{", "struct_close": "}"},
}


def material_constant(name: str) -> str:
    """HBRDF_MATERIAL_<NAME>: upper-cased, every non-identifier character turned into '_'."""
    return "HBRDF_MATERIAL_" + re.sub(r"[^A-Za-z0-9_]", "_", name).upper()


def generate(model: HybridModel, target: str, materials: Optional[Sequence[str]] = None,
             model_path: str = "MODEL", extra_args: str = "") -> str:
    """Source code of ``model`` for ``target`` (glsl, hlsl or cpp), for all or the named materials."""
    if target not in DIALECTS:
        raise ValueError(f"unknown target {target!r}; expected one of {', '.join(TARGETS)}")
    import jinja2

    names = list(materials) if materials else model.materials
    for n in names:
        model.index(n)  # KeyError naming the material if absent
    consts = [material_constant(n) for n in names]
    clash = sorted({c for c in consts if consts.count(c) > 1})
    if clash:
        raise ValueError(f"materials map to the same constant name: {', '.join(clash)}")
    a = model.arch
    latent = a["latent"]
    t = model.tensors
    layers = []
    for i in range(a["depth"]):
        w = t[f"mlp.hidden.{i}.weight"]
        layers.append({"n_in": w.shape[1], "n_out": w.shape[0], "weight": w.ravel(), "bias": t[f"mlp.hidden.{i}.bias"]})
    w = t["mlp.out.weight"]
    layers.append({"n_in": w.shape[1], "n_out": w.shape[0], "weight": w.ravel(), "bias": t["mlp.out.bias"]})
    mats = []
    for n, c in zip(names, consts):
        i = model.index(n)
        z = list(t["materials.z"][i]) or [0.0]
        if model.kind == "neural":
            kd, eta, alpha = [0.0] * 3, [1.0] * 3, [1.0, 1.0]
        else:
            kd, eta, alpha = t["materials.kd"][i], t["materials.eta"][i], t["materials.alpha"][i]
        mats.append({"const_name": c, "kd": [float_literal(v) for v in kd], "eta": [float_literal(v) for v in eta],
                     "alpha": [float_literal(v) for v in alpha], "z": z})
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(_template_dir())), undefined=jinja2.StrictUndefined,
                             keep_trailing_newline=True)
    d = DIALECTS[target]
    text = env.get_template("hbrdf.j2").render(
        d=d, target=target, model_path=model_path, extra_args=extra_args, kind=model.kind, width=a["width"],
        depth=a["depth"], activation=a["activation"], latent=latent, z_len=max(latent, 1), n_in=a["n_in"],
        n_out=a["n_out"], max_width=max(a["n_in"], a["width"]), conventions_version=_core.CONVENTIONS_VERSION,
        material_names=names, materials=mats, layers=layers, alpha_min=float_literal(_core.ALPHA_MIN),
        pre_exp_max=float_literal(a.get("pre_exp_max", 16.0)),
        frames_weight=t["frames.weight"].ravel() if model.kind == "neural" else [],
        frames_bias=t["frames.bias"] if model.kind == "neural" else [])
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="hbrdf-codegen", description="Generate GLSL, HLSL or C++ code from a model file.")
    ap.add_argument("model", help="model file written by hbrdf fit")
    ap.add_argument("--target", required=True, choices=TARGETS, help="output language")
    ap.add_argument("--materials", help="comma-separated material names to include (default: all)")
    ap.add_argument("-o", "--out", required=True, help="file to write (written atomically)")
    args = ap.parse_args(argv)
    try:
        model = load_model(args.model)
        materials = [m for m in args.materials.split(",") if m] if args.materials else None
        extra = f" --materials {args.materials}" if args.materials else ""
        text = generate(model, args.target, materials, model_path=os.path.basename(args.model), extra_args=extra)
        atomic_write_bytes(args.out, text.encode("utf-8"))
    except (InputFileError, ValueError, KeyError, OSError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        print(f"hbrdf-codegen: error: {msg}", file=sys.stderr)
        return 1
    print(f"wrote {args.out} ({args.target}, {len(materials or model.materials)} materials)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
