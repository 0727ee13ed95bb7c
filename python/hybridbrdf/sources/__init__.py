"""Readers for every BRDF source behind one interface (:class:`BRDFSource`).

    src = hybridbrdf.open_source("../shared/data/rgl/paper_white_rgb.bsdf")
    src.name, src.isotropic, src.origin
    f = src.eval(wi, wo)            # (N,3) float64, no cosine

Formats, detected from the file (extension, then contents):

    .binary   MERL (Matusik et al. 2003)                      sources/merl.py
    .bsdf     RGL tensor_file (Dupuy & Jakob 2018)            sources/rgl.py
    .bin      UTIA anisotropic (Filip & Vavra 2014)           sources/utia.py
    .h5       NBRDF network (Sztrajman et al. 2021)           sources/nbrdf.py
    synthetic:NAME   built-in material with exact ground truth sources/synthetic.py

Every problem with an input raises :class:`BRDFFormatError` naming the file. Each file is
checked before it is read (hybridbrdf.inputs): a regular file (a FIFO, a device or a folder is
refused by what it is), no larger than its format holds (MERL and UTIA: their one size; RGL
``.bsdf`` and NBRDF ``.h5``: 256 MiB; a Keras ``.json``: 1 MiB, nested at most 64 levels).
"""

from __future__ import annotations

import glob
import os
from typing import List

from hybridbrdf.sources.base import BRDFFormatError, BRDFSource
from hybridbrdf.sources.merl import open_merl, write_merl
from hybridbrdf.sources.names import material_names, source_material
from hybridbrdf.sources.nbrdf import open_nbrdf
from hybridbrdf.sources.rgl import open_rgl
from hybridbrdf.sources.synthetic import SYNTHETIC_MATERIALS, open_synthetic, synthetic_names
from hybridbrdf.sources.utia import open_utia, write_utia

SYNTHETIC_PREFIX = "synthetic:"
EXTENSIONS = (".binary", ".bsdf", ".bin", ".h5")


def open_source(path) -> BRDFSource:
    """Open one BRDF source; the format is detected from the file."""
    spec = os.fspath(path)
    if spec.startswith(SYNTHETIC_PREFIX):
        return open_synthetic(spec[len(SYNTHETIC_PREFIX):])
    if not os.path.exists(spec):
        raise BRDFFormatError(spec, "no such file")
    if os.path.isdir(spec):
        raise BRDFFormatError(spec, "is a folder; use expand_sources() for folders and globs")
    ext = os.path.splitext(spec)[1].lower()
    if ext == ".binary":
        return open_merl(spec)
    if ext == ".bsdf":
        return open_rgl(spec)
    if ext == ".bin":
        return open_utia(spec)
    if ext == ".h5":
        return open_nbrdf(spec)
    raise BRDFFormatError(spec, f"unknown BRDF format (extension {ext or 'none'!r}; expected one of "
                                f"{', '.join(EXTENSIONS)} or synthetic:NAME)")


def expand_sources(specs) -> List[str]:
    """Expand files, folders (their files with a known extension, sorted) and
    globs into a list of source specs; raises BRDFFormatError for a spec that
    matches nothing."""
    out: List[str] = []
    for spec in specs:
        spec = os.fspath(spec)
        if spec.startswith(SYNTHETIC_PREFIX):
            if spec == SYNTHETIC_PREFIX + "all":
                out.extend(SYNTHETIC_PREFIX + n for n in SYNTHETIC_MATERIALS)
            else:
                out.append(spec)
        elif os.path.isdir(spec):
            found = sorted(
                os.path.join(spec, f) for f in os.listdir(spec) if os.path.splitext(f)[1].lower() in EXTENSIONS
            )
            if not found:
                raise BRDFFormatError(spec, f"folder holds no BRDF file ({', '.join(EXTENSIONS)})")
            out.extend(found)
        elif any(ch in spec for ch in "*?["):
            found = sorted(glob.glob(spec))
            if not found:
                raise BRDFFormatError(spec, "glob matches no file")
            out.extend(found)
        else:
            out.append(spec)
    return out


__all__ = ["BRDFFormatError", "BRDFSource", "SYNTHETIC_MATERIALS", "SYNTHETIC_PREFIX", "expand_sources",
           "material_names", "open_source", "source_material", "synthetic_names", "write_merl", "write_utia"]
