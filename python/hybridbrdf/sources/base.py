"""The one interface every BRDF source presents: measured files, published
networks and synthetic materials alike. Nothing downstream knows the format."""

from __future__ import annotations

import abc
import os
from typing import Optional

import numpy as np

from hybridbrdf.errors import InputFileError
from hybridbrdf.inputs import read_input_bytes
from hybridbrdf.limits import pair_arguments

#: Peak bytes per direction pair of :meth:`BRDFSource.eval` (float64 copies, masks, the unit
#: directions, the reader's work: 408 measured for a synthetic material), with a margin.
BYTES_PER_PAIR = 512


class BRDFFormatError(InputFileError):
    """A file (or synthetic name) that cannot be read as a BRDF.

    ``str(err)`` is ``"<path>: <problem>"``, one line, meant for people; the
    CLI prints it as is. ``path`` and ``problem`` are kept as attributes.
    """


def read_file_bytes(spec: str, kind: str, limit: int) -> bytes:
    """The bytes of the file ``spec``, a ``kind`` file ("MERL") of at most ``limit`` bytes.

    Checked before it is read (hybridbrdf.inputs): a folder, a FIFO, a device (a symlink to
    /dev/zero) or a file larger than the format can hold raises :class:`BRDFFormatError`
    naming what it is, and no more than ``limit + 1`` bytes are ever read."""
    return read_input_bytes(spec, f"{kind} file", limit, BRDFFormatError)


def check_file_size(spec: str, data: bytes, kind: str, expected: int, layout: str) -> None:
    """Raises :class:`BRDFFormatError` unless ``data``, a ``kind`` file, is ``expected`` bytes
    long; the message names ``layout``, what those bytes hold."""
    if len(data) != expected:
        what = f"truncated {kind} file" if len(data) < expected else f"{kind} file too long"
        raise BRDFFormatError(spec, f"{what}: {len(data)} bytes, expected {expected} ({layout})")


def check_finite_table(spec: str, raw: np.ndarray, kind: str, describe) -> None:
    """Raises :class:`BRDFFormatError` if ``raw``, a ``kind`` table read from ``spec``, holds
    non-finite values, naming how many and the first, which ``describe(*index)`` words."""
    bad = ~np.isfinite(raw)
    if bad.any():
        first = (int(x[0]) for x in np.nonzero(bad))
        raise BRDFFormatError(
            spec, f"{int(bad.sum())} non-finite values in the {kind} table (first: {describe(*first)})"
        )


def table_array(values, shape: tuple, kind: str) -> np.ndarray:
    """``values`` as a float64 array; ``ValueError`` unless it has ``shape``."""
    table = np.asarray(values, dtype=np.float64)
    if table.shape != shape:
        raise ValueError(f"{kind} table must have shape {shape}, got {table.shape}")
    return table


def check_choice(what: str, value: str, choices: tuple) -> None:
    """``ValueError`` unless ``value`` (the option ``what``) is one of ``choices``."""
    if value not in choices:
        raise ValueError(f"{what} must be one of {choices}, got {value!r}")


def source_name(name: Optional[str], path: Optional[str], fallback: str) -> str:
    """A source's name: ``name`` when given, else the stem of ``path``, else ``fallback``."""
    if name is not None:
        return name
    return os.path.splitext(os.path.basename(path))[0] if path else fallback


class BRDFSource(abc.ABC):
    """A BRDF f(wi, wo) (no cosine, RGB) in the local frame of docs/CONVENTIONS.md.

    Attributes every source sets:

    - ``name``: material name (the file stem, or the synthetic material's name)
    - ``isotropic``: True when f depends on phi_i - phi_o only
    - ``origin``: where the values come from, the label figures must carry,
      e.g. ``"RGL measurement (raw .bsdf)"``, ``"MERL (NBRDF reconstruction)"``,
      ``"synthetic (exact)"``
    - ``path``: the file read, or None

    Subclasses implement :meth:`_eval` for unit directions strictly above the
    horizon; :meth:`eval` does the checking, normalising and masking.
    """

    name: str
    isotropic: bool
    origin: str
    path: Optional[str] = None

    def eval(self, wi, wo) -> np.ndarray:
        """f(wi, wo) for (N,3) arrays; returns (N,3) float64.

        Directions are normalised. Rows where either direction is at or
        below the horizon, has zero length or is not finite give 0. Measured
        sources return their data as it is: values may be slightly negative
        where the measurement was noisy (metrics clamp them to 0). Arrays that are not numbers
        raise TypeError, row counts beyond memory ValueError (hybridbrdf.limits), each naming
        the argument.
        """
        wi, wo = pair_arguments(("wi", "wo"), (wi, wo), (3, 3), BYTES_PER_PAIR)
        wi = np.asarray(wi, dtype=np.float64)
        wo = np.asarray(wo, dtype=np.float64)
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            li = np.sqrt((wi * wi).sum(axis=1))
            lo = np.sqrt((wo * wo).sum(axis=1))
            ok = np.isfinite(li) & np.isfinite(lo) & (li > 1e-300) & (lo > 1e-300)
            ok &= (wi[:, 2] > 0) & (wo[:, 2] > 0)
        out = np.zeros((wi.shape[0], 3))
        if ok.any():
            out[ok] = self._eval(wi[ok] / li[ok, None], wo[ok] / lo[ok, None])
        return out

    @abc.abstractmethod
    def _eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f for unit (M,3) float64 directions with wi.z > 0 and wo.z > 0; returns (M,3)."""

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} ({self.origin})>"
