"""The raster frame and the tracer read a minified glTF texture through the same mip chain
(docs/GLTF.md, "Samplers"; docs/RASTER.md): test_gltf_mips.py's quad with its 64 x 64 one-texel sRGB
checkerboard (every pixel at lod between 1 and 2), drawn by hbrdf_raster under lavapipe with the
validation layer (the chain gltf_mip_chain built, uploaded level by level) against the tracer at the
ray cone's footprint, per pixel over the quad (bench/raster_vs_tracer.py's relative error, floor 1e-3
of the image's largest value).

Measured (lavapipe): 1.4e-3 mean, 1.4e-3 at the 99th percentile; the tracer reading level 0
instead ("mip_lod": false: the tracer before the chain) 0.36 mean, 3.5 at the 99th."""

import json

import numpy as np
import pytest

import hybridbrdf
from hybridbrdf.render import render
from helpers import RASTER_TOOL, skip_without_raster_tool, lavapipe_without_llvm_passes  # noqa: F401 (autouse fixture)
import gltf_textured_asset as asset
from test_gltf_mips import CHECKER

TOOL = RASTER_TOOL
skip_without_raster_tool()
pytest.importorskip("pygltflib")


def errors(drawn, traced):
    on = traced.sum(-1) > 0
    err = (np.abs(drawn - traced) / np.maximum(traced, 1e-3 * traced.max()))[on]
    return err.mean(), np.quantile(err, 0.99)


def test_minified_checkerboard_frame_matches_tracer(tmp_path):
    glb = asset.write_asset(tmp_path / "checker.glb", images={"base": (asset.png_bytes(CHECKER), "image/png")},
                            normal=False)
    s = asset.scene(glb)
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(s))
    traced = np.asarray(render(str(path))[0], np.float64)
    stats = hybridbrdf.raster.draw_frame(path, tmp_path / "frame.exr", validation=True, lavapipe=True, tool=TOOL)
    assert stats["device"].startswith("llvmpipe")
    drawn = np.asarray(hybridbrdf.render.read_exr(tmp_path / "frame.exr"), np.float64)
    assert np.isfinite(drawn).all() and (drawn >= 0).all()
    mean, p99 = errors(drawn, traced)
    s["mip_lod"] = False  # the tracer before the chain: level 0 bilinear
    path.write_text(json.dumps(s))
    level0 = errors(drawn, np.asarray(render(str(path))[0], np.float64))
    print("chain", mean, p99, "level 0", *level0)
    assert mean <= 0.01 and p99 <= 0.05, (mean, p99)
    assert level0[0] > 10 * mean, (level0, mean)
