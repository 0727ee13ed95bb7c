"""The literals of generated code: float and contract constants, comments, material constant
names, and the dialect table that holds what differs between GLSL, HLSL and C++ (vector types,
constant and array syntax, out-parameters, the C++ prelude). Every value the template prints goes
through here, so that each dialect reads back the same float32."""

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
