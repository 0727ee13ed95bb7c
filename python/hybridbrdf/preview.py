"""A picture of fitted materials: each material as three spheres under the example scene's sky,
the exact (measured) material, the hybrid model and its analytic part f_a alone, rendered by
libhybridbrdf's path tracer and labelled (``hbrdf fit`` writes one next to the model).

    from hybridbrdf.preview import render_preview
    render_preview("out/synthetic.safetensors", ["synthetic:all"], "out/synthetic.png")

The spheres are rendered in one scene, a grid seen from far away (a narrow field of view, so
every sphere is seen from nearly the same direction); the measured reference goes through its
Python reader (docs/RENDERING.md, "measured"), which dominates the time.
"""

from __future__ import annotations

import math
import os
import tempfile
from typing import Dict, List, Optional, Sequence

import numpy as np

#: The sky of scenes/sphere_env.json, the example scene (kept here: an installed package has no scenes/).
EXAMPLE_SKY = {"type": "sky", "sun_elevation_deg": 35, "sun_azimuth_deg": 60, "sun_irradiance": [6, 5.6, 5],
               "sun_size_deg": 2, "sky_intensity": 1, "turbidity": 3, "resolution": [1024, 512]}

#: Rows of the picture: label, and the scene material of a model material (None: the measured source).
ROWS = (("exact", None), ("hybrid", "full"), ("f_a alone", "analytic"))

#: A preview shows at most this many materials (the first ones of the model): beyond it the spheres
#: get too small to see and the measured readers' time grows with every material.
MAX_MATERIALS = 8

_SPACING = 2.3       # sphere centres (radius 1)
_DISTANCE = 60.0     # camera distance: the view directions over the grid differ by < 10 degrees


def preview_scene(model_path: str, materials: Sequence[str], sources: Sequence[Optional[str]],
                  pixels_per_sphere: int = 72, spp: int = 16) -> Dict[str, object]:
    """The scene of a preview: one column per material, rows as :data:`ROWS`. ``sources[i]``
    is the measured source of ``materials[i]`` (a path or synthetic:NAME) or None, whose
    "exact" sphere is then left out."""
    if len(materials) != len(sources):
        raise ValueError(f"preview: {len(materials)} materials but {len(sources)} sources")
    cols, rows = len(materials), len(ROWS)
    height_world = rows * _SPACING
    fov = 2.0 * math.degrees(math.atan(0.5 * height_world / _DISTANCE))
    scene_materials: Dict[str, object] = {}
    objects: List[Dict[str, object]] = []
    for c, (name, source) in enumerate(zip(materials, sources)):
        x = (c - 0.5 * (cols - 1)) * _SPACING
        for r, (_, evaluate) in enumerate(ROWS):
            y = (0.5 * (rows - 1) - r) * _SPACING
            key = f"m{c}_{r}"
            if evaluate is None:
                if source is None:
                    continue
                scene_materials[key] = {"type": "measured", "source": source}
            else:
                scene_materials[key] = {"type": "model", "file": os.path.abspath(model_path), "material": name,
                                        "evaluate": evaluate}
            objects.append({"type": "sphere", "center": [x, y, 0], "radius": 1, "material": key})
    return {
        "camera": {"position": [0, 0, _DISTANCE], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": fov,
                   "width": cols * pixels_per_sphere, "height": rows * pixels_per_sphere},
        "environment": dict(EXAMPLE_SKY),
        "materials": scene_materials,
        "objects": objects,
        "spp": spp, "max_depth": 3, "sampler": "mis", "seed": 0, "threads": 0,
    }


def render_preview(model_path: str, sources: Sequence[str], png_path: str, pixels_per_sphere: int = 72,
                   spp: int = 16) -> Dict[str, object]:
    """Renders the first :data:`MAX_MATERIALS` materials of ``model_path`` (fitted to
    ``sources``, the SOURCE arguments of ``hbrdf fit``: files, folders, globs or synthetic:NAME)
    and writes a labelled PNG to ``png_path``. Returns {"materials", "seconds", "path"}.

    A source that names several materials (a folder, synthetic:all) is expanded; materials of
    the model that no source names (the base of a sparse fit) get no "exact" sphere."""
    import time

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt

    from hybridbrdf.model_file import load_model
    from hybridbrdf.render import render, write_png
    from hybridbrdf.sources import expand_sources, open_source

    model = load_model(model_path)
    specs = expand_sources(sources)
    everything = list(model.materials)
    names = everything[:MAX_MATERIALS]
    if len(specs) == len(everything):
        # A fit names its materials in the order of its sources (and may suffix a name to keep it unique).
        exact = specs[:MAX_MATERIALS]
    else:
        by_name = {}
        for spec in specs:
            by_name.setdefault(open_source(spec).name, spec)
        exact = [by_name.get(n) for n in names]
    t0 = time.perf_counter()
    image, _ = render(preview_scene(model_path, names, exact, pixels_per_sphere, spp))
    seconds = time.perf_counter() - t0

    with tempfile.TemporaryDirectory(prefix="hbrdf_preview_") as tmp:
        raw = os.path.join(tmp, "raw.png")
        write_png(np.asarray(image), raw, tonemap="aces")
        pixels = mpimg.imread(raw)
    cols, rows = len(names), len(ROWS)
    fig = plt.figure(figsize=(1.2 * cols + 0.9, 1.2 * rows + 0.5), dpi=100)
    ax = fig.add_axes([0.9 / (1.2 * cols + 0.9), 0.02, 1.2 * cols / (1.2 * cols + 0.9), 1.2 * rows / (1.2 * rows + 0.5)])
    ax.imshow(pixels, extent=(0, cols, rows, 0))
    ax.set_xticks([c + 0.5 for c in range(cols)])
    ax.set_xticklabels([n.replace("_", " ") for n in names], fontsize=7)
    ax.xaxis.tick_top()
    ax.set_yticks([r + 0.5 for r in range(rows)])
    ax.set_yticklabels([label for label, _ in ROWS], fontsize=8)
    ax.tick_params(length=0)
    for spine in ax.spines.values():
        spine.set_visible(False)
    os.makedirs(os.path.dirname(os.path.abspath(png_path)), exist_ok=True)
    fig.savefig(png_path, facecolor="white")
    plt.close(fig)
    return {"materials": names, "seconds": seconds, "path": png_path}
