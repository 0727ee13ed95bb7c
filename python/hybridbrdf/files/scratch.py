"""Private scratch folders in $TMPDIR (files a step needs for a while, not outputs)."""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import tempfile

from hybridbrdf.files.cleanup import _pid_alive, _sigterm_cleans_up


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
