"""Adding measured materials to a fitted network (``hbrdf add``): onto the shipped prior a
fine-tune (the prior as a starting point: its network trained further with the new materials),
onto a collection the paper's sparse fitting (Sec. 4.2, the network kept).

    model = hybridbrdf.add(["new_paint.bsdf"], to="collection.safetensors", out="collection+paint.safetensors")

Each new source gets its own analytic parameters p and latent code z, fitted against the
base model's frozen network (:func:`hybridbrdf.fit.fit` with ``frozen=``); the result is
one model file holding the base's materials, unchanged, followed by the new ones. Everything
that can be refused is refused before any training: the output path, the base model, sources
that cannot be read, and names that are already in the base or break the contract's name rule.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
from typing import Callable, List, Optional, Sequence, Union

import numpy as np

from hybridbrdf import spec
from hybridbrdf.errors import InputFileError
from hybridbrdf.fit.joint import fit, frozen_arch_settings
from hybridbrdf.fit.settings import ADD_LOSS_EPS, ADD_STEPS, FINETUNE_STEPS, MAX_DRIFT, STEPS, FitSettings
from hybridbrdf.model.file import HybridModel, load_model
from hybridbrdf.model.prior import prior_path
from hybridbrdf.names import names_problem
from hybridbrdf.sources import expand_sources, open_source
from hybridbrdf.sources.base import BRDFSource
from hybridbrdf.sources.model import ModelMaterialSource
from hybridbrdf.sources.names import material_names
from hybridbrdf.files import check_writable, file_lock

SourceLike = Union[str, os.PathLike, BRDFSource]


def _open(sources: Sequence[SourceLike]) -> List[BRDFSource]:
    """BRDFSource objects as given; paths, folders, globs and synthetic:NAME opened, in order."""
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
    arch = dict(base.arch)
    if "materials.energy_bound" in base.tensors or "materials.energy_bound" in added.tensors:
        # A model with tables for some materials: the others get tables of ones (no bound).
        base, added = _with_unit_tables(base), _with_unit_tables(added)
        arch["energy_bound"] = "albedo_table"
    tensors = {k: ((np.concatenate([v, added.tensors[k]]) if keep_base_materials else added.tensors[k].copy())
                   if k.startswith("materials.") else v.copy())
               for k, v in base.tensors.items()}
    training = dict(base.training) if isinstance(base.training, dict) else {}
    # The base's record describes the network; each addition keeps its own (settings, time, names).
    training["additions"] = list(training.get("additions", [])) + [dict(added.training, materials=added.materials)]
    materials = ([dict(m) for m in base.material_info] if keep_base_materials else []) + \
        [dict(m) for m in added.material_info]
    return HybridModel(arch, materials, tensors, training)


def _with_unit_tables(model: HybridModel) -> HybridModel:
    """``model`` with energy-bound tables: its own, or ones (no bound) where it has none."""
    if "materials.energy_bound" in model.tensors:
        return model
    tensors = dict(model.tensors)
    tensors["materials.energy_bound"] = np.ones((len(model.materials), spec.ENERGY_NODES), np.float32)
    return HybridModel(dict(model.arch, energy_bound="albedo_table"), model.material_info, tensors, model.training)


def add(sources: Sequence[SourceLike], to: Optional[Union[str, os.PathLike]] = None,
        out: Optional[Union[str, os.PathLike]] = None, settings: Optional[FitSettings] = None,
        progress: bool = True, log: Callable[[str], None] = lambda msg: None,
        keep_network: bool = False, finetune_steps: Optional[int] = None,
        prior: Optional[Union[str, os.PathLike]] = None, refine: bool = False,
        max_drift: float = MAX_DRIFT, reciprocal: Optional[bool] = None) -> HybridModel:
    """Add ``sources`` (paths, folders, globs, ``synthetic:NAME`` or BRDFSource objects) to a
    fitted network and return the model; with ``out``, also write it there (atomically; ``out``
    may be ``to`` itself, which is then replaced only once the fit has succeeded).

    Onto the shipped prior (``to`` None, :mod:`hybridbrdf.model.prior`), by default a **fine-tune**:
    the sparse fit below gives each source its (p, z) on the prior's frozen network, then
    ``finetune_steps`` (default :data:`~hybridbrdf.fit.settings.FINETUNE_STEPS`) steps train the
    network together with them (:func:`~hybridbrdf.fit.fit` with ``init=``); the model holds
    the new materials with a network of their own. ``keep_network``: stop after the sparse fit
    (the network bit-identical to the prior's, for engines that already ship it).

    Onto a model file ``to``: the sparse fit (paper Sec. 4.2), ``to``'s network kept bit-exact and
    its materials followed by the new ones. With ``refine``: after the sparse fit, ``to``'s
    network is trained further (``finetune_steps``) with the new materials and ``to``'s own,
    which are replayed against ``to``'s outputs (:class:`~hybridbrdf.sources.model.ModelMaterialSource`:
    no original measurement needed) with their (p, z) free. Each of ``to``'s materials then
    records its drift (``refine_drift``: SMAPE and cMAE of the refined model against ``to`` on
    the metric pairs); a drift in SMAPE above ``max_drift`` raises :class:`RefineDriftError`
    naming the material, and nothing is written.

    ``prior``: another prior's file in place of the shipped one (a prior trained without the
    materials being added, for an honest hold-out: bench/prior_heldout.py). ``reciprocal`` (the
    default onto the shipped priors, issue 60): onto the shipped reciprocal prior
    (``hybridbrdf.model.prior.RECIPROCAL_PRIOR_FILE``, architecture ``hybrid-reciprocal``), so the
    model is reciprocal bit for bit, fine-tuned or not; ``False``: onto the plain prior
    (``PRIOR_FILE``, architecture ``hybrid``). With ``to`` or ``prior`` the architecture is theirs:
    ``reciprocal`` is then left None, and True or False is a ValueError.

    ``settings``: the fit's training, loss and sparse settings (:class:`FitSettings`; its
    network fields are taken from ``to``); default: the default recipe with
    :data:`~hybridbrdf.fit.settings.ADD_STEPS` sparse steps and loss epsilon
    :data:`~hybridbrdf.fit.settings.ADD_LOSS_EPS`. Raises InputFileError /
    ModelFileError / ValueError, one line naming the input, before any training for every input
    that can be checked."""
    if out is not None:
        check_writable(out, "model")
    # ``out`` may be ``to``: the base is read under out's lock and the merged model written
    # before it is released, so a concurrent update of the same file is never lost (it waits for
    # this one, or refuses after LOCK_WAIT_SECONDS; docs/CONVENTIONS.md, "Writing files").
    if (to is not None or prior is not None) and reciprocal is not None:
        raise ValueError("--reciprocal and --no-reciprocal choose between the shipped priors; a --to BASE or "
                         "another prior keeps its own architecture (a base fitted with --arch hybrid-reciprocal "
                         "is reciprocal)")
    with file_lock(out) if out is not None else contextlib.nullcontext():
        return _add_locked(sources, to, out, settings, progress, log, keep_network, finetune_steps, prior, refine,
                           max_drift, reciprocal is not False)


def _add_locked(sources, to, out, settings, progress, log, keep_network, finetune_steps, prior, refine, max_drift,
                reciprocal):
    """The body of :func:`add`, run under the lock of ``out``."""
    on_prior = to is None
    to = _resolve_base(to, prior, reciprocal)
    finetune, finetune_steps = _check_options(on_prior, refine, keep_network, finetune_steps, max_drift)
    base = load_model(to)
    settings = _sparse_settings(settings, base, to)
    opened = _open_additions(sources, base, out, on_prior)
    settings.sources = [s.path or s.name for s in opened]
    # A fine-tune or a refine trains on from the sparse fit: the guard and the energy bound act at
    # their end (a head the guard set to f_a would start them with a gradient of 0).
    stage = dataclasses.replace(settings, analytic_guard=False, energy_bound=False) if (refine or finetune) else settings
    added = fit(opened, stage, frozen=base, progress=progress, log=log)
    if refine:
        merged = _refine(base, added, opened, settings, finetune_steps, max_drift, os.fspath(to), progress, log)
    elif finetune:
        merged = _finetune(opened, added, settings, finetune_steps, prior, to, progress, log)
    else:
        added.training["mode"] = "sparse"
        merged = merge(base, added, keep_base_materials=not on_prior)
    if out is not None:
        merged = merged.save_checked(out)
    return merged


def _resolve_base(to: Optional[Union[str, os.PathLike]], prior: Optional[Union[str, os.PathLike]],
                  reciprocal: bool):
    """The base model's path: ``to``, or without it ``prior`` or the shipped prior's file (the
    reciprocal prior's when ``reciprocal``, the plain one's otherwise)."""
    if to is not None:
        return to
    return prior if prior is not None else prior_path(reciprocal)


def _check_options(on_prior: bool, refine: bool, keep_network: bool, finetune_steps: Optional[int],
                   max_drift: float):
    """(whether the network is trained after the sparse fit, its steps); ValueError for options
    that contradict each other or are out of range."""
    if refine and on_prior:
        raise ValueError("--refine refines the network of --to BASE; onto the shipped prior the network is "
                         "fine-tuned by default")
    if refine and keep_network:
        raise ValueError("--refine trains the network; --keep-network keeps it: give one of them")
    if not max_drift > 0:
        raise ValueError(f"max drift must be > 0, got {max_drift}")
    finetune = (on_prior and not keep_network) or refine
    finetune_steps = FINETUNE_STEPS if finetune_steps is None else finetune_steps
    if finetune:
        problem = STEPS.problem(finetune_steps)
        if problem:
            raise ValueError(f"finetune steps {problem}")
    return finetune, finetune_steps


def _sparse_settings(settings: Optional[FitSettings], base: HybridModel, to) -> FitSettings:
    """A copy of ``settings`` (default: the default recipe with ADD_STEPS steps and loss epsilon
    ADD_LOSS_EPS) for the sparse fit
    on ``base``'s frozen network, its network fields taken from ``base``, checked."""
    settings = (dataclasses.replace(settings) if settings is not None
                else FitSettings(steps=ADD_STEPS, loss_eps=ADD_LOSS_EPS))
    settings.frozen_from, settings.init_from = os.fspath(to), None
    frozen_arch_settings(settings, base)
    settings.check()
    return settings


def _open_additions(sources: Sequence[SourceLike], base: HybridModel, out, on_prior: bool) -> List[BRDFSource]:
    """The sources opened; refused when there are none, when one of them is ``out``, or (onto a
    model file) when their names clash with ``base``'s."""
    opened = _open(sources)
    if not opened:
        raise ValueError("no sources to add")
    for src in opened:
        if out is not None and src.path and os.path.exists(out) and os.path.samefile(src.path, out):
            raise InputFileError(out, "--out names one of the sources")
    if not on_prior:  # the prior's own materials are not written: their names cannot clash
        check_additions(base, opened)
    return opened


def _finetune(opened: List[BRDFSource], added: HybridModel, settings: FitSettings, steps: int,
              prior: Optional[Union[str, os.PathLike]], base_path, progress: bool,
              log: Callable[[str], None]) -> HybridModel:
    """``hbrdf add`` onto a prior: its network and the new materials' (p, z) trained together for
    ``steps``, started from the sparse fit ``added``; the record keeps that sparse fit."""
    tuned_settings = dataclasses.replace(settings, steps=steps, frozen_from=None,
                                         init_from="prior" if prior is None else os.fspath(base_path))
    log(f"fine-tune: the network and the new materials' (p, z) together, {steps} steps")
    tuned = fit(opened, tuned_settings, init=added, progress=progress, log=log)
    # The record: the fine-tune's settings and time, and the sparse fit it started from.
    tuned.training["mode"] = "fine-tune"
    tuned.training["sparse_fit"] = dict(added.training)
    _record_sparse_starts(tuned.material_info, added.material_info)
    return tuned


def _record_sparse_starts(infos, sparse_infos) -> None:
    """Each fine-tuned material keeps the metrics of the sparse fit it started from."""
    for info, start in zip(infos, sparse_infos):
        info["sparse_fit"] = {"metrics": start["metrics"], **({"start": start["sparse_start"]}
                                                              if "sparse_start" in start else {})}


class RefineDriftError(ValueError):
    """``--refine`` moved one of the base's materials further than ``--max-drift`` allows;
    ``str()`` names the material and the drift, and nothing was written."""


def _refine(base: HybridModel, added: HybridModel, opened: List[BRDFSource], settings: FitSettings, steps: int,
            max_drift: float, base_path: str, progress: bool, log: Callable[[str], None]) -> HybridModel:
    """``hbrdf add --to BASE --refine``: BASE's network trained further with the new materials
    (started from their sparse fit) and BASE's own (replayed against BASE's outputs, their
    (p, z) free); each BASE material's drift measured against BASE on the metric pairs."""
    start = merge(base, added)  # every material's starting point, by name
    replayed = [ModelMaterialSource(base, name) for name in base.materials]
    tuned_settings = dataclasses.replace(settings, steps=steps, frozen_from=None, init_from=base_path,
                                         sources=[f"{base_path}:{n}" for n in base.materials] + settings.sources)
    log(f"refine: {base_path}'s network with its {len(base.materials)} materials (replayed against its own "
        f"output) and {len(opened)} new, {steps} steps")
    refined = fit(replayed + opened, tuned_settings, init=start, progress=progress, log=log)
    worst = (0.0, None)
    for info, src in zip(refined.material_info, replayed):
        # fit() scored each replayed material against its source, BASE's own output: that is its drift.
        info["refine_drift"] = {"smape": info["metrics"]["smape"], "cmae": info["metrics"]["cmae"]}
        info["origin"] = base.material_info[base.index(src.name)].get("origin", "")
        worst = max(worst, (info["refine_drift"]["smape"], src.name), key=lambda t: t[0])
    refined.training.update(mode="refine", sparse_fit=dict(added.training), max_drift=max_drift,
                            base_training=dict(base.training) if isinstance(base.training, dict) else {})
    _record_sparse_starts(refined.material_info[len(base.materials):], added.material_info)
    if worst[0] > max_drift:
        raise RefineDriftError(f"--refine moved {worst[1]} by SMAPE {worst[0]:.4f} against {base_path} (above "
                               f"--max-drift {max_drift:g}); nothing written (fewer --finetune-steps, a lower "
                               f"--network-lr, or add without --refine)")
    return refined
