"""The shipped prior: a network to add new measurements to (``hbrdf add`` without ``--to``).

The prior is a hybrid model (32x2, latent 8, material output layers) whose network was fitted to
every measured material of the project's data (the raw RGL files and the NBRDF reconstructions
of RGL, MERL and Nielsen), with the default recipe; it ships inside the package (about 170 KB: the
network and each training material's (p, z, head), which sparse fitting scores as starting
points). ``hbrdf add`` fits a measurement's (p, z, head) on the prior's frozen network, then by
default fine-tunes the network with it; the written model holds the new materials only
(docs/ADDING.md, "Adding to the prior" and "The shipped prior").
"""

from __future__ import annotations

import os
import pathlib

from hybridbrdf.errors import InputFileError
from hybridbrdf.model.file import load_model

#: Where the package keeps the prior.
PRIOR_FILE = pathlib.Path(__file__).resolve().parents[1] / "data" / "prior.safetensors"
#: The reciprocal prior (issue 60): the same materials and recipe with ``--arch hybrid-reciprocal``,
#: so that every model added onto it is reciprocal bit for bit, f(wi, wo) = f(wo, wi)
#: (docs/RECIPROCITY.md, "The reciprocal prior").
RECIPROCAL_PRIOR_FILE = PRIOR_FILE.with_name("prior_reciprocal.safetensors")


def prior_path(reciprocal: bool = False) -> str:
    """The shipped prior's model file (``reciprocal``: the reciprocal prior's); InputFileError if
    this installation lacks it (a source checkout before ``bench/train_prior.py`` has run)."""
    path = RECIPROCAL_PRIOR_FILE if reciprocal else PRIOR_FILE
    if not path.is_file():
        raise InputFileError(os.fspath(path), "the shipped prior is missing from this installation; "
                                              "pass --to BASE (or train one: python bench/train_prior.py)")
    return os.fspath(path)


def load_prior(reciprocal: bool = False):
    """The shipped prior as a :class:`~hybridbrdf.model.file.HybridModel` (``reciprocal``: the
    reciprocal prior)."""
    return load_model(prior_path(reciprocal))
