"""NBRDF networks (Sztrajman, Rainer, Ritschel, Weyrich, "Neural BRDF
Representation and Importance Sampling", CGF 40(6), 2021): small MLPs fitted
by their authors to one measured material each, saved with Keras 2.2.4
(``model.save_weights`` -> ``<name>.h5``, ``model.to_json`` -> ``<name>.json``).

Weights file (HDF5): root attribute ``layer_names`` lists the layers in
order; each layer is a group whose attribute ``weight_names`` lists its
datasets, for a Dense layer ``<layer>/kernel:0`` (shape (in, out)) and
``<layer>/bias:0`` (out), stored at ``/<layer>/<layer>/kernel:0``. The
published networks are 6 -> 21 (relu) -> 21 (relu) -> 3 (linear), followed by
a Lambda layer computing exp(x) - 1.

Forward pass, as the authors' evaluator (Mitsuba plugin ``nbrdf_npy`` and
``nn.h``) computes it:

    h = normalize(wi + wo)
    d = wi rotated by -phi_h about the normal, then by -theta_h about y
    x = (sin theta_h, 0, cos theta_h, d.x, d.y, d.z)      phi_h set to 0
    f = max(exp(MLP(x)) - 1, 0)                            RGB, no cosine

with ``wi`` the light direction (the authors' plugin passes Mitsuba's
``bRec.wo``, the light side, as the direction d is built from). The input
uses wi only for d, so the network is not exactly reciprocal; see the tests
for the measured asymmetry.

What is read from the files rather than assumed: the layer order, count and
sizes (from the h5), and each Dense layer's activation (from the JSON next
to the h5, when there is one; without it, hidden layers are relu and the
last is linear, as published). The Lambda layer's function is stored as
marshalled Python bytecode: it is never unpacked or run; the output
transform is the published exp(x) - 1, clamped at 0 as the authors'
evaluator does. Evaluation is float64 (the stored weights are float32).
"""

from __future__ import annotations

import os
import re
from typing import Dict, List, Optional, Tuple

import numpy as np

from hybridbrdf.inputs import check_input_file, loads_json, read_input_text
from hybridbrdf.sources.base import BRDFFormatError, BRDFSource, source_name
from hybridbrdf.sources.rusinkiewicz import half_diff_vectors

#: Network input: (sin theta_h, 0, cos theta_h, d.x, d.y, d.z).
INPUT_DIM = 6
#: Network output: RGB before the exp(x) - 1 transform.
OUTPUT_DIM = 3

ACTIVATIONS = {
    "relu": lambda x: np.maximum(x, 0.0),
    "linear": lambda x: x,
    "tanh": np.tanh,
    "sigmoid": lambda x: 0.5 * (1.0 + np.tanh(0.5 * x)),  # overflow-free logistic
    "elu": lambda x: np.where(x > 0, x, np.expm1(np.minimum(x, 0.0))),
    "softplus": lambda x: np.logaddexp(0.0, x),
}
#: Keras layer classes that carry no weights and are the identity at inference.
_IDENTITY_LAYERS = ("InputLayer", "Dropout")

_ORIGINS = (
    (("nbrdf", "merl"), "MERL (NBRDF reconstruction)"),
    (("nbrdf", "rgl"), "RGL (NBRDF reconstruction)"),
    (("nbrdf", "nielsen"), "Nielsen 2015 (NBRDF reconstruction)"),
)


def nbrdf_origin(path) -> str:
    """The figure label of a network file, from the folders it lies in:
    ``.../nbrdf/merl/x.h5`` -> "MERL (NBRDF reconstruction)", likewise for
    ``nbrdf/rgl`` and ``nbrdf/nielsen``; anything else "NBRDF network"."""
    parts = [p.lower() for p in os.path.abspath(os.fspath(path)).split(os.sep)[:-1]]
    pairs = set(zip(parts, parts[1:]))
    for key, label in _ORIGINS:
        if key in pairs:
            return label
    return "NBRDF network"


def nbrdf_input(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """The (N, 6) network input (sin theta_h, 0, cos theta_h, d.x, d.y, d.z)
    of unit (N, 3) directions above the horizon."""
    h, d = half_diff_vectors(wi, wo)
    x = np.empty((h.shape[0], INPUT_DIM))
    x[:, 0] = np.hypot(h[:, 0], h[:, 1])  # sin theta_h: phi_h is set to 0
    x[:, 1] = 0.0
    x[:, 2] = h[:, 2]
    x[:, 3:] = d
    return x


# ---- reading -----------------------------------------------------------------


def _as_str_list(value) -> List[str]:
    return [v.decode("utf-8") if isinstance(v, bytes) else str(v) for v in np.asarray(value).ravel()]


def _read_keras_config(json_path: str) -> Optional[List[dict]]:
    """The ``layers`` of a Keras Sequential JSON config, or None without a file."""
    if not os.path.exists(json_path):
        return None
    text = read_input_text(json_path, "Keras config", MAX_CONFIG_BYTES, BRDFFormatError)
    cfg = loads_json(text, json_path, "Keras config", BRDFFormatError)
    try:
        layers = cfg["config"]["layers"] if isinstance(cfg.get("config"), dict) else cfg["config"]
        if not isinstance(layers, list) or not all(isinstance(l, dict) and "class_name" in l for l in layers):
            raise TypeError
        for layer in layers:
            layer.setdefault("config", {})
            if not isinstance(layer["config"], dict):
                raise TypeError
    except (KeyError, TypeError, AttributeError):
        raise BRDFFormatError(json_path, "Keras config has no list of layers under config.layers") from None
    # The reader uses class names and layer names as text and set members: a list or an object
    # there would surface as "unhashable type" from deep inside, not as this file's problem.
    for i, layer in enumerate(layers):
        if not isinstance(layer["class_name"], str):
            raise BRDFFormatError(json_path, f"Keras config layer {i}: class_name is {_json_type(layer['class_name'])}, "
                                             "not a string")
        if "name" in layer["config"] and not isinstance(layer["config"]["name"], str):
            raise BRDFFormatError(json_path, f"Keras config layer {i}: config.name is "
                                             f"{_json_type(layer['config']['name'])}, not a string")
    return layers


def _json_type(value) -> str:
    """A JSON value's type as a message names it ("a list", "null")."""
    if value is None:
        return "null"
    return {bool: "a boolean", int: "a number", float: "a number", str: "a string", list: "a list",
            dict: "an object"}.get(type(value), "a " + type(value).__name__)


def _dense_layer_names_fallback(f) -> List[str]:
    """Groups named dense_<n>, in numeric order: the layer order when the file
    lacks the ``layer_names`` attribute."""
    names = [k for k in f.keys() if re.fullmatch(r"dense_\d+", k)]
    return sorted(names, key=lambda k: int(k.split("_")[1]))


#: Largest Keras .json config read (bytes): the published ones are about 2 KB.
MAX_CONFIG_BYTES = 1 << 20
#: Largest NBRDF .h5 file opened (bytes): the published ones are about 18 KB, and each layer is
#: bounded by MAX_LAYER_WEIGHTS below; HDF5 reads only what it is asked for.
MAX_H5_BYTES = 256 << 20

#: Most values one kernel or bias dataset may hold. The NBRDF networks of Sztrajman et al.
#: (6-21-21-3) have 588 kernel weights in all; this leaves room for far wider ones.
MAX_LAYER_WEIGHTS = 1 << 20


def _read_dense(f, spec: str, name: str) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    """(kernel, bias) of layer ``name`` as float64, or None for a layer without weights."""
    if name not in f:
        raise BRDFFormatError(spec, f"missing group '{name}' (listed in layer_names)")
    group = f[name]
    if "weight_names" in group.attrs:
        wnames = _as_str_list(group.attrs["weight_names"])
    else:  # not Keras-written: look for the usual dataset names
        wnames = [f"{name}/kernel:0", f"{name}/bias:0"]
    if not wnames:
        return None
    found: Dict[str, np.ndarray] = {}
    for wn in wnames:
        kind = wn.rsplit("/", 1)[-1]
        if kind not in ("kernel:0", "bias:0"):
            raise BRDFFormatError(spec, f"layer '{name}' has weight '{wn}': only Dense kernel and bias are supported")
        if wn not in group:
            raise BRDFFormatError(spec, f"missing dataset '{name}/{wn}'")
        obj = group[wn]
        if not hasattr(obj, "shape") or not hasattr(obj, "dtype"):
            raise BRDFFormatError(spec, f"'{name}/{wn}' is not a dataset")
        if obj.dtype.kind not in "fiu":
            raise BRDFFormatError(spec, f"'{name}/{wn}' has non-numeric type {obj.dtype}")
        # Shape first, from the header: an 18 KB file can declare a chunked dataset of
        # gigabytes, and reading it would allocate them before any check.
        ndim = 2 if kind == "kernel:0" else 1
        if len(obj.shape) != ndim:
            what, expected = ("kernel", "(in, out)") if ndim == 2 else ("bias", "(out,)")
            raise BRDFFormatError(spec, f"'{name}' {what} has shape {tuple(obj.shape)}, expected {expected}")
        size = int(np.prod(obj.shape, dtype=np.float64))
        if size > MAX_LAYER_WEIGHTS:
            raise BRDFFormatError(spec, f"'{name}/{wn}' has shape {tuple(obj.shape)}: {size} values, more than "
                                        f"{MAX_LAYER_WEIGHTS} (an NBRDF layer has a few hundred)")
        found[kind] = np.asarray(obj[()], dtype=np.float64)
    if "kernel:0" not in found or "bias:0" not in found:
        raise BRDFFormatError(spec, f"layer '{name}' needs both kernel:0 and bias:0, has {sorted(found)}")
    kernel, bias = found["kernel:0"], found["bias:0"]
    if kernel.ndim != 2:
        raise BRDFFormatError(spec, f"'{name}' kernel has shape {kernel.shape}, expected (in, out)")
    if bias.shape != (kernel.shape[1],):
        raise BRDFFormatError(
            spec, f"'{name}' bias has shape {bias.shape}, kernel {kernel.shape}: expected ({kernel.shape[1]},)"
        )
    if not (np.isfinite(kernel).all() and np.isfinite(bias).all()):
        raise BRDFFormatError(spec, f"'{name}' weights hold non-finite values")
    return kernel, bias


def _read_dense_layers(spec: str, config) -> List[Tuple[str, np.ndarray, np.ndarray]]:
    """(name, kernel, bias) of each Dense layer of the HDF5 weights file, in the file's layer order."""
    import h5py  # HDF5 is loaded only when an NBRDF file is read

    # Config layers that carry no weights may lack a group in the h5.
    weightless_ok = set() if config is None else {l["config"].get("name") for l in config if l["class_name"] != "Dense"}
    dense: List[Tuple[str, np.ndarray, np.ndarray]] = []
    try:
        with h5py.File(spec, "r") as f:
            if "layer_names" in f.attrs:
                names = _as_str_list(f.attrs["layer_names"])
            elif config is not None:
                names = [l["config"].get("name", "") for l in config]
            else:
                names = _dense_layer_names_fallback(f)
            if not names:
                raise BRDFFormatError(spec, "no layers: expected groups dense_1, dense_2, ... with kernel:0 and bias:0")
            for name in names:
                if name not in f and name in weightless_ok:
                    continue
                kb = _read_dense(f, spec, name)
                if kb is not None:  # None: a layer without weights (the Lambda)
                    dense.append((name, kb[0], kb[1]))
    except BRDFFormatError:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:
        raise BRDFFormatError(spec, f"not a readable Keras HDF5 weights file ({type(exc).__name__}: {exc})") from None
    if not dense:
        raise BRDFFormatError(spec, "no Dense layer with weights")
    return dense


def _config_activations(json_path: str, config, dense) -> List[str]:
    """The Dense layers' activations from the Keras JSON config, checked against the weights read."""
    cfg_dense = [l for l in config if l["class_name"] == "Dense"]
    for l in config:
        cls = l["class_name"]
        if cls not in ("Dense", "Lambda") + _IDENTITY_LAYERS:
            raise BRDFFormatError(json_path, f"unsupported Keras layer class {cls!r}")
    if config and config[-1]["class_name"] != "Lambda":
        raise BRDFFormatError(json_path, "the last layer is not the Lambda output transform exp(x) - 1")
    if sum(l["class_name"] == "Lambda" for l in config) != 1:
        raise BRDFFormatError(json_path, "expected exactly one Lambda layer (the output transform)")
    cfg_names = [l["config"].get("name") for l in cfg_dense]
    h5_names = [n for n, _, _ in dense]
    if cfg_names != h5_names:
        raise BRDFFormatError(json_path, f"Dense layers {cfg_names} do not match the weights file's {h5_names}")
    acts = []
    for l, (name, kernel, _) in zip(cfg_dense, dense):
        units = l["config"].get("units")
        if units is not None and units != kernel.shape[1]:
            raise BRDFFormatError(json_path, f"layer '{name}' has {units} units but its kernel is {kernel.shape}")
        if l["config"].get("use_bias", True) is False:
            raise BRDFFormatError(json_path, f"layer '{name}' has use_bias = false, but a bias was read")
        acts.append(l["config"].get("activation", "linear"))
    return acts


def read_nbrdf_layers(path) -> List[Tuple[str, np.ndarray, np.ndarray, str]]:
    """The Dense layers of an NBRDF network: a list of (name, kernel (in, out),
    bias (out,), activation), validated (6 inputs, 3 outputs, chained shapes,
    finite weights, known activations). Raises :class:`BRDFFormatError`."""
    spec = os.fspath(path)
    # A regular file of a sane size before HDF5 opens it: opening a FIFO would block.
    check_input_file(spec, "NBRDF .h5 file", MAX_H5_BYTES, BRDFFormatError)
    json_path = os.path.splitext(spec)[0] + ".json"
    config = _read_keras_config(json_path)
    dense = _read_dense_layers(spec, config)
    # Activations: from the JSON config when present, else the published network's.
    if config is None:
        acts = ["relu"] * (len(dense) - 1) + ["linear"]
    else:
        acts = _config_activations(json_path, config, dense)
    for (name, _, _), act in zip(dense, acts):
        if not isinstance(act, str) or act not in ACTIVATIONS:  # a custom activation is a dict
            raise BRDFFormatError(json_path if config is not None else spec,
                                  f"layer '{name}' has unsupported activation {act!r}")
    width = INPUT_DIM
    for name, kernel, _ in dense:
        if kernel.shape[0] != width:
            raise BRDFFormatError(spec, f"layer '{name}' kernel has shape {kernel.shape}, expected ({width}, n)")
        width = kernel.shape[1]
    if width != OUTPUT_DIM:
        raise BRDFFormatError(spec, f"the network has {width} outputs, expected 3 (RGB)")
    return [(n, k, b, a) for (n, k, b), a in zip(dense, acts)]


class NBRDFSource(BRDFSource):
    """An NBRDF network behind the :class:`BRDFSource` interface (forward pass
    in the module docstring)."""

    isotropic = True

    def __init__(self, layers, path: Optional[str] = None, name: Optional[str] = None,
                 origin: Optional[str] = None):
        """``layers``: (name, kernel, bias, activation) as :func:`read_nbrdf_layers` returns."""
        self.layers = [
            (n, np.asarray(k, dtype=np.float64), np.asarray(b, dtype=np.float64), a) for n, k, b, a in layers
        ]
        self.path = path
        self.name = source_name(name, path, "nbrdf")
        self.origin = origin if origin is not None else (nbrdf_origin(path) if path else "NBRDF network")

    def forward(self, x: np.ndarray) -> np.ndarray:
        """The MLP on network inputs x (N, 6), before the output transform."""
        for _, kernel, bias, act in self.layers:
            y = x @ kernel
            y += bias  # in place: the batch can be large
            x = np.maximum(y, 0.0, out=y) if act == "relu" else ACTIVATIONS[act](y)
        return x

    def _eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        y = self.forward(nbrdf_input(wi, wo))
        # exp(y) - 1, the Lambda layer; expm1 keeps small values accurate. The
        # clamp at 0 is the authors' evaluator's; overflow gives +inf (never seen
        # for the published networks, whose outputs stay far below exp's range).
        with np.errstate(over="ignore"):
            return np.maximum(np.expm1(y), 0.0)


def open_nbrdf(path) -> NBRDFSource:
    """Open an NBRDF network ``<name>.h5`` (with ``<name>.json`` beside it when
    available) as a :class:`BRDFSource`. ``origin`` follows the folder (see
    :func:`nbrdf_origin`). Raises :class:`BRDFFormatError` for a missing,
    truncated or corrupt file, a missing group, wrong shapes, non-finite
    weights or an unsupported layer."""
    spec = os.fspath(path)
    return NBRDFSource(read_nbrdf_layers(spec), path=spec)


__all__ = ["NBRDFSource", "nbrdf_input", "nbrdf_origin", "open_nbrdf", "read_nbrdf_layers"]
