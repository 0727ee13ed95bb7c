"""Fitting: settings, the training pool, loss, schedule, loop, record, checkpoints, ranks, hbrdf add.

    from hybridbrdf.fit import FitSettings, add       # add imports PyTorch on first use

Every fit imports PyTorch; its names here load on first access (PEP 562), so ``import
hybridbrdf.fit`` (FitSettings, the command line's flags) imports none. The joint fit itself is
:func:`hybridbrdf.fit.fit.fit` and the painter :func:`hybridbrdf.fit.paint.paint`: their modules
share their names, and a package attribute cannot be both the function and the submodule
(importing ``hybridbrdf.fit.fit`` sets the attribute to the module).
"""

from hybridbrdf.exports import public_face
from hybridbrdf.fit.settings import FitSettings

#: Public names whose module imports PyTorch, loaded on first access (PEP 562).
_LAZY = {"add": "hybridbrdf.fit.adding", "CheckpointError": "hybridbrdf.fit.checkpoint",
         "RankLostError": "hybridbrdf.fit.distributed"}

__all__ = ["CheckpointError", "FitSettings", "RankLostError", "add"]

__getattr__, __dir__ = public_face(__name__, globals(), _LAZY)
