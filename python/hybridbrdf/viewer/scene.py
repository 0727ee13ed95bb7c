"""The scene the page shows, as the path tracer renders it, and the page's tone map: what the page
(:mod:`hybridbrdf.viewer.page`) and its measured references (:mod:`hybridbrdf.viewer.measured`)
share, and what the tests compare the page with."""

from __future__ import annotations

import math
import os
from typing import Any, Dict, Optional

import numpy as np

from hybridbrdf.viewer import lighting as viewer_lighting

#: Camera of the page and of :func:`tracer_scene` (docs/RENDERING.md's pinhole): a unit sphere at
#: the origin seen from +z.
CAMERA = {"position": [0.0, 0.0, 4.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov_deg": 32.0}
#: Irradiance of the directional light on a surface facing it: pi, so that a white Lambert
#: surface facing the light has radiance kd.
SUN_IRRADIANCE = math.pi
#: Angular diameter of the sun disc in the tracer's environment (the page's light is a direction).
SUN_SIZE_DEG = 0.5
#: Defaults of the page's light (degrees; azimuth from -z toward +x, as the tracer's sky).
DEFAULT_SUN = {"elevation": 35.0, "azimuth": 150.0}


def tracer_scene(model_file: str, material: str, *, width: int = 256, height: int = 256, analytic: bool = False,
                 light: str = "environment", environment: Optional[Dict[str, Any]] = None, rotation: float = 0.0,
                 elevation: float = DEFAULT_SUN["elevation"], azimuth: float = DEFAULT_SUN["azimuth"],
                 spp: int = 16, resolution=(2048, 1024), svbrdf: Optional[str] = None) -> Dict[str, Any]:
    """A scene (docs/RENDERING.md) that the path tracer renders as the page shows ``material``: the
    page's camera, the unit sphere, direct light only (``max_depth`` 1), and the page's light:
    ``light="environment"``: ``environment`` (a scene environment object, default the page's sky,
    :data:`viewer_lighting.DEFAULT_ENVIRONMENT`) turned by ``rotation`` degrees about +y;
    ``light="sun"``: the sun alone at (``elevation``, ``azimuth``) with irradiance
    :data:`SUN_IRRADIANCE`, a disc of :data:`SUN_SIZE_DEG` in an otherwise black sky of
    ``resolution``. ``analytic``: the material's f_a (``"evaluate": "analytic"``). ``svbrdf``: a
    textured material's folder shown instead of ``material`` (``{"type": "textured"}``, bilinear)."""
    if light == "environment":
        env = dict(environment or viewer_lighting.DEFAULT_ENVIRONMENT, rotation_deg=rotation)
    elif light == "sun":
        env = {"type": "sky", "sun_elevation_deg": elevation, "sun_azimuth_deg": azimuth,
               "sun_irradiance": SUN_IRRADIANCE, "sun_size_deg": SUN_SIZE_DEG, "sky_intensity": 0.0,
               "ground_albedo": 0.0, "resolution": list(resolution)}
    else:
        raise ValueError(f"light: expected 'environment' or 'sun', got {light!r}")
    return {
        "camera": dict(CAMERA, width=width, height=height),
        "environment": env,
        "materials": {"m": {"type": "model", "file": os.path.abspath(model_file), "material": material,
                            "evaluate": "analytic" if analytic else "full"} if svbrdf is None else
                      {"type": "textured", "svbrdf": os.path.abspath(svbrdf), "filter": "bilinear",
                       "evaluate": "analytic" if analytic else "full"}},
        "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
        "spp": spp, "max_depth": 1, "sampler": "mis", "seed": 0,
    }


def srgb8(linear: np.ndarray, exposure: float = 0.0) -> np.ndarray:
    """What the page (and ``hbrdf render --png`` with ``--tonemap clamp``) shows for linear radiance:
    2^exposure x, clipped to [0, 1], the sRGB OETF, rounded to 8 bits."""
    x = np.clip(np.asarray(linear, dtype=np.float64) * 2.0 ** exposure, 0.0, 1.0)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.round(s * 255.0).astype(np.uint8)
