#!/usr/bin/env python3
"""SPIR-V size of the generated GLSL before and after scene specialisation.

    python bench/spirv_sizes.py MODEL MATERIAL

Prints the optimised (-Os) SPIR-V bytes of a compute shader evaluating
hbrdf_eval for MATERIAL: generic (all materials), a one-material scene
(latent folded, isotropic-only when the material is), an analytic-only scene;
for the network in both code forms (unrolled, the shader default, and loops).
"""

import pathlib
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))

import hybridbrdf as hb  # noqa: E402
from hybridbrdf.codegen.main import generate
from hybridbrdf.codegen.literals import material_constant
from shader_kernels import spirv_size  # noqa: E402


def main() -> int:
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    model = hb.load_model(sys.argv[1])
    mat = sys.argv[2]
    const = material_constant(mat)
    with tempfile.TemporaryDirectory() as d:
        rows = []
        for form in ("unrolled", "loops"):
            rows += [(f"{form}: generic, all materials", generate(model, "glsl", mlp_form=form)),
                     (f"{form}: scene, one material, full model", generate(model, "glsl", mlp_form=form, scene={
                         "name": "one", "materials": [{"name": mat, "evaluate": "full"}]}))]
        if model.kind != "neural":
            rows.append(("scene: one material, analytic only", generate(model, "glsl", scene={
                "name": "flat", "materials": [{"name": mat, "evaluate": "analytic"}]})))
        print(f"{sys.argv[1]}: {model.kind} {model.arch['width']}x{model.arch['depth']}, "
              f"{len(model.materials)} materials; material {mat}")
        for label, code in rows:
            print(f"{label:48s} {spirv_size(code, const, d):8d} bytes of SPIR-V")
    return 0


if __name__ == "__main__":
    sys.exit(main())
