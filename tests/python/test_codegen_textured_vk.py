"""The generated GLSL, HLSL and Slang lookups of a textured folder (``hbrdf-codegen DIR``; docs/CODEGEN.md,
"A textured material in an engine") RUN through real samplers under lavapipe: hbrdf_vk_runner --texture
uploads each map with its mip chain (a KTX2 file in its own format, BC blocks as stored: lavapipe's
texture unit decodes them) and binds it as a combined image sampler (GLSL) or a sampled image beside one
sampler (HLSL, Slang); textured_vk.py holds the kernels. Issue 58 part 4 and its first target:

- a weights-only material's level L read by the generated GLSL (textureLod and textureGrad) is the mean
  of libhybridbrdf's level-0 BRDFs over its 2^L x 2^L block within float rounding (relative 1e-6), where
  the sampler's filter is exact: power-of-two sides and uv at the level's texel centres (the bilinear
  fraction is 0: one texel), an integer lod and derivatives of 2^L texels (the trilinear fraction is 0:
  one level), float32 texels (R32G32B32A32_SFLOAT: the stored mean itself, no 8-bit rounding);
- a KTX2 folder (BC5 weights, sRGB BC7 kd, BC5 alpha, BC7 + BC4 latent maps), levels 0 and 1 at any uv,
  in GLSL, HLSL and Slang against libhybridbrdf reading the same KTX2 within the decode tolerance (one
  8-bit step per map channel, test_codegen_textured.py's measure of lavapipe's texture precision);
- between levels (lod L + 0.25, 0.5, 0.75, uv anywhere), libhybridbrdf's trilinear lookup within 1e-6;
- the breakages these tests catch: a wrong level, swapped channels, a level that is not its block's
  mean, no filter between levels, the sRGB decode applied twice; and the runner's one-line refusal of a BC map on a device
  without textureCompressionBC, and of a damaged KTX2 file."""

from __future__ import annotations

import json
import pathlib
import shutil

import numpy as np
import pytest

from hybridbrdf.codegen.main import generate_textured
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.svbrdf import SVBRDF, load_svbrdf
from hybridbrdf.svbrdf.ktx2 import read_ktx2, write_ktx2
from hybridbrdf.svbrdf.maps import read_map

import textured_engine as te
import textured_vk as tv
from helpers import saved_random_model, skip_without_vulkan
from slang_wgsl_tools import skip_without_slang

N = 16  # the weights-only folder's side: levels 0 .. 4
W = H = 16  # the KTX2 folder's


@pytest.fixture(scope="module")
def weights_only(tmp_path_factory):
    """A weights-only folder of four layers (one material twice) with its chain saved as EXR (float:
    each level the mean of the normalised level-0 weights, docs/SVBRDF.md "Mip chains"), the chain as
    one float KTX2 file, and the compiled GLSL kernel."""
    skip_without_vulkan()
    tmp = tmp_path_factory.mktemp("weights_only")
    _, model = saved_random_model(tmp, "hybrid", output_layer="material", energy_bound=True)
    rng = np.random.default_rng(4)
    weights = rng.dirichlet(np.ones(4), (N, N))[..., 1:].astype(np.float32)
    weights[5] = np.minimum(1.6 * weights[5], 1)  # a row whose weights sum past 1: normalised before the mean
    assert (weights.sum(axis=2) > 1.01).any()
    mats = model.materials
    SVBRDF(model, [mats[0], mats[1], mats[2], mats[1]], (N, N), weights, [{}] * 4, "repeat").with_mips().save(
        tmp / "sv", format="exr")
    folder = tmp / "sv"
    entry = json.loads((folder / "svbrdf.json").read_text())["maps"][0]
    chain = [read_map(folder / f)[0].astype(np.float32) for f in [entry["file"]] + entry["mips"]]
    assert len(chain) == 5 and chain[-1].shape == (1, 1, 3)
    write_ktx2(tmp / "weights.ktx2", chain, "R32G32B32A32_SFLOAT")
    SVBRDF(model, [mats[0], mats[1], mats[2], mats[1]], (N, N), weights, [{}] * 4, "clamp").with_mips().save(
        tmp / "clamped", format="exr")  # the same chain (a level's texels are its blocks' means), clamped
    spv = tv.compile_kernel(tmp / "glsl", generate_textured(folder, "glsl"), "glsl", (N, N), False)
    return {"tmp": tmp, "folder": folder, "chain": chain, "ktx2": tmp / "weights.ktx2", "spv": spv,
            "clamped": tmp / "clamped"}


def _level_pairs(rng, per_texel=2):
    """Every texel centre of every level, ``per_texel`` direction pairs each: (uv, wi, wo, lod) rows."""
    rows = []
    for level in range(5):
        s = N >> level
        cols, lines = np.meshgrid(np.arange(s), np.arange(s))
        uv = (np.stack([cols.ravel(), lines.ravel()], 1) + 0.5) / s
        rows += [np.concatenate([uv, np.full((len(uv), 1), level)], 1)] * per_texel
    meta = np.concatenate(rows)
    n = len(meta)
    return np.concatenate([meta[:, :2], cosine_directions(rng, n), cosine_directions(rng, n), meta[:, 2:]], 1)


def _block_mean(sv, pairs):
    """Per pair (a level-L texel centre), the mean of libhybridbrdf's level-0 f over the 2^L x 2^L block
    under it, each level-0 texel evaluated alone at its centre; float64 sums."""
    uv0, owner = [], []
    for k, (u, v, level) in enumerate(pairs[:, [0, 1, 8]]):
        b, s = 1 << int(level), N >> int(level)
        i, j = int(u * s), int(v * s)
        cols, lines = np.meshgrid(np.arange(b), np.arange(b))
        uv0.append(np.stack([(i * b + cols.ravel() + 0.5) / N, (j * b + lines.ravel() + 0.5) / N], 1))
        owner.append(np.full(b * b, k))
    uv0, owner = np.concatenate(uv0), np.concatenate(owner)
    f0 = sv.eval(uv0, pairs[owner, 2:5], pairs[owner, 5:8]).astype(np.float64)
    mean = np.zeros((len(pairs), 3))
    np.add.at(mean, owner, f0)
    return mean / np.bincount(owner)[:, None]


def _worst(got, ref):
    """The largest relative difference of f over every pair, through both lookups (lod, grad)."""
    return max(np.max(np.abs(got[:, c:c + 3] - ref) / np.abs(ref)) for c in (0, 3))


def test_weights_level_is_the_mean_of_its_block(weights_only, tmp_path):
    """Levels 0-4 through textureLod and textureGrad: relative 1e-6 of the block's mean BRDF
    (measured 3.2e-7 at most). Fails on a wrong level (lod + 1: 1e-2 and more), swapped weight
    channels, and a chain whose levels are one texel of the block instead of its mean."""
    rng = np.random.default_rng(8)
    pairs = _level_pairs(rng)
    sv = load_svbrdf(weights_only["folder"])
    ref = _block_mean(sv, pairs)
    assert np.abs(ref).min() > 1e-4
    got, _ = tv.run(weights_only["spv"], [weights_only["ktx2"]], pairs, False)
    assert np.array_equal(got[:, :3], got[:, 3:])  # textureLod(L) and textureGrad(2^L texels): one level
    for level in range(5):
        sel = pairs[:, 8] == level
        assert _worst(got[sel], ref[sel]) < 1e-6, level
    # The control: above level 0 the level-0 texel under the centre is not the block's mean.
    coarse = pairs[:, 8] > 0
    level0 = sv.eval(pairs[coarse, :2], pairs[coarse, 2:5], pairs[coarse, 5:8])
    assert np.max(np.abs(level0 - ref[coarse]) / ref[coarse]) > 1e-2
    # Breakages, each seen to fail the check above.
    wrong_level = pairs.copy()
    wrong_level[:, 8] = np.minimum(pairs[:, 8] + 1, 4)
    got, _ = tv.run(weights_only["spv"], [weights_only["ktx2"]], wrong_level, False)
    assert _worst(got[coarse & (pairs[:, 8] < 4)], ref[coarse & (pairs[:, 8] < 4)]) > 1e-3
    chain = weights_only["chain"]
    write_ktx2(tmp_path / "swapped.ktx2", [c[..., [1, 0, 2]] for c in chain], "R32G32B32A32_SFLOAT")
    write_ktx2(tmp_path / "picked.ktx2", [chain[0][::1 << k, ::1 << k] for k in range(5)], "R32G32B32A32_SFLOAT")
    for bad in ("swapped.ktx2", "picked.ktx2"):
        got, _ = tv.run(weights_only["spv"], [tmp_path / bad], pairs, False)
        assert _worst(got[coarse], ref[coarse]) > 1e-3, bad


def test_trilinear_lod_is_the_library(weights_only):
    """Between levels: textureLod at lod L + 0.25, 0.5, 0.75 (L = 1..3), uv anywhere (fractions of
    1/256 of a level-0 texel; repeat, and clamp to edge against a clamped folder), against libhybridbrdf's trilinear SVBRDF.eval(uv, lod) (OpenGL
    4.6 8.14: the two levels' bilinear values mixed by the fraction; f is linear in the weights, so
    the mix of the filtered weights is the mix of the BRDFs): within 1e-6 (measured 3.1e-7). Fails
    with the sampler's mip filter nearest (0.15). Not between levels 0 and 1 here: where level 0's
    filtered weights sum past 1 the shader normalises them after the sampler has mixed the two levels,
    the library each level before its mix (up to 5% apart; the chain's levels, and hbrdf paint's
    weights, sum to at most 1). textureGrad's level
    from derivatives of 2^(L + t) texels is lavapipe's approximation of log2 (up to 1-2% off f here), so
    it is compared at integer levels only (test_weights_level_is_the_mean_of_its_block)."""
    rng = np.random.default_rng(12)
    n = 1500
    lod = rng.integers(1, 4, n) + rng.choice([0.25, 0.5, 0.75], n)
    uv = (rng.integers(-N, 2 * N, (n, 2)) + rng.integers(0, 256, (n, 2)) / 256) / N
    pairs = np.concatenate([uv, cosine_directions(rng, n), cosine_directions(rng, n), lod[:, None]], 1)
    lib = load_svbrdf(weights_only["folder"]).eval(uv, pairs[:, 2:5], pairs[:, 5:8], lod=lod)
    assert np.abs(lib).min() > 1e-4
    got, _ = tv.run(weights_only["spv"], [weights_only["ktx2"]], pairs, False)
    assert np.max(np.abs(got[:, :3] - lib) / lib) < 1e-6
    got, _ = tv.run(weights_only["spv"], [weights_only["ktx2"]], pairs, False, nearest_mip=True)
    assert np.max(np.abs(got[:, :3] - lib) / lib) > 1e-2  # the breakage: no filter between levels
    # Clamp-to-edge addressing (hbrdf_vk_runner --clamp) against the same chain in a clamped folder.
    clamped = load_svbrdf(weights_only["clamped"]).eval(uv, pairs[:, 2:5], pairs[:, 5:8], lod=lod)
    got, _ = tv.run(weights_only["spv"], [weights_only["ktx2"]], pairs, False, clamp=True)
    assert np.max(np.abs(got[:, :3] - clamped) / clamped) < 1e-6
    assert np.max(np.abs(lib - clamped) / clamped) > 1e-2  # the control: repeat reads other texels there


# ---- a KTX2 folder of block formats -----------------------------------------------------------------


@pytest.fixture(scope="module")
def ktx2_folder(tmp_path_factory):
    """Three layers: weights (two channels: BC5), layer 0's kd (sRGB BC7), layer 1's alpha (BC5),
    layer 2's latent code (4 components: BC7 + BC4), 16 x 16 with the chain, saved by SVBRDF.save."""
    skip_without_vulkan()
    tmp = tmp_path_factory.mktemp("ktx2")
    _, model = saved_random_model(tmp, "hybrid", output_layer="material", energy_bound=True)
    rng = np.random.default_rng(5)
    weights = np.zeros((H, W, 3), np.float32)
    weights[:, 8:, 0] = 1.0
    weights[8:, :, 1] = np.linspace(0, 1, W)
    weights[3, :, :2] = rng.uniform(0, 0.6, (W, 2))
    maps = [{"kd": rng.uniform(0, 1, (H, W, 3)).astype(np.float32)},
            {"alpha": rng.uniform(0.05, 0.9, (H, W, 2)).astype(np.float32)},
            {"latent": rng.uniform(-1, 1, (H, W, 4)).astype(np.float32)}]
    # kd in sRGB BC7 (kd_format="bc7"), the sampler path this file checks; the writer's default BC1 is
    # bench/textured_bc_cost.py's (its f against the rgba8 chain printed).
    SVBRDF(model, model.materials[:3], (W, H), weights, maps, "repeat").with_mips().save(tmp / "sv", format="ktx2", kd_format="bc7")
    folder = tmp / "sv"
    names = {e["file"]: read_ktx2(folder / e["file"]).name for e in json.loads((folder / "svbrdf.json").read_text())["maps"]}
    assert names == {"weights.ktx2": "BC5_UNORM_BLOCK", "layer0_kd.ktx2": "BC7_SRGB_BLOCK",
                     "layer1_alpha.ktx2": "BC5_UNORM_BLOCK", "layer2_latent0.ktx2": "BC7_UNORM_BLOCK",
                     "layer2_latent1.ktx2": "BC4_UNORM_BLOCK"}
    return folder


def _level_view(folder: pathlib.Path, level: int, tmp: pathlib.Path) -> pathlib.Path:
    """A folder textured_engine's float64 sampler reference reads as ``folder``'s level ``level``: its
    index with that level's size (the model beside it); the stored values come from _ktx2_map."""
    view = tmp / f"level{level}"
    view.mkdir()
    index = json.loads((folder / "svbrdf.json").read_text())
    index["size"] = [max(1, s >> level) for s in index["size"]]
    (view / "svbrdf.json").write_text(json.dumps(index))
    shutil.copy(folder / index["model"], view / index["model"])
    return view


def _ktx2_map(folder: pathlib.Path, level: int):
    """read_map's stand-in for textured_engine: a KTX2 map's stored values at ``level`` (the decoded
    blocks, bytes / 255, channels past the format's 0), 8 bits."""
    def read(path):
        values = read_ktx2(folder / pathlib.Path(path).name).levels[level]
        out = np.zeros(values.shape[:2] + (3,))
        c = min(3, values.shape[2])
        out[..., :c] = values[..., :c] / 255.0
        return out, 8
    return read


def _pairs(n, rng, level):
    side = W >> level
    uv = rng.uniform(-1, 2, (n, 2))
    q = n // 3  # the level's texel centres, beyond [0, 1] too
    uv[:q] = (rng.integers(-side, 2 * side, (q, 2)) + 0.5) / side
    uv = uv.astype(np.float32).astype(np.float64)
    return np.concatenate([uv, cosine_directions(rng, n), cosine_directions(rng, n), np.full((n, 1), level)], 1), q


def _excess(got, refs, tols):
    """The largest (|f - ref| - tol) / |ref| over the pairs and both lookups: <= 0 when all hold."""
    return max(np.max((np.abs(got[:, c:c + 3] - refs) - tols) / np.maximum(np.abs(refs), 1e-6)) for c in (0, 3))


@pytest.mark.slow
@pytest.mark.parametrize("target", ["glsl", "hlsl", "slang"])
def test_ktx2_folder_runs_like_the_library(ktx2_folder, target, tmp_path, monkeypatch):
    """Levels 0 and 1 of every block format, at any uv (repeat addressing): within one 8-bit step per
    map channel of the float64 filter-then-decode of the same KTX2 blocks (sRGB kd decoded by the
    texture unit before its filter), which at each level's texel centres is libhybridbrdf's
    SVBRDF.eval(uv, wi, wo, lod) of the folder within float rounding. GLSL with the shader's sRGB
    decode left on over the sRGB texture (decoded twice) fails it."""
    if target == "slang":
        skip_without_slang()
    rng = np.random.default_rng(9)
    sv = load_svbrdf(ktx2_folder)
    blocks, refs, tols, libs = [], [], [], []
    for level in (0, 1):
        pairs, q = _pairs(1500, rng, level)
        view = _level_view(ktx2_folder, level, tmp_path)
        monkeypatch.setattr(te, "read_map", _ktx2_map(ktx2_folder, level))
        uv, wi, wo = pairs[:, :2], pairs[:, 2:5], pairs[:, 5:8]
        ref = te.eval_reference(view, uv, wi, wo, True)
        tols.append(te.step_tolerance(view, uv, wi, wo, True, ref) + 1e-4 * np.abs(ref) + 1e-6)
        lib = sv.eval(uv[:q], wi[:q], wo[:q], lod=float(level))
        big = np.abs(lib) > 1e-6
        assert big.mean() > 0.9
        assert np.max(np.abs(ref[:q] - lib)[big] / np.abs(lib)[big]) < 1e-5, level  # the reference is the library's
        blocks.append(pairs)
        refs.append(ref)
    pairs, ref, tol = np.concatenate(blocks), np.concatenate(refs), np.concatenate(tols)
    assert np.median(tol / np.maximum(np.abs(ref), 1e-6)) < 0.02  # not vacuous: about one 8-bit step
    code = generate_textured(ktx2_folder, target)
    spv = tv.compile_kernel(tmp_path / target, code, target, (W, H), True)
    textures = tv.folder_textures(ktx2_folder, tmp_path / "tex")
    got, r = tv.run(spv, textures, pairs, target != "glsl")
    assert "llvmpipe" in r.stdout and np.isfinite(got).all()
    assert _excess(got, ref, tol) <= 0
    if target == "glsl":
        twice = tv.compile_kernel(tmp_path / "srgb_off", code, target, (W, H), False)
        got, _ = tv.run(twice, textures, pairs, False)
        assert _excess(got, ref, tol) > 0.01


def test_runner_refuses_what_it_cannot_sample(ktx2_folder, weights_only, tmp_path):
    """One line naming the file and the device: a BC map where the device has no textureCompressionBC
    (--without-bc; the float map still runs there), and a truncated KTX2 file (the reader's words)."""
    pairs = _level_pairs(np.random.default_rng(1), per_texel=1)[:64]
    spv = weights_only["spv"]
    got, r = tv.run(spv, [weights_only["ktx2"]], pairs, False, extra=["--without-bc"])
    assert got is not None  # the control: a float texture needs no BC sampling
    bc5 = ktx2_folder / "weights.ktx2"
    got, r = tv.run(spv, [bc5], pairs, False, extra=["--without-bc"], check=False)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and got is None and len(lines) == 1, r.stderr
    assert str(bc5) in lines[0] and "BC5_UNORM_BLOCK needs textureCompressionBC" in lines[0] and "llvmpipe" in lines[0]
    cut = tmp_path / "cut.ktx2"
    cut.write_bytes(bc5.read_bytes()[:100])
    got, r = tv.run(spv, [cut], pairs, False, check=False)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1 and str(cut) in lines[0] and "truncated" in lines[0], r.stderr
