"""Authoring textured materials (``hbrdf paint``; docs/SVBRDF.md): a base material and layers
painted over it by grey masks, optional albedo and roughness textures per layer, written as a
textured-material folder.

    sv = paint("collection.safetensors", base="paper_white_rgb",
               layers=[("vch_golden_yellow_rgb", "film.png"), ("new_metal.bsdf", "scratches.png")],
               out="out/painted")

A layer names a material of the model, or a measured file (any format ``hbrdf add`` reads): the
file is added to the model first by the paper's sparse fit (``hybridbrdf.add(..., to=MODEL)``: its
(p, z, output layer) on the model's frozen network, the network and the model's own materials
unchanged), so every layer shares one network. Masks composite front to back in the order given
("over"): layer k keeps m_k times what the layers above it leave, the base the rest; per texel
the weights sum to 1, and the textured material is the mixture sum_k w_k f_k of its layers, exact
wherever the layers are (a convex combination of the measurements is matched up to the layers'
own errors).
"""

from __future__ import annotations

import os
from typing import Callable, Dict, Optional, Sequence, Tuple, Union

import numpy as np
from PIL import Image

from hybridbrdf import spec
from hybridbrdf.errors import InputFileError
from hybridbrdf.fit.adding import add
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.inputs import check_input_file
from hybridbrdf.model.editing import edit
from hybridbrdf.model.file import HybridModel, load_model
from hybridbrdf.sources import expand_sources, open_source
from hybridbrdf.sources.names import material_names
from hybridbrdf.svbrdf.asset import SVBRDF
from hybridbrdf.svbrdf.mips import chain_length, chain_problem
from hybridbrdf.svbrdf.normals import read_normal_map
from hybridbrdf.svbrdf.decode import transfer
from hybridbrdf.svbrdf.maps import MAX_MAP_BYTES, MAX_SIDE, map_bits, read_map

PathLike = Union[str, os.PathLike]


def read_grey(path: PathLike, what: str) -> np.ndarray:
    """A mask or roughness texture as (H, W) float64 in [0, 1]: a PNG's first channel (any mode
    Pillow reads: L, LA, RGB, RGBA, 8 or 16 bits) scaled to [0, 1], or an EXR's R channel (values
    outside [0, 1] or not finite refused). InputFileError naming the file otherwise."""
    path = os.fspath(path)
    bits = map_bits(path)
    check_input_file(path, what, MAX_MAP_BYTES)
    if not bits:
        values = read_map(path)[0][..., 0]
        if values.min() < 0 or values.max() > 1:
            raise InputFileError(path, f"{what} values must lie in [0, 1]; found {values.min():g} to {values.max():g}")
        return values
    try:
        with Image.open(path) as img:
            if not (0 < img.size[0] <= MAX_SIDE and 0 < img.size[1] <= MAX_SIDE):
                raise InputFileError(path, f"{what} is {img.size[0]}x{img.size[1]}; each side must be 1 to {MAX_SIDE}")
            arr = np.asarray(img)
    except InputFileError:
        raise
    except (OSError, ValueError, SyntaxError) as exc:
        raise InputFileError(path, f"cannot read the {what}: {exc}") from None
    top = 65535.0 if arr.dtype in (np.uint16, np.int32) and arr.max(initial=0) > 255 else 255.0
    grey = arr[..., 0] if arr.ndim == 3 else arr
    return np.clip(grey.astype(np.float64) / top, 0.0, 1.0)


def read_albedo(path: PathLike) -> np.ndarray:
    """An albedo texture as linear kd (H, W, 3): an 8-bit RGB PNG is sRGB-encoded (decoded by the
    sRGB EOTF), an EXR linear; every value must lie in [0, 1]."""
    path = os.fspath(path)
    values, bits = read_map(path)
    kd = transfer("srgb", values) if bits else values
    if kd.min() < spec.KD_MIN or kd.max() > spec.KD_MAX:
        raise InputFileError(path, f"albedo values must lie in [{spec.KD_MIN:g}, {spec.KD_MAX:g}]; found "
                                   f"{kd.min():g} to {kd.max():g}")
    return kd


def composite(masks: Sequence[np.ndarray]) -> np.ndarray:
    """Weights (H, W, len(masks)) of layers 1.. painted front to back by ``masks`` (each (H, W) in
    [0, 1], the last on top): w_k = m_k prod_{j > k} (1 - m_j); the base keeps 1 - sum."""
    remaining = np.ones_like(masks[0])
    weights = [None] * len(masks)
    for k in range(len(masks) - 1, -1, -1):
        weights[k] = masks[k] * remaining
        remaining = remaining - weights[k]
    return np.stack(weights, axis=2)


def _layer_materials(model_path: PathLike, model: HybridModel, names: Sequence[str], settings, progress: bool,
                     log: Callable[[str], None]) -> Tuple[HybridModel, list]:
    """The model with every layer that names a measured file added (sparse fit on the frozen
    network), and the layers' material names."""
    sources, where = [], []
    for k, name in enumerate(names):
        if name in model.materials:
            continue
        if not os.path.exists(name) and not name.startswith("synthetic:"):
            raise InputFileError(name, f"is neither a material of {model_path} nor a measured file")
        for p in expand_sources([name]):
            sources.append(open_source(p))
            where.append(k)
    if not sources:
        return model, list(names)
    if len(set(where)) != len(where):
        raise ValueError("a layer names a folder or glob of several files; give one measured file per layer")
    new_names = material_names(sources)
    log(f"adding {len(sources)} measured file(s) to the model by a sparse fit on its frozen network: "
        + ", ".join(new_names))
    merged = add(sources, to=model_path, settings=settings, progress=progress, log=log)
    out = list(names)
    for k, new in zip(where, new_names):
        out[k] = new
    return merged, out


def bound_bright_kd(model: HybridModel, names: Sequence[str], kd_maps: Dict[int, np.ndarray],
                    log: Callable[[str], None] = lambda msg: None) -> Tuple[HybridModel, list]:
    """Keep a layer whose kd map is brighter than its material within the energy bound: such a
    layer gets an edit of its material with kd = the map's per-channel maximum, and that edit's
    energy-bound table (``edit`` fits it), named ``<material>.kdmap<k>``. Every hybrid combine is
    non-decreasing in f_a and f_a in kd, so each texel's f_t is at most the edit's, and the edit's
    table keeps every texel's directional albedo within the bound; texels use their own kd (the
    map's) and the material's latent code and output layer as before. Returns (model, names)."""
    names = list(names)
    for k, kd in sorted(kd_maps.items()):
        brightest = kd.reshape(-1, 3).max(axis=0).astype(np.float64)
        own = np.asarray(model.analytic_params(names[k]).kd, np.float64)
        if np.all(brightest <= own):
            continue  # the material's table already bounds every texel
        name = f"{names[k][:56]}.kdmap{k}"
        model = edit(model, names[k], name, kd=np.clip(brightest, 0.0, 1.0))
        log(f"layer {k}: kd map up to {np.round(brightest, 3).tolist()} is brighter than {names[k]}'s kd "
            f"{np.round(own, 3).tolist()}: the layer uses {name}, its energy-bound table fitted for the brightest texel")
        names[k] = name
    return model, names


def paint(model: PathLike, base: str, layers: Sequence[Tuple[str, PathLike]], out: PathLike,
          size: Optional[Tuple[int, int]] = None, format: str = "png", addressing: str = "repeat",
          kd: Optional[Dict[int, PathLike]] = None, roughness: Optional[Dict[int, PathLike]] = None,
          settings: Optional[FitSettings] = None, progress: bool = False,
          log: Callable[[str], None] = lambda msg: None, mips: bool = False,
          normal: Optional[PathLike] = None, kd_format: str = "bc1") -> SVBRDF:
    """Write a textured material's folder ``out`` and return it (:class:`SVBRDF`).

    ``base``: a material of ``model`` (or a measured file); ``layers``: up to three
    (material or measured file, mask) pairs painted over it, the last on top; ``size`` (W, H),
    default the first mask's (masks of another size are refused); ``kd`` / ``roughness``: layer
    index (0 the base) -> albedo texture (sRGB PNG or linear EXR) / roughness texture (grey r,
    alpha = r^2 on both axes), of the same size. ``format``: 'png' (8-bit maps), 'exr' (float32) or
    'ktx2' (GPU block formats, :meth:`SVBRDF.save`: kd maps in ``kd_format`` 'bc1' or 'bc7'); ``mips``: with the complete mip chain
    (:meth:`SVBRDF.with_mips`; power-of-two sides, checked before any fitting). ``normal``: a
    glTF-style 8-bit RGB PNG normal map of the same size (:func:`hybridbrdf.svbrdf.normals.read_normal_map`). ``settings``: the sparse fit's (:class:`FitSettings`; default ``hbrdf add``'s).
    Everything is checked before any fitting; ``out`` is replaced only once complete."""
    if len(layers) > spec.SVBRDF["max_layers"] - 1:
        raise ValueError(f"at most {spec.SVBRDF['max_layers'] - 1} layers over the base, got {len(layers)}")
    base_model = load_model(model)
    masks = [read_grey(mask, "mask") for _, mask in layers]
    if size is None:
        if not masks:
            raise ValueError("give --size WxH when no layer has a mask")
        size = (masks[0].shape[1], masks[0].shape[0])
    w, h = int(size[0]), int(size[1])
    if not (0 < w <= spec.SVBRDF["max_side"] and 0 < h <= spec.SVBRDF["max_side"]):
        raise ValueError(f"size must be 1 to {spec.SVBRDF['max_side']} texels a side, got {w}x{h}")
    if mips and chain_problem((w, h), chain_length((w, h))):
        raise ValueError(chain_problem((w, h), chain_length((w, h))))
    for (_, mask_path), m in zip(layers, masks):
        if m.shape != (h, w):
            raise InputFileError(mask_path, f"mask is {m.shape[1]}x{m.shape[0]}; the textured material is {w}x{h}")
    n_layers = 1 + len(layers)
    textures = {}
    for label, table, reader in (("kd", kd or {}, read_albedo), ("alpha", roughness or {}, None)):
        for k, path in table.items():
            if not 0 <= int(k) < n_layers:
                raise ValueError(f"--{'kd' if label == 'kd' else 'roughness'} names layer {k}; layers are 0 to {n_layers - 1}")
            if reader is not None:
                values = reader(path)
            else:
                r = read_grey(path, "roughness texture")
                a = np.clip(r * r, spec.ALPHA_MIN, spec.ALPHA_MAX)
                values = np.stack([a, a], axis=2)
            if values.shape[:2] != (h, w):
                raise InputFileError(path, f"texture is {values.shape[1]}x{values.shape[0]}; the textured material is {w}x{h}")
            textures[(int(k), label)] = values.astype(np.float32)
    normal_xy = None if normal is None else read_normal_map(normal)
    if normal_xy is not None and normal_xy.shape[:2] != (h, w):
        raise InputFileError(normal, f"normal map is {normal_xy.shape[1]}x{normal_xy.shape[0]}; the textured material is {w}x{h}")
    names = [base] + [name for name, _ in layers]
    if len(set(names)) != len(names):
        raise ValueError("a material appears in two layers; paint it once with the union of its masks")
    merged, names = _layer_materials(model, base_model, names, settings, progress, log)
    merged, names = bound_bright_kd(merged, names, {k: v for (k, label), v in textures.items() if label == "kd"}, log)
    weights = composite(masks).astype(np.float32) if masks else None
    if weights is not None and weights.shape[2] < 3:
        weights = np.concatenate([weights, np.zeros((h, w, 3 - weights.shape[2]), np.float32)], axis=2)
    maps = [{label: v for (k2, label), v in textures.items() if k2 == k} for k in range(n_layers)]
    sv = SVBRDF(merged, names, (w, h), weights, maps, addressing, normal=normal_xy)
    if mips:
        sv = sv.with_mips()
    sv.save(out, format=format, kd_format=kd_format)
    return sv
