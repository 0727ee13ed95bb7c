"""How the files of an atomic write or a lock are named beside their destination, and the
error that names the destination (the file the user asked for) rather than a temporary."""

from __future__ import annotations

import os

from hybridbrdf.errors import OutputFileError


#: The longest part of the destination's name a temporary repeats (NAME_MAX is 255 bytes).
_TEMP_STEM_CHARS = 100


def _temp_prefix(path: str) -> str:
    """The name every temporary of ``path`` starts with, before the writer's pid."""
    return f".{os.path.basename(path)[:_TEMP_STEM_CHARS]}.tmp-"


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
