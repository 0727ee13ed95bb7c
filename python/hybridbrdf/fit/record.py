"""The training record a fit writes into its model file (``training``) and ``hbrdf info`` prints.

It holds the :class:`~hybridbrdf.fit.settings.FitSettings` (``device`` among them), the
timings (``train_seconds`` and, where they apply, ``train_seconds_from_step``,
``resumed_at_step``, ``compile_seconds``; ``pairs_x_materials_per_second``) and how the fit
was run (:data:`ENVIRONMENT`): the number of ranks of a data-parallel fit (1 otherwise), the
torch threads of each rank, and the torch and hybridbrdf versions. A resumed fit records the
run that finished it. Files written before a field existed lack it; readers must not need it.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, Dict, Optional

from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.version import __version__

#: How a fit was run, besides its settings: the keys :func:`environment` records.
ENVIRONMENT = ("world_size", "torch_threads", "torch_version", "hybridbrdf_version")


def environment(world_size: int, torch_threads: Optional[int] = None) -> Dict[str, Any]:
    """The :data:`ENVIRONMENT` fields of a fit on ``world_size`` ranks (``torch_threads``: the
    rank's torch.get_num_threads() while it trained; now when not given)."""
    import torch  # here, not at the top: `hbrdf info` reads ENVIRONMENT and must start without torch

    return {"world_size": int(world_size),
            "torch_threads": int(torch.get_num_threads() if torch_threads is None else torch_threads),
            "torch_version": str(torch.__version__), "hybridbrdf_version": __version__}


def training_record(settings: FitSettings, timing, start: int, earlier_seconds: float, timed_from: int,
                    pairs_per_step: int, world_size: int, torch_threads: Optional[int] = None) -> Dict[str, Any]:
    """The ``training`` dict of a fit that ran steps ``start`` .. ``settings.steps`` - 1 in
    ``timing`` (:class:`~hybridbrdf.fit.loop.Timing`), after ``earlier_seconds`` of
    training from step ``timed_from`` on (a resumed fit); ``pairs_per_step``: pairs times
    materials each step evaluates (global batch x rows of the module)."""
    training = dataclasses.asdict(settings)
    training["train_seconds"] = round(earlier_seconds + timing.elapsed, 3)
    if timed_from:
        # Resumed (perhaps more than once) from a checkpoint that kept no time.
        training["train_seconds_from_step"] = timed_from
    if start:
        training["resumed_at_step"] = start
    timed_steps, timed_seconds = settings.steps - start, timing.elapsed
    if timing.compile_seconds is not None:
        training["compile_seconds"] = round(timing.compile_seconds, 3)
        timed_steps, timed_seconds = timed_steps - 1, timing.elapsed - timing.compile_seconds
    training["pairs_x_materials_per_second"] = (
        round(timed_steps * pairs_per_step / timed_seconds) if timed_seconds > 0 else None)
    training.update(environment(world_size, torch_threads))
    return training


def environment_line(training: Dict[str, Any], shown: Callable[[Any], str]) -> str:
    """``run: ...`` as ``hbrdf info`` prints it: ranks, device, torch threads, versions. A file
    written before some of these were recorded gets what it has and ``not recorded: <keys>``.
    ``shown`` formats a value of the free-form record as one printable piece."""
    world = training.get("world_size")
    parts = []
    if world is not None:
        parts.append("1 rank" if world == 1 else f"{shown(world)} ranks (data-parallel)")
    if training.get("device") is not None:
        parts.append(f"device {shown(training['device'])}")
    if training.get("torch_threads") is not None:
        parts.append(f"torch threads {shown(training['torch_threads'])}" + ("" if world in (None, 1) else " per rank"))
    for key, label in (("torch_version", "torch"), ("hybridbrdf_version", "hybridbrdf")):
        if training.get(key) is not None:
            parts.append(f"{label} {shown(training[key])}")
    line = "run: " + ", ".join(parts)
    missing = [k for k in ENVIRONMENT if training.get(k) is None]
    if missing:
        line += ("; " if parts else "") + "not recorded: " + ", ".join(missing) + (
            " (a file from an earlier hybridbrdf)" if len(missing) == len(ENVIRONMENT) else "")
    return line
