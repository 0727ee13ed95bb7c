"""hbrdf-codegen: GLSL, HLSL, Slang, WGSL, C++ and BRDF Explorer sources from a model file.

    from hybridbrdf.codegen import generate, load_scene
    glsl = generate(hybridbrdf.load_model("model.safetensors"), "glsl", materials=["gold"])
    wgsl = generate_textured("out/textured", "wgsl")   # a textured material's folder (hbrdf paint)

The ``hbrdf-codegen`` command is :func:`hybridbrdf.codegen.main.main` (the module ``main``).
"""

from hybridbrdf.codegen.literals import DIALECTS
from hybridbrdf.codegen.scene import load_scene
from hybridbrdf.codegen.source import MLP_FORMS
from hybridbrdf.exports import public_face

#: Names of the old module hybridbrdf.codegen (codegen.py) that its public face does not hold.
_MOVED = {"NO_DEPTH_LIMIT": "hybridbrdf.codegen.scene", "check_material_selection": "hybridbrdf.codegen.source",
          "comment_text": "hybridbrdf.codegen.literals", "float_literal": "hybridbrdf.codegen.literals",
          "material_constant": "hybridbrdf.codegen.literals"}

__all__ = ["DIALECTS", "MLP_FORMS", "TARGETS", "generate", "generate_textured", "load_scene"]

# generate and TARGETS load from the command's module on first use: importing it here would make
# `python -m hybridbrdf.codegen.main` find its own module already imported (runpy's RuntimeWarning
# on stderr, where the command's errors are one line).
__getattr__, __dir__ = public_face(__name__, globals(), lazy={"generate": "hybridbrdf.codegen.main",
                                                             "generate_textured": "hybridbrdf.codegen.main",
                                                             "TARGETS": "hybridbrdf.codegen.main"}, moved=_MOVED)
