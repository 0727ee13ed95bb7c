"""The project's hand-written shader sources (glsl/): the compute kernels that run generated
shaders under Vulkan for the conformance tests and the benchmarks. They are Jinja2 templates
whose few varying parts (the included model file, the function, the material constant, a
pair-count guard) are filled by :func:`render_shader`."""

from __future__ import annotations

import pathlib

import jinja2

from hybridbrdf.util import package_data_dir


def shader_dir() -> pathlib.Path:
    """glsl/, inside the package in a wheel, at the top of the repository in the source tree."""
    return package_data_dir("glsl", "eval.comp.glsl")


def render_shader(name: str, **values) -> str:
    """The shader ``glsl/<name>`` with its template variables set from ``values``; a variable
    left unset is an error, not an empty string."""
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(shader_dir())), undefined=jinja2.StrictUndefined,
                             trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                             autoescape=False)
    return env.get_template(name).render(**values)
