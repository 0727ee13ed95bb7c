"""A Mitsuba 3 BSDF plugin for hybridbrdf model materials.

    import mitsuba as mi
    mi.set_variant("scalar_rgb")            # or "llvm_ad_rgb"
    import hybridbrdf.render.mitsuba
    hybridbrdf.render.mitsuba.register()
    bsdf = {"type": "hbrdf", "filename": "model.safetensors", "material": "satin_gold_rgb"}

Properties: ``filename`` (a model file), ``material`` (its name in the file; ``hbrdf info`` lists
them), or instead ``svbrdf`` (a textured material's folder, docs/SVBRDF.md: per query the texel
under Mitsuba's ``si.uv``, read unchanged as the folder's uv, with ``filter`` ``"bilinear"``, the
default, or ``"nearest"``; libhybridbrdf's ``Svbrdf``, the tracer's loader and lookup; with it,
``weights``: any Mitsuba texture whose R, G, B are the layers' weights w_1, w_2, w_3 at each query,
Mitsuba's own lookup replacing the folder's weights map: a bitmap with Mitsuba's filtering and
wrapping, a checkerboard, a mesh attribute; negative and non-finite values count as 0, a sum above
1 is divided out, the base layer takes the rest; the layers' p and z maps stay the folder's),
``sampler`` (``"mis"``, the default: the one-sample MIS of the cosine and GGX lobes of the
material's fitted f_a, paper Sec. 5.2; ``"ggx"`` or ``"cosine"``) and ``evaluate`` (``"full"``,
the default, f_t; ``"analytic"``: f_a alone, as the tracer's deeper bounces may use it).

Every query is one call into libhybridbrdf for all its lanes: eval runs the batched network
path (AVX2 kernels where the CPU has them), sample and pdf the library's analytic samplers; no
query runs the network for sampling. In a JIT variant (``llvm_ad_rgb``) a query hands the whole
wavefront over as NumPy arrays, so :func:`register` turns Dr.Jit's symbolic loops and calls off
(a recorded loop cannot leave the JIT); renders then run in wavefront mode. The plugin has no
gradients (it is not differentiable) and reflects on the front side only (wrap it in Mitsuba's
``twosided`` for both).

Conventions. Mitsuba's ``si.wi`` points toward the viewer and its ``wo`` toward the light;
hybridbrdf's wi points toward the light and wo toward the viewer (docs/CONVENTIONS.md). So the
plugin evaluates hybridbrdf f(wi = Mitsuba wo, wo = Mitsuba si.wi), and multiplies by the
cosine of Mitsuba's wo, as Mitsuba's BSDF interface asks. The shading frame is Mitsuba's
(``si.sh_frame``, its s axis along dp/du), as for its own anisotropic BSDFs.
"""

from __future__ import annotations

import numpy as np

from hybridbrdf import _core
from hybridbrdf.brdf.analytic import AnalyticParams
from hybridbrdf.model.file import load_model

PLUGIN_NAME = "hbrdf"
SAMPLERS = ("mis", "ggx", "cosine")
EVALUATE = ("full", "analytic")
FILTERS = ("bilinear", "nearest")
#: Oldest LLVM the llvm variants render with on x86-64 (see register()).
MIN_LLVM = (16,)


def _mi():
    try:
        import mitsuba as mi
    except ImportError as exc:  # pragma: no cover - the package is a test dependency
        raise ImportError("hybridbrdf.render.mitsuba needs Mitsuba 3 (pip install mitsuba)") from exc
    if mi.variant() is None:
        raise RuntimeError("set a Mitsuba variant first, e.g. mitsuba.set_variant('scalar_rgb')")
    return mi


def _rows(v) -> np.ndarray:
    """A Mitsuba Vector3f (one lane in a scalar variant, a wavefront in a JIT one) as (N, 3) float32."""
    a = np.asarray(v, dtype=np.float32)
    return a.reshape(3, -1).T.copy() if a.ndim == 2 else a.reshape(1, 3)


def _lanes(a: np.ndarray):
    """(N,) or (N, k) NumPy values back to Mitsuba values of the current variant."""
    mi = _mi()
    scalar = mi.variant().startswith("scalar")
    if a.ndim == 1:
        return mi.Float(float(a[0])) if scalar else mi.Float(a.astype(np.float32))
    cols = [a[:, c].astype(np.float32) for c in range(a.shape[1])]
    if scalar:
        cols = [float(c[0]) for c in cols]
    return mi.Color3f(*cols) if a.shape[1] == 3 else mi.Vector3f(*cols)


def _mask(active, n: int) -> np.ndarray:
    """Mitsuba's ``active`` (a bool, or lanes of which a width-1 one broadcasts) as (n,) bools."""
    return np.broadcast_to(np.asarray(active, dtype=bool).reshape(-1), (n,))


def _uv(si_uv, n: int) -> np.ndarray:
    """Mitsuba's si.uv as (n, 2) float32 (a width-1 value broadcast)."""
    a = np.asarray(si_uv, dtype=np.float32)
    a = a.reshape(2, -1).T if a.ndim == 2 else a.reshape(1, 2)
    return np.ascontiguousarray(np.broadcast_to(a, (n, 2)))


def _pair(si_wi, wo):
    """(light, view) rows in hybridbrdf's convention, broadcast to one width: Dr.Jit lets a
    width-1 value (e.g. one viewing direction) meet a wavefront."""
    view, light = _rows(si_wi), _rows(wo)
    n = max(len(view), len(light))
    return (np.ascontiguousarray(np.broadcast_to(light, (n, 3))),
            np.ascontiguousarray(np.broadcast_to(view, (n, 3))))


def register() -> None:
    """Register the ``hbrdf`` BSDF with Mitsuba for the current variant (call after
    ``mitsuba.set_variant``; again after changing variants). In JIT variants it also turns off
    Dr.Jit's symbolic loops and calls, which a plugin that evaluates in NumPy cannot run in."""
    mi = _mi()
    if mi.variant().startswith("llvm"):
        import drjit as dr

        version = tuple(dr.detail.llvm_version())
        if version < MIN_LLVM:
            # Seen with LLVM 14 and 15 on x86-64: Mitsuba's path integrator emits llvm.maximum,
            # which they cannot lower ("LLVM ERROR: Cannot select ... fmaximum"), and the process
            # aborts mid-render. Say so before that.
            raise RuntimeError(f"Dr.Jit uses LLVM {'.'.join(map(str, version))}; Mitsuba's llvm variants need LLVM "
                               f">= {MIN_LLVM[0]} here (Debian: apt install libllvm19; or point DRJIT_LIBLLVM_PATH "
                               f"at a newer libLLVM.so before importing mitsuba)")
    if not mi.variant().startswith("scalar"):
        import drjit as dr

        dr.set_flag(dr.JitFlag.SymbolicLoops, False)
        dr.set_flag(dr.JitFlag.SymbolicCalls, False)
    mi.register_bsdf(PLUGIN_NAME, lambda props: _bsdf_class()(props))


_CLASSES = {}


# One piece by design (the project's ~60-line rule): the plugin class is defined inside this
# function because Mitsuba's BSDF base class is per variant, so each variant needs its own class.
class _HybridBSDFMethods:
    """The methods of the plugin class (:func:`_bsdf_class` copies them into a subclass of the
    variant's ``mitsuba.BSDF``: Mitsuba's base class differs per variant, the methods do not).
    Never instantiated itself."""

    def __init__(self, props):
        mi = _mi()
        mi.BSDF.__init__(self, props)
        filename = props.get("filename")
        material = props.get("material")
        folder = props.get("svbrdf")
        self.sampler = props.get("sampler", "mis")
        self.evaluate = props.get("evaluate", "full")
        if self.sampler not in SAMPLERS:
            raise ValueError(f"hbrdf sampler {self.sampler!r}: expected one of {', '.join(SAMPLERS)}")
        if self.evaluate not in EVALUATE:
            raise ValueError(f"hbrdf evaluate {self.evaluate!r}: expected one of {', '.join(EVALUATE)}")
        self.svbrdf = None
        if folder is not None:
            if filename is not None or material is not None:
                raise ValueError("the hbrdf BSDF takes 'svbrdf' (a textured material's folder) or 'filename' and "
                                 "'material', not both")
            self.filter = props.get("filter", "bilinear")
            if self.filter not in FILTERS:
                raise ValueError(f"hbrdf filter {self.filter!r}: expected one of {', '.join(FILTERS)}")
            self.svbrdf = _core.Svbrdf(str(folder))
            self.folder = str(folder)
            # Unbounded: weights are data, not a reflectance to clamp or upsample (an 'rgb' value
            # becomes a constant texture; a bitmap should say "raw": true).
            self.weights = props.get_unbounded_texture("weights") if "weights" in props else None
            flags = (mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
                     | mi.BSDFFlags.Anisotropic | mi.BSDFFlags.SpatiallyVarying)
            self.m_components = [flags]
            self.m_flags = flags
            return
        if "weights" in props:
            raise ValueError("hbrdf weights: only a textured material ('svbrdf') has layer weights")
        if filename is None or material is None:
            raise ValueError("the hbrdf BSDF needs 'filename' (a model file) and 'material' (a name in it), or "
                             "'svbrdf' (a textured material's folder)")
        self.model = load_model(str(filename))
        self.material = str(material)
        self.index = self.model.index(self.material)
        self._core = _core.Model(self.model.path)
        if self.model.has_analytic:
            self.params = self.model.analytic_params(self.material).to_core()
        else:  # the neural baseline has no f_a: cosine sampling, full evaluation only
            if self.evaluate == "analytic":
                raise ValueError(f"{filename}: the neural baseline has no analytic part to evaluate")
            self.sampler = "cosine"
            self.params = AnalyticParams().to_core()
        iso = self.model.material_info[self.index].get("isotropic", True)
        flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
        if not iso:
            flags = flags | mi.BSDFFlags.Anisotropic
        self.m_components = [flags]
        self.m_flags = flags

    # -- hybridbrdf calls, (N, 3) arrays in hybridbrdf's convention -----------------------
    def _texture_weights(self, si, active, n: int):
        """The `weights` texture at si as (n, 3) float32, or None (the folder's map)."""
        if self.svbrdf is None or self.weights is None:
            return None
        a = np.asarray(self.weights.eval(si, active), dtype=np.float32)
        a = a.reshape(3, -1).T if a.ndim == 2 else a.reshape(1, 3)
        return np.ascontiguousarray(np.broadcast_to(a, (n, 3)))

    def _f(self, light: np.ndarray, view: np.ndarray, uv: np.ndarray, w=None) -> np.ndarray:
        if self.svbrdf is not None:
            analytic = self.evaluate == "analytic"
            return self.svbrdf.eval(uv, light, view, self.filter, analytic, not analytic, w)
        if self.evaluate == "analytic":
            return self._core.eval_analytic(light, view, self.index)
        return self._core.eval(light, view, self.index)

    def _pdf(self, light: np.ndarray, view: np.ndarray, uv: np.ndarray, w=None) -> np.ndarray:
        # The library's GGX pdf is the density of the visible-normal reflection, which also
        # reaches below the horizon; Mitsuba's BSDFs give those directions density 0 (their
        # samples carry no weight and are not counted by mitsuba.chi2), and so does the plugin.
        if self.svbrdf is not None:
            p = self.svbrdf.pdf(uv, light, view, self.sampler, self.filter, w)
        else:
            p = _core.pdf(light, view, self.params, self.sampler)
        return np.where(light[:, 2] > 0, p, 0.0)

    # -- Mitsuba's interface ---------------------------------------------------------
    def eval(self, ctx, si, wo, active=True):
        light, view = _pair(si.wi, wo)
        uv = _uv(si.uv, len(light))
        w = self._texture_weights(si, active, len(light))
        return _lanes(self._value(light, view, uv, _mask(active, len(light)), w))

    def pdf(self, ctx, si, wo, active=True):
        light, view = _pair(si.wi, wo)
        uv = _uv(si.uv, len(light))
        w = self._texture_weights(si, active, len(light))
        return _lanes(np.where(_mask(active, len(light)), self._pdf(light, view, uv, w), 0.0))

    def eval_pdf(self, ctx, si, wo, active=True):
        light, view = _pair(si.wi, wo)
        uv = _uv(si.uv, len(light))
        on = _mask(active, len(light))
        w = self._texture_weights(si, active, len(light))
        return _lanes(self._value(light, view, uv, on, w)), _lanes(np.where(on, self._pdf(light, view, uv, w), 0.0))

    def _value(self, light: np.ndarray, view: np.ndarray, uv: np.ndarray, on: np.ndarray, w=None) -> np.ndarray:
        """f cos(theta_light), 0 where inactive (and where a value is not finite: never, by the
        library's contract, but a renderer must not receive one)."""
        value = self._f(light, view, uv, w) * np.maximum(light[:, 2:3], 0.0)
        return np.where((on & np.isfinite(value).all(axis=1))[:, None], value, 0.0)

    def sample(self, ctx, si, sample1, sample2, active=True):
        mi = _mi()
        view = _rows(si.wi)
        u = np.asarray(sample2, dtype=np.float32).reshape(2, -1).T
        n = max(len(view), len(u))
        view = np.ascontiguousarray(np.broadcast_to(view, (n, 3)))
        u = np.ascontiguousarray(np.broadcast_to(u, (n, 2)))
        uv = _uv(si.uv, n)
        w = self._texture_weights(si, active, n)
        if self.svbrdf is not None:
            light, p, _ = self.svbrdf.sample(uv, view, u, self.sampler, self.filter, w)
        else:
            light, p, _ = _core.sample(view, u, self.params, self.sampler)
        f = self._f(light, view, uv, w)
        ok = _mask(active, n) & (p > 0) & (light[:, 2] > 0)
        weight = np.where(ok[:, None], f * np.maximum(light[:, 2:3], 0.0) / np.where(ok, p, 1.0)[:, None], 0.0)
        weight[~np.isfinite(weight).all(axis=1)] = 0.0
        bs = mi.BSDFSample3f()
        bs.wo = _lanes(light)
        bs.pdf = _lanes(np.where(ok, p, 0.0))
        bs.eta = 1.0
        bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
        bs.sampled_component = mi.UInt32(0)
        return bs, _lanes(weight)

    def traverse(self, callback):
        mi = _mi()
        if self.svbrdf is not None and self.weights is not None:
            callback.put_object("weights", self.weights, +mi.ParamFlags.NonDifferentiable)

    def to_string(self):
        if self.svbrdf is not None:
            weights = "" if self.weights is None else f", weights={self.weights}"
            return (f"HybridBSDF[svbrdf={self.folder!r}, filter={self.filter!r}{weights}, sampler={self.sampler!r}, "
                    f"evaluate={self.evaluate!r}]")
        return (f"HybridBSDF[filename={self.model.path!r}, material={self.material!r}, "
                f"sampler={self.sampler!r}, evaluate={self.evaluate!r}]")


def _bsdf_class():
    """The plugin class for the current variant (Mitsuba's BSDF base class differs per variant)."""
    mi = _mi()
    variant = mi.variant()
    if variant not in _CLASSES:
        # Single inheritance from the variant's BSDF, as Mitsuba's Python plugins are written: the
        # methods are copied in rather than mixed in (a Python mixin beside a bound base class is
        # not something Mitsuba documents).
        methods = {k: v for k, v in vars(_HybridBSDFMethods).items() if k == "__init__" or not k.startswith("__")}
        doc = "A material of a hybridbrdf model file as a Mitsuba BSDF (see the module's docstring)."
        _CLASSES[variant] = type("HybridBSDF", (mi.BSDF,), dict(methods, __doc__=doc))
    return _CLASSES[variant]


__all__ = ["PLUGIN_NAME", "SAMPLERS", "EVALUATE", "FILTERS", "register"]
