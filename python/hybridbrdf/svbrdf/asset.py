"""A textured material (docs/SVBRDF.md; spec/model.json, ``svbrdf``): a model's network with a
base layer and up to three more, each a material of the model whose analytic parameters p and
latent code z may vary per texel, mixed per texel by a weights map:

    f(uv, wi, wo) = sum_k w_k(uv) f_t(wi, wo; p_k(uv), z_k(uv), material k's output layer and table)

A convex combination of BRDFs is a BRDF: each layer reciprocal and bounded keeps the texel so,
and at a pure texel (one weight 1) the cost is one evaluation. Weights are linear in the
BRDF, so filtering the weights map *is* filtering the BRDFs; p and z maps are filtered as
values (the difference is measured in docs/SVBRDF.md).

The folder: ``svbrdf.json`` (the index), ``model.safetensors`` and the maps it names.
"""

from __future__ import annotations

import json
import os
from typing import TYPE_CHECKING, Dict, List, Optional, Sequence

import numpy as np

from hybridbrdf import spec
from hybridbrdf.errors import InputFileError
from hybridbrdf.inputs import loads_json, read_input_text
from hybridbrdf.limits import pair_arguments
from hybridbrdf.model.file import HybridModel, load_model
from hybridbrdf.svbrdf.entries import (LAYER_QUANTITIES, SVBRDFError, FORMATS as MAP_FORMATS, components, plain_name, read_entry,
                                       write_quantity, KTX2_KD_DEFAULT, KTX2_KD_FORMATS)
from hybridbrdf.svbrdf.mips import TOKSVIG_DEFAULT, build_chain, chain_problem, level_size, lod_levels, tangent_normals
from hybridbrdf.svbrdf.normals import to_shading
from hybridbrdf.files import atomic_folder, atomic_write_bytes

if TYPE_CHECKING:  # annotations only: PyTorch is imported where a material runs in it
    import torch

SV = spec.SVBRDF
MAX_LAYERS = SV["max_layers"]
CHANNELS = SV["map_channels"]
INDEX_KEYS = {"format_version", "model", "size", "addressing", "layers", "maps"}
FORMAT_VERSIONS = (1, SV["format_version"])  # 1: no mip chain; 2 adds "levels" and each map's "mips"
MAX_LEVELS = SV["max_side"].bit_length()
#: Bytes per pair of :meth:`SVBRDF.eval` besides the model's evaluation: float64 copies of uv,
#: wi, wo and four layers' texel values from four bilinear taps (an estimate, not a measurement:
#: 4 layers x 4 taps x 16 float64 values is 2 KiB).
BYTES_PER_PAIR = 2048


def texel_taps(uv: np.ndarray, size, addressing: str, filter: str):
    """[(rows, cols, weights)] of the texels a (W, H) = ``size`` map reads at uv (N, 2): one tap
    (``nearest``) or four (``bilinear``, between texel centres), ``repeat`` or ``clamp``
    addressing (docs/SVBRDF.md, "Texture coordinates")."""
    w, h = size
    u, v = uv[:, 0], uv[:, 1]
    repeat = addressing == "repeat"
    if filter == "nearest":
        if repeat:
            cols, rows = np.floor(u * w).astype(np.int64) % w, np.floor(v * h).astype(np.int64) % h
        else:
            cols = np.clip(np.floor(np.clip(u, 0, 1) * w), 0, w - 1).astype(np.int64)
            rows = np.clip(np.floor(np.clip(v, 0, 1) * h), 0, h - 1).astype(np.int64)
        return [(rows, cols, np.ones(len(uv)))]
    if filter != "bilinear":
        raise ValueError(f"filter must be one of {', '.join(SV['filters'])}, got {filter!r}")
    x = (u if repeat else np.clip(u, 0, 1)) * w - 0.5
    y = (v if repeat else np.clip(v, 0, 1)) * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)

    def wrap(i, n):
        return i % n if repeat else np.clip(i, 0, n - 1)

    taps = []
    for dy, wy in ((0, 1 - fy), (1, fy)):
        for dx, wx in ((0, 1 - fx), (1, fx)):
            taps.append((wrap(y0 + dy, h), wrap(x0 + dx, w), wx * wy))
    return taps


class SVBRDF:
    """A textured material in memory: ``model`` (a hybrid :class:`HybridModel`), ``layers`` (material
    names, the base first), ``weights`` ((H, W, 3) decoded w_1..3, or None for one layer),
    ``maps`` (per layer, quantity -> decoded (H, W, components) float32), ``size`` (W, H),
    ``addressing`` ('repeat' or 'clamp'), ``normal`` ((H, W, 2) tangent-space x, y of a normal map,
    one for the texel: :mod:`hybridbrdf.svbrdf.normals`; or None), ``mips`` (levels 1 .. 1x1 of
    a mip chain, each (weights, maps) or (weights, maps, normal) at its size, or empty:
    :meth:`with_mips` builds them; kept as ``mips``, (weights, maps) per level, and
    ``normal_mips``, the normal map per level or empty). Build one with :func:`load_svbrdf` or
    :func:`hybridbrdf.fit.paint`."""

    def __init__(self, model: HybridModel, layers: Sequence[str], size, weights: Optional[np.ndarray] = None,
                 maps: Optional[Sequence[Dict[str, np.ndarray]]] = None, addressing: str = "repeat",
                 path: Optional[str] = None, mips: Sequence = (), normal: Optional[np.ndarray] = None):
        if not model.has_analytic:
            raise ValueError("a textured material needs a hybrid model (f_a per texel); this one is "
                             f"'{model.kind}'")
        if not 1 <= len(layers) <= MAX_LAYERS:
            raise ValueError(f"a textured material has 1 to {MAX_LAYERS} layers, got {len(layers)}")
        if addressing not in SV["addressing"]:
            raise ValueError(f"addressing must be one of {', '.join(SV['addressing'])}, got {addressing!r}")
        self.model, self.layers, self.addressing, self.path = model, list(layers), addressing, path
        self.indices = [model.index(m) for m in self.layers]
        self.size = (int(size[0]), int(size[1]))
        w, h = self.size
        self.maps = [dict(m) for m in (maps or [{} for _ in self.layers])]
        if len(self.maps) != len(self.layers):
            raise ValueError("one dict of maps per layer")
        if weights is None and len(self.layers) > 1:
            raise ValueError("a textured material of several layers needs a weights map")
        self.weights = None if weights is None else np.asarray(weights, dtype=np.float32)
        self.normal = None if normal is None else np.asarray(normal, dtype=np.float32)
        for name, arr in [("weights", self.weights), ("normal", self.normal)] + [(q, a) for m in self.maps for q, a in m.items()]:
            if arr is None:
                continue
            c = 3 if name == "weights" else components(name, model.arch["latent"])
            if arr.shape != (h, w, c):
                raise ValueError(f"{name} map has shape {arr.shape}, expected {(h, w, c)}")
            if name == "normal" and not np.isfinite(arr).all():  # a NaN frame would shade every pair 0 silently
                raise ValueError("normal map is not finite")
        checked = [self._checked_level(level, *entry) for level, entry in enumerate(mips, start=1)]
        self.mips = [(w_l, m_l) for w_l, m_l, _ in checked]
        self.normal_mips = [n_l for _, _, n_l in checked] if self.normal is not None else []
        problem = chain_problem(self.size, self.levels)
        if problem:
            raise ValueError(problem)

    def _checked_level(self, level: int, weights, maps, normal=None):
        """(weights, maps, normal) of mip level ``level`` as float32, shaped as that level and
        holding the same maps as level 0 (ValueError otherwise)."""
        w, h = level_size(self.size, level)
        if (weights is None) != (self.weights is None) or (normal is None) != (self.normal is None) or len(maps) != len(
                self.maps) or any(set(m) != set(m0) for m, m0 in zip(maps, self.maps)):
            raise ValueError(f"mip level {level} must hold the same maps as level 0")
        weights = None if weights is None else np.asarray(weights, dtype=np.float32)
        normal = None if normal is None else np.asarray(normal, dtype=np.float32)
        maps = [{q: np.asarray(a, dtype=np.float32) for q, a in m.items()} for m in maps]
        for name, arr in [("weights", weights), ("normal", normal)] + [(q, a) for m in maps for q, a in m.items()]:
            if arr is not None and arr.shape[:2] != (h, w):
                raise ValueError(f"mip level {level}: {name} map has shape {arr.shape}, expected {h}x{w} texels")
        return weights, maps, normal

    @property
    def levels(self) -> int:
        """Mip levels: 1 (level 0 alone) or the complete chain down to 1x1."""
        return 1 + len(self.mips)

    def with_mips(self, alpha_rule: str = "perceptual", toksvig: float = TOKSVIG_DEFAULT) -> "SVBRDF":
        """This material with its complete mip chain (:mod:`hybridbrdf.svbrdf.mips`: weights
        averaged, kd by the layers' weights, alpha by the mean of sqrt(alpha) (``alpha_rule``:
        'perceptual', or 'value' / 'mean_square' for comparison), eta and z by value, the normal
        map's normalised mean widening alpha by ``toksvig`` (1 - |n|) / |n|; a layer without an
        alpha map then gains one, its material's alpha at level 0); needs power-of-two sides
        (ValueError)."""
        maps = [dict(m) for m in self.maps]
        if self.normal is not None:
            h, w = self.size[1], self.size[0]
            for i, m in zip(self.indices, maps):
                if "alpha" not in m:
                    own = np.asarray(self.model.tensors["materials.alpha"][i], dtype=np.float32)
                    m["alpha"] = np.broadcast_to(own, (h, w, 2)).copy()
        chain = build_chain(self.weights, maps, len(self.layers), self.size, alpha_rule, self.normal, toksvig)
        return SVBRDF(self.model, self.layers, self.size, self.weights, maps, self.addressing, self.path, chain, self.normal)

    # ---- texel lookup ------------------------------------------------------------------
    def texels(self, uv, filter: str = "bilinear", lod=None) -> Dict[str, np.ndarray]:
        """Per pair the texel's layer values: ``weight`` (N, L), ``kd``, ``eta`` (N, L, 3),
        ``alpha`` (N, L, 2), ``latent`` (N, L, l), ``normal`` (N, 3: the unit tangent-space normal,
        (0, 0, 1) without a normal map; x and y filtered, then z = sqrt(1 - x^2 - y^2) and
        normalised, as a GPU reconstructs a BC5 map), float32; decoded values filtered, then the
        weights normalised (w_0 = 1 - w_1 - w_2 - w_3, all divided by their sum when above 1). The row
        count is bounded by memory before anything is converted (hybridbrdf.limits: ValueError).
        ``lod`` (a number or (N,)): the level of detail, read trilinearly from the mip chain (the
        two levels around it, each filtered by ``filter``, mixed linearly; clamped to the chain;
        :func:`hybridbrdf.svbrdf.mips.lod_from_footprint` gives it from uv derivatives); None
        reads level 0."""
        uv = np.asarray(pair_arguments(("uv",), (uv,), (2,), BYTES_PER_PAIR)[0], dtype=np.float64)  # bounded first
        if not np.isfinite(uv).all():
            raise ValueError("uv must be finite")
        if lod is None or self.levels == 1:
            return _unit_normal(self._level_texels(uv, filter, 0))
        fine, t = lod_levels(np.broadcast_to(np.asarray(lod, dtype=np.float64), (len(uv),)), self.levels)
        out = None
        for level in np.unique(fine):
            rows = np.nonzero(fine == level)[0]
            a = self._level_texels(uv[rows], filter, int(level))
            if level + 1 < self.levels:
                b, f = self._level_texels(uv[rows], filter, int(level) + 1), t[rows]
                a = {key: (a[key] * (1 - f).reshape((-1,) + (1,) * (a[key].ndim - 1))
                           + b[key] * f.reshape((-1,) + (1,) * (b[key].ndim - 1))).astype(np.float32) for key in a}
            if out is None:
                out = {key: np.empty((len(uv),) + v.shape[1:], dtype=np.float32) for key, v in a.items()}
            for key in a:
                out[key][rows] = a[key]
        return _unit_normal(out)

    def _level_texels(self, uv: np.ndarray, filter: str, level: int) -> Dict[str, np.ndarray]:
        """:meth:`texels` at one mip level."""
        n, L = len(uv), len(self.layers)
        weights, level_maps = (self.weights, self.maps) if level == 0 else self.mips[level - 1]
        normal = self.normal if level == 0 or self.normal is None else self.normal_mips[level - 1]
        taps = texel_taps(uv, level_size(self.size, level), self.addressing, filter)

        def sample(arr):
            return sum(arr[r, c].astype(np.float64) * t[:, None] for r, c, t in taps)

        out = {}
        if weights is None:
            weight = np.ones((n, 1))
        else:
            rest = sample(weights)[:, :L - 1]
            total = rest.sum(axis=1, keepdims=True)
            rest = np.where(total > 1, rest / np.maximum(total, 1e-30), rest)
            weight = np.concatenate([np.clip(1 - rest.sum(axis=1, keepdims=True), 0, 1), rest], axis=1)
        out["weight"] = weight.astype(np.float32)
        out["normal"] = (np.zeros((n, 2)) if normal is None else sample(normal)).astype(np.float32)  # x, y: _unit_normal
        for q in LAYER_QUANTITIES:
            c = components(q, self.model.arch["latent"])
            vals = np.empty((n, L, c), dtype=np.float32)
            for k, (i, maps) in enumerate(zip(self.indices, level_maps)):
                if q in maps:
                    vals[:, k] = sample(maps[q])
                else:
                    own = self.model.tensors["materials.z" if q == "latent" else f"materials.{q}"][i]
                    vals[:, k] = np.asarray(own, dtype=np.float32)[None, :]
            out[q] = vals
        return out

    # ---- evaluation ----------------------------------------------------------------------
    def eval(self, uv, wi, wo, filter: str = "bilinear", dtype: Optional[torch.dtype] = None, lod=None) -> np.ndarray:
        """f(uv, wi, wo) (N, 3) float64, no cosine: uv (N, 2) in [0, 1]^2 (wrapping or clamped by
        ``addressing``), wi and wo (N, 3) in the *geometric* frame (t, b, n = x, y, z): with a normal
        map each texel's layers see them in its shading frame, and f is 0 unless both are above
        both horizons (:mod:`hybridbrdf.svbrdf.normals`); ``lod`` as :meth:`texels` reads it. By default
        libhybridbrdf's scalar path (``HybridModel::eval_texel``, the tracer's and the shaders'
        twin) for a model read from a file; ``dtype`` (torch.float32 / torch.float64) evaluates
        the PyTorch model instead."""
        uv, wi, wo = pair_arguments(("uv", "wi", "wo"), (uv, wi, wo), (2, 3, 3),
                                    BYTES_PER_PAIR + self.model.bytes_per_pair(dtype))
        wi, wo = (np.asarray(a, dtype=np.float64) for a in (wi, wo))
        t = self.texels(uv, filter, lod)
        visible = None
        if self.normal is not None:
            wi, wo, visible = to_shading(t["normal"], wi, wo)
        if dtype is None and self.model.path is not None:
            mat = np.broadcast_to(np.asarray(self.indices, dtype=np.int32), t["weight"].shape)
            f = self.model._cpp_model().eval_texels(
                wi.astype(np.float32), wo.astype(np.float32), np.ascontiguousarray(mat), t["weight"], t["kd"],
                t["eta"], t["alpha"], t["latent"]).astype(np.float64)
        else:
            import torch

            f = _eval_torch(self.model, self.indices, t, wi, wo, dtype or torch.float32)
        return f if visible is None else np.where(visible[:, None], f, 0.0)

    # ---- persistence ---------------------------------------------------------------------
    def save(self, folder, format: str = "png", extra: Optional[Dict[str, bytes]] = None,
             kd_format: str = KTX2_KD_DEFAULT) -> None:
        """Write the folder (index, model, maps) atomically (:func:`hybridbrdf.files.atomic_folder`):
        into a temporary folder beside it, then renamed over it; SIGTERM or an error leaves the old
        folder, an OSError names ``folder``. ``format``: 'png' (8-bit, the spec's decode; latent scale and offset from
        the values), 'exr' (float32, decoded values stored), each a file per mip level, or 'ktx2'
        (the 8-bit decode in GPU block formats, one file holding the chain:
        :data:`hybridbrdf.svbrdf.entries.KTX2_FORMATS`; kd maps in ``kd_format``, 'bc1' (half a byte
        a texel, the default) or 'bc7': :data:`~hybridbrdf.svbrdf.entries.KTX2_KD_FORMATS`). An existing ``folder`` is replaced
        only when it is a textured material's folder (it holds svbrdf.json) or empty. ``extra``:
        plain file name -> bytes, written into the folder with it (a fit's report)."""
        if format not in MAP_FORMATS:
            raise ValueError(f"format must be one of {', '.join(MAP_FORMATS)}, got {format!r}")
        if kd_format not in KTX2_KD_FORMATS:
            raise ValueError(f"kd_format must be one of {', '.join(KTX2_KD_FORMATS)}, got {kd_format!r}")
        folder = os.path.abspath(os.fspath(folder))
        if os.path.lexists(folder):
            if not os.path.isdir(folder):
                raise InputFileError(folder, "exists and is not a folder")
            if os.listdir(folder) and not os.path.isfile(os.path.join(folder, SV["index_file"])):
                raise InputFileError(folder, f"is a folder without {SV['index_file']}; refusing to replace it")
        with atomic_folder(folder) as tmp:
            before = self.model.path  # save_checked points the model at its copy, in a folder renamed below
            try:
                self.model.save_checked(os.path.join(tmp, SV["model_file"]))
            finally:
                self.model.path = before
            entries = []
            chain = [(self.weights, self.maps, self.normal)] + [
                (w_l, m_l, self.normal_mips[i] if self.normal is not None else None) for i, (w_l, m_l) in enumerate(self.mips)]
            if self.weights is not None:
                entries += write_quantity(tmp, "weights", None, [c[0] for c in chain], format, len(self.layers))
            if self.normal is not None:
                entries += write_quantity(tmp, "normal", None, [c[2] for c in chain], format)
            for k in range(len(self.layers)):
                for q in LAYER_QUANTITIES:
                    if q in self.maps[k]:
                        entries += write_quantity(tmp, q, k, [c[1][k][q] for c in chain], format, kd_format=kd_format)
            index = {"format_version": 1 if self.levels == 1 else SV["format_version"], "model": SV["model_file"],
                     "size": list(self.size), "addressing": self.addressing,
                     **({} if self.levels == 1 else {"levels": self.levels}),
                     "layers": [{"material": m} for m in self.layers], "maps": entries}
            atomic_write_bytes(os.path.join(tmp, SV["index_file"]), (json.dumps(index, indent=1) + "\n").encode())
            for name, data in (extra or {}).items():
                if os.path.basename(name) != name or name in os.listdir(tmp):
                    raise ValueError(f"extra file {name!r}: must be a plain name the folder does not use")
                atomic_write_bytes(os.path.join(tmp, name), data)
            load_svbrdf(tmp)  # what was written reads back
        self.path = folder
        self.model = load_model(os.path.join(folder, SV["model_file"]))  # evaluated by libhybridbrdf from now on


def _unit_normal(t: Dict[str, np.ndarray]) -> Dict[str, np.ndarray]:
    """:meth:`SVBRDF.texels`' filtered normal x, y made the unit tangent-space normal."""
    t["normal"] = tangent_normals(t["normal"]).astype(np.float32)
    return t


def _no_constant(name: str):
    """NaN, Infinity and -Infinity are not JSON (RFC 8259); libhybridbrdf's parser refuses them too."""
    raise ValueError(f"{name} is not a JSON number")


def _eval_torch(model: HybridModel, indices: List[int], t: Dict[str, np.ndarray], wi, wo, dtype) -> np.ndarray:
    """The texels' f with the PyTorch model: per layer, the pairs of positive weight."""
    import torch

    from hybridbrdf.brdf.torch_brdf import _normalize
    from hybridbrdf.model.networks import energy_bound_scale

    mod = model._module(dtype)
    f = torch.zeros((len(wi), 3), dtype=dtype)
    wi_t, wo_t = torch.as_tensor(wi, dtype=dtype), torch.as_tensor(wo, dtype=dtype)
    with torch.no_grad():
        for k, i in enumerate(indices):
            rows = np.nonzero(t["weight"][:, k] > 0)[0]
            if not len(rows):
                continue
            mt = model._material_tensors(i, dtype)
            head = (mt["head_weight"][0], mt["head_bias"][0]) if "head_weight" in mt else None
            sel = {q: torch.as_tensor(t[q][rows, k], dtype=dtype) for q in LAYER_QUANTITIES}
            fk, _ = mod.evaluate_pairs(wi_t[rows], wo_t[rows], sel["kd"], sel["eta"], sel["alpha"], sel["latent"], head)
            if "energy_bound" in mt:  # as HybridModel._eval scales a material's f_t
                wi_n, wo_n = (_normalize(w[rows])[0] for w in (wi_t, wo_t))
                table = mt["energy_bound"][0]
                fk = fk * (energy_bound_scale(table, wi_n[:, 2]) * energy_bound_scale(table, wo_n[:, 2]))[:, None]
            f[rows] += fk * torch.as_tensor(t["weight"][rows, k], dtype=dtype)[:, None]
    return f.double().numpy()


# ---- reading ------------------------------------------------------------------------------
def _layer_names(index, index_path, model) -> List[str]:
    """The index's layers' material names, each checked against the model."""
    layers = index["layers"]
    if not (isinstance(layers, list) and 1 <= len(layers) <= MAX_LAYERS):
        raise SVBRDFError(index_path, f"layers must be a list of 1 to {MAX_LAYERS} layers")
    names = []
    for k, layer in enumerate(layers):
        if not (isinstance(layer, dict) and set(layer) == {"material"} and isinstance(layer["material"], str)):
            raise SVBRDFError(index_path, f"layer {k} must be {{\"material\": NAME}}")
        if layer["material"] not in model.materials:
            raise SVBRDFError(index_path, f"layer {k}: material '{layer['material']}' is not in {index['model']}")
        names.append(layer["material"])
    return names


def load_svbrdf(folder) -> SVBRDF:
    """Read and validate a textured material's folder (docs/SVBRDF.md): the index, the model it
    names, every map (sizes bounded before reading; values finite and in range). Raises
    :class:`SVBRDFError` (or the model's ModelFileError), one line naming the file and the problem."""
    folder = os.fspath(folder)
    if not os.path.isdir(folder):
        raise SVBRDFError(folder, "no such folder" if not os.path.lexists(folder) else "is not a folder")
    index_path = os.path.join(folder, SV["index_file"])
    text = read_input_text(index_path, "textured-material index", SV["max_index_bytes"], SVBRDFError)
    index = loads_json(text, index_path, "textured-material index", SVBRDFError, parse_constant=_no_constant)
    if not isinstance(index, dict):
        raise SVBRDFError(index_path, "the index must be a JSON object")
    version = index.get("format_version")
    if version not in FORMAT_VERSIONS or isinstance(version, bool):
        raise SVBRDFError(index_path, f"format_version {version!r} is not supported "
                                      f"(this library reads {' and '.join(map(str, FORMAT_VERSIONS))})")
    keys = INDEX_KEYS | ({"levels"} if version >= 2 else set())
    unknown, missing = set(index) - keys, keys - set(index)
    if unknown or missing:
        raise SVBRDFError(index_path, f"unknown keys {sorted(unknown)}" if unknown else f"missing keys {sorted(missing)}")
    model_path = os.path.join(folder, plain_name(index_path, index["model"], "model"))
    model = load_model(model_path)
    if not model.has_analytic:
        raise SVBRDFError(model_path, f"a textured material needs a hybrid model; this one is '{model.kind}'")
    size = index["size"]
    if not (isinstance(size, list) and len(size) == 2 and all(isinstance(s, int) and not isinstance(s, bool)
                                                                 and 1 <= s <= SV["max_side"] for s in size)):
        raise SVBRDFError(index_path, f"size must be [W, H], integers 1 to {SV['max_side']}, got {size!r}")
    if index["addressing"] not in SV["addressing"]:
        raise SVBRDFError(index_path, f"addressing must be one of {', '.join(SV['addressing'])}, got {index['addressing']!r}")
    names = _layer_names(index, index_path, model)
    w, h = size
    levels = index.get("levels", 1)
    if not (isinstance(levels, int) and not isinstance(levels, bool) and 1 <= levels <= MAX_LEVELS):
        raise SVBRDFError(index_path, f"levels must be an integer 1 to {MAX_LEVELS}, got {levels!r}")
    problem = chain_problem((w, h), levels)
    if problem:
        raise SVBRDFError(index_path, problem)
    latent = model.arch["latent"]
    weights, normal, seen = None, None, set()
    parts: Dict = {}
    if not isinstance(index["maps"], list):
        raise SVBRDFError(index_path, "maps must be a list")
    for entry in index["maps"]:
        quantity, layer, first, path, values = read_entry(folder, index_path, entry, len(names), latent, (w, h), levels)
        key = (quantity, layer, first)
        if key in seen:
            raise SVBRDFError(index_path, f"two maps give {quantity} {first}..{first + 2}"
                                          + ("" if layer is None else f" of layer {layer}"))
        seen.add(key)
        if quantity == "weights":
            for file, level_values in zip(path, values):
                if level_values[..., len(names) - 1:].any():
                    raise SVBRDFError(file, f"weights of layers beyond the last ({len(names) - 1}) must be 0")
            weights = values
        elif quantity == "normal":
            normal = [v[..., :2] for v in values]
        else:
            parts.setdefault((layer, quantity), {})[first] = values
    maps = [[{} for _ in names] for _ in range(levels)]
    for (layer, quantity), pieces in parts.items():
        c = components(quantity, latent)
        firsts = sorted(pieces)
        if firsts != list(range(0, c, CHANNELS)):
            raise SVBRDFError(index_path, f"layer {layer}: {quantity} maps must cover components 0..{c - 1} "
                                          f"(maps start at {firsts})")
        for level in range(levels):
            maps[level][layer][quantity] = np.concatenate([pieces[f][level] for f in firsts], axis=2)[..., :c].astype(np.float32)
    if len(names) > 1 and weights is None:
        raise SVBRDFError(index_path, f"{len(names)} layers need a weights map")
    chain = [(None if weights is None else weights[level], maps[level], None if normal is None else normal[level])
             for level in range(levels)]
    return SVBRDF(model, names, (w, h), chain[0][0], chain[0][1], index["addressing"], path=os.path.abspath(folder),
                  mips=chain[1:], normal=chain[0][2])


