"""Adding measured materials to a fitted collection without retraining its network
(``hbrdf add``; the paper's sparse fitting, Sec. 4.2).

    model = hybridbrdf.add(["new_paint.bsdf"], to="collection.safetensors", out="collection+paint.safetensors")

Each new source gets its own analytic parameters p and latent code z, fitted against the
base model's frozen network (:func:`hybridbrdf.fitting.fit` with ``frozen=``); the result is
one model file holding the base's materials, unchanged, followed by the new ones. Everything
that can be refused is refused before any training: the output path, the base model, sources
that cannot be read, and names that are already in the base or break the contract's name rule.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Callable, List, Optional, Sequence, Union

import numpy as np

from hybridbrdf.errors import InputFileError
from hybridbrdf.fit_settings import FitSettings
from hybridbrdf.model_file import HybridModel, load_model
from hybridbrdf.names import names_problem
from hybridbrdf.sources.base import BRDFSource

SourceLike = Union[str, os.PathLike, BRDFSource]


def _open(sources: Sequence[SourceLike]) -> List[BRDFSource]:
    """BRDFSource objects as given; paths, folders, globs and synthetic:NAME opened, in order."""
    from hybridbrdf.sources import expand_sources, open_source

    opened: List[BRDFSource] = []
    for s in sources:
        if isinstance(s, BRDFSource):
            opened.append(s)
        else:
            opened.extend(open_source(p) for p in expand_sources([os.fspath(s)]))
    return opened


def check_additions(base: HybridModel, sources: Sequence[BRDFSource]) -> List[str]:
    """The names the new materials will have; raises InputFileError (naming the source's file)
    for a name already in ``base``, and ValueError when base and new names together break the
    contract (two names sharing a shader constant)."""
    from hybridbrdf.fitting import material_names

    names = material_names(sources)  # the name rule and clashes among the new ones
    taken = set(base.materials)
    for src, name in zip(sources, names):
        if name in taken:
            raise InputFileError(src.path or name, f"material '{name}' is already in {base.path or 'the base model'}; "
                                                   f"rename the file, or add it to another model")
    problem = names_problem(list(base.materials) + names)
    if problem:
        raise ValueError(f"{problem} (the base model's names and the new ones must stay distinct)")
    return names


def merge(base: HybridModel, added: HybridModel, keep_base_materials: bool = True) -> HybridModel:
    """One model: ``base``'s network and materials followed by ``added``'s materials (only
    ``added``'s without ``keep_base_materials``: a model built on the shipped prior). ``added``
    must have been fitted against ``base``'s frozen network (its network tensors are checked to
    be bit-identical)."""
    for key, value in base.tensors.items():
        if not key.startswith("materials.") and not np.array_equal(value, added.tensors[key]):
            raise ValueError(f"cannot merge: tensor {key} differs; the added materials were not fitted to this network")
    tensors = {k: ((np.concatenate([v, added.tensors[k]]) if keep_base_materials else added.tensors[k].copy())
                   if k.startswith("materials.") else v.copy())
               for k, v in base.tensors.items()}
    training = dict(base.training) if isinstance(base.training, dict) else {}
    # The base's record describes the network; each addition keeps its own (settings, time, names).
    training["additions"] = list(training.get("additions", [])) + [dict(added.training, materials=added.materials)]
    materials = ([dict(m) for m in base.material_info] if keep_base_materials else []) + \
        [dict(m) for m in added.material_info]
    return HybridModel(dict(base.arch), materials, tensors, training)


def add(sources: Sequence[SourceLike], to: Optional[Union[str, os.PathLike]] = None,
        out: Optional[Union[str, os.PathLike]] = None, settings: Optional[FitSettings] = None,
        progress: bool = True, log: Callable[[str], None] = lambda msg: None) -> HybridModel:
    """Sparse-fit ``sources`` (paths, folders, globs, ``synthetic:NAME`` or BRDFSource objects)
    onto the frozen network of the model file ``to`` and return the merged model (``to``'s
    materials, then the new ones); with ``out``, also write it there (atomically; ``out`` may be
    ``to`` itself, which is then replaced only once the fit has succeeded). Without ``to``, the
    network is the shipped prior's (:mod:`hybridbrdf.prior`) and the model holds the new
    materials only.

    ``settings``: the fit's training, loss and sparse settings (:class:`FitSettings`; its
    network fields are taken from ``to``); default: the default recipe with
    :data:`~hybridbrdf.fit_settings.ADD_STEPS` steps. Raises InputFileError / ModelFileError /
    ValueError, one line naming the input, before any training for every input that can be checked."""
    from hybridbrdf.fit_settings import ADD_STEPS
    from hybridbrdf.fitting import fit, frozen_arch_settings
    from hybridbrdf.prior import prior_path
    from hybridbrdf.util import check_writable

    if out is not None:
        check_writable(out, "model")
    on_prior = to is None
    to = prior_path() if on_prior else to
    base = load_model(to)
    settings = dataclasses.replace(settings) if settings is not None else FitSettings(steps=ADD_STEPS)
    settings.frozen_from = os.fspath(to)
    frozen_arch_settings(settings, base)
    settings.check()
    opened = _open(sources)
    if not opened:
        raise ValueError("no sources to add")
    for src in opened:
        if out is not None and src.path and os.path.exists(out) and os.path.samefile(src.path, out):
            raise InputFileError(out, "--out names one of the sources")
    if not on_prior:  # the prior's own materials are not written: their names cannot clash
        check_additions(base, opened)
    settings.sources = [s.path or s.name for s in opened]
    added = fit(opened, settings, frozen=base, progress=progress, log=log)
    merged = merge(base, added, keep_base_materials=not on_prior)
    if out is not None:
        merged = merged.save_checked(out)
    return merged
