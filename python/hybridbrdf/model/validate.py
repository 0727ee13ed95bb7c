"""The model-file contract checks of :func:`hybridbrdf.model.file.load_model`: the document's
versions, ``arch`` (each field against its row of spec.ARCH_FIELDS), the materials and their
names, the tensors' names and shapes, the analytic parameters' ranges and a bound on every value
the network can reach. Same order, same messages as the C++ loader (``cpp/src/model_validate.cpp``);
each check raises :class:`hybridbrdf.errors.ModelFileError` naming the file and the problem."""

from __future__ import annotations

from typing import Any, Dict, List, Optional

import numpy as np

from hybridbrdf import spec
from hybridbrdf.errors import ModelFileError
from hybridbrdf.inputs import loads_json
from hybridbrdf.model.container import METADATA_KEY, network_tensor_shapes, output_layer
from hybridbrdf.names import name_problem, names_problem


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


def validate(path: str, doc: Dict[str, Any], tensors: Dict[str, np.ndarray]) -> Dict[str, Any]:
    """Checks ``doc`` and ``tensors`` against the model contract (spec/model.json), in the C++
    loader's order and words (HybridModel::load, cpp/src/model_load.cpp: one step each below);
    returns the ``arch`` object with defaults filled in."""
    _check_versions(path, doc)
    arch = _read_arch(path, doc)
    names = _read_materials(path, doc)
    _check_tensors(path, tensors, _expected_tensors(path, arch, len(names)))
    if spec.ARCHS[arch["kind"]]["analytic"]:
        _read_analytic_params(path, tensors, doc["materials"])
    _read_energy_bounds(path, arch, tensors, doc["materials"])
    problem = network_overflow_problem(arch, tensors)
    if problem:
        raise ModelFileError(path, problem)
    return arch


def read_document(path: str, metadata: Dict[str, str]) -> Dict[str, Any]:
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
    """format_version and conventions_version are ones this library reads (C++ check_versions)."""
    for field, oldest, newest in (("format_version", spec.OLDEST_FORMAT_VERSION, spec.FORMAT_VERSION),
                                  ("conventions_version", spec.CONVENTIONS_VERSION, spec.CONVENTIONS_VERSION)):
        v = doc.get(field)
        reads = " and ".join(str(n) for n in range(oldest, newest + 1))
        if not _is_json_integer(v):
            raise ModelFileError(path, f"{field} must be an integer, got {_json_type(v) if field in doc else 'nothing'} "
                                       f"(this library reads {reads})")
        if not oldest <= v <= newest:
            raise ModelFileError(path, f"{field} {v} is not supported (this library reads {reads})")


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
    if doc["format_version"] < a["since_format"]:  # an older definition of the same inputs (spec: since_format)
        fail(f"arch.kind '{arch['kind']}' in format_version {doc['format_version']}: {a['refused_before']}; "
             f"refit with --arch {arch['kind']}")
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
    if arch["energy_bound"] == "albedo_table":
        expected["materials.energy_bound"] = (n_mat, spec.ENERGY_NODES)
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


def _read_energy_bounds(path: str, arch: Dict[str, Any], tensors: Dict[str, np.ndarray],
                        materials: List[Dict[str, Any]]) -> None:
    """With arch.energy_bound "albedo_table": every node of every material's table in [0, 1] (a
    factor above 1 would add light), material by material, node by node (C++ read_energy_bounds)."""
    if arch["energy_bound"] != "albedo_table":
        return
    table = tensors["materials.energy_bound"]
    for i, m in enumerate(materials):
        for j, k in enumerate(table[i]):
            if not 0.0 <= k <= 1.0:
                raise ModelFileError(path, f"material '{m['name']}': energy_bound[{j}] = {_num(k)} is outside [0, 1]")


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
