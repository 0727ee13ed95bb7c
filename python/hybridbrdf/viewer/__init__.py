"""hbrdf view: the page, its shaders (WebGL2, WebGPU), lighting and measured references.

    from hybridbrdf.viewer import write_page, tracer_scene
    write_page("model.safetensors", "page.html")
"""

from hybridbrdf.exports import lazy_names, public_face
from hybridbrdf.viewer.glsl import fragment_shader

#: The names whose modules import NumPy (and the renderer, Jinja2, Pillow), loaded on first access
#: (PEP 562): ``hbrdf view``'s parser reads hybridbrdf.viewer.sizes (plain Python) without them.
_LAZY = {**lazy_names(["MAX_VIEW_WEIGHT_BYTES", "ViewError", "render_page", "write_page"], "hybridbrdf.viewer.page"),
         "tracer_scene": "hybridbrdf.viewer.scene", "TexturedViewError": "hybridbrdf.viewer.textured"}

#: Names of the old module hybridbrdf.viewer (viewer.py) that its public face does not hold.
_MOVED = {"CAMERA": "hybridbrdf.viewer.scene", "DEFAULT_SUN": "hybridbrdf.viewer.scene",
          "SUN_IRRADIANCE": "hybridbrdf.viewer.scene", "SUN_SIZE_DEG": "hybridbrdf.viewer.scene",
          "srgb8": "hybridbrdf.viewer.scene", "DISPLAY_SHADER": "hybridbrdf.viewer.glsl",
          "check_size": "hybridbrdf.viewer.page", "page_data": "hybridbrdf.viewer.page",
          "script_json": "hybridbrdf.viewer.page", "weight_bytes": "hybridbrdf.viewer.page"}

__all__ = ["MAX_VIEW_WEIGHT_BYTES", "TexturedViewError", "ViewError", "fragment_shader", "render_page",
           "tracer_scene", "write_page"]

__getattr__, __dir__ = public_face(__name__, globals(), _LAZY, moved=_MOVED)
