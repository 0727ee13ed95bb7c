"""Textured materials (docs/SVBRDF.md): the folder's contract, texel lookup, the layered
evaluation in libhybridbrdf (HybridModel::eval_texel) against PyTorch in float64, the
uniform material as the special case of constant maps, filtering, and hbrdf paint."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
import torch
from PIL import Image

import hybridbrdf as hb
import hybridbrdf.render.tracer  # noqa: F401  (hb.render.tracer)
from hybridbrdf import spec
from hybridbrdf.brdf.torch_brdf import eval_analytic
from hybridbrdf.errors import OutputFileError
from hybridbrdf.evaluate.directions import cosine_directions
from hybridbrdf.evaluate.metrics import metric_directions
from hybridbrdf.fit.painting import composite, paint
from hybridbrdf.fit.settings import FitSettings
from hybridbrdf.model.file import load_model
from hybridbrdf.model.random import random_model
from hybridbrdf.svbrdf.asset import SVBRDF, load_svbrdf
from hybridbrdf.svbrdf.entries import SVBRDFError
from hybridbrdf.svbrdf.decode import decode, encode, inverse_transfer, png_channel, transfer
from hybridbrdf.svbrdf.maps import write_map

from helpers import run_cli_here, saved_random_model


def _directions(n=3000, seed=3):
    wi, wo = metric_directions(n, seed)
    return np.asarray(wi, np.float64), np.asarray(wo, np.float64)


def _constant_maps(model, i, h, w):
    t = model.tensors
    return {"kd": np.broadcast_to(t["materials.kd"][i], (h, w, 3)).copy(),
            "eta": np.broadcast_to(t["materials.eta"][i], (h, w, 3)).copy(),
            "alpha": np.broadcast_to(t["materials.alpha"][i], (h, w, 2)).copy(),
            "latent": np.broadcast_to(t["materials.z"][i], (h, w, t["materials.z"].shape[1])).copy()}


@pytest.fixture(params=[("hybrid", "material", True), ("hybrid-reciprocal", "shared", False)],
                ids=["heads-bounded", "reciprocal-shared"])
def model(request, tmp_path):
    arch, output_layer, bound = request.param
    path, m = saved_random_model(tmp_path, arch, output_layer=output_layer, energy_bound=bound)
    return m


def test_constant_exr_maps_are_the_uniform_material_bit_for_bit(model, tmp_path):
    """Maps holding a material's own values (float EXR) evaluate to that material, through the scalar
    path, bit for bit: same operations, same order (the texel's p and z are the material's floats)."""
    h, w = 5, 7
    sv = SVBRDF(model, [model.materials[1]], (w, h), None, [_constant_maps(model, 1, h, w)])
    sv.save(tmp_path / "sv", format="exr")
    back = load_svbrdf(tmp_path / "sv")
    assert set(back.maps[0]) == {"kd", "eta", "alpha", "latent"}
    wi, wo = _directions()
    uv = np.random.default_rng(0).uniform(-2, 3, size=(len(wi), 2))  # wrapping too
    for filt in ("nearest", "bilinear"):
        f = back.eval(uv, wi, wo, filter=filt)
        uniform = back.model._cpp_model().eval_scalar(wi.astype(np.float32), wo.astype(np.float32), 1)
        np.testing.assert_array_equal(f, uniform)
    assert np.abs(f).max() > 0


# The spec's transfers written out here from spec/model.json's text and IEC 61966-2-1, independently
# of hybridbrdf.svbrdf.decode: the references the quantisation and transfer tests measure against.
def _srgb_eotf(v):
    v = np.asarray(v, np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((np.maximum(v, 0.04045) + 0.055) / 1.055) ** 2.4)


def _srgb_oetf(t):
    t = np.asarray(t, np.float64)
    return np.where(t <= 0.0031308, 12.92 * t, 1.055 * np.maximum(t, 0.0031308) ** (1 / 2.4) - 0.055)


_REFERENCE_TRANSFERS = {"linear": (lambda v: np.asarray(v, np.float64), lambda t: np.asarray(t, np.float64)),
                        "srgb": (_srgb_eotf, _srgb_oetf),
                        "square": (lambda v: np.asarray(v, np.float64) ** 2, lambda t: np.sqrt(np.asarray(t, np.float64)))}


def _reference_decode(v, d):
    return d["offset"] + d["scale"] * _REFERENCE_TRANSFERS[d["transfer"]][0](v)


def _reference_stored(x, d):
    """The exact (unrounded) stored value in [0, 1] whose decode is x."""
    return np.clip(_REFERENCE_TRANSFERS[d["transfer"]][1]((np.asarray(x, np.float64) - d["offset"]) / d["scale"]), 0, 1)


def test_constant_png_maps_stay_within_their_quantisation(model, tmp_path):
    """8-bit maps of a material's values: every decoded value within half a step of the value (the
    decode of the nearest byte, not of the one below or above it), and f within the change that
    half step makes to it, measured against the same maps stored unquantised (EXR)."""
    h, w = 4, 4
    maps = _constant_maps(model, 0, h, w)
    SVBRDF(model, [model.materials[0]], (w, h), None, [maps]).save(tmp_path / "png", format="png")
    back = load_svbrdf(tmp_path / "png")
    index = json.loads((tmp_path / "png" / "svbrdf.json").read_text())
    half = 0.5 / 255
    steps = {}  # (quantity, component) -> the largest change in the decoded value half a step makes
    for entry in index["maps"]:
        q = entry["quantity"]
        for ch, d in enumerate(entry["decode"]):
            if d is None:
                continue
            c = entry["first"] + ch
            x = maps[q][0, 0, c].astype(np.float64)
            v = _reference_stored(x, d)
            lo, hi = (_reference_decode(np.clip(v + s, 0, 1), d) for s in (-half, half))
            got = back.maps[0][q][..., c].astype(np.float64)
            slack = 1e-6 * max(1.0, abs(x))  # the float32 of the decoded value
            assert np.all((got >= min(lo, hi) - slack) & (got <= max(lo, hi) + slack)), (q, c, x, got[0, 0], lo, hi)
            steps[q, c] = max(abs(hi - x), abs(lo - x))
    assert ("kd", 0) in steps and ("eta", 0) in steps and ("alpha", 0) in steps
    # f: the PNG texel against the EXR one (the material's float values), within the sum over the
    # parameters of the change half a step of each makes on its own (the first-order bound), per pair.
    wi, wo = _directions(1500)
    uv = np.full((len(wi), 2), 0.5)

    def f_of(values):
        return SVBRDF(model, [model.materials[0]], (w, h), None, [values]).eval(uv, wi, wo, "nearest", torch.float64)

    exact = f_of(maps)
    bound = np.zeros_like(exact)
    for (q, c), step in steps.items():
        moved = {k: a.copy() for k, a in maps.items()}
        moved[q][..., c] += np.float32(step)
        bound += np.abs(f_of(moved) - exact)
    f_png = back.eval(uv, wi, wo, "nearest", torch.float64)
    err = np.abs(f_png - exact)
    assert err.max() > 0  # the control: the 8-bit maps do change f
    assert np.all(err <= 1.05 * bound + 1e-6 * np.abs(exact) + 1e-9), float(np.max(err / np.maximum(bound, 1e-30)))


def test_mixed_texels_are_the_mixture_of_their_layers(model, tmp_path):
    """A texel of weights w is sum_k w_k f_k: libhybridbrdf's eval_texel against each layer material's
    own float64 PyTorch evaluation, weighted."""
    h, w = 3, 4
    weights = np.zeros((h, w, 3), np.float32)
    weights[..., 0] = np.linspace(0, 1, w)[None, :]
    weights[..., 1] = (1 - weights[..., 0]) * np.linspace(0, 1, h)[:, None]
    sv = SVBRDF(model, model.materials[:3], (w, h), weights)
    sv.save(tmp_path / "sv", format="exr")
    back = load_svbrdf(tmp_path / "sv")
    wi, wo = _directions(600)
    rows, cols = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    for r, c in zip(rows.ravel(), cols.ravel()):
        uv = np.tile([(c + 0.5) / w, (r + 0.5) / h], (len(wi), 1))
        f = back.eval(uv, wi, wo, filter="nearest")
        wt = back.texels(uv[:1], "nearest")["weight"][0].astype(np.float64)
        assert abs(wt.sum() - 1) < 1e-6 and np.all(wt >= 0)
        ref = sum(wt[k] * model.eval(wi, wo, k, dtype=torch.float64) for k in range(3))
        scale = max(np.abs(ref).max(), 1e-6)
        assert np.abs(f - ref).max() <= 2e-4 * scale + 1e-7, (r, c)
        torch_f = back.eval(uv, wi, wo, filter="nearest", dtype=torch.float64)
        assert np.abs(torch_f - ref).max() <= 1e-9 * scale + 1e-12


def _reference_bilinear_taps(uv, w, h, addressing):
    """[(row, col, weight)] per uv, written from docs/CONVENTIONS.md alone: texel (i, j) centred at
    ((i + 0.5) / W, (j + 0.5) / H), u right (columns), v down (rows); the four centres around uv,
    weighted by the distances to them; repeat wraps the texel indices, clamp clamps uv to [0, 1]
    first and then the indices to the map."""
    out = []
    for u, v in uv:
        if addressing == "clamp":
            u, v = min(max(u, 0.0), 1.0), min(max(v, 0.0), 1.0)
        i0, j0 = int(np.floor(u * w - 0.5)), int(np.floor(v * h - 0.5))
        taps = []
        for j in (j0, j0 + 1):
            for i in (i0, i0 + 1):
                cu, cv = (i + 0.5) / w, (j + 0.5) / h  # the texel centre (outside the map for i = -1 or W)
                weight = (1 - abs(u - cu) * w) * (1 - abs(v - cv) * h)
                col, row = (i % w, j % h) if addressing == "repeat" else (min(max(i, 0), w - 1), min(max(j, 0), h - 1))
                taps.append((row, col, weight))
        out.append(taps)
    return out


@pytest.mark.parametrize("addressing", ["repeat", "clamp"])
def test_bilinear_weights_filter_the_brdfs(model, addressing):
    """Without p or z maps, the bilinear texel is the bilinear combination of the four texels'
    BRDFs (f is linear in the weights): the filter of the BRDFs, not an approximation of it. The
    taps and their weights are computed here from the convention (not from the lookup under test),
    on a non-square map with uv outside [0, 1] (wrapping or clamping)."""
    rng = np.random.default_rng(1)
    h, w = 6, 5
    raw = rng.uniform(0, 1, size=(h, w, 3)).astype(np.float32)
    raw[..., 1:] *= 0.5
    weights = raw / np.maximum(raw.sum(axis=2, keepdims=True), 1)
    weights[..., 2] = 0
    sv = SVBRDF(model, model.materials[:3], (w, h), weights, addressing=addressing)
    wi, wo = _directions(300)
    uv = rng.uniform(-0.3, 1.3, size=(len(wi), 2))
    uv[:4] = [[0.5 / w, 0.5 / h], [0.0, 0.0], [1.0, 1.0], [0.3, 0.95]]  # a centre, both corners, an edge
    f = sv.eval(uv, wi, wo, filter="bilinear", dtype=torch.float64)
    # Each texel's own f, at its centre (one nearest tap): (h, w, N, 3) for the N pairs.
    centres = [[(c + 0.5) / w, (r + 0.5) / h] for r in range(h) for c in range(w)]
    own = np.stack([sv.eval(np.tile(cu, (len(wi), 1)), wi, wo, filter="nearest", dtype=torch.float64)
                    for cu in centres]).reshape(h, w, len(wi), 3)
    ref = np.zeros_like(f)
    for n, taps in enumerate(_reference_bilinear_taps(uv, w, h, addressing)):
        assert abs(sum(t for _, _, t in taps) - 1) < 1e-12 and all(t >= -1e-12 for _, _, t in taps)
        ref[n] = sum(t * own[r, c, n] for r, c, t in taps)
    assert np.abs(f - ref).max() <= 1e-5 * np.abs(ref).max()


def test_a_mixture_of_reciprocal_layers_is_reciprocal(tmp_path):
    path, m = saved_random_model(tmp_path, "hybrid-reciprocal", output_layer="material")
    weights = np.full((2, 2, 3), 0.3, np.float32)
    weights[..., 2] = 0
    sv = SVBRDF(m, m.materials[:3], (2, 2), weights)
    sv.save(tmp_path / "sv", format="exr")
    back = load_svbrdf(tmp_path / "sv")
    wi, wo = _directions(2000)
    uv = np.random.default_rng(2).uniform(0, 1, size=(len(wi), 2))
    np.testing.assert_array_equal(back.eval(uv, wi, wo), back.eval(uv, wo, wi))


def test_uv_addressing_and_nearest_texel(tmp_path):
    _, m = saved_random_model(tmp_path, "hybrid")
    h, w = 2, 4
    weights = np.zeros((h, w, 3), np.float32)
    weights[0, 3, 0] = 1  # top-right texel: layer 1
    for addressing, uv, expect in (("repeat", [0.9, 0.1], 1), ("repeat", [-0.1, 1.1], 1), ("repeat", [0.1, 0.1], 0),
                                   ("clamp", [1.7, -3.0], 1), ("clamp", [-0.5, -0.5], 0)):
        sv = SVBRDF(m, m.materials[:2], (w, h), weights, addressing=addressing)
        got = sv.texels(np.array([uv]), "nearest")["weight"][0]
        assert got[expect] == 1.0, (addressing, uv, got)
    with pytest.raises(ValueError, match="finite"):
        sv.texels(np.array([[np.nan, 0.5]]))


def test_transfers_invert():
    v = np.linspace(0, 1, 256)
    for name in spec.SVBRDF["transfers"]:
        d = {"transfer": name, "scale": 1.0, "offset": 0.0}
        np.testing.assert_allclose(encode(decode(v, d), d), v, atol=1e-12)
    assert png_channel("latent", -2.0, 6.0) == {"transfer": "linear", "scale": 8.0, "offset": -2.0}


def test_transfers_are_the_published_functions():
    """Each transfer and its inverse against its definition written out here (not a round trip
    through the module: a gamma of 2.2 in both directions inverts as well as the sRGB curve does):
    the sRGB EOTF and its inverse of IEC 61966-2-1 (linear below 0.04045 / 0.0031308, 2.4 above),
    at published points and on a grid over both pieces, T(v) = v^2 and T(v) = v."""
    # Published values: sRGB 0.5 is 21.4% linear, 18% grey is sRGB 0.4614; the pieces meet at
    # (0.04045, 0.0031308); 8-bit 1 / 255 is in the linear toe.
    np.testing.assert_allclose(transfer("srgb", np.array([0.0, 1 / 255, 0.04045, 0.5, 1.0])),
                               [0.0, 1 / 255 / 12.92, 0.0031308, 0.21404114, 1.0], rtol=2e-6, atol=1e-9)
    np.testing.assert_allclose(inverse_transfer("srgb", np.array([0.0, 0.001, 0.0031308, 0.18, 0.21404114, 1.0])),
                               [0.0, 0.01292, 0.04045, 0.46135613, 0.5, 1.0], rtol=2e-6, atol=1e-9)
    v = np.linspace(0, 1, 1001)
    for name, (eotf, oetf) in _REFERENCE_TRANSFERS.items():
        np.testing.assert_allclose(transfer(name, v), eotf(v), rtol=1e-12, atol=1e-15, err_msg=name)
        np.testing.assert_allclose(inverse_transfer(name, v), oetf(v), rtol=1e-12, atol=1e-15, err_msg=name)
    # Below the range (a float32 alpha a rounding under ALPHA_MIN): the bottom of it, not NaN.
    np.testing.assert_array_equal(inverse_transfer("square", np.array([-1e-9, -1.0])), [0.0, 0.0])
    np.testing.assert_array_equal(inverse_transfer("srgb", np.array([-1e-9, -1.0])), [0.0, 0.0])
    # A channel's decode is offset + scale T(v) (spec/model.json), here alpha's 8-bit decode.
    d = png_channel("alpha")
    np.testing.assert_allclose(decode(v, d), 1e-4 + 0.9999 * v * v, rtol=1e-12)


def test_unknown_transfers_are_refused_and_8_bit_codes_are_bytes():
    for name in ("gamma", "Linear", "sRGB", "", "squares"):  # before, between and after the known names
        for fn in (transfer, inverse_transfer):
            with pytest.raises(ValueError, match="unknown transfer"):
                fn(name, np.array([0.5]))
    d = {"transfer": "linear", "scale": 1.0, "offset": 0.0}
    x = np.array([0.0, 0.2, 0.61, 1.0])  # 0.61: 155.55 of 255 (the nearest byte 156, not 155), 39976.35 of 65535
    codes = encode(x, d, bits=8)
    assert codes.dtype == np.uint8 and codes.tolist() == [0, 51, 156, 255]
    codes = encode(x, d, bits=16)
    assert codes.dtype == np.uint16 and codes.tolist() == [0, 13107, 39976, 65535]


# ---- malformed folders ------------------------------------------------------------------


@pytest.fixture
def folder(tmp_path):
    _, m = saved_random_model(tmp_path, "hybrid", output_layer="material")
    weights = np.zeros((4, 4, 3), np.float32)
    weights[..., 0] = 0.5
    maps = [{"kd": np.full((4, 4, 3), 0.25, np.float32)}, {}]
    SVBRDF(m, m.materials[:2], (4, 4), weights, maps).save(tmp_path / "sv", format="png")
    return tmp_path / "sv"


def _edit_index(folder, change):
    path = folder / "svbrdf.json"
    index = json.loads(path.read_text())
    change(index)
    path.write_text(json.dumps(index))


def _set_decode(index, quantity, **kw):
    entry = next(e for e in index["maps"] if e["quantity"] == quantity)
    entry["decode"][0].update(kw)


def _write_png(path, arr, mode):
    Image.fromarray(arr, mode).save(path)


def _add_normal(folder, file="normal.png", value=128, **entry):
    """A normal map (issue 58, item 3) added to the folder: the file of constant ``value`` (bytes for
    a PNG, a float for an EXR) and its entry, changed by ``entry``."""
    write_map(folder / file, np.full((4, 4, 3), value, np.uint8 if file.endswith(".png") else np.float32))
    d = {"transfer": "linear", "scale": 2.0, "offset": -1.0} if file.endswith(".png") else {"transfer": "linear", "scale": 1.0, "offset": 0.0}
    _edit_index(folder, lambda i: i["maps"].append({"file": file, "quantity": "normal", "first": 0,
                                                    "decode": [dict(d), dict(d), None], **entry}))


CORRUPTIONS = [
    ("no index", lambda f: (f / "svbrdf.json").unlink(), "no such file"),
    ("not JSON", lambda f: (f / "svbrdf.json").write_text("{"), "not valid JSON"),
    ("unknown key", lambda f: _edit_index(f, lambda i: i.update(extra=1)), "unknown keys"),
    ("future version", lambda f: _edit_index(f, lambda i: i.update(format_version=3)), "format_version 3"),
    ("model outside", lambda f: _edit_index(f, lambda i: i.update(model="../m.safetensors")), "plain file name"),
    ("size too big", lambda f: _edit_index(f, lambda i: i.update(size=[4, 9000])), "size must be"),
    ("size mismatch", lambda f: _edit_index(f, lambda i: i.update(size=[4, 5])), "the index says 4x5"),
    ("addressing", lambda f: _edit_index(f, lambda i: i.update(addressing="mirror")), "addressing must be"),
    ("unknown material", lambda f: _edit_index(f, lambda i: i["layers"][1].update(material="nope")), "'nope' is not in"),
    ("five layers", lambda f: _edit_index(f, lambda i: i.update(layers=i["layers"] * 3)), "1 to 4 layers"),
    ("decode out of range", lambda f: _edit_index(f, lambda i: _set_decode(i, "kd", scale=2.0)), "outside kd's range"),
    ("decode below range", lambda f: _edit_index(f, lambda i: _set_decode(i, "kd", offset=-0.5, scale=1.0)),
     "decodes to [-0.5, 0.5], outside kd's range"),
    ("unknown transfer", lambda f: _edit_index(f, lambda i: _set_decode(i, "kd", transfer="gamma")), "unknown transfer"),
    ("nan scale", lambda f: (f / "svbrdf.json").write_text((f / "svbrdf.json").read_text().replace('"scale": 1.0', '"scale": NaN', 1)),
     "not valid JSON"),
    ("weights of a missing layer", lambda f: write_map(f / "weights.png", np.full((4, 4, 3), 60, np.uint8)),
     "beyond the last"),
    ("grey PNG", lambda f: _write_png(f / "weights.png", np.zeros((4, 4), np.uint8), "L"), "texel maps are 8-bit RGB PNG"),
    ("truncated PNG", lambda f: (f / "weights.png").write_bytes((f / "weights.png").read_bytes()[:40]), "cannot read the PNG map"),
    ("huge PNG header", lambda f: _write_png(f / "weights.png", np.zeros((1, 8193, 3), np.uint8), "RGB"), "1 to 8192"),
    ("duplicate map", lambda f: _edit_index(f, lambda i: i["maps"].append(dict(i["maps"][0]))), "two maps give"),
    ("layer out of range", lambda f: _edit_index(f, lambda i: next(e for e in i["maps"] if e["quantity"] == "kd").update(layer=5)),
     "layer must be 0 to 1"),
    ("missing map file", lambda f: (f / "weights.png").unlink(), "no such file"),
    ("map is a folder", lambda f: ((f / "weights.png").unlink(), (f / "weights.png").mkdir()), "is a folder"),
    ("bad extension", lambda f: _edit_index(f, lambda i: i["maps"][0].update(file="weights.tga")), ".exr (float32) or .ktx2, not '.tga'"),
    ("normal map of a layer", lambda f: _add_normal(f, layer=0), 'a normal map has no "layer"'),
    ("normal decode out of range", lambda f: _add_normal(f, decode=[{"transfer": "linear", "scale": 2.0, "offset": 0.0}] * 2 + [None]),
     "decodes to [0, 2], outside normal's range [-1, 1]"),
    ("normal texel out of range", lambda f: _add_normal(f, "normal.exr", 1.5), "decodes to 1.5, outside normal's range [-1, 1]"),
    ("normal's third channel", lambda f: _add_normal(f, decode=[{"transfer": "linear", "scale": 2.0, "offset": -1.0}] * 3),
     "channel B holds no normal component; its decode must be null"),
]


@pytest.mark.parametrize("name,corrupt,words", CORRUPTIONS, ids=[c[0] for c in CORRUPTIONS])
def test_malformed_folders_are_refused_in_one_line_by_both_loaders(folder, name, corrupt, words):
    corrupt(folder)
    with pytest.raises(hb.InputFileError) as err:
        load_svbrdf(folder)
    msg = str(err.value)
    assert words in msg and "\n" not in msg, msg
    assert str(folder) in msg
    one = np.zeros((1, 2), np.float32)
    with pytest.raises(ValueError) as err:  # RenderFileError from libhybridbrdf's loader (render::load_svbrdf), the tracer's
        hb._core.Svbrdf(str(folder)).eval(one, np.array([[0, 0, 1]], np.float32), np.array([[0, 0, 1]], np.float32))
    msg = str(err.value)
    assert words in msg and "\n" not in msg, msg
    assert str(folder) in msg


def test_exr_maps_with_nan_or_out_of_range_values_are_refused(tmp_path):
    _, m = saved_random_model(tmp_path, "hybrid")
    sv = SVBRDF(m, m.materials[:1], (3, 3), None, [{"eta": np.full((3, 3, 3), 1.5, np.float32)}])
    sv.save(tmp_path / "sv", format="exr")
    bad = np.full((3, 3, 3), 1.5, np.float32)
    bad[1, 2, 1] = 0.5  # eta below 1
    hb._core.render_write_exr(bad, str(tmp_path / "sv" / "layer0_eta.exr"))
    with pytest.raises(SVBRDFError, match=r"texel \(2, 1\) channel G decodes to 0.5, outside eta's range"):
        load_svbrdf(tmp_path / "sv")
    bad[1, 2, 1] = np.nan
    hb._core.render_write_exr(bad, str(tmp_path / "sv" / "layer0_eta.exr"))
    with pytest.raises(hb.InputFileError, match="must be finite"):
        load_svbrdf(tmp_path / "sv")


def test_a_truncated_exr_map_is_one_line_naming_the_file_once(tmp_path):
    _, m = saved_random_model(tmp_path, "hybrid")
    SVBRDF(m, m.materials[:1], (3, 3), None, [{"eta": np.full((3, 3, 3), 1.5, np.float32)}]).save(tmp_path / "sv", format="exr")
    path = tmp_path / "sv" / "layer0_eta.exr"
    path.write_bytes(path.read_bytes()[:60])
    with pytest.raises(hb.InputFileError) as err:
        load_svbrdf(tmp_path / "sv")
    text = str(err.value)
    assert "\n" not in text and text.count("layer0_eta.exr") == 1, text
    assert text.split("layer0_eta.exr: ", 1)[-1].startswith("Failed to read"), text  # the reader's reason after the name


@pytest.mark.parametrize("size", [(5, 1), (1, 4), (1, 1)])
def test_maps_one_texel_wide_or_high(tmp_path, size):
    _, m = saved_random_model(tmp_path, "hybrid")
    w, h = size
    weights = np.zeros((h, w, 3), np.float32)
    weights[..., 0] = np.linspace(0, 1, w * h).reshape(h, w)
    for fmt in ("png", "exr"):
        SVBRDF(m, m.materials[:2], size, weights).save(tmp_path / fmt, format=fmt)
        back = load_svbrdf(tmp_path / fmt)
        assert back.size == size
        np.testing.assert_allclose(back.weights[..., 0], weights[..., 0], atol=0.5 / 255 + 1e-7)


def test_weights_summing_above_one_are_divided_by_their_sum():
    """docs/CONVENTIONS.md: w_0 = 1 - w_1 - w_2 - w_3, all divided by their sum when it exceeds 1."""
    _, m = random_model("hybrid", n=4)
    texels = [(0.2, 0.3, 0.1), (0.9, 0.6, 0.0), (0.7, 0.6, 0.5), (1.0, 1.0, 1.0)]
    weights = np.array([texels], np.float32)  # (1, 4, 3)
    sv = SVBRDF(m, m.materials[:4], (4, 1), weights)
    uv = np.array([[(i + 0.5) / 4, 0.5] for i in range(4)])
    got = sv.texels(uv, "nearest")["weight"].astype(np.float64)
    for n, rest in enumerate(texels):
        total = sum(rest)
        expect = [1 - total, *rest] if total <= 1 else [0.0, *(r / total for r in rest)]
        np.testing.assert_allclose(got[n], expect, atol=1e-6, err_msg=str(rest))


def test_save_refuses_to_replace_a_folder_that_is_not_a_textured_material(tmp_path):
    _, m = saved_random_model(tmp_path, "hybrid")
    other = tmp_path / "photos"
    other.mkdir()
    (other / "keep.jpg").write_bytes(b"x")
    with pytest.raises(hb.InputFileError, match="without svbrdf.json"):
        SVBRDF(m, m.materials[:1], (2, 2)).save(other)
    assert (other / "keep.jpg").exists()
    SVBRDF(m, m.materials[:1], (2, 2)).save(tmp_path / "sv")
    SVBRDF(m, m.materials[1:2], (3, 3)).save(tmp_path / "sv")  # a textured material's folder is replaced
    assert load_svbrdf(tmp_path / "sv").layers == [m.materials[1]]
    assert not [p for p in tmp_path.iterdir() if ".tmp" in p.name or ".old" in p.name]


# ---- painting ------------------------------------------------------------------------------


def test_composite_is_over_and_sums_to_one():
    rng = np.random.default_rng(4)
    masks = [rng.uniform(0, 1, (5, 6)) for _ in range(3)]
    w = composite(masks)
    assert np.all(w >= 0) and np.all(w.sum(axis=2) <= 1 + 1e-12)
    np.testing.assert_allclose(w[..., 2], masks[2])  # the top layer keeps its mask
    np.testing.assert_allclose(w[..., 1], masks[1] * (1 - masks[2]))
    np.testing.assert_allclose(w[..., 0], masks[0] * (1 - masks[1]) * (1 - masks[2]))


def test_paint_with_masks_and_an_albedo_texture(tmp_path):
    path, m = saved_random_model(tmp_path, "hybrid", output_layer="material")
    mask = np.tile(np.linspace(0, 255, 8).astype(np.uint8), (6, 1))
    _write_png(tmp_path / "mask.png", mask, "L")
    albedo = np.random.default_rng(5).integers(0, 256, (6, 8, 3), dtype=np.uint8)
    _write_png(tmp_path / "albedo.png", albedo, "RGB")
    sv = paint(path, m.materials[0], [(m.materials[2], tmp_path / "mask.png")], tmp_path / "sv",
               kd={1: tmp_path / "albedo.png"})
    back = load_svbrdf(tmp_path / "sv")
    # the albedo texture is brighter than material 2 somewhere: the layer uses its bounded edit
    assert back.layers == [m.materials[0], m.materials[2] + ".kdmap1"] and back.size == (8, 6)
    np.testing.assert_allclose(back.weights[..., 0], mask / 255.0, atol=0.5 / 255 + 1e-7)
    kd = transfer("srgb", albedo / 255.0)
    step = np.abs(transfer("srgb", np.minimum(albedo + 1, 255) / 255.0) - kd)
    assert np.all(np.abs(back.maps[1]["kd"] - kd) <= step + 1e-6)  # 8-bit sRGB round trip
    assert sv.path == str((tmp_path / "sv").resolve())


def _max_albedo(sv, uv, n=200_000, seed=3):
    """The largest directional albedo (max over RGB) of the texel at uv over 9 viewing elevations:
    pi times the mean of f over n cosine-distributed light directions (independent of the library's
    energy estimator, which samples f_a's MIS lobes)."""
    rng = np.random.default_rng(seed)
    wi = cosine_directions(rng, n)
    best = 0.0
    for theta in np.radians(np.linspace(0, 85, 9)):
        wo = np.tile([np.sin(theta), 0.0, np.cos(theta)], (n, 1))
        f = sv.eval(np.tile(uv, (n, 1)), wi, wo)
        best = max(best, float((np.pi * f.mean(axis=0)).max()))
    return best


def test_paint_bounds_a_kd_map_brighter_than_its_material(tmp_path):
    """A white albedo texture on a glossy, dark material (eta 10, kd 0.05): without a new table the
    texel reflects far more than it receives; paint gives the layer an edit of its material at the
    map's brightest kd, whose energy-bound table keeps every texel within the bound. A map darker
    than its material keeps the material."""
    import hybridbrdf.model.editing as editing

    path, m = saved_random_model(tmp_path, "hybrid", output_layer="material", energy_bound=True)
    shiny = editing.edit(m, m.materials[0], "shiny", kd=0.05, eta=10.0, alpha=0.2)
    shiny.save(tmp_path / "shiny.safetensors")
    _write_png(tmp_path / "white.png", np.full((4, 4, 3), 255, np.uint8), "RGB")
    _write_png(tmp_path / "dark.png", np.full((4, 4, 3), 10, np.uint8), "RGB")
    bright = paint(tmp_path / "shiny.safetensors", "shiny", [], tmp_path / "bright", size=(4, 4),
                   kd={0: tmp_path / "white.png"})
    assert bright.layers == ["shiny.kdmap0"]
    unbounded = SVBRDF(load_model(tmp_path / "shiny.safetensors"), ["shiny"], (4, 4), None,
                       [{"kd": np.ones((4, 4, 3), np.float32)}])
    unbounded.save(tmp_path / "unbounded", format="exr")
    before = _max_albedo(load_svbrdf(tmp_path / "unbounded"), [0.5, 0.5])
    after = _max_albedo(load_svbrdf(tmp_path / "bright"), [0.5, 0.5])
    assert before > 1.1, before  # the control: the material's own table does not bound a white kd
    assert after <= spec.ENERGY_TARGET + 0.02, after
    dark = paint(tmp_path / "shiny.safetensors", "shiny", [], tmp_path / "dark", size=(4, 4),
                 kd={0: tmp_path / "dark.png"})
    assert dark.layers == ["shiny"]


def test_paint_fits_a_measured_layer_on_the_frozen_network(tmp_path):
    """A measured file as a layer is fitted onto the model's frozen network: the network kept bit
    for bit, and the layer's material fits the measurement better than any material it could have
    started from (the model's own; the sparse fit starts from the nearest of them), measured
    here with the fit's loss (log(1 + cos f), docs/CONVENTIONS.md "Fitting") on pairs of its own."""
    path, m = saved_random_model(tmp_path, "hybrid", output_layer="material")
    _write_png(tmp_path / "mask.png", np.full((4, 4), 128, np.uint8), "L")
    sv = paint(path, m.materials[1], [("synthetic:gold", tmp_path / "mask.png")], tmp_path / "sv",
               settings=FitSettings(steps=150))
    assert sv.layers == [m.materials[1], "gold"] and "gold" in sv.model.materials
    for key, value in m.tensors.items():
        if not key.startswith("materials."):
            np.testing.assert_array_equal(sv.model.tensors[key], value)  # the network kept bit for bit
    wi, wo = _directions(20000, seed=11)
    g = np.maximum(hb.open_source("synthetic:gold").eval(wi, wo), 0)

    def loss(f):
        c = wi[:, 2:3]
        return float(np.mean((np.log1p(c * np.maximum(f, 0)) - np.log1p(c * g)) ** 2))

    start = min(loss(m.eval(wi, wo, k, dtype=torch.float64)) for k in range(len(m.materials)))
    fitted = loss(sv.model.eval(wi, wo, "gold", dtype=torch.float64))
    # 150 steps bring it to 0.68 of the best start (a 1-step fit stays at 1.0).
    assert fitted < 0.8 * start, (fitted, start)
    # The painted texel (mask 128: half gold) is the mixture of the base and the fitted layer.
    texel = sv.eval(np.full((len(wi), 2), 0.5), wi, wo)
    w1 = 128 / 255
    mixed = (1 - w1) * m.eval(wi, wo, 1, dtype=torch.float64) + w1 * sv.model.eval(wi, wo, "gold", dtype=torch.float64)
    assert np.abs(texel - mixed).max() <= 2e-4 * np.abs(mixed).max()


def test_hbrdf_paint_command_line(tmp_path):
    path, m = saved_random_model(tmp_path, "hybrid")
    _write_png(tmp_path / "mask.png", np.full((3, 5), 255, np.uint8), "L")
    r = run_cli_here("paint", str(path), "--base", m.materials[0], "--layer", f"{m.materials[1]}=" + str(tmp_path / "mask.png"),
                "--format", "exr", "--out", str(tmp_path / "sv"))
    assert r.returncode == 0, r.stderr
    assert "5x3 texels, 2 layer(s)" in r.stdout
    assert load_svbrdf(tmp_path / "sv").texels(np.array([[0.5, 0.5]]))["weight"][0].tolist() == [0.0, 1.0]
    _write_png(tmp_path / "small.png", np.full((2, 2), 255, np.uint8), "L")
    r = run_cli_here("paint", str(path), "--base", m.materials[0], "--layer", f"{m.materials[1]}=" + str(tmp_path / "mask.png"),
                "--layer", f"{m.materials[2]}=" + str(tmp_path / "small.png"), "--out", str(tmp_path / "sv2"))
    assert r.returncode != 0 and "small.png: mask is 2x2; the textured material is 5x3" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "sv2").exists()
    r = run_cli_here("paint", str(path), "--base", "no-such-material", "--size", "4x4", "--out", str(tmp_path / "sv3"))
    assert r.returncode != 0 and "neither a material of" in r.stderr


# ---- libhybridbrdf's loader, sampler and the tracer --------------------------------------------


def _rich_folder(tmp_path, fmt):
    """Three layers with maps of every quantity somewhere: kd on layer 1, alpha on layer 2, eta and
    the latent code on layer 0; weights varying over the texture."""
    _, m = saved_random_model(tmp_path, "hybrid", output_layer="material", energy_bound=True)
    rng = np.random.default_rng(7)
    h, w = 6, 5
    weights = np.zeros((h, w, 3), np.float32)
    weights[..., 0] = rng.uniform(0, 0.6, (h, w))
    weights[..., 1] = rng.uniform(0, 0.4, (h, w))
    weights[2, 3] = [0, 0, 0]  # a pure base texel
    latent = m.tensors["materials.z"]
    maps = [{"eta": rng.uniform(1.2, 3.0, (h, w, 3)).astype(np.float32),
             "latent": (latent[0] + rng.normal(0, 0.3, (h, w, latent.shape[1]))).astype(np.float32)},
            {"kd": rng.uniform(0, 1, (h, w, 3)).astype(np.float32)},
            {"alpha": np.repeat(rng.uniform(0.05, 0.8, (h, w, 1)), 2, axis=2).astype(np.float32)}]
    SVBRDF(m, m.materials[:3], (w, h), weights, maps).save(tmp_path / fmt, format=fmt)
    return load_svbrdf(tmp_path / fmt)


@pytest.mark.parametrize("fmt", ["png", "exr"])
@pytest.mark.parametrize("filt", ["bilinear", "nearest"])
def test_cpp_loader_and_lookup_agree_with_python(tmp_path, fmt, filt):
    sv = _rich_folder(tmp_path, fmt)
    wi, wo = _directions(1500, seed=9)
    uv = np.random.default_rng(8).uniform(-1, 2, size=(len(wi), 2)).astype(np.float32).astype(np.float64)
    ref = sv.eval(uv, wi, wo, filter=filt, dtype=torch.float64)
    got = hb._core.Svbrdf(sv.path).eval(uv.astype(np.float32), wi.astype(np.float32), wo.astype(np.float32), filt)
    scale = np.abs(ref).max(axis=1, keepdims=True) + 1e-6
    assert np.abs(got - ref).max() / scale.max() < 1e-4
    assert np.all(np.abs(got - ref) <= 2e-4 * scale + 1e-6)
    analytic = hb._core.Svbrdf(sv.path).eval(uv.astype(np.float32), wi.astype(np.float32), wo.astype(np.float32), filt, True)
    t = sv.texels(uv, filt)
    w64 = [torch.as_tensor(a, dtype=torch.float64) for a in (wi, wo)]
    fa = sum(t["weight"][:, k, None].astype(np.float64) * eval_analytic(
        *w64, *(torch.as_tensor(t[q][:, k], dtype=torch.float64) for q in ("kd", "eta", "alpha"))).numpy()
        for k in range(3))
    scale = np.abs(fa).max(axis=1, keepdims=True) + 1e-6
    assert np.all(np.abs(analytic - fa) <= 2e-4 * scale + 1e-6)


def _regions_folder(tmp_path, addressing):
    """Four layers in regions: pure blocks of each (layer 3, the base's material with a kd map: its
    pure texels take the per-lane path), soft edges between them, every texel of column 0 mixed."""
    _, m = saved_random_model(tmp_path, "hybrid", output_layer="material", energy_bound=True)
    rng = np.random.default_rng(21)
    h, w = 16, 24
    weights = np.zeros((h, w, 3), np.float32)
    weights[:8, 8:16, 0] = 1     # layer 1 pure
    weights[8:, :12, 1] = 1      # layer 2 pure
    weights[8:, 12:, 2] = 1      # layer 3 pure (mapped)
    weights[7:9, :, :] = 0.3     # a soft band across
    weights[:, 0, :] = [0.2, 0.1, 0.3]
    maps = [{}, {}, {}, {"kd": rng.uniform(0, 1, (h, w, 3)).astype(np.float32)}]
    layers = [m.materials[0], m.materials[1], m.materials[2], m.materials[0]]  # layers 0 and 3 share a material
    SVBRDF(m, layers, (w, h), weights, maps, addressing=addressing).save(tmp_path / addressing, format="exr")
    return load_svbrdf(tmp_path / addressing)


@pytest.mark.parametrize("simd", ["baseline", "avx2+fma", "avx512"])
@pytest.mark.parametrize("kind", ["mixed", "one layer", "regions repeat", "regions clamp", "regions nearest"])
def test_batched_texels_match_the_scalar_path(tmp_path, simd, kind):
    """Svbrdf::eval_batch (runs of pure texels through the uniform kernel, other pairs layer by
    layer: plain layers through HybridModel::eval_batch, mapped ones through eval_batch_layers, the
    vectorised kernels; one layer of one material: no gather) against Svbrdf::eval one pair at a
    time, on every SIMD level the CPU has. The regions' uv come in texture order (runs of one pure
    layer long and short) with random pairs between, and beyond [0, 1] (repeat and clamp)."""
    filt = "nearest" if kind == "regions nearest" else "bilinear"
    if kind == "mixed":
        sv = _rich_folder(tmp_path, "exr")
    elif kind.startswith("regions"):
        sv = _regions_folder(tmp_path, "clamp" if kind == "regions clamp" else "repeat")
    else:
        _, m = saved_random_model(tmp_path, "hybrid", output_layer="material", energy_bound=True)
        z = m.tensors["materials.z"][1] + np.random.default_rng(3).normal(0, 0.2, (4, 5, m.tensors["materials.z"].shape[1]))
        SVBRDF(m, [m.materials[1]], (5, 4), None, [{"latent": z.astype(np.float32)}]).save(tmp_path / "one", format="exr")
        sv = load_svbrdf(tmp_path / "one")
    wi, wo = _directions(3000, seed=12)
    rng = np.random.default_rng(13)
    uv = rng.uniform(0, 1, size=(len(wi), 2)).astype(np.float32)
    if kind.startswith("regions"):
        uv[: len(uv) // 2] = np.sort(rng.uniform(-0.2, 1.2, len(uv) // 2))[:, None] * [1.0, 0.37]  # texture order
        uv[len(uv) // 2: len(uv) // 2 + 200] = rng.uniform(0.4, 0.6, (200, 2))
    lib = hb._core.Svbrdf(sv.path)
    args = (uv, wi.astype(np.float32), wo.astype(np.float32), filt)
    scalar = lib.eval(*args)
    hb._core.limit_model_simd(simd)
    try:
        batched = lib.eval(*args, batched=True)
    finally:
        hb._core.limit_model_simd("avx512")
    assert np.array_equal(batched == 0, scalar == 0)
    scale = np.abs(scalar).max(axis=1, keepdims=True) + 1e-6
    assert np.all(np.abs(batched - scalar) <= 2e-5 * scale), np.abs(batched - scalar).max()


def test_texel_sampler_density_is_consistent_and_normalised(tmp_path):
    """The mixture sampler's pdf is the one pdf() recomputes, and it integrates to 1 over the
    hemisphere (cosine and MIS strategies), at a mixed texel."""
    sv = _rich_folder(tmp_path, "exr")
    rng = np.random.default_rng(10)
    n = 4000
    uv = np.tile([[0.3, 0.55]], (n, 1)).astype(np.float32)
    wo = np.tile([[0.4, -0.2, 0.89]], (n, 1)).astype(np.float32)
    for strategy in ("cosine", "mis"):
        wi, pdf, again = hb._core.Svbrdf(sv.path).sample(uv, wo, rng.uniform(0, 1, (n, 2)).astype(np.float32), strategy)
        ok = pdf > 0
        assert ok.mean() > 0.95
        np.testing.assert_allclose(pdf[ok], again[ok], rtol=1e-4)
    # A chi-square test of the draws against the density: 8 x 8 cells in (cos theta, phi), each cell's
    # probability by a 24 x 24 midpoint quadrature of pdf (d omega = d cos theta d phi).
    from scipy.stats import chi2

    m, nz, nphi, q = 100_000, 8, 8, 24
    cz = (np.arange(nz * q) + 0.5) / (nz * q)
    cphi = (np.arange(nphi * q) + 0.5) / (nphi * q) * 2 * np.pi
    Z, P = np.meshgrid(cz, cphi, indexing="ij")
    R = np.sqrt(1 - Z * Z)
    grid = np.stack([R * np.cos(P), R * np.sin(P), Z], axis=-1).reshape(-1, 3).astype(np.float32)
    d_omega = (1.0 / (nz * q)) * (2 * np.pi / (nphi * q))
    for strategy in ("cosine", "mis"):
        dens = hb._core.Svbrdf(sv.path).pdf(np.tile(uv[:1], (len(grid), 1)), grid, np.tile(wo[:1], (len(grid), 1)), strategy)
        cell = (dens.reshape(nz, q, nphi, q).sum(axis=(1, 3)) * d_omega).ravel()
        total = cell.sum()
        assert 0.97 < total < 1.0 + 1e-3, (strategy, total)  # GGX draws below the horizon are lost, never gained
        wi, pdf, _ = hb._core.Svbrdf(sv.path).sample(np.tile(uv[:1], (m, 1)), np.tile(wo[:1], (m, 1)),
                                            rng.uniform(0, 1, (m, 2)).astype(np.float32), strategy)
        ok = (pdf > 0) & (wi[:, 2] > 0)  # GGX reflections below the horizon: drawn, then dropped by the tracer
        iz = np.clip((wi[ok, 2] * nz).astype(int), 0, nz - 1)
        iphi = np.clip((np.mod(np.arctan2(wi[ok, 1], wi[ok, 0]), 2 * np.pi) / (2 * np.pi) * nphi).astype(int), 0, nphi - 1)
        observed = np.bincount(iz * nphi + iphi, minlength=nz * nphi)
        expected = cell * m
        keep = expected > 5
        stat = ((observed[keep] - expected[keep]) ** 2 / expected[keep]).sum()
        assert chi2.sf(stat, keep.sum() - 1) > 1e-4, (strategy, stat, keep.sum())


def _sphere_scene(material, **kw):
    scene = {"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "fov_deg": 35, "width": 24, "height": 24},
             "environment": {"type": "sky", "resolution": [64, 32]},
             "materials": {"m": material},
             "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
             "spp": 1, "max_depth": 1, "threads": 1}
    scene.update(kw)
    return scene


def test_tracer_textured_material_of_one_layer_is_the_model_material(tmp_path):
    path, m = saved_random_model(tmp_path, "hybrid", output_layer="material")
    SVBRDF(m, [m.materials[1]], (4, 4)).save(tmp_path / "sv")
    uniform, _ = hb.render.tracer.render(_sphere_scene({"type": "model", "file": str(path), "material": m.materials[1]}),
                                         quiet=True)
    textured, _ = hb.render.tracer.render(_sphere_scene({"type": "textured", "svbrdf": str(tmp_path / "sv")}), quiet=True)
    assert np.abs(uniform).max() > 0
    np.testing.assert_allclose(textured, uniform, rtol=2e-4, atol=1e-6)


def test_tracer_reads_the_texel_under_each_hit(tmp_path):
    """A sphere textured half with material 0, half with material 2 (nearest texels): every pixel is
    the render of one of the two uniform materials, and both halves are seen."""
    path, m = saved_random_model(tmp_path, "hybrid", output_layer="material")
    weights = np.zeros((8, 16, 3), np.float32)
    weights[:, 12:, 0] = 1.0  # u >= 0.75: layer 1 (the camera on +z sees u in (0.5, 1))
    SVBRDF(m, [m.materials[0], m.materials[2]], (16, 8), weights).save(tmp_path / "sv")
    a, _ = hb.render.tracer.render(_sphere_scene({"type": "model", "file": str(path), "material": m.materials[0]}), quiet=True)
    b, _ = hb.render.tracer.render(_sphere_scene({"type": "model", "file": str(path), "material": m.materials[2]}), quiet=True)
    t, _ = hb.render.tracer.render(_sphere_scene({"type": "textured", "svbrdf": str(tmp_path / "sv"), "filter": "nearest"}),
                                   quiet=True)
    near_a = np.all(np.abs(t - a) <= 2e-4 * np.abs(a) + 1e-6, axis=2)
    near_b = np.all(np.abs(t - b) <= 2e-4 * np.abs(b) + 1e-6, axis=2)
    differ = ~np.all(np.abs(a - b) <= 1e-3 * np.abs(a) + 1e-6, axis=2)
    assert np.all(near_a | near_b)
    assert (near_a & ~near_b & differ).sum() > 20 and (near_b & ~near_a & differ).sum() > 20


def _two_lobe_sources(source):
    """Measured callables the tests know exactly: 'matte' a grey Lambertian, 'shiny' a tinted lobe
    around the mirror direction (keyed on the file name; the tracer resolves paths first)."""
    name = os.path.basename(source)

    def matte(wi, wo):
        return np.full((len(wi), 3), 0.6 / np.pi, np.float32)

    def shiny(wi, wo):
        mirror = wo * np.array([-1, -1, 1], np.float32)
        lobe = np.exp(20 * (np.sum(wi * mirror, axis=1) - 1))[:, None]
        return (lobe * np.array([2.0, 1.2, 0.4]) + 0.02).astype(np.float32)

    return {"matte": matte, "shiny": shiny}[name]


@pytest.mark.parametrize("layout", ["constant", "halves"])
def test_tracer_measured_mixture_is_the_weighted_sum_of_its_measurements(tmp_path, layout):
    """{"type": "measured", "layers": [...], "weights": FOLDER} against its measurements. Direct
    lighting with cosine sampling, one seed: a pixel is linear in the BRDF along fixed paths. Under a
    constant weight t the mixture is (1 - t) A + t B to rounding, A and B rendered as mixtures of one
    measurement with itself (the same layer choice per sample, hence the same paths); under a weights
    map of two pure halves (a pure texel samples as its layer alone) every pixel is the measurement
    rendered alone, A or B, and both are seen."""
    _, m = saved_random_model(tmp_path, "hybrid")
    weights = np.zeros((8, 16, 3), np.float32)
    if layout == "constant":
        weights[..., 0] = 0.3
    else:
        weights[:, 12:, 0] = 1.0  # u >= 0.75: layer 1
    SVBRDF(m, [m.materials[0], m.materials[2]], (16, 8), weights).save(tmp_path / "sv", format="exr")  # t exactly
    for name in ("matte", "shiny"):
        (tmp_path / name).write_text("")

    def render(material):
        scene = _sphere_scene(material, sampler="cosine", spp=2)
        scene["materials"]["m"] = material
        with open(tmp_path / "scene.json", "w") as fh:
            json.dump(scene, fh)
        return hb.render.tracer.render(str(tmp_path / "scene.json"), quiet=True, measured_factory=_two_lobe_sources)[0]

    if layout == "constant":
        a = render({"type": "measured", "layers": ["matte", "matte"], "weights": "sv", "filter": "nearest"})
        b = render({"type": "measured", "layers": ["shiny", "shiny"], "weights": "sv", "filter": "nearest"})
    else:
        a = render({"type": "measured", "source": "matte"})
        b = render({"type": "measured", "source": "shiny"})
    mix = render({"type": "measured", "layers": ["matte", "shiny"], "weights": "sv", "filter": "nearest"})
    assert np.abs(a - b).max() > 0.05
    if layout == "constant":
        np.testing.assert_allclose(mix, 0.7 * a + 0.3 * b, rtol=1e-5, atol=1e-6)
    else:
        near_a = np.all(np.abs(mix - a) <= 1e-5 * np.abs(a) + 1e-6, axis=2)
        near_b = np.all(np.abs(mix - b) <= 1e-5 * np.abs(b) + 1e-6, axis=2)
        assert np.all(near_a | near_b)
        assert (near_a & ~near_b).sum() > 20 and (near_b & ~near_a).sum() > 20


@pytest.mark.parametrize("material, message", [
    ({"type": "measured", "layers": ["matte"], "weights": "sv"}, "1 sources for the 2 layers of"),
    ({"type": "measured", "layers": ["matte", "shiny"], "source": "matte"}, "not both or neither"),
    ({"type": "measured", "layers": ["matte", "shiny"]}, "missing key 'weights'|weights"),
    ({"type": "measured", "layers": ["matte", "shiny"], "weights": "sv",
      "sampling_params": {"kd": 0.5}}, "takes no sampling_params"),
    ({"type": "measured", "source": "matte", "weights": "sv"}, "only a mixture"),
    ({"type": "measured", "layers": [], "weights": "sv"}, "array of 1 to 4 sources"),
    ({"type": "measured", "layers": ["matte", "shiny"], "weights": "nowhere"}, "weights: .*nowhere"),
])
def test_tracer_measured_mixture_refusals(tmp_path, material, message):
    _, m = saved_random_model(tmp_path, "hybrid")
    SVBRDF(m, [m.materials[0], m.materials[2]], (4, 2), np.full((2, 4, 3), 0.2, np.float32)).save(tmp_path / "sv")
    for name in ("matte", "shiny"):
        (tmp_path / name).write_text("")
    with open(tmp_path / "scene.json", "w") as fh:
        json.dump(_sphere_scene(material), fh)
    with pytest.raises(ValueError, match=message) as info:
        hb.render.tracer.render(str(tmp_path / "scene.json"), quiet=True, measured_factory=_two_lobe_sources)
    assert "\n" not in str(info.value) and "scene.json" in str(info.value)


def test_tracer_refuses_the_tabulated_sampler_for_a_measured_mixture(tmp_path):
    _, m = saved_random_model(tmp_path, "hybrid")
    SVBRDF(m, [m.materials[0], m.materials[2]], (4, 2), np.full((2, 4, 3), 0.2, np.float32)).save(tmp_path / "sv")
    for name in ("matte", "shiny"):
        (tmp_path / name).write_text("")
    with open(tmp_path / "scene.json", "w") as fh:
        json.dump(_sphere_scene({"type": "measured", "layers": ["matte", "shiny"], "weights": "sv"}, sampler="tabulated"), fh)
    with pytest.raises(ValueError, match="tabulated sampler tabulates one BRDF"):
        hb.render.tracer.render(str(tmp_path / "scene.json"), quiet=True, measured_factory=_two_lobe_sources)


def test_tracer_refuses_the_tabulated_sampler_for_textured_materials(tmp_path):
    _, m = saved_random_model(tmp_path, "hybrid")
    SVBRDF(m, [m.materials[0]], (2, 2)).save(tmp_path / "sv")
    with pytest.raises(ValueError, match="tabulated sampler tabulates one BRDF"):
        hb.render.tracer.render(_sphere_scene({"type": "textured", "svbrdf": str(tmp_path / "sv")}, sampler="tabulated"),
                                quiet=True)


def test_save_is_atomic_and_names_the_folder(tmp_path, monkeypatch):
    """SVBRDF.save: a failure while writing (ENOSPC at an fsync) leaves the old folder as it was,
    no temporary beside it, and one OutputFileError naming the folder; a temporary folder of a
    writer killed outright (a dead pid in its name) is removed by the next save."""
    import hybridbrdf.files.atomic as util

    _, m = saved_random_model(tmp_path, "hybrid")
    SVBRDF(m, [m.materials[0]], (2, 2)).save(tmp_path / "sv")
    before = sorted(os.listdir(tmp_path / "sv"))
    stale = tmp_path / ".sv.tmp-999999999-0123456789abcdef"
    stale.mkdir()
    (stale / "svbrdf.json").write_text("{}")
    real_fsync = os.fsync

    def full(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(util.os, "fsync", full)
    with pytest.raises(OutputFileError, match=r"/sv: No space left on device \(writing model.safetensors\)$"):
        SVBRDF(m, [m.materials[1]], (2, 2)).save(tmp_path / "sv")
    monkeypatch.setattr(util.os, "fsync", real_fsync)
    assert sorted(os.listdir(tmp_path / "sv")) == before
    assert load_svbrdf(tmp_path / "sv").layers == [m.materials[0]]
    assert not stale.exists()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".sv")) == []


def test_texels_bound_the_row_count_before_copying(tmp_path):
    """A broadcast view of 10^10 uv rows (16 bytes of data) is refused by its row count at once,
    not after numpy tried to convert it; a wrong shape names uv."""
    _, m = saved_random_model(tmp_path, "hybrid")
    sv = SVBRDF(m, [m.materials[0]], (2, 2))
    huge = np.broadcast_to(np.array([[0.5, 0.5]]), (10**10, 2))
    with pytest.raises(ValueError, match="uv rows"):
        sv.texels(huge)
    with pytest.raises(ValueError, match=r"uv must have shape \(N, 2\)"):
        sv.texels(np.zeros((3, 3)))
