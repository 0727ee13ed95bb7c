#!/usr/bin/env python3
"""How close ``hbrdf view``'s page (WebGL2, headless chromium on SwiftShader) draws the picture the
path tracer renders for the same scene: the figures behind tests/python/test_view.py's bound,
MAD(page, tracer seed 0) <= MAD(tracer seed 0, tracer seed 1) + 1, over the pixels the sphere covers
entirely, in 8-bit sRGB units (96 x 96; the page 256 samples per pixel under the map, the tracer 64),
and the same page against the tracer's map turned the other way (what a wrong rotation would give).

    python bench/viewer_vs_tracer.py
"""

from __future__ import annotations

import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))

import test_view as tv  # noqa: E402  (the tests' page, tracer and mask helpers)
from hybridbrdf.viewer.scene import tracer_scene  # noqa: E402

CASES = [("paper_white_rgb.rgl", False, 70), ("cc_ibiza_sunset_rgb.rgl", False, -40), ("cc_ibiza_sunset_rgb.rgl", True, 0)]


def main() -> int:
    mask = tv.interior_mask()
    print(f"model {tv.MODEL}; {tv.SIZE} x {tv.SIZE}; page 256 spp (WebGL2), tracer {tv.SPP} spp; MAD in 8-bit sRGB")
    print(f"{'material':26} {'f':>8} {'rotation':>8} {'page-t0':>8} {'t0-t1':>8} {'mirrored':>9}")
    with tempfile.TemporaryDirectory() as d:
        page = pathlib.Path(d) / "page.html"
        subprocess.run([sys.executable, "-m", "hybridbrdf.cli", "view", tv.MODEL, "--out", str(page)], check=True,
                       capture_output=True)
        for material, analytic, rotation in CASES:
            img, scene, _ = tv.page_state(page, f"material={material}&analytic={int(analytic)}&rotation={rotation}&spp=256")
            t0, t1 = tv.tracer_pixels(scene, 0), tv.tracer_pixels(scene, 1)
            mirrored = "-"
            if rotation:
                other = tracer_scene(tv.MODEL, material, width=tv.SIZE, height=tv.SIZE, analytic=analytic,
                                            rotation=-rotation)
                mirrored = f"{tv.mad(img, tv.tracer_pixels(other), mask):.2f}"
            print(f"{material:26} {'f_a' if analytic else 'full':>8} {rotation:>8} {tv.mad(img, t0, mask):>8.2f} "
                  f"{tv.mad(t0, t1, mask):>8.2f} {mirrored:>9}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
