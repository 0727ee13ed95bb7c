"""``hbrdf raster``: a scene drawn the way an engine draws it, by a headless Vulkan graphics pipeline
with the generated GLSL in the fragment stage (``hbrdf_raster``; docs/RASTER.md).

    from hybridbrdf.raster import draw_frame
    stats = draw_frame("scene.json", "out/frame.exr", png="out/frame.png", lavapipe=True, validation=True)

:mod:`~hybridbrdf.raster.shaders` plans and compiles the shaders of a scene,
:mod:`~hybridbrdf.raster.frame` runs the tool. Its names load on first access (PEP 562):
``hbrdf raster``'s parser reads :mod:`~hybridbrdf.raster.sizes` (plain Python) without NumPy.
"""

from hybridbrdf.exports import lazy_names, public_face
from hybridbrdf.raster.sizes import LAVAPIPE_ICD, SPHERE_SEGMENTS

_LAZY = {**lazy_names(["draw_frame", "find_tool"], "hybridbrdf.raster.frame"),
         **lazy_names(["FramePlan", "build_frame_shaders", "frame_plan"], "hybridbrdf.raster.shaders")}

__all__ = ["FramePlan", "LAVAPIPE_ICD", "SPHERE_SEGMENTS", "build_frame_shaders", "draw_frame", "find_tool",
           "frame_plan"]

__getattr__, __dir__ = public_face(__name__, globals(), _LAZY)
