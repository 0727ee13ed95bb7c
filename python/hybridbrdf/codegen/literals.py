"""The literals of generated code: float and contract constants, comments, material constant
names, and the dialect table that holds what differs between GLSL, HLSL, Slang, WGSL and C++ (vector
types, declarations, constant and array syntax, selection, loops, out-parameters, the C++ prelude).
Every value the template prints goes through here, so that each dialect reads back the same float32."""

from __future__ import annotations

from typing import Dict, List

import numpy as np

from hybridbrdf import spec
from hybridbrdf.names import shader_constant_key


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

using std::abs;
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

# ---- declarations and statements, per dialect ---------------------------------------------------
# The template writes declarations in one abstract form, "[const|out] TYPE NAME[N]" with TYPE one of
# float, int, uint, bool, v3, v2 or HbrdfMaterial, and each dialect turns it into its own syntax:
# "const v3 wi" is GLSL's "const vec3 wi", HLSL's "const float3 wi", WGSL's "wi: vec3f".


def _parse_decl(text: str):
    """("const"/"out"/None, type, name, array length or None) of "[const|out] TYPE NAME[N]"."""
    words = text.split()
    qualifier = words[0] if words[0] in ("const", "out") else None
    typ, name = words[-2], words[-1]
    n = None
    if name.endswith("]"):
        name, n = name[:-1].split("[")
    return qualifier, typ, name, n


def _c_like(v3: str, v2: str, uint: str, const: str, fn: str, out_array: str, out_float):
    """Declarations and statements of the C-like dialects (GLSL, HLSL, Slang, C++)."""
    types = {"v3": v3, "v2": v2, "uint": uint}

    def decl(text: str) -> str:
        qualifier, typ, name, n = _parse_decl(text)
        return (f"{qualifier} " if qualifier == "const" else "") + f"{types.get(typ, typ)} {name}" + (
            f"[{n}]" if n is not None else "")

    def param(text: str) -> str:
        qualifier, typ, name, n = _parse_decl(text)
        if qualifier == "out":
            return out_float(name) if n is None else f"{out_array}{decl(text[4:])}"
        return decl(text)

    return {"decl": decl, "let": decl, "var": decl, "constant": lambda t: f"{const} {decl(t)}",
            "field": lambda t: f"{decl(t)};",
            "func": lambda ret, name, *params: f"{fn}{types.get(ret, ret)} {name}({', '.join(param(p) for p in params)})",
            "sel": lambda cond, t, f: f"{cond} ? {t} : {f}",
            "for_": lambda k, n: f"for (int {k} = 0; {k} < {n}; ++{k})",
            "block": lambda s: s, "deref": lambda n: n, "ref": lambda n: n,
            "immutable_params": False, "returns_arrays": False, "half_to_float": ""}


_WGSL_TYPES = {"float": "f32", "int": "i32", "uint": "u32", "bool": "bool", "v3": "vec3f", "v2": "vec2f"}


def _wgsl_type(typ: str, n=None) -> str:
    t = _WGSL_TYPES.get(typ, typ)
    return t if n is None else f"array<{t}, {n}>"


def _wgsl_name_type(text: str) -> str:
    _, typ, name, n = _parse_decl(text)
    return f"{name}: {_wgsl_type(typ, n)}"


def _wgsl_param(text: str) -> str:
    qualifier, typ, name, n = _parse_decl(text)
    if qualifier == "out":  # no out parameters: a pointer to the caller's variable
        return f"{name}: ptr<function, {_wgsl_type(typ, n)}>"
    return f"{name}: {_wgsl_type(typ, n)}"


def _wgsl_func(ret: str, name: str, *params: str) -> str:
    """``fn name(p: T, ...) -> R``; ``ret`` "void", a type, or "float[N]" (an array returned by value)."""
    if ret.endswith("]"):
        typ, n = ret[:-1].split("[")
        ret_type = _wgsl_type(typ, n)
    else:
        ret_type = None if ret == "void" else _wgsl_type(ret)
    return f"fn {name}({', '.join(_wgsl_param(p) for p in params)})" + (f" -> {ret_type}" if ret_type else "")


def _wgsl_array(n: int, values) -> str:
    return f"array<f32, {n}>(" + ", ".join(float_literal(v) for v in values) + ")"


# Slang's f16tof32 becomes 16-bit integer and float types in SPIR-V (capabilities Int16 and Float16,
# which many Vulkan devices, lavapipe among them, do not enable); this exact conversion uses none.
# Binary16 subnormals (exponent 0) are m * 2^-24, computed in float32 without a subnormal
# intermediate; normal values move their exponent from bias 15 to 127 (Inf/NaN never occur:
# --precision fp16 refuses weights beyond the half range).
SLANG_HALF_TO_FLOAT = """// IEEE binary16 (low 16 bits of h) to float, exactly, without 16-bit types; used for fp16 weights.
float hbrdf_half_to_float(uint h) {
    uint a = h & 0x7fffu;
    float magnitude = a < 0x400u ? float(a) * 5.96046448e-8f : asfloat((a << 13) + 0x38000000u);
    return (h & 0x8000u) != 0u ? -magnitude : magnitude;
}
"""

def _c_like_row(name: str, v3: str, v2: str, uint: str, const: str, fn: str, out_array: str, out_float,
                **rest) -> Dict[str, object]:
    """A dialect row of the C-like family: its spellings, the declarations _c_like makes of them,
    and the row's own entries (``rest``)."""
    spellings = {"v3": v3, "v2": v2, "uint": uint, "const": const, "fn": fn, "out_array": out_array,
                 "out_float": out_float}
    return {"name": name, "comment": "//", "prelude": "", "epilogue": "", "unused": lambda n: "", **spellings,
            **_c_like(v3, v2, uint, const, fn, out_array, out_float), **rest}


# The loops form's unroll hint (docs/CODEGEN.md, "Unroll hints in the loops form"): "unroll" prefixes
# each counted loop over the network's weights, "unroll_setup" is written once before the weight
# arrays. HLSL and Slang have [unroll]; GLSL has [[unroll]] only with GL_EXT_control_flow_attributes,
# hence a macro that is empty where the compiler lacks the extension (or that the including shader
# has defined itself, e.g. empty to opt out); WGSL has no loop attribute and C++ leaves loops to its
# vectoriser, so neither gets a hint.
GLSL_UNROLL_SETUP = """// [[unroll]] on the loops over the weights where the compiler has GL_EXT_control_flow_attributes:
// unrolled, every index is a constant and the weights fold into the code (docs/CODEGEN.md).
// Define HBRDF_UNROLL before this file to choose otherwise (empty: no hint).
#ifndef HBRDF_UNROLL
#ifdef GL_EXT_control_flow_attributes
#extension GL_EXT_control_flow_attributes : enable
#define HBRDF_UNROLL [[unroll]]
#else
#define HBRDF_UNROLL
#endif
#endif"""

_HLSL = _c_like_row("HLSL (Shader Model 5+, glslang/DXC)", "float3", "float2", "uint", "static const", "", "out ",
                    lambda n: f"out float {n}", array=_brace_array, struct_open=lambda t: "{",
                    struct_close="}", uint_array=lambda n, v: "{" + _hex_list(v) + "}",
                    weight=lambda a, i: f"f16tof32({a}[({i}) >> 1] >> (16u * (uint({i}) & 1u)))",
                    unroll="[unroll] ", unroll_setup="")

DIALECTS: Dict[str, Dict[str, object]] = {
    "glsl": _c_like_row("GLSL 4.50", "vec3", "vec2", "uint", "const", "", "out ", lambda n: f"out float {n}",
                        array=_glsl_array, struct_open=lambda t: f"{t}(", struct_close=")",
                        uint_array=lambda n, v: f"uint[{n}](" + _hex_list(v) + ")",
                        weight=lambda a, i: f"unpackHalf2x16({a}[({i}) >> 1])[({i}) & 1]",
                        unroll="HBRDF_UNROLL ", unroll_setup=GLSL_UNROLL_SETUP),
    "hlsl": _HLSL,
    # Slang reads HLSL: the same text but for fp16 weights, widened without 16-bit types.
    "slang": {**_HLSL, "name": "Slang (slangc)",
              "weight": lambda a, i: f"hbrdf_half_to_float({a}[({i}) >> 1] >> (16u * (uint({i}) & 1u)))",
              "half_to_float": SLANG_HALF_TO_FLOAT},
    "cpp": {"name": "C++17, dependency-free", "comment": "//", "prelude": CPP_PRELUDE,
            "epilogue": "}  // namespace hbrdf", "v3": "float3", "v2": "float2", "const": "inline constexpr",
            "fn": "inline ", "out_array": "", "out_float": lambda n: f"float& {n}", "array": _brace_array,
            "unused": lambda n: f"(void){n}; ",  # a parameter the code ignores, without -Wunused-parameter
            "struct_open": lambda t: "{", "struct_close": "}", "uint": "unsigned",
            "uint_array": lambda n, v: "{" + _hex_list(v) + "}",
            "weight": lambda a, i: f"hbrdf_half_to_float({a}[({i}) >> 1] >> (16u * unsigned(({i}) & 1)))",
            "unroll": "", "unroll_setup": "",
            **_c_like("float3", "float2", "unsigned", "inline constexpr", "inline ", "", lambda n: f"float& {n}")},
    # WGSL (WebGPU): no ?: (select(false, true, cond), both evaluated), no out parameters (a pointer,
    # or an array returned by value), immutable parameters, let/var/const with the type after the
    # name, braces on every body, no implicit conversions. fp16 weights need no f16 type (no
    # `enable f16;`): unpack2x16float widens the packed halves.
    "wgsl": {"name": "WGSL (WebGPU)", "comment": "//", "prelude": "", "epilogue": "", "v3": "vec3f", "v2": "vec2f",
             "const": "const", "fn": "fn ", "out_array": "", "out_float": lambda n: f"{n}: ptr<function, f32>",
             "unused": lambda n: "",
             "array": _wgsl_array, "struct_open": lambda t: f"{t}(", "struct_close": ")", "uint": "u32",
             "uint_array": lambda n, v: f"array<u32, {n}>(" + _hex_list(v) + ")",
             "weight": lambda a, i: f"unpack2x16float({a}[({i}) >> 1u])[({i}) & 1]",
             "unroll": "", "unroll_setup": "",
             "decl": _wgsl_name_type, "let": lambda t: "let " + _wgsl_name_type(t),
             "var": lambda t: "var " + _wgsl_name_type(t), "constant": lambda t: "const " + _wgsl_name_type(t),
             "field": lambda t: _wgsl_name_type(t) + ",", "func": _wgsl_func,
             "sel": lambda cond, t, f: f"select({f}, {t}, {cond})",
             "for_": lambda k, n: f"for (var {k}: i32 = 0; {k} < {n}; {k}++)",
             "block": lambda s: "{ " + s + " }", "deref": lambda n: f"(*{n})", "ref": lambda n: f"&{n}",
             "immutable_params": True, "returns_arrays": True, "half_to_float": "",
             # FLT_MAX: Tint (Chrome's WGSL compiler) refuses 3.40282347e+38, which is above the largest f32
             # ("value cannot be represented as 'f32'"; naga rounds it); 3.40282346e+38 is the same float32.
             "flt_max": "3.40282346e+38f"},
}


def contract_literals() -> Dict[str, str]:
    """The model contract's constants (spec/model.json) as float literals for the template."""
    c = {k: float_literal(getattr(spec, k.upper())) for k in
         ("kd_min", "kd_max", "eta_min", "eta_max", "alpha_max", "hardgelu_knee", "mis_min_lobe_probability")}
    c["hardgelu_inv_width"] = float_literal(np.float32(1.0) / np.float32(2.0 * spec.HARDGELU_KNEE))
    return c


def material_constant(name: str) -> str:
    """HBRDF_MATERIAL_<NAME>: upper-cased, every non-identifier character turned into '_'
    (hybridbrdf.names.shader_constant_key; the model contract keeps them distinct)."""
    return "HBRDF_MATERIAL_" + shader_constant_key(name)
