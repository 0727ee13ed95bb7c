"""The raster frame against the tracer on a glTF scene of three objects, the issue-59 target
(bench/raster_vs_tracer.py, small): a hybrid model material, a textured folder with a normal map
painted from the same model, and an unbound glTF material (f_a of its factors) in one frame.

Mean relative error over the bench's lit pixels (exact-geometry mask: silhouettes, light
terminators and the normal map's horizon band excluded; docs/RASTER.md) at most 1%, and no pixel
NaN or negative in either image. Also: the frame plan refuses a full model material of another
model file beside a textured folder (the generated files would define the same names)."""

import json
import sys

import numpy as np
import pytest

import hybridbrdf
from helpers import ROOT, RASTER_TOOL, skip_without_raster_tool, lavapipe_without_llvm_passes  # noqa: F401 (autouse fixture)

TOOL = RASTER_TOOL
MODEL = ROOT / "results" / "rgl54_fast.safetensors"

skip_without_raster_tool()
if not MODEL.exists():
    pytest.skip("results/rgl54_fast.safetensors is not in this checkout", allow_module_level=True)
pytest.importorskip("trimesh")
sys.path.insert(0, str(ROOT / "bench"))
import raster_vs_tracer  # noqa: E402


def test_gltf_scene_meets_the_issue_target(tmp_path):
    """~7 s of CPU (the paint, the tracer's and the raster's 160 x 96 frames). Measured: mean 8.7e-4,
    p99 2.5e-2 over 8,067 lit pixels. Seen failing with the normal map's y flipped in the fragment
    stage (mean 0.019: the mapped sphere is a third of the lit pixels) and with the textured cases
    starting one case early (the model material drawn as the folder: mean 3.2)."""
    r = raster_vs_tracer.compare(width=160, height=96, segments=32, model=MODEL, tool=TOOL, keep=tmp_path)
    print(r)
    assert r["lit_pixels"] > 0.7 * r["covered_pixels"] > 0.3 * 160 * 96
    assert r["mean_rel"] <= 0.01, r
    assert all(r[k] == 0 for k in r if k.endswith(("_nan", "_negative"))), r
    # All three kinds are in the frame: the plan's cases (model material first, then the folder)
    plan = hybridbrdf.raster.shaders.frame_plan(str(tmp_path / "scene.json"))
    assert plan.case_constants == ["HBRDF_MATERIAL_CC_IBIZA_SUNSET_RGB_RGL"] and plan.normal is not None
    assert plan.cases == ["objects[0]:Uniform", "objects[0]:Painted"]


def test_textured_beside_another_models_material_is_refused(tmp_path):
    """A full model material of a model file other than the folder's: one line naming it."""
    folder = raster_vs_tracer.paint_folder(tmp_path, MODEL)
    other = ROOT / "results" / "rgl54_hybrid_32x2.safetensors"
    if not other.exists():
        pytest.skip("results/rgl54_hybrid_32x2.safetensors is not in this checkout")
    scene = {"camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 40, "width": 8,
                        "height": 8},
             "materials": {"t": {"type": "textured", "svbrdf": str(folder)},
                           "m": {"type": "model", "file": str(other), "material": "paper_white_rgb.rgl"}},
             "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "t"},
                         {"type": "sphere", "center": [2, 0, 0], "radius": 1, "material": "m"}]}
    (tmp_path / "s.json").write_text(json.dumps(scene))
    with pytest.raises(hybridbrdf.errors.InputFileError, match="is not the model of"):
        hybridbrdf.raster.shaders.frame_plan(str(tmp_path / "s.json"))
