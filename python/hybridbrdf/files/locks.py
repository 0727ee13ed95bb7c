"""Locks for updates in place: fcntl.flock on ".<name>.hbrdf-lock" beside the file, held from
before the read to after the rename, so that two updates of one file are serialised and none is lost."""

from __future__ import annotations

import contextlib
import fcntl
import os
import signal
import sys
import threading
import time

from hybridbrdf.errors import OutputFileError

from hybridbrdf.files.names import _TEMP_STEM_CHARS, _named


#: How long an update waits for another process's lock on the same file before refusing.
LOCK_WAIT_SECONDS = 60.0

_held_locks = {}  # lock file path -> [descriptor, depth]: this process's locks (re-entrant)
_held_guard = threading.Lock()


def _lock_name(path: str) -> str:
    """The lock file of ``path``: ".<name>.hbrdf-lock" in its folder."""
    folder = os.path.dirname(os.path.abspath(path))
    return os.path.join(folder, f".{os.path.basename(path)[:_TEMP_STEM_CHARS]}.hbrdf-lock")


def _lock_holder(lock: str) -> str:
    """The pid a lock file records (its holder writes it), for messages."""
    try:
        with open(lock, "rb") as fh:
            pid = fh.read(32).strip()
    except OSError:
        pid = b""
    return f"pid {pid.decode()}" if pid.isdigit() else "another process"


@contextlib.contextmanager
def _signals_deferred():
    """SIGINT and SIGTERM held back by the kernel for the block, delivered (and Python's handler
    run) when it ends. Around the few statements that take a lock and record it, or forget a lock
    and remove its file: a signal between the two would leave a lock file that no cleanup knows
    (a test saw `.out.bin.hbrdf-lock` left by a SIGTERM there). Never around a wait. Main thread
    only: Python runs signal handlers there, and other threads' masks are theirs."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _try_lock(path: str, lock: str, state: dict):
    """One attempt at ``lock``: its descriptor, flocked and recorded as held; "busy" when another
    process holds it; None when its holder removed it under us (try again at once)."""
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
    except OSError as exc:
        raise _named(path, exc) from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return "busy"
    try:
        same = os.path.samestat(os.fstat(fd), os.stat(lock))
    except FileNotFoundError:
        same = False
    if not same:
        os.close(fd)  # the holder released and removed it before our flock: take the new one
        return None
    with contextlib.suppress(OSError):  # the pid is for messages only (a full disk may refuse it)
        os.ftruncate(fd, 0)
        os.write(fd, b"%d\n" % os.getpid())
    with _held_guard:
        _held_locks[lock] = [fd, 1]
        state["counted"] = True
    return fd


def _acquire(path: str, lock: str, wait: float, state: dict) -> int:
    """flock ``lock`` exclusively, record it as held and return its descriptor, waiting up to
    ``wait`` seconds; ``state["counted"]`` is set with the record (:func:`file_lock`).

    The lock file is removed by its holder on release; a waiter that then gets the lock of the
    removed file sees that the name no longer leads to it and tries again, so exactly one
    process holds the lock of the file the name leads to."""
    start = time.monotonic()
    deadline = start + wait
    told = False
    while True:
        with _signals_deferred():
            fd = _try_lock(path, lock, state)
        if fd is None:
            continue
        if fd != "busy":
            return fd
        if time.monotonic() >= deadline:
            raise OutputFileError(path, f"is being written by {_lock_holder(lock)} (it holds {lock}); "
                                        "try again when that process ends") from None
        if not told and time.monotonic() >= start + 1.0:  # say why a command seems to hang
            told = True
            print(f"waiting for {path}: {_lock_holder(lock)} is writing it", file=sys.stderr)
        time.sleep(0.05)


def _release_all_locks() -> None:
    """Release (and remove) every lock this process holds: it is about to end by SIGTERM."""
    with _held_guard:
        held = list(_held_locks.items())
        _held_locks.clear()
    for lock, entry in held:
        with contextlib.suppress(OSError):
            os.unlink(lock)
        os.close(entry[0])
        entry[0] = None  # the blocks that took it release nothing more


class file_lock:
    """Hold the advisory lock of the file ``path`` for the block (``fcntl.flock`` on
    ".<name>.hbrdf-lock" beside it, removed on release; the kernel drops it when the process
    dies, even by SIGKILL). A read-modify-write of ``path`` inside the block cannot lose another
    process's update: every hbrdf update in place and every :func:`atomic_write_bytes` rename
    takes it. Waits up to ``wait`` seconds (default :data:`LOCK_WAIT_SECONDS`) for another
    process's lock (one line on stderr while it waits), then raises
    :class:`~hybridbrdf.errors.OutputFileError` naming ``path`` and the holder's pid.
    Re-entrant within a process.

    A class, not a generator context manager: with ``contextlib.contextmanager`` a Ctrl-C that
    Python raised in contextlib's ``__enter__`` after the generator had taken the lock and
    yielded (the check for signals after its ``next(gen)`` call) left the ``with`` statement
    unentered, so no ``__exit__`` ran and the suspended generator kept the lock file until the
    interpreter's shutdown, which did not remove it (CI, 2026-11-29: `.out.bin.hbrdf-lock` left
    by a SIGINT, test_fit_hostile). Here every exception raised while entering passes through
    :meth:`__enter__`'s own handler, which gives back what it took."""

    def __init__(self, path, wait: float = None):
        self.path = os.fspath(path)
        self.lock = _lock_name(self.path)
        self.wait = LOCK_WAIT_SECONDS if wait is None else wait
        # ``counted``: this block's share of the lock is recorded, set in the same signal-deferred
        # statements that record it, so that whatever stops the block releases exactly that share.
        self.state = {"counted": False}

    def __enter__(self) -> None:
        try:
            with _signals_deferred():
                with _held_guard:
                    held = _held_locks.get(self.lock)
                    if held is not None:
                        held[1] += 1
                        self.state["counted"] = True
            if not self.state["counted"]:
                _acquire(self.path, self.lock, self.wait, self.state)
        except BaseException:
            self.__exit__(None, None, None)
            raise

    def __exit__(self, *exc) -> bool:
        if self.state["counted"]:
            self.state["counted"] = False
            _release(self.lock)
        return False


def _release(lock: str) -> None:
    """This block's share of ``lock`` given back; the last share removes the lock file (while
    still holding it: see :func:`_acquire`) and closes it. Nothing when :func:`_release_all_locks`
    already released it (SIGTERM)."""
    with _signals_deferred():
        with _held_guard:
            held = _held_locks.get(lock)
            if held is None:
                return
            held[1] -= 1
            last = held[1] == 0 and held[0] is not None
            if last:
                _held_locks.pop(lock, None)
        if last:
            with contextlib.suppress(OSError):
                os.unlink(lock)
            os.close(held[0])
