"""Error types for bad input files and failed writes. Every one names the file and the problem
in one line (``"<path>: <problem>"``) so the CLI can print it as is."""

from __future__ import annotations

import os


def one_line_text(text: str) -> str:
    """``text`` with control characters (U+0000-U+001F, U+007F) and lone surrogates (what
    undecodable bytes become) written as ``\\xNN``: one printable line. libhybridbrdf's
    ``hbrdf::one_line_text`` applies the same rule to its messages."""
    out = []
    for ch in text:
        o = ord(ch)
        if o < 0x20 or o == 0x7F:
            out.append(f"\\x{o:02x}")
        elif 0xDC80 <= o <= 0xDCFF:  # os.fsdecode / surrogateescape: the raw byte o - 0xDC00
            out.append(f"\\x{o - 0xDC00:02x}")
        elif 0xD800 <= o <= 0xDFFF:
            out.append(f"\\u{o:04x}")
        else:
            out.append(ch)
    return "".join(out)


class InputFileError(ValueError):
    """An input that cannot be used: ``str(err) == f"{err.path}: {err.problem}"``, one line
    (the problem passes through :func:`one_line_text`)."""

    def __init__(self, path, problem: str):
        self.path = os.fspath(path) if path is not None else "<unknown>"
        self.problem = one_line_text(str(problem))
        super().__init__(f"{one_line_text(self.path)}: {self.problem}")


class ModelFileError(InputFileError):
    """A model file that is missing, truncated, malformed or inconsistent."""


class OutputFileError(OSError):
    """An output that could not be written (a full disk, a read-only folder, another process
    updating it): ``str(err) == f"{err.path}: {err.problem}"``, one line. An OSError (``errno``
    kept, ``filename`` the output) so that code catching OSError around a write still does."""

    def __init__(self, path, problem: str, errno_: int = 0):
        self.path = os.fspath(path) if path is not None else "<unknown>"
        self.problem = one_line_text(str(problem))
        super().__init__(errno_, self.problem, self.path)

    def __str__(self) -> str:
        return f"{one_line_text(self.path)}: {self.problem}"
