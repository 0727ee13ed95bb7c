"""The raster frame draws a glTF asset's own textures as the tracer does (docs/RASTER.md, docs/GLTF.md
"Textures"): the pygltflib quad of gltf_textured_asset.py (two-colour sRGB baseColor, a roughness
ramp and metallic step through a NEAREST mirrored sampler, a tilted normal map with its scale),
unbound (f_a of the mapping per pixel in the fragment stage) and bound to a scene material (the
asset's normal map kept), under lavapipe with the validation layer, against the tracer's
deterministic direct light (bench/raster_vs_tracer.py's comparison: relative error per channel,
floor 1e-3 of the image's largest value) over the pixels on the quad.

The texture unit filters 8-bit values as 8-bit values (docs/RASTER.md, "the tracer, textured"), so
the bound is the issue's 1% on the mean. Measured (lavapipe, 1,320 pixels): unbound 3.4e-3 mean,
1.6e-2 at the 99th percentile; bound 2.5e-4, 2.7e-3. Seen failing (then reverted): the frame's sRGB
decode skipped (baseColor uploaded UNORM: mean 1.30), the metallic and roughness channels swapped
in the shader (0.87) and the normal map's y flipped in the shader (0.23; bound 0.13). Mirrored uv
island (TANGENT.w = -1 or the sign from the uvs): 3.4e-3 mean, bound model 3.3e-5; the shader
ignoring the handedness attribute fails them (0.33, bound model 0.053), w read as +1 by the loader
fails the sign by hand. Not caught: the normal map's b_s built right-handed (paper_white's network
is near mirror-symmetric, the bound comparison stays at 3.3e-5)."""

import json

import numpy as np
import pytest

import hybridbrdf
from hybridbrdf.render import render
from helpers import ROOT, RASTER_TOOL, skip_without_raster_tool, lavapipe_without_llvm_passes  # noqa: F401 (autouse fixture)
import gltf_textured_asset as asset

TOOL = RASTER_TOOL
skip_without_raster_tool()
pytest.importorskip("pygltflib")


def both(tmp_path, s, language="glsl"):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(s))
    traced = np.asarray(render(str(path))[0], np.float64)
    return draw(path, tmp_path, language), traced


def draw(path, tmp_path, language="glsl"):
    stats = hybridbrdf.raster.draw_frame(path, tmp_path / "frame.exr", validation=True, lavapipe=True, tool=TOOL,
                                         keep_shaders=tmp_path / f"shaders_{language}", language=language)
    assert stats["device"].startswith("llvmpipe")
    drawn = np.asarray(hybridbrdf.render.read_exr(tmp_path / "frame.exr"), np.float64)
    assert np.isfinite(drawn).all() and (drawn >= 0).all()
    return drawn


def compare(drawn, traced):
    _, on = asset.reference(lambda u, v: (np.zeros(3), np.ones(3) * 1.5, (0.5, 0.5)), normal=False)
    err = (np.abs(drawn - traced) / np.maximum(traced, 1e-3 * traced.max()))[on]
    return err.mean(), np.quantile(err, 0.99)


def test_unbound_textured_material_matches_tracer(tmp_path):
    glb = asset.write_asset(tmp_path / "quad.glb")
    drawn, traced = both(tmp_path, asset.scene(glb))
    mean, p99 = compare(drawn, traced)
    print(mean, p99)
    assert mean <= 0.01, (mean, p99)
    plan = hybridbrdf.raster.shaders.frame_plan(str(tmp_path / "scene.json"))
    assert plan.gltf_slots == 3


def test_bound_material_keeps_normal_map_in_frame(tmp_path):
    glb = asset.write_asset(tmp_path / "quad.glb")
    paint = {"type": "analytic", "kd": [0.5, 0.3, 0.2], "eta": [1.8, 1.7, 1.6], "alpha": [0.3, 0.3]}
    drawn, traced = both(tmp_path, asset.scene(glb, bind={"Painted": "paint"}, materials={"paint": paint}))
    mean, p99 = compare(drawn, traced)
    print(mean, p99)
    assert mean <= 0.01, (mean, p99)


def test_bound_model_material_keeps_normal_map_in_frame(tmp_path):
    """A full model material (its network, the per-pixel form at the normal map's wo) in the asset's
    normal-map frame."""
    model = ROOT / "results" / "rgl54_fast.safetensors"
    if not model.exists():
        pytest.skip("results/rgl54_fast.safetensors is not in this checkout")
    glb = asset.write_asset(tmp_path / "quad.glb")
    drawn, traced = both(tmp_path, asset.scene(glb, bind={"Painted": f"{model}#paper_white_rgb.rgl"}))
    mean, p99 = compare(drawn, traced)
    print(mean, p99)
    assert mean <= 0.01, (mean, p99)


@pytest.mark.parametrize("bind", ["unbound", "model"])
def test_hlsl_frame_matches_glsl_frame_and_tracer(tmp_path, bind):
    """The generated HLSL in the fragment stage (codegen/raster.hlsl.j2 through glslang's HLSL front
    end: each slot a Texture2D and its own SamplerState at one binding, the tool's combined image
    sampler) draws the asset's textures as the GLSL stage does: against the tracer with the GLSL
    frame's bound, and against the GLSL frame itself. Unbound: the mapping of baseColor,
    metallicRoughness and the normal map in the fragment stage; bound to a full model material: its
    per-pixel form at the normal map's wo. Measured: the same frame bit for bit in both; against the
    tracer 3.4e-3 mean (unbound), 3.7e-5 (model). Seen failing (then reverted) with metallic and
    roughness swapped in the HLSL stage's mapping (unbound 0.87), every slot read through slot 0's
    sampler (the NEAREST mirrored one lost: 0.45) and the normal map's y flipped there (unbound 0.23,
    model 0.047)."""
    model = ROOT / "results" / "rgl54_fast.safetensors"
    if bind == "model" and not model.exists():
        pytest.skip("results/rgl54_fast.safetensors is not in this checkout")
    glb = asset.write_asset(tmp_path / "quad.glb")
    s = asset.scene(glb, bind={"Painted": f"{model}#paper_white_rgb.rgl"}) if bind == "model" else asset.scene(glb)
    hlsl, traced = both(tmp_path, s, "hlsl")
    source = (tmp_path / "shaders_hlsl" / "frame.hlsl").read_text()
    assert "Texture2D<float4> hbrdf_gltf_2;" in source and "SamplerState hbrdf_gltf_2_sampler;" in source
    mean, p99 = compare(hlsl, traced)
    print(bind, "hlsl against the tracer", mean, p99)
    assert mean <= 0.01, (mean, p99)
    glsl = draw(tmp_path / "scene.json", tmp_path)
    _, on = asset.reference(lambda u, v: (np.zeros(3), np.ones(3) * 1.5, (0.5, 0.5)), normal=False)
    apart = (np.abs(hlsl - glsl) / np.maximum(glsl, 1e-3 * glsl.max()))[on]
    print(bind, "hlsl against glsl", apart.max())
    assert apart.max() <= 1e-5, apart.max()


def drop_tangent(doc):
    del doc["meshes"][0]["primitives"][0]["attributes"]["TANGENT"]


@pytest.mark.parametrize("tangent", ["given", "from_uvs"])
def test_mirrored_uv_island_matches_tracer_and_the_sign_by_hand(tmp_path, tangent):
    """A mirrored uv island (u decreasing along +x; TANGENT w = -1, or no TANGENT and the sign from
    the uvs): the frame draws it as the tracer (the handedness a flat vertex attribute, b = w n x t),
    and a light from the image's top brightens the quad in the frame as on the unmirrored one."""
    edit = drop_tangent if tangent == "from_uvs" else None
    glb = asset.write_asset(tmp_path / "mirrored.glb", mirrored=True, edit=edit)
    drawn, traced = both(tmp_path, asset.scene(glb))
    mean, p99 = compare(drawn, traced)
    print(mean, p99)
    assert mean <= 0.01, (mean, p99)

    def lit(direction, normal):
        s = asset.scene(asset.write_asset(tmp_path / f"m{normal}.glb", normal=normal, mirrored=True, edit=edit))
        s["lights"] = [{"type": "directional", "direction": direction, "irradiance": [1, 1, 1]}]
        return both(tmp_path, s)[0].sum()
    above, below = [0.0, 0.8, 0.6], [0.0, -0.8, 0.6]
    assert lit(above, True) > 1.05 * lit(above, False)
    assert lit(below, True) < 0.95 * lit(below, False)


def test_mirrored_island_bound_model_matches_tracer(tmp_path):
    """A full model material on the mirrored island: the network sees the frame the tracer gives it,
    left-handed there (b and the normal map's b_s both carry w)."""
    model = ROOT / "results" / "rgl54_fast.safetensors"
    if not model.exists():
        pytest.skip("results/rgl54_fast.safetensors is not in this checkout")
    glb = asset.write_asset(tmp_path / "mirrored.glb", mirrored=True)
    drawn, traced = both(tmp_path, asset.scene(glb, bind={"Painted": f"{model}#paper_white_rgb.rgl"}))
    mean, p99 = compare(drawn, traced)
    print(mean, p99)
    assert mean <= 0.01, (mean, p99)
