#!/usr/bin/env python3
"""How far out float32 places geometry well enough (docs/RENDERING.md, "Geometry float32 can place";
the limits of cpp/include/hybridbrdf/render/limits.hpp).

A unit sphere on a Lambert plane under the sky, the camera at distance d = 4.24 from its look_at
point, 64x48 pixels at 64 spp. It prints the mean relative difference of the image's lower half
(the plane, the sphere's contact shadow) from the same render with a plane of size 1e3 (same seed,
so that sampling noise cancels and only geometry error is left), for plane sizes up to the limit
(half-size 5e4 d = 212132), then for the whole scene translated away from the origin (the camera's
limit is 500 d); and the noise floor (seed 1 against seed 0) for scale. Limits refuse the sizes
beyond them, so those are not rendered. About 10 s on 2 cores.

    python bench/render_float_limits.py
"""

from __future__ import annotations

import numpy as np

from hybridbrdf.render.tracer import render


def scene(size: float, offset: float = 0.0, seed: int = 0) -> dict:
    """The scene, every point moved by `offset` along x."""
    o = np.array([offset, 0.0, 0.0])
    return {"camera": {"position": list(o + [0, 0.6, 4.2]), "look_at": list(o), "width": 64, "height": 48},
            "environment": {"type": "sky", "sun_elevation_deg": 35, "sun_azimuth_deg": 60, "resolution": [256, 128]},
            "materials": {"m": {"type": "analytic", "kd": 0.8}, "s": {"type": "analytic", "kd": 0.3, "alpha": 0.1}},
            "objects": [{"type": "plane", "center": list(o + [0, -1, 0]), "normal": [0, 1, 0], "size": size, "material": "m"},
                        {"type": "sphere", "center": list(o), "radius": 1, "material": "s"}],
            "spp": 64, "max_depth": 3, "seed": seed}


def main() -> None:
    ref, _ = render(scene(1e3))

    def rel(img: np.ndarray) -> float:
        return float(np.abs(img - ref)[24:].mean() / ref[24:].mean())

    print(f"noise floor (seed 1 against seed 0): {rel(render(scene(1e3, seed=1))[0]):.4f}")
    for size in (1e4, 1e5, 4e5):
        print(f"plane of size {size:g} (half-size {size / 2 / 4.243:.3g} d): {rel(render(scene(size))[0]):.4f}")
    for offset in (1e2, 1e3, 2e3):
        print(f"scene translated by {offset:g} ({offset / 4.243:.3g} d): {rel(render(scene(1e3, offset))[0]):.4f}")


if __name__ == "__main__":
    main()
