"""``hbrdf view MODEL SOURCE...``: the measurement beside the model (docs/VIEWER.md, "The measurement
beside the model").

For each SOURCE (a measured file or ``synthetic:NAME``; folders and globs expand as for ``hbrdf
eval``) the page gets, for the model material the fitter named after it:

- the C++ path tracer's render of the *measured* BRDF (scene material ``{"type": "measured",
  "source": ...}``) in the page's own scene: :func:`hybridbrdf.viewer.scene.tracer_scene` with only
  ``materials.m`` replaced, so that camera, light and settings are the page's; tone-mapped as the
  page (:func:`hybridbrdf.viewer.scene.srgb8`, exposure 0) and embedded as a PNG ``data:`` URI;
- BRDF slices of the model (f_t), its analytic part f_a and the measurement (the reader's
  ``eval``), as numbers the page's plot script (viewer_plots.js) draws.

The slices (:func:`slice_directions`): the in-plane slices of BRDF Explorer / MERL practice, for
theta_i in :data:`SLICE_THETA_I_DEG` at phi_i = 0 (the plane of the tangent, the alpha_x axis),
f(theta_o) for theta_o in :data:`SLICE_THETA_O_DEG` in the plane of incidence, theta_o > 0 on the
mirror side (the mirror direction is theta_o = theta_i) and theta_o < 0 back toward the light;
for anisotropic materials the same slices in the plane phi_i = 90 degrees (the alpha_y axis) too.
f without the cosine, RGB, five significant digits.

Pairing uses :func:`hybridbrdf.sources.names.source_material`, the rule ``hbrdf eval`` matches
sources with: a source is its material ``<name>`` or, where a fit held the name in two formats,
``<name>.<format>``.
"""

from __future__ import annotations

import base64
import copy
import math
import os
import struct
import time
import zlib
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from hybridbrdf import _core
from hybridbrdf.errors import InputFileError
from hybridbrdf.render.tracer import open_measured, render
from hybridbrdf.sources import SYNTHETIC_PREFIX, expand_sources, open_source
from hybridbrdf.sources.names import format_tag, source_material
from hybridbrdf.viewer.scene import srgb8, tracer_scene
from hybridbrdf.viewer.sizes import DEFAULT_SOURCE_SIZE, DEFAULT_SOURCE_SPP

#: Incidence angles of the slices (degrees, phi_i = 0; and phi_i = 90 for anisotropic materials).
SLICE_THETA_I_DEG = (0.0, 30.0, 60.0)
#: Outgoing angles of the slices (degrees, signed: > 0 on the mirror side of the plane of incidence).
SLICE_THETA_O_DEG = tuple(float(t) for t in range(-89, 90))
#: Relative difference of alpha_x and alpha_y above which a fitted material counts as anisotropic.
ANISOTROPY_MIN = 0.05
#: Significant digits of the slice values in the page.
DIGITS = 5


def slice_directions(theta_i_deg: float, phi_i_deg: float = 0.0,
                     theta_o_deg: Sequence[float] = SLICE_THETA_O_DEG) -> Tuple[np.ndarray, np.ndarray]:
    """(wi, wo), each (N, 3) float64, of one in-plane slice: wi at (theta_i, phi_i); wo in the plane of
    incidence at signed theta_o, positive on the mirror side (theta_o = theta_i is the mirror
    direction), negative toward the light (docs/CONVENTIONS.md's frame: normal +z, tangent x)."""
    ti, pi_ = math.radians(theta_i_deg), math.radians(phi_i_deg)
    to = np.radians(np.asarray(theta_o_deg, dtype=np.float64))
    wi = np.tile([math.sin(ti) * math.cos(pi_), math.sin(ti) * math.sin(pi_), math.cos(ti)], (len(to), 1))
    wo = np.stack([-np.sin(to) * math.cos(pi_), -np.sin(to) * math.sin(pi_), np.cos(to)], axis=1)
    return wi, wo


def png_bytes(rgb: np.ndarray) -> bytes:
    """An 8-bit RGB PNG of ``rgb`` ((H, W, 3) uint8, top row first): one IDAT, each row with PNG
    filter 1 (Sub: each byte minus the byte one pixel to its left), zlib level 9."""
    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"png_bytes: expected (H, W, 3) uint8, got shape {rgb.shape}")
    h, w, _ = rgb.shape
    rows = rgb.reshape(h, 3 * w)
    sub = rows.copy()
    sub[:, 3:] = rows[:, 3:] - rows[:, :-3]  # uint8 arithmetic wraps modulo 256, as the filter wants
    raw = np.concatenate([np.ones((h, 1), np.uint8), sub], axis=1)

    def chunk(tag: bytes, payload: bytes) -> bytes:
        return struct.pack(">I", len(payload)) + tag + payload + struct.pack(">I", zlib.crc32(tag + payload) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw.tobytes(), 9)) + chunk(b"IEND", b""))


def png_data_uri(rgb: np.ndarray) -> str:
    """``rgb`` as a ``data:image/png;base64,...`` URI (:func:`png_bytes`), what the page's policy
    allows as an image source."""
    return "data:image/png;base64," + base64.b64encode(png_bytes(rgb)).decode("ascii")


def pair_sources(model, model_path: str, specs: Sequence[str]) -> List[Tuple[str, Any, str]]:
    """(source spec, opened source, model material name) for each source of ``specs`` (expanded as
    ``hbrdf eval`` expands them). Raises the reader's BRDFFormatError for a source it refuses, and
    InputFileError "<source>: ..." (one line) for a source that names no material of the model or
    one that another source already paired with."""
    out: List[Tuple[str, Any, str]] = []
    taken: Dict[str, str] = {}
    for spec in expand_sources(specs):
        src = open_source(spec)
        name = source_material(model, src)
        if name is None:
            raise InputFileError(spec, f"names no material of {model_path} (as fitted it would be '{src.name}' or "
                                       f"'{src.name}.{format_tag(src)}'); `hbrdf info {model_path}` lists the "
                                       f"model's materials")
        if name in taken:
            raise InputFileError(spec, f"pairs with the material '{name}', as {taken[name]} does; give one source "
                                       f"per material")
        taken[name] = spec
        out.append((spec, src, name))
    return out


def _rounded(values: np.ndarray) -> List[List[Optional[float]]]:
    """(N, 3) -> three lists (R, G, B) of DIGITS significant digits; non-finite values as None."""
    out = []
    for channel in np.asarray(values, dtype=np.float64).T:
        out.append([float(f"{v:.{DIGITS}g}") if math.isfinite(v) else None for v in channel.tolist()])
    return out


def anisotropic(model, name: str, src) -> bool:
    """Whether a material gets the slices across (phi_i = 90): its source says it is anisotropic,
    or its fitted alpha_x and alpha_y differ by more than :data:`ANISOTROPY_MIN` (relative)."""
    if not getattr(src, "isotropic", True):
        return True
    if not model.has_analytic:
        return False
    ax, ay = (float(v) for v in model.tensors["materials.alpha"][model.index(name)])
    return abs(ax - ay) > ANISOTROPY_MIN * max(ax, ay)


def slices(model, name: str, src) -> List[Dict[str, Any]]:
    """The slices of one material: model (f_t), analytic (f_a; None for the neural baseline) and
    measured (the source's eval), each as three channel lists over :data:`SLICE_THETA_O_DEG`."""
    planes = (0.0, 90.0) if anisotropic(model, name, src) else (0.0,)
    out = []
    for phi_i in planes:
        for theta_i in SLICE_THETA_I_DEG:
            wi, wo = slice_directions(theta_i, phi_i)
            out.append({
                "theta_i": theta_i, "phi_i": phi_i,
                "model": _rounded(model.eval(wi, wo, name)),
                "analytic": _rounded(model.eval_analytic(wi, wo, name)) if model.has_analytic else None,
                "measured": _rounded(src.eval(wi, wo)),
            })
    return out


def measured_material(model, material: str, source: str) -> Dict[str, Any]:
    """The scene material of the measurement: ``{"type": "measured", "source": ...}`` (a path made
    absolute, or synthetic:NAME) with, for a model that has an analytic part, the paired material's
    fitted f_a as ``sampling_params``: the tracer then samples the measurement as it samples the model
    (cosine and GGX, MIS) instead of by the cosine alone; the BRDF value is always the measurement's,
    so the expectation is the same and only the noise is less (5x less on glossy RGL materials)."""
    out: Dict[str, Any] = {"type": "measured",
                           "source": source if source.startswith(SYNTHETIC_PREFIX) else os.path.abspath(source)}
    if model.has_analytic:
        p = model.analytic_params(material)
        out["sampling_params"] = {"kd": [float(v) for v in p.kd], "eta": [float(v) for v in p.eta],
                                  "alpha": [float(v) for v in p.alpha]}
    return out


def measured_scene(model, model_path: str, material: str, source: str, size: int, spp: int,
                   page_scene: Optional[Dict[str, Any]] = None) -> Dict[str, Any]:
    """The page's tracer scene with the measured ``source`` as its material, ``size`` x ``size``
    pixels and ``spp`` samples per pixel; everything else (camera, light, ``max_depth``, sampler,
    seed) as the page's. ``page_scene``: the scene the page prints (``page_data(...)["scene"]``);
    without it, :func:`hybridbrdf.viewer.scene.tracer_scene`'s defaults, which are the page's."""
    if page_scene is None:
        page_scene = tracer_scene(model_file=model_path, material=material, width=size, height=size, spp=spp)
    scene = copy.deepcopy(page_scene)
    scene["camera"] = dict(scene["camera"], width=int(size), height=int(size))
    scene["spp"] = int(spp)
    scene["materials"]["m"] = measured_material(model, material, source)
    return scene


def light_text(scene: Dict[str, Any]) -> str:
    """The light of a tracer scene in words, for the caption."""
    env = scene.get("environment") or {}
    kind = env.get("type")
    if kind == "sky":
        text = (f"the path tracer's sky (sun at elevation {env.get('sun_elevation_deg', 0):g}, azimuth "
                f"{env.get('sun_azimuth_deg', 0):g} degrees, sky intensity {env.get('sky_intensity', 1):g})")
    elif kind == "file":
        text = f"the environment map {os.path.basename(str(env.get('file', '')))}"
    else:
        text = f"the environment {kind}"
    rotation = env.get("rotation_deg", 0) or 0
    return text + (f" turned by {rotation:g} degrees" if rotation else "") + ": the page's initial light"


def render_measured(scene: Dict[str, Any], src) -> Tuple[np.ndarray, float]:
    """(8-bit sRGB image as the page tone-maps it, seconds) of ``scene`` (:func:`measured_scene`);
    ``src`` is its opened source, evaluated by the tracer as ``hbrdf render`` evaluates it."""
    target = scene["materials"]["m"]["source"]

    def factory(spec):
        if spec != target:
            return open_measured(spec)
        return lambda wi, wo: np.ascontiguousarray(src.eval(wi, wo), dtype=np.float32)

    t0 = time.perf_counter()
    img, _ = render(scene, measured_factory=factory)
    seconds = time.perf_counter() - t0
    return srgb8(img), seconds


def check_settings(size: int, spp: int) -> None:
    """Refuse a measured render's ``--source-size`` outside [8, 1024] or ``--source-spp`` outside
    [1, 65536] (ValueError naming the flag), before anything is rendered."""
    if not 8 <= int(size) <= 1024:
        raise ValueError(f"--source-size {size}: must be in [8, 1024]")
    if not 1 <= int(spp) <= 65536:
        raise ValueError(f"--source-spp {spp}: must be in [1, 65536]")


def panels(model, model_path: str, sources: Sequence[str], page_scene: Optional[Dict[str, Any]] = None,
           size: int = DEFAULT_SOURCE_SIZE, spp: int = DEFAULT_SOURCE_SPP) -> Optional[Dict[str, Any]]:
    """The page's ``sources_panel``: None without sources, else {"theta_o", "theta_i", "render":
    {"width", "height", "spp", "exposure", "max_depth", "light"}, "materials": [None, or {"source",
    "file", "material", "origin", "image", "seconds", "slices"}, per model material in the model's
    order]}. ``page_scene``: the tracer scene the page prints (its camera and light are rendered);
    ``image`` is None in a build without the renderer."""
    if not sources:
        return None
    check_settings(size, spp)
    size, spp = int(size), int(spp)
    pairs = pair_sources(model, model_path, sources)
    have_renderer = getattr(_core, "HAVE_RENDERER", False)
    rows: List[Optional[Dict[str, Any]]] = [None] * len(model.materials)
    scene: Dict[str, Any] = {}
    for spec, src, name in pairs:
        image, seconds = None, None
        scene = measured_scene(model, model_path, name, spec, size, spp, page_scene)
        if have_renderer:
            rgb, seconds = render_measured(scene, src)
            image = png_data_uri(rgb)
        rows[model.index(name)] = {
            "source": spec, "file": spec if spec.startswith(SYNTHETIC_PREFIX) else os.path.basename(spec),
            "material": name, "origin": str(getattr(src, "origin", "")), "image": image,
            "seconds": None if seconds is None else round(seconds, 2), "slices": slices(model, name, src),
        }
    return {"theta_o": list(SLICE_THETA_O_DEG), "theta_i": list(SLICE_THETA_I_DEG),
            "render": {"width": size, "height": size, "spp": spp, "exposure": 0.0,
                       "max_depth": scene.get("max_depth"), "light": light_text(scene)},
            "materials": rows}


__all__ = ["ANISOTROPY_MIN", "SLICE_THETA_I_DEG", "SLICE_THETA_O_DEG",
           "anisotropic", "light_text", "measured_material", "measured_scene", "pair_sources", "panels", "png_bytes", "png_data_uri",
           "render_measured", "slice_directions", "slices"]
