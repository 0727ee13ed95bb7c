"""The optimiser steps of a fit: what it trains (:class:`FitState`, restored from a checkpoint
when it resumes) and the loop that advances it (:func:`run_steps`).

Each step draws one global batch of pool indices from the fit's own generator (every rank
draws the same one and trains on its share; :mod:`hybridbrdf.fit.distributed`), takes one AdamW
step with the gradient norm clipped, and steps the schedule. Checkpoints are written by rank 0
every ``checkpoint_every`` steps, at ``stop_after`` and when SIGINT or SIGTERM asks the fit to
stop after the step in progress.
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass
from typing import Any, Callable, List, Optional

import torch
from tqdm import tqdm

from hybridbrdf.fit import checkpoint as ckpt
from hybridbrdf.fit import distributed as dd
from hybridbrdf.fit.schedule import optimizer_and_schedule
from hybridbrdf.fit.pool import TrainingPool
from hybridbrdf.fit.settings import FitSettings


class FitInterrupted(KeyboardInterrupt):
    """A fit stopped by SIGINT or SIGTERM after a finished step: ``step`` steps done, written to
    ``checkpoint`` when there is one. ``str()`` says what to do next, in one line."""

    def __init__(self, step: int, checkpoint: Optional[str]):
        self.step, self.checkpoint = step, checkpoint
        super().__init__(f"interrupted after step {step}; " + (
            f"checkpoint {checkpoint} written: continue with the same command and --resume" if checkpoint
            else "nothing saved (no --checkpoint)"))


@dataclass
class FitState:
    """What the steps advance: the module, its optimiser and schedule, the batch generator, and
    where the fit (re)starts. ``earlier_seconds``: training time of the steps from
    ``timed_from`` to ``start`` (from the checkpoint); a checkpoint that predates that record
    kept no time, and the clock then starts at the resume."""

    module: torch.nn.Module
    opt: torch.optim.Optimizer
    sched: Any
    gen: torch.Generator
    start: int = 0
    earlier_seconds: float = 0.0
    timed_from: int = 0

    @classmethod
    def new(cls, module: torch.nn.Module, settings: FitSettings, frozen: bool) -> "FitState":
        """Step 0 of a fit of ``module`` (already on its device); ``frozen``: a sparse fit."""
        opt, sched = optimizer_and_schedule(module, settings, frozen)
        return cls(module, opt, sched, torch.Generator(device="cpu").manual_seed(settings.seed))

    def resume(self, checkpoint: str, saved: dict, names: List[str], settings: FitSettings) -> None:
        """Continue from a checkpoint :func:`hybridbrdf.fit.checkpoint.load` read: module, optimiser,
        schedule and RNG states (checked against this fit first), the step and the clock."""
        ckpt.restore(checkpoint, saved, names, self.module, self.opt, self.sched)
        self.start = saved["step"]
        if "train_seconds" in saved:
            self.earlier_seconds, self.timed_from = float(saved["train_seconds"]), saved["timed_from_step"]
        else:
            self.timed_from = self.start
        if "batch_rng" in saved:
            self.gen.set_state(saved["batch_rng"])
        else:  # an older checkpoint: replay its batches (start <= steps: checked)
            for _ in range(self.start):
                draw_batch(self.gen, settings)


@dataclass
class Timing:
    """The clock of one run of :func:`run_steps` (seconds): all of it, and the first step's share
    when it compiled the graphs (None for an eager fit); and the torch threads it ran on."""

    elapsed: float
    compile_seconds: Optional[float]
    torch_threads: int


def draw_batch(gen: torch.Generator, settings: FitSettings) -> torch.Tensor:
    """One global batch of pool indices; the same on every rank."""
    return torch.randint(0, settings.pool, (settings.batch,), generator=gen)


def _rank_lost(exc: RuntimeError, ranks: dd.Ranks, step: int, checkpoint: Optional[str],
               saved_step: Optional[int]) -> dd.RankLostError:
    """The one-line error of a rank whose collective failed: the gist of the backend's message."""
    # gloo's "[file.cc:537] Read error [addr]:port: Connection reset by peer. This is ..." -> its gist
    reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return _lost_line(re.sub(r"^\[[^\]]*\]\s*", "", reason).split(". ")[0], ranks, step, checkpoint, saved_step)


def _lost_line(reason: str, ranks: dd.Ranks, step: int, checkpoint: Optional[str],
               saved_step: Optional[int]) -> dd.RankLostError:
    """The lost-rank error for ``reason``: the step, and what is kept on disk."""
    kept = f"checkpoint {checkpoint} (step {saved_step})" if saved_step is not None else "no checkpoint"
    return dd.RankLostError(f"rank {ranks.rank} of {ranks.world}: lost the other ranks at step {step} "
                            f"({reason}); kept: {kept}, no model written")


def _progress_bar(settings: FitSettings, start: int):
    return tqdm(total=settings.steps, initial=start, desc=f"fit {settings.arch} {settings.width}x{settings.depth}",
                unit="step", dynamic_ncols=True, mininterval=0.5)


def run_steps(state: FitState, pool: TrainingPool, settings: FitSettings,
              batch_loss: Callable[[torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor],
              ranks: dd.Ranks, names: List[str], *, checkpoint: Optional[str] = None, checkpoint_every: int = 1000,
              stop_after: Optional[int] = None, saved_step: Optional[int] = None, progress: bool = False,
              compile_step: bool = False,
              observe: Optional[Callable[[int, torch.nn.Module], None]] = None) -> Optional[Timing]:
    """Steps ``state.start`` .. ``settings.steps`` - 1 of the fit, each on one batch of ``pool``;
    returns their :class:`Timing`, or None when the fit stopped into its checkpoint at
    ``stop_after``. ``saved_step``: the step of the newest checkpoint on disk, named when a rank
    is lost. Raises :class:`FitInterrupted` when a signal asked the fit to stop,
    :class:`~hybridbrdf.fit.distributed.RankLostError` when a rank stopped answering and
    FloatingPointError when the loss is not finite. ``observe(step, module)``: called on rank 0
    after every optimiser step."""
    # One piece: the order of the generator draws, the collectives every rank must reach together
    # and the checkpoint a signal asks for are what make a fit reproducible and resumable, and
    # they are easiest to check in one loop.
    module, opt, sched = state.module, state.opt, state.sched
    bar = _progress_bar(settings, state.start) if progress else None
    compile_seconds = None
    threads = torch.get_num_threads()
    t0 = time.perf_counter()
    step = state.start
    # Asked to stop, a rank whose step cannot end (a lost peer's work that never completes) ends
    # itself with the lost-rank line after the grace, before the launcher's SIGKILL.
    stop = dd.StopRequest(dd.STOP_GRACE_SECONDS if ranks.distributed else None, lambda: str(_lost_line(
        f"no step ended within {dd.STOP_GRACE_SECONDS:g} s of the stop request", ranks, step, checkpoint,
        saved_step))).install()
    try:
        for step in range(state.start, settings.steps):
            # Every rank draws the same global batch and trains on its share of it.
            idx = dd.share(draw_batch(state.gen, settings), ranks).to(settings.device)
            wi, wo, ref = pool.wi[idx], pool.wo[idx], pool.ref[:, idx]
            try:
                with stop.collective():
                    loss = batch_loss(wi, wo, ref)
                    if not torch.isfinite(loss):
                        raise FloatingPointError(
                            f"loss became {loss.item()} at step {step}; lower --lr or check the sources")
                    opt.zero_grad(set_to_none=True)
                    loss.backward()  # under DistributedDataParallel: gradients averaged over the ranks
                    stopping_now = dd.any_rank(stop.requested is not None, ranks, settings.device)
            except RuntimeError as exc:
                if not ranks.distributed:
                    raise
                raise _rank_lost(exc, ranks, step, checkpoint, saved_step) from None
            torch.nn.utils.clip_grad_norm_([p for p in module.parameters() if p.requires_grad], settings.clip)
            opt.step()
            sched.step()
            if observe is not None and ranks.main:
                observe(step + 1, module)
            if compile_step and compile_seconds is None:
                # The first compiled step builds the graphs; the throughput counts the steps after it.
                compile_seconds = time.perf_counter() - t0
            if bar is not None:
                bar.update(1)
                if step % 20 == 0:
                    bar.set_postfix(loss=f"{loss.item() / len(names):.4g}")  # .item(): no autograd warning
            stopping = stop_after is not None and step + 1 == stop_after and step + 1 < settings.steps
            if checkpoint and (stopping or stopping_now or
                               ((step + 1) % checkpoint_every == 0 and step + 1 < settings.steps)):
                # Once per step even where stop_after falls on a regular checkpoint.
                if ranks.main:
                    ckpt.save_fit_state(checkpoint, module, opt, sched, step + 1, settings, names,
                                        state.earlier_seconds + time.perf_counter() - t0, state.timed_from, state.gen)
                saved_step = step + 1
            if stopping_now:
                raise FitInterrupted(step + 1, checkpoint)
            if stopping:
                return None
    finally:
        stop.restore()
        if bar is not None:
            bar.close()
    return Timing(time.perf_counter() - t0, compile_seconds, threads)
