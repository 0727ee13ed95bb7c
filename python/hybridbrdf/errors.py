"""Error types for bad input files. Every one names the file and the problem
in one line (``"<path>: <problem>"``) so the CLI can print it as is."""

from __future__ import annotations

import os


class InputFileError(ValueError):
    """An input that cannot be used: ``str(err) == f"{err.path}: {err.problem}"``."""

    def __init__(self, path, problem: str):
        self.path = os.fspath(path) if path is not None else "<unknown>"
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class ModelFileError(InputFileError):
    """A model file that is missing, truncated, malformed or inconsistent."""
