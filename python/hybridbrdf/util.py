"""Small shared helpers."""

from __future__ import annotations

import contextlib
import os
import pathlib
import re
import secrets
import signal
import threading

from hybridbrdf.errors import InputFileError


def package_data_dir(name: str, marker: str) -> pathlib.Path:
    """The data folder ``name`` (codegen/, glsl/): installed inside the package in a wheel,
    at the top of the repository in the source tree; ``marker`` is a file it must hold."""
    here = pathlib.Path(__file__).resolve().parent
    for candidate in (here / name, here.parents[1] / name):
        if (candidate / marker).is_file():
            return candidate
    raise FileNotFoundError(f"{name}/{marker} not found next to the package or in the source tree")


# ---- atomic writes ---------------------------------------------------------------
#
# A file is written to ".<name>.tmp-<pid>-<random>" in the destination's folder, then renamed
# over the destination: a reader sees the old file or the new one, never half of one. An
# exception or Ctrl-C (KeyboardInterrupt) removes the temporary; SIGTERM does too (it is turned
# into an exception for the length of the write, then delivered again). SIGKILL and a power cut
# cannot be cleaned up by the dying process, so the temporary carries its writer's pid and the
# next write to the same destination removes those whose writer is no longer alive.

#: The longest part of the destination's name a temporary repeats (NAME_MAX is 255 bytes).
_TEMP_STEM_CHARS = 100


def _temp_prefix(path: str) -> str:
    """The name every temporary of ``path`` starts with, before the writer's pid."""
    return f".{os.path.basename(path)[:_TEMP_STEM_CHARS]}.tmp-"


def _pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists on this machine (one we may not signal counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except (OverflowError, ValueError):  # not a pid this system can have
        return False
    return True


def remove_stale_temporaries(path) -> list:
    """Remove the temporaries of earlier atomic writes to ``path`` whose writer is no longer
    alive (killed with SIGKILL, or the machine went down); returns their paths.

    Only this machine's process table is consulted: a folder shared with other machines
    could hold a live writer's temporary under a pid that is free here, and that writer's
    rename would then fail (its destination stays as it was)."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    pattern = re.compile(re.escape(_temp_prefix(path)) + r"(\d+)-[A-Za-z0-9_]+\Z")
    removed = []
    try:
        entries = os.listdir(folder)
    except OSError:
        return removed
    for entry in entries:
        m = pattern.match(entry)
        if not m or int(m.group(1)) == os.getpid() or _pid_alive(int(m.group(1))):
            continue  # our own (another thread's write) or a live writer's
        stale = os.path.join(folder, entry)
        with contextlib.suppress(FileNotFoundError):  # a concurrent cleaner got there first
            os.unlink(stale)
            removed.append(stale)
    return removed


class _Terminated(BaseException):
    """SIGTERM arrived during an atomic write (BaseException: no ``except Exception`` keeps it)."""


@contextlib.contextmanager
def _sigterm_cleans_up():
    """Within the block, a SIGTERM raises :class:`_Terminated` so that ``except``/``finally``
    clauses run (the temporary is removed); on leaving, the signal is delivered again so the
    process still ends as SIGTERM ends it. Only where SIGTERM would kill outright (the default
    handler, main thread: Python runs signal handlers there); a program's own handler is left
    alone."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL):
        yield
        return
    received = []

    def handler(signum, frame):
        if not received:  # a second SIGTERM must not interrupt the cleanup of the first
            received.append(signum)
            raise _Terminated()

    try:
        signal.signal(signal.SIGTERM, handler)
        yield
    except _Terminated:
        pass
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if received:
        signal.raise_signal(signal.SIGTERM)  # the default action: the process ends here
        raise KeyboardInterrupt("SIGTERM")  # reached only where the signal is blocked


def _temporary_name(path: str, folder: str) -> str:
    """A fresh temporary name for ``path``: its prefix, this process's pid and 64 random bits.

    The name is chosen before the file exists so that a caller can hold it in its cleanup
    before creating the file: a signal between the file's creation and the caller learning
    its name would otherwise leave it behind (mkstemp returns the name only after creating)."""
    return os.path.join(folder, f"{_temp_prefix(path)}{os.getpid()}-{secrets.token_hex(8)}")


def _create_temporary(tmp: str) -> int:
    """Create ``tmp`` exclusively for writing, with the permissions open() would give (0666
    less the umask); returns its descriptor."""
    return os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)


def _fsync_folder(folder: str) -> None:
    """Make a rename in ``folder`` durable (best effort: not every file system allows it)."""
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder
    and a rename, so that a reader never sees a half-written file and a
    failure leaves any previous file intact. An exception, Ctrl-C or SIGTERM
    during the write removes the temporary; temporaries left by writers that
    were killed outright (SIGKILL) are removed by the next write to ``path``."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    remove_stale_temporaries(path)
    with _sigterm_cleans_up():
        tmp = _temporary_name(path, folder)  # known to the cleanup before the file exists
        try:
            fd = _create_temporary(tmp)
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
            tmp = None
        finally:
            if tmp is not None:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(tmp)
    _fsync_folder(folder)


def check_writable(path, what: str = "output") -> None:
    """Fail now, not after hours of work, if :func:`atomic_write_bytes` could not write ``path``.

    Raises :class:`~hybridbrdf.errors.InputFileError` (one line naming ``path``) when ``path``
    is a folder, a folder on the way is a file or cannot be created, or the folder does not let
    this process create files (permissions, read-only file system). Missing folders are
    created, as the write would create them; a probe temporary is created and removed."""
    path = os.fspath(path)
    if not path:
        raise InputFileError(path or "''", f"the {what} path is empty")
    if os.path.isdir(path):
        raise InputFileError(path, f"is a folder; the {what} must be a file name")
    folder = os.path.dirname(os.path.abspath(path))
    existing = folder
    while not os.path.lexists(existing) and os.path.dirname(existing) != existing:
        existing = os.path.dirname(existing)
    if not os.path.isdir(existing):
        raise InputFileError(path, f"cannot create its folder: {existing} is a file, not a folder")
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise InputFileError(path, f"cannot create its folder {exc.filename or folder}: "
                                   f"{exc.strerror or exc}") from None
    try:
        tmp = _temporary_name(path, folder)
        os.close(_create_temporary(tmp))
        os.unlink(tmp)
    except OSError as exc:
        raise InputFileError(path, f"cannot write the {what} into {folder}: {exc.strerror or exc}") from None
