"""The material name of each source in a fit, and the source a model material was fitted from."""

from __future__ import annotations

import os
from typing import List, Optional, Sequence

from hybridbrdf.errors import InputFileError
from hybridbrdf.names import name_problem, names_problem
from hybridbrdf.sources.base import BRDFSource


_FORMAT_TAGS = {".bsdf": "rgl", ".h5": "nbrdf", ".binary": "merl", ".bin": "utia"}


def format_tag(src: BRDFSource) -> str:
    """Short name of a source's format: rgl, nbrdf, merl, utia, synthetic (or other)."""
    if src.path is None:
        return "synthetic"
    return _FORMAT_TAGS.get(os.path.splitext(src.path)[1].lower(), "other")


def material_names(sources: Sequence[BRDFSource]) -> List[str]:
    """Material names for a collection: each source's name, except that names
    shared by sources of different formats (e.g. an RGL file and the NBRDF
    network fitted to it) become ``<name>.<format>``. Raises ValueError if
    names still collide."""
    names = [s.name for s in sources]
    shared = {n for n in names if names.count(n) > 1}
    out = [f"{s.name}.{format_tag(s)}" if s.name in shared else s.name for s in sources]
    dupes = sorted({n for n in out if out.count(n) > 1})
    if dupes:
        raise ValueError(f"two sources share the material name(s) {', '.join(dupes)}; names must be unique")
    # The model contract's name rule (hybridbrdf.names), checked before any training: a name the
    # loaders would refuse must not cost a fit. Names come from file names, so the error names the file.
    for src, name in zip(sources, out):
        problem = name_problem(name)
        if problem:
            raise InputFileError(src.path or name, f"material name '{name}' breaks the rule: {problem} "
                                                   f"(rename the file)")
    problem = names_problem(out)
    if problem:
        raise ValueError(f"{problem}; rename one of the files")
    return out


def source_material(model, src: BRDFSource) -> Optional[str]:
    """The model material a source was fitted as: ``<name>`` or, where a collection held the same
    name in two formats, ``<name>.<format>`` (see material_names); None if the model lacks both."""
    return next((c for c in (src.name, f"{src.name}.{format_tag(src)}") if c in model.materials), None)
