"""Counts bounded by the memory they would take, and arguments checked at the public API.

Every count a command or a public function takes (albedo samples, direction pairs, ...) is
checked before anything is allocated: its cost in bytes (a per-unit figure each caller states,
measured as peak resident memory; docs/CONVENTIONS.md, "Counts and memory") against this
machine's memory (:func:`memory_budget`). An over-large count is refused in one line naming the
flag or argument, what it would take and the largest count that fits, instead of a traceback
from NumPy or PyTorch after minutes or a machine driven into swap.

Arguments of the wrong type are refused with a one-line ``TypeError`` naming the argument before
NumPy converts them (NumPy reads the string ``"0.5"`` as 0.5 and ``True`` as 1; it allocates a
broadcast view's full size when it copies one).
"""

from __future__ import annotations

import numbers
import os
import resource

import numpy as np

from hybridbrdf.errors import one_line_text


def memory_budget() -> int:
    """Bytes one call may allocate: the machine's physical memory, or what is left of this
    process's address-space limit (``ulimit -v``) when that is smaller."""
    budget = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY:
        budget = min(budget, max(soft - _address_space_used(), 0))
    return int(budget)


def _address_space_used() -> int:
    try:
        with open("/proc/self/status") as fh:
            return next(int(line.split()[1]) * 1024 for line in fh if line.startswith("VmSize:"))
    except (OSError, StopIteration, ValueError):
        return 0


def format_bytes(n: float) -> str:
    """``n`` bytes in the largest binary unit that keeps a leading digit: "98.3 GiB"."""
    for unit, size in (("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= size:
            return f"{n / size:.1f} {unit}"
    return f"{int(n)} bytes"


def _shown(value) -> str:
    """A wrong argument in an error: its type and the start of its repr, one line."""
    return f"{type(value).__name__} {one_line_text(repr(value))[:80]}"


def check_count(what: str, count: int, bytes_each: float, fixed: float = 0.0) -> None:
    """Raises ValueError (one line naming ``what``, a flag or an argument) when ``count`` units of
    ``bytes_each`` bytes, plus ``fixed``, would take more than :func:`memory_budget`."""
    budget = memory_budget()
    need = fixed + float(count) * bytes_each
    if need > budget:
        most = max(int((budget - fixed) // bytes_each), 0)
        raise ValueError(f"{what} {count:,}: would allocate about {format_bytes(need)}, more than this machine's "
                         f"{format_bytes(budget)} of memory; at most {most:,}")


def count_argument(name: str, value, lo: int = 1) -> int:
    """``value`` as a Python int >= ``lo``: TypeError naming ``name`` for a bool, a float, a string
    or anything else that is not an integer; ValueError for one below ``lo``."""
    what = "a positive integer" if lo == 1 else f"an integer >= {lo}"
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be {what}, got {_shown(value)}")
    if value < lo:
        raise ValueError(f"{name} must be {what}, got {int(value)}")
    return int(value)


def real_argument(name: str, value) -> float:
    """``value`` as a float: TypeError naming ``name`` unless it is a real number (not a bool or
    a string; NumPy scalars and 0-d arrays of numbers are real numbers)."""
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number, got {_shown(value)}")
    return float(value)


def bool_argument(name: str, value) -> bool:
    """``value`` when it is a bool (NumPy's included): TypeError naming ``name`` otherwise (the
    string "no" is true)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {_shown(value)}")
    return bool(value)


def rows_argument(name: str, value, cols: int) -> np.ndarray:
    """``value`` as an (N, ``cols``) array of numbers, not copied where it already is an array
    (a broadcast view stays a view): TypeError naming ``name`` for strings, booleans, objects
    and None; ValueError for another shape."""
    if value is None or isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be an (N, {cols}) array of numbers, got {type(value).__name__}")
    try:
        arr = value if isinstance(value, np.ndarray) else np.asarray(value)
    except (ValueError, TypeError):  # ragged nested lists: NumPy's words name no argument
        raise ValueError(f"{name} must be an (N, {cols}) array of numbers, got {type(value).__name__} of rows of "
                         f"different lengths") from None
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must be an (N, {cols}) array of numbers, got an array of dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] != cols:
        raise ValueError(f"{name} must have shape (N, {cols}), got {arr.shape}")
    return arr


def pair_arguments(names, values, cols, bytes_per_pair: float):
    """Arrays of one call that pair row by row (``wi`` and ``wo``, ``wo`` and ``u``): each
    checked by :func:`rows_argument`, the same row count, and that count bounded by
    ``bytes_per_pair`` (:func:`check_count`) before any of them is converted or copied."""
    arrays = [rows_argument(n, v, c) for n, v, c in zip(names, values, cols)]
    for n, a in zip(names[1:], arrays[1:]):
        if a.shape[0] != arrays[0].shape[0]:
            raise ValueError(f"{names[0]} has {arrays[0].shape[0]} rows but {n} has {a.shape[0]}")
    check_count(f"{names[0]} rows", arrays[0].shape[0], bytes_per_pair)
    return arrays


__all__ = ["bool_argument", "check_count", "count_argument", "format_bytes", "memory_budget", "pair_arguments",
           "real_argument", "rows_argument"]
