"""Model files: the single hand-off between fitting and everything else.

Container: safetensors (a standard, safe format: an 8-byte little-endian header
length, a JSON header, raw little-endian tensor bytes), read and written here by the
``safetensors`` package and read in C++ by libhybridbrdf's own reader. The JSON
header's ``__metadata__`` holds one entry, ``"hybridbrdf"``, a JSON document:

    format_version       1
    conventions_version  docs/CONVENTIONS.md version the math follows
    library_version      hybridbrdf version that wrote the file
    arch                 {kind, width, depth, activation, latent, n_in, n_out, pre_exp_max,
                          input: a description of the network input (informative)}
    materials            [{name, origin, isotropic, metrics: {...}}]  (order = row order of the tensors)
    training             settings of the fit (steps, batch, lr, seed, sources, ...)

Tensors (float32): ``mlp.hidden.<i>.weight`` (out, in), ``mlp.hidden.<i>.bias``,
``mlp.out.weight``, ``mlp.out.bias`` (``arch.output_layer`` "shared", the default);
``frames.weight``/``frames.bias`` (neural only); per material ``materials.kd`` (M,3),
``materials.eta`` (M,3), ``materials.alpha`` (M,2) (hybrid kinds only), ``materials.z`` (M,l)
and, with ``arch.output_layer`` "material", each material's own output layer
``materials.head_weight`` (M, n_out, width) and ``materials.head_bias`` (M, n_out). Values are evaluation-ready (not the
optimiser's raw parameters), so saving then loading is bit-exact.

The contract (architectures, the fields of ``arch`` with their types and bounds, the
parameter ranges) is declared once in ``spec/model.json`` (:mod:`hybridbrdf.spec`);
loading checks it in the same order, with the same messages, as the C++ loader
(``cpp/src/model_validate.cpp``), and raises :class:`hybridbrdf.errors.ModelFileError` naming
the file and the first problem found. ``tests/data/malformed_models.json`` is the
shared table of broken files both loaders must reject alike.
"""

from __future__ import annotations

import json
import os
import struct
from typing import Any, Dict, List, Optional

import numpy as np
import safetensors
import safetensors.numpy
import torch

from hybridbrdf import _core, spec

from hybridbrdf.model import editing
from hybridbrdf.errors import ModelFileError
from hybridbrdf.inputs import check_input_file, loads_json
from hybridbrdf.model.networks import build_model
from hybridbrdf.names import name_problem, names_problem
from hybridbrdf.util import atomic_write_bytes
from hybridbrdf.version import __version__

FORMAT_VERSION = spec.FORMAT_VERSION
METADATA_KEY = spec.METADATA_KEY
MAX_HEADER_BYTES = spec.MAX_HEADER_BYTES


#: The output layer of a model whose ``arch`` does not name one (files older than material output
#: layers): spec/model.json's default of the arch field. (A new fit's default is FitSettings'.)
DEFAULT_OUTPUT_LAYER = next(f["default"] for f in spec.ARCH_FIELDS if f["key"] == "output_layer")


def output_layer(arch: Dict[str, Any]) -> str:
    """The output layer of an ``arch`` description: "shared" or "material" (spec/model.json)."""
    return arch.get("output_layer", DEFAULT_OUTPUT_LAYER)


def network_tensor_shapes(arch: Dict[str, Any]) -> Dict[str, tuple]:
    """Expected shapes of the shared-network tensors for an ``arch`` description."""
    shapes = {}
    sizes = [arch["n_in"]] + [arch["width"]] * arch["depth"]
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        shapes[f"mlp.hidden.{i}.weight"] = (b, a)
        shapes[f"mlp.hidden.{i}.bias"] = (b,)
    if output_layer(arch) == "shared":
        shapes["mlp.out.weight"] = (arch["n_out"], arch["width"])
        shapes["mlp.out.bias"] = (arch["n_out"],)
    if spec.ARCHS[arch["kind"]]["directions"] == "frames":
        shapes["frames.weight"] = (6 * spec.NEURAL_FRAMES, arch["latent"])
        shapes["frames.bias"] = (6 * spec.NEURAL_FRAMES,)
    return shapes


def input_description(kind: str, latent: int) -> str:
    """The network input of an architecture in words (recorded as ``arch.input``)."""
    a = spec.ARCHS[kind]
    directions = {"local": "wi.x wi.y wi.z wo.x wo.y wo.z",
                  "local_half": "wi.x wi.y wi.z wo.x wo.y wo.z cos_theta_h cos_theta_d"}.get(
        a["directions"], "wi and wo in 3 predicted frames (t, b, n each; 18 values)")
    extra = " log1p(f_a.r) log1p(f_a.g) log1p(f_a.b)" if a["extra"] == "log1p_fa" else ""
    return directions + "".join(f" z_{i}" for i in range(latent)) + extra


def arch_description(module) -> Dict[str, Any]:
    kind = module.arch
    latent = module.latent_dim
    return {"kind": kind, "width": module.width, "depth": module.depth, "activation": module.activation,
            "latent": latent, "n_in": module.mlp.hidden[0].in_features, "n_out": module.n_out,
            "pre_exp_max": module.pre_exp_max, "output_layer": module.output_layer,
            "input": input_description(kind, latent)}


def encode(tensors: Dict[str, np.ndarray], metadata: Dict[str, str]) -> bytes:
    """A safetensors file's bytes (float32 tensors, string metadata), by the safetensors package."""
    return safetensors.numpy.save({k: np.ascontiguousarray(v, dtype="<f4") for k, v in tensors.items()}, metadata)


def decode(path: str):
    """(metadata, tensors) of a safetensors file; ModelFileError for anything unreadable.

    The two checks before the safetensors package runs are the C++ reader's first two, with
    its messages (they catch the commonest damage: empty and cut-off files). Before them, the
    file must be a regular one (hybridbrdf.inputs: a FIFO would block the open, a device never
    end), and no longer than the largest model the contract allows (spec.MAX_DATA_BYTES, the
    C++ loader's bound and words too); safetensors maps the file and reads only the header and
    the tensors the header declares, each checked against the file's size."""
    check_input_file(path, "model file", 8 + MAX_HEADER_BYTES + spec.MAX_DATA_BYTES, ModelFileError)
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
            size = os.fstat(fh.fileno()).st_size
    except FileNotFoundError:
        raise ModelFileError(path, "no such file") from None
    except OSError as exc:
        raise ModelFileError(path, f"cannot read: {exc.strerror}") from None
    if size < 8:
        raise ModelFileError(path, f"truncated: {size} bytes, not even a safetensors header length")
    (hlen,) = struct.unpack("<Q", head)
    if hlen > MAX_HEADER_BYTES or 8 + hlen > size:
        raise ModelFileError(path, f"not a safetensors file or truncated (header length {hlen}, file {size} bytes)")
    try:
        with safetensors.safe_open(path, framework="numpy") as f:
            metadata = f.metadata() or {}
            tensors = {}
            for name in f.keys():
                dtype = f.get_slice(name).get_dtype()
                if dtype != spec.TENSOR_DTYPE:
                    raise ModelFileError(path, f"tensor '{name}': dtype {dtype}, expected {spec.TENSOR_DTYPE}")
                tensors[name] = np.array(f.get_tensor(name), dtype=np.float32)
    except safetensors.SafetensorError as exc:
        raise ModelFileError(path, f"not a valid safetensors file ({exc})") from None
    except MemoryError:  # the file's declared tensors, within the contract's bound, but not this machine's
        raise ModelFileError(path, f"needs {size - 8 - hlen} bytes of tensor data, more than this process could allocate") from None
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
    def output_layer(self) -> str:
        """"shared" (one output layer, the paper's) or "material" (each material its own head)."""
        return output_layer(self.arch)

    @property
    def has_analytic(self) -> bool:
        """Whether the architecture has an analytic part f_a (all but the neural baseline)."""
        return spec.ARCHS[self.kind]["analytic"]

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
        from hybridbrdf.brdf.analytic import AnalyticParams

        if not self.has_analytic:
            raise ValueError("the neural baseline has no analytic part")
        i = self.index(material)
        return AnalyticParams(kd=self.tensors["materials.kd"][i].astype(np.float64),
                              eta=self.tensors["materials.eta"][i].astype(np.float64),
                              alpha=self.tensors["materials.alpha"][i].astype(np.float64))

    def latent(self, material) -> np.ndarray:
        return self.tensors["materials.z"][self.index(material)].copy()

    # ---- editing (hybridbrdf.model.editing) ------------------------------------------------
    def edit(self, material, name: str, *, kd=None, eta=None, alpha=None,
             conserve_energy: bool = False) -> "HybridModel":
        """A new model: these materials and ``name``, ``material`` with the given analytic
        parameters (kd, eta, alpha) replaced; see :func:`hybridbrdf.model.editing.edit`."""
        return editing.edit(self, material, name, kd=kd, eta=eta, alpha=alpha, conserve_energy=conserve_energy)

    def mix(self, a, b, t: float, name: str, conserve_energy: bool = False) -> "HybridModel":
        """A new model: these materials and ``name``, the linear blend at ``t`` of the analytic
        parameters and latent codes of ``a`` and ``b``; see :func:`hybridbrdf.model.editing.mix`."""
        return editing.mix(self, a, b, t, name, conserve_energy=conserve_energy)

    def albedo(self, material, samples: Optional[int] = None) -> Dict[str, Any]:
        """Directional albedo of a material over a grid of outgoing directions and its maximum;
        see :func:`hybridbrdf.model.editing.albedo_profile`."""
        return editing.albedo_profile(self, material, editing.ALBEDO_SAMPLES if samples is None else samples)

    # ---- evaluation ------------------------------------------------------------
    def _module(self, dtype: torch.dtype):
        if dtype not in self._modules:
            a = self.arch
            mod = build_model(a["kind"], 1, a["width"], a["depth"], a["latent"], a["activation"],
                              pre_exp_max=a["pre_exp_max"], output_layer=self.output_layer)
            state = {k: torch.from_numpy(v) for k, v in self.tensors.items() if not k.startswith("materials.")}
            missing = mod.load_state_dict(state, strict=False)
            unexpected = [k for k in missing.missing_keys
                          if not k.startswith(("kd_raw", "eta_raw", "alpha_raw", "z", "isotropic", "head_"))]
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
        if not self.has_analytic:
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
            if not self.has_analytic:
                f, fa = mod.evaluate(wi_t, wo_t, m["z"])
            else:
                head = (m["head_weight"], m["head_bias"]) if "head_weight" in m else None
                f, fa = mod.evaluate(wi_t, wo_t, m["kd"], m["eta"], m["alpha"], m["z"], head)
        out = f[0].double().numpy()
        return out, (fa[0].double().numpy() if fa is not None else None)

    # ---- persistence -----------------------------------------------------------
    def header(self) -> Dict[str, Any]:

        return {"format_version": FORMAT_VERSION, "conventions_version": _core.CONVENTIONS_VERSION,
                "library_version": __version__, "arch": self.arch, "materials": self.material_info,
                "training": self.training}

    def save(self, path) -> None:
        """Write the model file atomically (temporary file + rename)."""
        meta = {METADATA_KEY: json.dumps(self.header(), sort_keys=True)}
        atomic_write_bytes(path, encode(self.tensors, meta))
        self.path = os.fspath(path)
        self._cpp = None

    def save_checked(self, path) -> "HybridModel":
        """Write the model file only once the loaders' own rules accept it: the file is first
        written to a temporary folder and read back by :func:`load_model` (so a model no reader
        would load never replaces ``path``), then written atomically. Returns the model as read
        back, with ``path`` set."""
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            probe = os.path.join(tmp, "model.safetensors")
            self.save(probe)
            checked = load_model(probe)
            with open(probe, "rb") as fh:
                data = fh.read()
        atomic_write_bytes(path, data)
        # save() pointed this model at the probe, which is gone: point it at the file written.
        self.path, self._cpp = os.fspath(path), None
        checked.path = os.fspath(path)
        return checked

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


def _num(v) -> str:
    """The number format of every value quoted in a message ("%.9g"), as the C++ loader."""
    return f"{float(v):.9g}"


def _is_json_integer(v) -> bool:
    """An integer as a 64-bit JSON reader sees one: libhybridbrdf's parser (nlohmann::json)
    reads integers outside [-2^63, 2^64 - 1] as floating-point numbers, so they are numbers here too."""
    return isinstance(v, int) and not isinstance(v, bool) and -(2**63) <= v <= 2**64 - 1


def _json_type(v) -> str:
    if isinstance(v, bool):
        return "a boolean"
    if isinstance(v, int):
        return "an integer" if _is_json_integer(v) else "a number"
    if isinstance(v, float):
        return "a number"
    if isinstance(v, str):
        return "a string"
    if v is None:
        return "null"
    return "an array" if isinstance(v, list) else "an object"


def _arch_field(fail, arch: Dict[str, Any], f: Dict[str, Any]):
    """arch.<key> checked against its row of spec.ARCH_FIELDS; returns the value (or the default)."""
    where = f"arch.{f['key']}"
    if f["key"] not in arch:
        if "default" in f:
            return f["default"]
        fail(f"{where} is missing")
    v = arch[f["key"]]
    if f["type"] == "enum":
        if not isinstance(v, str):
            fail(f"{where} must be a string, got {_json_type(v)}")
        names = list(getattr(spec, f["values"].upper()))
        if v not in names:
            fail(f"{where} '{v}' is not one of {', '.join(names)}")
        return v
    if f["type"] == "int":
        if not _is_json_integer(v):
            fail(f"{where} must be an integer, got {_json_type(v)}")
        if not f["min"] <= v <= f["max"]:
            fail(f"{where} = {v} is outside [{_num(f['min'])}, {_num(f['max'])}]")
        return v
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        fail(f"{where} must be a number, got {_json_type(v)}")
    if not f["min"] <= v <= f["max"]:
        fail(f"{where} = {_num(v)} is outside [{_num(f['min'])}, {_num(f['max'])}]")
    return float(v)


def _validate(path: str, doc: Dict[str, Any], tensors: Dict[str, np.ndarray]) -> Dict[str, Any]:
    """Checks ``doc`` and ``tensors`` against the model contract (spec/model.json), in the C++
    loader's order and words (HybridModel::load, cpp/src/model_load.cpp: one step each below);
    returns the ``arch`` object with defaults filled in."""
    _check_versions(path, doc)
    arch = _read_arch(path, doc)
    names = _read_materials(path, doc)
    _check_tensors(path, tensors, _expected_tensors(path, arch, len(names)))
    if spec.ARCHS[arch["kind"]]["analytic"]:
        _read_analytic_params(path, tensors, doc["materials"])
    problem = network_overflow_problem(arch, tensors)
    if problem:
        raise ModelFileError(path, problem)
    return arch


def _read_document(path: str, metadata: Dict[str, str]) -> Dict[str, Any]:
    """The ``hybridbrdf`` metadata entry parsed into a JSON object (C++ read_document)."""
    if METADATA_KEY not in metadata:
        raise ModelFileError(path, f"safetensors file without '{METADATA_KEY}' metadata: not a hybridbrdf model")
    # Bounded nesting first: 5,000 levels in the free-form records would be a RecursionError.
    doc = loads_json(metadata[METADATA_KEY], path, f"'{METADATA_KEY}' metadata", ModelFileError,
                     parse_constant=_reject_constant)
    if not isinstance(doc, dict):
        raise ModelFileError(path, f"'{METADATA_KEY}' metadata is not a JSON object")
    return doc


def _check_versions(path: str, doc: Dict[str, Any]) -> None:
    """format_version and conventions_version are the ones this library reads (C++ check_versions)."""
    for field, expected in (("format_version", spec.FORMAT_VERSION), ("conventions_version", spec.CONVENTIONS_VERSION)):
        v = doc.get(field)
        if not _is_json_integer(v):
            raise ModelFileError(path, f"{field} must be an integer, got {_json_type(v) if field in doc else 'nothing'} "
                                       f"(this library reads {expected})")
        if v != expected:
            raise ModelFileError(path, f"{field} {v} is not supported (this library reads {expected})")


def _read_arch(path: str, doc: Dict[str, Any]) -> Dict[str, Any]:
    """The ``arch`` object, each field checked against spec.ARCH_FIELDS and defaults filled in,
    with n_in/n_out matching its kind and latent size (C++ read_arch)."""
    def fail(problem):
        raise ModelFileError(path, problem)

    arch = doc.get("arch")
    if not isinstance(arch, dict):
        fail("metadata has no 'arch' object")
    arch = dict(arch)
    for f in spec.ARCH_FIELDS:
        arch[f["key"]] = _arch_field(fail, arch, f)
    a = spec.ARCHS[arch["kind"]]
    expected_in = a["direction_count"] + arch["latent"] + a["extra_count"]
    if (arch["n_in"], arch["n_out"]) != (expected_in, a["n_out"]):
        fail(f"arch n_in/n_out {arch['n_in']}/{arch['n_out']} do not match kind {arch['kind']} with latent "
             f"{arch['latent']} (expected {expected_in}/{a['n_out']})")
    return arch


def _read_materials(path: str, doc: Dict[str, Any]) -> List[str]:
    """The material names, in file order: the list's size, each record's name (the name rule),
    origin and isotropic flag, and no two names sharing a shader constant (C++ read_materials)."""
    materials = doc.get("materials")
    if not isinstance(materials, list) or not materials:
        raise ModelFileError(path, "metadata lists no materials")
    if len(materials) > spec.MAX_MATERIALS:
        raise ModelFileError(path, f"metadata lists {len(materials)} materials, more than {spec.MAX_MATERIALS}")
    names: List[str] = []
    seen = set()
    for i, m in enumerate(materials):
        if not isinstance(m, dict) or not isinstance(m.get("name"), str) or not m["name"]:
            raise ModelFileError(path, f"material {i} has no name")
        problem = name_problem(m["name"])
        if problem:
            raise ModelFileError(path, f"material {i}: {problem}")
        if m["name"] in seen:
            raise ModelFileError(path, f"duplicate material names: {m['name']}")
        seen.add(m["name"])
        names.append(m["name"])
        if "origin" in m and not isinstance(m["origin"], str):
            raise ModelFileError(path, f"material '{m['name']}': origin must be a string")
        if "isotropic" in m and not isinstance(m["isotropic"], bool):
            raise ModelFileError(path, f"material '{m['name']}': isotropic must be true or false")
    problem = names_problem(names)  # the names are valid and distinct: this finds shared shader constants
    if problem:
        raise ModelFileError(path, problem)
    return names


def _expected_tensors(path: str, arch: Dict[str, Any], n_mat: int) -> Dict[str, tuple]:
    """Name -> shape of every tensor the architecture needs for ``n_mat`` materials; refuses a
    per-material output layer on a kind without an analytic part (C++ expected_tensors)."""
    a = spec.ARCHS[arch["kind"]]
    expected = dict(network_tensor_shapes(arch))
    expected["materials.z"] = (n_mat, arch["latent"])
    if a["analytic"]:
        expected.update({f"materials.{r['tensor']}": (n_mat, r["components"]) for r in spec.MATERIAL_RANGES})
    if arch["output_layer"] == "material":
        if not a["analytic"]:
            raise ModelFileError(path, f"arch.output_layer 'material' is for architectures with an analytic part, "
                                       f"not {arch['kind']}")
        expected["materials.head_weight"] = (n_mat, arch["n_out"], arch["width"])
        expected["materials.head_bias"] = (n_mat, arch["n_out"])
    return expected


def _check_tensors(path: str, tensors: Dict[str, np.ndarray], expected: Dict[str, tuple]) -> None:
    """Exactly the expected tensors, each of its shape and finite (C++ check_tensors)."""
    missing = sorted(set(expected) - set(tensors))
    extra = sorted(set(tensors) - set(expected))
    if missing:
        raise ModelFileError(path, f"missing tensors: {', '.join(missing)}")
    if extra:
        raise ModelFileError(path, f"unexpected tensors: {', '.join(extra)}")
    for name in sorted(expected):
        if tuple(tensors[name].shape) != expected[name]:
            raise ModelFileError(path, f"tensor {name} has shape {tuple(tensors[name].shape)}, expected {expected[name]}")
        if not np.isfinite(tensors[name]).all():
            raise ModelFileError(path, f"tensor {name} holds NaN or Inf")


def _read_analytic_params(path: str, tensors: Dict[str, np.ndarray], materials: List[Dict[str, Any]]) -> None:
    """Each material's kd/eta/alpha inside spec.MATERIAL_RANGES (compared in float32, as C++) and
    alpha_x == alpha_y where it is marked isotropic (C++ read_analytic_params, which also stores
    them; here they stay in ``tensors``)."""
    for i, m in enumerate(materials):
        name = m["name"]
        for r in spec.MATERIAL_RANGES:
            row = tensors[f"materials.{r['tensor']}"][i]
            lo, hi = np.float32(r["min"]), np.float32(r["max"])
            for c in range(r["components"]):
                if not lo <= row[c] <= hi:
                    raise ModelFileError(path, f"material '{name}': {r['tensor']}[{c}] = {_num(row[c])} is outside "
                                               f"[{_num(r['min'])}, {_num(r['max'])}]")
        alpha = tensors["materials.alpha"][i]
        if m.get("isotropic", True) and alpha[0] != alpha[1]:
            raise ModelFileError(path, f"material '{name}' is marked isotropic but alpha_x != alpha_y")


def network_overflow_problem(arch: Dict[str, Any], tensors: Dict[str, np.ndarray]) -> Optional[str]:
    """None when no network value can exceed spec.MAX_NETWORK_VALUE, else the loaders' message.

    Interval propagation: every input is bounded (direction inputs are coordinates of unit
    vectors, |x| <= 1; latent input k by max |z_k| over the file's materials; log1p(f_a) by
    log1p(FLT_MAX) for finite f_a), a layer maps bounds b to |W| b + |bias|, and relu and
    hardGeLU never grow a magnitude. Exact arithmetic bounds float32 rounding to within a
    factor (1 + 2^-24)^width, which the limit's 8 orders below FLT_MAX absorb. The same
    computation, in the same order of layers, is libhybridbrdf's (cpp/src/model_validate.cpp); the
    figure is printed with 3 digits so that summation order cannot change the text."""
    a = spec.ARCHS[arch["kind"]]
    z = np.abs(tensors["materials.z"].astype(np.float64))
    z_bound = z.max(axis=0) if z.size else np.zeros(arch["latent"])
    limit = spec.MAX_NETWORK_VALUE

    def layer(prefix: str, b_in: np.ndarray) -> np.ndarray:
        w = np.abs(tensors[prefix + ".weight"].astype(np.float64))
        return (w * b_in[None, :]).sum(axis=1) + np.abs(tensors[prefix + ".bias"].astype(np.float64))

    if a["directions"] == "frames":
        raw = layer("frames", z_bound)
        if raw.max(initial=0.0) > limit:
            return _overflow_message("frames.weight", raw.max())
    extra = np.full(a["extra_count"], float(np.log1p(np.float64(np.finfo(np.float32).max))))
    b = np.concatenate([np.ones(a["direction_count"]), z_bound, extra])
    for prefix in [f"mlp.hidden.{i}" for i in range(arch["depth"])]:
        b = layer(prefix, b)
        if b.max(initial=0.0) > limit:
            return _overflow_message(prefix + ".weight", b.max())
    if output_layer(arch) == "material":
        # Every material's head on the shared bound of the last hidden layer; the largest output counts.
        w = np.abs(tensors["materials.head_weight"].astype(np.float64))
        out = (w * b[None, None, :]).sum(axis=2) + np.abs(tensors["materials.head_bias"].astype(np.float64))
        if out.max(initial=0.0) > limit:
            return _overflow_message("materials.head_weight", out.max())
        return None
    b = layer("mlp.out", b)
    if b.max(initial=0.0) > limit:
        return _overflow_message("mlp.out.weight", b.max())
    return None


def _overflow_message(tensor: str, bound: float) -> str:
    return (f"tensor {tensor}: network values may reach {float(bound):.3g}, beyond {spec.MAX_NETWORK_VALUE:.3g} "
            f"(float32 evaluation could overflow)")


def _reject_constant(name: str):
    raise ValueError(f"{name} is not JSON")  # NaN / Infinity: Python extensions C++ does not read


def load_model(path) -> HybridModel:
    """Read and validate a model file; raises ModelFileError naming the file and the problem."""
    path = os.fspath(path)
    metadata, tensors = decode(path)
    doc = _read_document(path, metadata)
    arch = _validate(path, doc, tensors)
    model = HybridModel(arch, doc["materials"], tensors, doc.get("training"), path)
    model.written_by = doc.get("library_version")  # informative only: which hybridbrdf wrote the file
    return model
