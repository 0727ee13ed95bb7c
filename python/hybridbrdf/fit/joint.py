"""Joint fitting of a collection of BRDFs (paper Sec. 3.3, docs/CONVENTIONS.md "Fitting"):
:func:`fit`, the orchestration of the steps below, each in a module of its own.

- :mod:`hybridbrdf.sources.names`: the material names of the sources.
- :mod:`hybridbrdf.fit.pool`: direction pairs and the sources' values on them, computed once.
- :mod:`hybridbrdf.fit.loss`: the loss, L(f_ref, f_t) + L(f_ref, f_a) per material, and its variants.
- :mod:`hybridbrdf.fit.schedule`: AdamW and the learning-rate decay.
- :mod:`hybridbrdf.fit.sparse_start`: where a sparse fit (``frozen=``) or a warm start (``init=``)
  starts each new material, and which of several starts it keeps.
- :mod:`hybridbrdf.fit.loop`: the optimiser steps, checkpoints and stop signals.
- :mod:`hybridbrdf.fit.record`: what the model file records of the fit.
- :mod:`hybridbrdf.evaluate.evaluation`: the per-material metrics stored with the model, and the tables.

Sparse fitting (paper Sec. 4.2): ``frozen=<HybridModel>`` keeps that model's network and fits
only (p, z) of the given materials, each started from the frozen model's best-fitting material
(FitSettings.sparse_init).

"""

from __future__ import annotations

import contextlib
import os
from typing import Callable, List, Optional, Sequence, Tuple

import torch

from hybridbrdf.fit import checkpoint as ckpt
from hybridbrdf.fit import distributed as dd
from hybridbrdf.fit import guard
from hybridbrdf import spec
from hybridbrdf.model import energy
from hybridbrdf.model.sizes import torch_bytes_per_pair
from hybridbrdf.model.file import HybridModel
from hybridbrdf.model.networks import build_model
from hybridbrdf.limits import check_count
from hybridbrdf.sources.base import BYTES_PER_PAIR as SOURCE_BYTES_PER_PAIR, BRDFSource
from hybridbrdf.files import check_writable, file_lock

from hybridbrdf.evaluate.evaluation import BYTES_PER_PAIR as METRIC_BYTES_PER_PAIR, evaluate
from hybridbrdf.fit.loop import FitState, run_steps
from hybridbrdf.fit.loss import batch_loss_function, loss_epsilons
from hybridbrdf.fit.pool import TrainingPool, pool_bytes_per_pair
from hybridbrdf.fit.record import training_record
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.fit.sparse_start import best_starts, keep_materials, start_from_nearest
from hybridbrdf.sources.names import material_names


def default_device() -> str:
    return "cuda" if torch.cuda.is_available() else "cpu"


def frozen_arch_settings(settings: FitSettings, frozen: HybridModel) -> FitSettings:
    """Set ``settings``' network fields (arch, width, depth, latent, activation, output layer) to
    those of the frozen model a sparse fit keeps; returns ``settings``. With material output
    layers each new material gets (and fits) a head of its own on the frozen hidden layers."""
    a = frozen.arch
    settings.arch, settings.width, settings.depth = a["kind"], a["width"], a["depth"]
    settings.latent, settings.activation = a["latent"], a["activation"]
    settings.output_layer = frozen.output_layer
    return settings


def fit(sources: Sequence[BRDFSource], settings: FitSettings, frozen: Optional[HybridModel] = None,
        init: Optional[HybridModel] = None, checkpoint: Optional[str] = None, checkpoint_every: int = 1000, resume: bool = False,
        progress: bool = True, log: Callable[[str], None] = print,
        stop_after: Optional[int] = None, compile_step: bool = False,
        ranks: Optional[dd.Ranks] = None,
        observe: Optional[Callable[[int, torch.nn.Module], None]] = None, force: bool = False) -> Optional[HybridModel]:
    """Fit ``sources`` jointly; returns the fitted :class:`HybridModel` (with per-material metrics).

    ``checkpoint``: file written every ``checkpoint_every`` steps (atomically);
    with ``resume`` an existing checkpoint is continued, reproducing the
    uninterrupted run exactly (same batches, optimiser state and RNG).
    ``stop_after``: write the checkpoint after that many steps and return None
    (splits a long fit into bounded jobs; requires ``checkpoint``).
    ``compile_step``: run the model and the loss of each step through ``torch.compile``
    (TorchInductor fuses the element-wise GGX, gate and loss arithmetic of the forward
    and backward passes; docs/FITTING.md, "Training speed"). The first step then takes
    the compilation time (recorded as ``compile_seconds``); the result differs from an
    eager fit only by float rounding, and a checkpoint resumes either way.

    Before any source is evaluated, ``checkpoint`` must be writable and, when resumed, pass
    every check of :mod:`hybridbrdf.fit.checkpoint` (checksum, structure, settings, step, finite
    values, shapes); otherwise :class:`~hybridbrdf.errors.InputFileError` naming the file.
    An existing ``checkpoint`` is another fit's until shown otherwise: without ``resume`` it is
    refused unless ``force`` (replace it). The fit holds the checkpoint's lock
    (:func:`hybridbrdf.files.file_lock`) from its first check to its end: a second fit on the same
    checkpoint is refused at once (:class:`~hybridbrdf.errors.OutputFileError` naming the file
    and the pid that holds it).

    ``init``: a warm start from a fitted model (FitSettings.init_from names its file): its
    network is loaded and trained further (at ``lr * network_lr``), each source starts from
    ``init``'s material of the same name, else (sparse_init "nearest") from the one whose
    (p, z) fits it best, as a sparse fit starts; the network settings are ``init``'s. A model
    fitted with ``frozen=`` and then continued with ``init=`` is ``hbrdf add``'s fine-tune.

    ``ranks``: this process's place in a data-parallel fit (:func:`hybridbrdf.fit.distributed.join`
    under torchrun): every rank trains on its share of the same global batch, gradients are
    averaged by DistributedDataParallel, and only rank 0 logs, writes checkpoints and returns
    the model (the others return None). SIGINT or SIGTERM stops the fit after the step in
    progress on every rank; with ``checkpoint`` rank 0 writes it first; then
    :class:`FitInterrupted` is raised. A rank that loses the others raises
    :class:`~hybridbrdf.fit.distributed.RankLostError`; neither writes a model.

    ``observe(step, module)``: called on rank 0 after every optimiser step (``step`` steps done)
    with the module being fitted, e.g. to snapshot it for a time-to-accuracy curve
    (bench/bench_fit_time.py); it must not change the module.
    """
    ranks = ranks or dd.Ranks()
    dd.check_batch_split(settings.batch, ranks)
    if not ranks.main:
        progress, log = False, (lambda msg: None)
    if checkpoint and ranks.main:
        check_writable(checkpoint, "checkpoint")
    with file_lock(checkpoint, wait=0) if checkpoint and ranks.main else contextlib.nullcontext():
        return _fit_holding_checkpoint(sources, settings, frozen, init, checkpoint, checkpoint_every, resume, force,
                                       progress, log, stop_after, compile_step, ranks, observe)


def _fit_holding_checkpoint(sources, settings, frozen, init, checkpoint, checkpoint_every, resume, force, progress,
                            log, stop_after, compile_step, ranks, observe) -> Optional[HybridModel]:
    """The body of :func:`fit`, run holding the lock of ``checkpoint`` (rank 0)."""
    names, starts, saved = _check_fit(sources, settings, frozen, init, checkpoint, resume, force, stop_after, ranks, log)
    iso = [bool(s.isotropic) for s in sources]
    module, own_rows = _build_module(settings, len(names), iso, starts, frozen if frozen is not None else init,
                                     init, names)
    module.to(settings.device)
    state = FitState.new(module, settings, frozen is not None)
    if saved is not None:
        state.resume(checkpoint, saved, names, settings)
        log(f"resuming from {checkpoint} at step {state.start}")
    # After the checkpoint: evaluating every source on the pool is the expensive part of the set-up.
    pool = TrainingPool(sources, settings.pool, settings.seed, log if progress else None,
                        settings.specular, settings.specular_alpha).repeat_materials(starts).to(settings.device)
    module.train()
    eps, eps_analytic = loss_epsilons(settings, pool)
    start_names = None
    if state.start == 0 and settings.sparse_init == "nearest":
        start_names = _place_starts(module, pool, eps, eps_analytic, settings, names, own_rows, frozen, init,
                                    starts, log)
    batch_loss = batch_loss_function(dd.wrap(module, ranks, settings.device),  # DistributedDataParallel under torchrun
                                     settings, eps, eps_analytic, compile_step)
    timing = run_steps(state, pool, settings, batch_loss, ranks, names, checkpoint=checkpoint,
                       checkpoint_every=checkpoint_every, stop_after=stop_after,
                       saved_step=state.start if saved is not None else None, progress=progress,
                       compile_step=compile_step, observe=observe)
    if timing is None or not ranks.main:
        return None  # stopped into the checkpoint, or a rank that is not rank 0
    if starts > 1:
        keep = best_starts(module, pool, starts, eps, eps_analytic, settings)
        module = keep_materials(module, keep, settings, iso)
        start_names = [start_names[r] for r in keep]
        log("kept the fits started from " + ", ".join(f"{n} <- {s}" for n, s in zip(names, start_names)))
    module.eval().cpu()
    training = training_record(settings, timing, state.start, state.earlier_seconds, state.timed_from,
                               settings.batch * len(sources) * starts, ranks.world, timing.torch_threads)
    return _model_with_metrics(module, names, sources, training, settings, frozen, start_names, log)


def _check_fit(sources: Sequence[BRDFSource], settings: FitSettings, frozen: Optional[HybridModel],
               init: Optional[HybridModel], checkpoint: Optional[str], resume: bool, force: bool,
               stop_after: Optional[int],
               ranks: dd.Ranks, log: Callable[[str], None]) -> Tuple[List[str], int, Optional[dict]]:
    """Whatever can fail before the expensive work, in this order: the arguments, the settings,
    the material names, the checkpoint (not another fit's unless ``resume`` or ``force``; when resumed, every check of
    :mod:`hybridbrdf.fit.checkpoint`). Seeds torch and takes the network settings of the model the
    fit starts from. Returns (names, starts per material, the checkpoint to resume or None)."""
    if stop_after is not None and not checkpoint:
        raise ValueError("stop_after needs a checkpoint file to stop into")
    settings.check()
    if not sources:
        raise ValueError("no BRDF sources to fit")
    names = material_names(sources)
    torch.manual_seed(settings.seed)
    if frozen is not None and init is not None:
        raise ValueError("a fit keeps a frozen network or starts from one (init), not both")
    start_model = frozen if frozen is not None else init  # whose network the fit starts from
    if start_model is not None:
        frozen_arch_settings(settings, start_model)
    # Sparse fitting from several starts: every new material k times over (rows m k + j).
    starts = (min(settings.sparse_starts, len(frozen.materials))
              if frozen is not None and settings.sparse_init == "nearest" else 1)
    if starts > 1 and checkpoint:
        raise ValueError("--sparse-starts above 1 fits without --checkpoint (a sparse fit is minutes long)")
    _check_counts(settings, len(sources) * starts)
    if checkpoint and ranks.main:
        ckpt.check_not_another_fits(checkpoint, resume, force)
    saved = None
    if resume and checkpoint and os.path.exists(checkpoint):
        # Before any expensive work: a checkpoint that cannot be resumed must not cost the pool.
        saved, checksummed = ckpt.load(checkpoint, settings)
        if not checksummed:
            log(f"{checkpoint}: checkpoint from an earlier hybridbrdf has no checksum; damage cannot be detected")
    return names, starts, saved


def _check_counts(settings: FitSettings, rows: int) -> None:
    """--pool, --batch and --eval-pairs bounded by the memory they take for ``rows`` material rows
    (hybridbrdf.limits; one line naming the flag), before the pool is drawn. A step's cost per pair
    and row: the network's float32 activations (HybridModel.bytes_per_pair's formula) three times
    over for the backward pass, 4608 bytes at 32x3 where a step of 32768 pairs x 8 materials
    measured 2145 (peak RSS over a fit of batch 64)."""
    activations = torch_bytes_per_pair(settings.width, settings.depth)
    check_count("--pool", settings.pool, pool_bytes_per_pair(rows))
    check_count("--batch", settings.batch, 3 * activations * rows)
    check_count("--eval-pairs", settings.eval_pairs, METRIC_BYTES_PER_PAIR + SOURCE_BYTES_PER_PAIR + activations)


def _build_module(settings: FitSettings, n_sources: int, iso: List[bool], starts: int,
                  start_model: Optional[HybridModel], init: Optional[HybridModel], names: List[str]):
    """The module a fit trains, ``starts`` rows per source, and the rows that start from
    ``init``'s material of their own name: f_c's bias at ``fc_init`` (gated architectures), or
    the network of ``start_model`` (a sparse fit's frozen one or a warm start's)."""
    module = build_model(settings.arch, n_sources * starts, settings.width, settings.depth, settings.latent,
                         settings.activation, [i for i in iso for _ in range(starts)],
                         output_layer=settings.network_output_layer())
    if spec.ARCHS[settings.arch]["combine"] == "gated" and start_model is None:
        module.set_output_bias(slice(0, 3), settings.fc_init)
    if start_model is not None:
        _load_network(module, start_model)
    own_rows: List[int] = []  # warm start: the sources that start from init's material of their name
    if init is not None:
        own_rows = [m for m, n in enumerate(names) if n in init.materials]
        with torch.no_grad():
            for m in own_rows:
                _set_material(module, m, init, init.materials.index(names[m]))
    return module, own_rows


def _load_network(module, start_model: HybridModel) -> None:
    """``start_model``'s network into ``module``; each material's output layer (if any) as the
    mean of ``start_model``'s (sparse_init "nearest" then replaces it with the nearest material's)."""
    state = {k: torch.from_numpy(v) for k, v in start_model.tensors.items() if not k.startswith("materials.")}
    module.load_state_dict(state, strict=False)
    if "materials.head_weight" in start_model.tensors:
        with torch.no_grad():
            module.head_weight[:] = torch.from_numpy(start_model.tensors["materials.head_weight"].mean(axis=0))
            module.head_bias[:] = torch.from_numpy(start_model.tensors["materials.head_bias"].mean(axis=0))


def _set_material(module, m: int, model: HybridModel, k: int) -> None:
    """Row ``m`` of ``module`` starts as ``model``'s material ``k``: (p, z) and its output layer."""
    row = {key[len("materials."):]: torch.from_numpy(v[k]) for key, v in model.tensors.items()
           if key.startswith("materials.")}
    if "kd" in row:
        module.set_analytic(m, row["kd"], row["eta"], row["alpha"])
    module.z[m] = row["z"]
    if "head_weight" in row:
        module.head_weight[m] = row["head_weight"]
        module.head_bias[m] = row["head_bias"]


def _place_starts(module, pool: TrainingPool, eps, eps_analytic, settings: FitSettings, names: List[str],
                  own_rows: List[int], frozen: Optional[HybridModel], init: Optional[HybridModel], starts: int,
                  log: Callable[[str], None]) -> Optional[List[str]]:
    """sparse_init "nearest" at step 0: a warm start's sources without a material of their name
    in ``init``, and every source of a sparse fit, start from their best-fitting material
    (:func:`start_from_nearest`). Returns the names of a sparse fit's starts (row order), else None."""
    if init is not None and len(own_rows) < len(names):
        rest = [m for m in range(len(names)) if m not in own_rows]
        chosen = start_from_nearest(module, init, pool, eps, eps_analytic, settings, rows=rest)
        log("warm start: " + ", ".join(f"{names[m]} <- {init.materials[chosen[m]]}" for m in rest))
    if frozen is None:
        return None
    chosen = start_from_nearest(module, frozen, pool, eps, eps_analytic, settings, starts=starts)
    start_names = [frozen.materials[k] for k in chosen]
    log("sparse fit starts from " + ", ".join(
        f"{n} <- {' | '.join(start_names[m * starts:(m + 1) * starts])}" for m, n in enumerate(names)))
    return start_names


def _model_with_metrics(module, names: List[str], sources: Sequence[BRDFSource], training: dict,
                        settings: FitSettings, frozen: Optional[HybridModel],
                        start_names: Optional[List[str]], log: Callable[[str], None] = print) -> HybridModel:
    """The fitted model with each material's metrics and, for a sparse fit, its start's; energy-bound
    tables (settings.energy_bound), and no material worse than its f_a (settings.analytic_guard)."""
    model = HybridModel.from_module(module, names, [s.origin for s in sources], training)
    if settings.energy_bound:
        model = energy.with_bound(model)
    metrics = evaluate(model, sources, n_pairs=settings.eval_pairs, names=names)
    for info, row in zip(model.material_info, metrics):
        info["metrics"] = {k: v for k, v in row.items() if k not in ("material", "origin")}
    if start_names is not None:
        # What the sparse fit started from and how far that start was off: the frozen network bounds
        # what (p, z) can reach, so a fit that ends near its start says the network, not the
        # optimiser, is the limit (docs/ADDING.md, "Sparse fitting").
        start_metrics = evaluate(frozen, sources, n_pairs=settings.eval_pairs, names=start_names)
        for info, name, row in zip(model.material_info, start_names, start_metrics):
            info["sparse_start"] = {"material": name, "smape": row["smape"], "cmae": row["cmae"]}
    if settings.analytic_guard and model.has_analytic:
        model = guard.apply(model, sources, names, settings, fit, log)
    return model
