"""Normal maps on textured materials (docs/SVBRDF.md, "Normal maps"; hybridbrdf.svbrdf.normals):
SVBRDF.eval takes geometric-frame directions and shades each texel in its perturbed frame; checked
against a float64 reference that rotates the directions by hand, for reciprocity and within the
energy bound in the perturbed frame; the format's round trip and refusals; the mip chain's
normalised mean and Toksvig widening against values computed by hand."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hybridbrdf.evaluate.metrics import metric_directions
from hybridbrdf.svbrdf.asset import SVBRDF, load_svbrdf
from hybridbrdf.svbrdf.entries import SVBRDFError
from hybridbrdf.svbrdf.normals import shading_frame, to_shading

from helpers import saved_random_model


@pytest.fixture(params=[("hybrid", "material", True), ("hybrid-reciprocal", "shared", False)],
                ids=["heads-bounded", "reciprocal-shared"])
def model(request, tmp_path):
    arch, output_layer, bound = request.param
    return saved_random_model(tmp_path, arch, output_layer=output_layer, energy_bound=bound)[1]


def _directions(n=4000, seed=5):
    wi, wo = metric_directions(n, seed)
    return np.asarray(wi, np.float64), np.asarray(wo, np.float64)


def _constant_normal(xy, h=4, w=4):
    return np.broadcast_to(np.asarray(xy, np.float32), (h, w, 2)).copy()


def _rot_y(theta):  # rotation about the bitangent (y) by theta: +z goes to (sin, 0, cos)
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rot_x(phi):  # rotation about the tangent (x) by -phi: +z goes to (0, sin, cos)
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


@pytest.mark.parametrize("rotation,xy", [
    (_rot_y(0.5), (np.sin(0.5), 0.0)),      # tilted towards +u: the shading frame is a rotation about b
    (_rot_x(-0.4), (0.0, np.sin(0.4))),     # tilted towards +b (the image's top): a rotation about t
])
def test_eval_is_the_layer_in_the_frame_rotated_by_hand(model, rotation, xy):
    """A constant normal map whose normal is a rotation R of +z about one axis: the shading frame is
    R's columns (Gram-Schmidt leaves t on the rotation's plane), so f(wi, wo) is the plain
    material at R^T wi, R^T wo, and 0 where either is below either horizon (float64 reference)."""
    name = model.materials[1]  # the anisotropic one: a wrong tangent shows
    plain = SVBRDF(model, [name], (4, 4))
    mapped = SVBRDF(model, [name], (4, 4), normal=_constant_normal(xy))
    wi, wo = _directions()
    assert np.allclose(rotation @ [0, 0, 1], [xy[0], xy[1], np.sqrt(1 - xy[0] ** 2 - xy[1] ** 2)])
    uv = np.full((len(wi), 2), 0.3)
    wi_s, wo_s = wi @ rotation, wo @ rotation  # rows: R^T w
    visible = (wi_s[:, 2] > 0) & (wo_s[:, 2] > 0) & (wi[:, 2] > 0) & (wo[:, 2] > 0)
    assert 0.05 < (~visible).mean() < 0.6  # both sides of the rule are exercised
    reference = np.where(visible[:, None], plain.eval(uv, np.where(visible[:, None], wi_s, wi),
                                                      np.where(visible[:, None], wo_s, wo)), 0.0)
    got = mapped.eval(uv, wi, wo)
    assert np.abs(got - reference).max() <= 2e-5 * max(1.0, np.abs(reference).max())


def test_frame_is_orthonormal_right_handed_and_follows_the_tangent():
    rng = np.random.default_rng(1)
    xy = rng.uniform(-0.7, 0.7, (500, 2))
    n = np.concatenate([xy, np.sqrt(np.maximum(0, 1 - (xy ** 2).sum(1, keepdims=True)))], 1)
    t_s, b_s, n_s = shading_frame(n)
    m = np.stack([t_s, b_s, n_s], axis=2)
    assert np.allclose(np.einsum("nij,nik->njk", m, m), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(m), 1.0)
    assert np.allclose(n_s, n)
    # Gram-Schmidt: t_s lies in the plane of t and n_s, on t's side (b_s is orthogonal to t)
    assert (t_s[:, 0] > 0).all() and np.allclose(np.sum(t_s * np.cross([1.0, 0, 0], n_s), axis=1), 0, atol=1e-12)
    assert np.allclose(b_s[:, 0], 0, atol=1e-12)


def test_reciprocal_where_the_layers_are(tmp_path):
    """A reciprocal model with a varying normal map: f(wi, wo) = f(wo, wi), the same rule for both."""
    model = saved_random_model(tmp_path, "hybrid-reciprocal", output_layer="shared")[1]
    rng = np.random.default_rng(2)
    normal = rng.uniform(-0.6, 0.6, (8, 8, 2)).astype(np.float32)
    sv = SVBRDF(model, [model.materials[0], model.materials[1]], (8, 8),
                weights=rng.uniform(0, 1, (8, 8, 3)).astype(np.float32) * [1, 0, 0], normal=normal)
    wi, wo = _directions(3000, 9)
    uv = rng.uniform(0, 1, (len(wi), 2))
    a, b = sv.eval(uv, wi, wo, dtype=__import__("torch").float64), sv.eval(uv, wo, wi, dtype=__import__("torch").float64)
    assert (a > 0).any(axis=1).mean() > 0.3
    assert np.abs(a - b).max() <= 1e-9 * max(1.0, np.abs(a).max())


def test_white_furnace_in_the_perturbed_frame(model):
    """Albedo in the shading frame, int f(wi, wo) cos_s(wi) dwi by cosine-weighted Monte Carlo about
    n_s: never above the layer's own albedo at wo_s with the same samples (the rule only removes
    lobe), and for the energy-bounded model at most 1 within the estimate's noise."""
    xy = (0.45, -0.3)
    n = np.array([xy[0], xy[1], np.sqrt(1 - xy[0] ** 2 - xy[1] ** 2)])
    t_s, b_s, n_s = (v[0] for v in shading_frame(n[None]))
    frame = np.stack([t_s, b_s, n_s], axis=1)  # columns: the shading axes in the geometric frame
    mapped = SVBRDF(model, [model.materials[2]], (2, 2), normal=_constant_normal(xy, 2, 2))
    plain = SVBRDF(model, [model.materials[2]], (2, 2))
    rng = np.random.default_rng(4)
    m = 20000
    u1, u2 = rng.uniform(size=m), rng.uniform(size=m)
    local = np.stack([np.sqrt(u1) * np.cos(2 * np.pi * u2), np.sqrt(u1) * np.sin(2 * np.pi * u2), np.sqrt(1 - u1)], 1)
    wi = local @ frame.T  # to the geometric frame
    for theta in (0.2, 0.9, 1.3):
        wo = np.tile([np.sin(theta), 0.0, np.cos(theta)], (m, 1))
        uv = np.full((m, 2), 0.5)
        f = mapped.eval(uv, wi, wo).mean(axis=1) * np.pi  # f cos / pdf with pdf = cos / pi
        wo_s = wo @ frame
        g = plain.eval(uv, local, wo_s).mean(axis=1) * np.pi
        assert (f <= g * (1 + 1e-5) + 1e-7).all()  # the layers run in float32: rotated inputs round differently
        assert (f < g * 0.5).mean() > 0.01 if theta == 1.3 else True  # and the rule does remove lobe at grazing wo
        if any("energy_bound" in key for key in model.tensors):
            assert f.mean() <= 1 + 4 * f.std() / np.sqrt(m)


@pytest.mark.parametrize("fmt", ["png", "exr", "ktx2"])
def test_round_trip(model, tmp_path, fmt):
    u = (np.arange(8) + 0.5) / 8  # a smooth bump field: BC5 holds it to an index step of each block's range
    normal = np.stack(np.broadcast_arrays(0.5 * np.sin(2 * np.pi * u)[None, :], 0.4 * np.cos(2 * np.pi * u)[:, None]), 2)
    sv = SVBRDF(model, [model.materials[0]], (8, 8), normal=normal.astype(np.float32)).with_mips()
    sv.save(tmp_path / "sv", format=fmt)
    back = load_svbrdf(tmp_path / "sv")
    tol = 1e-6 if fmt == "exr" else 1.01 / 255 * 2 if fmt == "png" else 0.012  # BC5 of a smooth field: 8-bit endpoints, 3-bit indices
    assert np.abs(back.normal - sv.normal).max() <= tol
    assert all(np.abs(a - b).max() <= tol for a, b in zip(back.normal_mips, sv.normal_mips))
    index = json.loads((tmp_path / "sv" / "svbrdf.json").read_text())
    entry = next(e for e in index["maps"] if e["quantity"] == "normal")
    assert "layer" not in entry and entry["decode"][2] is None
    if fmt != "exr":
        assert entry["decode"][0] == {"transfer": "linear", "scale": 2.0, "offset": -1.0}


def _saved_with_normal(model, tmp_path):
    normal = _constant_normal((0.2, -0.1))
    SVBRDF(model, [model.materials[0]], (4, 4), normal=normal).save(tmp_path / "sv", format="png")
    return tmp_path / "sv", json.loads((tmp_path / "sv" / "svbrdf.json").read_text())


@pytest.mark.parametrize("change,words", [
    (lambda e: e.update(layer=0), 'a normal map has no "layer"'),
    (lambda e: e["decode"][0].update(scale=3.0), "decodes to [-1, 2], outside normal's range [-1, 1]"),
    (lambda e: e["decode"].__setitem__(2, {"transfer": "linear", "scale": 2.0, "offset": -1.0}),
     "channel B holds no normal component; its decode must be null"),
])
def test_refusals(model, tmp_path, change, words):
    folder, index = _saved_with_normal(model, tmp_path)
    change(next(e for e in index["maps"] if e["quantity"] == "normal"))
    (folder / "svbrdf.json").write_text(json.dumps(index))
    with pytest.raises(SVBRDFError, match=words.replace("[", r"\[").replace("]", r"\]")):
        load_svbrdf(folder)


def test_mip_normal_is_the_normalised_mean_and_widens_alpha_by_toksvig(model):
    """A checkerboard of normals tilted by +-theta about b: level 1 holds +z and |mean n| = cos
    theta, so every layer's alpha^2 grows by (1 - cos theta) / cos theta (Toksvig's variance,
    mips.TOKSVIG_DEFAULT); a constant normal leaves alpha as the chain without a normal map has it."""
    theta = 0.3
    board = np.zeros((4, 4, 2), np.float32)
    board[..., 0] = np.sin(theta) * np.where((np.add.outer(np.arange(4), np.arange(4)) % 2) == 0, 1, -1)
    alpha = np.full((4, 4, 2), [0.1, 0.3], np.float32)
    sv = SVBRDF(model, [model.materials[0]], (4, 4), maps=[{"alpha": alpha}], normal=board).with_mips()
    (w1, maps1), n1 = sv.mips[0], sv.normal_mips[0]
    assert np.abs(n1).max() <= 1e-6
    expected = np.sqrt(np.array([0.1, 0.3]) ** 2 + (1 - np.cos(theta)) / np.cos(theta))
    assert np.allclose(maps1[0]["alpha"], expected, rtol=1e-5)
    flat = SVBRDF(model, [model.materials[0]], (4, 4), maps=[{"alpha": alpha}],
                  normal=_constant_normal((0.3, 0.2))).with_mips()
    plain = SVBRDF(model, [model.materials[0]], (4, 4), maps=[{"alpha": alpha}]).with_mips()
    assert np.allclose(flat.mips[0][1][0]["alpha"], plain.mips[0][1][0]["alpha"], rtol=1e-6)
    # a layer without an alpha map gains one (its material's alpha), widened the same way
    bare = SVBRDF(model, [model.materials[0]], (4, 4), normal=board).with_mips()
    own = np.asarray(model.tensors["materials.alpha"][model.index(model.materials[0])], np.float64)
    assert np.allclose(bare.mips[0][1][0]["alpha"], np.sqrt(own ** 2 + (1 - np.cos(theta)) / np.cos(theta)), rtol=1e-5)


def _bumpy(model, size=16, layers=2):
    """A two-layer material with a smooth bump field, alpha maps and its mip chain."""
    rng = np.random.default_rng(6)
    u = (np.arange(size) + 0.5) / size
    normal = np.stack(np.broadcast_arrays(0.6 * np.sin(4 * np.pi * u)[None, :], 0.5 * np.cos(2 * np.pi * u)[:, None]), 2)
    weights = np.zeros((size, size, 3), np.float32)
    weights[..., 0] = rng.uniform(0, 1, (size, size))
    names = [model.materials[0], model.materials[1]][:layers]
    return SVBRDF(model, names, (size, size), weights if layers > 1 else None,
                  [{"alpha": rng.uniform(0.05, 0.6, (size, size, 2)).astype(np.float32)}, {}][:layers],
                  normal=normal.astype(np.float32)).with_mips()


@pytest.mark.parametrize("fmt", ["exr", "ktx2"])
def test_libhybridbrdf_shades_in_the_same_frame(model, tmp_path, fmt):
    """libhybridbrdf's loader and Svbrdf (the tracer's) against Python's SVBRDF.eval on the same
    folder: scalar and batched paths, level 0 and trilinear lods, and its texel sampler returns
    geometric-frame directions whose pdf its pdf() recomputes."""
    import hybridbrdf as hb

    _bumpy(model).save(tmp_path / "sv", format=fmt)
    sv, lib = load_svbrdf(tmp_path / "sv"), hb._core.Svbrdf(str(tmp_path / "sv"))
    wi, wo = _directions(3000, 11)
    rng = np.random.default_rng(7)
    uv = rng.uniform(0, 1, (len(wi), 2))
    lod = rng.uniform(-0.5, 4.5, len(wi))
    want = sv.eval(uv, wi, wo)
    assert (want == 0).all(axis=1).mean() > 0.05
    f32 = [np.ascontiguousarray(a, np.float32) for a in (uv, wi, wo)]
    scale = max(1.0, np.abs(want).max())
    for batched in (False, True):
        assert np.abs(lib.eval(*f32, batched=batched) - want).max() <= 2e-4 * scale
        assert np.abs(lib.eval(*f32, batched=batched, lod=lod.astype(np.float32)) - sv.eval(uv, wi, wo, lod=lod)).max() <= 2e-4 * scale
    dirs, pdf, again = lib.sample(f32[0], f32[2], rng.uniform(0, 1, (len(wi), 2)).astype(np.float32))
    ok = pdf > 0
    assert ok.mean() > 0.5 and np.allclose(pdf[ok], again[ok], rtol=1e-3)
    assert (dirs[ok, 2] > 0).all()  # in the geometric frame, above its horizon


def test_libhybridbrdf_refuses_a_normal_map_as_python_does(model, tmp_path):
    import hybridbrdf as hb

    folder, index = _saved_with_normal(model, tmp_path)
    next(e for e in index["maps"] if e["quantity"] == "normal")["layer"] = 0
    (folder / "svbrdf.json").write_text(json.dumps(index))
    with pytest.raises(SVBRDFError) as py_err:
        load_svbrdf(folder)
    with pytest.raises(Exception) as cpp_err:
        hb._core.Svbrdf(str(folder))
    assert str(py_err.value) == str(cpp_err.value)


def test_hbrdf_paint_normal(tmp_path):
    """hbrdf paint --normal reads a glTF-style 8-bit normal map (R, G = (x + 1) / 2, (y + 1) / 2),
    writes it (KTX2: BC5; with its mip chain) and refuses another size in one line, writing nothing."""
    from PIL import Image

    from helpers import run_cli_here

    path, m = saved_random_model(tmp_path, "hybrid")
    rgb = np.zeros((4, 8, 3), np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 191, 64, 200  # x = 0.498, y = -0.498 (green low: tilted towards +v)
    Image.fromarray(rgb, "RGB").save(tmp_path / "n.png")
    r = run_cli_here("paint", str(path), "--base", m.materials[0], "--size", "8x4", "--normal", str(tmp_path / "n.png"),
                "--format", "ktx2", "--mips", "--out", str(tmp_path / "sv"))
    assert r.returncode == 0, r.stderr
    assert "a normal map" in r.stdout
    sv = load_svbrdf(tmp_path / "sv")
    assert np.abs(sv.normal - [191 / 255 * 2 - 1, 64 / 255 * 2 - 1]).max() <= 1.01 / 255 * 2
    assert sv.levels == 4 and np.abs(sv.normal_mips[-1] - sv.normal[0, 0]).max() <= 0.01
    Image.fromarray(rgb[:2], "RGB").save(tmp_path / "small.png")
    r = run_cli_here("paint", str(path), "--base", m.materials[0], "--size", "8x4", "--normal", str(tmp_path / "small.png"),
                "--out", str(tmp_path / "sv2"))
    assert r.returncode != 0 and "small.png: normal map is 8x2; the textured material is 8x4" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "sv2").exists()


def test_tracer_shades_in_the_normal_maps_frame(tmp_path):
    """The tracer's textured material (eval, sample and pdf at each hit): a flat normal map (x = y
    = 0, EXR so exactly +z) renders as no normal map, bit for bit within float rounding; a tilted
    one changes most lit pixels (fails when the tracer's material ignores the map)."""
    import hybridbrdf as hb
    import hybridbrdf.render.tracer  # noqa: F401

    path, m = saved_random_model(tmp_path, "hybrid", output_layer="material")
    SVBRDF(m, [m.materials[1]], (4, 4)).save(tmp_path / "plain", format="exr")
    SVBRDF(m, [m.materials[1]], (4, 4), normal=_constant_normal((0.0, 0.0))).save(tmp_path / "flat", format="exr")
    SVBRDF(m, [m.materials[1]], (4, 4), normal=_constant_normal((0.5, 0.3))).save(tmp_path / "tilted", format="exr")

    def render(folder, spp=1):
        scene = {"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "fov_deg": 35, "width": 20, "height": 20},
                 "environment": {"type": "sky", "resolution": [64, 32]},
                 "materials": {"m": {"type": "textured", "svbrdf": str(tmp_path / folder)}},
                 "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
                 "spp": spp, "max_depth": 1, "threads": 1}
        return hb.render.tracer.render(scene, quiet=True)[0]

    plain, flat, tilted = render("plain"), render("flat"), render("tilted")
    lit = np.abs(plain).max(axis=2) > 1e-4
    assert lit.sum() > 100
    np.testing.assert_allclose(flat, plain, rtol=2e-4, atol=1e-6)
    changed = np.abs(tilted - plain).max(axis=2) > 1e-2 * np.abs(plain).max(axis=2)
    assert changed[lit].mean() > 0.5


def test_codegen_and_viewer_read_a_normal_map(tmp_path):
    """Both read it now (tests/python/test_codegen_normals.py, test_view_svbrdf.py): the plan reads the
    map, the page carries it as a plane and shows it beside the sphere."""
    path, m = saved_random_model(tmp_path, "hybrid")
    SVBRDF(m, [m.materials[0]], (4, 4), normal=_constant_normal((0.2, 0.1))).save(tmp_path / "sv", format="png")
    from hybridbrdf.codegen.textured import textured_plan
    from hybridbrdf.viewer.textured import page_textured

    assert textured_plan(tmp_path / "sv")["has_normal"]
    page = page_textured(load_svbrdf(tmp_path / "sv"), str(tmp_path / "sv"), 8)
    assert page["plane"]["normal"] == 0 and page["thumbnails"][0]["label"] == "normal map"
