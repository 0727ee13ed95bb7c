"""hbrdf view: the page, its shaders (WebGL2, WebGPU), lighting and measured references.

    from hybridbrdf.viewer import write_page, tracer_scene
    write_page("model.safetensors", "page.html")
"""

from hybridbrdf.exports import public_face
from hybridbrdf.viewer.glsl import fragment_shader
from hybridbrdf.viewer.page import MAX_VIEW_WEIGHT_BYTES, ViewError, render_page, write_page
from hybridbrdf.viewer.scene import tracer_scene
from hybridbrdf.viewer.textured import TexturedViewError

#: Names of the old module hybridbrdf.viewer (viewer.py) that its public face does not hold.
_MOVED = {"CAMERA": "hybridbrdf.viewer.scene", "DEFAULT_SUN": "hybridbrdf.viewer.scene",
          "SUN_IRRADIANCE": "hybridbrdf.viewer.scene", "SUN_SIZE_DEG": "hybridbrdf.viewer.scene",
          "srgb8": "hybridbrdf.viewer.scene", "DISPLAY_SHADER": "hybridbrdf.viewer.glsl",
          "check_size": "hybridbrdf.viewer.page", "page_data": "hybridbrdf.viewer.page",
          "script_json": "hybridbrdf.viewer.page", "weight_bytes": "hybridbrdf.viewer.page"}

__all__ = ["MAX_VIEW_WEIGHT_BYTES", "TexturedViewError", "ViewError", "fragment_shader", "render_page",
           "tracer_scene", "write_page"]

__getattr__, __dir__ = public_face(__name__, globals(), moved=_MOVED)
