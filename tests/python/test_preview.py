"""The fit preview (hybridbrdf.render.preview): each cell of its grid shows the material and the
evaluation its labels say.

Oracle: a model whose network is switched off (f_c = exp(-80) = 0, f_g = sigmoid(80) = 1) holds
synthetic plastic's exact parameters, so for plastic the exact, hybrid and f_a spheres are the
same BRDF and must agree within Monte Carlo noise; a second column pairs those parameters with
synthetic:velvet's measurement, whose exact sphere must then differ from its model spheres. A
swapped row or column, or a cell rendered with another material, fails one of the two."""

import numpy as np
import pytest
import torch

from hybridbrdf import _core
from hybridbrdf.model.file import HybridModel
from hybridbrdf.model.networks import build_model
from hybridbrdf.render.preview import ROWS, preview_scenes, render_grid

pytestmark = pytest.mark.skipif(not getattr(_core, "HAVE_RENDERER", False), reason="build without the renderer")

PIXELS = 48


def switched_off_model(path):
    mod = build_model("hybrid", 2, 8, 1, 4, "hardgelu")
    for i in range(2):  # synthetic plastic (sources/synthetic.py): kd (0.45, 0.22, 0.08), eta 1.5, alpha 0.2
        mod.set_analytic(i, (0.45, 0.22, 0.08), (1.5, 1.5, 1.5), (0.2, 0.2))
    with torch.no_grad():
        mod.mlp.out.weight.zero_()
        mod.mlp.out.bias[0:3] = -80.0
        mod.mlp.out.bias[3:6] = 80.0
    HybridModel.from_module(mod, ["plastic", "velvet"], ["test", "test"], {"steps": 0}).save(str(path))


def cell_means(image, cols):
    """Mean radiance of the disc of each sphere (rows x cols x 3)."""
    h, w = PIXELS, PIXELS
    yy, xx = np.mgrid[0:h, 0:w]
    disc = (xx - w / 2 + 0.5) ** 2 + (yy - h / 2 + 0.5) ** 2 < (0.35 * w) ** 2
    return np.array([[image[r * h:(r + 1) * h, c * w:(c + 1) * w][disc].mean(axis=0) for c in range(cols)]
                     for r in range(len(ROWS))])


def test_preview_cells_show_what_their_labels_say(tmp_path):
    model = tmp_path / "m.safetensors"
    switched_off_model(model)
    image = render_grid(str(model), ["plastic", "velvet"], ["synthetic:plastic", "synthetic:velvet"],
                        pixels_per_sphere=PIXELS, spp=64)
    assert image.shape == (len(ROWS) * PIXELS, 2 * PIXELS, 3)
    m = cell_means(image, 2)
    exact, hybrid, analytic = (m[[label for label, _ in ROWS].index(k)] for k in ("exact", "hybrid", "f_a alone"))
    assert (m > 0.01).all(), m  # every sphere is lit and where its cell is
    # Plastic: one BRDF three times; the model's two rows take the same paths (same scene, same
    # seed, same sampler), the measured row cosine sampling: 64 spp over ~900 pixels.
    np.testing.assert_allclose(hybrid[0], analytic[0], rtol=1e-4)
    np.testing.assert_allclose(exact[0], hybrid[0], rtol=0.03)
    # Velvet measured against plastic's parameters: visibly different.
    assert np.abs(exact[1] - hybrid[1]).max() / hybrid[1].max() > 0.1, (exact[1], hybrid[1])
    np.testing.assert_allclose(hybrid[1], hybrid[0], rtol=0.03)  # the same model material in both columns


def test_a_material_without_a_source_gets_no_exact_sphere(tmp_path):
    model = tmp_path / "m.safetensors"
    switched_off_model(model)
    cells = preview_scenes(str(model), ["plastic", "velvet"], ["synthetic:plastic", None])
    assert len(cells) == 2 * len(ROWS) - 1
    assert (0, 1) not in {(r, c) for r, c, _ in cells}  # velvet's exact sphere
    assert [s["materials"]["sphere"]["type"] for r, c, s in cells if r == 0] == ["measured"]
