"""glTF 2.0 assets: hybrid materials exported with a fitted metallic-roughness fallback and the
HBRDF_hybrid_material extension, and a bounded reader (docs/GLTF.md).

    from hybridbrdf.gltf import export_gltf, read_hybrid, read_gltf
    export_gltf("model.safetensors", "out.glb", mesh="sphere")     # fits each material's fallback
    found = read_hybrid("out.glb", "out_materials")                  # {name: HybridMaterial}
    asset = read_gltf("scene.glb")                                   # checked whole, or GltfError
"""

from hybridbrdf.gltf.brdf import GltfMaterial, gltf_eval
from hybridbrdf.gltf.export import export_gltf
from hybridbrdf.gltf.fallback import FallbackReport, fit_fallback
from hybridbrdf.gltf.glb import GltfError
from hybridbrdf.gltf.hybrid import HybridMaterial, read_hybrid
from hybridbrdf.gltf.mapping import fa_to_material, material_to_fa
from hybridbrdf.gltf.meshes import Mesh, plane, read_obj, uv_sphere
from hybridbrdf.gltf.reader import GltfAsset, read_gltf

__all__ = ["FallbackReport", "GltfAsset", "GltfError", "GltfMaterial", "HybridMaterial", "Mesh", "export_gltf",
           "fa_to_material", "fit_fallback", "gltf_eval", "material_to_fa", "plane", "read_gltf", "read_hybrid",
           "read_obj", "uv_sphere"]
