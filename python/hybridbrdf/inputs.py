"""Reading untrusted input files without trusting them: every file the Python side
opens as input goes through here first.

- :func:`check_input_file` refuses what is not a regular file *before* opening it (``os.stat``
  follows symlinks): opening a FIFO for reading blocks until a writer comes, and a character
  device such as ``/dev/zero`` never ends, so either would hang or fill memory. It also refuses a
  file larger than its format can hold, from its size alone.
- :func:`read_input_bytes` reads at most ``limit + 1`` bytes, so a file that grows while being
  read still cannot take more memory than its format allows.
- :func:`loads_json` parses JSON only once a scan of the raw text has shown it is nested no deeper
  than :data:`MAX_JSON_DEPTH` (Python's json module recurses once per level: 5,000 levels raise
  RecursionError, a traceback and not an error message).
- :func:`refuse_output_over_input` keeps a command from writing its result over one of its own
  inputs (compared by path and by file identity, symlinks followed).

Every error is the caller's one-line ``InputFileError`` subclass, ``"<path>: <problem>"``.
Torch-free, and numpy is the only dependency beyond the standard library.
"""

from __future__ import annotations

import json
import os
import re
import stat
from typing import Iterable, Optional, Type

import numpy as np

from hybridbrdf import spec
from hybridbrdf.errors import InputFileError

#: Deepest JSON nesting (arrays and objects) any input may have: the model contract's
#: ``max_json_depth`` (spec/model.json), which libhybridbrdf's model loader applies too. Model
#: metadata, scenes and Keras configs are at most about 8 levels deep; 64 leaves room and stays
#: far from Python's recursion limit.
MAX_JSON_DEPTH = spec.MAX_JSON_DEPTH


def file_kind(mode: int) -> str:
    """What a non-regular file is, as an error message says it ("a FIFO", "a character device")."""
    for test, words in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                        (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return words
    return "not a regular file"


def check_input_file(path, what: str, limit: Optional[int] = None,
                     error: Type[InputFileError] = InputFileError) -> int:
    """The size of ``path`` once it is known to be a regular file of at most ``limit`` bytes
    (``None``: no limit); ``what`` names the format in messages ("MERL file"). Raises ``error``:
    "no such file", "is a folder, not a MERL file", "is a FIFO, not a regular file", "MERL file too
    long: N bytes (a MERL file is at most L bytes)" or "cannot read the MERL file: <reason>". Nothing is
    opened, so a FIFO cannot block."""
    path = os.fspath(path)
    try:
        st = os.stat(path)  # follows symlinks: a link to /dev/zero is a character device
    except FileNotFoundError:
        raise error(path, "no such file") from None
    except OSError as exc:
        raise error(path, f"cannot read the {what}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode):
        raise error(path, f"is a folder, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        kind = file_kind(st.st_mode)
        raise error(path, f"is {kind}, not a regular file" if kind.startswith("a ") else f"is {kind}")
    if limit is not None and st.st_size > limit:
        raise error(path, f"{what} too long: {st.st_size} bytes (a {what} is at most {limit} bytes)")
    return st.st_size


def read_input_bytes(path, what: str, limit: int, error: Type[InputFileError] = InputFileError) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them (:func:`check_input_file`
    first; the read itself stops at ``limit + 1`` bytes, so a file growing meanwhile is caught too)."""
    path = os.fspath(path)
    check_input_file(path, what, limit, error)
    try:
        with open(path, "rb") as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise error(path, f"cannot read the {what}: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise error(path, f"{what} too long: more than {limit} bytes (it grew while being read)")
    return data


def read_input_text(path, what: str, limit: int, error: Type[InputFileError] = InputFileError) -> str:
    """:func:`read_input_bytes` decoded as UTF-8 (an undecodable file is ``error``)."""
    data = read_input_bytes(path, what, limit, error)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(path, f"the {what} is not UTF-8 text (byte {exc.start})") from None


# A JSON string (quotes, escapes); what is outside strings is structure, numbers and literals.
# An unterminated one runs to the end, as libhybridbrdf's scan reads it (the same depth, so both
# loaders refuse the same files with the same words). The unrolled form: no backtracking.
_JSON_STRING = re.compile(r'"[^"\\]*(?:\\[\s\S]?[^"\\]*)*(?:"|\Z)')
_NOT_BRACKET = re.compile(r"[^\[\]{}]+")


def json_depth(text: str) -> int:
    """The deepest nesting of arrays and objects in JSON ``text`` (brackets inside strings do not
    count). Vectorised: a few passes in C over the text, never a Python loop per character, so a
    100 MB model header costs well under a second. On malformed JSON it is a bound the parser then
    rejects for another reason (an unterminated string runs to the end, as in libhybridbrdf)."""
    brackets = _NOT_BRACKET.sub("", _JSON_STRING.sub("", text))
    if not brackets:
        return 0
    codes = np.frombuffer(brackets.encode("ascii"), dtype=np.uint8)
    steps = np.where((codes == ord("[")) | (codes == ord("{")), 1, -1).astype(np.int64)
    return int(np.cumsum(steps).max())


def value_depth(value, limit: int = MAX_JSON_DEPTH) -> int:
    """The deepest nesting of dicts and lists (and tuples, which JSON writes as arrays) in a Python
    ``value``, counted as :func:`json_depth` counts brackets (``{"a": [1]}`` is 2), so that a scene
    passed as a dict meets the same bound as its file. Iterative (``copy.deepcopy`` and
    ``json.dumps`` recurse once per level: 10,000 levels raise RecursionError), and it stops at
    ``limit + 1``, so a dict that contains itself ends too."""
    deepest = 0
    stack = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict):
            children = item.values()
        elif isinstance(item, (list, tuple)):
            children = item
        else:
            continue
        deepest = max(deepest, depth)
        if deepest > limit:
            return deepest
        stack.extend((child, depth + 1) for child in children)
    return deepest


def loads_json(text, path, what: str, error: Type[InputFileError] = InputFileError,
               max_depth: int = MAX_JSON_DEPTH, **kwargs):
    """``json.loads(text, **kwargs)`` once ``text`` is known to nest at most ``max_depth`` levels.
    Raises ``error(path, "<what>: JSON nested deeper than N levels")`` before parsing, and
    ``error(path, "<what> is not valid JSON (<reason>)")`` for a syntax error; ``what`` names the
    document ("scene file", "'hbrdf' metadata")."""
    if isinstance(text, (bytes, bytearray)):
        try:
            text = bytes(text).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise error(path, f"{what} is not UTF-8 text (byte {exc.start})") from None
    if json_depth(text) > max_depth:
        raise error(path, f"{what}: JSON nested deeper than {max_depth} levels")
    try:
        return json.loads(text, **kwargs)
    except RecursionError:  # cannot happen below the bound; kept so that no traceback can
        raise error(path, f"{what}: JSON nested deeper than {max_depth} levels") from None
    except (TypeError, ValueError) as exc:
        raise error(path, f"{what} is not valid JSON ({exc})") from None


# ---- outputs that are inputs ------------------------------------------------------------


def same_file(a, b) -> bool:
    """Whether paths ``a`` and ``b`` name one file: the same path once symlinks are resolved, or
    (both existing) the same inode, which catches hard links and bind mounts too."""
    a, b = os.fspath(a), os.fspath(b)
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet): the paths decided
        return False


def refuse_output_over_input(out, inputs: Iterable, flag: str = "the output",
                             error: Type[InputFileError] = InputFileError) -> None:
    """Raise ``error(out, "<flag> names the input <input>; writing it would destroy that input")``
    when ``out`` is one of ``inputs`` (paths; None and empty ones are skipped). Called before any
    work, so that a refused command leaves every file as it was."""
    if not out:
        return
    for item in inputs:
        if item and same_file(out, item):
            raise error(out, f"{flag} names the input {os.fspath(item)}; writing it would destroy that input")
