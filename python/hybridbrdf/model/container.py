"""The model file's container: safetensors bytes to and from (metadata, float32 tensors), the
tensors an ``arch`` description calls for, and the description of a trained module. The format
and the document it holds are described in :mod:`hybridbrdf.model.file`; the C++ twin is
``cpp/src/model_container.cpp``."""

from __future__ import annotations

import os
import struct
from typing import Any, Dict

import numpy as np
import safetensors
import safetensors.numpy

from hybridbrdf import spec
from hybridbrdf.errors import ModelFileError
from hybridbrdf.inputs import check_input_file

METADATA_KEY = spec.METADATA_KEY
MAX_HEADER_BYTES = spec.MAX_HEADER_BYTES


#: The output layer of a model whose ``arch`` does not name one (files older than material output
#: layers): spec/model.json's default of the arch field. (A new fit's default is FitSettings'.)
DEFAULT_OUTPUT_LAYER = next(f["default"] for f in spec.ARCH_FIELDS if f["key"] == "output_layer")


def format_version(kind: str) -> int:
    """The format_version a model file of architecture ``kind`` is written in: the oldest that
    defines it (spec/model.json, since_format), so that older readers keep reading what they read
    correctly and refuse the rest (format 2: the hybrid-reciprocal inputs without the halves)."""
    return spec.ARCHS[kind]["since_format"]


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
                  "local_half": "wi.x wi.y wi.z wo.x wo.y wo.z cos_theta_h cos_theta_d",
                  "reciprocal": "s.x s.y s.z d.x^2 d.y^2 d.z^2 d.x*d.y d.x*d.z d.y*d.z (s = wi + wo, "
                                "d = wi - wo)"}.get(
        a["directions"], "wi and wo in 3 predicted frames (t, b, n each; 18 values)")
    extra = " log1p(f_a.r) log1p(f_a.g) log1p(f_a.b)" if a["extra"] == "log1p_fa" else ""
    return directions + "".join(f" z_{i}" for i in range(latent)) + extra


def arch_description(module) -> Dict[str, Any]:
    kind = module.arch
    latent = module.latent_dim
    return {"kind": kind, "width": module.width, "depth": module.depth, "activation": module.activation,
            "latent": latent, "n_in": module.mlp.hidden[0].in_features, "n_out": module.n_out,
            "pre_exp_max": module.pre_exp_max, "output_layer": module.output_layer, "energy_bound": "none",
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
