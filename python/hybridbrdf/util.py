"""Small shared helpers."""

from __future__ import annotations

import contextlib
import fcntl
import os
import pathlib
import re
import secrets
import shutil
import signal
import stat
import sys
import tempfile
import threading
import time

from hybridbrdf.errors import InputFileError, OutputFileError


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
# The temporary gets the replaced file's permissions (a chmod 600 model stays 600); a new file
# gets what open() gives (0666 less the umask). Every step (create, write, fsync, close, rename)
# is checked, and an OSError names the destination: "out/m.safetensors: No space left on device".
#
# Updates in place (read a file, change it, write it back) hold the destination's lock
# (:func:`file_lock`: fcntl.flock on ".<name>.hbrdf-lock" beside it) from before the read to
# after the rename, so two of them at once are serialised (the second reads the first's
# result) and no update is lost; every atomic write takes the same lock for its rename.

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
        _release_all_locks()  # as the kernel would, but removing the lock files too
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


def _named(path: str, exc: OSError) -> OutputFileError:
    """``exc`` as an :class:`OutputFileError` naming ``path`` (the file the user asked for, not
    the temporary); another file it names (a folder on the way) is named too."""
    if isinstance(exc, OutputFileError):
        return exc
    problem = exc.strerror or str(exc) or type(exc).__name__
    other = exc.filename if isinstance(exc.filename, str) else None
    ours = (os.path.basename(other).startswith(_temp_prefix(path)) or other.endswith(".hbrdf-lock")
            or os.path.abspath(other) == os.path.abspath(path)) if other else True
    return OutputFileError(path, problem if ours else f"{problem} ({other})", exc.errno or 0)


def _write_all(fd: int, data) -> None:
    """Write all of ``data`` to ``fd``: os.write may write less than asked (a signal, a nearly
    full disk); the rest is written on, and an error (ENOSPC, EIO, EDQUOT) raises."""
    view = memoryview(data).cast("B")
    while view:
        written = os.write(fd, view)
        if written <= 0:  # a regular file never does this; refuse rather than spin
            raise OSError(0, "the file system accepted no bytes")
        view = view[written:]


def _kept_mode(path: str):
    """The permission bits of the file ``path`` replaces, or None when there is none (the new
    file then gets the umask default)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return stat.S_IMODE(st.st_mode) if stat.S_ISREG(st.st_mode) else None


def atomic_write_bytes(path, data: bytes, verify=None, wait: float = None) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder
    and a rename, so that a reader never sees a half-written file and a
    failure leaves any previous file intact. An exception, Ctrl-C or SIGTERM
    during the write removes the temporary; temporaries left by writers that
    were killed outright (SIGKILL) are removed by the next write to ``path``.

    ``verify(tmp)``: called with the temporary's path once it is complete on disk and before
    the rename (e.g. read it back with the loaders' own checks); an exception from it leaves
    ``path`` as it was. The replaced file's permission bits are kept. The rename is made under
    :func:`file_lock` (``wait``: how long to wait for it, default :data:`LOCK_WAIT_SECONDS`).
    Every OSError is raised as :class:`~hybridbrdf.errors.OutputFileError` naming ``path``
    ("out/m.safetensors: No space left on device")."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise _named(path, exc) from None
    remove_stale_temporaries(path)
    with _sigterm_cleans_up():
        tmp = _temporary_name(path, folder)  # known to the cleanup before the file exists
        try:
            fd = _create_temporary(tmp)
            try:
                mode = _kept_mode(path)
                if mode is not None:  # before any byte is written: a 0600 file's bytes never sit in a 0644 one
                    os.fchmod(fd, mode)
                _write_all(fd, data)
                os.fsync(fd)  # a full disk can show only here (delayed allocation) ...
            finally:
                os.close(fd)  # ... or here (NFS reports write errors on close); both raise
            if verify is not None:
                verify(tmp)
            with file_lock(path, wait):
                os.replace(tmp, path)
            tmp = None
        except OSError as exc:
            raise _named(path, exc) from None
        finally:
            if tmp is not None:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(tmp)
    _fsync_folder(folder)


@contextlib.contextmanager
def atomic_folder(folder):
    """A temporary folder beside ``folder`` for the block to fill; when the block ends normally
    it replaces ``folder`` (the old one renamed aside, then removed), so that a reader sees the
    old folder or the complete new one. An exception, Ctrl-C or SIGTERM in the block removes the
    temporary; temporaries of writers killed outright (their pid, in the name, no longer alive)
    are removed first. The replacement is made under :func:`file_lock` of ``folder``. Every
    OSError is raised as :class:`~hybridbrdf.errors.OutputFileError` naming ``folder``."""
    folder = os.path.abspath(os.fspath(folder))
    parent = os.path.dirname(folder)
    try:
        os.makedirs(parent, exist_ok=True)
    except OSError as exc:
        raise _named(folder, exc) from None
    pattern = re.compile(re.escape(_temp_prefix(folder)) + r"(\d+)-[A-Za-z0-9_]+(\.old)?\Z")
    with contextlib.suppress(OSError):
        for entry in os.listdir(parent):
            m = pattern.match(entry)
            if m and int(m.group(1)) != os.getpid() and not _pid_alive(int(m.group(1))):
                shutil.rmtree(os.path.join(parent, entry), ignore_errors=True)
    with _sigterm_cleans_up():
        tmp = _temporary_name(folder, parent)  # known to the cleanup before the folder exists
        old = tmp + ".old"
        try:
            os.mkdir(tmp)
            yield tmp
            with file_lock(folder):
                if os.path.lexists(folder):
                    os.rename(folder, old)
                os.rename(tmp, folder)
        except OutputFileError as exc:  # a file in the temporary: name the folder, and the file in it
            inner = os.path.relpath(exc.path, tmp) if exc.path.startswith(tmp + os.sep) else exc.path
            raise OutputFileError(folder, f"{exc.problem} (writing {inner})", exc.errno or 0) from None
        except OSError as exc:
            raise _named(folder, exc) from None
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
            shutil.rmtree(old, ignore_errors=True)
    _fsync_folder(parent)


# ---- locks for updates in place ----------------------------------------------------------

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


def _acquire(path: str, lock: str, wait: float) -> int:
    """flock ``lock`` exclusively and return its descriptor, waiting up to ``wait`` seconds.

    The lock file is removed by its holder on release; a waiter that then gets the lock of the
    removed file sees that the name no longer leads to it and tries again, so exactly one
    process holds the lock of the file the name leads to."""
    start = time.monotonic()
    deadline = start + wait
    told = False
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
        except OSError as exc:
            raise _named(path, exc) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            if time.monotonic() >= deadline:
                raise OutputFileError(path, f"is being written by {_lock_holder(lock)} (it holds {lock}); "
                                            "try again when that process ends") from None
            if not told and time.monotonic() >= start + 1.0:  # say why a command seems to hang
                told = True
                print(f"waiting for {path}: {_lock_holder(lock)} is writing it", file=sys.stderr)
            time.sleep(0.05)
            continue
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            with contextlib.suppress(OSError):  # the pid is for messages only (a full disk may refuse it)
                os.ftruncate(fd, 0)
                os.write(fd, b"%d\n" % os.getpid())
            return fd
        os.close(fd)  # the holder released and removed it before our flock: take the new one


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


@contextlib.contextmanager
def file_lock(path, wait: float = None):
    """Hold the advisory lock of the file ``path`` for the block (``fcntl.flock`` on
    ".<name>.hbrdf-lock" beside it, removed on release; the kernel drops it when the process
    dies, even by SIGKILL). A read-modify-write of ``path`` inside the block cannot lose another
    process's update: every hbrdf update in place and every :func:`atomic_write_bytes` rename
    takes it. Waits up to ``wait`` seconds (default :data:`LOCK_WAIT_SECONDS`) for another
    process's lock (one line on stderr while it waits), then raises
    :class:`~hybridbrdf.errors.OutputFileError` naming ``path`` and the holder's pid.
    Re-entrant within a process."""
    path = os.fspath(path)
    lock = _lock_name(path)
    with _held_guard:
        held = _held_locks.get(lock)
        if held is not None:
            held[1] += 1
    if held is None:
        fd = _acquire(path, lock, LOCK_WAIT_SECONDS if wait is None else wait)
        with _held_guard:
            held = _held_locks[lock] = [fd, 1]
    try:
        yield
    finally:
        with _held_guard:
            held[1] -= 1
            last = held[1] == 0 and held[0] is not None
            if last:
                _held_locks.pop(lock, None)
        if last:
            with contextlib.suppress(OSError):
                os.unlink(lock)  # while still holding it: see _acquire
            os.close(held[0])


# ---- scratch folders ---------------------------------------------------------------------

#: The name every scratch folder in $TMPDIR starts with, before its process's pid.
_SCRATCH_PREFIX = "hbrdf-scratch-"


def _remove_stale_scratch(base: str) -> None:
    """Remove the scratch folders in ``base`` whose process is no longer alive (SIGKILL)."""
    pattern = re.compile(re.escape(_SCRATCH_PREFIX) + r"(\d+)-[A-Za-z0-9_]+\Z")
    try:
        entries = os.listdir(base)
    except OSError:
        return
    for entry in entries:
        m = pattern.match(entry)
        if m and int(m.group(1)) != os.getpid() and not _pid_alive(int(m.group(1))):
            shutil.rmtree(os.path.join(base, entry), ignore_errors=True)


@contextlib.contextmanager
def scratch_folder():
    """A private folder in $TMPDIR for the block's scratch files (a model file libhybridbrdf
    reads, not an output), removed on leaving the block, on an exception, Ctrl-C or SIGTERM;
    one left by a process killed outright (its pid, in the name, no longer alive) is removed by
    the next :func:`scratch_folder` on this machine."""
    base = tempfile.gettempdir()
    _remove_stale_scratch(base)
    with _sigterm_cleans_up():
        path = tempfile.mkdtemp(prefix=f"{_SCRATCH_PREFIX}{os.getpid()}-", dir=base)
        try:
            yield path
        finally:
            shutil.rmtree(path, ignore_errors=True)


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
