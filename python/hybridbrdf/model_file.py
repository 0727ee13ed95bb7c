"""Model files: the single hand-off between fitting and everything else.

Container: safetensors (a standard, safe format: an 8-byte little-endian header
length, a JSON header, raw little-endian tensor bytes; readable from C++ with a
small JSON parser). The JSON header's ``__metadata__`` holds one entry,
``"hybridbrdf"``, a JSON document:

    format_version       1
    conventions_version  docs/CONVENTIONS.md version the math follows
    library_version      hybridbrdf version that wrote the file
    arch                 {kind, width, depth, activation, latent, n_in, n_out, pre_exp_max,
                          input: "wi.x wi.y wi.z wo.x wo.y wo.z z_0 .. z_{l-1}" (+ "log1p f_a" for analytic-input)}
    materials            [{name, origin, isotropic, metrics: {...}}]  (order = row order of the tensors)
    training             settings of the fit (steps, batch, lr, seed, sources, ...)

Tensors (float32): ``mlp.hidden.<i>.weight`` (out, in), ``mlp.hidden.<i>.bias``,
``mlp.out.weight``, ``mlp.out.bias``; ``frames.weight``/``frames.bias`` (neural only);
per material ``materials.kd`` (M,3), ``materials.eta`` (M,3), ``materials.alpha`` (M,2)
(hybrid kinds only) and ``materials.z`` (M,l). Values are evaluation-ready (not the
optimiser's raw parameters), so saving then loading is bit-exact.

Loading validates everything and raises :class:`hybridbrdf.errors.ModelFileError`
naming the file and the first problem found.
"""

from __future__ import annotations

import json
import os
import struct
from typing import Any, Dict, List, Optional

import numpy as np
import torch

from hybridbrdf import _core
from hybridbrdf.errors import ModelFileError
from hybridbrdf.models import ACTIVATIONS, ARCHS, PRE_EXP_MAX, build_model
from hybridbrdf.util import atomic_write_bytes

FORMAT_VERSION = 1
METADATA_KEY = "hybridbrdf"
MAX_HEADER_BYTES = 64 << 20


def network_tensor_shapes(arch: Dict[str, Any]) -> Dict[str, tuple]:
    """Expected shapes of the shared-network tensors for an ``arch`` description."""
    shapes = {}
    sizes = [arch["n_in"]] + [arch["width"]] * arch["depth"]
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        shapes[f"mlp.hidden.{i}.weight"] = (b, a)
        shapes[f"mlp.hidden.{i}.bias"] = (b,)
    shapes["mlp.out.weight"] = (arch["n_out"], arch["width"])
    shapes["mlp.out.bias"] = (arch["n_out"],)
    if arch["kind"] == "neural":
        shapes["frames.weight"] = (18, arch["latent"])
        shapes["frames.bias"] = (18,)
    return shapes


def arch_description(module) -> Dict[str, Any]:
    kind = module.arch
    latent = module.latent_dim
    n_in = module.mlp.hidden[0].in_features
    n_out = module.mlp.out.out_features
    inputs = "wi.x wi.y wi.z wo.x wo.y wo.z" + "".join(f" z_{i}" for i in range(latent))
    if kind == "neural":
        inputs = "wi and wo in 3 predicted frames (t, b, n each; 18 values)" + "".join(f" z_{i}" for i in range(latent))
    if kind == "analytic-input":
        inputs += " log1p(f_a.r) log1p(f_a.g) log1p(f_a.b)"
    return {"kind": kind, "width": module.width, "depth": module.depth, "activation": module.activation,
            "latent": latent, "n_in": n_in, "n_out": n_out, "pre_exp_max": PRE_EXP_MAX, "input": inputs}


def _encode_safetensors(tensors: Dict[str, np.ndarray], metadata: Dict[str, str]) -> bytes:
    """safetensors serialisation (done here so the byte layout is ours to document)."""
    header: Dict[str, Any] = {"__metadata__": metadata}
    offset = 0
    blobs = []
    for name in sorted(tensors):
        arr = np.ascontiguousarray(tensors[name], dtype="<f4")
        data = arr.tobytes()
        header[name] = {"dtype": "F32", "shape": list(arr.shape), "data_offsets": [offset, offset + len(data)]}
        offset += len(data)
        blobs.append(data)
    hbytes = json.dumps(header, separators=(",", ":")).encode("utf-8")
    hbytes += b" " * ((8 - len(hbytes) % 8) % 8)  # align the data section to 8 bytes
    return struct.pack("<Q", len(hbytes)) + hbytes + b"".join(blobs)


def _decode_safetensors(path: str):
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except FileNotFoundError:
        raise ModelFileError(path, "no such file") from None
    except OSError as exc:
        raise ModelFileError(path, f"cannot read: {exc.strerror}") from None
    if len(raw) < 8:
        raise ModelFileError(path, f"truncated: {len(raw)} bytes, not even a safetensors header length")
    (hlen,) = struct.unpack("<Q", raw[:8])
    if hlen > MAX_HEADER_BYTES or 8 + hlen > len(raw):
        raise ModelFileError(path, f"not a safetensors file or truncated (header length {hlen}, file {len(raw)} bytes)")
    try:
        header = json.loads(raw[8:8 + hlen].decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(path, f"safetensors header is not valid JSON ({exc})") from None
    if not isinstance(header, dict):
        raise ModelFileError(path, "safetensors header is not a JSON object")
    metadata = header.pop("__metadata__", None) or {}
    data = memoryview(raw)[8 + hlen:]
    tensors = {}
    for name, info in header.items():
        try:
            dtype, shape, (start, end) = info["dtype"], tuple(int(s) for s in info["shape"]), info["data_offsets"]
        except (KeyError, TypeError, ValueError):
            raise ModelFileError(path, f"tensor {name!r}: malformed entry in the header") from None
        if dtype != "F32":
            raise ModelFileError(path, f"tensor {name!r}: dtype {dtype}, expected F32")
        n = int(np.prod(shape)) if shape else 1
        if not (0 <= start <= end <= len(data)) or end - start != 4 * n:
            raise ModelFileError(path, f"tensor {name!r}: data range [{start}, {end}) does not fit shape {shape} "
                                       f"in {len(data)} data bytes (truncated?)")
        tensors[name] = np.frombuffer(data[start:end], dtype="<f4").reshape(shape).copy()
    return metadata, tensors


class HybridModel:
    """A fitted collection: shared network + per-material parameters, ready to evaluate.

    ``materials``: names in file order. ``eval(wi, wo, material)`` gives f_t (N,3)
    and ``eval_analytic(wi, wo, material)`` its analytic part (hybrid kinds).
    Computed in PyTorch (float32 by default; ``dtype=torch.float64`` for a reference).
    """

    def __init__(self, arch: Dict[str, Any], materials: List[Dict[str, Any]], tensors: Dict[str, np.ndarray],
                 training: Optional[Dict[str, Any]] = None, path: Optional[str] = None):
        self.arch = arch
        self.material_info = materials
        self.tensors = tensors
        self.training = training or {}
        self.path = path
        self._modules: Dict[torch.dtype, torch.nn.Module] = {}
        self._cpp = None  # libhybridbrdf's HybridModel for this file, loaded on first use

    # ---- description ---------------------------------------------------------
    @property
    def kind(self) -> str:
        return self.arch["kind"]

    @property
    def materials(self) -> List[str]:
        return [m["name"] for m in self.material_info]

    def index(self, material) -> int:
        if isinstance(material, (int, np.integer)):
            if not 0 <= int(material) < len(self.material_info):
                raise KeyError(f"material index {material} out of range (0..{len(self.material_info) - 1})")
            return int(material)
        try:
            return self.materials.index(material)
        except ValueError:
            raise KeyError(f"no material {material!r} in the model; it has: {', '.join(self.materials)}") from None

    def analytic_params(self, material):
        """The analytic parameters of a material as :class:`hybridbrdf.AnalyticParams`."""
        from hybridbrdf.analytic import AnalyticParams

        if self.kind == "neural":
            raise ValueError("the neural baseline has no analytic part")
        i = self.index(material)
        return AnalyticParams(kd=self.tensors["materials.kd"][i].astype(np.float64),
                              eta=self.tensors["materials.eta"][i].astype(np.float64),
                              alpha=self.tensors["materials.alpha"][i].astype(np.float64))

    def latent(self, material) -> np.ndarray:
        return self.tensors["materials.z"][self.index(material)].copy()

    # ---- evaluation ------------------------------------------------------------
    def _module(self, dtype: torch.dtype):
        if dtype not in self._modules:
            a = self.arch
            mod = build_model(a["kind"], 1, a["width"], a["depth"], a["latent"], a["activation"])
            state = {k: torch.from_numpy(v) for k, v in self.tensors.items() if not k.startswith("materials.")}
            missing = mod.load_state_dict(state, strict=False)
            unexpected = [k for k in missing.missing_keys if not k.startswith(("kd_raw", "eta_raw", "alpha_raw", "z", "isotropic"))]
            if unexpected:
                raise ModelFileError(self.path, f"network tensors missing: {', '.join(unexpected)}")
            self._modules[dtype] = mod.to(dtype).eval()
        return self._modules[dtype]

    def _material_tensors(self, i: int, dtype):
        t = {k.split(".", 1)[1]: torch.from_numpy(v[i:i + 1]).to(dtype)
             for k, v in self.tensors.items() if k.startswith("materials.")}
        return t

    def eval(self, wi, wo, material, dtype: Optional[torch.dtype] = None) -> np.ndarray:
        """f_t(wi, wo) for material (name or index): (N,3) float64 array (no cosine).

        By default a model read from (or saved to) a file is evaluated by
        libhybridbrdf in float32, the runtime every engine uses; ``dtype``
        (torch.float32 or torch.float64) evaluates the PyTorch model instead,
        float64 being the reference the C++ library is tested against."""
        if dtype is None and self.path is not None:
            return self._cpp_model().eval(*self._rows(wi, wo), self.index(material)).astype(np.float64)
        return self._eval(wi, wo, material, dtype or torch.float32)[0]

    def eval_analytic(self, wi, wo, material, dtype: Optional[torch.dtype] = None) -> np.ndarray:
        """The analytic part f_a of a hybrid material (not available for the neural baseline)."""
        if self.kind == "neural":
            raise ValueError("the neural baseline has no analytic part")
        if dtype is None and self.path is not None:
            return self._cpp_model().eval_analytic(*self._rows(wi, wo), self.index(material)).astype(np.float64)
        return self._eval(wi, wo, material, dtype or torch.float32)[1]

    def _cpp_model(self):
        if self._cpp is None:
            self._cpp = _core.Model(self.path)
        return self._cpp

    @staticmethod
    def _rows(wi, wo):
        a, b = np.asarray(wi, dtype=np.float32), np.asarray(wo, dtype=np.float32)
        if a.ndim != 2 or a.shape[1] != 3 or b.shape != a.shape:
            raise ValueError(f"wi and wo must both have shape (N, 3), got {a.shape} and {b.shape}")
        return a, b

    def _eval(self, wi, wo, material, dtype):
        i = self.index(material)
        wi_t = torch.as_tensor(np.asarray(wi), dtype=dtype)
        wo_t = torch.as_tensor(np.asarray(wo), dtype=dtype)
        if wi_t.ndim != 2 or wi_t.shape[1] != 3 or wo_t.shape != wi_t.shape:
            raise ValueError(f"wi and wo must both have shape (N, 3), got {tuple(wi_t.shape)} and {tuple(wo_t.shape)}")
        mod = self._module(dtype)
        m = self._material_tensors(i, dtype)
        with torch.no_grad():
            if self.kind == "neural":
                f, fa = mod.evaluate(wi_t, wo_t, m["z"])
            else:
                f, fa = mod.evaluate(wi_t, wo_t, m["kd"], m["eta"], m["alpha"], m["z"])
        out = f[0].double().numpy()
        return out, (fa[0].double().numpy() if fa is not None else None)

    # ---- persistence -----------------------------------------------------------
    def header(self) -> Dict[str, Any]:
        from hybridbrdf import __version__

        return {"format_version": FORMAT_VERSION, "conventions_version": _core.CONVENTIONS_VERSION,
                "library_version": __version__, "arch": self.arch, "materials": self.material_info,
                "training": self.training}

    def save(self, path) -> None:
        """Write the model file atomically (temporary file + rename)."""
        meta = {METADATA_KEY: json.dumps(self.header(), sort_keys=True)}
        atomic_write_bytes(path, _encode_safetensors(self.tensors, meta))
        self.path = os.fspath(path)
        self._cpp = None

    @classmethod
    def from_module(cls, module, names: List[str], origins: List[str], training: Dict[str, Any],
                    metrics: Optional[List[Dict[str, Any]]] = None) -> "HybridModel":
        """Freeze a trained module into a model."""
        tensors = {k: v.detach().float().cpu().numpy().copy() for k, v in module.state_dict().items()
                   if k.startswith(("mlp.", "frames."))}
        for k, v in module.material_tensors().items():
            tensors[f"materials.{k}"] = v.cpu().numpy().copy()
        iso = module.isotropic.cpu().tolist()
        materials = [{"name": n, "origin": o, "isotropic": bool(s), "metrics": (metrics[i] if metrics else {})}
                     for i, (n, o, s) in enumerate(zip(names, origins, iso))]
        return cls(arch_description(module), materials, tensors, training)


def _validate(path: str, doc: Dict[str, Any], tensors: Dict[str, np.ndarray]) -> None:
    def fail(problem):
        raise ModelFileError(path, problem)

    if doc.get("format_version") != FORMAT_VERSION:
        fail(f"format_version {doc.get('format_version')!r} is not supported (this library reads {FORMAT_VERSION})")
    if doc.get("conventions_version") != _core.CONVENTIONS_VERSION:
        fail(f"conventions_version {doc.get('conventions_version')!r} differs from this library's "
             f"{_core.CONVENTIONS_VERSION}")
    arch = doc.get("arch")
    if not isinstance(arch, dict):
        fail("metadata has no 'arch' object")
    for key, typ in (("kind", str), ("width", int), ("depth", int), ("activation", str), ("latent", int),
                     ("n_in", int), ("n_out", int)):
        if not isinstance(arch.get(key), typ) or isinstance(arch.get(key), bool):
            fail(f"arch.{key} is missing or not a {typ.__name__}")
    if arch["kind"] not in ARCHS:
        fail(f"arch.kind {arch['kind']!r} is not one of {', '.join(ARCHS)}")
    if arch["activation"] not in ACTIVATIONS:
        fail(f"arch.activation {arch['activation']!r} is not one of {', '.join(ACTIVATIONS)}")
    if arch["width"] < 1 or arch["depth"] < 1 or arch["latent"] < 0:
        fail(f"arch has width {arch['width']}, depth {arch['depth']}, latent {arch['latent']}")
    expected_in = {"neural": 18 + arch["latent"], "analytic-input": 9 + arch["latent"]}.get(arch["kind"], 6 + arch["latent"])
    expected_out = 6 if arch["kind"] in ("hybrid", "analytic-input") else 3
    if (arch["n_in"], arch["n_out"]) != (expected_in, expected_out):
        fail(f"arch n_in/n_out {arch['n_in']}/{arch['n_out']} do not match kind {arch['kind']} with latent "
             f"{arch['latent']} (expected {expected_in}/{expected_out})")
    materials = doc.get("materials")
    if not isinstance(materials, list) or not materials:
        fail("metadata lists no materials")
    names = []
    for i, m in enumerate(materials):
        if not isinstance(m, dict) or not isinstance(m.get("name"), str) or not m["name"]:
            fail(f"material {i} has no name")
        names.append(m["name"])
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        fail(f"duplicate material names: {', '.join(dupes)}")
    n_mat = len(materials)
    expected = dict(network_tensor_shapes(arch))
    expected["materials.z"] = (n_mat, arch["latent"])
    if arch["kind"] != "neural":
        expected.update({"materials.kd": (n_mat, 3), "materials.eta": (n_mat, 3), "materials.alpha": (n_mat, 2)})
    missing = sorted(set(expected) - set(tensors))
    extra = sorted(set(tensors) - set(expected))
    if missing:
        fail(f"missing tensors: {', '.join(missing)}")
    if extra:
        fail(f"unexpected tensors: {', '.join(extra)}")
    for name, shape in expected.items():
        if tuple(tensors[name].shape) != shape:
            fail(f"tensor {name} has shape {tuple(tensors[name].shape)}, expected {shape}")
        if not np.isfinite(tensors[name]).all():
            fail(f"tensor {name} holds NaN or Inf")
    if arch["kind"] != "neural":
        for name, lo, hi in (("kd", 0.0, 1.0), ("eta", _core.ETA_MIN, _core.ETA_MAX),
                             ("alpha", np.float32(_core.ALPHA_MIN), _core.ALPHA_MAX)):
            t = tensors[f"materials.{name}"]
            bad = np.argwhere((t < lo) | (t > hi))
            if len(bad):
                r, c = bad[0]
                fail(f"material {names[r]!r}: {name}[{c}] = {float(t[r, c])!r} is outside [{lo:g}, {hi:g}]")
        alpha = tensors["materials.alpha"]
        for i, m in enumerate(materials):
            if m.get("isotropic", True) and alpha[i, 0] != alpha[i, 1]:
                fail(f"material {names[i]!r} is marked isotropic but alpha_x != alpha_y")


def load_model(path) -> HybridModel:
    """Read and validate a model file; raises ModelFileError naming the file and the problem."""
    path = os.fspath(path)
    metadata, tensors = _decode_safetensors(path)
    if METADATA_KEY not in metadata:
        raise ModelFileError(path, f"safetensors file without '{METADATA_KEY}' metadata: not a hybridbrdf model")
    try:
        doc = json.loads(metadata[METADATA_KEY])
    except (TypeError, json.JSONDecodeError) as exc:
        raise ModelFileError(path, f"'{METADATA_KEY}' metadata is not valid JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise ModelFileError(path, f"'{METADATA_KEY}' metadata is not a JSON object")
    _validate(path, doc, tensors)
    return HybridModel(doc["arch"], doc["materials"], tensors, doc.get("training"), path)
