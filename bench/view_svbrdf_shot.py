#!/usr/bin/env python3
"""The screenshot of ``hbrdf view --svbrdf`` in docs/VIEWER.md and docs/SVBRDF.md (docs/figures/view_svbrdf.png).

Writes the page of the example textured material (``python bench/textured_scene.py`` paints it into
out/textured_example/painted: paper_white, vch_golden_yellow in a soft disc, a metallic paint in
stripes, from results/rgl54_fast.safetensors) and photographs it in headless chromium with software
WebGL2 (the flags of tests/python/test_view.py), every sample drawn at load (``readback=1``).

    python bench/view_svbrdf_shot.py [--svbrdf out/textured_example/painted] [--png docs/figures/view_svbrdf.png]
        [--hash "rotation=-60&spp=64"]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.parse

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: tests/python/test_view.py's CHROMIUM_FLAGS with a longer virtual-time budget and a window for the picture.
FLAGS = ["--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--enable-webgl",
         "--ignore-gpu-blocklist", "--disable-dev-shm-usage", "--no-first-run", "--virtual-time-budget=120000",
         "--hide-scrollbars", "--window-size=1180,900"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--svbrdf", default=str(ROOT / "out" / "textured_example" / "painted"),
                    help="textured material folder (default: bench/textured_scene.py's)")
    ap.add_argument("--png", default=str(ROOT / "docs" / "figures" / "view_svbrdf.png"), help="screenshot to write")
    ap.add_argument("--hash", default="rotation=-60&spp=64", help="the page's URL parameters (docs/VIEWER.md)")
    args = ap.parse_args()
    if not os.path.isfile(os.path.join(args.svbrdf, "svbrdf.json")):
        print(f"{args.svbrdf}: no textured material; run python bench/textured_scene.py first", file=sys.stderr)
        return 1
    exe = os.environ.get("HBRDF_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        print("chromium not found (scripts/setup.sh installs it)", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        page = os.path.join(tmp, "view_svbrdf.html")
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "hybridbrdf.cli", "view", "--svbrdf", args.svbrdf, "--out", page],
                       check=True)
        url = "file://" + urllib.parse.quote(page) + "#backend=webgl2&readback=1&" + args.hash
        shot = os.path.join(tmp, "shot.png")
        subprocess.run([exe, *FLAGS, f"--user-data-dir={os.path.join(tmp, 'profile')}", f"--screenshot={shot}", url],
                       check=True, capture_output=True, timeout=600)
        os.makedirs(os.path.dirname(os.path.abspath(args.png)), exist_ok=True)
        shutil.move(shot, args.png)  # complete before it replaces the old picture
    print(f"wrote {args.png} ({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
