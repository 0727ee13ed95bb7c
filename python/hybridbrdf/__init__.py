"""hybridbrdf — hybrid neural-microfacet BRDFs.

The analytic component f_a (Lambert + anisotropic GGX with exact dielectric
Fresnel) is evaluated and sampled by the C++ library (``hybridbrdf._core``);
``hybridbrdf.brdf.torch_brdf`` holds the same formulas in PyTorch for fitting.
Conventions: ``docs/CONVENTIONS.md``.

Each subpackage's ``__init__`` is its public face, one import deep: ``hybridbrdf.render.render``,
``hybridbrdf.codegen.generate``, ``hybridbrdf.model.edit``, ... (``__all__`` lists them). The names
here load on first access (PEP 562), except the C++ library's constants: ``import hybridbrdf``
imports neither PyTorch nor NumPy, and so neither does ``hbrdf --help`` (every command line
imports this package first). ``hybridbrdf.<subpackage>`` imports the subpackage on first access
too. Modules of the layout before the subpackages (``hybridbrdf.mitsuba``,
``hybridbrdf.model_file``, ...) raise an ImportError naming their new home
(:data:`hybridbrdf.exports.MOVED_MODULES`).
"""

from hybridbrdf._core import (
    ALPHA_MAX,
    ALPHA_MIN,
    CONVENTIONS_VERSION,
    ETA_MAX,
    ETA_MIN,
    MIS_MIN_LOBE_PROBABILITY,
)
import importlib as _importlib
import pathlib as _pathlib

from hybridbrdf import _core
from hybridbrdf._core import __version__ as _core_version
from hybridbrdf.errors import InputFileError, ModelFileError
from hybridbrdf.exports import install_finder as _install_finder, lazy_names as _lazy_names
from hybridbrdf.exports import public_face as _public_face
from hybridbrdf.version import __version__

#: Public names loaded on first access (PEP 562): their modules import NumPy (0.1 s) or PyTorch
#: (seconds), and ``import hybridbrdf`` (every ``hbrdf`` command line, even ``--help``) should not.
_LAZY = {
    **_lazy_names(["AnalyticParams", "analytic_eval", "pdf", "sample", "simd_path"], "hybridbrdf.brdf.analytic"),
    "FitSettings": "hybridbrdf.fit.settings", "add": "hybridbrdf.fit.adding",
    **_lazy_names(["HybridModel", "load_model"], "hybridbrdf.model.file"),
    **_lazy_names(["load_prior", "prior_path"], "hybridbrdf.model.prior"),
    **_lazy_names(["expand_sources", "open_source"], "hybridbrdf.sources"),
    **_lazy_names(["BRDFFormatError", "BRDFSource"], "hybridbrdf.sources.base"),
    **_lazy_names(["SVBRDF", "load_svbrdf"], "hybridbrdf.svbrdf.asset"),
}

#: This package's modules and subpackages: ``hybridbrdf.<name>`` imports one on first access, as
#: an ``import hybridbrdf`` that imported them all used to leave them reachable.
_SUBMODULES = {p.stem for p in _pathlib.Path(__file__).parent.iterdir()
               if (p.suffix == ".py" and p.stem != "__init__") or (p / "__init__.py").is_file()}

# ``import hybridbrdf.mitsuba`` (an old module name) names hybridbrdf.render.mitsuba in its error.
_install_finder()

if _core_version != __version__:  # a stale extension from an older build
    raise ImportError(f"hybridbrdf {__version__} found extension hybridbrdf._core {_core_version}; reinstall the package")

#: Names of the sampling strategies of sample() and pdf(), from the C++ library (sampling.hpp).
STRATEGIES = tuple(_core.STRATEGIES)

__all__ = [
    "ALPHA_MAX",
    "ALPHA_MIN",
    "CONVENTIONS_VERSION",
    "ETA_MAX",
    "ETA_MIN",
    "MIS_MIN_LOBE_PROBABILITY",
    "STRATEGIES",
    "AnalyticParams",
    "BRDFFormatError",
    "BRDFSource",
    "FitSettings",
    "HybridModel",
    "add",
    "InputFileError",
    "ModelFileError",
    "expand_sources",
    "load_model",
    "load_svbrdf",
    "SVBRDF",
    "load_prior",
    "prior_path",
    "open_source",
    "analytic_eval",
    "pdf",
    "sample",
    "simd_path",
]


# ``hybridbrdf.add`` loads on first use; ``hybridbrdf.model_file`` (a moved module) raises an
# ImportError naming its new home.
_face_getattr, __dir__ = _public_face(__name__, globals(), _LAZY)


def __getattr__(name):
    if name in _SUBMODULES:
        return _importlib.import_module(f"{__name__}.{name}")
    return _face_getattr(name)
