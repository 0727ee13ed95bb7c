"""The project's hand-written shader sources (glsl/): the compute kernels that run generated
shaders under Vulkan for the conformance tests and the benchmarks. They are Jinja2 templates
whose few varying parts (the included model file, the function, the material constant, a
pair-count guard) are filled by :func:`render_shader`."""

from __future__ import annotations

import pathlib

import jinja2


def shader_dir() -> pathlib.Path:
    """glsl/ installed inside the package (the wheel), else the source tree's."""
    here = pathlib.Path(__file__).resolve().parent
    for candidate in (here / "glsl", here.parents[1] / "glsl"):
        if (candidate / "eval.comp.glsl").is_file():
            return candidate
    raise FileNotFoundError("shader sources (eval.comp.glsl) not found next to the package or in the source tree")


def render_shader(name: str, **values) -> str:
    """The shader ``glsl/<name>`` with its template variables set from ``values``; a variable
    left unset is an error, not an empty string."""
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(shader_dir())), undefined=jinja2.StrictUndefined,
                             trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                             autoescape=False)
    return env.get_template(name).render(**values)
