"""``hbrdf view``: one self-contained HTML page that shows a model's materials live on a sphere
(WebGL2), with the analytic part alone as a toggle, a material picker, kd / eta / alpha sliders that
preview what ``hbrdf edit`` would write (and the matching command line), exposure and the light's
direction (docs/VIEWER.md).

The page's shader is the GLSL that ``hbrdf-codegen --target glsl`` writes (the same template as
every dialect), preceded by ``#version 300 es`` and precision qualifiers: GLSL ES 3.00 reads that
output as it is, and WebGL2 wants ``#version`` on the first line, before the generated header's
comments, so the version line cannot come from the template. The material is not one of the
generated ``HBRDF_MATERIAL_<NAME>`` constants but uniforms (kd, eta, alpha and the packed latent
code and output-layer head), so that the picker and the sliders change it without a recompile.

Lighting: a directional light (the sun) of irradiance :data:`SUN_IRRADIANCE` and no sky. The path
tracer renders the same camera, light and material with :func:`tracer_scene` (a ``sky`` environment
with ``sky_intensity`` 0, a sun disc of :data:`SUN_SIZE_DEG`, ``max_depth`` 1: direct light only),
which the tests compare with the page.

Everything the page shows that comes from the model file (names, origin labels, training records,
paths) reaches it inside one JSON document in a ``<script type="application/json">`` element,
written with every ``<``, ``>``, ``&``, U+2028 and U+2029 escaped, and the page's script puts it into
the document only as text (``textContent``, ``new Option``), never as markup.
"""

from __future__ import annotations

import json
import math
import os
import pathlib
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from hybridbrdf.codegen import generate
from hybridbrdf.model_file import HybridModel

#: The largest model one page takes: float32 tensors (shared network and every material's row), in
#: bytes. The page inlines the materials as JSON text (about 2.5 times their binary size) and the
#: network as literals in the shader, and a browser parses and compiles all of it at load.
MAX_VIEW_WEIGHT_BYTES = 16 << 20
#: Most floats per material in the uniform block (latent code and, for material output layers, the
#: head): WebGL2 guarantees 224 fragment uniform vectors; the page packs 4 floats in each.
MAX_PACKED_FLOATS = 4 * 192

#: Camera of the page and of :func:`tracer_scene` (docs/RENDERING.md's pinhole): a unit sphere at
#: the origin seen from +z.
CAMERA = {"position": [0.0, 0.0, 4.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov_deg": 32.0}
#: Irradiance of the directional light on a surface facing it: pi, so that a white Lambert
#: surface facing the light has radiance kd.
SUN_IRRADIANCE = math.pi
#: Angular diameter of the sun disc in the tracer's environment (the page's light is a direction).
SUN_SIZE_DEG = 0.5
#: Defaults of the page's light (degrees; azimuth from -z toward +x, as the tracer's sky).
DEFAULT_SUN = {"elevation": 35.0, "azimuth": 150.0}


#: GLSL ES 3.00 in front of the generated GLSL: WebGL2 takes the version only on the first line.
ES_PREFIX = "#version 300 es\nprecision highp float;\nprecision highp int;\n"

#: The page's own shader code after the generated GLSL: the material from uniforms, the camera ray,
#: the sphere in the tracer's frame, f cos E, exposure and the sRGB OETF.
_MAIN = """
// ---- hbrdf view: one unit sphere at the origin lit by a directional light (docs/VIEWER.md) ----
uniform vec3 u_kd;
uniform vec3 u_eta;
uniform vec2 u_alpha;
uniform vec4 u_pack[{n_vec}];
uniform bool u_analytic;
uniform vec3 u_sun;
uniform float u_irradiance;
uniform float u_gain;
uniform vec3 u_cam_pos, u_cam_fwd, u_cam_right, u_cam_up;
uniform vec2 u_tan;
uniform vec2 u_size;
out vec4 frag_color;
float hbrdf_view_packed(int i) {{ return u_pack[i / 4][i % 4]; }}
HbrdfMaterial hbrdf_view_material() {{
    HbrdfMaterial m;
    m.kd = u_kd;
    m.eta = u_eta;
    m.alpha_x = u_alpha.x;
    m.alpha_y = u_alpha.y;
    for (int i = 0; i < {z_len}; ++i) m.z[i] = hbrdf_view_packed(i);
{head_lines}    return m;
}}
float hbrdf_view_srgb(float x) {{
    x = clamp(x, 0.0, 1.0);
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}}
void main() {{
    // The tracer's pinhole (docs/RENDERING.md): pixel (0, 0) top left, y down; the pixel's centre.
    vec2 p = vec2(gl_FragCoord.x, u_size.y - gl_FragCoord.y);
    float sx = (2.0 * p.x / u_size.x - 1.0) * u_tan.x;
    float sy = (1.0 - 2.0 * p.y / u_size.y) * u_tan.y;
    vec3 d = normalize(u_cam_fwd + u_cam_right * sx + u_cam_up * sy);
    vec3 o = u_cam_pos;
    float b = dot(o, d), disc = b * b - (dot(o, o) - 1.0);
    vec3 radiance = vec3(0.0);
    if (disc > 0.0) {{
        float t = -b - sqrt(disc);
        vec3 n = normalize(o + t * d);
        // The tracer's sphere frame: tangent d p / d phi about +y (the alpha_x axis).
        vec3 tg = vec3(-n.z, 0.0, n.x);
        float len2 = dot(tg, tg);
        tg = len2 > 1e-12 ? tg / sqrt(len2) : vec3(1.0, 0.0, 0.0);
        vec3 bt = cross(n, tg);
        vec3 wi = vec3(dot(u_sun, tg), dot(u_sun, bt), dot(u_sun, n));
        vec3 wo = vec3(dot(-d, tg), dot(-d, bt), dot(-d, n));
        if (wi.z > 0.0 && wo.z > 0.0) {{
            HbrdfMaterial m = hbrdf_view_material();
            vec3 f = u_analytic ? hbrdf_eval_analytic(wi, wo, m) : hbrdf_eval(wi, wo, m);
            radiance = max(f, vec3(0.0)) * wi.z * u_irradiance;
        }}
    }}
    vec3 c = radiance * u_gain;
    frag_color = vec4(hbrdf_view_srgb(c.r), hbrdf_view_srgb(c.g), hbrdf_view_srgb(c.b), 1.0);
}}
"""


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


def fragment_shader(glsl: str, z_len: int, n_pack: int, head_w: int = 0, n_out: int = 0) -> str:
    """The page's fragment shader (GLSL ES 3.00): :data:`ES_PREFIX`, ``glsl`` (``hbrdf-codegen --target
    glsl`` output, unchanged) and the page's ``main``. ``head_w``/``n_out``: the material output
    layer's sizes (0 for a shared one); the packed uniforms hold z, then head_w, then head_b."""
    head_lines = ""
    if head_w:
        head_lines = (f"    for (int i = 0; i < {head_w}; ++i) m.head_w[i] = hbrdf_view_packed({z_len} + i);\n"
                      f"    for (int i = 0; i < {n_out}; ++i) m.head_b[i] = hbrdf_view_packed({z_len + head_w} + i);\n")
    return ES_PREFIX + glsl + _MAIN.format(n_vec=(n_pack + 3) // 4, z_len=z_len, head_lines=head_lines)


def script_json(value: Any) -> str:
    """JSON safe inside a ``<script>`` element and as a JavaScript literal: ASCII only (U+2028 and
    U+2029 escaped), and ``<``, ``>`` and ``&`` as ``\\u003c`` ... so that no ``</script>`` or
    ``<!--`` can appear."""
    text = json.dumps(value, ensure_ascii=True, allow_nan=False, separators=(",", ":"))
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def page_data(model: HybridModel, model_path: str, sources: Sequence[str] = ()) -> Dict[str, Any]:
    """What the page's script reads: the shader, the materials, the camera and light, the model's labels."""
    check_size(model, model_path)
    a = model.arch
    heads = a.get("output_layer", "shared") == "material"
    glsl = generate(model, "glsl", materials=[model.materials[0]], model_path=model_path)
    rows = _material_rows(model)
    n_pack = len(rows[0]["pack"])
    if n_pack > MAX_PACKED_FLOATS:
        raise ViewError(f"{model_path}: {n_pack} floats per material (latent code and output layer) is more than "
                        f"the page's uniforms hold ({MAX_PACKED_FLOATS})")
    training = model.training if isinstance(model.training, dict) else {}
    return {
        "model_path": model_path, "kind": model.kind, "has_analytic": bool(model.has_analytic),
        "arch": f"{model.kind} {a['width']}x{a['depth']} {a['activation']}, latent {a['latent']}"
                + (", output layer per material" if heads else ""),
        "z_len": max(a["latent"], 1), "heads": heads, "head_w": a["n_out"] * a["width"] if heads else 0,
        "n_out": a["n_out"], "n_pack": n_pack, "materials": rows,
        "training_sources": [str(s) for s in training.get("sources", [])][:50] if isinstance(
            training.get("sources"), list) else [],
        "sources": [str(s) for s in sources],
        "camera": CAMERA, "sun_irradiance": SUN_IRRADIANCE, "sun": DEFAULT_SUN,
        "fragment": fragment_shader(glsl, max(a["latent"], 1), n_pack, a["n_out"] * a["width"] if heads else 0,
                                    a["n_out"]),
        # the page fills in the material, the light, analytic or full, and the size
        "scene": tracer_scene(model_path, model.materials[0], spp=64),
    }


def render_page(model: HybridModel, model_path: str, sources: Sequence[str] = ()) -> str:
    """The HTML page (a str)."""
    data = page_data(model, model_path, sources)
    folder = pathlib.Path(__file__).resolve().parent / "data"
    html = (folder / "viewer.html").read_text(encoding="utf-8")
    js = (folder / "viewer.js").read_text(encoding="utf-8")
    if "</script" in js.lower():
        raise AssertionError("viewer.js must not contain </script")
    return html.replace("/*HBRDF_DATA*/", script_json(data)).replace("/*HBRDF_SCRIPT*/", js)


def write_page(model_path: str, out: str, sources: Sequence[str] = ()) -> Dict[str, Any]:
    """Load ``model_path`` (ModelFileError as ``hbrdf info`` prints it), write the page to ``out``
    atomically; returns {"bytes", "materials"}."""
    from hybridbrdf.inputs import refuse_output_over_input
    from hybridbrdf.model_file import load_model
    from hybridbrdf.util import atomic_write_bytes, check_writable

    refuse_output_over_input(out, [model_path, *sources], "--out")
    check_writable(out, "page")
    model = load_model(model_path)
    page = render_page(model, model_path, sources).encode("utf-8")
    atomic_write_bytes(out, page)
    return {"bytes": len(page), "materials": len(model.materials)}


def tracer_scene(model_file: str, material: str, *, width: int = 256, height: int = 256, analytic: bool = False,
                 elevation: float = DEFAULT_SUN["elevation"], azimuth: float = DEFAULT_SUN["azimuth"],
                 spp: int = 16, resolution=(2048, 1024)) -> Dict[str, Any]:
    """A scene (docs/RENDERING.md) that the path tracer renders as the page shows ``material``: the
    page's camera, the unit sphere, the sun at (``elevation``, ``azimuth``) with irradiance
    :data:`SUN_IRRADIANCE` as a disc of :data:`SUN_SIZE_DEG` in an otherwise black sky, direct
    light only (``max_depth`` 1). ``analytic``: the material's f_a (``"evaluate": "analytic"``)."""
    return {
        "camera": dict(CAMERA, width=width, height=height),
        "environment": {"type": "sky", "sun_elevation_deg": elevation, "sun_azimuth_deg": azimuth,
                        "sun_irradiance": SUN_IRRADIANCE, "sun_size_deg": SUN_SIZE_DEG, "sky_intensity": 0.0,
                        "ground_albedo": 0.0, "resolution": list(resolution)},
        "materials": {"m": {"type": "model", "file": os.path.abspath(model_file), "material": material,
                            "evaluate": "analytic" if analytic else "full"}},
        "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
        "spp": spp, "max_depth": 1, "sampler": "mis", "seed": 0,
    }


def srgb8(linear: np.ndarray, exposure: float = 0.0) -> np.ndarray:
    """What the page (and ``hbrdf render --png`` with ``--tonemap clamp``) shows for linear radiance:
    2^exposure x, clipped to [0, 1], the sRGB OETF, rounded to 8 bits."""
    x = np.clip(np.asarray(linear, dtype=np.float64) * 2.0 ** exposure, 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(s * 255.0).astype(np.uint8)


__all__ = ["CAMERA", "DEFAULT_SUN", "MAX_VIEW_WEIGHT_BYTES", "SUN_IRRADIANCE", "SUN_SIZE_DEG", "ViewError",
           "check_size", "fragment_shader", "page_data", "render_page", "script_json", "srgb8", "tracer_scene", "weight_bytes",
           "write_page"]
