"""Atomic writes of files and folders.

A file is written to ".<name>.tmp-<pid>-<random>" in the destination's folder, then renamed
over the destination: a reader sees the old file or the new one, never half of one. An
exception or Ctrl-C (KeyboardInterrupt) removes the temporary; SIGTERM does too (it is turned
into an exception for the length of the write, then delivered again). SIGKILL and a power cut
cannot be cleaned up by the dying process, so the temporary carries its writer's pid and the
next write to the same destination removes those whose writer is no longer alive.
The temporary gets the replaced file's permissions (a chmod 600 model stays 600); a new file
gets what open() gives (0666 less the umask). Every step (create, write, fsync, close, rename)
is checked, and an OSError names the destination: "out/m.safetensors: No space left on device".

Updates in place (read a file, change it, write it back) hold the destination's lock
(:func:`file_lock`: fcntl.flock on ".<name>.hbrdf-lock" beside it) from before the read to
after the rename, so two of them at once are serialised (the second reads the first's
result) and no update is lost; every atomic write takes the same lock for its rename.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import shutil
import stat

from hybridbrdf.errors import InputFileError, OutputFileError

from hybridbrdf.files.cleanup import _pid_alive, _sigterm_cleans_up
from hybridbrdf.files.locks import file_lock
from hybridbrdf.files.names import _named, _temp_prefix


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


def make_parent_folder(path) -> str:
    """Create the missing folders on the way to ``path`` (a file or a folder to be written) and
    return its folder: the one rule of every command's outputs (docs/CONVENTIONS.md, "Writing
    files"). Raises :class:`~hybridbrdf.errors.InputFileError` naming ``path`` when a file is in
    the way or a folder cannot be created."""
    path = os.fspath(path)
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
    return folder


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
    folder = make_parent_folder(path)
    try:
        tmp = _temporary_name(path, folder)
        os.close(_create_temporary(tmp))
        os.unlink(tmp)
    except OSError as exc:
        raise InputFileError(path, f"cannot write the {what} into {folder}: {exc.strerror or exc}") from None
