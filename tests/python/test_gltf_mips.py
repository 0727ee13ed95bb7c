"""A minified glTF texture in the tracer reads its mip chain at the ray cone's footprint (docs/GLTF.md,
"Samplers"; the chain's rule and the level selection are tested by hand in tests/cpp/test_gltf_mips.cpp).

The asset is gltf_textured_asset.py's quad (48 x 32 pixels, no normal map) with a 64 x 64 one-texel
black and white checkerboard as its sRGB baseColorTexture: every pixel at lod between 1 and 2 (a
48 x 48 board is the smallest whose pixels all read no level 0; 40 x 40 does), so each reads
levels 1 and 2 only, both uniform linear 0.5, stored as the sRGB byte
round(255 (1.055 0.5^(1/2.4) - 0.055)) = 188. The reference: the same quad with a 1 x 1 texture of
188, rendered alike (direct light, no jitter: deterministic). The two breakages, measured through
the renders they amount to: the chain averaged in sRGB bytes makes level 1 the byte 128 (the quad
of a 1 x 1 texture of 128: 0.42 of the image's peak); the level of detail one level too
fine reads as a 32 x 32 board does (near pixels mix in level 0: 0.18). The C++ test shows both
failing in the code itself."""

import json

import numpy as np

from hybridbrdf.render import render
import gltf_textured_asset as asset

N = 64
CHECKER = np.repeat((np.indices((N, N)).sum(0) % 2 * 255).astype(np.uint8)[:, :, None], 3, 2)
HALF_GREY = np.full((1, 1, 3), 188, np.uint8)  # the checkerboard's level 1, by hand


def traced(tmp_path, name, texels, min_filter=9987, mip_lod=True):
    def edit(doc):
        doc["samplers"][0]["minFilter"] = min_filter

    glb = asset.write_asset(tmp_path / f"{name}.glb", images={"base": (asset.png_bytes(texels), "image/png")},
                            normal=False, edit=edit)
    s = asset.scene(glb)
    s["mip_lod"] = mip_lod
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(s))
    return np.asarray(render(str(path))[0], np.float64)


def test_minified_checkerboard_reads_its_uniform_level_1(tmp_path):
    checker, grey = traced(tmp_path, "checker", CHECKER), traced(tmp_path, "grey", HALF_GREY)
    on = grey.sum(-1) > 0
    assert on.sum() > 1000
    err = np.abs(checker - grey)[on].max() / grey.max()
    assert err <= 1e-6, err


def test_min_filter_without_mips_reads_level_0(tmp_path):
    """minFilter LINEAR (no mipmap mode) builds no chain: minified pixels read level 0 bilinearly,
    as with the ray cones off ("mip_lod": false, the point footprint), and not the grey of level 1."""
    linear = traced(tmp_path, "linear", CHECKER, min_filter=9729)
    point = traced(tmp_path, "point", CHECKER, mip_lod=False)
    grey = traced(tmp_path, "grey", HALF_GREY)
    assert np.array_equal(linear, point)
    on = grey.sum(-1) > 0
    assert np.abs(linear - grey)[on].max() / grey.max() > 0.1
