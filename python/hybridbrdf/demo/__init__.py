"""``hbrdf demo``: a look at the analytic BRDF f_a, in-plane slices and directional albedo of a few
built-in materials (:mod:`~hybridbrdf.demo.slices`).

    from hybridbrdf.demo import run_demo
    run_demo("out/analytic_slices.png", samples=200_000)

Its names load on first access (PEP 562): ``hbrdf demo``'s parser reads
:mod:`~hybridbrdf.demo.sizes` (plain Python) without NumPy.
"""

from hybridbrdf.demo.sizes import BYTES_PER_SAMPLE, SAMPLES
from hybridbrdf.exports import lazy_names, public_face

#: The names whose module imports NumPy, loaded on first access.
_LAZY = lazy_names(["DEMO_MATERIALS", "directional_albedo", "in_plane", "run_demo"], "hybridbrdf.demo.slices")

__all__ = ["BYTES_PER_SAMPLE", "DEMO_MATERIALS", "SAMPLES", "directional_albedo", "in_plane", "run_demo"]

__getattr__, __dir__ = public_face(__name__, globals(), _LAZY)
