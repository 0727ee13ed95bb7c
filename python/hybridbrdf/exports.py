"""The public faces' machinery: each package's ``__init__`` exports its public names one import deep
(``hybridbrdf.render.render``, ``hybridbrdf.codegen.generate``, ...), and this module gives it

- names loaded on first access (PEP 562): a public name whose module imports PyTorch (seconds of
  start-up) is imported only when it is used, so ``import hybridbrdf`` and ``import hybridbrdf.fit``
  import no torch;
- an ImportError naming the new home of a name or module that moved (:data:`MOVED_MODULES`, the
  modules of the layout before the subpackages): ``import hybridbrdf.mitsuba`` says
  ``hybridbrdf.mitsuba moved to hybridbrdf.render.mitsuba``. Not a re-export: the old path stays an
  error, with a message, for one release (CHANGELOG.md).

A module ``hybridbrdf.X`` that does not exist is looked up by the finders of ``sys.meta_path`` and
never reaches a package's ``__getattr__``, so :class:`MovedModuleFinder` (installed by
``hybridbrdf/__init__.py``, last on ``sys.meta_path``) answers for the old module names only.
"""

from __future__ import annotations

import importlib
import sys
from typing import Callable, Dict, Iterable, Tuple

#: The release that moved the names below.
MOVED_IN = "0.1.0"

#: Modules of the layout before the subpackages (and of this release) -> their home now. Where
#: a package's public face holds all of an old module's public names, the home is the package.
MOVED_MODULES = {
    "hybridbrdf.acquire.command": "hybridbrdf.cli.acquire",
    "hybridbrdf.adding": "hybridbrdf.fit.adding",
    "hybridbrdf.analytic": "hybridbrdf.brdf",
    "hybridbrdf.brdfexplorer": "hybridbrdf.codegen.brdfexplorer",
    "hybridbrdf.checkpoint": "hybridbrdf.fit.checkpoint",
    "hybridbrdf.codegen_literals": "hybridbrdf.codegen.literals",
    "hybridbrdf.codegen_network": "hybridbrdf.codegen.network",
    "hybridbrdf.codegen_render": "hybridbrdf.codegen.source",
    "hybridbrdf.codegen_scene": "hybridbrdf.codegen.scene",
    "hybridbrdf.directions": "hybridbrdf.evaluate.directions",
    "hybridbrdf.distributed": "hybridbrdf.fit.distributed",
    "hybridbrdf.editing": "hybridbrdf.model.editing",
    "hybridbrdf.evaluation": "hybridbrdf.evaluate.evaluation",
    "hybridbrdf.fit_loss": "hybridbrdf.fit.loss",
    "hybridbrdf.fit_schedule": "hybridbrdf.fit.schedule",
    "hybridbrdf.fit_settings": "hybridbrdf.fit.settings",
    "hybridbrdf.fitting": "hybridbrdf.fit.joint",
    "hybridbrdf.metrics": "hybridbrdf.evaluate.metrics",
    "hybridbrdf.mitsuba": "hybridbrdf.render.mitsuba",
    "hybridbrdf.model_file": "hybridbrdf.model",
    "hybridbrdf.models": "hybridbrdf.model.networks",
    "hybridbrdf.precision": "hybridbrdf.model.precision",
    "hybridbrdf.preview": "hybridbrdf.render.preview",
    "hybridbrdf.prior": "hybridbrdf.model",
    "hybridbrdf.random_model": "hybridbrdf.model.random",
    "hybridbrdf.reference": "hybridbrdf.brdf.microfacet",
    "hybridbrdf.source_names": "hybridbrdf.sources.names",
    "hybridbrdf.sparse_start": "hybridbrdf.fit.sparse_start",
    "hybridbrdf.torch_brdf": "hybridbrdf.brdf.torch_brdf",
    "hybridbrdf.training_loop": "hybridbrdf.fit.loop",
    "hybridbrdf.training_pool": "hybridbrdf.fit.pool",
    "hybridbrdf.training_record": "hybridbrdf.fit.record",
    "hybridbrdf.viewer_glsl": "hybridbrdf.viewer.glsl",
    "hybridbrdf.viewer_lighting": "hybridbrdf.viewer.lighting",
    "hybridbrdf.viewer_sources": "hybridbrdf.viewer.measured",
    "hybridbrdf.viewer_wgsl": "hybridbrdf.viewer.wgsl",
    "hybridbrdf.util": "hybridbrdf.files",
    # Modules named like their functions, which hid them (the function is the package's name now).
    "hybridbrdf.fit.fit": "hybridbrdf.fit.joint",
    "hybridbrdf.fit.paint": "hybridbrdf.fit.painting",
    "hybridbrdf.acquire.simulate": "hybridbrdf.acquire.simulation",
}


def moved_message(old: str, new: str) -> str:
    return f"{old} moved to {new} (hybridbrdf {MOVED_IN}); see CHANGELOG.md"


class MovedModuleFinder:
    """A meta path finder that raises ModuleNotFoundError naming the new home of an old module
    name (:data:`MOVED_MODULES`) and finds nothing else. Last on ``sys.meta_path``: a module
    that exists is always found before it is asked."""

    @staticmethod
    def find_spec(fullname, path=None, target=None):
        if fullname in MOVED_MODULES:
            raise ModuleNotFoundError(moved_message(fullname, MOVED_MODULES[fullname]), name=fullname)
        return None


def install_finder() -> None:
    """Puts :class:`MovedModuleFinder` last on ``sys.meta_path`` once (a re-import adds no second)."""
    if MovedModuleFinder not in sys.meta_path:
        sys.meta_path.append(MovedModuleFinder)


def public_face(package: str, namespace: dict, lazy: Dict[str, str] = None,
                moved: Dict[str, str] = None) -> Tuple[Callable, Callable]:
    """``__getattr__`` and ``__dir__`` for the package ``package`` whose globals are ``namespace``:
    ``lazy`` maps a public name to the module that defines it (imported on first access, then a
    plain global); ``moved`` maps a name the package no longer has to its home (an ImportError
    says where, for ``package.name`` and ``from package import name`` alike); the modules of
    :data:`MOVED_MODULES` just under ``package`` raise the same way, unless the package now exports
    a name so spelled (``hybridbrdf.fit.fit`` is the joint fit; ``import hybridbrdf.fit.fit``, the old
    module, still raises, through :class:`MovedModuleFinder`)."""
    lazy = dict(lazy or {})
    moved = dict(moved or {})
    moved.update({old.rsplit(".", 1)[1]: new for old, new in MOVED_MODULES.items()
                  if old.rsplit(".", 1)[0] == package and old.rsplit(".", 1)[1] not in lazy})

    def __getattr__(name):
        if name in lazy:
            value = getattr(importlib.import_module(lazy[name]), name)
            namespace[name] = value  # later accesses are plain attribute lookups
            return value
        if name in moved:
            # An ImportError, not an AttributeError: ``from package import name`` shows this message
            # (an AttributeError would become "cannot import name").
            raise ImportError(moved_message(f"{package}.{name}", moved[name]), name=f"{package}.{name}")
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted(set(namespace) | set(lazy))

    return __getattr__, __dir__


def lazy_names(names: Iterable[str], module: str) -> Dict[str, str]:
    """``{name: module}`` for each of ``names``: a ``lazy`` table of :func:`public_face`."""
    return {n: module for n in names}
