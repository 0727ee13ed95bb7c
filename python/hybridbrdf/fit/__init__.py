"""Fitting: settings, the training pool, loss, schedule, loop, record, checkpoints, ranks, hbrdf add.

    from hybridbrdf.fit import FitSettings, add, fit, paint   # all but FitSettings import PyTorch on first use

Every fit imports PyTorch; its names here load on first access (PEP 562), so ``import
hybridbrdf.fit`` (FitSettings, the command line's flags) imports none. The joint fit
:func:`fit` lives in ``joint.py`` and the painter :func:`paint` in ``painting.py``: a module named
like its function would hide it (importing ``hybridbrdf.fit.X`` sets the package's attribute ``X``
to the module).
"""

from hybridbrdf.exports import public_face
from hybridbrdf.fit.settings import FitSettings

#: Public names whose module imports PyTorch, loaded on first access (PEP 562).
_LAZY = {"add": "hybridbrdf.fit.adding", "CheckpointError": "hybridbrdf.fit.checkpoint",
         "RankLostError": "hybridbrdf.fit.distributed", "fit": "hybridbrdf.fit.joint",
         "paint": "hybridbrdf.fit.painting"}

__all__ = ["CheckpointError", "FitSettings", "RankLostError", "add", "fit", "paint"]

__getattr__, __dir__ = public_face(__name__, globals(), _LAZY)
