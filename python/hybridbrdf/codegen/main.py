"""Code generation: a model file becomes self-contained GLSL, HLSL, Slang, WGSL, C++ or BRDF Explorer code,
and a textured material's folder the code of its layers with its maps' lookup and decode.

    hbrdf-codegen MODEL --target glsl|hlsl|slang|wgsl|cpp|brdfexplorer [--materials a,b | --scene SCENE.json] [--per-pixel] -o OUT
    hbrdf-codegen DIR --target glsl|hlsl|slang|wgsl|cpp [--per-pixel] -o OUT

One Jinja2 template (``codegen/hbrdf.j2``) serves every shader and header target; a small
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

This module is the entry point (:func:`generate` and the ``hbrdf-codegen`` command); the parts
live in one module each of this package: :mod:`~hybridbrdf.codegen.literals` (literals, comments,
the dialect table), :mod:`~hybridbrdf.codegen.scene` (the scene plan), :mod:`~hybridbrdf.codegen.network`
(the network's layers and unrolled statements), :mod:`~hybridbrdf.codegen.source` (the template
rendered for one dialect) and :mod:`~hybridbrdf.codegen.brdfexplorer`.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from typing import Dict, Optional, Sequence

from hybridbrdf.codegen.brdfexplorer import generate_brdfexplorer
from hybridbrdf.codegen.literals import DIALECTS
from hybridbrdf.codegen.source import MLP_FORMS, generate_source
from hybridbrdf.codegen.scene import load_scene
from hybridbrdf.codegen.textured import textured_plan
from hybridbrdf.errors import InputFileError, one_line_text
from hybridbrdf.inputs import refuse_output_over_input
from hybridbrdf.model.file import HybridModel, load_model
from hybridbrdf.files import atomic_write_bytes, check_writable

TARGETS = ("glsl", "hlsl", "slang", "wgsl", "cpp", "brdfexplorer")


def generate(model: HybridModel, target: str, materials: Optional[Sequence[str]] = None,
             model_path: str = "MODEL", extra_args: str = "", scene: Optional[Dict[str, object]] = None,
             precision: str = "fp32", mlp_form: str = "auto", literal_head: Optional[str] = None,
             textured: Optional[Dict[str, object]] = None, pixel_split: bool = False) -> str:
    """Source code of ``model`` for ``target`` (one of :data:`TARGETS`), for all or
    the named materials. For brdfexplorer the first (or only) material gives the parameters'
    default values; kd, eta, alpha and the latent code become sliders.

    ``mlp_form`` is "unrolled" (straight-line code, weights as literals), "loops"
    (weights in constant arrays, loops over them) or "auto": unrolled for the shading languages
    (shader compilers turn constant arrays indexed in loops into per-invocation memory;
    see docs/CODEGEN.md), loops for C++ (the C++ compiler vectorises the loops).
    With ``precision="fp16"`` the layer weights are rounded to IEEE binary16: unrolled
    code prints the rounded values (exactly), loops store them packed two per 32-bit word.
    ``scene`` is the plan :func:`load_scene` makes of a path-tracer scene: ``{"name", "materials":
    [{"name", "evaluate"}], "neural_max_depth" (optional), "not_emitted" (optional)}``.
    ``textured`` is the plan :func:`generate_textured` makes of a textured material's folder.
    ``pixel_split`` (GLSL, HLSL; unrolled; local direction inputs) adds ``hbrdf_pixel(wo, m)`` and
    ``hbrdf_eval_pixel(wi, px, m)``: hbrdf_eval split at a frame's light loop, the first layer's
    latent and wo terms summed once per pixel (docs/CODEGEN.md, "The per-pixel form")."""
    if target == "brdfexplorer":
        if textured is not None:
            raise ValueError("a BRDF Explorer file shows one uniform material, not a textured one")
        return generate_brdfexplorer(model, materials, model_path, extra_args)
    if target not in DIALECTS:
        raise ValueError(f"unknown target {target!r}; expected one of {', '.join(TARGETS)}")
    return generate_source(model, target, materials, model_path, extra_args, scene, precision, mlp_form, literal_head,
                           textured, pixel_split)


def generate_textured(folder, target: str, precision: str = "fp32", mlp_form: str = "auto",
                      extra_args: str = "", own_normal: bool = False, materials=None, pixel_split: bool = False) -> str:
    """Source code for ``target`` (glsl, hlsl, slang, wgsl or cpp) of the textured material in
    ``folder`` (docs/SVBRDF.md; read by :func:`hybridbrdf.svbrdf.load_svbrdf`, whose one-line errors
    it raises): its model restricted to exactly the layers' materials, plus the maps' decode
    constants, ``HbrdfTexel``, ``hbrdf_decode_texel``, the sampler lookups ``hbrdf_texel_grad`` and
    ``hbrdf_texel_lod`` (not in C++) and ``hbrdf_eval_texel`` / ``hbrdf_pdf_texel`` /
    ``hbrdf_sample_texel`` (docs/CODEGEN.md, "A textured material in an engine"); a normal map is
    read as the lookups' last map and applied by the texel functions. ``own_normal``: a folder with
    a normal map is generated without it (the caller reads the map and applies the shading frame
    itself, as the raster frame does). ``materials``: more materials of the folder's model
    to emit beside the layers' (their ``HBRDF_MATERIAL_*`` constants; the raster frame's model cases).
    ``pixel_split``: the per-pixel form as :func:`generate`'s (for those constants; the texel's
    functions stay per light)."""
    if target not in DIALECTS:
        raise ValueError(f"a textured material's folder generates {', '.join(DIALECTS)} code, not {target!r}")
    plan = textured_plan(folder, own_normal=own_normal)
    emitted = list(dict.fromkeys(list(plan["materials"]) + list(materials or [])))
    return generate(plan["model"], target, emitted, model_path=plan["folder"], extra_args=extra_args,
                    precision=precision, mlp_form=mlp_form, textured=plan, pixel_split=pixel_split)


def build_parser() -> argparse.ArgumentParser:
    """The ``hbrdf-codegen`` parser (tests/python/test_doc_commands.py parses the documents' command lines with it)."""
    ap = argparse.ArgumentParser(prog="hbrdf-codegen",
                                 description="Generate GLSL, HLSL, Slang, WGSL or C++ code from a model file, or from "
                                             "a textured material's folder.")
    ap.add_argument("model", metavar="MODEL|DIR",
                    help="model file written by hbrdf fit, or a textured material's folder DIR (hbrdf paint; "
                         "docs/SVBRDF.md): then the code holds exactly its layers' materials and the lookup of its "
                         "maps through samplers (hbrdf_texel_grad / hbrdf_texel_lod, hbrdf_eval_texel; C++: "
                         "hbrdf_decode_texel of filtered stored values); --materials and --scene do not apply "
                         "(docs/CODEGEN.md, 'A textured material in an engine')")
    ap.add_argument("--target", required=True, choices=TARGETS,
                    help="output language: glsl (GLSL 4.50), hlsl (DXC/glslang), slang (slangc), wgsl (WebGPU; "
                         "hbrdf_sample takes pdf as ptr<function, f32>), cpp (C++17 header), brdfexplorer (Disney "
                         "BRDF Explorer .brdf); docs/CODEGEN.md")
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
                         "(default: unrolled for GLSL/HLSL/Slang/WGSL, loops for C++)")
    ap.add_argument("--per-pixel", action="store_true",
                    help="also emit the per-pixel form: hbrdf_pixel(wo, m) once per pixel, hbrdf_eval_pixel(wi, px, m) "
                         "per light (glsl and hlsl, unrolled, models whose inputs keep wi and wo apart; refused "
                         "otherwise; docs/CODEGEN.md, 'The per-pixel form')")
    ap.add_argument("-o", "--out", required=True, help="file to write (written atomically)")
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        # Before any work: -o naming the model or the scene (by any path) would replace it with code.
        refuse_output_over_input(args.out, [args.model, args.scene], "-o/--out")
        if os.path.isdir(args.model):
            return _main_textured(args)
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
        if args.target == "brdfexplorer" and args.per_pixel:
            raise ValueError(f"{args.model}: --per-pixel: GLSL and HLSL only (a BRDF Explorer file has no light loop)")
        with _per_pixel_errors(args):
            text = generate(model, args.target, materials, model_path=os.path.basename(args.model),
                            extra_args=extra + (" --per-pixel" if args.per_pixel else ""), scene=scene,
                            precision=args.precision, mlp_form=args.mlp_form, pixel_split=args.per_pixel)
        if scene is not None:
            materials = [m["name"] for m in scene["materials"]]
        atomic_write_bytes(args.out, text.encode("utf-8"))
    except (InputFileError, ValueError, KeyError, OSError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        print(f"hbrdf-codegen: error: {one_line_text(str(msg))}", file=sys.stderr)
        return 1
    print(f"wrote {args.out} ({args.target}, {len(materials or model.materials)} materials)")
    return 0


@contextlib.contextmanager
def _per_pixel_errors(args):
    """generate's refusal of the per-pixel form (``pixel_split: <why> (...)``) in the command's words:
    ``MODEL: --per-pixel: <why> (...)``."""
    try:
        yield
    except ValueError as exc:
        if not str(exc).startswith("pixel_split: "):
            raise
        raise ValueError(f"{args.model}: --per-pixel: {str(exc)[len('pixel_split: '):]}") from None


def _main_textured(args) -> int:
    """``hbrdf-codegen DIR``: the textured material's code (errors reach main's handler)."""
    folder = args.model
    # Before any work: -o naming a file of the folder (by any path: its index, model or a map) or
    # landing inside it would replace an input, or be replaced with the folder when it is re-painted.
    if os.path.realpath(os.path.dirname(os.path.abspath(args.out))) == os.path.realpath(folder):
        raise InputFileError(args.out, f"-o/--out is inside the textured material's folder {folder}; write the code "
                                       "elsewhere (the folder holds its index, model and maps only)")
    with os.scandir(folder) as entries:
        refuse_output_over_input(args.out, [e.path for e in entries if e.is_file()], "-o/--out")
    for flag, given in (("--materials", args.materials), ("--scene", args.scene)):
        if given:
            raise ValueError(f"{folder}: a textured material's folder names its own materials (its layers); "
                             f"{flag} does not apply")
    if args.target not in DIALECTS:
        raise ValueError(f"{folder}: a textured material's folder generates {', '.join(DIALECTS)} code, not "
                         f"{args.target} (a BRDF Explorer file shows one uniform material)")
    check_writable(args.out, "generated code")
    extra = (f" --precision {args.precision}" if args.precision != "fp32" else "") + (
        f" --mlp-form {args.mlp_form}" if args.mlp_form != "auto" else "") + (" --per-pixel" if args.per_pixel else "")
    with _per_pixel_errors(args):
        text = generate_textured(folder, args.target, args.precision, args.mlp_form, extra, pixel_split=args.per_pixel)
    atomic_write_bytes(args.out, text.encode("utf-8"))
    print(f"wrote {args.out} ({args.target}, textured material {os.path.basename(os.path.abspath(folder))})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
