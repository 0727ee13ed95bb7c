"""Rendering: the path tracer's Python side, the fit preview, the Mitsuba 3 plugin.

    from hybridbrdf.render import render, write_exr, read_exr
    img, stats = render("scenes/sphere_env.json", out="out/sphere.exr", spp=256)

The Mitsuba 3 plugin is a module of its own, :mod:`hybridbrdf.render.mitsuba` (it imports mitsuba):
``import hybridbrdf.render.mitsuba; hybridbrdf.render.mitsuba.register()``.
"""

from hybridbrdf.exports import public_face
from hybridbrdf.render.preview import render_preview
from hybridbrdf.render.tracer import (MAX_SCENE_BYTES, SETTINGS, RenderMaterialError, load_scene_dict, read_exr,
                                      read_image, render, settings, write_exr, write_png)

#: Names of the old module hybridbrdf.render (render.py) that its public face does not hold.
_MOVED = {"scene_inputs": "hybridbrdf.render.tracer"}

__all__ = ["MAX_SCENE_BYTES", "RenderMaterialError", "SETTINGS", "load_scene_dict", "read_exr", "read_image",
           "render", "render_preview", "settings", "write_exr", "write_png"]

__getattr__, __dir__ = public_face(__name__, globals(), moved=_MOVED)
