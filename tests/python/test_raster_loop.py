"""The raster frame's light loop as lavapipe needs it (codegen/raster.frag.j2, codegen/raster.hlsl.j2;
docs/RASTER.md "Cost"): llvmpipe runs a loop body under a lane mask and leaves the loop only when
no lane is left, so a loop whose exit test comes first (a ``for`` loop's, or the test a ``continue``
jumps to, which NIR moves to the top) runs its whole body, every BRDF evaluation in it, once more
than there are lights, all lanes off: on M2 the 32x2 frame's CPU time was 1.58x at one light and
1.35x at two (``bench/raster_frame.py`` before and after; ``bench/raster_anatomy.py``'s
loop-test-top). The fragment stage therefore tests at the end of the body and has no ``continue``; what the loop computes is unchanged (test_raster.py's frames against the library
and the tracer, one and two lights). Seen failing with the template's former ``for`` loop."""

import json
import re

import pytest

from hybridbrdf.raster.shaders import frame_plan, write_frame_sources

from helpers import ROOT

MODEL = ROOT / "results" / "rgl54_fast.safetensors"


def light_loop(source: str) -> str:
    """The code from the light count to the end of the fragment stage, comments left out."""
    start = source.index("n_lights =")
    return re.sub(r"//[^\n]*", "", source[start:])


@pytest.mark.skipif(not MODEL.exists(), reason="results/rgl54_fast.safetensors is not in this checkout")
@pytest.mark.parametrize("language", ["glsl", "hlsl"])
@pytest.mark.parametrize("per_pixel", [True, False])
def test_light_loop_tests_at_the_end_without_continue(tmp_path, language, per_pixel):
    scene = {"camera": {"position": [0, 0.9, 3.4], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 45,
                        "width": 8, "height": 8},
             "environment": {"type": "constant", "radiance": [0, 0, 0]},
             "lights": [{"type": "directional", "direction": [0, 1, 0], "irradiance": [1, 1, 1]}],
             "materials": {"m": {"type": "model", "file": str(MODEL), "material": "paper_white_rgb.rgl",
                                 "evaluate": "full"},
                           "a": {"type": "analytic", "kd": 0.4, "eta": 1.8, "alpha": 0.3}},
             "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"},
                         {"type": "sphere", "center": [2, 0, 0], "radius": 1, "material": "a"}],
             "max_depth": 1}
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    _, frag = write_frame_sources(frame_plan(str(path)), tmp_path, language, per_pixel)
    loop = light_loop(frag.read_text())
    assert "continue" not in loop and not re.search(r"\bfor\s*\(", loop), loop
    assert re.search(r"if \(n_lights > 0u?\) while \(true\) \{", loop), loop
    # The exit test is the body's last statement: the closing brace of the loop follows it.
    assert re.search(r"if \(\+\+k >= n_lights\) break;\s*\}", loop), loop
    assert loop.count("raster_brdf(") == 2  # the normal-mapped and the plain call, both inside the loop
