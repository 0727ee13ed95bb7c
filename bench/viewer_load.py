#!/usr/bin/env python3
"""How long ``hbrdf view``'s page takes to load: milliseconds from navigation to the first picture
(the page writes them on ``body``'s ``data-load-ms`` when its first frame is done), for pages of
N materials and each backend, in headless chromium on SwiftShader (WebGL2 and WebGPU in software:
the CPU compiles the shader and draws; a GPU browser compiles and draws faster, so these are upper
bounds of the browser's own share). The target (issue 32): a 100-material collection loads in
under 2 s.

"Done" means drawn, not only submitted: the page is opened with ``readback=1&spp=1`` (one sample
per pixel, the first frame), so the page reads its pixels back before it writes ``data-load-ms``;
a WebGL2 draw call returns before SwiftShader has compiled the shader or drawn anything. Real
time, no virtual time: chromium is driven over its DevTools pipe and read once the page's title
says it loaded (tests/python/test_view_webgpu.py's driver).

A page of N materials is built from a fitted model by repeating its materials under new names
(the page's cost depends on the number of materials and the network, not on their values); the
network, the environment map (the default sky) and the shader are those of any page. Each size is
opened ``--runs`` times (a fresh browser profile each time) and the median printed, with the page's
bytes and chromium's whole wall time (process start to DOM dump, which includes starting chromium).

    python bench/viewer_load.py [--model results/rgl54_hybrid_32x2.safetensors] [--sizes 1,100,400] [--runs 3]
                                [--backends webgl2,webgpu]
"""

from __future__ import annotations

import argparse
import os
import pathlib
import re
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.parse

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))

from hybridbrdf.model.file import HybridModel, load_model  # noqa: E402
from hybridbrdf.viewer.page import write_page  # noqa: E402
from test_view_webgpu import open_page_devtools  # noqa: E402  (chromium over DevTools, WebGL2 and WebGPU flags)


def collection(model: HybridModel, n: int) -> HybridModel:
    """``model`` with its materials repeated (``NAME+k``) or cut to ``n`` materials."""
    m = len(model.materials)
    rows = [i % m for i in range(n)]
    tensors = {k: (np.asarray(v)[rows] if k.startswith("materials.") else v) for k, v in model.tensors.items()}
    info = []
    for j, i in enumerate(rows):
        row = dict(model.material_info[i])
        row["name"] = row["name"][:58] + (f"+{j // m}" if j >= m else "")
        info.append(row)
    return HybridModel(model.arch, info, tensors, model.training)


def load_ms(page: pathlib.Path, backend: str) -> tuple:
    t = time.perf_counter()
    title, status, dom, _ = open_page_devtools(str(page), f"backend={backend}&readback=1&spp=1", fresh=True)
    wall = time.perf_counter() - t
    if title != "hbrdf view: ok":
        raise SystemExit(f"{page}: the page did not load ({backend}): {title}")
    return float(re.search(r'data-load-ms="(\d+)"', dom).group(1)), wall


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=str(ROOT / "results" / "rgl54_hybrid_32x2.safetensors"))
    ap.add_argument("--sizes", default="1,100,400", help="materials per page, comma-separated")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--backends", default="webgl2,webgpu")
    args = ap.parse_args()
    base = load_model(args.model)
    print(f"model {args.model}: {base.kind} {base.arch['width']}x{base.arch['depth']}; "
          f"chromium headless on SwiftShader; {os.cpu_count()} cores")
    print(f"{'materials':>9} {'page MiB':>9} {'backend':>8} {'first picture ms (median)':>26} {'runs':>20} "
          f"{'chromium wall s':>16}")
    with tempfile.TemporaryDirectory() as d:
        for n in (int(x) for x in args.sizes.split(",")):
            model_path = pathlib.Path(d) / f"m{n}.safetensors"
            collection(base, n).save(str(model_path))
            page = pathlib.Path(d) / f"p{n}.html"
            write_page(str(model_path), str(page))
            for backend in args.backends.split(","):
                runs = [load_ms(page, backend) for _ in range(args.runs)]
                ms = [r[0] for r in runs]
                print(f"{n:>9} {page.stat().st_size / 2**20:>9.2f} {backend:>8} {statistics.median(ms):>26.0f} "
                      f"{','.join(f'{x:.0f}' for x in ms):>20} {statistics.median(r[1] for r in runs):>16.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
