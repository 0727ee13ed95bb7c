"""Data-parallel fitting on torch.distributed (docs/FITTING.md, "Fitting on several processes").

``hbrdf fit`` started by ``torchrun`` (which sets RANK, WORLD_SIZE, MASTER_ADDR, ...) joins
the process group torchrun describes: gloo on CPU, NCCL on CUDA (each rank on the GPU of
its LOCAL_RANK). Every rank holds the whole training pool and the same generator of pool
indices, so all ranks draw the same global batch of ``--batch`` pairs and each trains on
its own contiguous share of it; PyTorch's DistributedDataParallel averages the gradients,
which is then the gradient of the whole batch, and the optimiser steps agree on every rank.
A fit on k ranks is therefore the 1-rank fit with the same global batch and seed up to the
order of float additions, and a checkpoint (global step, generator state, optimiser) resumes
on any number of ranks that divides the batch. Rank 0 alone logs, writes checkpoints and the
model file.
"""

from __future__ import annotations

import contextlib
import datetime
import os
import select
import signal
import socket
import sys
import threading
import time
from dataclasses import dataclass
from typing import Callable, Optional

import torch
import torch.distributed as dist
from torch.nn.parallel import DistributedDataParallel

#: How long a rank waits in a collective for the others before it gives up (a rank that died
#: mid-step is usually noticed at once, when its sockets close; this bounds the other cases).
COLLECTIVE_TIMEOUT = datetime.timedelta(minutes=5)

#: How long a rank asked to stop (torchrun's SIGTERM, Ctrl-C) waits in a step's collectives before it
#: takes the other ranks for lost and ends itself (:class:`StopRequest`). torchrun follows its
#: SIGTERM with SIGKILL after 30 s; this leaves the rank time to say why it ends. Why it exists: a
#: rank whose peer died can wait in DistributedDataParallel's reducer for gloo work that neither
#: completes nor fails (seen 4 times in about 200 runs under load: rank 0 in
#: ``Reducer::finalize_backward`` until torchrun killed it), where a Python signal handler never runs.
STOP_GRACE_SECONDS = 20.0

#: The start of the line a rank writes when it ends itself (:meth:`StopRequest` on a stuck step);
#: ``hbrdf fit`` sets its own, "hbrdf fit: error: ", as it prints every other error.
error_prefix = "error: "


class RankLostError(RuntimeError):
    """Another rank stopped answering (it died or was killed): the fit cannot go on."""


@dataclass
class Ranks:
    """This process's place in a data-parallel fit: rank 0 of 1 when not under torchrun."""

    rank: int = 0
    world: int = 1
    local_rank: int = 0

    @property
    def main(self) -> bool:
        """Rank 0: the one that logs and writes files."""
        return self.rank == 0

    @property
    def distributed(self) -> bool:
        return self.world > 1


def launched_world_size() -> int:
    """WORLD_SIZE as torchrun sets it (1 without torchrun); ValueError for a malformed value."""
    raw = os.environ.get("WORLD_SIZE", "1")
    try:
        world = int(raw)
    except ValueError:
        raise ValueError(f"WORLD_SIZE={raw!r} is not a number of ranks") from None
    if world < 1:
        raise ValueError(f"WORLD_SIZE={world} is not a number of ranks")
    return world


def join(device: str) -> Ranks:
    """Join torchrun's process group when WORLD_SIZE > 1 (gloo for a CPU ``device``, NCCL for
    CUDA) and return this process's :class:`Ranks`; a plain ``Ranks()`` otherwise. With CUDA
    each rank uses the device of its LOCAL_RANK."""
    world = launched_world_size()
    if world == 1:
        return Ranks()
    local = int(os.environ.get("LOCAL_RANK", "0"))
    if not dist.is_initialized():
        cuda = device.startswith("cuda")
        if cuda:
            torch.cuda.set_device(local)
        dist.init_process_group("nccl" if cuda else "gloo", timeout=COLLECTIVE_TIMEOUT)
    return Ranks(dist.get_rank(), dist.get_world_size(), local)


def leave(ranks: Ranks) -> None:
    """Leave the process group (a no-op for a single process)."""
    if ranks.distributed and dist.is_initialized():
        dist.destroy_process_group()


def end_process(code: int) -> None:
    """End a rank's process once its work is done and the process group is left: flush the
    standard streams, then ``os._exit`` without the interpreter's teardown, where gloo's worker
    threads can still hold references and abort the process (SIGABRT, "terminate called
    without an active exception"; seen in a test, and pytorch/pytorch#179291 describes it)."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def rank_device(device: str, ranks: Ranks) -> str:
    """``cuda`` becomes ``cuda:<local rank>`` under torchrun; other devices are kept."""
    return f"cuda:{ranks.local_rank}" if ranks.distributed and device == "cuda" else device


def check_batch_split(batch: int, ranks: Ranks) -> None:
    """Every rank trains on batch / world pairs of each global batch: it must divide."""
    if batch % ranks.world:
        raise ValueError(f"--batch {batch} does not split over {ranks.world} ranks "
                         f"(a multiple of {ranks.world} keeps every rank's share equal)")


def share(idx: torch.Tensor, ranks: Ranks) -> torch.Tensor:
    """This rank's contiguous share of a global batch of pool indices."""
    n = idx.shape[0] // ranks.world
    return idx[ranks.rank * n:(ranks.rank + 1) * n]


def wrap(module: torch.nn.Module, ranks: Ranks, device: str) -> torch.nn.Module:
    """``module`` under DistributedDataParallel (gradients averaged over the ranks in
    backward), or ``module`` itself for a single process."""
    if not ranks.distributed:
        return module
    ids = [torch.device(device).index] if device.startswith("cuda") else None
    return DistributedDataParallel(module, device_ids=ids)


def any_rank(flag: bool, ranks: Ranks, device: str) -> bool:
    """True on every rank when ``flag`` is true on any (so that all stop at the same step)."""
    if not ranks.distributed:
        return flag
    t = torch.tensor([1.0 if flag else 0.0], device=device)
    dist.all_reduce(t, op=dist.ReduceOp.MAX)
    return bool(t.item() > 0)


class StopRequest:
    """SIGINT and SIGTERM (torchrun passes Ctrl-C on as SIGTERM) ask the fit to stop after the
    step in progress instead of killing it mid-way, so that a checkpoint of a finished step can
    be written. A second signal stops at once. Installed only in the main thread.

    With ``grace`` (seconds; data-parallel fits: :data:`STOP_GRACE_SECONDS`) a watchdog thread
    bounds the wait: a signal that arrives while the main thread is in :meth:`collective` and
    still in it ``grace`` seconds later (a lost peer whose work never completes) ends the process
    with ``on_stuck()``'s one line, exit status 1. The thread learns of the signal from the
    interpreter's wakeup fd, written by the C-level handler at once: the Python handler runs only
    when the main thread returns to the interpreter, which a stuck collective never does."""

    def __init__(self, grace: Optional[float] = None, on_stuck: Optional[Callable[[], str]] = None) -> None:
        self.requested: Optional[int] = None
        self.grace, self.on_stuck = grace, on_stuck
        self._previous = {}
        self._signalled_at: Optional[float] = None
        self._collective_since: Optional[float] = None
        self._watch: Optional[tuple] = None  # (thread, read socket, write socket, previous wakeup fd, done)

    def install(self) -> "StopRequest":
        """Take over SIGINT and SIGTERM until :meth:`restore` (main thread only)."""
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self._handle)
            if self.grace is not None:
                self._start_watchdog()
        return self

    def restore(self) -> None:
        """Give the signals back to the handlers they had before (and stop the watchdog)."""
        if self._watch is not None:
            thread, r, w, previous, done = self._watch
            signal.set_wakeup_fd(previous)
            done.set()
            thread.join()
            r.close()
            w.close()
            self._watch = None
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()

    @contextlib.contextmanager
    def collective(self):
        """The part of a step that waits for the other ranks: what the watchdog bounds."""
        self._collective_since = time.monotonic()
        try:
            yield
        finally:
            self._collective_since = None

    def _start_watchdog(self) -> None:
        r, w = socket.socketpair()
        r.setblocking(False)
        w.setblocking(False)
        previous = signal.set_wakeup_fd(w.fileno(), warn_on_full_buffer=False)
        done = threading.Event()
        thread = threading.Thread(target=self._watchdog, args=(r, done), name="hbrdf-stop-watchdog", daemon=True)
        self._watch = (thread, r, w, previous, done)
        thread.start()

    def _watchdog(self, r: socket.socket, done: threading.Event) -> None:
        stops = {signal.SIGINT, signal.SIGTERM}
        while not done.is_set():
            if select.select([r], [], [], 0.1)[0]:
                try:
                    if stops & set(r.recv(64)) and self._signalled_at is None:
                        self._signalled_at = time.monotonic()
                except BlockingIOError:
                    pass
            since = self._collective_since
            if self._signalled_at is None or since is None:
                continue
            if time.monotonic() - max(since, self._signalled_at) > self.grace:
                message = self.on_stuck() if self.on_stuck is not None else "no step ended after the stop request"
                print(f"{error_prefix}{message}", file=sys.stderr)
                end_process(1)

    def _handle(self, signum, frame) -> None:
        if self.requested is not None:
            raise KeyboardInterrupt
        self.requested = signum

    __enter__ = install

    def __exit__(self, *exc) -> None:
        self.restore()


__all__ = ["COLLECTIVE_TIMEOUT", "STOP_GRACE_SECONDS", "RankLostError", "Ranks", "StopRequest", "error_prefix", "any_rank", "check_batch_split", "end_process", "join",
           "launched_world_size", "leave", "rank_device", "share", "wrap"]
