"""libhybridbrdf's BC4/BC5 encoder (``_core.bc_encode_level``, the writer's default for one- and
two-channel maps; docs/TEXTURES.md, "Encoders"), checked against texture2ddecoder's decoder (an
independent implementation) and against the min/max palette the PyPI encoders use."""

from __future__ import annotations

import numpy as np
import pytest

from hybridbrdf import _core
from hybridbrdf.svbrdf import bcenc

texture2ddecoder = pytest.importorskip("texture2ddecoder")  # the test extra (scripts/setup.sh)

#: A 4 x 4 block of a soft mask's steep edge (bench/svbrdf_mixture.py's stripes, 512 x 512): seven
#: values about 27 steps apart along the block's diagonal.
RAMP = np.array([[49, 73, 100, 127], [73, 100, 127, 155], [100, 127, 155, 182], [127, 155, 182, 206]], np.uint8)


def _decoded(blocks: bytes, w: int, h: int) -> np.ndarray:
    """Texels of BC4 blocks by texture2ddecoder (BGRA: the red channel is byte 2)."""
    return np.frombuffer(texture2ddecoder.decode_bc4(blocks, w, h), np.uint8).reshape(h, w, 4)[..., 2]


def _min_max_error(block: np.ndarray) -> int:
    """Squared error of the eight-level palette from the block's minimum to its maximum (floored
    sevenths, as the decoders compute them), each texel at its nearest level."""
    lo, hi = int(block.min()), int(block.max())
    if lo == hi:
        return 0
    palette = np.array([((7 - i) * hi + i * lo) // 7 for i in range(8)])
    return int((np.abs(block.reshape(-1, 1).astype(int) - palette[None]).min(axis=1) ** 2).sum())


def test_a_steep_ramp_falls_on_a_palette_that_extends_past_the_block():
    blocks = _core.bc_encode_level("bc4", RAMP[..., None])
    got = _decoded(blocks, 4, 4).astype(int)
    error = ((got - RAMP) ** 2).sum()
    assert error <= 13 and np.abs(got - RAMP).max() <= 2, (error, got)
    # The min/max palette (quicktex's, bc7enc's BC4) leaves 749 and 11 steps: what the search fixes.
    old = bcenc.encode_decode(RAMP, "bc4", "quicktex").astype(int)
    assert ((old - RAMP) ** 2).sum() > 20 * 13


def test_never_worse_than_the_min_max_palette_and_decoded_alike():
    rng = np.random.default_rng(4)
    y, x = np.mgrid[0:64, 0:64] / 64.0
    smooth = 127.5 + 127.5 * np.sin(2 * np.pi * (3 * x + 2 * y + 0.3 * np.sin(9 * y)))
    noise = rng.integers(0, 256, (64, 64))
    edges = np.clip((x * 64 % 16 - 6) * 40, 0, 255)  # ramps between runs of 0 and of 255
    for image in (smooth, noise, edges, np.clip(rng.normal(128, 3, (64, 64)), 0, 255)):
        image = np.rint(image).astype(np.uint8)
        got = _decoded(_core.bc_encode_level("bc4", image[..., None]), 64, 64)
        assert np.array_equal(got, bcenc.decode_blocks(_core.bc_encode_level("bc4", image[..., None]), "bc4", 64, 64)[..., 0])
        for by in range(0, 64, 4):
            for bx in range(0, 64, 4):
                src, dec = image[by:by + 4, bx:bx + 4], got[by:by + 4, bx:bx + 4]
                assert ((dec.astype(int) - src) ** 2).sum() <= _min_max_error(src), (by, bx, src, dec)


def test_weights_of_exactly_zero_and_one_stay_exact():
    rng = np.random.default_rng(5)
    # Blocks of a few 0 or 255 texels among values near them: the cheapest palette for the others
    # would move a 0 to 1 or a 255 to 254 (a layer faintly back where it was painted out).
    texels = rng.integers(1, 40, (128, 128)).astype(np.uint8)
    texels[rng.random((128, 128)) < 0.2] = 0
    high = rng.integers(215, 255, (128, 128)).astype(np.uint8)
    high[rng.random((128, 128)) < 0.2] = 255
    image = np.concatenate([texels, high], axis=1)
    got = _decoded(_core.bc_encode_level("bc4", image[..., None]), 256, 128)
    assert np.array_equal(got[image == 0], np.zeros((image == 0).sum(), np.uint8))
    assert np.array_equal(got[image == 255], np.full((image == 255).sum(), 255, np.uint8))


def test_a_weights_map_of_soft_masks_within_a_step_where_min_max_is_not():
    """The writer's BC5 on two layers' weights (bench/svbrdf_compression.py's masks): the mean
    error over the channels' texels strictly between 0 and 1 at most 1.6 steps (1.39); quicktex's
    2.54, etcpak's 3.21 (the mixed texels' median cMAE against the measurements +5.3% with
    quicktex, +3.0% with this)."""
    from hybridbrdf.fit.painting import composite

    size = 512
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / size
    smooth = lambda e0, e1, v: (lambda t: t * t * (3 - 2 * t))(np.clip((v - e0) / (e1 - e0), 0, 1))  # noqa: E731
    masks = [1 - smooth(0.26, 0.34, np.hypot(x - 0.38, y - 0.5)), smooth(-0.25, 0.25, np.sin(2 * np.pi * 3 * (x + y)))]
    stored = np.rint(np.clip(composite(masks)[..., :2], 0, 1) * 255).astype(np.uint8)
    mixed = (stored > 0) & (stored < 255)
    assert bcenc.DEFAULT_ENCODER["bc5"] == "hybridbrdf"
    for encoder, bound in (("hybridbrdf", 1.6), ("quicktex", -1.6)):
        got = bcenc.encode_decode(stored, "bc5", encoder).astype(int)
        mean = np.abs(got - stored)[mixed].mean()
        assert (mean <= bound) if bound > 0 else (mean > -bound), (encoder, mean)


def test_edge_blocks_and_refusals():
    image = (np.arange(5 * 7 * 2).reshape(5, 7, 2) * 3).astype(np.uint8)
    blocks = _core.bc_encode_level("bc5", image)
    # A partial edge block repeats the level's last row and column (what a sampler never reads).
    assert blocks == _core.bc_encode_level("bc5", np.pad(image, ((0, 3), (0, 1), (0, 0)), mode="edge"))
    with pytest.raises(ValueError, match="encodes bc4 and bc5"):
        _core.bc_encode_level("bc7", image)
    with pytest.raises(ValueError, match="C >= 2"):
        _core.bc_encode_level("bc5", image[..., :1])
