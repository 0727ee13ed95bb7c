"""hybridbrdf — hybrid neural-microfacet BRDFs.

The analytic component f_a (Lambert + anisotropic GGX with exact dielectric
Fresnel) is evaluated and sampled by the C++ library (``hybridbrdf._core``);
``hybridbrdf.brdf.torch_brdf`` holds the same formulas in PyTorch for fitting.
Conventions: ``docs/CONVENTIONS.md``.

Each subpackage's ``__init__`` is its public face, one import deep: ``hybridbrdf.render.render``,
``hybridbrdf.codegen.generate``, ``hybridbrdf.model.edit``, ... (``__all__`` lists them). Names
whose modules import PyTorch load on first access (``hybridbrdf.add``; PEP 562), so ``import
hybridbrdf`` imports none. Modules of the layout before the subpackages (``hybridbrdf.mitsuba``,
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
from hybridbrdf import _core
from hybridbrdf._core import __version__ as _core_version
from hybridbrdf.brdf.analytic import AnalyticParams, analytic_eval, pdf, sample, simd_path
from hybridbrdf.errors import InputFileError, ModelFileError
from hybridbrdf.exports import install_finder as _install_finder, public_face as _public_face
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.model.file import HybridModel, load_model
from hybridbrdf.model.prior import load_prior, prior_path
from hybridbrdf.sources import expand_sources, open_source
from hybridbrdf.sources.base import BRDFFormatError, BRDFSource
from hybridbrdf.svbrdf.asset import SVBRDF, load_svbrdf
from hybridbrdf.version import __version__

#: Public names whose modules import PyTorch, loaded on first access (PEP 562): importing torch
#: costs seconds, and ``import hybridbrdf`` (every ``hbrdf`` command line, even ``--help``) should not.
_LAZY = {"add": "hybridbrdf.fit.adding"}

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
__getattr__, __dir__ = _public_face(__name__, globals(), _LAZY)
