"""The material-name rule of the model contract (spec/model.json: ``max_name_length``,
``name_punctuation``, ``name_rule``).

A material name ends up in places where a stray character is code, not text: ``//`` comments
of generated GLSL, HLSL and C++ (a newline or carriage return ends the comment, a trailing
backslash splices the next line into it), the constant ``HBRDF_MATERIAL_<NAME>``, scene keys
and comma-separated ``--materials`` lists. So names are 1 to 64 characters from ``A-Z a-z 0-9
_ . + -``, hold at least one letter or digit, and stay distinct once mapped to their shader
constant (:func:`shader_constant_key`). Both model-file loaders
(this package's and libhybridbrdf's ``cpp/src/model_validate.cpp``) and ``hbrdf fit`` enforce it with
the same words. Torch-free.
"""

from __future__ import annotations

import re
from typing import Optional, Sequence

from hybridbrdf import spec

#: What a name keeps in its shader constant: ASCII letters and digits; any run of other
#: characters becomes one '_' (never two: identifiers holding "__" are reserved in GLSL, an
#: error in GLSL ES, and in C++), and none is kept at either end (so never "HBRDF_MATERIAL__").
_NOT_ALNUM_RUN = re.compile(r"[^A-Za-z0-9]+")

_ALLOWED = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789" + spec.NAME_PUNCTUATION)


def describe_character(ch: str) -> str:
    """A character as an error message shows it: 'x' when printable ASCII, else U+XXXX
    (never the raw character, which could be a newline or a terminal escape)."""
    return f"'{ch}'" if " " <= ch <= "~" else f"U+{ord(ch):04X}"


def name_problem(name: str) -> Optional[str]:
    """Why ``name`` breaks the rule (one phrase, no name echoed), or None when it is valid."""
    for i, ch in enumerate(name):
        if ch not in _ALLOWED:
            return f"name character {i + 1} is {describe_character(ch)}; a name is {spec.NAME_RULE}"
    if not name:
        return "has no name"
    if len(name) > spec.MAX_NAME_LENGTH:
        return f"name is {len(name)} characters long; a name is {spec.NAME_RULE}"
    if not shader_constant_key(name):
        return "name has no letter or digit, so it gives no shader constant HBRDF_MATERIAL_<NAME>"
    return None


def shader_constant_key(name: str) -> str:
    """The <NAME> of HBRDF_MATERIAL_<NAME>: upper case, each run of characters other than ASCII
    letters and digits as one '_', none at either end ("a..b" -> "A_B", "_a" -> "A", "-" -> "").
    A valid name maps to a non-empty suffix that holds no "__" and starts with no '_', so the
    constant is an identifier no GLSL, HLSL or C++ compiler reserves."""
    return _NOT_ALNUM_RUN.sub("_", name).strip("_").upper()


def names_problem(names: Sequence[str]) -> Optional[str]:
    """The first problem of a list of material names, in the loaders' words: a name that
    breaks the rule ("material 3: ..."), a duplicate, or two names that share a shader
    constant; None when all are valid."""
    seen, keys = set(), {}
    for i, name in enumerate(names):
        problem = name_problem(name)
        if problem:
            return f"material {i} {problem}" if problem == "has no name" else f"material {i}: {problem}"
        if name in seen:
            return f"duplicate material names: {name}"
        seen.add(name)
    for name in names:
        key = shader_constant_key(name)
        if key in keys:
            return (f"materials '{keys[key]}' and '{name}' would share the shader constant "
                    f"HBRDF_MATERIAL_{key}")
        keys[key] = name
    return None
