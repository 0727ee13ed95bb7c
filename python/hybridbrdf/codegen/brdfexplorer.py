"""Disney BRDF Explorer output (``hbrdf-codegen --target brdfexplorer``): a ``.brdf`` file whose
``::begin parameters`` block makes kd, eta, alpha and the latent code sliders and whose shader
block is the generated GLSL without material constants, in the explorer's dialect (no line
starting with '#', which its parser drops, and no 'f' suffixes; docs/CODEGEN.md)."""

from __future__ import annotations

import re
from typing import Dict, List

import numpy as np

from hybridbrdf import _core
from hybridbrdf.codegen.literals import comment_text
from hybridbrdf.codegen.source import check_material_selection, generate_source, template
from hybridbrdf.model.file import HybridModel

_F_SUFFIX = re.compile(r"(?<=[0-9.])f\b")


def _param_line_value(x: float) -> str:
    s = f"{float(np.float32(x)):.9g}"
    return s if ("." in s or "e" in s) else s + ".0"


def _shader_body(model: HybridModel, material: str, model_path: str, extra_args: str) -> str:
    """The GLSL body without material constants; BRDF Explorer's GLSL takes no 'f' suffixes.
    A model with material output layers: ``material``'s head as literals (the sliders move p
    and z; a head has 6 x width numbers, no slider's worth)."""
    literal = material if model.output_layer == "material" else None
    body = generate_source(model, "glsl", [material], model_path, extra_args, literal_head=literal)
    body = "\n".join(line for line in body.splitlines()
                     if not line.startswith(("const HbrdfMaterial", "// hybridbrdf generated", "//   hbrdf-codegen")))
    return _F_SUFFIX.sub("", body)


def _parameters(model: HybridModel, default: int) -> List[Dict[str, str]]:
    """The sliders, ``{"name", "min", "max", "default"}`` each: kd_r/g/b, eta_r/g/b, alpha_x/y
    (fixed at their neutral values for the neural baseline) and the latent z0.., defaulting to
    material ``default``'s values."""
    t = model.tensors
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
    for k in range(model.arch["latent"]):
        params.append({"name": f"z{k}", "min": _param_line_value(-span), "max": _param_line_value(span),
                       "default": _param_line_value(z[default, k])})
    return params


def generate_brdfexplorer(model: HybridModel, materials, model_path: str, extra_args: str) -> str:
    """The ``.brdf`` file of ``model``; its sliders default to the first of ``materials``
    (default: the model's first material)."""
    names = list(materials) if materials else model.materials
    check_material_selection(model, names)
    latent = model.arch["latent"]
    a = model.arch
    return template("brdfexplorer.j2").render(
        model_path=comment_text(model_path), extra_args=comment_text(extra_args), kind=model.kind, width=a["width"],
        depth=a["depth"], activation=a["activation"], latent=latent, conventions_version=_core.CONVENTIONS_VERSION,
        default_material=comment_text(names[0]), material_names=[comment_text(n) for n in model.materials],
        params=_parameters(model, model.index(names[0])),
        body=_shader_body(model, names[0], model_path, extra_args), z_len=max(latent, 1),
        z_args=", ".join(f"z{k}" for k in range(latent)) if latent else "0.0")
