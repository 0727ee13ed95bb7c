"""Where the package's data folders are, installed or in the source tree."""

from __future__ import annotations

import pathlib



def package_data_dir(name: str, marker: str) -> pathlib.Path:
    """The data folder ``name`` (codegen/, glsl/): installed inside the package in a wheel,
    at the top of the repository in the source tree; ``marker`` is a file it must hold."""
    here = pathlib.Path(__file__).resolve().parents[1]  # the hybridbrdf package
    for candidate in (here / name, here.parents[1] / name):
        if (candidate / marker).is_file():
            return candidate
    raise FileNotFoundError(f"{name}/{marker} not found next to the package or in the source tree")
