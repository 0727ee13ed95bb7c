"""Textured (spatially varying) materials: the asset folder, its maps and their decode, texel
lookup and evaluation (docs/SVBRDF.md; spec/model.json, ``svbrdf``).

    sv = hybridbrdf.svbrdf.load_svbrdf("out/painted")
    f = sv.eval(uv, wi, wo)          # uv (N, 2) in [0, 1]^2, wi and wo (N, 3): (N, 3)
"""

from hybridbrdf.svbrdf.asset import SVBRDF, load_svbrdf
from hybridbrdf.svbrdf.entries import SVBRDFError

__all__ = ["SVBRDF", "SVBRDFError", "load_svbrdf"]
