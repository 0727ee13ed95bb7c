"""``export_gltf``: a model file's materials, or a textured material's folder, as a GLB that any
glTF viewer opens (docs/GLTF.md): each material a fitted metallic-roughness fallback plus the
HBRDF_hybrid_material extension carrying the hybrid material itself.
"""

from __future__ import annotations

from dataclasses import replace
import io
import os
from typing import Callable, List, Optional, Sequence

import numpy as np
from PIL import Image

from hybridbrdf.errors import InputFileError
from hybridbrdf.files import check_writable, scratch_folder
from hybridbrdf.gltf.fallback import FallbackReport, fit_fallback
from hybridbrdf.gltf.hybrid import MODEL_FILE, folder_payload, model_payload
from hybridbrdf.gltf.meshes import Mesh, plane, read_obj, uv_sphere
from hybridbrdf.gltf.writer import ExportMaterial, write_glb
from hybridbrdf.inputs import refuse_output_over_input
from hybridbrdf.model.file import load_model
from hybridbrdf.svbrdf.asset import load_svbrdf

#: The largest side of the baseColor and normal images a textured material's fallback carries.
MAX_FALLBACK_IMAGE_SIDE = 1024


def export_mesh(mesh) -> Mesh:
    """"sphere", "plane" or the path of an OBJ file as a :class:`~hybridbrdf.gltf.meshes.Mesh`."""
    if mesh == "sphere":
        return uv_sphere()
    if mesh == "plane":
        return plane()
    return read_obj(mesh)


def report_json(report: FallbackReport) -> dict:
    """The fit's report as the extension stores it: SMAPE and cMAE per (material, reference)."""
    return {"kept": report.kept, "metrics": {f"{which} vs {against}": {"smape": round(s, 6), "cmae": round(c, 8)}
                                             for (which, against), (s, c) in report.metrics.items()}}


def _srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear values in [0, 1] as 8-bit sRGB (IEC 61966-2-1), rounded."""
    x = np.clip(linear, 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.rint(s * 255.0).astype(np.uint8)


def _png(rgb8: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(rgb8, "RGB").save(buf, format="PNG")
    return buf.getvalue()


def _textured_images(sv, metallic: float) -> dict:
    """The fallback's baseColor image (the texel's kd = sum_k w_k kd_k over (1 - metallic), sRGB)
    and normal image (the texel's tangent-space normal, glTF's (n + 1) / 2), sampled at the texel
    centres of a grid of at most MAX_FALLBACK_IMAGE_SIDE a side."""
    w, h = (min(s, MAX_FALLBACK_IMAGE_SIDE) for s in sv.size)
    u, v = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    t = sv.texels(uv, filter="bilinear")
    kd = np.einsum("nl,nlc->nc", t["weight"].astype(np.float64), t["kd"].astype(np.float64))
    images = {"baseColor": _png(_srgb8(kd / max(1.0 - metallic, 1e-6)).reshape(h, w, 3))}
    if sv.normal is not None:
        n = np.rint((np.clip(t["normal"], -1, 1) * 0.5 + 0.5) * 255.0).astype(np.uint8)
        images["normal"] = _png(n.reshape(h, w, 3))
    return images


def _textured_entry(folder: str, fit_kwargs: dict):
    """The ExportMaterial of a textured material's folder and its fit's report (the fallback
    fitted to the base layer's f_a, its kd and normal maps as images)."""
    files = folder_payload(folder)
    sv = load_svbrdf(folder)
    base = sv.layers[0]
    p = sv.model.analytic_params(base)
    report = fit_fallback(p.kd, p.eta, p.alpha, hybrid=lambda wi, wo: sv.model.eval(wi, wo, base), **fit_kwargs)
    fallback = report.material
    images = _textured_images(sv, fallback.metallic)
    # The texture carries the colour: the factor is white (glTF multiplies factor and texture).
    fallback = replace(fallback, base_color=(1.0, 1.0, 1.0))
    name = os.path.basename(os.path.normpath(folder)) or "textured"
    hybrid = {"kind": "textured", "layers": list(sv.layers), "fallback": dict(report_json(report), fitted_to=base)}
    return ExportMaterial(name, fallback, hybrid, files, images), report


def export_gltf(source, out, mesh="sphere", materials: Optional[Sequence[str]] = None,
                progress: Optional[Callable[[str, FallbackReport], None]] = None, **fit_kwargs) -> List[FallbackReport]:
    """Write ``out`` (.glb): the materials of the model file ``source`` (all, or those named in
    ``materials``), or the textured material whose folder is ``source``, on ``mesh`` ("sphere",
    "plane" or an OBJ path). Returns the fits' reports (each also stored in the asset);
    ``progress(name, report)`` is called after each fit. Bad input: a one-line InputFileError
    (or KeyError for a material the model lacks); nothing is written unless everything worked."""
    source, out = os.fspath(source), os.fspath(out)
    refuse_output_over_input(out, [source] + ([mesh] if mesh not in ("sphere", "plane") else []), "--gltf")
    check_writable(out, "glTF output")  # fail now, not after the fits
    geometry = export_mesh(mesh)
    entries, reports = [], []
    if os.path.isdir(source):
        entry, report = _textured_entry(source, fit_kwargs)
        entries.append(entry)
        reports.append(report)
        if progress:
            progress(entry.name, report)
    else:
        data, _ = model_payload(source)
        with scratch_folder() as tmp:  # libhybridbrdf evaluates exactly the bytes embedded
            copy = os.path.join(tmp, MODEL_FILE)
            with open(copy, "wb") as fh:
                fh.write(data)
            model = load_model(copy)
            if not model.has_analytic:
                raise InputFileError(source, f"a '{model.kind}' model has no analytic part f_a: no glTF fallback to fit")
            names = list(materials) if materials else model.materials
            indices = [model.index(n) for n in names]  # KeyError naming a missing material, before any fit
            for name, i in zip(names, indices):
                p = model.analytic_params(i)
                report = fit_fallback(p.kd, p.eta, p.alpha, hybrid=lambda wi, wo, i=i: model.eval(wi, wo, i),
                                      **fit_kwargs)
                hybrid = {"kind": "model", "material": name, "fallback": report_json(report)}
                entries.append(ExportMaterial(name, report.material, hybrid, [(MODEL_FILE, data)]))
                reports.append(report)
                if progress:
                    progress(name, report)
    write_glb(out, geometry, entries)
    return reports
