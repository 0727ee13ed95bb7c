"""Small shared helpers."""

from __future__ import annotations

import os
import pathlib
import tempfile


def package_data_dir(name: str, marker: str) -> pathlib.Path:
    """The data folder ``name`` (codegen/, glsl/): installed inside the package in a wheel,
    at the top of the repository in the source tree; ``marker`` is a file it must hold."""
    here = pathlib.Path(__file__).resolve().parent
    for candidate in (here / name, here.parents[1] / name):
        if (candidate / marker).is_file():
            return candidate
    raise FileNotFoundError(f"{name}/{marker} not found next to the package or in the source tree")


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder
    and a rename, so that a reader never sees a half-written file and a
    failure leaves any previous file intact."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=os.path.basename(path), dir=folder)
    try:
        # mkstemp creates 0600; give the file the permissions open() would (0666 less the umask).
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
