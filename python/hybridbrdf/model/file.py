"""Model files: the single hand-off between fitting and everything else.

Container: safetensors (a standard, safe format: an 8-byte little-endian header
length, a JSON header, raw little-endian tensor bytes), read and written here by the
``safetensors`` package and read in C++ by libhybridbrdf's own reader. The JSON
header's ``__metadata__`` holds one entry, ``"hybridbrdf"``, a JSON document:

    format_version       1, or 2 for hybrid-reciprocal (its inputs without the halves; a format 1
                         hybrid-reciprocal file is refused): container.format_version
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
the file and the first problem found (:mod:`hybridbrdf.model.validate`, as
``cpp/src/model_validate.cpp``). ``tests/data/malformed_models.json`` is the shared table of
broken files both loaders must reject alike.
"""

from __future__ import annotations

import json
import os
from typing import TYPE_CHECKING, Any, Dict, List, Optional

import numpy as np

from hybridbrdf import _core, spec
from hybridbrdf.brdf.analytic import AnalyticParams
from hybridbrdf.errors import ModelFileError
from hybridbrdf.limits import pair_arguments
from hybridbrdf.model import editing, sizes
from hybridbrdf.model.container import (METADATA_KEY, arch_description, decode, encode, format_version,
                                        output_layer)
from hybridbrdf.model.validate import read_document, validate
from hybridbrdf.files import atomic_write_bytes
from hybridbrdf.version import __version__

if TYPE_CHECKING:  # annotations only: PyTorch is imported where a model runs in it
    import torch


def _torch():
    """PyTorch, imported on first use: reading, checking, editing and writing model files (and
    evaluating them through libhybridbrdf) need none of it, and importing it costs seconds."""
    import torch

    return torch


class HybridModel:
    """A fitted collection: shared network + per-material parameters, ready to evaluate.

    ``materials``: names in file order. ``eval(wi, wo, material)`` gives f_t (N,3)
    and ``eval_analytic(wi, wo, material)`` its analytic part (hybrid kinds).
    Computed in PyTorch (float32 by default; ``dtype=torch.float64`` for a reference).
    """

    #: Peak bytes per direction pair of :meth:`eval` through libhybridbrdf (its home, plain Python
    #: for the command line's help: :data:`hybridbrdf.model.sizes.LIBRARY_BYTES_PER_PAIR`).
    LIBRARY_BYTES_PER_PAIR = sizes.LIBRARY_BYTES_PER_PAIR

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
        """The row of ``material``, a name or an index: KeyError naming it when the model has no
        such material, TypeError when it is neither a str nor an int (a bool is neither)."""
        if isinstance(material, (bool, np.bool_)) or not isinstance(material, (str, int, np.integer)):
            raise TypeError(f"material must be a name (str) or an index (int), got {type(material).__name__}")
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
            import torch

            from hybridbrdf.model.networks import build_model
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
        import torch

        t = {k.split(".", 1)[1]: torch.from_numpy(v[i:i + 1]).to(dtype)
             for k, v in self.tensors.items() if k.startswith("materials.")}
        return t

    def eval(self, wi, wo, material, dtype: Optional[torch.dtype] = None) -> np.ndarray:
        """f_t(wi, wo) for material (name or index): (N,3) float64 array (no cosine).

        By default a model read from (or saved to) a file is evaluated by
        libhybridbrdf in float32, the runtime every engine uses; ``dtype``
        (torch.float32 or torch.float64) evaluates the PyTorch model instead,
        float64 being the reference the C++ library is tested against."""
        if self._check_dtype(dtype) is None and self.path is not None:
            return self._cpp_model().eval(*self._rows(wi, wo), self.index(material)).astype(np.float64)
        return self._eval(wi, wo, material, dtype or _torch().float32)[0]

    def eval_analytic(self, wi, wo, material, dtype: Optional[torch.dtype] = None) -> np.ndarray:
        """The analytic part f_a of a hybrid material (not available for the neural baseline)."""
        if not self.has_analytic:
            raise ValueError("the neural baseline has no analytic part")
        if self._check_dtype(dtype) is None and self.path is not None:
            return self._cpp_model().eval_analytic(*self._rows(wi, wo), self.index(material)).astype(np.float64)
        return self._eval(wi, wo, material, dtype or _torch().float32)[1]

    def _cpp_model(self):
        if self._cpp is None:
            self._cpp = _core.Model(self.path)
        return self._cpp

    @staticmethod
    def _check_dtype(dtype):
        if dtype is not None and dtype not in (_torch().float32, _torch().float64):
            raise TypeError(f"dtype must be None (libhybridbrdf), torch.float32 or torch.float64, got {dtype!r}")
        return dtype

    def bytes_per_pair(self, dtype: Optional[torch.dtype] = None) -> int:
        """Peak memory of :meth:`eval` per direction pair, what its row count is bounded by
        (hybridbrdf.limits): libhybridbrdf's float32 copies and outputs
        (:data:`LIBRARY_BYTES_PER_PAIR`), or PyTorch's activations (model/sizes.py's
        torch_bytes_per_pair; 827 bytes measured at 32x3 in float32), each with a margin."""
        if dtype is None and self.path is not None:
            return self.LIBRARY_BYTES_PER_PAIR
        size = 8 if dtype is not None and dtype == _torch().float64 else 4
        return sizes.torch_bytes_per_pair(self.arch["width"], self.arch["depth"], size)

    def _rows(self, wi, wo):
        a, b = pair_arguments(("wi", "wo"), (wi, wo), (3, 3), self.bytes_per_pair())
        return np.asarray(a, dtype=np.float32), np.asarray(b, dtype=np.float32)

    def _eval(self, wi, wo, material, dtype):
        import torch

        from hybridbrdf.brdf.torch_brdf import _normalize
        from hybridbrdf.model.networks import energy_bound_scale

        i = self.index(material)
        wi, wo = pair_arguments(("wi", "wo"), (wi, wo), (3, 3), self.bytes_per_pair(dtype))
        wi_t = torch.as_tensor(wi, dtype=dtype)
        wo_t = torch.as_tensor(wo, dtype=dtype)
        mod = self._module(dtype)
        m = self._material_tensors(i, dtype)
        with torch.no_grad():
            if not self.has_analytic:
                f, fa = mod.evaluate(wi_t, wo_t, m["z"])
            else:
                head = (m["head_weight"], m["head_bias"]) if "head_weight" in m else None
                f, fa = mod.evaluate(wi_t, wo_t, m["kd"], m["eta"], m["alpha"], m["z"], head)
            if "energy_bound" in m:  # f = k(wi.z) k(wo.z) f_t (spec/model.json, energy_bounds)
                wi_n, wo_n = (_normalize(w)[0] for w in (wi_t, wo_t))  # invalid rows: +z (f is 0 there)
                k = energy_bound_scale(m["energy_bound"], wi_n[:, 2]) * energy_bound_scale(m["energy_bound"], wo_n[:, 2])
                f = f * k[None, :, None]
        out = f[0].double().numpy()
        return out, (fa[0].double().numpy() if fa is not None else None)

    # ---- persistence -----------------------------------------------------------
    def header(self) -> Dict[str, Any]:

        return {"format_version": format_version(self.arch["kind"]), "conventions_version": _core.CONVENTIONS_VERSION,
                "library_version": __version__, "arch": self.arch, "materials": self.material_info,
                "training": self.training}

    def _file_bytes(self) -> bytes:
        meta = {METADATA_KEY: json.dumps(self.header(), sort_keys=True)}
        return encode(self.tensors, meta)

    def save(self, path) -> None:
        """Write the model file atomically (temporary file beside it + rename; the replaced
        file's permissions kept; :func:`hybridbrdf.files.atomic_write_bytes`)."""
        atomic_write_bytes(path, self._file_bytes())
        self.path = os.fspath(path)
        self._cpp = None

    def save_checked(self, path) -> "HybridModel":
        """Write the model file only once the loaders' own rules accept it: the temporary
        beside ``path`` is read back by :func:`load_model` before it is renamed over ``path``
        (so a model no reader would load never replaces ``path``, and an interruption leaves
        no copy anywhere else). Returns the model as read back, with ``path`` set."""
        path = os.fspath(path)
        checked = []

        def verify(tmp: str) -> None:
            try:
                checked.append(load_model(tmp))
            except ModelFileError as exc:  # name the file asked for, not its temporary
                raise ModelFileError(path, exc.problem) from None

        atomic_write_bytes(path, self._file_bytes(), verify=verify)
        self.path, self._cpp = path, None
        checked[0].path = path
        return checked[0]

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


def load_model(path) -> HybridModel:
    """Read and validate a model file; raises ModelFileError naming the file and the problem."""
    path = os.fspath(path)
    metadata, tensors = decode(path)
    doc = read_document(path, metadata)
    arch = validate(path, doc, tensors)
    model = HybridModel(arch, doc["materials"], tensors, doc.get("training"), path)
    model.written_by = doc.get("library_version")  # informative only: which hybridbrdf wrote the file
    return model
