"""The environment that ``hbrdf view`` lights its sphere with: the path tracer's own environment
(docs/RENDERING.md, "Environments"), read and baked by the tracer's scene loader, so that the page and
``hbrdf render`` light with the same texels.

The page stores the map as float32 texels (nearest lookup, as the tracer's EnvironmentLight) and
samples it in proportion to luminance x sin(theta), as the tracer does; a map wider than
:data:`MAX_ENV_WIDTH` is reduced by area averaging (rows weighted by their solid angle, so that the
power of every region, a small sun included, is kept) and the page says so.
"""

from __future__ import annotations

import base64
import json
import math
import os
from typing import Any, Dict, Optional

import numpy as np
from hybridbrdf import _core

#: The page's default light: the tracer's procedural sky (a sun disc of irradiance pi, so that a
#: white Lambert surface facing it has radiance 1 from the sun, and a dim blue sky and grey ground).
DEFAULT_ENVIRONMENT: Dict[str, Any] = {
    "type": "sky", "sun_elevation_deg": 35.0, "sun_azimuth_deg": 150.0, "sun_irradiance": math.pi,
    "sun_size_deg": 1.0, "sky_intensity": 0.25, "turbidity": 3.0, "ground_albedo": 0.3, "resolution": [512, 256],
}
#: Widest map the page carries (texels; height is half of it for an equirect map). 1024 x 512
#: float32 RGB is 6 MiB of texels, 8 MiB of base64 text: more would slow the page's load.
MAX_ENV_WIDTH = 1024


def _area_matrix(n_in: int, n_out: int, weights: Optional[np.ndarray] = None) -> np.ndarray:
    """(n_out, n_in) averaging matrix: output cell j is the mean of the input cells it overlaps,
    each by its overlap length (times ``weights``, e.g. the rows' solid angle)."""
    edges_in = np.arange(n_in + 1) / n_in
    edges_out = np.arange(n_out + 1) / n_out
    lo = np.maximum(edges_out[:-1, None], edges_in[None, :-1])
    hi = np.minimum(edges_out[1:, None], edges_in[None, 1:])
    m = np.clip(hi - lo, 0.0, None)
    if weights is not None:
        m = m * weights[None, :]
    return m / m.sum(axis=1, keepdims=True)


def reduce_map(image: np.ndarray, width: int) -> np.ndarray:
    """``image`` (H, W, 3) averaged down to ``width`` x ``width // 2`` texels (no change when it is not
    wider). Rows are weighted by sin(theta) at their centre, the solid angle the tracer gives them,
    so the reduced map delivers the same irradiance up to the texel-shape change."""
    h, w, _ = image.shape
    if w <= width:
        return np.ascontiguousarray(image, dtype=np.float32)
    out_h = max(2, width // 2)
    sin_rows = np.sin(np.pi * (np.arange(h) + 0.5) / h)
    my = _area_matrix(h, out_h, sin_rows)
    mx = _area_matrix(w, width)
    # Rows, then columns: two matrix products (one three-operand einsum would loop over all four sizes).
    rows = (my @ image.astype(np.float64).reshape(h, w * 3)).reshape(out_h, w, 3)
    return np.einsum("xw,owc->oxc", mx, rows, optimize=True).astype(np.float32)


def environment_spec(env: Optional[str]) -> Dict[str, Any]:
    """The scene's environment object for ``hbrdf view --env``: ``None`` or ``"sky"`` the default sky,
    anything else an ``.exr`` or ``.hdr`` map (made absolute, so the printed scene renders from
    anywhere; the tracer's reader checks it)."""
    if env is None or env == "sky":
        return dict(DEFAULT_ENVIRONMENT)
    return {"type": "file", "file": os.path.abspath(env)}


def page_environment(spec: Dict[str, Any], origin: str = "--env") -> Dict[str, Any]:
    """What the page carries of the environment ``spec``: its texels (base64 float32 RGB, rows from
    the zenith down), their size, the spec (for the printed scene; without ``rotation_deg``, which the
    page sets) and whether the texels are the tracer's exactly (false when reduced)."""
    spec = {k: v for k, v in spec.items() if k != "rotation_deg"}
    image = np.asarray(_core.render_environment(json.dumps(spec), os.getcwd(), origin), dtype=np.float32)
    reduced = reduce_map(image, MAX_ENV_WIDTH)
    return {"width": int(reduced.shape[1]), "height": int(reduced.shape[0]), "spec": spec,
            "exact": reduced.shape == image.shape, "source_size": [int(image.shape[1]), int(image.shape[0])],
            "rgb": base64.b64encode(np.ascontiguousarray(reduced, dtype="<f4").tobytes()).decode("ascii")}


__all__ = ["DEFAULT_ENVIRONMENT", "MAX_ENV_WIDTH", "environment_spec", "page_environment", "reduce_map"]
