"""Mip chains of textured materials (docs/SVBRDF.md, "Mip chains"; hybridbrdf.svbrdf.mips).

The reference for a level's texel is independent of the chain's code: the mean, over the level-0
texels of its footprint, of each texel's BRDF evaluated alone (nearest lookup, float64 PyTorch).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

import hybridbrdf as hb
from hybridbrdf.evaluate.metrics import metric_directions
from hybridbrdf.svbrdf import SVBRDF, load_svbrdf
from hybridbrdf.svbrdf.mips import chain_length, level_size, lod_from_footprint

from helpers import saved_random_model

SIZE = 16  # 5 levels: 16, 8, 4, 2, 1


def _directions(n=1500, seed=3):
    wi, wo = metric_directions(n, seed)
    return np.asarray(wi, np.float64), np.asarray(wo, np.float64)


def _weights(rng, h, w, layers):
    """Weights of `layers` layers that sum to at most 1, with pure texels and soft mixtures."""
    raw = rng.dirichlet(np.full(layers, 0.7), size=(h, w))
    pure = rng.uniform(size=(h, w)) < 0.3
    raw[pure] = np.eye(layers)[rng.integers(0, layers, size=int(pure.sum()))]
    out = np.zeros((h, w, 3), np.float32)
    out[..., :layers - 1] = raw[..., 1:]
    return out


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    _, m = saved_random_model(tmp_path_factory.mktemp("mips"), "hybrid", output_layer="material", energy_bound=True)
    return m


def _footprint_mean(sv, level, col, row, wi, wo, how="python"):
    """Mean of the level-0 texels' BRDFs over level `level`'s texel (col, row): each evaluated alone
    (nearest lookup at level 0), in float64 PyTorch, or by libhybridbrdf's own path (`how`) so that
    its float32 evaluation error cancels and what remains is the chain's."""
    block = 2 ** level
    ys, xs = np.mgrid[row * block:(row + 1) * block, col * block:(col + 1) * block]
    centres = np.stack([(xs.ravel() + 0.5) / sv.size[0], (ys.ravel() + 0.5) / sv.size[1]], axis=1)
    uv = np.repeat(centres, len(wi), axis=0)
    wi_all, wo_all = np.tile(wi, (len(centres), 1)), np.tile(wo, (len(centres), 1))
    if how == "python":
        f = sv.eval(uv, wi_all, wo_all, filter="nearest", dtype=torch.float64)
    else:
        f = hb._core.Svbrdf(sv.path).eval(uv.astype(np.float32), wi_all.astype(np.float32), wo_all.astype(np.float32),
                                          "nearest", batched=(how == "batched")).astype(np.float64)
    return f.reshape(len(centres), len(wi), 3).mean(axis=0)


def _level_texel(sv, level, col, row, wi, wo, how):
    w, h = level_size(sv.size, level)
    uv = np.repeat([[(col + 0.5) / w, (row + 0.5) / h]], len(wi), axis=0)
    lod = np.full(len(wi), float(level), np.float32)
    if how == "python":
        return sv.eval(uv, wi, wo, lod=level, dtype=torch.float64)
    core = hb._core.Svbrdf(sv.path)
    args = (uv.astype(np.float32), wi.astype(np.float32), wo.astype(np.float32), "bilinear")
    return core.eval(*args, batched=(how == "batched"), lod=lod).astype(np.float64)


@pytest.mark.parametrize("how", ["python", "scalar", "batched"])
def test_a_level_of_weights_and_kd_is_the_mean_brdf_of_its_footprint(model, tmp_path, how):
    """f is linear in the weights and in kd: a level's texel of a material whose maps are weights and
    kd is exactly the mean of its footprint's BRDFs (float32 storage: 1e-6 relative), in Python and
    in libhybridbrdf's scalar and batched lookups."""
    rng = np.random.default_rng(5)
    weights = _weights(rng, SIZE, SIZE, 3)
    maps = [{}, {"kd": rng.uniform(0, 1, (SIZE, SIZE, 3)).astype(np.float32)}, {}]
    SVBRDF(model, model.materials[:3], (SIZE, SIZE), weights, maps).with_mips().save(tmp_path / "sv", format="exr")
    sv = load_svbrdf(tmp_path / "sv")
    assert sv.levels == chain_length(sv.size) == 5 and hb._core.Svbrdf(sv.path).levels == 5
    wi, wo = _directions(300)
    for level, col, row in [(1, 3, 5), (2, 1, 2), (3, 1, 0), (4, 0, 0)]:
        ref = _footprint_mean(sv, level, col, row, wi, wo, how)
        got = _level_texel(sv, level, col, row, wi, wo, how)
        assert np.abs(got - ref).max() <= 1e-6 * np.abs(ref).max(), (level, np.abs(got - ref).max() / np.abs(ref).max())


def test_plain_averaging_of_weights_is_not_what_the_chain_does(model, tmp_path):
    """The check above can fail: a chain built from un-normalised weights above 1 (the lookup divides
    them by their sum; averaging them raw is not the mean BRDF) misses the footprint mean."""
    rng = np.random.default_rng(6)
    weights = np.zeros((SIZE, SIZE, 3), np.float32)
    weights[..., 0] = rng.uniform(0.5, 1.0, (SIZE, SIZE))
    weights[..., 1] = rng.uniform(0.5, 1.0, (SIZE, SIZE))  # sums above 1: divided per texel
    sv = SVBRDF(model, model.materials[:3], (SIZE, SIZE), weights, [{}, {}, {}]).with_mips()
    raw = weights.reshape(8, 2, 8, 2, 3).mean(axis=(1, 3))
    assert not np.allclose(sv.mips[0][0], raw, atol=1e-3)  # the chain normalised first
    wi, wo = _directions(400)
    ref = _footprint_mean(sv, 1, 2, 3, wi, wo)
    got = _level_texel(sv, 1, 2, 3, wi, wo, "python")
    assert np.abs(got - ref).max() <= 1e-6 * np.abs(ref).max()


def test_the_alpha_rules_filter_what_they_say(model):
    """Rough and smooth texels in one footprint, weighted by their layer: the level's alpha is the
    weighted mean of sqrt(alpha), squared (the default), of alpha, or the root of the mean of
    alpha^2; a texel of weight 0 does not count. (Which rule is nearest the footprint's mean BRDF
    is measured in bench/svbrdf_mips.py, not asserted here.)"""
    alpha = np.array([[[0.05, 0.1], [0.5, 0.4]], [[0.3, 0.3], [0.9, 0.02]]], np.float32)
    weights = np.zeros((2, 2, 3), np.float32)
    weights[..., 0] = [[0.0, 0.5], [0.75, 1.0]]  # layer 1's weight; the alpha map is layer 0's (1 - w)
    sv = SVBRDF(model, model.materials[:2], (2, 2), weights, [{"alpha": alpha}, {}])
    w0 = 1 - weights[..., 0].astype(np.float64)
    expect = {"perceptual": lambda a: (np.sum(w0[..., None] * np.sqrt(a), axis=(0, 1)) / w0.sum()) ** 2,
              "value": lambda a: np.sum(w0[..., None] * a, axis=(0, 1)) / w0.sum(),
              "mean_square": lambda a: np.sqrt(np.sum(w0[..., None] * a * a, axis=(0, 1)) / w0.sum())}
    for rule, ref in expect.items():
        got = sv.with_mips(rule).mips[0][1][0]["alpha"][0, 0]
        np.testing.assert_allclose(got, ref(alpha.astype(np.float64)), rtol=1e-6)
    assert not np.allclose(expect["perceptual"](alpha), expect["value"](alpha), rtol=1e-3)


def test_trilinear_lookup_mixes_the_two_levels_around_lod(model, tmp_path):
    rng = np.random.default_rng(8)
    weights = _weights(rng, SIZE, SIZE, 2)
    maps = [{"alpha": rng.uniform(0.05, 0.6, (SIZE, SIZE, 2)).astype(np.float32)}, {}]
    SVBRDF(model, model.materials[:2], (SIZE, SIZE), weights, maps).with_mips().save(tmp_path / "sv", format="exr")
    sv = load_svbrdf(tmp_path / "sv")
    uv = rng.uniform(-0.5, 1.5, (300, 2))
    a, b, mid = (sv.texels(uv, "bilinear", lod) for lod in (2.0, 3.0, 2.25))
    for key in a:
        np.testing.assert_allclose(mid[key], 0.75 * a[key] + 0.25 * b[key], rtol=1e-6, atol=1e-7)
    top, beyond, nan = (sv.texels(uv, "bilinear", lod) for lod in (4.0, 9.0, np.nan))
    for key in a:
        assert np.array_equal(top[key], beyond[key])  # clamped to the 1x1 level
        assert np.array_equal(nan[key], sv.texels(uv, "bilinear")[key])  # NaN reads level 0
    wi, wo = _directions(300)
    lod = rng.uniform(-1, 5, 300).astype(np.float32)
    ref = sv.eval(uv, wi, wo, lod=lod.astype(np.float64))
    core = hb._core.Svbrdf(sv.path)
    args = (uv.astype(np.float32), wi.astype(np.float32), wo.astype(np.float32), "bilinear")
    for batched in (False, True):
        got = core.eval(*args, batched=batched, lod=lod)
        assert np.all(np.abs(got - ref) <= 2e-4 * np.abs(ref).max(axis=1, keepdims=True) + 1e-6)


def test_lod_from_a_footprint_is_log2_of_its_longer_axis_in_texels(model):
    sv = SVBRDF(model, [model.materials[0]], (64, 32), None, [{}])
    lod = lod_from_footprint(np.array([[4 / 64, 0.0], [0.0, 0.0]]), np.array([[0.0, 1 / 32], [0.0, 8 / 32]]), sv.size)
    np.testing.assert_allclose(lod, [2.0, 3.0])


def test_png_chain_round_trips_within_a_quantisation_step(model, tmp_path):
    rng = np.random.default_rng(9)
    weights = _weights(rng, SIZE, SIZE, 2)
    maps = [{"kd": rng.uniform(0, 1, (SIZE, SIZE, 3)).astype(np.float32)}, {}]
    sv = SVBRDF(model, model.materials[:2], (SIZE, SIZE), weights, maps).with_mips()
    sv.save(tmp_path / "png", format="png")
    back = load_svbrdf(tmp_path / "png")
    index = json.loads((tmp_path / "png" / "svbrdf.json").read_text())
    assert index["format_version"] == 2 and index["levels"] == 5
    assert all(len(e["mips"]) == 4 for e in index["maps"])
    for (w0, m0), (w1, m1) in zip(sv.mips, back.mips):
        assert np.abs(w0 - w1).max() <= 0.5 / 255 + 1e-7
        assert np.abs(m0[0]["kd"] - m1[0]["kd"]).max() <= 0.01  # sRGB steps are at most 0.0125 wide (at 1)


def _chained_folder(model, tmp_path):
    rng = np.random.default_rng(2)
    sv = SVBRDF(model, model.materials[:2], (8, 4), _weights(rng, 4, 8, 2), [{}, {"kd": np.full((4, 8, 3), 0.3, np.float32)}])
    sv.with_mips().save(tmp_path / "sv", format="png")
    return tmp_path / "sv"


def _edit(folder, change):
    index = json.loads((folder / "svbrdf.json").read_text())
    change(index)
    (folder / "svbrdf.json").write_text(json.dumps(index))


CHAIN_CORRUPTIONS = [
    ("chain not complete", lambda f: _edit(f, lambda i: (i.update(levels=3), [e.update(mips=e["mips"][:2]) for e in i["maps"]])),
     "mip chain has 1 or 4 levels"),
    ("levels not an integer", lambda f: _edit(f, lambda i: i.update(levels=2.5)), "levels must be an integer"),
    ("a missing level", lambda f: _edit(f, lambda i: i["maps"][0].update(mips=i["maps"][0]["mips"][:-1])), "lists 3 mip files"),
    ("mips in one level", lambda f: _edit(f, lambda i: i.update(levels=1)), "\"mips\" needs \"levels\" above 1"),
    ("level of the wrong size", lambda f: (f / "weights.mip1.png").write_bytes((f / "weights.mip2.png").read_bytes()),
     "the index says 4x2"),
    ("missing level file", lambda f: (f / "weights.mip3.png").unlink(), "no such file"),
    ("level outside the folder", lambda f: _edit(f, lambda i: i["maps"][0]["mips"].__setitem__(0, "../x.png")), "plain file name"),
    ("level in another format", lambda f: _edit(f, lambda i: i["maps"][0]["mips"].__setitem__(0, "weights.mip1.exr")),
     "stored as level 0 is (.png)"),
    ("levels in version 1", lambda f: _edit(f, lambda i: i.update(format_version=1)), "unknown keys ['levels']"),
    ("a level with weights of no layer", lambda f: (f / "weights.mip2.png").write_bytes((f / "layer1_kd.mip2.png").read_bytes()),
     "weights of layers beyond the last (1) must be 0"),
]


@pytest.mark.parametrize("name,corrupt,words", CHAIN_CORRUPTIONS, ids=[c[0] for c in CHAIN_CORRUPTIONS])
def test_malformed_chains_are_refused_in_one_line_by_both_loaders(model, tmp_path, name, corrupt, words):
    folder = _chained_folder(model, tmp_path)
    corrupt(folder)
    _refused_by_both_loaders(folder, words)


def _refused_by_both_loaders(folder, words):
    """Python's loader and libhybridbrdf's (the tracer's) refuse ``folder`` in one line naming it."""
    for load in (load_svbrdf, hb._core.Svbrdf):
        with pytest.raises((hb.InputFileError, ValueError)) as err:
            load(str(folder))
        msg = str(err.value)
        assert words in msg and "\n" not in msg and str(folder) in msg, (load, msg)


def test_chains_need_power_of_two_sides(model):
    sv = SVBRDF(model, [model.materials[0]], (12, 8), None, [{}])
    with pytest.raises(ValueError, match="power-of-two sides, the size is 12x8"):
        sv.with_mips()


# ---- KTX2 maps: the chain in one file per map, GPU block formats (docs/SVBRDF.md, "KTX2 maps") ----
def _ktx2_folder(model, tmp_path, size=16):
    rng = np.random.default_rng(12)
    weights = _weights(rng, size, size, 3)
    smooth = np.linspace(0, 1, size)
    maps = [{"kd": np.stack([np.add.outer(smooth, smooth) / 2] * 3, axis=2).astype(np.float32) * 0.8},
            {"alpha": np.repeat((0.05 + 0.4 * np.outer(smooth, smooth))[..., None], 2, axis=2).astype(np.float32)},
            {"eta": np.full((size, size, 3), 1.6, np.float32)}]
    sv = SVBRDF(model, model.materials[:3], (size, size), weights, maps).with_mips()
    sv.save(tmp_path / "png", format="png")
    sv.save(tmp_path / "ktx2", format="ktx2")
    return tmp_path / "png", tmp_path / "ktx2"


def test_ktx2_maps_hold_the_chain_in_block_formats_and_both_loaders_agree(model, tmp_path):
    import texture2ddecoder  # the test extra (scripts/setup.sh): an independent BC decoder
    from PIL import Image

    from hybridbrdf.svbrdf import bcenc
    from hybridbrdf.svbrdf.ktx2 import read_ktx2

    png, ktx2 = _ktx2_folder(model, tmp_path)
    index = json.loads((ktx2 / "svbrdf.json").read_text())
    formats = {e["file"]: read_ktx2(ktx2 / e["file"]).name for e in index["maps"]}
    assert formats == {"weights.ktx2": "BC5_UNORM_BLOCK", "layer0_kd.ktx2": "BC1_RGB_SRGB_BLOCK",
                       "layer1_alpha.ktx2": "BC5_UNORM_BLOCK", "layer2_eta.ktx2": "BC7_UNORM_BLOCK"}
    # The writer's default kd format, read from the file's own vkFormat field (offset 12): BC1 sRGB (132).
    assert int.from_bytes((ktx2 / "layer0_kd.ktx2").read_bytes()[12:16], "little") == 132
    assert all("mips" not in e for e in index["maps"]) and sorted(p.name for p in ktx2.iterdir()) == sorted(
        list(formats) + ["model.safetensors", "svbrdf.json"])
    a, b = load_svbrdf(png), load_svbrdf(ktx2)
    assert b.levels == a.levels == 5
    for level, ((wa, ma), (wb, mb)) in enumerate(zip([(a.weights, a.maps)] + a.mips, [(b.weights, b.maps)] + b.mips)):
        # The weights read back are the BC5 blocks of the PNG level's bytes (the same 8-bit encode),
        # decoded by texture2ddecoder, an independent decoder: exactly.
        stored = np.asarray(Image.open(png / (f"weights.mip{level}.png" if level else "weights.png")))[..., :2]
        h, w = stored.shape[:2]
        blocks = np.zeros((-(-h // 4) * 4, -(-w // 4) * 4, 2), np.uint8)
        blocks[:h, :w] = stored
        blocks[h:, :w], blocks[:, w:] = blocks[h - 1:h, :w], blocks[:, w - 1:w]  # the edge texels repeated into the pad
        data = bcenc.encode_blocks(blocks, "bc5")
        ref = np.frombuffer(texture2ddecoder.decode_bc5(data, blocks.shape[1], blocks.shape[0]), np.uint8)
        ref = ref.reshape(blocks.shape[0], blocks.shape[1], 4)[:h, :w, [2, 1]] / 255.0  # BGRA: R in byte 2, G in 1
        np.testing.assert_array_equal(wb[..., :2], ref.astype(np.float32))
        # Smooth gradients: a block's channel holds 8 (BC5) or 4 (BC1: kd, 5-6-5 endpoints) levels
        # between its two endpoints, so the error is a fraction of the block's range: BC1's, at most
        # a sixth of it in sRGB (0.056 of kd at level 0; 0.136 at level 2, one block over the whole
        # 0.06-0.7 ramp).
        assert np.abs(ma[1]["alpha"] - mb[1]["alpha"]).max() <= 0.04
        assert np.abs(ma[0]["kd"] - mb[0]["kd"]).max() <= (0.07 if level < 2 else 0.15)
    wi, wo = _directions(400)
    uv = np.random.default_rng(1).uniform(-0.2, 1.2, (len(wi), 2))
    lod = np.random.default_rng(2).uniform(-0.5, 4.5, len(wi)).astype(np.float32)
    ref = b.eval(uv, wi, wo, lod=lod.astype(np.float64), dtype=torch.float64)
    got = hb._core.Svbrdf(str(ktx2)).eval(uv.astype(np.float32), wi.astype(np.float32), wo.astype(np.float32), "bilinear",
                                          batched=True, lod=lod)
    assert np.all(np.abs(got - ref) <= 2e-4 * np.abs(ref).max(axis=1, keepdims=True) + 1e-6)


def _rewrite_ktx2(folder, file, levels_of, vk):
    from hybridbrdf.svbrdf.ktx2 import read_ktx2, vk_format, write_ktx2

    tex = read_ktx2(folder / file)
    write_ktx2(folder / file, levels_of([lv[..., :3] if lv.shape[2] > 3 else lv for lv in tex.levels]), vk_format(vk))


KTX2_CORRUPTIONS = [
    ("kd in one channel", lambda f: _rewrite_ktx2(f, "layer0_kd.ktx2", lambda lv: [x[..., :1] for x in lv], "BC4_UNORM_BLOCK"),
     "BC4_UNORM_BLOCK holds 1 channel(s); this kd map needs 3"),
    ("weights in sRGB", lambda f: _rewrite_ktx2(f, "weights.ktx2", lambda lv: [np.pad(x, ((0, 0), (0, 0), (0, 1))) for x in lv],
                                                "BC7_SRGB_BLOCK"),
     "BC7_SRGB_BLOCK is sRGB-encoded (a sampler decodes it), so its transfer must be srgb, not linear"),
    ("a level short", lambda f: _rewrite_ktx2(f, "layer1_alpha.ktx2", lambda lv: lv[:-1], "BC5_UNORM_BLOCK"),
     "holds 4 mip level(s); the index says 5"),
    ("another size", lambda f: _rewrite_ktx2(f, "layer1_alpha.ktx2", lambda lv: lv[1:], "BC5_UNORM_BLOCK"),
     "map is 8x8; the index says 16x16"),
    ("mips beside KTX2", lambda f: _edit(f, lambda i: i["maps"][0].update(mips=["a.png"] * 4)), "a KTX2 map holds its own mip levels"),
    ("truncated KTX2", lambda f: (f / "weights.ktx2").write_bytes((f / "weights.ktx2").read_bytes()[:100]), "truncated"),
]


@pytest.mark.parametrize("name,corrupt,words", KTX2_CORRUPTIONS, ids=[c[0] for c in KTX2_CORRUPTIONS])
def test_ktx2_maps_the_quantity_cannot_hold_are_refused_by_both_loaders(model, tmp_path, name, corrupt, words):
    _, folder = _ktx2_folder(model, tmp_path)
    corrupt(folder)
    _refused_by_both_loaders(folder, words)


def test_paint_and_convert_write_chains_and_ktx2_on_the_command_line(model, tmp_path):
    from PIL import Image

    from helpers import run_cli_here

    Image.fromarray(np.tile(np.array([[0, 255]], np.uint8), (8, 4)), "L").save(tmp_path / "mask.png")  # 8x8 stripes
    Image.fromarray(np.full((8, 8, 3), 90, np.uint8), "RGB").save(tmp_path / "albedo.png")
    r = run_cli_here("paint", model.path, "--base", model.materials[0], "--layer", f"{model.materials[1]}={tmp_path / 'mask.png'}",
                "--mips", "--format", "ktx2", "--out", str(tmp_path / "painted"))
    assert r.returncode == 0, r.stderr
    assert "8x8 texels, 2 layer(s)" in r.stdout and "ktx2 maps, 4 mip levels" in r.stdout
    r = run_cli_here("paint", model.path, "--base", model.materials[0], "--layer", f"{model.materials[1]}={tmp_path / 'mask.png'}",
                     "--kd", f"0={tmp_path / 'albedo.png'}", "--format", "ktx2", "--out", str(tmp_path / "kd_bc1"))
    assert r.returncode == 0, r.stderr
    r = run_cli_here("convert", str(tmp_path / "kd_bc1"), "--format", "ktx2", "--kd-format", "bc7", "--out", str(tmp_path / "kd_bc7"))
    assert r.returncode == 0, r.stderr
    for folder, vk in (("kd_bc1", 132), ("kd_bc7", 146)):  # BC1_RGB_SRGB_BLOCK, BC7_SRGB_BLOCK: the file's vkFormat
        assert int.from_bytes((tmp_path / folder / "layer0_kd.ktx2").read_bytes()[12:16], "little") == vk, folder
    painted = load_svbrdf(tmp_path / "painted")
    assert painted.levels == 4 and np.allclose(painted.mips[2][0][..., 0], 0.5, atol=1 / 255)  # stripes average to 1/2
    r = run_cli_here("convert", str(tmp_path / "painted"), "--format", "png", "--out", str(tmp_path / "png"))
    assert r.returncode == 0 and load_svbrdf(tmp_path / "png").levels == 4, r.stderr  # the chain kept as it is
    r = run_cli_here("convert", str(tmp_path / "png"), "--format", "exr", "--no-mips", "--out", str(tmp_path / "exr"))
    assert r.returncode == 0 and load_svbrdf(tmp_path / "exr").levels == 1, r.stderr
    Image.fromarray(np.zeros((6, 8), np.uint8), "L").save(tmp_path / "npot.png")
    r = run_cli_here("paint", model.path, "--base", model.materials[0], "--layer", f"{model.materials[1]}={tmp_path / 'npot.png'}",
                "--mips", "--out", str(tmp_path / "npot"))
    assert r.returncode != 0 and "power-of-two sides, the size is 8x6" in r.stderr and not (tmp_path / "npot").exists()
