"""A picture of fitted materials: each material as three spheres under the example scene's sky,
the exact (measured) material, the hybrid model and its analytic part f_a alone, rendered by
libhybridbrdf's path tracer and labelled (``hbrdf fit`` writes one next to the model).

    from hybridbrdf.render.preview import render_preview
    render_preview("out/synthetic.safetensors", ["synthetic:all"], "out/synthetic.png")

Each sphere is a scene of its own (in one shared scene the spheres would shadow and light each
other), seen from far away through a narrow field of view; the measured reference goes through
its Python reader (docs/RENDERING.md, "measured"), which dominates the time.
"""

from __future__ import annotations

import time
import math
import os
import tempfile
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
from hybridbrdf.model.file import load_model
from hybridbrdf.render.tracer import render, write_png
from hybridbrdf.sources import expand_sources, open_source

#: The sky of scenes/sphere_env.json, the example scene (kept here: an installed package has no scenes/).
EXAMPLE_SKY = {"type": "sky", "sun_elevation_deg": 35, "sun_azimuth_deg": 60, "sun_irradiance": [6, 5.6, 5],
               "sun_size_deg": 2, "sky_intensity": 1, "turbidity": 3, "resolution": [1024, 512]}

#: Rows of the picture: label, and the scene material of a model material (None: the measured source).
ROWS = (("exact", None), ("hybrid", "full"), ("f_a alone", "analytic"))

#: A preview shows at most this many materials (the first ones of the model): beyond it the spheres
#: get too small to see and the measured readers' time grows with every material.
MAX_MATERIALS = 8

#: Samples per pixel of an exact (measured) sphere relative to the model's spheres (see preview_scenes).
EXACT_SPP_FACTOR = 4

_FRAME = 2.3        # world units across one sphere's square image (radius 1: a small margin)
_DISTANCE = 60.0     # camera distance: the view directions over a sphere differ by < 2 degrees


def sphere_scene(material: Dict[str, object], pixels: int = 72, spp: int = 16) -> Dict[str, object]:
    """One sphere of ``material`` (a scene material: model, measured or analytic) under the
    example sky, framed by a square image of ``pixels``. Each sphere is a scene of its own: in
    one shared scene the spheres would shadow and light each other, differently by position."""
    fov = 2.0 * math.degrees(math.atan(0.5 * _FRAME / _DISTANCE))
    return {
        "camera": {"position": [0, 0, _DISTANCE], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": fov,
                   "width": pixels, "height": pixels},
        "environment": dict(EXAMPLE_SKY),
        "materials": {"sphere": material},
        "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "sphere"}],
        "spp": spp, "max_depth": 3, "sampler": "mis", "seed": 0, "threads": 0,
    }


def preview_scenes(model_path: str, materials: Sequence[str], sources: Sequence[Optional[str]],
                   pixels_per_sphere: int = 72, spp: int = 16) -> List[Tuple[int, int, Dict[str, object]]]:
    """(row, column, scene) of each sphere of a preview: one column per material, rows as
    :data:`ROWS`. ``sources[i]`` is the measured source of ``materials[i]`` (a path or
    synthetic:NAME) or None, whose "exact" sphere is then left out."""
    if len(materials) != len(sources):
        raise ValueError(f"preview: {len(materials)} materials but {len(sources)} sources")
    out = []
    for c, (name, source) in enumerate(zip(materials, sources)):
        for r, (_, evaluate) in enumerate(ROWS):
            samples = spp
            if evaluate is None:
                if source is None:
                    continue
                material: Dict[str, object] = {"type": "measured", "source": source}
                # A measured material is sampled by cosine (docs/RENDERING.md): its glossy lobes are
                # noisy at the models' spp, so it gets EXACT_SPP_FACTOR times as many samples.
                samples = spp * EXACT_SPP_FACTOR
            else:
                material = {"type": "model", "file": os.path.abspath(model_path), "material": name,
                            "evaluate": evaluate}
            out.append((r, c, sphere_scene(material, pixels_per_sphere, samples)))
    return out


def render_grid(model_path: str, materials: Sequence[str], sources: Sequence[Optional[str]],
                pixels_per_sphere: int = 72, spp: int = 16) -> np.ndarray:
    """The preview's linear radiance image (rows x pixels, columns x pixels, 3); a left-out
    sphere's square is black."""
    n = pixels_per_sphere
    image = np.zeros((len(ROWS) * n, len(materials) * n, 3), dtype=np.float32)
    for r, c, scene in preview_scenes(model_path, materials, sources, pixels_per_sphere, spp):
        tile, _ = render(scene)
        image[r * n:(r + 1) * n, c * n:(c + 1) * n] = np.asarray(tile)
    return image


def render_preview(model_path: str, sources: Sequence[str], png_path: str, pixels_per_sphere: int = 72,
                   spp: int = 16) -> Dict[str, object]:
    """Renders the first :data:`MAX_MATERIALS` materials of ``model_path`` (fitted to
    ``sources``, the SOURCE arguments of ``hbrdf fit``: files, folders, globs or synthetic:NAME)
    and writes a labelled PNG to ``png_path``. Returns {"materials", "seconds", "path"}.

    A source that names several materials (a folder, synthetic:all) is expanded; materials of
    the model that no source names (the base of a sparse fit) get no "exact" sphere."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt


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
    image = render_grid(model_path, names, exact, pixels_per_sphere, spp)
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
