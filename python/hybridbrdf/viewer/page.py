"""``hbrdf view``: one self-contained HTML page that shows a model's materials live on a sphere
(WebGPU where the browser has it, its WGSL from :mod:`hybridbrdf.viewer.wgsl`; else WebGL2), with
the analytic part alone as a toggle, a material picker, kd / eta / alpha sliders that preview what
``hbrdf edit`` would write (and the matching command line), exposure and the light
(docs/VIEWER.md).

The page's WebGL2 shaders (:mod:`hybridbrdf.viewer.glsl`) are the GLSL that ``hbrdf-codegen
--target glsl`` writes (the same template as every dialect) as GLSL ES 3.00 plus the page's own
``main``; the material is not one of the generated ``HBRDF_MATERIAL_<NAME>`` constants but uniforms,
so that the picker and the sliders change it without a recompile. The measurements beside their
materials (SOURCE arguments) come from :mod:`hybridbrdf.viewer.measured`.

Lighting (docs/VIEWER.md): the tracer's environment map (default its sky; hybridbrdf.viewer.lighting),
integrated by Monte Carlo in the shader and accumulated over frames, or the sun alone (a direction,
exact). The path tracer renders the same camera, light and material with :func:`tracer_scene`
(``max_depth`` 1: direct light only), which the tests compare with the page.

Everything the page shows that comes from the model file (names, origin labels, training records,
paths) reaches it inside one JSON document in a ``<script type="application/json">`` element,
written with every ``<``, ``>``, ``&``, U+2028 and U+2029 escaped, and the page's script puts it into
the document only as text (``textContent``, ``new Option``), never as markup.
"""

from __future__ import annotations

import json
import os
import pathlib
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from hybridbrdf import spec
from hybridbrdf.codegen.main import generate
from hybridbrdf.inputs import refuse_output_over_input
from hybridbrdf.model.file import HybridModel, load_model
from hybridbrdf.sources import expand_sources
from hybridbrdf.files import atomic_write_bytes, check_writable
from hybridbrdf.svbrdf.asset import SVBRDF, load_svbrdf
from hybridbrdf.viewer import lighting as viewer_lighting, measured, textured as viewer_textured, wgsl as viewer_wgsl
from hybridbrdf.viewer.glsl import DISPLAY_SHADER, fragment_shader
from hybridbrdf.viewer.scene import CAMERA, DEFAULT_SUN, SUN_IRRADIANCE, tracer_scene

#: The largest model one page takes: float32 tensors (shared network and every material's row), in
#: bytes. The page inlines the materials as JSON text (about 2.5 times their binary size) and the
#: network as literals in the shader, and a browser parses and compiles all of it at load.
MAX_VIEW_WEIGHT_BYTES = 16 << 20
#: Most floats per material in the uniform block (latent code and, for material output layers, the
#: head): WebGL2 guarantees 224 fragment uniform vectors; the page packs 4 floats in each.
MAX_PACKED_FLOATS = 4 * 192

class ViewError(ValueError):
    """A model ``hbrdf view`` refuses (one line)."""


def weight_bytes(model: HybridModel) -> int:
    """Bytes of the model's tensors as float32 (what the size limit counts)."""
    return int(sum(4 * np.asarray(v).size for v in model.tensors.values()))


def check_size(model: HybridModel, path: str, limit: Optional[int] = None) -> None:
    """Raise :class:`ViewError` naming the model's size and the limit when it is too large for one page."""
    limit = MAX_VIEW_WEIGHT_BYTES if limit is None else limit
    n = weight_bytes(model)
    if n > limit:
        raise ViewError(f"{path}: {n / 2**20:.1f} MiB of weights ({n // 4} float32 values) is more than one page "
                        f"takes (hbrdf view's limit: {limit / 2**20:g} MiB)")


def _packed(model: HybridModel, i: int) -> List[float]:
    """The material's latent code (at least one float, as the generated struct) and head, flat."""
    t = model.tensors
    z = [float(v) for v in t["materials.z"][i]] or [0.0]
    if "materials.head_weight" in t:
        z += [float(v) for v in np.asarray(t["materials.head_weight"][i]).ravel()]
        z += [float(v) for v in t["materials.head_bias"][i]]
    if "materials.energy_bound" in t:
        z += [float(v) for v in t["materials.energy_bound"][i]]
    return z


def _material_rows(model: HybridModel) -> List[Dict[str, Any]]:
    t = model.tensors
    rows = []
    for i, info in enumerate(model.material_info):
        if model.has_analytic:
            kd, eta, alpha = (t[k][i] for k in ("materials.kd", "materials.eta", "materials.alpha"))
        else:
            kd, eta, alpha = [0.0] * 3, [1.0] * 3, [1.0, 1.0]
        rows.append({"name": info["name"], "origin": str(info.get("origin", "")),
                     "kd": [float(v) for v in kd], "eta": [float(v) for v in eta],
                     "alpha": [float(v) for v in alpha], "pack": _packed(model, i)})
    return rows


def script_json(value: Any) -> str:
    """JSON safe inside a ``<script>`` element and as a JavaScript literal: ASCII only (U+2028 and
    U+2029 escaped), and ``<``, ``>`` and ``&`` as ``\\u003c`` ... so that no ``</script>`` or
    ``<!--`` can appear."""
    text = json.dumps(value, ensure_ascii=True, allow_nan=False, separators=(",", ":"))
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def page_data(model: HybridModel, model_path: str, sources: Sequence[str] = (),
              environment: Optional[Dict[str, Any]] = None, svbrdf: Optional[SVBRDF] = None) -> Dict[str, Any]:
    """What the page's script reads: the shaders, the materials, the camera and lights, the model's
    labels. ``environment``: the scene environment object to light with (default
    :data:`viewer_lighting.DEFAULT_ENVIRONMENT`, the tracer's sky). ``svbrdf``: a textured material
    of ``model`` (its folder's model) that the page shows instead of one material at a time
    (``hbrdf view --svbrdf``; WebGL2 only)."""
    check_size(model, model_path)
    a = model.arch
    heads = model.output_layer == "material"
    glsl = generate(model, "glsl", materials=[model.materials[0]], model_path=model_path)
    wgsl = generate(model, "wgsl", materials=[model.materials[0]], model_path=model_path)
    rows = _material_rows(model)
    n_pack = len(rows[0]["pack"])
    energy = spec.ENERGY_NODES if "materials.energy_bound" in model.tensors else 0
    if n_pack > MAX_PACKED_FLOATS:
        raise ViewError(f"{model_path}: {n_pack} floats per material (latent code and output layer) is more than "
                        f"the page's uniforms hold ({MAX_PACKED_FLOATS})")
    training = model.training if isinstance(model.training, dict) else {}
    env = viewer_lighting.page_environment(environment or viewer_lighting.DEFAULT_ENVIRONMENT)
    return {
        "model_path": model_path, "kind": model.kind, "has_analytic": bool(model.has_analytic),
        "arch": f"{model.kind} {a['width']}x{a['depth']} {a['activation']}, latent {a['latent']}"
                + (", output layer per material" if heads else ""),
        "z_len": max(a["latent"], 1), "heads": heads, "head_w": a["n_out"] * a["width"] if heads else 0,
        "n_out": a["n_out"], "n_pack": n_pack, "materials": rows,
        "training_sources": [str(s) for s in training.get("sources", [])][:50] if isinstance(
            training.get("sources"), list) else [],
        "sources": [str(s) for s in sources],
        "camera": CAMERA, "sun_irradiance": SUN_IRRADIANCE, "sun": DEFAULT_SUN, "environment": env,
        "fragment": fragment_shader(glsl, max(a["latent"], 1), n_pack, a["n_out"] * a["width"] if heads else 0,
                                    a["n_out"], energy, textured=svbrdf is not None),
        "textured": None if svbrdf is None else viewer_textured.page_textured(svbrdf, svbrdf.path, n_pack),
        "display": DISPLAY_SHADER,
        # the WebGPU backend (docs/VIEWER.md, "WebGPU"): hbrdf-codegen --target wgsl and the page's WGSL
        "wgsl": viewer_wgsl.compute_shader(wgsl, max(a["latent"], 1), n_pack, a["n_out"] * a["width"] if heads else 0,
                                           a["n_out"], energy),
        "wgsl_display": viewer_wgsl.DISPLAY_SHADER,
        # the page fills in the material, the light, analytic or full, and the size
        "scene": tracer_scene(model_path, model.materials[0], spp=64, environment=env["spec"],
                              svbrdf=None if svbrdf is None else svbrdf.path),
        "sun_environment": tracer_scene(model_path, model.materials[0], light="sun")["environment"],
    }


def render_page(model: HybridModel, model_path: str, sources: Sequence[str] = (),
                environment: Optional[Dict[str, Any]] = None, source_options: Optional[Dict[str, Any]] = None,
                svbrdf: Optional[SVBRDF] = None) -> str:
    """The HTML page (a str); ``environment`` and ``svbrdf`` as :func:`page_data`; ``source_options``:
    ``size`` and ``spp`` of the measured renders (:func:`hybridbrdf.viewer.measured.panels`)."""
    data = page_data(model, model_path, sources, environment, svbrdf)
    data["sources_panel"] = measured.panels(model, model_path, sources, data["scene"], **(source_options or {}))
    folder = pathlib.Path(__file__).resolve().parent
    html = (folder / "viewer.html").read_text(encoding="utf-8")
    js = (folder / "viewer.js").read_text(encoding="utf-8")
    js = (folder / "viewer_webgpu.js").read_text(encoding="utf-8") + "\n" + js  # the WebGPU backend viewer.js uses
    js = (folder / "viewer_plots.js").read_text(encoding="utf-8") + "\n" + js  # first: its "use strict" opens the script
    if "</script" in js.lower() or "<script" in js.lower():
        raise AssertionError("viewer.js, viewer_webgpu.js and viewer_plots.js must not contain <script or </script")
    return html.replace("/*HBRDF_DATA*/", script_json(data)).replace("/*HBRDF_SCRIPT*/", js)


def write_page(model_path: Optional[str], out: str, sources: Sequence[str] = (), env: Optional[str] = None,
               source_options: Optional[Dict[str, Any]] = None, svbrdf: Optional[str] = None) -> Dict[str, Any]:
    """Load ``model_path`` (ModelFileError as ``hbrdf info`` prints it), write the page to ``out``
    atomically; ``env``: ``None``/``"sky"`` or an .exr/.hdr map (``hbrdf view --env``). ``svbrdf``: a
    textured material's folder (``hbrdf view --svbrdf``; its loader's one-line errors): the page shows
    it with the folder's model, which ``model_path`` may be omitted for or must name (the same
    bytes). Returns {"bytes", "materials"}."""
    if svbrdf is None and model_path is None:
        raise ViewError("give MODEL, or --svbrdf DIR")
    if svbrdf is not None and sources:
        raise ViewError(f"{svbrdf}: SOURCE arguments are not shown beside a textured material (--svbrdf); "
                        "view its model without --svbrdf for them")
    # The files the SOURCE arguments stand for (a folder or a glob names several), not the arguments.
    inputs = [*([model_path] if model_path else []), *expand_sources(sources),
              *([env] if env not in (None, "sky") else [])]
    sv = None
    if svbrdf is not None:
        sv = load_svbrdf(svbrdf)
        inputs += [os.path.join(sv.path, spec.SVBRDF["index_file"]), sv.model.path]
        if model_path is not None:
            check_same_model(model_path, sv.model.path, svbrdf)
    refuse_output_over_input(out, inputs, "--out")
    check_writable(out, "page")
    model = sv.model if sv is not None else load_model(model_path)
    shown_path = sv.model.path if sv is not None else model_path
    page = render_page(model, shown_path, sources, viewer_lighting.environment_spec(env), source_options,
                       svbrdf=sv).encode("utf-8")
    atomic_write_bytes(out, page)
    return {"bytes": len(page), "materials": len(model.materials)}


def check_same_model(model_path: str, folder_model: str, folder: str) -> None:
    """Raise :class:`ViewError` unless ``model_path`` holds the bytes of the textured material's own
    model (``hbrdf view MODEL --svbrdf DIR``: the page renders DIR's model; MODEL only confirms it)."""
    load_model(model_path)  # a model the loaders refuse: their line first
    with open(model_path, "rb") as a, open(folder_model, "rb") as b:
        same = os.path.samefile(model_path, folder_model) or a.read() == b.read()
    if not same:
        raise ViewError(f"{model_path}: is not the model of the textured material {folder} (its "
                        f"{spec.SVBRDF['model_file']}); give that one, or --svbrdf alone")
